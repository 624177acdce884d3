//! Host tests of the setup services split over the board's tasks: the motor test across the
//! outer → inner mailbox (and its deadline when the outer task stops renewing it), storage jobs
//! through a RAM flash with the real outer stage, the level calibration from the inner task's
//! raw samples, refusals while armed.

use super::*;
use crate::app::cascade::OuterStage;
use crate::app::mailbox::Mailboxes;
use crate::setup::{CMD_DO_MOTOR_TEST, CMD_PREFLIGHT_CALIBRATION, CMD_PREFLIGHT_STORAGE, STILL_TIME_US};
use crate::storage::ram::RamFlash;
use embassy_futures::block_on;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use parapet_core::frame::GRAVITY;

type Mb = SetupMailboxes<CriticalSectionRawMutex>;

/// An outer stage stand-in: keeps parameters, armed by a flag.
#[derive(Default)]
struct Fake {
    params: ControllerParams,
    armed: bool,
    commands: usize,
}

impl Autopilot for &mut Fake {
    fn update_position(&mut self, _fix: &PositionFix) {}
    fn navigation_fix(&mut self, _fix: &PositionFix, _kind: FixKind, _noise: SourceNoise) {}
    fn navigation_height(&mut self, _t_us: u64, _down: f32) {}
    fn update_obstacles(&mut self, _now_us: u64, _o: &[ObstaclePoint]) {}
    fn set_path(&mut self, _w: &[Vec3]) -> Result<(), PathRejected> {
        Ok(())
    }
    fn clear_path(&mut self) {}
    fn command(&mut self, _now_us: u64, _cmd: VehicleCommand) -> Result<(), CommandRejected> {
        self.commands += 1;
        Ok(())
    }
    fn telemetry(&self) -> TelemetrySnapshot {
        TelemetrySnapshot { armed: self.armed, ..TelemetrySnapshot::BOOT }
    }
    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        params::set(&mut self.params, name, value)
    }
    fn get_param(&self, name: &str) -> Option<f32> {
        params::get(&self.params, name)
    }
}

/// The inner part's motor output without a kill frame.
trait NoKill {
    fn motors_(&mut self, now_us: u64, out: MotorCommand, mb: &Mb) -> MotorCommand;
}
impl NoKill for SetupInner {
    fn motors_(&mut self, now_us: u64, out: MotorCommand, mb: &Mb) -> MotorCommand {
        self.motors(now_us, out, false, mb)
    }
}

const DISARMED: MotorCommand = MotorCommand { throttle: [0.0; 4], armed: false };
/// DO_MOTOR_TEST motor `m` at 10 % for `s` seconds.
fn motor_test(m: f32, s: f32) -> [f32; 7] {
    [m, 0.0, 10.0, s, 0.0, 0.0, 0.0]
}
fn texts(o: &mut SetupOuter) -> std::vec::Vec<std::string::String> {
    core::iter::from_fn(|| o.setup().pop_text()).map(|t| t.as_str().into()).collect()
}

#[test]
fn motor_test_reaches_the_inner_task_and_stops_at_its_deadline_without_the_outer_task() {
    let mb = Mb::new();
    let mut fake = Fake::default();
    let mut outer = SetupOuter::new(ControllerParams::default(), Loaded::Empty);
    let mut inner = SetupInner::new(&ControllerParams::default());
    let ack = outer.port(&mut fake, &mb).setup_command(0, CMD_DO_MOTOR_TEST, motor_test(2.0, 5.0));
    assert_eq!(ack, Some(SetupAck::Accepted));
    // Nothing before the outer step published it.
    assert_eq!(inner.motors_(1_000, DISARMED, &mb), DISARMED);
    outer.step(4_000, &mut fake, &mb);
    let m = inner.motors_(5_000, DISARMED, &mb);
    assert!(m.armed && m.throttle[1] > 0.05 && m.throttle[0] == 0.0, "{m:?}");
    // The outer task stops renewing it (stalled): the inner task stops at the deadline.
    assert!(inner.motors_(4_000 + MOTOR_TEST_HOLD_US - 1, DISARMED, &mb).armed);
    assert_eq!(inner.motors_(4_000 + MOTOR_TEST_HOLD_US, DISARMED, &mb), DISARMED);
    // Renewed while the outer task runs, well past one hold.
    for k in 0..20u64 {
        outer.step(30_000 + k * 4_000, &mut fake, &mb);
        assert!(inner.motors_(31_000 + k * 4_000, DISARMED, &mb).armed);
    }
    // Any command stops it at once.
    let _ = outer.port(&mut fake, &mb).command(120_000, VehicleCommand::Land);
    assert_eq!(inner.motors_(120_500, DISARMED, &mb), DISARMED);
    // A new test, then the vehicle arms: the inner task passes the cascade's output through.
    outer.port(&mut fake, &mb).setup_command(200_000, CMD_DO_MOTOR_TEST, motor_test(1.0, 5.0));
    outer.step(204_000, &mut fake, &mb);
    let flying = MotorCommand { throttle: [0.4; 4], armed: true };
    assert_eq!(inner.motors_(205_000, flying, &mb), flying);
    assert_eq!(inner.motors_(206_000, DISARMED, &mb), DISARMED);
}

#[test]
fn setup_commands_are_refused_while_armed_with_a_reason() {
    let mb = Mb::new();
    let mut fake = Fake { armed: true, ..Default::default() };
    let mut outer = SetupOuter::new(ControllerParams::default(), Loaded::Empty);
    let mut inner = SetupInner::new(&ControllerParams::default());
    outer.step(0, &mut fake, &mb);
    for (id, p) in [
        (CMD_DO_MOTOR_TEST, motor_test(1.0, 1.0)),
        (CMD_PREFLIGHT_STORAGE, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (CMD_PREFLIGHT_CALIBRATION, [0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0]),
    ] {
        assert_eq!(outer.port(&mut fake, &mb).setup_command(10, id, p), Some(SetupAck::Denied), "{id}");
    }
    let t = texts(&mut outer);
    assert_eq!(t.len(), 3, "{t:?}");
    assert!(t[0].contains("vehicle armed") && t[1].contains("denied while armed") && t[2].contains("armed"));
    assert_eq!(inner.motors_(20, DISARMED, &mb), DISARMED);
    assert!(mb.jobs.try_receive().is_err(), "no storage job while armed");
}

#[test]
fn storage_jobs_save_read_and_reset_through_the_real_outer_stage() {
    type F = RamFlash<8192, 4096>;
    let mut store = ParamStore::new(F::new(), 0..8192).unwrap();
    let boxes: Mailboxes<CriticalSectionRawMutex> = Mailboxes::new();
    let mb = Mb::new();
    let (mut stage, _inner) = OuterStage::new(ControllerParams::default()).unwrap();
    let mut outer = SetupOuter::new(ControllerParams::default(), Loaded::Empty);
    let default_mu = ControllerParams::default().cbf.mu;
    // PARAM_SET, then the debounced save 1 s later (a job for the storage task).
    assert_eq!(outer.port(stage.port(&boxes), &mb).set_param("CBF_MU", 2.0), Ok(2.0));
    outer.step(500_000, stage.port(&boxes), &mb);
    assert!(mb.jobs.try_receive().is_err(), "not before the debounce");
    outer.step(1_000_001, stage.port(&boxes), &mb);
    let job = mb.jobs.try_receive().expect("the debounced save");
    assert_eq!(block_on(storage_job(&mut store, &job)), StorageResult::Saved);
    mb.results.signal(StorageResult::Saved);
    // Change it, then PREFLIGHT_STORAGE read: the stored 2.0 comes back into the stage.
    outer.port(stage.port(&boxes), &mb).set_param("CBF_MU", 1.0).unwrap();
    let read = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_eq!(
        outer.port(stage.port(&boxes), &mb).setup_command(1_100_000, CMD_PREFLIGHT_STORAGE, read),
        Some(SetupAck::Accepted)
    );
    outer.step(1_104_000, stage.port(&boxes), &mb);
    let job = mb.jobs.try_receive().expect("read job");
    assert_eq!(job, StorageJob::Read);
    let r = block_on(storage_job(&mut store, &job));
    assert!(matches!(r, StorageResult::Loaded(p) if p.cbf.mu == 2.0), "{r:?}");
    mb.results.signal(r);
    outer.step(1_108_000, stage.port(&boxes), &mb);
    assert_eq!(stage.port(&boxes).get_param("CBF_MU"), Some(2.0));
    assert_eq!(outer.params().cbf.mu, 2.0);
    // Reset: erased, the defaults applied and said.
    let reset = [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    outer.port(stage.port(&boxes), &mb).setup_command(1_200_000, CMD_PREFLIGHT_STORAGE, reset);
    outer.step(1_204_000, stage.port(&boxes), &mb);
    let r = block_on(storage_job(&mut store, &mb.jobs.try_receive().expect("reset job")));
    assert_eq!(r, StorageResult::Erased);
    mb.results.signal(r);
    outer.step(1_208_000, stage.port(&boxes), &mb);
    assert_eq!(stage.port(&boxes).get_param("CBF_MU"), Some(default_mu));
    assert!(texts(&mut outer).iter().any(|t| t == "Params: reset to defaults"));
    // A read now finds nothing: said, nothing applied.
    let r = block_on(storage_job(&mut store, &StorageJob::Read));
    assert_eq!(r, StorageResult::Text("Params: nothing stored"));
}

#[test]
fn a_second_storage_request_while_the_task_is_busy_is_said_and_the_save_stays_pending() {
    let mb = Mb::new();
    let mut fake = Fake::default();
    let mut outer = SetupOuter::new(ControllerParams::default(), Loaded::Empty);
    let write = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    outer.port(&mut fake, &mb).setup_command(0, CMD_PREFLIGHT_STORAGE, write);
    outer.step(4_000, &mut fake, &mb);
    outer.port(&mut fake, &mb).setup_command(5_000, CMD_PREFLIGHT_STORAGE, write);
    outer.step(8_000, &mut fake, &mb);
    assert!(texts(&mut outer).iter().any(|t| t.contains("storage busy")));
    // The storage task takes the first; until its answer is back nothing else is sent.
    assert!(matches!(mb.jobs.try_receive(), Ok(StorageJob::Save(_))));
    outer.step(8_000 + crate::storage::SAVE_DEBOUNCE_US, &mut fake, &mb);
    assert!(mb.jobs.try_receive().is_err(), "a job while the previous one runs");
    // The answer: the pending save goes out at the next step.
    mb.results.signal(StorageResult::Saved);
    outer.step(12_000 + crate::storage::SAVE_DEBOUNCE_US, &mut fake, &mb);
    assert!(matches!(mb.jobs.try_receive(), Ok(StorageJob::Save(_))));
}

#[test]
fn level_calibration_runs_on_the_inner_tasks_raw_samples_and_corrects_the_inner_task() {
    let mb = Mb::new();
    let mut fake = Fake::default();
    let mut outer = SetupOuter::new(ControllerParams::default(), Loaded::Empty);
    let mut inner = SetupInner::new(&ControllerParams::default());
    let tilt: f32 = 0.05;
    let raw =
        ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(GRAVITY * tilt.sin(), 0.0, -GRAVITY * tilt.cos()) };
    let level = [0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0];
    assert_eq!(
        outer.port(&mut fake, &mb).setup_command(0, CMD_PREFLIGHT_CALIBRATION, level),
        Some(SetupAck::Accepted)
    );
    // Inner at 1 kHz, outer every 4th step, until the still time is over.
    let mut t = 0;
    while t <= STILL_TIME_US + 10_000 {
        inner.imu(t, &raw, &mb);
        if t % 4_000 == 0 {
            outer.step(t, &mut fake, &mb);
        }
        t += 1_000;
    }
    assert!(!outer.setup().calibrating());
    assert!(!mb.calibrating.load(Ordering::Relaxed));
    let trim = fake.params.sensors.trim_pitch;
    assert!((trim.abs() - tilt).abs() < 0.005, "trim {trim}");
    assert!(texts(&mut outer).iter().any(|t| t == "[cal] calibration done: level"));
    // The inner task took the new correction: the tilted board now reads level.
    let c = inner.imu(t, &raw, &mb);
    assert!(c.accel.x.abs() < 0.05 && (c.accel.z + GRAVITY).abs() < 0.05, "{:?}", c.accel);
}

#[test]
fn a_kill_switch_frame_stops_the_motor_test_in_the_inner_task_and_it_stays_stopped() {
    let mb = Mb::new();
    let mut fake = Fake::default();
    let mut outer = SetupOuter::new(ControllerParams::default(), Loaded::Empty);
    let mut inner = SetupInner::new(&ControllerParams::default());
    outer.port(&mut fake, &mb).setup_command(0, CMD_DO_MOTOR_TEST, motor_test(3.0, 5.0));
    outer.step(4_000, &mut fake, &mb);
    assert!(inner.motors(5_000, DISARMED, false, &mb).armed);
    // The kill frame's step: off at once, although a renewal is already waiting.
    outer.step(8_000, &mut fake, &mb);
    assert_eq!(inner.motors(8_500, DISARMED, true, &mb), DISARMED);
    assert_eq!(inner.motors(9_000, DISARMED, false, &mb), DISARMED);
    // The outer task stops its state machine: no renewal afterwards.
    for k in 0..10u64 {
        outer.step(12_000 + 4_000 * k, &mut fake, &mb);
        assert_eq!(inner.motors(13_000 + 4_000 * k, DISARMED, false, &mb), DISARMED);
    }
    assert!(!mb.test_killed.load(Ordering::Relaxed));
    // A new test afterwards works again.
    outer.port(&mut fake, &mb).setup_command(60_000, CMD_DO_MOTOR_TEST, motor_test(3.0, 5.0));
    outer.step(64_000, &mut fake, &mb);
    assert!(inner.motors(65_000, DISARMED, false, &mb).armed);
}
