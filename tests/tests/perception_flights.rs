//! Flights with range sensors in the loop (issue 19, `parapet run --perception`):
//! noise on, the planner's path of the seed (as `parapet run` flies it), the
//! core's obstacle memory fed by the simulated lidar / forward camera / ToF.
//!
//! * `ci_subset_*`: the cases of the full matrix that flew without a collision
//!   for every seed 0–4 when measured (docs/perception.md), seeds 0 and 1 — a
//!   regression guard (a collision here is a change, not a tolerance). Reaching
//!   the goal is not asserted (see docs/perception.md: time to goal).
//! * `ci_subset_yaw_travel`: forward-camera cases flown with `--yaw-mode travel`
//!   (`MIS_YAW_MODE` 1, `parapet run`'s default for a forward-only sensor set) that reach
//!   the goal without a collision; with `hold` (the camera looking north while the path goes
//!   elsewhere) the same cases stop short of the goal at the frontier's walls (measured,
//!   docs/perception.md): the goal is asserted too.
//! * `full_matrix` (ignored, the documented command of docs/perception.md):
//!   seven scenes (`blind_corner`: a turn towards a pillar the camera has not seen)
//!   × lidar, camera, ToF (ten, `tof`; four, `tof4`) × seeds 0–4 × yaw hold and travel, asserting no
//!   collision; it fails today and prints the table of what collided.
//!
//! `cargo test -p parapet-tests --release --test perception_flights -- --ignored --nocapture`

use std::path::PathBuf;

use parapet_core::outer::path_yaw::YawMode;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{RunConfig, RunOutput};
use parapet_sim::plan::{plan, PlanProblem, PlannerParams};
use parapet_sim::sim::range::preset;
use parapet_sim::world::scene::{to_f64, Scene};

fn scene(name: &str) -> Scene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(format!("{name}.toml"));
    Scene::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

/// `parapet run --scene scenes/<name>.toml --perception <sensors> --seed <seed>`.
fn fly(name: &str, sensors: &str, seed: u64) -> RunOutput {
    fly_yaw(name, sensors, seed, YawMode::Hold)
}

/// [`fly`] with `--yaw-mode <yaw>`.
fn fly_yaw(name: &str, sensors: &str, seed: u64, yaw: YawMode) -> RunOutput {
    fly_with(name, sensors, seed, yaw, &[])
}

/// [`fly_yaw`] with `--param NAME=VALUE` for each of `params`.
fn fly_with(name: &str, sensors: &str, seed: u64, yaw: YawMode, params: &[(&'static str, f32)]) -> RunOutput {
    let s = scene(name);
    let planned = plan(&PlanProblem::from_scene(&s), &PlannerParams { seed, ..PlannerParams::default() })
        .unwrap_or_else(|e| panic!("{name}: planning failed: {e}"));
    let path = planned.waypoints.iter().map(to_f64).collect();
    let mut cfg = RunConfig::for_scene(&s, path).unwrap();
    cfg.seed = seed;
    cfg.yaw_mode = yaw;
    cfg.perception = if sensors == "truth" { None } else { Some(preset(sensors).unwrap()) };
    cfg.param_overrides.extend_from_slice(params);
    assert!(cfg.sensors.noise, "{name}: noise must be on");
    run(&s, &cfg, &mut |_| {}).unwrap()
}

fn check(name: &str, sensors: &str, seed: u64) {
    check_yaw(name, sensors, seed, YawMode::Hold);
}

fn check_yaw(name: &str, sensors: &str, seed: u64, yaw: YawMode) -> RunOutput {
    check_with(name, sensors, seed, yaw, &[])
}

fn check_with(
    name: &str,
    sensors: &str,
    seed: u64,
    yaw: YawMode,
    params: &[(&'static str, f32)],
) -> RunOutput {
    let out = fly_with(name, sensors, seed, yaw, params);
    let s = &out.summary;
    assert!(
        !s.collided,
        "{name} {sensors} seed {seed}: collision with {:?} at {:?} s",
        s.collision_with, s.first_collision_time_s
    );
    // The goal is not asserted: with a limited field of view the frontier's speed cap may
    // hold the vehicle back until the duration limit (docs/perception.md, time to goal).
    // The sensors really scanned and the filter worked from their points.
    assert!(
        !out.ranges.is_empty() && out.ranges.iter().any(|r| r.range.is_some()),
        "{name} {sensors}: no returns"
    );
    assert!(s.filter_active_fraction > 0.0, "{name} {sensors}: the filter never acted");
    out
}

#[test]
fn ci_subset_lidar() {
    for seed in 0..2 {
        check("dogleg_corridor", "lidar", seed);
        check("person_headon", "lidar", seed);
        // Collided before static structure stopped being tracked as moving (office, door
        // lintel, outdoor) and before the track hand-over kept the velocity (overtaking).
        check("office", "lidar", seed);
        check("outdoor_static", "lidar", seed);
        check("door_lintel", "lidar", seed);
        check("sphere_overtaking", "lidar", seed);
    }
}

#[test]
fn ci_subset_camera() {
    for seed in 0..2 {
        check("dogleg_corridor", "camera", seed);
        // Collided before the frontier's walls for a held heading (`PCP_FOV_WALLS` 2, the
        // default): the camera looks north while the paths go elsewhere, and the speed cap
        // alone let the vehicle creep into what it never saw (office desk A / partition A/B,
        // trees 4 and 11, the lintel's wall, the hidden pillar). With the walls it stops
        // where nothing observed is left (the goal is not reached: docs/perception.md).
        check("office", "camera", seed);
        check("outdoor_static", "camera", seed);
        check("door_lintel", "camera", seed);
        check("blind_corner", "camera", seed);
    }
}

/// The four ToFs (`tof4`; `tof` until 2026-12-05): the cases that flew without a collision.
#[test]
fn ci_subset_tof4() {
    for seed in 0..2 {
        check("door_lintel", "tof4", seed);
    }
}

/// The ring of eight ToFs (`tof8`, views meeting): the movers the four (`tof4`) lose in their
/// 45° gaps — the head-on walker, the chaser, the paper's 0.2 m/s walker — fly without a
/// collision (0 of 20 seeds for the first two, docs/perception.md; `tof`: 15 and 13).
#[test]
fn ci_subset_tof8_movers() {
    for seed in 0..2 {
        check("person_headon", "tof8", seed);
        check("sphere_overtaking", "tof8", seed);
        check("outdoor_person", "tof8", seed);
    }
}

/// The movers under the trajectory guidance (`MIS_GUIDANCE` 1), seeds 0–1:
/// * the overtaking sphere pushes the vehicle ahead of its reference. Until the tracking limited
///   the vehicle's lead (`tracking::limit_lead`), the reference's clock stopped on the large
///   error and the cascade pulled the vehicle back into the sphere with its full acceleration
///   limit: lidar and tof8 seed 0 collided at 7.8 s. Then no contact, but the sphere herded
///   the vehicle along its line past the goal; since the vehicle steps aside when pushed
///   faster than its reference (`ad023cd`, docs/cascade.md) it lets the sphere pass and
///   reaches the goal;
/// * the head-on walker pushes the vehicle back behind its reference. Until the velocity
///   set-point was limited to the mission speed, the cascade drove the vehicle back into the
///   walker with the gain times the whole error: the forward camera (yaw travel) collided at
///   22.2 s. Now it reaches the goal with every sensor set.
#[test]
fn ci_subset_movers_on_the_trajectory() {
    let trajectory = [("MIS_GUIDANCE", 1.0)];
    for seed in 0..2 {
        for sensors in ["lidar", "tof8"] {
            let out = check_with("sphere_overtaking", sensors, seed, YawMode::Hold, &trajectory);
            assert!(out.summary.reached_goal, "sphere_overtaking {sensors} seed {seed}: no goal");
            let out = check_with("person_headon", sensors, seed, YawMode::Hold, &trajectory);
            assert!(out.summary.reached_goal, "person_headon {sensors} seed {seed}: no goal");
        }
        let out = check_with("person_headon", "camera", seed, YawMode::Travel, &trajectory);
        assert!(out.summary.reached_goal, "person_headon camera seed {seed}: no goal");
    }
    // At 1 m/s (the sphere's speed) the vehicle waits at the goal for the sphere: it collided
    // in 3/3 seeds with `tof8` until the cascade stepped aside at the ended trajectory's goal
    // too (docs/filter.md § 16).
    let fast = [("MIS_GUIDANCE", 1.0), ("WP_SPEED", 1.0)];
    let out = check_with("sphere_overtaking", "tof8", 0, YawMode::Hold, &fast);
    assert!(out.summary.reached_goal, "sphere_overtaking tof8 at 1 m/s: no goal");
}

/// The ring plus one ToF looking up and one down (`tof`): 0 collisions in the 70 flights of
/// the matrix (7 scenes × seeds 0–4 × both yaw modes, docs/perception.md). The cases here
/// collided with the ring alone (`tof8`): printer B's top (office, hold, seed 3), the legs'
/// walls (dogleg_corridor, travel, seed 0), the lintel (door_lintel, travel, seed 1).
#[test]
fn ci_subset_tof() {
    check_yaw("office", "tof", 3, YawMode::Hold);
    check_yaw("dogleg_corridor", "tof", 0, YawMode::Travel);
    check_yaw("door_lintel", "tof", 1, YawMode::Travel);
    check("person_headon", "tof", 0);
}

/// outdoor_static with the four ToFs and yaw hold, seed 0: left the CI subset at 0680bf1,
/// when it stopped flying 5 / 5 seeds without a collision (docs/perception.md). From that
/// commit (the disturbance observer fed the realisable command, which changes the
/// trajectory) seed 0 hit tree 3 at 33.07 s: the vehicle moved at 1.4 m/s along a bearing
/// the east ToF observed free, and the tree sat 44° off that bearing in the blind wedge
/// between two ToFs — the frontier checks the line of motion, not the corridor the hull
/// sweeps (docs/filter.md § 14, "Where it ends"). It was an ignored known failure until the
/// walls for a held heading (`PCP_FOV_WALLS` 2): the vehicle now stops where the free range of
/// its direction of motion is used up instead of creeping on (no contact, 107 s to the
/// duration limit, min clearance 1.13 m). The fixed regression case of that failure.
#[test]
fn regression_outdoor_static_tof_seed0_blind_wedge() {
    check("outdoor_static", "tof4", 0);
}

/// Forward camera, yaw travel: every case here collided with yaw hold before the walls for a
/// held heading (measured: office seed 0 desk A at 13.7 s, seed 1 partition A/B north at
/// 32.6 s; outdoor_static 0, 1 trees 4 and 11 at 70.4 / 94.8 s; blind_corner 0, 2 the hidden
/// pillar at 31.8 / 32.8 s; with the walls, hold stops short of the goal) and reaches the
/// goal with travel (1.1 s for the eight flights, release, 2026-12-05).
#[test]
fn ci_subset_yaw_travel() {
    for (name, seed) in [
        ("office", 0),
        ("office", 1),
        ("outdoor_static", 0),
        ("outdoor_static", 1),
        ("blind_corner", 0),
        ("blind_corner", 2),
        // The head-on walker: collided with travel too until the free-cell map let the
        // vehicle back away into space the camera saw on the way (docs/perception.md).
        ("person_headon", 0),
        ("person_headon", 1),
        // The paper's 0.2 m/s walker: collided in 20 of 20 seeds while nothing slower than
        // 0.3 m/s could be proven moving (track.rs, MOTION_WINDOW_S; docs/perception.md).
        ("outdoor_person", 0),
        ("outdoor_person", 1),
    ] {
        let s = check_yaw(name, "camera", seed, YawMode::Travel).summary;
        assert!(s.reached_goal, "{name} camera seed {seed} travel: goal not reached ({})", s.end_reason);
        assert_eq!(s.yaw_mode, "travel");
    }
}

#[test]
fn ranges_follow_the_sensor_rate_and_beams() {
    // 10 Hz × 72 beams, one scan per 0.1 s from t = 0 (the run's last scan at or before its end).
    let out = fly("dogleg_corridor", "lidar", 0);
    let t_end = out.summary.sim_time_s;
    let scans = (t_end * 10.0 + 1e-9).floor() as usize + 1;
    assert!(
        (out.ranges.len() as i64 - (scans * 72) as i64).abs() <= 72,
        "{} beams for {t_end} s",
        out.ranges.len()
    );
    // Every return lies on a surface: within the noise of the nearest obstacle or the ground.
    let s = scene("dogleg_corridor");
    let mut on_surface = 0;
    let hits: Vec<_> = out.ranges.iter().filter_map(|r| r.point).collect();
    for p in &hits {
        let q = nalgebra::Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        let (d, _) = parapet_sim::flight::runner::nearest_with_ground(&s, &q, 0.0);
        on_surface += usize::from(d.abs() < 0.05);
    }
    assert!(
        on_surface as f64 > 0.99 * hits.len() as f64,
        "{on_surface} of {} returns on a surface",
        hits.len()
    );
}

#[test]
#[ignore = "full matrix, the documented command of docs/perception.md; collides today (see there)"]
fn full_matrix() {
    // blind_corner: forward camera, a path turning towards a pillar hidden behind a wall's end.
    let scenes = [
        "office",
        "outdoor_static",
        "dogleg_corridor",
        "door_lintel",
        "person_headon",
        "sphere_overtaking",
        "blind_corner",
    ];
    let mut failed = Vec::new();
    for yaw in YawMode::ALL {
        for name in scenes {
            for sensors in ["lidar", "camera", "tof", "tof4"] {
                for seed in 0..5 {
                    let s = fly_yaw(name, sensors, seed, yaw).summary;
                    println!(
                        "{name:18} {sensors:7} {:6} seed {seed}: collided {} ({:?}), min clearance {:.3} m, goal {:?} s, filter active {:.1} %",
                        yaw.as_str(),
                        s.collided,
                        s.collision_with,
                        s.min_clearance_m,
                        s.time_to_goal_s,
                        100.0 * s.filter_active_fraction
                    );
                    if s.collided {
                        failed.push(format!("{name} {sensors} {} {seed}", yaw.as_str()));
                    }
                }
            }
        }
    }
    assert!(failed.is_empty(), "{} collisions: {failed:?}", failed.len());
}
