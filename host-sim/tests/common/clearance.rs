//! An independent clearance check of planned paths (issue 38): the distance from
//! every segment of a path to every obstacle by parry3d's own algorithms (GJK /
//! the shape pairs' closed forms in `f64`), not the planner's clearance stepping
//! and not the core's `Shape` distances. Shared by `tests/plan_dense.rs` and
//! `benches/scale.rs` (`#[path]`).

use parapet_core::obstacle::Shape;
use parapet_core::Vec3;
use parry3d_f64::math::{Pose, Vector};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Cuboid, Cylinder, Segment};

fn v(a: &[f32; 3]) -> Vector {
    Vector::new(a[0] as f64, a[1] as f64, a[2] as f64)
}

/// The obstacle as a parry shape and its pose (NED, m).
fn parry(shape: &Shape) -> (Pose, Box<dyn parry3d_f64::shape::Shape>) {
    match shape {
        Shape::Point { center } => (Pose::from_translation(v(center)), Box::new(Ball::new(0.0))),
        Shape::Sphere { center, radius } => {
            (Pose::from_translation(v(center)), Box::new(Ball::new(*radius as f64)))
        }
        Shape::Box { min, max } => {
            let (a, b) = (v(min), v(max));
            (Pose::from_translation((a + b) * 0.5), Box::new(Cuboid::new((b - a) * 0.5)))
        }
        Shape::Cylinder { base, radius, height } => {
            // NED: the axis runs up (−z) from the base; parry's cylinder is centred on
            // its local y axis, turned onto z by a quarter turn about x.
            let h = *height as f64;
            let centre = v(base) - Vector::new(0.0, 0.0, h / 2.0);
            let pose = Pose::new(centre, Vector::new(std::f64::consts::FRAC_PI_2, 0.0, 0.0));
            (pose, Box::new(Cylinder::new(h / 2.0, *radius as f64)))
        }
    }
}

/// The obstacles as parry shapes with their poses and bounding boxes, built once.
pub struct Obstacles(Vec<(Pose, Box<dyn parry3d_f64::shape::Shape>, [f64; 6])>);

impl Obstacles {
    pub fn new(obstacles: &[Shape]) -> Self {
        Obstacles(
            obstacles
                .iter()
                .map(|o| {
                    let (pose, s) = parry(o);
                    let aabb = s.compute_aabb(&pose);
                    let (mn, mx) = (aabb.mins, aabb.maxs);
                    (pose, s, [mn.x, mn.y, mn.z, mx.x, mx.y, mx.z])
                })
                .collect(),
        )
    }

    /// The smallest distance (m) from any segment of `path` (NED) to any obstacle,
    /// and the segment and obstacle where it occurs. Obstacles whose bounding box
    /// is farther than `cutoff` from a segment's box on some axis are skipped
    /// (their distance exceeds `cutoff`).
    pub fn min_clearance(&self, path: &[Vec3], cutoff: f64) -> (f64, usize, usize) {
        let mut best = (f64::INFINITY, usize::MAX, usize::MAX);
        for (k, w) in path.windows(2).enumerate() {
            let (a, b) = (v(&[w[0].x, w[0].y, w[0].z]), v(&[w[1].x, w[1].y, w[1].z]));
            let (lo, hi) = (a.min(b), a.max(b));
            let seg = Segment::new(a, b);
            for (i, (pose, s, bb)) in self.0.iter().enumerate() {
                let gap =
                    [lo.x - bb[3], bb[0] - hi.x, lo.y - bb[4], bb[1] - hi.y, lo.z - bb[5], bb[2] - hi.z];
                if gap.iter().any(|g| *g > cutoff) {
                    continue;
                }
                let d = query::distance(&Pose::identity(), &seg, pose, s.as_ref())
                    .expect("supported shape pair")
                    .distance;
                if d < best.0 {
                    best = (d, k, i);
                }
            }
        }
        best
    }
}
