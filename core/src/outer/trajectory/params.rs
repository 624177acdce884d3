//! The trajectory's parameters (limits, corner tolerance, tracking-error bound) with their
//! units, defaults and ranges, and their validation. Owns [`TrajectoryParams`] and
//! [`ParamError`] and the `TRJ_*` parameters ([`TrajectoryParams::params`]); imports
//! `param_decl` only.

use crate::param_decl::{field, Has, Param};

/// Which parameter is out of range (or NaN/Inf).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamError {
    /// [`TrajectoryParams::cruise_speed`] not in (0, 20] m/s.
    CruiseSpeed,
    /// [`TrajectoryParams::accel_horizontal`] not in (0, 15] m/s².
    AccelHorizontal,
    /// [`TrajectoryParams::speed_up`] not in (0, 10] m/s.
    SpeedUp,
    /// [`TrajectoryParams::speed_down`] not in (0, 10] m/s.
    SpeedDown,
    /// [`TrajectoryParams::accel_vertical`] not in (0, 15] m/s².
    AccelVertical,
    /// [`TrajectoryParams::jerk`] not in (0, 80] m/s³.
    Jerk,
    /// [`TrajectoryParams::corner_tolerance`] not in [0, 5] m.
    CornerTolerance,
    /// [`TrajectoryParams::tracking_error_bound`] not in (0, 10] m.
    TrackingErrorBound,
}

/// Limits of the trajectory (world NED, SI). The defaults are PX4's mission defaults where
/// PX4 has one (parameter names given); the ranges are checked by [`validate`](Self::validate).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrajectoryParams {
    /// Cruise speed: bound on the horizontal speed, m/s. Default 3, range (0, 20]
    /// (PX4 `MPC_XY_CRUISE` defaults to 5).
    pub cruise_speed: f32,
    /// Horizontal acceleration limit, m/s². Default 3 (PX4 `MPC_ACC_HOR`), range (0, 15].
    pub accel_horizontal: f32,
    /// Upward speed limit (−z), m/s. Default 3 (PX4 `MPC_Z_V_AUTO_UP`), range (0, 10].
    pub speed_up: f32,
    /// Downward speed limit (+z), m/s. Default 1.5 (PX4 `MPC_Z_V_AUTO_DN`), range (0, 10].
    pub speed_down: f32,
    /// Vertical acceleration limit, m/s². Default 3 (PX4 `MPC_ACC_UP_MAX` is 4,
    /// `MPC_ACC_DOWN_MAX` 3: the smaller), range (0, 15].
    pub accel_vertical: f32,
    /// Jerk limit along the path, m/s³. Default 4 (PX4 `MPC_JERK_AUTO`), range (0, 80].
    pub jerk: f32,
    /// Corner tolerance: the largest distance by which the flown curve may cut a corner of
    /// the polyline, m — the planner's clearance margin. Default 0.1, range [0, 5]; 0 stops
    /// at every corner.
    pub corner_tolerance: f32,
    /// Tracking error at which the trajectory's clock stops, m (see
    /// [`clock_scale`](super::clock_scale): full speed up to half of it). Default 0.5, range
    /// (0, 10] (PX4 `MPC_XY_ERR_MAX` is 2).
    pub tracking_error_bound: f32,
}

impl Default for TrajectoryParams {
    fn default() -> Self {
        TrajectoryParams {
            cruise_speed: 3.0,
            accel_horizontal: 3.0,
            speed_up: 3.0,
            speed_down: 1.5,
            accel_vertical: 3.0,
            jerk: 4.0,
            corner_tolerance: 0.1,
            tracking_error_bound: 0.5,
        }
    }
}

impl TrajectoryParams {
    /// The trajectory's limits as parameters (issue 35; `crate::params`, for
    /// `MIS_GUIDANCE` 1; PX4's `MPC_ACC_HOR`, `MPC_JERK_AUTO`, `MPC_Z_V_AUTO_*`,
    /// `MPC_XY_ERR_MAX`). The cruise speed is `WP_SPEED`.
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 7] {
        [
            Param::new("TRJ_ACC", "Mission", "m/s^2", (0.1, 15.0), 2, field!(accel_horizontal),
                "MIS_GUIDANCE 1: horizontal acceleration limit of the trajectory (tangential and lateral)"),
            Param::new("TRJ_ACC_VERT", "Mission", "m/s^2", (0.1, 15.0), 2, field!(accel_vertical),
                "MIS_GUIDANCE 1: vertical acceleration limit of the trajectory"),
            Param::new("TRJ_JERK", "Mission", "m/s^3", (0.1, 80.0), 2, field!(jerk),
                "MIS_GUIDANCE 1: jerk limit along the trajectory"),
            Param::new("TRJ_V_UP", "Mission", "m/s", (0.1, 10.0), 2, field!(speed_up),
                "MIS_GUIDANCE 1: upward speed limit of the trajectory"),
            Param::new("TRJ_V_DN", "Mission", "m/s", (0.1, 10.0), 2, field!(speed_down),
                "MIS_GUIDANCE 1: downward speed limit of the trajectory"),
            Param::new("TRJ_CORNER_TOL", "Mission", "m", (0.0, 5.0), 3, field!(corner_tolerance),
                "MIS_GUIDANCE 1: largest corner cut of the trajectory (the planner's margin); 0 stops at every corner"),
            Param::new("TRJ_ERR_MAX", "Mission", "m", (0.05, 10.0), 2, field!(tracking_error_bound),
                "MIS_GUIDANCE 1: tracking error at which the trajectory's clock stops (full speed up to half of it)"),
        ]
    }
}

/// `lo < x ≤ hi` (false for NaN).
fn in_open_closed(x: f32, lo: f32, hi: f32) -> bool {
    x > lo && x <= hi
}

impl TrajectoryParams {
    /// Check every field against its range (NaN and ±∞ are out of range); the first bad
    /// field is named.
    pub fn validate(&self) -> Result<(), ParamError> {
        let checks = [
            (in_open_closed(self.cruise_speed, 0.0, 20.0), ParamError::CruiseSpeed),
            (in_open_closed(self.accel_horizontal, 0.0, 15.0), ParamError::AccelHorizontal),
            (in_open_closed(self.speed_up, 0.0, 10.0), ParamError::SpeedUp),
            (in_open_closed(self.speed_down, 0.0, 10.0), ParamError::SpeedDown),
            (in_open_closed(self.accel_vertical, 0.0, 15.0), ParamError::AccelVertical),
            (in_open_closed(self.jerk, 0.0, 80.0), ParamError::Jerk),
            (self.corner_tolerance >= 0.0 && self.corner_tolerance <= 5.0, ParamError::CornerTolerance),
            (in_open_closed(self.tracking_error_bound, 0.0, 10.0), ParamError::TrackingErrorBound),
        ];
        match checks.iter().find(|(ok, _)| !ok) {
            Some((_, e)) => Err(*e),
            None => Ok(()),
        }
    }
}
