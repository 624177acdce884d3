//! Up-front checks of a run's configuration against the limits that the flight
//! controller (`parapet-core`) and the runner enforce, so that a bad value is
//! refused before the flight with an [`InputError`] naming where it came from
//! (a command-line option, the scene file's table and field, or the built-in
//! default), the value and the allowed range — instead of a library error enum
//! (`Waypoint(BadParams)`, `Tracking`, `Thrust`, …) after the start.
//!
//! The ranges are the core's own constants and rules ([`waypoint::PARAM_LIMIT`],
//! `CbfParams::validate`, `ControllerParams::validate`) and the caps of
//! [`crate::input::limits`]; nothing is retyped.
//!
//! Owns: [`Given`], [`check_run`], and the words for the core's error enums
//! ([`describe_param_error`], [`describe_path_error`], [`describe_command_error`]).
//! May import: `input`, `world::scene`, `flight::runner`, `parapet-core`.

use parapet_core::cbf::CbfParams;
use parapet_core::controller::{CommandError, ControllerParams, ParamError};
use parapet_core::frame::GRAVITY;
use parapet_core::params;
use parapet_core::waypoint::{self, PathError};

use crate::flight::runner::{controller_params, RunConfig};
use crate::input::f32_as_f64;
use crate::input::{limits, num, InputError};
use crate::world::scene::Scene;
use crate::world::schema::param_accepts;

/// Which run settings were given on the command line (they win over the scene),
/// and the duration cap in force (`--max-duration`).
#[derive(Clone, Debug)]
pub struct Given {
    /// Names (without dashes) of the options given: `mu`, `delta`, `delta1`,
    /// `kp`, `kd`, `speed`, `duration`, `sensing-range`.
    pub options: Vec<&'static str>,
    /// Longest duration allowed, s ([`limits::MAX_DURATION_S`] unless raised).
    pub max_duration: f64,
}

impl Default for Given {
    fn default() -> Self {
        Given { options: Vec::new(), max_duration: limits::MAX_DURATION_S }
    }
}

impl Given {
    fn has(&self, name: &str) -> bool {
        self.options.contains(&name)
    }
}

/// Where a controller setting came from, to build the error about it.
struct Origin<'a> {
    scene: &'a Scene,
    given: &'a Given,
}

impl Origin<'_> {
    /// An error about the setting `option` (CLI name) / `[table] field` (scene).
    fn err(
        &self,
        option: &'static str,
        table: &str,
        field: &str,
        in_scene: bool,
        reason: String,
    ) -> InputError {
        if self.given.has(option) {
            InputError::option(option, reason)
        } else if in_scene {
            InputError::file(&self.scene.source, reason).table(table).field(field)
        } else {
            InputError::file("built-in default", reason).field(field)
        }
    }

    /// A short label of where the setting came from, for messages about two values.
    fn label(&self, option: &'static str, in_scene: bool) -> String {
        if self.given.has(option) {
            format!("--{option}")
        } else if in_scene {
            format!("{} [controller]", self.scene.source)
        } else {
            "built-in default".into()
        }
    }
}

/// Check the run configuration `cfg` for `scene` before flying; `given` says
/// which settings came from the command line. Covers the reference speed, the
/// filter parameters (μ, δ, δ1 > δ, A, ε_v, in `f32`), the PD gains, the
/// duration against `given.max_duration`, dt and the plant-step cap, the
/// sensing range, the position latency, and finally the core's own
/// `ControllerParams::validate` (vehicle mass vs. thrust limits, …), every
/// refusal naming its origin.
pub fn check_run(scene: &Scene, cfg: &RunConfig, given: &Given) -> Result<(), InputError> {
    let o = Origin { scene, given };
    let c = &scene.controller;
    let p = &cfg.params;

    // The controller settings against the parameter table's ranges (parapet_core::params,
    // in f32 as the core sees them), each refusal naming where the value came from.
    let speed_table = if c.speed.is_some() { "controller" } else { "mission" };
    for (key, x, table, in_scene) in [
        ("speed", p.speed, speed_table, true),
        ("kp", p.kp, "controller", c.kp.is_some()),
        ("kd", p.kd, "controller", c.kd.is_some()),
        ("mu", p.mu, "controller", c.mu.is_some()),
        ("delta", p.delta, "controller", c.delta.is_some()),
        ("delta1", p.delta1, "controller", c.delta1.is_some()),
        ("accel_bound", cfg.accel_bound, "controller", c.accel_bound.is_some()),
        ("velocity_margin", cfg.velocity_margin, "controller", c.velocity_margin.is_some()),
        ("mem_voxel", f64::from(cfg.memory.voxel), "controller", c.mem_voxel.is_some()),
        ("mem_forget", f64::from(cfg.memory.forget_s), "controller", c.mem_forget.is_some()),
        ("mem_keep_near", f64::from(cfg.memory.keep_near), "controller", c.mem_keep_near.is_some()),
        ("mem_clear_margin", f64::from(cfg.memory.clear_margin), "controller", c.mem_clear_margin.is_some()),
        ("mem_track_size", f64::from(cfg.memory.track_size), "controller", c.mem_track_size.is_some()),
        ("fov_margin", f64::from(cfg.memory.fov_margin), "controller", c.fov_margin.is_some()),
        ("fov_walls", f64::from(cfg.memory.fov_walls), "controller", c.fov_walls.is_some()),
    ] {
        let Some(d) = params::by_key(key) else { continue };
        if !param_accepts(d, x) {
            return Err(o
                .err(key, table, key, in_scene, format!("out of range ({})", d.description))
                .value(num(x))
                .allowed(d.range().to_string()));
        }
    }
    if (p.delta1 as f32) <= (p.delta as f32) {
        let (d_scene, d1_scene) = (c.delta.is_some(), c.delta1.is_some());
        // Blame the value the user set (δ1 when both or neither were set).
        let delta_is_user = given.has("delta") || d_scene;
        let delta1_is_user = given.has("delta1") || d1_scene;
        return Err(if delta_is_user && !delta1_is_user {
            o.err(
                "delta",
                "controller",
                "delta",
                d_scene,
                format!(
                    "the safety level δ must be below the engagement level δ1 = {} ({}; set delta1 too)",
                    p.delta1,
                    o.label("delta1", d1_scene)
                ),
            )
            .value(num(p.delta))
            .allowed(format!("0 < delta < {}", p.delta1))
        } else {
            o.err(
                "delta1",
                "controller",
                "delta1",
                d1_scene,
                format!(
                    "the engagement level δ1 must exceed the safety level δ = {} ({})",
                    p.delta,
                    o.label("delta", d_scene)
                ),
            )
            .value(num(p.delta1))
            .allowed(format!("delta1 > {}", p.delta))
        });
    }
    check_duration(&o, cfg)?;
    if !(cfg.sensing_range > 0.0 && cfg.sensing_range <= limits::MAX_COORDINATE_M) {
        let in_scene = scene.sim.sensing_range.is_some();
        return Err(o
            .err("sensing-range", "sim", "sensing_range", in_scene, "sensing range out of range".into())
            .value(num(cfg.sensing_range))
            .allowed(format!("0 < sensing range ≤ {} m", limits::MAX_COORDINATE_M)));
    }
    let lat = cfg.sensors.position_latency;
    let lat_cap = limits::max_position_latency_s(cfg.sensors.position_source.is_mocap());
    if !(lat.is_finite() && (0.0..=lat_cap).contains(&lat)) {
        return Err(InputError::file(
            &scene.source,
            format!(
                "position latency beyond the cap (the flight controller's position timeout is {} s)",
                num(limits::position_timeout_s())
            ),
        )
        .table("sensors")
        .field("position_latency")
        .value(num(lat))
        .allowed(format!("0 ≤ position_latency ≤ {} s", num(lat_cap))));
    }
    // The core's own parameter check, for what the scene's vehicle implies.
    let cbf = CbfParams {
        mu: p.mu as f32,
        delta: p.delta as f32,
        delta1: p.delta1 as f32,
        accel_bound: cfg.accel_bound as f32,
        velocity_margin: cfg.velocity_margin as f32,
        ..CbfParams::default()
    };
    let params = controller_params(scene, cfg, cbf, cfg.variant);
    match params.validate() {
        // δ comes from `--delta`, the scene's [controller] or the default: name where.
        Err(ParamError::DeltaBelowHull { delta, hull_sq }) => {
            return Err(o
                .err(
                    "delta",
                    "controller",
                    "delta",
                    c.delta.is_some(),
                    delta_below_hull(delta, hull_sq, scene),
                )
                .value(format!("{delta}"))
                .allowed(format!("delta >= hull_radius² = {hull_sq} m²")))
        }
        Err(e) => return Err(describe_param_error(scene, &params, e)),
        Ok(()) => {}
    }
    check_vehicle_integrable(scene, cfg)
}

/// Why δ below the squared hull radius is refused (both values named).
fn delta_below_hull(delta: f32, hull_sq: f32, scene: &Scene) -> String {
    format!(
        "delta = {delta} m² is below the squared hull radius {hull_sq} m² \
         ([vehicle] hull_radius = {} m): the filter would let obstacles inside the hull",
        num(scene.vehicle.hull_radius)
    )
}

/// `[vehicle]` values the plant's fixed-step RK4 cannot integrate (the state
/// went non-finite within milliseconds, exit 1 without naming the field):
/// linear drag faster than the step (drag / mass ≤ 1 / dt; RK4 diverges at
/// 2.8 / dt), and a yaw torque coefficient beyond the roll arm's moment per
/// unit thrust (k_m ≤ k_f · arm_length; propellers have k_m / k_f ≈ 0.01–0.05 m).
fn check_vehicle_integrable(scene: &Scene, cfg: &RunConfig) -> Result<(), InputError> {
    let v = &scene.vehicle;
    let err =
        |field: &str, reason: &str| InputError::file(&scene.source, reason).table("vehicle").field(field);
    let max_drag = v.mass / cfg.dt;
    if let Some(d) = v.drag.iter().find(|d| **d > max_drag) {
        return Err(err(
            "drag",
            "linear drag too fast for the plant step (time constant mass / drag below dt)",
        )
        .value(num(*d))
        .allowed(format!("0 ≤ drag ≤ mass / dt = {} N/(m/s)", num(max_drag))));
    }
    let max_km = v.k_f * v.arm_length;
    if v.k_m > max_km {
        return Err(err("k_m", "yaw torque coefficient beyond the roll arm's moment per unit thrust")
            .value(num(v.k_m))
            .allowed(format!("0 ≤ k_m ≤ k_f · arm_length = {} N m/(rad/s)²", num(max_km))));
    }
    Ok(())
}

/// The duration against the cap in force, and duration / dt against the step cap.
fn check_duration(o: &Origin, cfg: &RunConfig) -> Result<(), InputError> {
    let (scene, given) = (o.scene, o.given);
    let cap = given.max_duration;
    let dt_range = format!("{:e} ≤ dt ≤ {:e} s", limits::MIN_DT_S, limits::MAX_DT_S);
    if !(cfg.dt >= limits::MIN_DT_S && cfg.dt <= limits::MAX_DT_S) {
        return Err(InputError::file(&scene.source, "plant integration step out of range")
            .table("sim")
            .field("dt")
            .value(num(cfg.dt))
            .allowed(dt_range));
    }
    let d = cfg.duration;
    let raise = if cap < limits::MAX_DURATION_CEILING_S {
        format!("; --max-duration raises the cap up to {} s", limits::MAX_DURATION_CEILING_S)
    } else {
        String::new()
    };
    let err = |reason: String| {
        if given.has("duration") {
            InputError::option("duration", reason)
        } else if scene.sim.duration.is_some() {
            InputError::file(&scene.source, reason).table("sim").field("duration")
        } else {
            InputError::option(
                "duration",
                format!(
                    "the default duration (from the path length and the reference speed {} m/s) {reason}; \
                     give --duration or a higher --speed",
                    num(cfg.params.speed)
                ),
            )
        }
    };
    if !(d.is_finite() && d > 0.0 && d <= cap) {
        return Err(err(format!("is beyond the duration cap{raise}"))
            .value(num(d))
            .allowed(format!("0 < duration ≤ {} s", num(cap))));
    }
    let steps = d / cfg.dt;
    if steps > limits::MAX_PLANT_STEPS {
        return Err(err(format!(
            "needs {steps:.3e} plant steps at dt = {} s, above the cap of {:e} steps (shorten it or raise [sim] dt)",
            cfg.dt,
            limits::MAX_PLANT_STEPS
        ))
        .value(num(d))
        .allowed(format!("duration ≤ {} s at this dt", limits::MAX_PLANT_STEPS * cfg.dt)));
    }
    Ok(())
}

/// A core parameter error as an [`InputError`] about the scene's table and
/// field it comes from, in words (never the enum's debug text).
pub fn describe_param_error(scene: &Scene, params: &ControllerParams, e: ParamError) -> InputError {
    let file = &scene.source;
    let v = &scene.vehicle;
    match e {
        ParamError::Cbf(c) => {
            InputError::file(file, format!("filter parameters rejected: {c}")).table("controller")
        }
        ParamError::Waypoint(_) => {
            InputError::file(file, "reference speed rejected by the waypoint follower")
                .table("mission")
                .field("speed")
                .value(num(scene.speed))
                .allowed(params::by_key("speed").map(|p| p.range().to_string()).unwrap_or_default())
        }
        ParamError::Tracking => InputError::file(file, "PD gains rejected by the tracking controller")
            .table("controller")
            .allowed("kp, kd finite and > 0"),
        ParamError::Thrust => {
            let th = &params.thrust;
            let (lo, hi) = (th.thrust_min as f64 / GRAVITY as f64, th.thrust_max as f64 / GRAVITY as f64);
            InputError::file(
                file,
                format!(
                    "the hover thrust m·g = {} N must lie between the controller's minimum thrust {} N \
                     and 90 % of the rotors' maximum {:.3} N",
                    num(v.mass * GRAVITY as f64),
                    th.thrust_min,
                    th.thrust_max
                ),
            )
            .table("vehicle")
            .field("mass")
            .value(num(v.mass))
            .allowed(format!("{lo:.4} < mass < {hi:.4} kg with these rotors"))
        }
        ParamError::Mixer(_) => InputError::file(
            file,
            "the vehicle's airframe is unusable by the mixer (arm length, inertia, k_m/k_f)",
        )
        .table("vehicle"),
        ParamError::Attitude(_) => {
            InputError::file(file, "attitude controller rejected the vehicle's inertia")
                .table("vehicle")
                .field("inertia")
        }
        ParamError::DeltaBelowHull { delta, hull_sq } => {
            InputError::file(file, delta_below_hull(delta, hull_sq, scene))
                .table("controller")
                .field("delta")
                .value(format!("{delta}"))
                .allowed(format!("delta >= hull_radius² = {hull_sq} m²"))
        }
        ParamError::PlantAware(r) => {
            InputError::file(file, format!("plant-aware filter parameters rejected: {r}")).table("controller")
        }
        ParamError::Governor => InputError::file(file, "speed governor parameters rejected")
            .table("controller")
            .field("GOV_MARGIN, GOV_DELAY, GOV_RANGE")
            .allowed("0 <= GOV_MARGIN <= 2 m, 0 <= GOV_DELAY <= 1 s, 0.5 <= GOV_RANGE <= 100 m"),
        ParamError::Estimator(_) | ParamError::Failsafe | ParamError::Loop => InputError::file(
            file,
            "the flight controller's built-in parameters were rejected (a parapet bug)",
        ),
    }
}

/// A core path error in words (never the enum's debug text).
pub fn describe_path_error(e: PathError) -> String {
    let lim = waypoint::COORDINATE_LIMIT;
    match e {
        PathError::Empty => "the path has no waypoint".into(),
        PathError::TooMany { capacity } => format!("the path has more than {capacity} waypoints"),
        PathError::NonFinite { index } => format!("waypoint {index} is not finite"),
        PathError::OutOfRange { index } => format!("waypoint {index} has a coordinate beyond ±{lim} m"),
        PathError::BadParams => {
            format!(
                "cruise speed not in (0, {0}] m/s or corner radius not in [0, {0}] m",
                waypoint::PARAM_LIMIT
            )
        }
        PathError::BadOrigin => format!("the start is not finite or beyond ±{lim} m"),
        PathError::NoPath => "no path was set".into(),
    }
}

/// A core command refusal in words (never the enum's debug text).
pub fn describe_command_error(e: CommandError) -> String {
    match e {
        CommandError::Arm(r) => format!("arming refused: {r}"),
        CommandError::NotArmed => "the controller is not armed".into(),
        CommandError::AlreadyDisarmed => "the controller is already disarmed".into(),
        CommandError::BadHeight => "takeoff height not finite or above the limit".into(),
        CommandError::BadTarget => "target position not finite".into(),
        CommandError::NotFlying => "the vehicle is not flying (take off first)".into(),
        CommandError::Path(p) => format!("path rejected: {}", describe_path_error(p)),
        CommandError::NoPosition => "no fresh position fix".into(),
        CommandError::ModeUnavailable => {
            "the flight mode cannot be flown now (Manual/Position need RC, Offboard a fresh setpoint, Return a fix)"
                .into()
        }
    }
}

/// Built-in defaults of the controller settings, for `--help`: every parameter-table entry
/// with a scene/option key but the scene's own speed, with its unit, as shortest decimals
/// (the filter variant by name).
pub fn defaults_help() -> String {
    let list: Vec<String> = params::TABLE
        .iter()
        .filter_map(|p| p.key.filter(|k| *k != "speed").map(|k| (p, k)))
        .map(|(p, k)| match p.label.and_then(|l| l(p.default_value() as i32)) {
            Some(name) => format!("{k} {name}"),
            None => format!("{k} {} {}", f32_as_f64(p.default_value()), p.unit),
        })
        .collect();
    format!(
        "Built-in defaults (a scene's [controller] table and the options override them):\n  {}",
        list.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = include_str!("../../tests/data/scenes/validate_unit.toml");

    fn setup(extra: &str) -> (Scene, RunConfig) {
        let s = Scene::parse(&format!("{SCENE}{extra}"), "t.toml").unwrap_or_else(|e| panic!("{e}"));
        let cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).unwrap_or_else(|e| panic!("{e}"));
        (s, cfg)
    }

    #[test]
    fn the_defaults_pass_and_shortest_decimals() {
        let (s, cfg) = setup("");
        check_run(&s, &cfg, &Given::default()).unwrap();
        // No [controller] table: the core's f32 defaults, printed as written.
        assert_eq!(format!("{} {} {}", cfg.params.mu, cfg.params.delta, cfg.params.delta1), "1.4 0.05 0.1");
        assert_eq!(f32_as_f64(1.4), 1.4);
        assert_eq!(f32_as_f64(1.4) as f32, 1.4f32);
        assert!(defaults_help().contains("mu 1.4 s"), "{}", defaults_help());
    }

    #[test]
    fn core_errors_in_words() {
        let m = describe_path_error(PathError::OutOfRange { index: 3 });
        assert!(m.contains("waypoint 3") && m.contains("100000"), "{m}");
        let m =
            describe_command_error(CommandError::Arm(parapet_core::failsafe::ArmRefusal::NoFreshPosition));
        assert!(m.contains("position") && !m.contains("NoFreshPosition"), "{m}");
        let (s, cfg) = setup("[vehicle]\nmass = 1e-9\n");
        let p = controller_params(&s, &cfg, CbfParams::default(), cfg.variant);
        let m = describe_param_error(&s, &p, ParamError::Thrust).to_string();
        assert!(m.contains("[vehicle] field `mass`") && !m.contains("Thrust"), "{m}");
    }

    #[test]
    fn each_refusal_names_its_origin() {
        let msg = |extra: &str, f: &dyn Fn(&mut RunConfig), given: &[&'static str]| {
            let (s, mut cfg) = setup(extra);
            f(&mut cfg);
            let g = Given { options: given.to_vec(), ..Given::default() };
            check_run(&s, &cfg, &g).unwrap_err().to_string()
        };
        let m = msg("", &|c| c.params.speed = 200.0, &["speed"]);
        assert!(m.contains("option --speed") && m.contains("200") && m.contains("≤ 100"), "{m}");
        let m = msg("", &|c| c.params.speed = 150.0, &[]);
        assert!(m.contains("t.toml: [mission] field `speed`"), "{m}");
        let m = msg("", &|c| c.params.kp = 1e300, &["kp"]);
        assert!(m.contains("option --kp") && m.contains("1e300"), "{m}");
        let m = msg("[controller]\ndelta1 = 0.01\n", &|_| {}, &[]);
        assert!(
            m.contains("t.toml: [controller] field `delta1`") && m.contains("0.01") && m.contains("0.05"),
            "{m}"
        );
        let m = msg("[controller]\ndelta = 0.5\n", &|_| {}, &[]);
        assert!(m.contains("field `delta`:") && m.contains("0.5") && m.contains("0.1"), "{m}");
        let m = msg("", &|c| c.duration = 1e7, &["duration"]);
        assert!(m.contains("option --duration") && m.contains("3600") && m.contains("--max-duration"), "{m}");
        let m = msg("[sim]\nduration = 1e7\n", &|_| {}, &[]);
        assert!(m.contains("[sim] field `duration`") && m.contains("1e7"), "{m}");
        let m = msg("", &|c| c.duration = 5e6, &[]);
        assert!(m.contains("default duration") && m.contains("--duration"), "{m}");
        let m = msg("", &|c| c.sensors.position_latency = 10.0, &[]);
        assert!(m.contains("[sensors] field `position_latency`") && m.contains("0.1"), "{m}");
        let m = msg("[vehicle]\nmass = 1e-9\n", &|_| {}, &[]);
        assert!(m.contains("[vehicle] field `mass`") && m.contains("1e-9") && m.contains("< mass <"), "{m}");
        let m = msg("", &|c| c.dt = 2e-3, &[]);
        assert!(m.contains("t.toml: [sim] field `dt`") && m.contains("0.002") && m.contains("1e-3"), "{m}");
        // More steps than the cap: a long flight with the smallest dt, cap raised.
        let (s, mut cfg) = setup("");
        cfg.dt = limits::MIN_DT_S;
        cfg.duration = 5000.0;
        let g = Given { options: vec!["duration"], max_duration: limits::MAX_DURATION_CEILING_S };
        let m = check_run(&s, &cfg, &g).unwrap_err().to_string();
        assert!(m.contains("plant steps"), "{m}");
    }

    #[test]
    fn vehicles_the_plant_cannot_integrate_are_refused() {
        let (s, cfg) = setup("[vehicle]\nk_m = 1e10\n");
        let m = check_run(&s, &cfg, &Given::default()).unwrap_err().to_string();
        assert!(
            m.contains("t.toml: [vehicle] field `k_m`") && m.contains("1e10") && m.contains("k_f"),
            "{m}"
        );
        let (s, cfg) = setup("[vehicle]\ndrag = [0.1, 0.1, 1e30]\n");
        let m = check_run(&s, &cfg, &Given::default()).unwrap_err().to_string();
        assert!(m.contains("[vehicle] field `drag`") && m.contains("1e30") && m.contains("500"), "{m}");
        // Heavy drag that still integrates (time constant 0.83 ms at dt 1 ms) and the default pass.
        let (s, cfg) = setup("[vehicle]\ndrag = [600, 600, 600]\nmass = 0.6\n");
        check_run(&s, &cfg, &Given::default()).unwrap();
    }

    #[test]
    fn options_are_checked_against_the_parameter_table() {
        // A 1 cm hull, so the table's smallest δ (1e-4 m²) is not refused as below hull² (issue 17).
        let (s, base) = setup("[vehicle]\nhull_radius = 0.01\n");
        for name in ["mu", "delta", "kp", "kd"] {
            let range = params::by_key(name).unwrap();
            for (x, ok) in [(1e-300, false), (range.min as f64 * 0.99, false), (f32_as_f64(range.min), true)]
            {
                let mut cfg = base.clone();
                match name {
                    "mu" => cfg.params.mu = x,
                    "delta" => cfg.params.delta = x,
                    "kp" => cfg.params.kp = x,
                    _ => cfg.params.kd = x,
                }
                let g = Given { options: vec![name], ..Given::default() };
                let r = check_run(&s, &cfg, &g);
                if ok {
                    assert!(r.is_ok(), "{name} = {x}: {r:?}");
                    continue;
                }
                let m = r.unwrap_err().to_string();
                assert!(
                    m.contains(&format!("option --{name}"))
                        && m.contains(&num(x))
                        && m.contains(&range.range().to_string()),
                    "{m}"
                );
            }
        }
        // δ below the hull's square: refused, naming both values (issue 17).
        let (s, mut cfg) = setup("");
        cfg.params.delta = 0.01;
        let m = check_run(&s, &cfg, &Given { options: vec!["delta"], ..Given::default() })
            .unwrap_err()
            .to_string();
        assert!(m.contains("delta = 0.01") && m.contains("0.049999997") && m.contains("hull_radius"), "{m}");
        // A tiny cap prints as a number, not 300 zeros.
        let mut cfg = base.clone();
        cfg.duration = 45.0;
        let g = Given { options: vec!["duration"], max_duration: 1e-300 };
        let m = check_run(&s, &cfg, &g).unwrap_err().to_string();
        assert!(m.contains("≤ 1e-300 s") && m.len() < 300, "{m}");
    }
}
