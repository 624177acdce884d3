//! The in-flight speed governor (issue 36): limits the velocity towards every direction so
//! the vehicle can stop inside space observed free, in every flight mode that goes through
//! the PD tracker (mission, hold, position-assist, offboard, return, brake, land; not Manual).
//!
//! **Stopping speed.** From PX4's collision prevention (`CollisionPrevention.cpp`,
//! `_getMaxSpeedFromDistance`): the largest speed `v` from which braking at `a` after a dead
//! time `τ` ends within `d`, `v² + 2aτ·v = 2a·d`, i.e.
//! `v*(d) = √((aτ)² + 2a·d) − aτ` (PX4's `v² + (4a²/j)·v = 2a(d − CP_DIST − v·(CP_DELAY + age))`
//! with the jerk term folded into `τ`; the issue's `v* = √(2a(R − margin)) − aτ` is a
//! slightly lower approximation of the same root). `a` = the braking deceleration the filter
//! assumes, `min(CBF_BRAKE_ACC, g·tan(tilt_max))`; `τ` = `CBF_BRAKE_DLY` (actuation lag and
//! sensing latency) + `GOV_DELAY` (further latency) + the age of the obstacle data.
//!
//! **Directions and distances** ([`govern`]), `r` the hull radius, `m` = `GOV_MARGIN`:
//! * every obstacle point `q` the filter is given: towards it (`n = (q − p)/|q − p|`, or
//!   `−normal` for a surface point, whose tangent plane is then the obstacle), at
//!   `d = |q − p| − r − m` (resp. `normalᵀ(p − q) − r − m`), with the relative velocity for a
//!   moving point. The memory's frontier point and walls (`crate::perception::frontier`) are
//!   such points: a direction the sensors have not observed counts as blocked at the free
//!   range `D(u)` last observed along it (cause [`GovernorCause::Unseen`]);
//! * the sensing range `R` (`GOV_RANGE`): along the current direction of motion (3-D), free at
//!   most to `d = R − r − m` (cause [`GovernorCause::Range`]). With ground-truth perception
//!   (the map is the sensor) this is the only limit until an obstacle comes into range.
//!
//! Vertically: obstacle points above or below count like any other (their direction is
//! 3-D) and the range limit applies to the 3-D speed; the ground and the ceiling are not
//! points (they are the plant-aware barriers' business, `crate::plant_aware`), and a planar
//! lidar gives no frontier above or below its plane: what it cannot see vertically is limited
//! only by `R`. The pre-flight coverage check names that gap (host `sim::coverage`).
//!
//! **Enforcement.** Each direction `n` with limit `w = v*(d)` and speed `s = nᵀ(ṗ − v̄)` gives
//! the half-space `nᵀu ≤ k·(w − s) − w′(d)·s⁺` on the nominal acceleration (`k` = [`GAIN`],
//! `w′ = a/(w + aτ)`): a first-order barrier on the velocity, `ḣ ≥ −k·h` for `h = w(d) − s`
//! with `ḋ = −s` (static point; the centripetal part dropped), so a speed over the limit is
//! braked, one under it may approach it no faster than `k·(w − s)`, and on the limit the
//! vehicle brakes along the stopping curve itself at `w′·w = a·w/(w + aτ) < a` (it reaches the
//! margin only asymptotically, `d` decaying at the rate `1/τ`; without the `w′` term the loop
//! is a damped oscillator that overshoots into the margin). The range's distance moves with
//! the vehicle (`w′ = 0`). The [`MAX_ACTIVE`] tightest
//! half-spaces (smallest slack at the nominal command) are enforced at once by the exact
//! projection of [`super::qp3`] (with the braking input `−k·ṗ`, which satisfies every static
//! one, as the reference point). O(points), no allocation, no panics; disabled
//! (`GOV_ENABLE` 0) it returns the command unchanged.
//!
//! Owns [`GovernorParams`], [`GovernorTelemetry`], [`GovernorCause`], [`stop_speed`],
//! [`govern`].
//!
//! May import: [`super::obstacle`], [`super::qp3`], the crate root foundation.

use super::obstacle::ObstaclePoint;
use super::qp3::{project, HalfSpace};
use crate::fmath::{atan2_approx, maxf, sqrtf};
use crate::param_decl::{field, flag, on_off, Has, Param};
use crate::Vec3;

/// Rate `k` of the velocity barrier, 1/s.
pub const GAIN: f32 = 5.0;
/// Half-spaces enforced at once.
pub const MAX_ACTIVE: usize = 4;
/// The identifier the obstacle memory gives its frontier point and walls
/// (`crate::perception::FRONTIER_ID`; equal, checked by a test).
pub const UNSEEN_ID: u16 = 65_534;
/// Below this speed there is no direction of motion (no range limit, no reported limit), m/s.
const MIN_SPEED: f32 = 0.05;

/// The governor's parameters (`GOV_*`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GovernorParams {
    /// On (`GOV_ENABLE` 1, the default since stop 51) or off. The outer loop does not run it
    /// under the paper's guidance (`MIS_GUIDANCE` 0), which flies the paper's method unchanged.
    pub enable: bool,
    /// Distance kept beyond the hull when stopped, m (`GOV_MARGIN`, [0, 2]). Default 0.05: the
    /// offline planner's clearance beyond the hull, so a planned path never asks the governor
    /// to stop short of it (0.1 stalled a mission in the office, docs/filter.md § 17).
    pub margin: f32,
    /// Latency added to the braking delay, s (`GOV_DELAY`, [0, 1]).
    pub delay: f32,
    /// Sensing range `R`, m (`GOV_RANGE`, [0.5, 100]).
    pub range: f32,
}

impl Default for GovernorParams {
    fn default() -> Self {
        GovernorParams { enable: true, margin: 0.05, delay: 0.05, range: 3.0 }
    }
}

impl GovernorParams {
    /// The speed governor's parameters (issue 36; `crate::params`, MAVLink `param_index` order).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 4] {
        [
            Param::new("GOV_ENABLE", "Governor", "", (0.0, 1.0), 0, flag!(enable),
                "Speed governor: 1 limits the speed towards each direction to what can stop inside observed free space (not with MIS_GUIDANCE 0; docs/filter.md)").code(on_off),
            Param::new("GOV_MARGIN", "Governor", "m", (0.0, 2.0), 2, field!(margin),
                "Speed governor: distance kept beyond the hull radius when stopped"),
            Param::new("GOV_DELAY", "Governor", "s", (0.0, 1.0), 3, field!(delay),
                "Speed governor: latency added to CBF_BRAKE_DLY (plus the obstacle data age) before braking"),
            Param::new("GOV_RANGE", "Governor", "m", (0.5, 100.0), 1, field!(range),
                "Speed governor: sensing range; space beyond it counts as blocked (set from the sensors by the simulator)"),
        ]
    }
}

impl GovernorParams {
    /// Every field finite and within its table range.
    pub fn valid(&self) -> bool {
        (0.0..=2.0).contains(&self.margin)
            && (0.0..=1.0).contains(&self.delay)
            && (0.5..=100.0).contains(&self.range)
    }
}

/// What limits the speed along the direction of motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum GovernorCause {
    /// Nothing (off, not moving, or no direction limits the motion).
    #[default]
    None = 0,
    /// The sensing range `R`.
    Range = 1,
    /// An observed obstacle point.
    Obstacle = 2,
    /// The end of the observed free space (frontier point or wall).
    Unseen = 3,
    /// The limit's direction as `Obstacle`/`Unseen`/`Range`, but the data age is the larger part of `τ`.
    DataAge = 4,
}

impl GovernorCause {
    /// Every cause, in code order.
    pub const ALL: [GovernorCause; 5] = [
        GovernorCause::None,
        GovernorCause::Range,
        GovernorCause::Obstacle,
        GovernorCause::Unseen,
        GovernorCause::DataAge,
    ];

    /// The cause with code `code` (its `repr(u8)` value), if any.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|c| *c as u8 == code)
    }
}

/// The governor's output for telemetry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GovernorTelemetry {
    /// Speed allowed along the current direction of motion, m/s (`+∞`: no limit).
    pub limit: f32,
    /// What sets [`limit`](Self::limit).
    pub cause: GovernorCause,
    /// NED bearing of the limiting direction, rad (0 without one).
    pub bearing: f32,
    /// The governor changed the nominal command.
    pub active: bool,
    /// What it took off: nominal minus governed command, m/s² (NED).
    pub cut: Vec3,
}

impl Default for GovernorTelemetry {
    fn default() -> Self {
        GovernorTelemetry {
            limit: f32::INFINITY,
            cause: GovernorCause::None,
            bearing: 0.0,
            active: false,
            cut: Vec3::zeros(),
        }
    }
}

/// What the governor needs of the vehicle: braking deceleration `a` (m/s², > 0), the
/// braking delay without the data age (s) and the hull radius (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vehicle {
    /// Braking deceleration `a`, m/s².
    pub accel: f32,
    /// `CBF_BRAKE_DLY + GOV_DELAY`, s.
    pub delay: f32,
    /// Hull radius, m.
    pub hull_radius: f32,
}

/// `v*(d) = √((aτ)² + 2a·d) − aτ` (0 for `d ≤ 0`), m/s. Its slope is
/// `dv*/dd = a/(v* + aτ)` (from `2v·v′ + 2aτ·v′ = 2a`).
pub fn stop_speed(d: f32, a: f32, tau: f32) -> f32 {
    let at = a * tau;
    maxf(sqrtf(at * at + 2.0 * a * maxf(d, 0.0)) - at, 0.0)
}

#[derive(Clone, Copy)]
struct Limit {
    n: Vec3,
    slack: f32,
}

/// The governed command for the nominal acceleration `u` at position `p`, velocity `v`
/// (NED), obstacle data `age_s` old (see the module docs). Non-finite input or an
/// infeasible projection returns `u` unchanged.
pub fn govern(
    params: &GovernorParams,
    veh: &Vehicle,
    p: &Vec3,
    v: &Vec3,
    u: &Vec3,
    obstacles: &[ObstaclePoint],
    age_s: f32,
) -> (Vec3, GovernorTelemetry) {
    let mut tel = GovernorTelemetry::default();
    if !params.enable || ![p, v, u].iter().all(|x| x.iter().all(|c| c.is_finite())) {
        return (*u, tel);
    }
    let age = if age_s.is_finite() { maxf(age_s, 0.0) } else { 0.0 };
    let tau = veh.delay + age;
    let a = veh.accel;
    let keep = veh.hull_radius + params.margin;
    let speed = v.norm();
    let dir = (speed > MIN_SPEED).then(|| v / speed);

    let mut active = [None::<Limit>; MAX_ACTIVE];
    let mut best = (f32::INFINITY, GovernorCause::None, 0.0f32);
    let mut consider = |n: Vec3, (w, dw): (f32, f32), s: f32, cause: GovernorCause| {
        // Speed allowed along the direction of motion by this direction's limit.
        if let Some(m) = dir {
            let c = n.dot(&m);
            if c > 0.1 && w / c < best.0 {
                best = (w / c, cause, atan2_approx(n.y, n.x));
            }
        }
        let slack = GAIN * (w - s) - dw * maxf(s, 0.0) - n.dot(u);
        let new = Limit { n, slack };
        // Keep the MAX_ACTIVE smallest slacks (insertion, bounded).
        let mut cur = Some(new);
        for slot in active.iter_mut() {
            match (cur, *slot) {
                (Some(c), None) => {
                    *slot = Some(c);
                    cur = None;
                }
                (Some(c), Some(o)) if c.slack < o.slack => {
                    *slot = Some(c);
                    cur = Some(o);
                }
                _ => {}
            }
        }
    };
    if let Some(m) = dir {
        // The range moves with the vehicle: its distance does not shrink (dw = 0).
        consider(m, (stop_speed(params.range - keep, a, tau), 0.0), speed, GovernorCause::Range);
    }
    for o in obstacles {
        let (n, dist) = match o.normal {
            Some(nrm) => (-nrm, nrm.dot(&(p - o.point))),
            None => {
                let d = o.point - p;
                let l = d.norm();
                if l.is_nan() || l <= 1e-5 {
                    continue;
                }
                (d / l, l)
            }
        };
        if !(dist.is_finite() && n.iter().all(|c| c.is_finite())) {
            continue;
        }
        let rel = v - o.velocity.unwrap_or_else(Vec3::zeros);
        let cause = if o.id == UNSEEN_ID { GovernorCause::Unseen } else { GovernorCause::Obstacle };
        let w = stop_speed(dist - keep, a, tau);
        consider(n, (w, a / (w + a * tau)), n.dot(&rel), cause);
    }
    if best.0.is_finite() {
        let cause = if age > veh.delay { GovernorCause::DataAge } else { best.1 };
        tel = GovernorTelemetry { limit: best.0, cause, bearing: best.2, ..tel };
    }
    let mut cons = [HalfSpace { n: Vec3::zeros(), c: 0.0 }; MAX_ACTIVE];
    let mut k = 0;
    for l in active.iter().flatten() {
        if let Some(c) = cons.get_mut(k) {
            // nᵀu ≤ k(w − s)  ⇔  (−n)ᵀu ≥ −(nᵀu + slack).
            *c = HalfSpace { n: -l.n, c: -(l.n.dot(u) + l.slack) };
            k += 1;
        }
    }
    if active.iter().flatten().all(|l| l.slack >= 0.0) {
        return (*u, tel);
    }
    let sol = project(u, cons.get(..k).unwrap_or(&[]), &(-v * GAIN));
    if !sol.u.iter().all(|c| c.is_finite()) {
        return (*u, tel);
    }
    tel.active = true;
    tel.cut = u - sol.u;
    (sol.u, tel)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn veh() -> Vehicle {
        Vehicle { accel: 3.0, delay: 0.15, hull_radius: 0.2236 }
    }

    fn on() -> GovernorParams {
        GovernorParams { enable: true, ..GovernorParams::default() }
    }

    #[test]
    fn stop_speed_solves_the_braking_equation() {
        for &(d, a, tau) in &[(2.7f32, 3.0f32, 0.1f32), (0.5, 5.0, 0.3), (10.0, 2.0, 0.0)] {
            let v = stop_speed(d, a, tau);
            assert!((v * v + 2.0 * a * tau * v - 2.0 * a * d).abs() < 1e-4 * (1.0 + d), "{d} {a} {tau}");
        }
        assert_eq!(stop_speed(-1.0, 3.0, 0.1), 0.0);
        // The figure: R = 3 m, a = 3 m/s², τ = 0.1 s: about 3.6 m/s (√(2aR) − aτ = 3.94).
        let v = stop_speed(3.0, 3.0, 0.1);
        assert!((v - 3.95).abs() < 0.05, "{v}");
    }

    #[test]
    fn off_returns_the_command() {
        let u = Vec3::new(3.0, 0.0, 0.0);
        let (g, t) = govern(
            &GovernorParams { enable: false, ..GovernorParams::default() },
            &veh(),
            &Vec3::zeros(),
            &Vec3::new(9.0, 0.0, 0.0),
            &u,
            &[],
            0.0,
        );
        assert_eq!(g, u);
        assert_eq!(t, GovernorTelemetry::default());
    }

    #[test]
    fn over_the_range_limit_it_brakes() {
        let p = on();
        let w = stop_speed(p.range - veh().hull_radius - p.margin, 3.0, 0.15);
        let v = Vec3::new(w + 1.0, 0.0, 0.0);
        let u = Vec3::new(2.0, 0.5, 0.0);
        let (g, t) = govern(&p, &veh(), &Vec3::zeros(), &v, &u, &[], 0.0);
        assert!(t.active && t.cause == GovernorCause::Range);
        assert!((t.limit - w).abs() < 1e-4, "{} {w}", t.limit);
        assert!((g.x - GAIN * (w - v.x)).abs() < 1e-3, "{g:?}");
        assert!((g.y - 0.5).abs() < 1e-5, "the cross component is kept: {g:?}");
        // Below the limit, a small acceleration passes unchanged.
        let v = Vec3::new(w - 1.0, 0.0, 0.0);
        let (g, t) = govern(&p, &veh(), &Vec3::zeros(), &v, &u, &[], 0.0);
        assert!(!t.active && g == u);
    }

    #[test]
    fn an_obstacle_ahead_limits_the_approach_not_the_motion_beside_it() {
        let p = on();
        let wall = ObstaclePoint::surface(Vec3::new(1.5, 0.0, 0.0), Vec3::new(-1.0, 0.0, 0.0), 1);
        let w = stop_speed(1.5 - veh().hull_radius - p.margin, 3.0, 0.15);
        let v = Vec3::new(w + 0.5, 0.0, 0.0);
        let (g, t) = govern(&p, &veh(), &Vec3::zeros(), &v, &Vec3::zeros(), &[wall], 0.0);
        assert!(t.active && t.cause == GovernorCause::Obstacle && (t.limit - w).abs() < 1e-4);
        assert!(g.x < -2.0, "{g:?}");
        // Flying along the wall (parallel) at 1 m/s: untouched.
        let (g, t) = govern(
            &p,
            &veh(),
            &Vec3::zeros(),
            &Vec3::new(0.0, 1.0, 0.0),
            &Vec3::new(0.0, 1.0, 0.0),
            &[wall],
            0.0,
        );
        assert!(!t.active && g == Vec3::new(0.0, 1.0, 0.0));
        // An unseen-space point (the memory's frontier) is named as such; old data as the age.
        let f = ObstaclePoint { id: UNSEEN_ID, ..wall };
        let (_, t) = govern(&p, &veh(), &Vec3::zeros(), &v, &Vec3::zeros(), &[f], 0.0);
        assert_eq!(t.cause, GovernorCause::Unseen);
        let (_, t) = govern(&p, &veh(), &Vec3::zeros(), &v, &Vec3::zeros(), &[f], 0.5);
        assert_eq!(t.cause, GovernorCause::DataAge);
        assert!(t.limit < w, "older data, lower limit");
    }

    #[test]
    fn the_frontier_id_is_the_memorys() {
        assert_eq!(UNSEEN_ID, crate::perception::FRONTIER_ID);
    }

    /// Closed loop (point mass, a = GAIN-governed command, 250 Hz) at a wall 6 m ahead with
    /// the nominal command pushing at the filter's limit: the vehicle stops short of the hull.
    #[test]
    fn a_point_mass_pushed_at_a_wall_stops_before_it() {
        let p = on();
        let wall_x = 6.0;
        let (mut x, mut vx) = (0.0f32, 4.0f32);
        for _ in 0..2500 {
            let wall = ObstaclePoint::surface(Vec3::new(wall_x, 0.0, 0.0), Vec3::new(-1.0, 0.0, 0.0), 1);
            let pos = Vec3::new(x, 0.0, 0.0);
            let (g, _) =
                govern(&p, &veh(), &pos, &Vec3::new(vx, 0.0, 0.0), &Vec3::new(6.0, 0.0, 0.0), &[wall], 0.0);
            let ax = g.x.clamp(-6.0, 6.0);
            vx += ax * 0.004;
            x += vx * 0.004;
        }
        assert!(x < wall_x - veh().hull_radius, "{x}");
        assert!(x > wall_x - veh().hull_radius - p.margin - 0.05, "stops near the margin: {x}");
    }
}
