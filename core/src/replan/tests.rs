//! Hand-checkable replanning cases: a wall with one gap, no gap, a waypoint inside an
//! obstacle, the expansion cap, the trigger's rate and cooldown.

use super::*;

const Z: f32 = -1.0;
const HULL: f32 = 0.22;

fn v(x: f32, y: f32) -> Vec3 {
    Vec3::new(x, y, Z)
}

/// Static points every 0.1 m along x = `x` for y in [y0, y1] (m).
fn wall(x: f32, y0: f32, y1: f32, out: &mut heapless::Vec<ObstaclePoint, 512>) {
    let n = ((y1 - y0) / 0.1) as i32;
    for k in 0..=n {
        let _ = out.push(ObstaclePoint::fixed(v(x, y0 + 0.1 * k as f32), 1));
    }
}

/// Static points every 0.1 m along y = `y` for x in [x0, x1] (m).
fn wall_x(y: f32, x0: f32, x1: f32, out: &mut heapless::Vec<ObstaclePoint, 512>) {
    let n = ((x1 - x0) / 0.1) as i32;
    for k in 0..=n {
        let _ = out.push(ObstaclePoint::fixed(v(x0 + 0.1 * k as f32, y), 1));
    }
}

/// Smallest distance (x, y) from the segments of `path` (from `start`) to the points.
fn clearance(start: &Vec3, path: &[Vec3], pts: &[ObstaclePoint]) -> f32 {
    let mut a = *start;
    let mut best = f32::INFINITY;
    for b in path {
        for o in pts {
            let (ab, ap) = ((b - a).xy(), (o.point - a).xy());
            let t =
                if ab.norm_squared() > 0.0 { (ap.dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0) } else { 0.0 };
            best = best.min((ap - ab * t).norm());
        }
        a = *b;
    }
    best
}

fn on() -> ReplanParams {
    ReplanParams { enable: true, ..ReplanParams::default() }
}

fn replanner_with(pts: &[ObstaclePoint], at: &Vec3) -> Replanner {
    let mut r = Replanner::new(on(), HULL);
    r.observe(at, pts);
    r
}

#[test]
fn a_wall_with_one_gap_is_passed_through_the_gap() {
    // Wall across x = 2 from y = -3 to 3 with a 1.2 m gap at y 1.4..2.6; mission straight on.
    let mut pts = heapless::Vec::new();
    wall(2.1, -3.0, 1.3, &mut pts);
    wall(2.1, 2.7, 3.0, &mut pts);
    let (at, goal) = (v(0.1, 0.1), v(4.1, 0.1));
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    let res = r.plan(&at, &at, &[goal], &pts, false, &mut out);
    assert!(matches!(res, ReplanOutcome::Replanned { .. }), "{res:?}");
    assert_eq!(out.last(), Some(&goal), "the rest of the mission follows: {out:?}");
    // Through the gap: a waypoint near it, and every leg clear of the wall by hull + margin
    // less the grid's rounding (half a cell diagonal).
    assert!(out.iter().any(|w| (1.4..=2.6).contains(&w.y)), "{out:?}");
    let c = clearance(&at, &out, &pts);
    assert!(c >= HULL + 0.1 - 0.15, "clearance {c} of {out:?}");
    // A detour of two or three line-of-sight legs, not one per cell.
    assert!(out.len() <= 4, "{out:?}");
    assert!(out.iter().all(|w| w.z == Z));
    assert_eq!(r.stats().replans, 1);
}

#[test]
fn a_wall_without_a_gap_is_no_path() {
    let mut pts = heapless::Vec::new();
    wall(2.1, -7.0, 7.0, &mut pts);
    let at = v(0.1, 0.1);
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    assert_eq!(r.plan(&at, &at, &[v(4.1, 0.1), v(5.1, 0.1)], &pts, false, &mut out), ReplanOutcome::NoPath);
    assert!(out.is_empty());
    assert_eq!((r.stats().no_path, r.stats().replans), (1, 0));
}

#[test]
fn a_clear_path_needs_no_plan_and_a_far_blockage_waits() {
    let mut pts = heapless::Vec::new();
    wall(5.1, -3.0, 3.0, &mut pts);
    let at = v(0.1, 0.1);
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    assert_eq!(
        r.plan(&at, &at, &[v(3.1, 0.1), v(3.0, 3.0)], &pts, false, &mut out),
        ReplanOutcome::NotNeeded
    );
    // The wall 5 m ahead is beyond the 3 m horizon; with an unlimited horizon it is planned round.
    assert_eq!(r.plan(&at, &at, &[v(6.1, 0.1)], &pts, false, &mut out), ReplanOutcome::NotNeeded);
    assert!(matches!(
        r.plan(&at, &at, &[v(6.1, 0.1)], &pts, true, &mut out),
        ReplanOutcome::Replanned { .. }
    ));
}

#[test]
fn a_path_over_a_table_or_past_a_door_edge_is_clear() {
    // A table top 0.25 m below the path (within the 0.3 m band: the grid marks it) and a door
    // post 0.25 m beside it (its cell's centre closer): the planner's clearance (hull + 0.05 m)
    // holds in 3D, so nothing is replanned.
    let mut pts: heapless::Vec<ObstaclePoint, 512> = heapless::Vec::new();
    for k in 0..10 {
        let _ = pts.push(ObstaclePoint::fixed(Vec3::new(1.0 + 0.1 * k as f32, 0.1, Z + 0.25), 1));
    }
    let _ = pts.push(ObstaclePoint::fixed(v(2.5, 0.35), 2));
    let at = v(0.1, 0.1);
    let mut r = replanner_with(&pts, &at);
    assert!(r.grid().occupied_count() >= 5, "the table is in the grid");
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    assert_eq!(r.plan(&at, &at, &[v(3.1, 0.1)], &pts, false, &mut out), ReplanOutcome::NotNeeded);
    // 0.15 m below the path: within the hull radius, blocked.
    let _ = pts.push(ObstaclePoint::fixed(Vec3::new(1.5, 0.1, Z + 0.15), 3));
    let res = r.plan(&at, &at, &[v(3.1, 0.1)], &pts, false, &mut out);
    assert_ne!(res, ReplanOutcome::NotNeeded);
}

/// The two false triggers of the mapped office (docs/perception.md § On-board replanning):
/// the check walks the path from the guidance's reference, not the line from a vehicle pushed
/// off the path (truth seed 4 at 1 m/s cut a door corner that way: 6 replans, 5 no-path, no
/// goal); and a memory point up to half a voxel nearer than the surface the planner kept
/// hull + 0.05 m from ([`POINT_SLACK_M`]) is no blockage.
#[test]
fn a_vehicle_off_its_path_or_a_conservative_memory_point_is_no_blockage() {
    // A door edge at (2.0, 0.5); the path runs along y = 0.2 (0.3 m from it: clear).
    let edge = [ObstaclePoint::fixed(v(2.0, 0.5), 1)];
    let (reference, vehicle, next) = (v(1.0, 0.2), v(1.0, 0.6), v(3.0, 0.2));
    let mut r = replanner_with(&edge, &vehicle);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    // From the vehicle, 0.4 m off the path, the straight line to the next waypoint passes
    // 0.06 m from the edge; the path itself does not.
    assert_eq!(r.plan(&vehicle, &reference, &[next], &edge, false, &mut out), ReplanOutcome::NotNeeded);
    assert_ne!(r.plan(&vehicle, &vehicle, &[next], &edge, false, &mut out), ReplanOutcome::NotNeeded);
    // A point 0.19 m from the path (the planner's 0.27 m less a memory cell's 0.08 m): clear;
    // 0.15 m: blocked.
    let at = v(0.1, 0.2);
    for (d, blocked) in [(HULL - 0.03, false), (HULL - POINT_SLACK_M - 0.02, true)] {
        let p = [ObstaclePoint::fixed(v(2.0, 0.2 + d), 1)];
        let mut r = replanner_with(&p, &at);
        let res = r.plan(&at, &at, &[next], &p, false, &mut out);
        assert_eq!(res != ReplanOutcome::NotNeeded, blocked, "point {d} m from the path: {res:?}");
    }
}

#[test]
fn a_waypoint_inside_an_obstacle_is_skipped_for_the_next_reachable_one() {
    // A closed room (2 m square walls) around the first waypoint: the first free point beyond
    // the blockage is inside the room, unreachable; the next waypoint, outside, is the target.
    let mut pts = heapless::Vec::new();
    wall(2.1, -1.0, 1.0, &mut pts);
    wall(4.1, -1.0, 1.0, &mut pts);
    wall_x(-0.9, 2.1, 4.1, &mut pts);
    wall_x(1.1, 2.1, 4.1, &mut pts);
    let at = v(0.1, 0.1);
    let (inside, after) = (v(3.1, 0.1), v(6.1, 0.1));
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    let res = r.plan(&at, &at, &[inside, after], &pts, false, &mut out);
    assert!(matches!(res, ReplanOutcome::Replanned { .. }), "{res:?}");
    assert!(!out.contains(&inside), "{out:?}");
    assert_eq!(out.last(), Some(&after));
    assert!(clearance(&at, &out, &pts) >= HULL);
    // The farthest waypoint (inside the room) is tried first, cannot be reached, and the
    // nearer one is the target; the rest of the mission follows it.
    let res = r.plan(&at, &at, &[after, inside], &pts, false, &mut out);
    assert!(matches!(res, ReplanOutcome::Replanned { .. }), "{res:?}");
    assert_eq!(&out[out.len() - 2..], &[after, inside]);
}

#[test]
fn the_expansion_cap_is_a_defined_result() {
    let mut pts = heapless::Vec::new();
    wall(2.1, -3.0, 1.3, &mut pts);
    wall(2.1, 2.7, 3.0, &mut pts);
    let at = v(0.1, 0.1);
    let mut r = Replanner::new(ReplanParams { max_expansions: 10, ..on() }, HULL);
    r.observe(&at, &pts);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    assert_eq!(r.plan(&at, &at, &[v(4.1, 0.1)], &pts, false, &mut out), ReplanOutcome::BudgetExceeded);
    assert!(out.is_empty());
    // A path that would not fit the capacity: the same result, nothing written.
    let mut r = replanner_with(&pts, &at);
    let mut small: heapless::Vec<Vec3, 2> = heapless::Vec::new();
    assert_eq!(
        r.plan(&at, &at, &[v(4.1, 0.1), v(5.1, 0.1)], &pts, false, &mut small),
        ReplanOutcome::BudgetExceeded
    );
    assert!(small.is_empty());
}

#[test]
fn the_trigger_keeps_its_rate_and_cooldown() {
    let mut pts = heapless::Vec::new();
    wall(2.1, -3.0, 1.3, &mut pts);
    wall(2.1, 2.7, 3.0, &mut pts);
    let at = v(0.1, 0.1);
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    let path = [v(4.1, 0.1)];
    assert!(matches!(
        r.step(0, &at, &at, false, &path, &pts, &mut out),
        Some(ReplanOutcome::Replanned { .. })
    ));
    // Cooldown 2 s: nothing until then, whatever the path.
    assert_eq!(r.step(1_999_999, &at, &at, false, &path, &pts, &mut out), None);
    assert!(r.step(2_000_000, &at, &at, false, &path, &pts, &mut out).is_some());
    // A clear path is checked again after 1 / rate = 0.5 s.
    let mut clear = Replanner::new(on(), HULL);
    assert_eq!(clear.step(0, &at, &at, false, &path, &[], &mut out), Some(ReplanOutcome::NotNeeded));
    assert_eq!(clear.step(499_999, &at, &at, false, &path, &[], &mut out), None);
    assert_eq!(clear.step(500_000, &at, &at, false, &path, &[], &mut out), Some(ReplanOutcome::NotNeeded));
    // Off: never.
    let mut off = Replanner::new(ReplanParams { enable: false, ..on() }, HULL);
    off.observe(&at, &pts);
    assert_eq!(off.step(0, &at, &at, true, &path, &pts, &mut out), None);
}

/// The wall of [`wall`] with its points handed out by an obstacle memory (static cells).
fn sensed(pts: &[ObstaclePoint], dy: f32) -> heapless::Vec<ObstaclePoint, 512> {
    pts.iter().map(|o| ObstaclePoint::fixed(o.point + Vec3::new(0.0, dy, 0.0), STATIC_ID)).collect()
}

#[test]
fn a_sensed_blockage_is_planned_around_once_it_stood_still_for_the_dwell() {
    // The wall with a gap, its points sensed: checks every 0.5 s find the blockage, and the
    // plan waits until it has stood for RPL_DWELL (4 s by default).
    let mut mapped = heapless::Vec::new();
    wall(2.1, -3.0, 1.3, &mut mapped);
    wall(2.1, 2.7, 3.0, &mut mapped);
    let pts = sensed(&mapped, 0.0);
    let at = v(0.1, 0.1);
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    let path = [v(4.1, 0.1)];
    let dwell_us = (ReplanParams::default().dwell_s * 1e6) as u64;
    // The vehicle closes in, 0.16 m per check (more than STUCK_M: not stalled).
    let (mut t, mut x) = (0, at);
    while t < dwell_us {
        assert_eq!(r.step(t, &x, &x, false, &path, &pts, &mut out), Some(ReplanOutcome::NotNeeded), "{t} µs");
        assert!(out.is_empty());
        t += 500_000;
        x.x += 0.16;
    }
    assert!(matches!(r.step(t, &x, &x, false, &path, &pts, &mut out), Some(ReplanOutcome::Replanned { .. })));
    // The same wall from a map (ids below the memory's): at once.
    let mut m = replanner_with(&mapped, &at);
    assert!(matches!(
        m.step(0, &at, &at, false, &path, &mapped, &mut out),
        Some(ReplanOutcome::Replanned { .. })
    ));
    // A stall is not confirmed either: planned at once.
    let mut s = replanner_with(&pts, &at);
    assert!(matches!(
        s.step(0, &at, &at, true, &path, &pts, &mut out),
        Some(ReplanOutcome::Replanned { .. })
    ));
}

#[test]
fn a_blockage_that_keeps_moving_is_never_planned_around() {
    // A sensed post (0.2 m wide) that moves 0.5 m sideways between checks (1 m/s; its points
    // never within STILL_M of where they were a check before): the wait restarts at every
    // check, no plan.
    let mut mapped = heapless::Vec::new();
    wall(2.1, -0.1, 0.1, &mut mapped);
    let at = v(0.1, 0.1);
    let mut r = Replanner::new(on(), HULL);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    let path = [v(4.1, 0.1)];
    for k in 0..40u64 {
        // Back and forth across the path.
        let dy = if k % 2 == 0 { 0.0 } else { 0.5 };
        let pts = sensed(&mapped, dy);
        // The vehicle moves back and forth too (not stalled).
        let x = v(0.1 + 0.2 * (k % 2) as f32, 0.1);
        r.observe(&x, &pts);
        assert_eq!(
            r.step(k * 500_000, &x, &x, false, &path, &pts, &mut out),
            Some(ReplanOutcome::NotNeeded),
            "check {k}"
        );
    }
    // With RPL_DWELL 0 the first check plans.
    let mut now = Replanner::new(ReplanParams { dwell_s: 0.0, ..on() }, HULL);
    let pts = sensed(&mapped, 0.0);
    now.observe(&at, &pts);
    assert!(matches!(
        now.step(0, &at, &at, false, &path, &pts, &mut out),
        Some(ReplanOutcome::Replanned { .. })
    ));
}

#[test]
fn a_stall_in_a_passage_the_planner_threaded_is_no_blockage_a_crate_in_it_is() {
    // A 4 m passage along x with walls 0.3 m either side of the path (the offline planner's
    // clearance is hull + 0.05 = 0.27 m; the inflation radius hull + margin = 0.32 m).
    let mut pts = heapless::Vec::new();
    wall_x(0.4, 0.0, 4.0, &mut pts);
    wall_x(-0.2, 0.0, 4.0, &mut pts);
    let (at, goal) = (v(0.5, 0.1), v(4.1, 0.1));
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    // Stalled (wind, the filter): the path is not blocked, nothing to plan.
    assert_eq!(r.plan(&at, &at, &[goal], &pts, true, &mut out), ReplanOutcome::NotNeeded);
    // A crate across the passage at x = 2.1: blocked (no way round inside it).
    let _ = pts.push(ObstaclePoint::fixed(v(2.1, 0.1), 1));
    let mut r = replanner_with(&pts, &at);
    assert_ne!(r.plan(&at, &at, &[goal], &pts, true, &mut out), ReplanOutcome::NotNeeded);
}

#[test]
fn moving_points_and_points_off_the_flight_level_are_not_marked() {
    let mut r = Replanner::new(ReplanParams::default(), HULL);
    let at = v(0.1, 0.1);
    let walker =
        ObstaclePoint { point: v(1.0, 0.0), velocity: Some(Vec3::new(0.5, 0.0, 0.0)), id: 2, normal: None };
    let low = ObstaclePoint::fixed(Vec3::new(1.0, 0.0, Z + 1.0), 3);
    r.observe(&at, &[walker, low]);
    assert_eq!(r.grid().occupied_count(), 0);
    r.observe(&at, &[ObstaclePoint::fixed(v(1.0, 0.0), 4)]);
    assert_eq!(r.grid().occupied_count(), 1);
}

#[test]
fn the_flight_area_closes_the_way_round() {
    // A 4 m wall across the path: round its ends without an area, no path inside a 4.4 m wide one.
    let mut pts = heapless::Vec::new();
    wall(2.1, -2.0, 2.0, &mut pts);
    let at = v(0.1, 0.1);
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    assert!(matches!(
        r.plan(&at, &at, &[v(4.1, 0.1)], &pts, false, &mut out),
        ReplanOutcome::Replanned { .. }
    ));
    assert!(out.iter().any(|w| w.y.abs() > 2.0), "{out:?}");
    r.set_area(Some(([-1.0, -2.2], [5.0, 2.2])));
    assert_eq!(r.plan(&at, &at, &[v(4.1, 0.1)], &pts, false, &mut out), ReplanOutcome::NoPath);
}

/// Static points every 0.1 m along x = `x` for y in [y0, y1] and every 0.2 m in NED z over
/// [z0, z1] (m): a wall (or the side of a box) of that height.
fn wall_3d(x: f32, (y0, y1): (f32, f32), (z0, z1): (f32, f32), out: &mut heapless::Vec<ObstaclePoint, 2048>) {
    let (ny, nz) = (((y1 - y0) / 0.1 + 0.5) as i32, ((z1 - z0) / 0.2 + 0.5) as i32);
    for k in 0..=ny {
        for m in 0..=nz {
            let _ = out.push(ObstaclePoint::fixed(Vec3::new(x, y0 + 0.1 * k as f32, z0 + 0.2 * m as f32), 1));
        }
    }
}

/// A wall across x = 2.1 (floor to 2.5 m, beyond the grid's ends) with a 1.2 m gap at y 1.4..2.6 that a box 1.3 m
/// tall fills (a printer in a door); the vehicle at 1 m, the mission straight through the wall
/// at its height, then climbing to 1.8 m beyond it (the heights the remaining path flies).
fn door_with_a_printer() -> (heapless::Vec<ObstaclePoint, 2048>, [Vec3; 3]) {
    let mut pts = heapless::Vec::new();
    wall_3d(2.1, (-7.0, 1.3), (-2.5, -0.1), &mut pts);
    wall_3d(2.1, (2.7, 7.0), (-2.5, -0.1), &mut pts);
    wall_3d(2.1, (1.4, 2.6), (-1.3, -0.1), &mut pts);
    let path = [v(3.1, 0.1), Vec3::new(3.1, 2.0, -1.8), v(4.1, 2.0)];
    (pts, path)
}

#[test]
fn a_door_closed_at_the_flight_level_is_passed_at_a_level_the_path_flies() {
    let (pts, path) = door_with_a_printer();
    let at = v(0.1, 0.1);
    let mut r = replanner_with(&pts, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    // At the vehicle's height the printer closes the gap: no 2-D path there.
    let mut flat = Replanner::new(on(), HULL);
    flat.observe(&at, &pts);
    let mut flat_out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    let flat_path = [v(3.1, 0.1), v(4.1, 2.0)];
    assert_eq!(flat.plan(&at, &at, &flat_path, &pts, false, &mut flat_out), ReplanOutcome::NoPath);
    // The remaining path climbs to 1.8 m beyond the wall: the plan at that level passes over
    // the printer through the gap and rejoins the mission where it flies at 1.8 m.
    let res = r.plan(&at, &at, &path, &pts, false, &mut out);
    assert!(matches!(res, ReplanOutcome::Replanned { .. }), "{res:?}");
    assert_eq!(&out[out.len() - 2..], &path[1..], "{out:?}");
    // The vehicle climbs where it stands, then flies at 1.8 m.
    assert_eq!(out[0], Vec3::new(at.x, at.y, -1.8), "{out:?}");
    assert!(out[..out.len() - 1].iter().all(|w| w.z == -1.8), "{out:?}");
    // The leg across the wall's line lies in the gap (y 1.4..2.6 less the clearance).
    for leg in out.windows(2) {
        let (a, b) = (leg[0], leg[1]);
        if (a.x - 2.1) * (b.x - 2.1) < 0.0 {
            let y = a.y + (b.y - a.y) * (2.1 - a.x) / (b.x - a.x);
            assert!((1.4 + HULL..=2.6 - HULL).contains(&y), "crosses the wall at y {y}: {out:?}");
        }
    }
}

#[test]
fn a_column_blocked_above_the_vehicle_is_not_climbed_through() {
    let (mut pts, path) = door_with_a_printer();
    let at = v(0.1, 0.1);
    // A shelf 0.4 m above the vehicle, 0.6 m to its side: the climb is clear.
    let mut side = pts.clone();
    wall_3d(0.1, (0.7, 1.0), (-1.4, -1.4), &mut side);
    let mut r = replanner_with(&side, &at);
    let mut out: heapless::Vec<Vec3, 64> = heapless::Vec::new();
    let res = r.plan(&at, &at, &path, &side, false, &mut out);
    assert!(matches!(res, ReplanOutcome::Replanned { .. }), "{res:?}");
    // The same shelf over the vehicle: no climb there, and at its own height the printer
    // closes the gap: no path (the vehicle does not climb through the shelf).
    wall_3d(0.1, (-0.3, 0.4), (-1.4, -1.4), &mut pts);
    let mut r = replanner_with(&pts, &at);
    let res = r.plan(&at, &at, &path, &pts, false, &mut out);
    assert_eq!(res, ReplanOutcome::NoPath, "{out:?}");
}
