//! The whole flight-control cascade behind one API, [`FlightController`]: a thin facade over
//! the two loops, [`OuterLoop`] ([`crate::outer`], with the [`crate::supervisor`]) and
//! [`InnerLoop`] ([`crate::inner`]), which exchange only the [`crate::msg`] messages.
//!
//! ```text
//!  outer loop, step_outer (default 250 Hz)                         inner loop, step_inner (default 1 kHz)
//!  ┌──────────────┐ p_d,ṗ_d,p̈_d ┌──────────┐ u* ┌────────────┐ u ┌───────────────┐ AttitudeCommand ┌──────────────┐ ω_sp ┌──────────┐ τ ┌───────┐
//!  │ guidance /   ├────────────▶│ PD track ├───▶│ CBF filter ├──▶│ thrust/att.   ├────────────────▶│ attitude P   ├─────▶│ rate PID ├──▶│ mixer ├─▶ motors
//!  │ supervisor   │             │ (eq. 2)  │    │ (eq. 12)   │   │ map (eq. 4-5) │ φ_d,θ_d,ψ_d,T   │ (Euler, wrap)│      │          │   │       │
//!  └──────────────┘             └──────────┘    └────────────┘   └───────────────┘                 └──────────────┘      └──────────┘   └───────┘
//!        ▲ position fix (p, ṗ; external)            ▲ obstacles                 ▲ φ, θ, tilt            ▲ attitude            ▲ ω (gyro − bias)
//!        └───────────────────────────────────────────┴──────────────────────────┴──── StateEstimate ◀── Mahony estimator (gyro + accel, step_inner)
//! ```
//!
//! The facade hands each message over at once (the outer step's [`crate::msg::AttitudeCommand`] to the
//! inner loop, every inner step's [`crate::msg::StateEstimate`] to the outer loop, every fix's
//! [`crate::msg::EstimatorAid`] to the inner loop), so it behaves exactly as one controller. A firmware
//! that runs the loops in different tasks takes them apart with [`FlightController::into_loops`]
//! and passes the same messages through its own mailboxes; which inner step runs the outer
//! step is [`crate::schedule::OuterSchedule`].
//!
//! * [`FlightController::update_position`] stores an external position/velocity
//!   fix (motion capture, VIO, simulator). Between fixes the outer loop uses the
//!   fix extrapolated with its velocity: `p = p_fix + ṗ_fix·age`.
//! * [`FlightController::update_obstacles`] replaces the obstacle set (capacity
//!   [`OBSTACLE_CAPACITY`] = 32, nearest kept, see [`crate::obstacle::ObstacleSet`]). An empty
//!   update means "the sensor sees nothing" and keeps the obstacle data fresh;
//!   no update for longer than the limit is a data loss (failsafe), unless
//!   `failsafe.obstacles_required` is `false` (flights without an obstacle source).
//! * [`FlightController::step_outer`]: failsafe data check, reference, PD, CBF,
//!   thrust/attitude mapping. [`FlightController::step_inner`]: estimator, crash
//!   check, attitude and rate loops, mixer. Both are O(obstacles + waypoints),
//!   allocation-free and never panic; the motor output is always finite and in range.
//!
//! ## Modes
//! Failsafe states ([`crate::failsafe`]) take precedence over the nominal guidance:
//! * **Armed**: guidance is *Ground* (motors at idle, no control) until
//!   [`takeoff`](FlightController::takeoff) (vertical ramp at `takeoff_speed`),
//!   then *Hold* / *Takeoff* / *Mission* ([`start_mission`](FlightController::start_mission))
//!   or a position step ([`hold_position`](FlightController::hold_position)).
//! * **Brake** / **Land**: see [`crate::supervisor`].
//! * **Disarmed / MotorsOff**: all motor outputs zero.
//!
//! Yaw: the yaw reference is the estimated yaw at arming, held constant.
//!
//! Estimator aids: with a fresh fix, the world acceleration from successive fix
//! velocities (low-passed) and the fix yaw; flying without a fix, the commanded
//! acceleration `u`. While the motors are off the estimator runs its at-rest gyro-bias
//! calibration.
//!
//! May import: every stage ([`crate::outer`], [`crate::inner`], [`crate::supervisor`],
//! [`crate::safety`]), [`crate::config`], [`crate::msg`]. Nothing in the crate imports it.

use crate::cbf::{FilterDiagnostics, FilterVariant};
use crate::estimator::AttitudeEstimator;
use crate::failsafe::{FailsafeState, Transition};
use crate::fmath::maxf;
use crate::governor::GovernorTelemetry;
use crate::inner::{InnerError, InnerLoop, InnerParams};
use crate::mixer::MixerOutput;
use crate::msg::{AttitudeSetpoint, Euler, ImuSample, ImuStatus};
use crate::obstacle::ObstaclePoint;
use crate::obstacle_set::SetReport;
use crate::outer::inputs::InputParams;
use crate::outer::{OuterError, OuterLoop, OuterParams};
use crate::plant_aware::{lag_time_constant, PlantAwareTelemetry};
use crate::supervisor::SupervisorParams;
use crate::tracking::Reference;
use crate::waypoint::Progress;
use crate::Vec3;

use crate::battery::BatteryState;
pub use crate::config::{ControllerParams, ParamError};
pub use crate::msg::{MotorOutput, PositionFix};
pub use crate::outer::guidance::{GuidanceMode, PATH_CAPACITY};
pub use crate::outer::inputs::OBSTACLE_CAPACITY;
pub use crate::outer::offboard::OffboardSetpoint;
pub use crate::outer::CommandError;
use crate::rc::RcInput;
pub use crate::supervisor::modes::{FlightMode, ModeTransition};

/// One telemetry record (updated by every step; copy with [`FlightController::telemetry`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Telemetry {
    /// Time of the last outer step, µs.
    pub t_outer_us: u64,
    /// Time of the last inner step, µs.
    pub t_inner_us: u64,
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
    /// Position and velocity used by the outer loop (fix extrapolated), NED.
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
    /// Estimated attitude (Euler ZYX, rad).
    pub attitude: Euler,
    /// Estimated gyro bias, rad/s FRD.
    pub gyro_bias: Vec3,
    /// Estimator status of the last IMU sample.
    pub imu_status: ImuStatus,
    /// Body-rate setpoint, rad/s FRD.
    pub rate_sp: [f32; 3],
    /// Torque command, N·m FRD.
    pub torque: [f32; 3],
    /// Motor output of the last inner step.
    pub motors: MotorOutput,
    /// Mixer saturation flags of the last inner step.
    pub mixer: MixerOutput,
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
    pub outer_count: u32,
    /// Inner steps run.
    pub inner_count: u32,
    /// Selected flight mode (issue 21; [`FlightMode`]).
    pub flight_mode: FlightMode,
    /// Last flight-mode change (reason, time).
    pub last_mode_change: Option<ModeTransition>,
    /// Flight-mode changes so far.
    pub mode_changes: u32,
    /// The safety filter changed the nominal command in the last outer step (never in Manual).
    pub filter_active: bool,
    /// Outer steps with the filter active, per flight mode (index `FlightMode as usize`).
    pub filter_interventions: [u32; FlightMode::COUNT],
    /// RC frames rejected (NaN/Inf or out-of-range sticks) since start.
    pub rc_rejected: u32,
    /// Offboard setpoints rejected since start.
    pub offboard_rejected: u32,
    /// The speed governor's limit and its cause at the last outer step ([`crate::governor`]).
    pub governor: GovernorTelemetry,
}

impl ControllerParams {
    /// The outer loop's part. For every filter variant but `Paper` (kept exactly as
    /// published) the filter's `sample_time` is raised to at least the outer period, so the
    /// event rule does not engage a sample late (see `cbf::CbfParams::sample_time`), γ to at
    /// least `robust.gamma` and A by the observer's `robust.dob_margin` (issue 17).
    pub fn outer_params(&self) -> OuterParams {
        let mut cbf = self.cbf;
        if self.filter_variant != FilterVariant::Paper {
            cbf.sample_time = maxf(cbf.sample_time, 1.0 / self.outer_rate_hz);
            // Plant-aware (docs/filter.md §9-§12): class-K relaxation, and the observer's
            // error bound ē joins the robust term A.
            cbf.gamma = maxf(cbf.gamma, self.plant_aware.gamma);
            if self.plant_aware.dob_bandwidth > 0.0 {
                cbf.accel_bound += self.plant_aware.dob_margin;
            }
        }
        OuterParams {
            plant_aware: self.plant_aware,
            lag_tau: lag_time_constant(&self.attitude.att_p, self.plant_aware.motor_tau),
            rate_hz: self.outer_rate_hz,
            tracking: self.tracking,
            cbf,
            filter_variant: self.filter_variant,
            thrust: self.thrust,
            mass: self.airframe.mass,
            guidance: self.guidance,
            waypoint: self.waypoint,
            inputs: InputParams {
                position_timeout_us: self.failsafe.position_timeout_us,
                obstacle_timeout_us: self.failsafe.obstacle_timeout_us,
                accel_comp_tau_s: self.accel_comp_tau_s,
                hull_delta: self.cbf.delta,
            },
            supervisor: SupervisorParams { failsafe: self.failsafe, landing: self.landing },
            modes: self.modes,
            governor: self.governor,
            // The braking the filter assumes: its deceleration, within what the tilt limit gives.
            governor_vehicle: crate::governor::Vehicle {
                accel: crate::fmath::minf(
                    self.cbf.brake_accel,
                    crate::frame::GRAVITY * crate::fmath::tanf(self.thrust.tilt_max),
                ),
                delay: self.cbf.brake_delay + self.governor.delay,
                hull_radius: self.hull_radius,
            },
        }
    }

    /// The inner loop's part.
    pub fn inner_params(&self) -> InnerParams {
        InnerParams {
            airframe: self.airframe,
            estimator: self.estimator,
            attitude: self.attitude,
            rate_hz: self.inner_rate_hz,
            idle_throttle: self.idle_throttle,
            position_timeout_us: self.failsafe.position_timeout_us,
            tilt_limit: self.failsafe.tilt_limit,
        }
    }
}

impl From<InnerError> for ParamError {
    fn from(e: InnerError) -> Self {
        match e {
            InnerError::Attitude(e) => ParamError::Attitude(e),
            InnerError::Estimator(e) => ParamError::Estimator(e),
            InnerError::Mixer(e) => ParamError::Mixer(e),
        }
    }
}

impl From<OuterError> for ParamError {
    fn from(e: OuterError) -> Self {
        match e {
            OuterError::Cbf(e) => ParamError::Cbf(e),
            OuterError::Waypoint(e) => ParamError::Waypoint(e),
        }
    }
}

/// The cascade (see the module documentation).
#[derive(Clone, Debug)]
pub struct FlightController {
    params: ControllerParams,
    outer: OuterLoop,
    inner: InnerLoop,
}

impl FlightController {
    /// A disarmed controller; errors on invalid parameters.
    pub fn new(params: ControllerParams) -> Result<Self, ParamError> {
        params.validate()?;
        let inner = InnerLoop::new(params.inner_params())?;
        let outer = OuterLoop::new(params.outer_params(), inner.estimate())?;
        Ok(FlightController { params, outer, inner })
    }

    /// The two loops, to run in different tasks. They then exchange the messages the facade
    /// hands over: after every [`OuterLoop::step`] and command, [`OuterLoop::command`] →
    /// [`InnerLoop::set_command`]; after every [`OuterLoop::update_position`],
    /// [`OuterLoop::aid`] → [`InnerLoop::set_aid`]; after every [`InnerLoop::step`],
    /// [`InnerLoop::estimate`] → [`OuterLoop::on_estimate`] (and its command back when it
    /// returns `true`).
    pub fn into_loops(self) -> (OuterLoop, InnerLoop) {
        (self.outer, self.inner)
    }

    /// Parameters in use.
    pub fn params(&self) -> &ControllerParams {
        &self.params
    }

    /// The outer loop (read-only).
    pub fn outer(&self) -> &OuterLoop {
        &self.outer
    }

    /// The inner loop (read-only).
    pub fn inner(&self) -> &InnerLoop {
        &self.inner
    }

    /// Copy of the latest telemetry record.
    pub fn telemetry(&self) -> Telemetry {
        let o = self.outer.telemetry();
        let i = self.inner.telemetry();
        Telemetry {
            t_outer_us: o.t_us,
            t_inner_us: i.t_us,
            state: o.state,
            last_transition: o.last_transition,
            transitions: o.transitions,
            mode: o.mode,
            reference: o.reference,
            progress: o.progress,
            position: o.position,
            velocity: o.velocity,
            u_nominal: o.u_nominal,
            u_filtered: o.u_filtered,
            attitude_sp: o.attitude_sp,
            filter: o.filter,
            attitude: i.attitude,
            gyro_bias: i.gyro_bias,
            imu_status: i.imu_status,
            rate_sp: i.rate_sp,
            torque: i.torque,
            motors: i.motors,
            mixer: i.mixer,
            position_age_us: o.position_age_us,
            obstacle_age_us: o.obstacle_age_us,
            obstacle_count: o.obstacle_count,
            obstacles_dropped: o.obstacles_dropped,
            obstacle_set: o.obstacle_set,
            plant_aware: o.plant_aware,
            non_finite_inputs: o.non_finite_inputs,
            outer_count: o.count,
            inner_count: i.count,
            flight_mode: o.flight_mode,
            last_mode_change: o.last_mode_change,
            mode_changes: o.mode_changes,
            filter_active: o.filter_active,
            filter_interventions: o.filter_interventions,
            rc_rejected: o.rc_rejected,
            offboard_rejected: o.offboard_rejected,
            governor: o.governor,
        }
    }

    /// Failsafe state.
    pub fn state(&self) -> FailsafeState {
        self.outer.state()
    }

    /// Obstacle points currently used by the filter.
    pub fn obstacles(&self) -> &[ObstaclePoint] {
        self.outer.obstacles()
    }

    /// The attitude estimator (read-only).
    pub fn estimator(&self) -> &AttitudeEstimator {
        self.inner.estimator()
    }

    fn publish_command(&mut self) {
        self.inner.set_command(self.outer.command());
    }

    /// Store an external position fix. A fix with a NaN/Inf position or velocity,
    /// a component beyond ±[`crate::cbf::INPUT_LIMIT`] (1e5 m or m/s), a non-finite yaw, or
    /// time-stamped more than the position timeout after the controller clock, is rejected
    /// and counts as a bad input (failsafe brake). Fixes older than the stored one are ignored.
    pub fn update_position(&mut self, fix: PositionFix) {
        self.outer.update_position(fix);
        self.inner.set_aid(self.outer.aid());
    }

    /// The navigation filter reset its position to a source that jumped: the estimate (the
    /// next fixes) jumped by `delta` (NED, m; `NavStatus::last_reset_delta` of an absolute
    /// source). The guidance moves its reference with it (`outer::reset_shift`), so the
    /// commanded acceleration does not jump. Call it once per reset, before the first fix
    /// after it. Non-finite: ignored.
    pub fn position_reset(&mut self, delta: Vec3) {
        self.outer.position_reset(delta);
    }

    /// The position's vertical error is bounded by `m` (m; a navigation filter's bound,
    /// `docs/filter.md` § 18): the ground and ceiling barriers keep `m` more (they are world
    /// planes, as mapped obstacles). Default 0; negative or non-finite: 0.
    pub fn set_boundary_margin(&mut self, m: f32) {
        self.outer.set_boundary_margin(m);
    }

    /// Replace the obstacle set with `obstacles` (closest surface points, NED),
    /// valid at `now_us`. At most [`OBSTACLE_CAPACITY`] are kept (the nearest to
    /// the vehicle); points (or velocities) that are non-finite or beyond
    /// ±[`crate::cbf::INPUT_LIMIT`] are dropped and count as a bad input, as does
    /// a `now_us` more than the obstacle timeout after the controller clock (the
    /// update is then ignored).
    pub fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]) {
        self.outer.update_obstacles(now_us, obstacles);
    }

    /// Replace the path (waypoints NED, m; at most [`PATH_CAPACITY`]). Rejected paths
    /// leave the old one. While a mission is flying, the new path starts at once from
    /// the current reference position (re-planning without a jump).
    pub fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), CommandError> {
        self.outer.set_path(waypoints_ned)
    }

    /// One step of streaming a path longer than [`PATH_CAPACITY`] (issue 38): the next of the
    /// `waiting` waypoints go onto the path when a refill is due; returns how many (see
    /// [`OuterLoop::stream_path`](crate::outer::OuterLoop::stream_path)). Call after each
    /// outer step.
    pub fn stream_path(&mut self, waiting: &[Vec3]) -> Result<usize, CommandError> {
        self.outer.stream_path(waiting)
    }

    /// The stored path's waypoints (NED; see [`OuterLoop::path`](crate::outer::OuterLoop::path)).
    pub fn path(&self) -> &[Vec3] {
        self.outer.path()
    }

    /// Drop the stored path (see [`OuterLoop::clear_path`](crate::outer::OuterLoop::clear_path)).
    pub fn clear_path(&mut self) {
        self.outer.clear_path();
    }

    /// Arm: needs a fresh, finite position fix, fresh obstacle data, no bad input
    /// pending, no reported obstacle point inside the hull (distance from the
    /// position estimate below √δ: the vehicle would start in collision) and an
    /// initialised, level-enough attitude estimate. The yaw reference
    /// is the current estimated yaw; the vehicle stays on the ground (motors idle).
    pub fn arm(&mut self, now_us: u64) -> Result<(), CommandError> {
        self.outer.arm(now_us)?;
        self.publish_command();
        Ok(())
    }

    /// Disarm (operator kill): motors off at once, from any state.
    pub fn disarm(&mut self, now_us: u64) -> Result<(), CommandError> {
        self.outer.disarm(now_us)?;
        self.publish_command();
        Ok(())
    }

    /// Take off: vertical ramp at `takeoff_speed` to `height_m` (m, > 0) above the
    /// arming position (home). Needs Armed and a fresh fix.
    pub fn takeoff(&mut self, now_us: u64, height_m: f32) -> Result<(), CommandError> {
        self.outer.takeoff(now_us, height_m)
    }

    /// Position step: hold `target` (NED, m) from now on. Needs Armed and a fresh fix.
    pub fn hold_position(&mut self, now_us: u64, target: Vec3) -> Result<(), CommandError> {
        self.outer.hold_position(now_us, target)
    }

    /// Fly the stored path from the current reference position. Needs Armed and airborne.
    pub fn start_mission(&mut self, now_us: u64) -> Result<(), CommandError> {
        self.outer.start_mission(now_us)
    }

    /// Land (from Armed or Brake).
    pub fn land(&mut self, now_us: u64) -> Result<(), CommandError> {
        self.outer.land(now_us)?;
        self.publish_command();
        Ok(())
    }

    /// Take one RC frame (issue 21; [`RcInput`], time-stamped on the controller clock).
    /// Kill switch on: motors off at once (the very next [`Self::step_inner`] outputs zero),
    /// from any state. Arm switch on (an edge): arm with the usual checks; off: disarm on the
    /// ground (or in Manual at zero throttle). Mode switch moved: that position's mode
    /// (`MODE_SW_*`; the first frame only while disarmed). NaN/Inf or out-of-range sticks:
    /// the frame is rejected and counted (`rc_rejected`); no valid frame for `FS_RC_TIMEOUT`
    /// is an RC loss (per-mode failsafe, [`crate::supervisor::modes`]).
    pub fn set_rc(&mut self, rc: &RcInput) {
        if self.outer.set_rc(rc) {
            self.publish_command();
        }
    }

    /// Take one offboard setpoint ([`OffboardSetpoint`]); bad ones are rejected and counted.
    /// In Offboard, no valid setpoint for `OFFB_TIMEOUT` → Hold.
    pub fn set_offboard(&mut self, sp: &OffboardSetpoint) {
        self.outer.set_offboard(sp);
    }

    /// Take one battery measurement: Low → Return, Critical → Land (once each, `FS_BAT_ACT`).
    pub fn set_battery(&mut self, b: &BatteryState) {
        self.outer.set_battery(b);
    }

    /// Select a flight mode (CLI/host API, MAVLink DO_SET_MODE). Manual and Position need a
    /// valid RC frame, Offboard a fresh setpoint, Return a position fix
    /// ([`CommandError::ModeUnavailable`] otherwise).
    pub fn set_mode(&mut self, now_us: u64, mode: FlightMode) -> Result<(), CommandError> {
        self.outer.set_mode(now_us, mode)?;
        self.publish_command();
        Ok(())
    }

    /// The selected flight mode.
    pub fn mode(&self) -> FlightMode {
        self.outer.mode()
    }

    /// Outer loop (nominal 250 Hz): failsafe data check, reference, PD tracking,
    /// CBF filter, thrust/attitude mapping. Bounded; never panics.
    pub fn step_outer(&mut self, now_us: u64) {
        let command = self.outer.step(now_us);
        self.inner.set_command(command);
    }

    /// Inner loop (nominal 1 kHz): attitude estimator, crash check, attitude P,
    /// rate PID, mixer. `imu`: gyro rad/s FRD, specific force m/s² FRD. Returns the
    /// motor commands — always finite and in range; all zero unless armed.
    pub fn step_inner(&mut self, now_us: u64, imu: &ImuSample) -> MotorOutput {
        let out = self.inner.step(now_us, imu);
        if self.outer.on_estimate(&self.inner.estimate()) {
            self.publish_command();
        }
        out
    }
}

/// The on-board replanner's view of the facade (the host's in-process controller runs
/// [`crate::replan::onboard`] on it; the firmware on its `OuterLoop`).
impl crate::replan::onboard::MissionControl for FlightController {
    fn outer_telemetry(&self) -> &crate::outer::OuterTelemetry {
        self.outer.telemetry()
    }
    fn mission_path(&self) -> &[Vec3] {
        self.path()
    }
    fn replace_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), CommandError> {
        self.set_path(waypoints_ned)
    }
    fn restart_mission(&mut self, now_us: u64) -> Result<(), CommandError> {
        self.start_mission(now_us)
    }
}
