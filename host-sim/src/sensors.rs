//! Simulated sensors: an IMU (gyroscope + accelerometer) and a position /
//! velocity measurement (motion capture, or a companion computer's estimate)
//! with latency.
//!
//! All outputs are in the frames of [`parapet_core::frame`]: IMU in body FRD
//! (gyro rad/s, accelerometer = specific force m/s², reading (0, 0, −g) when
//! level and still), position/velocity in world NED (m, m/s).
//!
//! Noise is white Gaussian per sample plus a constant bias per run (drawn once
//! from the bias standard deviation), from a seeded ChaCha8 generator, so a run
//! is reproducible from its seed. `noise = false` turns every noise and bias
//! term off (latency stays: it is not noise).

use std::collections::VecDeque;

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::plant::Plant;

/// Sensor noise and latency parameters (standard deviations, SI units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// Master switch: `false` removes every noise and bias term.
    pub noise: bool,
    /// Gyro white noise per sample, rad/s.
    pub gyro_noise: f64,
    /// Gyro constant bias (per axis, drawn once), standard deviation, rad/s.
    pub gyro_bias: f64,
    /// Accelerometer white noise per sample, m/s².
    pub accel_noise: f64,
    /// Accelerometer constant bias (per axis, drawn once), standard deviation, m/s².
    pub accel_bias: f64,
    /// Position measurement noise per sample, m.
    pub position_noise: f64,
    /// Velocity measurement noise per sample, m/s.
    pub velocity_noise: f64,
    /// Latency of the position/velocity measurement, s (0 = none).
    pub position_latency: f64,
    /// Noise on the velocity of moving obstacles as the proximity sensor /
    /// tracker reports it, m/s per axis (default 0: the true velocity).
    pub obstacle_velocity_noise: f64,
}

impl Default for SensorParams {
    /// A small MEMS IMU (MPU-6000 class) and a motion-capture-like position fix:
    /// gyro 0.005 rad/s noise, 0.002 rad/s bias; accel 0.05 m/s² noise, 0.02 m/s² bias;
    /// position 5 mm, velocity 0.02 m/s noise, 10 ms latency; obstacle velocities exact.
    fn default() -> Self {
        SensorParams {
            noise: true,
            gyro_noise: 0.005,
            gyro_bias: 0.002,
            accel_noise: 0.05,
            accel_bias: 0.02,
            position_noise: 0.005,
            velocity_noise: 0.02,
            position_latency: 0.01,
            obstacle_velocity_noise: 0.0,
        }
    }
}

/// One IMU sample, body FRD.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuReading {
    /// Angular rate, rad/s.
    pub gyro: Vector3<f64>,
    /// Specific force, m/s².
    pub accel: Vector3<f64>,
}

/// One position/velocity measurement, world NED.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionReading {
    /// Time the measurement describes (the true state's time, before latency), s.
    pub t_measured: f64,
    /// Position, m.
    pub position: Vector3<f64>,
    /// Velocity, m/s.
    pub velocity: Vector3<f64>,
    /// Heading (yaw, FRD ZYX w.r.t. NED), rad, as motion capture measures it (no noise).
    pub yaw: f64,
}

/// The sensor suite of one run.
#[derive(Clone, Debug)]
pub struct Sensors {
    params: SensorParams,
    rng: ChaCha8Rng,
    gyro_bias: Vector3<f64>,
    accel_bias: Vector3<f64>,
    pending: VecDeque<PositionReading>,
}

fn normal3(rng: &mut ChaCha8Rng, std: f64) -> Vector3<f64> {
    match Normal::new(0.0, std) {
        Ok(n) if std > 0.0 => Vector3::new(n.sample(rng), n.sample(rng), n.sample(rng)),
        _ => Vector3::zeros(),
    }
}

impl Sensors {
    /// A sensor suite seeded with `seed` (same seed → same noise sequence).
    pub fn new(params: SensorParams, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (gyro_bias, accel_bias) = if params.noise {
            (normal3(&mut rng, params.gyro_bias), normal3(&mut rng, params.accel_bias))
        } else {
            (Vector3::zeros(), Vector3::zeros())
        };
        Sensors { params, rng, gyro_bias, accel_bias, pending: VecDeque::new() }
    }

    /// The parameters.
    pub fn params(&self) -> &SensorParams {
        &self.params
    }

    /// Sample the IMU from the plant's current state.
    pub fn imu(&mut self, plant: &Plant) -> ImuReading {
        let mut gyro = plant.state.rates;
        let mut accel = plant.specific_force_body();
        if self.params.noise {
            gyro += self.gyro_bias + normal3(&mut self.rng, self.params.gyro_noise);
            accel += self.accel_bias + normal3(&mut self.rng, self.params.accel_noise);
        }
        ImuReading { gyro, accel }
    }

    /// A moving obstacle's velocity (NED, m/s) as reported: the true one plus
    /// `obstacle_velocity_noise` (when noise is on).
    pub fn obstacle_velocity(&mut self, v: Vector3<f64>) -> Vector3<f64> {
        if self.params.noise {
            v + normal3(&mut self.rng, self.params.obstacle_velocity_noise)
        } else {
            v
        }
    }

    /// Record the plant's true position/velocity at time `t` (s) and return the
    /// newest measurement whose latency has elapsed at `t`, if any. Call at the
    /// measurement rate; with zero latency the measurement of `t` itself is returned.
    pub fn position(&mut self, t: f64, plant: &Plant) -> Option<PositionReading> {
        self.position_with_yaw(t, plant, plant.state.euler().2)
    }

    /// [`position`](Self::position) with the plant's true yaw (rad) given by a
    /// caller that has already computed the Euler angles of this state.
    pub fn position_with_yaw(&mut self, t: f64, plant: &Plant, yaw: f64) -> Option<PositionReading> {
        let mut r =
            PositionReading { t_measured: t, position: plant.state.pos, velocity: plant.state.vel, yaw };
        if self.params.noise {
            r.position += normal3(&mut self.rng, self.params.position_noise);
            r.velocity += normal3(&mut self.rng, self.params.velocity_noise);
        }
        self.pending.push_back(r);
        let mut out = None;
        // Small tolerance so a latency that is a multiple of the call period is exact.
        while let Some(front) = self.pending.front() {
            if front.t_measured + self.params.position_latency <= t + 1e-9 {
                out = self.pending.pop_front();
            } else {
                break;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{VehicleParams, GRAVITY};

    fn hover_plant() -> Plant {
        let mut p = Plant::new(VehicleParams::default()).unwrap();
        p.set_hover(Vector3::new(0.0, 0.0, -1.0), 0.0);
        p
    }

    #[test]
    fn noise_off_gives_truth() {
        let p = hover_plant();
        let mut s =
            Sensors::new(SensorParams { noise: false, position_latency: 0.0, ..Default::default() }, 1);
        let imu = s.imu(&p);
        assert_eq!(imu.gyro, Vector3::zeros());
        assert!((imu.accel - Vector3::new(0.0, 0.0, -GRAVITY)).norm() < 1e-12);
        let r = s.position(0.0, &p).unwrap();
        assert_eq!(r.position, p.state.pos);
    }

    #[test]
    fn noise_is_seeded_and_has_the_stated_size() {
        let p = hover_plant();
        let params = SensorParams { gyro_bias: 0.0, ..Default::default() };
        let mut a = Sensors::new(params.clone(), 7);
        let mut b = Sensors::new(params.clone(), 7);
        let mut c = Sensors::new(params.clone(), 8);
        let (ra, rb, rc) = (a.imu(&p), b.imu(&p), c.imu(&p));
        assert_eq!(ra, rb);
        assert_ne!(ra, rc);
        let n = 20000;
        let var: f64 = (0..n).map(|_| a.imu(&p).gyro.x.powi(2)).sum::<f64>() / n as f64;
        assert!((var.sqrt() - params.gyro_noise).abs() < 0.1 * params.gyro_noise, "std {}", var.sqrt());
    }

    #[test]
    fn obstacle_velocity_noise_only_when_asked() {
        let v = Vector3::new(0.2, 0.0, 0.0);
        let mut exact = Sensors::new(SensorParams::default(), 1);
        assert_eq!(exact.obstacle_velocity(v), v);
        let p = SensorParams { obstacle_velocity_noise: 0.1, ..Default::default() };
        let mut noisy = Sensors::new(p.clone(), 1);
        assert_ne!(noisy.obstacle_velocity(v), v);
        let mut off = Sensors::new(SensorParams { noise: false, ..p }, 1);
        assert_eq!(off.obstacle_velocity(v), v);
    }

    #[test]
    fn position_latency_delays_the_fix() {
        let mut p = hover_plant();
        let mut s =
            Sensors::new(SensorParams { noise: false, position_latency: 0.012, ..Default::default() }, 1);
        let dt = 0.004;
        let mut got = Vec::new();
        for k in 0..10 {
            let t = k as f64 * dt;
            p.state.pos.x = t; // a recognisable truth
            if let Some(r) = s.position(t, &p) {
                got.push((t, r));
            }
        }
        // First fix appears at t = 12 ms and describes t = 0.
        assert!((got[0].0 - 0.012).abs() < 1e-9);
        for (t, r) in &got {
            assert!((t - r.t_measured - 0.012).abs() < 1e-9);
            assert!((r.position.x - r.t_measured).abs() < 1e-12);
        }
    }
}
