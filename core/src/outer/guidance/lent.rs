//! The guidance's one trajectory lent to the other flight modes that fly to a place (issue 35):
//! **Return** flies the breadcrumbs reversed and **Offboard** a position-only set-point on the
//! same jerk-limited generator as a mission ([`super::super::trajectory`]), with the `TRJ_*`
//! limits and the clock that waits for the vehicle, when `MIS_GUIDANCE` = 1. One trajectory
//! serves all three (the modes exclude each other; a second one would cost 3 KB of RAM and its
//! by-value copies in the firmware's boot): the guidance is in its `Lent` mode while another
//! flight mode flies it, and the mission's commands take it back by re-building it.
//!
//! * Return: [`Guidance::start_return`] from the vehicle through the trail (built by
//!   [`crate::outer::return_path::ReturnPath::trail_back`]) at `RTL_SPEED`, from rest; the yaw
//!   follows `MIS_YAW_MODE` as on a mission.
//! * Offboard: [`Guidance::offboard_position`] flies a straight trajectory from the last
//!   reference to the set-point at the mission speed, carrying the reference's motion over when
//!   it moves towards the set-point; re-generated when the set-point moves by more than
//!   [`OFFBOARD_RETARGET_M`] from the one flown (or by more than [`MIN_LEG_LENGTH`] once
//!   the trajectory has arrived). The yaw is the set-point's.
//!
//! Owns nothing but these methods of [`Guidance`] and [`OFFBOARD_RETARGET_M`].

use super::{trajectory_points, Guidance, Mode, MIN_LEG_LENGTH};
use crate::fmath::norm3;
use crate::outer::path_yaw::Steering;
use crate::outer::CommandError;
use crate::tracking::Reference;
use crate::waypoint::Progress;
use crate::Vec3;

/// An offboard position set-point that moves by more than this (m) from the one flown
/// re-generates the trajectory to it (a companion streaming a slowly moving target is followed
/// in steps of at most this; the trajectory's goal is within it of the set-point).
pub const OFFBOARD_RETARGET_M: f32 = 0.05;

impl Guidance {
    /// Return on the trajectory: from `origin` (the vehicle) through `trail` (the breadcrumbs
    /// reversed, ending above home) at `speed` m/s (`RTL_SPEED`), from rest. Refused (the
    /// guidance then holds `origin`) when the trajectory cannot be built.
    pub fn start_return(&mut self, origin: Vec3, trail: &[Vec3], speed: f32) -> Result<(), CommandError> {
        self.offboard_target = None;
        self.reset_shift = None;
        self.path_yaw.reset();
        let built = trajectory_points(origin, trail, &mut self.point_waypoint)
            .and_then(|points| self.fly_points(&points, None, speed));
        self.mode = if built.is_ok() { Mode::Lent } else { Mode::Hold(origin) };
        built
    }

    /// Offboard position-only set-point `target`: fly to it on a straight trajectory from
    /// `reference` (the last reference flown) at the mission speed, unless the trajectory
    /// being flown already goes there (see the module documentation). On an error (a target
    /// the trajectory refuses) the guidance holds the reference and nothing is lent.
    pub fn offboard_position(&mut self, target: Vec3, reference: &Reference) -> Result<(), CommandError> {
        if let (Mode::Lent, true, Some(t)) = (self.mode, self.flying_trajectory, self.offboard_target) {
            let moved = norm3(&(target - t));
            let bound = if self.trajectory.is_done() { MIN_LEG_LENGTH } else { OFFBOARD_RETARGET_M };
            if moved <= bound {
                return Ok(());
            }
        }
        self.reset_shift = None;
        self.path_yaw.reset();
        let speed = self.mission_speed();
        let built = trajectory_points(reference.position, &[target], &mut self.point_waypoint)
            .and_then(|points| self.fly_points(&points, Some(*reference), speed));
        self.offboard_target = built.is_ok().then_some(target);
        self.mode = if built.is_ok() { Mode::Lent } else { Mode::Hold(reference.position) };
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
        self.offboard_target = None;
    }
}
