//! Board layer: MATEKF405 (STM32F405RGT6, 8 MHz HSE, MPU-6000 on SPI1) and pin-compatible
//! F405 flight controllers. The whole pin map and clock tree of the board is in this file; another
//! F405/F7/H7 board is one new file next to it.
//!
//! | function | peripheral | pins | DMA |
//! |---|---|---|---|
//! | IMU MPU-6000 | SPI1, mode 3, 1 MHz (init) / 10.5 MHz (reads) | SCK PA5, MISO PA6, MOSI PA7, CS PC2 | TX DMA2 stream 3, RX DMA2 stream 0 |
//! | IMU data ready | EXTI3 | PC3 (rising edge) | – |
//! | motors M1..M4, DShot600 | TIM8 CH1..CH4 (AF3) | PC6, PC7, PC8, PC9 | TIM8_UP burst, DMA2 stream 1 |
//! | companion link, MAVLink 921 600 Bd | USART3 | TX PC10, RX PC11 | TX DMA1 stream 3, RX DMA1 stream 1 (ring buffer) |
//! | RC receiver CRSF (ExpressLRS / Crossfire), 420 000 Bd 8N1 — `RC_RECEIVER` (of `impl FlightBoard for MatekF405`) `Crsf` (default) | USART1 | RX PA10 (pad R1; receiver TX → R1; TX PA9 unused) | RX DMA2 stream 2 (ring buffer) |
//! | RC receiver SBUS, 100 000 Bd 8E2, inverted — `RC_RECEIVER` (of `impl FlightBoard for MatekF405`) `Sbus` | USART2 | RX PA3 (the board's SBUS pad: hardware inverter in front of R2) | RX DMA1 stream 5 (ring buffer) |
//! | battery voltage (VBAT divider 10 kΩ / 1 kΩ, `BAT_V_DIV` 11) | ADC1 IN15 | PC5 | – (blocking reads, [`BatteryAdc`]) |
//! | battery current (pad CURR, external sensor, `BAT_A_PER_V`) | ADC1 IN14 | PC4 | – |
//! | log card, microSD (raw blocks: `log::card`) | SPI3, mode 0, 400 kHz (init) / 21 MHz | SCK PB3, MISO PB4, MOSI PB5, CS PC1 (Betaflight `MATEKF405` `SDCARD_SPI_CS_PIN`) | – (blocking, in the link task) |
//! | parameter store | FLASH, sectors 10-11 (`storage::F405_RANGE`) | – | – (FLASH interrupt) |
//! | embassy time driver | TIM2 | – | – |
//! | software interrupts for the executors | UART4 (high), UART5 (medium), I2C1_EV (RC + battery) | unused UARTs, unused I2C1 | – |
//!
//! Clocks: HSE 8 MHz → PLL (M 4, N 168, P 2, Q 7) → SYSCLK 168 MHz, AHB 168 MHz, APB1 42 MHz
//! (timers 84 MHz), APB2 84 MHz (timers 168 MHz), USB/SDIO 48 MHz.
//!
//! Motor order M1..M4 must match `parapet_core::airframe` (rotor 0..3): wire the ESCs (or remap
//! `MOTOR_PINS` below) accordingly; the IMU axis map [`IMU_AXES`] is the board's `CW180`
//! mounting (Betaflight `GYRO_1_ALIGN CW180_DEG`); check both on the bench before flight.

use embassy_stm32::adc::{Adc, AdcChannel, AnyAdcChannel, SampleTime, VrefInt};
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::flash::Flash;
use embassy_stm32::gpio::{Output, Pull};
use embassy_stm32::peripherals;
use embassy_stm32::spi::{self, Spi};
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

/// IMU mounting: Betaflight `CW180_DEG` on a chip whose default frame is x forward, y left, z up.
pub const IMU_AXES: AxisMap = AxisMap { axis: [0, 1, 2], sign: [-1, 1, -1] };

stm32_irqs!(
    uarts: [USART3, USART1, USART2],
    dma: [DMA2_STREAM2 => DMA2_CH2, DMA1_STREAM5 => DMA1_CH5, DMA2_STREAM0 => DMA2_CH0, DMA2_STREAM1 => DMA2_CH1,
        DMA2_STREAM3 => DMA2_CH3, DMA1_STREAM1 => DMA1_CH1, DMA1_STREAM3 => DMA1_CH3],
    exti: EXTI3
);

/// Four DShot600 outputs on TIM8 CH1..CH4, updated together by one DMA burst per frame.
pub struct DshotMotors {
    pwm: SimplePwm<'static, peripherals::TIM8>,
    dma: Peri<'static, peripherals::DMA2_CH1>,
    period: u16,
    buf: [u16; dshot::BURST_LEN],
}

impl MotorOutput for DshotMotors {
    /// Sends one frame per motor (≈ 30 µs). Disarmed → DShot 0 (motor stop).
    async fn write(&mut self, cmd: &MotorCommand) {
        let cmd = cmd.sanitized();
        let frames = dshot::frames(cmd.throttle, cmd.armed);
        dshot::fill_burst(frames, self.period, &mut self.buf);
        self.pwm
            .waveform_up_multi_channel(self.dma.reborrow(), Irqs, Channel::Ch1, Channel::Ch4, &self.buf)
            .await;
    }
}

/// The battery inputs (see the pin table): VBAT, current, and the internal reference for the
/// actual analog supply. Read by the battery task (lowest priority).
pub struct BatteryAdc {
    adc: Adc<'static, peripherals::ADC1>,
    vbat: AnyAdcChannel<'static, peripherals::ADC1>,
    current: AnyAdcChannel<'static, peripherals::ADC1>,
    vrefint: VrefInt,
}

/// Address of the STM32F405's factory VREFINT calibration word (DS8626: measured at VDDA 3.3 V).
const VREFINT_CAL_ADDR: usize = 0x1FFF_7A2A;

impl BatteryInput for BatteryAdc {
    /// One blocking conversion of each input: 3 × (480 + 12) ADC cycles at 21 MHz ≈ 70 µs,
    /// busy-waiting in the calling (lowest-priority) task; the control tasks preempt it.
    fn read(&mut self) -> AdcReading {
        let vbat = self.adc.blocking_read(&mut self.vbat, SampleTime::CYCLES480);
        let current = self.adc.blocking_read(&mut self.current, SampleTime::CYCLES480);
        let vref = self.adc.blocking_read(&mut self.vrefint, SampleTime::CYCLES480);
        // SAFETY: a read-only, always-mapped system-memory word of this chip.
        let cal = unsafe { core::ptr::read_volatile(VREFINT_CAL_ADDR as *const u16) };
        AdcReading { vbat, current: Some(current), vrefint: Some((vref, cal)) }
    }
}

/// SPI clock while the SD card is initialised (SD spec: 100-400 kHz).
pub const SD_SPI_SLOW_HZ: u32 = 400_000;
/// SPI clock after the card answered (SD spec: ≤ 25 MHz; APB1 42 MHz / 2).
pub const SD_SPI_FAST_HZ: u32 = 21_000_000;

/// The SD card's SPI configuration at `hz` (mode 0).
#[cfg(feature = "onboard-log")]
pub fn sd_spi_config(hz: u32) -> spi::Config {
    let mut cfg = spi::Config::default();
    cfg.mode = spi::MODE_0;
    cfg.frequency = Hertz(hz);
    cfg
}

#[cfg(feature = "onboard-log")]
type SdDevice = embedded_hal_bus::spi::ExclusiveDevice<
    Spi<'static, embassy_stm32::mode::Blocking, spi::mode::Master>,
    Output<'static>,
    embassy_time::Delay,
>;

/// The log card: `embedded-sdmmc`'s SPI SD driver on SPI3 as the log store's [`BlockDevice`].
/// Every call blocks (the card's busy time included): the link task only.
#[cfg(feature = "onboard-log")]
pub struct LogCard(embedded_sdmmc::SdCard<SdDevice, embassy_time::Delay>);

#[cfg(feature = "onboard-log")]
impl LogCardDevice for LogCard {
    /// The SPI clock after the card answered ([`SD_SPI_FAST_HZ`]).
    fn go_fast(&mut self) {
        let _ = self.0.spi(|d| d.bus_mut().set_config(&sd_spi_config(SD_SPI_FAST_HZ)));
    }
}

#[cfg(feature = "onboard-log")]
impl BlockDevice for LogCard {
    fn read(&mut self, lba: u32, buf: &mut [u8; BLOCK]) -> Result<(), LogError> {
        let mut b = [embedded_sdmmc::Block::new()];
        embedded_sdmmc::BlockDevice::read(&self.0, &mut b, embedded_sdmmc::BlockIdx(lba))
            .map_err(|_| LogError::Device)?;
        *buf = b[0].contents;
        Ok(())
    }
    fn write(&mut self, lba: u32, buf: &[u8; BLOCK]) -> Result<(), LogError> {
        let mut b = embedded_sdmmc::Block::new();
        b.contents = *buf;
        embedded_sdmmc::BlockDevice::write(&self.0, &[b], embedded_sdmmc::BlockIdx(lba))
            .map_err(|_| LogError::Device)
    }
    fn blocks(&mut self) -> Result<u32, LogError> {
        embedded_sdmmc::BlockDevice::num_blocks(&self.0).map(|c| c.0).map_err(|_| LogError::Device)
    }
}

/// The MATEKF405 board (the pin table above): the [`FlightBoard`] of `parapet-firmware`.
pub struct MatekF405;

impl FlightBoard for MatekF405 {
    const NAME: &'static str = "matekf405";
    /// Core clock, Hz (DWT cycle counter rate).
    const SYSCLK_HZ: u32 = 168_000_000;
    /// SPI clock for sensor reads (datasheet: ≤ 20 MHz; APB2 84 MHz / 8).
    const IMU_SPI_FAST_HZ: u32 = 10_500_000;
    /// The RC receiver of this build: one protocol on its UART (see the pin table). A build-time
    /// choice, like the pin map: only the chosen decoder and UART are linked (flash), and both
    /// arms are type-checked in every build. Change it here and rebuild for an SBUS receiver.
    /// (Inversion: in hardware, the SBUS pad's inverter; the F405's USART has no RXINV.)
    const RC_RECEIVER: RcProtocol = RcProtocol::Crsf;
    /// The parameter store's range in the internal flash (offsets from 0x0800_0000): sectors 10-11.
    const PARAM_RANGE: core::ops::Range<u32> = crate::storage::F405_RANGE;
    type Motors = DshotMotors;
    type Battery = BatteryAdc;
    #[cfg(feature = "onboard-log")]
    type LogCard = LogCard;

    /// Clock tree of the board (see the module docs).
    fn clock_config() -> Config {
        use embassy_stm32::rcc::{
            AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv, PllSource,
            Sysclk,
        };
        let mut config = Config::default();
        config.rcc.hse = Some(Hse { freq: Hertz(8_000_000), mode: HseMode::Oscillator });
        config.rcc.pll_src = PllSource::HSE;
        config.rcc.pll = Some(Pll {
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL168,
            divp: Some(PllPDiv::DIV2),
            divq: Some(PllQDiv::DIV7),
            divr: None,
        });
        config.rcc.ahb_pre = AHBPrescaler::DIV1;
        config.rcc.apb1_pre = APBPrescaler::DIV4;
        config.rcc.apb2_pre = APBPrescaler::DIV2;
        config.rcc.sys = Sysclk::PLL1_P;
        config
    }

    fn bring_up(p: embassy_stm32::Peripherals, rings: Rings) -> Result<Peripherals<Self>, BoardError> {
        let (pwm, period) =
            dshot_timer(p.TIM8, motor_pin(p.PC6), motor_pin(p.PC7), motor_pin(p.PC8), motor_pin(p.PC9));
        let motors = DshotMotors { pwm, dma: p.DMA2_CH1, period, buf: [0; dshot::BURST_LEN] };

        let bus = imu_bus(p.SPI1, p.PA5, p.PA7, p.PA6, p.DMA2_CH3, p.DMA2_CH0, Irqs);
        let imu = ImuParts { bus, cs: chip_select(p.PC2), axes: IMU_AXES };
        let imu_ready = ExtiInput::new(p.PC3, p.EXTI3, Pull::None, Irqs);
        let link = companion_link(p.USART3, p.PC11, p.PC10, p.DMA1_CH3, p.DMA1_CH1, Irqs, rings.link)?;
        let cfg = rc_uart_config(Self::RC_RECEIVER);
        let rc_rx = match Self::RC_RECEIVER {
            RcProtocol::Crsf => rc_receiver(p.USART1, p.PA10, p.DMA2_CH2, Irqs, cfg, rings.rc),
            RcProtocol::Sbus => rc_receiver(p.USART2, p.PA3, p.DMA1_CH5, Irqs, cfg, rings.rc),
        }?;
        let chip = ChipParts { imu, imu_ready, link, rc_rx, flash: Flash::new(p.FLASH, Irqs) };

        let adc = Adc::new(p.ADC1);
        let vrefint = adc.enable_vrefint();
        let battery = BatteryAdc { adc, vbat: p.PC5.degrade_adc(), current: p.PC4.degrade_adc(), vrefint };

        #[cfg(feature = "onboard-log")]
        let log_card = {
            // The SD card: 80 clocks with CS high before its first command (SD spec, SPI mode).
            let mut sd_bus = Spi::new_blocking(p.SPI3, p.PB3, p.PB5, p.PB4, sd_spi_config(SD_SPI_SLOW_HZ));
            let _ = sd_bus.blocking_write(&[0xFFu8; 10]);
            match embedded_hal_bus::spi::ExclusiveDevice::new(sd_bus, chip_select(p.PC1), embassy_time::Delay)
            {
                Ok(d) => LogCard(embedded_sdmmc::SdCard::new(d, embassy_time::Delay)),
                Err(e) => match e {},
            }
        };

        Ok(Peripherals::new(
            chip,
            (motors, battery),
            #[cfg(feature = "onboard-log")]
            log_card,
        ))
    }

    /// Panic / fault path: stops the motor outputs at register level, whatever the drivers were
    /// doing (TIM8 DMA requests off, compare values 0, main output disabled → lines low; DShot ESCs
    /// stop on signal loss).
    fn force_motors_off() {
        let tim = embassy_stm32::pac::TIM8;
        tim.dier().modify(|w| w.set_ude(false));
        for ch in 0..4 {
            tim.ccr(ch).write_value(embassy_stm32::pac::timer::regs::Ccr1ch(0));
        }
        tim.bdtr().modify(|w| w.set_moe(false));
    }
}
