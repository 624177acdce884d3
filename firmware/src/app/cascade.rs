//! The real flight-control cascade, as two stages that exchange messages through
//! [`Mailboxes`] (see [`crate::app::mailbox`]):
//!
//! - [`OuterStage`]: `parapet_core::outer::OuterLoop` (guidance, PD tracking, CBF filter,
//!   thrust/attitude map, supervisor) plus the parameter set a ground station edits and the
//!   navigation filter ([`crate::app::navigation`]: predicted with the inner stage's samples,
//!   its estimate the outer loop's fix before each step). It takes everything the link
//!   delivers (fixes, obstacles, path, commands, parameters) through [`OuterPort`], its
//!   [`Autopilot`] view, and publishes attitude commands, the estimator aid and the telemetry
//!   snapshot.
//! - [`InnerStage`]: `parapet_core::inner::InnerLoop` (estimator, attitude and rate control,
//!   mixer). Each step takes the queued commands, the latest aid and a new parameter set if
//!   any, runs, and publishes its state estimate and the IMU sample for the navigation filter.
//!
//! On the board each stage is owned by its own task (`src/bin/fc/mod.rs`). [`Cascade`] owns both
//! stages and their mailboxes and runs them in one context in the order of
//! `parapet_core::controller::FlightController` (inner step, estimate to the outer loop, outer
//! step): the PIL application and the host tests use it.
//!
//! Parameters (see `crate::link::params`): a PARAM_SET is checked against that parameter's
//! range only and written to the stored set, which PARAM_VALUE reports. The loops are
//! rebuilt from the stored set whenever the set is consistent ([`ControllerParams::validate`]:
//! δ1 > δ, m·g < THR_MAX ≤ 4·VEH_ROTOR_TMAX) — the outer loop in the outer task, the inner loop
//! by the inner task from the parameters it is sent, never with interrupts masked; while it is
//! not consistent, the loops keep the last consistent set and arming is refused
//! (MAV_RESULT_TEMPORARILY_REJECTED), so no order of PARAM_SETs is ever needed.
//!
//! May import: `parapet_core`, [`crate::app::autopilot`], [`crate::app::mailbox`],
//! [`crate::app::replanner`], [`crate::app::navigation`].

use embassy_sync::blocking_mutex::raw::{CriticalSectionRawMutex, RawMutex};
use parapet_core::battery::{BatteryParams, BatteryState};
use parapet_core::controller::{CommandError, ControllerParams, FlightController, GuidanceMode, ParamError};
use parapet_core::failsafe::{FailsafeState, TransitionReason};
use parapet_core::inner::InnerLoop;
use parapet_core::msg::{AttitudeCommand, MotorStage, StateEstimate};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::outer::{OuterLoop, OuterTelemetry};
use parapet_core::params;
use parapet_core::rc::map::RcParams;
use parapet_core::rc::RcInput;
use parapet_core::waypoint::PathError;
use parapet_core::wire::codes;
use parapet_core::Vec3;

use crate::app::autopilot::{
    Autopilot, CommandRejected, ControlSteps, Failsafe, FixKind, FlightPhase, ImuSample, MotorCommand,
    OffboardSetpoint, ParamRejected, PathRejected, PositionFix, RcReport, SetpointReport, SourceNoise,
    TelemetrySnapshot, VehicleCommand,
};
use crate::app::mailbox::Mailboxes;
use crate::app::navigation::{NavSample, Navigation, NAV_SAMPLE_DEPTH};
use crate::app::replanner::ReplanOuter;
use parapet_core::nav::bound::ErrorBound;

/// Takeoff height used when NAV_TAKEOFF gives none, m (capped by the cascade's limit).
pub const DEFAULT_TAKEOFF_HEIGHT_M: f32 = 1.0;

fn rejected(e: CommandError) -> CommandRejected {
    match e {
        CommandError::BadHeight | CommandError::BadTarget | CommandError::Path(_) => CommandRejected::Invalid,
        CommandError::Arm(_)
        | CommandError::NotArmed
        | CommandError::AlreadyDisarmed
        | CommandError::NotFlying
        | CommandError::NoPosition
        | CommandError::ModeUnavailable => CommandRejected::NotNow,
    }
}

/// The telemetry snapshot of the outer loop's record and the inner loop's latest estimate.
pub fn snapshot(t: &OuterTelemetry, est: &StateEstimate) -> TelemetrySnapshot {
    let commanded_land = t.last_transition.is_some_and(|tr| tr.reason == TransitionReason::LandCommand);
    let failsafe = match t.state {
        FailsafeState::Brake => Some(codes::failsafe::BRAKE),
        FailsafeState::Land if !commanded_land => Some(codes::failsafe::LAND),
        FailsafeState::MotorsOff => Some(codes::failsafe::MOTORS_OFF),
        _ => None,
    }
    .map(|code| Failsafe { code, reason: t.last_transition.map_or("unknown", |tr| tr.reason.as_str()) });
    let phase = match (t.state, t.mode) {
        (FailsafeState::Disarmed | FailsafeState::MotorsOff, _) => FlightPhase::Disarmed,
        (FailsafeState::Brake, _) => FlightPhase::Failsafe,
        (FailsafeState::Land, _) => FlightPhase::Landing,
        (FailsafeState::Armed, GuidanceMode::Takeoff) => FlightPhase::Takeoff,
        (FailsafeState::Armed, GuidanceMode::Mission) => FlightPhase::Mission,
        (FailsafeState::Armed, GuidanceMode::Hold) => FlightPhase::Hover,
        (FailsafeState::Armed, GuidanceMode::Land) => FlightPhase::Landing,
        (FailsafeState::Armed, _) => FlightPhase::Idle,
    };
    let a = &est.attitude;
    let phase = match (t.state, t.mode) {
        (FailsafeState::Armed, GuidanceMode::Return) => FlightPhase::Mission,
        (FailsafeState::Armed, GuidanceMode::Manual | GuidanceMode::Assist | GuidanceMode::Offboard) => {
            FlightPhase::Hover
        }
        _ => phase,
    };
    TelemetrySnapshot {
        armed: t.state.motors_enabled(),
        phase,
        guidance: t.mode,
        failsafe,
        attitude_rpy: Vec3::new(a.roll, a.pitch, a.yaw),
        body_rates_frd: est.rate,
        position_ned: t.position,
        velocity_ned: t.velocity,
        filter: t.filter,
        setpoint: SetpointReport {
            position_ned: t.reference.position,
            velocity_ned: t.reference.velocity,
            accel_nominal_ned: t.u_nominal,
            accel_filtered_ned: t.u_filtered,
        },
        mode: t.flight_mode,
        mode_changes: t.mode_changes,
        mode_reason: t.last_mode_change.map(|m| m.reason.as_str()),
        filter_active: t.filter_active,
        mission_seq: t.progress.segment,
        mission_done: t.progress.done,
        battery: t.battery,
        attitude_sp: t.attitude_sp,
        // The pilot input, fix freshness, arm check and navigation status are the outer
        // stage's (OuterStage::snapshot).
        rc: None,
        position_fresh: false,
        armable: false,
        replan: crate::app::replanner::ReplanReport { events: 0, last: None },
        nav: None,
        governor_limit: t.governor.limit,
        governor_cause: t.governor.cause as u8,
        governor_active: t.governor.active,
    }
}

/// The outer stage (see the module docs); its [`Autopilot`] view is [`OuterPort`].
#[derive(Clone, Debug)]
pub struct OuterStage {
    outer: OuterLoop,
    /// The parameter set the loops fly (the last consistent stored set).
    flown: ControllerParams,
    /// The parameter set PARAM_SET edits and PARAM_VALUE reports.
    stored: ControllerParams,
    /// The inner loop's latest estimate.
    estimate: StateEstimate,
    /// The latest pilot input for RC_CHANNELS.
    rc_report: Option<RcReport>,
    /// The on-board replanner's outer side (`RPL_*`).
    replan: ReplanOuter,
    /// The navigation filter (GPS_INPUT, VISION_POSITION_ESTIMATE).
    nav: Navigation,
    /// The bound on its error of the last outer step, for the mapped obstacles
    /// ([`Autopilot::mapped_margin`]); `None` without an initialised filtered source.
    mapped_margin: Option<ErrorBound>,
}

impl OuterStage {
    /// The outer stage for `params` and the inner loop to give the inner stage.
    pub fn new(params: ControllerParams) -> Result<(Self, InnerLoop), ParamError> {
        let (outer, inner) = FlightController::new(params)?.into_loops();
        let estimate = inner.estimate();
        let replan = ReplanOuter::new(&params.replan, params.hull_radius);
        let nav = Navigation::new();
        Ok((
            Self {
                outer,
                flown: params,
                stored: params,
                estimate,
                rc_report: None,
                replan,
                nav,
                mapped_margin: None,
            },
            inner,
        ))
    }

    /// `true` when the stored parameter set is the one the loops fly (it satisfies the
    /// cross-parameter constraints); arming is refused otherwise.
    pub fn params_consistent(&self) -> bool {
        self.stored == self.flown
    }

    /// The parameter set the loops fly.
    pub fn flown_params(&self) -> &ControllerParams {
        &self.flown
    }

    /// The outer loop (read-only).
    pub fn outer(&self) -> &OuterLoop {
        &self.outer
    }

    /// Takes the inner loop's latest estimate, if a new one was published (a tilt trip or new
    /// rejected samples may change the command, which is then published).
    pub fn on_estimate<M: RawMutex>(&mut self, mb: &Mailboxes<M>) {
        if let Some(est) = mb.estimate.try_take() {
            self.take_estimate(est, mb);
        }
    }

    /// Takes `est` (already received from [`Mailboxes::estimate`]) after the pending inputs;
    /// publishes the command when it changed. The snapshot follows with the next outer step.
    pub fn take_estimate<M: RawMutex>(&mut self, est: StateEstimate, mb: &Mailboxes<M>) {
        self.take_inputs(mb);
        self.estimate = est;
        if self.outer.on_estimate(&est) {
            mb.send_command(self.outer.command());
        }
    }

    /// Takes the latest RC frame (mapped with the flown `RC_*` parameters) and battery state;
    /// publishes the command when it changed (the kill switch: Off at once). Every path that
    /// publishes a command calls this first, so a kill the inner stage already acted on
    /// ([`Mailboxes::kill`]) is never followed by a flying command.
    pub fn take_inputs<M: RawMutex>(&mut self, mb: &Mailboxes<M>) {
        if let Some(frame) = mb.rc.try_take() {
            self.rc_report =
                Some(RcReport { channels: frame.raw, link_quality: frame.link_quality, t_us: frame.t_us });
            if self.outer.set_rc(&frame.input(&self.flown.rc)) {
                mb.send_command(self.outer.command());
            }
        }
        if let Some(b) = mb.battery.try_take() {
            self.outer.set_battery(&b);
        }
    }

    /// The navigation filter (read-only).
    pub fn navigation(&self) -> &Navigation {
        &self.nav
    }

    /// Predicts the navigation filter with every queued IMU sample.
    fn predict_nav<M: RawMutex>(&mut self, mb: &Mailboxes<M>) {
        for _ in 0..NAV_SAMPLE_DEPTH {
            match mb.nav.try_receive() {
                Ok(s) => self.nav.sample(&s),
                Err(_) => break,
            }
        }
    }

    /// One outer step at `now_us`: an absolute source's reset handed to the guidance, the
    /// navigation filter's estimate as the fix of now (when it is usable), its vertical error
    /// bound as the ground/ceiling margin (with a filtered source), the step; publishes the
    /// attitude command and the snapshot. Then the
    /// replanner's outer side: a new path is flown from the next step on.
    pub fn step<M: RawMutex>(&mut self, now_us: u64, mb: &Mailboxes<M>) {
        self.take_inputs(mb);
        self.predict_nav(mb);
        if let Some(delta) = self.nav.take_reset() {
            self.outer.position_reset(delta);
        }
        if let Some(fix) = self.nav.controller_fix(now_us) {
            self.outer.update_position(fix);
            mb.aid.signal(self.outer.aid());
        }
        // The ground and ceiling are world planes: with a filtered source they get the vertical
        // error bound, as on the host; the mapped obstacles until the next step get the bound
        // once the filter is initialised (`crate::app::navigation` § Margins).
        let bound = self.nav.error_bound(now_us);
        if let Some(b) = bound {
            self.outer.set_boundary_margin(b.vertical as f32);
        }
        self.mapped_margin = bound.filter(|_| self.nav.aid().filter().is_initialised());
        mb.send_command(self.outer.step(now_us));
        self.replan.step(now_us, &mut self.outer, &mb.replan);
        mb.snapshot.signal(self.snapshot());
    }

    /// The telemetry snapshot now (with the latest pilot input).
    pub fn snapshot(&self) -> TelemetrySnapshot {
        let t = self.outer.telemetry();
        let s = snapshot(t, &self.estimate);
        // At the last outer step's time; the arm checks only while disarmed (O(obstacles)).
        let armable = s.armed || (self.params_consistent() && self.outer.arm_check(t.t_us).is_ok());
        TelemetrySnapshot {
            rc: self.rc_report,
            position_fresh: self.outer.position_fresh(t.t_us),
            armable,
            replan: self.replan.report(),
            nav: self.nav.report(t.t_us),
            ..s
        }
    }

    /// The [`Autopilot`] view of this stage, publishing to `mb`.
    pub fn port<'a, M: RawMutex>(&'a mut self, mb: &'a Mailboxes<M>) -> OuterPort<'a, M> {
        OuterPort { stage: self, mb }
    }
}

/// [`OuterStage`] with its mailboxes: what the link talks to.
pub struct OuterPort<'a, M: RawMutex> {
    stage: &'a mut OuterStage,
    mb: &'a Mailboxes<M>,
}

impl<M: RawMutex> OuterPort<'_, M> {
    /// Rebuilds both loops from `p` (consistent): the outer one here, the inner one from the
    /// parameters sent to the inner stage. Commands still queued for the old inner loop and its
    /// last estimate are dropped first, so the new loops start like a new controller.
    fn rebuild(&mut self, p: ControllerParams) -> Result<(), ParamError> {
        let (outer, inner) = FlightController::new(p)?.into_loops();
        self.mb.commands.clear();
        self.mb.inner_params.signal(*inner.params());
        self.mb.rc_params.signal(p.rc);
        self.mb.estimate.reset();
        let s = &mut *self.stage;
        s.outer = outer;
        s.replan.retune(&p.replan, p.hull_radius);
        s.estimate = inner.estimate();
        s.flown = p;
        self.mb.snapshot.signal(s.snapshot());
        Ok(())
    }
}

impl<M: RawMutex> Autopilot for OuterPort<'_, M> {
    fn mapped_margin(&self) -> Option<ErrorBound> {
        self.stage.mapped_margin
    }

    fn update_position(&mut self, fix: &PositionFix) {
        let s = &mut *self.stage;
        s.outer.update_position(*fix);
        self.mb.aid.signal(s.outer.aid());
    }

    fn navigation_fix(&mut self, fix: &PositionFix, kind: FixKind, noise: SourceNoise) {
        self.stage.predict_nav(self.mb);
        let _ = self.stage.nav.fix(fix, kind, noise);
    }

    fn navigation_height(&mut self, t_us: u64, down: f32) {
        self.stage.predict_nav(self.mb);
        let _ = self.stage.nav.height(t_us, down);
    }

    fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]) {
        self.stage.outer.update_obstacles(now_us, obstacles);
    }

    fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), PathRejected> {
        self.stage.outer.set_path(waypoints_ned).map_err(|e| match e {
            CommandError::Path(PathError::TooMany { .. }) => PathRejected::TooLong,
            _ => PathRejected::Invalid,
        })
    }

    fn stream_path(&mut self, waiting: &[Vec3]) -> usize {
        self.stage.outer.stream_path(waiting).unwrap_or(0)
    }

    fn clear_path(&mut self) {
        self.stage.outer.clear_path();
    }

    fn command(&mut self, now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected> {
        self.stage.take_inputs(self.mb);
        let s = &mut *self.stage;
        let consistent = s.params_consistent();
        let o = &mut s.outer;
        let r = match cmd {
            VehicleCommand::Arm if !consistent => return Err(CommandRejected::NotNow),
            VehicleCommand::Arm => o.arm(now_us),
            VehicleCommand::Disarm { force } => {
                let airborne = !matches!(o.telemetry().mode, GuidanceMode::Off | GuidanceMode::Ground);
                if airborne && !force {
                    return Err(CommandRejected::NotNow);
                }
                o.disarm(now_us)
            }
            VehicleCommand::Takeoff { height_m } => {
                let h = height_m.unwrap_or(DEFAULT_TAKEOFF_HEIGHT_M.min(s.flown.guidance.takeoff_height_max));
                o.takeoff(now_us, h)
            }
            VehicleCommand::Land => o.land(now_us),
            VehicleCommand::StartMission => o.start_mission(now_us),
            VehicleCommand::Hold { target_ned } => {
                let target = target_ned.unwrap_or(o.telemetry().position);
                o.hold_position(now_us, target)
            }
            VehicleCommand::SetMode(m) => o.set_mode(now_us, m),
            VehicleCommand::SetYaw { yaw_rad } => o.set_yaw(yaw_rad),
            VehicleCommand::SetSpeed { m_s } => {
                let limit = s.flown.waypoint.cruise_speed.max(s.flown.modes.assist_speed);
                let v = m_s.map_or(s.flown.waypoint.cruise_speed, |v| if v > limit { limit } else { v });
                o.set_mission_speed(v)
            }
        };
        // Arm, disarm, land and mode changes change the output stage at once (as the facade).
        if r.is_ok()
            && matches!(
                cmd,
                VehicleCommand::Arm
                    | VehicleCommand::Disarm { .. }
                    | VehicleCommand::Land
                    | VehicleCommand::SetMode(_)
            )
        {
            self.mb.send_command(o.command());
        }
        self.mb.snapshot.signal(s.snapshot());
        r.map_err(rejected)
    }

    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        let mut p = self.stage.stored;
        let v = params::set(&mut p, name, value)?;
        if self.stage.outer.state() != FailsafeState::Disarmed {
            // In-flight tuning (issue 41): only the IN_FLIGHT parameters, into the flown set in
            // place (between two outer steps: the link task holds the stage), the whole set
            // consistent; set-up and stateful parts' parameters wait for the disarm.
            // (Armed, the stored set is the flown one: arming needs a consistent set.)
            if !params::in_flight(name) {
                return Err(ParamRejected::NotNow);
            }
            if p.validate().is_err() {
                return Err(ParamRejected::Invalid);
            }
            let s = &mut *self.stage;
            s.outer.retune(&p.outer_params()).map_err(|_| ParamRejected::Invalid)?;
            s.stored = p;
            s.flown = p;
            return Ok(v);
        }
        self.stage.stored = p;
        // An inconsistent set is stored only (arming refused until it is consistent).
        let _ = self.rebuild(p);
        Ok(v)
    }

    fn get_param(&self, name: &str) -> Option<f32> {
        params::get(&self.stage.stored, name)
    }

    fn set_rc(&mut self, rc: &RcInput) {
        self.stage.take_inputs(self.mb);
        let channels = parapet_core::rc::map::channels_of(rc, &self.stage.flown.rc);
        self.stage.rc_report = Some(RcReport { channels, link_quality: rc.link_quality, t_us: rc.t_us });
        if self.stage.outer.set_rc(rc) {
            self.mb.send_command(self.stage.outer.command());
        }
    }

    fn rc_params(&self) -> RcParams {
        self.stage.flown.rc
    }

    fn set_offboard(&mut self, sp: &OffboardSetpoint) {
        self.stage.outer.set_offboard(sp);
    }

    fn set_battery(&mut self, b: &BatteryState) {
        self.stage.outer.set_battery(b);
    }

    fn telemetry(&self) -> TelemetrySnapshot {
        self.stage.snapshot()
    }
    fn flown_path(&self) -> &[Vec3] {
        self.stage.outer.path()
    }
}

/// The inner stage (see the module docs).
#[derive(Clone, Debug)]
pub struct InnerStage {
    inner: InnerLoop,
}

impl InnerStage {
    /// The stage around `inner` (from [`OuterStage::new`]).
    pub fn new(inner: InnerLoop) -> Self {
        Self { inner }
    }

    /// The inner loop (read-only).
    pub fn inner(&self) -> &InnerLoop {
        &self.inner
    }

    /// One inner step at `now_us` with `imu`: takes a rebuilt parameter set, the queued
    /// commands, the latest aid and a kill frame from `mb`, runs, and publishes the estimate.
    pub fn step<M: RawMutex>(&mut self, now_us: u64, imu: &ImuSample, mb: &Mailboxes<M>) -> MotorCommand {
        if let Some(p) = mb.inner_params.try_take() {
            // Sent only for parameter sets the outer stage built a controller from.
            if let Ok(l) = InnerLoop::new(p) {
                self.inner = l;
            }
        }
        for _ in 0..crate::app::mailbox::COMMAND_DEPTH {
            match mb.commands.try_receive() {
                Ok(c) => self.inner.set_command(c),
                Err(_) => break,
            }
        }
        if let Some(aid) = mb.aid.try_take() {
            self.inner.set_aid(aid);
        }
        // After the queued commands: a kill frame stops the motors in this very step, whatever
        // the outer stage queued before it took the frame (see `Mailboxes::kill`).
        if mb.kill.try_take().is_some() {
            self.inner.set_command(AttitudeCommand { stage: MotorStage::Off, ..AttitudeCommand::default() });
        }
        let out = self.inner.step(now_us, imu);
        let est = self.inner.estimate();
        mb.estimate.signal(est);
        mb.send_nav_sample(NavSample { t_us: now_us, accel: imu.accel, attitude: est.attitude });
        MotorCommand { throttle: out.throttle, armed: out.armed }
    }
}

/// Both stages and their mailboxes in one context (PIL application, host tests): the same
/// messages in the order of the controller facade.
pub struct Cascade {
    outer: OuterStage,
    inner: InnerStage,
    mb: Mailboxes<CriticalSectionRawMutex>,
}

impl Cascade {
    /// Cascade with `params` (validated by the controller).
    pub fn new(params: ControllerParams) -> Result<Self, ParamError> {
        let (outer, inner) = OuterStage::new(params)?;
        Ok(Self { outer, inner: InnerStage::new(inner), mb: Mailboxes::new() })
    }

    /// `true` when the stored parameter set is the one flown (see [`OuterStage`]).
    pub fn params_consistent(&self) -> bool {
        self.outer.params_consistent()
    }

    /// The parameter set flown.
    pub fn flown_params(&self) -> &ControllerParams {
        self.outer.flown_params()
    }

    /// The outer stage.
    pub fn outer(&self) -> &OuterStage {
        &self.outer
    }

    /// The inner stage.
    pub fn inner(&self) -> &InnerStage {
        &self.inner
    }

    fn port(&mut self) -> OuterPort<'_, CriticalSectionRawMutex> {
        self.outer.port(&self.mb)
    }
}

impl ControlSteps for Cascade {
    fn step_inner(&mut self, now_us: u64, imu: &ImuSample) -> MotorCommand {
        let m = self.inner.step(now_us, imu, &self.mb);
        self.outer.on_estimate(&self.mb);
        m
    }

    fn step_outer(&mut self, now_us: u64) {
        self.outer.step(now_us, &self.mb);
    }

    fn serve_replan(&mut self, planner: &mut parapet_core::replan::Replanner) -> bool {
        crate::app::replanner::serve_pending(planner, &self.mb.replan)
    }

    fn install_replan(&mut self, request: &'static mut parapet_core::replan::onboard::ReplanRequest) {
        self.mb.replan.install(request);
    }
}

impl Autopilot for Cascade {
    fn mapped_margin(&self) -> Option<ErrorBound> {
        self.outer.mapped_margin
    }
    fn update_position(&mut self, fix: &PositionFix) {
        self.port().update_position(fix);
    }
    fn navigation_fix(&mut self, fix: &PositionFix, kind: FixKind, noise: SourceNoise) {
        self.port().navigation_fix(fix, kind, noise);
    }
    fn navigation_height(&mut self, t_us: u64, down: f32) {
        self.port().navigation_height(t_us, down);
    }
    fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]) {
        self.port().update_obstacles(now_us, obstacles);
    }
    fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), PathRejected> {
        self.port().set_path(waypoints_ned)
    }
    fn stream_path(&mut self, waiting: &[Vec3]) -> usize {
        self.port().stream_path(waiting)
    }
    fn clear_path(&mut self) {
        self.port().clear_path();
    }
    fn command(&mut self, now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected> {
        self.port().command(now_us, cmd)
    }
    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        self.port().set_param(name, value)
    }
    fn get_param(&self, name: &str) -> Option<f32> {
        params::get(&self.outer.stored, name)
    }
    fn telemetry(&self) -> TelemetrySnapshot {
        self.outer.snapshot()
    }
    fn flown_path(&self) -> &[Vec3] {
        self.outer.outer.path()
    }
    fn set_rc(&mut self, rc: &RcInput) {
        self.port().set_rc(rc);
    }
    fn rc_params(&self) -> RcParams {
        self.outer.flown.rc
    }
    fn set_offboard(&mut self, sp: &OffboardSetpoint) {
        self.port().set_offboard(sp);
    }
    fn set_battery(&mut self, b: &BatteryState) {
        self.port().set_battery(b);
    }
    fn battery_params(&self) -> Option<BatteryParams> {
        // The set as written, as the boards' battery task gets it (`SetupOuter`'s mirror).
        Some(self.outer.stored.battery)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two stages exchanging messages through the mailboxes compute exactly what the
    /// controller facade computes (same calls, same order): bit-identical motor commands over
    /// arming, a takeoff with an obstacle in view, a hold and a landing, with a tilted IMU.
    #[test]
    fn stages_through_mailboxes_match_the_controller_facade_bit_for_bit() {
        let p = ControllerParams::default();
        let Ok(mut fc) = FlightController::new(p) else { panic!("defaults") };
        let Ok(mut st) = Cascade::new(p) else { panic!("defaults") };
        let obstacle = [ObstaclePoint::fixed(Vec3::new(0.6, 0.1, -0.8), 3)];
        for k in 0..3000u64 {
            let t = 1_000_000 + k * 1000;
            if k % 4 == 0 {
                let pos = Vec3::new(0.0, 0.0, -(k as f32) * 1e-4);
                let fix = PositionFix { t_us: t, position: pos, velocity: Vec3::zeros(), yaw: Some(0.01) };
                fc.update_position(fix);
                st.update_position(&fix);
                fc.update_obstacles(t, &obstacle);
                st.update_obstacles(t, &obstacle);
            }
            let cmd = match k {
                500 => Some(VehicleCommand::Arm),
                1000 => Some(VehicleCommand::Takeoff { height_m: Some(1.0) }),
                2000 => Some(VehicleCommand::Hold { target_ned: Some(Vec3::new(0.1, 0.0, -0.5)) }),
                2600 => Some(VehicleCommand::Land),
                _ => None,
            };
            if let Some(c) = cmd {
                let r_fc = match c {
                    VehicleCommand::Arm => fc.arm(t),
                    VehicleCommand::Takeoff { height_m } => fc.takeoff(t, height_m.unwrap_or(1.0)),
                    VehicleCommand::Hold { target_ned } => {
                        fc.hold_position(t, target_ned.unwrap_or_default())
                    }
                    _ => fc.land(t),
                };
                assert_eq!(st.command(t, c).is_ok(), r_fc.is_ok(), "step {k}: {c:?}");
            }
            let w = 0.02 * ((k as f32) * 0.01).sin();
            let imu = ImuSample { gyro: Vec3::new(w, -w, 0.5 * w), accel: Vec3::new(0.1 * w, 0.0, -9.81) };
            let a = fc.step_inner(t, &imu);
            let b = st.step_inner(t, &imu);
            assert_eq!(a.throttle.map(f32::to_bits), b.throttle.map(f32::to_bits), "step {k}");
            assert_eq!(a.armed, b.armed, "step {k}");
            if k % 4 == 0 {
                fc.step_outer(t);
                st.step_outer(t);
            }
        }
        let (ta, tb) = (fc.telemetry(), st.telemetry());
        assert_eq!(ta.state, FailsafeState::Land, "the landing was flown");
        assert_eq!(ta.position, tb.position_ned);
        assert_eq!(ta.u_filtered.map(f32::to_bits), tb.setpoint.accel_filtered_ned.map(f32::to_bits));
        assert_eq!(ta.filter, tb.filter);
    }

    /// A heavier vehicle in table order (mass first, which alone cannot hover on the boot
    /// THR_MAX) and in reverse order: every PARAM_SET is taken, the stored set is flown once
    /// it is consistent, whatever the order.
    #[test]
    fn parameter_changes_need_no_order() {
        let changes = [("VEH_MASS", 1.5), ("VEH_IZZ", 0.01), ("VEH_ROTOR_TMAX", 9.0), ("THR_MAX", 30.0)];
        for reverse in [false, true] {
            let Ok(mut ap) = Cascade::new(ControllerParams::default()) else { panic!("defaults") };
            let mut order = changes;
            if reverse {
                order.reverse();
            }
            for (i, (name, v)) in order.iter().enumerate() {
                assert_eq!(ap.set_param(name, *v), Ok(*v), "{name}");
                assert_eq!(ap.params_consistent(), i == order.len() - 1 || (reverse && i >= 1), "{name}");
            }
            let p = ap.flown_params();
            assert_eq!((p.airframe.mass, p.thrust.thrust_max, p.airframe.rotor_thrust_max), (1.5, 30.0, 9.0));
        }
    }
    use crate::link::dialect::{
        MavCmd, MavFrame, MavResult, COMMAND_LONG_DATA, HIL_SENSOR_DATA, OBSTACLE_DISTANCE_3D_DATA,
        ODOMETRY_DATA,
    };
    /// The kill switch through the receiver mailbox (`Mailboxes::deliver_rc`, as the board's
    /// receiver task): the frame delivered before inner step k stops the motors in step k itself
    /// (0 steps; it was step k + 1, up to two inner periods after the frame, when the frame went
    /// through the outer stage only), the outer stage then disarms and they stay off; a
    /// DO_SET_MODE-style mode command changes the flight mode (Position needs RC first).
    #[test]
    fn kill_frame_stops_the_motors_in_the_next_inner_step_and_modes_switch() {
        use crate::app::autopilot::FlightMode;
        use parapet_core::rc::map::RcFrame;
        use parapet_core::rc::{RawChannels, RcSource};
        let Ok(mut ap) = Cascade::new(ControllerParams::default()) else { panic!("defaults") };
        let imu = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -9.81) };
        let frame = |t_us, kill: bool| {
            let mut us = [1500u16; parapet_core::rc::MAX_CHANNELS];
            us[2] = 1500; // throttle mid
            us[4] = 2000; // arm switch on
            us[5] = 1000; // mode switch low
            us[6] = if kill { 2000 } else { 1000 };
            let raw = RawChannels { us, count: 16, failsafe: false, frame_lost: false };
            RcFrame { raw, t_us, link_quality: 100, rssi_dbm: None, source: RcSource::Crsf }
        };
        let mut last = MotorCommand::OFF;
        let mut stopped_at = None;
        for k in 0..3000u64 {
            let t = 1_000_000 + k * 1000;
            if k % 4 == 0 {
                let fix = PositionFix {
                    t_us: t,
                    position: Vec3::new(0.0, 0.0, -1.0),
                    velocity: Vec3::zeros(),
                    yaw: Some(0.0),
                };
                ap.update_position(&fix);
                ap.update_obstacles(t, &[]);
            }
            if k % 10 == 0 {
                ap.mb.deliver_rc(frame(t, k >= 2500), &RcParams::default());
            }
            match k {
                500 => assert_eq!(ap.command(t, VehicleCommand::Arm), Ok(())),
                600 => assert_eq!(ap.command(t, VehicleCommand::Takeoff { height_m: Some(1.0) }), Ok(())),
                700 => {
                    assert_eq!(ap.command(t, VehicleCommand::SetMode(FlightMode::Position)), Ok(()));
                    assert_eq!(ap.telemetry().mode, FlightMode::Position);
                    assert_eq!(ap.telemetry().mode_reason, Some("mode-command"));
                }
                _ => {}
            }
            let m = ap.step_inner(t, &imu);
            if k == 2500 {
                assert!(last.armed && last.throttle.iter().any(|&x| x > 0.0), "flying before the kill");
            }
            if k >= 2500 && m.throttle == [0.0; 4] && stopped_at.is_none() {
                stopped_at = Some(k);
            }
            if stopped_at.is_some() {
                assert_eq!(m.throttle, [0.0; 4], "step {k}: motors on again after the kill");
            }
            last = m;
            if k % 4 == 0 {
                ap.step_outer(t);
            }
        }
        let steps = stopped_at.map(|k| k - 2500);
        std::println!("kill frame before inner step 2500: motors zero {steps:?} inner steps later");
        assert_eq!(steps, Some(0), "motors zero in the inner step the kill frame arrived before");
        assert!(!ap.telemetry().armed);
        assert_eq!(
            ap.outer().outer().telemetry().last_transition.map(|t| t.reason),
            Some(TransitionReason::KillSwitch)
        );
    }

    use crate::link::framing::FrameWriter;
    use crate::link::obstacles::CLEAR_ID;
    use crate::link::outbound::Outbound;
    use crate::link::{FixClock, Link};
    use crate::pil::lockstep::LockstepScheduler;

    /// The ODOMETRY yaw reaches the estimator (as in `parapet run`): the first external yaw
    /// sets the heading; without one the heading stays where the accelerometer start left it.
    #[test]
    fn position_fix_yaw_sets_the_estimated_heading() {
        let heading = |yaw: Option<f32>| {
            let Ok(mut ap) = Cascade::new(ControllerParams::default()) else { panic!("default params") };
            let imu = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -9.81) };
            for k in 0..50u64 {
                let t = 1_000_000 + k * 1000;
                if k % 4 == 0 {
                    let fix = PositionFix { t_us: t, position: Vec3::zeros(), velocity: Vec3::zeros(), yaw };
                    ap.update_position(&fix);
                }
                let _ = ap.step_inner(t, &imu);
            }
            ap.telemetry().attitude_rpy.z
        };
        assert!((heading(Some(1.0)) - 1.0).abs() < 1e-3, "{}", heading(Some(1.0)));
        assert!(heading(None).abs() < 1e-3, "{}", heading(None));
    }

    /// SET_POSITION_TARGET_LOCAL_NED through the link reaches the cascade: with a fresh
    /// velocity setpoint the Offboard mode can be selected and is flown; a refused type_mask
    /// (x, y ignored only) is counted as ignored.
    #[test]
    fn offboard_setpoints_through_the_link_select_and_fly_offboard() {
        use crate::app::autopilot::FlightMode;
        use crate::link::dialect::{PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA};
        let Ok(mut ap) = Cascade::new(ControllerParams::default()) else { panic!("defaults") };
        let mut link = Link::new(1, FixClock::Message);
        let mut host = FrameWriter::new(255, 190);
        let sp = |t: u64, mask: u16| SET_POSITION_TARGET_LOCAL_NED_DATA {
            time_boot_ms: (t / 1000) as u32,
            vx: 0.5,
            type_mask: PositionTargetTypemask::from_bits_truncate(mask),
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            target_system: 1,
            ..Default::default()
        };
        let t = 2_000_000;
        assert_eq!(
            ap.command(t, VehicleCommand::SetMode(FlightMode::Offboard)),
            Err(CommandRejected::NotNow)
        );
        let ignored = link.stats().ignored;
        link.push_bytes(host.encode(&sp(t, 0x0DFC)).raw_bytes(), t, &mut ap);
        assert_eq!(link.stats().ignored, ignored + 1, "partial mask refused");
        link.push_bytes(host.encode(&sp(t, 0x0DC7)).raw_bytes(), t, &mut ap);
        assert_eq!(ap.command(t, VehicleCommand::SetMode(FlightMode::Offboard)), Ok(()));
        assert_eq!(ap.telemetry().mode, FlightMode::Offboard);
    }

    /// The lockstep path with the real cascade on a vehicle at rest: arm is accepted once the
    /// position and obstacle data are fresh, the motors then idle, and a takeoff command spins
    /// them up (the cascade is the one the firmware flies).
    #[test]
    fn arm_and_takeoff_through_the_link_with_the_real_cascade() {
        let mut ap = match Cascade::new(ControllerParams::default()) {
            Ok(c) => c,
            Err(e) => panic!("default params rejected: {e:?}"),
        };
        // Parameters apply while disarmed (the cascade is rebuilt with them).
        assert_eq!(ap.set_param("CBF_MU", 1.2), Ok(1.2));
        assert_eq!(ap.get_param("CBF_MU"), Some(1.2));
        assert_eq!(ap.flown_params().cbf.mu, 1.2);
        // Out of range: refused, the old value stays.
        assert_eq!(ap.set_param("CBF_MU", -1.0), Err(ParamRejected::Invalid));
        assert_eq!(ap.set_param("CBF_VARIANT", 2.5), Err(ParamRejected::Invalid));
        assert_eq!(ap.get_param("CBF_MU"), Some(1.2));
        // In range but δ1 < δ: stored, not flown, and arming is refused until it is fixed.
        assert_eq!(ap.set_param("CBF_DELTA1", 0.01), Ok(0.01));
        assert_eq!(ap.get_param("CBF_DELTA1"), Some(0.01));
        assert!(!ap.params_consistent());
        assert_eq!(ap.flown_params().cbf.delta1, 0.1);
        assert_eq!(ap.command(0, VehicleCommand::Arm), Err(CommandRejected::NotNow));
        assert_eq!(ap.set_param("CBF_DELTA1", 0.1), Ok(0.1));
        assert!(ap.params_consistent());
        let mut link = Link::new(1, FixClock::Message);
        let mut sched = LockstepScheduler::default();
        let mut host = FrameWriter::new(255, 190);
        let mut acks = std::vec::Vec::new();
        let mut last_motors = MotorCommand::OFF;
        for k in 0..1500u64 {
            let t = 1_000_000 + k * 1000;
            if k % 4 == 0 {
                let odo = ODOMETRY_DATA {
                    time_usec: t,
                    q: [1.0, 0.0, 0.0, 0.0],
                    frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                    child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                    ..Default::default()
                };
                link.push_bytes(host.encode(&odo).raw_bytes(), t, &mut ap);
                let clear = OBSTACLE_DISTANCE_3D_DATA {
                    time_boot_ms: (t / 1000) as u32,
                    obstacle_id: CLEAR_ID,
                    frame: MavFrame::MAV_FRAME_LOCAL_NED,
                    // The empty-batch marker (an empty range): no point.
                    min_distance: parapet_core::wire::ids::EMPTY_BATCH_RANGE.0,
                    max_distance: parapet_core::wire::ids::EMPTY_BATCH_RANGE.1,
                    ..Default::default()
                };
                link.push_bytes(host.encode(&clear).raw_bytes(), t, &mut ap);
            }
            let cmd = |c: MavCmd, p1: f32, p7: f32| COMMAND_LONG_DATA {
                param1: p1,
                param7: p7,
                command: c as u16,
                target_system: 1,
                ..Default::default()
            };
            if k == 500 {
                link.push_bytes(
                    host.encode(&cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0)).raw_bytes(),
                    t,
                    &mut ap,
                );
            }
            if k == 1000 {
                link.push_bytes(
                    host.encode(&cmd(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 1.0)).raw_bytes(),
                    t,
                    &mut ap,
                );
            }
            let hil = HIL_SENSOR_DATA { time_usec: t, zacc: -9.81, ..Default::default() };
            link.push_bytes(host.encode(&hil).raw_bytes(), t, &mut ap);
            let Some(sample) = link.take_hil_sample() else { panic!("HIL_SENSOR not decoded at step {k}") };
            let out = sched.step(&sample, &mut link, &mut ap);
            while let Some(r) = link.pop_reply() {
                if let Outbound::CommandAck(a) = r {
                    acks.push(a.result);
                }
            }
            if k == 999 {
                assert!(out.motors.armed, "armed at idle before takeoff");
                assert!(out.motors.throttle.iter().all(|&x| x > 0.0 && x < 0.3), "{:?}", out.motors);
            }
            last_motors = out.motors;
        }
        assert_eq!(acks, vec![MavResult::MAV_RESULT_ACCEPTED, MavResult::MAV_RESULT_ACCEPTED]);
        // Armed: set-up parameters are refused, the in-flight tunables taken in place (issue
        // 41); a hold command switches to hover.
        assert_eq!(ap.set_param("VEH_MASS", 0.6), Err(ParamRejected::NotNow));
        assert_eq!(ap.set_param("CBF_MU", 0.9), Ok(0.9));
        assert_eq!(ap.flown_params().cbf.mu, 0.9);
        assert_eq!(ap.set_param("CBF_DELTA1", 0.01), Err(ParamRejected::Invalid), "δ1 below δ");
        assert_eq!(ap.command(2_500_000, VehicleCommand::Hold { target_ned: None }), Ok(()));
        ap.step_outer(2_500_000);
        assert_eq!(ap.telemetry().phase, FlightPhase::Hover);
        assert_eq!(
            ap.command(2_500_000, VehicleCommand::Disarm { force: false }),
            Err(CommandRejected::NotNow)
        );
        assert!(last_motors.armed);
        let s = ap.telemetry();
        assert!(s.failsafe.is_none(), "{s:?}");
    }
}
