//! The inbound message set of the link: which MAVLink messages the firmware accepts and their
//! decoding from CRC-checked frames.
//!
//! Only these ids are decoded; other ids of the firmware's dialect ([`crate::link::dialect`]) are
//! CRC-checked by the framer and then ignored (counted), ids outside it are skipped (see [`crate::link::frame_parser`]). Decoding is per message type (`MessageData::deser`), so the
//! firmware links only the deserialisers it needs, not the whole dialect.

#![allow(deprecated)] // PING, MISSION_SET_CURRENT, MISSION_ITEM, MISSION_REQUEST: deprecated by MAVLink, still sent by ground stations

use crate::link::dialect::{
    COMMAND_INT_DATA, FILE_TRANSFER_PROTOCOL_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA,
    PARAM_REQUEST_LIST_DATA, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA, TIMESYNC_DATA,
};
use crate::link::dialect::{
    COMMAND_LONG_DATA, DEBUG_VECT_DATA, DISTANCE_SENSOR_DATA, HEARTBEAT_DATA, HIL_SENSOR_DATA,
    MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
    OBSTACLE_DISTANCE_3D_DATA, OBSTACLE_DISTANCE_DATA, ODOMETRY_DATA,
};
use crate::link::dialect::{GPS_INPUT_DATA, VISION_POSITION_ESTIMATE_DATA};
use crate::link::dialect::{
    MANUAL_CONTROL_DATA, RC_CHANNELS_OVERRIDE_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use crate::link::dialect::{
    MISSION_ITEM_DATA, MISSION_REQUEST_DATA, MISSION_SET_CURRENT_DATA, PING_DATA, SET_MODE_DATA,
};
use mavlink_core::{MavlinkVersion, MessageData};

use crate::link::frame_parser::RawFrame;

/// A decoded inbound message.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // one message at a time, on the stack of the link task
pub enum Inbound {
    /// Peer heartbeat (the ground station or companion is alive).
    Heartbeat(HEARTBEAT_DATA),
    /// Simulated IMU (lockstep PIL link only).
    HilSensor(HIL_SENSOR_DATA),
    /// External position/velocity estimate (motion capture, VIO, simulator).
    Odometry(ODOMETRY_DATA),
    /// GNSS fix from a companion or an external receiver ([`crate::link::position_sources`]).
    GpsInput(GPS_INPUT_DATA),
    /// Vision position estimate ([`crate::link::position_sources`]).
    VisionPosition(VISION_POSITION_ESTIMATE_DATA),
    /// One obstacle point.
    Obstacle(OBSTACLE_DISTANCE_3D_DATA),
    /// Obstacle distances in sectors (PX4 / ArduPilot proximity), into the obstacle memory.
    ObstacleDistance(crate::link::obstacles::ObstacleDistance),
    /// One range finder beam, into the obstacle memory.
    DistanceSensor(crate::link::obstacles::DistanceSensor),
    /// Named vector; `OBV<id>` carries an obstacle's velocity (see [`crate::link::obstacles`]).
    DebugVect(DEBUG_VECT_DATA),
    /// Start of a mission upload.
    MissionCount(MISSION_COUNT_DATA),
    /// One mission item.
    MissionItemInt(MISSION_ITEM_INT_DATA),
    /// Mission acknowledgement from the peer.
    MissionAck(MISSION_ACK_DATA),
    /// Clear the stored mission.
    MissionClearAll(MISSION_CLEAR_ALL_DATA),
    /// Command (arm, disarm, takeoff, land, mission start, hold).
    CommandLong(COMMAND_LONG_DATA),
    /// Set a parameter.
    ParamSet(PARAM_SET_DATA),
    /// Read a parameter.
    ParamRequestRead(PARAM_REQUEST_READ_DATA),
    /// Read all parameters.
    ParamRequestList(PARAM_REQUEST_LIST_DATA),
    /// Start of a mission download.
    MissionRequestList(MISSION_REQUEST_LIST_DATA),
    /// One mission item of a download.
    MissionRequestInt(MISSION_REQUEST_INT_DATA),
    /// Command with integer position fields (answered like COMMAND_LONG).
    CommandInt(COMMAND_INT_DATA),
    /// Time synchronisation request (tc1 = 0) or answer.
    Timesync(TIMESYNC_DATA),
    /// A MAVLink FTP request (FILE_TRANSFER_PROTOCOL: header and path, [`crate::link::ftp`]).
    FtpRequest(crate::link::ftp::FtpRequest),
    /// PING request (answered) or answer (ignored).
    Ping(PING_DATA),
    /// Legacy mode change.
    SetMode(SET_MODE_DATA),
    /// Mission item to fly next.
    MissionSetCurrent(MISSION_SET_CURRENT_DATA),
    /// One mission item, float x/y (deprecated; see [`crate::link::mission_float`]).
    MissionItem(MISSION_ITEM_DATA),
    /// MISSION_REQUEST (deprecated): one mission item of a download, answered in MISSION_ITEM.
    MissionRequest(MISSION_REQUEST_DATA),
    /// Joystick input (ground station), see [`crate::link::manual_control`].
    ManualControl(MANUAL_CONTROL_DATA),
    /// RC channel values from the ground station, see [`crate::link::manual_control`].
    RcOverride(RC_CHANNELS_OVERRIDE_DATA),
    /// Offboard setpoint from a companion computer, see [`crate::link::offboard`].
    SetPositionTarget(SET_POSITION_TARGET_LOCAL_NED_DATA),
}

/// Why a CRC-valid frame could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// The payload holds an invalid enum/bitflag value.
    InvalidPayload,
    /// The id is not in the inbound set.
    NotHandled,
}

/// CRC_EXTRA byte of the inbound message ids; `None` for ids the firmware does not handle.
pub fn extra_crc(msg_id: u32) -> Option<u8> {
    Some(match msg_id {
        HEARTBEAT_DATA::ID => HEARTBEAT_DATA::EXTRA_CRC,
        HIL_SENSOR_DATA::ID => HIL_SENSOR_DATA::EXTRA_CRC,
        ODOMETRY_DATA::ID => ODOMETRY_DATA::EXTRA_CRC,
        OBSTACLE_DISTANCE_3D_DATA::ID => OBSTACLE_DISTANCE_3D_DATA::EXTRA_CRC,
        OBSTACLE_DISTANCE_DATA::ID => OBSTACLE_DISTANCE_DATA::EXTRA_CRC,
        DISTANCE_SENSOR_DATA::ID => DISTANCE_SENSOR_DATA::EXTRA_CRC,
        DEBUG_VECT_DATA::ID => DEBUG_VECT_DATA::EXTRA_CRC,
        MISSION_COUNT_DATA::ID => MISSION_COUNT_DATA::EXTRA_CRC,
        MISSION_ITEM_INT_DATA::ID => MISSION_ITEM_INT_DATA::EXTRA_CRC,
        MISSION_ACK_DATA::ID => MISSION_ACK_DATA::EXTRA_CRC,
        MISSION_CLEAR_ALL_DATA::ID => MISSION_CLEAR_ALL_DATA::EXTRA_CRC,
        COMMAND_LONG_DATA::ID => COMMAND_LONG_DATA::EXTRA_CRC,
        PARAM_SET_DATA::ID => PARAM_SET_DATA::EXTRA_CRC,
        PARAM_REQUEST_READ_DATA::ID => PARAM_REQUEST_READ_DATA::EXTRA_CRC,
        PARAM_REQUEST_LIST_DATA::ID => PARAM_REQUEST_LIST_DATA::EXTRA_CRC,
        MISSION_REQUEST_LIST_DATA::ID => MISSION_REQUEST_LIST_DATA::EXTRA_CRC,
        MISSION_REQUEST_INT_DATA::ID => MISSION_REQUEST_INT_DATA::EXTRA_CRC,
        COMMAND_INT_DATA::ID => COMMAND_INT_DATA::EXTRA_CRC,
        TIMESYNC_DATA::ID => TIMESYNC_DATA::EXTRA_CRC,
        FILE_TRANSFER_PROTOCOL_DATA::ID => FILE_TRANSFER_PROTOCOL_DATA::EXTRA_CRC,
        PING_DATA::ID => PING_DATA::EXTRA_CRC,
        SET_MODE_DATA::ID => SET_MODE_DATA::EXTRA_CRC,
        MISSION_SET_CURRENT_DATA::ID => MISSION_SET_CURRENT_DATA::EXTRA_CRC,
        MISSION_ITEM_DATA::ID => MISSION_ITEM_DATA::EXTRA_CRC,
        MISSION_REQUEST_DATA::ID => MISSION_REQUEST_DATA::EXTRA_CRC,
        MANUAL_CONTROL_DATA::ID => MANUAL_CONTROL_DATA::EXTRA_CRC,
        RC_CHANNELS_OVERRIDE_DATA::ID => RC_CHANNELS_OVERRIDE_DATA::EXTRA_CRC,
        SET_POSITION_TARGET_LOCAL_NED_DATA::ID => SET_POSITION_TARGET_LOCAL_NED_DATA::EXTRA_CRC,
        _ => return None,
    })
}

/// CRC_EXTRA for the framer: the inbound set first, then every other message of the firmware's
/// dialect ([`crate::link::dialect`], the messages the firmware speaks), so frames of that set the
/// firmware ignores are still CRC-checked and a corrupted one cannot make the framer skip valid
/// frames by a wrong length. `None` for ids outside that set (the framer counts them as unknown
/// and resynchronises after the header).
///
/// A binary search in [`FRAME_IDS`] / [`FRAME_CRCS`] (the dialect's `EXTRA_CRCS`, sorted at
/// compile time): the same answers as the generated `MavMessage::extra_crc` match, whose
/// 87-arm compare tree cost twice the flash on the F405 (no message of the dialect has
/// CRC_EXTRA 0, checked at compile time, so "0 = unknown" needs no special case).
pub fn frame_extra_crc(msg_id: u32) -> Option<u8> {
    let i = FRAME_IDS.binary_search(&msg_id).ok()?;
    FRAME_CRCS.get(i).copied()
}

/// Number of messages of the firmware's dialect.
const DIALECT_LEN: usize = crate::link::dialect::EXTRA_CRCS.len();

/// The dialect's `(ID, EXTRA_CRC)` pairs sorted by id (compile time; no duplicate ids, no
/// CRC_EXTRA 0, or the build fails).
const SORTED: [(u32, u8); DIALECT_LEN] = {
    let mut t = crate::link::dialect::EXTRA_CRCS;
    let mut i = 1;
    while i < DIALECT_LEN {
        let mut j = i;
        while j > 0 && t[j - 1].0 > t[j].0 {
            let x = t[j - 1];
            t[j - 1] = t[j];
            t[j] = x;
            j -= 1;
        }
        i += 1;
    }
    let mut k = 0;
    while k < DIALECT_LEN {
        assert!(t[k].1 != 0, "a message with CRC_EXTRA 0");
        assert!(k == 0 || t[k - 1].0 < t[k].0, "duplicate message id");
        k += 1;
    }
    assert!(DIALECT_LEN > 0, "build.rs found no messages in the generated extra_crc");
    t
};

/// Message ids of the dialect, ascending (see [`frame_extra_crc`]).
static FRAME_IDS: [u32; DIALECT_LEN] = {
    let mut ids = [0; DIALECT_LEN];
    let mut i = 0;
    while i < DIALECT_LEN {
        ids[i] = SORTED[i].0;
        i += 1;
    }
    ids
};

/// CRC_EXTRA of [`FRAME_IDS`]`[i]`.
static FRAME_CRCS: [u8; DIALECT_LEN] = {
    let mut crcs = [0; DIALECT_LEN];
    let mut i = 0;
    while i < DIALECT_LEN {
        crcs[i] = SORTED[i].1;
        i += 1;
    }
    crcs
};

/// `D` from a frame's payload, read from a zero-padded copy of the full MAVLink payload size:
/// the same result as `deser` on the payload itself (which zero-extends a trimmed payload and
/// reads only the message's own length), but with a buffer of known length the field reads'
/// bounds checks fold away (about 1 KB less code on the F405).
fn de<D: MessageData>(payload: &[u8]) -> Result<D, DecodeError> {
    D::deser(MavlinkVersion::V2, &padded(payload)).map_err(|_| DecodeError::InvalidPayload)
}

/// `payload` zero-extended to the largest MAVLink payload (255 bytes; longer input is cut).
#[inline(never)]
fn padded(payload: &[u8]) -> [u8; 255] {
    let mut buf = [0u8; 255];
    for (b, p) in buf.iter_mut().zip(payload) {
        *b = *p;
    }
    buf
}

/// Decodes a CRC-checked frame of the inbound set. Never inlined: it holds every inbound
/// deserialiser, and a copy per call site costs flash on the F405.
#[inline(never)]
pub fn decode(frame: &RawFrame<'_>) -> Result<Inbound, DecodeError> {
    let p = frame.payload;
    Ok(match frame.msg_id {
        HEARTBEAT_DATA::ID => Inbound::Heartbeat(de(p)?),
        HIL_SENSOR_DATA::ID => Inbound::HilSensor(de(p)?),
        ODOMETRY_DATA::ID => Inbound::Odometry(de(p)?),
        GPS_INPUT_DATA::ID => Inbound::GpsInput(de(p)?),
        VISION_POSITION_ESTIMATE_DATA::ID => Inbound::VisionPosition(de(p)?),
        OBSTACLE_DISTANCE_3D_DATA::ID => Inbound::Obstacle(de(p)?),
        // Decoded by hand with their extension fields (see crate::link::obstacles).
        OBSTACLE_DISTANCE_DATA::ID => {
            Inbound::ObstacleDistance(crate::link::obstacles::ObstacleDistance::parse(p))
        }
        DISTANCE_SENSOR_DATA::ID => Inbound::DistanceSensor(crate::link::obstacles::DistanceSensor::parse(p)),
        DEBUG_VECT_DATA::ID => Inbound::DebugVect(de(p)?),
        MISSION_COUNT_DATA::ID => Inbound::MissionCount(de(p)?),
        MISSION_ITEM_INT_DATA::ID => Inbound::MissionItemInt(de(p)?),
        MISSION_ACK_DATA::ID => Inbound::MissionAck(de(p)?),
        MISSION_CLEAR_ALL_DATA::ID => Inbound::MissionClearAll(de(p)?),
        COMMAND_LONG_DATA::ID => Inbound::CommandLong(de(p)?),
        PARAM_SET_DATA::ID => Inbound::ParamSet(de(p)?),
        PARAM_REQUEST_READ_DATA::ID => Inbound::ParamRequestRead(de(p)?),
        PARAM_REQUEST_LIST_DATA::ID => Inbound::ParamRequestList(de(p)?),
        MISSION_REQUEST_LIST_DATA::ID => Inbound::MissionRequestList(de(p)?),
        MISSION_REQUEST_INT_DATA::ID => Inbound::MissionRequestInt(de(p)?),
        COMMAND_INT_DATA::ID => Inbound::CommandInt(de(p)?),
        TIMESYNC_DATA::ID => Inbound::Timesync(de(p)?),
        FILE_TRANSFER_PROTOCOL_DATA::ID => Inbound::FtpRequest(crate::link::ftp::FtpRequest::parse(p)),
        PING_DATA::ID => Inbound::Ping(de(p)?),
        SET_MODE_DATA::ID => Inbound::SetMode(de(p)?),
        MISSION_SET_CURRENT_DATA::ID => Inbound::MissionSetCurrent(de(p)?),
        MISSION_ITEM_DATA::ID => Inbound::MissionItem(de(p)?),
        MISSION_REQUEST_DATA::ID => Inbound::MissionRequest(de(p)?),
        MANUAL_CONTROL_DATA::ID => Inbound::ManualControl(de(p)?),
        RC_CHANNELS_OVERRIDE_DATA::ID => Inbound::RcOverride(de(p)?),
        SET_POSITION_TARGET_LOCAL_NED_DATA::ID => Inbound::SetPositionTarget(de(p)?),
        _ => return Err(DecodeError::NotHandled),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::dialect::MavMessage;
    use mavlink_core::Message;

    /// The sorted table answers exactly as the inbound match and then the generated dialect
    /// match did, for every 16-bit id and the dialect's own (all below 2^16 today).
    #[test]
    fn frame_extra_crc_is_the_dialect_match() {
        let old = |id: u32| {
            extra_crc(id).or_else(|| {
                let c = <MavMessage as Message>::extra_crc(id);
                (c != 0).then_some(c)
            })
        };
        let ids = (0..=u32::from(u16::MAX)).chain(FRAME_IDS.iter().copied()).chain([1 << 23, u32::MAX]);
        for id in ids {
            assert_eq!(frame_extra_crc(id), old(id), "id {id}");
        }
        assert_eq!(FRAME_IDS.len(), 94);
    }
}
