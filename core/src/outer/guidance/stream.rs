//! A long mission path streamed through the guidance (issue 38, [`crate::outer::path_stream`]):
//! [`Guidance::stream_path`] takes the next waypoints of a path longer than
//! [`PATH_CAPACITY`] while the mission flies. The stored path becomes the waypoints not yet
//! passed followed by the new ones; a trajectory being flown is extended in place
//! ([`crate::outer::trajectory::Trajectory::extend`]: the motion is kept exactly, the old goal
//! becomes a corner) and its points are renumbered against the new path, so
//! [`crate::waypoint::Progress::segment`] keeps naming the waypoint flown to. The paper's
//! follower, a trajectory that cannot be extended (the reference on its last leg, a limit that
//! would change) and a guidance not flying the mission take the new path as
//! [`Guidance::set_path_from`] does (from the reference, carrying its motion when it can).
//!
//! Owns nothing but this method of [`Guidance`].

use super::{Guidance, Mode, PATH_CAPACITY};
use crate::outer::CommandError;
use crate::waypoint::PathError;
use crate::Vec3;

impl Guidance {
    /// The mission path goes on: its first `passed` waypoints are behind (the one flown to is
    /// `passed`, [`crate::waypoint::Progress::segment`]) and `more` follow its last. `origin`,
    /// `now_us`: as [`Guidance::set_path_from`] (used when the trajectory is not extended in
    /// place). Returns how many of `more` the path took (the trajectory may have room for
    /// fewer: the points it keeps behind the waypoint flown to count). Refused (nothing
    /// changed) when the waypoints left and `more` exceed [`PATH_CAPACITY`] or the follower
    /// refuses the new path. Bounded: O([`PATH_CAPACITY`]).
    pub fn stream_path(
        &mut self,
        passed: usize,
        more: &[Vec3],
        now_us: u64,
        origin: Vec3,
    ) -> Result<usize, CommandError> {
        let mut path: heapless::Vec<Vec3, PATH_CAPACITY> = heapless::Vec::new();
        let left = self.follower.waypoints().get(passed..).unwrap_or(&[]);
        let left_len = left.len();
        if path.extend_from_slice(left).is_err() || path.extend_from_slice(more).is_err() {
            return Err(CommandError::Path(PathError::TooMany { capacity: PATH_CAPACITY }));
        }
        let flying = matches!(self.mode, Mode::Mission { .. }) && self.flying_trajectory;
        if !flying {
            return self.set_path_from(&path, now_us, origin, true).map(|()| more.len());
        }
        let before = self.follower.waypoints().len();
        self.follower.set_path(&path).map_err(CommandError::Path)?;
        let Ok((dropped, appended)) = self.trajectory.extend(more) else {
            return self.set_path_from(&path, now_us, origin, true).map(|()| more.len());
        };
        if appended < more.len() {
            // The trajectory had room for fewer: the path ends where it does.
            path.truncate(left_len + appended);
            self.follower.set_path(&path).map_err(CommandError::Path)?;
        }
        // Points kept are renumbered against the new path (those behind it count as 0), the
        // appended ones follow the waypoints left.
        let old = self.point_waypoint.clone();
        self.point_waypoint.clear();
        let shift = |w: u16| w.saturating_sub(u16::try_from(passed).unwrap_or(u16::MAX));
        for w in old.iter().skip(dropped) {
            let _ = self.point_waypoint.push(shift(*w));
        }
        let base = before.saturating_sub(passed);
        for k in 0..appended {
            // Fits: the trajectory took them (one point each).
            let _ = self.point_waypoint.push(u16::try_from(base + k).unwrap_or(u16::MAX));
        }
        Ok(appended)
    }
}
