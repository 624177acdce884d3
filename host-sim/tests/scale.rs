//! Worlds at scale (issue 18): generated scenes are valid and reproducible from
//! their seed, and the simulator's indexed queries on them equal the full scans.
//! Small sizes only (seconds); the 10⁴–10⁵ figures are benchmarks
//! (`docs/performance.md`).

use nalgebra::Vector3;
use parapet_core::cbf::{CbfParams, FilterVariant, SafetyFilter};
use parapet_core::obstacle::Shape;
use parapet_sim::flight::runner::{
    nearest_with_ground, sense_and_h_bar, sense_obstacles, true_h_bar, OuterScratch,
};
use parapet_sim::plan::generate::generate;
use parapet_sim::plan::{path_is_valid, plan, PlanProblem, PlannerParams, DEFAULT_MARGIN_M};
use parapet_sim::sim::sensors::{SensorParams, Sensors};
use parapet_sim::world::generate::{GenParams, Kind, ENDPOINT_CLEARANCE_M};
use parapet_sim::world::scene::{to_f32, Motion, Scene, SceneObstacle};
use parapet_sim::world::NearestTracker;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn params(kind: Kind, n: usize, seed: u64) -> GenParams {
    GenParams { kind, obstacles: n, seed, ..GenParams::default() }
}

#[test]
fn generated_scenes_are_valid_and_reproducible_from_their_seed() {
    for kind in [Kind::Forest, Kind::City, Kind::Warehouse, Kind::Clutter] {
        let a = generate(&params(kind, 600, 3)).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        let b = generate(&params(kind, 600, 3)).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert_eq!(a.toml, b.toml, "{kind:?}: same seed, same file");
        let c = generate(&params(kind, 600, 4)).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert_ne!(a.toml, c.toml, "{kind:?}: another seed, another scene");
        // The file loads as written and holds what was asked for.
        let scene = Scene::parse(&a.toml, &a.scene.source).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert!(scene == a.scene, "{kind:?}: the file does not load as the generated scene");
        let n = scene.obstacles.len();
        assert!((590..=600).contains(&n), "{kind:?}: {n} obstacles");
        assert!(scene.obstacles.iter().all(|o| o.is_static() && o.shape.is_valid()));
        // Start and goal are clear and a planned path connects them.
        for p in [scene.start, scene.goal] {
            assert!(scene.nearest(&p, 0.0).0 >= ENDPOINT_CLEARANCE_M - 1e-6, "{kind:?}: endpoint at {p:?}");
        }
        assert!((scene.goal - scene.start).norm() > 30.0, "{kind:?}: mission too short");
        let problem = PlanProblem::from_scene(&scene);
        let path = plan(&problem, &PlannerParams { seed: 9, ..PlannerParams::default() })
            .unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert!(path_is_valid(&problem, DEFAULT_MARGIN_M, &path.waypoints), "{kind:?}");
        // The straight line is blocked in these scenes: the planner had work to do.
        let straight = vec![problem.start, problem.goal];
        if kind != Kind::Clutter {
            assert!(!path_is_valid(&problem, DEFAULT_MARGIN_M, &straight), "{kind:?}: trivial mission");
        }
    }
}

#[test]
fn generator_options_out_of_range_are_named() {
    let cases: [(&str, GenParams); 4] = [
        ("option --obstacles", GenParams { obstacles: 0, ..GenParams::default() }),
        ("option --density", GenParams { density: -1.0, ..GenParams::default() }),
        ("option --radius-max", GenParams { radius_min: 0.5, radius_max: 0.2, ..GenParams::default() }),
        ("option --ceiling", GenParams { ceiling: f64::NAN, ..GenParams::default() }),
    ];
    for (origin, p) in cases {
        let e = generate(&p).unwrap_err();
        assert_eq!(e.origin, origin, "{e}");
        assert!(e.allowed.is_some(), "{e}");
    }
}

/// A generated forest with a few moving obstacles added (walking people).
fn forest_with_walkers() -> Scene {
    let mut scene = generate(&params(Kind::Forest, 2000, 1)).expect("forest").scene;
    for k in 0..3 {
        let c = scene.start + Vector3::new(1.0 + k as f64, 0.5, -0.9);
        scene.obstacles.insert(
            500 * (k + 1),
            SceneObstacle {
                name: None,
                shape: Shape::cylinder(to_f32(&Vector3::new(c.x, c.y, 0.0)), 0.25, 1.8),
                motion: Motion::Velocity(Vector3::new(0.2, -0.3 + 0.2 * k as f64, 0.0)),
                mapped: true,
            },
        );
    }
    scene
}

#[test]
fn indexed_sensing_barrier_and_clearance_equal_the_full_scans_on_a_forest() {
    let scene = forest_with_walkers();
    let filter = SafetyFilter::new(CbfParams::default(), FilterVariant::default()).expect("filter");
    let params = SensorParams { obstacle_velocity_noise: 0.05, ..SensorParams::default() };
    let (mut full_sensors, mut fast_sensors) = (Sensors::new(params.clone(), 5), Sensors::new(params, 5));
    let mut tracker = NearestTracker::new(&scene);
    assert!(tracker.index().is_some(), "a 2000-obstacle scene is indexed");
    let mut ref_tracker = NearestTracker::with_index(&scene, tracker.index());
    let mut scratch = OuterScratch::default();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let (mut p, mut v) = (scene.start, Vector3::new(0.0, 0.8, 0.0));
    let (mut reported, mut fast_cases, mut inside) = (0, 0, 0);
    let n = 6000;
    for k in 0..n {
        let t = k as f64 * 0.004;
        let r: f64 = rng.random();
        if r < 0.003 {
            // A jump somewhere else in the forest (the set is rebuilt there).
            p += Vector3::new(rng.random_range(-30.0..30.0), rng.random_range(-30.0..30.0), 0.0);
        } else if r < 0.02 {
            v = Vector3::from_fn(|i, _| if i == 2 { 0.0 } else { rng.random_range(-4.0..4.0) });
        } else {
            v += Vector3::from_fn(|i, _| if i == 2 { 0.0 } else { rng.random_range(-0.1..0.1) });
        }
        p += v * 0.004;
        let full = sense_obstacles(&scene, t, &p, 3.0, &mut full_sensors);
        let h_full = true_h_bar(&scene, &filter, t, &p, &v);
        let h_fast =
            sense_and_h_bar(&scene, &mut tracker, &filter, t, &p, &v, 3.0, &mut fast_sensors, &mut scratch);
        assert_eq!(scratch.seen, full, "step {k} at {p:?}");
        assert_eq!(h_fast.to_bits(), h_full.to_bits(), "step {k} at {p:?}: {h_fast} vs {h_full}");
        let c_full = nearest_with_ground(&scene, &p, t);
        let c_fast = tracker.nearest(&scene, &p, t);
        let c_fast = if -p.z < c_fast.0 { (-p.z, None) } else { c_fast };
        assert_eq!((c_fast.0.to_bits(), c_fast.1), (c_full.0.to_bits(), c_full.1), "step {k}");
        // A second point (the reference) sharing the index.
        let q = p + Vector3::new(0.3, -0.2, 0.0);
        assert_eq!(ref_tracker.nearest(&scene, &q, t), scene.nearest(&q, t), "step {k}");
        reported += full.len();
        fast_cases += usize::from(v.norm() > 3.0);
        inside += usize::from(c_full.0 < 0.0);
    }
    assert!(reported > n / 2 && fast_cases > 50, "reported {reported}, fast {fast_cases}");
    assert!(inside > 0, "the walk never entered an obstacle");
    // Far fewer distance evaluations than full scans.
    let full_cost = (n * scene.obstacles.len()) as u64;
    assert!(tracker.evaluations * 100 < full_cost, "{} of {full_cost}", tracker.evaluations);
}

fn parapet(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_parapet")).args(args).output().expect("runs parapet")
}

#[test]
fn cli_scene_generate_writes_a_loadable_scene_and_plan_takes_budgets() {
    let dir = std::env::temp_dir().join(format!("parapet_scale_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("forest.toml");
    let f = file.to_str().unwrap();
    let o =
        parapet(&["scene", "generate", "--kind", "forest", "--obstacles", "300", "--seed", "2", "--out", f]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let scene = Scene::load(&file).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.obstacles.len(), 300);
    // An existing file is not replaced without --force.
    let o = parapet(&["scene", "generate", "--obstacles", "300", "--out", f]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("option --out"));
    let o = parapet(&["scene", "generate", "--obstacles", "0", "--out", &format!("{f}.2")]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(e.contains("option --obstacles") && e.contains("allowed"), "{e}");
    // plan: the budgets are options; out of range is exit 2 naming the option and range.
    let path = dir.join("path.json");
    let p = path.to_str().unwrap();
    let o = parapet(&["plan", "--scene", f, "--out", p, "--time-limit", "2", "--max-iterations", "5000"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (opt, value) in [("--time-limit", "0"), ("--time-limit", "nan"), ("--max-iterations", "0")] {
        let o = parapet(&["plan", "--scene", f, "--out", p, "--force", opt, value]);
        assert_eq!(o.status.code(), Some(2), "{opt} {value}");
        let e = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(e.contains(&format!("option {opt}")) && e.contains("allowed"), "{opt} {value}: {e}");
    }
    // One RRT-Connect iteration is not enough for this mission; the grid search
    // (issue 38), which the iteration budget does not limit, still finds the path.
    let o = parapet(&["plan", "--scene", f, "--out", p, "--force", "--max-iterations", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains(", grid, "),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
