//! Simulator throughput: `cargo bench -p parapet-tests --bench plant`.
//!
//! * `plant/rk4_step` — one 1 ms RK4 step of the 6-DOF plant (`Plant::step`),
//!   default vehicle hovering.
//! * `plant/office_flight` — a whole closed-loop flight of the office scene
//!   (`fc::control::run`: plant at 1 kHz, sensors, `FlightController` inner 1 kHz /
//!   outer 250 Hz, multi-relative filter, proximity sensing of all 26 obstacles,
//!   clearance and barrier metrics, samples recorded), duration limit 60 s, on
//!   the shipped path `scenes/office_path.json` (a planner path, fixed so the
//!   benchmark does not change when the planner does).
//!
//! * `plant/clearance_check` — `runner::nearest_with_ground` at one point of
//!   the office: the full scan (signed distance to all 26 obstacles and the
//!   ground), for reference;
//! * `plant/clearance_tracked` — what the runner does instead after every plant
//!   step: `NearestTracker::nearest` (same result, broad phase), along the flown
//!   trajectory at 1 ms spacing (it skips even this on most steps, see
//!   `runner`'s docs);
//! * `plant/sense_obstacles` — `runner::sense_obstacles` (closest points of all 26
//!   obstacles within 3 m), the full scan, for reference (`true_h_bar` is of
//!   similar cost);
//! * `plant/outer_sensing` — what the runner does instead every outer step:
//!   `runner::sense_and_h_bar` (the same report and true h̄, one shared pass
//!   with bounds), along the flown trajectory at 4 ms spacing.
//!
//! Before timing, 9 flights are timed by hand and a line is printed with the
//! simulated time, plant steps, wall time, steps per second and the real-time
//! factor (simulated seconds per wall second) of their median.

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use nalgebra::Vector3;
use parapet_core::cbf::SafetyFilter;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{
    nearest_with_ground, sense_and_h_bar, sense_obstacles, OuterScratch, RunConfig,
};
use parapet_sim::plan::pathfile::PathFile;
use parapet_sim::sim::plant::{Plant, VehicleParams};
use parapet_sim::sim::sensors::Sensors;
use parapet_sim::world::scene::{to_f64, Scene};
use parapet_sim::world::NearestTracker;

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
    for _ in 0..9 {
        let t0 = Instant::now();
        let out = run(&scene, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("office flight: {e}"));
        walls.push(t0.elapsed().as_secs_f64());
        last = Some(out);
    }
    let flight = last.expect("nine runs");
    let s = &flight.summary;
    assert!(
        !s.collided,
        "the benchmark flight collided with {:?} at {:?} s",
        s.collision_with, s.first_collision_time_s
    );
    walls.sort_by(f64::total_cmp);
    let wall = walls[4];
    println!(
        "\noffice flight: end {}, {:.2} s simulated, {} plant steps; median wall {:.4} s of 9 \
         (min {:.4}, max {:.4}): {:.0} steps/s, {:.0}x real time (best run {:.0}x)",
        s.end_reason,
        s.sim_time_s,
        s.steps,
        wall,
        walls[0],
        walls[8],
        s.steps as f64 / wall,
        s.sim_time_s / wall,
        s.sim_time_s / walls[0]
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
    // The flown trajectory: samples every 4 ms, and 1 ms points between them.
    let track: Vec<(Vector3<f64>, Vector3<f64>)> = flight.samples.iter().map(|s| (s.pos, s.vel)).collect();
    let fine: Vec<Vector3<f64>> = track
        .windows(2)
        .flat_map(|w| (0..4).map(move |j| w[0].0 + (w[1].0 - w[0].0) * (j as f64 / 4.0)))
        .collect();
    let mut tracker = NearestTracker::new(&scene);
    let mut k = 0;
    group.bench_function("clearance_tracked", |b| {
        b.iter(|| {
            k = (k + 1) % fine.len();
            tracker.nearest(black_box(&scene), black_box(&fine[k]), 1.0)
        })
    });
    let mut sensors = Sensors::new(cfg.sensors.clone(), 0);
    group.bench_function("sense_obstacles", |b| {
        b.iter(|| {
            i += 1;
            sense_obstacles(black_box(&scene), 1.0, black_box(&points[i % 64]), 3.0, &mut sensors).len()
        })
    });
    let filter =
        SafetyFilter::new(cfg.cbf_params().expect("office parameters"), cfg.variant).expect("filter");
    let mut tracker = NearestTracker::new(&scene);
    let mut scratch = OuterScratch::default();
    let range = cfg.sensing_range;
    group.bench_function("outer_sensing", |b| {
        b.iter(|| {
            k = (k + 1) % track.len();
            let (p, v) = &track[k];
            let h = sense_and_h_bar(
                black_box(&scene),
                &mut tracker,
                &filter,
                1.0,
                black_box(p),
                black_box(v),
                range,
                &mut sensors,
                &mut scratch,
            );
            (h, scratch.seen.len())
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
