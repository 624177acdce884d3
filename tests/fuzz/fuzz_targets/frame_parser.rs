//! Fuzz target `frame_parser`: arbitrary bytes into the firmware's MAVLink v2 framer.
//!
//! Invariants checked on every input `X` (see `docs/reliability.md`):
//! 1. no panic (overflow checks and debug assertions are on);
//! 2. bounded work: `FrameParser::work() <= WORK_PER_BYTE * bytes pushed`;
//! 3. every decoded frame is consistent (payload <= 255 bytes, `frames_ok` = frames delivered);
//! 4. `X ++ F` for a valid unsigned frame `F` without 0xFD after its start byte (the framing
//!    guarantee 1 of `frame_parser.rs`): the buffer is empty after `F`; while `F` is pushed at
//!    least one CRC-valid frame ends (decoded, or refused if signed); if the first one ends on
//!    `F`'s last byte, a decoded frame of `F`'s length there is `F` itself; if none ends before
//!    the last byte and the last byte's frame is not `F`, it is longer than `F` (begun in `X`).
//!    `F` not decoded is allowed only when an earlier CRC-valid frame overlapping `F` was taken;
//! 5. `X ++ [0; MAX_FRAME_LEN] ++ F`: the buffer is empty before `F`, and `F` alone is decoded.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavlink::dialects::ardupilotmega::{MavCmd, COMMAND_LONG_DATA, HEARTBEAT_DATA, MISSION_COUNT_DATA};
use parapet_firmware::link::frame_parser::{FrameParser, RawFrame, MAX_FRAME_LEN, WORK_PER_BYTE};
use parapet_firmware::link::messages::frame_extra_crc;
use parapet_firmware::link::framing::FrameWriter;

/// (msg id, seq, payload, length on the wire) of a decoded frame.
type Decoded = (u32, u8, Vec<u8>, usize);

fn decoded(f: &RawFrame<'_>) -> Decoded {
    assert!(f.payload.len() <= 255);
    (f.msg_id, f.seq, f.payload.to_vec(), 10 + f.payload.len() + 2)
}

fn expected(frame: &[u8]) -> Decoded {
    let id = u32::from_le_bytes([frame[7], frame[8], frame[9], 0]);
    (id, frame[4], frame[10..frame.len() - 2].to_vec(), frame.len())
}

/// A few valid frames of different lengths (16, 21, 45 bytes).
fn probes() -> Vec<Vec<u8>> {
    let mut w = FrameWriter::new(255, 190);
    vec![
        w.encode(&MISSION_COUNT_DATA { count: 2, target_system: 1, target_component: 1, ..Default::default() })
            .raw_bytes()
            .to_vec(),
        w.encode(&HEARTBEAT_DATA::default()).raw_bytes().to_vec(),
        w.encode(&COMMAND_LONG_DATA {
            param1: 1.0,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            target_system: 1,
            ..Default::default()
        })
        .raw_bytes()
        .to_vec(),
    ]
}

fn push(p: &mut FrameParser, bytes: &[u8], out: &mut Vec<Decoded>) {
    p.push_bytes(bytes, frame_extra_crc, |f| out.push(decoded(f)));
}

fuzz_target!(|data: &[u8]| {
    let probe_set = probes();
    assert!(probe_set.iter().all(|f| !f[1..].contains(&0xFD)), "a probe contains a start byte");
    let f = &probe_set[data.first().map_or(0, |b| usize::from(*b) % probe_set.len())];

    // Invariants 1-4.
    let mut p = FrameParser::new();
    let mut out = Vec::new();
    push(&mut p, data, &mut out);
    assert_eq!(p.stats().frames_ok as usize, out.len());
    assert!(p.work() <= WORK_PER_BYTE * data.len() as u64, "work {} for {} bytes", p.work(), data.len());
    // Per byte of F: frames decoded and signed frames refused on that byte.
    let mut events = Vec::with_capacity(f.len());
    for &b in f.iter() {
        let (n0, r0) = (out.len(), p.stats().signed_refused);
        push(&mut p, &[b], &mut out);
        events.push((out.len() - n0, (p.stats().signed_refused - r0) as usize));
    }
    let first = events.iter().position(|&(d, r)| d + r > 0);
    let Some(first) = first else { panic!("no frame ended while the probe was pushed") };
    if first == f.len() - 1 && events[first].0 == 1 {
        let got = &out[out.len() - 1];
        if got.3 == f.len() {
            assert_eq!(got, &expected(f), "the probe decoded wrong");
        } else {
            assert!(got.3 > f.len(), "a shorter frame than the probe ended on its last byte");
        }
    }
    assert_eq!(p.buffered(), 0, "bytes left in the buffer after the probe");
    let total = (data.len() + f.len()) as u64;
    assert!(p.work() <= WORK_PER_BYTE * total, "work {} for {total} bytes", p.work());

    // Invariant 5.
    let mut p = FrameParser::new();
    let mut out = Vec::new();
    push(&mut p, data, &mut out);
    push(&mut p, &[0; MAX_FRAME_LEN], &mut out);
    assert_eq!(p.buffered(), 0, "a gap of MAX_FRAME_LEN non-start bytes did not empty the buffer");
    let before = out.len();
    push(&mut p, f, &mut out);
    assert_eq!(&out[before..], &[expected(f)][..]);
});
