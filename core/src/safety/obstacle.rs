//! Obstacle geometry and the fixed-capacity obstacle set the safety filter reads.
//!
//! All positions are world NED, metres; velocities m/s. The filter never sees
//! a shape: it sees, per obstacle, the **closest surface point** `p̄` to the
//! vehicle's centre of mass (what a proximity sensor or a companion computer
//! reports), optionally with the obstacle's velocity. [`Shape::closest_point`]
//! produces that point from a known shape (simulator, planner, tests).

use crate::fmath::{norm3, sqrtf};
use crate::frame::{clampf, is_finite3};
use crate::Vec3;

/// First obstacle id of the **virtual** points the filter is given besides obstacles: the
/// field-of-view frontier (`crate::perception::FRONTIER_ID`), the ceiling and the ground
/// (`crate::safety::plant_aware::{CEILING_ID, GROUND_ID}`; each asserts it is at least this).
/// They stand for unseen space or the flight envelope and are static by construction, although
/// they carry no velocity (`ObstaclePoint::velocity` `None`).
pub const VIRTUAL_ID: u16 = 65_534;

/// First obstacle id of the points of **small clusters** a range sensor saw (ids up to
/// [`VIRTUAL_ID`], exclusive): what may be a mover — a person, a pole, a drone — as opposed to
/// the cells of walls and other extended surfaces (below this id). The obstacle memory gives
/// each tracked cluster's cells `CLUSTER_ID_BASE + track slot` (`crate::perception::CELL_ID_BASE`
/// is this value); a cluster it has not proven moving carries no velocity, or only an
/// estimated closing-in one (`crate::perception::track::Track::approach_velocity`), and
/// without one the braking barrier lets it approach at `CbfParams::brake_unknown_speed`.
pub const CLUSTER_ID_BASE: u16 = 60_000;

/// `true` for the point of a sensed small cluster whose velocity is unknown (id in
/// [`CLUSTER_ID_BASE`]`..`[`VIRTUAL_ID`], no velocity): it may be a mover not yet proven moving.
pub fn may_move_unseen(o: &ObstaclePoint) -> bool {
    o.velocity.is_none() && (CLUSTER_ID_BASE..VIRTUAL_ID).contains(&o.id)
}

/// Obstacle geometry in the world NED frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Shape {
    /// A point obstacle at `center` (m).
    Point {
        /// Position, NED, m.
        center: Vec3Data,
    },
    /// A solid sphere.
    Sphere {
        /// Centre, NED, m.
        center: Vec3Data,
        /// Radius, m (≥ 0).
        radius: f32,
    },
    /// A solid axis-aligned box `min ≤ p ≤ max` (component-wise), NED, m.
    Box {
        /// Minimum corner, NED, m.
        min: Vec3Data,
        /// Maximum corner, NED, m.
        max: Vec3Data,
    },
    /// A solid vertical cylinder of finite height. `base` is the centre of its
    /// bottom disc (NED, m); it extends *upwards* (towards −z) by `height`.
    Cylinder {
        /// Centre of the bottom disc, NED, m.
        base: Vec3Data,
        /// Radius, m (≥ 0).
        radius: f32,
        /// Height, m (≥ 0); the top disc is at `base.z - height`.
        height: f32,
    },
}

/// Plain `[x, y, z]` storage for shapes (keeps [`Shape`] `Copy`, `defmt`-able
/// and independent of nalgebra's layout). NED, m.
pub type Vec3Data = [f32; 3];

#[inline]
fn v(a: &Vec3Data) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

impl Shape {
    /// Sphere constructor from nalgebra vectors (NED, m).
    pub fn sphere(center: Vec3, radius: f32) -> Self {
        Shape::Sphere { center: center.into(), radius }
    }
    /// Axis-aligned box constructor (NED, m); corners are sorted component-wise.
    pub fn aabb(a: Vec3, b: Vec3) -> Self {
        Shape::Box { min: a.inf(&b).into(), max: a.sup(&b).into() }
    }
    /// Vertical cylinder constructor: bottom-disc centre (NED, m), radius, height (m).
    pub fn cylinder(base: Vec3, radius: f32, height: f32) -> Self {
        Shape::Cylinder { base: base.into(), radius, height }
    }
    /// Point obstacle constructor (NED, m).
    pub fn point(center: Vec3) -> Self {
        Shape::Point { center: center.into() }
    }

    /// The same shape moved by `offset` (m).
    pub fn translated(&self, offset: Vec3) -> Self {
        let t = |a: &Vec3Data| -> Vec3Data { (v(a) + offset).into() };
        match self {
            Shape::Point { center } => Shape::Point { center: t(center) },
            Shape::Sphere { center, radius } => Shape::Sphere { center: t(center), radius: *radius },
            Shape::Box { min, max } => Shape::Box { min: t(min), max: t(max) },
            Shape::Cylinder { base, radius, height } => {
                Shape::Cylinder { base: t(base), radius: *radius, height: *height }
            }
        }
    }

    /// `true` when every number of the shape is finite and sizes are ≥ 0.
    pub fn is_valid(&self) -> bool {
        match self {
            Shape::Point { center } => is_finite3(&v(center)),
            Shape::Sphere { center, radius } => {
                is_finite3(&v(center)) && radius.is_finite() && *radius >= 0.0
            }
            Shape::Box { min, max } => {
                is_finite3(&v(min)) && is_finite3(&v(max)) && (0..3).all(|i| min[i] <= max[i])
            }
            Shape::Cylinder { base, radius, height } => {
                is_finite3(&v(base))
                    && radius.is_finite()
                    && *radius >= 0.0
                    && height.is_finite()
                    && *height >= 0.0
            }
        }
    }

    /// The point of the shape's surface closest to `p` (NED, m), and the signed
    /// distance from `p` to the surface (m; negative inside the solid).
    ///
    /// For `p` strictly inside, the closest surface point is returned (the
    /// exit point). At a sphere's exact centre the choice of direction is +x.
    pub fn closest_point(&self, p: &Vec3) -> (Vec3, f32) {
        match self {
            Shape::Point { center } => {
                let c = v(center);
                (c, norm3(&(p - c)))
            }
            Shape::Sphere { center, radius } => {
                let c = v(center);
                let d = p - c;
                let n = norm3(&d);
                let dir = if n > 0.0 { d / n } else { Vec3::x() };
                (c + dir * *radius, n - *radius)
            }
            Shape::Box { min, max } => {
                let (lo, hi) = (v(min), v(max));
                let q = p.sup(&lo).inf(&hi);
                if q != *p {
                    return (q, norm3(&(p - q)));
                }
                // Inside (or on the surface): exit through the nearest face.
                let mut best = (q, f32::INFINITY);
                for i in 0..3 {
                    for (face, dist) in [(lo[i], p[i] - lo[i]), (hi[i], hi[i] - p[i])] {
                        if dist < best.1 {
                            let mut s = *p;
                            s[i] = face;
                            best = (s, dist);
                        }
                    }
                }
                (best.0, -best.1)
            }
            Shape::Cylinder { base, radius, height } => {
                let b = v(base);
                let (z_top, z_bot) = (b.z - *height, b.z);
                let rxy = nalgebra::Vector2::new(p.x - b.x, p.y - b.y);
                let r = sqrtf(rxy.norm_squared());
                let dir = if r > 0.0 { rxy / r } else { nalgebra::Vector2::x() };
                let inside_r = r <= *radius;
                let inside_z = p.z >= z_top && p.z <= z_bot;
                if inside_r && inside_z {
                    // Exit through the side, the top or the bottom, whichever is nearest.
                    let d_side = *radius - r;
                    let d_top = p.z - z_top;
                    let d_bot = z_bot - p.z;
                    if d_side <= d_top && d_side <= d_bot {
                        let s = Vec3::new(b.x + dir.x * *radius, b.y + dir.y * *radius, p.z);
                        (s, -d_side)
                    } else if d_top <= d_bot {
                        (Vec3::new(p.x, p.y, z_top), -d_top)
                    } else {
                        (Vec3::new(p.x, p.y, z_bot), -d_bot)
                    }
                } else {
                    let rc = if inside_r { r } else { *radius };
                    let zc = clampf(p.z, z_top, z_bot);
                    let s = Vec3::new(b.x + dir.x * rc, b.y + dir.y * rc, zc);
                    (s, norm3(&(p - s)))
                }
            }
        }
    }

    /// Signed distance from `p` to the surface, m (negative inside).
    pub fn signed_distance(&self, p: &Vec3) -> f32 {
        self.closest_point(p).1
    }

    /// The outward unit normal to report with the closest point `q` (signed distance `sd`,
    /// from [`closest_point`](Self::closest_point)) of this shape to `p`: the point is the
    /// closest point of an extended convex surface ([`ObstaclePoint::normal`]); `None` for a
    /// [`Shape::Point`] (a point has no surface) or when `p` is on the surface.
    pub fn surface_normal(&self, p: &Vec3, q: &Vec3, sd: f32) -> Option<Vec3> {
        match self {
            Shape::Point { .. } => None,
            _ => surface_normal(p, q, sd),
        }
    }
}

/// A moving or static obstacle: a shape at time 0 and a constant velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Obstacle {
    /// Geometry (NED, m) at the reference time.
    pub shape: Shape,
    /// Velocity of the whole solid, NED, m/s (zero for a static obstacle).
    pub velocity: Vec3Data,
}

impl Obstacle {
    /// A static obstacle.
    pub fn fixed(shape: Shape) -> Self {
        Obstacle { shape, velocity: [0.0; 3] }
    }
    /// What a proximity sensor reports about this obstacle seen from `p`:
    /// the closest surface point, the surface's outward normal there (not for a
    /// [`Shape::Point`]) and the obstacle's velocity.
    pub fn observe(&self, p: &Vec3, id: u16) -> ObstaclePoint {
        let (point, sd) = self.shape.closest_point(p);
        let normal = self.shape.surface_normal(p, &point, sd);
        ObstaclePoint { point, velocity: Some(v(&self.velocity)), id, normal }
    }
}

/// The outward unit normal of a convex solid's surface at its closest point `q` to `p`,
/// given the signed distance `sd` (negative inside): `(p − q)/|p − q|` outside, the
/// opposite inside; `None` when `p` is on the surface (no direction).
pub fn surface_normal(p: &Vec3, q: &Vec3, sd: f32) -> Option<Vec3> {
    let d = p - q;
    let r = norm3(&d);
    // r ≤ 1e-6 or NaN: no direction.
    if r.is_nan() || r <= 1.0e-6 || !sd.is_finite() {
        return None;
    }
    Some(if sd < 0.0 { -d / r } else { d / r })
}

/// One obstacle as the safety filter sees it: the closest surface point `p̄`
/// to the vehicle (NED, m), when known the obstacle's velocity (NED, m/s) and, when the
/// point is the closest point of an extended surface whose shape the source knows, the
/// surface's outward normal there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObstaclePoint {
    /// Closest point of the obstacle's surface to the vehicle, NED, m.
    pub point: Vec3,
    /// Obstacle velocity, NED, m/s; `None` when unknown (treated as static).
    pub velocity: Option<Vec3>,
    /// Caller-chosen identifier, echoed in the filter diagnostics.
    pub id: u16,
    /// Outward unit normal of the obstacle's surface at `point` (NED), set by a source that
    /// reports `point` as the closest point of an extended convex obstacle (a wall, box,
    /// cylinder or sphere) and knows its shape. The default filter (not `paper`) then guards
    /// the obstacle's tangent half-space `{x : nᵀ(x − point) ≤ 0}`, which contains it, with
    /// the normal fixed however long the point is held (`docs/filter.md` §9). `None`: a
    /// point obstacle, or a surface point whose normal is unknown (the half-space is then
    /// aimed from where the vehicle was at the report).
    pub normal: Option<Vec3>,
}

impl ObstaclePoint {
    /// A static obstacle point.
    pub fn fixed(point: Vec3, id: u16) -> Self {
        ObstaclePoint { point, velocity: None, id, normal: None }
    }
    /// A static point of an extended surface with outward normal `normal` (NED, unit).
    pub fn surface(point: Vec3, normal: Vec3, id: u16) -> Self {
        ObstaclePoint { point, velocity: None, id, normal: Some(normal) }
    }
    /// `true` when the position and (if present) the velocity and the normal are finite.
    pub fn is_finite(&self) -> bool {
        is_finite3(&self.point)
            && self.velocity.is_none_or(|v| is_finite3(&v))
            && self.normal.is_none_or(|n| is_finite3(&n))
    }
}

/// Default capacity of an [`ObstacleSet`].
pub const DEFAULT_OBSTACLE_CAPACITY: usize = 32;

/// What [`ObstacleSet::insert_nearest`] did with an obstacle point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InsertOutcome {
    /// Stored in a free slot.
    Added,
    /// The set was full; the point replaced the farthest stored one.
    ReplacedFarthest,
    /// The set was full and every stored point is nearer: the point was dropped.
    DroppedFarther,
    /// The point (or the vehicle position) was not finite: dropped.
    RejectedNonFinite,
}

/// Fixed-capacity set of obstacle points for one control step.
///
/// Capacity `N` (default [`DEFAULT_OBSTACLE_CAPACITY`] = 32). **When full**,
/// [`insert_nearest`](Self::insert_nearest) keeps the `N` points nearest to the
/// vehicle: a nearer point replaces the farthest stored one, a farther point is
/// dropped. The filter only ever acts on the nearest barriers, so what is
/// dropped is what matters least; the outcome is reported to the caller.
#[derive(Clone, Debug, Default)]
pub struct ObstacleSet<const N: usize = DEFAULT_OBSTACLE_CAPACITY> {
    points: heapless::Vec<ObstaclePoint, N>,
}

impl<const N: usize> ObstacleSet<N> {
    /// An empty set.
    pub const fn new() -> Self {
        ObstacleSet { points: heapless::Vec::new() }
    }
    /// Remove every point.
    pub fn clear(&mut self) {
        self.points.clear();
    }
    /// Stored points.
    pub fn as_slice(&self) -> &[ObstaclePoint] {
        &self.points
    }
    /// The storage, for the selection policies of [`crate::obstacle_set`].
    pub(crate) fn points_mut(&mut self) -> &mut heapless::Vec<ObstaclePoint, N> {
        &mut self.points
    }
    /// Number of stored points.
    pub fn len(&self) -> usize {
        self.points.len()
    }
    /// `true` when no point is stored.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
    /// Insert `point`, keeping the `N` points nearest to the vehicle at `vehicle` (NED, m).
    /// Bounded: O(N).
    pub fn insert_nearest(&mut self, vehicle: &Vec3, point: ObstaclePoint) -> InsertOutcome {
        if !point.is_finite() || !is_finite3(vehicle) {
            return InsertOutcome::RejectedNonFinite;
        }
        match self.points.push(point) {
            Ok(()) => InsertOutcome::Added,
            Err(point) => {
                let d_new = (point.point - vehicle).norm_squared();
                let mut far = (0usize, f32::NEG_INFINITY);
                for (i, q) in self.points.iter().enumerate() {
                    let d = (q.point - vehicle).norm_squared();
                    if d > far.1 {
                        far = (i, d);
                    }
                }
                if d_new < far.1 {
                    self.points[far.0] = point;
                    InsertOutcome::ReplacedFarthest
                } else {
                    InsertOutcome::DroppedFarther
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).norm() < 1e-5
    }

    #[test]
    fn sphere_closest_point_and_distance() {
        let s = Shape::sphere(Vec3::new(1.0, 0.0, 0.0), 0.5);
        let (q, d) = s.closest_point(&Vec3::new(3.0, 0.0, 0.0));
        assert!(close(q, Vec3::new(1.5, 0.0, 0.0)));
        assert!((d - 1.5).abs() < 1e-6);
        assert!((s.signed_distance(&Vec3::new(1.25, 0.0, 0.0)) + 0.25).abs() < 1e-6);
    }

    #[test]
    fn box_outside_edge_and_inside() {
        let b = Shape::aabb(Vec3::new(1.0, 1.0, -2.0), Vec3::new(0.0, 0.0, 0.0));
        // Outside, nearest to an edge.
        let (q, d) = b.closest_point(&Vec3::new(2.0, 2.0, -1.0));
        assert!(close(q, Vec3::new(1.0, 1.0, -1.0)));
        assert!((d - 2f32.sqrt()).abs() < 1e-5);
        // Inside: exits through the nearest face (x = 1).
        let (q, d) = b.closest_point(&Vec3::new(0.9, 0.5, -1.0));
        assert!(close(q, Vec3::new(1.0, 0.5, -1.0)));
        assert!((d + 0.1).abs() < 1e-5);
    }

    #[test]
    fn cylinder_extends_upwards_in_ned() {
        // Bottom disc on the ground (z = 0), 1.8 m tall: top at z = -1.8.
        let c = Shape::cylinder(Vec3::zeros(), 0.25, 1.8);
        assert!((c.signed_distance(&Vec3::new(1.0, 0.0, -1.0)) - 0.75).abs() < 1e-6);
        // Above the top.
        let (q, d) = c.closest_point(&Vec3::new(0.1, 0.0, -2.3));
        assert!(close(q, Vec3::new(0.1, 0.0, -1.8)));
        assert!((d - 0.5).abs() < 1e-5);
        // Below ground (z > 0) is outside too.
        assert!(c.signed_distance(&Vec3::new(0.0, 0.0, 0.5)) > 0.49);
        // Inside, near the side.
        let (q, d) = c.closest_point(&Vec3::new(0.2, 0.0, -1.0));
        assert!(close(q, Vec3::new(0.25, 0.0, -1.0)));
        assert!((d + 0.05).abs() < 1e-5);
    }

    #[test]
    fn observe_reports_the_surface_normal_of_extended_shapes_only() {
        let wall = Obstacle::fixed(Shape::aabb(Vec3::new(2.0, -5.0, -3.0), Vec3::new(2.2, 5.0, 0.0)));
        let o = wall.observe(&Vec3::new(1.7, 0.4, -1.0), 4);
        assert!(close(o.point, Vec3::new(2.0, 0.4, -1.0)) && o.id == 4);
        assert!(close(o.normal.unwrap(), Vec3::new(-1.0, 0.0, 0.0)));
        // Inside (0.05 m past the face): still the outward normal of the exit face.
        let o = wall.observe(&Vec3::new(2.05, 0.4, -1.0), 4);
        assert!(close(o.normal.unwrap(), Vec3::new(-1.0, 0.0, 0.0)), "{:?}", o.normal);
        let ball = Obstacle::fixed(Shape::sphere(Vec3::zeros(), 0.5));
        assert!(close(ball.observe(&Vec3::new(0.0, 2.0, 0.0), 1).normal.unwrap(), Vec3::y()));
        // A point has no surface; on the surface there is no direction.
        assert_eq!(Obstacle::fixed(Shape::point(Vec3::zeros())).observe(&Vec3::x(), 1).normal, None);
        assert_eq!(ball.observe(&Vec3::new(0.5, 0.0, 0.0), 1).normal, None);
        let bad = ObstaclePoint {
            normal: Some(Vec3::new(f32::NAN, 0.0, 0.0)),
            ..ObstaclePoint::fixed(Vec3::x(), 1)
        };
        assert!(!bad.is_finite());
    }

    #[test]
    fn set_keeps_nearest_when_full() {
        let mut s: ObstacleSet<2> = ObstacleSet::new();
        let o = Vec3::zeros();
        assert_eq!(
            s.insert_nearest(&o, ObstaclePoint::fixed(Vec3::new(3.0, 0.0, 0.0), 3)),
            InsertOutcome::Added
        );
        assert_eq!(
            s.insert_nearest(&o, ObstaclePoint::fixed(Vec3::new(2.0, 0.0, 0.0), 2)),
            InsertOutcome::Added
        );
        assert_eq!(
            s.insert_nearest(&o, ObstaclePoint::fixed(Vec3::new(1.0, 0.0, 0.0), 1)),
            InsertOutcome::ReplacedFarthest
        );
        assert_eq!(
            s.insert_nearest(&o, ObstaclePoint::fixed(Vec3::new(9.0, 0.0, 0.0), 9)),
            InsertOutcome::DroppedFarther
        );
        let mut ids: heapless::Vec<u16, 2> = s.as_slice().iter().map(|p| p.id).collect();
        ids.sort_unstable();
        assert_eq!(&ids[..], &[1, 2]);
        assert_eq!(
            s.insert_nearest(&o, ObstaclePoint::fixed(Vec3::new(f32::NAN, 0.0, 0.0), 7)),
            InsertOutcome::RejectedNonFinite
        );
    }
}
