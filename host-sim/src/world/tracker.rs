//! [`NearestTracker`]: exact nearest-obstacle and proximity queries for a
//! point that moves (the simulator's vehicle and its reference), equal to the
//! full scans ([`Scene::nearest`], the runner's `sense_obstacles` /
//! `true_h_bar`) bit for bit and cheap at any obstacle count.
//!
//! Owns the tracker. May import: `parapet-core` (shapes), [`super::index`],
//! [`super::scene`], [`super::obstacle`], [`super::frame`].

use std::sync::Arc;

use nalgebra::Vector3;
use parapet_core::obstacle::Shape;
use parapet_core::Vec3;

use super::frame::to_f32;
use super::index::{round_off_margin, StaticIndex};
use super::obstacle::SceneObstacle;
use super::scene::Scene;

/// Scenes with at least this many static obstacles use the spatial index;
/// smaller ones keep every obstacle in the candidate set (a scan of a few
/// dozen bounds is cheaper than a tree query; the office has 26 obstacles).
pub const INDEX_MIN_OBSTACLES: usize = 64;

/// How far (m) the candidate set reaches beyond what was asked for: the point
/// may move this far before the set is rebuilt.
pub const LOCAL_SLACK_M: f64 = 1.0;

/// Nearest-obstacle queries for a point that moves, **exactly** equal to
/// [`Scene::nearest`] and cheaper, with two broad phases that skip obstacles
/// that cannot be the nearest (or cannot be within a range):
///
/// 1. **Candidate set.** Moving obstacles always; of the static ones, those
///    whose bounding box is within a radius `R` of a centre `c`, found with the
///    [`StaticIndex`] (scenes with at least [`INDEX_MIN_OBSTACLES`] static
///    obstacles; smaller scenes: every obstacle, `R = ∞`). Any other obstacle
///    is at least `R − |p − c|` (less a round-off margin) from the point `p`
///    ([`outside_lower_bound`](Self::outside_lower_bound)). A query whose
///    answer is not certainly inside the set asks the index (exact) and
///    re-centres the set.
/// 2. **Lipschitz bounds.** The signed distance to a solid is 1-Lipschitz: a
///    static obstacle last evaluated at `p_i` with distance `d_i` is at least
///    `d_i − |p − p_i|` from `p`. The tracker keeps an odometer `s` (sum of
///    `|Δp|` over the points it was given, m) and per obstacle `d_i + s_i`;
///    since `|p − p_i| ≤ s − s_i`, the bound costs one comparison.
///
/// A margin (10⁻⁵ × (1 m + the largest coordinate)) covers the `f32` round-off
/// of the computed distances, so an obstacle is skipped only when its computed
/// distance is certainly larger than the best one: the result, value and index
/// (lowest index among equal distances), is the same as the full scan's.
#[derive(Clone, Debug)]
pub struct NearestTracker {
    /// Last point given, NED, m.
    last: Option<Vector3<f64>>,
    /// Path length of the points given so far, m.
    odo: f64,
    /// Per obstacle: last computed signed distance + odometer at that time, m
    /// (−∞ for a moving obstacle or one never evaluated).
    key: Vec<f64>,
    /// Per obstacle: it never moves.
    fixed: Vec<bool>,
    /// No obstacle moves.
    all_fixed: bool,
    /// Per obstacle: its shape (NED) if it never moves (then `at(t)` is the same for every t).
    fixed_shape: Vec<Option<Shape>>,
    /// Largest coordinate magnitude of the static obstacles, m.
    extent: f64,
    /// Largest coordinate magnitude of the points given so far, m.
    reach: f64,
    /// Obstacle found nearest by the last query (evaluated first).
    hint: Option<usize>,
    /// Result of the last [`nearest`](Self::nearest) plus the odometer then, m
    /// (−∞ when the scene has moving obstacles: no bound).
    nearest_key: f64,
    /// The index of the static obstacles (`None`: small scene, every obstacle a candidate).
    index: Option<Arc<StaticIndex>>,
    /// Indices of the moving obstacles.
    moving: Vec<usize>,
    /// The candidate set, scene indices increasing.
    local: Vec<usize>,
    /// Centre of the candidate set, NED, m.
    centre: Vector3<f64>,
    /// Radius of the candidate set, m (+∞ without an index; −∞ before the first build).
    radius: f64,
    /// The smallest radius the set is rebuilt with (the largest sticky
    /// [`ensure`](Self::ensure) so far), m.
    base: f64,
    /// Exact distance evaluations done, for benchmarks and tests.
    pub evaluations: u64,
}

impl NearestTracker {
    /// A tracker for the obstacles of `scene` (the same scene must be passed to
    /// every query); builds the scene's index when it is large enough.
    pub fn new(scene: &Scene) -> Self {
        let n_static = scene.obstacles.iter().filter(|o| o.is_static()).count();
        let index = (n_static >= INDEX_MIN_OBSTACLES).then(|| Arc::new(index_of(scene)));
        Self::with_index(scene, index)
    }

    /// A tracker that shares `index` (the one of [`index`](Self::index), built
    /// for the same scene), or keeps every obstacle a candidate with `None`.
    pub fn with_index(scene: &Scene, index: Option<Arc<StaticIndex>>) -> Self {
        let extent = scene.obstacles.iter().map(|o| super::index::shape_extent(&o.shape)).fold(0.0, f64::max);
        let moving: Vec<usize> =
            (0..scene.obstacles.len()).filter(|&i| !scene.obstacles[i].is_static()).collect();
        let (local, radius) = match index {
            Some(_) => (moving.clone(), f64::NEG_INFINITY),
            None => ((0..scene.obstacles.len()).collect(), f64::INFINITY),
        };
        NearestTracker {
            last: None,
            odo: 0.0,
            key: vec![f64::NEG_INFINITY; scene.obstacles.len()],
            fixed: scene.obstacles.iter().map(SceneObstacle::is_static).collect(),
            all_fixed: moving.is_empty(),
            fixed_shape: scene.obstacles.iter().map(|o| o.is_static().then(|| o.at(0.0).0)).collect(),
            extent,
            reach: 0.0,
            hint: None,
            nearest_key: f64::NEG_INFINITY,
            index,
            moving,
            local,
            centre: Vector3::zeros(),
            radius,
            base: 0.0,
            evaluations: 0,
        }
    }

    /// The index this tracker uses, to share with another tracker of the same scene.
    pub fn index(&self) -> Option<Arc<StaticIndex>> {
        self.index.clone()
    }

    /// Move the query point to `p` (NED, m): advances the odometer.
    pub fn move_to(&mut self, p: &Vector3<f64>) {
        if let Some(last) = self.last {
            if last == *p {
                return;
            }
            let step = (p - last).norm();
            // A non-finite point makes every bound −∞ (NaN compares false): full scans.
            self.odo += if step.is_finite() { step } else { f64::INFINITY };
        }
        self.last = Some(*p);
        self.reach = self.reach.max(p.amax());
    }

    /// The round-off margin (m) the bounds include at the current point.
    #[inline]
    pub fn margin(&self) -> f64 {
        round_off_margin(self.reach, self.extent)
    }

    /// A lower bound (m) on the signed distance [`Shape::signed_distance`] computes
    /// from the point of the last [`move_to`](Self::move_to) to obstacle `i`;
    /// −∞ when nothing is known (moving obstacle, never evaluated).
    #[inline]
    pub fn lower_bound(&self, i: usize) -> f64 {
        self.key[i] - self.odo - self.margin()
    }

    /// A lower bound (m) on what [`nearest`](Self::nearest) would return at the
    /// point of the last [`move_to`](Self::move_to) (the distance to the nearest
    /// obstacle is 1-Lipschitz too): one subtraction, no obstacle looked at.
    /// −∞ with moving obstacles or before the first query; +∞ without obstacles.
    #[inline]
    pub fn nearest_lower_bound(&self) -> f64 {
        self.nearest_key - self.odo - self.margin()
    }

    /// The candidate set: moving obstacles and the static ones near the
    /// current point, scene indices increasing.
    #[inline]
    pub fn candidates(&self) -> &[usize] {
        &self.local
    }

    /// A lower bound (m) on the signed distance computed from the current point
    /// to any obstacle **not** in [`candidates`](Self::candidates) (+∞ when
    /// every obstacle is a candidate; NaN for a non-finite point).
    #[inline]
    pub fn outside_lower_bound(&self) -> f64 {
        if self.radius == f64::INFINITY {
            return f64::INFINITY;
        }
        let p = self.last.unwrap_or(self.centre);
        self.radius - (p - self.centre).norm() - self.margin()
    }

    /// Make the candidate set hold every obstacle whose computed distance from
    /// the current point may be ≤ `need` (m), and keep `need` as the smallest
    /// radius of later rebuilds (the sensing range).
    pub fn ensure(&mut self, need: f64) {
        self.base = self.base.max(need);
        self.ensure_once(need);
    }

    /// [`ensure`](Self::ensure) without raising the smallest radius.
    pub fn ensure_once(&mut self, need: f64) {
        let covered = self.outside_lower_bound() >= need;
        if !covered {
            let p = self.last.unwrap_or(self.centre);
            self.rebuild(&p, need.max(self.base) + LOCAL_SLACK_M);
        }
    }

    /// Appends to `out` the static obstacles **not** in the candidate set whose
    /// bounding box is within `reach` (m) of the current point, in the index's
    /// order. Any other obstacle outside the set is farther than
    /// `reach − margin` (computed distance). Empty without an index.
    pub fn outside_within(&self, reach: f64, out: &mut Vec<usize>) {
        let (Some(index), Some(p)) = (&self.index, self.last) else { return };
        index.for_each_within(&p, reach, |leaf| {
            let i = index.leaf(leaf).0;
            if self.local.binary_search(&i).is_err() {
                out.push(i);
            }
        });
    }

    /// Re-centre the candidate set at `p` with radius `r` (m).
    fn rebuild(&mut self, p: &Vector3<f64>, r: f64) {
        let Some(index) = &self.index else { return };
        if !(p.iter().all(|x| x.is_finite()) && r.is_finite()) {
            // Keep the set: its bound is NaN at a non-finite point, so queries ask the index.
            return;
        }
        self.local.clear();
        self.local.extend_from_slice(&self.moving);
        index.for_each_within(p, r, |leaf| self.local.push(index.leaf(leaf).0));
        self.local.sort_unstable();
        self.centre = *p;
        self.radius = r;
    }

    /// Record the distance `d` (m) computed for obstacle `i` at the current point
    /// (ignored for moving obstacles).
    #[inline]
    pub fn record(&mut self, i: usize, d: f64) {
        self.evaluations += 1;
        if self.fixed[i] {
            self.key[i] = d + self.odo;
        }
    }

    /// The velocity of obstacle `i` at time `t` (NED, m/s), its closest point to
    /// the current point and the signed distance (see [`Shape::closest_point`]); recorded.
    #[inline]
    pub fn closest(&mut self, scene: &Scene, i: usize, pf: &Vec3, t: f64) -> (Vector3<f64>, Vec3, f32) {
        // The stored shape by reference: copying the enum costs more than the distance.
        let (vel, (q, d)) = match &self.fixed_shape[i] {
            Some(shape) => (Vector3::zeros(), shape.closest_point(pf)),
            None => {
                let (shape, vel) = scene.obstacles[i].at(t);
                (vel, shape.closest_point(pf))
            }
        };
        self.record(i, d as f64);
        (vel, q, d)
    }

    /// Signed distance (m) from `p` (NED) to the nearest obstacle surface at time
    /// `t` and that obstacle's index: the same as [`Scene::nearest`], bit for bit.
    pub fn nearest(&mut self, scene: &Scene, p: &Vector3<f64>, t: f64) -> (f64, Option<usize>) {
        self.move_to(p);
        let pf = to_f32(p);
        let margin = self.margin();
        let mut best = (f64::INFINITY, None);
        if let Some(h) = self.hint {
            let d = self.closest(scene, h, &pf, t).2 as f64;
            if d < best.0 {
                best = (d, Some(h));
            }
        }
        // Obstacle i is skipped when its bound key_i − odo − margin is above the best so far.
        let mut threshold = best.0 + self.odo + margin;
        for j in 0..self.local.len() {
            let i = self.local[j];
            if self.key[i] > threshold || Some(i) == self.hint {
                continue;
            }
            let d = self.closest(scene, i, &pf, t).2 as f64;
            // The full scan keeps the lowest index among equal distances.
            if d < best.0 || (d == best.0 && best.1.is_some_and(|b| i < b)) {
                best = (d, Some(i));
                threshold = best.0 + self.odo + margin;
            }
        }
        // An obstacle outside the set may be nearer (or as near, with a lower index).
        let inside_set = best.0 < self.outside_lower_bound();
        if !inside_set {
            if let Some(index) = self.index.clone() {
                let seed = best.1.filter(|&i| self.fixed[i]);
                let ((d, i), evaluations) = index.nearest_counted(p, seed);
                self.evaluations += evaluations;
                if let Some(i) = i {
                    if d < best.0 || (d == best.0 && best.1.is_some_and(|b| i < b)) {
                        best = (d, Some(i));
                    }
                }
                let r = best.0.max(0.0).max(self.base) + LOCAL_SLACK_M;
                self.rebuild(p, r);
            }
        }
        self.hint = best.1;
        self.nearest_key = if self.all_fixed { best.0 + self.odo } else { f64::NEG_INFINITY };
        best
    }
}

/// The index of `scene`'s static obstacles (scene indices kept).
pub fn index_of(scene: &Scene) -> StaticIndex {
    StaticIndex::new(
        scene.obstacles.iter().enumerate().filter(|(_, o)| o.is_static()).map(|(i, o)| (i, o.shape)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::scene::Motion;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A scene of `n` random static obstacles (shared generator of the index
    /// tests) and two moving spheres, bounds ±`size`.
    fn random_scene(seed: u64, n: usize, size: f32) -> Scene {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let shapes = crate::world::index::tests::random_shapes(&mut rng, n, size);
        let src = format!(
            "name = \"r\"\n[bounds]\nmin = [{m}, {m}, 0]\nmax = [{s}, {s}, {s}]\n[mission]\nstart = [0, 0, 1]\ngoal = [1, 0, 1]\nspeed = 0.3\n",
            m = -size,
            s = size
        );
        let mut scene = Scene::parse(&src, "r.toml").unwrap();
        scene.obstacles = shapes
            .into_iter()
            .map(|shape| SceneObstacle { name: None, shape, motion: Motion::Static, mapped: true })
            .collect();
        for k in 0..2 {
            let c = Vec3::new(k as f32, 1.0, -1.0);
            scene.obstacles.insert(
                n / (k + 2),
                SceneObstacle {
                    name: None,
                    shape: Shape::sphere(c, 0.4),
                    motion: Motion::Velocity(Vector3::new(0.3, -0.2, 0.0)),
                    mapped: true,
                },
            );
        }
        scene
    }

    #[test]
    fn indexed_tracker_equals_the_full_scan_bit_for_bit() {
        for (seed, n) in [(1, 80), (2, 3000)] {
            let scene = random_scene(seed, n, 30.0);
            let mut tracker = NearestTracker::new(&scene);
            assert!(tracker.index().is_some());
            let mut rng = ChaCha8Rng::seed_from_u64(seed + 10);
            let mut p = Vector3::new(0.0, 0.0, -1.0);
            let mut inside = 0;
            for k in 0..20_000 {
                let r: f64 = rng.random();
                p = if r < 0.005 {
                    Vector3::new(
                        rng.random_range(-35.0..35.0),
                        rng.random_range(-35.0..35.0),
                        rng.random_range(-35.0..1.0),
                    )
                } else {
                    let s = if r < 0.95 { 0.003 } else { 0.4 };
                    p + Vector3::from_fn(|_, _| rng.random_range(-s..=s))
                };
                let t = k as f64 * 0.001;
                let full = scene.nearest(&p, t);
                let fast = tracker.nearest(&scene, &p, t);
                assert_eq!(
                    fast.0.to_bits(),
                    full.0.to_bits(),
                    "n {n} query {k} at {p:?}: {fast:?} vs {full:?}"
                );
                assert_eq!(fast.1, full.1, "n {n} query {k}");
                inside += usize::from(full.0 < 0.0);
                if k % 50 == 0 {
                    // The candidate set holds everything within the asked range.
                    tracker.ensure(3.0);
                    let lb = tracker.outside_lower_bound();
                    assert!(lb >= 3.0);
                    for (i, o) in scene.obstacles.iter().enumerate() {
                        let d = o.at(t).0.signed_distance(&to_f32(&p)) as f64;
                        if !tracker.candidates().contains(&i) {
                            assert!(d >= lb, "obstacle {i} at {d} m is outside the set (bound {lb})");
                        }
                    }
                }
            }
            assert!(inside > 0 || n < 100, "n {n}: never inside");
            // Far fewer evaluations than a full scan per query.
            assert!(tracker.evaluations < 20_000 * 30, "n {n}: {} evaluations", tracker.evaluations);
        }
    }
}
