//! Simulated position sources (issue 39): the `[sensors] position_source` presets and the
//! errors they add to the true position, velocity and yaw — motion capture (as before), GPS,
//! RTK GPS and visual-inertial odometry — plus a magnetometer's yaw and a barometer's height.
//!
//! | source | rate | position σ | velocity σ | latency | other |
//! |--------|------|-----------|-----------|---------|-------|
//! | `mocap` | every outer step (250 Hz) | 5 mm | 0.02 m/s | 10 ms | true yaw |
//! | `gps`   | 10 Hz | 0.5 m | 0.1 m/s | 150 ms | multipath outliers (1 %, σ 5 m); magnetometer yaw (σ 0.03 rad, constant disturbance σ 0.05 rad); barometer (σ 0.3 m, drift 0.02 m/√s) |
//! | `rtk`   | 10 Hz | 0.02 m | 0.05 m/s | 100 ms | magnetometer yaw and barometer as `gps` |
//! | `vio`   | 30 Hz | 0.02 m | 0.05 m/s | 50 ms | position drift (random walk 0.03 m/√s), a frame reset every 60 s (jump σ 1 m), vision yaw (σ 0.01 rad); barometer as `gps` |
//!
//! Explicit `[sensors]` keys (`position_noise`, `velocity_noise`, `position_latency`, `rate`)
//! override the preset's values (`crate::world::scene` applies them);
//! `dropout_start`/`dropout_length` remove every fix of a window.
//!
//! Owns: [`PositionSource`], [`SourcePreset`], [`SourceModel`]. May import: nothing of the crate.

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Where the position fix comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PositionSource {
    /// Motion capture: today's idealised fix, the controller extrapolates the latest one.
    #[default]
    Mocap,
    /// Single-frequency GPS with a magnetometer and a barometer.
    Gps,
    /// RTK GPS.
    Rtk,
    /// Visual-inertial odometry (its own frame: drift and resets).
    Vio,
}

impl PositionSource {
    /// Every source, in the order of the docs.
    pub const ALL: [PositionSource; 4] =
        [PositionSource::Mocap, PositionSource::Gps, PositionSource::Rtk, PositionSource::Vio];

    /// The scene-file name.
    pub fn as_str(self) -> &'static str {
        match self {
            PositionSource::Mocap => "mocap",
            PositionSource::Gps => "gps",
            PositionSource::Rtk => "rtk",
            PositionSource::Vio => "vio",
        }
    }

    /// `true` for motion capture (no navigation filter: the latest fix extrapolated).
    pub fn is_mocap(self) -> bool {
        self == PositionSource::Mocap
    }

    /// `true` for the sources whose yaw is a compass's (`gps`, `rtk`): the PIL host sends it as
    /// HIL_SENSOR's magnetometer field (`parapet_core::nav::mag`).
    pub fn has_magnetometer(self) -> bool {
        matches!(self, PositionSource::Gps | PositionSource::Rtk)
    }

    /// The preset (see the module table).
    pub fn preset(self) -> SourcePreset {
        let mag = (0.03, 0.05);
        let baro = (0.3, 0.02);
        let none = SourcePreset {
            rate_hz: 0.0,
            position_noise: 0.005,
            velocity_noise: 0.02,
            position_latency: 0.01,
            multipath_prob: 0.0,
            multipath_size: 0.0,
            drift: 0.0,
            reset_interval: 0.0,
            reset_size: 0.0,
            yaw: None,
            baro: None,
        };
        match self {
            PositionSource::Mocap => none,
            PositionSource::Gps => SourcePreset {
                rate_hz: 10.0,
                position_noise: 0.5,
                velocity_noise: 0.1,
                position_latency: 0.15,
                multipath_prob: 0.01,
                multipath_size: 5.0,
                yaw: Some(mag),
                baro: Some(baro),
                ..none
            },
            PositionSource::Rtk => SourcePreset {
                rate_hz: 10.0,
                position_noise: 0.02,
                velocity_noise: 0.05,
                position_latency: 0.1,
                yaw: Some(mag),
                baro: Some(baro),
                ..none
            },
            PositionSource::Vio => SourcePreset {
                rate_hz: 30.0,
                position_noise: 0.02,
                velocity_noise: 0.05,
                position_latency: 0.05,
                drift: 0.03,
                reset_interval: 60.0,
                reset_size: 1.0,
                yaw: Some((0.01, 0.0)),
                baro: Some(baro),
                ..none
            },
        }
    }
}

impl core::str::FromStr for PositionSource {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        PositionSource::ALL.into_iter().find(|p| p.as_str() == s).ok_or(())
    }
}

/// The numbers of a source (see the module table).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SourcePreset {
    /// Fix rate, Hz (0: one fix per call, i.e. per outer step).
    pub rate_hz: f64,
    /// Position σ, m.
    pub position_noise: f64,
    /// Velocity σ, m/s.
    pub velocity_noise: f64,
    /// Latency, s.
    pub position_latency: f64,
    /// Probability of a multipath outlier per fix.
    pub multipath_prob: f64,
    /// σ of a multipath outlier, m.
    pub multipath_size: f64,
    /// Position drift (random walk), m/√s.
    pub drift: f64,
    /// Period of the frame resets, s (0: none).
    pub reset_interval: f64,
    /// σ of the offset a frame reset leaves, m.
    pub reset_size: f64,
    /// Measured yaw (noise σ, constant disturbance σ), rad; `None`: the true yaw.
    pub yaw: Option<(f64, f64)>,
    /// Barometer (noise σ m, drift m/√s); `None`: no barometer.
    pub baro: Option<(f64, f64)>,
}

fn normal(rng: &mut ChaCha8Rng, std: f64) -> f64 {
    match Normal::new(0.0, std) {
        Ok(n) if std > 0.0 => n.sample(rng),
        _ => 0.0,
    }
}

fn normal3(rng: &mut ChaCha8Rng, std: f64) -> Vector3<f64> {
    Vector3::new(normal(rng, std), normal(rng, std), normal(rng, std))
}

/// The state of one run's source errors (its own generator: the IMU's noise stream is the
/// same whatever the source).
#[derive(Clone, Debug)]
pub struct SourceModel {
    preset: SourcePreset,
    rng: ChaCha8Rng,
    /// Frame offset (drift + the last reset), m.
    offset: Vector3<f64>,
    /// Constant yaw disturbance of the run, rad.
    yaw_bias: f64,
    /// Barometer drift, m.
    baro_drift: f64,
    last_t: Option<f64>,
    next_reset: f64,
    last_baro_t: Option<f64>,
}

/// Barometer rate, Hz.
pub const BARO_RATE_HZ: f64 = 50.0;

impl SourceModel {
    /// The errors of `preset`, seeded with `seed`.
    pub fn new(preset: SourcePreset, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x534f_5552_4345_2139);
        let yaw_bias = preset.yaw.map_or(0.0, |(_, d)| normal(&mut rng, d));
        let next_reset = if preset.reset_interval > 0.0 { preset.reset_interval } else { f64::INFINITY };
        SourceModel {
            preset,
            rng,
            offset: Vector3::zeros(),
            yaw_bias,
            baro_drift: 0.0,
            last_t: None,
            next_reset,
            last_baro_t: None,
        }
    }

    /// Add the source's errors to a fix measured at `t`: drift, frame resets, multipath
    /// outliers (position, NED m) and the measured yaw (rad, from the true `yaw`).
    pub fn corrupt(&mut self, t: f64, position: &mut Vector3<f64>, yaw: &mut f64) {
        let p = self.preset;
        let dt = self.last_t.map_or(0.0, |t0| (t - t0).max(0.0));
        self.last_t = Some(t);
        if p.drift > 0.0 && dt > 0.0 {
            self.offset += normal3(&mut self.rng, p.drift * dt.sqrt());
        }
        if t >= self.next_reset {
            self.offset = normal3(&mut self.rng, p.reset_size);
            self.offset.z *= 0.2;
            self.next_reset += p.reset_interval;
        }
        *position += self.offset;
        if p.multipath_prob > 0.0 && self.rng.random::<f64>() < p.multipath_prob {
            *position += normal3(&mut self.rng, p.multipath_size);
        }
        if let Some((noise, _)) = p.yaw {
            *yaw += self.yaw_bias + normal(&mut self.rng, noise);
        }
    }

    /// A barometer reading at `t` (at [`BARO_RATE_HZ`]): the true NED `down` (m) plus drift
    /// and noise; `None` between readings or without a barometer.
    pub fn baro(&mut self, t: f64, down: f64) -> Option<f64> {
        let (noise, drift) = self.preset.baro?;
        let period = 1.0 / BARO_RATE_HZ;
        if self.last_baro_t.is_some_and(|t0| t < t0 + period - 1e-9) {
            return None;
        }
        let dt = self.last_baro_t.map_or(0.0, |t0| t - t0);
        self.last_baro_t = Some(t);
        self.baro_drift += normal(&mut self.rng, drift * dt.sqrt());
        Some(down + self.baro_drift + normal(&mut self.rng, noise))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vio_drifts_and_resets_and_gps_has_outliers() {
        let mut vio = SourceModel::new(PositionSource::Vio.preset(), 1);
        let (mut yaw, mut before, mut jump) = (0.0, Vector3::zeros(), 0.0f64);
        for k in 0..(70 * 30) {
            let t = k as f64 / 30.0;
            let mut p = Vector3::zeros();
            vio.corrupt(t, &mut p, &mut yaw);
            if k > 0 {
                jump = jump.max((p - before).norm());
            }
            before = p;
        }
        assert!(jump > 0.3, "a reset jumps: {jump}");
        let mut gps = SourceModel::new(PositionSource::Gps.preset(), 2);
        let outliers = (0..10_000)
            .filter(|&k| {
                let mut p = Vector3::zeros();
                gps.corrupt(k as f64 * 0.1, &mut p, &mut yaw);
                p.norm() > 2.0
            })
            .count();
        assert!((50..200).contains(&outliers), "{outliers} multipath outliers in 10^4 fixes");
    }
}
