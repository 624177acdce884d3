//! Closed-loop flights at scale (issue 18): `cargo bench -p parapet-sim --bench flight_scale`.
//!
//! Flies, as `parapet run` does (planner seed 0, `RunConfig::for_scene`, the
//! full cascade, sensing and metrics), the office and generated forests of
//! 10³, 10⁴ and 10⁵ trunks (generator seed 0), `REPS` times each
//! (alternating), and prints per scene: the index build (`NearestTracker::new`,
//! thread CPU), the flight's simulated time, the best and median **thread-CPU**
//! real-time factor (simulated s / CPU s of `fc::control::run`, not inflated by
//! waiting for a core) and the median wall-clock factor (`summary.wall_time_s`,
//! as `parapet run` prints it), and the summary numbers (to check the flight is
//! the one `parapet run` flies).

use std::path::Path;

use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::RunConfig;
use parapet_sim::plan::generate::generate;
use parapet_sim::plan::{plan, PlanProblem, PlannerParams};
use parapet_sim::world::generate::{GenParams, Kind};
use parapet_sim::world::scene::{to_f64, Scene};
use parapet_sim::world::NearestTracker;

const REPS: usize = 7;

mod common;

/// This thread's CPU time, ns (0 where it cannot be read).
fn thread_cpu_ns() -> u64 {
    common::thread_cpu_ns().unwrap_or(0)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let office = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/office.toml");
    let mut scenes = vec![("office".to_string(), Scene::load(&office).expect("office"))];
    for n in [1_000, 10_000, 100_000] {
        let g = generate(&GenParams { kind: Kind::Forest, obstacles: n, seed: 0, ..GenParams::default() })
            .expect("forest");
        scenes.push((format!("forest {n}"), g.scene));
    }
    let cfgs: Vec<RunConfig> = scenes
        .iter()
        .map(|(name, s)| {
            let path = plan(&PlanProblem::from_scene(s), &PlannerParams::default())
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            RunConfig::for_scene(s, path.waypoints.iter().map(to_f64).collect()).expect("config")
        })
        .collect();
    let (mut cpu, mut wall, mut build) =
        (vec![vec![]; scenes.len()], vec![vec![]; scenes.len()], vec![vec![]; scenes.len()]);
    let mut last = Vec::new();
    for _ in 0..REPS {
        last.clear();
        for (k, ((_, scene), cfg)) in scenes.iter().zip(&cfgs).enumerate() {
            let c = thread_cpu_ns();
            std::hint::black_box(NearestTracker::new(scene));
            build[k].push((thread_cpu_ns() - c) as f64 / 1e6);
            let c = thread_cpu_ns();
            let out = run(scene, cfg, &mut |_| {}).expect("flies");
            let c = (thread_cpu_ns() - c) as f64 / 1e9;
            let s = &out.summary;
            cpu[k].push(s.sim_time_s / c);
            wall[k].push(s.sim_time_s / s.wall_time_s);
            last.push(out.summary);
        }
    }
    println!(
        "{:<14} {:>8} {:>10} {:>12} {:>12} {:>12} {:>6} {:>9} {:>9} {:>8}",
        "scene",
        "obst",
        "index_ms",
        "sim_s",
        "best_cpu_x",
        "med_cpu_x",
        "wall_x",
        "goal_s",
        "min_clr",
        "rms_m"
    );
    for (k, (name, scene)) in scenes.iter().enumerate() {
        let s = &last[k];
        let best = cpu[k].iter().cloned().fold(0.0, f64::max);
        println!(
            "{:<14} {:>8} {:>10.2} {:>12.2} {:>12.0} {:>12.0} {:>6.0} {:>9} {:>9.4} {:>8.3}",
            name,
            scene.obstacles.len(),
            median(&mut build[k]),
            s.sim_time_s,
            best,
            median(&mut cpu[k]),
            median(&mut wall[k]),
            s.time_to_goal_s.map_or("-".into(), |t| format!("{t:.2}")),
            s.min_clearance_m,
            s.tracking_rms_m
        );
    }
}
