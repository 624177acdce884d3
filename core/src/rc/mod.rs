//! Pilot input: RC receiver frames (CRSF, SBUS) and MAVLink manual control, turned into one
//! normalised [`RcInput`] that the supervisor's mode machine reads.
//!
//! Owns the [`RcInput`] message (the one contract between the receiver side — decoders,
//! channel map, RC-loss detection — and the modes), the decoders and the channel map.
//!
//! Sign conventions (stated once, like PX4's `manual_control_setpoint`): sticks are
//! normalised to [−1, 1] with centre 0; `roll` > 0 = right, `pitch` > 0 = forward (nose
//! down), `yaw` > 0 = clockwise seen from above, `throttle` in [0, 1] (0 = stick down).
//!
//! Units of this folder (each imports only this module's types and the ones listed before it):
//!
//! | unit | owns |
//! |---|---|
//! | this module | [`RcInput`], [`RcLost`], [`RcSource`], [`RawChannels`], [`unpack_11bit`] |
//! | [`crsf`] | the CRSF (Crossfire / ExpressLRS) byte-stream decoder: RC channels, link statistics |
//! | [`sbus`] | the SBUS byte-stream decoder (byte-timestamp resync) |
//! | [`map`] | [`map::RcParams`] (channel map, ranges, deadband, switch thresholds, loss limits), raw channels → [`RcInput`], the receivers (decoder + map) and the RC-loss detector [`map::RcMonitor`] |
//! | [`manual`] | MAVLink MANUAL_CONTROL / RC_CHANNELS_OVERRIDE values → [`RcInput`] (plain integers: no MAVLink types in core) |
//!
//! Why hand-written, not a crate: see [`crsf`] and [`sbus`] (byte-timestamp resync, bounded
//! time per byte, flash size, no allocation).
//!
//! May import: the crate root foundation only (`crate::rc::*` inside the folder).

pub mod crsf;
pub mod manual;
pub mod map;
pub mod sbus;

/// Position of a three-position mode switch (or the two ends of a two-position one).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SwitchPosition {
    /// Low end (channel value below the lower threshold).
    #[default]
    Low,
    /// Middle.
    Mid,
    /// High end.
    High,
}

/// One normalised pilot input, produced by the receiver side at the frame rate and consumed
/// by the supervisor's mode machine. A `Copy` message (see [`crate::msg`]).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct RcInput {
    /// Time the frame was received, µs, controller clock.
    pub t_us: u64,
    /// Roll stick, [−1, 1], > 0 right.
    pub roll: f32,
    /// Pitch stick, [−1, 1], > 0 forward.
    pub pitch: f32,
    /// Yaw stick, [−1, 1], > 0 clockwise from above.
    pub yaw: f32,
    /// Throttle stick, [0, 1].
    pub throttle: f32,
    /// Arm switch on.
    pub arm: bool,
    /// Kill switch on: motors off at once, from any mode.
    pub kill: bool,
    /// Mode switch position.
    pub mode: SwitchPosition,
    /// Link quality, percent (0–100), from the receiver's link statistics; 100 when the
    /// protocol has none and the frame is good.
    pub link_quality: u8,
    /// Received signal strength, dBm, when the protocol reports it.
    pub rssi_dbm: Option<i16>,
    /// The receiver itself flags failsafe (SBUS failsafe bit, CRSF link lost): the sticks are
    /// not the pilot's.
    pub failsafe: bool,
    /// `None`: a valid pilot input. `Some(reason)`: RC is lost (set by the producer for a
    /// receiver failsafe / low link quality, and by [`map::RcMonitor`] also for a timeout);
    /// the sticks then hold the documented loss output (see [`map::RcMonitor`]).
    pub lost: Option<RcLost>,
    /// Where the input came from.
    pub source: RcSource,
}

/// Why the pilot input is not valid (the RC-loss detector's answer, [`map::RcMonitor`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RcLost {
    /// No valid frame since start-up.
    NoSignal,
    /// No valid frame for the loss timeout (`FS_RC_TIMEOUT`).
    Timeout,
    /// The receiver flags failsafe (SBUS failsafe bit, CRSF link quality 0).
    ReceiverFailsafe,
    /// Link quality below `RC_LQ_MIN`.
    LowLinkQuality,
}

/// The producer of an [`RcInput`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RcSource {
    /// Simulated pilot (host) or a test.
    #[default]
    Sim,
    /// CRSF receiver.
    Crsf,
    /// SBUS receiver.
    Sbus,
    /// MAVLink MANUAL_CONTROL / RC_CHANNELS_OVERRIDE.
    Mavlink,
}

/// Most channels a frame carries (SBUS: 16 proportional + 2 digital).
pub const MAX_CHANNELS: usize = 18;

/// One decoded receiver frame: channel values in µs (1000..2000 nominal) and the receiver's flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RawChannels {
    /// Channel values, µs; `us[i]` is channel `i + 1`; only the first `count` are valid.
    pub us: [u16; MAX_CHANNELS],
    /// Number of valid channels (16 for CRSF, 18 for SBUS).
    pub count: u8,
    /// The receiver flags failsafe (SBUS flag bit 3): the values are the receiver's failsafe
    /// settings, not the pilot's.
    pub failsafe: bool,
    /// The receiver reports the previous frame lost (SBUS flag bit 2).
    pub frame_lost: bool,
}

impl RawChannels {
    /// Channel `n` (1-based) in µs, `None` when `n` is 0 or beyond [`RawChannels::count`].
    pub fn channel(&self, n: u8) -> Option<u16> {
        let i = usize::from(n).checked_sub(1)?;
        if i < usize::from(self.count) {
            self.us.get(i).copied()
        } else {
            None
        }
    }
}

/// 16 channels × 11 bits packed LSB first (channel 1 in the low bits of byte 0), the payload
/// layout CRSF RC_CHANNELS_PACKED and SBUS share.
pub fn unpack_11bit(packed: &[u8; 22]) -> [u16; 16] {
    let mut out = [0u16; 16];
    let mut acc: u32 = 0;
    let mut bits = 0u32;
    let mut bytes = packed.iter();
    for ch in out.iter_mut() {
        while bits < 11 {
            // 16 × 11 = 176 = 22 × 8 bits: the bytes never run out.
            acc |= u32::from(bytes.next().copied().unwrap_or(0)) << bits;
            bits += 8;
        }
        *ch = (acc & 0x7FF) as u16;
        acc >>= 11;
        bits -= 11;
    }
    out
}
