//! Extending a trajectory in flight (issue 38, `crate::outer::path_stream`): a path longer
//! than the trajectory holds is given to it in windows; each refill drops legs already flown
//! and appends the next waypoints after the goal, in place, keeping the motion (position,
//! speed, acceleration, the piece flown) exactly as it is. A rebuild from the reference
//! ([`Trajectory::rebuild_moving`]) can carry the motion over only along the first leg, which
//! a reference in a corner's blend never is: every refill on a curve would restart at rest.
//!
//! Why the motion stays safe: the goal was a stop; it becomes a corner whose speed limit is
//! ≥ 0, and the new limits lie beyond it, so every braking plan that was feasible stays
//! feasible ([`Trajectory::safe`] looks only at limits ahead). The legs kept are unchanged, so
//! the pieces before the old goal keep their lengths, blends and limits; the last leg's
//! straight part shortens by the new corner's half-blend, which is why the piece flown must
//! lie before the last leg.
//!
//! May import: the rest of [`super`] (it is part of the trajectory).

use super::{PathError, Trajectory, TrajectoryError, COORDINATE_LIMIT, MIN_LEG_LENGTH};
use crate::fmath::norm3;
use crate::frame::is_finite3;
use crate::Vec3;

impl<const N: usize> Trajectory<N> {
    /// Drops the legs before the one flown but one and appends as many of `more` after the goal
    /// as then fit `N` points. Returns `(dropped, appended)`: trajectory point `k` becomes
    /// point `k − dropped`, `more[..appended]` were appended. Refused, the trajectory
    /// untouched: done, `more` empty, the piece flown on the last leg (its length changes with
    /// the new corner), no room for one more point, a waypoint appended not finite, beyond
    /// [`COORDINATE_LIMIT`], within [`MIN_LEG_LENGTH`] of the one before it, or a new leg off
    /// the horizontal on a horizontal path whose vertical acceleration limit is lower (the
    /// limits of the motion flown would change). Bounded: O(`N`).
    pub fn extend(&mut self, more: &[Vec3]) -> Result<(usize, usize), TrajectoryError> {
        let legs = self.legs.len();
        if self.done || more.is_empty() || legs == 0 || self.piece + 1 >= 2 * legs - 1 {
            return Err(TrajectoryError::BadStartState);
        }
        let drop = (self.piece / 2).saturating_sub(1);
        // Points kept: legs − drop + 1.
        let room = N.saturating_sub(legs - drop + 1);
        let Some(more) = more.get(..more.len().min(room)).filter(|m| !m.is_empty()) else {
            return Err(PathError::TooMany { capacity: N }.into());
        };
        if let Some(index) = more.iter().position(|w| !is_finite3(w)) {
            return Err(PathError::NonFinite { index }.into());
        }
        if let Some(index) = more.iter().position(|w| w.amax() > COORDINATE_LIMIT) {
            return Err(PathError::OutOfRange { index }.into());
        }
        let mut prev = self.goal;
        for (i, w) in more.iter().enumerate() {
            if norm3(&(w - prev)) < MIN_LEG_LENGTH {
                return Err(TrajectoryError::RepeatedWaypoint { index: i });
            }
            prev = *w;
        }
        let horizontal = |d: &Vec3| d.z.abs() <= 1e-6 * norm3(d);
        let was_horizontal = self.legs.iter().all(|l| l.dir.z.abs() <= 1e-6);
        let stays_horizontal =
            core::iter::once(&self.goal).chain(more).zip(more).all(|(a, b)| horizontal(&(b - a)));
        if was_horizontal && !stays_horizontal && self.params.accel_vertical < self.params.accel_horizontal {
            return Err(TrajectoryError::BadStartState);
        }
        // The legs and corners flown (all but the one before the current leg) go.
        self.legs.rotate_left(drop);
        self.legs.truncate(legs - drop);
        let corners = self.corners.len();
        self.corners.rotate_left(drop.min(corners));
        self.corners.truncate(corners.saturating_sub(drop));
        self.piece -= 2 * drop;
        self.flown = self.flown.take().and_then(|(k, c)| Some((k.checked_sub(drop)?, c)));
        // The new legs, then the corners: at the old goal and between the new legs.
        let axes = super::axis_limits(&self.params);
        let mut from = self.goal;
        for w in more {
            let d = w - from;
            let length = norm3(&d);
            let dir = d / length;
            // Fits: checked against N above.
            let _ = self.legs.push(super::Leg { from, dir, length, limit: axes.along(&dir) });
            from = *w;
        }
        for k in self.corners.len()..self.legs.len() - 1 {
            let brief = self.corner(k).map_or(super::CornerBrief::default(), |c| c.brief());
            let _ = self.corners.push(brief);
        }
        self.goal = from;
        let ahead: f32 = (self.piece..self.piece_count()).map(|p| self.piece_len(p)).sum();
        self.total = self.piece_start + ahead;
        Ok((drop, more.len()))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::super::{TrajectoryParams, MAX_STEP_DT};
    use super::*;
    use std::format;

    /// A gentle zigzag along north at 1.5 m a leg: waypoint `k`.
    fn wp(k: usize) -> Vec3 {
        Vec3::new(1.5 * k as f32, if k % 2 == 1 { 0.15 } else { 0.0 }, -1.0)
    }

    fn params() -> TrajectoryParams {
        TrajectoryParams { cruise_speed: 5.0, ..TrajectoryParams::default() }
    }

    /// Streamed in windows (a 16-point trajectory topped up each time the flight passes 4 of
    /// its waypoints), a 60-waypoint path is flown without a stop to its end at rest; the
    /// reference stays continuous across every extension and keeps within the limits.
    #[test]
    fn a_long_path_streamed_in_windows_is_flown_without_stopping() {
        let path: heapless::Vec<Vec3, 64> = (0..60).map(wp).collect();
        let mut t: Trajectory<16> = Trajectory::new(params(), &path[..12]).expect("trajectory");
        let (mut sent, mut count) = (12, 12); // waypoints given, trajectory points held
        let mut passed_at = 0; // trajectory point 0 is waypoint `passed_at`
        let dt = MAX_STEP_DT;
        let mut last = t.step(dt, 1.0).expect("step");
        let (mut min_speed_mid, mut extensions) = (f32::INFINITY, 0);
        for _ in 0..20_000 {
            let s = t.step(dt, 1.0).expect("step");
            let v = last.speed.max(s.speed);
            assert!((s.position - last.position).norm() <= v * dt + 1e-4, "{s:?} after {last:?}");
            assert!((s.velocity - last.velocity).norm() <= 5.0 * dt + 1e-4, "{s:?} after {last:?}");
            assert!(s.speed <= 5.0 + 1e-3);
            if sent < path.len() && s.segment >= 4 && !s.done {
                // At least segment − 2 points go: room for that many more.
                let room = 16 - (count - (s.segment - 2));
                let more = &path[sent..(sent + room).min(path.len())];
                let (dropped, appended) = t.extend(more).expect("extend");
                assert!(dropped >= s.segment - 2);
                assert_eq!(appended, more.len());
                count = count - dropped + more.len();
                (passed_at, sent, extensions) = (passed_at + dropped, sent + more.len(), extensions + 1);
            }
            let k = passed_at + s.segment;
            if (10..50).contains(&k) {
                min_speed_mid = min_speed_mid.min(s.speed);
            }
            last = s;
            if s.done {
                break;
            }
        }
        assert!(last.done, "not done: {last:?}");
        assert!((last.position - path[59]).norm() < 1e-3);
        assert!(extensions >= 6, "{extensions}");
        assert!(min_speed_mid > 2.0, "the flight slowed to {min_speed_mid} m/s between windows");
    }

    #[test]
    fn an_extension_that_cannot_be_flown_leaves_the_trajectory_as_it_was() {
        let path: heapless::Vec<Vec3, 8> = (0..4).map(wp).collect();
        let mut t: Trajectory<8> = Trajectory::new(params(), &path).expect("trajectory");
        let before = format!("{t:?}");
        assert_eq!(t.extend(&[]), Err(TrajectoryError::BadStartState));
        assert_eq!(t.extend(&[wp(3)]), Err(TrajectoryError::RepeatedWaypoint { index: 0 }));
        assert_eq!(
            t.extend(&[wp(4), Vec3::new(f32::NAN, 0.0, 0.0)]),
            Err(PathError::NonFinite { index: 1 }.into())
        );
        // No room: the trajectory holds 8 points already (none flown).
        let mut full: Trajectory<4> = Trajectory::new(params(), &path).expect("trajectory");
        assert_eq!(full.extend(&[wp(4)]), Err(PathError::TooMany { capacity: 4 }.into()));
        assert_eq!(format!("{t:?}"), before);
        // Room for four more of five: four appended.
        let many: heapless::Vec<Vec3, 8> = (4..9).map(wp).collect();
        assert_eq!(t.extend(&many), Ok((0, 4)));
        // On the last leg: refused (its straight part would change under the reference).
        for _ in 0..10_000 {
            let s = t.step(MAX_STEP_DT, 1.0).expect("step");
            if t.total_length() - s.s < 0.3 {
                break;
            }
        }
        let on_last = format!("{t:?}");
        assert_eq!(t.extend(&[wp(9)]), Err(TrajectoryError::BadStartState));
        assert_eq!(format!("{t:?}"), on_last);
    }
}
