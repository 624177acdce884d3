//! Battery state: the message between the battery measurement (ADC on the board, the
//! simulator's battery model in host-sim/PIL) and the supervisor's low-battery failsafes.
//!
//! Owns [`BatteryState`] and [`BatteryLevel`].
//!
//! May import: the crate root foundation only.

/// How the supervisor must treat the battery.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
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
