//! Paper experiment A (outdoor, static obstacles) on the 6-DOF plant with the paper's
//! filter variant: speed 0.3 m/s, (δ1, δ, μ, k_p, k_d) = (0.08, 0.05, 0.9, 0.32, 0.50).
//!
//! The path is the committed `scenes/outdoor_static_path.json`: a zig-zag through the
//! tree rows whose five turn-in corners sit √δ1 = 0.283 m from a trunk or the shed (hull
//! 0.224 m plus 0.059 m), so the claim does not depend on a planner seed. Sensor noise is on
//! (three fixed seeds): the claim must hold for a real, noisy flight.
//! Results and the reproducing commands: docs/results.md, "Experiment A".

mod paper_common;
use paper_common::{fly, path_file, scene};

#[test]
fn a_corners_hug_obstacles_and_the_path_itself_is_clear() {
    let s = scene("outdoor_static.toml");
    let path = path_file("outdoor_static_path.json");
    let hull = s.vehicle.hull_radius;
    assert!(path.len() >= 10, "the path should zig-zag: {} waypoints", path.len());
    // The five turn-in corners (heading straight at a trunk or the shed) are at most 7 cm beyond
    // the hull from it (the overshoot of the soft PD gains at a corner is larger than that); the
    // other corners lie in gaps or at the shed's edges. Every point of the path is clear.
    let corners: Vec<f64> = path[1..path.len() - 1].iter().map(|w| s.nearest(w, 0.0).0 - hull).collect();
    println!("A corner clearances {corners:.3?}");
    assert!(corners.iter().all(|&c| c > 0.0), "{corners:?}");
    let tight = corners.iter().filter(|&&c| c < 0.07).count();
    assert!(tight >= 5, "only {tight} corners within 7 cm: {corners:?}");
    for seg in path.windows(2) {
        for k in 0..=100 {
            let p = seg[0] + (seg[1] - seg[0]) * (k as f64 / 100.0);
            assert!(s.nearest(&p, 0.0).0 - hull > 0.0, "path point {p:?} collides");
        }
    }
}

#[test]
fn a_filter_keeps_clearance_and_without_it_the_vehicle_hits_a_corner_obstacle() {
    let s = scene("outdoor_static.toml");
    let path = path_file("outdoor_static_path.json");
    assert_eq!((s.controller.mu, s.controller.delta1), (Some(0.9), Some(0.08)));
    assert_eq!((s.controller.kp, s.controller.kd, s.speed), (Some(0.32), Some(0.5), 0.3));
    for seed in [0, 1, 2] {
        let with = fly(&s, &path, true, seed, true, |_| {}).summary;
        println!(
            "A seed {seed} filter: collided {} goal {} min clearance {:.3} m min h_bar {:.4} RMS {:.3}",
            with.collided, with.reached_goal, with.min_clearance_m, with.min_h_bar, with.tracking_rms_m
        );
        assert!(!with.collided && with.reached_goal, "{with:?}");
        // Clearance above zero for the whole flight, and the barrier itself never violated.
        assert!(with.min_clearance_m > 0.02, "min clearance {}", with.min_clearance_m);
        assert!(with.min_h_bar > 0.0, "min h_bar {}", with.min_h_bar);
        assert!(with.filter_active_fraction > 0.0);

        let out = fly(&s, &path, false, seed, true, |_| {});
        let without = &out.summary;
        assert!(without.collided, "seed {seed}: no collision without the filter: {without:?}");
        // Where: next to a corner of the path (within 0.5 m of an interior waypoint).
        let hit = out.samples.last().unwrap().pos;
        let corner = path[1..path.len() - 1].iter().map(|w| (w - hit).norm()).fold(f64::INFINITY, f64::min);
        println!(
            "A seed {seed} no filter: collided with {:?} at t = {:?} s, {corner:.2} m from a corner",
            without.collision_with, without.first_collision_time_s
        );
        assert!(corner < 0.5, "collision {corner} m from the nearest corner");
        assert!(without.collision_obstacle.is_some(), "hit the ground, not an obstacle");
    }
}
