//! One obstacle of a scene and how it moves: [`SceneObstacle`] (shape as
//! written, NED) with its [`Motion`] (static, constant velocity, or piecewise
//! linear waypoints of its [`reference_point`]).
//!
//! Owns the obstacle type and its motion. May import: `parapet-core` (shapes),
//! [`super::frame`].

use nalgebra::Vector3;
use parapet_core::obstacle::Shape;

use super::frame::to_f32;

/// How an obstacle moves. Positions/velocities NED.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// Does not move.
    Static,
    /// Constant velocity from t = 0, m/s.
    Velocity(Vector3<f64>),
    /// Piecewise-linear trajectory of the reference point: `(t s, position m)`,
    /// times strictly increasing; held at the first/last point outside the range.
    Waypoints(Vec<(f64, Vector3<f64>)>),
}

/// One obstacle of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObstacle {
    /// Optional name from the file.
    pub name: Option<String>,
    /// Geometry as written in the file (converted to NED), i.e. at t = 0 for
    /// `Velocity` motion; for `Waypoints` the reference point is moved along the waypoints.
    pub shape: Shape,
    /// Motion.
    pub motion: Motion,
    /// Part of the map (`mapped`, default `true`). An unmapped obstacle is in the
    /// world — the sensors, the collision check and the reports see it — but not in
    /// what the vehicle is told beforehand: the planner, the mission and the
    /// pre-flight path check never see it ([`crate::world::scene::Scene::map_shapes`]).
    pub mapped: bool,
}

fn v3(a: &[f32; 3]) -> Vector3<f64> {
    Vector3::new(a[0] as f64, a[1] as f64, a[2] as f64)
}

/// Reference point of a shape (NED): sphere/point centre, box centre,
/// cylinder bottom-disc centre. Waypoints move this point.
pub fn reference_point(shape: &Shape) -> Vector3<f64> {
    match shape {
        Shape::Point { center } | Shape::Sphere { center, .. } => v3(center),
        Shape::Box { min, max } => (v3(min) + v3(max)) * 0.5,
        Shape::Cylinder { base, .. } => v3(base),
    }
}

impl SceneObstacle {
    /// `true` when the obstacle is static and part of the map: what an offline
    /// planner knows about.
    pub fn in_map(&self) -> bool {
        self.mapped && self.is_static()
    }

    /// `true` when the obstacle never moves.
    pub fn is_static(&self) -> bool {
        match &self.motion {
            Motion::Static => true,
            Motion::Velocity(v) => v.norm() == 0.0,
            Motion::Waypoints(w) => w.len() < 2 || w.windows(2).all(|p| p[0].1 == p[1].1),
        }
    }

    /// The obstacle's shape (NED) and velocity (NED, m/s) at time `t` (s).
    pub fn at(&self, t: f64) -> (Shape, Vector3<f64>) {
        match &self.motion {
            Motion::Static => (self.shape, Vector3::zeros()),
            Motion::Velocity(v) => (self.shape.translated(to_f32(&(v * t))), *v),
            Motion::Waypoints(w) => {
                let (p, v) = interpolate(w, t);
                let off = p - reference_point(&self.shape);
                (self.shape.translated(to_f32(&off)), v)
            }
        }
    }
}

fn interpolate(w: &[(f64, Vector3<f64>)], t: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (first, last) = (w[0], w[w.len() - 1]);
    if t <= first.0 || w.len() == 1 {
        return (first.1, Vector3::zeros());
    }
    if t >= last.0 {
        return (last.1, Vector3::zeros());
    }
    for seg in w.windows(2) {
        let ((t0, p0), (t1, p1)) = (seg[0], seg[1]);
        if t >= t0 && t < t1 {
            let v = (p1 - p0) / (t1 - t0);
            return (p0 + v * (t - t0), v);
        }
    }
    (last.1, Vector3::zeros())
}
