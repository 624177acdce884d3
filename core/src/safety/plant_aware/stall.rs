//! Stall (deadlock) detection: flying the mission more than
//! [`STALL_TRACKING_ERROR_M`] from the reference, the safety filter
//! intervenes, and the vehicle has not moved `stall_distance_m` for
//! `stall_time_s`. The controller's defined action on `deadlock`: report it
//! (telemetry) and hold the position where it stalled (the mission ends there;
//! a new `start_mission` or path resumes). May import: [`crate::Vec3`].

use crate::Vec3;

/// Tracking error above which a mission step can count towards a stall, m.
pub const STALL_TRACKING_ERROR_M: f32 = 0.3;

/// Detector state (no allocation, O(1) per step).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct StallDetector {
    anchor: Option<(Vec3, u64)>,
}

impl StallDetector {
    /// Forget the anchor (mission start, or any step where the filter is inactive).
    pub fn reset(&mut self) {
        self.anchor = None;
    }

    /// One outer step at `now_us` with vehicle position `p`. `stalling` is "mission
    /// not finished and the filter intervened this step". Returns `true` once the
    /// vehicle has stayed within `distance` of where it was `time_s` ago with
    /// `stalling` true throughout.
    pub fn update(&mut self, now_us: u64, p: &Vec3, stalling: bool, time_s: f32, distance: f32) -> bool {
        if !stalling || !p.iter().all(|c| c.is_finite()) {
            self.anchor = None;
            return false;
        }
        match self.anchor {
            Some((a, t0)) if (p - a).norm_squared() <= distance * distance => {
                now_us.saturating_sub(t0) as f32 * 1e-6 >= time_s
            }
            _ => {
                self.anchor = Some((*p, now_us));
                false
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stall_needs_the_whole_time_without_progress() {
        let mut s = StallDetector::default();
        let p = Vec3::new(1.0, 0.0, -1.0);
        assert!(!s.update(0, &p, true, 2.0, 0.1));
        assert!(!s.update(1_999_000, &(p + Vec3::new(0.05, 0.0, 0.0)), true, 2.0, 0.1));
        assert!(s.update(2_000_000, &p, true, 2.0, 0.1));
        // Progress restarts the clock; an inactive filter resets it.
        assert!(!s.update(2_100_000, &(p + Vec3::new(0.2, 0.0, 0.0)), true, 2.0, 0.1));
        assert!(!s.update(3_000_000, &p, false, 2.0, 0.1));
        assert!(!s.update(4_900_000, &p, true, 2.0, 0.1));
        assert!(s.update(6_900_000, &p, true, 2.0, 0.1));
    }
}
