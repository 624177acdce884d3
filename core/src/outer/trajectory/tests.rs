//! Unit tests of the trajectory: exact timing on a straight leg, a right-angle corner, a
//! reversal, the waiting clock and the refused inputs.

use super::*;

const DT: f32 = 0.004;

fn v3(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// What a flight of a trajectory showed.
#[derive(Debug, Default)]
struct Flight {
    steps: usize,
    max_speed: f32,
    max_accel: f32,
    max_jerk: f32,
    max_lateral: f32,
    done: bool,
}

/// Fly `t` with clock scale 1 until done (at most `max_steps`), checking the 1-D limits.
fn fly<const N: usize>(
    t: &mut Trajectory<N>,
    max_steps: usize,
    mut each: impl FnMut(&TrajectorySample),
) -> Flight {
    let mut f = Flight::default();
    let mut prev_a = 0.0f32;
    for i in 0..max_steps {
        let s = t.step(DT, 1.0).unwrap();
        each(&s);
        f.max_speed = f.max_speed.max(s.speed);
        f.max_accel = f.max_accel.max(s.path_acceleration.abs());
        f.max_jerk = f.max_jerk.max((s.path_acceleration - prev_a).abs() / DT);
        prev_a = s.path_acceleration;
        let lateral = s.acceleration - s.velocity.normalize() * s.path_acceleration;
        if s.speed > 1e-3 {
            f.max_lateral = f.max_lateral.max(lateral.norm());
        }
        if s.done {
            f.steps = i + 1;
            f.done = true;
            return f;
        }
    }
    f.steps = max_steps;
    f
}

#[path = "../../../tests/support/s_curve.rs"]
mod s_curve;
use s_curve::s_curve_time;

#[test]
fn straight_leg_takes_the_analytic_s_curve_time() {
    let p = TrajectoryParams::default();
    for &len in &[20.0f32, 3.0, 0.5] {
        let mut t: Trajectory<4> = Trajectory::new(p, &[v3(0.0, 0.0, -1.0), v3(len, 0.0, -1.0)]).unwrap();
        let f = fly(&mut t, 100_000, |_| {});
        assert!(f.done);
        let time = f.steps as f32 * DT;
        let analytic = s_curve_time(f64::from(len), 3.0, 3.0, 4.0) as f32;
        assert!(
            time <= 1.05 * analytic + 2.0 * DT && time >= analytic - 2.0 * DT,
            "{len} m: {time} s vs {analytic} s"
        );
        assert!(
            f.max_speed <= 3.0 + 1e-4 && f.max_accel <= 3.0 + 1e-3 && f.max_jerk <= 4.0 * 1.001 + 1e-3,
            "{f:?}"
        );
    }
    // 20 m at 3 m/s, 3 m/s², 4 m/s³: 2 × 1.75 s of ramps and 14.75 m of cruise.
    assert!((s_curve_time(20.0, 3.0, 3.0, 4.0) - (3.5 + 14.75 / 3.0)).abs() < 1e-5);
}

#[test]
fn right_angle_corner_cuts_within_the_tolerance_and_keeps_lateral_acceleration() {
    let p = TrajectoryParams { corner_tolerance: 0.2, ..TrajectoryParams::default() };
    let corner = v3(10.0, 0.0, -2.0);
    let mut t: Trajectory<4> =
        Trajectory::new(p, &[v3(0.0, 0.0, -2.0), corner, v3(10.0, 10.0, -2.0)]).unwrap();
    let mut closest = f32::INFINITY;
    let f = fly(&mut t, 100_000, |s| {
        // Distance to the polyline: to the nearer of the two legs (x axis, then y = 10 line).
        let to_first = if s.position.x <= 10.0 { s.position.y.abs() } else { (s.position - corner).norm() };
        let to_second =
            if s.position.y >= 0.0 { (s.position.x - 10.0).abs() } else { (s.position - corner).norm() };
        assert!(to_first.min(to_second) <= 0.2 + 1e-4, "{:?}", s.position);
        assert!((s.position.z + 2.0).abs() < 1e-5);
        closest = closest.min((s.position - corner).norm());
    });
    assert!(f.done, "{f:?}");
    assert!((0.2 - 0.01..=0.2 + 1e-3).contains(&closest), "the blend uses the tolerance: {closest}");
    assert!(f.max_lateral <= 3.0 * 1.002, "{f:?}");
    assert!(f.max_jerk <= 4.0 * 1.001 + 1e-3 && f.max_accel <= 3.0 + 1e-3, "{f:?}");
    // The corner is flown slower than cruise but without stopping.
    let c = t.corners.first().unwrap();
    assert!(c.limit > 0.5 && c.limit < 3.0, "{}", c.limit);
}

#[test]
fn reversal_stops_at_the_turn() {
    let p = TrajectoryParams::default();
    let turn = v3(5.0, 0.0, -1.0);
    let mut t: Trajectory<4> = Trajectory::new(p, &[v3(0.0, 0.0, -1.0), turn, v3(1.0, 0.0, -1.0)]).unwrap();
    let mut farthest = 0.0f32;
    let mut speed_at_turn = f32::INFINITY;
    let f = fly(&mut t, 100_000, |s| {
        farthest = farthest.max(s.position.x);
        if (s.position - turn).norm() < 1e-3 {
            speed_at_turn = speed_at_turn.min(s.speed);
        }
    });
    assert!(f.done);
    assert!(farthest <= 5.0 + 1e-5, "{farthest}");
    assert!(speed_at_turn <= SNAP_SPEED, "{speed_at_turn}");
    assert!(f.max_jerk <= 4.0 * 1.001 + 1e-3, "{f:?}");
}

#[test]
fn zero_tolerance_stops_at_every_corner() {
    let p = TrajectoryParams { corner_tolerance: 0.0, ..TrajectoryParams::default() };
    let mut t: Trajectory<4> =
        Trajectory::new(p, &[v3(0.0, 0.0, 0.0), v3(4.0, 0.0, 0.0), v3(4.0, 4.0, 0.0)]).unwrap();
    assert!(t.corners.first().unwrap().stop);
    let mut worst = 0.0f32;
    let f = fly(&mut t, 100_000, |s| worst = worst.max(s.position.y.min(4.0 - s.position.x)));
    assert!(f.done && worst <= 1e-5, "{worst}");
}

#[test]
fn clock_scale_zero_brakes_jerk_limited_and_waits() {
    let p = TrajectoryParams::default();
    let mut t: Trajectory<4> = Trajectory::new(p, &[v3(0.0, 0.0, 0.0), v3(50.0, 0.0, 0.0)]).unwrap();
    let mut prev = t.step(DT, 1.0).unwrap();
    for _ in 0..1000 {
        prev = t.step(DT, 1.0).unwrap();
    }
    assert!((prev.speed - 3.0).abs() < 1e-4);
    let mut stopped_at = None;
    for i in 0..2000 {
        let s = t.step(DT, 0.0).unwrap();
        assert!((s.path_acceleration - prev.path_acceleration).abs() / DT <= 4.0 * 1.001);
        assert!(s.path_acceleration >= -3.0 - 1e-4);
        assert!(s.speed <= prev.speed + 1e-6 && s.position.x >= prev.position.x);
        assert!((s.position - prev.position).norm() <= prev.speed * DT + 1e-4);
        if s.speed == 0.0 && stopped_at.is_none() {
            stopped_at = Some((i, s.position.x));
        }
        prev = s;
    }
    let (i, x) = stopped_at.unwrap();
    // It stops within the jerk-limited braking time of 3 m/s (1.75 s) and stays.
    assert!(i as f32 * DT <= 1.75 + 0.05, "{i}");
    assert_eq!(prev.position.x, x);
    assert!(!prev.done);
    // And carries on when allowed.
    let f = fly(&mut t, 100_000, |_| {});
    assert!(f.done && f.max_jerk <= 4.0 * 1.001 + 1e-3);
}

#[test]
fn clock_scale_helper() {
    assert_eq!(clock_scale(0.0, 0.5), 1.0);
    assert_eq!(clock_scale(0.25, 0.5), 1.0);
    assert!((clock_scale(0.375, 0.5) - 0.5).abs() < 1e-6);
    assert_eq!(clock_scale(0.5, 0.5), 0.0);
    assert_eq!(clock_scale(7.0, 0.5), 0.0);
    assert_eq!(clock_scale(f32::NAN, 0.5), 0.0);
    assert_eq!(clock_scale(0.1, 0.0), 0.0);
    assert_eq!(clock_scale(0.1, f32::INFINITY), 0.0);
}

#[test]
fn bad_parameters_name_the_field() {
    let d = TrajectoryParams::default();
    assert_eq!(d.validate(), Ok(()));
    let cases: [(TrajectoryParams, ParamError); 12] = [
        (TrajectoryParams { cruise_speed: 0.0, ..d }, ParamError::CruiseSpeed),
        (TrajectoryParams { cruise_speed: -1.0, ..d }, ParamError::CruiseSpeed),
        (TrajectoryParams { cruise_speed: 21.0, ..d }, ParamError::CruiseSpeed),
        (TrajectoryParams { cruise_speed: f32::NAN, ..d }, ParamError::CruiseSpeed),
        (TrajectoryParams { accel_horizontal: f32::INFINITY, ..d }, ParamError::AccelHorizontal),
        (TrajectoryParams { speed_up: 0.0, ..d }, ParamError::SpeedUp),
        (TrajectoryParams { speed_down: 11.0, ..d }, ParamError::SpeedDown),
        (TrajectoryParams { accel_vertical: -3.0, ..d }, ParamError::AccelVertical),
        (TrajectoryParams { jerk: 0.0, ..d }, ParamError::Jerk),
        (TrajectoryParams { corner_tolerance: -0.1, ..d }, ParamError::CornerTolerance),
        (TrajectoryParams { corner_tolerance: f32::NAN, ..d }, ParamError::CornerTolerance),
        (TrajectoryParams { tracking_error_bound: 0.0, ..d }, ParamError::TrackingErrorBound),
    ];
    for (p, e) in cases {
        assert_eq!(p.validate(), Err(e));
        let t = Trajectory::<4>::new(p, &[Vec3::zeros(), Vec3::x()]);
        assert_eq!(t.err(), Some(TrajectoryError::Param(e)));
    }
    let ok = TrajectoryParams { corner_tolerance: 0.0, cruise_speed: 20.0, ..d };
    assert_eq!(ok.validate(), Ok(()));
}

#[test]
fn bad_paths_and_steps_are_refused() {
    let p = TrajectoryParams::default();
    let new = |w: &[Vec3]| Trajectory::<4>::new(p, w).err();
    assert_eq!(new(&[]), Some(TrajectoryError::Path(PathError::Empty)));
    assert_eq!(new(&[Vec3::zeros(); 5]), Some(TrajectoryError::Path(PathError::TooMany { capacity: 4 })));
    assert_eq!(
        new(&[Vec3::zeros(), v3(f32::NAN, 0.0, 0.0)]),
        Some(TrajectoryError::Path(PathError::NonFinite { index: 1 }))
    );
    assert_eq!(
        new(&[Vec3::zeros(), v3(0.0, 0.0, -2e5)]),
        Some(TrajectoryError::Path(PathError::OutOfRange { index: 1 }))
    );
    // Repeated consecutive waypoints: a zero-length leg.
    assert_eq!(
        new(&[Vec3::zeros(), Vec3::x(), Vec3::x(), v3(2.0, 0.0, 0.0)]),
        Some(TrajectoryError::RepeatedWaypoint { index: 2 })
    );
    assert_eq!(new(&[Vec3::x(), v3(1.0, 0.0, 1e-4)]), Some(TrajectoryError::RepeatedWaypoint { index: 1 }));
    // A repeat that is not consecutive is fine (a return).
    assert!(new(&[Vec3::zeros(), Vec3::x(), Vec3::zeros()]).is_none());
    let mut t = Trajectory::<4>::new(p, &[Vec3::zeros(), Vec3::x()]).unwrap();
    for dt in [0.0, -0.004, f32::NAN, f32::INFINITY, 0.2] {
        assert_eq!(t.step(dt, 1.0), Err(TrajectoryError::BadDt));
    }
    for c in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert_eq!(t.step(DT, c), Err(TrajectoryError::BadClockScale));
    }
    // One waypoint: done at once, at it.
    let mut one = Trajectory::<4>::new(p, &[v3(1.0, 2.0, 3.0)]).unwrap();
    let s = one.step(DT, 1.0).unwrap();
    assert!(s.done && s.position == v3(1.0, 2.0, 3.0) && s.velocity == Vec3::zeros());
}

#[test]
fn vertical_legs_respect_the_climb_and_descent_limits() {
    let p = TrajectoryParams { speed_up: 1.0, speed_down: 0.5, ..TrajectoryParams::default() };
    // Straight up 10 m, then a 45° descent over 10 m horizontally.
    let w = [v3(0.0, 0.0, 0.0), v3(0.0, 0.0, -10.0), v3(10.0, 0.0, 0.0)];
    let mut t: Trajectory<4> = Trajectory::new(p, &w).unwrap();
    let f = fly(&mut t, 200_000, |s| {
        assert!(-s.velocity.z <= 1.0 + 1e-4, "{:?}", s.velocity);
        assert!(s.velocity.z <= 0.5 + 1e-4, "{:?}", s.velocity);
        assert!(s.velocity.xy().norm() <= 3.0 + 1e-4);
    });
    assert!(f.done);
}

#[test]
fn regeneration_from_a_moving_state_is_continuous() {
    let p = TrajectoryParams::default();
    let mut old: Trajectory<4> = Trajectory::new(p, &[v3(0.0, 0.0, -1.0), v3(30.0, 0.0, -1.0)]).unwrap();
    let mut s = old.step(DT, 1.0).unwrap();
    for _ in 0..1000 {
        s = old.step(DT, 1.0).unwrap();
    }
    assert!((s.speed - 3.0).abs() < 1e-4);
    // The mission changes: carry on east, then turn north.
    let w = [s.position, s.position + v3(10.0, 0.0, 0.0), s.position + v3(10.0, 10.0, 0.0)];
    let mut new: Trajectory<4> = Trajectory::new_moving(p, &w, s.speed, s.path_acceleration).unwrap();
    let mut prev = s;
    let mut steps = 0;
    loop {
        let n = new.step(DT, 1.0).unwrap();
        assert!((n.position - prev.position).norm() <= 3.0 * DT + 1e-4);
        assert!((n.velocity - prev.velocity).norm() <= 2.0 * 3.0 * DT + 1e-4);
        assert!((n.path_acceleration - prev.path_acceleration).abs() <= 4.0 * DT * 1.001 + 1e-6);
        prev = n;
        steps += 1;
        if n.done {
            break;
        }
        assert!(steps < 100_000);
    }
    assert_eq!(prev.position, w[2]);
    // Too fast to stop before the goal, or above the leg's limit, or wild: refused.
    let near = [v3(0.0, 0.0, 0.0), v3(0.5, 0.0, 0.0)];
    assert_eq!(Trajectory::<4>::new_moving(p, &near, 3.0, 0.0).err(), Some(TrajectoryError::BadStartState));
    let far = [v3(0.0, 0.0, 0.0), v3(50.0, 0.0, 0.0)];
    assert!(Trajectory::<4>::new_moving(p, &far, 3.0, 0.0).is_ok());
    for (v, a) in [(3.5, 0.0), (-0.1, 0.0), (1.0, 3.5), (f32::NAN, 0.0), (1.0, f32::INFINITY)] {
        assert_eq!(Trajectory::<4>::new_moving(p, &far, v, a).err(), Some(TrajectoryError::BadStartState));
    }
    assert_eq!(
        Trajectory::<4>::new_moving(p, &[v3(1.0, 2.0, 3.0)], 1.0, 0.0).err(),
        Some(TrajectoryError::BadStartState)
    );
}

#[test]
fn the_trajectory_fits_the_flight_controllers_ram() {
    // The guidance keeps one in the outer stage's static state (module docs: 3,540 bytes).
    let size = core::mem::size_of::<Trajectory<64>>();
    assert!(size <= 3_600, "Trajectory<64> is {size} bytes");
}

/// The speed cap is absolute: through a 90° corner whose limit is below the cruise speed the
/// reference flies at the cap where the path allows it, never above it, and a corner slower
/// than the cap still gets its own limit — not the cap scaled by the corner's ratio to the
/// cruise (what scaling the clock by cap/cruise did: 5 m/s missions slower than 3 m/s ones).
#[test]
fn a_speed_cap_bounds_the_speed_without_scaling_the_corners() {
    let d = TrajectoryParams::default();
    let pts = [v3(0.0, 0.0, -1.0), v3(20.0, 0.0, -1.0), v3(20.0, 20.0, -1.0)];
    let cap = 2.0f32;
    for cruise in [3.0f32, 5.0, 8.0] {
        let p = TrajectoryParams { cruise_speed: cruise, ..d };
        let mut t: Trajectory<4> = Trajectory::new(p, &pts).unwrap();
        let (mut top, mut corner_min, mut done) = (0.0f32, f32::INFINITY, false);
        for _ in 0..100_000 {
            let s = t.step_capped(DT, 1.0, cap).unwrap();
            top = top.max(s.speed);
            if (s.position - pts[1]).norm() < 1.5 {
                corner_min = corner_min.min(s.speed);
            }
            if s.done {
                done = true;
                break;
            }
        }
        assert!(done, "cruise {cruise}");
        assert!(top <= cap + 1e-4 && top > cap - 1e-3, "cruise {cruise}: top {top}");
        // The same corner without a cap: its own limit is below the cap, so the capped
        // reference flies it as fast (scaling by cap/cruise would give cap/cruise of it).
        let mut free: Trajectory<4> = Trajectory::new(p, &pts).unwrap();
        let mut free_min = f32::INFINITY;
        for _ in 0..100_000 {
            let s = free.step(DT, 1.0).unwrap();
            if (s.position - pts[1]).norm() < 1.5 {
                free_min = free_min.min(s.speed);
            }
            if s.done {
                break;
            }
        }
        assert!(free_min < cap, "the corner is slower than the cap: {free_min}");
        // (scaled: at most cap/cruise ≤ 2/3 of it; the capped one arrives slower and brakes less.)
        assert!(corner_min >= 0.9 * free_min, "cruise {cruise}: corner {corner_min}, free {free_min}");
    }
    let mut t: Trajectory<4> = Trajectory::new(d, &pts).unwrap();
    assert_eq!(t.step_capped(DT, 1.0, f32::NAN), Err(TrajectoryError::BadClockScale));
    // A negative cap brakes like 0: from rest, nothing moves.
    let s = t.step_capped(DT, 1.0, -1.0).unwrap();
    assert!(s.speed <= 1e-6);
}
