//! What the link receives and counts, shared by the dispatcher ([`crate::link::router`]) and
//! the link's public face ([`crate::link::endpoint`]): a decoded frame and its sender
//! ([`Received`], [`ReceivedMessage`]) and the link counters ([`LinkStats`]). Plain data, so
//! neither of the two imports the other's internals (no import cycle).
//!
//! May import: `link::frame_parser`, `link::messages`.

use crate::link::frame_parser::RawFrame;
use crate::link::messages::{decode, DecodeError, Inbound};

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
    /// HIL_SENSOR samples received.
    pub hil_samples: u32,
    /// HIL_SENSOR samples overwritten before the control step took them.
    pub hil_overwritten: u32,
    /// PARAM_SET / PARAM_REQUEST_READ for unknown names or indices.
    pub unknown_params: u32,
    /// Messages addressed to another system or component (ignored).
    pub not_for_us: u32,
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
