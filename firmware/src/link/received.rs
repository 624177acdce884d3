//! What the link receives and counts, shared by the dispatcher ([`crate::link::router`]) and
//! the link's public face ([`crate::link::endpoint`]): a decoded frame and its sender
//! ([`Received`], [`ReceivedMessage`]), the link counters ([`LinkStats`]) and the byte-stream
//! front end that makes them ([`Framer`]: MAVLink 2 framing plus the MAVLink v1 HEARTBEAT
//! detector of [`crate::link::v1`]), the one piece a board's receiving task and the
//! [`crate::link::Link`] both run. Plain data and framing, so neither of the two imports the
//! other's internals (no import cycle).
//!
//! May import: `link::frame_parser`, `link::messages`, `link::v1`.

use crate::link::frame_parser::{FrameParser, ParserStats, RawFrame};
use crate::link::messages::{decode, frame_extra_crc, DecodeError, Inbound};
use crate::link::v1::V1Detector;

/// Link counters beyond the framer's (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// CRC-valid frames whose payload did not decode (invalid enum values).
    pub decode_errors: u32,
    /// CRC-valid frames of messages the firmware does not handle.
    pub ignored: u32,
    /// Replies dropped because the queue was full.
    pub replies_dropped: u32,
    /// ODOMETRY messages rejected (unsupported frame or non-finite values).
    pub odometry_rejected: u32,
    /// GPS_INPUT / VISION_POSITION_ESTIMATE fixes refused (no 3D fix, non-finite, out of
    /// range, stale: [`crate::link::position_sources`]).
    pub position_rejected: u32,
    /// HIL_SENSOR samples received.
    pub hil_samples: u32,
    /// HIL_SENSOR samples overwritten before the control step took them.
    pub hil_overwritten: u32,
    /// HIL_SENSOR barometer heights handed to the navigation filter
    /// ([`crate::link::inputs::hil_baro_down`]).
    pub baro_heights: u32,
    /// HIL_SENSOR magnetometer fields that gave a heading ([`crate::link::inputs::hil_mag`]).
    pub mag_headings: u32,
    /// PARAM_SET / PARAM_REQUEST_READ for unknown names or indices.
    pub unknown_params: u32,
    /// Messages addressed to another system or component (ignored).
    pub not_for_us: u32,
    /// Valid MAVLink v1 HEARTBEATs (refused, [`crate::link::v1`]).
    pub v1_heartbeats: u32,
}

impl LinkStats {
    /// Every counter 0 (for `const` constructors).
    pub const ZERO: LinkStats = LinkStats {
        decode_errors: 0,
        ignored: 0,
        replies_dropped: 0,
        odometry_rejected: 0,
        position_rejected: 0,
        hil_samples: 0,
        hil_overwritten: 0,
        baro_heights: 0,
        mag_headings: 0,
        unknown_params: 0,
        not_for_us: 0,
        v1_heartbeats: 0,
    };
}

/// A decoded inbound message and its sender.
#[derive(Clone, Debug, PartialEq)]
pub struct ReceivedMessage {
    /// Sender's system id.
    pub sys_id: u8,
    /// Sender's component id.
    pub comp_id: u8,
    /// The message.
    pub msg: Inbound,
}

/// One CRC-checked frame after decoding: what a board's receiving task hands to the task that
/// owns the [`Link`] ([`Link::receive`]) when framing and dispatch run in different tasks.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // one message at a time, copied once into a channel
pub enum Received {
    /// A message of the inbound set.
    Message(ReceivedMessage),
    /// A frame that is not (counted by the link).
    Undecodable(DecodeError),
    /// A complete, CRC-valid MAVLink **v1** HEARTBEAT: not dispatched, answered with the v1
    /// refusal ([`crate::link::v1`]).
    V1Heartbeat,
}

impl Received {
    /// Decodes `f`.
    pub fn of(f: &RawFrame<'_>) -> Self {
        match decode(f) {
            Ok(msg) => Received::Message(ReceivedMessage { sys_id: f.sys_id, comp_id: f.comp_id, msg }),
            Err(e) => Received::Undecodable(e),
        }
    }
}

/// The received byte stream's front end: MAVLink 2 frames ([`FrameParser`], decoded by
/// [`Received::of`]) and MAVLink v1 HEARTBEATs ([`V1Detector`], [`Received::V1Heartbeat`]).
/// [`crate::link::Link::push_byte`] runs one, and so does a board whose receiving task frames
/// the bytes and hands [`Received`] values to the task that owns the link
/// ([`crate::link::Link::receive`]): both paths see the same frames and the same v1 refusals.
/// O(1) state (the parser's 280-byte buffer, the detector's 17-byte window).
pub struct Framer {
    parser: FrameParser,
    v1: V1Detector,
}

impl Default for Framer {
    fn default() -> Self {
        Self::new()
    }
}

impl Framer {
    /// Nothing received yet.
    pub const fn new() -> Self {
        Self { parser: FrameParser::new(), v1: V1Detector::new() }
    }

    /// Feeds one byte. Every frame it completes goes to `divert` first (`true`: the caller takes
    /// it elsewhere, e.g. the F405's LOG_* requests to its log task), the others to `on`
    /// decoded; a v1 HEARTBEAT it completes goes to `on` as [`Received::V1Heartbeat`], unless
    /// the same byte completed a MAVLink 2 frame (bytes that are a valid v2 frame are not a v1
    /// ground station).
    pub fn push(
        &mut self,
        byte: u8,
        divert: &mut impl FnMut(&RawFrame<'_>) -> bool,
        on: &mut impl FnMut(Received),
    ) {
        let mut framed = false;
        self.parser.push(byte, &frame_extra_crc, &mut |f: &RawFrame<'_>| {
            framed = true;
            if !divert(f) {
                on(Received::of(f));
            }
        });
        if self.v1.push(byte) && !framed {
            on(Received::V1Heartbeat);
        }
    }

    /// Framer counters.
    pub fn stats(&self) -> ParserStats {
        self.parser.stats()
    }

    /// Framer work so far (see [`FrameParser::work`]).
    pub fn work(&self) -> u64 {
        self.parser.work()
    }
}
