//! [`SetupVehicle`]: a flight-control cascade (any [`ControlSteps`], the real
//! [`crate::app::cascade::Cascade`] on the boards) with the setup services around it, so a
//! board switches them on by wrapping its cascade:
//!
//! * the link's PREFLIGHT_STORAGE / PREFLIGHT_CALIBRATION / DO_MOTOR_TEST
//!   ([`Autopilot::setup_command`]) go to [`Setup`], its STATUSTEXTs to the link;
//! * every IMU sample is corrected ([`ImuCorrection`]: accelerometer offset and scale, board
//!   rotation `SENS_BOARD_ROT`, level trim) before the cascade sees it, and fed raw to a
//!   running calibration; a result is written to the cascade's parameters;
//! * a running motor test replaces the (disarmed) motor command; arming, an RC arm or kill
//!   switch, and any vehicle command stop it;
//! * parameter changes schedule a save; [`SetupVehicle::storage_step`] (boot load, PREFLIGHT_STORAGE
//!   requests, the debounced save) is **not** part of the control steps: the board runs it in
//!   its lowest-priority context (the F405: a task of the low executor; QEMU: between
//!   lockstep steps), because a flash write there may stall the CPU.
//!
//! A board whose cascade runs in separate tasks (the F405 / H743 binary) uses the same services
//! split over its tasks: [`tasks`].
//!
//! Owns [`SetupVehicle`]. May import [`crate::app`], [`crate::setup`], [`crate::storage`],
//! `parapet_core`. Every control-step addition is bounded (two 3×3 products; the
//! calibration's per-sample work).

use crate::app::autopilot::{
    Autopilot, CommandRejected, ControlSteps, FixKind, ImuSample, MotorCommand, OffboardSetpoint,
    PathRejected, PositionFix, SourceNoise, TelemetrySnapshot, VehicleCommand,
};
use crate::setup::{Setup, SetupAck, StorageRequest, Text};
use crate::storage::{Loaded, ParamStore};
use embedded_storage_async::nor_flash::NorFlash;
use parapet_core::battery::{BatteryParams, BatteryState};
use parapet_core::calibration::ImuCorrection;
use parapet_core::config::ControllerParams;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::params::{self, ParamRejected, TABLE};
use parapet_core::rc::map::RcParams;
use parapet_core::rc::RcInput;
use parapet_core::Vec3;

/// The cascade `A` with the setup services (see the module docs).
pub struct SetupVehicle<A> {
    inner: A,
    /// The parameters as set (mirror of the cascade's, for the store and the correction).
    params: ControllerParams,
    setup: Setup,
    correction: ImuCorrection,
    armed: bool,
    now_us: u64,
}

impl<A: ControlSteps> SetupVehicle<A> {
    /// Wrap `inner`, built from `params`.
    pub fn new(inner: A, params: ControllerParams) -> Self {
        Self {
            inner,
            params,
            setup: Setup::new(),
            correction: ImuCorrection::new(&params.sensors),
            armed: false,
            now_us: 0,
        }
    }

    /// The wrapped cascade.
    pub fn inner(&self) -> &A {
        &self.inner
    }

    /// The parameters as set.
    pub fn params(&self) -> &ControllerParams {
        &self.params
    }

    /// The setup services (tests, telemetry).
    pub fn setup(&mut self) -> &mut Setup {
        &mut self.setup
    }

    /// Hand every parameter of `p` to the cascade (after a load / reset); returns how many
    /// were refused by the cascade (0 normally).
    fn apply_all(&mut self, p: &ControllerParams) -> usize {
        let mut refused = 0;
        for d in TABLE.iter() {
            if self.set_param_inner(d.name, (d.get)(p)).is_err() {
                refused += 1;
            }
        }
        refused
    }

    fn set_param_inner(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        let v = self.inner.set_param(name, value)?;
        params::set(&mut self.params, name, v)?;
        if name.starts_with("CAL_") || name == "SENS_BOARD_ROT" {
            self.correction = ImuCorrection::new(&self.params.sensors);
        }
        Ok(v)
    }

    /// At boot, before the first control step: load the stored parameters (the defaults
    /// stay when the store is empty, corrupt or of another firmware; the warning is queued
    /// as a STATUSTEXT).
    pub async fn boot_load<F: NorFlash>(&mut self, store: &mut ParamStore<F>) -> Loaded {
        let mut p = self.params;
        let loaded = store.load(&mut p).await;
        if loaded == Loaded::Stored {
            self.apply_all(&p);
        }
        if let Some(t) = loaded.statustext() {
            self.setup.say_text(t);
        }
        loaded
    }

    /// The storage work due at `now_us` (a PREFLIGHT_STORAGE request, or the debounced save
    /// while disarmed). Run it outside the control steps (module docs). Failures are queued
    /// as STATUSTEXTs; the parameters in effect never change on a failed write. Returns
    /// `true` when it used the flash (the board measures those calls).
    pub async fn storage_step<F: NorFlash>(&mut self, now_us: u64, store: &mut ParamStore<F>) -> bool {
        match self.setup.take_storage() {
            Some(StorageRequest::Write) => {
                if store.save(&self.params).await.is_err() {
                    self.setup.say_text("Params: save failed");
                }
            }
            Some(StorageRequest::Read) => {
                let mut p = self.params;
                match store.load(&mut p).await {
                    Loaded::Stored => {
                        self.apply_all(&p);
                    }
                    other => self.setup.say_text(other.statustext().unwrap_or("Params: nothing stored")),
                }
            }
            Some(StorageRequest::Reset) => {
                if store.reset().await.is_err() {
                    self.setup.say_text("Params: reset failed");
                } else {
                    self.apply_all(&ControllerParams::default());
                    self.setup.say_text("Params: reset to defaults");
                }
            }
            None => {
                if !self.setup.save_due(now_us, self.armed) {
                    return false;
                }
                if store.save(&self.params).await.is_err() {
                    self.setup.say_text("Params: save failed");
                }
            }
        }
        true
    }
}

impl<A: ControlSteps> Autopilot for SetupVehicle<A> {
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
        self.setup.stop_motors();
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
        self.setup.param_changed(self.now_us);
        Ok(v)
    }
    fn get_param(&self, name: &str) -> Option<f32> {
        self.inner.get_param(name)
    }
    fn set_rc(&mut self, rc: &RcInput) {
        if rc.arm || rc.kill {
            self.setup.stop_motors();
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
    fn battery_params(&self) -> Option<BatteryParams> {
        self.inner.battery_params()
    }
    fn setup_command(&mut self, now_us: u64, id: u16, p: [f32; 7]) -> Option<SetupAck> {
        let params = self.params;
        self.setup.command(now_us, id, p, self.armed, &params)
    }
    fn setup_text(&mut self) -> Option<Text> {
        self.setup.pop_text()
    }
}

impl<A: ControlSteps> ControlSteps for SetupVehicle<A> {
    fn step_inner(&mut self, now_us: u64, imu: &ImuSample) -> MotorCommand {
        self.now_us = now_us;
        let raw = *imu;
        if self.setup.calibrating() {
            let mut p = self.params;
            if self.setup.imu(now_us, &raw, &mut p) {
                for name in [
                    "CAL_ACC0_XOFF",
                    "CAL_ACC0_YOFF",
                    "CAL_ACC0_ZOFF",
                    "CAL_ACC0_XSCALE",
                    "CAL_ACC0_YSCALE",
                    "CAL_ACC0_ZSCALE",
                    "CAL_TRIM_ROLL",
                    "CAL_TRIM_PITCH",
                ] {
                    if let Some(v) = params::get(&p, name) {
                        let _ = self.set_param_inner(name, v);
                    }
                }
            }
        }
        let c = self.correction.apply(&raw);
        let mut out = self.inner.step_inner(now_us, &c);
        self.armed = out.armed;
        if out.armed {
            self.setup.stop_motors();
        } else if let Some(m) = self.setup.motor_output(now_us, None) {
            // The motor test drives the ESCs while the vehicle stays disarmed.
            out = MotorCommand { throttle: m, armed: true };
        }
        out
    }

    fn step_outer(&mut self, now_us: u64) {
        self.now_us = now_us;
        self.inner.step_outer(now_us)
    }

    fn serve_replan(&mut self, planner: &mut parapet_core::replan::Replanner) -> bool {
        self.inner.serve_replan(planner)
    }

    fn install_replan(&mut self, request: &'static mut parapet_core::replan::onboard::ReplanRequest) {
        self.inner.install_replan(request);
    }
}

pub mod tasks;

#[cfg(test)]
mod tests;
