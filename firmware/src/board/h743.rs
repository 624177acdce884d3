//! Board layer: MATEKH743 (STM32H743VIT6, 8 MHz HSE, MPU-6000 on SPI1) — the second board,
//! with the same public items as [`crate::board::f405`] so the same binary (`src/main.rs`,
//! built as `parapet-firmware-h743` with `--no-default-features --features board-h743`) runs
//! the same tasks on it. Pins from Matek's H743 wiring as Betaflight's/INAV's `MATEKH743`
//! targets describe it; **not flown yet: check the IMU axes, the motor order and the UART
//! on the bench** (`docs/bring-up.md`).
//!
//! | function | peripheral | pins | DMA (any stream: DMAMUX) |
//! |---|---|---|---|
//! | IMU MPU-6000 (IMU 1) | SPI1, mode 3, 1 MHz (init) / 10 MHz (reads), kernel clock PLL1_Q 100 MHz | SCK PA5, MISO PA6, MOSI PD7, CS PC15 | TX DMA1 stream 0, RX DMA1 stream 1 |
//! | IMU data ready | EXTI2 | PB2 (rising edge) | – |
//! | motors M1, M2, DShot600 | TIM3 CH3, CH4 | PB0, PB1 | TIM3_UP burst, DMA1 stream 2 |
//! | motors M3, M4, DShot600 | TIM5 CH1, CH2 | PA0, PA1 | TIM5_UP burst, DMA1 stream 3 |
//! | companion link, MAVLink 921 600 Bd | USART1 | TX PA9, RX PA10 (pads TX1/RX1) | TX DMA1 stream 4, RX DMA1 stream 5 (ring buffer) |
//! | RC receiver CRSF, 420 000 Bd 8N1 — [`RC_RECEIVER`] `Crsf` (default) | USART2 | RX PD6 (pad R2; receiver TX → R2) | RX DMA1 stream 6 (ring buffer) |
//! | RC receiver SBUS, 100 000 Bd 8E2, inverted — [`RC_RECEIVER`] `Sbus` | USART6 | RX PC7 (pad R6); inverted by the H7's USART (RXINV), no inverter on the board | RX DMA1 stream 7 (ring buffer) |
//! | battery voltage (VBAT divider, `BAT_V_DIV` 11: Betaflight `vbat_scale` 110) | ADC1 INP10, 12-bit | PC0 | – (blocking reads, [`BatteryAdc`]) |
//! | battery current (pad CURR, `BAT_A_PER_V`; Betaflight `ibata_scale` 250 = 40 A/V) | ADC1 INP11 | PC1 | – |
//! | parameter store | FLASH bank 2, sectors 6-7 (0x081C_0000..0x0820_0000, [`PARAM_RANGE`]; kept out of `FLASH` by `memory-h743.x`) | – | – (FLASH interrupt) |
//! | embassy time driver | TIM2 | – | – |
//! | software interrupts for the executors | UART4 (high), UART5 (medium), I2C1_EV (RC + battery) | unused UARTs, unused I2C1 | – |
//!
//! Clocks: HSE 8 MHz → PLL1 (M 2, N 200: VCO 800 MHz; P 2, Q 8) → SYSCLK 400 MHz (VOS1),
//! AHB 200 MHz, APB1..4 100 MHz (timers 200 MHz), SPI1 kernel clock PLL1_Q = 100 MHz.
//!
//! Memory: `memory-h743.x` — flash 2 MiB at 0x0800_0000; RAM = the 512 KiB AXI SRAM at
//! 0x2400_0000, because the DMA streams that feed SPI1 and USART1 cannot reach the DTCM at
//! 0x2000_0000 (reference manual RM0433, bus matrix).
//!
//! What the board has and the app does not use (yet): the second IMU (ICM20602 / ICM42605 on
//! SPI4), the microSD blackbox on SDMMC1 (CK PC12, CMD PD2, D0-D3 PC8-PC11). The parameter
//! store's sectors are in bank 2 while the program runs from bank 1, so (unlike the F405) an
//! erase there does not stall instruction fetches (RM0433, dual-bank flash). The four motors sit on two timers, so a motor update is two DMA bursts
//! (≈ 30 µs each, run concurrently).

use embassy_embedded_hal::shared_bus::asynch::spi::SpiDeviceWithConfig;
use embassy_stm32::adc::{Adc, AdcChannel, AdcConfig, AnyAdcChannel, Resolution, SampleTime};
use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::flash::{self, Flash};
use embassy_stm32::gpio::{Level, Output, OutputType, Pull, Speed};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::timer::Channel;
use embassy_stm32::usart::{self, RingBufferedUartRx, Uart, UartRx, UartTx};
use embassy_stm32::{bind_interrupts, dma, interrupt, Config, Peri};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;

use crate::app::autopilot::MotorCommand;
use crate::drivers::dshot;
use crate::drivers::mpu6000::{AxisMap, Mpu6000};
use crate::drivers::rc_uart::{RcProtocol, RC_RX_RING};
use crate::log::card::{BlockDevice, BLOCK};
use crate::log::ulog::LogError;
use parapet_core::battery::AdcReading;

/// Companion UART baud rate.
pub const COMPANION_BAUD: u32 = 921_600;
/// Core clock, Hz (DWT cycle counter rate).
pub const SYSCLK_HZ: u32 = 400_000_000;
/// IMU mounting: Betaflight `CW0_DEG_FLIP` (chip upside down) on a chip whose default frame is
/// x forward, y left, z up: FRD = (−x, −y, z).
pub const IMU_AXES: AxisMap = AxisMap { axis: [0, 1, 2], sign: [-1, -1, 1] };
/// SPI clock for MPU-6000 register writes (datasheet: ≤ 1 MHz).
pub const IMU_SPI_SLOW_HZ: u32 = 1_000_000;
/// SPI clock asked for sensor reads (datasheet: ≤ 20 MHz); the driver takes the highest
/// power-of-two division of the 100 MHz kernel clock at or below it: 6.25 MHz.
pub const IMU_SPI_FAST_HZ: u32 = 10_000_000;
/// DMA ring buffer for the companion UART receiver, bytes.
pub const COMPANION_RX_RING: usize = 1024;

/// Compare slots of a two-channel DShot burst.
const PAIR_BURST_LEN: usize = dshot::SLOTS * 2;

bind_interrupts!(
    /// Interrupt bindings of the board's drivers.
    pub struct Irqs {
    USART1 => usart::InterruptHandler<peripherals::USART1>;
    USART2 => usart::InterruptHandler<peripherals::USART2>;
    USART6 => usart::InterruptHandler<peripherals::USART6>;
    EXTI2 => exti::InterruptHandler<interrupt::typelevel::EXTI2>;
    DMA1_STREAM0 => dma::InterruptHandler<peripherals::DMA1_CH0>;
    DMA1_STREAM1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_STREAM2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    DMA1_STREAM3 => dma::InterruptHandler<peripherals::DMA1_CH3>;
    DMA1_STREAM4 => dma::InterruptHandler<peripherals::DMA1_CH4>;
    DMA1_STREAM5 => dma::InterruptHandler<peripherals::DMA1_CH5>;
    DMA1_STREAM6 => dma::InterruptHandler<peripherals::DMA1_CH6>;
    DMA1_STREAM7 => dma::InterruptHandler<peripherals::DMA1_CH7>;
    FLASH => flash::InterruptHandler;
});

/// The parameter store's range (offsets from 0x0800_0000): the last two 128 KiB sectors of
/// bank 2.
pub const PARAM_RANGE: core::ops::Range<u32> = 0x001C_0000..0x0020_0000;

/// The battery inputs (see the pin table), 12-bit conversions; the analog supply is taken as the
/// nominal 3.3 V (the H7's VREFINT calibration is a 16-bit value: not used here).
pub struct BatteryAdc {
    adc: Adc<'static, peripherals::ADC1>,
    vbat: AnyAdcChannel<'static, peripherals::ADC1>,
    current: AnyAdcChannel<'static, peripherals::ADC1>,
}

impl BatteryAdc {
    /// One blocking conversion of each input (2 × 810.5 ADC cycles), in the calling
    /// (lowest-priority) task.
    pub fn read(&mut self) -> AdcReading {
        let vbat = self.adc.blocking_read(&mut self.vbat, SampleTime::CYCLES810_5);
        let current = self.adc.blocking_read(&mut self.current, SampleTime::CYCLES810_5);
        AdcReading { vbat, current: Some(current), vrefint: None }
    }
}

/// Clock tree of the board (see the module docs).
pub fn clock_config() -> Config {
    use embassy_stm32::rcc::{
        AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllDiv, PllMul, PllPreDiv, PllSource, Sysclk,
        VoltageScale,
    };
    let mut config = Config::default();
    config.rcc.hse = Some(Hse { freq: Hertz(8_000_000), mode: HseMode::Oscillator });
    config.rcc.pll1 = Some(Pll {
        source: PllSource::HSE,
        prediv: PllPreDiv::DIV2,
        mul: PllMul::MUL200,
        fracn: None,
        divp: Some(PllDiv::DIV2),
        divq: Some(PllDiv::DIV8),
        divr: None,
    });
    config.rcc.sys = Sysclk::PLL1_P;
    config.rcc.ahb_pre = AHBPrescaler::DIV2;
    config.rcc.apb1_pre = APBPrescaler::DIV2;
    config.rcc.apb2_pre = APBPrescaler::DIV2;
    config.rcc.apb3_pre = APBPrescaler::DIV2;
    config.rcc.apb4_pre = APBPrescaler::DIV2;
    config.rcc.voltage_scale = VoltageScale::Scale1;
    config
}

/// SPI1, the IMU's bus (one device on it).
pub type ImuSpiBus = Spi<'static, Async, spi::mode::Master>;
/// The bus behind an async mutex (the inner-loop task is its only user: [`NoopRawMutex`]).
pub type ImuSpiBusMutex = Mutex<NoopRawMutex, ImuSpiBus>;
/// The IMU's SPI device: chip select PC15, its own bus configuration per transaction.
pub type ImuSpi<'a> = SpiDeviceWithConfig<'a, NoopRawMutex, ImuSpiBus, Output<'static>>;

/// The IMU's SPI configuration at `hz` (mode 3).
pub fn imu_spi_config(hz: u32) -> spi::Config {
    let mut cfg = spi::Config::default();
    cfg.mode = spi::MODE_3;
    cfg.frequency = Hertz(hz);
    cfg
}

/// The IMU's bus and chip select.
pub struct ImuParts {
    /// SPI1.
    pub bus: ImuSpiBus,
    /// Chip select (high = idle).
    pub cs: Output<'static>,
}

impl ImuParts {
    /// The MPU-6000 driver on `bus` at the slow register-write clock.
    pub fn device<'a>(bus: &'a ImuSpiBusMutex, cs: Output<'static>) -> Mpu6000<ImuSpi<'a>> {
        Mpu6000::new(SpiDeviceWithConfig::new(bus, cs, imu_spi_config(IMU_SPI_SLOW_HZ)), IMU_AXES)
    }
}

/// Four DShot600 outputs: M1, M2 on TIM3 CH3/CH4, M3, M4 on TIM5 CH1/CH2; each pair updated by
/// one DMA burst, both bursts concurrently.
pub struct DshotMotors {
    pwm12: SimplePwm<'static, peripherals::TIM3>,
    pwm34: SimplePwm<'static, peripherals::TIM5>,
    dma12: Peri<'static, peripherals::DMA1_CH2>,
    dma34: Peri<'static, peripherals::DMA1_CH3>,
    period12: u16,
    period34: u16,
    buf12: [u16; PAIR_BURST_LEN],
    buf34: [u16; PAIR_BURST_LEN],
}

/// A two-channel burst (rows of two compare values) from the four-channel layout of
/// [`dshot::fill_burst`], channels `first` and `first + 1`.
fn pair_burst(frames: [u16; dshot::CHANNELS], first: usize, period: u16, out: &mut [u16; PAIR_BURST_LEN]) {
    let mut four = [0u16; dshot::BURST_LEN];
    dshot::fill_burst(frames, period, &mut four);
    for (row, dst) in four.chunks_exact(dshot::CHANNELS).zip(out.chunks_exact_mut(2)) {
        for (d, s) in dst.iter_mut().zip(row.iter().skip(first)) {
            *d = *s;
        }
    }
}

impl DshotMotors {
    /// Sends one frame per motor (≈ 30 µs). Disarmed → DShot 0 (motor stop).
    pub async fn write(&mut self, cmd: &MotorCommand) {
        let cmd = cmd.sanitized();
        let frames = cmd.throttle.map(|t| dshot::frame(dshot::throttle_to_value(t, cmd.armed), false));
        pair_burst(frames, 0, self.period12, &mut self.buf12);
        pair_burst(frames, 2, self.period34, &mut self.buf34);
        let a = self.pwm12.waveform_up_multi_channel(
            self.dma12.reborrow(),
            Irqs,
            Channel::Ch3,
            Channel::Ch4,
            &self.buf12,
        );
        let b = self.pwm34.waveform_up_multi_channel(
            self.dma34.reborrow(),
            Irqs,
            Channel::Ch1,
            Channel::Ch2,
            &self.buf34,
        );
        embassy_futures::join::join(a, b).await;
    }
}

/// Panic / fault path: stops the motor outputs at register level (DMA requests off, compare
/// values 0 → lines low; DShot ESCs stop on signal loss).
pub fn force_motors_off() {
    let t3 = embassy_stm32::pac::TIM3;
    t3.dier().modify(|w| w.set_ude(false));
    for ch in 2..4 {
        t3.ccr(ch).write_value(embassy_stm32::pac::timer::regs::Ccr1ch(0));
    }
    let t5 = embassy_stm32::pac::TIM5;
    t5.dier().modify(|w| w.set_ude(false));
    for ch in 0..2 {
        t5.ccr(ch).write_value(0);
    }
}

/// The board name the log records (`parapet_board`).
pub const BOARD_NAME: &str = "matekh743";

/// The log card of this board: **not implemented** (the microSD is on SDMMC1; no SDMMC driver is
/// wired yet). Every access fails, so the log store stays off: the link task says so once in a
/// STATUSTEXT and nothing is logged (docs/bring-up.md §9).
pub struct LogCard;

impl LogCard {
    /// No bus clock to change.
    pub fn go_fast(&mut self) {}
}

impl BlockDevice for LogCard {
    fn read(&mut self, _lba: u32, _buf: &mut [u8; BLOCK]) -> Result<(), LogError> {
        Err(LogError::Device)
    }
    fn write(&mut self, _lba: u32, _buf: &[u8; BLOCK]) -> Result<(), LogError> {
        Err(LogError::Device)
    }
    fn blocks(&mut self) -> Result<u32, LogError> {
        Err(LogError::Device)
    }
}

/// The board's drivers, ready for the tasks.
pub struct Board {
    /// SPI1 and the MPU-6000's chip select.
    pub imu: ImuParts,
    /// Data-ready line of the IMU.
    pub imu_ready: ExtiInput<'static, Async>,
    /// Motor outputs.
    pub motors: DshotMotors,
    /// Companion link transmitter.
    pub link_tx: UartTx<'static, Async>,
    /// Companion link receiver (DMA ring buffer).
    pub link_rx: RingBufferedUartRx<'static>,
    /// RC receiver ([`RC_RECEIVER`]: CRSF on USART2 or SBUS on USART6; DMA ring buffer).
    pub rc_rx: RingBufferedUartRx<'static>,
    /// The internal flash (the parameter store's sectors, [`PARAM_RANGE`]).
    pub flash: Flash<'static, flash::Async>,
    /// The battery inputs.
    pub battery: BatteryAdc,
    /// The log card ([`LogCard`]: none on this board yet).
    pub log_card: LogCard,
}

/// The RC receiver's protocol on this board (as on the F405: one receiver).
pub const RC_RECEIVER: RcProtocol = RcProtocol::Crsf;

/// The UART configuration of an RC protocol's line (8 data bits; with parity a 9-bit word;
/// an inverted line is inverted by the USART itself).
pub fn rc_uart_config(protocol: RcProtocol) -> usart::Config {
    let line = protocol.line();
    let mut cfg = usart::Config::default();
    cfg.baudrate = line.baud;
    cfg.data_bits = usart::DataBits::DataBits8;
    cfg.parity = if line.even_parity { usart::Parity::ParityEven } else { usart::Parity::ParityNone };
    cfg.stop_bits = if line.two_stop_bits { usart::StopBits::STOP2 } else { usart::StopBits::STOP1 };
    cfg.invert_rx = line.inverted;
    cfg
}

/// Errors of the board bring-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum BoardError {
    /// A UART configuration (companion or RC receiver) was refused.
    Uart,
}

/// Clocks, pins and drivers. `rx_ring` is the DMA ring buffer of the companion receiver,
/// `rc_ring` that of the RC receiver.
pub fn init(
    rx_ring: &'static mut [u8; COMPANION_RX_RING],
    rc_ring: &'static mut [u8; RC_RX_RING],
) -> Result<Board, BoardError> {
    let p = embassy_stm32::init(clock_config());

    let bus =
        Spi::new(p.SPI1, p.PA5, p.PD7, p.PA6, p.DMA1_CH0, p.DMA1_CH1, Irqs, imu_spi_config(IMU_SPI_SLOW_HZ));
    let cs = Output::new(p.PC15, Level::High, Speed::VeryHigh);
    let imu = ImuParts { bus, cs };
    let imu_ready = ExtiInput::new(p.PB2, p.EXTI2, Pull::None, Irqs);

    let pwm12 = SimplePwm::new(
        p.TIM3,
        None,
        None,
        Some(PwmPin::new(p.PB0, OutputType::PushPull)),
        Some(PwmPin::new(p.PB1, OutputType::PushPull)),
        Hertz(dshot::BITRATE_HZ),
        CountingMode::EdgeAlignedUp,
    );
    let pwm34 = SimplePwm::new(
        p.TIM5,
        Some(PwmPin::new(p.PA0, OutputType::PushPull)),
        Some(PwmPin::new(p.PA1, OutputType::PushPull)),
        None,
        None,
        Hertz(dshot::BITRATE_HZ),
        CountingMode::EdgeAlignedUp,
    );
    let period12 = u16::try_from(pwm12.max_duty_cycle()).unwrap_or(u16::MAX);
    let period34 = u16::try_from(pwm34.max_duty_cycle()).unwrap_or(u16::MAX);
    let motors = DshotMotors {
        pwm12,
        pwm34,
        dma12: p.DMA1_CH2,
        dma34: p.DMA1_CH3,
        period12,
        period34,
        buf12: [0; PAIR_BURST_LEN],
        buf34: [0; PAIR_BURST_LEN],
    };

    let mut uart_cfg = usart::Config::default();
    uart_cfg.baudrate = COMPANION_BAUD;
    let uart = Uart::new(p.USART1, p.PA10, p.PA9, p.DMA1_CH4, p.DMA1_CH5, Irqs, uart_cfg)
        .map_err(|_| BoardError::Uart)?;
    let (link_tx, rx) = uart.split();
    let link_rx = rx.into_ring_buffered(rx_ring);

    let cfg = rc_uart_config(RC_RECEIVER);
    let rc_uart = match RC_RECEIVER {
        RcProtocol::Crsf => UartRx::new(p.USART2, p.PD6, p.DMA1_CH6, Irqs, cfg),
        RcProtocol::Sbus => UartRx::new(p.USART6, p.PC7, p.DMA1_CH7, Irqs, cfg),
    };
    let rc_rx = rc_uart.map_err(|_| BoardError::Uart)?.into_ring_buffered(rc_ring);

    let flash = Flash::new(p.FLASH, Irqs);
    let adc = Adc::new_with_config(
        p.ADC1,
        AdcConfig { resolution: Some(Resolution::BITS12), ..Default::default() },
    );
    let battery = BatteryAdc { adc, vbat: p.PC0.degrade_adc(), current: p.PC1.degrade_adc() };

    Ok(Board { imu, imu_ready, motors, link_tx, link_rx, rc_rx, flash, battery, log_card: LogCard })
}
