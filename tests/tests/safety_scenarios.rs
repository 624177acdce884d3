//! Issue 17 scenario tests: the situations where the default filter failed on the 6-DOF
//! plant (measured before the changes in `docs/robustness.md`, "Issue 17"), flown
//! with the real flight controller and the default filter (`multi-relative`):
//!
//! * the 0.6 m door (`scenes/narrow_passage.toml`, straight) at δ1 ∈ {0.1, 0.2, 0.3},
//!   seeds 0–4: no collision, goal reached;
//! * the dog-leg corridor (`scenes/dogleg_corridor.toml` + its path) at δ1 ∈ {0.1, 0.2,
//!   0.3} × speed {0.25, 0.5} m/s × seeds 0–4: no collision, goal reached in ≥ 95 %;
//! * a sphere (r 0.3 m) overtaking from behind (`scenes/sphere_overtaking.toml`) at 0.5–1.5
//!   m/s, on the path and 0.1 m beside it, and a person walking head-on
//!   (`scenes/person_headon.toml`) at 0.2–0.5 m/s, with the office parameters (μ 1.4,
//!   δ1 0.1, k_p 0.5, k_d 0.8), noise on and off: no collision, or `unavoidable` raised
//!   before the contact with a closing speed above the documented limit μ·u_max/2;
//! * a sphere hanging over the path at the vehicle's height 0.45 m above the ground
//!   (`scenes/low_sphere.toml`): no ground contact (no contact at all);
//! * 632 tiny spheres nearer than a wall across the path (`scenes/points_then_wall.toml`):
//!   no collision, and the obstacle set's drops are reported in the summary;
//! * the office path with the attitude loop slowed (attitude P gains × [`ATT_SCALES`]) at
//!   δ1 = 0.051, seeds 0–1: the default filter does not collide, where `paper` does (0.1×).
//!
//! Each test prints its table (`cargo test -p parapet-tests --test safety_scenarios --
//! --nocapture`); `docs/robustness.md` quotes them. Noise on unless a row says otherwise;
//! the seed is the sensor-noise seed.

use std::path::PathBuf;

use nalgebra::Vector3;
use parapet_core::cbf::{CbfParams, FilterVariant};
use parapet_core::outer::guidance::MissionGuidance;
use parapet_sim::fc::control::{run, Controller};
use parapet_sim::flight::runner::{controller_params, path_length, run_with, RunConfig, RunOutput};
use parapet_sim::plan::pathfile::PathFile;
use parapet_sim::report::Summary;
use parapet_sim::world::scene::{to_f64, Scene};

/// Attitude P gains of the slowed-attitude cases, as factors on the defaults (6.5, 6.5,
/// 2.8 s⁻¹; the rate loop unchanged). At 0.3× the published law dips below h̄ = 0 but does
/// not collide on this plant; at 0.1× (attitude time constant ≈ 1.5 s) it collides.
const ATT_SCALES: [f32; 2] = [0.3, 0.1];
const SEEDS: [u64; 5] = [0, 1, 2, 3, 4];
const DELTA1S: [f64; 3] = [0.1, 0.2, 0.3];

fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

fn scene(name: &str) -> Scene {
    Scene::load(&scenes_dir().join(format!("{name}.toml"))).unwrap_or_else(|e| panic!("{e}"))
}

/// `name.toml` with each `(from, to)` line replaced (the line must be there).
fn scene_edited(name: &str, edits: &[(&str, String)]) -> Scene {
    let p = scenes_dir().join(format!("{name}.toml"));
    let mut src = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    for (from, to) in edits {
        assert!(src.contains(from), "{}: template line {from:?} changed", p.display());
        src = src.replace(from, to);
    }
    Scene::parse(&src, &p.display().to_string()).unwrap_or_else(|e| panic!("{e}"))
}

fn committed_path(name: &str) -> Vec<Vector3<f64>> {
    let f = PathFile::read(&scenes_dir().join(format!("{name}_path.json"))).unwrap_or_else(|e| panic!("{e}"));
    f.waypoints_ned().iter().map(to_f64).collect()
}

/// The run configuration `parapet run` builds for these options.
fn config(
    s: &Scene,
    path: Vec<Vector3<f64>>,
    delta1: Option<f64>,
    speed: Option<f64>,
    seed: u64,
) -> RunConfig {
    let mut cfg = RunConfig::for_scene(s, path).unwrap_or_else(|e| panic!("{e}"));
    if let Some(d) = delta1 {
        cfg.params.delta1 = d;
    }
    if let Some(v) = speed {
        cfg.params.speed = v;
        if s.sim.duration.is_none() {
            cfg.duration = 1.5 * path_length(&cfg.path) / v + 15.0;
        }
    }
    cfg.seed = seed;
    cfg
}

fn straight(s: &Scene) -> Vec<Vector3<f64>> {
    vec![s.start, s.goal]
}

fn fly(s: &Scene, cfg: &RunConfig) -> RunOutput {
    run(s, cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{}: {e}", s.name))
}

fn outcome(su: &Summary) -> String {
    match (&su.collision_with, su.first_collision_time_s) {
        (Some(w), Some(t)) => format!("collision {w} at {t:.2} s"),
        _ if su.reached_goal => format!("goal at {:.1} s", su.time_to_goal_s.unwrap_or(f64::NAN)),
        _ => su.end_reason.clone(),
    }
}

fn row(tag: &str, su: &Summary) -> String {
    let f = &su.safety_steps;
    format!(
        "| {tag} | {} | {:.3} | {:.4} | {} | {} | {} | {} ({}) |",
        outcome(su),
        su.min_clearance_m,
        su.min_h_bar,
        f.unavoidable,
        f.infeasible,
        f.deadlock,
        f.obstacles_dropped,
        f.obstacles_dropped_near
    )
}

const HEADER: &str = "| case | outcome | min clearance (m) | min h̄ (m²) | unavoidable steps | infeasible steps | deadlock steps | steps with drops (near) |";

#[test]
fn narrow_door_is_passed_at_every_delta1() {
    let s = scene("narrow_passage");
    println!("{HEADER}\n|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for d in DELTA1S {
        for seed in SEEDS {
            let su = fly(&s, &config(&s, straight(&s), Some(d), None, seed)).summary;
            let tag = format!("narrow_passage δ1 {d} seed {seed}");
            println!("{}", row(&tag, &su));
            if su.collided || !su.reached_goal {
                failures.push(format!("{tag}: {}", outcome(&su)));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

fn dogleg(delta1: f64) -> (usize, usize, Vec<String>) {
    let s = scene("dogleg_corridor");
    let path = committed_path("dogleg_corridor");
    let (mut flights, mut goals, mut collisions) = (0, 0, Vec::new());
    for speed in [0.25, 0.5] {
        for seed in SEEDS {
            let su = fly(&s, &config(&s, path.clone(), Some(delta1), Some(speed), seed)).summary;
            let tag = format!("dogleg δ1 {delta1} {speed} m/s seed {seed}");
            println!("{}", row(&tag, &su));
            flights += 1;
            goals += usize::from(su.reached_goal);
            if su.collided {
                collisions.push(format!("{tag}: {}", outcome(&su)));
            }
        }
    }
    (flights, goals, collisions)
}

/// δ1 0.1 and 0.2 here, 0.3 in its own test (the harness runs them in parallel).
#[test]
fn dogleg_corridor_without_collision_and_with_the_goal() {
    let mut all = (0, 0, Vec::new());
    for d in [0.1, 0.2] {
        let (f, g, c) = dogleg(d);
        all.0 += f;
        all.1 += g;
        all.2.extend(c);
    }
    check_dogleg(all);
}

#[test]
fn dogleg_corridor_at_delta1_0_3() {
    check_dogleg(dogleg(0.3));
}

fn check_dogleg((flights, goals, collisions): (usize, usize, Vec<String>)) {
    assert!(collisions.is_empty(), "{collisions:#?}");
    // ≥ 95 % of the flights reach the goal.
    assert!(goals * 100 >= flights * 95, "goal in {goals} of {flights} flights");
}

/// The closing speed (m/s) above which the default filter may flag `unavoidable`:
/// μ·u_max/2 (docs/results.md, issue 10), 4.2 m/s with the office parameters.
fn closing_limit(cfg: &RunConfig) -> f64 {
    cfg.params.mu * f64::from(CbfParams::default().u_max) / 2.0
}

/// No collision, or `unavoidable` raised before the contact with the closing speed at the
/// contact above the limit. `obstacle_velocity` is the moving obstacle's (NED).
fn check_moving(
    tag: &str,
    cfg: &RunConfig,
    out: &RunOutput,
    obstacle_velocity: Vector3<f64>,
    failures: &mut Vec<String>,
) {
    let su = &out.summary;
    let Some(t_hit) = su.first_collision_time_s else { return };
    let closing = out.samples.last().map_or(0.0, |k| (obstacle_velocity - k.vel).norm());
    let flagged = su.safety_steps.first_unavoidable_time_s.is_some_and(|t| t < t_hit);
    if !(flagged && closing > closing_limit(cfg)) {
        failures.push(format!(
            "{tag}: {} (closing {closing:.2} m/s, limit {:.1}; unavoidable first at {:?})",
            outcome(su),
            closing_limit(cfg),
            su.safety_steps.first_unavoidable_time_s
        ));
    }
}

#[test]
fn sphere_overtaking_from_behind() {
    println!("{HEADER}\n|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for offset in [0.0, 0.1] {
        for speed in [0.5, 0.7, 1.0, 1.5] {
            let s = scene_edited(
                "sphere_overtaking",
                &[
                    ("center = [-1.5, 5.0, 1.2]", format!("center = [-1.5, {:.1}, 1.2]", 5.0 + offset)),
                    ("velocity = [1.0, 0.0, 0.0]", format!("velocity = [{speed:.1}, 0.0, 0.0]")),
                ],
            );
            for noise in [true, false] {
                let mut cfg = config(&s, straight(&s), None, None, 0);
                cfg.sensors.noise = noise;
                let out = fly(&s, &cfg);
                let tag = format!("overtaking {speed} m/s, offset {offset} m, noise {noise}");
                println!("{}", row(&tag, &out.summary));
                // ENU east = NED y.
                check_moving(&tag, &cfg, &out, Vector3::new(0.0, speed, 0.0), &mut failures);
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The person walking head-on at `speed` (m/s), offset 0, office parameters.
fn person_head_on(speed: f64, noise: bool, failures: &mut Vec<String>) {
    let s = scene_edited(
        "person_headon",
        &[
            ("base = [12.0, 5.1, 0.0]", "base = [12.0, 5.0, 0.0]".into()),
            ("velocity = [-0.3, 0.0, 0.0]", format!("velocity = [{:.1}, 0.0, 0.0]", -speed)),
        ],
    );
    let mut cfg = config(&s, straight(&s), Some(0.1), None, 0);
    (cfg.params.mu, cfg.params.kp, cfg.params.kd) = (1.4, 0.5, 0.8);
    cfg.sensors.noise = noise;
    let out = fly(&s, &cfg);
    let tag = format!("person head-on {speed} m/s, noise {noise}");
    println!("{}", row(&tag, &out.summary));
    // ENU west = NED −y.
    check_moving(&tag, &cfg, &out, Vector3::new(0.0, -speed, 0.0), failures);
}

#[test]
fn person_head_on_with_the_office_parameters() {
    println!("{HEADER}\n|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for speed in [0.2, 0.3, 0.5] {
        person_head_on(speed, true, &mut failures);
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The exactly symmetric case (offset 0, no noise): the law can only retreat along the
/// axis (no sidestep); before issue 17 the drag cancelled the retreat and the walker closed
/// in (contact at 26.1 / 21.5 / 16.3 s).
#[test]
fn person_exactly_head_on_without_noise() {
    println!("{HEADER}\n|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for speed in [0.2, 0.3, 0.5] {
        person_head_on(speed, false, &mut failures);
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn low_sphere_over_the_path_does_not_push_the_vehicle_into_the_ground() {
    let s = scene("low_sphere");
    println!("{HEADER}\n|---|---|---|---|---|---|---|---|");
    for (noise, seed) in [(false, 0), (true, 0), (true, 1)] {
        let mut cfg = config(&s, straight(&s), None, None, seed);
        cfg.sensors.noise = noise;
        let su = fly(&s, &cfg).summary;
        let tag = format!("low_sphere noise {noise} seed {seed}");
        println!("{}", row(&tag, &su));
        assert!(!su.collided, "{tag}: {}", outcome(&su));
    }
}

#[test]
fn many_points_then_a_wall_keep_the_wall_and_report_the_drops() {
    let s = scene("points_then_wall");
    assert_eq!(s.obstacles.len(), 633, "632 spheres and the wall");
    println!("{HEADER}\n|---|---|---|---|---|---|---|---|");
    for (noise, seed) in [(false, 0), (true, 0)] {
        let mut cfg = config(&s, straight(&s), None, None, seed);
        cfg.sensors.noise = noise;
        let out = fly(&s, &cfg);
        let su = &out.summary;
        let tag = format!("points_then_wall noise {noise} seed {seed}");
        println!("{}", row(&tag, su));
        assert!(!su.collided, "{tag}: {}", outcome(su));
        // More than 32 points are in range for most of the flight: drops are reported,
        // per step in the trajectory and counted in the summary.
        let f = &su.safety_steps;
        assert!(f.obstacles_dropped * 2 > f.outer, "{tag}: {f:?}");
        assert!(f.max_obstacles_dropped as usize >= 600 - 32, "{tag}: {f:?}");
        let csv = parapet_sim::report::trajectory_csv(&out.samples[..10]);
        assert!(csv.lines().next().is_some_and(|h| h
            .ends_with(",deadlock,obstacles_dropped,obstacles_dropped_near,gov_limit,gov_cause,gov_active")));
    }
}

/// Fly the office path at δ1 = 0.051 with the attitude P gains × `scale`.
fn slowed_office(variant: FilterVariant, scale: f32, seed: u64) -> Summary {
    let s = scene("office");
    let mut cfg = config(&s, committed_path("office"), Some(0.051), None, seed);
    cfg.variant = variant;
    if variant == FilterVariant::Paper {
        // The published method: the paper's guidance with the paper's law.
        cfg.guidance = MissionGuidance::Paper;
    }
    let cbf = cfg.cbf_params().unwrap_or_else(|e| panic!("{e}"));
    let mut params = controller_params(&s, &cfg, cbf, variant);
    for g in params.attitude.att_p.iter_mut() {
        *g *= scale;
    }
    let mut ctrl = Controller::with_params(&s, &cfg, params).unwrap_or_else(|e| panic!("{e}"));
    run_with(&s, &cfg, &mut ctrl, &mut |_| {}).unwrap_or_else(|e| panic!("{e}")).summary
}

#[test]
fn office_with_a_slowed_attitude_loop() {
    println!("{HEADER}\n|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for scale in ATT_SCALES {
        let mut paper_collisions = 0;
        for seed in [0, 1] {
            let paper = slowed_office(FilterVariant::Paper, scale, seed);
            let default = slowed_office(FilterVariant::default(), scale, seed);
            println!("{}", row(&format!("office att ×{scale} δ1 0.051 paper seed {seed}"), &paper));
            println!("{}", row(&format!("office att ×{scale} δ1 0.051 default seed {seed}"), &default));
            paper_collisions += usize::from(paper.collided);
            if default.collided {
                failures.push(format!("att ×{scale}, default filter, seed {seed}: {}", outcome(&default)));
            }
        }
        // The slowest case is a real test: the published law collides there.
        if scale == 0.1 && paper_collisions == 0 {
            failures.push("paper did not collide with the attitude loop at 0.1×".into());
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
