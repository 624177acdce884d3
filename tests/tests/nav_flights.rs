//! Flights with a filtered position source (issue 39): the navigation filter bridges a 1 s
//! fix dropout, a 5 s one triggers the failsafe (`host-sim/src/fc/nav.rs`), and the small
//! CI subset of `outdoor_static` with `gps` and the lidar does not collide (1 m/s, and 3 m/s on
//! the trajectory guidance)
//! (`docs/navigation.md` has the full table).

use std::path::PathBuf;

use nalgebra::Vector3;
use parapet_core::controller::GuidanceMode;
use parapet_core::outer::guidance::MissionGuidance;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{default_duration, default_yaw_mode, RunConfig, RunOutput};
use parapet_sim::plan::pathfile::PathFile;
use parapet_sim::sim::source::PositionSource;
use parapet_sim::world::scene::Scene;

fn scene(name: &str) -> Scene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name);
    Scene::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

fn config(s: &Scene, path: Vec<Vector3<f64>>, source: PositionSource, speed: f64, seed: u64) -> RunConfig {
    let mut cfg = RunConfig::for_scene(s, path).unwrap();
    cfg.sensors.position_source = source;
    cfg.sensors.apply_source_preset(&[]);
    cfg.params.speed = speed;
    cfg.seed = seed;
    cfg.duration = default_duration(s, &cfg.path, speed);
    cfg
}

/// `one_sphere` straight through the sphere at 3 m/s with `gps`, fixes dropped from 2 s for
/// `length` s.
fn sphere_with_dropout(length: f64) -> RunOutput {
    let s = scene("one_sphere.toml");
    let mut cfg = config(&s, vec![s.start, s.goal], PositionSource::Gps, 3.0, 0);
    cfg.sensors.dropout_start = 2.0;
    cfg.sensors.dropout_length = length;
    run(&s, &cfg, &mut |_| {}).unwrap()
}

/// `true` when some outer step flew the brake or the landing.
fn braked(out: &RunOutput) -> bool {
    out.samples.iter().any(|s| matches!(s.mode, GuidanceMode::Brake | GuidanceMode::Land))
}

#[test]
fn a_one_second_fix_dropout_at_3_mps_is_bridged_without_a_brake() {
    let out = sphere_with_dropout(1.0);
    let sum = &out.summary;
    assert!(!sum.collided, "{sum:?}");
    assert!(sum.reached_goal, "{sum:?}");
    assert!(!braked(&out), "the dropout was not bridged: {sum:?}");
}

#[test]
fn a_five_second_fix_dropout_triggers_the_failsafe() {
    let out = sphere_with_dropout(5.0);
    assert!(braked(&out), "{:?}", out.summary);
    assert!(!out.summary.reached_goal, "{:?}", out.summary);
}

/// `outdoor_static` on its committed path with `gps` and the 72-beam lidar at `speed`.
fn outdoor_static_gps_lidar(speed: f64, seed: u64) -> RunConfig {
    let s = scene("outdoor_static.toml");
    let file = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/outdoor_static_path.json");
    let path = PathFile::read(&file).unwrap_or_else(|e| panic!("{e}"));
    let wps: Vec<Vector3<f64>> =
        path.waypoints.iter().map(|w| Vector3::new(w[1] as f64, w[0] as f64, -(w[2] as f64))).collect();
    let mut cfg = config(&s, wps, PositionSource::Gps, speed, seed);
    cfg.perception = parapet_sim::sim::range::preset("lidar");
    cfg.yaw_mode = default_yaw_mode(cfg.perception.as_deref());
    cfg
}

#[test]
fn outdoor_static_with_gps_and_the_lidar_does_not_collide() {
    let s = scene("outdoor_static.toml");
    let sum = run(&s, &outdoor_static_gps_lidar(1.0, 0), &mut |_| {}).unwrap().summary;
    assert!(!sum.collided, "{sum:?}");
}

/// At speed with the trajectory guidance (`MIS_GUIDANCE 1`, named: it passes under either
/// default): `gps` + lidar at 3 m/s, seed 0, does not collide and keeps the hull clear
/// (measured 0.138 m; the paper's guidance collides on this flight at 10.7 s, so the test
/// fails with `MissionGuidance::Paper`: checked). `docs/navigation.md` § No collision at speed.
#[test]
fn outdoor_static_with_gps_and_the_lidar_at_3_mps_on_the_trajectory_does_not_collide() {
    let s = scene("outdoor_static.toml");
    let mut cfg = outdoor_static_gps_lidar(3.0, 0);
    cfg.guidance = MissionGuidance::Trajectory;
    let sum = run(&s, &cfg, &mut |_| {}).unwrap().summary;
    assert!(!sum.collided, "{sum:?}");
    assert!(sum.min_clearance_m > 0.05, "{sum:?}");
}
