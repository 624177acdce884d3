//! Simulated battery: a LiPo pack whose charge drains with the current the motors draw and
//! whose terminal voltage sags with that current, read by a voltage/current sensor — the
//! simulator's side of `parapet_core::battery` (the estimator takes these readings exactly as
//! it takes the F405's ADC readings).
//!
//! ## Model
//! * Current: `I = I_avionics + Σ_i I_motor_max · c_i³` for the motor commands `c_i ∈ [0, 1]`
//!   (throttle ∝ rotor speed, `core/src/airframe.rs`; rotor power ∝ ω³ at a fixed pitch, so
//!   at a constant pack voltage the current goes with the cube of the command).
//! * Charge: `soc ← soc − I·dt / capacity` (coulomb counting, clamped to [0, 1]).
//! * Voltage: `V = cells · OCV(soc) − I · R_internal`, OCV the resting LiPo cell curve
//!   (3.27 V empty … 4.20 V full; the points a LiPo discharge table gives).
//! * Sensor: Gaussian noise on voltage and current (seeded ChaCha8, reproducible), read at
//!   [`BatteryModelParams::rate_hz`].
//!
//! Not modelled: the pack voltage's effect on the motors' top speed (the plant's rotor limit
//! stays fixed), temperature, recovery dynamics (the sag is instantaneous).
//!
//! Owns [`BatteryModel`], [`BatteryModelParams`], [`BatteryReading`]. May import `parapet-core`
//! and [`crate::input`] only.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::input::InputError;

/// Battery model parameters (the scene's `[battery]` table).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BatteryModelParams {
    /// Cells in series, 1..=14. Default 3.
    pub cells: u8,
    /// Capacity, mAh, > 0. Default 1300.
    pub capacity_mah: f64,
    /// Charge at the start, fraction in [0, 1]. Default 1.
    pub initial_soc: f64,
    /// Pack internal resistance, Ω, ≥ 0. Default 0.03.
    pub r_internal_ohm: f64,
    /// Current of one motor at full command, A, ≥ 0. Default 10.
    pub motor_max_a: f64,
    /// Current of the electronics, A, ≥ 0. Default 0.3.
    pub avionics_a: f64,
    /// Voltage sensor noise (standard deviation), V, ≥ 0. Default 0.02.
    pub voltage_noise: f64,
    /// Current sensor noise (standard deviation), A, ≥ 0. Default 0.1.
    pub current_noise: f64,
    /// The board measures the current at all. Default true.
    pub current_sensor: bool,
    /// Sensor rate, Hz, in (0, 1000]. Default 10.
    pub rate_hz: f64,
}

impl Default for BatteryModelParams {
    fn default() -> Self {
        Self {
            cells: 3,
            capacity_mah: 1300.0,
            initial_soc: 1.0,
            r_internal_ohm: 0.03,
            motor_max_a: 10.0,
            avionics_a: 0.3,
            voltage_noise: 0.02,
            current_noise: 0.1,
            current_sensor: true,
            rate_hz: 10.0,
        }
    }
}

impl BatteryModelParams {
    /// The controller's battery estimator parameters `d` told this pack's cells and internal
    /// resistance (BAT_CELLS, BAT_R_INT), as on a configured vehicle: a run starts armed, so
    /// there is no disarmed power-up to detect the cell count from.
    pub fn estimator_params(
        &self,
        d: parapet_core::battery::BatteryParams,
    ) -> parapet_core::battery::BatteryParams {
        parapet_core::battery::BatteryParams {
            cells: self.cells,
            r_internal_ohm: self.r_internal_ohm as f32,
            ..d
        }
    }

    /// Every field in its range; the error names `origin` (the scene file or option), the
    /// `[battery]` table, the field, value and range.
    pub fn validate(&self, origin: &str) -> Result<(), InputError> {
        let bad = |field: &str, value: f64, range: &str| {
            Err(InputError::file(origin, "out of range")
                .table("battery")
                .field(field)
                .value(value)
                .allowed(range))
        };
        let nonneg = |x: f64| x.is_finite() && x >= 0.0;
        if !(1..=14).contains(&self.cells) {
            return bad("cells", f64::from(self.cells), "in 1..=14");
        }
        if !(self.capacity_mah.is_finite() && self.capacity_mah > 0.0) {
            return bad("capacity_mah", self.capacity_mah, "> 0");
        }
        if !(0.0..=1.0).contains(&self.initial_soc) {
            return bad("initial_soc", self.initial_soc, "in [0, 1]");
        }
        for (f, v) in [
            ("r_internal_ohm", self.r_internal_ohm),
            ("motor_max_a", self.motor_max_a),
            ("avionics_a", self.avionics_a),
            ("voltage_noise", self.voltage_noise),
            ("current_noise", self.current_noise),
        ] {
            if !nonneg(v) {
                return bad(f, v, "finite and >= 0");
            }
        }
        if !(self.rate_hz > 0.0 && self.rate_hz <= 1000.0) {
            return bad("rate_hz", self.rate_hz, "in (0, 1000]");
        }
        Ok(())
    }
}

/// One sensor reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatteryReading {
    /// Simulation time, s.
    pub t: f64,
    /// Measured pack voltage, V.
    pub voltage_v: f32,
    /// Measured current, A (`None` without a current sensor).
    pub current_a: Option<f32>,
}

/// Resting LiPo cell voltage at charge `soc` (the same discharge table the estimator uses,
/// read the other way).
const OCV: [(f64, f64); 21] = [
    (0.00, 3.27),
    (0.05, 3.61),
    (0.10, 3.69),
    (0.15, 3.71),
    (0.20, 3.73),
    (0.25, 3.75),
    (0.30, 3.77),
    (0.35, 3.79),
    (0.40, 3.80),
    (0.45, 3.82),
    (0.50, 3.84),
    (0.55, 3.85),
    (0.60, 3.87),
    (0.65, 3.91),
    (0.70, 3.95),
    (0.75, 3.98),
    (0.80, 4.02),
    (0.85, 4.08),
    (0.90, 4.11),
    (0.95, 4.15),
    (1.00, 4.20),
];

/// Resting cell voltage at `soc` (clamped to the table).
pub fn cell_ocv(soc: f64) -> f64 {
    let s = soc.clamp(0.0, 1.0);
    for w in OCV.windows(2) {
        let ((s0, v0), (s1, v1)) = (w[0], w[1]);
        if s <= s1 {
            return v0 + (v1 - v0) * (s - s0) / (s1 - s0);
        }
    }
    OCV[OCV.len() - 1].1
}

/// The pack and its sensor (see the module docs).
#[derive(Clone, Debug)]
pub struct BatteryModel {
    p: BatteryModelParams,
    soc: f64,
    current_a: f64,
    t: f64,
    next_read: f64,
    rng: ChaCha8Rng,
    v_noise: Normal<f64>,
    i_noise: Normal<f64>,
}

impl BatteryModel {
    /// A charged pack (`initial_soc`); `seed` drives the sensor noise. `origin` names the
    /// input the parameters came from (for the error).
    pub fn new(p: BatteryModelParams, seed: u64, origin: &str) -> Result<Self, InputError> {
        p.validate(origin)?;
        let normal = |sd: f64| {
            Normal::new(0.0, sd).map_err(|e| InputError::file(origin, e.to_string()).table("battery"))
        };
        Ok(Self {
            soc: p.initial_soc,
            current_a: p.avionics_a,
            t: 0.0,
            next_read: 0.0,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0xBA77_E125),
            v_noise: normal(p.voltage_noise)?,
            i_noise: normal(p.current_noise)?,
            p,
        })
    }

    /// Charge left, fraction.
    pub fn soc(&self) -> f64 {
        self.soc
    }

    /// True current, A.
    pub fn current(&self) -> f64 {
        self.current_a
    }

    /// True terminal voltage, V.
    pub fn voltage(&self) -> f64 {
        f64::from(self.p.cells) * cell_ocv(self.soc) - self.current_a * self.p.r_internal_ohm
    }

    /// Advance by `dt` s with the motor commands `throttles` (non-finite commands count as 0);
    /// returns a reading when the sensor is due.
    pub fn step(&mut self, dt: f64, throttles: &[f32; 4]) -> Option<BatteryReading> {
        let motors: f64 = throttles
            .iter()
            .map(|&c| if c.is_finite() { f64::from(c).clamp(0.0, 1.0).powi(3) } else { 0.0 })
            .sum();
        self.current_a = self.p.avionics_a + self.p.motor_max_a * motors;
        self.soc = (self.soc - self.current_a * dt / (self.p.capacity_mah * 3.6)).clamp(0.0, 1.0);
        self.t += dt;
        if self.t + 1e-9 < self.next_read {
            return None;
        }
        self.next_read += 1.0 / self.p.rate_hz;
        let v = self.voltage() + self.v_noise.sample(&mut self.rng);
        let i = self.current_a + self.i_noise.sample(&mut self.rng);
        Some(BatteryReading {
            t: self.t,
            voltage_v: v.max(0.0) as f32,
            current_a: self.p.current_sensor.then_some(i as f32),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::battery::{BatteryEstimator, BatteryLevel, BatteryParams};

    #[test]
    fn ocv_curve_is_monotone() {
        assert_eq!(cell_ocv(1.0), 4.2);
        assert_eq!(cell_ocv(-1.0), 3.27);
        let mut last = 0.0;
        for k in 0..=100 {
            let v = cell_ocv(k as f64 / 100.0);
            assert!(v >= last);
            last = v;
        }
    }

    #[test]
    fn voltage_sags_with_the_motor_current_and_charge_drains() {
        let p = BatteryModelParams { voltage_noise: 0.0, current_noise: 0.0, ..Default::default() };
        let mut b = BatteryModel::new(p.clone(), 1, "test").unwrap();
        b.step(0.001, &[0.0; 4]);
        let rest = b.voltage();
        assert!((rest - (3.0 * 4.2 - 0.3 * 0.03)).abs() < 1e-3, "{rest}");
        b.step(0.001, &[1.0; 4]);
        // 40.3 A × 0.03 Ω = 1.21 V of sag.
        assert!((rest - b.voltage() - 40.0 * 0.03).abs() < 0.01);
        // 1300 mAh at 40.3 A lasts 116 s.
        let mut t = 0.0f64;
        while b.soc() > 0.0 && t < 200.0 {
            b.step(0.01, &[1.0; 4]);
            t += 0.01;
        }
        assert!((t - 1.3 * 3600.0 / 40.3).abs() < 1.0, "{t}");
    }

    #[test]
    fn readings_come_at_the_rate_and_are_reproducible() {
        let run = |seed| {
            let mut b = BatteryModel::new(BatteryModelParams::default(), seed, "test").unwrap();
            (0..999).filter_map(|_| b.step(0.001, &[0.5; 4])).collect::<Vec<_>>()
        };
        let a = run(7);
        assert_eq!(a.len(), 10);
        assert_eq!(a, run(7));
        assert_ne!(a, run(8));
        let mut b =
            BatteryModel::new(BatteryModelParams { current_sensor: false, ..Default::default() }, 1, "test")
                .unwrap();
        assert_eq!(b.step(0.001, &[0.5; 4]).unwrap().current_a, None);
    }

    #[test]
    fn bad_parameters_name_the_field() {
        for (p, field) in [
            (BatteryModelParams { cells: 0, ..Default::default() }, "`cells`"),
            (BatteryModelParams { capacity_mah: 0.0, ..Default::default() }, "`capacity_mah`"),
            (BatteryModelParams { initial_soc: 1.5, ..Default::default() }, "`initial_soc`"),
            (BatteryModelParams { r_internal_ohm: f64::NAN, ..Default::default() }, "`r_internal_ohm`"),
            (BatteryModelParams { rate_hz: 0.0, ..Default::default() }, "`rate_hz`"),
        ] {
            let e = BatteryModel::new(p, 0, "scene.toml").unwrap_err().to_string();
            assert!(e.starts_with("scene.toml: [battery] field `") && e.contains(field), "{e}");
        }
    }

    /// The model feeding the core estimator, as in a flight: a hover draining the pack
    /// reaches Low and then Critical, in that order, and the estimate's remaining charge
    /// follows the true one.
    #[test]
    fn the_estimator_sees_low_then_critical_on_a_draining_pack() {
        let p = BatteryModelParams { capacity_mah: 300.0, ..Default::default() };
        let mut b = BatteryModel::new(p, 3, "test").unwrap();
        let mut e = BatteryEstimator::new(BatteryParams { r_internal_ohm: 0.03, ..Default::default() });
        let (mut low_at, mut crit_at) = (None, None);
        let mut t_us = 0u64;
        let mut checked = false;
        for _ in 0..400_000 {
            t_us += 1000;
            // Powered up disarmed (the cell count is detected then), armed after 1 s.
            let armed = t_us > 1_000_000;
            let throttle = if armed { 0.6 } else { 0.0 };
            if let Some(r) = b.step(0.001, &[throttle; 4]) {
                let s = e.update(t_us, r.voltage_v, r.current_a, armed).state();
                if s.level == BatteryLevel::Low && low_at.is_none() {
                    low_at = Some((t_us, b.soc()));
                }
                if s.level == BatteryLevel::Critical && crit_at.is_none() {
                    crit_at = Some((t_us, b.soc()));
                }
                if t_us >= 60_000_000 && !checked {
                    checked = true;
                    let est = f64::from(s.remaining.unwrap());
                    assert!((est - b.soc()).abs() < 0.1, "estimate {est} vs {}", b.soc());
                }
            }
        }
        assert!(checked);
        let (tl, soc_low) = low_at.expect("low reached");
        let (tc, soc_crit) = crit_at.expect("critical reached");
        assert!(tl < tc);
        assert_eq!(e.cells(), 3);
        // Low at 3.5 V/cell resting, between 5 % and 2 % on this curve; critical near empty.
        assert!(soc_low > 0.01 && soc_low < 0.06, "{soc_low}");
        assert!(soc_crit < soc_low, "{soc_crit}");
    }
}
