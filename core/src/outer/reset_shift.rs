//! The reference's shift after a position reset (issue 39): when the navigation filter resets
//! its position to an absolute source that jumped (`crate::nav`, `NavStatus::last_reset_delta`,
//! as PX4's `xy_reset_counter` / `xy_reset_delta`), the estimate jumps by the delta `δ`. A
//! reference left where it was would jump the tracking error by `δ` and the commanded
//! acceleration by the position gain times `δ`. The guidance instead adds the shift `δ` to
//! the reference at the reset and lets it decay to zero along a quintic `s(τ) = 1 − 10τ³ +
//! 15τ⁴ − 6τ⁵` (`τ` from 0 to 1 over [`ResetShift::duration_s`]): position, velocity and
//! acceleration of the shift start at `δ`, 0, 0 and end at 0, 0, 0, so the tracking error is
//! continuous and the reference returns to the world path within the bounded acceleration
//! `5.77 |δ| / T²`.
//!
//! Owns: [`ResetShift`]. May import: the crate root foundation.

use crate::fmath::norm3;
use crate::Vec3;

/// Shortest decay of a shift, s.
pub const RESET_SHIFT_MIN_S: f32 = 2.0;
/// Largest mean speed at which a shift decays, m/s (a 1 m jump decays over 2 s at most 0.94 m/s).
pub const RESET_SHIFT_SPEED: f32 = 0.5;

/// A decaying shift of the reference (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResetShift {
    delta: Vec3,
    t0_us: u64,
    duration_s: f32,
}

impl ResetShift {
    /// A shift `delta` (NED, m) from `now_us`; `None` when `delta` is not finite or zero.
    pub fn new(delta: Vec3, now_us: u64) -> Option<Self> {
        let len = norm3(&delta);
        if !len.is_finite() || len <= 0.0 {
            return None;
        }
        Some(ResetShift {
            delta,
            t0_us: now_us,
            duration_s: (len / RESET_SHIFT_SPEED).max(RESET_SHIFT_MIN_S),
        })
    }

    /// How long the shift takes to decay, s.
    pub fn duration_s(&self) -> f32 {
        self.duration_s
    }

    /// Position, velocity and acceleration of the shift at `now_us` (NED); `None` once decayed.
    pub fn at(&self, now_us: u64) -> Option<(Vec3, Vec3, Vec3)> {
        let t = now_us.saturating_sub(self.t0_us) as f32 * 1e-6;
        let d = self.duration_s;
        if t >= d {
            return None;
        }
        let x = t / d;
        let (x2, x3) = (x * x, x * x * x);
        let s = 1.0 - 10.0 * x3 + 15.0 * x3 * x - 6.0 * x3 * x2;
        let ds = (-30.0 * x2 + 60.0 * x3 - 30.0 * x2 * x2) / d;
        let dds = (-60.0 * x + 180.0 * x2 - 120.0 * x3) / (d * d);
        Some((self.delta * s, self.delta * ds, self.delta * dds))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shift_starts_at_delta_at_rest_and_decays_smoothly_to_zero() {
        let delta = Vec3::new(1.0, -0.5, 0.2);
        let s = ResetShift::new(delta, 1_000_000).unwrap();
        let (p, v, a) = s.at(1_000_000).unwrap();
        assert!(norm3(&(p - delta)) < 1e-6 && norm3(&v) < 1e-6 && norm3(&a) < 1e-6);
        let d = s.duration_s();
        assert!((d - norm3(&delta) / RESET_SHIFT_SPEED).abs() < 1e-4 || d == RESET_SHIFT_MIN_S);
        // Largest acceleration 5.77 |δ| / T² (at τ = 0.21); the shift's velocity is its derivative.
        let mut top = 0.0f32;
        let mut prev = p;
        for k in 1..1000 {
            let t = 1_000_000 + (k as f32 * d * 1e3) as u64;
            let Some((p, v, a)) = s.at(t) else { break };
            top = top.max(norm3(&a));
            let fd = (p - prev) / (d * 1e-3);
            assert!(norm3(&(fd - v)) < 0.02, "{fd:?} vs {v:?}");
            prev = p;
        }
        assert!((top - 5.7735 * norm3(&delta) / (d * d)).abs() < 0.01, "{top}");
        assert!(s.at(1_000_000 + (d * 1e6) as u64 + 1).is_none());
        assert!(ResetShift::new(Vec3::zeros(), 0).is_none());
        assert!(ResetShift::new(Vec3::new(f32::NAN, 0.0, 0.0), 0).is_none());
    }
}
