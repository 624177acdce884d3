//! Closed-loop tests of the yaw along a path (`MIS_YAW_MODE`, `core/src/outer/path_yaw.rs`) on
//! the core's test plant (`plant/`): with travel the vehicle faces each leg before it flies it
//! (Mission and Return, turns through ±π included); with hold (the default) the heading stays
//! the one at arming and the path never waits. Deterministic (no noise).

#[allow(dead_code)] // `Quad::on_ground` is not used here
mod plant;

use core::f32::consts::{FRAC_PI_2, PI};
use parapet_core::controller::{ControllerParams, FlightMode, GuidanceMode};
use parapet_core::frame::wrap_pi;
use parapet_core::outer::path_yaw::MAX_HEADING_ERROR;
use parapet_core::params;
use parapet_core::Vec3;
use plant::Sim;

const HOVER: Vec3 = Vec3::new(0.0, 0.0, -1.0);
/// East 2 m, south 2 m, west 2 m: yaw 0 → π/2 → π → −π/2 (the last turn through ±π).
const PATH: [Vec3; 3] = [Vec3::new(0.0, 2.0, -1.0), Vec3::new(-2.0, 2.0, -1.0), Vec3::new(-2.0, 0.0, -1.0)];

/// What a flight along [`PATH`] showed.
#[derive(Debug, Default)]
struct Flown {
    /// Largest |heading − direction of the reference's velocity| while the reference moved, rad.
    worst_heading_error: f32,
    /// Outer-step samples in Mission with the path started, not done, and a stationary reference.
    waiting_s: f32,
    /// Time to the goal, s.
    to_goal_s: f32,
    /// Largest |heading| (true yaw) over the mission, rad.
    max_abs_yaw: f32,
    /// Heading (true yaw) when the reference reached the goal, rad.
    yaw_at_goal: f32,
}

fn record(f: &mut Flown, quad: &plant::Quad, tel: &parapet_core::controller::Telemetry) {
    let (_, _, heading) = quad.q.euler_angles();
    f.max_abs_yaw = f.max_abs_yaw.max(heading.abs());
    let v = tel.reference.velocity;
    if v.x.hypot(v.y) > 0.01 {
        let e = wrap_pi(v.y.atan2(v.x) - heading).abs();
        f.worst_heading_error = f.worst_heading_error.max(e);
    } else if matches!(tel.mode, GuidanceMode::Mission | GuidanceMode::Return) && !tel.progress.done {
        f.waiting_s += 0.001;
    }
}

/// Armed, hovering at `HOVER` facing north, then the mission along [`PATH`] at 0.5 m/s with
/// `MIS_YAW_MODE` = `mode`.
fn fly_mission(mode: f32) -> (Sim, Flown) {
    let mut p = ControllerParams::default();
    params::set(&mut p, "MIS_YAW_MODE", mode).unwrap();
    params::set(&mut p, "WP_SPEED", 0.5).unwrap();
    // The paper's reference (`MIS_GUIDANCE` 0): it stops while the vehicle turns to a leg.
    params::set(&mut p, "MIS_GUIDANCE", 0.0).unwrap();
    let mut sim = Sim::new(p, HOVER);
    sim.ctl.arm(sim.t_us).unwrap();
    sim.ctl.hold_position(sim.t_us, HOVER).unwrap();
    sim.run(1.0, |_, _| {});
    sim.ctl.set_path(&PATH).unwrap();
    sim.ctl.start_mission(sim.t_us).unwrap();
    let t0 = sim.t_us;
    let mut f = Flown::default();
    let mut done_at = None;
    for _ in 0..40_000 {
        sim.run(0.001, |q, c| record(&mut f, q, &c.telemetry()));
        if done_at.is_none() && sim.ctl.telemetry().progress.done {
            done_at = Some(sim.t_us);
            f.yaw_at_goal = sim.quad.q.euler_angles().2;
        }
        if done_at.is_some_and(|t| sim.t_us > t + 10_000_000) {
            break;
        }
    }
    f.to_goal_s = done_at.map_or(f32::INFINITY, |t| (t - t0) as f32 * 1e-6);
    (sim, f)
}

#[test]
fn travel_faces_each_leg_before_flying_it() {
    let (sim, f) = fly_mission(1.0);
    println!("travel: {f:?}");
    assert!((sim.quad.p - PATH[2]).norm() < 0.1, "at the goal: {:?}", sim.quad.p);
    // The last leg is west: yaw −π/2 (reached through ±π from south). (After an overshoot
    // past the goal of more than 0.1 m the vehicle faces the goal again: not checked here.)
    assert!(wrap_pi(f.yaw_at_goal + FRAC_PI_2).abs() < 0.05, "{f:?}");
    // The reference never moved while the heading was more than MAX_HEADING_ERROR (12°) off its
    // direction (+ the estimate's error against the true yaw, a few mrad).
    let max_err = MAX_HEADING_ERROR;
    assert!(f.worst_heading_error < max_err + 0.02, "{f:?}");
    // Three turns of 90° at 45°/s, each waiting until within 12°: ≈ 3 × 1.73 s.
    assert!(f.waiting_s > 4.5 && f.waiting_s < 7.5, "{f:?}");
    assert!(f.to_goal_s < 12.0 + 7.5, "{f:?}");
}

#[test]
fn hold_keeps_the_heading_and_never_waits() {
    let (sim, f) = fly_mission(0.0);
    println!("hold: {f:?}");
    assert!((sim.quad.p - PATH[2]).norm() < 0.1, "at the goal: {:?}", sim.quad.p);
    assert!(f.max_abs_yaw < 0.02, "{f:?}");
    assert_eq!(f.waiting_s, 0.0, "{f:?}");
    // 6 m at 0.5 m/s.
    assert!((f.to_goal_s - 12.0).abs() < 0.01, "{f:?}");
    // …and the leg south is flown backwards, the west leg sideways: the case travel is for.
    assert!(f.worst_heading_error > PI - 0.01, "{f:?}");
}

#[test]
fn return_with_travel_faces_the_way_back() {
    let (mut sim, _) = fly_mission(1.0);
    sim.ctl.set_mode(sim.t_us, FlightMode::Return).unwrap();
    let mut f = Flown::default();
    let mut returned = false;
    for _ in 0..40_000 {
        sim.run(0.001, |q, c| {
            let tel = c.telemetry();
            if tel.mode == GuidanceMode::Return {
                record(&mut f, q, &tel);
            }
        });
        if sim.ctl.mode() == FlightMode::Land {
            returned = true;
            break;
        }
    }
    println!("return: {f:?}");
    assert!(returned, "back home: {:?}", sim.quad.p);
    assert!(sim.quad.p.xy().norm() < 0.15, "{:?}", sim.quad.p);
    let max_err = MAX_HEADING_ERROR;
    assert!(f.worst_heading_error < max_err + 0.02, "{f:?}");
    // At least the turn from west to east (π) before the first leg back.
    assert!(f.waiting_s > 2.5, "{f:?}");
}
