//! Simulator throughput: `cargo bench -p parapet-tests --bench plant`.
//!
//! * `plant/rk4_step` — one 1 ms RK4 step of the 6-DOF plant (`Plant::step`),
//!   default vehicle hovering.
//! * `plant/office_flight` — a whole closed-loop flight of the office scene
//!   (`runner::run`: plant at 1 kHz, sensors, `FlightController` inner 1 kHz /
//!   outer 250 Hz, multi-relative filter, proximity sensing of all 26 obstacles,
//!   clearance and barrier metrics, samples recorded), duration limit 60 s, on
//!   the shipped path `scenes/office_path.json` (a planner path, fixed so the
//!   benchmark does not change when the planner does).
//!
//! * `plant/clearance_check` — `runner::nearest_with_ground` at one point of
//!   the office (signed distance to all 26 obstacles and the ground), which the
//!   runner does after every plant step for collisions and clearance;
//! * `plant/sense_obstacles` — `runner::sense_obstacles` (closest points of all 26
//!   obstacles within 3 m), which the runner does every outer step (and
//!   `true_h_bar`, of similar cost, too).
//!
//! Before timing, 5 flights are timed by hand and a line is printed with the
//! simulated time, plant steps, wall time, steps per second and the real-time
//! factor (simulated seconds per wall second) of their median.

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use nalgebra::Vector3;
use parapet_sim::pathfile::PathFile;
use parapet_sim::plant::{Plant, VehicleParams};
use parapet_sim::runner::{nearest_with_ground, run, sense_obstacles, RunConfig};
use parapet_sim::scene::{to_f64, Scene};
use parapet_sim::sensors::Sensors;

/// The office scene and its shipped path, with a 60 s duration limit.
fn office() -> (Scene, RunConfig) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let scene = Scene::load(&dir.join("office.toml")).unwrap_or_else(|e| panic!("{e}"));
    let file = PathFile::read(&dir.join("office_path.json")).unwrap_or_else(|e| panic!("{e}"));
    let path: Vec<Vector3<f64>> = file.waypoints_ned().iter().map(to_f64).collect();
    let mut cfg = RunConfig::for_scene(&scene, path).unwrap_or_else(|e| panic!("{e}"));
    cfg.path_source = "file".into();
    cfg.duration = 60.0;
    (scene, cfg)
}

fn bench_plant(c: &mut Criterion) {
    let mut group = c.benchmark_group("plant");
    let mut plant = Plant::new(VehicleParams::default()).expect("default vehicle");
    plant.set_hover(Vector3::new(0.0, 0.0, -1.0), 0.0);
    group.bench_function("rk4_step", |b| b.iter(|| plant.step(black_box(0.001))));

    let (scene, cfg) = office();
    let mut walls = Vec::new();
    let mut last = None;
    for _ in 0..5 {
        let t0 = Instant::now();
        let out = run(&scene, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("office flight: {e}"));
        walls.push(t0.elapsed().as_secs_f64());
        last = Some(out.summary);
    }
    let s = last.expect("five runs");
    assert!(
        !s.collided,
        "the benchmark flight collided with {:?} at {:?} s",
        s.collision_with, s.first_collision_time_s
    );
    walls.sort_by(f64::total_cmp);
    let wall = walls[2];
    println!(
        "\noffice flight: end {}, {:.2} s simulated, {} plant steps; median wall {:.4} s of 5 \
         (min {:.4}, max {:.4}): {:.0} steps/s, {:.0}x real time",
        s.end_reason,
        s.sim_time_s,
        s.steps,
        wall,
        walls[0],
        walls[4],
        s.steps as f64 / wall,
        s.sim_time_s / wall
    );
    // Points along the path, so the distance checks see near and far obstacles.
    let points: Vec<Vector3<f64>> = (0..64)
        .map(|i| {
            let s = i as f64 / 63.0 * (cfg.path.len() - 1) as f64;
            let (j, f) = (s.floor() as usize, s.fract());
            let b = cfg.path[(j + 1).min(cfg.path.len() - 1)];
            cfg.path[j] * (1.0 - f) + b * f
        })
        .collect();
    let mut i = 0;
    group.bench_function("clearance_check", |b| {
        b.iter(|| {
            i += 1;
            nearest_with_ground(black_box(&scene), black_box(&points[i % 64]), 1.0)
        })
    });
    let mut sensors = Sensors::new(cfg.sensors.clone(), 0);
    group.bench_function("sense_obstacles", |b| {
        b.iter(|| {
            i += 1;
            sense_obstacles(black_box(&scene), 1.0, black_box(&points[i % 64]), 3.0, &mut sensors).len()
        })
    });
    group.sample_size(10);
    group.sampling_mode(SamplingMode::Flat);
    group.bench_function("office_flight", |b| {
        b.iter(|| run(black_box(&scene), black_box(&cfg), &mut |_| {}).map(|o| o.summary.steps))
    });
    group.finish();
}

criterion_group!(benches, bench_plant);
criterion_main!(benches);
