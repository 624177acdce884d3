//! Outgoing MAVLink v2 framing: header, sequence numbers and CRC for one message at a time.
//!
//! The frame is written here rather than by `MAVLinkV2MessageRaw::serialize_message_data`: that
//! one places the payload at an offset read back from the frame's own flags (32-bit system ids),
//! so none of each message's buffer-length checks (and their panic paths) could be folded. Here
//! the payload area is a fixed 255-byte array at offset 10 (this link never sends 32-bit system
//! ids or signed frames): the same bytes on the wire, about 2 KB less code on the F405.

use mavlink_core::{MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, MavlinkVersion, MessageData};

pub use parapet_core::wire::ids::{AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};

/// MAVLink v2 start-of-frame marker.
const STX_V2: u8 = 0xFD;
/// STX plus the 9-byte v2 header (no 32-bit system id): where the payload starts.
const HEADER_LEN: usize = 10;
/// Largest MAVLink payload.
pub const MAX_PAYLOAD: usize = 255;
/// MAVLink v1 start-of-frame marker.
const STX_V1: u8 = 0xFE;
/// STX plus the 5-byte v1 header: where a v1 payload starts.
const HEADER_LEN_V1: usize = 6;

/// Serialises messages into MAVLink v2 frames with a running sequence number.
#[derive(Clone, Debug)]
pub struct FrameWriter {
    system_id: u8,
    component_id: u8,
    sequence: u8,
}

impl FrameWriter {
    /// A writer that sends as `system_id`/`component_id`, sequence starting at 0.
    pub const fn new(system_id: u8, component_id: u8) -> Self {
        Self { system_id, component_id, sequence: 0 }
    }

    /// Encodes one message into a complete frame (`raw_bytes()` is what goes on the wire):
    /// STX, payload length, flags 0/0, sequence, system and component id, the 24-bit message
    /// id, the payload (trailing zeros trimmed, as MAVLink 2 sends it) and the CRC-16/MCRF4XX
    /// over everything after the STX plus the message's CRC_EXTRA.
    pub fn encode<D: MessageData>(&mut self, msg: &D) -> MAVLinkV2MessageRaw {
        self.encode_with(|p| (D::ID, D::EXTRA_CRC, msg.ser(MavlinkVersion::V2, p)))
    }

    /// [`FrameWriter::encode`] with the payload written by `payload` into the frame's 255-byte
    /// payload area, returning the message id, its CRC_EXTRA and the payload length: one frame
    /// set-up for a `match` over many message types ([`crate::link::outbound::Outbound::encode`])
    /// instead of one per type (flash on the F405).
    pub fn encode_with(
        &mut self,
        payload: impl FnOnce(&mut [u8; MAX_PAYLOAD]) -> (u32, u8, usize),
    ) -> MAVLinkV2MessageRaw {
        let sequence = self.sequence;
        self.sequence = self.sequence.wrapping_add(1);
        let mut raw = MAVLinkV2MessageRaw::new();
        let frame = raw.as_mut_slice();
        let Some((_, rest)) = frame.split_first_chunk_mut::<HEADER_LEN>() else { return raw };
        let Some((p, _)) = rest.split_first_chunk_mut::<MAX_PAYLOAD>() else { return raw };
        let (msg_id, extra_crc, len) = payload(p);
        self.finish(&mut raw, sequence, len.min(MAX_PAYLOAD), msg_id, extra_crc);
        raw
    }

    /// Encodes one message into a MAVLink **v1** frame (the answer to a v1 ground station,
    /// [`crate::link::v1`]), on the same sequence counter: STX 0xFE, payload length, sequence,
    /// system and component id, the 8-bit message id, the payload (v1: no extension fields, not
    /// trimmed) and the CRC with the message's CRC_EXTRA — mavlink-core's bytes (test), written
    /// here for the reason of [`FrameWriter::encode`] (its checks cost flash on the F405).
    pub fn encode_v1<D: MessageData>(&mut self, msg: &D) -> MAVLinkV1MessageRaw {
        let sequence = self.sequence;
        self.sequence = self.sequence.wrapping_add(1);
        let mut raw = MAVLinkV1MessageRaw::new();
        let frame = raw.as_mut_slice();
        let Some((head, rest)) = frame.split_first_chunk_mut::<HEADER_LEN_V1>() else { return raw };
        let Some((payload, _)) = rest.split_first_chunk_mut::<MAX_PAYLOAD>() else { return raw };
        let len = msg.ser(MavlinkVersion::V1, payload).min(MAX_PAYLOAD);
        *head = [STX_V1, len as u8, sequence, self.system_id, self.component_id, D::ID as u8];
        let end = HEADER_LEN_V1 + len;
        let crc = mavlink_core::calculate_crc(frame.get(1..end).unwrap_or_default(), D::EXTRA_CRC);
        if let Some(c) = frame.get_mut(end..end + 2) {
            c.copy_from_slice(&crc.to_le_bytes());
        }
        raw
    }

    /// Header and CRC of a frame whose payload (`len` bytes) is in place: the part of
    /// [`FrameWriter::encode`] that does not depend on the message type, once in the image
    /// rather than once per message.
    #[inline(never)]
    fn finish(&self, raw: &mut MAVLinkV2MessageRaw, sequence: u8, len: usize, msg_id: u32, extra_crc: u8) {
        let frame = raw.as_mut_slice();
        let Some((head, _)) = frame.split_first_chunk_mut::<HEADER_LEN>() else { return };
        let id = msg_id.to_le_bytes();
        *head = [
            STX_V2,
            len as u8,
            0, // incompatibility flags
            0, // compatibility flags
            sequence,
            self.system_id,
            self.component_id,
            id[0],
            id[1],
            id[2],
        ];
        let end = HEADER_LEN + len;
        let crc = mavlink_core::calculate_crc(frame.get(1..end).unwrap_or_default(), extra_crc);
        if let Some(c) = frame.get_mut(end..end + 2) {
            c.copy_from_slice(&crc.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::dialect::{HEARTBEAT_DATA, PARAM_VALUE_DATA};
    use mavlink_core::MavHeader;

    /// The frames are mavlink-core's own, byte for byte (sequence included).
    fn same_as_mavlink_core<D: MessageData>(msg: &D) {
        let mut w = FrameWriter::new(VEHICLE_SYSTEM_ID, AUTOPILOT_COMPONENT_ID);
        for sequence in 0..3u8 {
            let ours = w.encode(msg);
            let mut theirs = MAVLinkV2MessageRaw::new();
            let header = MavHeader {
                system_id: u32::from(VEHICLE_SYSTEM_ID),
                component_id: AUTOPILOT_COMPONENT_ID,
                sequence,
            };
            theirs.serialize_message_data(header, msg);
            assert_eq!(ours.raw_bytes(), theirs.raw_bytes());
            assert!(ours.has_valid_crc_with_extra_crc(D::EXTRA_CRC));
        }
    }

    /// v1 frames too (the STATUSTEXT a v1 ground station gets).
    #[test]
    fn v1_frames_match_mavlink_core() {
        let mut t = crate::link::dialect::STATUSTEXT_DATA {
            severity: crate::link::dialect::MavSeverity::MAV_SEVERITY_WARNING,
            ..Default::default()
        };
        t.text = crate::link::outbound::name("MAVLink 1 not supported");
        let mut w = FrameWriter::new(VEHICLE_SYSTEM_ID, AUTOPILOT_COMPONENT_ID);
        for sequence in 0..3u8 {
            let ours = w.encode_v1(&t);
            let mut theirs = MAVLinkV1MessageRaw::new();
            let header = MavHeader {
                system_id: u32::from(VEHICLE_SYSTEM_ID),
                component_id: AUTOPILOT_COMPONENT_ID,
                sequence,
            };
            theirs.serialize_message_data(header, &t);
            assert_eq!(ours.raw_bytes(), theirs.raw_bytes());
        }
    }

    #[test]
    fn frames_match_mavlink_core() {
        same_as_mavlink_core(&HEARTBEAT_DATA { custom_mode: 0x0102_0304, ..Default::default() });
        // All-zero payload: MAVLink 2 trims it to one byte.
        same_as_mavlink_core(&HEARTBEAT_DATA::default());
        let mut p =
            PARAM_VALUE_DATA { param_value: 1.5, param_count: 71, param_index: 70, ..Default::default() };
        p.param_id = crate::link::outbound::name("CBF_MU");
        same_as_mavlink_core(&p);
    }
}
