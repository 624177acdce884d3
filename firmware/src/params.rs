//! Tunable parameters over MAVLink (PARAM_SET / PARAM_REQUEST_READ → PARAM_VALUE): the scene
//! settings a simulator run or a flight changes, mapped onto `ControllerParams`.
//!
//! | name | field | unit / values |
//! |---|---|---|
//! | `CBF_MU` | `cbf.mu` | s |
//! | `CBF_DELTA` | `cbf.delta` | m² |
//! | `CBF_DELTA1` | `cbf.delta1` | m² |
//! | `CBF_ACC_BOUND` | `cbf.accel_bound` | m/s² |
//! | `CBF_VARIANT` | `filter_variant` | 0 paper, 1 relative, 2 multi, 3 multi-relative |
//! | `TRK_KP` | `tracking.kp` (all axes) | 1/s² |
//! | `TRK_KD` | `tracking.kd` (all axes) | 1/s |
//! | `WP_SPEED` | `waypoint.cruise_speed` | m/s |
//! | `FS_OBST_REQ` | `failsafe.obstacles_required` | 0 / 1 |
//!
//! Values are REAL32. The cascade takes a new value only while disarmed and only if the whole
//! parameter set still validates; it is rebuilt, which clears its path, fix and obstacles (set
//! parameters before the mission upload).

use parapet_core::cbf::FilterVariant;
use parapet_core::controller::ControllerParams;

/// Parameter names, in index order.
pub const NAMES: [&str; 9] = [
    "CBF_MU",
    "CBF_DELTA",
    "CBF_DELTA1",
    "CBF_ACC_BOUND",
    "CBF_VARIANT",
    "TRK_KP",
    "TRK_KD",
    "WP_SPEED",
    "FS_OBST_REQ",
];

/// Index of `name` in [`NAMES`].
pub fn index_of(name: &str) -> Option<usize> {
    NAMES.iter().position(|n| *n == name)
}

fn variant_code(v: FilterVariant) -> f32 {
    match v {
        FilterVariant::Paper => 0.0,
        FilterVariant::Relative => 1.0,
        FilterVariant::Multi => 2.0,
        FilterVariant::MultiRelative => 3.0,
    }
}

/// Current value of `name`.
pub fn get(p: &ControllerParams, name: &str) -> Option<f32> {
    Some(match name {
        "CBF_MU" => p.cbf.mu,
        "CBF_DELTA" => p.cbf.delta,
        "CBF_DELTA1" => p.cbf.delta1,
        "CBF_ACC_BOUND" => p.cbf.accel_bound,
        "CBF_VARIANT" => variant_code(p.filter_variant),
        "TRK_KP" => p.tracking.kp[0],
        "TRK_KD" => p.tracking.kd[0],
        "WP_SPEED" => p.waypoint.cruise_speed,
        "FS_OBST_REQ" => f32::from(u8::from(p.failsafe.obstacles_required)),
        _ => return None,
    })
}

/// Why a value was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamRejected {
    /// No such parameter.
    Unknown,
    /// Not finite, not an allowed value, or the resulting set does not validate.
    Invalid,
    /// Not while armed.
    NotNow,
}

/// Writes `value` into `p` (no validation of the whole set; see [`ControllerParams::validate`]).
pub fn set(p: &mut ControllerParams, name: &str, value: f32) -> Result<(), ParamRejected> {
    if !value.is_finite() {
        return Err(ParamRejected::Invalid);
    }
    match name {
        "CBF_MU" => p.cbf.mu = value,
        "CBF_DELTA" => p.cbf.delta = value,
        "CBF_DELTA1" => p.cbf.delta1 = value,
        "CBF_ACC_BOUND" => p.cbf.accel_bound = value,
        "CBF_VARIANT" => {
            p.filter_variant = match value as i32 {
                0 if value == 0.0 => FilterVariant::Paper,
                1 if value == 1.0 => FilterVariant::Relative,
                2 if value == 2.0 => FilterVariant::Multi,
                3 if value == 3.0 => FilterVariant::MultiRelative,
                _ => return Err(ParamRejected::Invalid),
            }
        }
        "TRK_KP" => p.tracking.kp = [value; 3],
        "TRK_KD" => p.tracking.kd = [value; 3],
        "WP_SPEED" => p.waypoint.cruise_speed = value,
        "FS_OBST_REQ" => {
            p.failsafe.obstacles_required = if value == 0.0 {
                false
            } else if value == 1.0 {
                true
            } else {
                return Err(ParamRejected::Invalid);
            }
        }
        _ => return Err(ParamRejected::Unknown),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_round_trips() {
        let mut p = ControllerParams::default();
        for (i, name) in NAMES.iter().enumerate() {
            assert_eq!(index_of(name), Some(i));
            let v = match *name {
                "CBF_VARIANT" => 1.0,
                "FS_OBST_REQ" => 0.0,
                _ => 0.75,
            };
            assert_eq!(set(&mut p, name, v), Ok(()), "{name}");
            assert_eq!(get(&p, name), Some(v), "{name}");
        }
        assert_eq!(p.tracking.kd, [0.75; 3]);
        assert_eq!(p.filter_variant, FilterVariant::Relative);
        assert!(!p.failsafe.obstacles_required);
    }

    #[test]
    fn bad_values_are_refused() {
        let mut p = ControllerParams::default();
        assert_eq!(set(&mut p, "CBF_MU", f32::NAN), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "CBF_VARIANT", 1.5), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "CBF_VARIANT", 7.0), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "FS_OBST_REQ", 0.5), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "NOPE", 1.0), Err(ParamRejected::Unknown));
        assert_eq!(get(&p, "NOPE"), None);
        assert_eq!(p, ControllerParams::default());
    }
}
