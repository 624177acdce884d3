//! The telemetry stream registry: every periodic stream of the vehicle's telemetry scheduler
//! with its MAVLink message, default period and whether a ground station may set it
//! (MAV_CMD_SET_MESSAGE_INTERVAL / REQUEST_MESSAGE), defined once — as PX4 keeps one class per
//! stream in one registry. The firmware's scheduler (`firmware/src/link/telemetry.rs`) walks
//! [`STREAMS`] in order and encodes each entry by its [`Stream`]; its interval service
//! (`firmware/src/link/services.rs`) takes the settable ones ([`SETTABLE`]); the host's
//! ground-station bridge (`host-sim/src/fc/bridge/inprocess.rs`) sends HEARTBEAT,
//! LOCAL_POSITION_NED and POSITION_TARGET_LOCAL_NED at these periods.
//!
//! May import: nothing of the crate.

/// A telemetry stream (its encoder is the firmware's, chosen by this value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stream {
    /// HEARTBEAT, with NAMED_VALUE_INT `PHASE`.
    Heartbeat,
    /// SYS_STATUS.
    SysStatus,
    /// EXTENDED_SYS_STATE.
    LandedState,
    /// ATTITUDE.
    Attitude,
    /// LOCAL_POSITION_NED.
    Position,
    /// DEBUG_VECT `CBF`, NAMED_VALUE_INT `CBF_FLAGS`, DEBUG_VECT `U_NOM`.
    Filter,
    /// DEBUG_VECT `LOOP_IN` / `LOOP_OUT`, NAMED_VALUE_INT `OVR_IN` / `OVR_OUT`.
    Loops,
    /// DEBUG_VECT `LINK`, `LINK_DROP`, `HW_ERR`.
    Link,
    /// POSITION_TARGET_LOCAL_NED.
    Target,
    /// ESTIMATOR_STATUS (the navigation filter's flags, test ratios and accuracies; sent only
    /// once a filtered position source initialised it).
    Estimator,
}

/// One registry entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamSpec {
    /// The stream (and its encoder).
    pub stream: Stream,
    /// Its MAVLink message id (the first message it sends).
    pub msg_id: u32,
    /// Default period, µs.
    pub default_us: u32,
    /// A ground station may set its interval or request it (by `msg_id`).
    pub settable: bool,
}

const fn spec(stream: Stream, msg_id: u32, default_us: u32, settable: bool) -> StreamSpec {
    StreamSpec { stream, msg_id, default_us, settable }
}

/// HEARTBEAT's message id.
pub const HEARTBEAT_ID: u32 = 0;
/// DEBUG_VECT's message id.
const DEBUG_VECT_ID: u32 = 250;

/// Every stream of the scheduler, in the order one poll sends them.
pub const STREAMS: [StreamSpec; 10] = [
    spec(Stream::Heartbeat, HEARTBEAT_ID, 1_000_000, true),
    spec(Stream::SysStatus, 1, 1_000_000, true),
    spec(Stream::LandedState, 245, 1_000_000, true),
    spec(Stream::Attitude, 30, 20_000, true),
    spec(Stream::Position, 32, 40_000, true),
    spec(Stream::Filter, DEBUG_VECT_ID, 40_000, false),
    spec(Stream::Loops, DEBUG_VECT_ID, 500_000, false),
    spec(Stream::Link, DEBUG_VECT_ID, 1_000_000, false),
    spec(Stream::Target, 85, 40_000, true),
    spec(Stream::Estimator, 230, 500_000, true),
];

/// Number of settable streams.
pub const SETTABLE_COUNT: usize = {
    let mut n = 0;
    let mut k = 0;
    while k < STREAMS.len() {
        if STREAMS[k].settable {
            n += 1;
        }
        k += 1;
    }
    n
};

/// The settable streams as `(message id, default period µs)`, in [`STREAMS`] order: the slots of
/// the interval service.
pub const SETTABLE: [(u32, u32); SETTABLE_COUNT] = {
    let mut out = [(0, 0); SETTABLE_COUNT];
    let (mut k, mut n) = (0, 0);
    while k < STREAMS.len() {
        if STREAMS[k].settable {
            out[n] = (STREAMS[k].msg_id, STREAMS[k].default_us);
            n += 1;
        }
        k += 1;
    }
    out
};

/// The [`SETTABLE`] slot of `stream`; `None` when it is not settable.
pub const fn slot(stream: Stream) -> Option<usize> {
    let (mut k, mut n) = (0, 0);
    while k < STREAMS.len() {
        if STREAMS[k].settable {
            if STREAMS[k].stream as u8 == stream as u8 {
                return Some(n);
            }
            n += 1;
        }
        k += 1;
    }
    None
}

/// The [`SETTABLE`] slot of each [`STREAMS`] entry (`None`: not settable), in [`STREAMS`] order.
pub const SLOTS: [Option<usize>; STREAMS.len()] = {
    let mut out = [None; STREAMS.len()];
    let mut k = 0;
    while k < STREAMS.len() {
        out[k] = slot(STREAMS[k].stream);
        k += 1;
    }
    out
};

/// The registry entry of `stream`.
pub const fn spec_of(stream: Stream) -> StreamSpec {
    let mut k = 0;
    while k < STREAMS.len() {
        if STREAMS[k].stream as u8 == stream as u8 {
            return STREAMS[k];
        }
        k += 1;
    }
    // Every stream has an entry (checked by the test below); never reached.
    STREAMS[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_stream_once_and_settable_ids_unique() {
        let all = [
            Stream::Heartbeat,
            Stream::SysStatus,
            Stream::LandedState,
            Stream::Attitude,
            Stream::Position,
            Stream::Filter,
            Stream::Loops,
            Stream::Link,
            Stream::Target,
            Stream::Estimator,
        ];
        for s in all {
            assert_eq!(STREAMS.iter().filter(|e| e.stream == s).count(), 1, "{s:?}");
            assert_eq!(spec_of(s).stream, s);
        }
        for (i, a) in SETTABLE.iter().enumerate() {
            assert!(SETTABLE[i + 1..].iter().all(|b| b.0 != a.0), "message {} twice", a.0);
        }
        assert_eq!(SETTABLE_COUNT, 7);
        assert_eq!(slot(Stream::Heartbeat), Some(0));
        assert_eq!(slot(Stream::Target), Some(5));
        assert_eq!(slot(Stream::Filter), None);
        for (spec, s) in STREAMS.iter().zip(SLOTS) {
            assert_eq!(s, slot(spec.stream));
        }
        assert_eq!(SETTABLE[slot(Stream::Attitude).unwrap()], (30, 20_000));
        // The registry's rates: heartbeat 1 Hz, attitude 50 Hz, position and target 25 Hz.
        assert_eq!(spec_of(Stream::Position).default_us, 40_000);
        assert_eq!(spec_of(Stream::Target).default_us, 40_000);
    }
}
