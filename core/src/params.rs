//! The controller's parameter table: every tunable parameter **once**, with its
//! MAVLink name, unit, default, range, one-line description and how it reads and
//! writes [`ControllerParams`]. Everything that names parameters is driven by
//! [`TABLE`]: the firmware's MAVLink parameter protocol (PARAM_SET /
//! PARAM_REQUEST_READ → PARAM_VALUE, `param_index` = table index, `param_count` =
//! [`COUNT`]), the processor-in-the-loop host (which sends a scene's settings as
//! PARAM_SETs), the scene file's `[controller]` keys and the `parapet` command-line
//! options ([`Param::key`]), the run summary, and the ground-station metadata file
//! (`cargo xtask params`, QGroundControl / PX4 `parameters.json` format).
//!
//! ## Validation: per parameter, no ordered updates
//! [`set`] checks a value against **that parameter's own** range ([`Param::min`],
//! [`Param::max`], finite, integral for [`Param::integer`] parameters) and nothing
//! else: every in-range value is accepted whatever the other parameters are, so any
//! set of changes can be sent one PARAM_SET at a time in any order. A refused value
//! leaves the set unchanged (MAVLink: the answer carries the value still in effect).
//!
//! The ranges are chosen so that each field's own rule in
//! [`ControllerParams::validate`] holds for every in-range value (e.g. `VEH_MASS`
//! ≥ 0.07 kg keeps the hover thrust above the built-in minimum thrust 0.6 N). Only
//! three constraints link parameters, and they are checked **at use**, on the whole
//! set, by [`ControllerParams::validate`] (see [`consistency`]):
//!
//! * `CBF_DELTA1` > `CBF_DELTA` (the filter engages above the safety level);
//! * `CBF_DELTA` ≥ `VEH_HULL_R`² (the safe set excludes obstacles inside the hull; issue 17);
//! * `VEH_MASS`·g < `THR_MAX` ≤ 4·`VEH_ROTOR_TMAX` (the vehicle can hover, and the
//!   collective limit is one the rotors can give).
//!
//! The defined outcome of an inconsistent set (the firmware's rule, `app::cascade` in `parapet-firmware`):
//! the stored values are what PARAM_VALUE reports, the controller keeps flying the
//! last consistent set, and arming is refused until the stored set is consistent
//! again. (The earlier design validated the whole set on every PARAM_SET, so some
//! changes had to be sent in a planned order: a heavier vehicle needed the larger
//! `THR_MAX` first.)
//!
//! Owns: [`Param`], [`TABLE`], [`COUNT`], [`ParamRejected`], lookup by name / key,
//! [`get`], [`set`]. May import: `config` (the [`ControllerParams`] struct),
//! `safety::cbf` (the filter variant codes), `supervisor::modes` (the flight-mode codes),
//! `frame` (tests). No allocation, no panics.

use crate::config::{ControllerParams, ParamError};
use crate::safety::cbf::FilterVariant;
use crate::supervisor::modes::{FlightMode, RcLossAction};

fn mode_label(code: i32) -> Option<&'static str> {
    FlightMode::from_code(code).map(FlightMode::as_str)
}

fn rc_act_label(code: i32) -> Option<&'static str> {
    match code {
        0 => Some("continue"),
        1 => Some("return"),
        _ => None,
    }
}

fn bat_act_label(code: i32) -> Option<&'static str> {
    match code {
        0 => Some("off"),
        1 => Some("return/land"),
        _ => None,
    }
}

/// `s` on the host, `""` on the flight controller (`target_os = "none"`): descriptions and
/// scene keys are read only by host tools (`cargo xtask params`, the scene parser, QGC metadata),
/// and on the F405 their strings would take ~5 KB of the 128 KiB flash.
pub const fn host_text(s: &'static str) -> &'static str {
    if cfg!(target_os = "none") {
        ""
    } else {
        s
    }
}

/// An `RC_MAP_*` entry: a whole channel number up to 18 (issue 21, `rc::map`).
const fn rc_map(
    name: &'static str,
    min: f32,
    default: f32,
    description: &'static str,
    get: fn(&ControllerParams) -> f32,
    write: fn(&mut ControllerParams, f32),
) -> Param {
    Param {
        name,
        key: None,
        unit: "",
        default,
        min,
        max: 18.0,
        integer: true,
        decimals: 0,
        group: "RC",
        description: host_text(description),
        label: None,
        get,
        write,
    }
}

/// An RC pulse-width entry (`RC_*_US`), µs.
const fn rc_us(
    name: &'static str,
    (min, default, max): (f32, f32, f32),
    description: &'static str,
    get: fn(&ControllerParams) -> f32,
    write: fn(&mut ControllerParams, f32),
) -> Param {
    Param {
        name,
        key: None,
        unit: "us",
        default,
        min,
        max,
        integer: false,
        decimals: 0,
        group: "RC",
        description: host_text(description),
        label: None,
        get,
        write,
    }
}

/// A continuous entry of the battery and sensor groups (issue 22).
#[allow(clippy::too_many_arguments)]
const fn num(
    name: &'static str,
    group: &'static str,
    unit: &'static str,
    (min, default, max): (f32, f32, f32),
    decimals: u8,
    description: &'static str,
    get: fn(&ControllerParams) -> f32,
    write: fn(&mut ControllerParams, f32),
) -> Param {
    Param {
        name,
        key: None,
        unit,
        default,
        min,
        max,
        integer: false,
        decimals,
        group,
        description: host_text(description),
        label: None,
        get,
        write,
    }
}

/// An accelerometer calibration entry (`CAL_ACC0_*`), per sensor axis.
const fn acc(
    name: &'static str,
    scale: bool,
    description: &'static str,
    get: fn(&ControllerParams) -> f32,
    write: fn(&mut ControllerParams, f32),
) -> Param {
    let (unit, range) = if scale {
        ("", (crate::calibration::ACCEL_SCALE_RANGE.0, 1.0, crate::calibration::ACCEL_SCALE_RANGE.1))
    } else {
        ("m/s^2", (-crate::calibration::ACCEL_OFFSET_MAX, 0.0, crate::calibration::ACCEL_OFFSET_MAX))
    };
    num(name, "Sensors", unit, range, 4, description, get, write)
}

/// One parameter: the single place its name, unit, default, range and meaning are written.
#[derive(Clone, Copy)]
pub struct Param {
    /// MAVLink `param_id` (≤ 16 ASCII bytes), e.g. `CBF_MU`.
    pub name: &'static str,
    /// Key of the scene file's `[controller]` table and of the `parapet` command-line
    /// option (`--key`), when the host exposes the parameter there; `None` otherwise
    /// (the vehicle parameters come from the scene's `[vehicle]` table instead).
    pub key: Option<&'static str>,
    /// Unit (SI), `""` for codes and flags.
    pub unit: &'static str,
    /// Default value: [`ControllerParams::default`]'s (a test checks they agree).
    pub default: f32,
    /// Smallest allowed value.
    pub min: f32,
    /// Largest allowed value.
    pub max: f32,
    /// `true` for codes and flags: only whole numbers in `[min, max]`.
    pub integer: bool,
    /// Decimal places a ground station should show.
    pub decimals: u8,
    /// Ground-station group (`CBF`, `Tracking`, …).
    pub group: &'static str,
    /// One-line description (host builds only: `""` on the flight controller, see [`host_text`]).
    pub description: &'static str,
    /// Names of the values of a code parameter (`None` for a continuous one).
    pub label: Option<fn(i32) -> Option<&'static str>>,
    /// Reads the parameter from a set.
    pub get: fn(&ControllerParams) -> f32,
    /// Writes a value that [`Param::check`] accepted.
    write: fn(&mut ControllerParams, f32),
}

impl core::fmt::Debug for Param {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Param")
            .field("name", &self.name)
            .field("unit", &self.unit)
            .field("default", &self.default)
            .field("min", &self.min)
            .field("max", &self.max)
            .finish_non_exhaustive()
    }
}

impl Param {
    /// `value` if this parameter accepts it: finite, in `[min, max]`, whole for codes.
    pub fn check(&self, value: f32) -> Result<f32, ParamRejected> {
        // `!(a ≤ x ≤ b)` also refuses NaN; ±∞ are outside every finite range.
        if !(value >= self.min && value <= self.max) {
            return Err(ParamRejected::Invalid);
        }
        // In range, so the cast cannot saturate: whole numbers survive the round trip.
        if self.integer && (value as i32) as f32 != value {
            return Err(ParamRejected::Invalid);
        }
        Ok(value)
    }

    /// The allowed values in words, e.g. `0.01 ≤ CBF_MU ≤ 100 s` (for messages).
    pub fn range(&self) -> RangeText<'_> {
        RangeText(self)
    }
}

/// [`Param::range`]'s `Display`.
pub struct RangeText<'a>(&'a Param);

impl core::fmt::Display for RangeText<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let p = self.0;
        let name = p.key.unwrap_or(p.name);
        if p.integer {
            write!(f, "{name} one of")?;
            let (lo, hi) = (p.min as i32, p.max as i32);
            for c in lo..=hi {
                match p.label.and_then(|l| l(c)) {
                    Some(s) => write!(f, " {c} ({s})")?,
                    None => write!(f, " {c}")?,
                }
            }
            Ok(())
        } else {
            write!(f, "{} ≤ {name} ≤ {}", p.min, p.max)?;
            if !p.unit.is_empty() {
                write!(f, " {}", p.unit)?;
            }
            Ok(())
        }
    }
}

/// Why a value was not taken (the parameter keeps its value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamRejected {
    /// No such parameter.
    Unknown,
    /// Not finite, outside the parameter's range, or not a whole number for a code.
    Invalid,
    /// Not now (e.g. while armed).
    NotNow,
}

fn variant_code(v: FilterVariant) -> f32 {
    match v {
        FilterVariant::Paper => 0.0,
        FilterVariant::Relative => 1.0,
        FilterVariant::Multi => 2.0,
        FilterVariant::MultiRelative => 3.0,
    }
}

fn variant_of(code: i32) -> Option<FilterVariant> {
    match code {
        0 => Some(FilterVariant::Paper),
        1 => Some(FilterVariant::Relative),
        2 => Some(FilterVariant::Multi),
        3 => Some(FilterVariant::MultiRelative),
        _ => None,
    }
}

/// Number of parameters.
pub const COUNT: usize = 71;

/// The parameters, in MAVLink `param_index` order.
pub const TABLE: [Param; COUNT] = [
    Param {
        name: "CBF_MU",
        key: Some(host_text("mu")),
        unit: "s",
        default: 1.4,
        min: 0.01,
        max: 100.0,
        integer: false,
        decimals: 2,
        group: "CBF",
        description: host_text("Barrier velocity weight mu: the filter keeps h + mu*dh/dt above delta"),
        label: None,
        get: |p| p.cbf.mu,
        write: |p, v| p.cbf.mu = v,
    },
    Param {
        name: "CBF_DELTA",
        key: Some(host_text("delta")),
        unit: "m^2",
        default: 0.05,
        min: 1e-4,
        max: 100.0,
        integer: false,
        decimals: 4,
        group: "CBF",
        description: host_text("Safety level delta (hull radius squared); must stay below CBF_DELTA1"),
        label: None,
        get: |p| p.cbf.delta,
        write: |p, v| p.cbf.delta = v,
    },
    Param {
        name: "CBF_DELTA1",
        key: Some(host_text("delta1")),
        unit: "m^2",
        default: 0.1,
        min: 1e-4,
        max: 100.0,
        integer: false,
        decimals: 4,
        group: "CBF",
        description: host_text("Engagement level delta1 > CBF_DELTA: the filter acts below it"),
        label: None,
        get: |p| p.cbf.delta1,
        write: |p, v| p.cbf.delta1 = v,
    },
    Param {
        name: "CBF_ACC_BOUND",
        key: Some(host_text("accel_bound")),
        unit: "m/s^2",
        default: 0.0,
        min: 0.0,
        max: 50.0,
        integer: false,
        decimals: 2,
        group: "CBF",
        description: host_text("Bound A on the unknown obstacle acceleration (relative variants)"),
        label: None,
        get: |p| p.cbf.accel_bound,
        write: |p, v| p.cbf.accel_bound = v,
    },
    Param {
        name: "CBF_VARIANT",
        key: Some(host_text("filter")),
        unit: "",
        default: 3.0,
        min: 0.0,
        max: 3.0,
        integer: true,
        decimals: 0,
        group: "CBF",
        description: host_text("Filter law: 0 paper, 1 relative, 2 multi, 3 multi-relative"),
        label: Some(|c| variant_of(c).map(|v| v.as_str())),
        get: |p| variant_code(p.filter_variant),
        write: |p, v| {
            if let Some(f) = variant_of(v as i32) {
                p.filter_variant = f;
            }
        },
    },
    Param {
        name: "TRK_KP",
        key: Some(host_text("kp")),
        unit: "1/s^2",
        default: 0.5,
        min: 0.01,
        max: 100.0,
        integer: false,
        decimals: 3,
        group: "Tracking",
        description: host_text("PD position gain k_p (all axes)"),
        label: None,
        get: |p| p.tracking.kp[0],
        write: |p, v| p.tracking.kp = [v; 3],
    },
    Param {
        name: "TRK_KD",
        key: Some(host_text("kd")),
        unit: "1/s",
        default: 0.8,
        min: 0.01,
        max: 100.0,
        integer: false,
        decimals: 3,
        group: "Tracking",
        description: host_text("PD velocity gain k_d (all axes)"),
        label: None,
        get: |p| p.tracking.kd[0],
        write: |p, v| p.tracking.kd = [v; 3],
    },
    Param {
        name: "WP_SPEED",
        key: Some(host_text("speed")),
        unit: "m/s",
        default: 0.25,
        min: 0.001,
        max: crate::outer::waypoint::PARAM_LIMIT,
        integer: false,
        decimals: 2,
        group: "Mission",
        description: host_text("Reference speed along the path"),
        label: None,
        get: |p| p.waypoint.cruise_speed,
        write: |p, v| p.waypoint.cruise_speed = v,
    },
    Param {
        name: "FS_OBST_REQ",
        key: None,
        unit: "",
        default: 1.0,
        min: 0.0,
        max: 1.0,
        integer: true,
        decimals: 0,
        group: "Failsafe",
        description: host_text("Obstacle data must be fresh to arm and to stay armed (0 no, 1 yes)"),
        label: Some(|c| match c {
            0 => Some("not required"),
            1 => Some("required"),
            _ => None,
        }),
        get: |p| f32::from(u8::from(p.failsafe.obstacles_required)),
        write: |p, v| p.failsafe.obstacles_required = v != 0.0,
    },
    Param {
        name: "CBF_VEL_MARGIN",
        key: Some(host_text("velocity_margin")),
        unit: "m/s",
        default: 0.0,
        min: 0.0,
        max: 10.0,
        integer: false,
        decimals: 3,
        group: "CBF",
        description: host_text("Velocity-uncertainty margin eps_v of the filter's constraint"),
        label: None,
        get: |p| p.cbf.velocity_margin,
        write: |p, v| p.cbf.velocity_margin = v,
    },
    Param {
        name: "VEH_MASS",
        key: None,
        unit: "kg",
        default: 0.5,
        min: 0.07,
        max: 50.0,
        integer: false,
        decimals: 3,
        group: "Vehicle",
        description: host_text("Vehicle mass; hover thrust mass*g must stay below THR_MAX"),
        label: None,
        get: |p| p.airframe.mass,
        write: |p, v| {
            p.airframe.mass = v;
        },
    },
    Param {
        name: "VEH_IXX",
        key: None,
        unit: "kg m^2",
        default: 0.0019,
        min: 1e-5,
        max: 10.0,
        integer: false,
        decimals: 5,
        group: "Vehicle",
        description: host_text("Moment of inertia about body x (roll)"),
        label: None,
        get: |p| p.airframe.inertia[0],
        write: |p, v| {
            p.airframe.inertia[0] = v;
        },
    },
    Param {
        name: "VEH_IYY",
        key: None,
        unit: "kg m^2",
        default: 0.0019,
        min: 1e-5,
        max: 10.0,
        integer: false,
        decimals: 5,
        group: "Vehicle",
        description: host_text("Moment of inertia about body y (pitch)"),
        label: None,
        get: |p| p.airframe.inertia[1],
        write: |p, v| {
            p.airframe.inertia[1] = v;
        },
    },
    Param {
        name: "VEH_IZZ",
        key: None,
        unit: "kg m^2",
        default: 0.0033,
        min: 1e-5,
        max: 10.0,
        integer: false,
        decimals: 5,
        group: "Vehicle",
        description: host_text("Moment of inertia about body z (yaw)"),
        label: None,
        get: |p| p.airframe.inertia[2],
        write: |p, v| {
            p.airframe.inertia[2] = v;
        },
    },
    Param {
        name: "VEH_ARM",
        key: None,
        unit: "m",
        default: 0.13,
        min: 0.02,
        max: 2.0,
        integer: false,
        decimals: 3,
        group: "Vehicle",
        description: host_text("Distance from the centre of mass to each rotor axis"),
        label: None,
        get: |p| p.airframe.arm_length,
        write: |p, v| p.airframe.arm_length = v,
    },
    Param {
        name: "VEH_ROTOR_TMAX",
        key: None,
        unit: "N",
        default: 3.07,
        min: 0.1,
        max: 500.0,
        integer: false,
        decimals: 2,
        group: "Vehicle",
        description: host_text("Largest thrust of one rotor; 4x it must be at least THR_MAX"),
        label: None,
        get: |p| p.airframe.rotor_thrust_max,
        write: |p, v| p.airframe.rotor_thrust_max = v,
    },
    Param {
        name: "VEH_KAPPA",
        key: None,
        unit: "m",
        default: 0.016,
        min: 1e-4,
        max: 0.5,
        integer: false,
        decimals: 4,
        group: "Vehicle",
        description: host_text("Rotor drag-torque to thrust ratio k_m/k_f"),
        label: None,
        get: |p| p.airframe.torque_to_thrust,
        write: |p, v| p.airframe.torque_to_thrust = v,
    },
    Param {
        name: "THR_MAX",
        key: None,
        unit: "N",
        default: 11.0,
        min: 0.5,
        max: 2000.0,
        integer: false,
        decimals: 2,
        group: "Vehicle",
        description: host_text(
            "Largest collective thrust commanded; above VEH_MASS*g, at most 4*VEH_ROTOR_TMAX",
        ),
        label: None,
        get: |p| p.thrust.thrust_max,
        write: |p, v| p.thrust.thrust_max = v,
    },
    // Issue 17: the hull that bounds δ, and the ground / ceiling planes the filter keeps.
    Param {
        name: "VEH_HULL_R",
        key: None,
        unit: "m",
        default: crate::config::DEFAULT_HULL_RADIUS,
        min: 0.01,
        max: 5.0,
        integer: false,
        decimals: 4,
        group: "Vehicle",
        description: host_text(
            "Radius of the sphere bounding the vehicle; CBF_DELTA must be at least its square",
        ),
        label: None,
        get: |p| p.hull_radius,
        write: |p, v| p.hull_radius = v,
    },
    Param {
        name: "GND_HEIGHT",
        key: None,
        unit: "m",
        default: 0.0,
        min: -100.0,
        max: 100.0,
        integer: false,
        decimals: 3,
        group: "CBF",
        description: host_text(
            "Ground height (up); the filter keeps the plane z = -GND_HEIGHT as a barrier in flight",
        ),
        label: None,
        get: |p| p.robust.ground_height,
        write: |p, v| p.robust.ground_height = v,
    },
    Param {
        name: "CEIL_HEIGHT",
        key: None,
        unit: "m",
        default: 0.0,
        min: 0.0,
        max: 1000.0,
        integer: false,
        decimals: 3,
        group: "CBF",
        description: host_text("Ceiling height (up) kept as a barrier in flight; 0 = no ceiling"),
        label: None,
        get: |p| p.robust.ceiling_height,
        write: |p, v| p.robust.ceiling_height = v,
    },
    // Issue 19: the obstacle memory of the range-sensor perception (`crate::perception`).
    Param {
        name: "PCP_VOXEL",
        key: Some(host_text("mem_voxel")),
        unit: "m",
        default: 0.2,
        min: 0.02,
        max: 5.0,
        integer: false,
        decimals: 3,
        group: "Perception",
        description: host_text("Obstacle memory voxel edge: range returns in one cube merge into one point"),
        label: None,
        get: |p| p.perception.voxel,
        write: |p, v| p.perception.voxel = v,
    },
    Param {
        name: "PCP_FORGET",
        key: Some(host_text("mem_forget")),
        unit: "s",
        default: 5.0,
        min: 0.05,
        max: 600.0,
        integer: false,
        decimals: 2,
        group: "Perception",
        description: host_text("An obstacle cell not seen again for this long is forgotten"),
        label: None,
        get: |p| p.perception.forget_s,
        write: |p, v| p.perception.forget_s = v,
    },
    Param {
        name: "PCP_CLR_MARGIN",
        key: Some(host_text("mem_clear_margin")),
        unit: "m",
        default: 0.3,
        min: 0.0,
        max: 5.0,
        integer: false,
        decimals: 3,
        group: "Perception",
        description: host_text(
            "A beam clears a cell it passes when its return lies this far beyond the cell",
        ),
        label: None,
        get: |p| p.perception.clear_margin,
        write: |p, v| p.perception.clear_margin = v,
    },
    Param {
        name: "PCP_TRK_SIZE",
        key: Some(host_text("mem_track_size")),
        unit: "m",
        default: 0.8,
        min: 0.0,
        max: 10.0,
        integer: false,
        decimals: 2,
        group: "Perception",
        description: host_text(
            "Clusters up to this size are tracked for their velocity; larger ones are static",
        ),
        label: None,
        get: |p| p.perception.track_size,
        write: |p, v| p.perception.track_size = v,
    },
    Param {
        name: "PCP_FOV_MARGIN",
        key: Some(host_text("fov_margin")),
        unit: "m",
        default: 0.25,
        min: 0.0,
        max: 5.0,
        integer: false,
        decimals: 3,
        group: "Perception",
        description: host_text("Frontier point beyond the observed free range (>= hull radius); 0 = off"),
        label: None,
        get: |p| p.perception.fov_margin,
        write: |p, v| p.perception.fov_margin = v,
    },
    Param {
        name: "MAN_TILT_MAX",
        key: None,
        unit: "rad",
        default: 0.35,
        min: 0.05,
        max: 1.0,
        integer: false,
        decimals: 2,
        group: "Modes",
        description: host_text(
            "Manual: tilt at full roll/pitch stick (capped by the thrust map's tilt limit)",
        ),
        label: None,
        get: |p| p.modes.manual_tilt_max,
        write: |p, v| p.modes.manual_tilt_max = v,
    },
    Param {
        name: "PA_SPEED_MAX",
        key: None,
        unit: "m/s",
        default: 1.0,
        min: 0.1,
        max: 10.0,
        integer: false,
        decimals: 2,
        group: "Modes",
        description: host_text("Position assist: horizontal speed at full stick (heading frame)"),
        label: None,
        get: |p| p.modes.assist_speed,
        write: |p, v| p.modes.assist_speed = v,
    },
    Param {
        name: "PA_CLIMB_MAX",
        key: None,
        unit: "m/s",
        default: 0.5,
        min: 0.1,
        max: 5.0,
        integer: false,
        decimals: 2,
        group: "Modes",
        description: host_text("Position assist: climb/descent rate at full throttle deflection from mid"),
        label: None,
        get: |p| p.modes.assist_climb,
        write: |p, v| p.modes.assist_climb = v,
    },
    Param {
        name: "PA_YAWRATE_MAX",
        key: None,
        unit: "rad/s",
        default: 1.0,
        min: 0.1,
        max: 6.0,
        integer: false,
        decimals: 2,
        group: "Modes",
        description: host_text("Yaw rate at full yaw stick (Manual, Position)"),
        label: None,
        get: |p| p.modes.yaw_rate_max,
        write: |p, v| p.modes.yaw_rate_max = v,
    },
    Param {
        name: "PA_DEADBAND",
        key: None,
        unit: "",
        default: 0.05,
        min: 0.0,
        max: 0.5,
        integer: false,
        decimals: 3,
        group: "Modes",
        description: host_text(
            "Stick deadband around centre (throttle: around 0.5), fraction of full deflection",
        ),
        label: None,
        get: |p| p.modes.deadband,
        write: |p, v| p.modes.deadband = v,
    },
    Param {
        name: "MODE_SW_LOW",
        key: None,
        unit: "",
        default: 1.0,
        min: 0.0,
        max: 6.0,
        integer: true,
        decimals: 0,
        group: "Modes",
        description: host_text("Flight mode of the RC mode switch's low position"),
        label: Some(mode_label),
        get: |p| p.modes.switch_modes[0] as i32 as f32,
        write: |p, v| {
            p.modes.switch_modes[0] = FlightMode::from_code(v as i32).unwrap_or(p.modes.switch_modes[0])
        },
    },
    Param {
        name: "MODE_SW_MID",
        key: None,
        unit: "",
        default: 4.0,
        min: 0.0,
        max: 6.0,
        integer: true,
        decimals: 0,
        group: "Modes",
        description: host_text("Flight mode of the RC mode switch's middle position"),
        label: Some(mode_label),
        get: |p| p.modes.switch_modes[1] as i32 as f32,
        write: |p, v| {
            p.modes.switch_modes[1] = FlightMode::from_code(v as i32).unwrap_or(p.modes.switch_modes[1])
        },
    },
    Param {
        name: "MODE_SW_HIGH",
        key: None,
        unit: "",
        default: 2.0,
        min: 0.0,
        max: 6.0,
        integer: true,
        decimals: 0,
        group: "Modes",
        description: host_text("Flight mode of the RC mode switch's high position"),
        label: Some(mode_label),
        get: |p| p.modes.switch_modes[2] as i32 as f32,
        write: |p, v| {
            p.modes.switch_modes[2] = FlightMode::from_code(v as i32).unwrap_or(p.modes.switch_modes[2])
        },
    },
    Param {
        name: "FS_RC_TIMEOUT",
        key: None,
        unit: "s",
        default: 0.5,
        min: 0.05,
        max: 10.0,
        integer: false,
        decimals: 2,
        group: "Failsafe",
        description: host_text("No valid RC frame for this long is an RC loss (once RC was seen)"),
        label: None,
        get: |p| p.modes.rc_timeout_s,
        write: |p, v| p.modes.rc_timeout_s = v,
    },
    Param {
        name: "FS_RC_LAND_T",
        key: None,
        unit: "s",
        default: 5.0,
        min: 0.0,
        max: 120.0,
        integer: false,
        decimals: 1,
        group: "Failsafe",
        description: host_text("RC loss in Manual/Position: Hold, then Land after this long without RC"),
        label: None,
        get: |p| p.modes.rc_loss_land_s,
        write: |p, v| p.modes.rc_loss_land_s = v,
    },
    Param {
        name: "FS_RC_ACT",
        key: None,
        unit: "",
        default: 0.0,
        min: 0.0,
        max: 1.0,
        integer: true,
        decimals: 0,
        group: "Failsafe",
        description: host_text("RC loss in Mission/Offboard: 0 continue, 1 return"),
        label: Some(rc_act_label),
        get: |p| p.modes.rc_loss_auto as i32 as f32,
        write: |p, v| {
            p.modes.rc_loss_auto = if v >= 0.5 { RcLossAction::Return } else { RcLossAction::Continue }
        },
    },
    Param {
        name: "OFFB_TIMEOUT",
        key: None,
        unit: "s",
        default: 0.5,
        min: 0.05,
        max: 10.0,
        integer: false,
        decimals: 2,
        group: "Failsafe",
        description: host_text("Offboard: no valid setpoint for this long -> Hold"),
        label: None,
        get: |p| p.modes.offboard_timeout_s,
        write: |p, v| p.modes.offboard_timeout_s = v,
    },
    Param {
        name: "RTL_CRUMB_DIST",
        key: None,
        unit: "m",
        default: 0.5,
        min: 0.1,
        max: 10.0,
        integer: false,
        decimals: 2,
        group: "Modes",
        description: host_text(
            "Return: breadcrumb spacing of the flown path (doubles when the 32-crumb buffer fills)",
        ),
        label: None,
        get: |p| p.modes.crumb_spacing,
        write: |p, v| p.modes.crumb_spacing = v,
    },
    Param {
        name: "RTL_SPEED",
        key: None,
        unit: "m/s",
        default: 0.5,
        min: 0.05,
        max: 5.0,
        integer: false,
        decimals: 2,
        group: "Modes",
        description: host_text("Return: speed back along the breadcrumbs"),
        label: None,
        get: |p| p.modes.return_speed,
        write: |p, v| p.modes.return_speed = v,
    },
    Param {
        name: "FS_BAT_ACT",
        key: None,
        unit: "",
        default: 1.0,
        min: 0.0,
        max: 1.0,
        integer: true,
        decimals: 0,
        group: "Failsafe",
        description: host_text("Battery failsafes: 0 off, 1 low -> Return, critical -> Land"),
        label: Some(bat_act_label),
        get: |p| if p.modes.battery_failsafe { 1.0 } else { 0.0 },
        write: |p, v| p.modes.battery_failsafe = v >= 0.5,
    },
    // Issue 21: the RC receiver's channel map and ranges (`rc::map`; the loss timeout is FS_RC_TIMEOUT).
    rc_map(
        "RC_MAP_ROLL",
        1.0,
        1.0,
        "RC channel of the roll stick",
        |p| f32::from(p.rc.map_roll),
        |p, v| p.rc.map_roll = v as u8,
    ),
    rc_map(
        "RC_MAP_PITCH",
        1.0,
        2.0,
        "RC channel of the pitch stick",
        |p| f32::from(p.rc.map_pitch),
        |p, v| p.rc.map_pitch = v as u8,
    ),
    rc_map(
        "RC_MAP_THR",
        1.0,
        3.0,
        "RC channel of the throttle stick",
        |p| f32::from(p.rc.map_throttle),
        |p, v| p.rc.map_throttle = v as u8,
    ),
    rc_map(
        "RC_MAP_YAW",
        1.0,
        4.0,
        "RC channel of the yaw stick",
        |p| f32::from(p.rc.map_yaw),
        |p, v| p.rc.map_yaw = v as u8,
    ),
    rc_map(
        "RC_MAP_ARM",
        0.0,
        5.0,
        "RC channel of the arm switch (on above RC_SW_HIGH_US); 0 none",
        |p| f32::from(p.rc.map_arm),
        |p, v| p.rc.map_arm = v as u8,
    ),
    rc_map(
        "RC_MAP_MODE",
        0.0,
        6.0,
        "RC channel of the mode switch (MODE_SW_LOW/MID/HIGH); 0 none",
        |p| f32::from(p.rc.map_mode),
        |p, v| p.rc.map_mode = v as u8,
    ),
    rc_map(
        "RC_MAP_KILL",
        0.0,
        7.0,
        "RC channel of the kill switch (on unless below RC_SW_LOW_US); 0 none",
        |p| f32::from(p.rc.map_kill),
        |p, v| p.rc.map_kill = v as u8,
    ),
    rc_us(
        "RC_MIN_US",
        (700.0, 1000.0, 1400.0),
        "RC stick low end (throttle 0, stick -1)",
        |p| p.rc.min_us,
        |p, v| p.rc.min_us = v,
    ),
    rc_us(
        "RC_TRIM_US",
        (1410.0, 1500.0, 1590.0),
        "RC stick centre (Futaba SBUS: 1520)",
        |p| p.rc.trim_us,
        |p, v| p.rc.trim_us = v,
    ),
    rc_us(
        "RC_MAX_US",
        (1600.0, 2000.0, 2300.0),
        "RC stick high end (throttle 1, stick +1)",
        |p| p.rc.max_us,
        |p, v| p.rc.max_us = v,
    ),
    rc_us(
        "RC_DEADBAND_US",
        (0.0, 20.0, 100.0),
        "RC roll/pitch/yaw deadband around RC_TRIM_US",
        |p| p.rc.deadband_us,
        |p, v| p.rc.deadband_us = v,
    ),
    rc_us(
        "RC_SW_LOW_US",
        (800.0, 1300.0, 1500.0),
        "RC switch: below this = low position",
        |p| p.rc.switch_low_us,
        |p, v| p.rc.switch_low_us = v,
    ),
    rc_us(
        "RC_SW_HIGH_US",
        (1500.0, 1700.0, 2200.0),
        "RC switch: above this = high position",
        |p| p.rc.switch_high_us,
        |p, v| p.rc.switch_high_us = v,
    ),
    Param {
        name: "RC_LQ_MIN",
        key: None,
        unit: "%",
        default: 10.0,
        min: 0.0,
        max: 100.0,
        integer: false,
        decimals: 0,
        group: "RC",
        description: host_text("RC link quality below this = RC lost (CRSF link statistics)"),
        label: None,
        get: |p| p.rc.lq_min,
        write: |p, v| p.rc.lq_min = v,
    },
    num(
        "BAT_LOW_V",
        "Battery",
        "V",
        (3.0, 3.5, 4.2),
        2,
        "Low battery: resting voltage per cell below this (return)",
        |p| p.battery.low_cell_v,
        |p, v| p.battery.low_cell_v = v,
    ),
    num(
        "BAT_CRIT_V",
        "Battery",
        "V",
        (2.8, 3.3, 4.0),
        2,
        "Critical battery: resting voltage per cell below this (land)",
        |p| p.battery.critical_cell_v,
        |p, v| p.battery.critical_cell_v = v,
    ),
    num(
        "BAT_R_INT",
        "Battery",
        "Ohm",
        (0.0, 0.02, 1.0),
        3,
        "Pack internal resistance for the sag compensation (with a current sensor)",
        |p| p.battery.r_internal_ohm,
        |p, v| p.battery.r_internal_ohm = v,
    ),
    num(
        "BAT_V_DIV",
        "Battery",
        "",
        (1.0, 11.0, 100.0),
        2,
        "VBAT divider: pack volts per ADC volt (MATEKF405 11)",
        |p| p.battery.v_divider,
        |p, v| p.battery.v_divider = v,
    ),
    num(
        "BAT_A_PER_V",
        "Battery",
        "A/V",
        (0.0, 0.0, 500.0),
        1,
        "Current sensor scale, A per ADC volt (0 = no current sensor)",
        |p| p.battery.amps_per_volt,
        |p, v| p.battery.amps_per_volt = v,
    ),
    Param {
        name: "BAT_CELLS",
        key: None,
        unit: "",
        default: 0.0,
        min: 0.0,
        max: crate::battery::MAX_CELLS as f32,
        integer: true,
        decimals: 0,
        group: "Battery",
        description: host_text("Cells in series (0 = detect at power-up, disarmed)"),
        label: None,
        get: |p| f32::from(p.battery.cells),
        write: |p, v| p.battery.cells = v as u8,
    },
    Param {
        name: "BAT_ENABLE",
        key: None,
        unit: "",
        default: 1.0,
        min: 0.0,
        max: 1.0,
        integer: true,
        decimals: 0,
        group: "Battery",
        description: host_text("Battery measured (0: no battery failsafe)"),
        label: Some(|c| match c {
            0 => Some("off"),
            1 => Some("on"),
            _ => None,
        }),
        get: |p| f32::from(u8::from(p.battery.enabled)),
        write: |p, v| p.battery.enabled = v != 0.0,
    },
    acc(
        "CAL_ACC0_XOFF",
        false,
        "Accelerometer offset, sensor x",
        |p| p.sensors.accel_offset.x,
        |p, v| p.sensors.accel_offset.x = v,
    ),
    acc(
        "CAL_ACC0_YOFF",
        false,
        "Accelerometer offset, sensor y",
        |p| p.sensors.accel_offset.y,
        |p, v| p.sensors.accel_offset.y = v,
    ),
    acc(
        "CAL_ACC0_ZOFF",
        false,
        "Accelerometer offset, sensor z",
        |p| p.sensors.accel_offset.z,
        |p, v| p.sensors.accel_offset.z = v,
    ),
    acc(
        "CAL_ACC0_XSCALE",
        true,
        "Accelerometer scale, sensor x",
        |p| p.sensors.accel_scale.x,
        |p, v| p.sensors.accel_scale.x = v,
    ),
    acc(
        "CAL_ACC0_YSCALE",
        true,
        "Accelerometer scale, sensor y",
        |p| p.sensors.accel_scale.y,
        |p, v| p.sensors.accel_scale.y = v,
    ),
    acc(
        "CAL_ACC0_ZSCALE",
        true,
        "Accelerometer scale, sensor z",
        |p| p.sensors.accel_scale.z,
        |p, v| p.sensors.accel_scale.z = v,
    ),
    num(
        "CAL_TRIM_ROLL",
        "Sensors",
        "rad",
        (-crate::calibration::TRIM_MAX, 0.0, crate::calibration::TRIM_MAX),
        4,
        "Level-horizon trim, roll",
        |p| p.sensors.trim_roll,
        |p, v| p.sensors.trim_roll = v,
    ),
    num(
        "CAL_TRIM_PITCH",
        "Sensors",
        "rad",
        (-crate::calibration::TRIM_MAX, 0.0, crate::calibration::TRIM_MAX),
        4,
        "Level-horizon trim, pitch",
        |p| p.sensors.trim_pitch,
        |p, v| p.sensors.trim_pitch = v,
    ),
    Param {
        name: "SENS_BOARD_ROT",
        key: None,
        unit: "",
        default: 0.0,
        min: 0.0,
        max: crate::calibration::BoardRotation::MAX_CODE as f32,
        integer: true,
        decimals: 0,
        group: "Sensors",
        description: host_text("IMU orientation on the board (PX4 SENS_BOARD_ROT codes 0-15)"),
        label: Some(crate::calibration::BoardRotation::name),
        get: |p| f32::from(p.sensors.board_rotation.code()),
        write: |p, v| {
            if let Some(r) = crate::calibration::BoardRotation::from_code(v as u8) {
                p.sensors.board_rotation = r;
            }
        },
    },
];

/// The names of [`TABLE`], in index order (derived from it, for code that needs a list).
pub const NAMES: [&str; COUNT] = {
    let mut n = [""; COUNT];
    let mut i = 0;
    while i < COUNT {
        n[i] = TABLE[i].name;
        i += 1;
    }
    n
};

/// Index of parameter `name` in [`TABLE`] (MAVLink `param_index`).
pub fn index_of(name: &str) -> Option<usize> {
    TABLE.iter().position(|p| p.name == name)
}

/// The parameter called `name`.
pub fn find(name: &str) -> Option<&'static Param> {
    TABLE.iter().find(|p| p.name == name)
}

/// The parameter with the scene `[controller]` / command-line key `key`.
pub fn by_key(key: &str) -> Option<&'static Param> {
    TABLE.iter().find(|p| p.key == Some(key))
}

/// Current value of `name` in `p`.
pub fn get(p: &ControllerParams, name: &str) -> Option<f32> {
    find(name).map(|d| (d.get)(p))
}

/// Sets `name` to `value` in `p` if the value is in that parameter's range (see the
/// module docs: no other parameter is consulted); returns the value now in `p`.
/// A refusal leaves `p` unchanged.
pub fn set(p: &mut ControllerParams, name: &str, value: f32) -> Result<f32, ParamRejected> {
    let d = find(name).ok_or(ParamRejected::Unknown)?;
    let v = d.check(value)?;
    (d.write)(p, v);
    Ok((d.get)(p))
}

/// Whether the set satisfies the constraints between parameters (and every field no
/// parameter sets): [`ControllerParams::validate`]. Per-parameter ranges cannot
/// break it except through the two cross-constraints of the module docs.
pub fn consistency(p: &ControllerParams) -> Result<(), ParamError> {
    p.validate()
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use proptest::strategy::Strategy;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

    #[test]
    fn names_are_mavlink_ids_and_unique() {
        for (i, d) in TABLE.iter().enumerate() {
            assert!(!d.name.is_empty() && d.name.len() <= 16, "{} is not a MAVLink param_id", d.name);
            assert!(d.name.bytes().all(|b| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_'));
            assert_eq!(index_of(d.name), Some(i), "{} twice", d.name);
            if let Some(k) = d.key {
                assert_eq!(by_key(k).map(|q| q.name), Some(d.name), "key {k} twice");
            }
            assert!(!d.description.is_empty() && !d.group.is_empty());
        }
    }

    #[test]
    fn defaults_are_in_range_and_are_the_controller_defaults() {
        let p = ControllerParams::default();
        for d in &TABLE {
            assert!(d.min < d.max, "{}", d.name);
            assert_eq!(d.check(d.default), Ok(d.default), "{} default out of range", d.name);
            assert_eq!((d.get)(&p).to_bits(), d.default.to_bits(), "{}", d.name);
        }
        assert!(consistency(&p).is_ok());
    }

    /// Values to try for `d`: both ends, the default and a point inside.
    fn samples(d: &Param) -> [f32; 4] {
        let mid = if d.integer { ((d.min + d.max) / 2.0) as i32 as f32 } else { 0.5 * (d.min + d.max) };
        [d.min, d.max, d.default, mid]
    }

    #[test]
    fn each_parameter_round_trips_and_writes_only_itself() {
        for d in &TABLE {
            for v in samples(d) {
                let mut p = ControllerParams::default();
                let before = p;
                assert_eq!(set(&mut p, d.name, v), Ok(v), "{} = {v}", d.name);
                assert_eq!(get(&p, d.name), Some(v));
                for o in TABLE.iter().filter(|o| o.name != d.name) {
                    assert_eq!(
                        (o.get)(&p).to_bits(),
                        (o.get)(&before).to_bits(),
                        "{} moved {}",
                        d.name,
                        o.name
                    );
                }
            }
        }
        let mut p = ControllerParams::default();
        set(&mut p, "TRK_KD", 0.75).unwrap();
        assert_eq!(p.tracking.kd, [0.75; 3]);
        set(&mut p, "CBF_VARIANT", 1.0).unwrap();
        assert_eq!(p.filter_variant, FilterVariant::Relative);
        set(&mut p, "FS_OBST_REQ", 0.0).unwrap();
        assert!(!p.failsafe.obstacles_required);
        set(&mut p, "VEH_MASS", 0.6).unwrap();
        set(&mut p, "VEH_IZZ", 0.004).unwrap();
        assert_eq!((p.airframe.mass, p.airframe.inertia[2]), (0.6, 0.004));
    }

    #[test]
    fn out_of_range_values_are_refused_and_the_old_value_kept() {
        for d in &TABLE {
            let below = if d.min > 0.0 { d.min * 0.5 } else { d.min - 1.0 };
            let above = d.max * 2.0;
            let mut bad = [below, above, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, 0.0];
            let n = if d.integer {
                bad[5] = d.min + 0.5;
                bad[6] = d.max - 0.25;
                7
            } else {
                5
            };
            for v in &bad[..n] {
                let mut p = ControllerParams::default();
                assert_eq!(set(&mut p, d.name, *v), Err(ParamRejected::Invalid), "{} = {v}", d.name);
                assert_eq!(p, ControllerParams::default(), "{} = {v} changed the set", d.name);
            }
        }
        let mut p = ControllerParams::default();
        assert_eq!(set(&mut p, "NOPE", 1.0), Err(ParamRejected::Unknown));
        assert_eq!(get(&p, "NOPE"), None);
    }

    /// Any target within the ranges is reached by single PARAM_SETs in any order, each
    /// accepted, and the result does not depend on the order (fixed seed).
    #[test]
    fn single_sets_in_any_order_reach_the_target() {
        let mut runner = TestRunner::new_with_rng(
            Config { cases: 256, failure_persistence: None, ..Config::default() },
            TestRng::deterministic_rng(RngAlgorithm::ChaCha),
        );
        let strategy = (
            proptest::collection::vec(0.0f32..=1.0, COUNT),
            proptest::sample::subsequence((0..COUNT).collect::<std::vec::Vec<_>>(), COUNT).prop_shuffle(),
        );
        runner
            .run(&strategy, |(fractions, order)| {
                let target: std::vec::Vec<f32> = TABLE
                    .iter()
                    .zip(&fractions)
                    .map(|(d, f)| {
                        let v = d.min + f * (d.max - d.min);
                        let v = if d.integer { libm::roundf(v) } else { v };
                        v.clamp(d.min, d.max)
                    })
                    .collect();
                let mut in_order = ControllerParams::default();
                for (d, v) in TABLE.iter().zip(&target) {
                    set(&mut in_order, d.name, *v).unwrap();
                }
                let mut p = ControllerParams::default();
                for &i in &order {
                    let d = &TABLE[i];
                    proptest::prop_assert_eq!(set(&mut p, d.name, target[i]), Ok(target[i]), "{}", d.name);
                }
                for (d, v) in TABLE.iter().zip(&target) {
                    proptest::prop_assert_eq!(get(&p, d.name), Some(*v));
                }
                proptest::prop_assert_eq!(p, in_order);
                Ok(())
            })
            .unwrap();
    }

    /// The ranges leave only the documented cross-constraints: with every other
    /// parameter at its default, each parameter's whole range validates except where
    /// δ1 ≤ δ, δ < hull_radius² (issue 17) or the hover/thrust chain m·g < THR_MAX ≤
    /// 4·VEH_ROTOR_TMAX breaks.
    #[test]
    fn only_the_documented_constraints_link_parameters() {
        for d in &TABLE {
            for v in samples(d) {
                let mut p = ControllerParams::default();
                set(&mut p, d.name, v).unwrap();
                let hover = p.airframe.mass * crate::frame::GRAVITY;
                let linked = p.cbf.delta1 <= p.cbf.delta
                    || p.cbf.delta < p.hull_radius * p.hull_radius * (1.0 - 1e-6)
                    || hover >= p.thrust.thrust_max
                    || p.thrust.thrust_max > 4.0 * p.airframe.rotor_thrust_max;
                assert_eq!(consistency(&p).is_ok(), !linked, "{} = {v}: {:?}", d.name, consistency(&p));
            }
        }
    }

    #[test]
    fn ranges_read_as_words() {
        use std::string::ToString;
        let mu = find("CBF_MU").unwrap();
        assert_eq!(mu.range().to_string(), "0.01 ≤ mu ≤ 100 s");
        let v = find("CBF_VARIANT").unwrap();
        assert_eq!(
            v.range().to_string(),
            "filter one of 0 (paper) 1 (relative) 2 (multi) 3 (multi-relative)"
        );
    }
}
