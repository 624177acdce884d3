//! Path lengths, the default duration limit of a run and the distance to the ground (moved out
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
/// figure.
pub fn default_duration(scene: &Scene, path: &[Vector3<f64>], speed: f64) -> f64 {
    1.5 * flown_length(&scene.start, path) / speed.min(DURATION_PACE) + 15.0
}

/// The fastest pace the default duration limit assumes, m/s ([`default_duration`]).
pub const DURATION_PACE: f64 = 1.0;

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
