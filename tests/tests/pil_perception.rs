//! Processor-in-the-loop with a planar lidar (issue 19): `parapet pil --perception lidar`
//! sends each simulated lidar scan to the QEMU firmware as `OBSTACLE_DISTANCE` (72 sectors,
//! `MAV_FRAME_BODY_FRD`) and no obstacle points; the firmware's own obstacle memory builds
//! the safety filter's set (`firmware/src/link/obstacles.rs`, `host-sim/src/fc/pil/proximity.rs`).
//!
//! Noise on, the planner's path of the seed, as `parapet pil` flies it. The full matrix
//! (seven scenes × seeds 0–4) is the documented command of docs/perception.md.
//!
//! The ELF comes from `PARAPET_FIRMWARE_QEMU_ELF` (`cargo xtask test`), see `pil_support`.

use std::path::PathBuf;

use parapet_core::perception::{CELL_ID_BASE, STATIC_ID};
use parapet_sim::fc::pil::{run_pil, PilOptions};
use parapet_sim::plan::{plan, PlanProblem, PlannerParams};
use parapet_sim::sim::range::preset;
use parapet_sim::world::scene::{to_f64, Scene};
use parapet_tests::pil_support::firmware;

fn check(name: &str, seed: u64) {
    let Some(elf) = firmware() else { return };
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(format!("{name}.toml"));
    let scene = Scene::load(&p).unwrap_or_else(|e| panic!("{e}"));
    let planned = plan(&PlanProblem::from_scene(&scene), &PlannerParams { seed, ..PlannerParams::default() })
        .unwrap_or_else(|e| panic!("{name}: planning failed: {e}"));
    let mut cfg = parapet_sim::flight::runner::RunConfig::for_scene(
        &scene,
        planned.waypoints.iter().map(to_f64).collect(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    cfg.seed = seed;
    cfg.perception = preset("lidar");
    assert!(cfg.sensors.noise);
    let (out, fig) = run_pil(&scene, &cfg, PilOptions::new(elf), &mut |_| {}).expect("PIL flight");
    let s = &out.summary;
    println!(
        "{name} seed {seed}: collided {}, goal {:?} s, min clearance {:.3} m, OBSTACLE_DISTANCE scans {}, \
         real-time factor {:.2}",
        s.collided, s.time_to_goal_s, s.min_clearance_m, fig.obstacle_distance_scans, fig.real_time_factor
    );
    assert!(
        !s.collided,
        "{name} seed {seed}: collision with {:?} at {:?} s",
        s.collision_with, s.first_collision_time_s
    );
    assert!(s.reached_goal, "{name} seed {seed}: goal not reached ({} m left)", s.final_distance_to_goal_m);
    // One OBSTACLE_DISTANCE per lidar scan (10 Hz, the first at t = 0, delivered 20 ms later).
    let scans = (s.sim_time_s * 10.0 - 0.2).floor() as u64;
    assert!(
        fig.obstacle_distance_scans >= scans && fig.obstacle_distance_scans <= scans + 2,
        "{} OBSTACLE_DISTANCE for {} s",
        fig.obstacle_distance_scans,
        s.sim_time_s
    );
    assert_eq!(fig.firmware_obstacles_rejected, 0, "{fig:?}");
    assert_eq!(fig.frames_dropped, 0, "{fig:?}");
    // The filter acted on points of the firmware's own memory (cells: STATIC_ID, tracks:
    // CELL_ID_BASE + slot), not on scene obstacle ids (the host sent none).
    let memory_ids = out
        .samples
        .iter()
        .filter_map(|x| x.filter.active_id)
        .filter(|&id| id == STATIC_ID || (CELL_ID_BASE..CELL_ID_BASE + 64).contains(&id))
        .count();
    assert!(memory_ids > 0, "{name}: the filter never acted on a point of the firmware's memory");
    assert!(s.filter_active_fraction > 0.0);
}

#[test]
fn pil_lidar_person_head_on() {
    check("person_headon", 0);
}

#[test]
fn pil_lidar_dogleg_corridor() {
    check("dogleg_corridor", 0);
}

/// A sphere chasing the vehicle along its path at 1 m/s: collided in 5 of 5 seeds while the
/// firmware held its memory's points from one 10 Hz scan to the next (now re-selected every
/// outer period, `firmware/src/link/obstacles.rs`).
#[test]
fn pil_lidar_sphere_overtaking() {
    check("sphere_overtaking", 0);
}
