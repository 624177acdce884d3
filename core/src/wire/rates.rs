//! The loop rates, defined once (as Crazyflie's `RATE_MAIN_LOOP` / `RATE_DO_EXECUTE`): the
//! inner loop at the IMU's rate, the outer loop every [`OUTER_DIVIDER`]-th inner step. The
//! controller's defaults ([`crate::config::ControllerParams`]), the outer-loop schedule
//! ([`crate::schedule::OuterSchedule::DEFAULT`]), the firmware's loop timer and IMU
//! configuration, and the host simulator's plant step all derive from these.

/// Inner-loop rate (attitude, rates, mixer; the IMU's sample rate), Hz.
pub const INNER_RATE_HZ: u32 = 1000;
/// Inner steps per outer step.
pub const OUTER_DIVIDER: u32 = 4;
/// Outer-loop rate (guidance, tracking, safety filter), Hz: 250.
pub const OUTER_RATE_HZ: u32 = INNER_RATE_HZ / OUTER_DIVIDER;
/// Inner-loop period, µs: 1 000.
pub const INNER_PERIOD_US: u32 = 1_000_000 / INNER_RATE_HZ;
/// Outer-loop period, µs: 4 000.
pub const OUTER_PERIOD_US: u32 = INNER_PERIOD_US * OUTER_DIVIDER;

// The rates divide exactly (integer periods, a whole divider).
const _: () =
    assert!(1_000_000u32.is_multiple_of(INNER_RATE_HZ) && INNER_RATE_HZ.is_multiple_of(OUTER_DIVIDER));

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rates_are_1_khz_and_250_hz() {
        assert_eq!((INNER_RATE_HZ, OUTER_RATE_HZ, INNER_PERIOD_US, OUTER_PERIOD_US), (1000, 250, 1000, 4000));
    }
}
