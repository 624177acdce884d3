//! Outgoing MAVLink v2 framing: header, sequence numbers and CRC for one message at a time.

use mavlink_core::{MAVLinkV2MessageRaw, MavHeader, MessageData};

pub use parapet_core::wire::ids::{AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};

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

    /// Encodes one message into a complete frame (`raw_bytes()` is what goes on the wire).
    pub fn encode<D: MessageData>(&mut self, msg: &D) -> MAVLinkV2MessageRaw {
        let header = MavHeader {
            system_id: u32::from(self.system_id),
            component_id: self.component_id,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message_data(header, msg);
        raw
    }
}
