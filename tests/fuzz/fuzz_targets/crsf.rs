//! Fuzz target `crsf`: arbitrary bytes, at arbitrary times, into the CRSF receiver
//! (`parapet_core::rc::crsf` decoder + `rc::map` channel map + the RC-loss monitor).
//!
//! Input: pairs `(byte, dt)`; byte `i` arrives `dt · 40 µs` after byte `i − 1` (so both the
//! back-to-back and the > `GAP_US` cases occur). Invariants checked on every input `X`:
//! 1. no panic (overflow checks and debug assertions are on);
//! 2. counters agree with what came out (`stats().frames` = frames delivered);
//! 3. every RC frame has 16 channels within the 11-bit range's µs (881..=2159); every
//!    [`RcInput`] has finite sticks in [−1, 1], throttle in [0, 1], link quality ≤ 100, and the
//!    monitor's output is the same kind of value (lost or not);
//! 4. `X`, a pause > `GAP_US`, then a good RC frame `F`: exactly `F` comes out of it.
#![no_main]

use libfuzzer_sys::fuzz_target;
use parapet_core::rc::crsf::{encode_channels, ticks_to_us, CrsfDecoder, CrsfFrame, GAP_US};
use parapet_core::rc::map::{CrsfReceiver, RcMonitor, RcParams};
use parapet_core::rc::RcInput;

fn check_input(i: &RcInput) {
    for s in [i.roll, i.pitch, i.yaw] {
        assert!(s.is_finite() && (-1.0..=1.0).contains(&s), "{i:?}");
    }
    assert!((0.0..=1.0).contains(&i.throttle), "{i:?}");
    assert!(i.link_quality <= 100, "{i:?}");
}

fuzz_target!(|data: &[u8]| {
    let p = RcParams::default();
    let mut d = CrsfDecoder::new();
    let mut rx = CrsfReceiver::default();
    let mut mon = RcMonitor::new();
    let mut delivered = 0u32;
    let mut t = 0u64;
    for pair in data.chunks(2) {
        let (b, dt) = (pair[0], pair.get(1).copied().unwrap_or(0));
        t += u64::from(dt) * 40;
        let mut next = d.push(b, t);
        while let Some(f) = next {
            delivered += 1;
            if let CrsfFrame::Channels(c) = f {
                assert_eq!(c.count, 16);
                assert!(c.us[..16].iter().all(|&us| (881..=2159).contains(&us)), "{c:?}");
            }
            next = d.poll();
        }
        rx.push_slice(&[b], t, &p, |i| {
            check_input(&i);
            mon.on_input(&i);
        });
        check_input(&mon.input(t, 0.5, &p));
    }
    assert_eq!(d.stats().frames, delivered);
    // 4: a pause, then a good frame.
    let ticks: [u16; 16] = core::array::from_fn(|k| (k as u16 * 131 + data.len() as u16) % 2048);
    let mut out = Vec::new();
    d.push_slice(&encode_channels(&ticks), t + GAP_US + 1, |f| out.push(f));
    assert_eq!(out.len(), 1, "{:?}", d.stats());
    match out[0] {
        CrsfFrame::Channels(c) => assert_eq!(c.us[..16], ticks.map(ticks_to_us)),
        other => panic!("{other:?}"),
    }
});
