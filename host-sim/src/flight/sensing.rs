//! What the closed loop tells the controller about obstacles in ground-truth mode, and the
//! true barrier it is judged by: the proximity report ([`sense_obstacles`], closest surface
//! point and velocity of every obstacle within the sensing range, bounded by
//! [`bound_report`]), the true `h̄` ([`true_h_bar`]), and both in one pass at the outer
//! rate ([`sense_and_h_bar`], same results bit for bit, obstacles that provably cannot
//! matter skipped through the vehicle's [`NearestTracker`]). Split out of [`super::runner`]
//! (which re-exports these names) as its own concern.
//!
//! With a filtered position source the report is given in the frame of the vehicle's
//! estimate ([`to_estimate_frame`], issue 39).
//!
//! Owns: [`OuterScratch`], [`true_h_bar`], [`sense_and_h_bar`], [`sense_obstacles`],
//! [`bound_report`], [`to_estimate_frame`]. May import: `parapet-core`, [`crate::input`] (limits), [`crate::sim`]
//! (sensors, track ids), [`crate::world`] (scene, nearest-distance tracker).

use nalgebra::Vector3;
use parapet_core::cbf::SafetyFilter;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::Vec3;

use crate::input::limits;
use crate::sim::sensors::Sensors;
use crate::sim::track_ids::TrackIds;
use crate::world::scene::{to_f32, Scene};
use crate::world::NearestTracker;

/// The true barrier `h̄` (m²) of obstacle `i` whose closest point is `q` (signed
/// distance `sd`, velocity `vel`) for the vehicle at `pf`, `vf`; inside counts as −δ or less.
fn h_bar_of(
    filter: &SafetyFilter,
    pf: &Vec3,
    vf: &Vec3,
    i: usize,
    q: Vec3,
    vel: &Vector3<f64>,
    sd: f32,
) -> f64 {
    let delta = filter.params.delta as f64;
    let op = ObstaclePoint { point: q, velocity: Some(to_f32(vel)), id: i as u16, normal: None };
    let h = match filter.barrier(pf, vf, &op) {
        Some(b) => b.h as f64 - delta,
        None => -delta,
    };
    if sd < 0.0 {
        h.min(-delta)
    } else {
        h
    }
}

/// Min over all obstacles of the filter's barrier `h̄ = h − δ` (m²) at time `t`
/// for the true state; `+∞` without obstacles. Inside an obstacle counts as −δ or less.
pub fn true_h_bar(scene: &Scene, filter: &SafetyFilter, t: f64, p: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    let (pf, vf) = (to_f32(p), to_f32(v));
    let mut h_min = f64::INFINITY;
    for (i, o) in scene.obstacles.iter().enumerate() {
        let (shape, vel) = o.at(t);
        let (q, sd) = shape.closest_point(&pf);
        h_min = h_min.min(h_bar_of(filter, &pf, &vf, i, q, &vel, sd));
    }
    h_min
}

/// Relative margin on the lower bound of an obstacle's barrier in
/// [`sense_and_h_bar`] (covers the `f32` round-off of `h`).
const H_BOUND_MARGIN: f64 = 1e-4;

/// `true` when an obstacle whose distance is at least `l` (m) certainly has a
/// barrier `h̄` above `h_min` (m²) for a vehicle at speed `s` (`mu_s` = μ s, m):
/// `h = |d|² + μ dᵀḋ ≥ |d|² − μ s |d|` for a static obstacle, increasing in
/// `|d|` for `|d| ≥ μ s / 2`; with a relative margin for round-off.
#[inline]
fn h_bar_certainly_above(l: f64, mu_s: f64, delta: f64, h_min: f64) -> bool {
    if !(l > 0.01 && 2.0 * l >= mu_s) {
        return false;
    }
    let (l2, ml) = (l * l, mu_s * l);
    l2 - ml - delta - H_BOUND_MARGIN * (l2 + ml + delta + 1.0) > h_min
}

/// Reusable buffers of [`sense_and_h_bar`].
#[derive(Clone, Debug, Default)]
pub struct OuterScratch {
    /// The proximity report (output of [`sense_and_h_bar`]).
    pub seen: Vec<ObstaclePoint>,
    /// Obstacles certainly beyond the sensing range.
    far: Vec<usize>,
    /// Obstacles evaluated: index, closest point, velocity, signed distance.
    near: Vec<(usize, Vec3, Vector3<f64>, f32)>,
    /// Track ids of the obstacles in view (kept from one outer step to the next).
    pub ids: TrackIds,
}

/// The proximity report ([`sense_obstacles`], into `scratch.seen`) and the true
/// barrier ([`true_h_bar`], returned) at one outer step, with the same results:
/// the closest points are computed once for both, and only for the obstacles
/// that can matter. `tracker` is the vehicle's (same scene). Time `t` s,
/// position `p` NED m, velocity `v` NED m/s, sensing range m; returns h̄, m².
///
/// Obstacles that may be within `range` (lower bound of the distance ≤ range;
/// moving obstacles always) are evaluated in index order (the order of the
/// report and of the sensor-noise draws). The barrier is evaluated for the
/// nearest of them, then for each other one unless a lower bound of its `h̄`
/// is above the smallest found so far: `|d|² − μ s |d| − δ` for a static
/// obstacle (whose `ḋ` is the vehicle's velocity, speed `s`), with `|d|` its
/// distance (or, beyond the range, the tracker's lower bound of it).
#[allow(clippy::too_many_arguments)]
pub fn sense_and_h_bar(
    scene: &Scene,
    tracker: &mut NearestTracker,
    filter: &SafetyFilter,
    t: f64,
    p: &Vector3<f64>,
    v: &Vector3<f64>,
    range: f64,
    sensors: &mut Sensors,
    scratch: &mut OuterScratch,
) -> f64 {
    tracker.move_to(p);
    // Every obstacle that may be within the range is a candidate (scene order).
    tracker.ensure(range);
    let (pf, vf) = (to_f32(p), to_f32(v));
    let OuterScratch { seen, far, near, ids } = scratch;
    ids.begin_pass();
    seen.clear();
    far.clear();
    near.clear();
    let mut far_min = f64::INFINITY;
    for j in 0..tracker.candidates().len() {
        let i = tracker.candidates()[j];
        let o = &scene.obstacles[i];
        let lb = tracker.lower_bound(i);
        if lb > range {
            far.push(i);
            far_min = far_min.min(lb);
            continue;
        }
        let (vel, q, sd) = tracker.closest(scene, i, &pf, t);
        if (sd as f64) <= range {
            let v = if o.is_static() { Vector3::zeros() } else { sensors.obstacle_velocity(vel) };
            if let Some(id) = ids.id(i) {
                seen.push(ObstaclePoint { point: q, velocity: Some(to_f32(&v)), id, normal: None });
            }
        }
        near.push((i, q, vel, sd));
    }
    bound_report(seen, &pf);
    let mu_s = filter.params.mu as f64 * v.norm();
    let delta = filter.params.delta as f64;
    let margin = tracker.margin();
    let mut h_min = f64::INFINITY;
    // The nearest first: its barrier is usually the smallest.
    let first = (0..near.len()).min_by(|&a, &b| near[a].3.total_cmp(&near[b].3));
    if let Some(j) = first {
        let (i, q, vel, sd) = near[j];
        h_min = h_bar_of(filter, &pf, &vf, i, q, &vel, sd);
    }
    for (j, &(i, q, vel, sd)) in near.iter().enumerate() {
        let bounded =
            scene.obstacles[i].is_static() && h_bar_certainly_above(sd as f64 - margin, mu_s, delta, h_min);
        if Some(j) != first && !bounded {
            h_min = h_min.min(h_bar_of(filter, &pf, &vf, i, q, &vel, sd));
        }
    }
    // The bound grows with the distance: the nearest far obstacle's covers them all
    // (obstacles outside the candidate set are farther than its bound).
    let outside = tracker.outside_lower_bound();
    far_min = far_min.min(outside);
    if (far.is_empty() && outside == f64::INFINITY)
        || h_bar_certainly_above(far_min - margin, mu_s, delta, h_min)
    {
        return h_min;
    }
    if !h_bar_certainly_above(outside - margin, mu_s, delta, h_min) {
        // Obstacles outside the set, within a reach that doubles until the bound
        // covers what lies beyond it (1e7 m: every obstacle).
        let local_far = far.len();
        let mut reach = 2.0 * range.max(1.0);
        loop {
            far.truncate(local_far);
            tracker.outside_within(reach, far);
            for &i in &far[local_far..] {
                if !h_bar_certainly_above(tracker.lower_bound(i) - margin, mu_s, delta, h_min) {
                    let (vel, q, sd) = tracker.closest(scene, i, &pf, t);
                    h_min = h_min.min(h_bar_of(filter, &pf, &vf, i, q, &vel, sd));
                }
            }
            if reach >= 1e7 || h_bar_certainly_above(reach - 2.0 * margin, mu_s, delta, h_min) {
                break;
            }
            reach *= 2.0;
        }
        far.truncate(local_far);
    }
    for &i in far.iter() {
        // Far obstacles are static (moving ones have no bound).
        if !h_bar_certainly_above(tracker.lower_bound(i) - margin, mu_s, delta, h_min) {
            let (vel, q, sd) = tracker.closest(scene, i, &pf, t);
            h_min = h_min.min(h_bar_of(filter, &pf, &vf, i, q, &vel, sd));
        }
    }
    h_min
}

/// What the proximity sensor reports at time `t` from true position `p`: for
/// each obstacle whose surface is within `range` (m; at most
/// [`limits::MAX_OBSTACLES_REPORTED`], [`bound_report`]), the closest surface point
/// and the obstacle's velocity (NED), id = a track id of a fresh table (the first pass of
/// [`sense_and_h_bar`]'s; the scene index below 65,535 obstacles). Moving obstacles'
/// velocities pass through [`Sensors::obstacle_velocity`] (optional noise);
/// static obstacles are reported with velocity exactly zero.
pub fn sense_obstacles(
    scene: &Scene,
    t: f64,
    p: &Vector3<f64>,
    range: f64,
    sensors: &mut Sensors,
) -> Vec<ObstaclePoint> {
    let pf = to_f32(p);
    let mut out = Vec::new();
    let mut ids = TrackIds::new();
    ids.begin_pass();
    for (i, o) in scene.obstacles.iter().enumerate() {
        let (shape, vel) = o.at(t);
        let (q, sd) = shape.closest_point(&pf);
        if (sd as f64) <= range {
            let v = if o.is_static() { Vector3::zeros() } else { sensors.obstacle_velocity(vel) };
            if let Some(id) = ids.id(i) {
                out.push(ObstaclePoint { point: q, velocity: Some(to_f32(&v)), id, normal: None });
            }
        }
    }
    bound_report(&mut out, &pf);
    out
}

/// Bound a proximity report to [`limits::MAX_OBSTACLES_REPORTED`] points: beyond it the
/// nearest to `p` (NED) are kept (ties: the earlier), in report order. Every point in
/// range reaches the controller up to the bound; the controller's set then keeps the
/// most critical (`parapet_core::obstacle_set`, issue 17).
pub fn bound_report(seen: &mut Vec<ObstaclePoint>, p: &Vec3) {
    let max = limits::MAX_OBSTACLES_REPORTED;
    if seen.len() <= max {
        return;
    }
    let mut d: Vec<(f32, usize)> =
        seen.iter().enumerate().map(|(i, o)| ((o.point - p).norm_squared(), i)).collect();
    d.select_nth_unstable_by(max - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut keep = vec![false; seen.len()];
    for &(_, i) in d.iter().take(max) {
        keep[i] = true;
    }
    let mut k = keep.into_iter();
    seen.retain(|_| k.next().unwrap_or(false));
}

/// Margin on mapped obstacles, in σ of the filter's position, and the bound on the estimate's
/// error they are moved by (`docs/filter.md` § 18): the core's, which the firmware applies too.
pub use parapet_core::nav::bound::{ErrorBound, MAPPED_MARGIN_SIGMA};

/// Put an obstacle report into the frame the controller flies in when its position comes
/// from the navigation filter (estimate `est`, NED m; `err` = estimate − truth; `bound` on
/// `|err|`), `docs/filter.md` § Position uncertainty:
///
/// * `sensed` (range sensors, `--perception`): the vehicle measures obstacles relative to
///   itself, so the points are the true ones shifted by the estimation error (`q + err`): the
///   relative geometry the barrier uses is exact, whatever the global error.
/// * mapped (the ground-truth report: a map in the world frame): the points stay where the
///   map says, moved towards the estimate by the bound along their direction
///   ([`ErrorBound::along`]: a point below the vehicle by the vertical bound, one beside it by
///   the horizontal one), so the barrier sees no obstacle farther than it truly is while the
///   error is within the bound (at least 1 cm of distance is left).
pub fn to_estimate_frame(
    seen: &mut [ObstaclePoint],
    err: &Vector3<f64>,
    est: &Vector3<f64>,
    bound: &ErrorBound,
    sensed: bool,
) {
    if sensed {
        let e = to_f32(err);
        for o in seen.iter_mut() {
            o.point += e;
        }
        return;
    }
    let e = to_f32(est);
    for o in seen.iter_mut() {
        o.point = bound.shift_mapped(&o.point, &e);
    }
}
