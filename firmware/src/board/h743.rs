//! Board layer: MATEKH743 (STM32H743VIT6, 8 MHz HSE, MPU-6000 on SPI1) — the second board,
//! a [`FlightBoard`] like [`crate::board::f405`], so its binary (`src/bin/parapet-firmware-h743.rs`,
//! built with `--no-default-features --features board-h743`) runs the same tasks (`src/bin/fc/`)
//! on it. Pins from Matek's H743 wiring as Betaflight's/INAV's `MATEKH743`
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
//! | RC receiver CRSF, 420 000 Bd 8N1 — `RC_RECEIVER` (of `impl FlightBoard for MatekH743`) `Crsf` (default) | USART2 | RX PD6 (pad R2; receiver TX → R2) | RX DMA1 stream 6 (ring buffer) |
//! | RC receiver SBUS, 100 000 Bd 8E2, inverted — `RC_RECEIVER` (of `impl FlightBoard for MatekH743`) `Sbus` | USART6 | RX PC7 (pad R6); inverted by the H7's USART (RXINV), no inverter on the board | RX DMA1 stream 7 (ring buffer) |
//! | battery voltage (VBAT divider, `BAT_V_DIV` 11: Betaflight `vbat_scale` 110) | ADC1 INP10, 12-bit | PC0 | – (blocking reads, [`BatteryAdc`]) |
//! | battery current (pad CURR, `BAT_A_PER_V`; Betaflight `ibata_scale` 250 = 40 A/V) | ADC1 INP11 | PC1 | – |
//! | parameter store | FLASH bank 2, sectors 6-7 (0x081C_0000..0x0820_0000, `FlightBoard::PARAM_RANGE`; kept out of `FLASH` by `memory-h743.x`) | – | – (FLASH interrupt) |
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

use embassy_stm32::adc::{Adc, AdcChannel, AdcConfig, AnyAdcChannel, Resolution, SampleTime};
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::flash::Flash;
use embassy_stm32::gpio::Pull;
use embassy_stm32::peripherals;
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::simple_pwm::SimplePwm;
use embassy_stm32::timer::Channel;
use embassy_stm32::{Config, Peri};

#[cfg(feature = "onboard-log")]
use super::stm32::LogCardDevice;
use super::stm32::{
    chip_select, companion_link, dshot_timer, imu_bus, motor_pin, rc_receiver, rc_uart_config, stm32_irqs,
    BatteryInput, BoardError, ChipParts, FlightBoard, ImuParts, MotorOutput, Peripherals, Rings,
};
use crate::app::autopilot::MotorCommand;
use crate::drivers::dshot;
use crate::drivers::mpu6000::AxisMap;
use crate::drivers::rc_uart::RcProtocol;
#[cfg(feature = "onboard-log")]
use crate::log::card::{BlockDevice, BLOCK};
#[cfg(feature = "onboard-log")]
use crate::log::ulog::LogError;
use parapet_core::battery::AdcReading;

/// IMU mounting: Betaflight `CW0_DEG_FLIP` (chip upside down) on a chip whose default frame is
/// x forward, y left, z up: FRD = (−x, −y, z).
pub const IMU_AXES: AxisMap = AxisMap { axis: [0, 1, 2], sign: [-1, -1, 1] };

/// Compare slots of a two-channel DShot burst.
const PAIR_BURST_LEN: usize = dshot::SLOTS * 2;

stm32_irqs!(
    uarts: [USART1, USART2, USART6],
    dma: [DMA1_STREAM0 => DMA1_CH0, DMA1_STREAM1 => DMA1_CH1, DMA1_STREAM2 => DMA1_CH2, DMA1_STREAM3 => DMA1_CH3,
        DMA1_STREAM4 => DMA1_CH4, DMA1_STREAM5 => DMA1_CH5, DMA1_STREAM6 => DMA1_CH6, DMA1_STREAM7 => DMA1_CH7],
    exti: EXTI2
);

/// The battery inputs (see the pin table), 12-bit conversions; the analog supply is taken as the
/// nominal 3.3 V (the H7's VREFINT calibration is a 16-bit value: not used here).
pub struct BatteryAdc {
    adc: Adc<'static, peripherals::ADC1>,
    vbat: AnyAdcChannel<'static, peripherals::ADC1>,
    current: AnyAdcChannel<'static, peripherals::ADC1>,
}

impl BatteryInput for BatteryAdc {
    /// One blocking conversion of each input (2 × 810.5 ADC cycles), in the calling
    /// (lowest-priority) task.
    fn read(&mut self) -> AdcReading {
        let vbat = self.adc.blocking_read(&mut self.vbat, SampleTime::CYCLES810_5);
        let current = self.adc.blocking_read(&mut self.current, SampleTime::CYCLES810_5);
        AdcReading { vbat, current: Some(current), vrefint: None }
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

impl MotorOutput for DshotMotors {
    /// Sends one frame per motor (≈ 30 µs). Disarmed → DShot 0 (motor stop).
    async fn write(&mut self, cmd: &MotorCommand) {
        let cmd = cmd.sanitized();
        let frames = dshot::frames(cmd.throttle, cmd.armed);
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

/// The log card of this board: **not implemented** (the microSD is on SDMMC1; no SDMMC driver is
/// wired yet). Every access fails, so the log store stays off: the link task says so once in a
/// STATUSTEXT and nothing is logged (docs/bring-up.md §9).
#[cfg(feature = "onboard-log")]
pub struct LogCard;

#[cfg(feature = "onboard-log")]
impl LogCardDevice for LogCard {
    /// No bus clock to change.
    fn go_fast(&mut self) {}
}

#[cfg(feature = "onboard-log")]
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

/// The MATEKH743 board (the pin table above): the [`FlightBoard`] of `parapet-firmware-h743`.
pub struct MatekH743;

impl FlightBoard for MatekH743 {
    const NAME: &'static str = "matekh743";
    /// Core clock, Hz (DWT cycle counter rate).
    const SYSCLK_HZ: u32 = 400_000_000;
    /// SPI clock asked for sensor reads (datasheet: ≤ 20 MHz); the driver takes the highest
    /// power-of-two division of the 100 MHz kernel clock at or below it: 6.25 MHz.
    const IMU_SPI_FAST_HZ: u32 = 10_000_000;
    /// The RC receiver's protocol on this board (as on the F405: one receiver).
    const RC_RECEIVER: RcProtocol = RcProtocol::Crsf;
    /// The parameter store's range (offsets from 0x0800_0000): the last two 128 KiB sectors of
    /// bank 2.
    const PARAM_RANGE: core::ops::Range<u32> = 0x001C_0000..0x0020_0000;
    type Motors = DshotMotors;
    type Battery = BatteryAdc;
    #[cfg(feature = "onboard-log")]
    type LogCard = LogCard;

    /// Clock tree of the board (see the module docs).
    fn clock_config() -> Config {
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

    fn bring_up(p: embassy_stm32::Peripherals, rings: Rings) -> Result<Peripherals<Self>, BoardError> {
        let (pwm12, period12) = dshot_timer(p.TIM3, None, None, motor_pin(p.PB0), motor_pin(p.PB1));
        let (pwm34, period34) = dshot_timer(p.TIM5, motor_pin(p.PA0), motor_pin(p.PA1), None, None);
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

        let bus = imu_bus(p.SPI1, p.PA5, p.PD7, p.PA6, p.DMA1_CH0, p.DMA1_CH1, Irqs);
        let imu = ImuParts { bus, cs: chip_select(p.PC15), axes: IMU_AXES };
        let imu_ready = ExtiInput::new(p.PB2, p.EXTI2, Pull::None, Irqs);
        let link = companion_link(p.USART1, p.PA10, p.PA9, p.DMA1_CH4, p.DMA1_CH5, Irqs, rings.link)?;
        let mut cfg = rc_uart_config(Self::RC_RECEIVER);
        // No inverter on the board: an inverted line (SBUS) is inverted by the H7's USART.
        cfg.invert_rx = Self::RC_RECEIVER.line().inverted;
        let rc_rx = match Self::RC_RECEIVER {
            RcProtocol::Crsf => rc_receiver(p.USART2, p.PD6, p.DMA1_CH6, Irqs, cfg, rings.rc),
            RcProtocol::Sbus => rc_receiver(p.USART6, p.PC7, p.DMA1_CH7, Irqs, cfg, rings.rc),
        }?;
        let chip = ChipParts { imu, imu_ready, link, rc_rx, flash: Flash::new(p.FLASH, Irqs) };

        let adc = Adc::new_with_config(
            p.ADC1,
            AdcConfig { resolution: Some(Resolution::BITS12), ..Default::default() },
        );
        let battery = BatteryAdc { adc, vbat: p.PC0.degrade_adc(), current: p.PC1.degrade_adc() };

        Ok(Peripherals::new(
            chip,
            (motors, battery),
            #[cfg(feature = "onboard-log")]
            LogCard,
        ))
    }

    /// Panic / fault path: stops the motor outputs at register level (DMA requests off, compare
    /// values 0 → lines low; DShot ESCs stop on signal loss).
    fn force_motors_off() {
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
}
