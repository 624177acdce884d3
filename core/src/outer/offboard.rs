//! Offboard setpoints (issue 21): what a companion computer commands through MAVLink
//! `SET_POSITION_TARGET_LOCAL_NED` (the firmware's `link::offboard` decodes its `type_mask`
//! into the `Option` fields), and the reference the outer loop flies from them. Every
//! setpoint goes through the PD tracker and the safety filter like the mission's reference.
//!
//! * position given: the reference is that point, with the given velocity and acceleration
//!   as feed-forward (zero when absent);
//! * velocity given (no position): the leashed velocity reference of [`super::assist`];
//! * acceleration only: the acceleration is the nominal command `u*` itself (the PD law is
//!   bypassed), filtered.
//!
//! Bad setpoints (a NaN/Inf or beyond ±[`crate::cbf::INPUT_LIMIT`] in a given field, or no
//! position, velocity or acceleration at all) are rejected and counted; they do not refresh
//! the setpoint timeout, so a stream of bad setpoints ends in Hold.
//!
//! May import: the crate root foundation and [`crate::safety`] (the input limit).

use crate::cbf::INPUT_LIMIT;
use crate::Vec3;

/// One offboard setpoint (world NED, SI, controller clock). A `Copy` message.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct OffboardSetpoint {
    /// Time the setpoint was received, µs.
    pub t_us: u64,
    /// Position target, m.
    pub position: Option<Vec3>,
    /// Velocity target (feed-forward with a position), m/s.
    pub velocity: Option<Vec3>,
    /// Acceleration target (feed-forward with a position or velocity), m/s².
    pub acceleration: Option<Vec3>,
    /// Yaw target, rad.
    pub yaw: Option<f32>,
    /// Yaw rate target (used when no yaw is given), rad/s.
    pub yaw_rate: Option<f32>,
}

fn ok3(v: &Option<Vec3>) -> bool {
    v.is_none_or(|v| v.iter().all(|x| x.is_finite() && x.abs() <= INPUT_LIMIT))
}

fn ok1(v: Option<f32>, limit: f32) -> bool {
    v.is_none_or(|x| x.is_finite() && x.abs() <= limit)
}

impl OffboardSetpoint {
    /// `true` when every given field is finite and in range and at least one of position,
    /// velocity and acceleration is given.
    pub fn is_valid(&self) -> bool {
        (self.position.is_some() || self.velocity.is_some() || self.acceleration.is_some())
            && ok3(&self.position)
            && ok3(&self.velocity)
            && ok3(&self.acceleration)
            && ok1(self.yaw, 100.0)
            && ok1(self.yaw_rate, 100.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn setpoints_need_a_finite_target() {
        let v = Vec3::new(1.0, 0.0, 0.0);
        assert!(OffboardSetpoint { velocity: Some(v), ..Default::default() }.is_valid());
        assert!(!OffboardSetpoint::default().is_valid(), "nothing to fly");
        assert!(!OffboardSetpoint { velocity: Some(Vec3::new(f32::NAN, 0.0, 0.0)), ..Default::default() }
            .is_valid());
        assert!(
            !OffboardSetpoint { position: Some(Vec3::new(2e5, 0.0, 0.0)), ..Default::default() }.is_valid()
        );
        assert!(!OffboardSetpoint { acceleration: Some(v), yaw: Some(f32::INFINITY), ..Default::default() }
            .is_valid());
    }
}
