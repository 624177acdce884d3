//! SBUS receiver byte stream → channel frames, one byte at a time, with a byte timestamp.
//!
//! Frame: 25 bytes at 100 000 Bd 8E2, inverted on the wire (the F405 board's SBUS pad has an
//! inverter; see `docs/rc.md`): header 0x0F, 22 bytes = 16 channels × 11 bits LSB first
//! ([`crate::rc::unpack_11bit`]), a flags byte (bit 0 digital channel 17, bit 1 channel 18,
//! bit 2 frame lost, bit 3 failsafe) and a footer: 0x00, or for SBUS2 receivers 0x04 / 0x14 /
//! 0x24 / 0x34 (the telemetry slot). Channel values → µs as Betaflight does (`5·v/8 + 880`:
//! the Futaba range 352..1696 ↔ 1100..1940 µs, centre 1024 ↔ 1520 µs, [`ticks_to_us`]);
//! digital channels 17/18 → 1000 / 2000 µs.
//!
//! **Resync.** Frames come every 7–14 ms with no bytes in between except, on SBUS2, a few
//! telemetry-slot bytes about 2 ms after a frame. A byte arriving more than [`GAP_US`] (3 ms;
//! one byte takes 120 µs) after the previous one starts a new frame (PX4's rule). Without a
//! timestamp gap the decoder still resyncs by content: when 25 bytes are buffered and the footer
//! is wrong, it drops bytes up to the next 0x0F inside the buffer and looks again. **Bounded**:
//! at most [`FRAME_LEN`] drop steps (each moves < 25 bytes) per byte; no allocation, no panics.
//!
//! **Why hand-written** (crates checked 2026-12: `sbus` 0.2.2 — last release 2020, an
//! `arraydeque` buffer; `sbus-rs` 0.1 — a streaming parser without timestamps; `uf-sbus` 0.1):
//! none resyncs on the inter-frame gap, which needs the byte timestamp; the decoder is ~100 lines.
//!
//! May import: [`crate::rc`] (its types).

use super::{unpack_11bit, RawChannels, MAX_CHANNELS};

/// Bytes in a frame.
pub const FRAME_LEN: usize = 25;
/// Header byte.
pub const HEADER: u8 = 0x0F;
/// A byte this long after the previous one (µs) starts a new frame.
pub const GAP_US: u64 = 3_000;
/// Flags bit: digital channel 17.
pub const FLAG_CH17: u8 = 0x01;
/// Flags bit: digital channel 18.
pub const FLAG_CH18: u8 = 0x02;
/// Flags bit: the receiver lost a frame.
pub const FLAG_FRAME_LOST: u8 = 0x04;
/// Flags bit: the receiver is in failsafe.
pub const FLAG_FAILSAFE: u8 = 0x08;

/// Whether `b` is a valid footer (SBUS 0x00, SBUS2 0x04/0x14/0x24/0x34).
pub const fn is_footer(b: u8) -> bool {
    matches!(b, 0x00 | 0x04 | 0x14 | 0x24 | 0x34)
}

/// SBUS channel value (11 bits) → µs: `5·v/8 + 880` (Betaflight `sbusChannelsReadRawRC`).
pub fn ticks_to_us(ticks: u16) -> u16 {
    (5 * u32::from(ticks & 0x7FF) / 8 + 880) as u16
}

/// Decoder counters (wrapping).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SbusStats {
    /// Frames decoded.
    pub frames: u32,
    /// 25 bytes from a header without a valid footer.
    pub footer_errors: u32,
    /// Partial frames dropped by the [`GAP_US`] rule.
    pub gap_resets: u32,
    /// Bytes dropped while looking for a frame (includes SBUS2 telemetry-slot bytes).
    pub bytes_dropped: u32,
    /// Decoded frames with the frame-lost flag.
    pub lost_flags: u32,
    /// Decoded frames with the failsafe flag.
    pub failsafe_flags: u32,
}

/// Streaming SBUS decoder (see the module docs). 25 bytes of buffer + counters.
#[derive(Clone, Debug)]
pub struct SbusDecoder {
    buf: [u8; FRAME_LEN],
    len: usize,
    last_byte_us: Option<u64>,
    stats: SbusStats,
}

impl Default for SbusDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl SbusDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            buf: [0; FRAME_LEN],
            len: 0,
            last_byte_us: None,
            stats: SbusStats {
                frames: 0,
                footer_errors: 0,
                gap_resets: 0,
                bytes_dropped: 0,
                lost_flags: 0,
                failsafe_flags: 0,
            },
        }
    }

    /// Counters since start.
    pub fn stats(&self) -> SbusStats {
        self.stats
    }

    /// Feeds one byte received at `t_us` (controller clock). Returns a frame when this byte
    /// completes one.
    pub fn push(&mut self, byte: u8, t_us: u64) -> Option<RawChannels> {
        if let Some(last) = self.last_byte_us {
            if self.len > 0 && t_us.saturating_sub(last) > GAP_US {
                self.stats.gap_resets = self.stats.gap_resets.wrapping_add(1);
                self.drop_bytes(self.len);
            }
        }
        self.last_byte_us = Some(t_us);
        if self.len == 0 && byte != HEADER {
            self.stats.bytes_dropped = self.stats.bytes_dropped.wrapping_add(1);
            return None;
        }
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = byte;
            self.len += 1;
        }
        // Each pass decodes, waits for more bytes, or drops at least one byte.
        for _ in 0..=FRAME_LEN {
            if self.len < FRAME_LEN {
                return None;
            }
            let frame = self.buf;
            if frame[0] == HEADER && is_footer(frame[24]) {
                self.len = 0;
                return Some(self.decode(&frame));
            }
            self.stats.footer_errors = self.stats.footer_errors.wrapping_add(1);
            let next = frame.iter().skip(1).position(|&b| b == HEADER).map_or(FRAME_LEN, |i| i + 1);
            self.drop_bytes(next);
        }
        None
    }

    /// Feeds `bytes` (all read at `t_us`) and hands every decoded frame to `f`.
    pub fn push_slice(&mut self, bytes: &[u8], t_us: u64, mut f: impl FnMut(RawChannels)) {
        for &b in bytes {
            if let Some(frame) = self.push(b, t_us) {
                f(frame);
            }
        }
    }

    fn drop_bytes(&mut self, n: usize) {
        let n = n.min(self.len);
        self.stats.bytes_dropped = self.stats.bytes_dropped.wrapping_add(n as u32);
        self.buf.copy_within(n..self.len, 0);
        self.len -= n;
    }

    fn decode(&mut self, frame: &[u8; FRAME_LEN]) -> RawChannels {
        let mut packed = [0u8; 22];
        packed.copy_from_slice(&frame[1..23]);
        let flags = frame[23];
        let mut us = [0u16; MAX_CHANNELS];
        for (o, t) in us.iter_mut().zip(unpack_11bit(&packed)) {
            *o = ticks_to_us(t);
        }
        us[16] = if flags & FLAG_CH17 != 0 { 2000 } else { 1000 };
        us[17] = if flags & FLAG_CH18 != 0 { 2000 } else { 1000 };
        let failsafe = flags & FLAG_FAILSAFE != 0;
        let frame_lost = flags & FLAG_FRAME_LOST != 0;
        self.stats.frames = self.stats.frames.wrapping_add(1);
        if failsafe {
            self.stats.failsafe_flags = self.stats.failsafe_flags.wrapping_add(1);
        }
        if frame_lost {
            self.stats.lost_flags = self.stats.lost_flags.wrapping_add(1);
        }
        RawChannels { us, count: MAX_CHANNELS as u8, failsafe, frame_lost }
    }
}

/// Encodes a frame from 16 channel values (11 bits; higher bits ignored), a flags byte and a
/// footer: for tests, the simulator and fuzz seeds.
pub fn encode(ticks: &[u16; 16], flags: u8, footer: u8) -> [u8; FRAME_LEN] {
    let mut f = [0u8; FRAME_LEN];
    f[0] = HEADER;
    let mut acc: u32 = 0;
    let mut bits = 0u32;
    let mut out = f.iter_mut().skip(1).take(22);
    for &t in ticks {
        acc |= u32::from(t & 0x7FF) << bits;
        bits += 11;
        while bits >= 8 {
            if let Some(o) = out.next() {
                *o = acc as u8;
            }
            acc >>= 8;
            bits -= 8;
        }
    }
    f[23] = flags;
    f[24] = footer;
    f
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// A logic-analyser capture of a Futaba R7008SB receiver's SBUS2 output: PX4-Autopilot
    /// `src/lib/rc/rc_tests/test_data/sbus2_r7008SB.txt` (commit d537a1b6), its first 0.138 s
    /// as (time µs, byte). It starts mid-frame, has SBUS2 footers 0x14/0x24/0x34/0x04,
    /// telemetry-slot bytes ~2 ms after the 0x04 frames, and one frame missing a byte (at 60 ms).
    const PX4_SBUS2_CAPTURE: &[(u64, u8)] = &[
        (120, 0x11),
        (240, 0x04),
        (360, 0x20),
        (480, 0xA8),
        (600, 0x01),
        (720, 0x08),
        (840, 0x16),
        (960, 0x50),
        (1080, 0x03),
        (1200, 0x10),
        (1320, 0x80),
        (1440, 0x00),
        (1560, 0x04),
        (15001, 0x0F),
        (15121, 0x11),
        (15241, 0x04),
        (15361, 0x20),
        (15481, 0xA8),
        (15601, 0x01),
        (15721, 0x08),
        (15841, 0x16),
        (15961, 0x50),
        (16081, 0x03),
        (16201, 0x10),
        (16321, 0x80),
        (16441, 0x00),
        (16561, 0x04),
        (16681, 0x20),
        (16801, 0x00),
        (16921, 0x01),
        (17041, 0x08),
        (17161, 0x40),
        (17281, 0x00),
        (17401, 0x02),
        (17521, 0x10),
        (17641, 0x80),
        (17761, 0x00),
        (17881, 0x14),
        (30001, 0x0F),
        (30121, 0x11),
        (30241, 0x04),
        (30361, 0x20),
        (30481, 0xA8),
        (30601, 0x01),
        (30721, 0x08),
        (30841, 0x16),
        (30961, 0x50),
        (31081, 0x03),
        (31201, 0x10),
        (31321, 0x80),
        (31441, 0x00),
        (31561, 0x04),
        (31681, 0x20),
        (31801, 0x00),
        (31921, 0x01),
        (32041, 0x08),
        (32161, 0x40),
        (32281, 0x00),
        (32401, 0x02),
        (32521, 0x10),
        (32641, 0x80),
        (32761, 0x00),
        (32881, 0x24),
        (45002, 0x0F),
        (45122, 0x11),
        (45242, 0x04),
        (45362, 0x20),
        (45482, 0xA8),
        (45602, 0x01),
        (45722, 0x08),
        (45842, 0x16),
        (45962, 0x50),
        (46082, 0x03),
        (46202, 0x10),
        (46322, 0x80),
        (46442, 0x00),
        (46562, 0x04),
        (46682, 0x20),
        (46802, 0x00),
        (46922, 0x01),
        (47042, 0x08),
        (47162, 0x40),
        (47282, 0x00),
        (47402, 0x02),
        (47522, 0x10),
        (47642, 0x80),
        (47762, 0x00),
        (47882, 0x34),
        (60002, 0x0F),
        (60122, 0x11),
        (60242, 0x04),
        (60362, 0x20),
        (60482, 0xA8),
        (60602, 0x01),
        (60722, 0x08),
        (60842, 0x16),
        (60963, 0x50),
        (61083, 0x03),
        (61203, 0x10),
        (61323, 0x80),
        (61563, 0x04),
        (61683, 0x20),
        (61803, 0x00),
        (61923, 0x01),
        (62043, 0x08),
        (62163, 0x40),
        (62283, 0x00),
        (62403, 0x02),
        (62523, 0x10),
        (62643, 0x80),
        (62763, 0x00),
        (62883, 0x04),
        (65033, 0x03),
        (65153, 0xC0),
        (65273, 0x2E),
        (75003, 0x0F),
        (75123, 0x11),
        (75243, 0x04),
        (75363, 0x20),
        (75483, 0xA8),
        (75603, 0x01),
        (75723, 0x08),
        (75843, 0x16),
        (75963, 0x50),
        (76083, 0x03),
        (76203, 0x10),
        (76323, 0x80),
        (76443, 0x00),
        (76563, 0x04),
        (76683, 0x20),
        (76803, 0x00),
        (76923, 0x01),
        (77043, 0x08),
        (77163, 0x40),
        (77283, 0x00),
        (77403, 0x02),
        (77523, 0x10),
        (77643, 0x80),
        (77763, 0x00),
        (77883, 0x14),
        (90004, 0x0F),
        (90124, 0x11),
        (90244, 0x04),
        (90364, 0x20),
        (90484, 0xA8),
        (90604, 0x01),
        (90724, 0x08),
        (90844, 0x16),
        (90964, 0x50),
        (91084, 0x03),
        (91204, 0x10),
        (91324, 0x80),
        (91444, 0x00),
        (91564, 0x04),
        (91684, 0x20),
        (91804, 0x00),
        (91924, 0x01),
        (92044, 0x08),
        (92164, 0x40),
        (92284, 0x00),
        (92404, 0x02),
        (92524, 0x10),
        (92644, 0x80),
        (92764, 0x00),
        (92884, 0x24),
        (105014, 0x0F),
        (105134, 0x11),
        (105254, 0x04),
        (105374, 0x20),
        (105494, 0xA8),
        (105614, 0x01),
        (105734, 0x08),
        (105854, 0x16),
        (105974, 0x50),
        (106094, 0x03),
        (106214, 0x10),
        (106334, 0x80),
        (106454, 0x00),
        (106574, 0x04),
        (106694, 0x20),
        (106814, 0x00),
        (106934, 0x01),
        (107054, 0x08),
        (107174, 0x40),
        (107294, 0x00),
        (107414, 0x02),
        (107534, 0x10),
        (107654, 0x80),
        (107774, 0x00),
        (107894, 0x34),
        (120005, 0x0F),
        (120125, 0x11),
        (120245, 0x04),
        (120365, 0x20),
        (120485, 0xA8),
        (120605, 0x01),
        (120725, 0x08),
        (120845, 0x16),
        (120965, 0x50),
        (121085, 0x03),
        (121205, 0x10),
        (121325, 0x80),
        (121445, 0x00),
        (121565, 0x04),
        (121685, 0x20),
        (121805, 0x00),
        (121925, 0x01),
        (122045, 0x08),
        (122165, 0x40),
        (122285, 0x00),
        (122405, 0x02),
        (122525, 0x10),
        (122645, 0x80),
        (122765, 0x00),
        (122885, 0x04),
        (125035, 0x03),
        (125155, 0xC4),
        (125275, 0x00),
        (135006, 0x0F),
        (135126, 0x11),
        (135246, 0x04),
        (135366, 0x20),
        (135486, 0xA8),
        (135606, 0x01),
        (135726, 0x08),
        (135846, 0x16),
        (135966, 0x50),
        (136086, 0x03),
        (136206, 0x10),
        (136326, 0x80),
        (136446, 0x00),
        (136566, 0x04),
        (136686, 0x20),
        (136806, 0x00),
        (136926, 0x01),
        (137046, 0x08),
        (137166, 0x40),
        (137286, 0x00),
        (137406, 0x02),
        (137526, 0x10),
        (137646, 0x80),
        (137766, 0x00),
        (137886, 0x14),
    ];

    fn channels(ticks: u16) -> u16 {
        ticks_to_us(ticks)
    }

    /// Never panics on any bytes at any times, and after any garbage a pause longer than
    /// [`GAP_US`] always lets the next good frame through, exactly (fixed seed).
    #[test]
    fn proptest_garbage_then_gap_then_the_good_frame() {
        use proptest::collection::vec;
        use proptest::prelude::*;
        use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
        let mut runner = TestRunner::new_with_rng(
            Config { cases: 2000, failure_persistence: None, ..Config::default() },
            TestRng::deterministic_rng(RngAlgorithm::ChaCha),
        );
        let strategy = (vec((any::<u8>(), 0u64..5_000), 0..300), vec(0u16..2048, 16), 0u8..16, 0usize..5);
        runner
            .run(&strategy, |(garbage, ticks, flags, footer)| {
                let ticks: [u16; 16] = ticks.try_into().unwrap();
                let mut d = SbusDecoder::new();
                let mut t = 0u64;
                for &(b, dt) in &garbage {
                    t += dt;
                    let _ = d.push(b, t);
                }
                let footer = [0x00, 0x04, 0x14, 0x24, 0x34][footer];
                let mut out = Vec::new();
                d.push_slice(&encode(&ticks, flags, footer), t + GAP_US + 1, |f| out.push(f));
                prop_assert_eq!(out.len(), 1);
                let f = out[0];
                prop_assert_eq!(f.us[..16].to_vec(), ticks.map(ticks_to_us).to_vec());
                prop_assert_eq!(
                    (f.failsafe, f.frame_lost),
                    (flags & FLAG_FAILSAFE != 0, flags & FLAG_FRAME_LOST != 0)
                );
                Ok(())
            })
            .unwrap();
    }

    #[test]
    fn px4_capture_decodes_every_whole_frame_and_drops_the_rest() {
        let mut d = SbusDecoder::new();
        let mut out = Vec::new();
        for &(t, b) in PX4_SBUS2_CAPTURE {
            if let Some(f) = d.push(b, t) {
                out.push((t, f));
            }
        }
        // Whole frames start at 15, 30, 45, 75, 90, 105, 120 and 135 ms; the 60 ms one lacks a
        // byte, the 0.1 ms fragment has no header.
        let starts: Vec<u64> = out.iter().map(|(t, _)| t / 15_000).collect();
        assert_eq!(starts, [1, 2, 3, 5, 6, 7, 8, 9]);
        let expect =
            [1041, 1024, 1696, 1024, 352, 1696, 1024, 1024, 1024, 1024, 1024, 1024, 1024, 1024, 1024, 1024]
                .map(channels);
        for (_, f) in &out {
            assert_eq!(&f.us[..16], &expect);
            assert_eq!(&f.us[16..], &[1000, 1000]);
            assert!(!f.failsafe && !f.frame_lost);
        }
        assert_eq!(&expect[..6], &[1530, 1520, 1940, 1520, 1100, 1940]);
        let s = d.stats();
        assert_eq!(s.frames, 8);
        // The 60 ms frame is the one footer error; no partial frame meets a gap here (the
        // fragment at the start has no header), so the gap rule is exercised by the tests below.
        assert_eq!((s.footer_errors, s.gap_resets), (1, 0), "{s:?}");
    }

    #[test]
    fn the_capture_without_timestamps_still_resyncs_by_content() {
        // All bytes at one instant: only the header/footer rule. The 60 ms frame (24 bytes) is
        // completed by the telemetry byte 0x03, fails (no other 0x0F inside it), the telemetry
        // bytes are dropped and the next frames decode again: the same 8 frames.
        let mut d = SbusDecoder::new();
        let n = PX4_SBUS2_CAPTURE.iter().filter(|&&(_, b)| d.push(b, 0).is_some()).count();
        assert_eq!(n, 8, "{:?}", d.stats());
    }

    #[test]
    fn flags_failsafe_frame_lost_and_digital_channels() {
        let mut d = SbusDecoder::new();
        let f = encode(&[1024; 16], FLAG_CH17 | FLAG_FAILSAFE | FLAG_FRAME_LOST, 0x00);
        let mut got = None;
        d.push_slice(&f, 0, |c| got = Some(c));
        let c = got.unwrap();
        assert!(c.failsafe && c.frame_lost);
        assert_eq!((c.us[16], c.us[17]), (2000, 1000));
        assert_eq!(c.channel(17), Some(2000));
        assert_eq!(c.channel(19), None);
        assert_eq!(c.channel(0), None);
        let s = d.stats();
        assert_eq!((s.failsafe_flags, s.lost_flags), (1, 1));
    }

    #[test]
    fn scaling_range_ends() {
        assert_eq!(ticks_to_us(0), 880);
        assert_eq!(ticks_to_us(2047), 2159);
        assert_eq!(ticks_to_us(172), 987);
        assert_eq!(ticks_to_us(1811), 2011);
    }

    #[test]
    fn gap_splits_a_frame_and_split_chunks_join() {
        let f = encode(&[300; 16], 0, 0x00);
        // Split in two chunks 1 ms apart: one frame.
        let mut d = SbusDecoder::new();
        let mut n = 0;
        d.push_slice(&f[..10], 0, |_| n += 1);
        d.push_slice(&f[10..], 1_000, |_| n += 1);
        assert_eq!(n, 1);
        // The second half 4 ms late: the first half is dropped, the second half is not a frame,
        // the next whole frame decodes.
        let mut d = SbusDecoder::new();
        let mut n = 0;
        d.push_slice(&f[..10], 0, |_| n += 1);
        d.push_slice(&f[10..], 4_000, |_| n += 1);
        d.push_slice(&f, 20_000, |_| n += 1);
        assert_eq!(n, 1);
        assert_eq!(d.stats().gap_resets, 1);
    }

    #[test]
    fn all_footers_accepted_others_refused() {
        for footer in [0x00, 0x04, 0x14, 0x24, 0x34] {
            let mut d = SbusDecoder::new();
            let mut n = 0;
            d.push_slice(&encode(&[1000; 16], 0, footer), 0, |_| n += 1);
            assert_eq!(n, 1, "{footer:#x}");
        }
        for footer in [0x01, 0x0F, 0x44, 0xFF] {
            let mut d = SbusDecoder::new();
            let mut n = 0;
            d.push_slice(&encode(&[1000; 16], 0, footer), 0, |_| n += 1);
            assert_eq!(n, 0, "{footer:#x}");
        }
    }
}
