//! The setup services of [`super::SetupVehicle`] on a board whose cascade runs in two tasks
//! (`src/bin/fc/mod.rs`: the inner stage at the IMU rate, the outer stage with the link at the outer
//! rate) and whose flash is written by a third, lowest-priority task. Each part runs where its
//! data is, and they talk through [`SetupMailboxes`] (embassy-sync, `Copy` messages):
//!
//! | part | task | does |
//! |---|---|---|
//! | [`SetupInner`] | inner | corrects every IMU sample ([`ImuCorrection`], replaced from [`SetupMailboxes::correction`]); hands raw samples to the outer task while a calibration runs; drives the ESCs with the motor test's output while disarmed, **only until the output's deadline** ([`MotorTestOutput::until_us`], [`MOTOR_TEST_HOLD_US`] after the outer task last renewed it) |
//! | [`SetupOuter`] / [`SetupPort`] | outer | the setup commands and STATUSTEXTs ([`crate::setup::Setup`]) on the link's [`Autopilot`]; the calibrations on the raw samples, results through `set_param`; the motor-test state machine, renewed every outer step; storage requests and the debounced save as [`StorageJob`]s; the stored sets coming back applied with `set_param` |
//! | [`storage_job`] | storage (lowest priority) | one job on the [`ParamStore`]: save, read, reset. A flash erase or write never runs in a control task |
//!
//! The battery measurement (lowest priority too) gets the `BAT_*` parameters after a change
//! through [`SetupMailboxes::battery_params`].
//!
//! Safety: the motor test stops when the vehicle arms (the inner task sees its own armed
//! output), on a kill-switch frame (inner, in the step the frame arrives for, then the outer
//! state machine), on any link command or RC arm/kill input through the link (outer), at its
//! timeout (outer), and — should the outer task stop renewing it — at the deadline (inner), so a
//! stalled outer task cannot leave a motor spinning. Every call is bounded.
//!
//! Owns [`SetupMailboxes`], [`SetupInner`], [`SetupOuter`], [`SetupPort`], [`StorageJob`],
//! [`StorageResult`], [`MotorTestOutput`]. May import what [`super`] may.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_sync::blocking_mutex::raw::RawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embedded_storage_async::nor_flash::NorFlash;
use parapet_core::battery::{BatteryParams, BatteryState};
use parapet_core::calibration::ImuCorrection;
use parapet_core::config::ControllerParams;
use parapet_core::motor_test::MAX_MOTORS;
use parapet_core::msg;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::params::{self, ParamRejected, TABLE};
use parapet_core::rc::map::RcParams;
use parapet_core::rc::RcInput;
use parapet_core::Vec3;

use crate::app::autopilot::{
    Autopilot, CommandRejected, FixKind, ImuSample, MotorCommand, OffboardSetpoint, PathRejected,
    PositionFix, SourceNoise, TelemetrySnapshot, VehicleCommand,
};
use crate::setup::{Setup, SetupAck, StorageRequest, Text};
use crate::storage::{Loaded, ParamStore};

/// How long the inner task keeps a motor-test output after the outer task last renewed it, µs
/// (5 outer periods at 250 Hz).
pub const MOTOR_TEST_HOLD_US: u64 = 20_000;

/// The calibration results [`SetupOuter`] writes through `set_param`.
const CAL_PARAMS: [&str; 8] = [
    "CAL_ACC0_XOFF",
    "CAL_ACC0_YOFF",
    "CAL_ACC0_ZOFF",
    "CAL_ACC0_XSCALE",
    "CAL_ACC0_YSCALE",
    "CAL_ACC0_ZSCALE",
    "CAL_TRIM_ROLL",
    "CAL_TRIM_PITCH",
];

/// A motor-test output for the inner task: per-motor throttle 0..1 (output order), valid until
/// `until_us` (firmware clock).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorTestOutput {
    /// Throttle per motor.
    pub throttle: [f32; MAX_MOTORS],
    /// Deadline: from here on the motors get the cascade's (disarmed) command again.
    pub until_us: u64,
}

impl MotorTestOutput {
    /// Stop now.
    pub const STOP: Self = Self { throttle: [0.0; MAX_MOTORS], until_us: 0 };
}

/// Work for the storage task.
// No allocation: the parameter set travels inline (≈ 600 B; one message in a channel of depth 1).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StorageJob {
    /// Write these parameters (a PREFLIGHT_STORAGE write, or the debounced save).
    Save(ControllerParams),
    /// Read the stored set.
    Read,
    /// Erase the store (reset to defaults).
    Reset,
}

/// The storage task's answer.
// As `StorageJob`: the loaded set inline.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StorageResult {
    /// Saved (nothing to do).
    Saved,
    /// A complete stored set: apply it.
    Loaded(ControllerParams),
    /// Erased: apply the defaults.
    Erased,
    /// Failed or nothing stored: tell the ground station.
    Text(&'static str),
}

/// One job on `store` (the storage task's whole work; see the module docs).
/// (`job` by reference: the caller's copy is the only one in the task's state.)
pub async fn storage_job<F: NorFlash>(store: &mut ParamStore<F>, job: &StorageJob) -> StorageResult {
    match job {
        StorageJob::Save(p) => match store.save(p).await {
            Ok(_) => StorageResult::Saved,
            Err(_) => StorageResult::Text("Params: save failed"),
        },
        StorageJob::Read => {
            let mut p = ControllerParams::default();
            match store.load(&mut p).await {
                Loaded::Stored => StorageResult::Loaded(p),
                other => StorageResult::Text(other.statustext().unwrap_or("Params: nothing stored")),
            }
        }
        StorageJob::Reset => match store.reset().await {
            Ok(()) => StorageResult::Erased,
            Err(_) => StorageResult::Text("Params: reset failed"),
        },
    }
}

/// The mailboxes between the three parts (see the module docs). `M`: the raw mutex
/// (`CriticalSectionRawMutex` between tasks of different priorities).
pub struct SetupMailboxes<M: RawMutex> {
    /// Outer → inner: the IMU correction of the parameters now set.
    pub correction: Signal<M, ImuCorrection>,
    /// Outer → inner: the motor-test output (renewed every outer step while a test runs).
    pub motor_test: Signal<M, MotorTestOutput>,
    /// Inner → outer: the latest raw IMU sample and its time, while [`Self::calibrating`].
    pub raw_imu: Signal<M, (u64, msg::ImuSample)>,
    /// Outer → inner: a calibration runs (the inner task publishes raw samples).
    pub calibrating: AtomicBool,
    /// Outer → storage: the next job (one at a time: the outer part sends the next one only
    /// after the answer to the previous one).
    pub jobs: Channel<M, StorageJob, 1>,
    /// Storage → outer: the answer to the job.
    pub results: Signal<M, StorageResult>,
    /// Inner → outer: a kill-switch frame stopped the motor test; the outer task stops its test
    /// and clears the flag (after publishing the stop).
    pub test_killed: AtomicBool,
    /// Outer → battery measurement: the `BAT_*` parameters after a change.
    pub battery_params: Signal<M, BatteryParams>,
}

impl<M: RawMutex> Default for SetupMailboxes<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: RawMutex> SetupMailboxes<M> {
    /// Empty mailboxes.
    pub const fn new() -> Self {
        Self {
            correction: Signal::new(),
            motor_test: Signal::new(),
            raw_imu: Signal::new(),
            calibrating: AtomicBool::new(false),
            jobs: Channel::new(),
            results: Signal::new(),
            test_killed: AtomicBool::new(false),
            battery_params: Signal::new(),
        }
    }
}

/// The inner task's part (module docs).
pub struct SetupInner {
    correction: ImuCorrection,
    test: MotorTestOutput,
}

impl SetupInner {
    /// With the correction of `params` (the set the board booted with).
    pub fn new(params: &ControllerParams) -> Self {
        Self { correction: ImuCorrection::new(&params.sensors), test: MotorTestOutput::STOP }
    }

    /// The corrected sample for the cascade; the raw one goes to the outer task while a
    /// calibration runs.
    pub fn imu<M: RawMutex>(&mut self, now_us: u64, raw: &ImuSample, mb: &SetupMailboxes<M>) -> ImuSample {
        if let Some(c) = mb.correction.try_take() {
            self.correction = c;
        }
        let raw = *raw;
        if mb.calibrating.load(Ordering::Relaxed) {
            mb.raw_imu.signal((now_us, raw));
        }
        self.correction.apply(&raw)
    }

    /// The command for the ESCs: the cascade's `out`, or while disarmed a motor test's output
    /// until its deadline. `kill`: a kill-switch frame arrived for this step (the board's
    /// `Mailboxes::kill` was signalled): the test stops here, and no test output is taken
    /// until the outer task has stopped its test too ([`SetupMailboxes::test_killed`]).
    pub fn motors<M: RawMutex>(
        &mut self,
        now_us: u64,
        out: MotorCommand,
        kill: bool,
        mb: &SetupMailboxes<M>,
    ) -> MotorCommand {
        if kill {
            mb.test_killed.store(true, Ordering::Release);
        }
        if let Some(t) = mb.motor_test.try_take() {
            self.test = t;
        }
        if mb.test_killed.load(Ordering::Acquire) {
            self.test = MotorTestOutput::STOP;
        }
        if out.armed || now_us >= self.test.until_us {
            self.test = MotorTestOutput::STOP;
            return out;
        }
        MotorCommand { throttle: self.test.throttle, armed: true }
    }
}

/// The outer task's part (module docs): the setup state and the parameters as set.
pub struct SetupOuter {
    setup: Setup,
    params: ControllerParams,
    armed: bool,
    now_us: u64,
    testing: bool,
    /// A job was sent and its answer has not come back yet.
    busy: bool,
}

impl SetupOuter {
    /// For the cascade built from `params`; `boot` is what the boot load found (its warning is
    /// queued as a STATUSTEXT).
    pub fn new(params: ControllerParams, boot: Loaded) -> Self {
        let mut setup = Setup::new();
        if let Some(t) = boot.statustext() {
            setup.say_text(t);
        }
        Self { setup, params, armed: false, now_us: 0, testing: false, busy: false }
    }

    /// The parameters as set.
    pub fn params(&self) -> &ControllerParams {
        &self.params
    }

    /// The vehicle was armed at the last [`SetupOuter::step`].
    pub fn armed(&self) -> bool {
        self.armed
    }

    /// The setup services (tests, telemetry).
    pub fn setup(&mut self) -> &mut Setup {
        &mut self.setup
    }

    /// The [`Autopilot`] the link talks to: `inner` (the outer stage's port) with the setup
    /// services around it.
    pub fn port<'a, P: Autopilot, M: RawMutex>(
        &'a mut self,
        inner: P,
        mb: &'a SetupMailboxes<M>,
    ) -> SetupPort<'a, P, M> {
        SetupPort { outer: self, inner, mb }
    }

    /// One outer step's setup work at `now_us` on `port` (the outer stage's port): motor test
    /// renewal, calibration samples, storage answers and requests.
    pub fn step<P: Autopilot, M: RawMutex>(&mut self, now_us: u64, port: P, mb: &SetupMailboxes<M>) {
        let mut p = self.port(port, mb);
        p.outer.now_us = now_us;
        p.step_motors(now_us);
        p.step_calibration();
        p.step_storage(now_us);
    }
}

/// [`SetupOuter`] around the outer stage's [`Autopilot`] `P`, with the mailboxes.
pub struct SetupPort<'a, P: Autopilot, M: RawMutex> {
    outer: &'a mut SetupOuter,
    inner: P,
    mb: &'a SetupMailboxes<M>,
}

impl<P: Autopilot, M: RawMutex> SetupPort<'_, P, M> {
    fn set_param_inner(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        let v = self.inner.set_param(name, value)?;
        params::set(&mut self.outer.params, name, v)?;
        if name.starts_with("CAL_") || name == "SENS_BOARD_ROT" {
            self.mb.correction.signal(ImuCorrection::new(&self.outer.params.sensors));
        }
        if name.starts_with("BAT_") {
            self.mb.battery_params.signal(self.outer.params.battery);
        }
        Ok(v)
    }

    /// Every parameter of `p` to the cascade (a stored set, the defaults); returns how many
    /// the cascade refused.
    fn apply_all(&mut self, p: &ControllerParams) -> usize {
        TABLE.iter().filter(|d| self.set_param_inner(d.name, (d.get)(p)).is_err()).count()
    }

    fn stop_motors(&mut self) {
        self.outer.setup.stop_motors();
        if self.outer.testing {
            self.outer.testing = false;
            self.mb.motor_test.signal(MotorTestOutput::STOP);
        }
    }

    fn step_motors(&mut self, now_us: u64) {
        if self.mb.test_killed.load(Ordering::Acquire) {
            // The stop first, then the flag: the inner task never takes an older renewal.
            self.outer.setup.stop_motors();
            self.outer.testing = false;
            self.mb.motor_test.signal(MotorTestOutput::STOP);
            self.mb.test_killed.store(false, Ordering::Release);
        }
        self.outer.armed = self.inner.telemetry().armed;
        if self.outer.armed {
            self.stop_motors();
            return;
        }
        match self.outer.setup.motor_output(now_us, None) {
            Some(throttle) => {
                self.outer.testing = true;
                let until_us = now_us.saturating_add(MOTOR_TEST_HOLD_US);
                self.mb.motor_test.signal(MotorTestOutput { throttle, until_us });
            }
            None => self.stop_motors(),
        }
    }

    fn step_calibration(&mut self) {
        let calibrating = self.outer.setup.calibrating();
        self.mb.calibrating.store(calibrating, Ordering::Relaxed);
        let Some((t, raw)) = self.mb.raw_imu.try_take() else { return };
        if !calibrating {
            return;
        }
        let mut p = self.outer.params;
        if self.outer.setup.imu(t, &raw, &mut p) {
            for name in CAL_PARAMS {
                if let Some(v) = params::get(&p, name) {
                    let _ = self.set_param_inner(name, v);
                }
            }
        }
        self.mb.calibrating.store(self.outer.setup.calibrating(), Ordering::Relaxed);
    }

    fn step_storage(&mut self, now_us: u64) {
        if let Some(r) = self.mb.results.try_take() {
            self.outer.busy = false;
            match r {
                StorageResult::Saved => {}
                StorageResult::Loaded(p) => {
                    self.apply_all(&p);
                }
                StorageResult::Erased => {
                    self.apply_all(&ControllerParams::default());
                    self.outer.setup.say_text("Params: reset to defaults");
                }
                StorageResult::Text(t) => self.outer.setup.say_text(t),
            }
        }
        let busy = self.outer.busy;
        let job = match self.outer.setup.take_storage() {
            Some(req) if busy => {
                // The storage task is still on the previous job: say so; a write becomes a
                // pending save (sent once the answer is back and the debounce has passed).
                if req == StorageRequest::Write {
                    self.outer.setup.param_changed(now_us);
                }
                self.outer.setup.say_text("Params: storage busy, try again");
                None
            }
            Some(StorageRequest::Write) => Some(StorageJob::Save(self.outer.params)),
            Some(StorageRequest::Read) => Some(StorageJob::Read),
            Some(StorageRequest::Reset) => Some(StorageJob::Reset),
            // While busy the due save waits (still pending, its time kept).
            None if !busy && self.outer.setup.save_due(now_us, self.outer.armed) => {
                Some(StorageJob::Save(self.outer.params))
            }
            None => None,
        };
        if let Some(j) = job {
            match self.mb.jobs.try_send(j) {
                Ok(()) => self.outer.busy = true,
                // Not busy, so the queue is empty; should it not be, the save stays pending.
                Err(_) => {
                    self.outer.setup.param_changed(now_us);
                    self.outer.setup.say_text("Params: storage busy, try again");
                }
            }
        }
    }
}

impl<P: Autopilot, M: RawMutex> Autopilot for SetupPort<'_, P, M> {
    fn update_position(&mut self, fix: &PositionFix) {
        self.inner.update_position(fix)
    }
    fn navigation_fix(&mut self, fix: &PositionFix, kind: FixKind, noise: SourceNoise) {
        self.inner.navigation_fix(fix, kind, noise)
    }
    fn navigation_height(&mut self, t_us: u64, down: f32) {
        self.inner.navigation_height(t_us, down)
    }
    fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]) {
        self.inner.update_obstacles(now_us, obstacles)
    }
    fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), PathRejected> {
        self.inner.set_path(waypoints_ned)
    }
    fn stream_path(&mut self, waiting: &[Vec3]) -> usize {
        self.inner.stream_path(waiting)
    }
    fn clear_path(&mut self) {
        self.inner.clear_path()
    }
    fn command(&mut self, now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected> {
        self.stop_motors();
        self.inner.command(now_us, cmd)
    }
    fn telemetry(&self) -> TelemetrySnapshot {
        self.inner.telemetry()
    }
    fn mapped_margin(&self) -> Option<parapet_core::nav::bound::ErrorBound> {
        self.inner.mapped_margin()
    }
    fn flown_path(&self) -> &[parapet_core::Vec3] {
        self.inner.flown_path()
    }
    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        let v = self.set_param_inner(name, value)?;
        self.outer.setup.param_changed(self.outer.now_us);
        Ok(v)
    }
    fn get_param(&self, name: &str) -> Option<f32> {
        self.inner.get_param(name)
    }
    fn set_rc(&mut self, rc: &RcInput) {
        if rc.arm || rc.kill {
            self.stop_motors();
        }
        self.inner.set_rc(rc)
    }
    fn rc_params(&self) -> RcParams {
        self.inner.rc_params()
    }
    fn set_offboard(&mut self, sp: &OffboardSetpoint) {
        self.inner.set_offboard(sp)
    }
    fn set_battery(&mut self, b: &BatteryState) {
        self.inner.set_battery(b)
    }
    fn setup_command(&mut self, now_us: u64, id: u16, p: [f32; 7]) -> Option<SetupAck> {
        let params = self.outer.params;
        let armed = self.outer.armed || self.inner.telemetry().armed;
        let ack = self.outer.setup.command(now_us, id, p, armed, &params);
        if id != crate::setup::CMD_DO_MOTOR_TEST {
            self.stop_motors();
        }
        ack
    }
    fn setup_text(&mut self) -> Option<Text> {
        self.outer.setup.pop_text()
    }
}

#[cfg(test)]
mod tests;
