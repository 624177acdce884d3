//! The braking-distance barrier (filter variant [`FilterVariant::Braking`], issue 36): a
//! barrier whose look-ahead is what the vehicle needs to stop, instead of the paper's fixed
//! `μ`. Derivation and guarantee: `docs/filter.md` § Braking-distance barrier.
//!
//! For an obstacle point `p̄` with velocity `v̄` (relative velocity, as `multi-relative`),
//! `d = p − p̄`, `n = d/|d|`, the approach speed `s = −nᵀ(ṗ − v̄) + ε_v` and the hull radius
//! `r = √δ`:
//!
//! * barrier `h_b = |d| − r − φ(s)`, `φ(s) = s⁺²/(2a_b) + τ·s⁺` (`s⁺ = max(s, 0)`): the
//!   distance left after braking at `a_b` (m/s², [`CbfParams::brake_accel`]) once the
//!   command takes effect after `τ` (s, [`CbfParams::brake_delay`]: actuation lag and
//!   sensing latency). `h_b ≥ 0` ⇒ `|d| ≥ r`.
//! * `ṡ = −|ḋ_⊥|²/|d| − nᵀ(u − ā)`; the centripetal part is dropped (it is zero for a wall,
//!   whose closest point slides with the vehicle), which only makes the constraint stricter.
//!   `ḣ_b ≥ −γ h_b` is then the half-space `nᵀu ≥ c`,
//!   `c = (s − γ h_b)/φ′(s) + A`, `φ′(s) = s⁺/a_b + τ > 0` (`γ` = [`CbfParams::brake_gamma`],
//!   `A` = [`CbfParams::accel_bound`]).
//! * On the boundary (`h_b = 0`, `s > 0`) `c − A = s/(s/a_b + τ) < a_b`: braking at `a_b` is
//!   always enough for one barrier, whatever the speed — unlike the paper's barrier, which asks
//!   for `(2/μ)·s` and is entered at speed as soon as an obstacle comes into sensing range
//!   closer than `2μs` (`docs/filter.md`).
//!
//! Every point's constraint is in force, not only near ones: with `γ > 0` it is slack far away
//! (`c` very negative) and tightens continuously as `h_b` shrinks, so the command changes
//! gradually and an actuation lag costs little of `h_b`; below 0 it pushes back. (An on/off
//! engagement at a small `h_b` let the lag eat 0.5 m at 8 m/s: the command jumped by 6 m/s²
//! and took 30 ms to act.) The `K` = [`MAX_ACTIVE_BARRIERS`] smallest `h_b` are enforced at
//! once through the exact projection of [`super::qp3`] (as `multi`); the region is `far` while
//! every `h_b > √δ1 − √δ` and the nominal command satisfies them.
//! [`FilterDiagnostics::h_bar`] is `min h_b` in metres for this variant.
//!
//! May import: [`super::cbf`], [`super::qp3`], the crate root foundation.

use super::cbf::{
    CbfParams, FilterDiagnostics, FilterFault, FilterVariant, Region, SafetyFilter, MAX_ACTIVE_BARRIERS,
    MIN_DISTANCE_SQ,
};
use super::cbf::project_near;
use super::qp3::HalfSpace;
use crate::fmath::{maxf, minf, norm3, sqrtf};
use crate::obstacle::ObstaclePoint;
use crate::Vec3;

/// One obstacle's braking barrier at the current state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrakingBarrier {
    /// `h_b = |d| − r − φ(s)`, m.
    pub h: f32,
    /// Approach speed `s` (with the velocity margin), m/s.
    pub approach_speed: f32,
    /// The constraint `nᵀu ≥ c` that keeps `ḣ_b ≥ −γ h_b`.
    pub constraint: HalfSpace,
}

/// The braking barrier of a point at offset `d = p − p̄` (m, `|d|` > 0) with relative
/// velocity `d_dot` (m/s) under `params` (module docs). `None` at zero distance or with a
/// non-finite input.
pub fn barrier(params: &CbfParams, d: &Vec3, d_dot: &Vec3) -> Option<BrakingBarrier> {
    let dist_sq = d.norm_squared();
    if dist_sq.is_nan() || dist_sq <= MIN_DISTANCE_SQ || !dist_sq.is_finite() || !d_dot.iter().all(|x| x.is_finite()) {
        return None;
    }
    let dist = sqrtf(dist_sq);
    let n = d / dist;
    let s = -n.dot(d_dot) + params.velocity_margin;
    let (a, tau) = (params.brake_accel, params.brake_delay);
    let sp = maxf(s, 0.0);
    let h = dist - sqrtf(params.delta) - (sp * sp / (2.0 * a) + tau * sp);
    let slope = sp / a + tau;
    let c = (s - params.brake_gamma * h) / slope + params.accel_bound;
    Some(BrakingBarrier { h, approach_speed: s, constraint: HalfSpace { n, c } })
}

/// [`SafetyFilter::apply`] for [`FilterVariant::Braking`] (module docs). Never panics; the
/// output is always finite. Cost: O(len) plus the ≤ 15-candidate projection.
pub fn apply(f: &SafetyFilter, p: &Vec3, v: &Vec3, u_nom: &Vec3, obstacles: &[ObstaclePoint]) -> (Vec3, FilterDiagnostics) {
    let fault = |kind| {
        let mut diag = FilterDiagnostics::new(Region::Fault);
        diag.fault = Some(kind);
        diag.intervened = true;
        (f.brake(v), diag)
    };
    let ok = |x: &Vec3| x.iter().all(|c| c.abs() <= super::cbf::INPUT_LIMIT);
    if !ok(p) || !ok(v) {
        return fault(FilterFault::BadState);
    }
    if !ok(u_nom) {
        return fault(FilterFault::BadNominal);
    }
    if obstacles.is_empty() {
        return (*u_nom, FilterDiagnostics::new(Region::NoObstacle));
    }
    let params = &f.params;
    let engage = sqrtf(params.delta1) - sqrtf(params.delta);
    let mut diag = FilterDiagnostics::new(Region::Far);
    let mut near: heapless::Vec<(BrakingBarrier, u16), MAX_ACTIVE_BARRIERS> = heapless::Vec::new();
    let mut closest: Option<(u16, f32)> = None;
    for o in obstacles {
        if !ok(&o.point) || !o.velocity.is_none_or(|w| ok(&w)) {
            return fault(FilterFault::BadObstacle);
        }
        let d = p - o.point;
        let d_dot = v - o.velocity.unwrap_or_else(Vec3::zeros);
        let Some(b) = barrier(params, &d, &d_dot) else { return fault(FilterFault::ZeroDistance) };
        diag.h_bar = minf(diag.h_bar, b.h);
        if closest.is_none_or(|(_, h)| b.h < h) {
            closest = Some((o.id, b.h));
        }
        if b.h <= engage {
            diag.n_near = diag.n_near.saturating_add(1);
        }
        // Keep the K smallest h_b: replace the largest kept when full.
        if let Err(item) = near.push((b, o.id)) {
            let worst = near.iter().enumerate().fold(0, |w, (i, x)| if x.0.h > near[w].0.h { i } else { w });
            if item.0.h < near[worst].0.h {
                near[worst] = item;
            }
        }
    }
    diag.active_id = closest.map(|(id, _)| id);
    if near.is_empty() {
        return (*u_nom, diag);
    }
    let mut cons = [HalfSpace { n: Vec3::zeros(), c: 0.0 }; MAX_ACTIVE_BARRIERS];
    for (slot, (b, _)) in cons.iter_mut().zip(near.iter()) {
        *slot = b.constraint;
    }
    let cons = &cons[..near.len()];
    diag.unavoidable = cons.iter().any(|h| h.c > params.u_max);
    diag.n_constraints = near.len() as u8;
    diag.active_id = near.iter().min_by(|a, b| a.0.h.total_cmp(&b.0.h)).map(|x| x.1);
    if cons.iter().all(|h| h.n.dot(u_nom) >= h.c) {
        diag.region = if diag.n_near == 0 { Region::Far } else { Region::NominalSafe };
        return (*u_nom, diag);
    }
    // Reference for the bounded projection: braking along the velocity at a_b.
    let speed = norm3(v);
    let u_brake = if speed > 1e-6 { v * (-minf(params.brake_accel, params.u_max) / speed) } else { Vec3::zeros() };
    debug_assert!(f.variant == FilterVariant::Braking);
    (project_near(u_nom, cons, &u_brake, &mut diag), diag)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> CbfParams {
        CbfParams { brake_accel: 3.0, brake_delay: 0.1, brake_gamma: 0.0, ..CbfParams::default() }
    }

    #[test]
    fn barrier_hand_computed() {
        // 5 m ahead (obstacle at +x), closing at 3 m/s: φ = 9/6 + 0.3 = 1.8, r = √0.05.
        let b = barrier(&params(), &Vec3::new(-5.0, 0.0, 0.0), &Vec3::new(3.0, 0.0, 0.0)).unwrap();
        assert!((b.h - (5.0 - 0.05f32.sqrt() - 1.8)).abs() < 1e-5, "{b:?}");
        assert!((b.approach_speed - 3.0).abs() < 1e-6);
        // c = s/(s/a + τ) = 3/(1 + 0.1) with γ = 0; n points from the obstacle to the vehicle.
        assert!((b.constraint.c - 3.0 / 1.1).abs() < 1e-5);
        assert!((b.constraint.n - Vec3::new(-1.0, 0.0, 0.0)).norm() < 1e-6);
        // Receding: no braking term, h_b = |d| − r.
        let r = barrier(&params(), &Vec3::new(-5.0, 0.0, 0.0), &Vec3::new(-1.0, 0.0, 0.0)).unwrap();
        assert!((r.h - (5.0 - 0.05f32.sqrt())).abs() < 1e-5);
        assert!(barrier(&params(), &Vec3::zeros(), &Vec3::zeros()).is_none());
        assert!(barrier(&params(), &Vec3::new(1.0, 0.0, 0.0), &Vec3::new(f32::NAN, 0.0, 0.0)).is_none());
    }

    #[test]
    fn on_the_boundary_braking_at_a_b_is_enough_at_any_speed() {
        let p = params();
        for s in [0.5f32, 2.0, 5.0, 10.0, 20.0] {
            let dist = 0.05f32.sqrt() + s * s / 6.0 + 0.1 * s;
            let b = barrier(&p, &Vec3::new(-dist, 0.0, 0.0), &Vec3::new(s, 0.0, 0.0)).unwrap();
            assert!(b.h.abs() < 1e-3 * dist, "{s}: {b:?}");
            assert!(b.constraint.c < p.brake_accel, "{s}: {b:?}");
        }
    }

    #[test]
    fn the_filter_brakes_a_vehicle_that_pushes_towards_a_wall() {
        let f = SafetyFilter::new(CbfParams::default(), FilterVariant::Braking).unwrap();
        // Wall point 2 m ahead, closing at 2.5 m/s (h_b = 2 − 0.224 − 1.042 − 0.25 < engage).
        let o = [ObstaclePoint::fixed(Vec3::new(2.0, 0.0, -1.0), 7)];
        let (u, d) = apply(&f, &Vec3::new(0.0, 0.0, -1.0), &Vec3::new(2.5, 0.0, 0.0), &Vec3::new(2.0, 0.5, 0.0), &o);
        assert!(d.intervened && d.region == Region::Perpendicular, "{d:?}");
        assert_eq!(d.active_id, Some(7));
        // −u_x ≥ c: it decelerates at least c; the sideways part is kept.
        let b = barrier(&f.params, &Vec3::new(-2.0, 0.0, 0.0), &Vec3::new(2.5, 0.0, 0.0)).unwrap();
        assert!(-u.x >= b.constraint.c - 1e-4, "{u:?} {b:?}");
        assert!((u.y - 0.5).abs() < 1e-4, "{u:?}");
        // Far away: the nominal passes.
        let (u2, d2) = apply(&f, &Vec3::new(-20.0, 0.0, -1.0), &Vec3::new(2.5, 0.0, 0.0), &Vec3::new(2.0, 0.5, 0.0), &o);
        assert_eq!(u2, Vec3::new(2.0, 0.5, 0.0));
        assert_eq!(d2.region, Region::Far);
    }

    #[test]
    fn bad_inputs_brake_with_a_finite_output() {
        let f = SafetyFilter::new(params(), FilterVariant::Braking).unwrap();
        let o = [ObstaclePoint::fixed(Vec3::new(2.0, 0.0, 0.0), 0)];
        let nan = Vec3::new(f32::NAN, 0.0, 0.0);
        for (p, v, u) in [(nan, Vec3::zeros(), Vec3::zeros()), (Vec3::zeros(), nan, Vec3::zeros()), (Vec3::zeros(), Vec3::zeros(), nan)] {
            let (out, d) = apply(&f, &p, &v, &u, &o);
            assert!(out.iter().all(|x| x.is_finite()));
            assert!(d.fault.is_some());
        }
        let (out, d) = apply(&f, &Vec3::new(2.0, 0.0, 0.0), &Vec3::zeros(), &Vec3::zeros(), &o);
        assert_eq!(d.fault, Some(FilterFault::ZeroDistance));
        assert!(out.iter().all(|x| x.is_finite()));
    }
}
