//! Segment and point validity of the planner (`Space`): bounds, the grown
//! boxes / spatial index broad phase and clearance-based stepping (see the
//! `planner` module docs). May import: the planner's parent items, `world`.

use super::*;

/// Segment and point validity against one problem (see the module docs).
pub(super) struct Space<'a> {
    pub(super) obstacles: &'a [Shape],
    pub(super) lo: Vec3,
    pub(super) hi: Vec3,
    /// hull radius + margin, m.
    pub(super) required: f32,
    pub(super) min_step: f32,
    /// Per obstacle: its axis-aligned bounding box grown by `required`
    /// (min, max), NED, m. A point or segment outside it is at least
    /// `required` from the obstacle (broad phase).
    pub(super) inflated: Vec<(Vec3, Vec3)>,
    /// The spatial index of the obstacles (problems with at least
    /// [`INDEX_MIN_OBSTACLES`]; smaller ones scan every grown box).
    pub(super) index: Option<Cow<'a, StaticIndex>>,
    /// Largest growth of a box beyond the obstacle's own bounding box, m.
    pub(super) grow: f64,
    /// Obstacles that may matter for the current segment (scratch for `free_prefix`).
    pub(super) cand: Vec<usize>,
    /// Per candidate: certified arc length (scratch for `free_prefix`).
    pub(super) cert: Vec<f32>,
}

/// Axis-aligned bounding box of a shape (min, max), NED, m.
pub(super) fn shape_aabb(shape: &Shape) -> (Vec3, Vec3) {
    let v = |a: &[f32; 3]| Vec3::new(a[0], a[1], a[2]);
    match shape {
        Shape::Point { center } => (v(center), v(center)),
        Shape::Sphere { center, radius } => {
            (v(center) - Vec3::repeat(*radius), v(center) + Vec3::repeat(*radius))
        }
        Shape::Box { min, max } => (v(min), v(max)),
        Shape::Cylinder { base, radius, height } => (
            Vec3::new(base[0] - radius, base[1] - radius, base[2] - height),
            Vec3::new(base[0] + radius, base[1] + radius, base[2]),
        ),
    }
}

/// `true` when boxes `[a0, a1]` and `[b0, b1]` overlap (touching counts).
pub(super) fn boxes_overlap(a0: &Vec3, a1: &Vec3, b0: &Vec3, b1: &Vec3) -> bool {
    a0.x <= b1.x && b0.x <= a1.x && a0.y <= b1.y && b0.y <= a1.y && a0.z <= b1.z && b0.z <= a1.z
}

impl<'a> Space<'a> {
    pub(super) fn new(problem: &'a PlanProblem, required: f32, min_step: f32) -> Self {
        Self::new_unindexed(problem, required, min_step).indexed(None)
    }

    pub(super) fn new_unindexed(problem: &'a PlanProblem, required: f32, min_step: f32) -> Self {
        Space {
            obstacles: &problem.obstacles,
            lo: problem.bounds_min,
            hi: problem.bounds_max,
            required,
            min_step,
            inflated: problem
                .obstacles
                .iter()
                .map(|o| {
                    // Grown a little beyond `required` so that f32 rounding
                    // can never cull an obstacle that matters.
                    let (lo, hi) = shape_aabb(o);
                    let g = Vec3::repeat(required + 1e-3 + 1e-5 * (lo.abs().max() + hi.abs().max()));
                    (lo - g, hi + g)
                })
                .collect(),
            index: None,
            grow: 0.0,
            cand: Vec::new(),
            cert: Vec::new(),
        }
    }

    /// Use `index` (of `problem.obstacles`), or build one, for a large problem.
    pub(super) fn indexed(mut self, index: Option<&'a StaticIndex>) -> Self {
        if self.obstacles.len() >= INDEX_MIN_OBSTACLES {
            self.index = Some(match index {
                Some(i) => Cow::Borrowed(i),
                None => Cow::Owned(StaticIndex::from_shapes(self.obstacles)),
            });
            self.grow = self
                .obstacles
                .iter()
                .zip(&self.inflated)
                .map(|(o, (lo, hi))| {
                    let (a, b) = shape_aabb(o);
                    (0..3).fold(0f64, |m, i| m.max((a[i] - lo[i]) as f64).max((hi[i] - b[i]) as f64))
                })
                .fold(0.0, f64::max);
        }
        self
    }

    pub(super) fn in_bounds(&self, p: &Vec3) -> bool {
        (0..3).all(|i| p[i] >= self.lo[i] && p[i] <= self.hi[i])
    }

    pub(super) fn point_valid(&self, p: &Vec3) -> bool {
        self.in_bounds(p) && self.clear_of_obstacles(p)
    }

    /// Clearance ≥ required (bounds not checked).
    pub(super) fn clear_of_obstacles(&self, p: &Vec3) -> bool {
        let blocks = |i: usize| {
            let (lo, hi) = &self.inflated[i];
            let clear = self.obstacles[i].signed_distance(p) >= self.required;
            boxes_overlap(p, p, lo, hi) && !clear
        };
        match &self.index {
            None => !(0..self.obstacles.len()).any(blocks),
            Some(index) => {
                let g = self.grow;
                let q = [p.x as f64, p.y as f64, p.z as f64];
                let (lo, hi) = ([q[0] - g, q[1] - g, q[2] - g], [q[0] + g, q[1] + g, q[2] + g]);
                let mut clear = true;
                index.for_each_overlapping(&lo, &hi, |leaf| {
                    clear = !blocks(index.leaf(leaf).0);
                    clear
                });
                clear
            }
        }
    }

    /// Length of the prefix of segment `a → b` certified valid (m). Returns
    /// `|b − a|` when the whole segment is valid, 0 when `a` itself is not
    /// certified. `a` and `b` must be in bounds (the caller guarantees it).
    pub(super) fn free_prefix(&mut self, a: &Vec3, b: &Vec3) -> f32 {
        let delta = b - a;
        let len = delta.norm();
        if len.is_nan() || len <= 0.0 {
            return if self.point_valid(a) { len.max(0.0) } else { 0.0 };
        }
        let dir = delta / len;
        // Broad phase: an obstacle whose grown box misses the segment's box
        // (small problems) or the segment itself (indexed problems) is
        // certified for the whole segment; the others are the candidates.
        let (seg_lo, seg_hi) = (a.inf(b), a.sup(b));
        let (inflated, cand) = (&self.inflated, &mut self.cand);
        cand.clear();
        match &self.index {
            None => cand.extend(
                (0..inflated.len())
                    .filter(|&i| boxes_overlap(&seg_lo, &seg_hi, &inflated[i].0, &inflated[i].1)),
            ),
            Some(index) => {
                let (a64, b64) = ([a.x as f64, a.y as f64, a.z as f64], [b.x as f64, b.y as f64, b.z as f64]);
                index.for_each_on_segment(&a64, &b64, self.grow, |leaf| {
                    cand.push(index.leaf(leaf).0);
                    true
                });
                cand.sort_unstable();
            }
        }
        self.cert.clear();
        self.cert.resize(self.cand.len(), f32::NEG_INFINITY);
        let mut s = 0.0f32;
        for _ in 0..MAX_SEGMENT_STEPS {
            let p = a + dir * s;
            let mut s_next = f32::INFINITY;
            for (k, &i) in self.cand.iter().enumerate() {
                let shape = &self.obstacles[i];
                if self.cert[k] > s {
                    s_next = s_next.min(self.cert[k]);
                    continue;
                }
                let (q, c) = shape.closest_point(&p);
                let excess = c - self.required - CERT_EPS_M;
                if excess.is_nan() || excess < 0.0 {
                    return s;
                }
                let step = if c > 1e-4 {
                    let dn = dir.dot(&(p - q)) / c;
                    if dn >= 0.0 {
                        f32::INFINITY
                    } else {
                        excess / -dn
                    }
                } else {
                    excess
                };
                if step < self.min_step {
                    return s;
                }
                self.cert[k] = s + step;
                s_next = s_next.min(self.cert[k]);
            }
            if s_next >= len {
                return len;
            }
            s = s_next;
        }
        s
    }

    pub(super) fn segment_valid(&mut self, a: &Vec3, b: &Vec3) -> bool {
        let len = (b - a).norm();
        self.free_prefix(a, b) >= len
    }
}
