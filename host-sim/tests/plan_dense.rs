//! The planner in dense worlds (issue 38): generated forests of 0.35 trunks/m²
//! (radius 0.08–0.3 m, a 60 m mission) are solved by every planner seed, and
//! every path keeps the hull + margin from every trunk by an independent check
//! (parry3d's distances, `common/clearance.rs`). Timing is a benchmark
//! (`cargo bench -p parapet-sim --bench scale`, `docs/performance.md`), not a test.

use parapet_sim::plan::generate::generate;
use parapet_sim::plan::{
    index_for, plan_with_index, PlanMethod, PlanProblem, PlannerParams, DEFAULT_MARGIN_M,
};
use parapet_sim::world::generate::{GenParams, Kind};

#[path = "common/clearance.rs"]
mod clearance;

fn dense(obstacles: usize, seed: u64) -> GenParams {
    GenParams {
        kind: Kind::Forest,
        obstacles,
        seed,
        density: 0.35,
        radius_min: 0.08,
        radius_max: 0.3,
        mission_length: 60.0,
        ..GenParams::default()
    }
}

#[test]
fn dense_forest_every_seed_solves_with_clearance() {
    for (n, scene_seed) in [(3_000, 0), (10_000, 0), (10_000, 1)] {
        let g = generate(&dense(n, scene_seed)).unwrap_or_else(|e| panic!("{n}/{scene_seed}: {e}"));
        let problem = PlanProblem::from_scene(&g.scene);
        let index = index_for(&problem);
        let obstacles = clearance::Obstacles::new(&problem.obstacles);
        let required = (problem.hull_radius + DEFAULT_MARGIN_M) as f64;
        let straight = (problem.goal - problem.start).norm();
        for seed in 0..3 {
            let p = plan_with_index(&problem, index.as_ref(), &PlannerParams { seed, ..Default::default() })
                .unwrap_or_else(|e| panic!("{n}/{scene_seed} seed {seed}: {e}"));
            assert_eq!((p.waypoints[0], *p.waypoints.last().unwrap()), (problem.start, problem.goal));
            let (d, k, i) = obstacles.min_clearance(&p.waypoints, required + 1.0);
            assert!(d >= required - 1e-4, "{n}/{scene_seed} seed {seed}: segment {k} {d} m from trunk {i}");
            // The sampling planner's paths in these forests were 1.3–1.5 × the straight line.
            assert!(
                p.length_m < 1.1 * straight,
                "{n}/{scene_seed} seed {seed}: {} m for {straight} m",
                p.length_m
            );
            assert_eq!(p.method, PlanMethod::Grid, "{n}/{scene_seed} seed {seed}");
        }
    }
}

/// The independent check itself fails a path through a trunk (it can fail).
#[test]
fn the_clearance_check_sees_a_path_through_a_trunk() {
    let g = generate(&dense(1_000, 2)).unwrap();
    let problem = PlanProblem::from_scene(&g.scene);
    let obstacles = clearance::Obstacles::new(&problem.obstacles);
    let required = (problem.hull_radius + DEFAULT_MARGIN_M) as f64;
    let (d, _, _) = obstacles.min_clearance(&[problem.start, problem.goal], required + 1.0);
    assert!(d < required, "the straight line through the forest is clear ({d} m)?");
}
