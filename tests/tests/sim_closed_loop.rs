//! Closed-loop flights on the 6-DOF simulator with the real flight controller.

use std::path::PathBuf;

use parapet_core::cbf::FilterVariant;
use parapet_core::outer::guidance::MissionGuidance;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{RunConfig, RunOutput};
use parapet_sim::world::scene::Scene;

fn scene(name: &str) -> Scene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name);
    Scene::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

/// Fly the straight line start → goal of `s` (through the obstacle) with the paper's guidance
/// (`MIS_GUIDANCE` 0: its reference runs on through the sphere and the filter slides the
/// vehicle round it, the paper's demonstration).
fn fly_straight(s: &Scene, cbf: bool, seed: u64) -> RunOutput {
    fly_straight_with(s, cbf, seed, MissionGuidance::Paper, &[])
}

fn fly_straight_with(
    s: &Scene,
    cbf: bool,
    seed: u64,
    guidance: MissionGuidance,
    params: &[(&'static str, f32)],
) -> RunOutput {
    let mut cfg = RunConfig::for_scene(s, vec![s.start, s.goal]).unwrap();
    cfg.cbf = cbf;
    cfg.seed = seed;
    cfg.guidance = guidance;
    cfg.param_overrides.extend_from_slice(params);
    run(s, &cfg, &mut |_| {}).unwrap()
}

/// The default guidance (the trajectory, whose clock waits while the filter holds the vehicle
/// back) on a path through the sphere: without on-board replanning the vehicle holds in front
/// of it (no contact, no goal: the defined stall); with the replanner (`RPL_ENABLE` 1) the
/// blocked path is replanned round the sphere from the obstacle memory and the goal reached.
#[test]
fn one_sphere_trajectory_holds_in_front_and_the_replanner_goes_round() {
    let s = scene("one_sphere.toml");
    assert_eq!(MissionGuidance::default(), MissionGuidance::Trajectory);
    let hold = fly_straight_with(&s, true, 1, MissionGuidance::Trajectory, &[("RPL_ENABLE", 0.0)]).summary;
    assert!(!hold.collided, "{hold:?}");
    assert!(!hold.reached_goal, "the clock ran through the sphere: {hold:?}");
    assert!(hold.min_clearance_m > 0.0);
    assert_eq!(hold.replan.replans, 0);
    let replanned =
        fly_straight_with(&s, true, 1, MissionGuidance::Trajectory, &[("RPL_ENABLE", 1.0)]).summary;
    assert!(!replanned.collided, "{replanned:?}");
    assert!(replanned.reached_goal, "{replanned:?}");
    assert!(replanned.replan.replans >= 1, "{replanned:?}");
    assert!(replanned.min_clearance_m > 0.0);
}

#[test]
fn one_sphere_cbf_reaches_goal_and_no_cbf_collides() {
    let s = scene("one_sphere.toml");
    // The straight path really goes through the sphere.
    let mid = (s.start + s.goal) / 2.0;
    assert!(s.nearest(&mid, 0.0).0 < 0.0);

    let with = fly_straight(&s, true, 1).summary;
    assert!(!with.collided, "CBF flight collided: {with:?}");
    assert!(with.reached_goal, "CBF flight did not reach the goal: {with:?}");
    assert!(with.min_clearance_m > 0.0);
    assert!(with.filter_active_fraction > 0.0, "the filter never acted");
    assert_eq!(with.final_controller_state, "Armed");

    let without = fly_straight(&s, false, 1).summary;
    assert!(without.collided, "flight without the filter did not collide: {without:?}");
    assert!(!without.reached_goal);
    assert_eq!(without.end_reason, "collision");
    assert_eq!(without.filter_active_fraction, 0.0);
    let t = without.first_collision_time_s.unwrap();
    // The sphere's surface is ~2.7 m from the start at 0.3 m/s: the hit comes after ~8 s.
    assert!(t > 5.0 && t < 15.0, "collision at {t} s");
}

#[test]
fn same_seed_same_flight_and_noise_changes_it() {
    let s = scene("one_sphere.toml");
    let a = fly_straight(&s, true, 3);
    let b = fly_straight(&s, true, 3);
    let c = fly_straight(&s, true, 4);
    assert_eq!(a.samples, b.samples);
    assert_ne!(a.samples, c.samples);
}

/// Mean tracking error (m) over 12..18 s of a straight obstacle-free flight.
/// Sensor noise off: an accelerometer bias b tilts the attitude estimate by b/g and,
/// with the soft k_p, moves the vehicle by g·(b/g)/k_p = b/k_p (4 cm for 0.02 m/s²).
fn mid_flight_error(s: &Scene) -> (f64, RunOutput) {
    mid_flight_error_with(s, FilterVariant::Paper)
}

/// Mean tracking error over 12-18 s with `variant` (the paper's: the PD law alone; the
/// default variants' disturbance observer cancels the drag, issue 17).
fn mid_flight_error_with(s: &Scene, variant: FilterVariant) -> (f64, RunOutput) {
    let mut cfg = RunConfig::for_scene(s, vec![s.start, s.goal]).unwrap();
    cfg.sensors.noise = false;
    cfg.variant = variant;
    // The paper's guidance (constant speed along the path), whose PD lag the checks predict.
    cfg.guidance = MissionGuidance::Paper;
    let out = run(s, &cfg, &mut |_| {}).unwrap();
    let mid: Vec<f64> =
        out.samples.iter().filter(|k| k.t > 12.0 && k.t < 18.0).map(|k| (k.pos - k.ref_pos).norm()).collect();
    (mid.iter().sum::<f64>() / mid.len() as f64, out)
}

#[test]
fn free_flight_tracking_lag_is_the_drag_over_kp() {
    // No obstacle on a straight path at constant speed V. The paper's PD law has no
    // horizontal integrator, so linear drag c leaves a steady lag e = c·V / (m·k_p);
    // without drag the cascade tracks the ramp within a few cm.
    let mut s = scene("one_sphere.toml");
    s.obstacles.clear();
    let (e_drag, out) = mid_flight_error(&s);
    let sum = &out.summary;
    assert!(sum.reached_goal && !sum.collided);
    let expected = s.vehicle.drag[0] * s.speed / (s.vehicle.mass * 0.5);
    println!("drag lag {e_drag:.3} m (predicted {expected:.3} m), RMS {:.3} m", sum.tracking_rms_m);
    assert!((e_drag - expected).abs() < 0.1 * expected, "lag {e_drag} vs {expected}");
    // Altitude hold (integrator on z): never more than 10 cm off the flight level.
    let z0 = s.start.z;
    let dz = out.samples.iter().map(|k| (k.pos.z - z0).abs()).fold(0.0, f64::max);
    assert!(dz < 0.1, "altitude error {dz}");
    // Time to goal ≈ path time (6 m at 0.3 m/s = 20 s) plus the settling.
    let t = sum.time_to_goal_s.unwrap();
    assert!(t > 20.0 && t < 40.0, "time to goal {t}");

    // Issue 17: the default filter feeds the observer's −d̂ forward and cancels the drag.
    let (e_default, _) = mid_flight_error_with(&s, FilterVariant::default());
    println!("drag lag with the default filter {e_default:.3} m");
    assert!(e_default < 0.1 * expected, "default-filter lag {e_default} vs PD {expected}");

    s.vehicle.drag = [0.0; 3];
    let (e_free, _) = mid_flight_error(&s);
    println!("no-drag error {e_free:.3} m");
    assert!(e_free < 0.03, "error without drag {e_free}");
}

#[test]
fn moving_person_is_reported_and_avoided_or_recorded() {
    // The walking person crosses the straight path; the run must complete and
    // record consistent metrics (the safety claims are checked in the experiment tests).
    let s = scene("outdoor_person.toml");
    let out = fly_straight(&s, true, 0);
    let sum = &out.summary;
    assert!(sum.sim_time_s > 10.0);
    assert_eq!(sum.collided, sum.min_clearance_m < 0.0);
    // The filter saw the person (obstacle 0) at some point.
    assert!(out.samples.iter().any(|k| k.filter.active_id == Some(0)));
}

#[test]
fn default_office_flight_is_safe_and_reaches_the_goal() {
    // The README's main command: the office scene, planned with seed 0, default filter.
    use parapet_sim::plan::{plan, PlanProblem, PlannerParams};
    let s = scene("office.toml");
    let planned = plan(&PlanProblem::from_scene(&s), &PlannerParams::default()).unwrap();
    let path = planned.waypoints.iter().map(parapet_sim::world::scene::to_f64).collect();
    let cfg = RunConfig::for_scene(&s, path).unwrap();
    let out = run(&s, &cfg, &mut |_| {}).unwrap();
    let sum = &out.summary;
    println!(
        "office: goal {} at {:?} s, min clearance {:.3} m, min h_bar {:.4}, RMS {:.3} m, active {:.3}",
        sum.reached_goal,
        sum.time_to_goal_s,
        sum.min_clearance_m,
        sum.min_h_bar,
        sum.tracking_rms_m,
        sum.filter_active_fraction
    );
    assert!(!sum.collided, "{sum:?}");
    assert!(sum.reached_goal, "{sum:?}");
    assert!(sum.min_h_bar > -0.01, "barrier violated: {}", sum.min_h_bar);
    assert!(sum.filter_active_fraction > 0.0);
}
