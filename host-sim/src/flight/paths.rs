//! Path lengths, the default duration limit of a run and its progress watchdog, and the distance to the ground (moved out
//! of [`super::runner`], which re-exports the public ones).
//!
//! May import: [`crate::world`] (the scene's start).

use nalgebra::Vector3;

use crate::world::scene::Scene;

/// Length of a polyline, m.
pub fn path_length(path: &[Vector3<f64>]) -> f64 {
    path.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// Length of what is flown, m: from the mission start (where the vehicle
/// hovers at t = 0) to the first waypoint, then along the path.
pub fn flown_length(start: &Vector3<f64>, path: &[Vector3<f64>]) -> f64 {
    path.first().map_or(0.0, |w| (w - start).norm()) + path_length(path)
}

/// Default duration limit, s: 1.5 × the flown length ([`flown_length`]) at `speed` (m/s), but
/// at no more than [`DURATION_PACE`], + 15 s for the start-up and the settling at the end. The
/// limit is a watchdog for a stuck run, not a target: at a cruise of metres per second the
/// corners, the doors and the safety filter set the pace (the office's path takes ≈ 22 s at
/// any cruise from 1 to 5 m/s), so a faster cruise does not shorten it below the walking-pace
/// figure; a run still making progress at it goes on ([`ProgressWatchdog`]).
pub fn default_duration(scene: &Scene, path: &[Vector3<f64>], speed: f64) -> f64 {
    1.5 * flown_length(&scene.start, path) / speed.min(DURATION_PACE) + 15.0
}

/// The fastest pace the default duration limit assumes, m/s ([`default_duration`]).
pub const DURATION_PACE: f64 = 1.0;

/// The default limit's watchdog goes on this long after the vehicle last made progress, s
/// ([`ProgressWatchdog`]; the rule's own allowance for the start-up and the settling).
pub const STALL_WINDOW_S: f64 = 15.0;
/// Progress: the path left to fly ([`remaining_length`]) fell this much below its smallest
/// value so far, m (a vehicle held in front of an obstacle, shaking, makes none).
pub const PROGRESS_STEP_M: f64 = 0.25;
/// A run under the default limit ends at this multiple of it at the latest.
pub const EXTEND_FACTOR: f64 = 4.0;

/// The watchdog of the default duration limit ([`default_duration`]; `RunConfig`'s
/// `default_duration_s`): a run that still makes progress at the limit goes on, and
/// ends [`STALL_WINDOW_S`] after its last progress, at [`EXTEND_FACTOR`] × the limit at the
/// latest. The limit assumes a pace ([`DURATION_PACE`]); with range sensors the safety side
/// sets a slower one in clutter (the speed governor and the filter hold the vehicle while it
/// sees its way), and a vehicle that is still getting there is not a stuck run. A run that
/// made no progress in the last [`STALL_WINDOW_S`] before the limit ends at the limit, as
/// before the watchdog existed; one given a duration (`--duration`, `[sim] duration`) ends
/// at it. A new path from the stack's on-board replanner ([`ProgressWatchdog::new_path`])
/// counts as progress and restarts the measure: a detour (along a wall to another door) may
/// lead away from the mission's path before it leads on, and the stack is still finding its
/// way (a stack replanning without end still ends at the cap).
#[derive(Clone, Copy, Debug)]
pub struct ProgressWatchdog {
    best: f64,
    last_progress_s: f64,
}

impl Default for ProgressWatchdog {
    fn default() -> Self {
        ProgressWatchdog { best: f64::INFINITY, last_progress_s: 0.0 }
    }
}

impl ProgressWatchdog {
    /// The path left to fly at time `t` (s) is `remaining` (m).
    pub fn observe(&mut self, t: f64, remaining: f64) {
        if remaining.is_finite() && (self.best.is_infinite() || remaining < self.best - PROGRESS_STEP_M) {
            self.best = remaining;
            self.last_progress_s = t;
        }
    }

    /// The stack flies a new path from time `t` (s; an on-board replan): progress, and the
    /// path left is measured afresh from the next observation.
    pub fn new_path(&mut self, t: f64) {
        self.best = f64::INFINITY;
        self.last_progress_s = t;
    }

    /// When a run with the default limit `base` (s) ends, s.
    pub fn end(&self, base: f64) -> f64 {
        base.max(self.last_progress_s + STALL_WINDOW_S).min(base * EXTEND_FACTOR)
    }
}

/// The length of the flown polyline (`start`, then `path`) left after the point of it nearest
/// to `p`, m (the first nearest point on a tie). O(waypoints).
pub fn remaining_length(start: &Vector3<f64>, path: &[Vector3<f64>], p: &Vector3<f64>) -> f64 {
    let mut best = (f64::INFINITY, 0.0);
    let mut prev = *start;
    let mut after = flown_length(start, path);
    for w in path {
        let seg = w - prev;
        let len = seg.norm();
        let u = if len > 0.0 { ((p - prev).dot(&seg) / (len * len)).clamp(0.0, 1.0) } else { 0.0 };
        let d = (prev + seg * u - p).norm();
        if d < best.0 {
            best = (d, after - u * len);
        }
        after -= len;
        prev = *w;
    }
    best.1.max(0.0)
}

/// Signed distance (m) from `p` (NED) to the nearest obstacle surface or the
/// ground plane (z = 0) at time `t`, and the obstacle index (`None` = ground).
pub fn nearest_with_ground(scene: &Scene, p: &Vector3<f64>, t: f64) -> (f64, Option<usize>) {
    with_ground(scene.nearest(p, t), p)
}

/// [`with_ground`], or the obstacles alone in a ground station's flight (`ground`: resting on,
/// taking off from and landing on the ground is no collision there).
pub(super) fn contact(ground: bool, nearest: (f64, Option<usize>), p: &Vector3<f64>) -> (f64, Option<usize>) {
    if ground {
        nearest
    } else {
        with_ground(nearest, p)
    }
}

/// [`nearest_with_ground`] from the obstacles' `(distance, index)` at `p`.
pub(super) fn with_ground(nearest: (f64, Option<usize>), p: &Vector3<f64>) -> (f64, Option<usize>) {
    let ground = -p.z;
    if ground < nearest.0 {
        (ground, None)
    } else {
        nearest
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_remaining_length_is_measured_from_the_nearest_point_of_the_flown_path() {
        let start = Vector3::new(0.0, 0.0, 1.0);
        // start → (2, 0) → (2, 3): 5 m.
        let path = [Vector3::new(2.0, 0.0, 1.0), Vector3::new(2.0, 3.0, 1.0)];
        let at = |x: f64, y: f64| remaining_length(&start, &path, &Vector3::new(x, y, 1.0));
        assert!((at(0.0, 0.0) - 5.0).abs() < 1e-12);
        assert!((at(1.0, 0.4) - 4.0).abs() < 1e-12, "beside the first leg");
        assert!((at(2.5, 1.0) - 2.0).abs() < 1e-12, "beside the second leg");
        assert!(at(2.0, 9.0).abs() < 1e-12, "past the end");
        assert!((at(-3.0, 0.0) - 5.0).abs() < 1e-12, "behind the start");
        assert!((remaining_length(&start, &[], &start)).abs() < 1e-12);
    }

    #[test]
    fn the_watchdog_ends_a_run_a_window_after_its_last_progress_within_the_cap() {
        let base = 40.0;
        let mut w = ProgressWatchdog::default();
        assert_eq!(w.end(base), base, "no progress: the limit");
        w.observe(0.0, 10.0);
        assert_eq!(w.end(base), base);
        // Progress at 35 s: 15 s more than that.
        w.observe(35.0, 9.0);
        assert_eq!(w.end(base), 35.0 + STALL_WINDOW_S);
        // Less than PROGRESS_STEP_M below the best, or back up: no progress.
        w.observe(45.0, 9.0 - 0.5 * PROGRESS_STEP_M);
        w.observe(46.0, 12.0);
        assert_eq!(w.end(base), 35.0 + STALL_WINDOW_S);
        // Never beyond the cap.
        w.observe(170.0, 1.0);
        assert_eq!(w.end(base), EXTEND_FACTOR * base);
        w.observe(171.0, f64::NAN);
        assert_eq!(w.end(base), EXTEND_FACTOR * base);
        // A new path (a replan): progress at once, and a path left that grew (the detour
        // leads away first) is the new measure.
        let mut w = ProgressWatchdog::default();
        w.observe(0.0, 10.0);
        w.observe(20.0, 8.0);
        w.new_path(30.0);
        assert_eq!(w.end(base), 30.0 + STALL_WINDOW_S);
        w.observe(31.0, 11.0);
        w.observe(40.0, 11.0 - 2.0 * PROGRESS_STEP_M);
        assert_eq!(w.end(base), 40.0 + STALL_WINDOW_S);
    }
}
