//! The bound on the navigation estimate's error against the world, and the margin it gives
//! the **mapped** obstacles (world-frame points: a map, the scene's points) and the ground and
//! ceiling (`docs/filter.md` § 18) — one definition for the host's in-process controller
//! (`host-sim/src/fc/nav.rs`, `host-sim/src/flight/sensing.rs`) and the firmware
//! (`firmware/src/app/navigation.rs`, `firmware/src/link/obstacles.rs`). Sensed obstacles
//! (range returns, placed relative to the vehicle) get no margin: their relative geometry is
//! exact whatever the global error.
//!
//! **The bound**: [`MAPPED_MARGIN_SIGMA`]·σ of the filter per axis (horizontal: the larger of
//! north and east; vertical: down) plus the bound of the random walks the filter cannot
//! observe, which its σ says nothing of ([`UnobservedDrift`]):
//!
//! * a relative source's (vision) frame drift (m/√s, 3-D) since the first fix;
//! * the barometer's drift (m/√s), on the vertical, weighted by the barometer's share of the
//!   height information (the host's `gps` flights; the firmware, which does not know the
//!   source's rate, carries the whole of [`BARO_DRIFT_M_PER_SQRT_S`] once it fused a height).
//!
//! A random walk's σ at `t` does not bound it over the flight: pressed against an obstacle,
//! the vehicle meets the walk's excursions, and `W(s) > 3σ(s)` for some `s ≤ t` is far likelier
//! than at one `s`. The bound is the normal mixture's (Robbins 1970; Ville's inequality on the
//! martingale `(ρ/(s+ρ))^{d/2} exp(|W_s|²/(2σ₁²(s+ρ)))`):
//! `|W(s)| ≤ σ₁ √((s+ρ)(2 ln(1/α) + d ln(1+s/ρ)))` for **every** `s ≥ 0` with probability
//! ≥ 1 − α (`d` the walk's dimensions, `σ₁` its rate; [`DRIFT_BOUND_ALPHA`],
//! [`DRIFT_BOUND_RHO_S`]). Computed in `f64`, as the host did before it moved here (with
//! `std`'s `ln_1p`; `libm`'s `log1p` differs from glibc's in the last bit at some times: 4 of
//! 600,000 sampled bounds by ≤ 2 ulp in `f64`, none in the `f32` the margins are used in —
//! `host-sim/src/fc/nav.rs`'s test); the `f32` margin is taken from it in [`ErrorBound::along`].
//!
//! **Bad data**: a bound that is not a number (a NaN σ: the filter's covariance is broken) or
//! beyond [`ERROR_BOUND_MAX_M`] is [`ERROR_BOUND_MAX_M`] — every mapped obstacle as near as the
//! largest error the filter is flown with allows, the ground raised and the ceiling lowered by
//! it — and the filter is not usable then ([`super::aid::NavAid::usable`]): the controller gets
//! no fix and its position timeout brakes and lands. A negative one is 0.
//!
//! Owns: [`ErrorBound`], [`UnobservedDrift`], [`drift_bound`], [`error_bound`] and their
//! constants. May import: [`super`] (the σ limit), [`crate::Vec3`], [`crate::fmath`], `libm`.

use super::NAV_MAX_SIGMA_M;
use crate::fmath::sqrtf;
use crate::Vec3;

/// Margin on mapped obstacles, in σ of the navigation filter's position (per axis).
pub const MAPPED_MARGIN_SIGMA: f64 = 3.0;
/// Probability that an unobserved drift leaves its bound at any time of the flight.
pub const DRIFT_BOUND_ALPHA: f64 = 1e-4;
/// Time scale of the drift bound, s: where it is tightest against the walk's σ.
pub const DRIFT_BOUND_RHO_S: f64 = 1.0;
/// Largest error bound, m: [`MAPPED_MARGIN_SIGMA`] × the largest horizontal σ the estimate is
/// flown with ([`NAV_MAX_SIGMA_M`], `super::aid`'s failsafe); also the bound of a NaN σ
/// (module docs).
pub const ERROR_BOUND_MAX_M: f64 = MAPPED_MARGIN_SIGMA * NAV_MAX_SIGMA_M as f64;
/// Drift of a relative (vision) source the firmware assumes, m/√s: the rate of the simulator's
/// `vio` preset (`host-sim/src/sim/source.rs`); a vehicle whose odometry drifts faster needs
/// a larger value here.
pub const VISION_DRIFT_M_PER_SQRT_S: f64 = 0.03;
/// Drift of a barometer's height the firmware assumes, m/√s: the rate of the simulator's
/// barometer (`host-sim/src/sim/source.rs`, the `gps`, `rtk` and `vio` presets). The firmware
/// does not know the position source's rate, so it carries the whole of it on the vertical
/// (the host weights it by the barometer's share of the height information, `fc/nav.rs`):
/// the larger, safe side.
pub const BARO_DRIFT_M_PER_SQRT_S: f64 = 0.02;

/// `2 ln(1/α)` of [`DRIFT_BOUND_ALPHA`] (a constant: no `log` in the firmware's image; the
/// test checks it against the formula).
const TWO_LN_INV_ALPHA: f64 = 18.420680743952367;

/// Bound on a `dims`-dimensional random walk of rate `rate` (m/√s) over the whole of
/// `[0, t]` s (module docs): `rate √((t+ρ)(2 ln(1/α) + dims·ln(1+t/ρ)))`.
pub fn drift_bound(rate: f64, t: f64, dims: f64) -> f64 {
    let (rho, t) = (DRIFT_BOUND_RHO_S, t.max(0.0));
    rate * libm::sqrt((t + rho) * (TWO_LN_INV_ALPHA + dims * libm::log1p(t / rho)))
}

/// The random walks the filter cannot observe (module docs), m/√s; 0: none.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UnobservedDrift {
    /// A relative source's frame drift (3-D).
    pub relative: f64,
    /// The barometer's drift carried by the filter's height (vertical).
    pub baro: f64,
}

/// How far the estimate may be from the truth: a bound on the horizontal and on the vertical
/// error, m.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ErrorBound {
    /// Bound on the horizontal error, m.
    pub horizontal: f64,
    /// Bound on the vertical error, m.
    pub vertical: f64,
}

impl ErrorBound {
    /// No error (motion capture).
    pub const ZERO: Self = ErrorBound { horizontal: 0.0, vertical: 0.0 };

    /// The largest error along the unit direction `u`: `horizontal·|u_h| + vertical·|u_z|`
    /// (the support function of the cylinder `|e_h| ≤ horizontal, |e_z| ≤ vertical`).
    pub fn along(&self, u: &Vec3) -> f32 {
        let uh = sqrtf(u.x * u.x + u.y * u.y);
        (self.horizontal as f32) * uh + (self.vertical as f32) * u.z.abs()
    }

    /// A mapped (world-frame) obstacle point `q` as the controller flying the estimate `est`
    /// must see it: moved towards `est` by the bound along its direction ([`Self::along`]), so
    /// that it is no farther than it truly is while the error is within the bound; at least
    /// 1 cm of distance is left, and a point at the estimate stays where it is.
    pub fn shift_mapped(&self, q: &Vec3, est: &Vec3) -> Vec3 {
        let d = q - est;
        let n = d.norm();
        if n > 0.0 {
            let m = self.along(&(d / n));
            est + d * ((n - m).max(0.01) / n)
        } else {
            *q
        }
    }
}

/// The bound for the filter's position σ `sigma_p` (NED, m), `t_s` s after the first fix and
/// the drifts `drift` (module docs); each axis within `[0, ERROR_BOUND_MAX_M]`, NaN → the max.
pub fn error_bound(sigma_p: &Vec3, t_s: f64, drift: &UnobservedDrift) -> ErrorBound {
    let rel = if drift.relative > 0.0 { drift_bound(drift.relative, t_s, 3.0) } else { 0.0 };
    let baro = if drift.baro > 0.0 { drift_bound(drift.baro, t_s, 1.0) } else { 0.0 };
    let k = MAPPED_MARGIN_SIGMA;
    ErrorBound {
        horizontal: capped(k * f64::from(sigma_p.x.max(sigma_p.y)) + rel),
        vertical: capped(k * f64::from(sigma_p.z) + rel + baro),
    }
}

/// `x` within `[0, ERROR_BOUND_MAX_M]`; NaN → the max.
fn capped(x: f64) -> f64 {
    if x.is_nan() {
        ERROR_BOUND_MAX_M
    } else {
        x.clamp(0.0, ERROR_BOUND_MAX_M)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_constant_is_two_ln_of_one_over_alpha() {
        assert_eq!(TWO_LN_INV_ALPHA.to_bits(), (2.0 * libm::log(1.0 / DRIFT_BOUND_ALPHA)).to_bits());
    }

    /// The bound's pieces add as the docs say; rel on both axes, the barometer's on the vertical.
    #[test]
    fn the_bound_is_three_sigma_per_axis_plus_the_drifts() {
        let s = Vec3::new(0.1, 0.2, 0.05);
        let b = error_bound(&s, 0.0, &UnobservedDrift::default());
        assert_eq!(b, ErrorBound { horizontal: 3.0 * f64::from(0.2f32), vertical: 3.0 * f64::from(0.05f32) });
        let d = UnobservedDrift { relative: 0.03, baro: 0.02 };
        let b2 = error_bound(&s, 8.0, &d);
        let (r, w) = (drift_bound(0.03, 8.0, 3.0), drift_bound(0.02, 8.0, 1.0));
        assert_eq!(b2.horizontal, b.horizontal + r);
        assert_eq!(b2.vertical, b.vertical + r + w);
        // docs/filter.md § 18: 0.45 m at 8 s and 1.30 m at 60 s for vio's 0.03 m/√s.
        assert!((r - 0.45).abs() < 0.01, "{r}");
        assert!((drift_bound(0.03, 60.0, 3.0) - 1.30).abs() < 0.01);
    }

    /// A NaN or huge σ gives the largest bound, a negative one 0: never a NaN margin.
    #[test]
    fn a_nan_or_huge_sigma_gives_the_largest_bound() {
        let none = UnobservedDrift::default();
        let nan = error_bound(&Vec3::new(f32::NAN, f32::NAN, f32::NAN), 1.0, &none);
        assert_eq!(nan, ErrorBound { horizontal: ERROR_BOUND_MAX_M, vertical: ERROR_BOUND_MAX_M });
        let z_nan = error_bound(&Vec3::new(0.1, 0.1, f32::NAN), 1.0, &none);
        assert_eq!(z_nan.vertical, ERROR_BOUND_MAX_M);
        let huge = error_bound(&Vec3::new(1e30, 0.0, f32::INFINITY), 1.0, &none);
        assert_eq!(huge, ErrorBound { horizontal: ERROR_BOUND_MAX_M, vertical: ERROR_BOUND_MAX_M });
        let neg = error_bound(&Vec3::new(-1.0, -1.0, -1.0), 1.0, &none);
        assert_eq!(neg, ErrorBound::ZERO);
        let nan_t =
            error_bound(&Vec3::new(0.1, 0.1, 0.1), f64::NAN, &UnobservedDrift { relative: 0.03, baro: 0.0 });
        assert!(nan_t.horizontal.is_finite() && nan_t.horizontal <= ERROR_BOUND_MAX_M);
    }

    /// A mapped point beside the estimate moves in by the horizontal bound, one below by the
    /// vertical one; 1 cm is left; a point at the estimate stays.
    #[test]
    fn a_mapped_point_moves_towards_the_estimate_by_the_bound_along_its_direction() {
        let b = ErrorBound { horizontal: 0.6, vertical: 0.2 };
        let est = Vec3::new(1.0, 2.0, -3.0);
        let side = b.shift_mapped(&(est + Vec3::new(2.0, 0.0, 0.0)), &est);
        assert!((side - (est + Vec3::new(1.4, 0.0, 0.0))).norm() < 1e-6, "{side:?}");
        let below = b.shift_mapped(&(est + Vec3::new(0.0, 0.0, 1.0)), &est);
        assert!((below - (est + Vec3::new(0.0, 0.0, 0.8))).norm() < 1e-6, "{below:?}");
        let near = b.shift_mapped(&(est + Vec3::new(0.0, 0.3, 0.0)), &est);
        assert!(((near - est).norm() - 0.01).abs() < 1e-6, "{near:?}");
        assert_eq!(b.shift_mapped(&est, &est), est);
        assert_eq!(
            ErrorBound::ZERO.shift_mapped(&(est + Vec3::new(2.0, 0.0, 0.0)), &est),
            est + Vec3::new(2.0, 0.0, 0.0)
        );
    }
}
