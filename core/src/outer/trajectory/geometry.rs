//! The flown curve: straight pieces of the legs joined at each corner by a symmetric quintic
//! Bézier blend (curvature-continuous), with its arc-length table, deviation bound, maximum
//! curvature and speed limit.
//!
//! ## The corner blend
//! At corner `C` with incoming unit direction `d₀`, outgoing `d₁` and turn angle
//! `θ = acos(d₀·d₁)`, the blend is the quintic Bézier with control points
//! `P₀ = C − L·d₀, P₁ = C − L/2·d₀, P₂ = P₃ = C, P₄ = C + L/2·d₁, P₅ = C + L·d₁`
//! (`L` = the length it takes from each leg). `P₀, P₁, P₂` lie on the incoming line and
//! `P₃, P₄, P₅` on the outgoing one, so the curve leaves and joins the legs tangentially
//! **with zero curvature**: curvature is continuous along the whole path (G²). In closed form
//! (derivation in `docs/cascade.md`):
//! * deviation from the corner (at `t = ½`, the farthest point): `|B(½) − C| = (7/32)·L·sin(θ/2)`;
//!   every point of the blend is at least as close to the polyline as that;
//! * maximum curvature (at `t = ½`; checked numerically on a dense grid of `t` and `θ`):
//!   `κ_max = 3.072·sin(θ/2) / (L·cos²(θ/2))`;
//! * `L = min(tol / ((7/32)·sin(θ/2)), ½·leg_in, ½·leg_out)`, so the blend never cuts the
//!   corner by more than the tolerance and never uses more than half of either leg.
//!
//! The blend's speed limit is `√(A/κ_max)` (lateral acceleration `≤ A`) and the axis limits
//! over the blend's directions (the great-circle arc from `d₀` to `d₁`). A turn of
//! (nearly) 180° or a zero tolerance makes a **stop corner**: no blend, speed 0 at `C`.
//!
//! Arc length along a blend: a table of [`TABLE_INTERVALS`]` + 1` cumulative lengths at
//! nodes in `t` that are denser near the middle ([`node`]; 3-point Gauss-Legendre per
//! interval) and cubic Hermite interpolation of `t(σ)` between the nodes (the node slopes are
//! `1/|B'(tᵢ)|`).
//!
//! Owns only geometry; imports [`crate::fmath`] and [`crate::Vec3`].

use crate::fmath::{maxf, minf, sqrtf};
use crate::Vec3;

/// Intervals of a blend's arc-length table.
pub(crate) const TABLE_INTERVALS: usize = 16;

/// Blends turning less than this (rad) are flown as straight: the velocity direction changes
/// by at most this angle without a blend (≤ 20 µm/s at 20 m/s).
pub(crate) const STRAIGHT_ANGLE: f32 = 1.0e-6;

/// `cos` of the sharpest turn that is blended (160°); sharper turns stop at the corner. Up
/// to it the blend's arc-length parameterisation is within 1 % (test
/// `arc_length_parameterisation_is_accurate_up_to_the_sharpest_blend`), and such blends crawl
/// anyway (`v_c ≈ 0.1·√(A·L)` at 160°).
pub(crate) const SHARPEST_BLEND_COS: f32 = -0.939_692_6;

/// A blend is replaced by a stop corner when its estimated time exceeds this many times the
/// stop's: a smooth pass is worth some time (at 90° and the default limits a blend is about
/// 1.3 times the stop's estimate).
pub(crate) const STOP_PREFERENCE: f32 = 1.5;

/// Blends shorter than this (m, `L`) are replaced by a stop corner.
pub(crate) const MIN_BLEND: f32 = 1.0e-4;

/// Deviation of the blend from its corner per unit `L` and unit `sin(θ/2)`: `(1 + 5a)/16`
/// with `a = ½`.
pub(crate) const DEVIATION_FACTOR: f32 = 7.0 / 32.0;

/// Maximum curvature times `L·cos²(θ/2)/sin(θ/2)`: `12.8·(1 + a)/(1 + 3a)²` with `a = ½`.
pub(crate) const CURVATURE_FACTOR: f32 = 3.072;

/// Speed limits per axis (all > 0), m/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct AxisLimits {
    /// Horizontal speed.
    pub horizontal: f32,
    /// Upward speed (−z NED).
    pub up: f32,
    /// Downward speed (+z NED).
    pub down: f32,
}

impl AxisLimits {
    /// Largest speed along directions whose horizontal part is at most `h`, upward (−z) part
    /// at most `up` and downward part at most `down` (all unit-direction components, ≥ 0).
    fn speed(&self, h: f32, up: f32, down: f32) -> f32 {
        let mut v = f32::INFINITY;
        if h > 0.0 {
            v = minf(v, self.horizontal / h);
        }
        if up > 0.0 {
            v = minf(v, self.up / up);
        }
        if down > 0.0 {
            v = minf(v, self.down / down);
        }
        v
    }

    /// Speed limit along the unit direction `d`.
    pub fn along(&self, d: &Vec3) -> f32 {
        let h = sqrtf(d.x * d.x + d.y * d.y);
        self.speed(h, maxf(-d.z, 0.0), maxf(d.z, 0.0))
    }

    /// Speed limit along every direction of the shorter great-circle arc from `d0` to `d1`
    /// (the blend's tangents), exactly: the vertical component along the arc is
    /// `R·cos(φ − φ*)`, whose extremes are at the ends or at `φ*` when it lies on the arc.
    pub fn along_arc(&self, d0: &Vec3, d1: &Vec3, cos_theta: f32) -> f32 {
        let perp = d1 - d0 * cos_theta;
        let pn = sqrtf(perp.norm_squared());
        let (mut zmax, mut zmin) = (maxf(d0.z, d1.z), minf(d0.z, d1.z));
        if pn > 1e-12 {
            let ez = perp.z / pn;
            let r = sqrtf(d0.z * d0.z + ez * ez);
            if r > 0.0 {
                if ez >= 0.0 && d0.z / r >= cos_theta {
                    zmax = r;
                }
                if ez <= 0.0 && -d0.z / r >= cos_theta {
                    zmin = -r;
                }
            }
        }
        let zmin_abs = if zmax >= 0.0 && zmin <= 0.0 { 0.0 } else { minf(zmax.abs(), zmin.abs()) };
        let h = sqrtf(maxf(1.0 - zmin_abs * zmin_abs, 0.0));
        self.speed(h, maxf(-zmin, 0.0), maxf(zmax, 0.0))
    }
}

/// A straight leg between two waypoints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Leg {
    /// Start waypoint, NED m.
    pub from: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    /// Length, m.
    pub length: f32,
    /// Speed limit along it (axis limits), m/s.
    pub limit: f32,
}

/// A corner (an interior waypoint) and its blend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Corner {
    /// The waypoint, NED m.
    pub at: Vec3,
    /// Incoming unit direction.
    pub d0: Vec3,
    /// Outgoing unit direction.
    pub d1: Vec3,
    /// Length taken from each leg, m (0 for a stop corner or a straight one).
    pub half: f32,
    /// `cos θ` (θ the turn angle).
    pub cos_theta: f32,
    /// Arc length of the blend, m.
    pub arc: f32,
    /// Speed limit on the blend, m/s (0 at a stop corner).
    pub limit: f32,
    /// Stop at the corner (turn sharper than 160°, zero tolerance, or a blend slower than stopping).
    pub stop: bool,
    /// Cumulative arc length at `t = node(i)`, m.
    pub table: [f32; TABLE_INTERVALS + 1],
}

/// Quintic Bernstein weights of `P₀ + a·P₁` (incoming side) and `a·P₄ + P₅` (outgoing side)
/// relative to `C`, with `a = ½`: `B(t) − C = L·(−f_in·d₀ + f_out·d₁)`.
fn position_weights(t: f32) -> (f32, f32) {
    let u = 1.0 - t;
    let (t2, u2) = (t * t, u * u);
    let f_in = u2 * u2 * u + 0.5 * 5.0 * t * u2 * u2;
    let f_out = t2 * t2 * t + 0.5 * 5.0 * t2 * t2 * u;
    (f_in, f_out)
}

/// `B'(t)/(5L) = α·d₀ + β·d₁` (quartic Bernstein weights, `a = ½`).
fn tangent_weights(t: f32) -> (f32, f32) {
    let u = 1.0 - t;
    let (t2, u2) = (t * t, u * u);
    let alpha = 0.5 * u2 * u2 + 0.5 * 4.0 * t * u2 * u;
    let beta = 0.5 * 4.0 * t2 * t * u + 0.5 * t2 * t2;
    (alpha, beta)
}

/// `B''(t)/(20L) = γ·d₀ + δ·d₁` (cubic Bernstein weights of the second differences,
/// `(2a−1)d₀, −a·d₀, a·d₁, (1−2a)·d₁` with `a = ½`).
fn curvature_weights(t: f32) -> (f32, f32) {
    let u = 1.0 - t;
    let gamma = -0.5 * 3.0 * t * u * u;
    let delta = 0.5 * 3.0 * t * t * u;
    (gamma, delta)
}

/// Slope of [`node`] at the blend's middle (the nodes are this much denser there than uniform).
const NODE_MID_SLOPE: f32 = 0.25;

/// Bézier parameter of table node `i`: `t(u) = ½ + (u − ½)·(k + (1 − k)·4(u − ½)²)` with
/// `u = i/TABLE_INTERVALS` and `k` = [`NODE_MID_SLOPE`]: monotone, `t(0) = 0`, `t(1) = 1`, and
/// dense near `t = ½`, where `|B'|` dips (to `∝ cos(θ/2)` for sharp turns).
fn node(i: usize) -> f32 {
    let u = i as f32 / TABLE_INTERVALS as f32 - 0.5;
    0.5 + u * (NODE_MID_SLOPE + (1.0 - NODE_MID_SLOPE) * 4.0 * u * u)
}

/// `|B'(t)|` for a blend of half-length `half`.
fn speed_at(t: f32, half: f32, cos_theta: f32) -> f32 {
    let (al, be) = tangent_weights(t);
    5.0 * half * sqrtf(maxf(al * al + be * be + 2.0 * al * be * cos_theta, 0.0))
}

/// Time to change speed by `dv` (≥ 0) from and to zero acceleration, jerk-limited.
fn ramp_time(dv: f32, accel: f32, jerk: f32) -> f32 {
    if dv >= accel * accel / jerk {
        dv / accel + accel / jerk
    } else {
        2.0 * sqrtf(dv / jerk)
    }
}

/// Would a blend of arc length `arc` flown at `v_blend` take more than [`STOP_PREFERENCE`]
/// times as long as stopping at the corner? Both are estimated against cruising at `v_leg`:
/// the blend costs `arc/v_blend` plus the time lost slowing from and speeding back to
/// `v_leg` (`T·(v_leg − v_blend)/v_leg` for a jerk-limited change of duration `T`), the stop
/// `2·half/v_leg` plus the time lost by stopping (`T(v_leg)`). Sharp turns, whose blends crawl
/// (`κ_max` grows as `1/cos²(θ/2)`), stop and turn instead.
fn slower_than_stopping(arc: f32, v_blend: f32, half: f32, (accel, jerk): (f32, f32), v_leg: f32) -> bool {
    if v_blend <= 0.0 {
        return true;
    }
    let v_blend = minf(v_blend, v_leg);
    let blend = arc / v_blend + ramp_time(v_leg - v_blend, accel, jerk) * (v_leg - v_blend) / v_leg;
    let stop = 2.0 * half / v_leg + ramp_time(v_leg, accel, jerk);
    blend > STOP_PREFERENCE * stop
}

/// What the timing needs of a corner ahead: its blend's size and speed limit. The
/// trajectory keeps one per corner and rebuilds the full [`Corner`] (its arc-length table)
/// only for the corner being flown: [`Corner::new`] is a pure function of the legs, so the
/// rebuilt corner is bit-identical, and a path costs 20 bytes per corner instead of 124.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct CornerBrief {
    /// Length taken from each leg, m.
    pub half: f32,
    /// Arc length of the blend, m.
    pub arc: f32,
    /// Speed limit on the blend, m/s (0 at a stop corner).
    pub limit: f32,
    /// Stop at the corner.
    pub stop: bool,
}

impl Corner {
    /// The corner's [`CornerBrief`].
    pub fn brief(&self) -> CornerBrief {
        CornerBrief { half: self.half, arc: self.arc, limit: self.limit, stop: self.stop }
    }

    /// The corner at waypoint `at` between legs of directions `d0`, `d1` and lengths
    /// `len_in`, `len_out`, for the corner tolerance `tol` (m), the lateral acceleration
    /// bound `accel` (m/s²), the jerk bound `jerk` (m/s³) and the axis limits.
    pub fn new(
        at: Vec3,
        legs: (&Leg, &Leg),
        tol: f32,
        (accel, jerk): (f32, f32),
        axes: &AxisLimits,
    ) -> Corner {
        let (d0, d1) = (legs.0.dir, legs.1.dir);
        let cos_theta = d0.dot(&d1).clamp(-1.0, 1.0);
        let mut c = Corner {
            at,
            d0,
            d1,
            half: 0.0,
            cos_theta,
            arc: 0.0,
            limit: minf(legs.0.limit, legs.1.limit),
            stop: false,
            table: [0.0; TABLE_INTERVALS + 1],
        };
        // sin(θ/2), cos(θ/2) from cos θ.
        let s_half = sqrtf(maxf(0.5 * (1.0 - cos_theta), 0.0));
        let c_half = sqrtf(maxf(0.5 * (1.0 + cos_theta), 0.0));
        // 2·sin(θ/2) ≈ θ for small angles.
        if 2.0 * s_half < STRAIGHT_ANGLE {
            return c;
        }
        let reversal = cos_theta < SHARPEST_BLEND_COS;
        let half = minf(tol / (DEVIATION_FACTOR * s_half), 0.5 * minf(legs.0.length, legs.1.length));
        if reversal || half < MIN_BLEND {
            c.stop = true;
            c.limit = 0.0;
            return c;
        }
        c.half = half;
        let kappa_max = CURVATURE_FACTOR * s_half / (half * c_half * c_half);
        let lateral = sqrtf(accel / kappa_max);
        c.limit = minf(minf(lateral, axes.along_arc(&d0, &d1, cos_theta)), c.limit);
        // Arc-length table (3-point Gauss-Legendre on each interval).
        let g = 0.5 * sqrtf(0.6);
        let mut acc = 0.0f32;
        for i in 0..TABLE_INTERVALS {
            let (t0, t1) = (node(i), node(i + 1));
            let (h, mid) = (t1 - t0, 0.5 * (t0 + t1));
            let f = |x: f32| speed_at(x, half, cos_theta);
            let integral = h * (5.0 * f(mid - g * h) + 8.0 * f(mid) + 5.0 * f(mid + g * h)) / 18.0;
            acc += integral;
            if let Some(slot) = c.table.get_mut(i + 1) {
                *slot = acc;
            }
        }
        c.arc = acc;
        if slower_than_stopping(acc, c.limit, half, (accel, jerk), minf(legs.0.limit, legs.1.limit)) {
            c.stop = true;
            c.limit = 0.0;
            c.half = 0.0;
            c.arc = 0.0;
            c.table = [0.0; TABLE_INTERVALS + 1];
        }
        c
    }

    /// Bézier parameter `t` at arc length `sigma` (clamped into the blend).
    fn t_of(&self, sigma: f32) -> f32 {
        let sigma = sigma.clamp(0.0, self.arc);
        let mut i = 0usize;
        while i + 1 < TABLE_INTERVALS && self.table.get(i + 1).is_some_and(|&x| x <= sigma) {
            i += 1;
        }
        let s0 = self.table.get(i).copied().unwrap_or(0.0);
        let s1 = self.table.get(i + 1).copied().unwrap_or(self.arc);
        let ds = s1 - s0;
        let (t0, t1) = (node(i), node(i + 1));
        if ds <= 0.0 {
            return t0;
        }
        let x = ((sigma - s0) / ds).clamp(0.0, 1.0);
        // Hermite with slopes dt/dσ·ds = ds/|B'(tᵢ)|.
        let m0 = ds / maxf(speed_at(t0, self.half, self.cos_theta), 1e-12);
        let m1 = ds / maxf(speed_at(t1, self.half, self.cos_theta), 1e-12);
        let (x2, x3) = (x * x, x * x * x);
        let t = (2.0 * x3 - 3.0 * x2 + 1.0) * t0
            + (x3 - 2.0 * x2 + x) * m0
            + (-2.0 * x3 + 3.0 * x2) * t1
            + (x3 - x2) * m1;
        t.clamp(t0, t1)
    }

    /// Point, unit tangent and curvature vector `κ·N` at arc length `sigma` along the blend.
    pub fn eval(&self, sigma: f32) -> (Vec3, Vec3, Vec3) {
        let t = self.t_of(sigma);
        let (fi, fo) = position_weights(t);
        let p = self.at + (self.d1 * fo - self.d0 * fi) * self.half;
        let (al, be) = tangent_weights(t);
        let b1 = (self.d0 * al + self.d1 * be) * (5.0 * self.half);
        let n1 = sqrtf(b1.norm_squared());
        if n1 <= 0.0 {
            return (p, self.d0, Vec3::zeros());
        }
        let tangent = b1 / n1;
        let (ga, de) = curvature_weights(t);
        let b2 = (self.d0 * ga + self.d1 * de) * (20.0 * self.half);
        let normal = (b2 - tangent * b2.dot(&tangent)) / (n1 * n1);
        (p, tangent, normal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const AXES: AxisLimits = AxisLimits { horizontal: 3.0, up: 3.0, down: 1.5 };

    fn leg(from: Vec3, to: Vec3) -> Leg {
        leg_with(from, to, &AXES)
    }

    fn leg_with(from: Vec3, to: Vec3, axes: &AxisLimits) -> Leg {
        let d = to - from;
        let length = d.norm();
        Leg { from, dir: d / length, length, limit: axes.along(&(d / length)) }
    }

    fn right_angle(tol: f32) -> Corner {
        let (a, b, c) = (Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0), Vec3::new(10.0, 10.0, 0.0));
        Corner::new(b, (&leg(a, b), &leg(b, c)), tol, (3.0, 4.0), &AXES)
    }

    #[test]
    fn blend_deviation_curvature_and_arc_length_match_the_closed_forms() {
        let c = right_angle(0.1);
        let s_half = libm::sinf(core::f32::consts::FRAC_PI_4);
        assert!((c.half - 0.1 / (DEVIATION_FACTOR * s_half)).abs() < 1e-5);
        // The point nearest the corner is the middle, at the tolerance from it.
        let mut nearest = f32::INFINITY;
        let mut kmax = 0.0f32;
        for i in 0..=1000 {
            let (p, t, k) = c.eval(c.arc * i as f32 / 1000.0);
            nearest = nearest.min((p - c.at).norm());
            kmax = kmax.max(k.norm());
            assert!((t.norm() - 1.0).abs() < 1e-5);
        }
        assert!((nearest - 0.1).abs() < 1e-4, "{nearest}");
        let expected = CURVATURE_FACTOR * s_half / (c.half * 0.5);
        assert!((kmax - expected).abs() < 1e-3 * expected, "{kmax} vs {expected}");
        // Ends: on the legs, tangent to them, zero curvature.
        let (p0, t0, k0) = c.eval(0.0);
        assert!((p0 - Vec3::new(10.0 - c.half, 0.0, 0.0)).norm() < 1e-5);
        assert!((t0 - Vec3::x()).norm() < 1e-5 && k0.norm() < 1e-4);
        let (p1, t1, k1) = c.eval(c.arc);
        assert!((p1 - Vec3::new(10.0, c.half, 0.0)).norm() < 1e-4, "{p1:?}");
        assert!((t1 - Vec3::y()).norm() < 1e-4 && k1.norm() < 1e-3);
        // Arc length: the sum of chords over a fine grid of σ matches σ.
        let mut len = 0.0;
        let mut prev = p0;
        for i in 1..=2000 {
            let (p, _, _) = c.eval(c.arc * i as f32 / 2000.0);
            len += (p - prev).norm();
            prev = p;
        }
        assert!((len - c.arc).abs() < 1e-4 * c.arc, "{len} vs {}", c.arc);
        // Speed limit: lateral acceleration ≤ 3 m/s².
        assert!(c.limit * c.limit * expected <= 3.0 * 1.0001);
    }

    #[test]
    fn reversal_and_zero_tolerance_stop() {
        assert!(right_angle(0.0).stop);
        let (a, b) = (Vec3::zeros(), Vec3::new(5.0, 0.0, 0.0));
        let c = Corner::new(b, (&leg(a, b), &leg(b, a)), 0.5, (3.0, 4.0), &AXES);
        assert!(c.stop && c.limit == 0.0);
        let straight = Corner::new(b, (&leg(a, b), &leg(b, b * 2.0)), 0.5, (3.0, 4.0), &AXES);
        assert!(!straight.stop && straight.half == 0.0 && straight.limit == 3.0);
    }

    #[test]
    fn arc_axis_limits_see_the_vertical_middle_of_a_sharp_climb_turn() {
        // Up-and-north, then up-and-south: the middle of the turn is straight up.
        let d0 = Vec3::new(1.0, 0.0, -1.0).normalize();
        let d1 = Vec3::new(-1.0, 0.0, -1.0).normalize();
        let v = AXES.along_arc(&d0, &d1, d0.dot(&d1));
        assert!((v - 3.0).abs() < 1e-5, "{v}"); // up limit, straight up
        let d0 = Vec3::new(1.0, 0.0, 1.0).normalize();
        let d1 = Vec3::new(-1.0, 0.0, 1.0).normalize();
        assert!((AXES.along_arc(&d0, &d1, d0.dot(&d1)) - 1.5).abs() < 1e-5);
        // A horizontal turn: the horizontal limit.
        assert!((AXES.along_arc(&Vec3::x(), &Vec3::y(), 0.0) - 3.0).abs() < 1e-6);
    }

    #[test]
    fn arc_length_parameterisation_is_accurate_up_to_the_sharpest_blend() {
        // Slow legs so that even sharp turns keep their blends; 10 m legs, 1 m tolerance.
        let axes = AxisLimits { horizontal: 0.3, up: 0.3, down: 0.3 };
        for deg in [30.0f32, 60.0, 90.0, 120.0, 135.0, 150.0, 159.0] {
            let th = deg.to_radians();
            let (a, b) = (Vec3::new(-10.0, 0.0, 0.0), Vec3::zeros());
            let c = Vec3::new(10.0 * libm::cosf(th), 10.0 * libm::sinf(th), 0.0);
            let k = Corner::new(b, (&leg_with(a, b, &axes), &leg_with(b, c, &axes)), 1.0, (3.0, 4.0), &axes);
            assert!(!k.stop, "{deg}");
            // |Δp| over a small step of σ is the step: the speed ratio error of the reference.
            let n = 4000;
            let h = k.arc / n as f32;
            let mut worst = 0.0f32;
            for i in 0..n {
                let (p0, _, _) = k.eval(i as f32 * h);
                let (p1, _, _) = k.eval((i + 1) as f32 * h);
                worst = worst.max(((p1 - p0).norm() / h - 1.0).abs());
            }
            assert!(worst < 0.01, "{deg}°: {worst}");
            if deg <= 90.0 {
                assert!(worst < 0.0025, "{deg}°: {worst}");
            }
        }
        // 161°: a stop.
        let th = 161.0f32.to_radians();
        let c = Vec3::new(10.0 * libm::cosf(th), 10.0 * libm::sinf(th), 0.0);
        let (a, b) = (Vec3::new(-10.0, 0.0, 0.0), Vec3::zeros());
        assert!(
            Corner::new(b, (&leg_with(a, b, &axes), &leg_with(b, c, &axes)), 1.0, (3.0, 4.0), &axes).stop
        );
    }
}
