//! Which inner step runs the outer step: the one outer-loop schedule of the project.
//!
//! The inner loop runs on every IMU sample (default 1 kHz); the outer loop runs after the
//! inner step of every `divider`-th sample (default 4, i.e. 250 Hz). Both rates are
//! [`ControllerParams`] fields (`outer_rate_hz`, `inner_rate_hz`); everything that drives
//! the cascade takes its period from here:
//!
//! * a loop that counts inner steps (the host runner, the closed-loop tests) asks
//!   [`OuterSchedule::is_outer_step`]`(k)`: `k % divider == 0`;
//! * a loop driven by time (the firmware's outer task, the lockstep PIL and its host twin)
//!   uses [`OuterSchedule::period_us`], or [`OuterSchedule::clock`] for the lockstep rule
//!   by simulated time ([`crate::wire::lockstep::LockstepClock`]: first sample, then
//!   `t ≥ next`, `next += period`, a skipped period or time going backwards restarts the phase).
//!
//! May import: [`crate::config::ControllerParams`] (read-only), [`crate::wire::lockstep`] and
//! [`crate::wire::rates`].

use crate::config::ControllerParams;
use crate::wire::lockstep::LockstepClock;

/// The outer-loop schedule of one parameter set (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OuterSchedule {
    period_us: u64,
    divider: u64,
}

impl OuterSchedule {
    /// The schedule of `params` (`outer_rate_hz`, `inner_rate_hz`).
    pub fn new(params: &ControllerParams) -> Self {
        Self::from_rates(params.outer_rate_hz, params.inner_rate_hz)
    }

    /// The schedule of an outer loop at `outer_rate_hz` under an inner loop at
    /// `inner_rate_hz`. Periods are rounded to whole µs and inner steps, at least 1; rates
    /// that are not finite and positive (rejected by [`ControllerParams::validate`]) give
    /// the default 4 000 µs / 4.
    pub fn from_rates(outer_rate_hz: f32, inner_rate_hz: f32) -> Self {
        let ok = |x: f32| x.is_finite() && x > 0.0;
        if !(ok(outer_rate_hz) && ok(inner_rate_hz)) {
            return Self::DEFAULT;
        }
        // `as` saturates (huge → u64::MAX); `max(1)` keeps a period and a divider.
        let period_us = libm::roundf(1.0e6 / outer_rate_hz) as u64;
        let divider = libm::roundf(inner_rate_hz / outer_rate_hz) as u64;
        Self { period_us: period_us.max(1), divider: divider.max(1) }
    }

    /// The default schedule: 250 Hz under 1 kHz.
    pub const DEFAULT: Self = Self {
        period_us: crate::wire::rates::OUTER_PERIOD_US as u64,
        divider: crate::wire::rates::OUTER_DIVIDER as u64,
    };

    /// Outer period, µs (default 4 000).
    pub const fn period_us(&self) -> u64 {
        self.period_us
    }

    /// Inner steps per outer step (default 4).
    pub const fn divider(&self) -> u64 {
        self.divider
    }

    /// `true` when inner step number `k` (0, 1, 2, …) is followed by an outer step.
    pub const fn is_outer_step(&self, k: u64) -> bool {
        k.is_multiple_of(self.divider)
    }

    /// The lockstep clock by simulated time with this period.
    pub const fn clock(&self) -> LockstepClock {
        LockstepClock::new(self.period_us)
    }
}

impl Default for OuterSchedule {
    fn default() -> Self {
        Self::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_parameters_give_250_hz_under_1_khz() {
        let s = OuterSchedule::new(&ControllerParams::default());
        assert_eq!(s, OuterSchedule::DEFAULT);
        assert_eq!((s.period_us(), s.divider()), (4_000, 4));
        let outer: [bool; 9] = core::array::from_fn(|k| s.is_outer_step(k as u64));
        assert_eq!(outer, [true, false, false, false, true, false, false, false, true]);
        assert_eq!(s.clock().period_us(), 4_000);
    }

    #[test]
    fn the_rates_drive_the_schedule() {
        let s = OuterSchedule::from_rates(500.0, 1000.0);
        assert_eq!((s.period_us(), s.divider()), (2_000, 2));
        let s = OuterSchedule::from_rates(100.0, 2000.0);
        assert_eq!((s.period_us(), s.divider()), (10_000, 20));
        // An outer rate above the inner rate still runs once per inner step.
        assert_eq!(OuterSchedule::from_rates(4000.0, 1000.0).divider(), 1);
        assert_eq!(OuterSchedule::from_rates(f32::NAN, 1000.0), OuterSchedule::DEFAULT);
        assert_eq!(OuterSchedule::from_rates(250.0, 0.0), OuterSchedule::DEFAULT);
        assert_eq!(OuterSchedule::from_rates(1e-30, 1.0).period_us(), u64::MAX);
        assert_eq!(OuterSchedule::from_rates(1e30, 1.0).period_us(), 1);
    }
}
