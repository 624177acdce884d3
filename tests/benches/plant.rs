//! Simulator throughput: `cargo bench -p parapet-tests --bench plant`.
//!
//! * `plant/rk4_step` — one 1 ms RK4 step of the 6-DOF plant (`Plant::step`),
//!   default vehicle hovering.
//! * `plant/office_flight` — a whole closed-loop flight of the office scene
//!   (`runner::run`: plant at 1 kHz, sensors, `FlightController` inner 1 kHz /
//!   outer 250 Hz, multi-relative filter, proximity sensing of all 26 obstacles,
//!   clearance and barrier metrics, samples recorded), duration limit 60 s; the
//!   path is planned once (seed 0) outside the timed loop.
//!
//! Before timing, 5 flights are timed by hand and a line is printed with the
//! simulated time, plant steps, wall time, steps per second and the real-time
//! factor (simulated seconds per wall second) of their median.

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Vector3;
use parapet_sim::planner::{plan, PlanProblem, PlannerParams};
use parapet_sim::plant::{Plant, VehicleParams};
use parapet_sim::runner::{run, RunConfig};
use parapet_sim::scene::{to_f64, Scene};

/// The office scene and a planned path, with a 60 s duration limit.
fn office() -> (Scene, RunConfig) {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/office.toml");
    let scene = Scene::load(&file).unwrap_or_else(|e| panic!("{e}"));
    let planned = plan(&PlanProblem::from_scene(&scene), &PlannerParams { seed: 0, ..Default::default() })
        .unwrap_or_else(|e| panic!("office: planning failed: {e}"));
    let path: Vec<Vector3<f64>> = planned.waypoints.iter().map(to_f64).collect();
    let mut cfg = RunConfig::for_scene(&scene, path).unwrap_or_else(|e| panic!("{e}"));
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
    assert!(!s.collided, "the benchmark flight collided: {}", s.end_reason);
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
    group.sample_size(10);
    group.bench_function("office_flight", |b| {
        b.iter(|| run(black_box(&scene), black_box(&cfg), &mut |_| {}).map(|o| o.summary.steps))
    });
    group.finish();
}

criterion_group!(benches, bench_plant);
criterion_main!(benches);
