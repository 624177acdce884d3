//! Streaming a path longer than the guidance holds (issue 38: "a path that needs more waypoints
//! is flown, not refused"). The guidance keeps [`PATH_CAPACITY`] waypoints (its trajectory
//! stores per-waypoint corner data, so the capacity is RAM on the MCU); a longer path — a
//! planned path on the host, a mission of more items over MAVLink — is given to it in windows.
//!
//! **The rule** ([`refill_count`], run by [`OuterLoop::stream_path`] after each outer step
//! with the waypoints waiting): while the mission is flown, once the guidance has passed
//! [`REFILL_PASSED`] waypoints of its path (it flies to `Progress::segment`), or when only
//! [`REFILL_LEFT`] or fewer are left (a window the replanner shortened), the waypoints left are
//! topped up with waiting ones to [`STREAM_WINDOW`]. The guidance keeps its motion
//! ([`super::guidance::Guidance::stream_path`]: the trajectory is extended in place, the old
//! goal becomes a corner), so the flight runs on: the window ends at least
//! `STREAM_WINDOW − REFILL_PASSED` = 46 waypoints ahead, and the trajectory only slows for a
//! window's end when those are closer together than its braking distance (46 waypoints within
//! ≈ 11 m at 8 m/s and 3 m/s², 0.24 m apart).
//!
//! The same rule serves a window that the replanner rewrote (its new path is the detour and the
//! rest of the window): what is left of the guidance's path, whatever it is, comes first.
//!
//! Bounded: one pass over at most [`PATH_CAPACITY`] points; no allocation.
//!
//! May import: [`super::guidance`] (the capacity, the mode), [`super::OuterLoop`] (the loop it
//! streams into), [`crate::Vec3`].

use super::guidance::{GuidanceMode, PATH_CAPACITY};
use super::{CommandError, OuterLoop};
use crate::Vec3;

/// A refill is due once the guidance has passed this many waypoints of its path…
pub const REFILL_PASSED: usize = PATH_CAPACITY / 4;
/// … or when this many or fewer are left in it.
pub const REFILL_LEFT: usize = PATH_CAPACITY / 2;
/// Waypoints a refill tops the guidance's path up to: two short of [`PATH_CAPACITY`], the room
/// the trajectory needs for the points behind the waypoint flown to that it keeps (the leg
/// flown, the one before it and, past a blend's middle, the corner's).
pub const STREAM_WINDOW: usize = PATH_CAPACITY - 2;

/// How many of `waiting` waypoints to append now to a path of `path_len` waypoints whose
/// waypoint `next` is flown to (`Progress::segment`): 0 when no refill is due (fewer than
/// [`REFILL_PASSED`] passed and more than [`REFILL_LEFT`] left, at least [`STREAM_WINDOW`]
/// left, or nothing waiting); else as many as top the waypoints left up to
/// [`STREAM_WINDOW`].
pub fn refill_count(path_len: usize, next: usize, waiting: usize) -> usize {
    let left = path_len.saturating_sub(next);
    if waiting == 0 || (next < REFILL_PASSED && left > REFILL_LEFT) || left >= STREAM_WINDOW {
        return 0;
    }
    waiting.min(STREAM_WINDOW - left)
}

impl OuterLoop {
    /// One streaming step (the module docs): while the mission is flown, the next of the
    /// `waiting` waypoints when a refill is due ([`refill_count`]) go onto the guidance's path
    /// ([`super::guidance::Guidance::stream_path`]). Returns how many it took (0: none due, or
    /// the guidance refused them: the caller keeps them waiting and tries again).
    pub fn stream_path(&mut self, waiting: &[Vec3]) -> Result<usize, CommandError> {
        let tel = &self.telemetry;
        if tel.mode != GuidanceMode::Mission || tel.progress.done {
            return Ok(0);
        }
        let next = usize::from(tel.progress.segment);
        let count = refill_count(self.path().len(), next, waiting.len());
        let Some(more) = waiting.get(..count).filter(|m| !m.is_empty()) else { return Ok(0) };
        let (now, reference) = (self.last_us.unwrap_or(0), self.telemetry.reference.position);
        let taken = self.guidance.stream_path(next, more, now, reference)?;
        // The waypoint flown to is the new path's first: until the next step refreshes the
        // telemetry, a second call (the firmware's link may poll twice between outer steps)
        // must not count the waypoints behind it as passed again.
        self.telemetry.progress.segment = 0;
        Ok(taken)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_is_topped_up_once_a_quarter_of_it_is_flown() {
        let full = PATH_CAPACITY;
        // Flying to waypoint 15: nothing yet; to 16: the window topped up to 62.
        assert_eq!(refill_count(full, REFILL_PASSED - 1, 100), 0);
        assert_eq!(refill_count(full, REFILL_PASSED, 100), STREAM_WINDOW - (full - REFILL_PASSED));
        // Only what waits.
        assert_eq!(refill_count(full, REFILL_PASSED, 3), 3);
        assert_eq!(refill_count(full, REFILL_PASSED, 0), 0);
        // A window the replanner shortened (4 left, none passed): due at once.
        assert_eq!(refill_count(4, 0, 100), STREAM_WINDOW - 4);
        // A full window: not due.
        assert_eq!(refill_count(STREAM_WINDOW, 0, 100), 0);
        assert_eq!(refill_count(STREAM_WINDOW + 20, 20, 100), 0);
        // Past the end (a finished window): the waiting ones.
        assert_eq!(refill_count(10, 12, 5), 5);
    }
}
