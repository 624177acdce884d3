//! Every message the firmware sends, as one enum, and its encoding into a MAVLink v2 frame.

use crate::link::dialect::RC_CHANNELS_DATA;
use crate::link::dialect::{
    ATTITUDE_DATA, COMMAND_ACK_DATA, DEBUG_VECT_DATA, HEARTBEAT_DATA, HIL_ACTUATOR_CONTROLS_DATA,
    LOCAL_POSITION_NED_DATA, MISSION_ACK_DATA, MISSION_REQUEST_INT_DATA, NAMED_VALUE_FLOAT_DATA,
    NAMED_VALUE_INT_DATA, POSITION_TARGET_LOCAL_NED_DATA, STATUSTEXT_DATA,
};
#[allow(deprecated)]
// PING: deprecated by MAVLink for TIMESYNC, still sent by tools (PX4 answers it); MISSION_ITEM
use crate::link::dialect::{
    ATTITUDE_TARGET_DATA, BATTERY_STATUS_DATA, GLOBAL_POSITION_INT_DATA, HOME_POSITION_DATA,
    MESSAGE_INTERVAL_DATA, MISSION_CURRENT_DATA, MISSION_ITEM_DATA, MISSION_ITEM_REACHED_DATA, PING_DATA,
    SYSTEM_TIME_DATA,
};
use crate::link::dialect::{
    AUTOPILOT_VERSION_DATA, EXTENDED_SYS_STATE_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
    PARAM_VALUE_DATA, SYS_STATUS_DATA, TIMESYNC_DATA,
};
use mavlink_core::{MAVLinkV1MessageRaw, MAVLinkV2MessageRaw};

use crate::link::framing::FrameWriter;

/// A message to send.
#[allow(deprecated)] // PING, MISSION_ITEM
#[derive(Clone, Debug, PartialEq)]
pub enum Outbound {
    /// HEARTBEAT.
    Heartbeat(HEARTBEAT_DATA),
    /// RC_CHANNELS (the pilot input's channels).
    RcChannels(RC_CHANNELS_DATA),
    /// ATTITUDE.
    Attitude(ATTITUDE_DATA),
    /// LOCAL_POSITION_NED.
    LocalPositionNed(LOCAL_POSITION_NED_DATA),
    /// POSITION_TARGET_LOCAL_NED (outer-loop reference and filtered acceleration).
    PositionTargetLocalNed(POSITION_TARGET_LOCAL_NED_DATA),
    /// DEBUG_VECT (filter diagnostics, loop timing, link statistics).
    DebugVect(DEBUG_VECT_DATA),
    /// NAMED_VALUE_INT (flags, counters, PIL instruction counts).
    NamedValueInt(NAMED_VALUE_INT_DATA),
    /// NAMED_VALUE_FLOAT.
    NamedValueFloat(NAMED_VALUE_FLOAT_DATA),
    /// STATUSTEXT (failsafe transitions).
    StatusText(STATUSTEXT_DATA),
    /// COMMAND_ACK.
    CommandAck(COMMAND_ACK_DATA),
    /// MISSION_REQUEST_INT.
    MissionRequestInt(MISSION_REQUEST_INT_DATA),
    /// MISSION_ACK.
    MissionAck(MISSION_ACK_DATA),
    /// HIL_ACTUATOR_CONTROLS (lockstep answer).
    HilActuatorControls(HIL_ACTUATOR_CONTROLS_DATA),
    /// PARAM_VALUE (answer to PARAM_SET / PARAM_REQUEST_READ / PARAM_REQUEST_LIST).
    ParamValue(PARAM_VALUE_DATA),
    /// MISSION_COUNT (mission download).
    MissionCount(MISSION_COUNT_DATA),
    /// MISSION_ITEM_INT (mission download).
    MissionItemInt(MISSION_ITEM_INT_DATA),
    /// MISSION_ITEM (mission download answering the deprecated MISSION_REQUEST,
    /// [`crate::link::mission_float`]).
    MissionItem(MISSION_ITEM_DATA),
    /// SYS_STATUS.
    SysStatus(SYS_STATUS_DATA),
    /// EXTENDED_SYS_STATE (landed state).
    ExtendedSysState(EXTENDED_SYS_STATE_DATA),
    /// AUTOPILOT_VERSION (capabilities; on request).
    AutopilotVersion(AUTOPILOT_VERSION_DATA),
    /// TIMESYNC answer.
    Timesync(TIMESYNC_DATA),
    /// SYSTEM_TIME (see [`crate::link::services`]).
    SystemTime(SYSTEM_TIME_DATA),
    /// GLOBAL_POSITION_INT (local position around the fixed home).
    GlobalPositionInt(GLOBAL_POSITION_INT_DATA),
    /// MISSION_CURRENT.
    MissionCurrent(MISSION_CURRENT_DATA),
    /// HOME_POSITION.
    HomePosition(HOME_POSITION_DATA),
    /// PING answer.
    Ping(PING_DATA),
    /// MESSAGE_INTERVAL (answer to MAV_CMD_GET_MESSAGE_INTERVAL).
    MessageInterval(MESSAGE_INTERVAL_DATA),
    /// MISSION_ITEM_REACHED.
    MissionItemReached(MISSION_ITEM_REACHED_DATA),
    /// ATTITUDE_TARGET (attitude setpoint).
    AttitudeTarget(ATTITUDE_TARGET_DATA),
    /// BATTERY_STATUS.
    BatteryStatus(BATTERY_STATUS_DATA),
    /// STATUSTEXT framed in MAVLink **v1** (the answer to a v1 ground station,
    /// [`crate::link::v1`]).
    StatusTextV1(STATUSTEXT_DATA),
}

/// One encoded frame: MAVLink 2, or v1 for [`Outbound::StatusTextV1`].
#[allow(clippy::large_enum_variant)] // one frame at a time, on the sender's stack
pub enum Encoded {
    /// MAVLink 2.
    V2(MAVLinkV2MessageRaw),
    /// MAVLink 1.
    V1(MAVLinkV1MessageRaw),
}

impl Encoded {
    /// The frame's bytes (what goes on the wire).
    pub fn raw_bytes(&self) -> &[u8] {
        match self {
            Encoded::V2(r) => r.raw_bytes(),
            Encoded::V1(r) => r.raw_bytes(),
        }
    }
}

#[allow(deprecated)] // PING, MISSION_ITEM
impl Outbound {
    /// Encodes the message as the next frame of `writer`.
    pub fn encode(&self, writer: &mut FrameWriter) -> Encoded {
        Encoded::V2(match self {
            Outbound::StatusTextV1(m) => return Encoded::V1(writer.encode_v1(m)),
            Outbound::Heartbeat(m) => writer.encode(m),
            Outbound::RcChannels(m) => writer.encode(m),
            Outbound::Attitude(m) => writer.encode(m),
            Outbound::LocalPositionNed(m) => writer.encode(m),
            Outbound::PositionTargetLocalNed(m) => writer.encode(m),
            Outbound::DebugVect(m) => writer.encode(m),
            Outbound::NamedValueInt(m) => writer.encode(m),
            Outbound::NamedValueFloat(m) => writer.encode(m),
            Outbound::StatusText(m) => writer.encode(m),
            Outbound::CommandAck(m) => writer.encode(m),
            Outbound::MissionRequestInt(m) => writer.encode(m),
            Outbound::MissionAck(m) => writer.encode(m),
            Outbound::HilActuatorControls(m) => writer.encode(m),
            Outbound::ParamValue(m) => writer.encode(m),
            Outbound::MissionCount(m) => writer.encode(m),
            Outbound::MissionItemInt(m) => writer.encode(m),
            Outbound::MissionItem(m) => writer.encode(m),
            Outbound::SysStatus(m) => writer.encode(m),
            Outbound::ExtendedSysState(m) => writer.encode(m),
            Outbound::AutopilotVersion(m) => writer.encode(m),
            Outbound::Timesync(m) => writer.encode(m),
            Outbound::SystemTime(m) => writer.encode(m),
            Outbound::GlobalPositionInt(m) => writer.encode(m),
            Outbound::MissionCurrent(m) => writer.encode(m),
            Outbound::HomePosition(m) => writer.encode(m),
            Outbound::Ping(m) => writer.encode(m),
            Outbound::MessageInterval(m) => writer.encode(m),
            Outbound::MissionItemReached(m) => writer.encode(m),
            Outbound::AttitudeTarget(m) => writer.encode(m),
            Outbound::BatteryStatus(m) => writer.encode(m),
        })
    }
}

/// A NUL-padded MAVLink name field from `s` (truncated to `N` bytes).
pub fn name<const N: usize>(s: &str) -> mavlink_core::types::CharArray<N> {
    let mut b = [0u8; N];
    for (d, c) in b.iter_mut().zip(s.bytes()) {
        *d = c;
    }
    b.into()
}

/// NAMED_VALUE_INT helper.
pub fn named_int(time_boot_ms: u32, key: &str, value: i32) -> Outbound {
    Outbound::NamedValueInt(NAMED_VALUE_INT_DATA { time_boot_ms, value, name: name(key) })
}

/// DEBUG_VECT helper.
pub fn debug_vect(time_usec: u64, key: &str, x: f32, y: f32, z: f32) -> Outbound {
    Outbound::DebugVect(DEBUG_VECT_DATA { time_usec, x, y, z, name: name(key) })
}
