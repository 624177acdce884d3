//! The closed-form Control Barrier Function safety filter (paper eq. 7-14)
//! and its two extensions (relative velocity for moving obstacles; several
//! barriers at once). Derivations: `docs/filter.md`.
//!
//! The translational dynamics are treated as a double integrator `p̈ = u`
//! (world NED, m/s², gravity excluded). For an obstacle point `p̄` with
//! velocity `v̄`, `d = p − p̄`, `ḋ = ṗ − v̄` (the paper's variants use `ḋ = ṗ`):
//!
//! * barrier `h = |d|² + μ dᵀḋ`, `h̄ = h − δ`, safe set `h̄ ≥ 0`;
//! * sufficient condition for `ḣ ≥ 0` (eq. 8): `2dᵀḋ + μ dᵀ(u − ā) ≥ 0`;
//!   with unit normal `n = d/|d|` and `|ā| ≤ A` unknown this is the half-space
//!   `nᵀu ≥ c`, `c = −(2/μ) (nᵀḋ − ε_v) + A` (`A = 0` in the paper's variants;
//!   `ε_v` a velocity-uncertainty margin, 0 by default);
//! * regions: `D_δ1 = {h > δ1}` (far), `D_u* = {nᵀu* > c}` (nominal safe),
//!   `D_⊥` otherwise, where the law (12) is `u = −(2/μ)Πḋ + Π⊥u* + A n`,
//!   i.e. the minimum-norm correction of `u*` onto the half-space.
//!
//! Variants ([`FilterVariant`]): `Paper` (eq. 12 + closest-active eq. 14, own
//! velocity), `Relative` (closest-active, relative velocity, robust term),
//! `Multi` (every near barrier at once, own velocity: exact min-norm QP),
//! `MultiRelative` (both; the default), and `Braking` (the braking-distance barrier of
//! [`super::braking`], every near barrier at once with relative velocity).

use super::braking::{self, BrakingBarrier, BrakingLimits};
use crate::fmath::{maxf, minf, norm3, sqrtf};
use crate::obstacle::{may_move_unseen, ObstaclePoint};
use crate::param_decl::{field, Has, Param};
use crate::qp3::{self, HalfSpace};
use crate::Vec3;

pub use super::diagnostics::{FilterDiagnostics, FilterFault, Region};
pub use super::variant::FilterVariant;

/// Magnitude beyond which an input is treated as corrupt (m, m/s or m/s²).
pub const INPUT_LIMIT: f32 = 1.0e5;

/// Squared distance (m²) below which the obstacle direction is undefined.
pub const MIN_DISTANCE_SQ: f32 = 1.0e-10;

/// Number of barriers the multi-barrier variants enforce at once (the `K`
/// most critical, smallest h̄). Others near the vehicle are reported in
/// [`FilterDiagnostics::n_near`] but not enforced.
pub const MAX_ACTIVE_BARRIERS: usize = 4;

/// Invalid filter parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CbfError {
    /// μ must be finite and > 0.
    MuNotPositive,
    /// δ must be finite and > 0.
    DeltaNotPositive,
    /// δ1 must be finite and > δ.
    Delta1NotAboveDelta,
    /// The obstacle acceleration bound A must be finite and ≥ 0.
    AccelBoundNegative,
    /// u_max must be finite and > 0.
    UMaxNotPositive,
    /// The sample time must be finite, ≥ 0 and ≤ 1 s.
    SampleTimeOutOfRange,
    /// The velocity margin must be finite and ≥ 0.
    VelocityMarginNegative,
    /// The class-K relaxation rate γ must be finite and ≥ 0.
    GammaNegative,
    /// The braking deceleration must be finite, > 0 and ≤ u_max.
    BrakeAccelOutOfRange,
    /// The braking delay must be finite and in [0.01, 1] s.
    BrakeDelayOutOfRange,
    /// The unknown points' speed `w` is not in [0, 10] m/s.
    BrakeUnknownSpeedOutOfRange,
}

impl core::fmt::Display for CbfError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CbfError::MuNotPositive => "mu must be finite and > 0",
            CbfError::DeltaNotPositive => "delta must be finite and > 0",
            CbfError::Delta1NotAboveDelta => "delta1 must be finite and > delta",
            CbfError::AccelBoundNegative => "accel_bound must be finite and >= 0",
            CbfError::UMaxNotPositive => "u_max must be finite and > 0",
            CbfError::SampleTimeOutOfRange => "sample_time must be finite and in [0, 1] s",
            CbfError::VelocityMarginNegative => "velocity_margin must be finite and >= 0",
            CbfError::GammaNegative => "gamma must be finite and >= 0",
            CbfError::BrakeAccelOutOfRange => "brake_accel must be finite, > 0 and <= u_max",
            CbfError::BrakeDelayOutOfRange => "brake_delay must be finite and in [0.01, 1] s",
            CbfError::BrakeUnknownSpeedOutOfRange => "brake_unknown_speed must be finite and in [0, 10] m/s",
        })
    }
}

/// Parameters of the safety filter.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CbfParams {
    /// μ, s: weight of the velocity term in the barrier. Default 1.4 (paper, office).
    pub mu: f32,
    /// δ, m²: squared hull radius; the safe set is `h ≥ δ`. Default 0.05 (r ≈ 0.224 m).
    pub delta: f32,
    /// δ1, m² (> δ): the filter engages when `h ≤ δ1`. Default 0.1.
    pub delta1: f32,
    /// A, m/s²: bound on unknown obstacle acceleration (relative variants only). Default 0.
    pub accel_bound: f32,
    /// u_max, m/s²: acceleration the vehicle can achieve; a constraint needing more
    /// along its normal raises [`FilterDiagnostics::unavoidable`]. Default 6.0
    /// (≈ g·tan 31°, below the thrust mapping's 35° tilt limit).
    pub u_max: f32,
    /// ε_v, m/s: bound on the error of the measured velocity along the obstacle
    /// direction. The constraint assumes the vehicle approaches ε_v faster than
    /// measured (`c += 2ε_v/μ`), so zero-mean velocity noise cannot rectify into a
    /// creep towards the obstacle (noisy "moving away" readings would otherwise let
    /// an inward-pushing `u*` through while "moving in" readings brake). Default 0
    /// (the paper's law).
    pub velocity_margin: f32,
    /// T, s: the period the filter is applied at (zero-order hold). With T > 0 the
    /// event rule engages a barrier when `h` or its one-step prediction under the
    /// nominal input, `h + T·min(0, ḣ(u*))`, is ≤ δ1, so the filter does not engage a
    /// sample too late. T = 0 is the paper's continuous-time rule `h ≤ δ1`. Default 0.
    pub sample_time: f32,
    /// γ, 1/s: class-K relaxation of an enforced barrier, `ḣ ≥ −γ(h − δ)` instead of
    /// `ḣ ≥ 0`: the constraint becomes `nᵀu ≥ c − γ(h − δ)/(μ|d|)`, so the vehicle may
    /// approach a barrier down to δ (exponentially slowly) instead of freezing where it
    /// first came within δ1 (deadlock in narrow spaces, `docs/filter.md` §9). Below δ the
    /// same term pushes back out. The event rule (δ1, [`sample_time`](Self::sample_time))
    /// is unchanged. Default 0 (the paper's `ḣ ≥ 0`).
    pub gamma: f32,
    /// a_b, m/s²: the deceleration the braking-distance barrier counts on
    /// ([`FilterVariant::Braking`], `super::braking`); at most `u_max`. Default 3.0.
    pub brake_accel: f32,
    /// τ, s: actuation lag plus sensing latency before braking takes effect, in the
    /// braking-distance barrier. Default 0.1.
    pub brake_delay: f32,
    /// γ_b, 1/s: class-K rate of the braking-distance barrier, `ḣ_b ≥ −γ_b h_b` (it is in
    /// force for every point, slack far away). Default 2.0.
    pub brake_gamma: f32,
    /// w, m/s: the speed at which a sensed small cluster of **unknown** velocity (one the
    /// obstacle memory tracks but has not proven moving, [`crate::obstacle::may_move_unseen`])
    /// may approach, in the braking-distance barrier: its approach speed counts `w` more than
    /// the vehicle's own. Walls' cells and virtual points stay static. 0 treats such clusters
    /// as static (a person walking into a stopped vehicle then pushes it through `h_b < 0`).
    /// Default 0: with `w` > 0 the vehicle keeps `r + φ(w) + w/γ_b` from every such cluster
    /// even at rest, which stalls it in clutter (`docs/filter.md` § 16, "Clusters of unknown
    /// velocity").
    pub brake_unknown_speed: f32,
}

impl Default for CbfParams {
    fn default() -> Self {
        CbfParams {
            mu: 1.4,
            delta: 0.05,
            delta1: 0.1,
            accel_bound: 0.0,
            u_max: 6.0,
            velocity_margin: 0.0,
            sample_time: 0.0,
            gamma: 0.0,
            brake_accel: 3.0,
            brake_delay: 0.1,
            brake_gamma: 2.0,
            brake_unknown_speed: 0.0,
        }
    }
}

impl CbfParams {
    /// The filter law's parameters (`crate::params`, MAVLink `param_index` order): μ, δ, δ1, A.
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 4] {
        [
            Param::new("CBF_MU", "CBF", "s", (0.01, 100.0), 2, field!(mu),
                "Barrier velocity weight mu: the filter keeps h + mu*dh/dt above delta").key("mu"),
            Param::new("CBF_DELTA", "CBF", "m^2", (1e-4, 100.0), 4, field!(delta),
                "Safety level delta (hull radius squared); must stay below CBF_DELTA1").key("delta"),
            Param::new("CBF_DELTA1", "CBF", "m^2", (1e-4, 100.0), 4, field!(delta1),
                "Engagement level delta1 > CBF_DELTA: the filter acts below it").key("delta1"),
            Param::new("CBF_ACC_BOUND", "CBF", "m/s^2", (0.0, 50.0), 2, field!(accel_bound),
                "Bound A on the unknown obstacle acceleration (relative variants)").key("accel_bound"),
        ]
    }

    /// The velocity margin and the braking-distance barrier's parameters (`crate::params`; a
    /// later group of the table, after the vehicle's tracking and mission parameters).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn margin_params<P: Has<Self>>() -> [Param<P>; 5] {
        [
            Param::new("CBF_VEL_MARGIN", "CBF", "m/s", (0.0, 10.0), 3, field!(velocity_margin),
                "Velocity-uncertainty margin eps_v of the filter's constraint").key("velocity_margin"),
            Param::new("CBF_BRAKE_ACC", "CBF", "m/s^2", (0.1, 15.0), 2, field!(brake_accel),
                "CBF_VARIANT 4: deceleration the braking-distance barrier counts on (at most the filter's u_max)"),
            Param::new("CBF_BRAKE_DLY", "CBF", "s", (0.01, 1.0), 3, field!(brake_delay),
                "CBF_VARIANT 4: actuation lag plus sensing latency before braking takes effect"),
            Param::new("CBF_BRAKE_GAMMA", "CBF", "1/s", (0.0, 20.0), 2, field!(brake_gamma),
                "CBF_VARIANT 4: class-K rate of the braking-distance barrier (how fast it may be approached)"),
            Param::new("CBF_BRAKE_UNK_V", "CBF", "m/s", (0.0, 10.0), 2, field!(brake_unknown_speed),
                "CBF_VARIANT 4: speed at which a sensed small cluster not proven moving may approach (0: static)"),
        ]
    }
}

impl CbfParams {
    /// What the braking-distance barrier ([`super::braking`]) uses of these parameters.
    pub fn braking(&self) -> BrakingLimits {
        BrakingLimits {
            hull_radius: sqrtf(self.delta),
            accel: self.brake_accel,
            delay: self.brake_delay,
            gamma: self.brake_gamma,
            velocity_margin: self.velocity_margin,
            accel_bound: self.accel_bound,
            unknown_speed: self.brake_unknown_speed,
        }
    }

    /// Parameters with the given μ (s), δ (m²), δ1 (m²) and the other defaults; validated.
    pub fn new(mu: f32, delta: f32, delta1: f32) -> Result<Self, CbfError> {
        let p = CbfParams { mu, delta, delta1, ..CbfParams::default() };
        p.validate().map(|_| p)
    }

    /// Check μ > 0, δ > 0, δ1 > δ, A ≥ 0, u_max > 0 (all finite).
    pub fn validate(&self) -> Result<(), CbfError> {
        if !(self.mu.is_finite() && self.mu > 0.0) {
            return Err(CbfError::MuNotPositive);
        }
        if !(self.delta.is_finite() && self.delta > 0.0) {
            return Err(CbfError::DeltaNotPositive);
        }
        if !(self.delta1.is_finite() && self.delta1 > self.delta) {
            return Err(CbfError::Delta1NotAboveDelta);
        }
        if !(self.accel_bound.is_finite() && self.accel_bound >= 0.0) {
            return Err(CbfError::AccelBoundNegative);
        }
        if !(self.u_max.is_finite() && self.u_max > 0.0) {
            return Err(CbfError::UMaxNotPositive);
        }
        if !(self.sample_time.is_finite() && (0.0..=1.0).contains(&self.sample_time)) {
            return Err(CbfError::SampleTimeOutOfRange);
        }
        if !(self.velocity_margin.is_finite() && self.velocity_margin >= 0.0) {
            return Err(CbfError::VelocityMarginNegative);
        }
        if !(self.gamma.is_finite() && self.gamma >= 0.0) {
            return Err(CbfError::GammaNegative);
        }
        if !(self.brake_accel.is_finite() && self.brake_accel > 0.0 && self.brake_accel <= self.u_max) {
            return Err(CbfError::BrakeAccelOutOfRange);
        }
        if !(self.brake_delay.is_finite() && (0.01..=1.0).contains(&self.brake_delay)) {
            return Err(CbfError::BrakeDelayOutOfRange);
        }
        if !(self.brake_gamma.is_finite() && self.brake_gamma >= 0.0) {
            return Err(CbfError::GammaNegative);
        }
        if !(self.brake_unknown_speed.is_finite() && (0.0..=10.0).contains(&self.brake_unknown_speed)) {
            return Err(CbfError::BrakeUnknownSpeedOutOfRange);
        }
        Ok(())
    }
}

/// One obstacle's barrier evaluated at the current state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Barrier {
    /// `h = |d|² + μ dᵀḋ`, m².
    pub h: f32,
    /// `μ(nᵀḋ)²`, m²/s: a lower bound on the part of `ḣ` that does not depend on
    /// the input. For a point obstacle that part is `μ|ḋ|²`; for an extended convex
    /// obstacle the closest point slides with the vehicle's tangential motion and
    /// only `μ ḋ_trueᵀḋ ≥ μ(nᵀḋ)²` remains (a wall keeps just the radial part).
    pub mu_radial_speed_sq: f32,
    /// `|d|²`, m².
    pub dist_sq: f32,
    /// The constraint `nᵀu ≥ c` that keeps `ḣ ≥ 0`.
    pub constraint: HalfSpace,
}

/// Barrier value `h = |d|² + μ dᵀḋ` (eq. 7), m².
#[inline]
pub fn barrier_value(mu: f32, d: &Vec3, d_dot: &Vec3) -> f32 {
    d.norm_squared() + mu * d.dot(d_dot)
}

/// Finite and every component within ±[`INPUT_LIMIT`] (one comparison per component:
/// `|x| ≤ L` is false for NaN and ±∞).
#[inline]
fn within_limits(v: &Vec3) -> bool {
    v.x.abs() <= INPUT_LIMIT && v.y.abs() <= INPUT_LIMIT && v.z.abs() <= INPUT_LIMIT
}

/// The closed-form CBF safety filter. Stateless, `Copy`, bounded time.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SafetyFilter {
    /// Validated parameters.
    pub params: CbfParams,
    /// Law in use.
    pub variant: FilterVariant,
}

impl SafetyFilter {
    /// A filter with validated parameters.
    pub fn new(params: CbfParams, variant: FilterVariant) -> Result<Self, CbfError> {
        params.validate()?;
        Ok(SafetyFilter { params, variant })
    }

    /// Evaluate the barrier of obstacle `o` at vehicle position `p` and velocity `v`
    /// (NED), using the variant's notion of velocity. `None` at zero distance.
    pub fn barrier(&self, p: &Vec3, v: &Vec3, o: &ObstaclePoint) -> Option<Barrier> {
        let d = p - o.point;
        let dist_sq = d.norm_squared();
        if dist_sq.is_nan() || dist_sq <= MIN_DISTANCE_SQ {
            return None;
        }
        let (d_dot, a_bound) = self.relative_velocity(v, o);
        Some(self.barrier_at(&d, dist_sq, sqrtf(dist_sq), &d_dot, a_bound))
    }

    /// `ḋ` (m/s) and the robust term `A` (m/s²) of obstacle `o` for this variant.
    #[inline(always)]
    fn relative_velocity(&self, v: &Vec3, o: &ObstaclePoint) -> (Vec3, f32) {
        if self.variant.uses_relative_velocity() {
            (v - o.velocity.unwrap_or_else(Vec3::zeros), self.params.accel_bound)
        } else {
            (*v, 0.0)
        }
    }

    /// The barrier from `d`, `|d|²`, `|d|` (> 0) and `ḋ`: the arithmetic of [`barrier`](Self::barrier).
    #[inline(always)]
    fn barrier_at(&self, d: &Vec3, dist_sq: f32, dist: f32, d_dot: &Vec3, a_bound: f32) -> Barrier {
        let n = d / dist;
        let mu = self.params.mu;
        let nd = n.dot(d_dot);
        let c = -(2.0 / mu) * (nd - self.params.velocity_margin) + a_bound;
        Barrier {
            h: barrier_value(mu, d, d_dot),
            mu_radial_speed_sq: mu * nd * nd,
            dist_sq,
            constraint: HalfSpace { n, c },
        }
    }

    /// The value the event rule compares with δ1: `h + T·min(0, ḣ(u))` where
    /// `ḣ(u) = μ|d|(nᵀu − c) + μ(nᵀḋ)²` is a lower bound on the barrier's rate under
    /// input `u` (worst case over the unknown obstacle acceleration and over convex
    /// obstacle shapes). Equals `h` when T = 0.
    pub fn trigger_value(&self, b: &Barrier, u: &Vec3) -> f32 {
        self.trigger_at(b, sqrtf(b.dist_sq), u)
    }

    /// [`trigger_value`](Self::trigger_value) with `|d| = √(b.dist_sq)` already known.
    #[inline(always)]
    fn trigger_at(&self, b: &Barrier, dist: f32, u: &Vec3) -> f32 {
        let t = self.params.sample_time;
        if t <= 0.0 {
            return b.h;
        }
        let h_dot = self.params.mu * dist * (b.constraint.n.dot(u) - b.constraint.c) + b.mu_radial_speed_sq;
        b.h + t * minf(h_dot, 0.0)
    }

    /// The constraint the multi variants enforce for a near barrier `b`: constraint (8)
    /// with the class-K relaxation of [`CbfParams::gamma`] (`b.constraint` itself when
    /// γ = 0). For tests and tools that rebuild the filter's constraint set.
    pub fn enforced_constraint(&self, b: &Barrier) -> HalfSpace {
        self.enforced(b, sqrtf(b.dist_sq))
    }

    /// The enforced constraint of a near barrier: `b.constraint` with the class-K
    /// relaxation `c − γ(h − δ)/(μ|d|)` (§9 of `docs/filter.md`); `b.constraint` itself
    /// when γ = 0. `dist = |d|` (> 0).
    #[inline(always)]
    fn enforced(&self, b: &Barrier, dist: f32) -> HalfSpace {
        let gamma = self.params.gamma;
        if gamma <= 0.0 {
            return b.constraint;
        }
        let relax = gamma * (b.h - self.params.delta) / (self.params.mu * dist);
        HalfSpace { n: b.constraint.n, c: b.constraint.c - relax }
    }

    /// `true` when the event-rule value ([`trigger_value`](Self::trigger_value)) of an
    /// obstacle is certainly above δ1, decided without building its barrier (no division):
    /// with `r = |d|` (given), `ḣ(u) = μ dᵀu + 2dᵀḋ − r(2ε_v + μA) + μ(nᵀḋ)²`, so dropping the last
    /// (non-negative) term gives a lower bound of `h + T·min(0, ḣ(u*))`. The bound must
    /// exceed δ1 by 1e-4 of the magnitudes involved, far above the f32 round-off of either
    /// side, so the decision is the one the full evaluation would take. `k0 = 2ε_v + μA` and
    /// `w = μ|u*| + 2|ḋ| + k0` come from [`Self::far_weights`]: the same for every obstacle
    /// without a velocity, so the loop computes them once for those.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn certainly_far(
        &self,
        d: &Vec3,
        dist_sq: f32,
        r: f32,
        h: f32,
        d_dot: &Vec3,
        k0: f32,
        w: f32,
        u_nom: &Vec3,
    ) -> bool {
        let (t, delta1) = (self.params.sample_time, self.params.delta1);
        if t <= 0.0 {
            return h > delta1; // the trigger value is h itself
        }
        let mu = self.params.mu;
        let bound = h + t * minf(mu * d.dot(u_nom) + 2.0 * d.dot(d_dot) - r * k0, 0.0);
        let scale = dist_sq + (h - dist_sq).abs() + delta1 + t * r * w;
        bound - delta1 > 1e-4 * scale
    }

    /// `(k0, w)` of [`Self::certainly_far`] for relative velocity `d_dot` and robust term
    /// `a_bound`: `k0 = 2ε_v + μA`, `w = μ|u*| + 2|ḋ| + k0` (`u_norm = |u*|`).
    #[inline(always)]
    fn far_weights(&self, d_dot: &Vec3, a_bound: f32, u_norm: f32) -> (f32, f32) {
        let mu = self.params.mu;
        let k0 = 2.0 * self.params.velocity_margin + mu * a_bound;
        (k0, mu * u_norm + 2.0 * norm3(d_dot) + k0)
    }

    /// Bounded braking command `u = −(2/μ)·ṗ`, saturated to `u_max` (zero if `ṗ` is bad).
    pub fn brake(&self, v: &Vec3) -> Vec3 {
        if !within_limits(v) {
            return Vec3::zeros();
        }
        let u = v * (-2.0 / self.params.mu);
        let n = norm3(&u);
        if n > self.params.u_max {
            u * (self.params.u_max / n)
        } else {
            u
        }
    }

    fn fault(&self, v: &Vec3, fault: FilterFault) -> (Vec3, FilterDiagnostics) {
        let mut diag = FilterDiagnostics::new(Region::Fault);
        diag.fault = Some(fault);
        diag.intervened = true;
        (self.brake(v), diag)
    }

    /// Filter the nominal acceleration `u_nom` (NED, m/s², `p̈ = u`) for a vehicle at
    /// `p` (m) moving at `v` (m/s) among `obstacles`. Returns the safe acceleration
    /// and what was decided. Never panics; the output is always finite.
    /// Cost: O(len) plus, for the multi variants, a fixed ≤ 15-candidate enumeration.
    pub fn apply(
        &self,
        p: &Vec3,
        v: &Vec3,
        u_nom: &Vec3,
        obstacles: &[ObstaclePoint],
    ) -> (Vec3, FilterDiagnostics) {
        // One copy per kind of law, so each obstacle loop carries only its own bookkeeping
        // (measured on the Cortex-M4F: the shared loop cost `paper` ≈ 240 instructions at K = 16).
        if self.variant == FilterVariant::Braking {
            self.apply_braking(p, v, u_nom, obstacles)
        } else if self.variant.is_multi() {
            self.apply_as::<true>(p, v, u_nom, obstacles)
        } else {
            self.apply_as::<false>(p, v, u_nom, obstacles)
        }
    }

    /// The answer before any barrier: the braking fallback for a bad state or nominal
    /// command, the nominal command with no obstacle; `None` to go on.
    #[inline(always)]
    fn screen(
        &self,
        p: &Vec3,
        v: &Vec3,
        u_nom: &Vec3,
        obstacles: &[ObstaclePoint],
    ) -> Option<(Vec3, FilterDiagnostics)> {
        if !within_limits(p) || !within_limits(v) {
            return Some(self.fault(v, FilterFault::BadState));
        }
        if !within_limits(u_nom) {
            return Some(self.fault(v, FilterFault::BadNominal));
        }
        obstacles.is_empty().then(|| (*u_nom, FilterDiagnostics::new(Region::NoObstacle)))
    }

    /// [`apply`](Self::apply) for [`FilterVariant::Braking`] (`super::braking`): every point's
    /// braking barrier is in force; the `K` smallest `h_b` are projected on exactly. The
    /// region is `far` while every `h_b > √δ1 − √δ` and the nominal satisfies them;
    /// `diag.h_bar` is `min h_b` (m).
    fn apply_braking(
        &self,
        p: &Vec3,
        v: &Vec3,
        u_nom: &Vec3,
        obstacles: &[ObstaclePoint],
    ) -> (Vec3, FilterDiagnostics) {
        if let Some(early) = self.screen(p, v, u_nom, obstacles) {
            return early;
        }
        let limits = self.params.braking();
        let engage = sqrtf(self.params.delta1) - limits.hull_radius;
        let mut diag = FilterDiagnostics::new(Region::Far);
        let mut near: Smallest<(BrakingBarrier, u16), MAX_ACTIVE_BARRIERS> = Smallest::new();
        let own_speed = norm3(v);
        for o in obstacles {
            if !within_limits(&o.point) || !o.velocity.is_none_or(|w| within_limits(&w)) {
                return self.fault(v, FilterFault::BadObstacle);
            }
            let d_dot = v - o.velocity.unwrap_or_else(Vec3::zeros);
            let d = p - o.point;
            // Certainly far: with K barriers kept, a point whose h_b is surely above both the
            // largest kept one and the engagement level changes nothing (not kept, not near,
            // not the minimum), so its barrier is not needed.
            // A sensed cluster's point of unknown velocity may approach at `w`; a wall's cell
            // and a virtual point (ground, ceiling, unseen-space frontier) are static.
            let velocity_known = !may_move_unseen(o);
            if near.is_full() {
                let speed_max = if velocity_known { norm3(&d_dot) } else { own_speed + limits.unknown_speed };
                let level = maxf(near.bound(), engage);
                if braking::certainly_above(&limits, d.norm_squared(), speed_max, level) {
                    continue;
                }
            }
            let Some(b) = braking::barrier(&limits, &d, &d_dot, velocity_known) else {
                return self.fault(v, FilterFault::ZeroDistance);
            };
            diag.h_bar = minf(diag.h_bar, b.h);
            if b.h <= engage {
                diag.n_near = diag.n_near.saturating_add(1);
            }
            near.offer(b.h, (b, o.id));
        }
        let near = near.kept();
        let mut cons = [HalfSpace { n: Vec3::zeros(), c: 0.0 }; MAX_ACTIVE_BARRIERS];
        for (slot, (b, _)) in cons.iter_mut().zip(near.iter()) {
            *slot = b.constraint;
        }
        let cons = &cons[..near.len()];
        diag.unavoidable = cons.iter().any(|h| h.c > self.params.u_max);
        diag.n_constraints = near.len() as u8;
        diag.active_id = near.iter().min_by(|a, b| a.0.h.total_cmp(&b.0.h)).map(|x| x.1);
        if cons.iter().all(|h| h.n.dot(u_nom) >= h.c) {
            diag.region = if diag.n_near == 0 { Region::Far } else { Region::NominalSafe };
            return (*u_nom, diag);
        }
        // Reference for the bounded projection: braking along the velocity at a_b.
        let speed = norm3(v);
        let u_brake =
            if speed > 1e-6 { v * (-minf(limits.accel, self.params.u_max) / speed) } else { Vec3::zeros() };
        (project_near(u_nom, cons, &u_brake, &mut diag), diag)
    }

    /// [`apply`](Self::apply) for a multi (`MULTI`) or single-barrier variant.
    fn apply_as<const MULTI: bool>(
        &self,
        p: &Vec3,
        v: &Vec3,
        u_nom: &Vec3,
        obstacles: &[ObstaclePoint],
    ) -> (Vec3, FilterDiagnostics) {
        if let Some(early) = self.screen(p, v, u_nom, obstacles) {
            return early;
        }
        let mut diag = FilterDiagnostics::new(Region::Far);
        // Closest obstacle (single-barrier variants) and the K most critical near ones (multi).
        let mut closest: Option<(usize, f32)> = None; // (index, |d|²)
        let mut near: Smallest<(Barrier, u16), MAX_ACTIVE_BARRIERS> = Smallest::new();
        let (mu, delta, delta1) = (self.params.mu, self.params.delta, self.params.delta1);
        let multi = MULTI;
        let u_norm = norm3(u_nom);
        // ḋ = ṗ and the far test's weights for the obstacles without a velocity (the same
        // values the per-obstacle evaluation gives: ṗ − 0 = ṗ exactly).
        let (v_fixed, a_fixed) = self.relative_velocity(v, &ObstaclePoint::fixed(Vec3::zeros(), 0));
        let (k0_fixed, w_fixed) = self.far_weights(&v_fixed, a_fixed, u_norm);
        for (i, o) in obstacles.iter().enumerate() {
            if !within_limits(&o.point) || !o.velocity.is_none_or(|w| within_limits(&w)) {
                return self.fault(v, FilterFault::BadObstacle);
            }
            let d = p - o.point;
            let dist_sq = d.norm_squared();
            if dist_sq <= MIN_DISTANCE_SQ {
                return self.fault(v, FilterFault::ZeroDistance);
            }
            let (d_dot, a_bound) = self.relative_velocity(v, o);
            let h = barrier_value(mu, &d, &d_dot);
            diag.h_bar = minf(diag.h_bar, h - delta);
            if closest.is_none_or(|(_, c)| dist_sq < c) {
                closest = Some((i, dist_sq));
            }
            // h ≤ δ1: near whatever ḣ is (the trigger value h + T·min(0, ḣ) is ≤ h, also
            // in f32, where adding a non-positive number to h cannot round above h).
            let near_for_sure = h <= delta1;
            // Near for sure, multi, the K kept are full and none has a larger h: it is
            // counted but cannot replace one of them (the replacement below needs a
            // strictly smaller h), so its barrier is not needed.
            if near_for_sure && multi && near.is_full() && h >= near.bound() {
                diag.n_near = diag.n_near.saturating_add(1);
                continue;
            }
            let dist = sqrtf(dist_sq);
            if !near_for_sure {
                let (k0, w) = if o.velocity.is_none() {
                    (k0_fixed, w_fixed)
                } else {
                    self.far_weights(&d_dot, a_bound, u_norm)
                };
                if self.certainly_far(&d, dist_sq, dist, h, &d_dot, k0, w, u_nom) {
                    continue; // only its h (h_bar) and |d|² (closest) were needed
                }
            }
            let b = self.barrier_at(&d, dist_sq, dist, &d_dot, a_bound);
            if near_for_sure || self.trigger_at(&b, dist, u_nom) <= delta1 {
                diag.n_near = diag.n_near.saturating_add(1);
                // Keep the K smallest h (multi variants; the others use only the closest
                // obstacle's barrier, below). The class-K relaxation is applied to the K
                // kept, after the loop.
                if multi {
                    near.offer(b.h, (b, o.id));
                }
            }
        }
        let near = near.kept();

        let u_max = self.params.u_max;
        if !multi {
            // Eq. 14: only the closest obstacle's barrier is active; eq. 12 on it.
            let Some(o) = closest.and_then(|(i, _)| obstacles.get(i)) else { return (*u_nom, diag) };
            let Some(b) = self.barrier(p, v, o) else { return self.fault(v, FilterFault::ZeroDistance) };
            let trigger = self.trigger_value(&b, u_nom);
            diag.active_id = Some(o.id);
            if trigger > delta1 {
                return (*u_nom, diag); // D_δ1
            }
            let HalfSpace { n, c } = self.enforced(&b, sqrtf(b.dist_sq));
            diag.n_constraints = 1;
            diag.unavoidable = c > u_max;
            if n.dot(u_nom) > c {
                diag.region = Region::NominalSafe; // D_u*
                return (*u_nom, diag);
            }
            // D_⊥: u = Π⊥u* + Π(−(2/μ)ḋ) + A n = u* + (c − nᵀu*) n.
            diag.region = Region::Perpendicular;
            diag.intervened = true;
            return (u_nom + n * (c - n.dot(u_nom)), diag);
        }

        if near.is_empty() {
            diag.active_id = closest.and_then(|(i, _)| obstacles.get(i)).map(|o| o.id);
            return (*u_nom, diag);
        }
        let mut cons = [HalfSpace { n: Vec3::zeros(), c: 0.0 }; MAX_ACTIVE_BARRIERS];
        let mut most_critical = (f32::INFINITY, 0u16);
        for (slot, (b, id)) in cons.iter_mut().zip(near.iter()) {
            *slot = self.enforced(b, sqrtf(b.dist_sq));
            diag.unavoidable |= slot.c > u_max;
            if b.h < most_critical.0 {
                most_critical = (b.h, *id);
            }
        }
        let cons = &cons[..near.len()];
        diag.n_constraints = near.len() as u8;
        diag.active_id = Some(most_critical.1);
        if cons.iter().all(|h| h.n.dot(u_nom) >= h.c) {
            diag.region = Region::NominalSafe;
            return (*u_nom, diag);
        }
        let u_brake = v * (-2.0 / self.params.mu);
        (project_near(u_nom, cons, &u_brake, &mut diag), diag)
    }
}

/// The `K` items with the smallest keys offered so far (fixed capacity, no allocation): once
/// `K` are kept, an item replaces the (first) largest kept key when its key is strictly
/// smaller, so ties keep the item offered first. The barriers the multi variants and the
/// braking variant enforce (keyed by `h`).
struct Smallest<T, const K: usize> {
    items: heapless::Vec<T, K>,
    /// `keys[i]` is `items[i]`'s key.
    keys: [f32; K],
    /// Index of the (first) largest key once `K` are kept (0 before).
    worst: usize,
}

impl<T, const K: usize> Smallest<T, K> {
    fn new() -> Self {
        Smallest { items: heapless::Vec::new(), keys: [f32::INFINITY; K], worst: 0 }
    }

    fn is_full(&self) -> bool {
        self.items.is_full()
    }

    /// The largest kept key once `K` are kept, `+∞` before.
    fn bound(&self) -> f32 {
        match self.keys.get(self.worst) {
            Some(key) if self.items.is_full() => *key,
            _ => f32::INFINITY,
        }
    }

    /// Offers `item` with `key`: kept while there is room, else in place of the largest kept
    /// key if `key` is strictly smaller.
    fn offer(&mut self, key: f32, item: T) {
        let at = if self.items.is_full() {
            if key >= self.bound() {
                return;
            }
            match self.items.get_mut(self.worst) {
                Some(slot) => *slot = item,
                None => return, // unreachable: worst < K when full
            }
            self.worst
        } else {
            let at = self.items.len();
            if self.items.push(item).is_err() {
                return; // unreachable: not full
            }
            at
        };
        if let Some(k) = self.keys.get_mut(at) {
            *k = key;
        }
        if self.items.is_full() {
            let mut worst = 0;
            for (i, k) in self.keys.iter().enumerate() {
                if self.keys.get(worst).is_some_and(|w| k > w) {
                    worst = i;
                }
            }
            self.worst = worst;
        }
    }

    /// The kept items, in the order they were placed.
    fn kept(&self) -> &[T] {
        &self.items
    }
}

/// The minimum-norm correction of `u_nom` onto the enforced constraints `cons` (violated by
/// `u_nom`), searched around the braking input `u_brake`; sets the diagnostics' region
/// (`D_⊥`), `intervened` and `infeasible`. Shared by the multi variants and the braking
/// variant.
fn project_near(u_nom: &Vec3, cons: &[HalfSpace], u_brake: &Vec3, diag: &mut FilterDiagnostics) -> Vec3 {
    // Bound: the optimum lies within 2|u* − u_brake| of the braking input whenever the
    // latter is feasible. Robust and margin terms shift each plane by c'_i = c_i − n_iᵀu_brake
    // beyond it; 4·Σ max(c'_i, 0) leaves room for those (a single plane's projection is
    // always within it, however large the class-K relaxation's demand: capped at 2·u_max
    // the projection was out of reach and u* itself came back), and excludes the far
    // sliver where nearly opposite, contradictory barriers meet (then: `infeasible`).
    let shift: f32 = cons.iter().map(|h| maxf(h.c - h.n.dot(u_brake), 0.0)).sum();
    let bound = 2.0 * norm3(&(u_nom - u_brake)) + 4.0 * shift;
    let sol = qp3::project_bounded(u_nom, cons, u_brake, bound);
    diag.region = Region::Perpendicular;
    diag.intervened = true;
    diag.infeasible = !sol.feasible;
    sol.u
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::CLUSTER_ID_BASE;
    use nalgebra::Matrix3;

    fn filt(variant: FilterVariant) -> SafetyFilter {
        SafetyFilter::new(CbfParams::new(0.9, 0.05, 0.08).unwrap(), variant).unwrap()
    }

    #[test]
    fn params_are_validated() {
        assert_eq!(CbfParams::new(0.0, 0.05, 0.1), Err(CbfError::MuNotPositive));
        assert_eq!(CbfParams::new(1.0, -0.1, 0.1), Err(CbfError::DeltaNotPositive));
        assert_eq!(CbfParams::new(1.0, 0.05, 0.05), Err(CbfError::Delta1NotAboveDelta));
        assert_eq!(CbfParams::new(f32::NAN, 0.05, 0.1), Err(CbfError::MuNotPositive));
        let bad = CbfParams { accel_bound: -1.0, ..CbfParams::default() };
        assert_eq!(SafetyFilter::new(bad, FilterVariant::Paper), Err(CbfError::AccelBoundNegative));
    }

    #[test]
    fn barrier_value_hand_computed() {
        // d = (0.3, 0, 0), ṗ = (−0.2, 0.1, 0), μ = 0.9: h = 0.09 + 0.9·(−0.06) = 0.036.
        let h = barrier_value(0.9, &Vec3::new(0.3, 0.0, 0.0), &Vec3::new(-0.2, 0.1, 0.0));
        assert!((h - 0.036).abs() < 1e-6);
    }

    #[test]
    fn law_12_matches_projection_matrices_and_zeroes_constraint() {
        let f = filt(FilterVariant::Paper);
        let p = Vec3::new(0.25, 0.05, -1.0);
        let v = Vec3::new(-0.3, 0.1, 0.0);
        let u_star = Vec3::new(-0.5, 0.2, 0.1);
        let obs = [ObstaclePoint::fixed(Vec3::new(0.0, 0.0, -1.0), 7)];
        let (u, diag) = f.apply(&p, &v, &u_star, &obs);
        assert_eq!(diag.region, Region::Perpendicular);
        assert_eq!(diag.active_id, Some(7));
        // Eq. 10-12 written with the projection matrices.
        let d = p - obs[0].point;
        let pi = d * d.transpose() / d.dot(&d);
        let pi_perp = Matrix3::identity() - pi;
        let expected = -(2.0 / 0.9) * pi * v + pi_perp * u_star;
        assert!((u - expected).norm() < 1e-5, "{u} vs {expected}");
        // In D_⊥: 2dᵀṗ + μdᵀu = 0.
        assert!((2.0 * d.dot(&v) + 0.9 * d.dot(&u)).abs() < 1e-5);
    }

    #[test]
    fn regions_far_and_nominal_safe() {
        let f = filt(FilterVariant::Paper);
        let obs = [ObstaclePoint::fixed(Vec3::zeros(), 1)];
        // Far: |d|² = 1 > δ1.
        let (u, d) = f.apply(&Vec3::new(1.0, 0.0, 0.0), &Vec3::zeros(), &Vec3::new(-1.0, 0.0, 0.0), &obs);
        assert_eq!((d.region, u), (Region::Far, Vec3::new(-1.0, 0.0, 0.0)));
        // Near but moving away with the nominal pushing away: D_u*.
        let (u, d) =
            f.apply(&Vec3::new(0.22, 0.0, 0.0), &Vec3::new(0.1, 0.0, 0.0), &Vec3::new(0.2, 0.3, 0.0), &obs);
        assert_eq!(d.region, Region::NominalSafe);
        assert_eq!(u, Vec3::new(0.2, 0.3, 0.0));
        assert!(!d.intervened);
    }

    #[test]
    fn bad_inputs_brake_with_finite_output() {
        let f = filt(FilterVariant::MultiRelative);
        let obs = [ObstaclePoint::fixed(Vec3::zeros(), 1)];
        let v = Vec3::new(1.0, 0.0, 0.0);
        for (p, u, o, fault) in [
            (Vec3::new(f32::NAN, 0.0, 0.0), Vec3::zeros(), obs[0], FilterFault::BadState),
            (Vec3::new(1.0, 0.0, 0.0), Vec3::new(f32::INFINITY, 0.0, 0.0), obs[0], FilterFault::BadNominal),
            (
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::zeros(),
                ObstaclePoint::fixed(Vec3::new(1e30, 0.0, 0.0), 1),
                FilterFault::BadObstacle,
            ),
            (Vec3::zeros(), Vec3::zeros(), obs[0], FilterFault::ZeroDistance),
        ] {
            let (out, d) = f.apply(&p, &v, &u, &[o]);
            assert_eq!(d.fault, Some(fault));
            assert_eq!(d.region, Region::Fault);
            assert!(out.iter().all(|x| x.is_finite()));
            // Braking opposes the velocity and is bounded.
            assert!(out.dot(&v) < 0.0 && out.norm() <= f.params.u_max + 1e-6);
        }
        let (out, _) = f.apply(&Vec3::zeros(), &Vec3::new(f32::NAN, 0.0, 0.0), &Vec3::zeros(), &obs);
        assert_eq!(out, Vec3::zeros());
    }

    #[test]
    fn relative_equals_paper_for_static_obstacles() {
        let p = Vec3::new(0.2, 0.1, 0.0);
        let v = Vec3::new(-0.4, 0.0, 0.1);
        let u = Vec3::new(-1.0, 0.5, 0.0);
        let obs = [ObstaclePoint::fixed(Vec3::zeros(), 1), ObstaclePoint::fixed(Vec3::new(2.0, 0.0, 0.0), 2)];
        assert_eq!(
            filt(FilterVariant::Paper).apply(&p, &v, &u, &obs),
            filt(FilterVariant::Relative).apply(&p, &v, &u, &obs)
        );
    }

    #[test]
    fn velocity_margin_pushes_away_when_at_rest_near_an_obstacle() {
        let p = Vec3::new(0.25, 0.0, 0.0);
        let obs = [ObstaclePoint::fixed(Vec3::zeros(), 1)];
        let prm = CbfParams { velocity_margin: 0.05, ..CbfParams::new(0.9, 0.05, 0.08).unwrap() };
        let f = SafetyFilter::new(prm, FilterVariant::Multi).unwrap();
        // Nominal pushes into the obstacle; at rest the margin demands 2ε_v/μ outwards.
        let (u, d) = f.apply(&p, &Vec3::zeros(), &Vec3::new(-1.0, 0.5, 0.0), &obs);
        assert!(d.intervened);
        assert!((u.x - 2.0 * 0.05 / 0.9).abs() < 1e-5 && (u.y - 0.5).abs() < 1e-6);
        let bad = CbfParams { velocity_margin: -0.1, ..CbfParams::default() };
        assert_eq!(bad.validate(), Err(CbfError::VelocityMarginNegative));
    }

    #[test]
    fn contradictory_nearly_opposite_walls_do_not_give_huge_accelerations() {
        // Reported from flight: corridor walls at x = ±0.45 m, position estimate 1 cm off,
        // velocity margin 0.05 m/s: the exact QP optimum is 3.24 m/s² straight down.
        let prm = CbfParams {
            velocity_margin: 0.05,
            sample_time: 0.004,
            ..CbfParams::new(1.4, 0.05, 0.3).unwrap()
        };
        let f = SafetyFilter::new(prm, FilterVariant::Multi).unwrap();
        let p = Vec3::new(0.0, 0.5, -0.99);
        let obs = [
            ObstaclePoint::fixed(Vec3::new(0.45, 0.5, -1.0), 1),
            ObstaclePoint::fixed(Vec3::new(-0.45, 0.5, -1.0), 2),
        ];
        let (u, d) = f.apply(&p, &Vec3::new(0.0, 0.2, 0.0), &Vec3::new(0.0, 0.2, 0.0), &obs);
        assert!(d.infeasible, "{d:?}");
        assert!(u.norm() < 1.0, "{u}");
    }

    #[test]
    fn deep_inside_the_margin_pushes_out_instead_of_passing_u_nom() {
        // 0.25 m from a point, closing at 1.5 m/s, the nominal pushing on towards it: h = −0.46,
        // and at γ = 20 the relaxation asks for c ≈ 31 m/s² along +x. With the search radius
        // capped at 2·u_max the projection was out of reach and u* = (−1, 0, 0) came back.
        for variant in [FilterVariant::Multi, FilterVariant::MultiRelative] {
            let prm =
                CbfParams { gamma: 20.0, sample_time: 0.004, ..CbfParams::new(1.4, 0.05, 0.1).unwrap() };
            let f = SafetyFilter::new(prm, variant).unwrap();
            let obs = [ObstaclePoint::fixed(Vec3::zeros(), 1)];
            let (u, d) = f.apply(
                &Vec3::new(0.25, 0.0, 0.0),
                &Vec3::new(-1.5, 0.0, 0.0),
                &Vec3::new(-1.0, 0.0, 0.0),
                &obs,
            );
            assert!(d.unavoidable && !d.infeasible, "{d:?}");
            let b = f.barrier(&Vec3::new(0.25, 0.0, 0.0), &Vec3::new(-1.5, 0.0, 0.0), &obs[0]).unwrap();
            let c = f.enforced_constraint(&b);
            assert!(c.c > 25.0, "{c:?}");
            assert!(c.violation(&u) <= 1e-4 * (1.0 + u.norm()), "{u} against {c:?}");
            assert!(u.x > prm.u_max, "{u}");
        }
    }

    #[test]
    fn relative_backs_away_from_approaching_obstacle() {
        // Vehicle at rest, obstacle 0.3 m away moving towards it at 0.5 m/s.
        let p = Vec3::new(0.3, 0.0, 0.0);
        let o = [ObstaclePoint {
            point: Vec3::zeros(),
            velocity: Some(Vec3::new(0.5, 0.0, 0.0)),
            id: 3,
            normal: None,
        }];
        let (u_paper, _) = filt(FilterVariant::Paper).apply(&p, &Vec3::zeros(), &Vec3::zeros(), &o);
        let (u_rel, d) = filt(FilterVariant::Relative).apply(&p, &Vec3::zeros(), &Vec3::zeros(), &o);
        assert_eq!(u_paper, Vec3::zeros()); // the paper's law sees nothing to do
        assert_eq!(d.region, Region::Perpendicular);
        assert!((u_rel.x - 2.0 * 0.5 / 0.9).abs() < 1e-5); // retreats along +x
    }

    #[test]
    fn multi_with_one_obstacle_equals_paper() {
        let p = Vec3::new(0.22, 0.05, 0.0);
        let v = Vec3::new(-0.3, 0.2, 0.0);
        let u = Vec3::new(-0.8, 0.1, 0.3);
        let obs = [ObstaclePoint::fixed(Vec3::zeros(), 1)];
        let (a, da) = filt(FilterVariant::Paper).apply(&p, &v, &u, &obs);
        let (b, db) = filt(FilterVariant::Multi).apply(&p, &v, &u, &obs);
        assert!((a - b).norm() < 1e-5);
        assert_eq!(da.region, db.region);
    }

    /// The filter as written before the far-obstacle shortcut (every obstacle's barrier and
    /// trigger value evaluated): `apply` must give exactly the same answer.
    fn apply_reference(
        f: &SafetyFilter,
        p: &Vec3,
        v: &Vec3,
        u_nom: &Vec3,
        obstacles: &[ObstaclePoint],
    ) -> (Vec3, FilterDiagnostics) {
        if !within_limits(p) || !within_limits(v) {
            return f.fault(v, FilterFault::BadState);
        }
        if !within_limits(u_nom) {
            return f.fault(v, FilterFault::BadNominal);
        }
        if obstacles.is_empty() {
            return (*u_nom, FilterDiagnostics::new(Region::NoObstacle));
        }
        let mut diag = FilterDiagnostics::new(Region::Far);
        let mut closest: Option<(Barrier, u16, f32)> = None;
        let mut near: heapless::Vec<(Barrier, u16), MAX_ACTIVE_BARRIERS> = heapless::Vec::new();
        for o in obstacles {
            if !within_limits(&o.point) || !o.velocity.is_none_or(|w| within_limits(&w)) {
                return f.fault(v, FilterFault::BadObstacle);
            }
            let Some(b) = f.barrier(p, v, o) else {
                return f.fault(v, FilterFault::ZeroDistance);
            };
            diag.h_bar = diag.h_bar.min(b.h - f.params.delta);
            let trigger = f.trigger_value(&b, u_nom);
            if closest.is_none_or(|(c, _, _)| b.dist_sq < c.dist_sq) {
                closest = Some((b, o.id, trigger));
            }
            if trigger <= f.params.delta1 {
                diag.n_near = diag.n_near.saturating_add(1);
                if let Err(item) = near.push((b, o.id)) {
                    let mut worst = 0;
                    for (i, (nb, _)) in near.iter().enumerate() {
                        if nb.h > near[worst].0.h {
                            worst = i;
                        }
                    }
                    if item.0.h < near[worst].0.h {
                        near[worst] = item;
                    }
                }
            }
        }
        let u_max = f.params.u_max;
        if !f.variant.is_multi() {
            let Some((b, id, trigger)) = closest else { return (*u_nom, diag) };
            diag.active_id = Some(id);
            if trigger > f.params.delta1 {
                return (*u_nom, diag);
            }
            let HalfSpace { n, c } = f.enforced(&b, sqrtf(b.dist_sq));
            diag.n_constraints = 1;
            diag.unavoidable = c > u_max;
            if n.dot(u_nom) > c {
                diag.region = Region::NominalSafe;
                return (*u_nom, diag);
            }
            diag.region = Region::Perpendicular;
            diag.intervened = true;
            return (u_nom + n * (c - n.dot(u_nom)), diag);
        }
        if near.is_empty() {
            diag.active_id = closest.map(|(_, id, _)| id);
            return (*u_nom, diag);
        }
        let mut cons = [HalfSpace { n: Vec3::zeros(), c: 0.0 }; MAX_ACTIVE_BARRIERS];
        let mut most_critical = (f32::INFINITY, 0u16);
        for (slot, (b, id)) in cons.iter_mut().zip(near.iter()) {
            *slot = f.enforced(b, sqrtf(b.dist_sq));
            diag.unavoidable |= slot.c > u_max;
            if b.h < most_critical.0 {
                most_critical = (b.h, *id);
            }
        }
        let cons = &cons[..near.len()];
        diag.n_constraints = near.len() as u8;
        diag.active_id = Some(most_critical.1);
        if cons.iter().all(|h| h.n.dot(u_nom) >= h.c) {
            diag.region = Region::NominalSafe;
            return (*u_nom, diag);
        }
        let u_brake = v * (-2.0 / f.params.mu);
        let shift: f32 = cons.iter().map(|h| (h.c - h.n.dot(&u_brake)).max(0.0)).sum();
        let bound = 2.0 * (u_nom - u_brake).norm() + 4.0 * shift;
        let sol = qp3::project_bounded(u_nom, cons, &u_brake, bound);
        diag.region = Region::Perpendicular;
        diag.intervened = true;
        diag.infeasible = !sol.feasible;
        (sol.u, diag)
    }

    mod props {
        extern crate std;
        use super::*;
        use proptest::prelude::*;
        use std::vec::Vec;

        fn vec(r: f32) -> impl Strategy<Value = Vec3> {
            (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
        }

        fn obstacle() -> impl Strategy<Value = ObstaclePoint> {
            // Mostly near the vehicle (within ~0.6 m, where the event rule switches), some far.
            (vec(0.6), 0.0f32..1.0, proptest::option::of(vec(1.0)), any::<u16>()).prop_map(
                |(d, far, w, id)| {
                    let scale = if far < 0.8 { 1.0 } else { 6.0 };
                    ObstaclePoint { point: d * scale, velocity: w, id, normal: None }
                },
            )
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(4000))]
            #[test]
            fn apply_equals_full_evaluation(
                v in vec(2.5),
                u in vec(8.0),
                obs in proptest::collection::vec(obstacle(), 0..12),
                variant in 0usize..4,
                t in prop_oneof![Just(0.0f32), Just(0.004), 0.0f32..0.05],
                margin in prop_oneof![Just(0.0f32), 0.0f32..0.2],
                accel in prop_oneof![Just(0.0f32), 0.0f32..2.0],
                delta1 in 0.06f32..0.4,
                gamma in prop_oneof![Just(0.0f32), 0.0f32..3.0],
            ) {
                let params = CbfParams {
                    gamma,
                    sample_time: t,
                    velocity_margin: margin,
                    accel_bound: accel,
                    ..CbfParams::new(1.4, 0.05, delta1).unwrap()
                };
                let f = SafetyFilter::new(params, FilterVariant::SQUARED_DISTANCE[variant]).unwrap();
                let p = Vec3::new(1.0, -2.0, -1.5);
                let obs: Vec<ObstaclePoint> =
                    obs.iter().map(|o| ObstaclePoint { point: p + o.point, ..*o }).collect();
                let (a, da) = f.apply(&p, &v, &u, &obs);
                let (b, db) = apply_reference(&f, &p, &v, &u, &obs);
                prop_assert_eq!(a, b);
                prop_assert_eq!(da, db);
            }
        }
    }

    #[test]
    fn gamma_lets_the_vehicle_approach_down_to_delta_and_pushes_back_below() {
        // At rest 0.3 m from a point (h = 0.09, δ = 0.05, δ1 = 0.1), nominal pulls at it.
        let obs = [ObstaclePoint::fixed(Vec3::zeros(), 3)];
        let u = Vec3::new(-1.0, 0.0, 0.0);
        for variant in FilterVariant::SQUARED_DISTANCE {
            let mk = |gamma: f32| {
                let p = CbfParams { gamma, ..CbfParams::new(1.4, 0.05, 0.1).unwrap() };
                SafetyFilter::new(p, variant).unwrap()
            };
            let (frozen, _) = mk(0.0).apply(&Vec3::new(0.3, 0.0, 0.0), &Vec3::zeros(), &u, &obs);
            assert!(frozen.x.abs() < 1e-6, "{variant:?}: γ = 0 freezes ({frozen})");
            // γ = 2: nᵀu ≥ −γ(h − δ)/(μ|d|) = −2·0.04/(1.4·0.3) = −0.190476.
            let (relaxed, d) = mk(2.0).apply(&Vec3::new(0.3, 0.0, 0.0), &Vec3::zeros(), &u, &obs);
            assert!((relaxed.x + 0.190476).abs() < 1e-5, "{variant:?}: {relaxed}");
            assert!(d.intervened);
            // Inside the hull (h = 0.04 < δ): the same term pushes out, 2·0.01/(1.4·0.2).
            let (out, _) = mk(2.0).apply(&Vec3::new(0.2, 0.0, 0.0), &Vec3::zeros(), &u, &obs);
            assert!((out.x - 0.0714286).abs() < 1e-5, "{variant:?}: {out}");
        }
        let bad = CbfParams { gamma: -1.0, ..CbfParams::default() };
        assert_eq!(bad.validate(), Err(CbfError::GammaNegative));
    }

    #[test]
    fn multi_satisfies_both_walls_of_a_corridor() {
        // Walls at y = ±0.25 m, vehicle drifting towards +y, nominal pushes +y harder.
        let p = Vec3::new(0.0, 0.05, 0.0);
        let v = Vec3::new(0.3, 0.1, 0.0);
        let u = Vec3::new(0.0, 2.0, 0.0);
        let obs = [
            ObstaclePoint::fixed(Vec3::new(0.0, 0.25, 0.0), 1),
            ObstaclePoint::fixed(Vec3::new(0.0, -0.25, 0.0), 2),
        ];
        let f = filt(FilterVariant::Multi);
        let (out, d) = f.apply(&p, &v, &u, &obs);
        assert!(d.intervened && !d.infeasible);
        for o in &obs {
            let b = f.barrier(&p, &v, o).unwrap();
            assert!(b.constraint.n.dot(&out) >= b.constraint.c - 1e-5);
        }
    }

    #[test]
    fn braking_variant_brakes_a_vehicle_that_pushes_towards_a_wall() {
        let f = SafetyFilter::new(CbfParams::default(), FilterVariant::Braking).unwrap();
        // Wall point 2 m ahead, closing at 2.5 m/s (h_b = 2 − 0.224 − 1.042 − 0.25 < engage).
        let o = [ObstaclePoint::fixed(Vec3::new(2.0, 0.0, -1.0), 7)];
        let (u, d) =
            f.apply(&Vec3::new(0.0, 0.0, -1.0), &Vec3::new(2.5, 0.0, 0.0), &Vec3::new(2.0, 0.5, 0.0), &o);
        assert!(d.intervened && d.region == Region::Perpendicular, "{d:?}");
        assert_eq!(d.active_id, Some(7));
        // −u_x ≥ c: it decelerates at least c; the sideways part is kept.
        let b = braking::barrier(
            &f.params.braking(),
            &Vec3::new(-2.0, 0.0, 0.0),
            &Vec3::new(2.5, 0.0, 0.0),
            true,
        )
        .unwrap();
        assert!(-u.x >= b.constraint.c - 1e-4, "{u:?} {b:?}");
        assert!((u.y - 0.5).abs() < 1e-4, "{u:?}");
        // Far away: the nominal passes.
        let (u2, d2) =
            f.apply(&Vec3::new(-20.0, 0.0, -1.0), &Vec3::new(2.5, 0.0, 0.0), &Vec3::new(2.0, 0.5, 0.0), &o);
        assert_eq!(u2, Vec3::new(2.0, 0.5, 0.0));
        assert_eq!(d2.region, Region::Far);
    }

    /// A double integrator at rest whose nominal command pushes it at 2 m/s² towards a point
    /// that walks into it at 0.3 m/s, reported every 4 ms as a cluster's point without velocity
    /// (what the obstacle memory gives for a mover it has not proven moving): the smallest distance
    /// between the vehicle and the point over 10 s.
    fn closest_approach_to_an_unproven_walker(unknown_speed: f32) -> f32 {
        let params = CbfParams { brake_unknown_speed: unknown_speed, ..CbfParams::default() };
        let f = SafetyFilter::new(params, FilterVariant::Braking).unwrap();
        let (dt, mut p, mut v) = (0.004f32, Vec3::zeros(), Vec3::zeros());
        let mut closest = f32::INFINITY;
        for k in 0..2500 {
            let walker = Vec3::new(1.5 - 0.3 * dt * k as f32, 0.0, 0.0);
            let (u, _) =
                f.apply(&p, &v, &Vec3::new(2.0, 0.0, 0.0), &[ObstaclePoint::fixed(walker, CLUSTER_ID_BASE)]);
            p += v * dt + u * (0.5 * dt * dt);
            v += u * dt;
            closest = closest.min((walker - p).norm());
        }
        closest
    }

    #[test]
    fn an_unproven_walker_is_kept_off_the_hull_by_the_unknown_speed() {
        let r = CbfParams::default().delta.sqrt();
        // w = 0.5 m/s ≥ the walker's 0.3: the vehicle backs off and keeps h_b ≥ 0 off the hull.
        let kept = closest_approach_to_an_unproven_walker(0.5);
        assert!(kept > r + 0.05, "closest {kept} with hull radius {r}");
        // Treated as static (w = 0) the walker pushes the vehicle through its hull radius:
        // with no approach speed of its own, h_b < 0 only pushes back once it is crossed.
        let static_model = closest_approach_to_an_unproven_walker(0.0);
        assert!(static_model < r, "closest {static_model} with hull radius {r}");
    }

    #[test]
    fn braking_variant_brakes_with_a_finite_output_on_bad_inputs() {
        let f = SafetyFilter::new(CbfParams::default(), FilterVariant::Braking).unwrap();
        let o = [ObstaclePoint::fixed(Vec3::new(2.0, 0.0, 0.0), 0)];
        let nan = Vec3::new(f32::NAN, 0.0, 0.0);
        for (p, v, u) in [
            (nan, Vec3::zeros(), Vec3::zeros()),
            (Vec3::zeros(), nan, Vec3::zeros()),
            (Vec3::zeros(), Vec3::zeros(), nan),
        ] {
            let (out, d) = f.apply(&p, &v, &u, &o);
            assert!(out.iter().all(|x| x.is_finite()));
            assert!(d.fault.is_some());
        }
        let (out, d) = f.apply(&Vec3::new(2.0, 0.0, 0.0), &Vec3::zeros(), &Vec3::zeros(), &o);
        assert_eq!(d.fault, Some(FilterFault::ZeroDistance));
        assert!(out.iter().all(|x| x.is_finite()));
    }
}
