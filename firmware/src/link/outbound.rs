//! Every message the firmware sends, as one enum, and its encoding into a MAVLink v2 frame.

use crate::link::dialect::RC_CHANNELS_DATA;
use crate::link::dialect::{HilActuatorControlsFlags, MavModeFlag, MavProtocolCapability};
use crate::link::dialect::{
    ATTITUDE_DATA, COMMAND_ACK_DATA, DEBUG_VECT_DATA, HEARTBEAT_DATA, HIL_ACTUATOR_CONTROLS_DATA,
    LOCAL_POSITION_NED_DATA, MISSION_ACK_DATA, MISSION_REQUEST_INT_DATA, NAMED_VALUE_FLOAT_DATA,
    NAMED_VALUE_INT_DATA, POSITION_TARGET_LOCAL_NED_DATA, STATUSTEXT_DATA,
};
#[allow(deprecated)]
// PING: deprecated by MAVLink for TIMESYNC, still sent by tools (PX4 answers it); MISSION_ITEM
use crate::link::dialect::{
    ATTITUDE_TARGET_DATA, BATTERY_STATUS_DATA, GLOBAL_POSITION_INT_DATA, GPS_GLOBAL_ORIGIN_DATA,
    GPS_RAW_INT_DATA, HOME_POSITION_DATA, MESSAGE_INTERVAL_DATA, MISSION_CURRENT_DATA, MISSION_ITEM_DATA,
    MISSION_ITEM_REACHED_DATA, PING_DATA, SYSTEM_TIME_DATA, VFR_HUD_DATA,
};
use crate::link::dialect::{
    AUTOPILOT_VERSION_DATA, CURRENT_MODE_DATA, ESTIMATOR_STATUS_DATA, EXTENDED_SYS_STATE_DATA,
    MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, PARAM_VALUE_DATA, SYS_STATUS_DATA, TIMESYNC_DATA,
};
use mavlink_core::{MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, MavlinkVersion, MessageData};

use crate::link::framing::{FrameWriter, MAX_PAYLOAD};

/// AUTOPILOT_VERSION capabilities, what the link implements: MAVLink 2, float parameters (C
/// cast), MISSION_ITEM_INT and the deprecated float MISSION_ITEM (`mission_float`), COMMAND_INT,
/// SET_POSITION_TARGET_LOCAL_NED (offboard, `offboard`), MAVLink FTP (read-only: the component
/// metadata files, `ftp`). Not announced: fence and rally missions (refused), SET_POSITION_TARGET_GLOBAL_INT
/// and SET_ATTITUDE_TARGET (not handled), terrain, flight information.
pub const CAPABILITIES: MavProtocolCapability = MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST)
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT)
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT)
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT)
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED)
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_FTP);

/// AUTOPILOT_VERSION of this firmware (version 0.1.0 as `major << 24 | minor << 16 | patch << 8`)
/// on the vehicle with unique id `uid` ([`crate::link::Link::set_uid`]; ground stations and
/// MAVSDK tell vehicles apart by it).
pub fn autopilot_version(uid: u64) -> AUTOPILOT_VERSION_DATA {
    AUTOPILOT_VERSION_DATA {
        capabilities: CAPABILITIES,
        flight_sw_version: 0x0001_0000,
        uid,
        ..Default::default()
    }
}

/// The 64-bit AUTOPILOT_VERSION `uid` of an STM32's 96-bit unique device id (`bytes` in memory
/// order): the first 8 bytes (wafer x/y, wafer number, 3 bytes of the lot) with the last 4 of
/// the lot folded in by XOR, so every byte counts.
pub fn uid_of_mcu(bytes: [u8; 12]) -> u64 {
    let mut lo = [0u8; 8];
    lo.copy_from_slice(&bytes[..8]);
    let mut hi = [0u8; 4];
    hi.copy_from_slice(&bytes[8..]);
    u64::from_le_bytes(lo) ^ (u64::from(u32::from_le_bytes(hi)) << 32)
}

/// HIL_ACTUATOR_CONTROLS as the lockstep answers (`crate::pil::lockstep`): `time_usec`,
/// `controls[0..4]` = the four rotor throttles and the other twelve 0, `mode` HIL_ENABLED
/// (+ SAFETY_ARMED when `armed`), `flags` LOCKSTEP. Kept in this form in [`Outbound`] — which
/// is as large as its largest variant in every queue — instead of the 88-byte message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HilControls {
    /// Simulated time of the step, µs.
    pub time_usec: u64,
    /// Rotor throttles 0..1 (rotor i of `parapet_core::airframe`), sanitised.
    pub throttle: [f32; 4],
    /// The vehicle is armed.
    pub armed: bool,
}

impl HilControls {
    /// The message.
    pub fn data(&self) -> HIL_ACTUATOR_CONTROLS_DATA {
        let mut controls = [0.0; 16];
        for (c, t) in controls.iter_mut().zip(self.throttle) {
            *c = t;
        }
        let mut mode = MavModeFlag::MAV_MODE_FLAG_HIL_ENABLED;
        if self.armed {
            mode |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        let flags = HilActuatorControlsFlags::HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP;
        HIL_ACTUATOR_CONTROLS_DATA { time_usec: self.time_usec, flags, controls, mode }
    }
}

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
    /// ESTIMATOR_STATUS (the navigation filter).
    EstimatorStatus(ESTIMATOR_STATUS_DATA),
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
    HilActuatorControls(HilControls),
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
    /// AUTOPILOT_VERSION (capabilities; on request): [`autopilot_version`] of this uid.
    AutopilotVersion(u64),
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
    /// GPS_GLOBAL_ORIGIN (the local frame's origin, on request).
    GpsGlobalOrigin(GPS_GLOBAL_ORIGIN_DATA),
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
    /// GPS_RAW_INT (the position fix, [`crate::link::services::gps_raw_int`]).
    GpsRawInt(GPS_RAW_INT_DATA),
    /// VFR_HUD ([`crate::link::services::vfr_hud`]).
    VfrHud(VFR_HUD_DATA),
    /// FILE_TRANSFER_PROTOCOL: an FTP reply ([`crate::link::ftp`]; data copied from flash when
    /// encoded).
    Ftp(crate::link::ftp::FtpReply),
    /// COMPONENT_METADATA at this `time_boot_ms` ([`crate::link::metadata::component_metadata`]).
    ComponentMetadata(u32),
    /// AVAILABLE_MODES of mode index `i` (from 1; [`crate::link::standard_modes::available_mode`]).
    AvailableMode(u8),
    /// CURRENT_MODE ([`crate::link::standard_modes::current_mode`]).
    CurrentMode(CURRENT_MODE_DATA),
    /// AVAILABLE_MODES_MONITOR ([`crate::link::standard_modes::monitor`]).
    AvailableModesMonitor,
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
        match self {
            Outbound::StatusTextV1(m) => Encoded::V1(writer.encode_v1(m)),
            _ => Encoded::V2(writer.encode_with(|p| self.ser_v2(p))),
        }
    }

    /// Writes the MAVLink 2 payload into `p`: (message id, CRC_EXTRA, length). One match with a
    /// serialiser call per type, the frame set up once ([`FrameWriter::encode_with`]).
    fn ser_v2(&self, p: &mut [u8; MAX_PAYLOAD]) -> (u32, u8, usize) {
        fn s<D: MessageData>(m: &D, p: &mut [u8; MAX_PAYLOAD]) -> (u32, u8, usize) {
            (D::ID, D::EXTRA_CRC, m.ser(MavlinkVersion::V2, p))
        }
        match self {
            Outbound::StatusTextV1(m) | Outbound::StatusText(m) => s(m, p),
            Outbound::Heartbeat(m) => s(m, p),
            Outbound::RcChannels(m) => s(m, p),
            Outbound::Attitude(m) => s(m, p),
            Outbound::LocalPositionNed(m) => s(m, p),
            Outbound::EstimatorStatus(m) => s(m, p),
            Outbound::PositionTargetLocalNed(m) => s(m, p),
            Outbound::DebugVect(m) => s(m, p),
            Outbound::NamedValueInt(m) => s(m, p),
            Outbound::NamedValueFloat(m) => s(m, p),
            Outbound::CommandAck(m) => s(m, p),
            Outbound::MissionRequestInt(m) => s(m, p),
            Outbound::MissionAck(m) => s(m, p),
            Outbound::HilActuatorControls(m) => s(&m.data(), p),
            Outbound::ParamValue(m) => s(m, p),
            Outbound::MissionCount(m) => s(m, p),
            Outbound::MissionItemInt(m) => s(m, p),
            Outbound::MissionItem(m) => s(m, p),
            Outbound::SysStatus(m) => s(m, p),
            Outbound::ExtendedSysState(m) => s(m, p),
            Outbound::AutopilotVersion(uid) => s(&autopilot_version(*uid), p),
            Outbound::Timesync(m) => s(m, p),
            Outbound::SystemTime(m) => s(m, p),
            Outbound::GlobalPositionInt(m) => s(m, p),
            Outbound::MissionCurrent(m) => s(m, p),
            Outbound::HomePosition(m) => s(m, p),
            Outbound::GpsGlobalOrigin(m) => s(m, p),
            Outbound::Ping(m) => s(m, p),
            Outbound::MessageInterval(m) => s(m, p),
            Outbound::MissionItemReached(m) => s(m, p),
            Outbound::AttitudeTarget(m) => s(m, p),
            Outbound::BatteryStatus(m) => s(m, p),
            Outbound::GpsRawInt(m) => s(m, p),
            Outbound::VfrHud(m) => s(m, p),
            Outbound::Ftp(m) => s(&m.data(), p),
            Outbound::ComponentMetadata(t) => s(&crate::link::metadata::component_metadata(*t), p),
            // Only listed indices are queued (the router's request check).
            Outbound::AvailableMode(i) => {
                s(&crate::link::standard_modes::available_mode(*i).unwrap_or_default(), p)
            }
            Outbound::CurrentMode(m) => s(m, p),
            Outbound::AvailableModesMonitor => s(&crate::link::standard_modes::monitor(), p),
        }
    }
}

pub use crate::link::dialect::name;

/// NAMED_VALUE_INT helper.
pub fn named_int(time_boot_ms: u32, key: &str, value: i32) -> Outbound {
    Outbound::NamedValueInt(NAMED_VALUE_INT_DATA { time_boot_ms, value, name: name(key) })
}

/// DEBUG_VECT helper.
pub fn debug_vect(time_usec: u64, key: &str, x: f32, y: f32, z: f32) -> Outbound {
    Outbound::DebugVect(DEBUG_VECT_DATA { time_usec, x, y, z, name: name(key) })
}

#[cfg(test)]
#[allow(deprecated)] // PING, MISSION_ITEM
mod tests {
    use super::*;
    use mavlink_core::MavHeader;

    /// mavlink-core's frame of `m` with sequence `seq` from system 1, component 1.
    fn theirs<D: MessageData>(m: &D, seq: u8) -> Vec<u8> {
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message_data(MavHeader { system_id: 1, component_id: 1, sequence: seq }, m);
        raw.raw_bytes().to_vec()
    }

    /// Every kind of message goes out as mavlink-core frames it (id, CRC_EXTRA, trimmed payload),
    /// through the one `encode_with` frame set-up.
    #[test]
    fn encode_writes_mavlink_core_s_frames() {
        let mut w = FrameWriter::new(1, 1);
        let text = crate::link::telemetry::status_text(
            crate::link::dialect::MavSeverity::MAV_SEVERITY_INFO,
            "",
            "x",
        );
        let item = MISSION_ITEM_INT_DATA {
            x: 473_977_420,
            y: -5,
            z: 1.5,
            seq: 3,
            command: 22,
            ..Default::default()
        };
        let float = crate::link::mission_float::float_item(&item);
        let frames: Vec<(Outbound, Vec<u8>)> = vec![
            (
                Outbound::Heartbeat(HEARTBEAT_DATA { custom_mode: 7, ..Default::default() }),
                theirs(&HEARTBEAT_DATA { custom_mode: 7, ..Default::default() }, 0),
            ),
            (Outbound::StatusText(text.clone()), theirs(&text, 1)),
            (Outbound::MissionItemInt(item.clone()), theirs(&item, 2)),
            (Outbound::MissionItem(float.clone()), theirs(&float, 3)),
            (
                debug_vect(9, "CBF", 1.0, 2.0, 3.0),
                theirs(&DEBUG_VECT_DATA { time_usec: 9, x: 1.0, y: 2.0, z: 3.0, name: name("CBF") }, 4),
            ),
        ];
        for (o, want) in frames {
            assert_eq!(o.encode(&mut w).raw_bytes(), &want[..], "{o:?}");
        }
        let v1 = Outbound::StatusTextV1(text).encode(&mut w);
        assert_eq!(v1.raw_bytes()[0], 0xFE, "the v1 refusal stays v1");
    }

    /// The two variants kept in a compact form go out as the full messages did: HIL_ACTUATOR_CONTROLS
    /// with the throttles in `controls[0..4]`, the rest 0, mode HIL_ENABLED (+ SAFETY_ARMED),
    /// flags LOCKSTEP; AUTOPILOT_VERSION = `autopilot_version()`. An `Outbound` is 80 bytes
    /// (was 96 with the 88-byte HIL_ACTUATOR_CONTROLS_DATA in it; STATUSTEXT's 72 now the largest).
    #[test]
    fn compact_variants_encode_the_full_messages() {
        let mut w = FrameWriter::new(1, 1);
        for (k, armed) in [(0u8, false), (1, true)] {
            let hc = HilControls { time_usec: 123_456_789, throttle: [0.5, 0.25, 1.0, 0.125], armed };
            let mut mode = MavModeFlag::MAV_MODE_FLAG_HIL_ENABLED;
            if armed {
                mode |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
            }
            let mut controls = [0.0; 16];
            controls[..4].copy_from_slice(&[0.5, 0.25, 1.0, 0.125]);
            let full = HIL_ACTUATOR_CONTROLS_DATA {
                time_usec: 123_456_789,
                flags: HilActuatorControlsFlags::HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP,
                controls,
                mode,
            };
            assert_eq!(Outbound::HilActuatorControls(hc).encode(&mut w).raw_bytes(), &theirs(&full, k)[..]);
        }
        let want = theirs(&autopilot_version(0x0123_4567_89AB_CDEF), 2);
        assert_eq!(Outbound::AutopilotVersion(0x0123_4567_89AB_CDEF).encode(&mut w).raw_bytes(), &want[..]);
        let uid = uid_of_mcu([1, 2, 3, 4, 5, 6, 7, 8, 0x10, 0x20, 0x30, 0x40]);
        assert_eq!(uid, 0x0807_0605_0403_0201 ^ 0x4030_2010_0000_0000);
        assert_eq!(core::mem::size_of::<Outbound>(), 80);
    }
}
