//! Worlds at scale (issues 18, 38): `cargo bench -p parapet-sim --bench scale`.
//!
//! For generated scenes (`world::generate`: the sparse forest of the defaults,
//! 0.05 trunks/m²; the dense forest of issue 38, 0.35 trunks/m², radius
//! 0.08–0.3 m; the city) of 10³, 10⁴ and 10⁵ obstacles, several generator seeds
//! each, it measures and prints:
//! * the scene file's size, the thread-CPU time (ms) to parse and validate it
//!   (`Scene::parse`, the loader's work after reading the file) and to build
//!   the planner's index;
//! * `plan` over planner seeds: success count, median / p95 wall time and
//!   median thread-CPU time **with a prebuilt index** (`plan_with_index`, what
//!   a sweep or a second mission in the same world costs) and of the whole
//!   `plan` call (index built inside), median iterations (RRT-Connect) or A*
//!   expansions (grid), how many paths the grid search found, and the median
//!   path length;
//! * an independent clearance check of every path (`tests/common/clearance.rs`:
//!   parry3d's segment–shape distances): the smallest clearance over all paths
//!   minus the planner's hull radius + margin (must be ≥ −0.1 mm; the bench
//!   fails otherwise).
//!
//! It writes `target/scale/plan_scale.csv` (one row per call) and the log-log
//! plot of planning cost against obstacle count, `target/scale/plan_scale.svg`
//! (copied to `docs/figures/` for `docs/performance.md`). `SCALE_QUICK=1` runs one
//! scene seed and 5 planner seeds per size; `SCALE_KINDS=forest,dense,city` (any
//! of them) and `SCALE_SIZES=10000,100000` choose the rows.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use parapet_sim::plan::generate::generate;
use parapet_sim::plan::{
    index_for, plan, plan_with_index, PlanMethod, PlanProblem, PlannerParams, DEFAULT_MARGIN_M,
};
use parapet_sim::world::generate::{GenParams, Kind};
use parapet_sim::world::scene::Scene;
use plotters::prelude::*;

#[path = "../tests/common/clearance.rs"]
mod clearance;
mod common;

/// Comma list of an environment variable (`None` when unset or empty).
fn env_list(name: &str) -> Option<Vec<String>> {
    let v = std::env::var(name).ok().filter(|v| !v.is_empty())?;
    Some(v.split(',').map(|x| x.trim().to_string()).collect())
}

/// This thread's CPU time, ns (0 where it cannot be read).
fn thread_cpu_ns() -> u64 {
    common::thread_cpu_ns().unwrap_or(0)
}

fn pct(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    v[((v.len() - 1) as f64 * q).round() as usize]
}

struct Row {
    kind: &'static str,
    n: usize,
    median_ms: f64,
}

fn main() {
    // `cargo bench` passes `--bench`; nothing to parse.
    let quick = std::env::var_os("SCALE_QUICK").is_some_and(|v| !v.is_empty());
    let (scene_seeds, plan_seeds) = if quick { (1u64, 5u64) } else { (5, 20) };
    let out_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/scale");
    std::fs::create_dir_all(&out_dir).expect("target/scale");
    let mut csv = String::from(
        "kind,obstacles,scene_seed,plan_seed,ok,wall_ms,cpu_ms,full_wall_ms,method,iterations,length_m,clearance_m\n",
    );
    let kinds = env_list("SCALE_KINDS");
    let sizes: Option<Vec<usize>> =
        env_list("SCALE_SIZES").map(|v| v.iter().map(|x| x.parse().expect("SCALE_SIZES: numbers")).collect());
    let mut rows: Vec<Row> = Vec::new();
    println!(
        "{:<7} {:>7} {:>6} {:>9} {:>8} {:>9} {:>7} {:>10} {:>9} {:>10} {:>11} {:>8} {:>8} {:>4} {:>8}",
        "kind",
        "obst",
        "scenes",
        "file_MB",
        "load_cpu",
        "index_cpu",
        "ok",
        "median_ms",
        "p95_ms",
        "cpu_med_ms",
        "full_med_ms",
        "med_iter",
        "len_m",
        "grid",
        "clear_mm"
    );
    let dense = GenParams { density: 0.35, radius_min: 0.08, radius_max: 0.3, ..GenParams::default() };
    let worlds = [
        ("forest", GenParams { kind: Kind::Forest, ..GenParams::default() }),
        ("dense", GenParams { kind: Kind::Forest, ..dense }),
        ("city", GenParams { kind: Kind::City, ..GenParams::default() }),
    ];
    for (name, base) in worlds {
        if kinds.as_ref().is_some_and(|k| !k.iter().any(|k| k == name)) {
            continue;
        }
        for n in [1_000usize, 10_000, 100_000] {
            if sizes.as_ref().is_some_and(|v| !v.contains(&n)) {
                continue;
            }
            let (mut load, mut build, mut wall, mut cpu, mut full, mut iters, mut lens) =
                (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
            let (mut ok, mut total, mut bytes, mut grid, mut clear) = (0, 0, 0usize, 0, f64::INFINITY);
            for s in 0..scene_seeds {
                let g = generate(&GenParams { obstacles: n, seed: s, ..base.clone() })
                    .unwrap_or_else(|e| panic!("{name} {n} seed {s}: {e}"));
                bytes = g.toml.len();
                let c = thread_cpu_ns();
                let scene = Scene::parse(&g.toml, "generated").expect("parses");
                load.push((thread_cpu_ns() - c) as f64 / 1e6);
                let problem = PlanProblem::from_scene(&scene);
                let c = thread_cpu_ns();
                let index = index_for(&problem);
                build.push((thread_cpu_ns() - c) as f64 / 1e6);
                let obstacles = clearance::Obstacles::new(&problem.obstacles);
                let required = (problem.hull_radius + DEFAULT_MARGIN_M) as f64;
                for seed in 0..plan_seeds {
                    let params = PlannerParams { seed, ..PlannerParams::default() };
                    let (t, c) = (Instant::now(), thread_cpu_ns());
                    let r = plan_with_index(&problem, index.as_ref(), &params);
                    let (w, c) = (t.elapsed().as_secs_f64() * 1e3, (thread_cpu_ns() - c) as f64 / 1e6);
                    let t = Instant::now();
                    let r_full = plan(&problem, &params);
                    let f = t.elapsed().as_secs_f64() * 1e3;
                    if let (Ok(a), Ok(b)) = (&r, &r_full) {
                        assert_eq!(a.waypoints, b.waypoints, "{name} {n}: prebuilt index and plan differ");
                    }
                    total += 1;
                    let (okk, it, len, method, margin) = match &r {
                        Ok(p) => {
                            let (d, k, i) = obstacles.min_clearance(&p.waypoints, required + 1.0);
                            assert!(
                                d >= required - 1e-4,
                                "{name} {n} seed {s}/{seed}: segment {k} is {d} m from obstacle {i} (< {required})"
                            );
                            (true, p.iterations as f64, p.length_m as f64, p.method.as_str(), d - required)
                        }
                        Err(_) => (false, f64::NAN, f64::NAN, "-", f64::NAN),
                    };
                    if method == PlanMethod::Grid.as_str() {
                        grid += 1;
                    }
                    clear = clear.min(margin);
                    let _ = writeln!(
                        csv,
                        "{name},{n},{s},{seed},{okk},{w:.4},{c:.4},{f:.4},{method},{it},{len:.3},{margin:.5}"
                    );
                    if okk {
                        ok += 1;
                        iters.push(it);
                        lens.push(len);
                    }
                    wall.push(w);
                    cpu.push(c);
                    full.push(f);
                }
            }
            let median = pct(&mut wall, 0.5);
            println!(
                "{:<7} {:>7} {:>6} {:>9.2} {:>8.1} {:>9.1} {:>3}/{:<3} {:>10.3} {:>9.3} {:>10.3} {:>11.3} {:>8.0} {:>8.2} {:>4} {:>8.2}",
                name,
                n,
                scene_seeds,
                bytes as f64 / 1e6,
                pct(&mut load, 0.5),
                pct(&mut build, 0.5),
                ok,
                total,
                median,
                pct(&mut wall, 0.95),
                pct(&mut cpu, 0.5),
                pct(&mut full, 0.5),
                pct(&mut iters, 0.5),
                pct(&mut lens, 0.5),
                grid,
                clear * 1e3
            );
            rows.push(Row { kind: name, n, median_ms: median });
        }
    }
    std::fs::write(out_dir.join("plan_scale.csv"), csv).expect("csv");
    plot(&out_dir.join("plan_scale.svg"), &rows).expect("plot");
    println!("wrote {}", out_dir.join("plan_scale.csv").display());
}

fn plot(path: &Path, rows: &[Row]) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (640, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let lo = rows.iter().map(|r| r.median_ms).fold(f64::INFINITY, f64::min).max(1e-3) / 2.0;
    let hi = rows.iter().map(|r| r.median_ms).fold(0.0, f64::max).max(lo * 4.0) * 2.0;
    let mut chart = ChartBuilder::on(&root)
        .caption("parapet plan: median time vs obstacle count", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((500f64..200_000f64).log_scale(), (lo..hi).log_scale())?;
    chart.configure_mesh().x_desc("static obstacles").y_desc("median planning time, ms").draw()?;
    for (kind, color) in [("forest", &BLUE), ("dense", &GREEN), ("city", &RED)] {
        let pts: Vec<(f64, f64)> =
            rows.iter().filter(|r| r.kind == kind).map(|r| (r.n as f64, r.median_ms)).collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color))?
            .label(kind)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
    }
    chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw()?;
    root.present()?;
    Ok(())
}
