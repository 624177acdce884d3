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
//!
//! Faults ([`FaultParams`], the `[faults]` table; [`Sensors::with_faults`]): IMU
//! bias random walk (per 1 kHz IMU sample), position-fix dropout bursts, outliers
//! and latency jitter, and obstacle reports with point noise, latency and missed
//! detections ([`Sensors::obstacle_report`]). They draw from a second generator
//! seeded from the same seed, so a flight's noise stream is the same with and
//! without faults, and nothing is drawn when every fault is off. Faults act
//! whether or not `noise` is on.
//!
//! May import: `crate::sim::plant`, `crate::sim::disturbance::faults`, `parapet-core`'s obstacle type.

use std::collections::VecDeque;

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use parapet_core::obstacle::ObstaclePoint;

pub use crate::sim::disturbance::faults::FaultParams;
use crate::sim::plant::Plant;
pub use crate::sim::source::PositionSource;
use crate::sim::source::SourceModel;

/// Period of the IMU samples the bias random walk assumes, s (1 kHz).
pub const IMU_PERIOD_S: f64 = super::INNER_DT;

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
    /// Where the fix comes from (`crate::sim::source`; default motion capture, as before).
    pub position_source: PositionSource,
    /// Fix rate, Hz (0: one fix per outer step, the motion-capture default).
    pub rate: f64,
    /// Start of a window without any fix, s (with `dropout_length` > 0).
    pub dropout_start: f64,
    /// Length of that window, s (0: none).
    pub dropout_length: f64,
    /// World assumptions that let a range-sensor set with a coverage gap fly
    /// (`crate::sim::coverage::Assumption`; `--assume` adds to them). None by default.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub assume: Vec<crate::sim::coverage::Assumption>,
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
            position_source: PositionSource::Mocap,
            rate: 0.0,
            dropout_start: 0.0,
            dropout_length: 0.0,
            assume: Vec::new(),
        }
    }
}

impl SensorParams {
    /// Apply the `position_source` preset to every source value not in `explicit` (the keys
    /// the scene's `[sensors]` table sets): `position_noise`, `velocity_noise`,
    /// `position_latency`, `rate`. Motion capture's preset is the defaults: nothing changes.
    pub fn apply_source_preset(&mut self, explicit: &[&str]) {
        let p = self.position_source.preset();
        let keep = |k: &str| explicit.contains(&k);
        if !keep("position_noise") {
            self.position_noise = p.position_noise;
        }
        if !keep("velocity_noise") {
            self.velocity_noise = p.velocity_noise;
        }
        if !keep("position_latency") {
            self.position_latency = p.position_latency;
        }
        if !keep("rate") {
            self.rate = p.rate_hz;
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
    /// Fixes measured, with the time each is delivered.
    pending: VecDeque<(f64, PositionReading)>,
    faults: FaultParams,
    fault_rng: ChaCha8Rng,
    /// No fix is measured before this time (dropout burst), s.
    dropout_until: f64,
    /// Time of the previous position call, s.
    last_fix_call: Option<f64>,
    /// Delivery time of the newest pending fix, s (fixes stay in order under jitter).
    last_delivery: f64,
    /// Obstacle reports measured, with their time.
    reports: VecDeque<(f64, Vec<ObstaclePoint>)>,
    /// The source's errors (`None` for motion capture: nothing drawn).
    source: Option<SourceModel>,
    /// No fix is measured before this time (the fix rate), s.
    next_fix_t: f64,
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
        Sensors {
            rng,
            gyro_bias,
            accel_bias,
            pending: VecDeque::new(),
            faults: FaultParams::default(),
            fault_rng: ChaCha8Rng::seed_from_u64(seed ^ 0x4641_554c_5453_2121),
            dropout_until: f64::NEG_INFINITY,
            last_fix_call: None,
            last_delivery: f64::NEG_INFINITY,
            reports: VecDeque::new(),
            source: (!params.position_source.is_mocap())
                .then(|| SourceModel::new(params.position_source.preset(), seed)),
            next_fix_t: f64::NEG_INFINITY,
            params,
        }
    }

    /// A barometer reading (NED down, m) at `t`, if the source has a barometer and one is due.
    pub fn baro(&mut self, t: f64, plant: &Plant) -> Option<f64> {
        self.source.as_mut()?.baro(t, plant.state.pos.z)
    }

    /// `false` when no fix is measured at `t`: between fixes of the `rate`, or in the
    /// `dropout_start`/`dropout_length` window.
    fn fix_due(&mut self, t: f64) -> bool {
        let p = &self.params;
        if p.dropout_length > 0.0 && t >= p.dropout_start && t < p.dropout_start + p.dropout_length {
            return false;
        }
        if p.rate > 0.0 {
            if t < self.next_fix_t - 1e-9 {
                return false;
            }
            let period = 1.0 / p.rate;
            self.next_fix_t =
                if self.next_fix_t + period > t { self.next_fix_t + period } else { t + period };
        }
        true
    }

    /// [`new`](Self::new) with faults (the same noise stream as without them).
    pub fn with_faults(params: SensorParams, faults: FaultParams, seed: u64) -> Self {
        let mut s = Sensors::new(params, seed);
        s.faults = faults;
        s
    }

    /// The faults.
    pub fn faults(&self) -> &FaultParams {
        &self.faults
    }

    /// The current IMU biases (gyro rad/s, accelerometer m/s²), body FRD.
    pub fn biases(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.gyro_bias, self.accel_bias)
    }

    /// The parameters.
    pub fn params(&self) -> &SensorParams {
        &self.params
    }

    /// Sample the IMU from the plant's current state.
    pub fn imu(&mut self, plant: &Plant) -> ImuReading {
        let mut gyro = plant.state.rates;
        let mut accel = plant.specific_force_body();
        let f = &self.faults;
        if f.gyro_bias_walk > 0.0 || f.accel_bias_walk > 0.0 {
            let sq = IMU_PERIOD_S.sqrt();
            let (g, a) = (f.gyro_bias_walk * sq, f.accel_bias_walk * sq);
            self.gyro_bias += normal3(&mut self.fault_rng, g);
            self.accel_bias += normal3(&mut self.fault_rng, a);
            if !self.params.noise {
                // The walk acts without the noise too (it starts at zero then).
                gyro += self.gyro_bias;
                accel += self.accel_bias;
            }
        }
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
        if self.fix_due(t) {
            self.measure_fix(t, plant, yaw);
        }
        let mut out = None;
        // Small tolerance so a latency that is a multiple of the call period is exact.
        while let Some(front) = self.pending.front() {
            if front.0 <= t + 1e-9 {
                out = self.pending.pop_front().map(|p| p.1);
            } else {
                break;
            }
        }
        out
    }

    /// Measure the fix of `t` and queue it for its delivery time.
    fn measure_fix(&mut self, t: f64, plant: &Plant, yaw: f64) {
        let mut r =
            PositionReading { t_measured: t, position: plant.state.pos, velocity: plant.state.vel, yaw };
        if self.params.noise {
            r.position += normal3(&mut self.rng, self.params.position_noise);
            r.velocity += normal3(&mut self.rng, self.params.velocity_noise);
        }
        if let Some(s) = self.source.as_mut().filter(|_| self.params.noise) {
            s.corrupt(t, &mut r.position, &mut r.yaw);
        }
        let mut delivery = t + self.params.position_latency;
        let measured =
            if self.faults.fix_faults() { self.fix_faults(t, &mut r, &mut delivery) } else { true };
        if measured {
            self.pending.push_back((delivery, r));
        }
    }

    /// Dropout bursts, outliers and latency jitter of the fix measured at `t`;
    /// `false` when no fix is measured (in a dropout).
    fn fix_faults(&mut self, t: f64, r: &mut PositionReading, delivery: &mut f64) -> bool {
        let f = &self.faults;
        let period = self.last_fix_call.map_or(0.0, |t0| (t - t0).max(0.0));
        self.last_fix_call = Some(t);
        if f.fix_dropout_rate > 0.0 {
            let p = 1.0 - (-f.fix_dropout_rate * period).exp();
            if t >= self.dropout_until && self.fault_rng.random::<f64>() < p {
                self.dropout_until = t + f.fix_dropout_length;
            }
            if t < self.dropout_until {
                return false;
            }
        }
        if f.fix_outlier_prob > 0.0 && self.fault_rng.random::<f64>() < f.fix_outlier_prob {
            r.position += normal3(&mut self.fault_rng, f.fix_outlier_size);
        }
        if f.fix_latency_jitter > 0.0 {
            *delivery += f.fix_latency_jitter * self.fault_rng.random::<f64>();
            *delivery = delivery.max(self.last_delivery);
            self.last_delivery = *delivery;
        }
        true
    }

    /// Apply the report faults to the obstacle report `seen` measured at `t` (s):
    /// missed detections, point noise, then latency (the report delivered is the
    /// newest measured at least `obstacle_latency` ago; empty before the first).
    /// Without report faults `seen` is left as it is.
    pub fn obstacle_report(&mut self, t: f64, seen: &mut Vec<ObstaclePoint>) {
        let f = &self.faults;
        if !f.report_faults() {
            return;
        }
        if f.obstacle_miss_prob > 0.0 {
            let (p, rng) = (f.obstacle_miss_prob, &mut self.fault_rng);
            seen.retain(|_| rng.random::<f64>() >= p);
        }
        if f.obstacle_position_noise > 0.0 {
            for o in seen.iter_mut() {
                let n = normal3(&mut self.fault_rng, f.obstacle_position_noise);
                o.point += parapet_core::Vec3::new(n.x as f32, n.y as f32, n.z as f32);
            }
        }
        if f.obstacle_latency > 0.0 {
            self.reports.push_back((t, seen.clone()));
            seen.clear();
            while let Some((t0, _)) = self.reports.front() {
                if t0 + f.obstacle_latency <= t + 1e-9 {
                    if let Some((_, r)) = self.reports.pop_front() {
                        *seen = r;
                    }
                } else {
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::plant::{VehicleParams, GRAVITY};

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

    fn fault_sensors(faults: FaultParams) -> Sensors {
        Sensors::with_faults(
            SensorParams { noise: false, position_latency: 0.0, ..Default::default() },
            faults,
            9,
        )
    }

    #[test]
    fn faults_off_change_nothing_and_leave_the_noise_stream() {
        let p = hover_plant();
        let mut a = Sensors::new(SensorParams::default(), 4);
        let faults = FaultParams { obstacle_position_noise: 0.1, gyro_bias_walk: 0.0, ..Default::default() };
        let mut b = Sensors::with_faults(SensorParams::default(), faults, 4);
        for k in 0..100 {
            assert_eq!(a.imu(&p), b.imu(&p));
            assert_eq!(a.position(k as f64 * 0.004, &p), b.position(k as f64 * 0.004, &p));
        }
        let mut none = Sensors::new(SensorParams::default(), 4);
        let mut seen = vec![ObstaclePoint::fixed(parapet_core::Vec3::new(1.0, 0.0, 0.0), 0)];
        let before = seen.clone();
        none.obstacle_report(0.0, &mut seen);
        assert_eq!(seen, before);
    }

    #[test]
    fn bias_random_walk_grows_as_the_square_root_of_time() {
        let p = hover_plant();
        let walk = 0.01;
        let (n, t) = (200, 4.0);
        let mut sq = 0.0;
        for seed in 0..n {
            let mut s = Sensors::with_faults(
                SensorParams { noise: false, ..Default::default() },
                FaultParams { gyro_bias_walk: walk, ..Default::default() },
                seed,
            );
            let mut last = Vector3::zeros();
            for _ in 0..(t / IMU_PERIOD_S) as usize {
                last = s.imu(&p).gyro;
            }
            sq += last.x * last.x;
        }
        // E[b²] = walk² t: std 0.02 rad/s after 4 s.
        let sd = (sq / n as f64).sqrt();
        assert!((sd - walk * t.sqrt()).abs() < 0.15 * walk * t.sqrt(), "{sd}");
    }

    #[test]
    fn fix_dropouts_come_in_bursts_of_the_given_length_and_rate() {
        let p = hover_plant();
        let mut s = fault_sensors(FaultParams {
            fix_dropout_rate: 0.5,
            fix_dropout_length: 0.2,
            ..Default::default()
        });
        let dt = 0.004;
        let n = 250 * 400; // 400 s
        let (mut missing, mut bursts, mut prev_missing) = (0, 0, false);
        for k in 0..n {
            let m = s.position(k as f64 * dt, &p).is_none();
            missing += usize::from(m);
            bursts += usize::from(m && !prev_missing);
            prev_missing = m;
        }
        // ~0.5 bursts/s of 0.2 s (a burst cannot start inside one): ~182 bursts, 9 % missing.
        let rate = bursts as f64 / 400.0;
        let frac = missing as f64 / n as f64;
        assert!((rate - 0.5 / 1.1).abs() < 0.1, "rate {rate}");
        assert!((frac - 0.1 / 1.1).abs() < 0.03, "fraction {frac}");
        assert!(((missing as f64 / bursts as f64) * dt - 0.2).abs() < 0.01, "mean length");
    }

    #[test]
    fn outliers_jitter_and_report_faults() {
        let mut p = hover_plant();
        let mut s = fault_sensors(FaultParams {
            fix_outlier_prob: 0.1,
            fix_outlier_size: 1.0,
            fix_latency_jitter: 0.02,
            ..Default::default()
        });
        let (mut outliers, mut n, mut last_t) = (0, 0, f64::NEG_INFINITY);
        for k in 0..5000 {
            let t = k as f64 * 0.004;
            p.state.pos.x = t;
            if let Some(r) = s.position(t, &p) {
                n += 1;
                let lag = t - r.t_measured;
                assert!((-1e-9..=0.02 + 0.004 + 1e-9).contains(&lag), "lag {lag}");
                assert!(r.t_measured > last_t, "in order");
                last_t = r.t_measured;
                outliers += usize::from((r.position - Vector3::new(r.t_measured, 0.0, -1.0)).norm() > 1e-9);
            }
        }
        let frac = outliers as f64 / n as f64;
        assert!((frac - 0.1).abs() < 0.02, "outliers {frac}");
        // Reports: misses, noise, latency.
        let mut s = fault_sensors(FaultParams {
            obstacle_miss_prob: 0.25,
            obstacle_position_noise: 0.05,
            obstacle_latency: 0.012,
            ..Default::default()
        });
        let (mut kept, mut total, mut err2) = (0, 0, 0.0);
        for k in 0..4000 {
            let t = k as f64 * 0.004;
            let pt = parapet_core::Vec3::new(t as f32, 0.0, 0.0);
            let mut seen = vec![ObstaclePoint::fixed(pt, 0); 4];
            s.obstacle_report(t, &mut seen);
            if k < 3 {
                assert!(seen.is_empty(), "nothing before the latency");
                continue;
            }
            total += 4;
            kept += seen.len();
            for o in &seen {
                // Measured 12 ms (3 outer steps) ago.
                let e = o.point - parapet_core::Vec3::new((t - 0.012) as f32, 0.0, 0.0);
                err2 += (e.y * e.y) as f64;
            }
        }
        assert!((kept as f64 / total as f64 - 0.75).abs() < 0.02);
        assert!(((err2 / kept as f64).sqrt() - 0.05).abs() < 0.005);
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
