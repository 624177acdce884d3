//! The vehicle-state inputs of the link: the lockstep IMU sample of HIL_SENSOR ([`HilSample`])
//! and its barometer height ([`hil_baro_down`]) and magnetometer field ([`hil_mag`]),
//! the ODOMETRY → position fix conversion ([`odometry_fix`]) and whose clock stamps a fix
//! ([`FixClock`]). Split out of [`crate::link::router`] (one file per concern).
//!
//! May import: `parapet_core`, the dialect, [`crate::app`] (the `Autopilot` boundary types).

use crate::app::autopilot::{ImuSample, PositionFix};
use crate::link::dialect::{HilSensorUpdatedFlags, MavFrame, HIL_SENSOR_DATA, ODOMETRY_DATA};
use parapet_core::nalgebra::{Quaternion, UnitQuaternion};
use parapet_core::wire::geo::{down_m, AltRef, MAX_RANGE_M};
use parapet_core::Vec3;

/// One simulated IMU sample from HIL_SENSOR.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HilSample {
    /// Simulated time, µs (the firmware clock on the lockstep link).
    pub time_usec: u64,
    /// Gyro and specific force, body FRD.
    pub imu: ImuSample,
}

impl HilSample {
    /// HIL_SENSOR → sample (xgyro.. rad/s FRD, xacc.. m/s² FRD specific force).
    pub fn from_message(m: &HIL_SENSOR_DATA) -> Self {
        Self {
            time_usec: m.time_usec,
            imu: ImuSample {
                gyro: Vec3::new(m.xgyro, m.ygyro, m.zgyro),
                accel: Vec3::new(m.xacc, m.yacc, m.zacc),
            },
        }
    }
}

/// The barometer height of a HIL_SENSOR (NED down, m): its `pressure_alt` (m AMSL; home at
/// `wire::geo::ORIGIN`'s altitude) when `fields_updated` has `HIL_SENSOR_UPDATED_PRESSURE_ALT`;
/// `None` without it, for a non-finite value or one farther than `MAX_RANGE_M` from home.
pub fn hil_baro_down(m: &HIL_SENSOR_DATA) -> Option<f32> {
    if !m.fields_updated.contains(HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_PRESSURE_ALT) {
        return None;
    }
    let down = down_m(m.pressure_alt, AltRef::Amsl);
    (down.is_finite() && down.abs() <= MAX_RANGE_M).then_some(down)
}

/// The magnetometer field of a HIL_SENSOR (body FRD, gauss) when `fields_updated` has the
/// XMAG, YMAG and ZMAG bits and the three values are finite; `None` otherwise.
pub fn hil_mag(m: &HIL_SENSOR_DATA) -> Option<Vec3> {
    let all = HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_XMAG
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_YMAG
        | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_ZMAG;
    let b = Vec3::new(m.xmag, m.ymag, m.zmag);
    (m.fields_updated.contains(all) && b.iter().all(|x| x.is_finite())).then_some(b)
}

/// Whose clock time-stamps a position fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FixClock {
    /// The firmware's clock when the message arrived (radio link: the companion's clock is
    /// not the firmware's).
    Arrival,
    /// The message's `time_usec` (lockstep link: simulated time is the firmware clock).
    Message,
}

/// STATUSTEXT of an ODOMETRY refused for its frame (LOCAL_FRD, …).
pub const ODOMETRY_REFUSED_TEXT: &str = "ODOMETRY refused: frame must be LOCAL_NED";
/// Shortest interval between two such STATUSTEXTs, µs.
pub const ODOMETRY_TEXT_US: u64 = 10_000_000;

/// Converts ODOMETRY into a position fix (with the yaw of `q` when it is a valid attitude);
/// `None` for unsupported frames or non-finite data.
pub fn odometry_fix(m: &ODOMETRY_DATA, t_us: u64) -> Option<PositionFix> {
    if m.frame_id != MavFrame::MAV_FRAME_LOCAL_NED {
        return None;
    }
    let p = Vec3::new(m.x, m.y, m.z);
    let v_raw = Vec3::new(m.vx, m.vy, m.vz);
    let v = match m.child_frame_id {
        MavFrame::MAV_FRAME_LOCAL_NED => v_raw,
        MavFrame::MAV_FRAME_BODY_FRD => {
            let q = Quaternion::new(m.q[0], m.q[1], m.q[2], m.q[3]);
            let n = q.norm();
            if !n.is_finite() || n < 0.5 {
                return None;
            }
            UnitQuaternion::from_quaternion(q) * v_raw
        }
        _ => return None,
    };
    if !(p.iter().chain(v.iter()).all(|x| x.is_finite())) {
        return None;
    }
    // The heading the fix measures (as `parapet run` feeds the estimator); unknown (zero or
    // NaN quaternion) → none.
    let yaw = parapet_core::wire::codes::odometry_yaw(m.q);
    Some(PositionFix { t_us, position: p, velocity: v, yaw })
}
