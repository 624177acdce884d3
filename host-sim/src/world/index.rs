//! The spatial index of a scene's **static** obstacles: a bounding-volume
//! hierarchy (parry3d-f64's [`Bvh`], binned SAH build) over the obstacles'
//! axis-aligned bounding boxes, with exact answers.
//!
//! The BVH is the broad phase only. Every distance is computed by the same
//! narrow phase as a full scan, [`Shape::closest_point`] of `parapet-core` (in
//! `f32`), so a query's result is the full scan's **bit for bit**: the value,
//! and among equal distances the lowest obstacle index. (parry's own distance
//! algorithms work in `f64` and differ from the core's `f32` ones in the last
//! bits; the controller is told the core's values, so the index uses those.)
//!
//! A box is pruned only when the query point is outside it and its `f64` distance to the point, minus a
//! round-off margin ([`round_off_margin`]), is **strictly** above what the
//! query still accepts: the signed distance to a solid is at least the distance
//! to its bounding box, and the margin covers the `f32` rounding of the point
//! and of the computed distance.
//!
//! Queries: nearest (with a seed), k nearest, every box within a radius, every
//! box overlapping a box, every grown box meeting a segment.
//!
//! Owns: [`StaticIndex`] and [`round_off_margin`]. May import: `parapet-core`
//! (shapes), parry3d-f64 (the BVH), nalgebra; nothing else of host-sim.

use nalgebra::Vector3;
use parapet_core::obstacle::Shape;
use parapet_core::Vec3;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhNode, TraversalAction};

/// Relative size of the margin that covers the `f32` round-off of
/// [`Shape::closest_point`]: the margin is this times (1 m + the largest
/// coordinate involved), about 84 `f32` epsilons of the largest coordinate,
/// well above the few ulps the computation can be off.
pub const ROUND_OFF_MARGIN: f64 = 1e-5;

/// The round-off margin (m) for a query point of largest coordinate magnitude
/// `reach` among obstacles of largest coordinate magnitude `extent` (m).
#[inline]
pub fn round_off_margin(reach: f64, extent: f64) -> f64 {
    ROUND_OFF_MARGIN * (1.0 + reach + extent)
}

/// Axis-aligned bounding box of a shape (NED, m), in `f64` (the `f32`
/// coordinates convert exactly; sums are rounded outwards by the margin of
/// the queries).
pub fn shape_aabb(shape: &Shape) -> ([f64; 3], [f64; 3]) {
    let v = |a: &[f32; 3]| [a[0] as f64, a[1] as f64, a[2] as f64];
    match shape {
        Shape::Point { center } => (v(center), v(center)),
        Shape::Sphere { center, radius } => {
            let (c, r) = (v(center), *radius as f64);
            ([c[0] - r, c[1] - r, c[2] - r], [c[0] + r, c[1] + r, c[2] + r])
        }
        Shape::Box { min, max } => (v(min), v(max)),
        Shape::Cylinder { base, radius, height } => {
            let (b, r, h) = (v(base), *radius as f64, *height as f64);
            ([b[0] - r, b[1] - r, b[2] - h], [b[0] + r, b[1] + r, b[2]])
        }
    }
}

/// Largest coordinate magnitude of a shape's bounding box, m.
pub fn shape_extent(shape: &Shape) -> f64 {
    let (lo, hi) = shape_aabb(shape);
    lo.iter().chain(hi.iter()).fold(0.0, |m: f64, x| m.max(x.abs()))
}

/// Euclidean distance (m) from `p` to the box of `node` (0 inside).
#[inline]
fn node_distance(node: &BvhNode, p: &[f64; 3]) -> f64 {
    let (lo, hi) = (node.mins(), node.maxs());
    let dx = (lo.x - p[0]).max(p[0] - hi.x).max(0.0);
    let dy = (lo.y - p[1]).max(p[1] - hi.y).max(0.0);
    let dz = (lo.z - p[2]).max(p[2] - hi.z).max(0.0);
    (dx * dx + dy * dy + dz * dz).sqrt()
}

/// `true` when the box of `node` overlaps `[lo, hi]` (touching counts).
#[inline]
fn node_overlaps(node: &BvhNode, lo: &[f64; 3], hi: &[f64; 3]) -> bool {
    let (a, b) = (node.mins(), node.maxs());
    a.x <= hi[0] && lo[0] <= b.x && a.y <= hi[1] && lo[1] <= b.y && a.z <= hi[2] && lo[2] <= b.z
}

/// `true` when the segment `a + t·d`, `t ∈ [0, 1]`, meets the box `[lo, hi]`
/// (slab test; touching counts; NaN input counts as meeting).
#[inline]
fn segment_meets_box(a: &[f64; 3], d: &[f64; 3], lo: &[f64; 3], hi: &[f64; 3]) -> bool {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for i in 0..3 {
        if d[i] == 0.0 {
            if a[i] < lo[i] || a[i] > hi[i] {
                return false;
            }
        } else {
            let (u, v) = ((lo[i] - a[i]) / d[i], (hi[i] - a[i]) / d[i]);
            let (u, v) = if u <= v { (u, v) } else { (v, u) };
            // NaN bounds leave t0/t1 unchanged (max/min ignore NaN): conservative.
            t0 = t0.max(u);
            t1 = t1.min(v);
            if t0 > t1 {
                return false;
            }
        }
    }
    true
}

/// The static obstacles of a scene in a BVH. Leaves are numbered in the order
/// given; each leaf remembers the obstacle's index in the scene.
#[derive(Clone)]
pub struct StaticIndex {
    bvh: Bvh,
    /// Per leaf: the obstacle's index in the scene.
    ids: Vec<usize>,
    /// Per leaf: the obstacle's shape (NED).
    shapes: Vec<Shape>,
    /// Largest coordinate magnitude of the indexed obstacles, m.
    extent: f64,
}

impl std::fmt::Debug for StaticIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StaticIndex").field("len", &self.ids.len()).field("extent", &self.extent).finish()
    }
}

impl StaticIndex {
    /// Index the obstacles `(scene index, shape)`, scene indices increasing.
    pub fn new(obstacles: impl IntoIterator<Item = (usize, Shape)>) -> Self {
        let (ids, shapes): (Vec<usize>, Vec<Shape>) = obstacles.into_iter().unzip();
        debug_assert!(ids.windows(2).all(|w| w[0] < w[1]), "scene indices must increase");
        let aabbs: Vec<Aabb> = shapes
            .iter()
            .map(|s| {
                let (lo, hi) = shape_aabb(s);
                Aabb::new(PVec::new(lo[0], lo[1], lo[2]), PVec::new(hi[0], hi[1], hi[2]))
            })
            .collect();
        let extent = shapes.iter().map(shape_extent).fold(0.0, f64::max);
        StaticIndex { bvh: Bvh::from_leaves(BvhBuildStrategy::Binned, &aabbs), ids, shapes, extent }
    }

    /// Index the shapes of a list (scene index = position in the list).
    pub fn from_shapes(shapes: &[Shape]) -> Self {
        Self::new(shapes.iter().copied().enumerate())
    }

    /// Number of indexed obstacles.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// `true` without obstacles.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The BVH (leaf `l` is [`leaf`](Self::leaf)`(l)`), for queries written
    /// elsewhere (the ray casts of [`super::raycast`]).
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Largest coordinate magnitude of the indexed obstacles, m.
    pub fn extent(&self) -> f64 {
        self.extent
    }

    /// Scene index and shape of leaf `leaf`.
    #[inline]
    pub fn leaf(&self, leaf: u32) -> (usize, &Shape) {
        (self.ids[leaf as usize], &self.shapes[leaf as usize])
    }

    /// Calls `f(leaf)` for every obstacle whose bounding box is within `r` (m)
    /// of `p` (NED); `r` may be negative (nothing) or infinite (everything).
    /// Order: the tree's, not the scene's.
    pub fn for_each_within(&self, p: &Vector3<f64>, r: f64, mut f: impl FnMut(u32)) {
        let q = [p.x, p.y, p.z];
        self.bvh.traverse(|node| {
            let near = node_distance(node, &q) <= r;
            if !near {
                return TraversalAction::Prune;
            }
            if let Some(leaf) = node.leaf_data() {
                f(leaf);
            }
            TraversalAction::Continue
        });
    }

    /// Calls `f(leaf)` for every obstacle whose bounding box overlaps the box
    /// `[lo, hi]` (touching counts); stops early when `f` returns `false`.
    pub fn for_each_overlapping(&self, lo: &[f64; 3], hi: &[f64; 3], mut f: impl FnMut(u32) -> bool) {
        self.bvh.traverse(|node| {
            if !node_overlaps(node, lo, hi) {
                return TraversalAction::Prune;
            }
            if let Some(leaf) = node.leaf_data() {
                if !f(leaf) {
                    return TraversalAction::EarlyExit;
                }
            }
            TraversalAction::Continue
        });
    }

    /// Calls `f(leaf)` for every obstacle whose bounding box, grown by `grow`
    /// (m) on every side, meets the segment `a → b` (NED, m; touching counts;
    /// a relative 10⁻⁹ more against rounding); stops early when `f` returns `false`.
    pub fn for_each_on_segment(&self, a: &[f64; 3], b: &[f64; 3], grow: f64, mut f: impl FnMut(u32) -> bool) {
        let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let eps = 1e-9 * (1.0 + a.iter().chain(b.iter()).fold(0.0f64, |m, x| m.max(x.abs())));
        let g = grow + eps;
        self.bvh.traverse(|node| {
            let (lo, hi) = (node.mins(), node.maxs());
            let (lo, hi) = ([lo.x - g, lo.y - g, lo.z - g], [hi.x + g, hi.y + g, hi.z + g]);
            if !segment_meets_box(a, &d, &lo, &hi) {
                return TraversalAction::Prune;
            }
            if let Some(leaf) = node.leaf_data() {
                if !f(leaf) {
                    return TraversalAction::EarlyExit;
                }
            }
            TraversalAction::Continue
        });
    }

    /// The `k` nearest indexed obstacles to `p` (NED): `(signed distance m,
    /// scene index)` in increasing distance, equal distances by increasing
    /// index (the first `k` of a full scan sorted that way; fewer when the
    /// index holds fewer; none for a non-finite point's NaN distances).
    pub fn nearest_k(&self, p: &Vector3<f64>, k: usize) -> Vec<(f64, usize)> {
        let pf = Vec3::new(p.x as f32, p.y as f32, p.z as f32);
        let q = [p.x, p.y, p.z];
        let margin = round_off_margin(p.amax(), self.extent);
        let mut best: Vec<(f64, usize)> = Vec::with_capacity(k + 1);
        if k == 0 {
            return best;
        }
        self.bvh.traverse(|node| {
            let d_box = node_distance(node, &q);
            if best.len() == k && d_box > 0.0 && d_box - margin > best[k - 1].0 {
                return TraversalAction::Prune;
            }
            if let Some(leaf) = node.leaf_data() {
                let l = leaf as usize;
                let d = self.shapes[l].signed_distance(&pf) as f64;
                let e = (d, self.ids[l]);
                if d.is_nan() || (best.len() == k && (best[k - 1].0, best[k - 1].1) < e) {
                    return TraversalAction::Continue;
                }
                let at = best.partition_point(|b| (b.0, b.1) < e);
                best.insert(at, e);
                best.truncate(k);
            }
            TraversalAction::Continue
        });
        best
    }

    /// Signed distance (m) from `p` (NED) to the nearest indexed obstacle
    /// (computed by [`Shape::signed_distance`] at `p` rounded to `f32`) and its
    /// scene index; the lowest index among equal distances; `(inf, None)`
    /// when empty. Equal to the full scan bit for bit. `seed`, a scene index
    /// likely to be near (e.g. the last answer), only speeds the search up.
    pub fn nearest(&self, p: &Vector3<f64>, seed: Option<usize>) -> (f64, Option<usize>) {
        self.nearest_counted(p, seed).0
    }

    /// [`nearest`](Self::nearest) and the number of distance evaluations it did.
    pub fn nearest_counted(&self, p: &Vector3<f64>, seed: Option<usize>) -> ((f64, Option<usize>), u64) {
        let pf = Vec3::new(p.x as f32, p.y as f32, p.z as f32);
        let q = [p.x, p.y, p.z];
        let margin = round_off_margin(p.amax(), self.extent);
        let mut best = (f64::INFINITY, None::<usize>);
        let mut evaluations = 0u64;
        let seed_leaf = seed.and_then(|s| self.ids.binary_search(&s).ok());
        if let Some(l) = seed_leaf {
            let d = self.shapes[l].signed_distance(&pf) as f64;
            evaluations += 1;
            if d < best.0 {
                best = (d, Some(self.ids[l]));
            }
        }
        self.bvh.traverse(|node| {
            // Outside the box (distance > 0) the signed distance is at least the
            // box distance; inside it may be negative, so nothing is pruned. A
            // NaN point prunes nothing (every comparison is false): a full scan.
            let d_box = node_distance(node, &q);
            if d_box > 0.0 && d_box - margin > best.0 {
                return TraversalAction::Prune;
            }
            if let Some(leaf) = node.leaf_data() {
                let l = leaf as usize;
                if Some(l) != seed_leaf {
                    let d = self.shapes[l].signed_distance(&pf) as f64;
                    evaluations += 1;
                    let id = self.ids[l];
                    // The full scan keeps the lowest index among equal distances.
                    if d < best.0 || (d == best.0 && best.1.is_some_and(|b| id < b)) {
                        best = (d, Some(id));
                    }
                }
            }
            TraversalAction::Continue
        });
        (best, evaluations)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Random spheres, boxes, cylinders and points in a `size` m cube, some duplicated.
    pub(crate) fn random_shapes(rng: &mut ChaCha8Rng, n: usize, size: f32) -> Vec<Shape> {
        let mut out: Vec<Shape> = Vec::with_capacity(n);
        for _ in 0..n {
            let c = Vec3::new(
                rng.random_range(-size..size),
                rng.random_range(-size..size),
                rng.random_range(-size..0.0),
            );
            let r = rng.random_range(0.05..1.5f32);
            let s = match rng.random_range(0..10) {
                0 if !out.is_empty() => out[rng.random_range(0..out.len())],
                1 => Shape::Point { center: [c.x, c.y, c.z] },
                2..=4 => Shape::sphere(c, r),
                5..=7 => {
                    Shape::aabb(c, c + Vec3::new(r, rng.random_range(0.05..2.0), rng.random_range(0.05..3.0)))
                }
                _ => Shape::cylinder(c, r, rng.random_range(0.1..5.0)),
            };
            out.push(s);
        }
        out
    }

    fn full_scan(shapes: &[Shape], p: &Vector3<f64>) -> (f64, Option<usize>) {
        let pf = Vec3::new(p.x as f32, p.y as f32, p.z as f32);
        let mut best = (f64::INFINITY, None);
        for (i, s) in shapes.iter().enumerate() {
            let d = s.signed_distance(&pf) as f64;
            if d < best.0 {
                best = (d, Some(i));
            }
        }
        best
    }

    #[test]
    fn nearest_equals_the_full_scan_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (mut inside, mut evaluations, mut queries) = (0, 0u64, 0u64);
        for (n, size) in [(1, 5.0), (7, 5.0), (300, 20.0), (3000, 60.0)] {
            let shapes = random_shapes(&mut rng, n, size);
            let index = StaticIndex::from_shapes(&shapes);
            let mut last = None;
            for k in 0..2000 {
                let s = size as f64 * 1.2;
                let p =
                    Vector3::new(rng.random_range(-s..s), rng.random_range(-s..s), rng.random_range(-s..1.0));
                let seed = if k % 3 == 0 { None } else { last };
                let (fast, evals) = index.nearest_counted(&p, seed);
                let full = full_scan(&shapes, &p);
                assert_eq!(fast.0.to_bits(), full.0.to_bits(), "n {n}, {p:?}: {fast:?} vs {full:?}");
                assert_eq!(
                    fast.1,
                    full.1,
                    "n {n}, {p:?} seed {seed:?} {:?}",
                    shapes
                        .iter()
                        .map(|s| s.signed_distance(&Vec3::new(p.x as f32, p.y as f32, p.z as f32)))
                        .collect::<Vec<_>>()
                );
                last = fast.1;
                inside += usize::from(full.0 < 0.0);
                if n == 3000 {
                    evaluations += evals;
                    queries += 1;
                }
            }
        }
        assert!(inside > 20, "only {inside} queries inside an obstacle");
        // The index looks at a small part of 3000 obstacles per query.
        assert!(evaluations < queries * 300, "{evaluations} evaluations for {queries} queries");
    }

    #[test]
    fn within_and_overlapping_find_exactly_the_boxes_that_qualify() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let shapes = random_shapes(&mut rng, 2000, 40.0);
        let index = StaticIndex::from_shapes(&shapes);
        for _ in 0..300 {
            let p = Vector3::new(
                rng.random_range(-45.0..45.0),
                rng.random_range(-45.0..45.0),
                rng.random_range(-45.0..1.0),
            );
            let r = rng.random_range(0.0..6.0);
            let mut got = Vec::new();
            index.for_each_within(&p, r, |l| got.push(index.leaf(l).0));
            got.sort_unstable();
            let want: Vec<usize> = (0..shapes.len())
                .filter(|&i| {
                    let (lo, hi) = shape_aabb(&shapes[i]);
                    let d2: f64 = (0..3).map(|k| (lo[k] - p[k]).max(p[k] - hi[k]).max(0.0).powi(2)).sum();
                    d2.sqrt() <= r
                })
                .collect();
            assert_eq!(got, want);
            // Every obstacle within r (exact distance) is among them.
            let pf = Vec3::new(p.x as f32, p.y as f32, p.z as f32);
            for (i, s) in shapes.iter().enumerate() {
                if (s.signed_distance(&pf) as f64) < r - 1e-3 {
                    assert!(want.contains(&i));
                }
            }
            let (lo, hi) = ([p.x - r, p.y - r, p.z - r], [p.x + r, p.y + r, p.z + r]);
            let mut got = Vec::new();
            index.for_each_overlapping(&lo, &hi, |l| {
                got.push(index.leaf(l).0);
                true
            });
            got.sort_unstable();
            let want: Vec<usize> = (0..shapes.len())
                .filter(|&i| {
                    let (a, b) = shape_aabb(&shapes[i]);
                    (0..3).all(|k| a[k] <= hi[k] && lo[k] <= b[k])
                })
                .collect();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn segment_query_finds_every_box_the_segment_meets() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let shapes = random_shapes(&mut rng, 1500, 40.0);
        let index = StaticIndex::from_shapes(&shapes);
        let mut found = 0;
        for _ in 0..400 {
            let mut pt = || {
                [rng.random_range(-45.0..45.0), rng.random_range(-45.0..45.0), rng.random_range(-45.0..1.0)]
            };
            let (a, mut b) = (pt(), pt());
            if rng.random_range(0..4) == 0 {
                b[2] = a[2]; // axis-parallel components
            }
            let grow = rng.random_range(0.0..0.5);
            let mut got = Vec::new();
            index.for_each_on_segment(&a, &b, grow, |l| {
                got.push(index.leaf(l).0);
                true
            });
            got.sort_unstable();
            // Brute force: sample the segment densely against the grown boxes.
            for (i, s) in shapes.iter().enumerate() {
                let (lo, hi) = shape_aabb(s);
                let hit = (0..=2000).any(|k| {
                    let t = k as f64 / 2000.0;
                    (0..3).all(|j| {
                        let x = a[j] + t * (b[j] - a[j]);
                        x >= lo[j] - grow && x <= hi[j] + grow
                    })
                });
                if hit {
                    assert!(got.contains(&i), "obstacle {i} missed");
                }
            }
            // And nothing whose grown box is far from the segment.
            for &i in &got {
                let (lo, hi) = shape_aabb(&shapes[i]);
                let near = (0..=2000).any(|k| {
                    let t = k as f64 / 2000.0;
                    (0..3).all(|j| {
                        let x = a[j] + t * (b[j] - a[j]);
                        x >= lo[j] - grow - 0.1 && x <= hi[j] + grow + 0.1
                    })
                });
                assert!(near, "obstacle {i} reported but far");
            }
            found += got.len();
        }
        assert!(found > 400, "only {found} hits");
    }

    #[test]
    fn nearest_k_equals_the_sorted_full_scan() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let shapes = random_shapes(&mut rng, 2500, 50.0);
        let index = StaticIndex::from_shapes(&shapes);
        for _ in 0..300 {
            let p = Vector3::new(
                rng.random_range(-55.0..55.0),
                rng.random_range(-55.0..55.0),
                rng.random_range(-55.0..1.0),
            );
            let k = rng.random_range(0..40);
            let pf = Vec3::new(p.x as f32, p.y as f32, p.z as f32);
            let mut all: Vec<(f64, usize)> =
                shapes.iter().enumerate().map(|(i, s)| (s.signed_distance(&pf) as f64, i)).collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            all.truncate(k);
            let got = index.nearest_k(&p, k);
            assert_eq!(got.len(), all.len());
            for (g, w) in got.iter().zip(&all) {
                assert_eq!((g.0.to_bits(), g.1), (w.0.to_bits(), w.1), "k {k} at {p:?}");
            }
        }
    }

    #[test]
    fn empty_index_and_nan_points() {
        let index = StaticIndex::from_shapes(&[]);
        assert_eq!(index.nearest(&Vector3::zeros(), None), (f64::INFINITY, None));
        let shapes =
            [Shape::sphere(Vec3::new(1.0, 0.0, 0.0), 0.5), Shape::sphere(Vec3::new(-1.0, 0.0, 0.0), 0.5)];
        let index = StaticIndex::from_shapes(&shapes);
        let nan = Vector3::new(f64::NAN, 0.0, 0.0);
        assert_eq!(index.nearest(&nan, None), full_scan(&shapes, &nan));
        // Equal distances: the lowest index, whatever the seed.
        assert_eq!(index.nearest(&Vector3::zeros(), Some(1)), (0.5, Some(0)));
    }
}
