//! Battery state: the message between the battery measurement (ADC on the board, the
//! simulator's battery model in host-sim/PIL) and the supervisor's low-battery failsafes,
//! and the estimator that turns raw pack voltage / current samples into it.
//!
//! Owns [`BatteryState`], [`BatteryLevel`], [`BatteryParams`], [`BatteryEstimator`], the ADC
//! conversion ([`AdcReading`], [`vdda_volts`], [`BatteryParams::convert`]) and the
//! LiPo charge curve [`remaining_of_cell_voltage`].
//!
//! ## The estimator ([`BatteryEstimator::update`], bounded: one table walk of 21 points)
//! 1. **Bad samples**: a voltage that is not finite or outside `[0, 100]` V, or a current
//!    that is not finite or outside `[-500, 500]` A, is refused ([`BatterySample::Rejected`]),
//!    counted ([`BatteryEstimator::rejected`]) and changes nothing; the state keeps the time of
//!    the last *accepted* sample (`t_us`), so a consumer sees a stale measurement by its age
//!    (the supervisor's rule; the estimator never invents a level from missing data).
//! 2. **Filter**: first-order low-pass on the voltage (and current), time constant
//!    [`BatteryParams::filter_tau_s`]; the first sample initialises it.
//! 3. **Sag compensation**: when the current is measured, the resting voltage is estimated as
//!    `v + i·R` with the pack's internal resistance [`BatteryParams::r_internal_ohm`].
//! 4. **Cells**: [`BatteryParams::cells`], or when 0 detected once from the first filtered
//!    voltage while disarmed as `ceil(v / 4.35 V)` (a charged or storage-charged LiPo is
//!    always detected right; a 4S below 3.26 V/cell would be taken for 3S — set the
//!    parameter for such packs).
//! 5. **Levels with hysteresis**: the level goes down (Ok → Low → Critical) when the
//!    compensated per-cell voltage stays below the threshold for [`BatteryParams::debounce_s`]
//!    (a short sag under a punch does not trigger it); it never goes back up while armed, and
//!    while disarmed only when the voltage is [`BatteryParams::hysteresis_v`] per cell above
//!    the threshold (a fresh pack plugged in).
//! 6. **Remaining**: the compensated per-cell voltage on a resting LiPo discharge curve.
//!
//! No battery configured ([`BatteryParams::enabled`] false): every sample gives level Ok and
//! no remaining charge.
//!
//! May import: the crate root foundation only (`fmath`).

use crate::fmath;
use crate::param_decl::{field, flag, on_off, u8_field, Has, Param};

/// How the supervisor must treat the battery.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BatteryLevel {
    /// Above the low threshold (or no battery measurement configured).
    #[default]
    Ok,
    /// Below the low threshold: return.
    Low,
    /// Below the critical threshold: land now.
    Critical,
}

/// One battery measurement. A `Copy` message (see [`crate::msg`]).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct BatteryState {
    /// Time of the measurement, µs, controller clock.
    pub t_us: u64,
    /// Pack voltage under load, V.
    pub voltage_v: f32,
    /// Current drawn, A, when the board measures it.
    pub current_a: Option<f32>,
    /// Estimated remaining charge, fraction in [0, 1], when known.
    pub remaining: Option<f32>,
    /// The level the thresholds give (with hysteresis: a level never goes back up in flight).
    pub level: BatteryLevel,
}

/// Battery estimator parameters (the `BAT_*` parameters of [`crate::params`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatteryParams {
    /// A battery is measured at all. Default true.
    pub enabled: bool,
    /// Cells in series; 0 = detect from the first voltage. Default 0.
    pub cells: u8,
    /// Low-battery threshold, V per cell (resting, sag-compensated). Default 3.5.
    pub low_cell_v: f32,
    /// Critical-battery threshold, V per cell. Default 3.3.
    pub critical_cell_v: f32,
    /// Rise above a threshold, V per cell, before a level may go back up (disarmed only). Default 0.1.
    pub hysteresis_v: f32,
    /// Time below a threshold before the level drops, s. Default 2.
    pub debounce_s: f32,
    /// Low-pass time constant of voltage and current, s. Default 0.5.
    pub filter_tau_s: f32,
    /// Pack internal resistance for the sag compensation, Ω (used when the current is measured). Default 0.02.
    pub r_internal_ohm: f32,
    /// Voltage divider of the board's VBAT input: pack volts per ADC-pin volt. Default 11
    /// (MATEKF405: 10 kΩ / 1 kΩ, Betaflight `vbat_scale` 110).
    pub v_divider: f32,
    /// Current sensor scale, A per ADC-pin volt; 0 = no current sensor. Default 0 (the
    /// MATEKF405's current pad needs an external sensor: Matek's PDBs read 55.9 A/V,
    /// Betaflight `ibata_scale` 179).
    pub amps_per_volt: f32,
}

impl BatteryParams {
    /// Pack voltage of an ADC-pin voltage.
    pub fn pack_volts(&self, pin_v: f32) -> f32 {
        pin_v * self.v_divider
    }

    /// Current of an ADC-pin voltage, `None` without a current sensor.
    pub fn amps(&self, pin_v: f32) -> Option<f32> {
        (self.amps_per_volt > 0.0).then_some(pin_v * self.amps_per_volt)
    }
}

impl Default for BatteryParams {
    fn default() -> Self {
        Self {
            enabled: true,
            cells: 0,
            low_cell_v: 3.5,
            critical_cell_v: 3.3,
            hysteresis_v: 0.1,
            debounce_s: 2.0,
            filter_tau_s: 0.5,
            r_internal_ohm: 0.02,
            v_divider: 11.0,
            amps_per_volt: 0.0,
        }
    }
}

impl BatteryParams {
    /// The battery's measurement and thresholds (issue 22; `crate::params`, MAVLink
    /// `param_index` order).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 7] {
        [
            Param::new("BAT_LOW_V", "Battery", "V", (3.0, 4.2), 2, field!(low_cell_v),
                "Low battery: resting voltage per cell below this (return)"),
            Param::new("BAT_CRIT_V", "Battery", "V", (2.8, 4.0), 2, field!(critical_cell_v),
                "Critical battery: resting voltage per cell below this (land)"),
            Param::new("BAT_R_INT", "Battery", "Ohm", (0.0, 1.0), 3, field!(r_internal_ohm),
                "Pack internal resistance for the sag compensation (with a current sensor)"),
            Param::new("BAT_V_DIV", "Battery", "", (1.0, 100.0), 2, field!(v_divider),
                "VBAT divider: pack volts per ADC volt (MATEKF405 11)"),
            Param::new("BAT_A_PER_V", "Battery", "A/V", (0.0, 500.0), 1, field!(amps_per_volt),
                "Current sensor scale, A per ADC volt (0 = no current sensor)"),
            Param::new("BAT_CELLS", "Battery", "", (0.0, MAX_CELLS as f32), 0, u8_field!(cells),
                "Cells in series (0 = detect at power-up, disarmed)").whole(),
            Param::new("BAT_ENABLE", "Battery", "", (0.0, 1.0), 0, flag!(enabled),
                "Battery measured (0: no battery failsafe)").code(on_off),
        ]
    }
}

/// Largest per-cell voltage the cell-count detection assumes (high-voltage LiPo), V.
pub const CELL_V_MAX: f32 = 4.35;
/// Most cells the estimator accepts (14S).
pub const MAX_CELLS: u8 = 14;

/// Resting LiPo voltage per cell → remaining charge (a common discharge table).
const CURVE: [(f32, f32); 21] = [
    (3.27, 0.00),
    (3.61, 0.05),
    (3.69, 0.10),
    (3.71, 0.15),
    (3.73, 0.20),
    (3.75, 0.25),
    (3.77, 0.30),
    (3.79, 0.35),
    (3.80, 0.40),
    (3.82, 0.45),
    (3.84, 0.50),
    (3.85, 0.55),
    (3.87, 0.60),
    (3.91, 0.65),
    (3.95, 0.70),
    (3.98, 0.75),
    (4.02, 0.80),
    (4.08, 0.85),
    (4.11, 0.90),
    (4.15, 0.95),
    (4.20, 1.00),
];

/// Remaining charge in [0, 1] of a resting LiPo cell at `v` volts (linear between table
/// points, clamped at the ends; NaN gives 0).
pub fn remaining_of_cell_voltage(v: f32) -> f32 {
    let mut prev = CURVE[0];
    if v.is_nan() || v <= prev.0 {
        return 0.0;
    }
    for &(cv, r) in CURVE.iter().skip(1) {
        if v <= cv {
            let span = cv - prev.0;
            return prev.1 + (r - prev.1) * (v - prev.0) / span;
        }
        prev = (cv, r);
    }
    1.0
}

/// What [`BatteryEstimator::update`] did with a sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BatterySample {
    /// Taken; the new state.
    Accepted(BatteryState),
    /// Not finite or out of range; the state is unchanged (the last accepted one).
    Rejected(BatteryState),
}

impl BatterySample {
    /// The state after the sample, whether it was taken or not.
    pub fn state(self) -> BatteryState {
        match self {
            BatterySample::Accepted(s) | BatterySample::Rejected(s) => s,
        }
    }
}

/// Raw samples → [`BatteryState`] (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct BatteryEstimator {
    params: BatteryParams,
    state: BatteryState,
    v_filt: Option<f32>,
    i_filt: Option<f32>,
    cells: u8,
    below_since_us: [Option<u64>; 2],
    rejected: u32,
}

impl BatteryEstimator {
    /// A new estimator (no sample yet: level Ok, voltage 0).
    pub fn new(params: BatteryParams) -> Self {
        Self {
            params,
            state: BatteryState::default(),
            v_filt: None,
            i_filt: None,
            cells: params.cells.min(MAX_CELLS),
            below_since_us: [None; 2],
            rejected: 0,
        }
    }

    /// Replace the parameters (kept: filter state and the level reached).
    pub fn set_params(&mut self, params: BatteryParams) {
        self.params = params;
        if params.cells != 0 {
            self.cells = params.cells.min(MAX_CELLS);
        }
    }

    /// Cells in series (0 until detected).
    pub fn cells(&self) -> u8 {
        self.cells
    }

    /// Samples refused so far.
    pub fn rejected(&self) -> u32 {
        self.rejected
    }

    /// The last state.
    pub fn state(&self) -> BatteryState {
        self.state
    }

    /// Take one sample: pack voltage, V, and current, A, when measured; `armed` freezes the
    /// level's way up.
    pub fn update(
        &mut self,
        t_us: u64,
        voltage_v: f32,
        current_a: Option<f32>,
        armed: bool,
    ) -> BatterySample {
        let v_ok = voltage_v.is_finite() && (0.0..=100.0).contains(&voltage_v);
        let i_ok = current_a.is_none_or(|i| i.is_finite() && (-500.0..=500.0).contains(&i));
        if !v_ok || !i_ok || t_us < self.state.t_us {
            self.rejected = self.rejected.saturating_add(1);
            return BatterySample::Rejected(self.state);
        }
        let dt = (t_us - self.state.t_us) as f32 * 1e-6;
        let alpha = if self.params.filter_tau_s > 0.0 {
            fmath::minf(dt / self.params.filter_tau_s, 1.0)
        } else {
            1.0
        };
        let v = match self.v_filt {
            Some(f) => f + alpha * (voltage_v - f),
            None => voltage_v,
        };
        self.v_filt = Some(v);
        let i = match (current_a, self.i_filt) {
            (Some(c), Some(f)) => Some(f + alpha * (c - f)),
            (Some(c), None) => Some(c),
            (None, _) => None,
        };
        self.i_filt = i;
        if self.cells == 0 && !armed && v > 1.0 {
            self.cells = fmath::minf(libm_ceil(v / CELL_V_MAX), f32::from(MAX_CELLS)) as u8;
        }
        let mut s =
            BatteryState { t_us, voltage_v: v, current_a: i, remaining: None, level: self.state.level };
        if self.params.enabled && self.cells > 0 {
            let rest = v + i.map_or(0.0, |i| fmath::maxf(i, 0.0) * self.params.r_internal_ohm);
            let cell = rest / f32::from(self.cells);
            s.remaining = Some(remaining_of_cell_voltage(cell));
            s.level = self.level(t_us, cell, armed);
        } else {
            s.level = BatteryLevel::Ok;
        }
        self.state = s;
        BatterySample::Accepted(s)
    }

    fn level(&mut self, t_us: u64, cell: f32, armed: bool) -> BatteryLevel {
        let p = self.params;
        let thresholds = [(BatteryLevel::Low, p.low_cell_v), (BatteryLevel::Critical, p.critical_cell_v)];
        let mut level = self.state.level;
        for (k, (lvl, th)) in thresholds.into_iter().enumerate() {
            if cell < th {
                let since = *self.below_since_us[k].get_or_insert(t_us);
                if (t_us - since) as f32 * 1e-6 >= p.debounce_s && level < lvl {
                    level = lvl;
                }
            } else {
                self.below_since_us[k] = None;
            }
        }
        if !armed {
            // Back up only with a clear rise (a fresh pack), never in flight.
            while level > BatteryLevel::Ok {
                let th = if level == BatteryLevel::Critical { p.critical_cell_v } else { p.low_cell_v };
                if cell > th + p.hysteresis_v {
                    level =
                        if level == BatteryLevel::Critical { BatteryLevel::Low } else { BatteryLevel::Ok };
                } else {
                    break;
                }
            }
        }
        level
    }
}

/// Full-scale count of a 12-bit ADC conversion (STM32F4; STM32H7 in 12-bit mode).
pub const ADC_12BIT_FULL_SCALE: u16 = 4095;
/// Analog supply (VDDA = VREF+) the boards are designed for, V; the conversion uses it when
/// there is no internal-reference reading.
pub const VDDA_NOMINAL_V: f32 = 3.3;
/// VDDA at which ST measured the internal reference's factory calibration `VREFINT_CAL`
/// (STM32F405: at 0x1FFF_7A2A, 3.3 V, 30 °C; DS8626 table "Internal reference voltage
/// calibration values"), V.
pub const VREFINT_CAL_VDDA_V: f32 = 3.3;
/// VDDA outside this range, V, means a bad internal-reference reading (the STM32F405 runs at
/// 1.8-3.6 V; a flight controller's regulator gives 3.3 V): the nominal supply is used.
pub const VDDA_PLAUSIBLE_V: (f32, f32) = (2.8, 3.6);

/// One conversion of the battery inputs of a board (raw ADC counts of
/// [`ADC_12BIT_FULL_SCALE`]). `Copy`, host-testable: the board's ADC task fills it,
/// [`BatteryParams::convert`] turns it into the estimator's volts and amps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct AdcReading {
    /// The VBAT divider's pin.
    pub vbat: u16,
    /// The current sensor's pin, on a board that has one.
    pub current: Option<u16>,
    /// The internal reference (VREFINT) channel and its factory calibration word, when read:
    /// corrects for the actual VDDA.
    pub vrefint: Option<(u16, u16)>,
}

/// VDDA from an internal-reference reading: `VREFINT_CAL_VDDA_V · cal / raw`; `None` when a
/// count is 0 or the result is outside [`VDDA_PLAUSIBLE_V`].
pub fn vdda_volts(vrefint_raw: u16, vrefint_cal: u16) -> Option<f32> {
    if vrefint_raw == 0 || vrefint_cal == 0 {
        return None;
    }
    let v = VREFINT_CAL_VDDA_V * f32::from(vrefint_cal) / f32::from(vrefint_raw);
    (VDDA_PLAUSIBLE_V.0..=VDDA_PLAUSIBLE_V.1).contains(&v).then_some(v)
}

impl BatteryParams {
    /// Pack volts and amps of one reading (the estimator's input): pin volts = counts · VDDA /
    /// full scale, VDDA from the internal reference when plausible, else [`VDDA_NOMINAL_V`];
    /// then [`BatteryParams::pack_volts`] / [`BatteryParams::amps`]. A VBAT count at full scale
    /// (the pin at or above VDDA: the pack is beyond the divider's range, or the pin is
    /// shorted) gives NaN, which the estimator refuses and counts: a clipped reading must not
    /// look like a healthy pack.
    pub fn convert(&self, r: &AdcReading) -> (f32, Option<f32>) {
        let vdda = r.vrefint.and_then(|(raw, cal)| vdda_volts(raw, cal)).unwrap_or(VDDA_NOMINAL_V);
        let pin = |c: u16| f32::from(c.min(ADC_12BIT_FULL_SCALE)) * vdda / f32::from(ADC_12BIT_FULL_SCALE);
        let v = if r.vbat >= ADC_12BIT_FULL_SCALE { f32::NAN } else { self.pack_volts(pin(r.vbat)) };
        (v, r.current.and_then(|c| self.amps(pin(c))))
    }
}

/// `ceil` for the small positive values of the cell count (no libm in this unit).
fn libm_ceil(x: f32) -> f32 {
    let t = x as i32 as f32;
    if t < x {
        t + 1.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000;

    #[test]
    fn adc_counts_become_pack_volts_and_amps_with_the_boards_divider() {
        let p = BatteryParams { amps_per_volt: 40.0, ..Default::default() };
        // 4S at 16.8 V behind 10k/1k: 1.527 V on the pin = 1895 counts at 3.3 V.
        let (v, i) = p.convert(&AdcReading { vbat: 1895, current: Some(124), vrefint: None });
        assert!((v - 16.797).abs() < 0.01, "{v}");
        assert!((i.unwrap() - 3.997).abs() < 0.01, "{i:?}");
        // No current sensor configured: no current even with a reading.
        let (_, i) =
            BatteryParams::default().convert(&AdcReading { vbat: 1895, current: Some(124), vrefint: None });
        assert_eq!(i, None);
        // A VDDA of 3.0 V (VREFINT reads high): the same counts are fewer volts.
        let cal = 1500;
        let raw = (1500.0 * 3.3 / 3.0_f32).round() as u16;
        assert!((vdda_volts(raw, cal).unwrap() - 3.0).abs() < 0.01);
        let (v3, _) = p.convert(&AdcReading { vbat: 1895, current: None, vrefint: Some((raw, cal)) });
        assert!((v3 - 16.797 * 3.0 / 3.3).abs() < 0.02, "{v3}");
        // Implausible references fall back to the nominal supply.
        for (raw, cal) in [(0, 1500), (1500, 0), (100, 1500), (4000, 1500)] {
            assert_eq!(vdda_volts(raw, cal), None, "{raw} {cal}");
            let (vn, _) = p.convert(&AdcReading { vbat: 1895, current: None, vrefint: Some((raw, cal)) });
            assert!((vn - v).abs() < 1e-4);
        }
    }

    #[test]
    fn a_clipped_vbat_reading_is_refused_by_the_estimator_not_taken_as_a_full_pack() {
        let p = BatteryParams::default();
        let mut e = BatteryEstimator::new(p);
        let (v, _) = p.convert(&AdcReading { vbat: 1700, ..Default::default() });
        assert!(matches!(e.update(S, v, None, false), BatterySample::Accepted(_)));
        for vbat in [ADC_12BIT_FULL_SCALE, u16::MAX] {
            let (v, _) = p.convert(&AdcReading { vbat, ..Default::default() });
            assert!(v.is_nan());
            assert!(matches!(e.update(2 * S, v, None, false), BatterySample::Rejected(_)));
        }
        assert_eq!(e.rejected(), 2);
        // A pack dropping through the thresholds on ADC counts reaches Low then Critical.
        let mut e = BatteryEstimator::new(BatteryParams { cells: 4, ..p });
        let counts = |cell_v: f32| (cell_v * 4.0 / 11.0 / 3.3 * 4095.0).round() as u16;
        let mut t = 0;
        let mut last = BatteryLevel::Ok;
        for (cell_v, want) in
            [(3.9, BatteryLevel::Ok), (3.4, BatteryLevel::Low), (3.2, BatteryLevel::Critical)]
        {
            for _ in 0..60 {
                t += S / 10;
                let (v, _) = p.convert(&AdcReading { vbat: counts(cell_v), ..Default::default() });
                last = e.update(t, v, None, true).state().level;
            }
            assert_eq!(last, want, "{cell_v} V/cell");
        }
    }

    fn feed(e: &mut BatteryEstimator, t0: u64, t1: u64, v: f32, i: Option<f32>, armed: bool) -> BatteryState {
        let mut s = e.state();
        let mut t = t0;
        while t <= t1 {
            s = e.update(t, v, i, armed).state();
            t += 100_000;
        }
        s
    }

    #[test]
    fn curve_is_monotone_and_clamped() {
        assert_eq!(remaining_of_cell_voltage(f32::NAN), 0.0);
        assert_eq!(remaining_of_cell_voltage(3.0), 0.0);
        assert_eq!(remaining_of_cell_voltage(4.3), 1.0);
        assert!((remaining_of_cell_voltage(3.84) - 0.5).abs() < 1e-6);
        let mut last = 0.0;
        for k in 0..200 {
            let r = remaining_of_cell_voltage(3.2 + k as f32 * 0.005);
            assert!(r >= last);
            last = r;
        }
    }

    #[test]
    fn detects_cells_and_reports_remaining() {
        for (cells, v) in [(3u8, 12.6f32), (4, 16.8), (4, 15.2), (6, 22.2), (3, 10.5)] {
            let mut e = BatteryEstimator::new(BatteryParams::default());
            let s = e.update(0, v, None, false).state();
            assert_eq!(e.cells(), cells, "{v} V");
            let r = s.remaining.unwrap();
            assert!((r - remaining_of_cell_voltage(v / f32::from(cells))).abs() < 1e-6);
        }
        // A fixed cell count is not re-detected.
        let mut e = BatteryEstimator::new(BatteryParams { cells: 4, ..Default::default() });
        e.update(0, 12.0, None, false);
        assert_eq!(e.cells(), 4);
    }

    #[test]
    fn low_and_critical_need_the_debounce_and_never_recover_in_flight() {
        let mut e = BatteryEstimator::new(BatteryParams { cells: 3, ..Default::default() });
        assert_eq!(feed(&mut e, 0, S, 12.0, None, true).level, BatteryLevel::Ok);
        // A 1 s sag to 3.2 V/cell: filtered, below both thresholds but shorter than 2 s.
        assert_eq!(feed(&mut e, S + 100_000, 2 * S, 9.6, None, true).level, BatteryLevel::Ok);
        assert_eq!(feed(&mut e, 2 * S + 100_000, 6 * S, 12.0, None, true).level, BatteryLevel::Ok);
        // Sustained 3.4 V/cell: Low after the debounce, not Critical.
        let s = feed(&mut e, 6 * S + 100_000, 12 * S, 10.2, None, true);
        assert_eq!(s.level, BatteryLevel::Low);
        // Recovering voltage in flight (load removed) does not raise the level.
        assert_eq!(feed(&mut e, 12 * S + 100_000, 20 * S, 12.3, None, true).level, BatteryLevel::Low);
        // Critical.
        assert_eq!(feed(&mut e, 20 * S + 100_000, 30 * S, 9.6, None, true).level, BatteryLevel::Critical);
        // Disarmed, the same pack resting a bit higher but within the hysteresis: stays.
        assert_eq!(
            feed(&mut e, 30 * S + 100_000, 40 * S, 3.35 * 3.0, None, false).level,
            BatteryLevel::Critical
        );
        // A fresh pack, disarmed: Ok again.
        assert_eq!(feed(&mut e, 40 * S + 100_000, 50 * S, 12.6, None, false).level, BatteryLevel::Ok);
    }

    #[test]
    fn current_compensates_the_sag() {
        let p = BatteryParams { cells: 3, r_internal_ohm: 0.05, ..Default::default() };
        let mut e = BatteryEstimator::new(p);
        // 3.4 V/cell under 20 A: resting 10.2 + 1.0 = 11.2 V = 3.73 V/cell, not low.
        let s = feed(&mut e, 0, 10 * S, 10.2, Some(20.0), true);
        assert_eq!(s.level, BatteryLevel::Ok);
        assert_eq!(s.current_a, Some(20.0));
        assert!((s.remaining.unwrap() - remaining_of_cell_voltage(11.2 / 3.0)).abs() < 1e-4);
        let mut e = BatteryEstimator::new(p);
        assert_eq!(feed(&mut e, 0, 10 * S, 10.2, None, true).level, BatteryLevel::Low);
    }

    #[test]
    fn bad_samples_are_refused_and_keep_the_last_state() {
        let mut e = BatteryEstimator::new(BatteryParams { cells: 3, ..Default::default() });
        let good = e.update(S, 11.5, Some(3.0), true).state();
        for (v, i) in
            [(f32::NAN, None), (f32::INFINITY, None), (-1.0, None), (150.0, None), (11.0, Some(f32::NAN))]
        {
            match e.update(2 * S, v, i, true) {
                BatterySample::Rejected(s) => assert_eq!(s, good),
                other => panic!("{v} {i:?} accepted: {other:?}"),
            }
        }
        // Time going backwards is refused too.
        assert!(matches!(e.update(0, 11.0, None, true), BatterySample::Rejected(_)));
        assert_eq!(e.rejected(), 6);
    }

    #[test]
    fn disabled_battery_is_always_ok() {
        let mut e = BatteryEstimator::new(BatteryParams { enabled: false, ..Default::default() });
        let s = feed(&mut e, 0, 10 * S, 6.0, None, true);
        assert_eq!(s.level, BatteryLevel::Ok);
        assert_eq!(s.remaining, None);
    }
}
