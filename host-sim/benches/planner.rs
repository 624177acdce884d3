//! Planner benchmark: `cargo bench -p parapet-sim --bench planner`.
//!
//! For every shipped scene (`scenes/*.toml`) it first prints a table of
//! per-call statistics over 200 seeds (median and 95th percentile wall-clock
//! planning time, median and mean CPU time, iterations, waypoints, path length
//! relative to the straight line),
//! then runs one criterion benchmark per scene whose iterations cycle through
//! seeds 0..100 (so the reported time is the typical time of a `plan` call,
//! not that of one lucky or unlucky seed; criterion's figure is therefore
//! close to the *mean* time per call, which the tail of slow seeds raises
//! above the median of the table).
//!
//! CPU time (`cpu_med_ms`) is the thread's CPU time
//! (`CLOCK_THREAD_CPUTIME_ID`, 64-bit Linux), each seed timed over 10
//! identical calls; unlike wall-clock time it does not grow when other
//! processes compete for the cores. `-` on other platforms.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use parapet_sim::plan::{plan, PlanProblem, PlannerParams};
use parapet_sim::world::scene::Scene;

fn scenes() -> Vec<(String, PlanProblem)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|f| {
            let scene = Scene::load(f).unwrap_or_else(|e| panic!("{e}"));
            (scene.name.clone(), PlanProblem::from_scene(&scene))
        })
        .collect()
}

mod common;
use common::thread_cpu_ns;

fn percentile(sorted: &[f64], q: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i]
}

fn print_table(scenes: &[(String, PlanProblem)]) {
    println!(
        "{:<24} {:>5} {:>10} {:>10} {:>11} {:>12} {:>9} {:>8} {:>8} {:>12}",
        "scene",
        "obst",
        "median_ms",
        "p95_ms",
        "cpu_med_ms",
        "cpu_mean_ms",
        "med_iter",
        "med_wps",
        "len_m",
        "len/straight"
    );
    for (name, problem) in scenes {
        let mut times = Vec::new();
        let mut iters = Vec::new();
        let mut wps = Vec::new();
        let mut lens = Vec::new();
        let mut cpu = Vec::new();
        for seed in 0..200 {
            let params = PlannerParams { seed, ..Default::default() };
            let t0 = Instant::now();
            let path = plan(problem, &params).unwrap_or_else(|e| panic!("{name}: seed {seed}: {e}"));
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            iters.push(path.iterations as f64);
            wps.push(path.waypoints.len() as f64);
            lens.push(path.length_m as f64);
            if let Some(c0) = thread_cpu_ns() {
                for _ in 0..10 {
                    black_box(plan(black_box(problem), &params).is_ok());
                }
                if let Some(c1) = thread_cpu_ns() {
                    cpu.push((c1 - c0) as f64 / 10.0 / 1e6);
                }
            }
        }
        for v in [&mut times, &mut iters, &mut wps, &mut lens, &mut cpu] {
            v.sort_by(f64::total_cmp);
        }
        let straight = (problem.goal - problem.start).norm() as f64;
        let (cpu_med, cpu_mean) = if cpu.len() == times.len() {
            (
                format!("{:.4}", percentile(&cpu, 0.5)),
                format!("{:.4}", cpu.iter().sum::<f64>() / cpu.len() as f64),
            )
        } else {
            ("-".into(), "-".into())
        };
        println!(
            "{:<24} {:>5} {:>10.4} {:>10.4} {:>11} {:>12} {:>9.0} {:>8.0} {:>8.2} {:>12.3}",
            name,
            problem.obstacles.len(),
            percentile(&times, 0.5),
            percentile(&times, 0.95),
            cpu_med,
            cpu_mean,
            percentile(&iters, 0.5),
            percentile(&wps, 0.5),
            percentile(&lens, 0.5),
            percentile(&lens, 0.5) / straight
        );
    }
}

fn bench_planner(c: &mut Criterion) {
    let scenes = scenes();
    print_table(&scenes);
    let mut group = c.benchmark_group("plan");
    for (name, problem) in &scenes {
        let mut seed = 0u64;
        group.bench_function(name.as_str(), |b| {
            b.iter(|| {
                seed = (seed + 1) % 100;
                let params = PlannerParams { seed, ..Default::default() };
                black_box(plan(black_box(problem), &params)).is_ok()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_planner);
criterion_main!(benches);
