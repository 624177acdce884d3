//! Pre-flight checks: is this scene + path flyable at all, before any flight?
//!
//! ```text
//! pub fn check(scene: &Scene, cfg: &RunConfig, opts: &PreflightOptions) -> Result<(), InputError>
//! pub fn check_start(scene: &Scene) -> Result<(), InputError>   // 1. only, before planning
//! ```
//!
//! Called by `parapet run`, `parapet pil` (through `cli::run_setup`) and
//! `parapet sweep` before the first step; a refusal is an [`InputError`]
//! (exit 2) naming the file (the scene, or the path file), the waypoint index,
//! the coordinate (ENU, as in the files), the obstacle (index and name) or the
//! bound violated, and the tolerance. What is checked, in this order:
//!
//! 1. **Start** (`[mission] start`, where the vehicle hovers at t = 0): the hull
//!    (radius `[vehicle] hull_radius`) is clear of the ground (hull bottom at or
//!    above z = 0 ENU) and of **every** obstacle at t = 0 (moving obstacles at
//!    their t = 0 position). The start inside the bounds is checked when the
//!    scene is loaded.
//! 2. **The path belongs to the scene**: its first waypoint within
//!    [`PATH_END_TOLERANCE_M`] of the mission start and its last within that of
//!    the mission goal, unless [`PreflightOptions::foreign_path`]
//!    (`--foreign-path`) says the path is meant to go elsewhere.
//! 3. **Every waypoint** `i` of the path: its centre inside the scene bounds
//!    (the bounds are where the centre of mass may be, as for the planner; with
//!    [`BOUNDS_TOLERANCE_M`] for the `f32` round-off of path files), the hull
//!    clear of the ground and of every **static mapped** obstacle (the map the
//!    path was planned on). Moving obstacles are not checked at waypoints: they
//!    are elsewhere when the vehicle gets there, and the safety filter handles
//!    them in flight; unmapped ones (`mapped = false`) are not known before the
//!    flight, and the sensors and the filter meet them in flight. Segments between
//!    waypoints are not checked either (a straight line through an obstacle is
//!    what the filter is there for).
//!
//! "Clear" means signed distance from the centre to the surface ≥ hull radius:
//! the runner's collision test (`sd < hull`), so a start the runner would
//! count as a collision at t = 0 is refused here instead.
//!
//! May import: `crate::world::scene`, `crate::flight::runner` (RunConfig), `crate::input`, `nalgebra`.

use nalgebra::Vector3;

use crate::flight::runner::RunConfig;
use crate::input::InputError;
use crate::world::scene::{ned_to_enu_arr, to_f32, Scene};

/// How far (m) the first / last waypoint may be from the mission start / goal
/// for the path to count as the scene's (without `--foreign-path`).
pub const PATH_END_TOLERANCE_M: f64 = 0.5;

/// How far (m) a waypoint's centre may be outside the scene bounds before it
/// is refused: covers the `f32` round-off of waypoints written by the planner.
pub const BOUNDS_TOLERANCE_M: f64 = 1e-3;

/// What the caller knows about the path besides its waypoints.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PreflightOptions {
    /// The path file as given (`--path`), named in messages about waypoints;
    /// `None` for a planned or straight path (messages then name the scene file
    /// and `the planned path` / `the straight line`).
    pub path_file: Option<String>,
    /// The path need not start at the mission start nor end at its goal
    /// (`--foreign-path`): the endpoint check (2.) is skipped; bounds and
    /// collision checks still apply.
    pub foreign_path: bool,
}

/// Run every pre-flight check (see the module doc); `Ok` when the flight may start.
pub fn check(scene: &Scene, cfg: &RunConfig, opts: &PreflightOptions) -> Result<(), InputError> {
    let hull = scene.vehicle.hull_radius;
    check_start(scene)?;
    let origin = path_origin(scene, cfg, opts);
    let field = |i: usize| format!("waypoints[{i}]");
    if cfg.path.is_empty() {
        return Err(InputError::file(&origin, "the path has no waypoints").field("waypoints"));
    }
    if !opts.foreign_path {
        let n = cfg.path.len();
        let ends = [(0, scene.start, "start"), (n - 1, scene.goal, "goal")];
        for (i, target, what) in ends {
            let d = (cfg.path[i] - target).norm();
            if d.is_nan() || d > PATH_END_TOLERANCE_M {
                return Err(InputError::file(
                    &origin,
                    format!(
                        "the path does not belong to scene {} ({}): its {} waypoint is {d:.3} m from the mission {what} {} (a path for another scene?); pass --foreign-path to fly it anyway",
                        scene.name,
                        scene.source,
                        if i == 0 { "first" } else { "last" },
                        fmt3(&ned_to_enu_arr(&target)),
                    ),
                )
                .field(field(i))
                .value(fmt3(&ned_to_enu_arr(&cfg.path[i])))
                .allowed(format!("within {PATH_END_TOLERANCE_M} m of the mission {what}")));
            }
        }
    }
    let (lo, hi) = scene.bounds_enu;
    for (i, w) in cfg.path.iter().enumerate() {
        let e = ned_to_enu_arr(w);
        if !e.iter().all(|x| x.is_finite()) {
            return Err(InputError::file(&origin, "the waypoint is not finite")
                .field(field(i))
                .value(fmt3(&e)));
        }
        if let Some(axis) =
            (0..3).find(|&k| e[k] < lo[k] - BOUNDS_TOLERANCE_M || e[k] > hi[k] + BOUNDS_TOLERANCE_M)
        {
            let name = ["x", "y", "z"][axis];
            return Err(InputError::file(&origin, format!(
                "the waypoint is outside the bounds of scene {} ({}; [bounds] is where the centre of mass may be, tolerance {BOUNDS_TOLERANCE_M} m)",
                scene.name, scene.source
            ))
            .field(field(i))
            .value(fmt3(&e))
            .allowed(format!("{} ≤ {name} ≤ {}", lo[axis], hi[axis])));
        }
        if let Some(msg) = ground_violation(w, hull) {
            return Err(InputError::file(&origin, format!("the waypoint puts {msg}"))
                .field(field(i))
                .value(fmt3(&e))
                .allowed(format!("z ≥ {hull:.4} (hull radius)")));
        }
        if let Some((j, sd)) = obstacle_violation(scene, w, hull, true) {
            return Err(InputError::file(
                &origin,
                format!(
                    "the waypoint puts the hull (radius {hull:.4} m) into {} of scene {}: {}",
                    scene.obstacle_label(j),
                    scene.source,
                    depth(sd)
                ),
            )
            .field(field(i))
            .value(fmt3(&e))
            .allowed(format!("distance to every static mapped obstacle ≥ {hull:.4} m")));
        }
    }
    Ok(())
}

/// Check 1 alone (the start: hull clear of the ground and of every obstacle
/// at t = 0), for callers that plan from the start before they have a path;
/// [`check`] includes it.
pub fn check_start(scene: &Scene) -> Result<(), InputError> {
    let hull = scene.vehicle.hull_radius;
    let s = scene.start;
    let e = ned_to_enu_arr(&s);
    if let Some(msg) = ground_violation(&s, hull) {
        return Err(InputError::file(&scene.source, format!("the start puts {msg}"))
            .table("mission")
            .field("start")
            .value(fmt3(&e))
            .allowed(format!("z ≥ {hull:.4} (hull radius)")));
    }
    if let Some((j, sd)) = obstacle_violation(scene, &s, hull, false) {
        return Err(InputError::file(
            &scene.source,
            format!(
                "the start puts the hull (radius {hull:.4} m) into {} at t = 0: {}",
                scene.obstacle_label(j),
                depth(sd)
            ),
        )
        .table("mission")
        .field("start")
        .value(fmt3(&e))
        .allowed(format!("distance to every obstacle ≥ {hull:.4} m")));
    }
    Ok(())
}

/// Label of the path in messages: the path file, else the scene file plus the path's kind.
fn path_origin(scene: &Scene, cfg: &RunConfig, opts: &PreflightOptions) -> String {
    match &opts.path_file {
        Some(f) => f.clone(),
        None => {
            let kind = match cfg.path_source.as_str() {
                "planner" => "the planned path",
                "straight" => "the straight line start → goal",
                _ => "the path",
            };
            format!("{} ({kind})", scene.source)
        }
    }
}

/// `Some(description)` when the hull at `p` (NED) reaches below the ground z = 0.
fn ground_violation(p: &Vector3<f64>, hull: f64) -> Option<String> {
    let height = -p.z;
    (height < hull).then(|| {
        format!("the hull (radius {hull:.4} m) into the ground: the centre is {height:.4} m above z = 0")
    })
}

/// The first obstacle (index, signed distance of `p` to its surface at t = 0)
/// that the hull at `p` intersects; only the map's (static, mapped) when `map_only`.
fn obstacle_violation(scene: &Scene, p: &Vector3<f64>, hull: f64, map_only: bool) -> Option<(usize, f64)> {
    let pf = to_f32(p);
    scene.obstacles.iter().enumerate().find_map(|(j, o)| {
        if map_only && !o.in_map() {
            return None;
        }
        let sd = o.at(0.0).0.signed_distance(&pf) as f64;
        (sd < hull).then_some((j, sd))
    })
}

/// Where the centre is, from its signed distance `sd` (m) to the obstacle's surface.
fn depth(sd: f64) -> String {
    if sd < 0.0 {
        format!("the centre is inside it, {:.4} m below its surface", -sd)
    } else {
        format!("the centre is {sd:.4} m from its surface")
    }
}

/// `[x, y, z]` with up to 4 decimals, as a user would write it.
fn fmt3(a: &[f64; 3]) -> String {
    let f = |x: f64| {
        let s = format!("{x:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
        if s == "-0" {
            "0".to_string()
        } else {
            s
        }
    };
    format!("[{}, {}, {}]", f(a[0]), f(a[1]), f(a[2]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::scene::enu_arr_to_ned;

    /// Start (0, 0, 1), goal (6, 0, 1); a static sphere at x = 3 beside the line,
    /// a box wall at x = 4.5, and a sphere walking from far away at t = 0.
    const SCENE: &str = include_str!("../../tests/data/scenes/preflight_unit.toml");

    fn scene(text: &str) -> Scene {
        Scene::parse(text, "pf.toml").unwrap_or_else(|e| panic!("{e}"))
    }

    fn cfg(s: &Scene, enu: &[[f64; 3]]) -> RunConfig {
        let path = enu.iter().map(|a| enu_arr_to_ned(*a)).collect();
        RunConfig::for_scene(s, path).unwrap_or_else(|e| panic!("{e}"))
    }

    fn refused(s: &Scene, c: &RunConfig, o: &PreflightOptions) -> String {
        match check(s, c, o) {
            Ok(()) => panic!("accepted {:?}", c.path),
            Err(e) => e.to_string(),
        }
    }

    fn file() -> PreflightOptions {
        PreflightOptions { path_file: Some("p.json".into()), foreign_path: false }
    }

    #[test]
    fn a_good_path_passes() {
        let s = scene(SCENE);
        let c = cfg(&s, &[[0.0, 0.0, 1.0], [3.0, -0.5, 1.5], [6.0, 0.0, 1.0]]);
        assert_eq!(check(&s, &c, &file()), Ok(()));
        // A waypoint where the walker was at t = 0 is fine: it has moved on by then.
        let c = cfg(&s, &[[0.0, 0.0, 1.0], [5.0, 1.5, 1.0], [6.0, 0.0, 1.0]]);
        assert_eq!(check(&s, &c, &file()), Ok(()));
        // End points within the tolerance.
        let c = cfg(&s, &[[0.0, 0.3, 1.2], [6.0, -0.3, 0.8]]);
        assert_eq!(check(&s, &c, &file()), Ok(()));
    }

    #[test]
    fn start_in_an_obstacle_or_the_ground_is_refused_naming_it() {
        // Start 0.2 m from the ball's surface (hull 0.2236): in collision at t = 0.
        let s = scene(&SCENE.replace("start = [0, 0, 1]", "start = [3, 0.7, 1]"));
        let e = refused(&s, &cfg(&s, &[[3.0, 0.7, 1.0], [6.0, 0.0, 1.0]]), &file());
        assert!(e.starts_with("pf.toml: [mission] field `start`"), "{e}");
        assert!(
            e.contains("obstacles[0] (ball)") && e.contains("[3, 0.7, 1]") && e.contains("0.2236"),
            "{e}"
        );
        // A moving obstacle is checked at its t = 0 position.
        let s = scene(&SCENE.replace("start = [0, 0, 1]", "start = [5, 1.4, 1.1]"));
        let e = refused(&s, &cfg(&s, &[[5.0, 1.4, 1.1], [6.0, 0.0, 1.0]]), &file());
        assert!(
            e.contains("obstacles[2] (walker) at t = 0") && e.contains("inside it, 0.1586 m below"),
            "{e}"
        );
        // Hull bottom below the ground.
        let s = scene(&SCENE.replace("start = [0, 0, 1]", "start = [0, 0, 0.15]"));
        let e = refused(&s, &cfg(&s, &[[0.0, 0.0, 0.15], [6.0, 0.0, 1.0]]), &file());
        assert!(
            e.contains("[mission] field `start`") && e.contains("ground") && e.contains("z ≥ 0.2236"),
            "{e}"
        );
    }

    #[test]
    fn bad_waypoints_are_refused_naming_file_index_and_coordinate() {
        let s = scene(SCENE);
        type Case<'a> = (&'a [[f64; 3]], &'a str, &'a [&'a str]);
        let cases: [Case; 4] = [
            (
                &[[0.0, 0.0, 1.0], [3.0, 2.5, 1.0], [6.0, 0.0, 1.0]],
                "waypoints[1]",
                &["outside the bounds", "-2 ≤ y ≤ 2"],
            ),
            (
                &[[0.0, 0.0, 1.0], [2.0, 0.0, 0.15], [6.0, 0.0, 1.0]],
                "waypoints[1]",
                &["ground", "z ≥ 0.2236"],
            ),
            (
                &[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [4.2, -1.5, 1.0], [6.0, 0.0, 1.0]],
                "waypoints[2]",
                &["obstacles[1]", "[4.2, -1.5, 1]"],
            ),
            (&[[0.0, 0.0, 1.0], [3.0, 1.0, 1.0], [6.0, 0.0, 1.0]], "waypoints[1]", &["obstacles[0] (ball)"]),
        ];
        for (wps, field, words) in cases {
            let e = refused(&s, &cfg(&s, wps), &file());
            assert!(e.starts_with(&format!("p.json: field `{field}`")), "{e}");
            for w in words {
                assert!(e.contains(w), "{w:?} missing in {e}");
            }
        }
        // Without a path file the scene file and the path's kind are named.
        let mut c = cfg(&s, &[[0.0, 0.0, 1.0], [3.0, 2.5, 1.0], [6.0, 0.0, 1.0]]);
        c.path_source = "planner".into();
        let e = refused(&s, &c, &PreflightOptions::default());
        assert!(e.starts_with("pf.toml (the planned path): field `waypoints[1]`"), "{e}");
    }

    #[test]
    fn a_foreign_path_is_refused_unless_allowed() {
        let s = scene(SCENE);
        // First waypoint 0.6 m from the start.
        let c = cfg(&s, &[[0.0, 0.6, 1.0], [6.0, 0.0, 1.0]]);
        let e = refused(&s, &c, &file());
        assert!(e.contains("field `waypoints[0]`") && e.contains("0.600 m from the mission start"), "{e}");
        assert!(e.contains("within 0.5 m") && e.contains("--foreign-path"), "{e}");
        // Last waypoint 3 m short of the goal.
        let c = cfg(&s, &[[0.0, 0.0, 1.0], [3.0, -0.5, 1.0]]);
        let e = refused(&s, &c, &file());
        assert!(e.contains("field `waypoints[1]`") && e.contains("from the mission goal [6, 0, 1]"), "{e}");
        let allow = PreflightOptions { foreign_path: true, ..file() };
        assert_eq!(check(&s, &c, &allow), Ok(()));
        // --foreign-path does not lift the collision checks.
        let c = cfg(&s, &[[0.0, 0.0, 1.0], [3.0, 1.0, 1.0]]);
        assert!(refused(&s, &c, &allow).contains("obstacles[0] (ball)"));
    }

    #[test]
    fn every_committed_scene_and_path_passes() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
        let mut n = 0;
        for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{e}")) {
            let f = entry.unwrap_or_else(|e| panic!("{e}")).path();
            if f.extension().is_none_or(|x| x != "toml") {
                continue;
            }
            let s = Scene::load(&f).unwrap_or_else(|e| panic!("{e}"));
            let c = RunConfig::for_scene(&s, vec![s.start, s.goal]).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(check(&s, &c, &PreflightOptions::default()), Ok(()), "{}", f.display());
            let stem = f.file_stem().and_then(|x| x.to_str()).unwrap_or_default();
            let pf = dir.join(format!("{stem}_path.json"));
            if pf.exists() {
                let file = crate::plan::pathfile::PathFile::read(&pf).unwrap_or_else(|e| panic!("{e}"));
                let path = file.waypoints_ned().iter().map(crate::world::scene::to_f64).collect();
                let c = RunConfig::for_scene(&s, path).unwrap_or_else(|e| panic!("{e}"));
                let o = PreflightOptions { path_file: Some(pf.display().to_string()), foreign_path: false };
                assert_eq!(check(&s, &c, &o), Ok(()), "{}", pf.display());
                n += 1;
            }
        }
        assert!(n >= 4, "only {n} committed paths checked");
        // The office's path flown in the outdoor scene is refused as foreign.
        let s = Scene::load(&dir.join("outdoor_static.toml")).unwrap_or_else(|e| panic!("{e}"));
        let file = crate::plan::pathfile::PathFile::read(&dir.join("office_path.json"))
            .unwrap_or_else(|e| panic!("{e}"));
        let c =
            RunConfig::for_scene(&s, file.waypoints_ned().iter().map(crate::world::scene::to_f64).collect())
                .unwrap_or_else(|e| panic!("{e}"));
        let e = refused(
            &s,
            &c,
            &PreflightOptions { path_file: Some("office_path.json".into()), foreign_path: false },
        );
        assert!(
            e.contains("does not belong to scene outdoor_static") || e.contains("outside the bounds"),
            "{e}"
        );
    }

    #[test]
    fn without_the_preflight_check_the_core_refuses_to_arm() {
        // The runner alone (no pre-flight check): the flight controller's arm
        // check sees the ball's surface point inside the hull and refuses.
        let s = scene(&SCENE.replace("start = [0, 0, 1]", "start = [3, 0.75, 1]"));
        let c = cfg(&s, &[[3.0, 0.75, 1.0], [6.0, 0.0, 1.0]]);
        let e = match crate::fc::control::run(&s, &c, &mut |_| {}) {
            Ok(o) => panic!("flew: {:?}", o.summary.end_reason),
            Err(e) => format!("{e:#}"),
        };
        assert!(e.contains("refused to arm") && e.contains("obstacle 0 is reported inside the hull"), "{e}");
    }
}
