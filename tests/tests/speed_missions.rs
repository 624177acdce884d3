//! Missions at the speeds drones fly (issue 35): the shipped scenes on their planned paths
//! with the jerk-limited trajectory (`MIS_GUIDANCE` 1, `--guidance trajectory`) and its
//! position → velocity tracking cascade, exact sensing (`truth`), at a cruise of 2 and 5 m/s:
//! the goal within the default duration limit, no collision. The same flights with the paper's
//! guidance (`MIS_GUIDANCE` 0) are the "before" of `docs/cascade.md` § Trajectory generation.
//!
//! Range sensing with moving obstacles is asserted in
//! `perception_flights::ci_subset_movers_on_the_trajectory` (`docs/cascade.md`: why the
//! trajectory is not yet the default).

use std::path::PathBuf;

use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{default_duration, RunConfig, RunOutput};
use parapet_sim::plan::{plan, PlanProblem, PlannerParams};
use parapet_sim::world::scene::{to_f64, Scene};

fn scene(name: &str) -> Scene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(format!("{name}.toml"));
    Scene::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

/// `parapet run --scene scenes/<name>.toml --speed <speed> --param MIS_GUIDANCE=<guidance>`.
fn fly(name: &str, speed: f64, guidance: f32) -> RunOutput {
    let mut s = scene(name);
    s.speed = speed;
    let planned = plan(&PlanProblem::from_scene(&s), &PlannerParams::default())
        .unwrap_or_else(|e| panic!("{name}: planning failed: {e}"));
    let path: Vec<_> = planned.waypoints.iter().map(to_f64).collect();
    let mut cfg = RunConfig::for_scene(&s, path).unwrap();
    cfg.duration = s.sim.duration.unwrap_or_else(|| default_duration(&s, &cfg.path, speed));
    cfg.param_overrides.push(("MIS_GUIDANCE", guidance));
    run(&s, &cfg, &mut |_| {}).unwrap()
}

const SCENES: [&str; 5] = ["office", "outdoor_static", "door_lintel", "dogleg_corridor", "one_sphere"];

#[test]
fn trajectory_missions_reach_the_goal_at_2_and_5_m_s_without_contact() {
    for name in SCENES {
        for speed in [2.0, 5.0] {
            let out = fly(name, speed, 1.0);
            let s = &out.summary;
            assert!(!s.collided, "{name} at {speed} m/s: collision {:?}", s.collision_obstacle);
            assert!(s.reached_goal, "{name} at {speed} m/s: goal not reached ({})", s.end_reason);
        }
    }
}

#[test]
fn the_cruise_speed_is_flown_on_an_open_leg() {
    // one_sphere's path has open legs: at a 5 m/s cruise the trajectory flies faster than
    // the paper's walking pace ever does (its reference moves at most at the cruise, and the
    // soft PD lags it): the fastest horizontal speed is at least 2 m/s.
    let out = fly("one_sphere", 5.0, 1.0);
    let vmax = out.samples.iter().map(|x| x.vel.xy().norm()).fold(0.0, f64::max);
    assert!(vmax >= 2.0, "fastest horizontal speed {vmax:.2} m/s");
    assert!(out.summary.reached_goal);
}
