//! What a mission item makes the vehicle do besides flying to its position: the holds, delays,
//! yaw and speed changes of a QGroundControl plan ([`Action`]), checked at upload
//! ([`check`]) and run by [`crate::link::mission_run`].
//!
//! | item | params used | action |
//! |---|---|---|
//! | NAV_WAYPOINT (16) | p1 hold s (≥ 0), p2 acceptance radius m (≥ 0) | p1 > 0: after the waypoint, once within p2 of it (0: when the reference arrived), hold p1 s |
//! | NAV_LOITER_UNLIM (17) | position (0, 0: here) | hold there until another mode is selected or a new plan is uploaded |
//! | NAV_LOITER_TIME (19) | p1 s (≥ 0), position (0, 0: here) | hold there p1 s |
//! | NAV_DELAY (93) | p1 s (≥ 0; −1 with a time of day: refused, the vehicle has no clock of day) | hold where the vehicle is p1 s |
//! | CONDITION_YAW (115) | p1 deg, p3 direction (−1 ccw, 1 cw, 0 shortest; relative only), p4 0 absolute / 1 relative | face the heading, then go on once within [`YAW_REACHED_DEG`] (or after [`YAW_TIMEOUT_US`]) |
//! | DO_CHANGE_SPEED (178) | p2 speed m/s (−1, 0, NaN: unchanged) | the path speed of the following legs, capped at the vehicle's limit (`VehicleCommand::SetSpeed`) |
//!
//! Refusals at upload (MISSION_ACK): a negative or non-finite hold, delay or radius →
//! INVALID_PARAM1 / INVALID_PARAM2; a non-finite yaw angle → INVALID_PARAM1.
//!
//! May import: the dialect and [`crate::link::command::id`]. O(1) per item.

use crate::link::dialect::{MavCmd, MavMissionResult};

/// MAV_CMD_NAV_LOITER_UNLIM.
pub const LOITER_UNLIM: u16 = MavCmd::MAV_CMD_NAV_LOITER_UNLIM as u16;
/// MAV_CMD_NAV_LOITER_TIME.
pub const LOITER_TIME: u16 = MavCmd::MAV_CMD_NAV_LOITER_TIME as u16;
/// MAV_CMD_NAV_DELAY.
pub const DELAY: u16 = MavCmd::MAV_CMD_NAV_DELAY as u16;
/// MAV_CMD_CONDITION_YAW.
pub const CONDITION_YAW: u16 = MavCmd::MAV_CMD_CONDITION_YAW as u16;
/// MAV_CMD_DO_CHANGE_SPEED.
pub const CHANGE_SPEED: u16 = MavCmd::MAV_CMD_DO_CHANGE_SPEED as u16;

/// A CONDITION_YAW is done when the heading is within this of its target, deg (PX4's
/// `MIS_YAW_ERR` default 12°).
pub const YAW_REACHED_DEG: f32 = 12.0;
/// A CONDITION_YAW not reached after this goes on anyway, µs (the mission never stalls on a
/// heading the vehicle cannot take).
pub const YAW_TIMEOUT_US: u64 = 30_000_000;

/// What an item does after its position (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Hold the position `secs` s (`None`: until another mode or plan), the timer starting once
    /// within `radius_m` of the item's point (0: at once).
    Hold {
        /// Hold time, s; `None` = unlimited.
        secs: Option<f32>,
        /// Acceptance radius, m (0: the reference's arrival is enough).
        radius_m: f32,
    },
    /// Face a heading.
    Yaw {
        /// Angle, deg.
        deg: f32,
        /// Direction of a relative turn: −1 ccw, 1 cw (0: as the sign of `deg`).
        dir: f32,
        /// `deg` is relative to the current heading.
        relative: bool,
    },
    /// Path speed of the following legs, m/s (`None`: unchanged).
    Speed(Option<f32>),
}

/// `true` for the items of this module that occupy the vehicle without a path point of their
/// own when their position is (0, 0) or they have none (delay, yaw, loiter here).
pub fn is_pause(command: u16) -> bool {
    matches!(command, LOITER_UNLIM | LOITER_TIME | DELAY | CONDITION_YAW)
}

fn non_negative(v: f32, refusal: MavMissionResult) -> Result<f32, MavMissionResult> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(refusal)
    }
}

/// The item's action (`Ok(None)`: none), or the upload refusal of its parameters.
pub fn check(command: u16, p: [f32; 4]) -> Result<Option<Action>, MavMissionResult> {
    use MavMissionResult::{MAV_MISSION_INVALID_PARAM1 as P1, MAV_MISSION_INVALID_PARAM2 as P2};
    let hold = |secs, radius_m| Ok(Some(Action::Hold { secs, radius_m }));
    match command {
        crate::link::command::id::WAYPOINT => {
            let secs = non_negative(p[0], P1)?;
            let radius = non_negative(p[1], P2)?;
            if secs > 0.0 {
                hold(Some(secs), radius)
            } else {
                Ok(None)
            }
        }
        LOITER_UNLIM => hold(None, 0.0),
        LOITER_TIME | DELAY => hold(Some(non_negative(p[0], P1)?), 0.0),
        CONDITION_YAW if p[0].is_finite() => {
            Ok(Some(Action::Yaw { deg: p[0], dir: p[2], relative: p[3] == 1.0 }))
        }
        CONDITION_YAW => Err(P1),
        CHANGE_SPEED => {
            let v = p[1];
            Ok(Some(Action::Speed((v.is_finite() && v > 0.0).then_some(v))))
        }
        _ => Ok(None),
    }
}

/// The heading a yaw action targets from `current` (rad), rad.
pub fn yaw_target(deg: f32, dir: f32, relative: bool, current: f32) -> f32 {
    let a = deg.to_radians();
    if !relative {
        return a;
    }
    let turn = if dir < 0.0 {
        -a.abs()
    } else if dir > 0.0 {
        a.abs()
    } else {
        a
    };
    parapet_core::frame::wrap_pi(current + turn)
}

/// `true` when `yaw` is within [`YAW_REACHED_DEG`] of `target` (rad).
pub fn yaw_reached(yaw: f32, target: f32) -> bool {
    parapet_core::frame::wrap_pi(yaw - target).abs() <= YAW_REACHED_DEG.to_radians()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::command::id::WAYPOINT;

    #[test]
    fn actions_of_the_items_and_refusals() {
        assert_eq!(check(WAYPOINT, [0.0, 0.0, 0.0, f32::NAN]), Ok(None));
        assert_eq!(
            check(WAYPOINT, [3.0, 0.4, 0.0, f32::NAN]),
            Ok(Some(Action::Hold { secs: Some(3.0), radius_m: 0.4 }))
        );
        assert_eq!(check(WAYPOINT, [-1.0, 0.0, 0.0, 0.0]), Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1));
        assert_eq!(
            check(WAYPOINT, [1.0, f32::NAN, 0.0, 0.0]),
            Err(MavMissionResult::MAV_MISSION_INVALID_PARAM2)
        );
        assert_eq!(check(LOITER_UNLIM, [0.0; 4]), Ok(Some(Action::Hold { secs: None, radius_m: 0.0 })));
        assert_eq!(
            check(LOITER_TIME, [2.5, 0.0, 0.0, 0.0]),
            Ok(Some(Action::Hold { secs: Some(2.5), radius_m: 0.0 }))
        );
        assert_eq!(check(DELAY, [-1.0, 12.0, 0.0, 0.0]), Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1));
        assert_eq!(
            check(CONDITION_YAW, [90.0, 10.0, 1.0, 1.0]),
            Ok(Some(Action::Yaw { deg: 90.0, dir: 1.0, relative: true }))
        );
        assert_eq!(
            check(CONDITION_YAW, [f32::NAN, 0.0, 0.0, 0.0]),
            Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1)
        );
        assert_eq!(check(CHANGE_SPEED, [1.0, 0.4, -1.0, 0.0]), Ok(Some(Action::Speed(Some(0.4)))));
        assert_eq!(check(CHANGE_SPEED, [1.0, -1.0, -1.0, 0.0]), Ok(Some(Action::Speed(None))));
        assert_eq!(check(205, [0.0; 4]), Ok(None));
    }

    #[test]
    fn yaw_targets() {
        use core::f32::consts::FRAC_PI_2;
        assert!((yaw_target(90.0, 0.0, false, 1.0) - FRAC_PI_2).abs() < 1e-6);
        assert!((yaw_target(90.0, -1.0, true, 0.0) + FRAC_PI_2).abs() < 1e-6);
        assert!((yaw_target(90.0, 1.0, true, 0.0) - FRAC_PI_2).abs() < 1e-6);
        assert!(yaw_reached(0.1, 0.0) && !yaw_reached(0.5, 0.0));
        assert!(yaw_reached(3.1, -3.1), "across ±π");
    }
}
