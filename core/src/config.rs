//! The controller's parameters: [`ControllerParams`] (every stage's parameter struct plus
//! the loop rates and the mode limits, with the paper's defaults) and their validation
//! ([`ParamError`]). The named MAVLink view of these fields is [`crate::params`]; each stage
//! takes its own part ([`crate::outer::OuterParams`], [`crate::inner::InnerParams`]).
//!
//! May import: the stages' parameter types ([`crate::outer`], [`crate::inner`],
//! [`crate::safety`], [`crate::plant_aware`], [`crate::supervisor`]), never their loops or the controller facade.

use crate::airframe::Airframe;
use crate::attitude::{AttitudeController, AttitudeError, AttitudeParams};
use crate::battery::BatteryParams;
use crate::calibration::SensorCal;
use crate::cbf::{CbfError, CbfParams, FilterVariant};
use crate::estimator::{EstimatorError, EstimatorParams};
use crate::failsafe::FailsafeParams;
use crate::frame::GRAVITY;
use crate::governor::GovernorParams;
use crate::mixer::{Mixer, MixerError};
use crate::outer::guidance::GuidanceParams;
use crate::param_decl::{field, Has, Param};
use crate::perception::MemoryParams;
use crate::plant_aware::{PlantAwareError, PlantAwareParams};
use crate::rc::map::RcParams;
use crate::supervisor::modes::ModeParams;
use crate::supervisor::LandingParams;
use crate::thrust::ThrustParams;
use crate::tracking::TrackingParams;
use crate::waypoint::{PathError, WaypointParams};

/// All controller parameters, with the paper's defaults (office experiment).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerParams {
    /// Vehicle (mass, inertia, rotor layout and limits). Default: the paper's 0.5 kg quadrotor.
    pub airframe: Airframe,
    /// PD tracking (eq. 2). Default kp 0.5 1/s², kd 0.8 1/s (paper, office), other limits as
    /// [`TrackingParams::default`], but the **vertical integral off** (`ki_z = 0`): with the
    /// paper's gentle kp/kd the integral winds up during a height change (measured on the
    /// closed-loop test model, 1 m climb: ki_z 0.02 → 20 % overshoot, 0.05 → 31 %, 0.3 → 89 %;
    /// 0 → 12 %). Enable it (with stiffer kp/kd) when the mass or thrust model is uncertain.
    pub tracking: TrackingParams,
    /// CBF filter. Default μ 1.4 s, δ 0.05 m², δ1 0.1 m² (paper, office). The filter
    /// runs at the outer rate: for every variant but `Paper` (kept exactly as published)
    /// the controller raises `cbf.sample_time` to at least the outer period, so the
    /// event rule does not engage a sample late (see `cbf::CbfParams::sample_time`).
    pub cbf: CbfParams,
    /// Filter law. Default [`FilterVariant::default`].
    pub filter_variant: FilterVariant,
    /// Plant-aware wrapping of the filter (lag, disturbance observer, ground and
    /// ceiling, stall), used by every variant but `Paper`. Default [`PlantAwareParams::default`].
    pub plant_aware: PlantAwareParams,
    /// Radius of the sphere bounding the vehicle, m: `cbf.delta` must be at least
    /// its square (refused otherwise, [`ParamError::DeltaBelowHull`]). Default √0.05 m.
    pub hull_radius: f32,
    /// Thrust/attitude mapping limits (eq. 4-5; the mass is `airframe.mass`).
    pub thrust: ThrustParams,
    /// Attitude and rate loops (the inertia is `airframe.inertia`).
    pub attitude: AttitudeParams,
    /// Attitude estimator.
    pub estimator: EstimatorParams,
    /// Waypoint follower. Default cruise 0.25 m/s (paper, office), no corner smoothing.
    pub waypoint: WaypointParams,
    /// Failsafe limits.
    pub failsafe: FailsafeParams,
    /// Flight modes and their failsafes (issue 21; see [`ModeParams`]).
    pub modes: ModeParams,
    /// RC receiver channel map, ranges, switch thresholds, link-quality minimum (issue 21; see
    /// [`RcParams`]).
    pub rc: RcParams,
    /// Nominal outer-loop rate, Hz. Default 250.
    pub outer_rate_hz: f32,
    /// Nominal inner-loop rate, Hz. Default 1000.
    pub inner_rate_hz: f32,
    /// Takeoff ramp (speed 0.5 m/s, at most 120 m above home) and the yaw along a path
    /// (`MIS_YAW_*`, default: hold the heading at arming).
    pub guidance: GuidanceParams,
    /// Landing and braking (descent 0.3 m/s, …; see [`LandingParams`]).
    pub landing: LandingParams,
    /// Motor command while armed on the ground, 0..1. Default 0.1.
    pub idle_throttle: f32,
    /// Time constant of the low-pass on the fix-derived acceleration fed to the estimator, s. Default 0.05.
    pub accel_comp_tau_s: f32,
    /// Obstacle memory of the range-sensor perception (issue 19; used by the caller that
    /// feeds scans, not by the truth-fed default). Default [`MemoryParams::default`].
    pub perception: MemoryParams,
    /// Battery measurement and thresholds (issue 22; see [`BatteryParams`]).
    pub battery: BatteryParams,
    /// IMU calibration and board orientation (issue 22; see [`SensorCal`]).
    pub sensors: SensorCal,
    /// The in-flight speed governor (issue 36; `GOV_*`, [`crate::governor`]).
    pub governor: GovernorParams,
    /// On-board replanning (issue 38; used by the caller that runs the replanner,
    /// `crate::replan::Replanner`). Default [`crate::replan::ReplanParams::default`].
    pub replan: crate::replan::ReplanParams,
}

/// Default hull radius, m: √0.05, so the default δ = 0.05 m² is its square.
pub const DEFAULT_HULL_RADIUS: f32 = 0.223_606_8;

impl Default for ControllerParams {
    fn default() -> Self {
        let airframe = Airframe::default();
        ControllerParams {
            airframe,
            tracking: TrackingParams { ki_z: 0.0, ..TrackingParams::uniform(0.5, 0.8) },
            cbf: CbfParams::default(),
            filter_variant: FilterVariant::default(),
            plant_aware: PlantAwareParams::default(),
            hull_radius: DEFAULT_HULL_RADIUS,
            thrust: ThrustParams::default(),
            attitude: AttitudeParams::default(),
            estimator: EstimatorParams::default(),
            waypoint: WaypointParams::default(),
            failsafe: FailsafeParams::default(),
            modes: ModeParams::default(),
            rc: RcParams::default(),
            outer_rate_hz: crate::wire::rates::OUTER_RATE_HZ as f32,
            inner_rate_hz: crate::wire::rates::INNER_RATE_HZ as f32,
            guidance: GuidanceParams::default(),
            landing: LandingParams::default(),
            idle_throttle: 0.1,
            accel_comp_tau_s: 0.05,
            perception: MemoryParams::default(),
            battery: BatteryParams::default(),
            sensors: SensorCal::default(),
            governor: GovernorParams::default(),
            replan: crate::replan::ReplanParams::default(),
        }
    }
}

impl ControllerParams {
    /// The parameter of a field of the set itself (`crate::params`): the hull radius (issue 17;
    /// δ must be at least its square).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 1] {
        [
            Param::new("VEH_HULL_R", "Vehicle", "m", (0.01, 5.0), 4, field!(hull_radius),
                "Radius of the sphere bounding the vehicle; CBF_DELTA must be at least its square"),
        ]
    }
}

impl ControllerParams {
    /// The obstacle memory's parameters (`perception`) with the ground plane of the
    /// plant-aware filter (`robust.ground_height`, `GND_HEIGHT`) and `fov_walls` resolved for
    /// the path's yaw mode (`MIS_YAW_MODE` 0, heading held: walls when `PCP_FOV_WALLS` is 2).
    pub fn memory_params(&self) -> MemoryParams {
        let held = matches!(self.guidance.path_yaw.mode, crate::outer::path_yaw::YawMode::Hold);
        MemoryParams { ground_height: self.plant_aware.ground_height, ..self.perception }
            .with_heading_held(held)
    }
}

/// Why parameters were rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamError {
    /// Plant-aware wrapping parameters.
    PlantAware(PlantAwareError),
    /// `cbf.delta` is below the squared hull radius: the filter would let obstacles
    /// inside the hull. Both values are given (m²).
    DeltaBelowHull {
        /// The δ given, m².
        delta: f32,
        /// `hull_radius²`, m² (the smallest δ accepted).
        hull_sq: f32,
    },
    /// CBF parameters.
    Cbf(CbfError),
    /// Attitude/rate parameters.
    Attitude(AttitudeError),
    /// Estimator parameters.
    Estimator(EstimatorError),
    /// Airframe unusable by the mixer.
    Mixer(MixerError),
    /// Waypoint parameters.
    Waypoint(PathError),
    /// Failsafe limits (also the flight-mode and RC-map parameters).
    Failsafe,
    /// Tracking gains/limits not finite and ≥ 0.
    Tracking,
    /// Thrust mapping limits invalid (0 < thrust_min < m·g < thrust_max ≤ 4·f_max, tilt in (0, 1.5)).
    Thrust,
    /// A rate, speed, time or factor is not finite and positive / in range.
    Loop,
    /// Speed-governor parameters out of range (`GOV_MARGIN`, `GOV_DELAY`, `GOV_RANGE`).
    Governor,
}

impl core::fmt::Display for ParamError {
    /// The rule broken, in words (the CBF's with its own message; the others by kind).
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ParamError::Cbf(e) => write!(f, "filter: {e}"),
            ParamError::DeltaBelowHull { delta, hull_sq } => {
                write!(f, "CBF_DELTA {delta} m^2 is below the squared hull radius {hull_sq} m^2")
            }
            other => write!(f, "{other:?}"),
        }
    }
}

impl ControllerParams {
    /// Check every parameter (see [`ParamError`]).
    pub fn validate(&self) -> Result<(), ParamError> {
        self.cbf.validate().map_err(ParamError::Cbf)?;
        self.plant_aware.validate().map_err(ParamError::PlantAware)?;
        if !self.governor.valid() {
            return Err(ParamError::Governor);
        }
        let hull_sq = self.hull_radius * self.hull_radius;
        // A relative tolerance of 1e-6 accepts δ = r² computed in either precision.
        if !(self.hull_radius.is_finite() && self.hull_radius > 0.0)
            || self.cbf.delta < hull_sq * (1.0 - 1e-6)
        {
            return Err(ParamError::DeltaBelowHull { delta: self.cbf.delta, hull_sq });
        }
        // The attitude gains with the airframe's inertia (checked where the rate loop uses it).
        AttitudeController::new(self.attitude, self.airframe.inertia).map_err(ParamError::Attitude)?;
        self.estimator.validate().map_err(ParamError::Estimator)?;
        Mixer::new(&self.airframe).map_err(ParamError::Mixer)?;
        self.waypoint.validate().map_err(ParamError::Waypoint)?;
        if !self.failsafe.is_valid() || !self.modes.is_valid() || !self.rc.is_valid() {
            return Err(ParamError::Failsafe);
        }
        let nonneg = |x: f32| x.is_finite() && x >= 0.0;
        let pos = |x: f32| x.is_finite() && x > 0.0;
        let t = &self.tracking;
        if !(t.kp.iter().chain(t.kd.iter()).all(|&x| nonneg(x))
            && nonneg(t.ki_z)
            && nonneg(t.integral_limit_z)
            && pos(t.accel_max_xy)
            && pos(t.accel_max_up)
            && pos(t.accel_max_down))
        {
            return Err(ParamError::Tracking);
        }
        let a = &self.airframe;
        let th = &self.thrust;
        let hover = a.mass * GRAVITY;
        if !(pos(a.mass)
            && a.inertia.iter().all(|&j| pos(j))
            && pos(th.thrust_min)
            && th.thrust_min < hover
            && th.thrust_max.is_finite()
            && th.thrust_max > hover
            && th.thrust_max <= 4.0 * a.rotor_thrust_max
            && pos(th.tilt_max)
            && th.tilt_max < 1.5)
        {
            return Err(ParamError::Thrust);
        }
        let (g, l) = (&self.guidance, &self.landing);
        let ok = pos(self.outer_rate_hz)
            && pos(self.inner_rate_hz)
            && pos(g.takeoff_speed)
            && pos(g.takeoff_height_max)
            && g.path_yaw.is_valid()
            && g.trajectory.validate().is_ok()
            && pos(l.land_speed)
            && pos(l.land_lead)
            && pos(l.landed_speed)
            && l.landed_time_us > 0
            && pos(l.land_thrust_factor)
            && l.land_thrust_factor <= 1.0
            && l.land_no_fix_time_us > 0
            && nonneg(self.idle_throttle)
            && self.idle_throttle <= 1.0
            && pos(l.blind_brake_accel)
            && l.blind_brake_accel <= 5.0
            && pos(self.accel_comp_tau_s);
        if ok {
            Ok(())
        } else {
            Err(ParamError::Loop)
        }
    }
}
