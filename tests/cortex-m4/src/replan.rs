//! Instruction counts of one on-board replan (issue 38, `parapet_core::replan`; the firmware's
//! replanner task serves one request per `RPL_RATE` period, `firmware/src/app/replanner.rs`):
//! `Replanner::serve` (mark the request's points in the grid, the trigger along the remaining
//! path, the A* searches, the line-of-sight simplification), default `RPL_*` parameters
//! (cell 0.2 m, 64 × 64 cells, ≤ 4096 expansions per search, ≤ 4 targets), hull 0.2236 m.
//!
//! * **typical**: the two-door world (`scenes/two_doors_blocked.toml`, in NED): a wall 2 m
//!   ahead across the grid, the planned door blocked, the open door 2.5 m to the side — one
//!   search finds the detour;
//! * **worst**: the remaining path ends inside a closed ring of points: every target
//!   (`MAX_TARGETS` = 4) is unreachable, so each search expands every cell it can reach
//!   outside the ring (the whole grid but the ring's inside) before it gives up: four full
//!   searches, the most one plan does (a search's cap, 4096 expansions, is the whole grid).
//!
//! Each case is measured once per call on a fresh planner (a plan has state: grid, cooldown).

use core::fmt::Write;

use parapet_core::config::DEFAULT_HULL_RADIUS;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::outer::guidance::PATH_CAPACITY;
use parapet_core::replan::onboard::ReplanRequest;
use parapet_core::replan::{ReplanParams, Replanner};
use parapet_core::Vec3;

use super::{Console, Counter, REPS};

/// Flight level, NED z, m.
const Z: f32 = -1.2;

fn point(x: f32, y: f32, id: u16) -> ObstaclePoint {
    ObstaclePoint { point: Vec3::new(x, y, Z), velocity: None, id, normal: None }
}

/// A request at the origin flying `path` among `points` (at most the request's capacity).
fn request(path: &[Vec3], points: impl Iterator<Item = ObstaclePoint>) -> ReplanRequest {
    let mut r = ReplanRequest::new();
    r.params = ReplanParams { enable: true, ..ReplanParams::DEFAULT };
    r.hull = DEFAULT_HULL_RADIUS;
    r.t_us = 1_000_000;
    r.position = Vec3::new(0.0, 0.0, Z);
    // The guidance's reference, where the path check starts: on the vehicle here.
    r.reference = r.position;
    let _ = r.remaining.extend_from_slice(&path[..path.len().min(PATH_CAPACITY)]);
    for p in points {
        if r.points.push(p).is_err() {
            break;
        }
    }
    r
}

/// The two-door wall at x = 2 m (door B open at y ∈ [2, 3] m; door A, on the path, blocked):
/// the 32 points nearest the vehicle, as the filter's set would hold them.
fn two_doors() -> ReplanRequest {
    let mut wall: heapless::Vec<ObstaclePoint, 128> = heapless::Vec::new();
    for k in 0..100u16 {
        let y = -5.0 + 0.1 * f32::from(k);
        if !(2.0..=3.0).contains(&y) {
            let _ = wall.push(point(2.0, y, k));
        }
    }
    wall.sort_unstable_by(|a, b| a.point.y.abs().total_cmp(&b.point.y.abs()));
    request(&[Vec3::new(6.0, 0.0, Z)], wall.into_iter())
}

/// The path's last waypoints inside a closed ring of radius 1 m around (4, 0): 32 points.
fn enclosed() -> ReplanRequest {
    let path =
        [Vec3::new(3.8, 0.0, Z), Vec3::new(4.0, 0.0, Z), Vec3::new(4.2, 0.0, Z), Vec3::new(4.2, 0.2, Z)];
    let ring = (0..32u16).map(|k| {
        let a = f32::from(k) * core::f32::consts::TAU / 32.0;
        point(4.0 + libm::cosf(a), libm::sinf(a), k)
    });
    request(&path, ring)
}

pub(crate) fn bench_replan(c: &Counter) {
    for (name, make) in
        [("typical (two doors)", two_doors as fn() -> ReplanRequest), ("worst (enclosed goal)", enclosed)]
    {
        let mut req = make();
        let mut planner = Replanner::new(req.params, req.hull);
        let ins = c.measure_once(|| planner.serve(&mut req)) / REPS as u64;
        let _ = writeln!(
            Console,
            "replan {name}: {ins} instructions, outcome {:?}, {} waypoints",
            req.outcome,
            req.path.len()
        );
    }
}
