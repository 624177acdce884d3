//! Why a flight went slower than it was told to (issues 35/36): `summary.json`'s
//! `speed_limited_by`, the speed governor's causes over the outer steps where it changed the
//! nominal command (`parapet_core::governor`).
//!
//! Each step where the governor acted counts its spacing to the step before (as
//! `safety_steps.governor_limited_s`) against the cause reported in that step — what sets the
//! limit along the direction of motion: `range` (the sensing range), `obstacle` (an observed
//! obstacle point), `unseen` (the end of the space observed free), `data_age` (the obstacle data's
//! age is the larger part of the braking delay) or `none` (the governor braked a direction the
//! vehicle was not moving along, or the vehicle was nearly at rest). The cause that limited
//! longest is `cause`; `fraction` is the limited time over the flight's time.
//!
//! Owns [`SpeedLimitedBy`]. May import: [`super`] ([`Sample`], [`governor_cause_name`]).

use std::collections::BTreeMap;

use serde::Serialize;

use super::{governor_cause_name, Sample};

/// Where the speed governor limited a flight (`summary.json`, `speed_limited_by`; null when it
/// never acted: off, or never needed).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpeedLimitedBy {
    /// The cause that limited longest (module docs).
    pub cause: &'static str,
    /// The time that cause limited, s.
    pub cause_s: f64,
    /// The time the governor limited, every cause, s.
    pub limited_s: f64,
    /// `limited_s` over the flight's time (first to last sample), 0…1.
    pub fraction: f64,
    /// Seconds per cause, for every cause that limited.
    pub by_cause: BTreeMap<&'static str, f64>,
}

impl SpeedLimitedBy {
    /// From the flight's samples; `None` when the governor never acted.
    pub fn of(samples: &[Sample]) -> Option<Self> {
        let mut by_cause: BTreeMap<&'static str, f64> = BTreeMap::new();
        let mut prev_t = None::<f64>;
        for k in samples {
            if k.safety.governor_active {
                let dt = prev_t.map_or(0.0, |t0| (k.t - t0).max(0.0));
                *by_cause.entry(governor_cause_name(k.safety.governor_cause)).or_insert(0.0) += dt;
            }
            prev_t = Some(k.t);
        }
        let (&cause, &cause_s) = by_cause.iter().max_by(|a, b| a.1.total_cmp(b.1))?;
        let limited_s: f64 = by_cause.values().sum();
        let span = match (samples.first(), samples.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        };
        let fraction = if span > 0.0 { (limited_s / span).clamp(0.0, 1.0) } else { 0.0 };
        Some(SpeedLimitedBy { cause, cause_s, limited_s, fraction, by_cause })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::replay::tests::sample;
    use parapet_core::governor::GovernorCause;

    /// One sample per step, 4 ms apart.
    fn flight(steps: &[(bool, GovernorCause)]) -> Vec<Sample> {
        steps
            .iter()
            .enumerate()
            .map(|(i, &(active, cause))| {
                let mut k = sample(i);
                k.safety.governor_active = active;
                k.safety.governor_cause = cause;
                k
            })
            .collect()
    }

    #[test]
    fn the_cause_that_limited_longest_and_the_fraction_of_the_flight() {
        use GovernorCause::{None as Free, Obstacle, Range};
        // 11 samples, 40 ms: range for 8 ms, obstacle for 12 ms, free otherwise.
        let s = flight(&[
            (false, Free),
            (true, Range),
            (true, Range),
            (false, Free),
            (true, Obstacle),
            (true, Obstacle),
            (true, Obstacle),
            (false, Free),
            (false, Free),
            (false, Free),
            (false, Free),
        ]);
        let by = SpeedLimitedBy::of(&s).expect("the governor acted");
        assert_eq!(by.cause, "obstacle");
        assert!((by.cause_s - 0.012).abs() < 1e-9, "{by:?}");
        assert!((by.limited_s - 0.020).abs() < 1e-9, "{by:?}");
        assert!((by.fraction - 0.5).abs() < 1e-9, "{by:?}");
        assert_eq!(by.by_cause.len(), 2);
        assert!((by.by_cause["range"] - 0.008).abs() < 1e-9);
    }

    #[test]
    fn null_when_the_governor_never_acted() {
        assert_eq!(SpeedLimitedBy::of(&flight(&[(false, GovernorCause::Range); 5])), None);
        assert_eq!(SpeedLimitedBy::of(&[]), None);
    }
}
