//! Parapet flight-control firmware for STM32F405 flight controllers (board: `board::f405`).
//!
//! Tasks and priorities (embassy multi-priority pattern):
//! - **inner loop** (interrupt executor on UART4's vector, NVIC priority 6, the highest used):
//!   waits for the IMU's data-ready interrupt (1 kHz), reads the MPU-6000, runs
//!   `step_inner` (estimator, attitude, rate control, mixer) and sends the DShot600 frame;
//!   period and execution time from the DWT cycle counter, overruns counted.
//! - **outer loop** (interrupt executor on UART5's vector, priority 7): 250 Hz ticker,
//!   `step_outer` (waypoints, PD, CBF filter, thrust mapping), timed the same way.
//! - **link** (thread-mode executor, lowest priority): MAVLink over USART3 (DMA ring buffer),
//!   telemetry streams.
//!
//! The cascade lives in one critical-section mutex ([`parapet_firmware::app::shared`]); loop reports
//! are published through [`parapet_firmware::app::shared::SharedCell`]s. No `static mut`.
//! `cargo run -p parapet-firmware --release` flashes through probe-rs; logs are defmt over RTT.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[cfg(target_os = "none")]
mod firmware {
    use defmt_rtt as _;
    use embassy_executor::{Executor, InterruptExecutor};
    use embassy_futures::select::{select, Either};
    use embassy_stm32::interrupt;
    use embassy_stm32::interrupt::{InterruptExt, Priority};
    use embassy_stm32::usart::{RingBufferedUartRx, UartTx};
    use embassy_time::{Duration, Instant, Ticker, Timer};
    use parapet_core::controller::ControllerParams;
    use parapet_core::Vec3;
    use parapet_firmware::app::autopilot::{Autopilot, ImuSample, MotorCommand};
    use parapet_firmware::app::cascade::Cascade;
    use parapet_firmware::app::loop_timing::{LoopReport, LoopTimer};
    use parapet_firmware::app::shared::{SharedAutopilot, SharedCell};
    use parapet_firmware::board::f405::{
        self, DshotMotors, ImuSpi, COMPANION_RX_RING, IMU_SPI_FAST_HZ, SYSCLK_HZ,
    };
    use parapet_firmware::drivers::mpu6000::{ImuError, Mpu6000};
    use parapet_firmware::link::framing::{FrameWriter, AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};
    use parapet_firmware::link::outbound::Outbound;
    use parapet_firmware::link::telemetry::{ErrorCounters, TelemetryInputs, TelemetryScheduler};
    use parapet_firmware::link::{FixClock, Link};
    use static_cell::StaticCell;

    /// Inner-loop period, µs (1 kHz, paced by the IMU's data-ready line).
    const INNER_PERIOD_US: u32 = 1000;
    /// Outer-loop rate, Hz.
    const OUTER_RATE_HZ: u64 = 250;
    /// Missing data-ready edges tolerated before the sample is read anyway, µs.
    const IMU_TIMEOUT_US: u64 = 2000;
    /// Loop reports are published (and a new window started) after this many steps.
    const REPORT_EVERY_INNER: u32 = 500;
    const REPORT_EVERY_OUTER: u32 = 125;

    static CASCADE: SharedAutopilot<Cascade> = SharedAutopilot::new();
    static INNER_REPORT: SharedCell<LoopReport> = SharedCell::new(LoopReport::ZERO);
    static OUTER_REPORT: SharedCell<LoopReport> = SharedCell::new(LoopReport::ZERO);
    static IMU_ERRORS: SharedCell<u32> = SharedCell::new(0);
    static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();
    static EXECUTOR_MED: InterruptExecutor = InterruptExecutor::new();
    static EXECUTOR_LOW: StaticCell<Executor> = StaticCell::new();
    static RX_RING: StaticCell<[u8; COMPANION_RX_RING]> = StaticCell::new();

    #[interrupt]
    unsafe fn UART4() {
        // SAFETY: UART4's vector is reserved for this executor (the UART itself is unused).
        unsafe { EXECUTOR_HIGH.on_interrupt() }
    }

    #[interrupt]
    unsafe fn UART5() {
        // SAFETY: as above, for the medium-priority executor.
        unsafe { EXECUTOR_MED.on_interrupt() }
    }

    fn cycles() -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }

    fn now_us() -> u64 {
        Instant::now().as_micros()
    }

    fn halt(reason: &str) -> ! {
        f405::force_motors_off();
        defmt::error!("halted: {}", reason);
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let Some(mut cp) = cortex_m::Peripherals::take() else { halt("core peripherals") };
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
        let board = match f405::init(RX_RING.init([0; COMPANION_RX_RING])) {
            Ok(b) => b,
            Err(e) => {
                defmt::error!("board init: {}", e);
                halt("board init")
            }
        };
        match Cascade::new(ControllerParams::default()) {
            Ok(c) => CASCADE.install(c),
            Err(_) => halt("controller parameters rejected"),
        }
        defmt::info!("parapet-firmware: board up, cascade installed");

        interrupt::UART4.set_priority(Priority::P6);
        let high = EXECUTOR_HIGH.start(interrupt::UART4);
        match inner_loop(board.imu, board.imu_ready, board.motors) {
            Ok(t) => high.spawn(t),
            Err(_) => halt("spawn inner loop"),
        }
        interrupt::UART5.set_priority(Priority::P7);
        let med = EXECUTOR_MED.start(interrupt::UART5);
        match outer_loop() {
            Ok(t) => med.spawn(t),
            Err(_) => halt("spawn outer loop"),
        }
        let low = EXECUTOR_LOW.init(Executor::new());
        low.run(|spawner| match link_task(board.link_tx, board.link_rx) {
            Ok(t) => spawner.spawn(t),
            Err(_) => halt("spawn link"),
        })
    }

    /// Attitude/rate loop at the IMU's 1 kHz data-ready rate.
    #[embassy_executor::task]
    async fn inner_loop(
        mut imu: Mpu6000<ImuSpi>,
        mut ready: embassy_stm32::exti::ExtiInput<'static, embassy_stm32::mode::Async>,
        mut motors: DshotMotors,
    ) {
        let mut delay = embassy_time::Delay;
        let mut imu_ok = false;
        while !imu_ok {
            match imu.init(&mut delay).await {
                Ok(()) => imu_ok = true,
                Err(e) => {
                    match e {
                        ImuError::Bus => defmt::error!("IMU init failed: SPI error"),
                        ImuError::WrongDevice(id) => {
                            defmt::error!("IMU init failed: WHO_AM_I = {=u8:#x}", id)
                        }
                    }
                    motors.write(&MotorCommand::OFF).await;
                    Timer::after_millis(500).await;
                }
            }
        }
        imu.bus_mut().set_frequency(IMU_SPI_FAST_HZ);
        let mut timer = LoopTimer::new(INNER_PERIOD_US, SYSCLK_HZ / 1_000_000);
        let mut ap = CASCADE.handle();
        let mut imu_errors: u32 = 0;
        loop {
            // Paced by data-ready; a missing edge (IMU stalled) still runs the step, so the
            // cascade sees the stale/failed sample and the motors keep being refreshed.
            let _ = select(ready.wait_for_rising_edge(), Timer::after_micros(IMU_TIMEOUT_US)).await;
            timer.start(cycles());
            let sample = match imu.read().await {
                Ok(s) => s,
                Err(_) => {
                    imu_errors = imu_errors.saturating_add(1);
                    IMU_ERRORS.set(imu_errors);
                    // A non-finite sample makes the cascade take its bad-input failsafe.
                    ImuSample { gyro_frd: Vec3::repeat(f32::NAN), accel_frd: Vec3::repeat(f32::NAN) }
                }
            };
            let cmd = ap.step_inner(now_us(), &sample);
            motors.write(&cmd).await;
            timer.end(cycles());
            if timer.report().steps >= REPORT_EVERY_INNER {
                INNER_REPORT.set(timer.take_report());
            }
        }
    }

    /// Position + CBF loop at 250 Hz.
    #[embassy_executor::task]
    async fn outer_loop() {
        let mut ticker = Ticker::every(Duration::from_hz(OUTER_RATE_HZ));
        let mut timer = LoopTimer::new((1_000_000 / OUTER_RATE_HZ) as u32, SYSCLK_HZ / 1_000_000);
        let mut ap = CASCADE.handle();
        loop {
            ticker.next().await;
            timer.start(cycles());
            ap.step_outer(now_us());
            timer.end(cycles());
            if timer.report().steps >= REPORT_EVERY_OUTER {
                OUTER_REPORT.set(timer.take_report());
            }
        }
    }

    /// MAVLink over the companion UART: inbound messages, replies and telemetry.
    #[embassy_executor::task]
    async fn link_task(
        mut tx: UartTx<'static, embassy_stm32::mode::Async>,
        mut rx: RingBufferedUartRx<'static>,
    ) {
        let mut link = Link::new(VEHICLE_SYSTEM_ID, FixClock::Arrival);
        let mut writer = FrameWriter::new(VEHICLE_SYSTEM_ID, AUTOPILOT_COMPONENT_ID);
        let mut telemetry = TelemetryScheduler::new();
        let mut ap = CASCADE.handle();
        let mut buf = [0u8; 64];
        let mut uart_errors: u32 = 0;
        loop {
            match select(rx.read(&mut buf), Timer::after_millis(5)).await {
                Either::First(Ok(n)) => link.push_bytes(&buf[..n.min(buf.len())], now_us(), &mut ap),
                Either::First(Err(_)) => uart_errors = uart_errors.saturating_add(1),
                Either::Second(()) => {}
            }
            let now = now_us();
            link.poll(now, &mut ap);
            while let Some(r) = link.pop_reply() {
                send(&mut tx, &mut writer, &r).await;
            }
            let inputs = TelemetryInputs {
                snapshot: ap.telemetry(),
                inner: INNER_REPORT.get(),
                outer: OUTER_REPORT.get(),
                parser: link.parser_stats(),
                counters: ErrorCounters {
                    imu_errors: IMU_ERRORS.get(),
                    uart_errors,
                    ..ErrorCounters::from_link(&link)
                },
            };
            let mut queued: heapless::Vec<Outbound, 20> = heapless::Vec::new();
            telemetry.poll(now, &inputs, |m| {
                // 20 > the at most 16 messages of one poll.
                let _ = queued.push(m);
            });
            for m in &queued {
                send(&mut tx, &mut writer, m).await;
            }
        }
    }

    async fn send(
        tx: &mut UartTx<'static, embassy_stm32::mode::Async>,
        writer: &mut FrameWriter,
        m: &Outbound,
    ) {
        let raw = m.encode(writer);
        // A failed write (DMA error) drops this frame; the streams resend.
        let _ = tx.write(raw.raw_bytes()).await;
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        cortex_m::interrupt::disable();
        f405::force_motors_off();
        // Location only: formatting the message would link core::fmt's float formatting (≈ 9 KiB).
        match info.location() {
            Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
            None => defmt::error!("panic"),
        }
        loop {
            cortex_m::asm::wfi();
        }
    }
}

/// On the host, `cargo run -p parapet-firmware --release` lands here: re-run cargo for the
/// Cortex-M target, whose runner (`.cargo/config.toml`) flashes the board through probe-rs.
#[cfg(not(target_os = "none"))]
fn main() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!("parapet-firmware: building for thumbv7em-none-eabihf and flashing through probe-rs");
    let status = std::process::Command::new(cargo)
        .args(["run", "-p", "parapet-firmware", "--release", "--target", "thumbv7em-none-eabihf", "--bin"])
        .arg("parapet-firmware")
        .args(std::env::args().skip(1))
        .status();
    match status {
        Ok(s) => std::process::exit(s.code().unwrap_or(1)),
        Err(e) => {
            eprintln!("parapet-firmware: cannot run cargo: {e}");
            std::process::exit(1);
        }
    }
}
