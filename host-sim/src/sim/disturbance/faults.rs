//! Sensor, report and actuator faults of a flight (the `[faults]` table):
//! IMU bias random walk, position-fix dropouts (bursts), outliers and latency
//! jitter, obstacle reports with position noise, latency and missed detections,
//! and a rotor fault (one rotor's thrust scaled from a time on).
//!
//! The parameters only; [`crate::sim::sensors::Sensors`] applies the sensor and report
//! faults (with its own fault generator, so the noise stream of a flight does not
//! change when faults are added), [`super::Live`] the rotor fault. All zero by
//! default: no fault, nothing drawn.
//!
//! May import: the external crates only.

use serde::{Deserialize, Serialize};

/// One rotor's thrust scaled down from a time on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotorFault {
    /// Rotor number, 1..=4 (PX4 order: 1 front-right, 2 rear-left, 3 front-left, 4 rear-right).
    pub rotor: u8,
    /// Thrust factor from `time` on, 0 (no thrust) ..= 1 (healthy).
    pub factor: f64,
    /// Time the fault starts, s.
    pub time: f64,
}

/// The `[faults]` table. Rates are per second, probabilities per sample.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FaultParams {
    /// Gyro bias random walk, rad/s/√s (the bias starts at the drawn constant bias).
    pub gyro_bias_walk: f64,
    /// Accelerometer bias random walk, m/s²/√s.
    pub accel_bias_walk: f64,
    /// Position-fix dropout bursts per second (Poisson starts).
    pub fix_dropout_rate: f64,
    /// Length of each dropout burst, s (no fix is measured during it).
    pub fix_dropout_length: f64,
    /// Probability that a fix is an outlier.
    pub fix_outlier_prob: f64,
    /// Standard deviation of an outlier's position error per axis, m.
    pub fix_outlier_size: f64,
    /// Extra latency of each fix, uniform in [0, this], s (fixes stay in order).
    pub fix_latency_jitter: f64,
    /// Noise on each reported obstacle point per axis, m.
    pub obstacle_position_noise: f64,
    /// Latency of the obstacle report, s (the controller gets the report measured this long ago).
    pub obstacle_latency: f64,
    /// Probability that an obstacle is missing from a report (missed detection).
    pub obstacle_miss_prob: f64,
    /// A rotor fault.
    pub rotor_fault: Option<RotorFault>,
}

/// Largest accepted rate or size of the fault table.
pub const MAX_FAULT_VALUE: f64 = 100.0;
/// Largest accepted latency of the fault table, s.
pub const MAX_FAULT_LATENCY_S: f64 = 0.1;

impl FaultParams {
    /// Whether any sensor-side fault is on.
    pub fn sensor_faults(&self) -> bool {
        self.gyro_bias_walk > 0.0 || self.accel_bias_walk > 0.0 || self.fix_faults() || self.report_faults()
    }

    /// Whether any position-fix fault is on.
    pub fn fix_faults(&self) -> bool {
        self.fix_dropout_rate > 0.0 || self.fix_outlier_prob > 0.0 || self.fix_latency_jitter > 0.0
    }

    /// Whether any obstacle-report fault is on.
    pub fn report_faults(&self) -> bool {
        self.obstacle_position_noise > 0.0 || self.obstacle_latency > 0.0 || self.obstacle_miss_prob > 0.0
    }

    /// Check every value; `Err((field, value, allowed))`.
    pub fn validate(&self) -> Result<(), (String, String, String)> {
        let check = |field: &str, x: f64, hi: f64| {
            if x.is_finite() && (0.0..=hi).contains(&x) {
                Ok(())
            } else {
                Err((field.to_string(), format!("{x}"), format!("0 ≤ x ≤ {hi}")))
            }
        };
        check("gyro_bias_walk", self.gyro_bias_walk, MAX_FAULT_VALUE)?;
        check("accel_bias_walk", self.accel_bias_walk, MAX_FAULT_VALUE)?;
        check("fix_dropout_rate", self.fix_dropout_rate, MAX_FAULT_VALUE)?;
        check("fix_dropout_length", self.fix_dropout_length, 60.0)?;
        check("fix_outlier_prob", self.fix_outlier_prob, 1.0)?;
        check("fix_outlier_size", self.fix_outlier_size, MAX_FAULT_VALUE)?;
        check("fix_latency_jitter", self.fix_latency_jitter, MAX_FAULT_LATENCY_S)?;
        check("obstacle_position_noise", self.obstacle_position_noise, MAX_FAULT_VALUE)?;
        check("obstacle_latency", self.obstacle_latency, MAX_FAULT_LATENCY_S)?;
        check("obstacle_miss_prob", self.obstacle_miss_prob, 1.0)?;
        if let Some(r) = &self.rotor_fault {
            if !(1..=4).contains(&r.rotor) {
                return Err(("rotor_fault.rotor".into(), r.rotor.to_string(), "1, 2, 3 or 4".into()));
            }
            check("rotor_fault.factor", r.factor, 1.0)?;
            check("rotor_fault.time", r.time, 86_400.0)?;
        }
        Ok(())
    }
}
