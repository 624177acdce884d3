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
//! May import: the crate root foundation only.

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
}
