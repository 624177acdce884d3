//! Byte-stream MAVLink v2 framer: finds frames in a serial byte stream, checks their CRC and counts
//! what it drops.
//!
//! The parser never stalls and never trusts a frame it cannot check:
//! - bytes outside a frame (noise, MAVLink v1 frames, which this link does not speak) are discarded
//!   and counted;
//! - a frame with unknown incompatibility flags is *malformed*: the parser drops its start byte and
//!   re-scans the buffered bytes for the next start byte;
//! - a frame whose CRC fails (corrupted, or truncated and completed by the bytes of the next frame)
//!   is dropped the same way, so a frame that follows a truncated one is still found;
//! - a frame whose message id is not one the firmware handles cannot be CRC-checked (the CRC needs
//!   the message's CRC_EXTRA byte); it is skipped by its declared length and counted as unknown.
//!
//! Work per byte is bounded: each re-scan discards at least one byte and scans at most
//! [`MAX_FRAME_LEN`] bytes, and the buffer is a fixed [`MAX_FRAME_LEN`]-byte array.

use mavlink::{calculate_crc, MAV_STX_V2};

/// Largest MAVLink v2 frame: 10 header bytes + 255 payload + 2 CRC + 13 signature bytes.
pub const MAX_FRAME_LEN: usize = 280;
/// Header length including the start byte.
const HEADER_LEN: usize = 10;
/// Incompatibility flag: the frame carries a 13-byte signature (accepted, not verified).
const IFLAG_SIGNED: u8 = 0x01;
const SIGNATURE_LEN: usize = 13;
const CRC_LEN: usize = 2;

/// Counters of the framer. All counters saturate at `u32::MAX`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ParserStats {
    /// Frames with a valid CRC handed to the caller.
    pub frames_ok: u32,
    /// Frames dropped because the CRC did not match (corrupted or truncated frames).
    pub crc_errors: u32,
    /// Frames dropped because of an invalid header (unknown incompatibility flags).
    pub malformed: u32,
    /// Frames with a message id this firmware does not handle (skipped by length, not checked).
    pub unknown_id: u32,
    /// Bytes discarded while searching for a start byte.
    pub bytes_discarded: u32,
}

impl ParserStats {
    /// Frames dropped for any reason (CRC, malformed header).
    pub fn dropped(&self) -> u32 {
        self.crc_errors.saturating_add(self.malformed)
    }
}

/// A CRC-checked MAVLink v2 frame borrowed from the parser's buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawFrame<'a> {
    /// Message id (24 bit).
    pub msg_id: u32,
    /// Sender system id.
    pub sys_id: u8,
    /// Sender component id.
    pub comp_id: u8,
    /// Sender sequence number.
    pub seq: u8,
    /// Payload bytes (MAVLink v2 trims trailing zeros; decoders zero-extend).
    pub payload: &'a [u8],
}

/// Incremental MAVLink v2 framer with a fixed 280-byte buffer.
pub struct FrameParser {
    buf: [u8; MAX_FRAME_LEN],
    len: usize,
    stats: ParserStats,
}

impl Default for FrameParser {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameParser {
    /// An empty parser.
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_FRAME_LEN],
            len: 0,
            stats: ParserStats {
                frames_ok: 0,
                crc_errors: 0,
                malformed: 0,
                unknown_id: 0,
                bytes_discarded: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> ParserStats {
        self.stats
    }

    /// Feeds bytes; calls `on_frame` for every CRC-valid frame whose CRC_EXTRA `extra_crc` knows.
    /// `extra_crc(msg_id)` returns `None` for message ids the caller does not handle.
    pub fn push_bytes(
        &mut self,
        bytes: &[u8],
        extra_crc: impl Fn(u32) -> Option<u8>,
        mut on_frame: impl FnMut(&RawFrame<'_>),
    ) {
        for &b in bytes {
            self.push(b, &extra_crc, &mut on_frame);
        }
    }

    /// Feeds one byte (see [`FrameParser::push_bytes`]).
    pub fn push(
        &mut self,
        byte: u8,
        extra_crc: &impl Fn(u32) -> Option<u8>,
        on_frame: &mut impl FnMut(&RawFrame<'_>),
    ) {
        if self.len == 0 && byte != MAV_STX_V2 {
            self.stats.bytes_discarded = self.stats.bytes_discarded.saturating_add(1);
            return;
        }
        // `len < MAX_FRAME_LEN` always holds here: a buffer holding a complete frame is consumed
        // by `process` before the next byte arrives, and no frame is longer than the buffer.
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = byte;
            self.len += 1;
        } else {
            self.resync();
            return;
        }
        self.process(extra_crc, on_frame);
    }

    /// Consumes every complete frame at the front of the buffer.
    fn process(&mut self, extra_crc: &impl Fn(u32) -> Option<u8>, on_frame: &mut impl FnMut(&RawFrame<'_>)) {
        // Each iteration either returns or removes at least one byte, so this loop is bounded by
        // the buffer length.
        loop {
            if self.len < HEADER_LEN {
                return;
            }
            let payload_len = usize::from(self.buf[1]);
            let incompat = self.buf[2];
            if incompat & !IFLAG_SIGNED != 0 {
                self.stats.malformed = self.stats.malformed.saturating_add(1);
                self.resync();
                continue;
            }
            let signature = if incompat & IFLAG_SIGNED != 0 { SIGNATURE_LEN } else { 0 };
            let total = HEADER_LEN + payload_len + CRC_LEN + signature;
            if self.len < total {
                return;
            }
            let msg_id = u32::from_le_bytes([self.buf[7], self.buf[8], self.buf[9], 0]);
            match extra_crc(msg_id) {
                None => {
                    self.stats.unknown_id = self.stats.unknown_id.saturating_add(1);
                    self.consume(total);
                }
                Some(extra) => {
                    let crc_at = HEADER_LEN + payload_len;
                    let crc = calculate_crc(&self.buf[1..crc_at], extra);
                    let got = u16::from_le_bytes([self.buf[crc_at], self.buf[crc_at + 1]]);
                    if crc == got {
                        self.stats.frames_ok = self.stats.frames_ok.saturating_add(1);
                        let frame = RawFrame {
                            msg_id,
                            sys_id: self.buf[5],
                            comp_id: self.buf[6],
                            seq: self.buf[4],
                            payload: &self.buf[HEADER_LEN..crc_at],
                        };
                        on_frame(&frame);
                        self.consume(total);
                    } else {
                        self.stats.crc_errors = self.stats.crc_errors.saturating_add(1);
                        self.resync();
                    }
                }
            }
        }
    }

    /// Removes the first `n` bytes (a consumed frame).
    fn consume(&mut self, n: usize) {
        let n = n.min(self.len);
        self.buf.copy_within(n..self.len, 0);
        self.len -= n;
    }

    /// Drops the current start byte and everything up to the next start byte in the buffer.
    fn resync(&mut self) {
        let next = self.buf[1..self.len].iter().position(|&b| b == MAV_STX_V2).map_or(self.len, |i| i + 1);
        self.stats.bytes_discarded = self.stats.bytes_discarded.saturating_add(next as u32);
        self.consume(next);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::FrameWriter;
    use mavlink::dialects::ardupilotmega::{HEARTBEAT_DATA, NAMED_VALUE_INT_DATA};
    use mavlink::MessageData;
    use std::vec::Vec;

    fn extra(id: u32) -> Option<u8> {
        crate::messages::frame_extra_crc(id)
    }

    fn frames(bytes: &[u8], p: &mut FrameParser) -> Vec<(u32, u8)> {
        let mut out = Vec::new();
        p.push_bytes(bytes, extra, |f| out.push((f.msg_id, f.seq)));
        out
    }

    fn heartbeat(w: &mut FrameWriter) -> Vec<u8> {
        w.encode(&HEARTBEAT_DATA::default()).raw_bytes().to_vec()
    }

    #[test]
    fn parses_back_to_back_frames_and_noise() {
        let mut w = FrameWriter::new(1, 1);
        let mut stream = vec![0x00, 0x55, 0xFE, 0x12];
        stream.extend(heartbeat(&mut w));
        stream.extend([0xAA, 0xBB]);
        stream.extend(heartbeat(&mut w));
        let mut p = FrameParser::new();
        let got = frames(&stream, &mut p);
        assert_eq!(got, vec![(HEARTBEAT_DATA::ID, 0), (HEARTBEAT_DATA::ID, 1)]);
        assert_eq!(p.stats().frames_ok, 2);
        assert_eq!(p.stats().bytes_discarded, 6);
        assert_eq!(p.stats().dropped(), 0);
    }

    #[test]
    fn corrupted_frame_is_counted_and_next_frame_survives() {
        let mut w = FrameWriter::new(1, 1);
        let mut bad = heartbeat(&mut w);
        let n = bad.len();
        bad[n - 3] ^= 0x40; // flip a payload bit
        let good = heartbeat(&mut w);
        let mut stream = bad;
        stream.extend(&good);
        let mut p = FrameParser::new();
        assert_eq!(frames(&stream, &mut p), vec![(HEARTBEAT_DATA::ID, 1)]);
        assert_eq!(p.stats().crc_errors, 1);
    }

    #[test]
    fn truncated_frame_does_not_swallow_the_next_one() {
        let mut w = FrameWriter::new(1, 1);
        let long = w.encode(&NAMED_VALUE_INT_DATA { time_boot_ms: 7, value: -3, name: "abcdefghij".into() });
        let cut = &long.raw_bytes()[..12];
        let mut stream = cut.to_vec();
        for _ in 0..3 {
            stream.extend(heartbeat(&mut w));
        }
        let mut p = FrameParser::new();
        let got = frames(&stream, &mut p);
        // The truncated frame's declared length swallows part of the following bytes; after the
        // CRC failure the parser re-scans and recovers every frame that is still complete.
        assert!(got.len() >= 2, "{got:?}");
        assert!(got.iter().all(|&(id, _)| id == HEARTBEAT_DATA::ID));
        assert_eq!(got.last().map(|g| g.1), Some(3));
        assert!(p.stats().crc_errors >= 1);
    }

    #[test]
    fn unknown_incompat_flags_are_malformed() {
        let mut w = FrameWriter::new(1, 1);
        let mut f = heartbeat(&mut w);
        f[2] = 0x80;
        f.extend(heartbeat(&mut w));
        let mut p = FrameParser::new();
        assert_eq!(frames(&f, &mut p), vec![(HEARTBEAT_DATA::ID, 1)]);
        assert_eq!(p.stats().malformed, 1);
    }

    #[test]
    fn unknown_message_id_is_skipped_by_length() {
        let mut w = FrameWriter::new(1, 1);
        let mut f = heartbeat(&mut w);
        f[7] = 0x99; // id 0x777799: outside the dialect
        f[8] = 0x77;
        f[9] = 0x77;
        f.extend(heartbeat(&mut w));
        let mut p = FrameParser::new();
        assert_eq!(frames(&f, &mut p), vec![(HEARTBEAT_DATA::ID, 1)]);
        assert_eq!(p.stats().unknown_id, 1);
    }

    #[test]
    fn random_garbage_never_stalls_and_valid_frames_still_arrive() {
        // Deterministic xorshift noise between valid frames.
        let mut s: u32 = 0x1234_5678;
        let mut w = FrameWriter::new(1, 1);
        let mut stream = Vec::new();
        for _ in 0..50 {
            for _ in 0..(s % 40) {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                // Avoid accidental start bytes so every noise burst is pure noise.
                stream.push(if (s as u8) == MAV_STX_V2 { 0 } else { s as u8 });
            }
            stream.extend(heartbeat(&mut w));
        }
        let mut p = FrameParser::new();
        let got = frames(&stream, &mut p);
        assert_eq!(got.len(), 50);
    }
}
