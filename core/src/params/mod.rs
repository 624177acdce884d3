//! The controller's parameter table: every tunable parameter **once**, with its
//! MAVLink name, unit, range, one-line description and how it reads and writes
//! [`ControllerParams`] (one [`Param::new`] entry each; the default is the stage's own,
//! [`Param::default_value`], written once in its parameters struct). Everything that names parameters is driven by
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

/// Text only host tools read ([`Param::description`], [`Param::key`]): the string on the host,
/// [`NoText`] on the flight controller (`target_os = "none"`). Read by `cargo xtask params`, the
/// scene parser and the QGC metadata; on the F405 the strings would take ~5 KB of the 128 KiB
/// flash, and even empty ones 16 bytes per table entry (~1.1 KB).
#[cfg(not(target_os = "none"))]
pub type HostText = &'static str;
/// Text only host tools read: nothing on the flight controller (see the host build's doc).
#[cfg(target_os = "none")]
pub type HostText = NoText;

/// [`HostText`] on the flight controller: zero-sized, the text is not in the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NoText;

/// `s` on the host, [`NoText`] on the flight controller (see [`HostText`]).
pub const fn host_text(s: &'static str) -> HostText {
    #[cfg(target_os = "none")]
    {
        let _ = s;
        NoText
    }
    #[cfg(not(target_os = "none"))]
    s
}

/// Reads and writes of a parameter: `(get, write)` ([`Param::get`], the private write).
pub type Access = (fn(&ControllerParams) -> f32, fn(&mut ControllerParams, f32));

/// The [`Access`] of an `f32` field of [`ControllerParams`]: `field!(cbf.mu)`.
macro_rules! field {
    ($($path:tt)+) => {
        (|p: &ControllerParams| p.$($path)+, |p: &mut ControllerParams, v: f32| p.$($path)+ = v)
    };
}

/// The [`Access`] of a `u8` field (a count or channel; written from a checked whole value).
macro_rules! u8_field {
    ($($path:tt)+) => {
        (|p: &ControllerParams| f32::from(p.$($path)+), |p: &mut ControllerParams, v: f32| p.$($path)+ = v as u8)
    };
}

/// The [`Access`] of a `bool` field (1 = on).
macro_rules! flag {
    ($($path:tt)+) => {
        (
            |p: &ControllerParams| f32::from(u8::from(p.$($path)+)),
            |p: &mut ControllerParams, v: f32| p.$($path)+ = v != 0.0,
        )
    };
}

/// An `RC_MAP_*` entry: a whole channel number up to 18 (issue 21, `rc::map`).
const fn rc_map(name: &'static str, min: f32, access: Access, description: &'static str) -> Param {
    Param::new(name, "RC", "", (min, 18.0), 0, access, description).whole()
}

/// An RC pulse-width entry (`RC_*_US`), µs.
const fn rc_us(name: &'static str, range: (f32, f32), access: Access, description: &'static str) -> Param {
    Param::new(name, "RC", "us", range, 0, access, description)
}

/// An accelerometer calibration entry (`CAL_ACC0_*`), per sensor axis.
const fn acc(name: &'static str, scale: bool, access: Access, description: &'static str) -> Param {
    let (unit, range) = if scale {
        ("", crate::calibration::ACCEL_SCALE_RANGE)
    } else {
        ("m/s^2", (-crate::calibration::ACCEL_OFFSET_MAX, crate::calibration::ACCEL_OFFSET_MAX))
    };
    Param::new(name, "Sensors", unit, range, 4, access, description)
}

/// One parameter: the single place its name, unit, range and meaning are written; its default
/// is the one of the stage's own parameters struct (`CbfParams::default()`, …, gathered by
/// [`ControllerParams::default`]), read through [`Param::get`] ([`Param::default_value`]), so it
/// is written once, beside the code that uses it.
#[derive(Clone, Copy)]
pub struct Param {
    /// MAVLink `param_id` (≤ 16 ASCII bytes), e.g. `CBF_MU`.
    pub name: &'static str,
    /// Key of the scene file's `[controller]` table and of the `parapet` command-line
    /// option (`--key`), when the host exposes the parameter there; `None` otherwise
    /// (the vehicle parameters come from the scene's `[vehicle]` table instead). Host builds
    /// only (see [`HostText`]).
    pub key: Option<HostText>,
    /// Unit (SI), `""` for codes and flags.
    pub unit: &'static str,
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
    /// One-line description (host builds only, see [`HostText`]).
    pub description: HostText,
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
            .field("default", &self.default_value())
            .field("min", &self.min)
            .field("max", &self.max)
            .finish_non_exhaustive()
    }
}

impl Param {
    /// A continuous parameter without a scene/option key: `name`, ground-station `group`, SI
    /// `unit`, allowed `(min, max)`, `decimals` shown, how it is read and written
    /// (`field!(cbf.mu)` for an `f32` field) and a one-line `description`. Chain [`Param::key`], [`Param::whole`],
    /// [`Param::code`].
    pub const fn new(
        name: &'static str,
        group: &'static str,
        unit: &'static str,
        (min, max): (f32, f32),
        decimals: u8,
        (get, write): Access,
        description: &'static str,
    ) -> Param {
        Param {
            name,
            key: None,
            unit,
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

    /// The scene file's `[controller]` key and command-line option of this parameter.
    pub const fn key(self, key: &'static str) -> Param {
        Param { key: Some(host_text(key)), ..self }
    }

    /// Only whole numbers (counts, flags).
    pub const fn whole(self) -> Param {
        Param { integer: true, ..self }
    }

    /// A code: whole numbers, each named by `label`.
    pub const fn code(self, label: fn(i32) -> Option<&'static str>) -> Param {
        Param { integer: true, label: Some(label), ..self }
    }

    /// The default value: [`ControllerParams::default`]'s.
    pub fn default_value(&self) -> f32 {
        (self.get)(&ControllerParams::default())
    }

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
        #[cfg(not(target_os = "none"))]
        let name = p.key.unwrap_or(p.name);
        #[cfg(target_os = "none")]
        let name = p.name;
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

/// Parameters a ground station may change while the vehicle is armed (in-flight tuning, as
/// PX4 allows): the PD gains, the safety filter's μ, δ, δ1, A and velocity margin, and the path
/// speed — what [`crate::outer::OuterLoop::retune`] applies in place between two outer steps.
/// Every other parameter is set-up (airframe, thrust, board rotation, calibration, RC map,
/// battery), or belongs to a part with state (filter law, modes and failsafes, perception,
/// trajectory, return path, takeoff limit) that is rebuilt only disarmed: PARAM_SET refused
/// while armed ([`ParamRejected::NotNow`]).
pub const IN_FLIGHT: [&str; 8] =
    ["TRK_KP", "TRK_KD", "CBF_MU", "CBF_DELTA", "CBF_DELTA1", "CBF_ACC_BOUND", "CBF_VEL_MARGIN", "WP_SPEED"];

/// `true` when `name` may change while armed ([`IN_FLIGHT`]).
pub fn in_flight(name: &str) -> bool {
    IN_FLIGHT.contains(&name)
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
        FilterVariant::Braking => 4.0,
    }
}

fn variant_of(code: i32) -> Option<FilterVariant> {
    match code {
        0 => Some(FilterVariant::Paper),
        1 => Some(FilterVariant::Relative),
        2 => Some(FilterVariant::Multi),
        3 => Some(FilterVariant::MultiRelative),
        4 => Some(FilterVariant::Braking),
        _ => None,
    }
}

mod table_flight;
mod table_pilot;
mod table_setup;

/// Number of parameters.
pub const COUNT: usize = table_flight::N + table_pilot::N + table_setup::N;

/// The parameters, in MAVLink `param_index` order: the parts of `table_flight`,
/// `table_pilot` and `table_setup`, one after the other.
///
/// A `static`, not a `const`: every use of a `const` array may materialise its own copy in
/// the image (the F405 build held three of these ~5 KB tables, one per using function group).
pub static TABLE: [Param; COUNT] = ENTRIES;

/// [`TABLE`]'s contents at compile time (for [`NAMES`]).
const ENTRIES: [Param; COUNT] = concat(&table_flight::TABLE, &table_pilot::TABLE, &table_setup::TABLE);

/// `a`, `b` and `c` one after the other (compile time only; a length mismatch does not compile).
const fn concat<const A: usize, const B: usize, const C: usize>(
    a: &[Param; A],
    b: &[Param; B],
    c: &[Param; C],
) -> [Param; COUNT] {
    assert!(A + B + C == COUNT && A > 0);
    let mut out = [a[0]; COUNT];
    let mut i = 0;
    while i < A {
        out[i] = a[i];
        i += 1;
    }
    while i < A + B {
        out[i] = b[i - A];
        i += 1;
    }
    while i < COUNT {
        out[i] = c[i - A - B];
        i += 1;
    }
    out
}

/// The names of [`TABLE`], in index order (derived from it, for code that needs a list).
pub const NAMES: [&str; COUNT] = {
    let mut n = [""; COUNT];
    let mut i = 0;
    while i < COUNT {
        n[i] = ENTRIES[i].name;
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

/// The parameter with the scene `[controller]` / command-line key `key` (host builds: the
/// flight controller has no keys).
#[cfg(not(target_os = "none"))]
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

    /// The in-flight tunables are parameters of the table, and only those.
    #[test]
    fn in_flight_names_are_table_parameters() {
        assert!(IN_FLIGHT.iter().all(|n| find(n).is_some()), "{IN_FLIGHT:?}");
        assert!(in_flight("TRK_KP") && in_flight("WP_SPEED"));
        assert!(!in_flight("VEH_MASS") && !in_flight("CBF_VARIANT") && !in_flight("NOPE"));
    }

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
            let default = (d.get)(&p);
            assert_eq!(d.check(default), Ok(default), "{} default {default} out of range", d.name);
        }
        assert!(consistency(&p).is_ok());
    }

    /// Values to try for `d`: both ends, the default and a point inside.
    fn samples(d: &Param) -> [f32; 4] {
        let mid = if d.integer { ((d.min + d.max) / 2.0) as i32 as f32 } else { 0.5 * (d.min + d.max) };
        [d.min, d.max, d.default_value(), mid]
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
    /// δ1 ≤ δ, δ < hull_radius² (issue 17), the hover/thrust chain m·g < THR_MAX ≤
    /// 4·VEH_ROTOR_TMAX breaks, or the braking barrier's deceleration exceeds the filter's
    /// u_max (`CBF_BRAKE_ACC` ≤ u_max, issue 36).
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
                    || p.thrust.thrust_max > 4.0 * p.airframe.rotor_thrust_max
                    || p.cbf.brake_accel > p.cbf.u_max;
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
            "filter one of 0 (paper) 1 (relative) 2 (multi) 3 (multi-relative) 4 (braking)"
        );
    }
}
