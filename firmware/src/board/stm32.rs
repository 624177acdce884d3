//! What every STM32 flight-controller board gives the flight binary, written once: the
//! [`FlightBoard`] trait (constants, driver types, bring-up; the compiler checks each board
//! against it), the drivers' interfaces ([`MotorOutput`], [`BatteryInput`]), the
//! [`Peripherals`] a board's `init` hands over, and the bring-up the boards share, generic over
//! the HAL's per-chip types: the HAL and clock start-up ([`FlightBoard::init`]), the interrupt
//! bindings' handler types (`stm32_irqs!`), the MPU-6000's SPI bus and device ([`imu_bus`],
//! [`chip_select`]), the companion link ([`companion_link`]), the RC receiver's UART line
//! ([`rc_receiver`], [`rc_uart_config`]), the DShot timers ([`dshot_timer`], [`motor_pin`]).
//!
//! A board file (`f405.rs`, `h743.rs`) holds only what differs: which pins, clocks, DMA streams,
//! motor timers, ADC, log card; it implements [`FlightBoard::clock_config`] and
//! [`FlightBoard::bring_up`] by calling the helpers here with its pins. A binary names its board once (`src/bin/parapet-firmware.rs`:
//! `flight_binary!(…::MatekF405, [])`) and runs the tasks of `src/bin/fc/` on it, which reach the board
//! only through this trait. May import: the HAL, [`crate::drivers`], [`crate::app`]
//! (the motor command), [`crate::log`] (the card's block device).

use core::ops::Range;

use embassy_embedded_hal::shared_bus::asynch::spi::SpiDeviceWithConfig;
use embassy_stm32::dma;
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::flash::{self, Flash};
use embassy_stm32::gpio::{Level, Output, OutputType, Pin, Speed};
use embassy_stm32::interrupt::typelevel::Binding;
use embassy_stm32::mode::Async;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::timer::{Ch1, Ch2, Ch3, Ch4, GeneralInstance4Channel, TimerChannel, TimerPin};
use embassy_stm32::usart::{self, RingBufferedUartRx, Uart, UartRx, UartTx};
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;

use crate::app::autopilot::MotorCommand;
use crate::drivers::dshot;
use crate::drivers::mpu6000::{AxisMap, Mpu6000};
use crate::drivers::rc_uart::{RcProtocol, RC_RX_RING};
#[cfg(feature = "onboard-log")]
use crate::log::card::BlockDevice;
use parapet_core::battery::AdcReading;

/// The board's interrupt bindings, `Irqs` (`embassy_stm32::bind_interrupts!`), with the
/// handler types written here once: a board lists its UARTs, its DMA streams (interrupt =>
/// channel) and the IMU's EXTI line; the flash interrupt is bound on every board.
macro_rules! stm32_irqs {
    (uarts: [$($uart:ident),*], dma: [$($stream:ident => $ch:ident),*], exti: $exti:ident) => {
        embassy_stm32::bind_interrupts!(
            /// Interrupt bindings of the board's drivers.
            pub struct Irqs {
                $($uart => embassy_stm32::usart::InterruptHandler<embassy_stm32::peripherals::$uart>;)*
                $($stream => embassy_stm32::dma::InterruptHandler<embassy_stm32::peripherals::$ch>;)*
                $exti => embassy_stm32::exti::InterruptHandler<embassy_stm32::interrupt::typelevel::$exti>;
                FLASH => embassy_stm32::flash::InterruptHandler;
            }
        );
    };
}
pub(crate) use stm32_irqs;

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

    /// The board's clock tree (HSE, PLL, bus prescalers).
    fn clock_config() -> embassy_stm32::Config;

    /// Pins and drivers, on the HAL's peripherals `p` (clocks already up).
    fn bring_up(p: embassy_stm32::Peripherals, rings: Rings) -> Result<Peripherals<Self>, BoardError>;

    /// Clocks ([`FlightBoard::clock_config`]), pins and drivers ([`FlightBoard::bring_up`]).
    /// `rx_ring` is the DMA ring buffer of the companion receiver, `rc_ring` that of the RC
    /// receiver.
    fn init(
        rx_ring: &'static mut [u8; COMPANION_RX_RING],
        rc_ring: &'static mut [u8; RC_RX_RING],
    ) -> Result<Peripherals<Self>, BoardError> {
        Self::bring_up(embassy_stm32::init(Self::clock_config()), Rings { link: rx_ring, rc: rc_ring })
    }

    /// Panic / fault path: stops the motor outputs at register level, whatever the drivers
    /// were doing.
    fn force_motors_off();
}

/// The DMA ring buffers of the board's receivers.
pub struct Rings {
    /// The companion link's receiver.
    pub link: &'static mut [u8; COMPANION_RX_RING],
    /// The RC receiver's.
    pub rc: &'static mut [u8; RC_RX_RING],
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

/// What every board brings up the same way on its own pins (made by [`imu_bus`],
/// [`chip_select`], [`companion_link`], [`rc_receiver`]); [`Peripherals::new`] adds the
/// board's own drivers.
pub struct ChipParts {
    /// The IMU's bus, chip select and mounting.
    pub imu: ImuParts,
    /// Data-ready line of the IMU.
    pub imu_ready: ExtiInput<'static, Async>,
    /// Companion link transmitter and receiver ([`companion_link`]).
    pub link: (UartTx<'static, Async>, RingBufferedUartRx<'static>),
    /// RC receiver ([`rc_receiver`]).
    pub rc_rx: RingBufferedUartRx<'static>,
    /// The internal flash.
    pub flash: Flash<'static, flash::Async>,
}

impl<B: FlightBoard> Peripherals<B> {
    /// The chip's common parts and the board's own drivers (motors, battery inputs, log card),
    /// handed to the tasks.
    pub fn new(
        chip: ChipParts,
        (motors, battery): (B::Motors, B::Battery),
        #[cfg(feature = "onboard-log")] log_card: B::LogCard,
    ) -> Self {
        let ChipParts { imu, imu_ready, link: (link_tx, link_rx), rc_rx, flash } = chip;
        Self {
            imu,
            imu_ready,
            motors,
            link_tx,
            link_rx,
            rc_rx,
            flash,
            battery,
            #[cfg(feature = "onboard-log")]
            log_card,
        }
    }
}

/// The IMU's SPI bus (mode 3, [`IMU_SPI_SLOW_HZ`] until the driver asks for more) on the
/// board's SPI peripheral, pins and DMA streams.
pub fn imu_bus<T: spi::Instance, Tx: spi::TxDma<T>, Rx: spi::RxDma<T>>(
    spi: Peri<'static, T>,
    sck: Peri<'static, impl spi::SckPin<T>>,
    mosi: Peri<'static, impl spi::MosiPin<T>>,
    miso: Peri<'static, impl spi::MisoPin<T>>,
    tx_dma: Peri<'static, Tx>,
    rx_dma: Peri<'static, Rx>,
    irqs: impl Binding<Tx::Interrupt, dma::InterruptHandler<Tx>>
        + Binding<Rx::Interrupt, dma::InterruptHandler<Rx>>
        + 'static,
) -> ImuSpiBus {
    Spi::new(spi, sck, mosi, miso, tx_dma, rx_dma, irqs, imu_spi_config(IMU_SPI_SLOW_HZ))
}

/// A chip-select output, idle high, fast edges.
pub fn chip_select(pin: Peri<'static, impl Pin>) -> Output<'static> {
    Output::new(pin, Level::High, Speed::VeryHigh)
}

/// The companion link: the UART at [`COMPANION_BAUD`], its receiver on the DMA ring buffer
/// `rx_ring`.
pub fn companion_link<T: usart::Instance, Tx: usart::TxDma<T>, Rx: usart::RxDma<T>>(
    uart: Peri<'static, T>,
    rx: Peri<'static, impl usart::RxPin<T>>,
    tx: Peri<'static, impl usart::TxPin<T>>,
    tx_dma: Peri<'static, Tx>,
    rx_dma: Peri<'static, Rx>,
    irqs: impl Binding<T::Interrupt, usart::InterruptHandler<T>>
        + Binding<Tx::Interrupt, dma::InterruptHandler<Tx>>
        + Binding<Rx::Interrupt, dma::InterruptHandler<Rx>>
        + 'static,
    rx_ring: &'static mut [u8; COMPANION_RX_RING],
) -> Result<(UartTx<'static, Async>, RingBufferedUartRx<'static>), BoardError> {
    let mut cfg = usart::Config::default();
    cfg.baudrate = COMPANION_BAUD;
    let uart = Uart::new(uart, rx, tx, tx_dma, rx_dma, irqs, cfg).map_err(|_| BoardError::Uart)?;
    let (link_tx, link_rx) = uart.split();
    Ok((link_tx, link_rx.into_ring_buffered(rx_ring)))
}

/// The RC receiver's line ([`rc_uart_config`] of `cfg`'s protocol, with the board's
/// inversion) on the DMA ring buffer `rc_ring`.
pub fn rc_receiver<T: usart::Instance, Rx: usart::RxDma<T>>(
    uart: Peri<'static, T>,
    rx: Peri<'static, impl usart::RxPin<T>>,
    rx_dma: Peri<'static, Rx>,
    irqs: impl Binding<T::Interrupt, usart::InterruptHandler<T>>
        + Binding<Rx::Interrupt, dma::InterruptHandler<Rx>>
        + 'static,
    cfg: usart::Config,
    rc_ring: &'static mut [u8; RC_RX_RING],
) -> Result<RingBufferedUartRx<'static>, BoardError> {
    Ok(UartRx::new(uart, rx, rx_dma, irqs, cfg).map_err(|_| BoardError::Uart)?.into_ring_buffered(rc_ring))
}

/// A motor output pin: channel `C` of timer `T`, push-pull.
pub fn motor_pin<T: GeneralInstance4Channel, C: TimerChannel>(
    pin: Peri<'static, impl TimerPin<T, C>>,
) -> Option<PwmPin<'static, T, C>> {
    Some(PwmPin::new(pin, OutputType::PushPull))
}

/// Timer `T` as DShot600 outputs on the channels given pins ([`motor_pin`]; `None`: not a
/// motor), with its period (max compare value + 1, the DShot burst's scale).
pub fn dshot_timer<T: GeneralInstance4Channel>(
    tim: Peri<'static, T>,
    ch1: Option<PwmPin<'static, T, Ch1>>,
    ch2: Option<PwmPin<'static, T, Ch2>>,
    ch3: Option<PwmPin<'static, T, Ch3>>,
    ch4: Option<PwmPin<'static, T, Ch4>>,
) -> (SimplePwm<'static, T>, u16) {
    let pwm = SimplePwm::new(tim, ch1, ch2, ch3, ch4, Hertz(dshot::BITRATE_HZ), CountingMode::EdgeAlignedUp);
    let period = u16::try_from(pwm.max_duty_cycle()).unwrap_or(u16::MAX);
    (pwm, period)
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
