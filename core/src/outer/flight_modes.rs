//! The outer loop's side of the flight modes (issue 21): it feeds the mode machine
//! ([`crate::supervisor::modes`]) with RC frames, offboard setpoints and battery states,
//! applies what the machine decides (arm/disarm/kill, mode entry, failsafe mode changes)
//! and produces each mode's reference while Armed:
//!
//! | mode | reference | filter |
//! |---|---|---|
//! | Manual | sticks → attitude/thrust setpoint ([`super::assist::manual_setpoint`]), PD and filter bypassed | **off** |
//! | Position | sticks → velocity setpoint, leashed target ([`super::assist`]) | on |
//! | Mission | the guidance of the commands (takeoff, hold, mission) | on |
//! | Offboard | position / velocity / acceleration setpoint ([`super::offboard`]; a position-only one on the trajectory with `MIS_GUIDANCE` 1) | on |
//! | Hold | the position at entry | on |
//! | Return | the breadcrumbs reversed ([`super::return_path`]; on the trajectory with `MIS_GUIDANCE` 1), then Land | on |
//! | Land | the supervisor's landing | on |
//!
//! Entry conditions (commands and the mode switch; a refused change leaves the mode):
//! Manual and Position need a valid RC frame, Offboard a fresh setpoint, Return a position fix.
//! Failsafe changes never fail: a Return without a fix lands instead.
//!
//! May import: what [`super`] may import, and [`crate::rc`], [`crate::battery`].

use super::assist::{manual_setpoint, stick_velocity, stick_yaw_rate, wrap_pi};
use super::guidance::{GuidanceMode, MissionGuidance};
use super::offboard::OffboardSetpoint;
use super::path_yaw::Steering;
use super::tracking::Reference;
use super::{CommandError, OuterLoop};
use crate::battery::BatteryState;
use crate::failsafe::{FailsafeState, TransitionReason};
use crate::msg::AttitudeSetpoint;
use crate::rc::RcInput;
use crate::supervisor::modes::{FlightContext, FlightMode};
use crate::Vec3;

/// Return ends (Land) once the reference is home and the vehicle within this distance, m.
pub const RETURN_SETTLED_M: f32 = 0.1;
/// … and slower than this, m/s.
pub const RETURN_SETTLED_MPS: f32 = 0.1;
/// The mission trajectory's clock stops while the safety filter takes more than this off the
/// nominal command along the reference's velocity, m/s² (a third of the trajectory's default
/// acceleration limit: a filter that only trims the command lets the clock run).
pub const HELD_BACK_ACCEL: f32 = 1.0;

impl OuterLoop {
    /// The selected flight mode.
    pub fn mode(&self) -> FlightMode {
        self.modes.mode()
    }

    /// Take one RC frame (see [`crate::controller::FlightController::set_rc`]). Returns `true`
    /// when the command for the inner loop changed (publish [`Self::command`]).
    pub fn set_rc(&mut self, rc: &RcInput) -> bool {
        let stage = self.stage;
        let now = rc.t_us;
        let req = self.modes.on_rc(rc);
        self.telemetry.rc_rejected = self.modes.rc_rejected();
        let Some(req) = req else { return false };
        if req.kill {
            if let Some(tr) = self.supervisor.disarm_for(now, TransitionReason::KillSwitch) {
                self.record(tr);
            }
            return self.stage != stage;
        }
        let state = self.supervisor.state();
        if req.arm && state == FailsafeState::Disarmed {
            // Refusals leave the vehicle disarmed (the arm checks' reasons are the command's).
            let _ = self.arm(now);
        }
        if req.disarm && state.motors_enabled() {
            let landed_manual = self.modes.mode() == FlightMode::Manual && rc.throttle <= 0.05;
            if self.guidance.on_ground() || self.supervisor.land_from_ground() || landed_manual {
                let _ = self.disarm(now);
            }
        }
        if let Some(m) = req.mode {
            let disarmed = self.supervisor.state() == FailsafeState::Disarmed;
            if !req.first || disarmed {
                let _ = self.enter_mode(now, m, TransitionReason::ModeSwitch, false);
            }
        }
        self.stage != stage
    }

    /// Take one offboard setpoint; a bad one is rejected and counted.
    pub fn set_offboard(&mut self, sp: &OffboardSetpoint) {
        if !sp.is_valid() {
            self.telemetry.offboard_rejected = self.telemetry.offboard_rejected.saturating_add(1);
            return;
        }
        self.offboard = Some(*sp);
        self.modes.on_offboard(sp.t_us);
    }

    /// Take one battery measurement.
    pub fn set_battery(&mut self, b: &BatteryState) {
        self.modes.on_battery(b);
        self.telemetry.battery = Some(*b);
    }

    /// Select `mode` (MAVLink DO_SET_MODE, the host API). Refused when the mode cannot be
    /// flown now (see the module documentation).
    pub fn set_mode(&mut self, now_us: u64, mode: FlightMode) -> Result<(), CommandError> {
        self.enter_mode(now_us, mode, TransitionReason::ModeCommand, false)
    }

    /// A position to hold or start from: the fresh estimate, else the last reference.
    fn here(&self, now_us: u64) -> (Vec3, bool) {
        match self.inputs.position_estimate(now_us) {
            Some((p, _)) => (p, true),
            None => (self.telemetry.reference.position, false),
        }
    }

    /// Enter `to` for `reason`; `forced` (failsafes) never refuses.
    pub(super) fn enter_mode(
        &mut self,
        now_us: u64,
        to: FlightMode,
        reason: TransitionReason,
        forced: bool,
    ) -> Result<(), CommandError> {
        let from = self.modes.mode();
        if to == from {
            return Ok(());
        }
        let state = self.supervisor.state();
        let armed = state.motors_enabled();
        let (p, fix) = self.here(now_us);
        if !forced {
            let ok = match to {
                FlightMode::Manual | FlightMode::Position => self.modes.rc(now_us).is_some(),
                FlightMode::Offboard => self.modes.offboard_fresh(now_us),
                FlightMode::Return => !armed || fix,
                FlightMode::Land => !armed || matches!(state, FailsafeState::Armed | FailsafeState::Brake),
                FlightMode::Mission | FlightMode::Hold => true,
            };
            if !ok {
                return Err(CommandError::ModeUnavailable);
            }
        }
        if matches!(from, FlightMode::Return | FlightMode::Offboard) {
            // The trajectory they borrowed (MIS_GUIDANCE 1) is given back: hold here.
            self.guidance.release(p);
        }
        if to == FlightMode::Return && armed && !self.guidance.on_ground() {
            if !fix || !self.start_return(now_us, p) {
                // Nothing to fly back along (or no fix): land instead.
                return self.enter_mode(now_us, FlightMode::Land, reason, true);
            }
            self.return_done = false;
        }
        if from == FlightMode::Return {
            self.ret.stop();
        }
        if to == FlightMode::Land && armed {
            // The failsafe machine's Land; `record` sets the mode.
            if let Some(tr) = self.supervisor.land_for(now_us, reason) {
                self.record(tr);
            }
            return Ok(());
        }
        match to {
            FlightMode::Hold => self.hold_point = p,
            FlightMode::Position | FlightMode::Offboard => self.assist.start(p),
            FlightMode::Mission if armed && !self.guidance.on_ground() => {
                // A mission flown again needs its start command: hold here until then.
                self.guidance.hold(p);
            }
            _ => {}
        }
        if let Some(tr) = self.modes.go(to, reason, now_us) {
            self.telemetry.last_mode_change = Some(tr);
            self.telemetry.mode_changes = self.modes.transition_count();
        }
        self.telemetry.flight_mode = self.modes.mode();
        Ok(())
    }

    /// Start flying back from `p`: on the guidance's trajectory with `MIS_GUIDANCE` 1, on the
    /// paper's follower with 0 ([`super::return_path`]). `false` when there is nothing to fly.
    fn start_return(&mut self, now_us: u64, p: Vec3) -> bool {
        if self.params.guidance.mission != MissionGuidance::Trajectory {
            return self.ret.start(now_us, p).is_ok();
        }
        match self.ret.trail_back(p) {
            Ok(trail) => self.guidance.start_return(p, &trail, self.params.modes.return_speed).is_ok(),
            Err(_) => false,
        }
    }

    /// The mode machine's part of a failsafe-state transition (called by `record`).
    pub(super) fn modes_on_transition(&mut self, to: FailsafeState, reason: TransitionReason, t_us: u64) {
        let tr = match to {
            FailsafeState::Land => self.modes.go(FlightMode::Land, reason, t_us),
            FailsafeState::Disarmed | FailsafeState::MotorsOff => {
                self.ret.stop();
                self.modes.reset_flight();
                let base = self.modes.base_mode(t_us);
                let keep = matches!(self.modes.mode(), FlightMode::Manual | FlightMode::Position)
                    || self.modes.mode() == base;
                if keep {
                    None
                } else {
                    self.modes.go(base, reason, t_us)
                }
            }
            FailsafeState::Armed => {
                let home = self.inputs.position_estimate(t_us).map_or(Vec3::zeros(), |(p, _)| p);
                if reason == TransitionReason::ArmCommand {
                    self.ret.reset(home);
                    if matches!(self.modes.mode(), FlightMode::Return | FlightMode::Land) {
                        self.modes.go(FlightMode::Hold, reason, t_us)
                    } else {
                        None
                    }
                } else {
                    None
                }
            }
            FailsafeState::Brake => None,
        };
        if let Some(tr) = tr {
            self.telemetry.last_mode_change = Some(tr);
            self.telemetry.mode_changes = self.modes.transition_count();
        }
        self.telemetry.flight_mode = self.modes.mode();
    }

    /// The per-mode failsafes and the breadcrumbs of one outer step (after the data check).
    pub(super) fn mode_step(&mut self, now_us: u64, fresh: Option<(Vec3, Vec3)>) {
        let state = self.supervisor.state();
        let airborne = state.motors_enabled() && !self.guidance.on_ground();
        if airborne && self.modes.mode() != FlightMode::Return {
            if let Some((p, _)) = fresh {
                self.ret.record(p);
            }
        }
        if self.modes.mode() == FlightMode::Return && self.return_done && state == FailsafeState::Armed {
            let _ = self.enter_mode(now_us, FlightMode::Land, TransitionReason::ReturnDone, true);
        }
        if let Some((to, reason)) = self.modes.check(now_us, FlightContext { airborne }) {
            let _ = self.enter_mode(now_us, to, reason, true);
        }
    }

    /// Leave the ground in a piloted mode: Position with the climb stick up (and a fix),
    /// Manual with the throttle above 0.1.
    fn liftoff(&mut self, now_us: u64) -> bool {
        let Some(rc) = self.modes.rc(now_us).copied() else { return false };
        let (p, fix) = self.here(now_us);
        let go = match self.modes.mode() {
            FlightMode::Position => fix && stick_velocity(self.modes.params(), &rc, 0.0).z < 0.0,
            FlightMode::Manual => rc.throttle > 0.1,
            _ => false,
        };
        if go {
            self.guidance.hold(p);
            self.assist.start(p);
        }
        go
    }

    /// The safety filter held the vehicle back in the last outer step: it took more than
    /// [`HELD_BACK_ACCEL`] off the nominal command along the reference's velocity.
    fn held_back(&self) -> bool {
        let tel = &self.telemetry;
        let v = tel.reference.velocity;
        let speed = v.norm();
        if !tel.filter_active || speed.is_nan() || speed <= 1e-3 {
            return false;
        }
        (tel.u_nominal - tel.u_filtered).dot(&v) / speed > HELD_BACK_ACCEL
    }

    /// The reference of one outer step while Armed, per mode; `None` on the ground and in
    /// Manual (whose setpoint is [`Self::manual_sp`]). `accel` is set for an offboard
    /// acceleration-only setpoint (the nominal command itself).
    pub(super) fn armed_reference(
        &mut self,
        now_us: u64,
        dt: f32,
        fresh: Option<(Vec3, Vec3)>,
        progress: &mut super::waypoint::Progress,
        accel: &mut Option<Vec3>,
    ) -> (GuidanceMode, Option<Reference>) {
        let mode = self.modes.mode();
        let steering = Steering {
            position: fresh.map(|(p, _)| p),
            heading: self.estimate.attitude.yaw,
            dt,
            held_back: self.held_back(),
            speed_limit: self.telemetry.governor.limit,
        };
        if mode == FlightMode::Mission || (self.guidance.on_ground() && !self.liftoff(now_us)) {
            return self.guidance.reference(now_us, &steering, progress);
        }
        let yaw = self.guidance.yaw_ref();
        let p = fresh.map_or(self.telemetry.position, |(p, _)| p);
        match mode {
            FlightMode::Manual => {
                if let Some(rc) = self.modes.rc(now_us).copied() {
                    let y = wrap_pi(yaw + stick_yaw_rate(self.modes.params(), &rc) * dt);
                    self.guidance.set_yaw_ref(y);
                }
                (GuidanceMode::Manual, None)
            }
            FlightMode::Position => {
                // Without RC (lost, before the failsafe acts): centred sticks, hold.
                let (v_sp, yaw_rate) = match self.modes.rc(now_us) {
                    Some(rc) => (
                        stick_velocity(self.modes.params(), rc, yaw),
                        stick_yaw_rate(self.modes.params(), rc),
                    ),
                    None => (Vec3::zeros(), 0.0),
                };
                let y = wrap_pi(yaw + yaw_rate * dt);
                self.guidance.set_yaw_ref(y);
                (GuidanceMode::Assist, Some(self.assist.step(&v_sp, &p, dt, y)))
            }
            FlightMode::Offboard => {
                let sp = self.offboard.unwrap_or_default();
                let y = match (sp.yaw, sp.yaw_rate) {
                    (Some(y), _) => wrap_pi(y),
                    (None, Some(r)) => wrap_pi(yaw + r * dt),
                    (None, None) => yaw,
                };
                self.guidance.set_yaw_ref(y);
                let a_ff = sp.acceleration.unwrap_or_else(Vec3::zeros);
                let on_trajectory = self.params.guidance.mission == MissionGuidance::Trajectory;
                let target = sp
                    .position
                    .filter(|_| on_trajectory && sp.velocity.is_none() && sp.acceleration.is_none());
                let lent = target.and_then(|pos| self.offboard_trajectory(pos, &steering));
                if lent.is_none() {
                    self.guidance.release(p);
                }
                let r = match (lent, sp.position, sp.velocity) {
                    (Some(r), _, _) => Reference { yaw: y, ..r },
                    (None, Some(pos), v) => Reference {
                        position: pos,
                        velocity: v.unwrap_or_else(Vec3::zeros),
                        acceleration: a_ff,
                        yaw: y,
                    },
                    (None, None, Some(v)) => {
                        let mut r = self.assist.step(&v, &p, dt, y);
                        r.acceleration = a_ff;
                        r
                    }
                    (None, None, None) => {
                        *accel = sp.acceleration;
                        self.assist.start(p);
                        Reference { position: p, velocity: Vec3::zeros(), acceleration: a_ff, yaw: y }
                    }
                };
                (GuidanceMode::Offboard, Some(r))
            }
            FlightMode::Return => {
                let mut y = yaw;
                let yaw_params = self.params.guidance.path_yaw;
                let mut prog = *progress;
                let lent = self.guidance.lent_reference(&steering, &mut prog, true).map(|r| (r, prog));
                match lent.or_else(|| self.ret.reference(now_us, &yaw_params, &mut y, &steering)) {
                    Some((r, prog)) => {
                        if lent.is_none() {
                            self.guidance.set_yaw_ref(y);
                        }
                        // Home reached: the reference is there and the vehicle has settled on it.
                        let settled = fresh.is_some_and(|(p, v)| {
                            (p - r.position).norm_squared() < RETURN_SETTLED_M * RETURN_SETTLED_M
                                && v.norm_squared() < RETURN_SETTLED_MPS * RETURN_SETTLED_MPS
                        });
                        self.return_done = prog.done && settled;
                        *progress = prog;
                        (GuidanceMode::Return, Some(r))
                    }
                    None => (GuidanceMode::Hold, Some(self.guidance.hold_ref(self.hold_point))),
                }
            }
            FlightMode::Hold | FlightMode::Land | FlightMode::Mission => {
                (GuidanceMode::Hold, Some(self.guidance.hold_ref(self.hold_point)))
            }
        }
    }

    /// An offboard position-only set-point `pos` on the guidance's trajectory (`MIS_GUIDANCE`
    /// 1): the next reference, `None` when the trajectory refuses the target (then today's
    /// reference, the set-point itself, is flown).
    fn offboard_trajectory(&mut self, pos: Vec3, steering: &Steering) -> Option<Reference> {
        let last = self.telemetry.reference;
        self.guidance.offboard_position(pos, &last).ok()?;
        let mut progress = super::waypoint::Progress::default();
        self.guidance.lent_reference(steering, &mut progress, false)
    }

    /// The Manual setpoint (sticks; centred, mid throttle without RC).
    pub(super) fn manual_sp(&self, now_us: u64) -> AttitudeSetpoint {
        let rc = self.modes.rc(now_us).copied().unwrap_or(RcInput { throttle: 0.5, ..RcInput::default() });
        manual_setpoint(
            self.modes.params(),
            &self.params.thrust,
            self.params.mass,
            &rc,
            self.guidance.yaw_ref(),
        )
    }
}
