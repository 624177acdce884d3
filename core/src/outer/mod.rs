//! The outer loop (default 250 Hz): guidance → PD tracking → safety filter →
//! thrust/attitude map, producing the [`AttitudeCommand`] the inner loop flies.
//!
//! ```text
//!  PositionFix, obstacles ─▶ inputs ─p, ṗ─┐
//!  supervisor (failsafe, brake, land) ────┤
//!  guidance (ground / takeoff / hold / path) ─p_d, ṗ_d, p̈_d─▶ PD (eq. 2) ─u*─▶ CBF filter ─u─▶ thrust map (eq. 4-5) ─▶ AttitudeCommand
//!  StateEstimate (φ̂, θ̂, tilt, bad IMU samples, tilt trip) ◀── inner loop
//! ```
//!
//! Owns [`guidance`] (nominal reference while Armed), [`inputs`] (position fix, obstacle
//! set), [`waypoint`] (the path follower), [`tracking`] (PD tracking, eq. 2), [`thrust`]
//! (acceleration → collective thrust and attitude, eq. 4-5), [`trajectory`] (issue 35, stage in
//! progress: the jerk-limited online trajectory along a blended path; [`guidance`] flies
//! missions, Return and offboard position set-points on it when `MIS_GUIDANCE` = 1), and [`OuterLoop`], which runs
//! them with the [`crate::supervisor::Supervisor`] and the [`crate::safety`] filter. It
//! reads the inner loop only through the [`StateEstimate`] message
//! ([`OuterLoop::on_estimate`]) and hands it only the [`AttitudeCommand`] and
//! [`crate::msg::EstimatorAid`] messages.
//!
//! May import: the crate root foundation ([`crate::frame`], [`crate::fmath`],
//! [`crate::airframe`], [`crate::Vec3`]), [`crate::msg`], [`crate::safety`] (with
//! [`crate::obstacle_set`] and [`crate::plant_aware`], the filter's set policy and plant-aware
//! wrapping) and [`crate::supervisor`]. Never [`crate::inner`], [`crate::config`] or the facade.

pub mod assist;
mod flight_modes;
pub mod guidance;
pub mod inputs;
pub mod offboard;
pub mod path_stream;
pub mod path_yaw;
pub mod reset_shift;
pub mod return_path;
pub mod thrust;
pub mod tracking;
pub mod trajectory;
pub mod waypoint;

use crate::cbf::{CbfError, CbfParams, FilterDiagnostics, FilterVariant, SafetyFilter};
use crate::failsafe::ArmRefusal;
use crate::failsafe::{DataHealth, FailsafeState, Transition};
use crate::fmath::{minf, norm3};
use crate::governor::{self, GovernorParams, GovernorTelemetry};
use crate::msg::{AttitudeCommand, AttitudeSetpoint, EstimatorAid, MotorStage, PositionFix, StateEstimate};
use crate::obstacle::ObstaclePoint;
use crate::obstacle_set::{Ranking, SetReport};
use crate::plant_aware::stall::STALL_TRACKING_ERROR_M;
use crate::plant_aware::{PlantAware, PlantAwareParams, PlantAwareTelemetry, StepInput};
use crate::supervisor::modes::{FlightMode, ModeParams, ModeTransition, Modes};
use crate::supervisor::{EntryContext, Supervisor, SupervisorParams};
use crate::Vec3;
use assist::VelocityRef;
use guidance::{Guidance, GuidanceMode, GuidanceParams, MissionGuidance};
use inputs::{InputParams, Inputs};
use offboard::OffboardSetpoint;
use return_path::ReturnPath;
use thrust::{map_acceleration, ThrustParams};
use tracking::{PdTracker, Reference, TrackingParams};
use waypoint::{PathError, Progress, WaypointParams};

/// Why a command was refused (the controller state is unchanged).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandError {
    /// Arming refused.
    Arm(ArmRefusal),
    /// The command needs the Armed state (nominal operation).
    NotArmed,
    /// Already disarmed.
    AlreadyDisarmed,
    /// Takeoff height not finite or outside (0, takeoff_height_max].
    BadHeight,
    /// Target position not finite.
    BadTarget,
    /// Mission needs a flying vehicle (take off first).
    NotFlying,
    /// Path rejected.
    Path(PathError),
    /// No fresh position fix.
    NoPosition,
    /// The flight mode cannot be flown now (Manual/Position without RC, Offboard without a
    /// fresh setpoint, Return without a position fix, Land while not flying).
    ModeUnavailable,
}

/// The outer loop's parameters (a part of [`crate::controller::ControllerParams`], see
/// `ControllerParams::outer_params`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OuterParams {
    /// Nominal rate, Hz (the step's `dt` when there is no previous step; `dt` is capped at
    /// 4 nominal periods).
    pub rate_hz: f32,
    /// PD tracking.
    pub tracking: TrackingParams,
    /// Safety filter (for every variant but `Paper` with the sample time raised to the
    /// outer period).
    pub cbf: CbfParams,
    /// Filter law.
    pub filter_variant: FilterVariant,
    /// Plant-aware wrapping of the filter (every variant but `Paper`; [`crate::plant_aware`]).
    pub plant_aware: PlantAwareParams,
    /// Actuation-lag time constant derived from the attitude gains, s ([`crate::plant_aware::lag_time_constant`]).
    pub lag_tau: f32,
    /// Thrust/attitude map.
    pub thrust: ThrustParams,
    /// Vehicle mass, kg (the airframe's).
    pub mass: f32,
    /// Guidance.
    pub guidance: GuidanceParams,
    /// Path follower.
    pub waypoint: WaypointParams,
    /// Inputs.
    pub inputs: InputParams,
    /// Supervisor.
    pub supervisor: SupervisorParams,
    /// Flight modes (issue 21).
    pub modes: ModeParams,
    /// Speed governor (issue 36).
    pub governor: GovernorParams,
    /// The braking the governor counts on.
    pub governor_vehicle: governor::Vehicle,
}

/// The outer loop's part of the telemetry (updated by every outer step and command).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OuterTelemetry {
    /// Time of the last outer step, µs.
    pub t_us: u64,
    /// Failsafe state.
    pub state: FailsafeState,
    /// Last failsafe transition.
    pub last_transition: Option<Transition>,
    /// Number of failsafe transitions.
    pub transitions: u32,
    /// Guidance in use at the last outer step.
    pub mode: GuidanceMode,
    /// Reference `p_d`, `ṗ_d`, `p̈_d` (NED) and yaw.
    pub reference: Reference,
    /// Progress along the path (when flying the mission).
    pub progress: Progress,
    /// Position used by the outer loop (fix extrapolated), NED m.
    pub position: Vec3,
    /// Velocity used by the outer loop, NED m/s.
    pub velocity: Vec3,
    /// Nominal acceleration `u*` (PD output), NED m/s².
    pub u_nominal: Vec3,
    /// Filtered acceleration `u` (CBF output), NED m/s².
    pub u_filtered: Vec3,
    /// Attitude/thrust setpoint for the inner loop.
    pub attitude_sp: AttitudeSetpoint,
    /// Safety-filter diagnostics of the last outer step.
    pub filter: FilterDiagnostics,
    /// Age of the last valid position fix at the last outer step, µs.
    pub position_age_us: Option<u64>,
    /// Age of the last obstacle update at the last outer step, µs.
    pub obstacle_age_us: Option<u64>,
    /// Obstacle points in the set.
    pub obstacle_count: u8,
    /// Obstacle points dropped (set full) or rejected (non-finite) in the last update.
    pub obstacles_dropped: u8,
    /// What the last obstacle update kept and dropped ([`crate::obstacle_set`]).
    pub obstacle_set: SetReport,
    /// Plant-aware wrapping of the last outer step (disturbance estimate, deadlock).
    pub plant_aware: PlantAwareTelemetry,
    /// Inputs rejected as NaN/Inf since start (fixes, obstacle points, IMU samples).
    pub non_finite_inputs: u32,
    /// Outer steps run.
    pub count: u32,
    /// Selected flight mode (issue 21).
    pub flight_mode: FlightMode,
    /// Last flight-mode change.
    pub last_mode_change: Option<ModeTransition>,
    /// Flight-mode changes so far.
    pub mode_changes: u32,
    /// The safety filter changed the nominal command in the last outer step (always `false`
    /// in Manual, which bypasses it).
    pub filter_active: bool,
    /// Outer steps with the filter active, per flight mode (index `FlightMode as usize`).
    pub filter_interventions: [u32; FlightMode::COUNT],
    /// RC frames rejected (NaN/Inf or out-of-range sticks) since start.
    pub rc_rejected: u32,
    /// Offboard setpoints rejected (NaN/Inf, out of range, empty) since start.
    pub offboard_rejected: u32,
    /// The last battery measurement taken ([`OuterLoop::set_battery`]; `None` before the
    /// first): what a ground station's BATTERY_STATUS / SYS_STATUS report.
    pub battery: Option<crate::battery::BatteryState>,
    /// The speed governor at the last outer step ([`crate::governor`]).
    pub governor: GovernorTelemetry,
}

/// Why the outer loop could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OuterError {
    /// Filter parameters.
    Cbf(CbfError),
    /// Waypoint parameters.
    Waypoint(PathError),
}

/// The outer loop with its supervisor (see the module documentation).
#[derive(Clone, Debug)]
pub struct OuterLoop {
    params: OuterParams,
    inputs: Inputs,
    guidance: Guidance,
    supervisor: Supervisor,
    tracker: PdTracker,
    filter: SafetyFilter,
    /// `Some` for every variant but `Paper`.
    plant_aware: Option<PlantAware>,
    stage: MotorStage,
    sp: AttitudeSetpoint,
    last_us: Option<u64>,
    estimate: StateEstimate,
    seen_rejected: u32,
    telemetry: OuterTelemetry,
    modes: Modes,
    assist: VelocityRef,
    hold_point: Vec3,
    offboard: Option<OffboardSetpoint>,
    ret: ReturnPath,
    return_done: bool,
}

fn age(now: u64, t: u64) -> u64 {
    now.saturating_sub(t)
}

impl OuterLoop {
    /// A disarmed outer loop; `estimate` is the inner loop's initial state estimate.
    /// `params` must come from validated parameters
    /// ([`crate::controller::ControllerParams::validate`]).
    pub fn new(params: OuterParams, estimate: StateEstimate) -> Result<Self, OuterError> {
        let filter = SafetyFilter::new(params.cbf, params.filter_variant).map_err(OuterError::Cbf)?;
        let (_, diag0) = filter.apply(&Vec3::zeros(), &Vec3::zeros(), &Vec3::zeros(), &[]);
        let telemetry = OuterTelemetry {
            t_us: 0,
            state: FailsafeState::Disarmed,
            last_transition: None,
            transitions: 0,
            mode: GuidanceMode::Off,
            reference: Reference::default(),
            progress: Progress::default(),
            position: Vec3::zeros(),
            velocity: Vec3::zeros(),
            u_nominal: Vec3::zeros(),
            u_filtered: Vec3::zeros(),
            attitude_sp: AttitudeSetpoint::default(),
            filter: diag0,
            position_age_us: None,
            obstacle_age_us: None,
            obstacle_count: 0,
            obstacles_dropped: 0,
            obstacle_set: SetReport::default(),
            plant_aware: PlantAwareTelemetry::default(),
            non_finite_inputs: 0,
            count: 0,
            flight_mode: FlightMode::default(),
            last_mode_change: None,
            mode_changes: 0,
            filter_active: false,
            filter_interventions: [0; FlightMode::COUNT],
            rc_rejected: 0,
            offboard_rejected: 0,
            battery: None,
            governor: GovernorTelemetry::default(),
        };
        let plant_aware = (params.filter_variant != FilterVariant::Paper).then(|| {
            PlantAware::new(params.plant_aware, params.lag_tau)
                .with_limits(thrust::accel_limits(&params.thrust, params.mass))
        });
        Ok(OuterLoop {
            inputs: Inputs::new(params.inputs),
            guidance: Guidance::new(params.guidance, params.waypoint).map_err(OuterError::Waypoint)?,
            supervisor: Supervisor::new(params.supervisor),
            tracker: PdTracker::new(params.tracking),
            filter,
            plant_aware,
            stage: MotorStage::Off,
            sp: AttitudeSetpoint::default(),
            last_us: None,
            seen_rejected: estimate.rejected_samples,
            estimate,
            telemetry,
            modes: Modes::new(params.modes),
            assist: VelocityRef::default(),
            hold_point: Vec3::zeros(),
            offboard: None,
            ret: ReturnPath::new(params.modes.crumb_spacing, params.modes.return_speed)
                .map_err(OuterError::Waypoint)?,
            return_done: false,
            params,
        })
    }

    /// Parameters in use.
    pub fn params(&self) -> &OuterParams {
        &self.params
    }

    /// The telemetry of the outer loop.
    pub fn telemetry(&self) -> &OuterTelemetry {
        &self.telemetry
    }

    /// Failsafe state.
    pub fn state(&self) -> FailsafeState {
        self.supervisor.state()
    }

    /// Obstacle points currently used by the filter.
    pub fn obstacles(&self) -> &[ObstaclePoint] {
        self.inputs.obstacles()
    }

    /// The message for the inner loop: publish it after every [`Self::step`] and every
    /// command (and after an [`Self::on_estimate`] that returns `true`).
    pub fn command(&self) -> AttitudeCommand {
        AttitudeCommand { stage: self.stage, setpoint: self.sp, accel_ned: self.telemetry.u_filtered }
    }

    /// The estimator aid for the inner loop: publish it after every [`Self::update_position`].
    pub fn aid(&self) -> EstimatorAid {
        self.inputs.aid()
    }

    /// Latest step time seen, µs: this loop's or the inner loop's (from the estimate).
    fn clock_us(&self) -> Option<u64> {
        match (self.estimate.t_us, self.last_us) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        }
    }

    /// Take the inner loop's latest state estimate: new rejected IMU samples count as bad
    /// inputs, a tilt trip cuts the motors (MotorsOff). Returns `true` when the command for
    /// the inner loop changed (publish [`Self::command`]).
    pub fn on_estimate(&mut self, est: &StateEstimate) -> bool {
        let new_rejected = est.rejected_samples.wrapping_sub(self.seen_rejected);
        self.seen_rejected = est.rejected_samples;
        self.supervisor.note_faults(new_rejected);
        self.telemetry.non_finite_inputs = self.supervisor.non_finite_inputs();
        self.estimate = *est;
        let stage = self.stage;
        if let Some(trip) = est.tilt_trip {
            if let Some(tr) = self.supervisor.check_tilt(trip.t_us, trip.tilt) {
                self.record(tr);
            }
        }
        self.stage != stage
    }

    fn note_fault(&mut self) {
        self.supervisor.note_faults(1);
        self.telemetry.non_finite_inputs = self.supervisor.non_finite_inputs();
    }

    fn record(&mut self, tr: Transition) {
        let tel = &mut self.telemetry;
        tel.last_transition = Some(tr);
        tel.transitions = self.supervisor.transition_count();
        tel.state = tr.to;
        if let FailsafeState::Disarmed | FailsafeState::MotorsOff = tr.to {
            self.stage = MotorStage::Off;
            self.guidance.ground();
            self.tracker.reset();
        }
        let at = EntryContext {
            position: self.inputs.position_estimate(tr.t_us).map(|(p, _)| p),
            last_fix: self.inputs.last_fix_position(),
            on_ground: self.guidance.on_ground(),
        };
        self.supervisor.on_enter(tr, &at);
        self.modes_on_transition(tr.to, tr.reason, tr.t_us);
    }

    fn health(&self, now_us: u64) -> DataHealth {
        let (position_age_us, obstacle_age_us) = self.inputs.ages(now_us);
        DataHealth {
            position_age_us,
            obstacle_age_us,
            non_finite: self.supervisor.fault_pending(),
            obstacle_in_hull: None,
        }
    }

    /// Store an external position fix (see [`crate::controller::FlightController::update_position`]).
    pub fn update_position(&mut self, fix: PositionFix) {
        if !self.inputs.update_position(fix, self.clock_us()) {
            self.note_fault();
        }
    }

    /// The navigation filter reset its position by `delta` (see
    /// [`crate::controller::FlightController::position_reset`]).
    pub fn position_reset(&mut self, delta: Vec3) {
        if let Some(now) = self.clock_us() {
            self.guidance.shift_reference(now, delta);
        }
    }

    /// The vertical error bound of the position (see
    /// [`crate::controller::FlightController::set_boundary_margin`]).
    pub fn set_boundary_margin(&mut self, m: f32) {
        if let Some(pa) = self.plant_aware.as_mut() {
            pa.set_boundary_margin(m);
        }
    }

    /// Replace the obstacle set (see [`crate::controller::FlightController::update_obstacles`]).
    pub fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]) {
        let variant = self.filter.variant;
        let ranking = if variant.is_multi() {
            Ranking::Critical { mu: self.filter.params.mu, relative: variant.uses_relative_velocity() }
        } else {
            Ranking::Nearest
        };
        let delta1 = self.filter.params.delta1;
        let intake = self.inputs.update_obstacles(now_us, obstacles, self.clock_us(), ranking, delta1);
        if intake.bad_inputs {
            self.note_fault();
        }
        if let Some(dropped) = intake.dropped {
            self.telemetry.obstacle_count = self.inputs.obstacles().len() as u8;
            self.telemetry.obstacles_dropped = dropped;
        }
        if let Some(rep) = intake.report {
            self.telemetry.obstacle_set = rep;
        }
    }

    /// Replace the path (see [`crate::controller::FlightController::set_path`]). A mission
    /// being flown restarts from the current reference (its motion carried over when it can),
    /// or — when the fresh position estimate is further than the tracking-error bound
    /// (`TRJ_ERR_MAX`) from that reference (a vehicle held back by the filter while the
    /// reference braked ahead of it, possibly past the obstacle) — at rest where the vehicle
    /// is: a replanned detour starts where the replanner planned it from, and its first leg
    /// never runs from a stale reference back through what stopped the vehicle.
    pub fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), CommandError> {
        let now = self.last_us.unwrap_or(0);
        let reference = self.telemetry.reference.position;
        let bound = self.guidance.params().trajectory.tracking_error_bound;
        match self.inputs.position_estimate(now) {
            Some((p, _)) if norm3(&(p - reference)) > bound => {
                self.guidance.set_path_from(waypoints_ned, now, p, false)
            }
            _ => self.guidance.set_path_from(waypoints_ned, now, reference, true),
        }
    }

    /// The stored path's waypoints (NED; the on-board replanner's input, `crate::replan`).
    pub fn path(&self) -> &[Vec3] {
        self.guidance.waypoints()
    }

    /// Drop the stored path (MAVLink MISSION_CLEAR_ALL); a mission being flown becomes a hold
    /// of the current reference position, a later mission start is refused until a new path.
    pub fn clear_path(&mut self) {
        self.guidance.clear_path(self.telemetry.reference.position);
    }

    /// The arm command's checks at `now_us` without arming (a ground station's pre-arm check):
    /// `Ok` when [`OuterLoop::arm`] would arm. O(obstacles).
    pub fn arm_check(&self, now_us: u64) -> Result<(), CommandError> {
        let (health, _) = self.arm_health(now_us);
        let est = self.estimate;
        self.supervisor.arm_check(&health, est.initialised, est.tilt).map_err(CommandError::Arm)
    }

    /// The data health the arm checks use (with the obstacle-in-hull check) and the position.
    fn arm_health(&self, now_us: u64) -> (DataHealth, Option<Vec3>) {
        let mut health = self.health(now_us);
        let position = self.inputs.position_estimate(now_us).map(|(p, _)| p);
        health.obstacle_in_hull = position.and_then(|p| self.inputs.obstacle_in_hull(&p));
        (health, position)
    }

    /// `true` when the last position fix is fresh at `now_us` (the failsafe's position timeout).
    pub fn position_fresh(&self, now_us: u64) -> bool {
        self.supervisor.position_fresh(self.inputs.ages(now_us).0)
    }

    /// Arm (see [`crate::controller::FlightController::arm`]).
    pub fn arm(&mut self, now_us: u64) -> Result<(), CommandError> {
        let (health, position) = self.arm_health(now_us);
        let est = self.estimate;
        let tr =
            self.supervisor.arm(now_us, &health, est.initialised, est.tilt).map_err(CommandError::Arm)?;
        self.guidance.arm(position.unwrap_or_else(Vec3::zeros), est.attitude.yaw);
        self.stage = MotorStage::Idle;
        self.tracker.reset();
        self.record(tr);
        Ok(())
    }

    /// Disarm: motors off at once, from any state.
    pub fn disarm(&mut self, now_us: u64) -> Result<(), CommandError> {
        let tr = self.supervisor.disarm(now_us).ok_or(CommandError::AlreadyDisarmed)?;
        self.record(tr);
        Ok(())
    }

    fn require_armed(&self) -> Result<(), CommandError> {
        if self.supervisor.state() == FailsafeState::Armed {
            Ok(())
        } else {
            Err(CommandError::NotArmed)
        }
    }

    /// Take off (see [`crate::controller::FlightController::takeoff`]).
    pub fn takeoff(&mut self, now_us: u64, height_m: f32) -> Result<(), CommandError> {
        self.require_armed()?;
        let position = self.inputs.position_estimate(now_us).map(|(p, _)| p);
        self.guidance.takeoff(now_us, height_m, position, self.telemetry.reference.position)?;
        self.mission_mode(now_us);
        Ok(())
    }

    /// The mission commands (takeoff, hold, mission start) fly in Mission mode.
    fn mission_mode(&mut self, now_us: u64) {
        if let Some(tr) =
            self.modes.go(FlightMode::Mission, crate::failsafe::TransitionReason::ModeCommand, now_us)
        {
            self.ret.stop();
            self.telemetry.last_mode_change = Some(tr);
            self.telemetry.mode_changes = self.modes.transition_count();
            self.telemetry.flight_mode = FlightMode::Mission;
        }
    }

    /// Hold `target` (see [`crate::controller::FlightController::hold_position`]).
    pub fn hold_position(&mut self, now_us: u64, target: Vec3) -> Result<(), CommandError> {
        self.require_armed()?;
        Guidance::check_target(&target)?;
        self.inputs.position_estimate(now_us).ok_or(CommandError::NoPosition)?;
        self.guidance.hold(target);
        self.mission_mode(now_us);
        Ok(())
    }

    /// In-flight tuning (a ground station's PARAM_SET while armed, applied between two outer
    /// steps): takes `p`'s PD gains (`tracking`), filter parameters (`cbf`, the same law) and
    /// the path speed (`waypoint.cruise_speed`, from the next path start); everything else of
    /// `p` is ignored (set-up and the stateful parts' parameters change only disarmed, by a new
    /// loop). Refused (nothing changed) when the filter parameters or the speed are invalid.
    /// The integrator and every state are kept.
    pub fn retune(&mut self, p: &OuterParams) -> Result<(), OuterError> {
        let filter = SafetyFilter::new(p.cbf, self.params.filter_variant).map_err(OuterError::Cbf)?;
        self.guidance
            .set_cruise_speed(p.waypoint.cruise_speed)
            .map_err(|_| OuterError::Waypoint(PathError::BadParams))?;
        self.filter = filter;
        self.tracker.params = p.tracking;
        self.params.tracking = p.tracking;
        self.params.cbf = p.cbf;
        self.params.waypoint.cruise_speed = p.waypoint.cruise_speed;
        Ok(())
    }

    /// The mission's cruise speed from the next path start on (m/s; a mission item's
    /// DO_CHANGE_SPEED): [`Guidance::set_cruise_speed`].
    pub fn set_mission_speed(&mut self, speed: f32) -> Result<(), CommandError> {
        self.guidance.set_cruise_speed(speed)
    }

    /// Face `yaw` (rad, NED heading; a mission item's CONDITION_YAW): the yaw reference of
    /// every guidance mode from now on. Needs Armed; a non-finite yaw is refused.
    pub fn set_yaw(&mut self, yaw: f32) -> Result<(), CommandError> {
        self.require_armed()?;
        if !yaw.is_finite() {
            return Err(CommandError::BadTarget);
        }
        self.guidance.set_yaw_ref(crate::frame::wrap_pi(yaw));
        Ok(())
    }

    /// Fly the stored path (see [`crate::controller::FlightController::start_mission`]).
    pub fn start_mission(&mut self, now_us: u64) -> Result<(), CommandError> {
        self.require_armed()?;
        self.guidance.start_mission(now_us, self.telemetry.reference.position)?;
        self.mission_mode(now_us);
        self.telemetry.plant_aware.deadlock = false;
        if let Some(pa) = self.plant_aware.as_mut() {
            pa.reset_stall();
        }
        Ok(())
    }

    /// Land (from Armed or Brake).
    pub fn land(&mut self, now_us: u64) -> Result<(), CommandError> {
        let tr = self.supervisor.land(now_us).ok_or(CommandError::NotArmed)?;
        self.record(tr);
        Ok(())
    }

    /// One outer step at `now_us`: data check, reference, PD tracking, CBF filter,
    /// thrust/attitude map. Bounded; never panics. Returns the command for the inner loop.
    pub fn step(&mut self, now_us: u64) -> AttitudeCommand {
        let nominal_dt = 1.0 / self.params.rate_hz;
        let dt = match self.last_us {
            Some(t) if now_us >= t => minf(age(now_us, t) as f32 * 1e-6, 4.0 * nominal_dt),
            Some(_) => 0.0,
            None => nominal_dt,
        };
        self.last_us = Some(now_us);
        self.telemetry.t_us = now_us;
        self.telemetry.count = self.telemetry.count.wrapping_add(1);

        let fresh = self.inputs.position_estimate(now_us);
        self.supervisor.track_fix(now_us, fresh);
        let health = self.health(now_us);
        self.telemetry.position_age_us = health.position_age_us;
        self.telemetry.obstacle_age_us = health.obstacle_age_us;
        if let Some(tr) = self.supervisor.check_data(now_us, &health, fresh) {
            self.record(tr);
        }
        self.mode_step(now_us, fresh);
        let state = self.supervisor.state();
        self.telemetry.state = state;

        // Reference and output stage.
        let mut progress = self.telemetry.progress;
        let mut accel_sp = None;
        let (mode, reference) = match state {
            FailsafeState::Disarmed | FailsafeState::MotorsOff => (GuidanceMode::Off, None),
            FailsafeState::Armed => self.armed_reference(now_us, dt, fresh, &mut progress, &mut accel_sp),
            FailsafeState::Brake if self.guidance.on_ground() => (GuidanceMode::Ground, None),
            FailsafeState::Brake => {
                (GuidanceMode::Brake, Some(self.guidance.hold_ref(self.supervisor.brake_point())))
            }
            FailsafeState::Land if self.supervisor.land_from_ground() => (GuidanceMode::Ground, None),
            FailsafeState::Land => {
                let target = self.supervisor.land_target(dt, fresh);
                let mut r = self.guidance.hold_ref(target);
                r.velocity = Vec3::new(0.0, 0.0, self.supervisor.params().landing.land_speed);
                (GuidanceMode::Land, Some(r))
            }
        };
        self.telemetry.progress = progress;
        self.stage = match mode {
            GuidanceMode::Off => MotorStage::Off,
            GuidanceMode::Ground => MotorStage::Idle,
            _ => MotorStage::Fly,
        };
        self.telemetry.filter_active = false;
        if mode == GuidanceMode::Manual {
            // The safety pilot's mode: sticks straight to the inner loop, no filter.
            self.sp = self.manual_sp(now_us);
            self.tracker.reset();
            if let Some(pa) = self.plant_aware.as_mut() {
                pa.reset();
            }
            let tel = &mut self.telemetry;
            tel.mode = mode;
            tel.attitude_sp = self.sp;
            tel.u_nominal = Vec3::zeros();
            tel.u_filtered = Vec3::zeros();
            if let Some((p, v)) = fresh {
                tel.position = p;
                tel.velocity = v;
            }
            return self.command();
        }
        let Some(reference) = reference else {
            self.telemetry.mode = mode;
            // Disarmed or on the ground the estimate is still reported (a ground station shows
            // where the vehicle stands from power-on, as PX4 does, not the origin until arming).
            if let Some((p, v)) = fresh {
                self.telemetry.position = p;
                self.telemetry.velocity = v;
            }
            self.tracker.reset();
            if let Some(pa) = self.plant_aware.as_mut() {
                pa.reset();
            }
            return self.command();
        };
        self.telemetry.reference = reference;
        let att = self.estimate.attitude;
        let yaw_ref = self.guidance.yaw_ref();
        match fresh {
            Some((p, v)) => {
                // The tracking cascade on a trajectory: a mission's, or the one lent to Return or
                // Offboard (its cruise speed and end).
                let cascade = if self.guidance.flying_trajectory() {
                    Some((self.guidance.mission_speed(), self.telemetry.progress.done))
                } else if matches!(mode, GuidanceMode::Return | GuidanceMode::Offboard) {
                    self.guidance.lent_tracking()
                } else {
                    None
                };
                let mut u_pd = match cascade {
                    Some((speed, ended)) => {
                        self.tracker.update_trajectory(&reference, &p, &v, dt, speed, ended)
                    }
                    None => self.tracker.update(&reference, &p, &v, dt),
                };
                if let Some(a) = accel_sp {
                    // Offboard acceleration setpoint: it is the nominal command.
                    u_pd = a;
                }
                // Speed governor: what can stop inside observed space (every mode but Manual;
                // not under the paper's guidance, `MIS_GUIDANCE` 0, which flies the paper's
                // method unchanged: docs/filter.md § 17).
                let age = self.telemetry.obstacle_age_us.map_or(0.0, |a| a as f32 * 1e-6);
                let paper = self.params.guidance.mission == MissionGuidance::Paper;
                let gov_params =
                    GovernorParams { enable: self.params.governor.enable && !paper, ..self.params.governor };
                let (u_pd, gov) = governor::govern(
                    &gov_params,
                    &self.params.governor_vehicle,
                    &p,
                    &v,
                    &u_pd,
                    self.inputs.obstacles(),
                    age,
                );
                self.telemetry.governor = gov;
                let (u_star, u, diag) = match self.plant_aware.as_mut() {
                    None => {
                        let (u, diag) = self.filter.apply(&p, &v, &u_pd, self.inputs.obstacles());
                        (u_pd, u, diag)
                    }
                    Some(pa) => {
                        // Stall armed: flying the mission and held away from the reference
                        // (the reference may have reached the goal; the vehicle has not).
                        let lag = (p - reference.position).norm_squared();
                        let input = StepInput {
                            now_us,
                            dt,
                            p,
                            v,
                            u_pd,
                            obstacles: self.inputs.obstacles(),
                            seen_from: self.inputs.obstacles_seen_from(),
                            boundaries: matches!(
                                mode,
                                GuidanceMode::Mission
                                    | GuidanceMode::Hold
                                    | GuidanceMode::Brake
                                    | GuidanceMode::Assist
                                    | GuidanceMode::Offboard
                                    | GuidanceMode::Return
                            ),
                            mission_running: mode == GuidanceMode::Mission
                                && lag > STALL_TRACKING_ERROR_M * STALL_TRACKING_ERROR_M,
                        };
                        let (u_star, u, diag, mut rt) = pa.apply(&self.filter, &input);
                        // Deadlock: latched until the next mission start; the vehicle holds
                        // where it stalled (docs/filter.md §11).
                        if rt.deadlock && !self.telemetry.plant_aware.deadlock {
                            self.guidance.hold(p);
                        }
                        rt.deadlock |= self.telemetry.plant_aware.deadlock;
                        self.telemetry.plant_aware = rt;
                        (u_star, u, diag)
                    }
                };
                self.sp =
                    map_acceleration(&self.params.thrust, self.params.mass, &u, yaw_ref, att.roll, att.pitch);
                let tel = &mut self.telemetry;
                tel.mode = mode;
                tel.position = p;
                tel.velocity = v;
                tel.u_nominal = u_star;
                tel.u_filtered = u;
                tel.filter = diag;
                tel.filter_active = (u - u_star).norm_squared() > 1e-12;
                if tel.filter_active {
                    let i = tel.flight_mode as usize;
                    if let Some(c) = tel.filter_interventions.get_mut(i) {
                        *c = c.saturating_add(1);
                    }
                }
            }
            None => {
                let u = self.supervisor.blind_accel(now_us);
                self.tracker.reset();
                if let Some(pa) = self.plant_aware.as_mut() {
                    pa.open_loop(&u, dt);
                }
                self.sp =
                    map_acceleration(&self.params.thrust, self.params.mass, &u, yaw_ref, att.roll, att.pitch);
                let tel = &mut self.telemetry;
                tel.mode = GuidanceMode::NoFix;
                tel.u_nominal = u;
                tel.u_filtered = u;
            }
        }
        self.telemetry.attitude_sp = self.sp;
        self.command()
    }
}
