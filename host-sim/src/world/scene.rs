//! Scene files: obstacles, bounds, mission and optional vehicle / controller /
//! sensor / simulation overrides, in TOML.
//!
//! Files are written **ENU, z up** (x east, y north, z = height above ground,
//! metres); [`Scene`] holds everything converted to the internal **NED** frame
//! with [`parapet_core::frame::enu_to_ned`]. The format (see `scenes/README.md`):
//!
//! ```toml
//! name = "office"
//! description = "optional text"
//! [bounds]     min = [x, y, z]   max = [x, y, z]
//! [mission]    start = [x, y, z]   goal = [x, y, z]   speed = 0.25
//! [vehicle]    hull_radius = 0.2236          # optional; any VehicleParams key
//! [controller] mu = 1.4  delta = 0.05  delta1 = 0.1  kp = 0.5  kd = 0.8  filter = "multi-relative"
//! [sensors]    noise = false                 # optional; any SensorParams key
//! [sim]        sensing_range = 3.0  duration = 120.0  dt = 0.001
//! [[obstacles]] kind = "sphere"   center = [x, y, z]  radius = r
//! [[obstacles]] kind = "box"      min = [x, y, z]     max = [x, y, z]
//! [[obstacles]] kind = "cylinder" base = [x, y, z]    radius = r  height = h
//! # any obstacle may move: velocity = [vx, vy, vz], or
//! #   waypoints = [[t, x, y, z], ...]  (piecewise linear in time)
//! # mapped = false: in the world (sensors, collisions, reports) but not in the map
//! #   (planner, mission, pre-flight path check); default true. Never over the start.
//! ```
//!
//! Unknown keys and invalid values are errors naming the file, the table
//! (`obstacles[i]` with a 0-based index), the field, the value and the allowed
//! range. The limits ([`crate::input::limits`]): coordinates and sizes ≤
//! `MAX_COORDINATE_M` (1e5 m), speed ≤ `MAX_SPEED_MPS` (100 m/s), `[sim] dt` in
//! [`MIN_DT_S`, `MAX_DT_S`] (10 µs … 1 ms), `position_latency` ≤
//! `MAX_POSITION_LATENCY_S` (0.1 s), noise ≤ `MAX_SENSOR_NOISE`, files ≤
//! `MAX_INPUT_FILE_BYTES`. The duration cap depends on `--max-duration` and is
//! checked by [`crate::flight::validate::check_run`].
//!
//! May import: `parapet-core`, [`super`]'s `schema`, `obstacle`, `frame`, `check`,
//! [`crate::input`], [`crate::sim`] (vehicle, sensor and disturbance settings).

use std::path::Path;

use nalgebra::Vector3;
use parapet_core::obstacle::Shape;

pub use super::frame::{enu_arr_to_ned, ned_to_enu_arr, to_f32, to_f64};
pub use super::obstacle::{reference_point, Motion, SceneObstacle};
pub(crate) use super::schema::describe_toml_error;
use super::schema::{bad, convert_obstacle, validate_controller, validate_sensors, within_limit, RawScene};
pub use super::schema::{ControllerOverrides, SimSettings};
use crate::input::{limits, InputError};
use crate::sim::plant::VehicleParams;
use crate::sim::sensors::SensorParams;

/// A scene file that could not be read or is invalid. `Display` gives
/// `"<file>: <where>: <what>"`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {message}")]
pub struct SceneError {
    /// The file (or label) the scene came from.
    pub file: String,
    /// What is wrong and where (table, obstacle index, field).
    pub message: String,
}

/// A validated scene, internal frame NED.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// Optional description.
    pub description: Option<String>,
    /// Where it was loaded from (label used in error messages).
    pub source: String,
    /// Bounds of the flight volume as written (ENU, m): (min, max).
    pub bounds_enu: ([f64; 3], [f64; 3]),
    /// Mission start, NED, m.
    pub start: Vector3<f64>,
    /// Mission goal, NED, m.
    pub goal: Vector3<f64>,
    /// Reference speed along the path, m/s (`[controller] speed` if given, else `[mission] speed`).
    pub speed: f64,
    /// Vehicle parameters (defaults overridden by `[vehicle]`).
    pub vehicle: VehicleParams,
    /// Controller overrides from `[controller]`.
    pub controller: ControllerOverrides,
    /// Sensor parameters from `[sensors]`, if the table is present.
    pub sensors: Option<SensorParams>,
    /// The keys the `[sensors]` table sets (they win over a `position_source` preset, also
    /// one given by `parapet run --position-source`).
    pub sensors_keys: Vec<String>,
    /// Simulation settings from `[sim]`.
    pub sim: SimSettings,
    /// Disturbances from `[wind]`, `[plant]`, `[faults]` (see [`crate::sim::disturbance`]).
    pub disturbances: crate::sim::disturbance::Disturbances,
    /// Obstacles (index = position in the file, 0-based).
    pub obstacles: Vec<SceneObstacle>,
    /// Range sensors of the `[[sensor]]` tables (`--perception scene`), checked.
    pub range_sensors: Vec<crate::sim::range::RangeSensor>,
    /// The battery model of the `[battery]` table (checked), if present: the run then
    /// simulates the pack and feeds its readings to the controller's battery estimator.
    pub battery: Option<crate::sim::battery::BatteryModelParams>,
}

impl From<SceneError> for InputError {
    fn from(e: SceneError) -> Self {
        InputError::file(e.file, e.message)
    }
}

impl Scene {
    /// Sets parameter `p` (one with a `[controller]` key) to `x` as the scene's `[controller]`
    /// table would (`--param NAME=VALUE`; `speed` then is the reference speed, as at load).
    pub fn apply_param(&mut self, p: &parapet_core::params::Param, x: f64) -> Result<(), String> {
        self.controller.set_param(p, x)?;
        if let Some(s) = self.controller.speed {
            self.speed = s;
        }
        Ok(())
    }

    /// Read and validate a scene file (at most `MAX_INPUT_FILE_BYTES`).
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let src = crate::input::read_text(path).map_err(|e| {
            let text = e.to_string();
            let message = text.strip_prefix(&format!("{file}: ")).unwrap_or(&text).to_string();
            SceneError { file: file.clone(), message }
        })?;
        Scene::parse(&src, &file)
    }

    /// Parse and validate scene TOML text; `file` labels error messages.
    pub fn parse(src: &str, file: &str) -> Result<Scene, SceneError> {
        let err = |message: String| SceneError { file: file.to_string(), message };
        let mut raw: RawScene = toml::from_str(src).map_err(|e| err(describe_toml_error(src, &e)))?;
        let coord = format!("finite, |x| ≤ {} m", limits::MAX_COORDINATE_M);
        let finite3 = |table: &str, field: &str, a: [f64; 3]| -> Result<(), SceneError> {
            if a.iter().all(|x| x.is_finite()) && within_limit(&a) {
                Ok(())
            } else {
                Err(err(format!("{table}: {}", bad(field, "coordinate out of range", a, &coord))))
            }
        };
        finite3("[bounds]", "min", raw.bounds.min)?;
        finite3("[bounds]", "max", raw.bounds.max)?;
        for i in 0..3 {
            if raw.bounds.min[i] >= raw.bounds.max[i] {
                return Err(err(format!(
                    "[bounds]: field `max`: must exceed `min` in every coordinate (min {:?}, max {:?})",
                    raw.bounds.min, raw.bounds.max
                )));
            }
        }
        let inside = |a: [f64; 3]| (0..3).all(|i| a[i] >= raw.bounds.min[i] && a[i] <= raw.bounds.max[i]);
        for (field, a) in [("start", raw.mission.start), ("goal", raw.mission.goal)] {
            finite3("[mission]", field, a)?;
            if !inside(a) {
                return Err(err(format!("[mission]: field `{field}`: {a:?} is outside the bounds")));
            }
        }
        // The reference speed's range is the parameter table's (WP_SPEED).
        let speed = parapet_core::params::by_key("speed");
        if !speed.is_some_and(|p| super::schema::param_accepts(p, raw.mission.speed)) {
            let range = speed.map_or_else(String::new, |p| p.range().to_string());
            return Err(err(format!(
                "[mission]: {}",
                bad("speed", "reference speed out of range", raw.mission.speed, &range)
            )));
        }
        let vehicle = raw.vehicle.unwrap_or_default();
        vehicle.validate().map_err(|e| err(format!("[vehicle]: field `{}`: {}", e.field, e.reason)))?;
        let controller = raw.controller.unwrap_or_default();
        validate_controller(&controller).map_err(|m| err(format!("[controller]: {m}")))?;
        let sim = raw.sim.unwrap_or_default();
        for (field, x) in [("sensing_range", sim.sensing_range), ("duration", sim.duration)] {
            if let Some(x) = x {
                if !(x.is_finite() && x > 0.0) {
                    return Err(err(format!("[sim]: {}", bad(field, "must be finite and > 0", x, "> 0"))));
                }
            }
        }
        if let Some(dt) = sim.dt {
            if !(limits::MIN_DT_S..=limits::MAX_DT_S).contains(&dt) {
                let allowed = format!("{:e} ≤ dt ≤ {:e} s", limits::MIN_DT_S, limits::MAX_DT_S);
                return Err(err(format!(
                    "[sim]: {}",
                    bad("dt", "plant integration step out of range", dt, &allowed)
                )));
            }
        }
        let sensors_keys = super::schema::sensors_keys(src);
        if let Some(s) = raw.sensors.as_mut() {
            // The source's preset under the keys the table sets (issue 39).
            let keys = &sensors_keys;
            s.apply_source_preset(&keys.iter().map(String::as_str).collect::<Vec<_>>());
            validate_sensors(s).map_err(|m| err(format!("[sensors]: {m}")))?;
        }
        let mut disturbances = crate::sim::disturbance::Disturbances::default();
        let tables =
            crate::sim::disturbance::RawTables { wind: raw.wind, plant: raw.plant, faults: raw.faults };
        disturbances.overlay(tables, &vehicle, file).map_err(|e| {
            let text = e.to_string();
            err(text.strip_prefix(&format!("{file}: ")).unwrap_or(&text).to_string())
        })?;
        let mut obstacles = Vec::with_capacity(raw.obstacles.len());
        for (i, o) in raw.obstacles.into_iter().enumerate() {
            obstacles.push(convert_obstacle(o).map_err(|m| err(format!("obstacles[{i}]: {m}")))?);
        }
        super::check::obstacles(&obstacles).map_err(err)?;
        unmapped_clear_of_start(&obstacles, &enu_arr_to_ned(raw.mission.start), vehicle.hull_radius)
            .map_err(err)?;
        let range_sensors = super::schema::convert_sensors(&raw.sensor).map_err(err)?;
        if let Some(b) = &raw.battery {
            b.validate(file).map_err(|e| {
                let text = e.to_string();
                err(text.strip_prefix(&format!("{file}: ")).unwrap_or(&text).to_string())
            })?;
        }
        Ok(Scene {
            name: raw.name,
            description: raw.description,
            source: file.to_string(),
            bounds_enu: (raw.bounds.min, raw.bounds.max),
            start: enu_arr_to_ned(raw.mission.start),
            goal: enu_arr_to_ned(raw.mission.goal),
            speed: controller.speed.unwrap_or(raw.mission.speed),
            vehicle,
            controller,
            sensors: raw.sensors,
            sensors_keys,
            disturbances,
            sim,
            obstacles,
            range_sensors,
            battery: raw.battery,
        })
    }

    /// Bounds of the flight volume, NED, m: (min, max) component-wise.
    pub fn bounds_ned(&self) -> (Vector3<f64>, Vector3<f64>) {
        let a = enu_arr_to_ned(self.bounds_enu.0);
        let b = enu_arr_to_ned(self.bounds_enu.1);
        (a.inf(&b), a.sup(&b))
    }

    /// Shapes of the static obstacles (NED), mapped or not (the world as it stands).
    pub fn static_shapes(&self) -> Vec<Shape> {
        self.obstacles.iter().filter(|o| o.is_static()).map(|o| o.shape).collect()
    }

    /// Shapes of the static **mapped** obstacles (NED): the map, what an offline
    /// planner and the mission know ([`SceneObstacle::in_map`]).
    pub fn map_shapes(&self) -> Vec<Shape> {
        self.obstacles.iter().filter(|o| o.in_map()).map(|o| o.shape).collect()
    }

    /// Number of obstacles with `mapped = false`.
    pub fn unmapped_count(&self) -> usize {
        self.obstacles.iter().filter(|o| !o.mapped).count()
    }

    /// `obstacles[i]`, with its name and `unmapped` when it is not in the map, as
    /// messages and reports name an obstacle: `obstacles[3] (crate, unmapped)`.
    pub fn obstacle_label(&self, i: usize) -> String {
        let o = self.obstacles.get(i);
        let mut notes: Vec<&str> = o.and_then(|o| o.name.as_deref()).into_iter().collect();
        if o.is_some_and(|o| !o.mapped) {
            notes.push("unmapped");
        }
        if notes.is_empty() {
            format!("obstacles[{i}]")
        } else {
            format!("obstacles[{i}] ({})", notes.join(", "))
        }
    }

    /// Every obstacle's shape and velocity at time `t` (s), NED.
    pub fn obstacles_at(&self, t: f64) -> Vec<(Shape, Vector3<f64>)> {
        self.obstacles.iter().map(|o| o.at(t)).collect()
    }

    /// Signed distance (m) from `p` (NED) to the nearest obstacle surface at
    /// time `t`, and the index of that obstacle; `(inf, None)` with no obstacles.
    pub fn nearest(&self, p: &Vector3<f64>, t: f64) -> (f64, Option<usize>) {
        let pf = to_f32(p);
        let mut best = (f64::INFINITY, None);
        for (i, o) in self.obstacles.iter().enumerate() {
            let d = o.at(t).0.signed_distance(&pf) as f64;
            if d < best.0 {
                best = (d, Some(i));
            }
        }
        best
    }
}

/// An unmapped obstacle may not cover the mission start (the hull of radius `hull`
/// at `start`, NED, intersecting it): the vehicle would start inside something the
/// map does not know. The error names the obstacle and the field `mapped`.
fn unmapped_clear_of_start(
    obstacles: &[SceneObstacle],
    start: &Vector3<f64>,
    hull: f64,
) -> Result<(), String> {
    let p = to_f32(start);
    for (i, o) in obstacles.iter().enumerate().filter(|(_, o)| !o.mapped) {
        let sd = o.at(0.0).0.signed_distance(&p) as f64;
        if sd.is_nan() || sd < hull {
            return Err(format!(
                "obstacles[{i}]: field `mapped`: false, but the obstacle covers the mission start {:?} \
                 (distance from the start to its surface {sd:.4} m < hull radius {hull:.4} m; allowed: an \
                 unmapped obstacle at least the hull radius from the start, or `mapped = true`)",
                ned_to_enu_arr(start)
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::frame::{enu_to_ned, ned_to_enu};
    use parapet_core::Vec3;

    const OK: &str = include_str!("../../tests/data/scenes/scene_ok.toml");

    #[test]
    fn f64_conversions_match_core() {
        let a = [1.0, 2.0, 3.0];
        let core = enu_to_ned(Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(to_f32(&enu_arr_to_ned(a)), core);
        assert_eq!(ned_to_enu_arr(&enu_arr_to_ned(a)), a);
        assert_eq!(to_f32(&Vector3::from(ned_to_enu_arr(&to_f64(&core)))), ned_to_enu(core));
    }

    #[test]
    fn parses_and_converts_to_ned() {
        let s = Scene::parse(OK, "ok.toml").unwrap();
        assert_eq!(s.start, Vector3::new(0.0, 0.0, -1.0));
        assert_eq!(s.goal, Vector3::new(0.0, 8.0, -1.0));
        assert_eq!(s.obstacles.len(), 3);
        assert_eq!(s.speed, 0.4); // [controller] speed overrides [mission] speed
                                  // Sphere at east 4, up 1 → NED (0, 4, -1).
        let (d, i) = s.nearest(&Vector3::new(0.0, 3.0, -1.0), 0.0);
        assert_eq!(i, Some(0));
        assert!((d - 0.7).abs() < 1e-6);
        // Cylinder moving south (ENU y = -0.5 → NED x = -0.5) at 2 s: base (NED 2, 6, 0) moved 1 m south.
        let (shape, v) = s.obstacles[1].at(2.0);
        assert_eq!(v, Vector3::new(-0.5, 0.0, 0.0));
        assert_eq!(shape, Shape::cylinder(Vec3::new(1.0, 6.0, 0.0), 0.25, 1.8));
        // Box centre follows the waypoints: at t = 1 it is at ENU (1.5, 2.5, 1).
        let (shape, v) = s.obstacles[2].at(1.0);
        assert!((reference_point(&shape) - Vector3::new(2.5, 1.5, -1.0)).norm() < 1e-6);
        assert!((v - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
        assert!(s.obstacles[0].is_static() && !s.obstacles[1].is_static());
        assert_eq!(s.static_shapes().len(), 1);
    }

    fn err_of(src: &str) -> String {
        Scene::parse(src, "bad.toml").unwrap_err().to_string()
    }

    #[test]
    fn errors_name_file_obstacle_and_field() {
        let e = err_of(&OK.replace("radius = 0.3", "radus = 0.3"));
        assert!(e.starts_with("bad.toml:"), "{e}");
        assert!(e.contains("obstacles[0]") && e.contains("radus"), "{e}");
        let e = err_of(&OK.replace("radius = 0.25", "radius = -0.25"));
        assert!(e.contains("obstacles[1]") && e.contains("`radius`"), "{e}");
        let e = err_of(&OK.replace("radius = 0.25", "radius = \"big\""));
        assert!(e.contains("obstacles[1]") && e.contains("radius"), "{e}");
        let e = err_of(&OK.replace("kind = \"box\"", "kind = \"cone\""));
        assert!(e.contains("obstacles[2]") && e.contains("`kind`"), "{e}");
        let e = err_of(&OK.replace("min = [1, 1, 0]", "min = [3, 1, 0]"));
        assert!(e.contains("obstacles[2]") && e.contains("`max`"), "{e}");
        let e = err_of(&OK.replace("[2, 1.5", "[0, 1.5"));
        assert!(e.contains("obstacles[2]") && e.contains("`waypoints`"), "{e}");
        let e = err_of(&OK.replace("speed = 0.3", "speed = 0.3\nsped = 1"));
        assert!(e.contains("[mission]") && e.contains("sped"), "{e}");
        let e = err_of(&OK.replace("mu = 1.4", "mu = 0"));
        assert!(e.contains("[controller]") && e.contains("`mu`"), "{e}");
        let e = err_of(&OK.replace("\"paper\"", "\"fancy\""));
        assert!(e.contains("`filter`"), "{e}");
        let e = err_of(&OK.replace("goal = [8, 0, 1]", "goal = [80, 0, 1]"));
        assert!(e.contains("`goal`") && e.contains("outside"), "{e}");
        let e = err_of(&OK.replace("[controller]", "[vehicle]\nmass = -2\n[controller]"));
        assert!(e.contains("[vehicle]") && e.contains("`mass`"), "{e}");
        let e = err_of(&OK.replace("[controller]", "[vehicle]\nmas = 2\n[controller]"));
        assert!(e.contains("mas"), "{e}");
    }

    #[test]
    fn an_array_longer_than_its_field_is_refused() {
        // toml's document deserializer would keep the first three and drop the rest.
        let cases = [
            ("start = [0, 0, 1]", "start = [0, 0, 1, 3]", "[mission]", "`start`"),
            ("max = [10, 5, 3]", "max = [10, 5, 3, 9]", "[bounds]", "`max`"),
            ("center = [4, 0, 1]", "center = [4, 0, 1, 0]", "obstacles[0]", "`center`"),
            ("[2, 1.5, 3.5, 1]", "[2, 1.5, 3.5, 1, 7]", "obstacles[2]", "`waypoints`"),
            (
                "[controller]",
                "[vehicle]\ninertia = [0.002, 0.002, 0.003, 1]\n[controller]",
                "[vehicle]",
                "`inertia`",
            ),
        ];
        for (from, to, table, field) in cases {
            let e = err_of(&OK.replace(from, to));
            assert!(e.starts_with("bad.toml:") && e.contains(table) && e.contains(field), "{to}: {e}");
            assert!(e.contains("invalid length"), "{e}");
        }
        assert!(Scene::parse(OK, "ok.toml").is_ok());
    }

    #[test]
    fn a_missing_key_names_its_own_obstacle() {
        // The span of a missing `kind` is the table header itself.
        let e = err_of(&OK.replace("kind = \"cylinder\"\n", ""));
        assert!(e.contains("obstacles[1]") && e.contains("kind"), "{e}");
        let e = err_of(&OK.replace("kind = \"sphere\"\n", ""));
        assert!(e.contains("obstacles[0]") && e.contains("kind"), "{e}");
    }

    #[test]
    fn values_beyond_the_documented_limits_name_field_value_and_range() {
        let cases = [
            (OK.replace("radius = 0.3", "radius = 1e300"), "obstacles[0]", "`radius`", "1e300"),
            (OK.replace("center = [4, 0, 1]", "center = [4, 2e5, 1]"), "obstacles[0]", "`center`", "200000"),
            (OK.replace("speed = 0.3", "speed = 200"), "[mission]", "`speed`", "200"),
            (OK.replace("speed = 0.4", "speed = 150"), "[controller]", "`speed`", "150"),
            (OK.replace("mu = 1.4", "mu = 1e300"), "[controller]", "`mu`", "1e300"),
            (OK.replace("mu = 1.4", "delta = 0.2\ndelta1 = 0.1"), "[controller]", "`delta1`", "0.2"),
            (OK.replace("[controller]", "[sim]\ndt = 0.002\n[controller]"), "[sim]", "`dt`", "0.002"),
            (OK.replace("[controller]", "[sim]\ndt = 1e-7\n[controller]"), "[sim]", "`dt`", "1e-5"),
            (
                OK.replace("[controller]", "[sensors]\nposition_latency = 10\n[controller]"),
                "[sensors]",
                "`position_latency`",
                "0.1",
            ),
            (OK.replace("max = [10, 5, 3]", "max = [1e6, 5, 3]"), "[bounds]", "`max`", "100000"),
            (OK.replace("[2, 1.5, 3.5, 1]", "[2, 1.5, 3e5, 1]"), "obstacles[2]", "`waypoints`", "300000"),
        ];
        for (src, table, field, value) in cases {
            let e = err_of(&src);
            assert!(e.starts_with("bad.toml:"), "{e}");
            assert!(e.contains(table) && e.contains(field) && e.contains(value), "{table} {field}: {e}");
            assert!(e.contains("allowed"), "{e}");
        }
    }
}

#[cfg(test)]
mod shipped {
    use super::*;

    #[test]
    fn shipped_scenes_load_and_start_goal_are_free() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
        let mut n = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                let s = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
                let r = s.vehicle.hull_radius;
                assert!(s.nearest(&s.start, 0.0).0 > r, "{}: start too close", path.display());
                // The goal is reached long after t = 0: check it against the static obstacles,
                // as the planner does (a moving obstacle may start near the goal and walk away).
                let goal = crate::world::scene::to_f32(&s.goal);
                let goal_clearance = s
                    .static_shapes()
                    .iter()
                    .map(|sh| sh.signed_distance(&goal))
                    .fold(f32::INFINITY, f32::min);
                assert!(f64::from(goal_clearance) > r, "{}: goal too close", path.display());
                n += 1;
            }
        }
        assert!(n >= 4, "found {n} scenes");
    }
}

#[cfg(test)]
mod tracker {
    use super::*;
    use crate::world::NearestTracker;
    use parapet_core::Vec3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn office() -> Scene {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
        Scene::load(&dir.join("office.toml")).unwrap_or_else(|e| panic!("{e}"))
    }

    /// A random walk through `scene`: small steps, sometimes a jump, sometimes a
    /// teleport anywhere in (and a little beyond) the bounds, inside obstacles too.
    fn walk(scene: &Scene, seed: u64, n: usize) -> Vec<Vector3<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (lo, hi) = scene.bounds_ned();
        let uniform =
            |rng: &mut ChaCha8Rng| Vector3::from_fn(|i, _| rng.random_range(lo[i] - 0.5..hi[i] + 0.5));
        let mut p = scene.start;
        (0..n)
            .map(|_| {
                let r: f64 = rng.random();
                let size = if r < 0.01 {
                    0.0
                } else if r < 0.95 {
                    0.002
                } else if r < 0.99 {
                    0.5
                } else {
                    -1.0
                };
                p = if size < 0.0 {
                    uniform(&mut rng)
                } else {
                    p + Vector3::from_fn(|_, _| rng.random_range(-size..=size))
                };
                p
            })
            .collect()
    }

    #[test]
    fn tracker_equals_the_full_scan_bit_for_bit() {
        let mut scene = office();
        // A duplicate (equal distances: the lowest index wins), and a moving obstacle.
        let dup = scene.obstacles[3].clone();
        scene.obstacles.push(dup);
        scene.obstacles.push(SceneObstacle {
            name: None,
            shape: Shape::sphere(to_f32(&(scene.start + Vector3::new(1.0, 0.0, 0.0))), 0.3),
            motion: Motion::Velocity(Vector3::new(0.1, 0.2, 0.0)),
            mapped: true,
        });
        // A "moving" obstacle that stands still away from where its shape was written.
        let still = scene.start + Vector3::new(-0.6, 0.4, 0.0);
        scene.obstacles.push(SceneObstacle {
            name: None,
            shape: Shape::aabb(Vec3::new(9.0, 9.0, -1.0), Vec3::new(9.3, 9.2, -0.5)),
            motion: Motion::Waypoints(vec![(0.0, still), (5.0, still)]),
            mapped: true,
        });
        assert!(scene.obstacles[scene.obstacles.len() - 1].is_static());
        let n = scene.obstacles.len();
        let mut tracker = NearestTracker::new(&scene);
        let points = walk(&scene, 7, 40_000);
        let (mut inside, mut moving_nearest, mut still_nearest) = (0, 0, 0);
        for (k, p) in points.iter().enumerate() {
            let t = k as f64 * 0.001;
            let full = scene.nearest(p, t);
            let fast = tracker.nearest(&scene, p, t);
            assert_eq!(fast.0.to_bits(), full.0.to_bits(), "query {k} at {p:?}: {fast:?} vs {full:?}");
            assert_eq!(fast.1, full.1, "query {k} at {p:?}");
            inside += usize::from(full.0 < 0.0);
            moving_nearest += usize::from(full.1 == Some(n - 2));
            still_nearest += usize::from(full.1 == Some(n - 1));
            assert_ne!(full.1, Some(n - 3), "the duplicate never wins over the original");
        }
        assert!(
            inside > 10 && moving_nearest > 10 && still_nearest > 10,
            "inside {inside}, moving {moving_nearest}, still {still_nearest}"
        );
        // The broad phase skips most evaluations on a walk.
        let full_cost = (points.len() * n) as u64;
        assert!(tracker.evaluations * 4 < full_cost, "{} of {full_cost}", tracker.evaluations);
    }

    #[test]
    fn lower_bounds_hold_and_bad_points_fall_back_to_full_scans() {
        let scene = office();
        let mut tracker = NearestTracker::new(&scene);
        let mut bounded = 0;
        for (k, p) in walk(&scene, 3, 5_000).iter().enumerate() {
            // The bound on the nearest distance from the previous query, moved here.
            tracker.move_to(p);
            let lb = tracker.nearest_lower_bound();
            let exact = scene.nearest(p, 0.0).0;
            assert!(lb <= exact, "at {p:?}: {lb} > {exact}");
            bounded += usize::from(lb > exact - 0.01);
            tracker.nearest(&scene, p, 0.0);
            if k % 7 == 0 {
                for (i, o) in scene.obstacles.iter().enumerate() {
                    let d = o.shape.signed_distance(&to_f32(p)) as f64;
                    assert!(tracker.lower_bound(i) <= d, "obstacle {i} at {p:?}");
                }
            }
        }
        assert!(bounded > 4_000, "the nearest bound was tight in {bounded} of 5000 steps");
        let before = tracker.evaluations;
        let nan = Vector3::new(f64::NAN, 0.0, 0.0);
        assert_eq!(tracker.nearest(&scene, &nan, 0.0).1, scene.nearest(&nan, 0.0).1);
        assert_eq!(tracker.evaluations - before, scene.obstacles.len() as u64);
        let p = scene.start;
        assert_eq!(tracker.nearest(&scene, &p, 0.0), scene.nearest(&p, 0.0));
        assert!(tracker.lower_bound(0).is_nan() || tracker.lower_bound(0) == f64::NEG_INFINITY);
    }
}
