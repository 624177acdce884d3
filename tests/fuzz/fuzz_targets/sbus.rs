//! Fuzz target `sbus`: arbitrary bytes, at arbitrary times, into the SBUS receiver
//! (`parapet_core::rc::sbus` decoder + `rc::map` channel map + the RC-loss monitor).
//!
//! Input: pairs `(byte, dt)`; byte `i` arrives `dt · 25 µs` after byte `i − 1` (back-to-back,
//! the 120 µs byte time, and > `GAP_US` gaps all occur). Invariants on every input `X`:
//! 1. no panic (overflow checks and debug assertions are on);
//! 2. counters agree with what came out (`stats().frames` = frames delivered, failsafe flags);
//! 3. every frame has 18 channels in 880..=2159 µs (17/18: 1000 or 2000); every [`RcInput`]
//!    has finite sticks in [−1, 1], throttle in [0, 1]; a failsafe frame is reported lost;
//! 4. `X`, a pause > `GAP_US`, then a good frame `F`: exactly `F` comes out of it.
#![no_main]

use libfuzzer_sys::fuzz_target;
use parapet_core::rc::map::{RcMonitor, RcParams, SbusReceiver};
use parapet_core::rc::sbus::{encode, ticks_to_us, SbusDecoder, GAP_US};
use parapet_core::rc::RcLost;

fuzz_target!(|data: &[u8]| {
    let p = RcParams::default();
    let mut d = SbusDecoder::new();
    let mut rx = SbusReceiver::default();
    let mut mon = RcMonitor::new();
    let (mut delivered, mut failsafe) = (0u32, 0u32);
    let mut t = 0u64;
    for pair in data.chunks(2) {
        let (b, dt) = (pair[0], pair.get(1).copied().unwrap_or(0));
        t += u64::from(dt) * 25;
        if let Some(c) = d.push(b, t) {
            delivered += 1;
            failsafe += u32::from(c.failsafe);
            assert_eq!(c.count, 18);
            assert!(c.us[..16].iter().all(|&us| (880..=2159).contains(&us)), "{c:?}");
            assert!(c.us[16..].iter().all(|&us| us == 1000 || us == 2000), "{c:?}");
        }
        rx.push_slice(&[b], t, &p, |i| {
            for s in [i.roll, i.pitch, i.yaw] {
                assert!(s.is_finite() && (-1.0..=1.0).contains(&s), "{i:?}");
            }
            assert!((0.0..=1.0).contains(&i.throttle), "{i:?}");
            if i.failsafe {
                assert_eq!(i.lost, Some(RcLost::ReceiverFailsafe));
            }
            mon.on_input(&i);
        });
        let o = mon.input(t, 0.5, &p);
        assert!((0.0..=1.0).contains(&o.throttle) && o.roll.is_finite());
    }
    let s = d.stats();
    assert_eq!((s.frames, s.failsafe_flags), (delivered, failsafe));
    // 4: a pause, then a good frame.
    let ticks: [u16; 16] = core::array::from_fn(|k| (k as u16 * 173 + data.len() as u16) % 2048);
    let mut out = Vec::new();
    d.push_slice(&encode(&ticks, 0, 0x00), t + GAP_US + 1, |f| out.push(f));
    assert_eq!(out.len(), 1, "{:?}", d.stats());
    assert_eq!(out[0].us[..16], ticks.map(ticks_to_us));
});
