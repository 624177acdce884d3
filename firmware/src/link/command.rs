//! COMMAND_LONG → [`VehicleCommand`] and the COMMAND_ACK answer.
//!
//! | MAV_CMD | params | action |
//! |---|---|---|
//! | COMPONENT_ARM_DISARM (400) | p1 = 1 arm, 0 disarm; p2 = 21196 force | arm / disarm |
//! | NAV_TAKEOFF (22) | p7 = height above home, m (positive up; NaN/0: default 1 m; above the cascade's limit, 120 m: DENIED with a STATUSTEXT) | take off |
//! | NAV_LAND (21) | – | land in place |
//! | MISSION_START (300) | – | fly the uploaded path |
//! | OVERRIDE_GOTO (252) | p1 = 0 (hold); p2 = 2 current position, or 3 with p3 = 1 (LOCAL_NED) and p5, p6, p7 = x, y, z NED m | hold a position |
//! | DO_SET_MODE (176) | p1 = base mode with MAV_MODE_FLAG_CUSTOM_MODE_ENABLED (1); p2/p3 = PX4 main/sub mode (`FlightMode::from_px4`: 1 Manual, 2/3 Position, 4/0 and 4/4 Mission, 4/3 Hold, 4/5 Return, 4/6 Land, 6 Offboard, 7 Manual). Without the custom flag, the base mode alone as PX4's Commander reads it ([`base_mode_px4`]: AUTO → Mission; MANUAL_INPUT with GUIDED → Position, else Manual): MAVProxy's `mode 4` | `VehicleCommand::SetMode` (TEMPORARILY_REJECTED when the mode cannot be flown now); unknown modes: DENIED |
//! | DO_SET_STANDARD_MODE (262) | p1 = MAV_STANDARD_MODE (`FlightMode::from_standard_mode`: POSITION_HOLD → Position, MISSION → Mission, SAFE_RECOVERY → Return, LAND → Land) | `VehicleCommand::SetMode` as DO_SET_MODE; NON_STANDARD and the standard modes not flown: DENIED |
//!
//! Anything else is answered MAV_RESULT_UNSUPPORTED. Commands addressed to another system or
//! component are ignored (no answer); target 0 is broadcast. The COMMAND_ACK is addressed to the
//! sender (`target_system`/`target_component` = the command frame's system/component id).
//!
//! COMMAND_INT is answered exactly like COMMAND_LONG ([`command_long_of_int`]): param1..4 as
//! they are, param5/param6 = `x`/`y` (local frames: metres × 10⁴ → metres; other frames:
//! the integer as a float), param7 = `z`.

use crate::link::dialect::{MavFrame, MavResult, COMMAND_ACK_DATA, COMMAND_INT_DATA, COMMAND_LONG_DATA};

use crate::app::autopilot::{Autopilot, CommandRejected, FlightMode, VehicleCommand};

/// COMPONENT_ARM_DISARM param2 value that forces a disarm in flight.
pub use parapet_core::wire::ids::FORCE_DISARM_MAGIC;

/// Command ids as the raw `u16` of the `command` fields (see [`crate::link::dialect`]: every id
/// decodes, an unknown one is answered UNSUPPORTED with its own id).
pub mod id {
    use crate::link::dialect::MavCmd;
    /// MAV_CMD_COMPONENT_ARM_DISARM.
    pub const ARM_DISARM: u16 = MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16;
    /// MAV_CMD_NAV_TAKEOFF.
    pub const TAKEOFF: u16 = MavCmd::MAV_CMD_NAV_TAKEOFF as u16;
    /// MAV_CMD_NAV_LAND.
    pub const LAND: u16 = MavCmd::MAV_CMD_NAV_LAND as u16;
    /// MAV_CMD_NAV_WAYPOINT (mission items).
    pub const WAYPOINT: u16 = MavCmd::MAV_CMD_NAV_WAYPOINT as u16;
    /// MAV_CMD_DO_SET_MODE.
    pub const DO_SET_MODE: u16 = MavCmd::MAV_CMD_DO_SET_MODE as u16;
    /// MAV_CMD_DO_SET_STANDARD_MODE.
    pub const DO_SET_STANDARD_MODE: u16 = MavCmd::MAV_CMD_DO_SET_STANDARD_MODE as u16;
    /// MAV_CMD_MISSION_START.
    pub const MISSION_START: u16 = MavCmd::MAV_CMD_MISSION_START as u16;
    /// MAV_CMD_OVERRIDE_GOTO.
    pub const OVERRIDE_GOTO: u16 = MavCmd::MAV_CMD_OVERRIDE_GOTO as u16;
    /// MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES.
    #[allow(deprecated)] // still sent by ground stations
    pub const REQUEST_AUTOPILOT_CAPABILITIES: u16 = MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES as u16;
    /// MAV_CMD_REQUEST_MESSAGE.
    pub const REQUEST_MESSAGE: u16 = MavCmd::MAV_CMD_REQUEST_MESSAGE as u16;
    /// MAV_CMD_GET_MESSAGE_INTERVAL.
    #[allow(deprecated)] // still sent by ground stations
    pub const GET_MESSAGE_INTERVAL: u16 = MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL as u16;
    /// MAV_CMD_SET_MESSAGE_INTERVAL.
    pub const SET_MESSAGE_INTERVAL: u16 = MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL as u16;
    /// MAV_CMD_GET_HOME_POSITION.
    #[allow(deprecated)] // still sent by ground stations
    pub const GET_HOME_POSITION: u16 = MavCmd::MAV_CMD_GET_HOME_POSITION as u16;
    /// MAV_CMD_DO_REPOSITION.
    pub const DO_REPOSITION: u16 = MavCmd::MAV_CMD_DO_REPOSITION as u16;
    /// MAV_CMD_DO_SET_HOME.
    pub const DO_SET_HOME: u16 = MavCmd::MAV_CMD_DO_SET_HOME as u16;
    /// MAV_CMD_REQUEST_PROTOCOL_VERSION.
    #[allow(deprecated)] // still sent by ground stations
    pub const REQUEST_PROTOCOL_VERSION: u16 = MavCmd::MAV_CMD_REQUEST_PROTOCOL_VERSION as u16;
}

/// The PX4 main/sub mode of a DO_SET_MODE base mode without MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
/// as PX4's Commander reads it ("use base mode"): AUTO_ENABLED (4) → AUTO (Mission);
/// MANUAL_INPUT_ENABLED (64) with GUIDED_ENABLED (8) → POSCTL, with STABILIZE_ENABLED (16) →
/// STABILIZED, alone → MANUAL; anything else none. MAVProxy 1.8.75 sends it for `mode N`
/// (pymavlink's `set_mode_px4(N, 0, 0)`).
pub fn base_mode_px4(base: u8) -> Option<(u8, u8)> {
    if base & 4 != 0 {
        Some((4, 0))
    } else if base & 64 != 0 {
        Some(if base & 8 != 0 {
            (3, 0)
        } else if base & 16 != 0 {
            (7, 0)
        } else {
            (1, 0)
        })
    } else {
        None
    }
}

/// Decodes a COMMAND_LONG; `Err` holds the result to report without executing.
pub fn decode_command(cmd: &COMMAND_LONG_DATA) -> Result<VehicleCommand, MavResult> {
    match cmd.command {
        id::ARM_DISARM => {
            if cmd.param1 == 1.0 {
                Ok(VehicleCommand::Arm)
            } else if cmd.param1 == 0.0 {
                Ok(VehicleCommand::Disarm { force: cmd.param2 == FORCE_DISARM_MAGIC })
            } else {
                Err(MavResult::MAV_RESULT_DENIED)
            }
        }
        id::TAKEOFF => {
            let h = cmd.param7;
            if h.is_nan() || h == 0.0 {
                Ok(VehicleCommand::Takeoff { height_m: None })
            } else if h > 0.0 && h.is_finite() {
                // The limit is the cascade's (crate::link::takeoff_limit).
                Ok(VehicleCommand::Takeoff { height_m: Some(h) })
            } else {
                Err(MavResult::MAV_RESULT_DENIED)
            }
        }
        id::LAND => Ok(VehicleCommand::Land),
        id::DO_SET_MODE => {
            // p1 = MAV_MODE base flags, must carry CUSTOM_MODE_ENABLED (1); p2/p3 = PX4's main /
            // sub mode (the HEARTBEAT's `custom_mode`, autopilot PX4), as pymavlink/MAVProxy,
            // MAVSDK and QGroundControl send them. (Before the HEARTBEAT said PX4, p2 = 3/4/5
            // with p3 = 0 meant the flight phases hover/mission/landing; that collided with PX4's
            // POSCTL (3/0), AUTO (4/0) and ACRO (5/0) and is gone.)
            // Without CUSTOM_MODE_ENABLED: the base mode alone, as PX4 (MAVProxy's `mode 4`).
            let whole = |x: f32| (0.0..=255.0).contains(&x) && f32::from(x as u8) == x;
            let main_sub = match whole(cmd.param1).then_some(cmd.param1 as u8) {
                Some(base) if base & 1 == 1 => {
                    (whole(cmd.param2) && whole(cmd.param3)).then_some((cmd.param2 as u8, cmd.param3 as u8))
                }
                Some(base) => base_mode_px4(base),
                None => None,
            };
            main_sub
                .and_then(|(main, sub)| FlightMode::from_px4(main, sub))
                .map(VehicleCommand::SetMode)
                .ok_or(MavResult::MAV_RESULT_DENIED)
        }
        id::DO_SET_STANDARD_MODE => {
            // p1 = MAV_STANDARD_MODE (`FlightMode::from_standard_mode`: POSITION_HOLD, MISSION,
            // SAFE_RECOVERY, LAND); the others (and NON_STANDARD) are not flown: DENIED.
            let whole = (0.0..=255.0).contains(&cmd.param1) && f32::from(cmd.param1 as u8) == cmd.param1;
            whole
                .then(|| FlightMode::from_standard_mode(cmd.param1 as u8))
                .flatten()
                .map(VehicleCommand::SetMode)
                .ok_or(MavResult::MAV_RESULT_DENIED)
        }
        id::MISSION_START => Ok(VehicleCommand::StartMission),
        id::OVERRIDE_GOTO => {
            // p1 MAV_GOTO_DO_HOLD (0); p2 HOLD_AT_CURRENT_POSITION (2) or
            // HOLD_AT_SPECIFIED_POSITION (3) with p3 = MAV_FRAME_LOCAL_NED (1), p5..p7 = x, y, z.
            if cmd.param1 != 0.0 {
                return Err(MavResult::MAV_RESULT_DENIED);
            }
            if cmd.param2 == 2.0 {
                return Ok(VehicleCommand::Hold { target_ned: None });
            }
            let p = parapet_core::Vec3::new(cmd.param5, cmd.param6, cmd.param7);
            if cmd.param2 == 3.0 && cmd.param3 == 1.0 && p.iter().all(|x| x.is_finite()) {
                Ok(VehicleCommand::Hold { target_ned: Some(p) })
            } else {
                Err(MavResult::MAV_RESULT_DENIED)
            }
        }
        _ => Err(MavResult::MAV_RESULT_UNSUPPORTED),
    }
}

/// COMMAND_INT as the equivalent COMMAND_LONG (see the module docs).
pub fn command_long_of_int(c: &COMMAND_INT_DATA) -> COMMAND_LONG_DATA {
    let local = matches!(
        c.frame,
        MavFrame::MAV_FRAME_LOCAL_NED | MavFrame::MAV_FRAME_LOCAL_OFFSET_NED | MavFrame::MAV_FRAME_LOCAL_ENU
    );
    let xy = |v: i32| if local { parapet_core::wire::ids::local_xy_from_wire(v) } else { v as f32 };
    let p = [c.param1, c.param2, c.param3, c.param4, xy(c.x), xy(c.y), c.z];
    command_long(c.command, p, (c.target_system, c.target_component))
}

/// COMMAND_LONG `command` with param1..param7 = `p`, for `target` (system, component id).
pub fn command_long(command: u16, p: [f32; 7], target: (u8, u8)) -> COMMAND_LONG_DATA {
    COMMAND_LONG_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        param5: p[4],
        param6: p[5],
        param7: p[6],
        command,
        target_system: target.0,
        target_component: target.1,
        confirmation: 0,
    }
}

/// `true` when a message with `target_system`/`target_component` is for this vehicle's
/// autopilot (`own`): each is 0 (broadcast) or ours.
pub fn addressed_to(target_system: u8, target_component: u8, own: (u8, u8)) -> bool {
    (target_system == 0 || target_system == own.0) && (target_component == 0 || target_component == own.1)
}

/// COMMAND_ACK for `command` with `result`, addressed to `sender` (system, component).
pub fn ack(command: u16, result: MavResult, sender: (u8, u8)) -> COMMAND_ACK_DATA {
    COMMAND_ACK_DATA {
        command,
        result,
        target_system: sender.0,
        target_component: sender.1,
        ..Default::default()
    }
}

/// Executes a vehicle command (already checked to be for us) and gives the MAV_RESULT.
pub fn execute<A: Autopilot>(cmd: &COMMAND_LONG_DATA, now_us: u64, autopilot: &mut A) -> MavResult {
    match decode_command(cmd) {
        Ok(vc) => result_of(autopilot.command(now_us, vc)),
        Err(r) => r,
    }
}

/// The COMMAND_ACK result of the cascade's answer to a command.
pub fn result_of(r: Result<(), CommandRejected>) -> MavResult {
    match r {
        Ok(()) => MavResult::MAV_RESULT_ACCEPTED,
        Err(CommandRejected::NotNow) => MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
        Err(CommandRejected::Invalid) => MavResult::MAV_RESULT_DENIED,
    }
}

/// Handles a COMMAND_LONG from `sender` addressed to `own` (system, component): executes it and
/// returns the COMMAND_ACK addressed to the sender, or `None` when the command is for another
/// system or component.
pub fn handle_command<A: Autopilot>(
    cmd: &COMMAND_LONG_DATA,
    own: (u8, u8),
    sender: (u8, u8),
    now_us: u64,
    autopilot: &mut A,
) -> Option<COMMAND_ACK_DATA> {
    if !addressed_to(cmd.target_system, cmd.target_component, own) {
        return None;
    }
    Some(ack(cmd.command, execute(cmd, now_us, autopilot), sender))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;
    use crate::link::dialect::MavCmd;

    fn cmd(command: MavCmd, p1: f32, p2: f32, p7: f32) -> COMMAND_LONG_DATA {
        COMMAND_LONG_DATA {
            param1: p1,
            param2: p2,
            param7: p7,
            command: command as u16,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }
    }

    #[test]
    fn decodes_the_supported_commands() {
        use MavCmd::*;
        assert_eq!(
            decode_command(&cmd(MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0, 0.0)),
            Ok(VehicleCommand::Arm)
        );
        assert_eq!(
            decode_command(&cmd(MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 21196.0, 0.0)),
            Ok(VehicleCommand::Disarm { force: true })
        );
        assert_eq!(
            decode_command(&cmd(MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 0.0, 0.0)),
            Ok(VehicleCommand::Disarm { force: false })
        );
        assert_eq!(
            decode_command(&cmd(MAV_CMD_COMPONENT_ARM_DISARM, 0.5, 0.0, 0.0)),
            Err(MavResult::MAV_RESULT_DENIED)
        );
        assert_eq!(
            decode_command(&cmd(MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 1.5)),
            Ok(VehicleCommand::Takeoff { height_m: Some(1.5) })
        );
        assert_eq!(
            decode_command(&cmd(MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, f32::NAN)),
            Ok(VehicleCommand::Takeoff { height_m: None })
        );
        assert_eq!(
            decode_command(&cmd(MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, -2.0)),
            Err(MavResult::MAV_RESULT_DENIED)
        );
        assert_eq!(
            decode_command(&cmd(MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, f32::INFINITY)),
            Err(MavResult::MAV_RESULT_DENIED)
        );
        assert_eq!(decode_command(&cmd(MAV_CMD_NAV_LAND, 0.0, 0.0, 0.0)), Ok(VehicleCommand::Land));
        assert_eq!(
            decode_command(&cmd(MAV_CMD_MISSION_START, 0.0, 0.0, 0.0)),
            Ok(VehicleCommand::StartMission)
        );
        assert_eq!(
            decode_command(&cmd(MAV_CMD_DO_SET_MODE, 0.0, 0.0, 0.0)),
            Err(MavResult::MAV_RESULT_DENIED)
        );
        // PX4 main/sub modes (p2/p3) select flight modes, as the HEARTBEAT (autopilot PX4)
        // reports them; 3/0 is POSCTL (was the legacy hover code, a hold: MAVProxy's `mode
        // POSCTL` held instead).
        let mode = |main: f32, sub: f32| {
            let mut c = cmd(MAV_CMD_DO_SET_MODE, 1.0, main, 0.0);
            c.param3 = sub;
            decode_command(&c)
        };
        assert_eq!(mode(6.0, 0.0), Ok(VehicleCommand::SetMode(FlightMode::Offboard)));
        assert_eq!(mode(1.0, 0.0), Ok(VehicleCommand::SetMode(FlightMode::Manual)));
        assert_eq!(mode(2.0, 0.0), Ok(VehicleCommand::SetMode(FlightMode::Position)));
        assert_eq!(mode(3.0, 0.0), Ok(VehicleCommand::SetMode(FlightMode::Position)));
        assert_eq!(mode(4.0, 3.0), Ok(VehicleCommand::SetMode(FlightMode::Hold)));
        assert_eq!(mode(4.0, 4.0), Ok(VehicleCommand::SetMode(FlightMode::Mission)));
        assert_eq!(mode(4.0, 5.0), Ok(VehicleCommand::SetMode(FlightMode::Return)));
        assert_eq!(mode(4.0, 6.0), Ok(VehicleCommand::SetMode(FlightMode::Land)));
        assert_eq!(mode(5.0, 0.0), Err(MavResult::MAV_RESULT_DENIED), "ACRO (was the legacy landing)");
        assert_eq!(mode(9.0, 0.0), Err(MavResult::MAV_RESULT_DENIED));
        assert_eq!(mode(f32::NAN, 0.0), Err(MavResult::MAV_RESULT_DENIED));
        assert_eq!(mode(4.0, 0.0), Ok(VehicleCommand::SetMode(FlightMode::Mission)));
        // Without the custom flag, the base mode alone as PX4's Commander reads it (MAVProxy's
        // `mode 4` sends DO_SET_MODE 4/0/0; was DENIED): AUTO → Mission, MANUAL_INPUT + GUIDED
        // → Position, MANUAL_INPUT (+ STABILIZE) → Manual; no mode bit, 1.5, NaN → DENIED.
        let base = |b: f32| decode_command(&cmd(MAV_CMD_DO_SET_MODE, b, 0.0, 0.0));
        assert_eq!(base(4.0), Ok(VehicleCommand::SetMode(FlightMode::Mission)));
        assert_eq!(base(4.0 + 128.0), Ok(VehicleCommand::SetMode(FlightMode::Mission)));
        assert_eq!(base(64.0 + 8.0), Ok(VehicleCommand::SetMode(FlightMode::Position)));
        assert_eq!(base(64.0 + 16.0), Ok(VehicleCommand::SetMode(FlightMode::Manual)));
        assert_eq!(base(64.0), Ok(VehicleCommand::SetMode(FlightMode::Manual)));
        for b in [0.0, 8.0, 16.0, 128.0, 1.5, f32::NAN, 300.0] {
            assert_eq!(base(b), Err(MavResult::MAV_RESULT_DENIED), "base mode {b}");
        }
        assert_eq!(
            decode_command(&cmd(MAV_CMD_DO_SET_SERVO, 0.0, 0.0, 0.0)),
            Err(MavResult::MAV_RESULT_UNSUPPORTED)
        );
        let mut goto = cmd(MAV_CMD_OVERRIDE_GOTO, 0.0, 3.0, -1.5);
        goto.param3 = 1.0;
        goto.param5 = 1.0;
        goto.param6 = 2.0;
        assert_eq!(
            decode_command(&goto),
            Ok(VehicleCommand::Hold { target_ned: Some(parapet_core::Vec3::new(1.0, 2.0, -1.5)) })
        );
        goto.param3 = 0.0; // global frame: refused
        assert_eq!(decode_command(&goto), Err(MavResult::MAV_RESULT_DENIED));
        assert_eq!(
            decode_command(&cmd(MAV_CMD_OVERRIDE_GOTO, 0.0, 2.0, 0.0)),
            Ok(VehicleCommand::Hold { target_ned: None })
        );
    }

    #[test]
    fn acks_reflect_the_autopilot_answer_and_other_systems_are_ignored() {
        let mut ap = RecordingAutopilot::new();
        let ack =
            handle_command(&cmd(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 1.0), (1, 1), (255, 190), 0, &mut ap);
        assert_eq!(ack.map(|a| a.result), Some(MavResult::MAV_RESULT_TEMPORARILY_REJECTED));
        let ack = handle_command(
            &cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0, 0.0),
            (1, 1),
            (255, 190),
            0,
            &mut ap,
        );
        assert_eq!(ack.map(|a| a.result), Some(MavResult::MAV_RESULT_ACCEPTED));
        assert!(ap.armed);
        let mut other = cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 0.0, 0.0);
        other.target_system = 7;
        assert_eq!(handle_command(&other, (1, 1), (255, 190), 0, &mut ap), None);
        assert!(ap.armed);
        other.target_system = 0;
        assert!(handle_command(&other, (1, 1), (255, 190), 0, &mut ap).is_some());
        assert!(!ap.armed);
    }
}
