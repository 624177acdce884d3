//! MAVLink v1: Parapet speaks MAVLink 2 only, as PX4 does by default since v1 became opt-in
//! (PX4-Autopilot PR 25583; QGroundControl dropped v1 too). A v1 frame is never handed to the
//! dispatcher (the framer takes 0xFD frames only), but a ground station that sends v1
//! HEARTBEATs is told so: [`V1Detector`] recognises a complete, CRC-valid v1 HEARTBEAT in the
//! received bytes, and the link answers with a STATUSTEXT WARNING [`V1_REFUSED_TEXT`] framed in
//! **v1** (so the v1 ground station can show it), at most once per [`V1_TEXT_US`].
//!
//! Bounded: O(1) per byte (a 17-byte window; the CRC only when a frame's fixed bytes match).
//! May import: `mavlink_core`, the dialect.

use crate::link::dialect::HEARTBEAT_DATA;
use mavlink_core::{calculate_crc, MessageData};

/// The STATUSTEXT a v1 ground station gets.
pub const V1_REFUSED_TEXT: &str = "MAVLink 1 not supported: use MAVLink 2";
/// Shortest interval between two such STATUSTEXTs, µs.
pub const V1_TEXT_US: u64 = 5_000_000;

/// v1 start byte.
const STX_V1: u8 = 0xFE;
/// A v1 HEARTBEAT frame: STX, len, seq, sys, comp, msgid, 9 payload bytes, CRC.
const FRAME_LEN: usize = 6 + 9 + 2;

/// Recognises v1 HEARTBEAT frames in a byte stream (see the module docs): the last 17 bytes in
/// a ring, checked at every byte (STX, length 9, message id 0: three compares; the CRC only when
/// they match), so any misalignment (a false start byte in other traffic) never hides a frame.
#[derive(Clone, Debug, Default)]
pub struct V1Detector {
    ring: [u8; FRAME_LEN],
    /// Index of the oldest byte (where the next one goes).
    next: usize,
    /// Bytes seen, saturating at the ring's length.
    filled: usize,
    /// Valid v1 HEARTBEATs seen.
    pub heartbeats: u32,
}

impl V1Detector {
    /// An empty detector.
    pub const fn new() -> Self {
        Self { ring: [0; FRAME_LEN], next: 0, filled: 0, heartbeats: 0 }
    }

    /// Takes one byte; `true` when it completed a valid v1 HEARTBEAT.
    pub fn push(&mut self, b: u8) -> bool {
        if let Some(slot) = self.ring.get_mut(self.next) {
            *slot = b;
        }
        self.next = (self.next + 1) % FRAME_LEN;
        self.filled = (self.filled + 1).min(FRAME_LEN);
        // Oldest byte first: `next` is the frame's start when the ring holds a whole frame.
        let at = |k: usize| self.ring.get((self.next + k) % FRAME_LEN).copied().unwrap_or(0);
        if self.filled < FRAME_LEN || at(0) != STX_V1 || at(1) != 9 || at(5) != 0 {
            return false;
        }
        let mut frame = [0u8; FRAME_LEN];
        for (k, d) in frame.iter_mut().enumerate() {
            *d = at(k);
        }
        let crc = calculate_crc(&frame[1..FRAME_LEN - 2], HEARTBEAT_DATA::EXTRA_CRC);
        let ok = crc.to_le_bytes() == [frame[FRAME_LEN - 2], frame[FRAME_LEN - 1]];
        if ok {
            self.heartbeats = self.heartbeats.saturating_add(1);
        }
        ok
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink_core::{MAVLinkV1MessageRaw, MavHeader};
    use std::vec::Vec;

    fn v1_heartbeat(seq: u8) -> Vec<u8> {
        let mut raw = MAVLinkV1MessageRaw::new();
        let h = MavHeader { system_id: 255, component_id: 190, sequence: seq };
        raw.serialize_message_data(h, &HEARTBEAT_DATA::default());
        raw.raw_bytes().to_vec()
    }

    #[test]
    fn finds_v1_heartbeats_among_other_bytes() {
        let mut d = V1Detector::new();
        let mut stream = vec![0xFD, 0x09, 0xFE, 0x00, 0x12];
        stream.extend(v1_heartbeat(1));
        stream.extend([0xFE, 0x09]); // a broken start
        stream.extend(v1_heartbeat(2));
        let mut bad = v1_heartbeat(3);
        bad[8] ^= 0x40; // payload corrupted: CRC fails
        stream.extend(bad);
        let hits = stream.iter().filter(|b| d.push(**b)).count();
        assert_eq!((hits, d.heartbeats), (2, 2));
    }

    #[test]
    fn a_v2_heartbeat_is_not_a_v1_one() {
        let mut d = V1Detector::new();
        let mut w = crate::link::framing::FrameWriter::new(255, 190);
        let v2 = w.encode(&HEARTBEAT_DATA::default());
        assert!(!v2.raw_bytes().iter().any(|b| d.push(*b)));
    }
}
