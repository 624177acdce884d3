//! The flight binary's tasks, the same on every STM32 flight-controller board: each binary under
//! `src/bin/` (`parapet-firmware.rs`: MATEKF405; `parapet-firmware-h743.rs`: MATEKH743) names its
//! board once (`type Board = …`, a [`FlightBoard`]) and includes this module, which reaches the
//! board only through that trait (`board::stm32`).
//!
//! Tasks and priorities (embassy multi-priority pattern); each owns its state, and they
//! exchange small `Copy` messages through embassy-sync primitives (no shared controller, no
//! global lock; a critical section only ever copies one message):
//! - **inner loop** (interrupt executor on UART4's vector, NVIC priority 6, the highest used):
//!   owns the inner stage (`InnerLoop`: estimator, attitude, rate control, mixer) and the IMU's
//!   SPI device; waits for the IMU's data-ready interrupt (1 kHz), reads the MPU-6000, takes the
//!   queued attitude commands / estimator aid / a rebuilt parameter set from the mailboxes,
//!   steps, publishes its state estimate, sends the DShot600 frame.
//! - **outer loop** (interrupt executor on UART5's vector, priority 7): owns the outer stage
//!   (`OuterLoop`: guidance, PD, CBF filter, thrust map, supervisor, parameter store) and the
//!   MAVLink dispatcher (`Link`: commands, mission, obstacle batches, parameters); wakes on the
//!   outer-rate ticker (`OuterSchedule`), on a decoded message from the link task, or on a new
//!   state estimate; publishes attitude commands and the telemetry snapshot.
//! - **link, RC receiver, battery** (one interrupt executor on I2C1's event vector, NVIC
//!   priority 8: below the control loops, above thread mode, so no card or flash driver call in
//!   thread mode delays them). The link task: USART3 (DMA ring buffer), MAVLink framing and
//!   decoding; decoded messages go to the outer task through a `Channel` (position fixes and
//!   obstacles included: their 0.2 s staleness failsafe must not see card stalls), replies come
//!   back through another; builds the telemetry streams from the published snapshot; LOG_*
//!   requests go to the log task and its replies come back (both `Channel`s). The RC receiver:
//!   the pilot's frames (kill switch). The battery: the battery failsafe's input.
//! - **onboard log** (thread-mode executor, the lowest priority, with the storage task only):
//!   the outer task hands a `LogSample` every `DEFAULT_PERIOD_US` (25 Hz) to `LOG_QUEUE`
//!   (`try_send`: dropped and counted when full, never waits); the log task turns them into ULog
//!   records (`FlightLogger`) on the log card (`log::card::CardStore` on
//!   the board's `LogCard`: the F405's microSD on SPI3; none on the H743 yet) and serves the
//!   MAVLink log download (`LogTransfer`). Card writes block (≈ 0.3 ms per 512-byte block at
//!   21 MHz plus the card's busy time, up to ≈ 250 ms) thread mode only: the log and the
//!   parameter storage. Bounded work per pass: ≤ `LOG_QUEUE_LEN` record sets (≤ 1 card block
//!   each plus a directory write every 16 blocks), the queued requests and ≤ `REPLIES_PER_POLL`
//!   LOG_* replies. The card is mounted when the log task starts (up to ≈ 1 s without a card);
//!   a formatted card or a card fault is said once in a STATUSTEXT, and logging stays off after
//!   a fault. Without the `onboard-log` feature there is no log task.
//! - **storage** (thread-mode executor, with the log task): the parameter store in the board's flash
//!   (`vehicle::tasks::storage_job`: saves, PREFLIGHT_STORAGE read/reset); flash erases and
//!   writes run here only, never in a control task, and only while disarmed (the outer task
//!   sends no job while armed). On the F405 (one flash bank) a flash write or erase still stalls
//!   every instruction fetch from flash, interrupts included (a word ≈ 16 µs, a 128 KiB sector
//!   erase 1-2 s): disarmed only, by design.
//! - **battery** (the link's executor above): [`BATTERY_PERIOD_MS`] ADC reads of VBAT, current and
//!   VREFINT → `BatteryParams::convert` → `BatteryEstimator` → the stages' `battery` mailbox (the outer
//!   stage's low/critical battery failsafes).
//! - **replanner** (thread-mode executor, with the log and storage tasks; issue 38): the on-board
//!   replanner (`app::replanner`), its planner (≈ 29 KiB) in the CPU-only RAM (`board::ccm`).
//!   The outer task hands it a request (state, remaining mission, obstacle points) at
//!   `RPL_RATE` by reference; the plan runs with interrupts enabled, preempted by every
//!   other task (it shares thread mode: a card write delays it, it delays the log writer), and
//!   the outer task flies the new path from its next step.
//!
//! The setup services (calibration, motor test, storage requests, IMU correction) are split over
//! the inner and outer tasks (`parapet_firmware::vehicle::tasks`). At boot the stored parameters
//! are loaded (blocking flash reads) before the cascade is built.
//!
//! Loop reports are `Signal`s, error counters atomics. No `static mut`.
//! `cargo run -p parapet-firmware --release` flashes through probe-rs; logs are defmt over RTT.
//!
//! May import: `parapet_firmware` (app, board's `stm32` trait, link, log, storage, vehicle),
//! `parapet_core`, the HAL and embassy. A module of the binaries, not of the library.

mod board_log;

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

#[cfg(feature = "onboard-log")]
use board_log::BoardLog;

use crate::Board;
use defmt_rtt as _;
use embassy_executor::{Executor, InterruptExecutor};
use embassy_futures::select::{select, select3, Either, Either3};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::usart::{RingBufferedUartRx, UartTx};
use embassy_sync::blocking_mutex::raw::{CriticalSectionRawMutex, NoopRawMutex};
use embassy_sync::channel::Channel;
use embassy_sync::mutex::Mutex;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant, Ticker, Timer};
use parapet_core::battery::{BatteryEstimator, BatteryParams};
use parapet_core::controller::ControllerParams;
use parapet_core::rc::map::{CrsfReceiver, RcFrame, RcParams, SbusReceiver};
use parapet_core::replan::Replanner;
use parapet_core::schedule::OuterSchedule;
use parapet_core::Vec3;
use parapet_firmware::app::autopilot::{ImuSample, MotorCommand, TelemetrySnapshot};
use parapet_firmware::app::cascade::{InnerStage, OuterStage};
use parapet_firmware::app::loop_timing::{LoopReport, LoopTimer};
use parapet_firmware::app::mailbox::Mailboxes;
use parapet_firmware::app::replanner;
use parapet_firmware::board::ccm;
// The board of the binary (`crate::Board`), reached only through its `FlightBoard` trait.
use parapet_firmware::board::stm32::{
    imu_spi_config, BatteryInput, FlightBoard, ImuParts, MotorOutput, COMPANION_RX_RING,
};
use parapet_firmware::drivers::mpu6000::ImuError;
use parapet_firmware::drivers::rc_uart::{RcProtocol, RC_RX_RING};
use parapet_firmware::link::frame_parser::RawFrame;
use parapet_firmware::link::framing::{FrameWriter, AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};
use parapet_firmware::link::outbound::Outbound;
use parapet_firmware::link::telemetry::{ErrorCounters, TelemetryInputs, TelemetryScheduler};
use parapet_firmware::link::{FixClock, Framer, Link, Received};
use parapet_firmware::storage::{Loaded, ParamStore};
use parapet_firmware::vehicle::tasks::{storage_job, SetupInner, SetupMailboxes, SetupOuter};
use static_cell::StaticCell;

/// Inner-loop period, µs (1 kHz, paced by the IMU's data-ready line).
const INNER_PERIOD_US: u32 = parapet_core::wire::rates::INNER_PERIOD_US;
/// Missing data-ready edges tolerated before the sample is read anyway, µs.
const IMU_TIMEOUT_US: u64 = 2000;
/// Loop reports are published (and a new window started) after this many steps.
const REPORT_EVERY_INNER: u32 = 500;
const REPORT_EVERY_OUTER: u32 = 125;
/// Decoded messages in flight from the link task to the outer task.
const INBOUND_DEPTH: usize = 2;
/// Bytes of one telemetry poll's frames. The `telemetry::MAX_PER_POLL` breakdown with each group's
/// longest frames (MAVLink 2: header 10 + payload + CRC 2) needs at most 1,099 B: failsafe
/// STATUSTEXT 66 + NAMED_VALUE_INT 30, mode STATUSTEXT 66 + CURRENT_MODE 21, RC_CHANNELS 54,
/// heartbeat group 21 + 30 + 21 (CURRENT_MODE) + 13 (AVAILABLE_MODES_MONITOR) + 55 + 14, two
/// streams ≤ 2 × 63, filter and loop groups ≤ 4 × 42 each, link 3 × 42; with the replan
/// STATUSTEXT 66 and ESTIMATOR_STATUS 54 (issue 39) 1,099 B. A frame that does not fit is
/// dropped and counted as a UART error.
const TX_BATCH: usize = 1152;
/// Replies in flight from the outer task to the link task.
const REPLY_DEPTH: usize = 8;

/// Battery measurement period, ms (10 Hz; the estimator filters with τ 0.5 s and debounces
/// a level change for 2 s).
const BATTERY_PERIOD_MS: u64 = 100;

/// The stages' mailboxes (`parapet_firmware::app::mailbox`) and the setup services'
/// (`parapet_firmware::vehicle::tasks`); every task that uses them gets the reference.
struct Boxes {
    stages: Mailboxes<CriticalSectionRawMutex>,
    setup: SetupMailboxes<CriticalSectionRawMutex>,
}
/// Filled at boot: a `StaticCell` is zeroed `.bss`, while a `static` initialised with the
/// empty mailboxes was a 2,296-byte `.data` image in flash (their empty state holds 7
/// non-zero enum tags).
static BOXES: StaticCell<Boxes> = StaticCell::new();
/// The vehicle is armed (outer task → battery task: the estimator's level only goes down
/// while armed).
static ARMED: AtomicBool = AtomicBool::new(false);
/// Link task → outer task: decoded frames, in order.
static INBOUND: Channel<CriticalSectionRawMutex, (u64, Received), INBOUND_DEPTH> = Channel::new();
/// Outer task → link task: replies (acks, mission requests, parameter values).
static REPLIES: Channel<CriticalSectionRawMutex, Outbound, REPLY_DEPTH> = Channel::new();
/// Outer task → link task: the dispatcher's error counters.
static LINK_COUNTERS: Signal<CriticalSectionRawMutex, ErrorCounters> = Signal::new();
static INNER_REPORT: Signal<CriticalSectionRawMutex, LoopReport> = Signal::new();
static OUTER_REPORT: Signal<CriticalSectionRawMutex, LoopReport> = Signal::new();
static IMU_ERRORS: AtomicU32 = AtomicU32::new(0);
/// RC receiver UART errors (framing, noise, overrun).
static RC_UART_ERRORS: AtomicU32 = AtomicU32::new(0);
static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_MED: InterruptExecutor = InterruptExecutor::new();
/// Link, RC receiver and battery (position fixes, the pilot's kill switch, the battery
/// failsafe's input): above thread mode, where the log task's blocking card writes run.
static EXECUTOR_SERVICE: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_LOW: StaticCell<Executor> = StaticCell::new();
static RX_RING: StaticCell<[u8; COMPANION_RX_RING]> = StaticCell::new();
// The large task states live here, handed to their tasks by reference: an async task's
// arguments are stored in its future next to the locals they move into (twice the RAM).
static OUTER_STAGE: StaticCell<OuterStage> = StaticCell::new();
static SETUP_OUTER: StaticCell<SetupOuter> = StaticCell::new();
static STORE: StaticCell<Store> = StaticCell::new();
/// The parameter store on the board's flash.
type Store = ParamStore<embassy_stm32::flash::Flash<'static, embassy_stm32::flash::Async>>;
/// DMA ring buffer of the RC receiver UART.
static RC_RING: StaticCell<[u8; RC_RX_RING]> = StaticCell::new();

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

#[interrupt]
unsafe fn I2C1_EV() {
    // SAFETY: I2C1's event vector is reserved for this executor (I2C1 is unused on both
    // boards).
    unsafe { EXECUTOR_SERVICE.on_interrupt() }
}

fn cycles() -> u32 {
    cortex_m::peripheral::DWT::cycle_count()
}

fn now_us() -> u64 {
    Instant::now().as_micros()
}

fn halt(reason: &str) -> ! {
    Board::force_motors_off();
    defmt::error!("halted: {}", reason);
    loop {
        cortex_m::asm::wfi();
    }
}

#[cortex_m_rt::entry]
fn main() -> ! {
    parapet_firmware::board::ccm::zero();
    let Some(mut cp) = cortex_m::Peripherals::take() else { halt("core peripherals") };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    let board = match Board::init(RX_RING.init([0; COMPANION_RX_RING]), RC_RING.init([0; RC_RX_RING])) {
        Ok(b) => b,
        Err(e) => {
            defmt::error!("board init: {}", e);
            halt("board init")
        }
    };
    // The stored parameters (blocking reads; no erase or write at boot). A stored set the
    // controller refuses (cross-parameter limits) falls back to the defaults, said as corrupt.
    let Some(mut store) = ParamStore::new(board.flash, Board::PARAM_RANGE) else {
        halt("parameter store range")
    };
    let mut params = ControllerParams::default();
    let mut loaded = embassy_futures::block_on(store.load(&mut params));
    let (outer, inner) = match OuterStage::new(params) {
        Ok(s) => s,
        Err(_) => {
            params = ControllerParams::default();
            loaded = Loaded::Corrupt;
            match OuterStage::new(params) {
                Ok(s) => s,
                Err(_) => halt("controller parameters rejected"),
            }
        }
    };
    defmt::info!("parapet-firmware: board up, cascade built (parameters {})", loaded == Loaded::Stored);

    let b: &'static Boxes = BOXES.init(Boxes { stages: Mailboxes::new(), setup: SetupMailboxes::new() });
    interrupt::UART4.set_priority(Priority::P6);
    let high = EXECUTOR_HIGH.start(interrupt::UART4);
    let setup_inner = SetupInner::new(&params);
    match inner_loop(InnerStage::new(inner), setup_inner, board.imu, board.imu_ready, board.motors, b) {
        Ok(t) => high.spawn(t),
        Err(_) => halt("spawn inner loop"),
    }
    interrupt::UART5.set_priority(Priority::P7);
    let med = EXECUTOR_MED.start(interrupt::UART5);
    let outer = OUTER_STAGE.init(outer);
    let setup_outer = SETUP_OUTER.init(SetupOuter::new(params, loaded));
    match outer_loop(outer, OuterSchedule::new(&params), setup_outer, b) {
        Ok(t) => med.spawn(t),
        Err(_) => halt("spawn outer loop"),
    }
    interrupt::I2C1_EV.set_priority(Priority::P8);
    let service = EXECUTOR_SERVICE.start(interrupt::I2C1_EV);
    match rc_task(board.rc_rx, params.rc, b) {
        Ok(t) => service.spawn(t),
        Err(_) => halt("spawn rc receiver"),
    }
    match battery_task(board.battery, params.battery, b) {
        Ok(t) => service.spawn(t),
        Err(_) => halt("spawn battery"),
    }
    match link_task(board.link_tx, board.link_rx, b) {
        Ok(t) => service.spawn(t),
        Err(_) => halt("spawn link"),
    }
    let low = EXECUTOR_LOW.init(Executor::new());
    #[cfg(feature = "onboard-log")]
    let log = board_log::LOG.init(BoardLog::new(board.log_card, params));
    low.run(|spawner| {
        #[cfg(feature = "onboard-log")]
        match log_task(log) {
            Ok(t) => spawner.spawn(t),
            Err(_) => halt("spawn log"),
        }
        match storage_task(STORE.init(store), b) {
            Ok(t) => spawner.spawn(t),
            Err(_) => halt("spawn storage"),
        }
        // In the CPU-only RAM (≈ 29 KiB, never on a stack); requests bring the RPL_* parameters.
        let Some(planner) = ccm::PLANNER.try_take() else { halt("replanner taken twice") };
        let Some(request) = ccm::REQUEST.try_take() else { halt("replan request taken twice") };
        b.stages.replan.install(request);
        match replanner_task(planner, b) {
            Ok(t) => spawner.spawn(t),
            Err(_) => halt("spawn replanner"),
        }
    })
}

/// The on-board replanner (issue 38, `parapet_firmware::app::replanner`): waits for the outer
/// stage's request, plans (milliseconds, preempted by every other task), hands the path back.
#[embassy_executor::task]
async fn replanner_task(planner: &'static mut Replanner, b: &'static Boxes) {
    replanner::run(planner, &b.stages.replan).await
}

/// Attitude + rate loop at the IMU rate.
#[embassy_executor::task]
async fn inner_loop(
    mut stage: InnerStage,
    mut setup: SetupInner,
    imu: ImuParts,
    mut ready: embassy_stm32::exti::ExtiInput<'static, embassy_stm32::mode::Async>,
    mut motors: <Board as FlightBoard>::Motors,
    b: &'static Boxes,
) {
    // This task is SPI1's only user: the bus mutex never masks interrupts.
    let bus: Mutex<NoopRawMutex, _> = Mutex::new(imu.bus);
    let mut imu = ImuParts::device(&bus, imu.cs, imu.axes);
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
    imu.bus_mut().set_config(imu_spi_config(Board::IMU_SPI_FAST_HZ));
    let mut timer = LoopTimer::new(INNER_PERIOD_US, Board::SYSCLK_HZ / 1_000_000);
    loop {
        // Paced by data-ready; a missing edge (IMU stalled) still runs the step, so the
        // cascade sees the stale/failed sample and the motors keep being refreshed.
        let _ = select(ready.wait_for_rising_edge(), Timer::after_micros(IMU_TIMEOUT_US)).await;
        timer.start(cycles());
        let sample = match imu.read().await {
            Ok(s) => s,
            Err(_) => {
                IMU_ERRORS.fetch_add(1, Ordering::Relaxed);
                // A non-finite sample makes the cascade take its bad-input failsafe.
                ImuSample { gyro: Vec3::repeat(f32::NAN), accel: Vec3::repeat(f32::NAN) }
            }
        };
        let now = now_us();
        let sample = setup.imu(now, &sample, &b.setup);
        // Before the stage takes it: a kill frame also stops a motor test in this step.
        let kill = b.stages.kill.signaled();
        let cmd = stage.step(now, &sample, &b.stages).sanitized();
        let cmd = setup.motors(now, cmd, kill, &b.setup);
        motors.write(&cmd).await;
        board_log::motors(&cmd);
        timer.end(cycles());
        if timer.report().steps >= REPORT_EVERY_INNER {
            INNER_REPORT.signal(timer.take_report());
        }
    }
}

/// Position + CBF loop at the outer rate, plus the MAVLink dispatcher.
#[embassy_executor::task]
async fn outer_loop(
    stage: &'static mut OuterStage,
    schedule: OuterSchedule,
    setup: &'static mut SetupOuter,
    b: &'static Boxes,
) {
    let period_us = schedule.period_us();
    let mut ticker = Ticker::every(Duration::from_micros(period_us));
    let mut timer = LoopTimer::new(period_us.min(u64::from(u32::MAX)) as u32, Board::SYSCLK_HZ / 1_000_000);
    let mut link = Link::new(VEHICLE_SYSTEM_ID, FixClock::Arrival);
    link.set_uid(parapet_firmware::link::outbound::uid_of_mcu(embassy_stm32::uid::uid()));
    #[cfg(feature = "onboard-log")]
    let mut next_log_us = 0u64;
    loop {
        match select3(ticker.next(), INBOUND.receive(), b.stages.estimate.wait()).await {
            Either3::First(()) => {
                timer.start(cycles());
                let now = now_us();
                stage.on_estimate(&b.stages);
                link.poll(now, &mut setup.port(stage.port(&b.stages), &b.setup));
                stage.step(now, &b.stages);
                setup.step(now, stage.port(&b.stages), &b.setup);
                ARMED.store(setup.armed(), Ordering::Relaxed);
                #[cfg(feature = "onboard-log")]
                board_log::sample(now, stage, &mut next_log_us);
                timer.end(cycles());
                if timer.report().steps >= REPORT_EVERY_OUTER {
                    OUTER_REPORT.signal(timer.take_report());
                }
                LINK_COUNTERS.signal(ErrorCounters::from_link(&link));
            }
            Either3::Second((t, r)) => link.receive(r, t, &mut setup.port(stage.port(&b.stages), &b.setup)),
            Either3::Third(est) => stage.take_estimate(est, &b.stages),
        }
        while let Some(r) = link.pop_reply() {
            // A full reply queue drops the reply (the peer retries).
            let _ = REPLIES.try_send(r);
        }
    }
}

/// The RC receiver (the board's `RC_RECEIVER`): every decoded frame goes to the outer stage
/// (the `rc` mailbox, latest wins), which maps it with the live `RC_*` parameters; a frame with
/// the kill switch on also straight to the inner stage (`Mailboxes::deliver_rc`, mapped with
/// this task's copy of the parameters, `rc_params` after a rebuild). UART errors
/// (noise, framing, overrun) restart the reception and are counted.
#[embassy_executor::task]
async fn rc_task(mut rx: RingBufferedUartRx<'static>, mut rc: RcParams, b: &'static Boxes) {
    // A const match: only the chosen receiver's decoder is linked.
    let mut publish = |f: RcFrame| {
        if let Some(p) = b.stages.rc_params.try_take() {
            rc = p;
        }
        b.stages.deliver_rc(f, &rc);
    };
    let mut buf = [0u8; 64];
    match Board::RC_RECEIVER {
        RcProtocol::Crsf => {
            let mut r = CrsfReceiver::default();
            loop {
                match rx.read(&mut buf).await {
                    Ok(n) => r.push_frames(buf.get(..n).unwrap_or(&[]), now_us(), &mut publish),
                    Err(_) => {
                        RC_UART_ERRORS.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        }
        RcProtocol::Sbus => {
            let mut r = SbusReceiver::default();
            loop {
                match rx.read(&mut buf).await {
                    Ok(n) => r.push_frames(buf.get(..n).unwrap_or(&[]), now_us(), &mut publish),
                    Err(_) => {
                        RC_UART_ERRORS.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        }
    }
}

/// The parameter store: one job at a time from the outer task, the answer back (module docs).
#[embassy_executor::task]
async fn storage_task(store: &'static mut Store, b: &'static Boxes) {
    loop {
        let job = b.setup.jobs.receive().await;
        let result = storage_job(store, &job).await;
        b.setup.results.signal(result);
    }
}

/// The battery measurement every [`BATTERY_PERIOD_MS`] (module docs); the `BAT_*`
/// parameters follow their changes (the setup mailboxes' `battery_params`).
#[embassy_executor::task]
async fn battery_task(
    mut adc: <Board as FlightBoard>::Battery,
    mut params: BatteryParams,
    b: &'static Boxes,
) {
    let mut estimator = BatteryEstimator::new(params);
    let mut ticker = Ticker::every(Duration::from_millis(BATTERY_PERIOD_MS));
    loop {
        ticker.next().await;
        if let Some(p) = b.setup.battery_params.try_take() {
            params = p;
            estimator.set_params(p);
        }
        let (volts, amps) = params.convert(&adc.read());
        let s = estimator.update(now_us(), volts, amps, ARMED.load(Ordering::Relaxed));
        b.stages.battery.signal(s.state());
    }
}

/// MAVLink over the companion UART: framing, decoding, replies and telemetry; LOG_* frames
/// to and from the log task (module doc).
#[embassy_executor::task]
async fn link_task(
    mut tx: UartTx<'static, embassy_stm32::mode::Async>,
    mut rx: RingBufferedUartRx<'static>,
    b: &'static Boxes,
) {
    let mut framer = Framer::new();
    let mut writer = FrameWriter::new(VEHICLE_SYSTEM_ID, AUTOPILOT_COMPONENT_ID);
    let mut telemetry = TelemetryScheduler::new();
    let mut snapshot = TelemetrySnapshot::BOOT;
    let (mut inner, mut outer) = (LoopReport::ZERO, LoopReport::ZERO);
    let mut counters = ErrorCounters::default();
    let mut buf = [0u8; 64];
    let mut uart_errors: u32 = 0;
    // Telemetry frames that did not fit the batch (none by its bound; counted as UART errors).
    let mut tx_dropped: u32 = 0;
    loop {
        match select(rx.read(&mut buf), Timer::after_millis(5)).await {
            Either::First(Ok(n)) => {
                let now = now_us();
                for &b in buf.get(..n).unwrap_or(&[]) {
                    // At most one frame (or v1 HEARTBEAT) completes per byte. LOG_* requests
                    // go to the log task, the rest (v1 HEARTBEATs too: the link answers
                    // them with its v1 refusal) to the outer task.
                    let mut got = None;
                    framer.push(b, &mut |f: &RawFrame<'_>| board_log::forward(f), &mut |r| got = Some(r));
                    if let Some(r) = got {
                        INBOUND.send((now, r)).await;
                    }
                }
            }
            Either::First(Err(_)) => uart_errors = uart_errors.saturating_add(1),
            Either::Second(()) => {}
        }
        while let Ok(r) = REPLIES.try_receive() {
            send(&mut tx, &mut writer, &r).await;
        }
        board_log::send_replies(&mut tx, &mut writer).await;
        if let Some(s) = b.stages.snapshot.try_take() {
            snapshot = s;
        }
        if let Some(r) = INNER_REPORT.try_take() {
            inner = r;
        }
        if let Some(r) = OUTER_REPORT.try_take() {
            outer = r;
        }
        if let Some(c) = LINK_COUNTERS.try_take() {
            counters = c;
        }
        // Encoded as emitted into one byte batch, written in one DMA transfer: the batch
        // (not the messages and a 280-byte frame each) is what the task keeps across the
        // write (RAM: docs/bring-up.md §9). The inputs are dropped before the await.
        let mut batch: heapless::Vec<u8, TX_BATCH> = heapless::Vec::new();
        {
            let inputs = TelemetryInputs {
                snapshot,
                inner,
                outer,
                parser: framer.stats(),
                counters: ErrorCounters {
                    imu_errors: IMU_ERRORS.load(Ordering::Relaxed),
                    uart_errors: uart_errors.saturating_add(tx_dropped),
                    ..counters
                },
            };
            telemetry.poll(now_us(), &inputs, |m| {
                // Fits by TX_BATCH's bound; a frame that did not is dropped (the streams
                // resend) and counted.
                if batch.extend_from_slice(m.encode(&mut writer).raw_bytes()).is_err() {
                    tx_dropped = tx_dropped.saturating_add(1);
                }
            });
        }
        if !batch.is_empty() {
            // A failed write (DMA error) drops these frames; the streams resend.
            let _ = tx.write(&batch).await;
        }
    }
}

/// The onboard log (module doc): alone in thread mode with the storage task, so its blocking
/// card calls delay neither the control loops nor the link, RC and battery tasks.
#[cfg(feature = "onboard-log")]
#[embassy_executor::task]
async fn log_task(log: &'static mut BoardLog) {
    log.run().await
}

async fn send(tx: &mut UartTx<'static, embassy_stm32::mode::Async>, writer: &mut FrameWriter, m: &Outbound) {
    let raw = m.encode(writer);
    // A failed write (DMA error) drops this frame; the streams resend.
    let _ = tx.write(raw.raw_bytes()).await;
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    Board::force_motors_off();
    // Location only: formatting the message would link core::fmt's float formatting (≈ 9 KiB).
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    loop {
        cortex_m::asm::wfi();
    }
}
