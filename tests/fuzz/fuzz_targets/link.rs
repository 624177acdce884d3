//! Fuzz target `link`: the firmware's whole MAVLink link as the PIL application runs it —
//! bytes in → framer → dispatcher (mission upload, commands, parameters, obstacles, odometry)
//! → lockstep control steps of the real cascade → replies and telemetry out.
//!
//! Input: first byte even → the rest is raw bytes on the wire. Odd → a list of chunks, so the
//! fuzzer reaches deep states without solving CRCs: `tag len bytes[len]`; `tag >= 0xF0` pushes
//! the bytes as they are (noise, cut frames), any other tag sends a CRC-valid frame of inbound
//! message `INBOUND[tag % INBOUND.len()]` with those payload bytes.
//!
//! Invariants checked on every input (see `docs/reliability.md`):
//! 1. no panic (overflow checks and debug assertions are on);
//! 2. everything the firmware sends parses as complete CRC-valid frames: a fresh framer drops
//!    nothing, discards no byte and is left with no partial frame;
//! 3. every answered control step sent exactly one HIL_ACTUATOR_CONTROLS, with finite throttles
//!    in 0..1 (0 when disarmed);
//! 4. every parameter reads back finite and the cascade's whole parameter set still validates;
//! 5. the framer's work stays within `WORK_PER_BYTE` per received byte.
#![no_main]

use std::cell::Cell;

use libfuzzer_sys::fuzz_target;
use mavlink::dialects::ardupilotmega::{
    MavModeFlag, COMMAND_LONG_DATA, DEBUG_VECT_DATA, HEARTBEAT_DATA, HIL_ACTUATOR_CONTROLS_DATA,
    HIL_SENSOR_DATA, MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
    OBSTACLE_DISTANCE_3D_DATA, ODOMETRY_DATA, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA,
};
use mavlink::{calculate_crc, MavlinkVersion, MessageData, MAV_STX_V2};
use parapet_core::controller::ControllerParams;
use parapet_firmware::app::autopilot::Autopilot;
use parapet_firmware::app::cascade::Cascade;
use parapet_firmware::link::frame_parser::{FrameParser, WORK_PER_BYTE};
use parapet_firmware::pil::lockstep::InstructionCalibration;
use parapet_firmware::link::messages::frame_extra_crc;
use parapet_firmware::link::params::NAMES;
use parapet_firmware::pil::{BytePort, PilApp, TickCounter};

/// The firmware's inbound message set (ids).
const INBOUND: [u32; 13] = [
    HEARTBEAT_DATA::ID,
    HIL_SENSOR_DATA::ID,
    ODOMETRY_DATA::ID,
    OBSTACLE_DISTANCE_3D_DATA::ID,
    DEBUG_VECT_DATA::ID,
    MISSION_COUNT_DATA::ID,
    MISSION_ITEM_INT_DATA::ID,
    MISSION_ACK_DATA::ID,
    MISSION_CLEAR_ALL_DATA::ID,
    COMMAND_LONG_DATA::ID,
    PARAM_SET_DATA::ID,
    PARAM_REQUEST_READ_DATA::ID,
    HIL_SENSOR_DATA::ID, // twice: it drives the control steps
];

/// The wire bytes the fuzz input stands for.
fn wire_bytes(data: &[u8]) -> Vec<u8> {
    let Some((&mode, rest)) = data.split_first() else { return Vec::new() };
    if mode & 1 == 0 {
        return rest.to_vec();
    }
    let mut out = Vec::new();
    let mut seq = 0u8;
    let mut i = 0;
    while i + 1 < rest.len() {
        let (tag, len) = (rest[i], usize::from(rest[i + 1]));
        let body = &rest[(i + 2).min(rest.len())..(i + 2 + len).min(rest.len())];
        i += 2 + len;
        if tag >= 0xF0 {
            out.extend_from_slice(body);
            continue;
        }
        let id = INBOUND[usize::from(tag) % INBOUND.len()];
        let start = out.len();
        out.extend_from_slice(&[MAV_STX_V2, body.len() as u8, 0, 0, seq, 255, 190]);
        out.extend_from_slice(&id.to_le_bytes()[..3]);
        out.extend_from_slice(body);
        let crc = calculate_crc(&out[start + 1..], frame_extra_crc(id).unwrap_or(0));
        out.extend_from_slice(&crc.to_le_bytes());
        seq = seq.wrapping_add(1);
    }
    out
}

struct Port {
    input: Vec<u8>,
    at: usize,
    sent: Vec<u8>,
}

impl BytePort for Port {
    fn try_read(&mut self) -> Option<u8> {
        let b = self.input.get(self.at).copied();
        self.at += 1;
        b
    }
    fn write(&mut self, bytes: &[u8]) {
        self.sent.extend_from_slice(bytes);
    }
}

struct Ticks(Cell<u32>);

impl TickCounter for Ticks {
    fn now(&self) -> u32 {
        let t = self.0.get().wrapping_add(7);
        self.0.set(t);
        t
    }
    fn since(&self, start: u32) -> u32 {
        self.now().wrapping_sub(start)
    }
}

fuzz_target!(|data: &[u8]| {
    let input = wire_bytes(data);
    let n_in = input.len() as u64;
    let cascade = Cascade::new(ControllerParams::default()).expect("the default parameters are valid");
    let mut app = PilApp::new(cascade, InstructionCalibration { instructions: 100_000, ticks: 16_800 });
    let mut port = Port { input, at: 0, sent: Vec::new() };
    let ticks = Ticks(Cell::new(0));
    let answered = app.poll(&mut port, &ticks);

    // 2. Replies and telemetry are well-formed frames.
    let mut out = FrameParser::new();
    let mut actuator_frames = 0u32;
    out.push_bytes(&port.sent, frame_extra_crc, |f| {
        if f.msg_id == HIL_ACTUATOR_CONTROLS_DATA::ID {
            actuator_frames += 1;
            let m = HIL_ACTUATOR_CONTROLS_DATA::deser(MavlinkVersion::V2, f.payload)
                .expect("HIL_ACTUATOR_CONTROLS decodes");
            // 3. Throttles.
            assert!(
                m.controls[..4].iter().all(|t| t.is_finite() && (0.0..=1.0).contains(t)),
                "{:?}",
                m.controls
            );
            if !m.mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED) {
                assert!(m.controls[..4].iter().all(|t| *t == 0.0), "disarmed but throttles {:?}", m.controls);
            }
        }
    });
    let s = out.stats();
    assert_eq!((s.dropped(), s.unknown_id, s.bytes_discarded), (0, 0, 0), "malformed output: {s:?}");
    assert_eq!(out.buffered(), 0, "the output ends inside a frame");
    assert_eq!(actuator_frames, answered, "one HIL_ACTUATOR_CONTROLS per answered step");

    // 4. Parameters.
    let ap = app.autopilot();
    for name in NAMES {
        let v = ap.get_param(name);
        assert!(v.is_some_and(f32::is_finite), "parameter {name} = {v:?}");
    }
    assert!(ap.flown_params().validate().is_ok(), "the parameter set flown no longer validates");

    // 5. Framer work.
    let work = app.link().parser_work();
    assert!(work <= WORK_PER_BYTE * n_in, "framer work {work} for {n_in} bytes");
});
