//! Issue 11 scene experiments: several barriers near at once — a dog-leg corridor
//! 0.9 m wide (`scenes/dogleg_corridor.toml`) and a door with a low lintel
//! (`scenes/door_lintel.toml`), flown on the 6-DOF simulator with the real flight
//! controller along the planner's path (seed 0, committed as `scenes/*_path.json` so
//! the tests do not change when the planner does).
//!
//! **Noise**: the default sensor model (IMU noise and bias, 5 mm / 0.02 m/s fix noise,
//! 10 ms latency), seeds 0–2.
//!
//! **ε = 2·10⁻³ m²** (as the double-integrator properties). Where the 6-DOF loop departs
//! from the double integrator:
//! * the filter runs at the outer rate, 250 Hz (T = 4 ms, zero-order hold): the controller's
//!   sampled-data guard engages a barrier one step early, and within a step h drifts by
//!   ~½|ḧ|T² ≈ 10⁻⁵ m² — covered by ε;
//! * the attitude loop (20 ms motor lag plus the attitude/rate loops) realises the filtered
//!   acceleration late, so h keeps falling for a while after the filter engaged at h = δ1.
//!   Estimate μ|d|·τ·Δu ≈ 1.4 · 0.3 m · 0.05 s · 0.5–1.5 m/s² ≈ 0.01–0.03 m²; measured here
//!   0.013 m² at 0.25 m/s and 0.033 m² at 0.5 m/s below the engagement level. That dip is
//!   absorbed by δ1 − δ = 0.05 m² (h̄ = h − δ stays ≥ +0.017 m²), so it does not enter ε;
//!   with δ1 close to δ it would (the paper's experiment-C failures).
//!
//! So the assertion is `min h̄ ≥ −ε` on the true state over the whole flight, over every
//! obstacle (`Summary::min_h_bar`), and no collision, at the scenes' δ1 = 0.1 m².

use std::path::PathBuf;

use nalgebra::Vector3;
use parapet_core::cbf::FilterVariant;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{path_length, RunConfig, RunOutput};
use parapet_sim::plan::pathfile::PathFile;
use parapet_sim::world::scene::{to_f64, Scene};

const EPS: f64 = 2e-3;
const SCENES: [&str; 2] = ["dogleg_corridor", "door_lintel"];

fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// The scene and its committed path (NED).
fn scene_and_path(name: &str) -> (Scene, Vec<Vector3<f64>>) {
    let s = Scene::load(&scenes_dir().join(format!("{name}.toml"))).unwrap_or_else(|e| panic!("{e}"));
    let f = PathFile::read(&scenes_dir().join(format!("{name}_path.json"))).unwrap_or_else(|e| panic!("{e}"));
    let path: Vec<_> = f.waypoints_ned().iter().map(to_f64).collect();
    assert!((path[0] - s.start).norm() < 1e-5 && (path[path.len() - 1] - s.goal).norm() < 1e-5);
    (s, path)
}

/// Fly `path` with `variant` at `speed` (m/s) and engagement level `delta1` (m²), as
/// `parapet run --path … --filter … --speed … --delta1 … --seed …` does.
fn fly(
    s: &Scene,
    path: &[Vector3<f64>],
    variant: FilterVariant,
    speed: f64,
    delta1: f64,
    seed: u64,
) -> RunOutput {
    let mut cfg = RunConfig::for_scene(s, path.to_vec()).unwrap();
    cfg.variant = variant;
    cfg.params.speed = speed;
    cfg.params.delta1 = delta1;
    cfg.duration = 1.5 * path_length(path) / speed + 15.0;
    cfg.seed = seed;
    run(s, &cfg, &mut |_| {}).unwrap()
}

#[test]
fn the_scenes_put_several_barriers_near_at_once() {
    // The committed paths keep the planner's clearance (hull + 5 cm margin), and along
    // them the multi filter really enforces two or more barriers at the same time.
    for name in SCENES {
        let (s, path) = scene_and_path(name);
        for w in path.windows(2) {
            for k in 0..=100 {
                let p = w[0] + (w[1] - w[0]) * (k as f64 / 100.0);
                assert!(
                    s.nearest(&p, 0.0).0 > s.vehicle.hull_radius + 0.04,
                    "{name}: path too close at {p:?}"
                );
            }
        }
        let out = fly(&s, &path, FilterVariant::Multi, s.speed, 0.1, 0);
        let n_max = out.samples.iter().map(|k| k.filter.n_constraints).max().unwrap_or(0);
        assert!(n_max >= 2, "{name}: at most {n_max} barrier(s) enforced at once");
    }
}

#[test]
fn multi_filters_fly_both_scenes_without_collision_and_keep_h_bar() {
    let mut failures = Vec::new();
    for name in SCENES {
        let (s, path) = scene_and_path(name);
        for variant in [FilterVariant::Multi, FilterVariant::MultiRelative] {
            for speed in [0.25, 0.5] {
                for seed in 0..3 {
                    let su = fly(&s, &path, variant, speed, 0.1, seed).summary;
                    let tag = format!("{name} {} {speed} m/s seed {seed}", variant.as_str());
                    if su.collided {
                        failures.push(format!("{tag}: collided with {:?}", su.collision_with));
                    }
                    if su.min_h_bar < -EPS {
                        failures.push(format!("{tag}: min h̄ {} < −ε", su.min_h_bar));
                    }
                    if !su.reached_goal {
                        failures.push(format!("{tag}: goal not reached ({})", su.end_reason));
                    }
                    if su.filter_active_fraction <= 0.0 {
                        failures.push(format!("{tag}: the filter never acted"));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The comparison of `docs/results.md` (seed 0; `--nocapture` prints it). Asserted: at
/// 0.5 m/s and δ1 = 0.1 the paper's closest-only law lets the barrier of a wall it
/// approaches but that is not the closest go negative (the active obstacle later switches
/// to it with h̄ < 0), while the multi filter keeps every h̄ ≥ −ε. Rows with δ1 = 0.3 are
/// reported, not asserted (see docs/results.md: the multi filter deadlocks there).
#[test]
fn comparison_with_the_paper_law() {
    println!("| scene | speed (m/s) | δ1 (m²) | variant | collided | min clearance (m) | min h̄ (m²) | reached goal | time to goal (s) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in SCENES {
        let (s, path) = scene_and_path(name);
        for delta1 in [0.1, 0.3] {
            for speed in [0.25, 0.5] {
                let mut min_h = [0.0; 2];
                for (i, variant) in [FilterVariant::Multi, FilterVariant::Paper].into_iter().enumerate() {
                    let su = fly(&s, &path, variant, speed, delta1, 0).summary;
                    min_h[i] = su.min_h_bar;
                    println!(
                        "| {name} | {speed} | {delta1} | {} | {} | {:.3} | {:.3} | {} | {} |",
                        variant.as_str(),
                        match (&su.first_collision_time_s, &su.collision_with) {
                            (Some(t), Some(w)) => format!("yes ({t:.1} s, {w})"),
                            _ => "no".into(),
                        },
                        su.min_clearance_m,
                        su.min_h_bar,
                        if su.reached_goal { "yes".to_string() } else { format!("no ({})", su.end_reason) },
                        su.time_to_goal_s.map_or("—".into(), |t| format!("{t:.1}")),
                    );
                }
                if delta1 == 0.1 && speed == 0.5 {
                    assert!(min_h[0] >= -EPS, "{name}: multi min h̄ {}", min_h[0]);
                    assert!(min_h[1] < -0.05, "{name}: paper min h̄ {} (measured −0.08 … −0.11)", min_h[1]);
                }
            }
        }
    }
}
