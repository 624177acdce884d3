//! Named, individually settable controller parameters: the table a ground station
//! (MAVLink PARAM_SET / PARAM_REQUEST_READ → PARAM_VALUE in the firmware) or the
//! processor-in-the-loop host uses to give a [`ControllerParams`] the settings of a
//! flight or a simulated scene. Shared by the firmware and the host so that both
//! map names onto fields the same way.
//!
//! | name | field(s) | unit / values |
//! |---|---|---|
//! | `CBF_MU` | `cbf.mu` | s |
//! | `CBF_DELTA` | `cbf.delta` | m² |
//! | `CBF_DELTA1` | `cbf.delta1` | m² |
//! | `CBF_ACC_BOUND` | `cbf.accel_bound` | m/s² |
//! | `CBF_VEL_MARGIN` | `cbf.velocity_margin` | m/s |
//! | `CBF_VARIANT` | `filter_variant` | 0 paper, 1 relative, 2 multi, 3 multi-relative |
//! | `TRK_KP` | `tracking.kp` (all axes) | 1/s² |
//! | `TRK_KD` | `tracking.kd` (all axes) | 1/s |
//! | `WP_SPEED` | `waypoint.cruise_speed` | m/s |
//! | `FS_OBST_REQ` | `failsafe.obstacles_required` | 0 / 1 |
//! | `VEH_MASS` | `airframe.mass` and `thrust.mass` | kg |
//! | `VEH_IXX`, `VEH_IYY`, `VEH_IZZ` | `airframe.inertia[i]` and `attitude.inertia[i]` | kg·m² |
//! | `VEH_ARM` | `airframe.arm_length` | m |
//! | `VEH_ROTOR_TMAX` | `airframe.rotor_thrust_max` | N, one rotor |
//! | `VEH_KAPPA` | `airframe.torque_to_thrust` | m |
//! | `THR_MAX` | `thrust.thrust_max` | N, collective |
//!
//! Values are `f32`. [`set`] writes one field (two for the mass and the inertia,
//! which the controller keeps in two places that must agree); it checks only that
//! the value is finite and allowed. Whether the whole set is usable is
//! [`ControllerParams::validate`]'s decision, which the caller makes after each
//! change: a change that leaves an invalid set must be refused as a whole. Some
//! changes are valid only in a certain order (a heavier vehicle needs the larger
//! `THR_MAX` first); [`plan_updates`] finds such an order.

use crate::cbf::FilterVariant;
use crate::controller::ControllerParams;

/// Number of parameters.
pub const COUNT: usize = 18;

/// Parameter names, in index order (MAVLink `param_index`), each at most 16 bytes.
pub const NAMES: [&str; COUNT] = [
    "CBF_MU",
    "CBF_DELTA",
    "CBF_DELTA1",
    "CBF_ACC_BOUND",
    "CBF_VARIANT",
    "TRK_KP",
    "TRK_KD",
    "WP_SPEED",
    "FS_OBST_REQ",
    "CBF_VEL_MARGIN",
    "VEH_MASS",
    "VEH_IXX",
    "VEH_IYY",
    "VEH_IZZ",
    "VEH_ARM",
    "VEH_ROTOR_TMAX",
    "VEH_KAPPA",
    "THR_MAX",
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

/// Current value of `name` in `p`.
pub fn get(p: &ControllerParams, name: &str) -> Option<f32> {
    Some(match name {
        "CBF_MU" => p.cbf.mu,
        "CBF_DELTA" => p.cbf.delta,
        "CBF_DELTA1" => p.cbf.delta1,
        "CBF_ACC_BOUND" => p.cbf.accel_bound,
        "CBF_VEL_MARGIN" => p.cbf.velocity_margin,
        "CBF_VARIANT" => variant_code(p.filter_variant),
        "TRK_KP" => p.tracking.kp[0],
        "TRK_KD" => p.tracking.kd[0],
        "WP_SPEED" => p.waypoint.cruise_speed,
        "FS_OBST_REQ" => f32::from(u8::from(p.failsafe.obstacles_required)),
        "VEH_MASS" => p.airframe.mass,
        "VEH_IXX" => p.airframe.inertia[0],
        "VEH_IYY" => p.airframe.inertia[1],
        "VEH_IZZ" => p.airframe.inertia[2],
        "VEH_ARM" => p.airframe.arm_length,
        "VEH_ROTOR_TMAX" => p.airframe.rotor_thrust_max,
        "VEH_KAPPA" => p.airframe.torque_to_thrust,
        "THR_MAX" => p.thrust.thrust_max,
        _ => return None,
    })
}

/// Why a value was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamRejected {
    /// No such parameter.
    Unknown,
    /// Not finite, not an allowed value, or the resulting set does not validate.
    Invalid,
    /// Not now (e.g. while armed).
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
        "CBF_VEL_MARGIN" => p.cbf.velocity_margin = value,
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
        "VEH_MASS" => {
            p.airframe.mass = value;
            p.thrust.mass = value;
        }
        "VEH_IXX" | "VEH_IYY" | "VEH_IZZ" => {
            let i = match name {
                "VEH_IXX" => 0,
                "VEH_IYY" => 1,
                _ => 2,
            };
            p.airframe.inertia[i] = value;
            p.attitude.inertia[i] = value;
        }
        "VEH_ARM" => p.airframe.arm_length = value,
        "VEH_ROTOR_TMAX" => p.airframe.rotor_thrust_max = value,
        "VEH_KAPPA" => p.airframe.torque_to_thrust = value,
        "THR_MAX" => p.thrust.thrust_max = value,
        _ => return Err(ParamRejected::Unknown),
    }
    Ok(())
}

/// Why [`plan_updates`] found no way to reach the target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlanError {
    /// The target itself does not validate.
    InvalidTarget,
    /// The target differs from the start in a field no parameter sets; the first such
    /// field is named.
    NotSettable(&'static str),
    /// No order of single changes keeps every intermediate set valid; `name` is one of
    /// the parameters left over.
    NoValidOrder(&'static str),
}

/// The changes that take `from` to `to`, in an order in which every intermediate set
/// validates (each step is one [`set`] as the firmware applies it). Returns the
/// number of entries written to `out` (`name`, value), at most [`COUNT`]. Bounded:
/// at most `COUNT²` validations.
pub fn plan_updates(
    from: &ControllerParams,
    to: &ControllerParams,
    out: &mut [(&'static str, f32); COUNT],
) -> Result<usize, PlanError> {
    if to.validate().is_err() {
        return Err(PlanError::InvalidTarget);
    }
    // Every difference must be representable: applying all the target's values to
    // `from` must give `to` exactly.
    let mut all = *from;
    for name in NAMES {
        if let Some(v) = get(to, name) {
            set(&mut all, name, v).map_err(|_| PlanError::NotSettable(name))?;
        }
    }
    if all != *to {
        return Err(PlanError::NotSettable(first_unsettable_field(&all, to)));
    }
    let mut pending = [false; COUNT];
    for (i, name) in NAMES.iter().enumerate() {
        pending[i] = get(from, name).map(f32::to_bits) != get(to, name).map(f32::to_bits);
    }
    let mut cur = *from;
    let mut n = 0;
    // Each pass applies at least one pending change or stops: at most COUNT passes.
    for _ in 0..COUNT {
        let mut progressed = false;
        for (i, name) in NAMES.iter().enumerate() {
            if !pending[i] {
                continue;
            }
            let Some(v) = get(to, name) else { continue };
            let mut next = cur;
            if set(&mut next, name, v).is_ok() && next.validate().is_ok() {
                cur = next;
                pending[i] = false;
                out[n] = (name, v);
                n += 1;
                progressed = true;
            }
        }
        if !progressed {
            break;
        }
    }
    match pending.iter().position(|&p| p) {
        Some(i) => Err(PlanError::NoValidOrder(NAMES[i])),
        None => Ok(n),
    }
}

/// Name of the first top-level field in which `a` and `b` differ (for error messages).
fn first_unsettable_field(a: &ControllerParams, b: &ControllerParams) -> &'static str {
    if a.airframe != b.airframe {
        "airframe"
    } else if a.tracking != b.tracking {
        "tracking"
    } else if a.cbf != b.cbf {
        "cbf"
    } else if a.thrust != b.thrust {
        "thrust"
    } else if a.attitude != b.attitude {
        "attitude"
    } else if a.estimator != b.estimator {
        "estimator"
    } else if a.waypoint != b.waypoint {
        "waypoint"
    } else if a.failsafe != b.failsafe {
        "failsafe"
    } else {
        "loop rates and timing"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_round_trips() {
        let mut p = ControllerParams::default();
        for (i, name) in NAMES.iter().enumerate() {
            assert!(name.len() <= 16, "{name} is longer than a MAVLink param_id");
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
        // The mass and the inertia are kept consistent in both places.
        assert_eq!(p.thrust.mass, p.airframe.mass);
        assert_eq!(p.attitude.inertia, p.airframe.inertia);
    }

    #[test]
    fn bad_values_are_refused() {
        let mut p = ControllerParams::default();
        assert_eq!(set(&mut p, "CBF_MU", f32::NAN), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "VEH_MASS", f32::INFINITY), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "CBF_VARIANT", 1.5), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "CBF_VARIANT", 7.0), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "FS_OBST_REQ", 0.5), Err(ParamRejected::Invalid));
        assert_eq!(set(&mut p, "NOPE", 1.0), Err(ParamRejected::Unknown));
        assert_eq!(get(&p, "NOPE"), None);
        assert_eq!(p, ControllerParams::default());
    }

    fn apply(from: &ControllerParams, plan: &[(&'static str, f32)]) -> ControllerParams {
        let mut p = *from;
        for (name, v) in plan {
            set(&mut p, name, *v).unwrap();
            assert!(p.validate().is_ok(), "invalid after {name} = {v}");
        }
        p
    }

    #[test]
    fn heavier_vehicle_needs_the_thrust_limit_first() {
        // 1.5 kg: hover thrust 14.7 N exceeds the default THR_MAX (11 N) and the default
        // rotors' 4 × 3.07 N, so VEH_ROTOR_TMAX, then THR_MAX, then VEH_MASS.
        let from = ControllerParams::default();
        let mut to = from;
        for (name, v) in [("VEH_ROTOR_TMAX", 9.0), ("THR_MAX", 30.0), ("VEH_MASS", 1.5), ("VEH_IZZ", 0.01)] {
            set(&mut to, name, v).unwrap();
        }
        assert!(to.validate().is_ok());
        // In table order the mass comes first and would be refused.
        let mut naive = from;
        set(&mut naive, "VEH_MASS", 1.5).unwrap();
        assert!(naive.validate().is_err());
        let mut out = [("", 0.0); COUNT];
        let n = plan_updates(&from, &to, &mut out).unwrap();
        assert_eq!(n, 4);
        assert_eq!(apply(&from, &out[..n]), to);
        let pos = |name| out[..n].iter().position(|(m, _)| *m == name).unwrap();
        assert!(pos("THR_MAX") < pos("VEH_MASS") && pos("VEH_ROTOR_TMAX") < pos("THR_MAX"));
    }

    #[test]
    fn unchanged_parameters_are_not_sent() {
        let p = ControllerParams::default();
        let mut out = [("", 0.0); COUNT];
        assert_eq!(plan_updates(&p, &p, &mut out), Ok(0));
    }

    #[test]
    fn fields_without_a_parameter_are_named() {
        let from = ControllerParams::default();
        let mut to = from;
        to.outer_rate_hz = 200.0;
        let mut out = [("", 0.0); COUNT];
        assert_eq!(plan_updates(&from, &to, &mut out), Err(PlanError::NotSettable("loop rates and timing")));
        let mut to = from;
        to.tracking.kp[2] = 0.9; // per-axis gains: TRK_KP sets all three
        assert_eq!(plan_updates(&from, &to, &mut out), Err(PlanError::NotSettable("tracking")));
        let mut to = from;
        to.cbf.mu = -1.0;
        assert_eq!(plan_updates(&from, &to, &mut out), Err(PlanError::InvalidTarget));
    }
}
