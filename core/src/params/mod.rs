//! The controller's parameter table: every tunable parameter **once**, with its
//! MAVLink name, unit, range, one-line description and how it reads and writes
//! [`ControllerParams`]. Each parameter is declared in its stage's file, beside the field and
//! its default (`CbfParams::params()` in `safety/cbf.rs`, …, see [`crate::param_decl`]); this
//! module only says where each struct sits in [`ControllerParams`] (`Has`, one line per
//! struct) and concatenates the structs' lists ([`PARTS`]) into [`TABLE`]: no entry and no
//! count is written here. Everything that names parameters is driven by [`TABLE`]: the firmware's MAVLink parameter protocol (PARAM_SET /
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
//! Owns: [`TABLE`], [`PARTS`], [`COUNT`], [`NAMES`], lookup by name / key, [`get`], [`set`],
//! the in-flight tunables. May import: `config` (the [`ControllerParams`] struct), the stages'
//! parameters structs (their lists), `param_decl`, `frame` (tests). No allocation, no panics.

use crate::airframe::Airframe;
use crate::battery::BatteryParams;
use crate::calibration::SensorCal;
use crate::cbf::{CbfParams, FilterVariant};
use crate::config::{ControllerParams, ParamError};
use crate::failsafe::FailsafeParams;
use crate::governor::GovernorParams;
use crate::outer::guidance::GuidanceParams;
use crate::outer::path_yaw::PathYawParams;
use crate::outer::trajectory::TrajectoryParams;
use crate::param_decl::Has;
use crate::perception::MemoryParams;
use crate::plant_aware::PlantAwareParams;
use crate::rc::map::RcParams;
use crate::replan::ReplanParams;
use crate::supervisor::modes::ModeParams;
use crate::thrust::ThrustParams;
use crate::tracking::TrackingParams;
use crate::waypoint::WaypointParams;

pub use crate::param_decl::{host_text, HostText, NoText, ParamRejected, RangeText};

/// One parameter of the controller (declared beside its struct, [`crate::param_decl::Param`]).
pub type Param = crate::param_decl::Param<ControllerParams>;

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
    /// The default value: [`ControllerParams::default`]'s.
    pub fn default_value(&self) -> f32 {
        (self.get)(&ControllerParams::default())
    }
}

/// Where each parameters struct sits in [`ControllerParams`] (`Has<CbfParams>` reads `cbf`, …):
/// one line per struct, however many parameters it declares.
macro_rules! parts {
    ($($ty:ty => $($field:ident).+;)+) => {
        $(
            impl Has<$ty> for ControllerParams {
                fn part(&self) -> &$ty {
                    &self.$($field).+
                }
                fn part_mut(&mut self) -> &mut $ty {
                    &mut self.$($field).+
                }
            }
        )+
    };
}

parts! {
    CbfParams => cbf;
    FilterVariant => filter_variant;
    TrackingParams => tracking;
    WaypointParams => waypoint;
    FailsafeParams => failsafe;
    Airframe => airframe;
    ThrustParams => thrust;
    PlantAwareParams => plant_aware;
    MemoryParams => perception;
    ModeParams => modes;
    PathYawParams => guidance.path_yaw;
    GuidanceParams => guidance;
    TrajectoryParams => guidance.trajectory;
    RcParams => rc;
    BatteryParams => battery;
    SensorCal => sensors;
    GovernorParams => governor;
    ReplanParams => replan;
}

/// The set's own fields (`hull_radius`, [`ControllerParams::params`]).
impl Has<ControllerParams> for ControllerParams {
    fn part(&self) -> &ControllerParams {
        self
    }
    fn part_mut(&mut self) -> &mut ControllerParams {
        self
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

/// [`PARTS`] from the structs' lists, and (tests) each list's parameters read from its struct's
/// own `Default`.
macro_rules! table {
    ($($ty:ident :: $list:ident,)+) => {
        /// Each struct's parameter list, in MAVLink `param_index` order (the order they came
        /// in: a struct's later parameters may be a second list further down, so no index
        /// moved).
        pub const PARTS: &[&[Param]] = &[$(&$ty::$list()),+];

        /// Calls `f` with each parameter of [`PARTS`] and its value in a set whose struct of
        /// that parameter is the struct's own `Default` (the rest as [`ControllerParams::default`]).
        #[cfg(test)]
        fn for_each_own_default(mut f: impl FnMut(&Param, f32)) {
            $(
                let mut own = ControllerParams::default();
                *Has::<$ty>::part_mut(&mut own) = $ty::default();
                for p in &$ty::$list::<ControllerParams>() {
                    f(p, (p.get)(&own));
                }
            )+
        }
    };
}

table! {
    // The flight parameters: CBF filter, tracking, mission speed, obstacle failsafe, vehicle,
    // ground/ceiling barriers, perception memory (issues 1-19).
    CbfParams::params,
    FilterVariant::params,
    TrackingParams::params,
    WaypointParams::params,
    FailsafeParams::params,
    CbfParams::margin_params,
    Airframe::params,
    ThrustParams::params,
    ControllerParams::params,
    PlantAwareParams::params,
    MemoryParams::params,
    // The pilot-facing parameters: flight modes, per-mode failsafes, return (issue 21), the
    // yaw along a path (issue 19), the mission's guidance and trajectory (issue 35), the RC
    // channel map and pulse ranges (issue 21).
    ModeParams::params,
    PathYawParams::params,
    GuidanceParams::params,
    TrajectoryParams::params,
    TrackingParams::trajectory_params,
    RcParams::params,
    // The set-up parameters: battery, calibration and board rotation (issue 22), the speed
    // governor (issue 36), on-board replanning (issue 38).
    BatteryParams::params,
    SensorCal::params,
    GovernorParams::params,
    ReplanParams::params,
}

/// Number of parameters: the lengths of [`PARTS`] added (nothing to count by hand).
pub const COUNT: usize = {
    let mut n = 0;
    let mut i = 0;
    while i < PARTS.len() {
        n += PARTS[i].len();
        i += 1;
    }
    n
};

/// The parameters, in MAVLink `param_index` order: the lists of [`PARTS`], one after the other.
///
/// A `static`, not a `const`: every use of a `const` array may materialise its own copy in
/// the image (the F405 build held three of these ~5 KB tables, one per using function group).
pub static TABLE: [Param; COUNT] = ENTRIES;

/// [`TABLE`]'s contents at compile time (for [`NAMES`]).
const ENTRIES: [Param; COUNT] = {
    let mut out = [PARTS[0][0]; COUNT];
    let mut k = 0;
    let mut i = 0;
    while i < PARTS.len() {
        let mut j = 0;
        while j < PARTS[i].len() {
            out[k] = PARTS[i][j];
            k += 1;
            j += 1;
        }
        i += 1;
    }
    out
};

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

    /// Each parameter's default is its struct's own (`CbfParams::default()`, …): the set's
    /// default (`ControllerParams::default`) writes no parameter's default a second time.
    #[test]
    fn defaults_are_the_structs_own() {
        let set = ControllerParams::default();
        let mut seen = 0;
        for_each_own_default(|p, own| {
            seen += 1;
            let v = (p.get)(&set);
            assert_eq!(
                v.to_bits(),
                own.to_bits(),
                "{}: ControllerParams::default() has {v}, its struct {own}",
                p.name
            );
        });
        assert_eq!(seen, COUNT);
    }

    /// Every `("NAME",` (a parameter declaration's first argument) in the non-test code of
    /// `core/src/**/*.rs`, with the files it is in (comments dropped).
    fn declarations() -> std::collections::BTreeMap<std::string::String, std::vec::Vec<std::string::String>> {
        use std::string::ToString;
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut out: std::collections::BTreeMap<_, std::vec::Vec<_>> = Default::default();
        let mut dirs = std::vec![root.clone()];
        while let Some(dir) = dirs.pop() {
            for entry in std::fs::read_dir(&dir).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() {
                    dirs.push(path);
                    continue;
                }
                if path.extension().is_none_or(|e| e != "rs") {
                    continue;
                }
                let text = std::fs::read_to_string(&path).unwrap();
                let code = text.split("#[cfg(test)]").next().unwrap_or("");
                let file = path.strip_prefix(&root).unwrap().display().to_string();
                for line in code.lines() {
                    let line = line.find("//").map_or(line, |k| &line[..k]);
                    for (k, _) in line.match_indices("(\"") {
                        let rest = &line[k + 2..];
                        let name: std::string::String = rest
                            .chars()
                            .take_while(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || *c == '_')
                            .collect();
                        if !name.is_empty() && rest[name.len()..].starts_with("\",") {
                            out.entry(name).or_default().push(file.clone());
                        }
                    }
                }
            }
        }
        out
    }

    /// The one-place rule, read from the source: each parameter of [`TABLE`] is declared once,
    /// in its struct's file (never in `params/`), and every declaration is in [`TABLE`] (a
    /// struct's list left out of [`PARTS`] fails here).
    #[test]
    fn each_parameter_is_declared_once_beside_its_struct() {
        let found = declarations();
        for d in &TABLE {
            let files = found.get(d.name).cloned().unwrap_or_default();
            assert_eq!(files.len(), 1, "{} declared {} times: {files:?}", d.name, files.len());
            assert!(
                !files[0].starts_with("params"),
                "{} declared in {}, not beside its struct",
                d.name,
                files[0]
            );
        }
        for (name, files) in &found {
            assert!(
                find(name).is_some(),
                "{name} is declared in {files:?} but not in TABLE: add its list to PARTS"
            );
        }
        assert_eq!(found.len(), COUNT);
    }

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
