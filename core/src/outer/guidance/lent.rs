//! The guidance's one trajectory lent to the other flight modes that fly to a place (issue 35):
//! **Return** flies the breadcrumbs reversed on the same jerk-limited generator as a mission ([`super::super::trajectory`]), with the `TRJ_*`
//! limits and the clock that waits for the vehicle, when `MIS_GUIDANCE` = 1. One trajectory
//! serves both (the modes exclude each other; a second one would cost 3 KB of RAM and its
//! by-value copies in the firmware's boot): the guidance is in its `Lent` mode while another
//! flight mode flies it, and the mission's commands take it back by re-building it.
//!
//! * Return: [`Guidance::start_return`] from the vehicle through the trail (built by
//!   [`crate::outer::return_path::ReturnPath::trail_back`]) at `RTL_SPEED`, from rest; the yaw
//!   follows `MIS_YAW_MODE` as on a mission.
//!
//! Owns nothing but these methods of [`Guidance`].

use super::{trajectory_points, Guidance, Mode};
use crate::outer::path_yaw::Steering;
use crate::outer::CommandError;
use crate::tracking::Reference;
use crate::waypoint::Progress;
use crate::Vec3;

impl Guidance {
    /// Return on the trajectory: from `origin` (the vehicle) through `trail` (the breadcrumbs
    /// reversed, ending above home) at `speed` m/s (`RTL_SPEED`), from rest. Refused (the
    /// guidance then holds `origin`) when the trajectory cannot be built.
    pub fn start_return(&mut self, origin: Vec3, trail: &[Vec3], speed: f32) -> Result<(), CommandError> {
        self.reset_shift = None;
        self.path_yaw.reset();
        let built = trajectory_points(origin, trail, &mut self.point_waypoint)
            .and_then(|points| self.fly_points(&points, None, speed));
        self.mode = if built.is_ok() { Mode::Lent } else { Mode::Hold(origin) };
        built
    }

    /// The lent trajectory's next reference (see `trajectory_ref`: the clock waits for the
    /// vehicle `v`), `progress` updated; `steer`: the yaw follows `MIS_YAW_MODE`. `None` when
    /// the trajectory is not lent.
    pub fn lent_reference(
        &mut self,
        v: &Steering,
        progress: &mut Progress,
        steer: bool,
    ) -> Option<Reference> {
        if !(self.mode == Mode::Lent && self.flying_trajectory) {
            return None;
        }
        Some(self.trajectory_ref(v, progress, &Vec3::zeros(), steer))
    }

    /// While the trajectory is lent: its cruise speed (the tracking cascade's limit on the
    /// correction) and whether it has ended at its goal.
    pub fn lent_tracking(&self) -> Option<(f32, bool)> {
        (self.mode == Mode::Lent && self.flying_trajectory)
            .then(|| (self.traj_cruise, self.trajectory.is_done()))
    }

    /// The flight mode that borrowed the trajectory ended (or stopped flying to a position):
    /// hold `p` instead.
    pub fn release(&mut self, p: Vec3) {
        if self.mode == Mode::Lent {
            self.mode = Mode::Hold(p);
        }
    }
}
