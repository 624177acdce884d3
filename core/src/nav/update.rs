//! The measurement updates of [`NavFilter`]: position (absolute or relative source),
//! velocity and height, each fused at the time it describes (the delayed-state Jacobian
//! `H Φ(t_m, now)`, `docs/cascade.md` § Navigation filter), χ²-gated, the correction carried
//! to now and back into the history.
//!
//! Owns: [`NavFilter::fuse_position`], [`NavFilter::fuse_velocity`],
//! [`NavFilter::fuse_height`]. May import: [`super`], the crate root foundation.

use nalgebra::{Matrix3, SMatrix, SVector};

use super::history::Past;
use super::{finite3, FixKind, Fusion, NavFilter, CHI2_GATE, INIT_GAP_US, INIT_SPEED_M_S};
use crate::Vec3;

/// What a fix is compared with: the state at its time and the delay to now.
struct Delayed {
    past: Past,
    /// now − t_m, s (≥ 0).
    delay: f32,
}

/// Two position fixes `dt` s apart (σ `s0`, `s1` m) agree: within the χ² gate of their
/// combined noise plus what the vehicle may move meanwhile ([`INIT_SPEED_M_S`]).
fn agrees(z0: &Vec3, s0: f32, z1: &Vec3, s1: f32, dt: f32) -> bool {
    let bound = crate::fmath::sqrtf(CHI2_GATE[2] * (s0 * s0 + s1 * s1)) + INIT_SPEED_M_S * dt;
    (z1 - z0).norm_squared() <= bound * bound
}

impl NavFilter {
    /// The history state at `t_us` (extrapolated from the entry before it with its velocity)
    /// and the delay to the filter's time; `None` when `t_us` lies before the history or more
    /// than one history period after now.
    fn delayed(&self, t_us: u64) -> Option<Delayed> {
        let now = self.t_us?;
        if t_us > now.saturating_add(self.params.history_period_us) {
            return None;
        }
        let e = self.history.at_or_before(t_us.min(now))?;
        let gap = (t_us.min(now) - e.t_us) as f32 * 1e-6;
        let past = Past { t_us, p: e.p + e.v * gap, v: e.v };
        Some(Delayed { past, delay: now.saturating_sub(t_us) as f32 * 1e-6 })
    }

    /// Check time, value and σ of a fix; counts it when invalid.
    fn admit(&mut self, t_us: u64, z: &Vec3, sigma: f32) -> Option<Delayed> {
        let d = if finite3(z) && sigma.is_finite() && sigma > 0.0 { self.delayed(t_us) } else { None };
        if d.is_none() {
            self.status.invalid = self.status.invalid.wrapping_add(1);
        }
        d
    }

    /// Fuse a position fix `z` (NED, m, σ `sigma` m per axis) that describes the time `t_us`.
    /// [`NavParams::init_fixes`](super::NavParams::init_fixes) consecutive agreeing valid
    /// ones initialise the filter (module docs: *Initialisation*). See the module docs for
    /// `kind`.
    pub fn fuse_position(&mut self, t_us: u64, z: &Vec3, sigma: f32, kind: FixKind) -> Fusion {
        if !self.initialised {
            if !(finite3(z) && sigma.is_finite() && sigma > 0.0) || self.t_us.is_none() {
                self.status.invalid = self.status.invalid.wrapping_add(1);
                return Fusion::Invalid;
            }
            let agreeing = match self.candidate {
                Some((t0, z0, s0, n))
                    if t_us >= t0
                        && t_us - t0 <= INIT_GAP_US
                        && agrees(&z0, s0, z, sigma, (t_us - t0) as f32 * 1e-6) =>
                {
                    n
                }
                _ => 0,
            };
            let n = agreeing.saturating_add(1);
            if n < self.params.init_fixes {
                self.candidate = Some((t_us, *z, sigma, n));
                return Fusion::Pending;
            }
            self.candidate = None;
            self.initialise(t_us, *z, sigma);
            return Fusion::Initialised;
        }
        let Some(d) = self.admit(t_us, z, sigma) else { return Fusion::Invalid };
        let offset = if kind == FixKind::Relative { self.offset } else { Vec3::zeros() };
        let y = z - d.past.p - offset;
        let r = sigma * sigma + self.process_position(d.delay);
        let h = self.h_position(d.delay);
        let fused = self.update::<3>(&h, &SVector::<f32, 3>::from(y), r);
        self.status.last_nis = self.nis;
        match fused {
            Some(_) => {
                self.consecutive_gated = 0;
                self.last_position_us = Some(t_us.max(self.last_position_us.unwrap_or(0)));
                Fusion::Fused
            }
            None => {
                self.consecutive_gated = self.consecutive_gated.saturating_add(1);
                if self.consecutive_gated < self.params.reset_after {
                    return Fusion::Gated;
                }
                self.reset_source(y, sigma, kind, t_us);
                Fusion::Reset
            }
        }
    }

    /// Fuse a velocity fix `z` (NED, m/s, σ `sigma` m/s per axis) of the time `t_us`.
    pub fn fuse_velocity(&mut self, t_us: u64, z: &Vec3, sigma: f32) -> Fusion {
        if !self.initialised {
            return Fusion::NotInitialised;
        }
        let Some(d) = self.admit(t_us, z, sigma) else { return Fusion::Invalid };
        let y = z - d.past.v;
        let r = sigma * sigma + self.params.accel_noise * self.params.accel_noise * d.delay;
        let mut h = SMatrix::<f32, 3, 9>::zeros();
        h.fixed_view_mut::<3, 3>(0, 3).copy_from(&Matrix3::identity());
        h.fixed_view_mut::<3, 3>(0, 6).copy_from(&(self.rot.matrix() * d.delay));
        let fused = self.update::<3>(&h, &SVector::<f32, 3>::from(y), r);
        self.status.last_velocity_nis = self.nis;
        match fused {
            Some(_) => Fusion::Fused,
            None => Fusion::Gated,
        }
    }

    /// Fuse a height fix: `down` = the NED z (m, −altitude), σ `sigma` m, of the time `t_us`
    /// (a barometer whose reference is the take-off height).
    pub fn fuse_height(&mut self, t_us: u64, down: f32, sigma: f32) -> Fusion {
        if !self.initialised {
            return Fusion::NotInitialised;
        }
        let Some(d) = self.admit(t_us, &Vec3::new(0.0, 0.0, down), sigma) else { return Fusion::Invalid };
        let y = down - d.past.p.z;
        let r = sigma * sigma + self.process_position(d.delay);
        let h = self.h_position(d.delay).fixed_rows::<1>(2).into_owned();
        let fused = self.update::<1>(&h, &SVector::<f32, 1>::new(y), r);
        self.status.last_height_nis = self.nis;
        match fused {
            Some(_) => Fusion::Fused,
            None => Fusion::Gated,
        }
    }

    /// Position variance the process adds over a delay `dt` (s): `σ_a² dt³ / 3`.
    fn process_position(&self, dt: f32) -> f32 {
        self.params.accel_noise * self.params.accel_noise * dt * dt * dt / 3.0
    }

    /// `H Φ(t_m, now)` of a position fix with delay `dt`: `[I, −dt I, −½dt² R]`.
    fn h_position(&self, dt: f32) -> SMatrix<f32, 3, 9> {
        let mut h = SMatrix::<f32, 3, 9>::zeros();
        h.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
        h.fixed_view_mut::<3, 3>(0, 3).copy_from(&(Matrix3::identity() * -dt));
        h.fixed_view_mut::<3, 3>(0, 6).copy_from(&(self.rot.matrix() * (-0.5 * dt * dt)));
        h
    }

    /// Kalman update with innovation `y`, Jacobian `h` and noise `r` per component: returns
    /// the normalised innovation squared when fused, `None` when gated (counted) or when `S`
    /// is not positive definite. The NIS, fused or gated, is left in `self.nis` (0 when `S`
    /// is not positive definite) for the status's test ratios.
    fn update<const M: usize>(&mut self, h: &SMatrix<f32, M, 9>, y: &SVector<f32, M>, r: f32) -> Option<f32> {
        let pht = self.cov * h.transpose();
        let mut s = h * pht;
        for i in 0..M {
            s[(i, i)] += r;
        }
        let chol = s.cholesky();
        self.nis = 0.0;
        let Some(chol) = chol else {
            self.status.invalid = self.status.invalid.wrapping_add(1);
            return None;
        };
        let s_inv_y = chol.solve(y);
        let nis = y.dot(&s_inv_y);
        self.nis = nis;
        if !nis.is_finite() || nis > CHI2_GATE[M.min(3) - 1] {
            self.status.gated = self.status.gated.wrapping_add(1);
            return None;
        }
        // K = P Hᵀ S⁻¹; δx = K y; P ← P − K H P.
        let k = pht * chol.inverse();
        let dx = pht * s_inv_y;
        let p = self.cov - k * pht.transpose();
        self.cov = (p + p.transpose()) * 0.5;
        self.apply(&dx);
        self.status.fused = self.status.fused.wrapping_add(1);
        Some(nis)
    }

    /// Apply the error-state correction `dx` (at now) to the state and carry it back into
    /// the history: entry `k`, `Δ = now − t_k`, gets `δp − δv Δ − ½ R δb Δ²`, `δv + R δb Δ`.
    fn apply(&mut self, dx: &SVector<f32, 9>) {
        let dp = Vec3::new(dx[0], dx[1], dx[2]);
        let dv = Vec3::new(dx[3], dx[4], dx[5]);
        let db = Vec3::new(dx[6], dx[7], dx[8]);
        self.p += dp;
        self.v += dv;
        self.ba += db;
        let rdb = self.rot * db;
        let now = self.t_us.unwrap_or(0);
        self.history.for_each_mut(|e| {
            let t = now.saturating_sub(e.t_us) as f32 * 1e-6;
            e.p += dp - dv * t - rdb * (0.5 * t * t);
            e.v += dv + rdb * t;
        });
    }

    /// The source jumped (see the module docs): a relative source's frame offset absorbs the
    /// jump; an absolute one resets the position (and its variance) to the fix.
    fn reset_source(&mut self, y: Vec3, sigma: f32, kind: FixKind, t_us: u64) {
        self.consecutive_gated = 0;
        self.status.resets = self.status.resets.wrapping_add(1);
        self.status.last_reset_delta = y;
        self.last_position_us = Some(t_us.max(self.last_position_us.unwrap_or(0)));
        if kind == FixKind::Relative {
            self.offset += y;
            return;
        }
        self.p += y;
        self.history.for_each_mut(|e| e.p += y);
        for i in 0..3 {
            for j in 0..9 {
                self.cov[(i, j)] = 0.0;
                self.cov[(j, i)] = 0.0;
            }
            self.cov[(i, i)] = sigma * sigma;
        }
    }
}
