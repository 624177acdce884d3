//! What every STM32 flight-controller board gives the flight binary, written once: the
//! [`FlightBoard`] trait (constants, driver types, bring-up; the compiler checks each board
//! against it), the drivers' interfaces ([`MotorOutput`], [`BatteryInput`]), the
//! [`Peripherals`] a board's `init` hands over, and the parts the boards share (the MPU-6000's
//! SPI device on SPI1, the RC receiver's UART line, the companion link's baud rate).
//!
//! A board file (`f405.rs`, `h743.rs`) holds only what differs: pins, clocks, DMA streams,
//! motor timers, ADC, log card. A binary names its board once (`src/bin/parapet-firmware.rs`:
//! `type Board = MatekF405`) and runs the tasks of `src/bin/fc/` on it, which reach the board
//! only through this trait. May import: the HAL, [`crate::drivers`], [`crate::app`]
//! (the motor command), [`crate::log`] (the card's block device).

use core::ops::Range;

use embassy_embedded_hal::shared_bus::asynch::spi::SpiDeviceWithConfig;
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::flash::{self, Flash};
use embassy_stm32::gpio::Output;
use embassy_stm32::mode::Async;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_stm32::usart::{self, RingBufferedUartRx, UartTx};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;

use crate::app::autopilot::MotorCommand;
use crate::drivers::mpu6000::{AxisMap, Mpu6000};
use crate::drivers::rc_uart::{RcProtocol, RC_RX_RING};
#[cfg(feature = "onboard-log")]
use crate::log::card::BlockDevice;
use parapet_core::battery::AdcReading;

/// Companion UART baud rate.
pub const COMPANION_BAUD: u32 = 921_600;
/// DMA ring buffer for the companion UART receiver, bytes.
pub const COMPANION_RX_RING: usize = 1024;
/// SPI clock for MPU-6000 register writes (datasheet: ≤ 1 MHz).
pub const IMU_SPI_SLOW_HZ: u32 = 1_000_000;

/// Four motor outputs (DShot600 on the boards so far).
#[allow(async_fn_in_trait)] // used by the binaries' tasks only (no `Send` bound wanted)
pub trait MotorOutput {
    /// Sends one frame per motor. Disarmed → motor stop.
    async fn write(&mut self, cmd: &MotorCommand);
}

/// The battery's analog inputs.
pub trait BatteryInput {
    /// One blocking conversion of each input (in the calling, lowest-priority task).
    fn read(&mut self) -> AdcReading;
}

/// The onboard log's card: a block device whose bus clock goes up once it answered.
#[cfg(feature = "onboard-log")]
pub trait LogCardDevice: BlockDevice {
    /// The SPI clock after the card answered.
    fn go_fast(&mut self);
}

/// A flight-controller board: what the flight binary (`src/bin/parapet-firmware*.rs`, tasks in
/// `src/bin/fc/`) needs of it. Each board implements it on a marker type; the binary names
/// its board once (`type Board = …`).
pub trait FlightBoard: Sized {
    /// The board name the log records (`parapet_board`).
    const NAME: &'static str;
    /// Core clock, Hz (DWT cycle counter rate).
    const SYSCLK_HZ: u32;
    /// SPI clock asked for IMU sample reads.
    const IMU_SPI_FAST_HZ: u32;
    /// The parameter store's range in the internal flash (offsets from 0x0800_0000).
    const PARAM_RANGE: Range<u32>;
    /// The RC receiver of this build (a build-time choice, like the pin map).
    const RC_RECEIVER: RcProtocol;
    /// Motor outputs.
    type Motors: MotorOutput;
    /// Battery inputs.
    type Battery: BatteryInput;
    /// The log card.
    #[cfg(feature = "onboard-log")]
    type LogCard: LogCardDevice;

    /// Clocks, pins and drivers. `rx_ring` is the DMA ring buffer of the companion receiver,
    /// `rc_ring` that of the RC receiver.
    fn init(
        rx_ring: &'static mut [u8; COMPANION_RX_RING],
        rc_ring: &'static mut [u8; RC_RX_RING],
    ) -> Result<Peripherals<Self>, BoardError>;

    /// Panic / fault path: stops the motor outputs at register level, whatever the drivers
    /// were doing.
    fn force_motors_off();
}

/// The board's drivers, ready for the tasks.
pub struct Peripherals<B: FlightBoard> {
    /// SPI1 and the MPU-6000's chip select (the inner-loop task builds the driver on them).
    pub imu: ImuParts,
    /// Data-ready line of the IMU.
    pub imu_ready: ExtiInput<'static, Async>,
    /// Motor outputs.
    pub motors: B::Motors,
    /// Companion link transmitter.
    pub link_tx: UartTx<'static, Async>,
    /// Companion link receiver (DMA ring buffer).
    pub link_rx: RingBufferedUartRx<'static>,
    /// RC receiver ([`FlightBoard::RC_RECEIVER`]; DMA ring buffer).
    pub rc_rx: RingBufferedUartRx<'static>,
    /// The internal flash (the parameter store's sectors, [`FlightBoard::PARAM_RANGE`]).
    pub flash: Flash<'static, flash::Async>,
    /// The battery inputs.
    pub battery: B::Battery,
    /// The log card (not yet initialised: the first access does it).
    #[cfg(feature = "onboard-log")]
    pub log_card: B::LogCard,
}

/// Errors of the board bring-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum BoardError {
    /// A UART configuration (companion or RC receiver) was refused.
    Uart,
}

/// SPI1, the IMU's bus (one device on it).
pub type ImuSpiBus = Spi<'static, Async, spi::mode::Master>;
/// The bus behind an async mutex, as [`ImuSpi`] shares it. The inner-loop task owns it (no other
/// task touches SPI1), so the mutex is a [`NoopRawMutex`]: it never masks interrupts.
pub type ImuSpiBusMutex = Mutex<NoopRawMutex, ImuSpiBus>;
/// The IMU's SPI device: `embassy-embedded-hal`'s device on [`ImuSpiBus`] with the board's GPIO
/// chip select and its own bus configuration (set before every transaction).
pub type ImuSpi<'a> = SpiDeviceWithConfig<'a, NoopRawMutex, ImuSpiBus, Output<'static>>;

/// The IMU's SPI configuration at `hz`: mode 3 ([`IMU_SPI_SLOW_HZ`] for register writes,
/// [`FlightBoard::IMU_SPI_FAST_HZ`] for sample reads).
pub fn imu_spi_config(hz: u32) -> spi::Config {
    let mut cfg = spi::Config::default();
    cfg.mode = spi::MODE_3;
    cfg.frequency = Hertz(hz);
    cfg
}

/// The IMU's bus, chip select and mounting, for the inner-loop task to build its [`ImuSpi`] and
/// the `Mpu6000` driver on ([`ImuParts::device`]).
pub struct ImuParts {
    /// SPI1.
    pub bus: ImuSpiBus,
    /// Chip select (high = idle).
    pub cs: Output<'static>,
    /// The board's IMU mounting.
    pub axes: AxisMap,
}

impl ImuParts {
    /// The MPU-6000 driver on `bus` (the [`ImuSpiBusMutex`] made from [`ImuParts::bus`]) at the
    /// slow register-write clock, with the mounting `axes`.
    pub fn device<'a>(bus: &'a ImuSpiBusMutex, cs: Output<'static>, axes: AxisMap) -> Mpu6000<ImuSpi<'a>> {
        Mpu6000::new(SpiDeviceWithConfig::new(bus, cs, imu_spi_config(IMU_SPI_SLOW_HZ)), axes)
    }
}

/// The UART configuration of an RC protocol's line ([`RcProtocol::line`]; 8 data bits, with
/// parity a 9-bit word). Inversion is the board's: a hardware inverter (F405) or the USART's
/// RXINV (H743).
pub fn rc_uart_config(protocol: RcProtocol) -> usart::Config {
    let line = protocol.line();
    let mut cfg = usart::Config::default();
    cfg.baudrate = line.baud;
    cfg.data_bits = usart::DataBits::DataBits8;
    cfg.parity = if line.even_parity { usart::Parity::ParityEven } else { usart::Parity::ParityNone };
    cfg.stop_bits = if line.two_stop_bits { usart::StopBits::STOP2 } else { usart::StopBits::STOP1 };
    cfg
}
