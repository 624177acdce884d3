//! The braking-distance barrier (filter variant [`FilterVariant::Braking`], issue 36): a
//! barrier whose look-ahead is what the vehicle needs to stop, instead of the paper's fixed
//! `μ`. Derivation and guarantee: `docs/filter.md` § Braking-distance barrier.
//!
//! For an obstacle point `p̄` with velocity `v̄` (relative velocity, as `multi-relative`),
//! `d = p − p̄`, `n = d/|d|`, the approach speed `s = −nᵀ(ṗ − v̄) + ε_v` and the hull radius
//! `r = √δ`. A point whose velocity is **unknown** (a range return the obstacle memory has not
//! proven moving: a small cluster's point without velocity, `crate::obstacle::may_move_unseen`) is not assumed static: it may approach at
//! up to `w` ([`CbfParams::brake_unknown_speed`]), so `v̄ = 0` and `s = −nᵀṗ + ε_v + w`, an
//! upper bound of the true approach speed of any point moving at `|v̄| ≤ w` (`docs/filter.md`
//! § 16, "Clusters of unknown velocity"; default `w` = 0):
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
//! Owns the barrier's arithmetic ([`barrier`], [`BrakingLimits`]); the filter loop that
//! enforces it is [`super::cbf::SafetyFilter::apply`] with [`FilterVariant::Braking`]
//! (`cbf` imports this module, never the reverse).
//!
//! May import: [`super::qp3`], the crate root foundation.
//!
//! [`FilterVariant::Braking`]: super::cbf::FilterVariant::Braking
//! [`CbfParams::brake_accel`]: super::cbf::CbfParams::brake_accel
//! [`CbfParams::brake_delay`]: super::cbf::CbfParams::brake_delay
//! [`CbfParams::brake_gamma`]: super::cbf::CbfParams::brake_gamma
//! [`CbfParams::brake_unknown_speed`]: super::cbf::CbfParams::brake_unknown_speed
//! [`CbfParams::accel_bound`]: super::cbf::CbfParams::accel_bound
//! [`MAX_ACTIVE_BARRIERS`]: super::cbf::MAX_ACTIVE_BARRIERS
//! [`FilterDiagnostics::h_bar`]: super::cbf::FilterDiagnostics::h_bar

use super::qp3::HalfSpace;
use crate::fmath::{maxf, sqrtf};
use crate::Vec3;

/// Squared distance (m²) below which the direction to a point is undefined (as the filter's).
const MIN_DISTANCE_SQ: f32 = 1.0e-10;

/// What the braking barrier needs of the filter's parameters (`CbfParams::braking`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrakingLimits {
    /// Hull radius `r = √δ`, m.
    pub hull_radius: f32,
    /// Braking deceleration `a_b`, m/s² (> 0).
    pub accel: f32,
    /// Delay `τ`, s (> 0).
    pub delay: f32,
    /// Class-K rate `γ_b`, 1/s.
    pub gamma: f32,
    /// Velocity margin `ε_v`, m/s.
    pub velocity_margin: f32,
    /// Robust term `A` (bound on the obstacle's acceleration), m/s².
    pub accel_bound: f32,
    /// `w`, m/s: the speed a point of unknown velocity may approach at (added to its `s`).
    pub unknown_speed: f32,
}

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
/// velocity `d_dot` (m/s) under `l` (module docs); `velocity_known` false adds the unknown
/// point's speed `w` to the approach speed. `None` at zero distance or with a non-finite
/// input.
pub fn barrier(l: &BrakingLimits, d: &Vec3, d_dot: &Vec3, velocity_known: bool) -> Option<BrakingBarrier> {
    let dist_sq = d.norm_squared();
    if dist_sq.is_nan()
        || dist_sq <= MIN_DISTANCE_SQ
        || !dist_sq.is_finite()
        || !d_dot.iter().all(|x| x.is_finite())
    {
        return None;
    }
    let dist = sqrtf(dist_sq);
    let n = d / dist;
    let unknown = if velocity_known { 0.0 } else { l.unknown_speed };
    let s = -n.dot(d_dot) + l.velocity_margin + unknown;
    let sp = maxf(s, 0.0);
    let h = dist - l.hull_radius - (sp * sp / (2.0 * l.accel) + l.delay * sp);
    let slope = sp / l.accel + l.delay;
    let c = (s - l.gamma * h) / slope + l.accel_bound;
    Some(BrakingBarrier { h, approach_speed: s, constraint: HalfSpace { n, c } })
}

/// `true` when the barrier of a point at squared distance `dist_sq` (m²) is certainly above
/// `level` (m) for every approach speed up to `speed_max` (m/s, `|ḋ|` bounds `s − ε_v`, plus
/// `w` for a point of unknown velocity: the caller adds it): then
/// `h_b ≥ |d| − r − φ(speed_max + ε_v) > level`, with a margin of 10⁻⁴·(1 + that distance) for
/// the `f32` roundings of [`barrier`]. The filter skips such a point once it keeps `K` barriers
/// all below `level` (its `h_b` could neither enter them nor lower their minimum): the
/// "certainly far" shortcut of the paper's variants for this barrier. `false` on a non-finite
/// input (the point is then evaluated).
pub fn certainly_above(l: &BrakingLimits, dist_sq: f32, speed_max: f32, level: f32) -> bool {
    let sp = maxf(speed_max + l.velocity_margin, 0.0);
    let reach = level + l.hull_radius + sp * sp / (2.0 * l.accel) + l.delay * sp;
    let need = reach + 1.0e-4 * (1.0 + reach.abs());
    need.is_finite()
        && dist_sq.is_finite()
        && dist_sq > MIN_DISTANCE_SQ
        && (need <= 0.0 || dist_sq > need * need)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> BrakingLimits {
        BrakingLimits {
            hull_radius: 0.05f32.sqrt(),
            accel: 3.0,
            delay: 0.1,
            gamma: 0.0,
            velocity_margin: 0.0,
            accel_bound: 0.0,
            unknown_speed: 0.0,
        }
    }

    #[test]
    fn barrier_hand_computed() {
        // 5 m ahead (obstacle at +x), closing at 3 m/s: φ = 9/6 + 0.3 = 1.8, r = √0.05.
        let b = barrier(&params(), &Vec3::new(-5.0, 0.0, 0.0), &Vec3::new(3.0, 0.0, 0.0), true).unwrap();
        assert!((b.h - (5.0 - 0.05f32.sqrt() - 1.8)).abs() < 1e-5, "{b:?}");
        assert!((b.approach_speed - 3.0).abs() < 1e-6);
        // c = s/(s/a + τ) = 3/(1 + 0.1) with γ = 0; n points from the obstacle to the vehicle.
        assert!((b.constraint.c - 3.0 / 1.1).abs() < 1e-5);
        assert!((b.constraint.n - Vec3::new(-1.0, 0.0, 0.0)).norm() < 1e-6);
        // Receding: no braking term, h_b = |d| − r.
        let r = barrier(&params(), &Vec3::new(-5.0, 0.0, 0.0), &Vec3::new(-1.0, 0.0, 0.0), true).unwrap();
        assert!((r.h - (5.0 - 0.05f32.sqrt())).abs() < 1e-5);
        assert!(barrier(&params(), &Vec3::zeros(), &Vec3::zeros(), true).is_none());
        assert!(barrier(&params(), &Vec3::new(1.0, 0.0, 0.0), &Vec3::new(f32::NAN, 0.0, 0.0), true).is_none());
    }

    #[test]
    fn certainly_above_is_a_lower_bound_of_the_barrier() {
        // Every direction of the relative velocity at |ḋ| ≤ speed_max: the computed h_b is
        // above the level whenever certainly_above says so, and it says so 2 cm beyond.
        let p = BrakingLimits { velocity_margin: 0.1, ..params() };
        for (speed, level) in [(0.0f32, 0.5f32), (3.0, 0.2), (8.0, 1.0), (1.0, -0.3)] {
            let phi = |s: f32| s * s / 6.0 + 0.1 * s;
            let edge = level + p.hull_radius + phi(speed + 0.1);
            for dist in [edge - 0.02, edge + 0.02, edge + 1.0] {
                let yes = certainly_above(&p, dist * dist, speed, level);
                assert_eq!(yes, dist > edge, "speed {speed} level {level} dist {dist}");
                for k in 0..16 {
                    let a = k as f32 * core::f32::consts::PI / 8.0;
                    let d_dot = Vec3::new(a.cos(), a.sin(), 0.0) * speed;
                    let b = barrier(&p, &Vec3::new(-dist, 0.0, 0.0), &d_dot, true).unwrap();
                    assert!(!yes || b.h > level, "{b:?} at level {level}");
                }
            }
        }
        assert!(!certainly_above(&p, f32::NAN, 1.0, 0.0));
        assert!(!certainly_above(&p, 100.0, f32::INFINITY, 0.0));
    }

    #[test]
    fn on_the_boundary_braking_at_a_b_is_enough_at_any_speed() {
        let p = params();
        for s in [0.5f32, 2.0, 5.0, 10.0, 20.0] {
            let dist = 0.05f32.sqrt() + s * s / 6.0 + 0.1 * s;
            let b = barrier(&p, &Vec3::new(-dist, 0.0, 0.0), &Vec3::new(s, 0.0, 0.0), true).unwrap();
            assert!(b.h.abs() < 1e-3 * dist, "{s}: {b:?}");
            assert!(b.constraint.c < p.accel, "{s}: {b:?}");
        }
    }
}
