//! Adapter between the runner and [`parapet_core::controller::FlightController`]:
//! f64 simulator types ↔ f32 core types, simulator time ↔ controller clock,
//! and the start-up sequence.
//!
//! * **Clock**: controller time (µs) = (simulated time + [`CLOCK_OFFSET_S`]) · 10⁶,
//!   so that position fixes measured before t = 0 (latency priming) keep
//!   non-negative timestamps.
//! * **Start-up** (at t = 0, vehicle hovering at the start): one IMU sample
//!   initialises the estimator, a position fix and the obstacle report are
//!   given, then `arm`, `hold_position(start)`, one outer step (the reference
//!   becomes the start) and `start_mission`.
//! * **Position fixes** carry the time they were measured (so the controller's
//!   latency compensation by extrapolation applies) and the true yaw (a motion
//!   capture system measures it).
//! * **`--no-cbf`**: the controller is told that no obstacle is in range (an
//!   empty report), so its filter passes the nominal input through unchanged
//!   (region "none"). The controller itself is the same.

use anyhow::{anyhow, Result};
use nalgebra::Vector3;
use parapet_core::cbf::{CbfParams, FilterVariant, Region};
use parapet_core::controller::{CommandError, ControllerParams, FlightController, PositionFix, Telemetry};
use parapet_core::estimator::ImuSample;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::thrust::ThrustParams;
use parapet_core::tracking::TrackingParams;
use parapet_core::waypoint::WaypointParams;
use parapet_core::Vec3;

use crate::report::SafetyFlags;
use crate::runner::RunConfig;
use crate::scene::{to_f32, to_f64, Scene};
use crate::sensors::{ImuReading, PositionReading};

/// Offset of the controller clock from simulated time, s.
pub const CLOCK_OFFSET_S: f64 = 1.0;

/// Controller clock (µs) at simulated time `t` (s).
pub fn clock_us(t: f64) -> u64 {
    ((t + CLOCK_OFFSET_S).max(0.0) * 1e6).round() as u64
}

/// What one outer step produced, for the recorder.
#[derive(Clone, Debug, PartialEq)]
pub struct OuterOut {
    /// Reference position, NED, m.
    pub reference: Vector3<f64>,
    /// Filter region name.
    pub region: &'static str,
    /// Filter region code ([`Region::code`]).
    pub region_code: u8,
    /// Obstacle the filter acted on.
    pub active_obstacle: Option<u16>,
    /// The filter changed u*.
    pub filter_active: bool,
    /// The path follower has reached the end of the path.
    pub path_done: bool,
    /// Nominal acceleration u* (PD output), NED, m/s².
    pub u_nominal: Vector3<f64>,
    /// Filtered acceleration u (filter output), NED, m/s².
    pub u_filtered: Vector3<f64>,
    /// The filter's own min h̄ over the obstacles it was given (controller's estimate), m².
    pub filter_h_bar: f64,
    /// Barriers enforced this step.
    pub n_constraints: u8,
    /// The filter flagged a constraint it cannot meet with the available acceleration.
    pub unavoidable: bool,
    /// The enforced constraints had no common solution.
    pub infeasible: bool,
    /// Guidance mode of the controller (e.g. "Mission", "Brake").
    pub mode: &'static str,
    /// Deadlock and obstacle-set flags (issue 17).
    pub safety: SafetyFlags,
}

impl OuterOut {
    /// The recorder's view of the controller's telemetry after an outer step.
    pub fn from_telemetry(tel: &Telemetry) -> Self {
        OuterOut {
            reference: to_f64(&tel.reference.position),
            region: region_name(tel.filter.region),
            region_code: tel.filter.region.code(),
            active_obstacle: tel.filter.active_id,
            filter_active: tel.filter.intervened,
            path_done: tel.progress.done,
            u_nominal: to_f64(&tel.u_nominal),
            u_filtered: to_f64(&tel.u_filtered),
            filter_h_bar: tel.filter.h_bar as f64,
            n_constraints: tel.filter.n_constraints,
            unavoidable: tel.filter.unavoidable,
            infeasible: tel.filter.infeasible,
            mode: tel.mode.as_str(),
            safety: SafetyFlags {
                deadlock: tel.robust.deadlock,
                obstacles_dropped: tel.obstacle_set.dropped,
                obstacles_dropped_near: tel.obstacle_set.dropped_near,
            },
        }
    }
}

/// Region name for reports.
pub fn region_name(r: Region) -> &'static str {
    match r {
        Region::NoObstacle => "none",
        Region::Far => "far",
        Region::NominalSafe => "nominal_safe",
        Region::Perpendicular => "filtering",
        Region::Fault => "fault",
    }
}

/// The controller parameters of a run: defaults of the core with the scene's
/// vehicle and the run's tracking / filter / speed settings.
pub fn controller_params(
    scene: &Scene,
    cfg: &RunConfig,
    cbf: CbfParams,
    variant: FilterVariant,
) -> ControllerParams {
    let af = scene.vehicle.airframe();
    let d = ControllerParams::default();
    ControllerParams {
        airframe: af,
        // The core's tracking defaults (vertical integral off: with the paper's soft
        // gains a z integrator is badly damped, and unstable once ki_z > kp·kd) with
        // the run's kp, kd on every axis.
        tracking: TrackingParams {
            kp: [cfg.params.kp as f32; 3],
            kd: [cfg.params.kd as f32; 3],
            ..d.tracking
        },
        cbf,
        filter_variant: variant,
        // The scene's hull bounds δ from below; the lag model uses its motor (issue 17).
        hull_radius: scene.vehicle.hull_radius as f32,
        robust: parapet_core::robust::RobustParams { motor_tau: scene.vehicle.motor_tau as f32, ..d.robust },
        thrust: ThrustParams {
            mass: af.mass,
            // 90 % of the rotors' total, leaving attitude authority (the core's default rule).
            thrust_max: 0.9 * 4.0 * af.rotor_thrust_max,
            ..d.thrust
        },
        attitude: parapet_core::attitude::AttitudeParams { inertia: af.inertia, ..d.attitude },
        waypoint: WaypointParams { cruise_speed: cfg.params.speed as f32, ..d.waypoint },
        ..d
    }
}

/// What the runner needs from a flight controller, in simulated time `t` (s).
/// Implemented by [`Controller`] (in-process `FlightController`); a
/// processor-in-the-loop link can implement it too. Call order per 1 ms step:
/// every 4th step `position_fix` (when a fix is due) then `outer`; every step `inner`.
pub trait Autopilot {
    /// Start-up at `t` with the vehicle hovering at `start` (NED): initialise,
    /// arm, hold `start`, start the mission.
    fn start(
        &mut self,
        t: f64,
        start: Vector3<f64>,
        fix: PositionReading,
        obstacles: &[ObstaclePoint],
        imu: &ImuReading,
    ) -> Result<()>;
    /// A position/velocity/yaw fix measured at `fix.t_measured`.
    fn position_fix(&mut self, fix: PositionReading);
    /// Outer step at `t` with the sensed obstacles; returns what the recorder needs.
    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut;
    /// Inner step at `t`: IMU in, motor throttles (0..1, rotors 1..4) out.
    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4];
    /// Name of the controller's failsafe state (e.g. "Armed").
    fn state_name(&self) -> String;
}

/// The flight controller as the runner drives it.
pub struct Controller {
    fc: FlightController,
    cbf: bool,
}

impl Controller {
    /// Build the controller and give it the path. Errors name the rejected parameter or path.
    pub fn new(scene: &Scene, cfg: &RunConfig, cbf: CbfParams) -> Result<Self> {
        Self::with_params(scene, cfg, controller_params(scene, cfg, cbf, cfg.variant))
    }

    /// [`new`](Self::new) with explicit controller parameters (e.g. [`controller_params`]
    /// with a slowed attitude loop, for tests).
    pub fn with_params(scene: &Scene, cfg: &RunConfig, params: ControllerParams) -> Result<Self> {
        let mut fc = FlightController::new(params)
            .map_err(|e| anyhow!("{}", crate::validate::describe_param_error(scene, &params, e)))?;
        let wps: Vec<Vec3> = cfg.path.iter().map(to_f32).collect();
        fc.set_path(&wps).map_err(|e| {
            anyhow!("path rejected by the controller: {}", crate::validate::describe_command_error(e))
        })?;
        Ok(Controller { fc, cbf: cfg.cbf })
    }

    fn report_obstacles(&mut self, now: u64, obstacles: &[ObstaclePoint]) {
        if self.cbf {
            self.fc.update_obstacles(now, obstacles);
        } else {
            self.fc.update_obstacles(now, &[]);
        }
    }

    /// Latest telemetry.
    pub fn telemetry(&self) -> Telemetry {
        self.fc.telemetry()
    }
}

impl Autopilot for Controller {
    /// Start-up at simulated time `t` (see the module docs).
    fn start(
        &mut self,
        t: f64,
        start: Vector3<f64>,
        fix: PositionReading,
        obstacles: &[ObstaclePoint],
        imu: &ImuReading,
    ) -> Result<()> {
        let now = clock_us(t);
        self.fc.step_inner(now, &imu_sample(imu));
        self.position_fix(fix);
        self.report_obstacles(now, obstacles);
        self.fc.arm(now).map_err(|e| match e {
            CommandError::Arm(r) => anyhow!("the flight controller refused to arm at the start: {r}"),
            other => anyhow!(
                "the flight controller refused to arm at the start: {}",
                crate::validate::describe_command_error(other)
            ),
        })?;
        self.fc
            .hold_position(now, to_f32(&start))
            .map_err(|e| anyhow!("hold refused: {}", crate::validate::describe_command_error(e)))?;
        self.fc.step_outer(now);
        self.fc
            .start_mission(now)
            .map_err(|e| anyhow!("mission start refused: {}", crate::validate::describe_command_error(e)))?;
        Ok(())
    }

    /// A position/velocity/yaw fix (measured at `fix.t_measured`).
    fn position_fix(&mut self, fix: PositionReading) {
        self.fc.update_position(PositionFix {
            t_us: clock_us(fix.t_measured),
            position: to_f32(&fix.position),
            velocity: to_f32(&fix.velocity),
            yaw: Some(fix.yaw as f32),
        });
    }

    /// One outer step at simulated time `t` with the obstacles the proximity sensor reports.
    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        let now = clock_us(t);
        self.report_obstacles(now, obstacles);
        self.fc.step_outer(now);
        OuterOut::from_telemetry(&self.fc.telemetry())
    }

    /// One inner step at simulated time `t`: IMU in, throttles out.
    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        self.fc.step_inner(clock_us(t), &imu_sample(imu)).throttle
    }

    fn state_name(&self) -> String {
        format!("{:?}", self.fc.state())
    }
}

fn imu_sample(imu: &ImuReading) -> ImuSample {
    ImuSample { gyro: to_f32(&imu.gyro), accel: to_f32(&imu.accel) }
}
