//! The navigation filter between a filtered position source (`gps`, `rtk`, `vio`:
//! `crate::sim::source`) and the in-process controller: [`parapet_core::nav::aid::NavAid`] (the
//! code the firmware runs too: IMU-rate predict, delayed fixes, the controller's fix and the
//! dropout failsafe of [`parapet_core::nav::aid::NAV_TIMEOUT_US`]) fed with the simulator's
//! readings and the σ the scene states for its source.
//!
//! **The error bound of mapped obstacles' margin** (`docs/filter.md` § 18,
//! [`NavAid::error_bound`]): the core's ([`parapet_core::nav::bound`], the firmware's too) for
//! this filter's σ and the drifts of the scene's source it cannot observe — a relative source's
//! (`vio`) frame drift and the barometer's drift (m/√s), on the vertical, weighted by the
//! barometer's share of the height information (`w = I_b / (I_b + I_s)`, `I = rate / σ²`: the
//! filter's height is that weighted mean of the two, so it carries `w` of the barometer's drift
//! — 0.86 with `gps`, 0.01 with `rtk`, 0.003 with `vio`).
//!
//! Owns: [`NavAid`]. May import: `parapet-core`, [`crate::sim`].

use parapet_core::controller::PositionFix;
use parapet_core::msg::Euler;
use parapet_core::nav::aid::{NavAid as CoreAid, SourceNoise};
use parapet_core::nav::bound::{ErrorBound, UnobservedDrift};
use parapet_core::nav::{FixKind, NavParams, NavStatus};
use parapet_core::Vec3;

use crate::sim::sensors::{PositionReading, SensorParams};
use crate::sim::source::{PositionSource, BARO_RATE_HZ};

/// The filter and what it knows of its source.
#[derive(Clone, Debug)]
pub struct NavAid {
    aid: CoreAid,
    kind: FixKind,
    noise: SourceNoise,
    sigma_baro: f32,
    /// A relative source's drift, m/√s (0 for an absolute one).
    drift: f32,
    /// The barometer's drift carried by the filter's height, m/√s (its rate × its share
    /// of the height information; module docs).
    baro_drift: f64,
}

impl NavAid {
    /// For the source of `sensors`; `None` for motion capture (the latest fix, as before).
    pub fn for_sensors(sensors: &SensorParams) -> Option<Self> {
        let src = sensors.position_source;
        if src.is_mocap() {
            return None;
        }
        let baro = src.preset().baro.map_or(1.0, |(n, _)| n);
        let noise = Self::noise_of(sensors);
        let rate = if sensors.rate > 0.0 { sensors.rate } else { src.preset().rate_hz.max(1.0) };
        let sigma_baro = floor(baro) * 1.5;
        let baro_drift = src.preset().baro.map_or(0.0, |(_, d)| {
            let ib = BARO_RATE_HZ / f64::from(sigma_baro * sigma_baro);
            let is = rate / f64::from(noise.position * noise.position);
            d * ib / (ib + is)
        });
        Some(NavAid {
            aid: CoreAid::new(NavParams::default()),
            kind: Self::kind_of(src),
            noise,
            sigma_baro,
            baro_drift,
            drift: if Self::kind_of(src) == FixKind::Relative { src.preset().drift as f32 } else { 0.0 },
        })
    }

    /// How the filter takes the fixes of `src` (vision: relative).
    pub fn kind_of(src: PositionSource) -> FixKind {
        if src == PositionSource::Vio {
            FixKind::Relative
        } else {
            FixKind::Absolute
        }
    }

    /// The σ the filter is told: the noise the scene gives the source (a floor keeps a
    /// noise-free flight well posed).
    pub fn noise_of(sensors: &SensorParams) -> SourceNoise {
        SourceNoise { position: floor(sensors.position_noise), velocity: floor(sensors.velocity_noise) }
    }

    /// One IMU sample (specific force, body FRD) at `t_us` with the estimator's attitude.
    pub fn imu(&mut self, t_us: u64, accel: &Vec3, attitude: &Euler) {
        let _ = self.aid.imu(t_us, accel, attitude);
    }

    /// A delayed fix (`t_us`: the time it describes).
    pub fn fix(&mut self, t_us: u64, r: &PositionReading) {
        let _ = self.aid.fix(&reading_fix(t_us, r), self.noise, self.kind);
    }

    /// A barometer reading (NED down, m) of `t_us`.
    pub fn height(&mut self, t_us: u64, down: f64) {
        let _ = self.aid.height(t_us, down as f32, self.sigma_baro);
    }

    /// The controller's fix at `now_us`; `None` before the first fix and in the failsafe.
    pub fn controller_fix(&self, now_us: u64) -> Option<PositionFix> {
        self.aid.controller_fix(now_us)
    }

    /// The estimate at `now_us` (NED position, velocity).
    pub fn estimate(&self, now_us: u64) -> Option<(Vec3, Vec3)> {
        self.aid.estimate(now_us)
    }

    /// The bound on the estimate's error against the world at `now_us` (module docs):
    /// [`parapet_core::nav::bound::error_bound`] of the filter's σ and the source's unobserved
    /// drifts since the first fix (a relative source's on every axis, the barometer's on the
    /// vertical).
    pub fn error_bound(&self, now_us: u64) -> ErrorBound {
        let drift = UnobservedDrift { relative: f64::from(self.drift), baro: self.baro_drift };
        self.aid.error_bound(now_us, &drift)
    }

    /// The delta of an absolute source's reset not yet handed on (the estimate jumped by it;
    /// `FlightController::position_reset`), once per reset. A relative source's reset moves
    /// only the frame offset: the estimate does not jump, nothing to hand on.
    pub fn take_reset(&mut self) -> Option<Vec3> {
        self.aid.take_reset()
    }

    /// Counters and σ.
    pub fn status(&self) -> NavStatus {
        self.aid.status()
    }
}

fn floor(x: f64) -> f32 {
    (x as f32).max(0.01)
}

/// A simulator reading as the core's fix of `t_us` (f64 → f32, the yaw attached).
pub fn reading_fix(t_us: u64, r: &PositionReading) -> PositionFix {
    let p = Vec3::new(r.position.x as f32, r.position.y as f32, r.position.z as f32);
    let v = Vec3::new(r.velocity.x as f32, r.velocity.y as f32, r.velocity.z as f32);
    PositionFix { t_us, position: p, velocity: v, yaw: Some(r.yaw as f32) }
}

#[cfg(test)]
mod tests {
    use parapet_core::nav::bound::{drift_bound, DRIFT_BOUND_ALPHA, DRIFT_BOUND_RHO_S};

    /// The barometer the firmware assumes (`BARO_SIGMA_M`, `BARO_DRIFT_M_PER_SQRT_S`: it cannot
    /// read the simulator's presets) is the one the host's filter is told for every source
    /// with a barometer, so the PIL flights and their host twin fly the same heights.
    #[test]
    fn the_firmware_barometer_is_the_presets() {
        use crate::sim::source::PositionSource;
        use parapet_core::nav::aid::BARO_SIGMA_M;
        use parapet_core::nav::bound::BARO_DRIFT_M_PER_SQRT_S;
        for src in [PositionSource::Gps, PositionSource::Rtk, PositionSource::Vio] {
            let sensors = crate::sim::sensors::SensorParams { position_source: src, ..Default::default() };
            let aid = super::NavAid::for_sensors(&sensors).expect("a filtered source");
            // 0.3 × 1.5 in f32 is 0.45000002: the same σ to its last bit but one.
            assert!((aid.sigma_baro - BARO_SIGMA_M).abs() < 1e-6, "{src:?}: {}", aid.sigma_baro);
            assert_eq!(src.preset().baro.map(|b| b.1), Some(BARO_DRIFT_M_PER_SQRT_S), "{src:?}");
        }
    }

    /// The core's bound (`libm`'s `log1p` and `sqrt`, so the firmware computes it too) against
    /// the one the host computed with `std` before it moved to the core, at every outer step
    /// (4 ms) of 10 minutes for the rates the host flies (`vio`, the barometer's shares of
    /// `gps`, `rtk`, `vio`): `libm`'s `log1p` and glibc's differ in the last bit at some times,
    /// so the bound does by a few ulp in `f64` and, rarely, by 1 ulp in the `f32` the margins
    /// are used in (`ErrorBound::along`, the boundary margin: ≈ 10⁻⁷ m); counted and printed.
    #[test]
    fn the_core_drift_bound_is_the_std_formula_to_a_few_ulp() {
        let old = |rate: f64, t: f64, dims: f64| {
            let (rho, t) = (DRIFT_BOUND_RHO_S, t.max(0.0));
            rate * ((t + rho) * (2.0 * (1.0 / DRIFT_BOUND_ALPHA).ln() + dims * (t / rho).ln_1p())).sqrt()
        };
        let (mut n, mut ulp, mut ulp32, mut max_ulp) = (0, 0, 0, 0);
        for (rate, dims) in [(f64::from(0.03f32), 3.0), (0.0172, 1.0), (0.0002, 1.0), (0.03, 1.0)] {
            for k in 0..150_000u64 {
                let t = (k * 4_000 + k % 7) as f64 * 1e-6;
                let (a, b) = (drift_bound(rate, t, dims), old(rate, t, dims));
                let d = a.to_bits().abs_diff(b.to_bits());
                assert!(d <= 4, "t = {t}: {a} vs {b}");
                max_ulp = max_ulp.max(d);
                let (a32, b32) = ((a as f32).to_bits(), (b as f32).to_bits());
                assert!(a32.abs_diff(b32) <= 1, "t = {t}");
                ulp += usize::from(a != b);
                ulp32 += usize::from(a32 != b32);
                n += 1;
            }
        }
        println!("drift bound, core against std: {ulp} of {n} differ in f64 (at most {max_ulp} ulp), {ulp32} by 1 ulp in f32");
        assert_eq!(n, 600_000);
        assert!(ulp32 * 1000 < n, "{ulp32} of {n} in f32");
    }
}
