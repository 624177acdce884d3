//! CRSF (TBS Crossfire / ExpressLRS) receiver byte stream → RC channel frames and link
//! statistics, one byte at a time.
//!
//! Frame: `[address] [len] [type] [payload …] [crc]`, `len` = bytes after it (type + payload +
//! crc, 2..=62, so a frame is at most [`FRAME_MAX`] = 64 bytes), CRC-8 DVB-S2 (polynomial
//! 0xD5, initial 0) over type and payload. 420 000 Bd 8N1 on the receiver's UART. The address
//! byte is accepted as sync when it is 0xC8 (flight controller, what receivers send), 0xEE
//! (transmitter module, EdgeTX), 0xEA (radio) or 0xEC (receiver) ([`is_sync`]).
//!
//! Decoded types: RC_CHANNELS_PACKED (0x16, 22-byte payload: 16 × 11 bits, 172..1811 ↔
//! 988..2012 µs, [`ticks_to_us`]) and LINK_STATISTICS (0x14, 10 bytes, [`LinkStats`]). Frames
//! of other types with a good CRC are counted ([`CrsfStats::ignored`]) and skipped; an RC or
//! link frame of the wrong length is a length error.
//!
//! **Resync.** The decoder keeps the bytes of the frame being received. Whenever the buffered
//! bytes cannot be a frame (no sync byte first, impossible length, bad CRC) it drops bytes up to
//! the next sync byte *inside the buffer* and looks again, so a false sync in garbage costs at
//! most the frame it overlaps; and a byte that arrives more than [`GAP_US`] after the previous
//! one starts afresh (a receiver that went quiet mid-frame). **Bounded**: one [`CrsfDecoder::push`]
//! does at most [`FRAME_MAX`] drop steps (each moves < 64 bytes) and one CRC over ≤ 61 bytes;
//! no allocation, no panics. A frame still complete in the buffer after one is returned is
//! delivered by [`CrsfDecoder::poll`] ([`CrsfDecoder::push_slice`] does both).
//!
//! A CRC-8 passes one random frame in 256: a false sync inside garbage can, that rarely, yield
//! a bogus frame (every CRSF decoder shares this; the RC map then clamps the values and the
//! mode machine's checks apply).
//!
//! **Why hand-written** (crates checked 2026-12: `crsf` 2.0.1 — last release 2024-04, a 1 KiB
//! ring buffer per parser; `uf-crsf` 0.6 — API "might change at any time", two more
//! dependencies (`crc`, `num_enum`); `ados-crsf-codec` 0.1 — needs `alloc`): none takes a byte
//! timestamp for the gap rule, and the F405 image has a few KiB of flash left; the two frame
//! types needed are ~150 lines here. Sources of the layout: the CRSF working group's
//! `crsf-wg/crsf` wiki (Message Format) and TBS's CRSF Rev07 document.
//!
//! May import: [`crate::rc`] (its types).

use super::{unpack_11bit, RawChannels, MAX_CHANNELS};

/// Largest frame: address + len + 62.
pub const FRAME_MAX: usize = 64;
/// Frame type RC_CHANNELS_PACKED.
pub const TYPE_RC_CHANNELS: u8 = 0x16;
/// Frame type LINK_STATISTICS.
pub const TYPE_LINK_STATISTICS: u8 = 0x14;
/// A byte this long after the previous one (µs) drops a partial frame (at 420 kBd a byte takes
/// 24 µs and a whole RC frame 620 µs; receivers send every 1–20 ms).
pub const GAP_US: u64 = 5_000;

/// Whether `b` starts a frame (see the module docs).
pub const fn is_sync(b: u8) -> bool {
    matches!(b, 0xC8 | 0xEE | 0xEA | 0xEC)
}

/// CRC-8 DVB-S2 (polynomial 0xD5, initial value 0, no reflection, no final xor).
pub fn crc8_dvb_s2(bytes: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 { (crc << 1) ^ 0xD5 } else { crc << 1 };
        }
    }
    crc
}

/// CRSF channel value (11-bit ticks) → µs: 172 ↔ 988, 992 ↔ 1500, 1811 ↔ 2012, linear
/// (1024/1639 µs per tick), rounded to the nearest µs. The whole 0..2047 range maps to
/// 881..2159 µs.
pub fn ticks_to_us(ticks: u16) -> u16 {
    let n = (i32::from(ticks) - 172) * 2048;
    let q = if n >= 0 { (n + 1639) / 3278 } else { (n - 1639) / 3278 };
    (988 + q).clamp(0, i32::from(u16::MAX)) as u16
}

/// LINK_STATISTICS (0x14): the receiver's view of the radio link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkStats {
    /// Uplink RSSI of antenna 1, dBm (the frame sends −dBm).
    pub uplink_rssi_ant1_dbm: i16,
    /// Uplink RSSI of antenna 2, dBm.
    pub uplink_rssi_ant2_dbm: i16,
    /// Uplink link quality, percent of packets received (0 = link lost).
    pub uplink_lq: u8,
    /// Uplink signal-to-noise ratio, dB.
    pub uplink_snr_db: i8,
    /// Active antenna (0 = antenna 1).
    pub active_antenna: u8,
    /// RF mode (packet-rate code of the link).
    pub rf_mode: u8,
    /// Uplink transmit power code.
    pub uplink_tx_power: u8,
    /// Downlink (telemetry) RSSI, dBm.
    pub downlink_rssi_dbm: i16,
    /// Downlink link quality, percent.
    pub downlink_lq: u8,
    /// Downlink SNR, dB.
    pub downlink_snr_db: i8,
}

impl LinkStats {
    /// RSSI of the active antenna, dBm.
    pub fn rssi_dbm(&self) -> i16 {
        if self.active_antenna == 0 {
            self.uplink_rssi_ant1_dbm
        } else {
            self.uplink_rssi_ant2_dbm
        }
    }

    fn parse(p: &[u8; 10]) -> Self {
        Self {
            uplink_rssi_ant1_dbm: -i16::from(p[0]),
            uplink_rssi_ant2_dbm: -i16::from(p[1]),
            uplink_lq: p[2],
            uplink_snr_db: p[3] as i8,
            active_antenna: p[4],
            rf_mode: p[5],
            uplink_tx_power: p[6],
            downlink_rssi_dbm: -i16::from(p[7]),
            downlink_lq: p[8],
            downlink_snr_db: p[9] as i8,
        }
    }
}

/// A decoded frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CrsfFrame {
    /// RC_CHANNELS_PACKED: 16 channels in µs (`count` 16; CRSF has no failsafe flag — receivers
    /// stop sending channels or report link quality 0).
    Channels(RawChannels),
    /// LINK_STATISTICS.
    Link(LinkStats),
}

/// Decoder counters (wrapping).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CrsfStats {
    /// Frames decoded (RC channels and link statistics).
    pub frames: u32,
    /// Frames with a bad CRC.
    pub crc_errors: u32,
    /// Impossible length byte, or an RC / link frame of the wrong length.
    pub length_errors: u32,
    /// Good frames of other types (telemetry, commands, …), skipped.
    pub ignored: u32,
    /// Partial frames dropped by the [`GAP_US`] rule.
    pub gap_resets: u32,
    /// Bytes dropped while looking for a frame.
    pub bytes_dropped: u32,
}

/// Streaming CRSF decoder (see the module docs). 64 bytes of buffer + counters.
#[derive(Clone, Debug)]
pub struct CrsfDecoder {
    buf: [u8; FRAME_MAX],
    len: usize,
    last_byte_us: Option<u64>,
    stats: CrsfStats,
}

impl Default for CrsfDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl CrsfDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            buf: [0; FRAME_MAX],
            len: 0,
            last_byte_us: None,
            stats: CrsfStats {
                frames: 0,
                crc_errors: 0,
                length_errors: 0,
                ignored: 0,
                gap_resets: 0,
                bytes_dropped: 0,
            },
        }
    }

    /// Counters since start.
    pub fn stats(&self) -> CrsfStats {
        self.stats
    }

    /// Feeds one byte received at `t_us` (controller clock; the time the byte, or the chunk it
    /// came in, was read). Returns a frame when this byte completes one.
    pub fn push(&mut self, byte: u8, t_us: u64) -> Option<CrsfFrame> {
        if let Some(last) = self.last_byte_us {
            if self.len > 0 && t_us.saturating_sub(last) > GAP_US {
                self.stats.gap_resets = self.stats.gap_resets.wrapping_add(1);
                self.drop_bytes(self.len);
            }
        }
        self.last_byte_us = Some(t_us);
        if self.len == 0 && !is_sync(byte) {
            self.stats.bytes_dropped = self.stats.bytes_dropped.wrapping_add(1);
            return None;
        }
        if self.len >= FRAME_MAX {
            // Unreachable (a complete frame is decided at its last byte), kept as a guard.
            self.drop_to_next_sync();
        }
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = byte;
            self.len += 1;
        }
        self.poll()
    }

    /// Feeds `bytes` (all read at `t_us`) and hands every decoded frame to `f`.
    pub fn push_slice(&mut self, bytes: &[u8], t_us: u64, mut f: impl FnMut(CrsfFrame)) {
        for &b in bytes {
            let mut next = self.push(b, t_us);
            while let Some(frame) = next {
                f(frame);
                next = self.poll();
            }
        }
    }

    /// A frame already complete in the buffer (after a resync), if any; no new byte needed.
    pub fn poll(&mut self) -> Option<CrsfFrame> {
        // Each pass drops at least one byte or returns: at most FRAME_MAX + 1 passes.
        for _ in 0..=FRAME_MAX {
            let head = self.buf.get(..self.len)?;
            let (&first, rest) = head.split_first()?;
            if !is_sync(first) {
                self.drop_to_next_sync();
                continue;
            }
            let &len = rest.first()?;
            let len = usize::from(len);
            if !(2..=FRAME_MAX - 2).contains(&len) {
                self.stats.length_errors = self.stats.length_errors.wrapping_add(1);
                self.drop_to_next_sync();
                continue;
            }
            let total = len + 2;
            if self.len < total {
                return None;
            }
            // type + payload, then the CRC byte.
            let (body, crc) = match (self.buf.get(2..total - 1), self.buf.get(total - 1)) {
                (Some(b), Some(&c)) => (b, c),
                _ => return None,
            };
            if crc8_dvb_s2(body) != crc {
                self.stats.crc_errors = self.stats.crc_errors.wrapping_add(1);
                self.drop_to_next_sync();
                continue;
            }
            let decoded = decode_body(body);
            self.consume(total);
            match decoded {
                Decoded::Frame(f) => {
                    self.stats.frames = self.stats.frames.wrapping_add(1);
                    return Some(f);
                }
                Decoded::Other => self.stats.ignored = self.stats.ignored.wrapping_add(1),
                Decoded::BadLength => self.stats.length_errors = self.stats.length_errors.wrapping_add(1),
            }
        }
        None
    }

    /// Removes a decoded frame of `n` bytes from the front.
    fn consume(&mut self, n: usize) {
        let n = n.min(self.len);
        self.buf.copy_within(n..self.len, 0);
        self.len -= n;
    }

    /// Drops `n` bytes from the front, counted.
    fn drop_bytes(&mut self, n: usize) {
        self.stats.bytes_dropped = self.stats.bytes_dropped.wrapping_add(n as u32);
        self.consume(n);
    }

    /// Drops the first byte and everything up to the next sync byte in the buffer.
    fn drop_to_next_sync(&mut self) {
        let next = self
            .buf
            .get(1..self.len)
            .and_then(|rest| rest.iter().position(|&b| is_sync(b)))
            .map_or(self.len, |i| i + 1);
        self.drop_bytes(next.max(1));
    }
}

enum Decoded {
    Frame(CrsfFrame),
    Other,
    BadLength,
}

/// `body` = type byte + payload (CRC already checked).
fn decode_body(body: &[u8]) -> Decoded {
    let Some((&kind, payload)) = body.split_first() else {
        return Decoded::BadLength;
    };
    match kind {
        TYPE_RC_CHANNELS => match <&[u8; 22]>::try_from(payload) {
            Ok(p) => {
                let ticks = unpack_11bit(p);
                let mut us = [0u16; MAX_CHANNELS];
                for (o, t) in us.iter_mut().zip(ticks) {
                    *o = ticks_to_us(t);
                }
                Decoded::Frame(CrsfFrame::Channels(RawChannels {
                    us,
                    count: 16,
                    failsafe: false,
                    frame_lost: false,
                }))
            }
            Err(_) => Decoded::BadLength,
        },
        TYPE_LINK_STATISTICS => match <&[u8; 10]>::try_from(payload) {
            Ok(p) => Decoded::Frame(CrsfFrame::Link(LinkStats::parse(p))),
            Err(_) => Decoded::BadLength,
        },
        _ => Decoded::Other,
    }
}

/// Encodes an RC_CHANNELS_PACKED frame (address 0xC8) from 16 channel values in ticks
/// (0..2047; higher bits ignored): for tests, the simulator and fuzz seeds.
pub fn encode_channels(ticks: &[u16; 16]) -> [u8; 26] {
    let mut f = [0u8; 26];
    f[0] = 0xC8;
    f[1] = 24;
    f[2] = TYPE_RC_CHANNELS;
    let mut acc: u32 = 0;
    let mut bits = 0u32;
    let mut out = f.iter_mut().skip(3).take(22);
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
    f[25] = crc8_dvb_s2(&f[2..25]);
    f
}

/// Encodes a LINK_STATISTICS frame (address 0xC8) from its 10 payload bytes.
pub fn encode_link(payload: &[u8; 10]) -> [u8; 14] {
    let mut f = [0u8; 14];
    f[0] = 0xC8;
    f[1] = 12;
    f[2] = TYPE_LINK_STATISTICS;
    f[3..13].copy_from_slice(payload);
    f[13] = crc8_dvb_s2(&f[2..13]);
    f
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// Betaflight `src/test/unit/rx_crsf_unittest.cc` (`capturedData`, two RC frames recorded
    /// from a receiver; address byte 0x00 = broadcast) and its expected values: channels
    /// 1–4 = 189, 993, 978, 983 ticks = 999, 1501, 1492, 1495 µs; the second frame's ch 4 = 981.
    const BETAFLIGHT_CAPTURED: [[u8; 26]; 2] = [
        [
            0x00, 0x18, 0x16, 0xBD, 0x08, 0x9F, 0xF4, 0xAE, 0xF7, 0xBD, 0xEF, 0x7D, 0xEF, 0xFB, 0xAD, 0xFD,
            0x45, 0x2B, 0x5A, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x6C,
        ],
        [
            0x00, 0x18, 0x16, 0xBD, 0x08, 0x9F, 0xF4, 0xAA, 0xF7, 0xBD, 0xEF, 0x7D, 0xEF, 0xFB, 0xAD, 0xFD,
            0x45, 0x2B, 0x5A, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x94,
        ],
    ];

    /// An ExpressLRS frame as a handset sends it (address 0xEE), from the README of
    /// `kielerrr/CRSFv2-elrs` (a Crossfire TX test): sticks near centre (993, 988, 1063, 995
    /// ticks), AUX 1–2 low (173).
    const ELRS_EE_FRAME: [u8; 26] = [
        0xEE, 0x18, 0x16, 0xE1, 0xE3, 0xDE, 0x09, 0xC7, 0xD7, 0x8A, 0x56, 0x80, 0x0F, 0x7C, 0xE0, 0x03, 0x1F,
        0xF8, 0xC0, 0x07, 0x3E, 0xF0, 0x81, 0x0F, 0x7C, 0x36,
    ];

    /// Betaflight's `buadrateNegotiationFrame` (a 0x32 command frame, extended header): good CRC,
    /// not an RC frame.
    const BETAFLIGHT_COMMAND: [u8; 14] =
        [0xC8, 0x0C, 0x32, 0xC8, 0xEC, 0x0A, 0x70, 0x01, 0x00, 0x1E, 0x84, 0x80, 0x22, 0x72];

    fn feed(d: &mut CrsfDecoder, bytes: &[u8], t_us: u64) -> Vec<CrsfFrame> {
        let mut out = Vec::new();
        d.push_slice(bytes, t_us, |f| out.push(f));
        out
    }

    fn channels(f: &CrsfFrame) -> RawChannels {
        match f {
            CrsfFrame::Channels(c) => *c,
            other => panic!("not channels: {other:?}"),
        }
    }

    fn runner(cases: u32) -> proptest::test_runner::TestRunner {
        use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
        TestRunner::new_with_rng(
            Config { cases, failure_persistence: None, ..Config::default() },
            TestRng::deterministic_rng(RngAlgorithm::ChaCha),
        )
    }

    /// Never panics on any bytes at any times, and after any garbage a receiver pause longer
    /// than [`GAP_US`] always lets the next good frame through, exactly (fixed seed).
    #[test]
    fn proptest_garbage_then_gap_then_the_good_frame() {
        use proptest::collection::vec;
        use proptest::prelude::*;
        let strategy = (vec((any::<u8>(), 0u64..10_000), 0..300), vec(0u16..2048, 16), any::<bool>());
        runner(2000)
            .run(&strategy, |(garbage, ticks, pause)| {
                let ticks: [u16; 16] = ticks.try_into().unwrap();
                let mut d = CrsfDecoder::new();
                let mut t = 0u64;
                for &(b, dt) in &garbage {
                    t += dt;
                    let _ = d.push(b, t);
                    while d.poll().is_some() {}
                }
                let good = encode_channels(&ticks);
                let t_good = t + GAP_US + 1;
                let mut out = Vec::new();
                if pause {
                    out = feed(&mut d, &good, t_good);
                } else {
                    // Garbage without a sync byte needs no pause.
                    let mut d = CrsfDecoder::new();
                    for &(b, _) in garbage.iter().filter(|(b, _)| !is_sync(*b)) {
                        prop_assert!(d.push(b, 0).is_none());
                    }
                    out.extend(feed(&mut d, &good, 0));
                }
                prop_assert_eq!(out.len(), 1);
                prop_assert_eq!(channels(&out[0]).us[..16].to_vec(), ticks.map(ticks_to_us).to_vec());
                Ok(())
            })
            .unwrap();
    }

    /// With no pause at all, random garbage (sync bytes included) before a stream of good
    /// frames: how often is the first or the second good frame lost? Measured (printed) and
    /// bounded: a false sync can swallow at most the frames within 64 bytes of it, so the
    /// third good frame always decodes unless a false frame passes the CRC-8 (1 in 256).
    #[test]
    fn garbage_without_a_pause_costs_at_most_the_frames_it_overlaps() {
        use proptest::collection::vec;
        use proptest::prelude::*;
        let strategy = (vec(any::<u8>(), 1..200), vec(0u16..2048, 16));
        let [first, second, third, n] = [(); 4].map(|_| core::cell::Cell::new(0u32));
        runner(10_000)
            .run(&strategy, |(garbage, ticks)| {
                let ticks: [u16; 16] = ticks.try_into().unwrap();
                let good = encode_channels(&ticks);
                let mut d = CrsfDecoder::new();
                let _ = feed(&mut d, &garbage, 0);
                let got: Vec<bool> = (0..3)
                    .map(|_| {
                        feed(&mut d, &good, 0).iter().any(
                            |f| matches!(f, CrsfFrame::Channels(c) if c.us[..16] == ticks.map(ticks_to_us)),
                        )
                    })
                    .collect();
                n.set(n.get() + 1);
                first.set(first.get() + u32::from(got[0]));
                second.set(second.get() + u32::from(got[0] || got[1]));
                third.set(third.get() + u32::from(got[2]));
                Ok(())
            })
            .unwrap();
        let [first, second, third, n] = [first, second, third, n].map(|c| c.get());
        std::println!(
            "CRSF no-pause resync over {n} cases: 1st frame {first}, by the 2nd {second}, 3rd {third}"
        );
        assert!(third as f32 >= 0.99 * n as f32, "{third}/{n}");
    }

    #[test]
    fn crc_of_recorded_frames() {
        for f in &BETAFLIGHT_CAPTURED {
            assert_eq!(crc8_dvb_s2(&f[2..25]), f[25]);
        }
        assert_eq!(crc8_dvb_s2(&ELRS_EE_FRAME[2..25]), 0x36);
        assert_eq!(crc8_dvb_s2(&BETAFLIGHT_COMMAND[2..13]), 0x72);
        // The DVB-S2 check value: CRC of ASCII "123456789" is 0xBC.
        assert_eq!(crc8_dvb_s2(b"123456789"), 0xBC);
    }

    #[test]
    fn scaling_matches_the_protocol_and_betaflight() {
        assert_eq!(ticks_to_us(172), 988);
        assert_eq!(ticks_to_us(992), 1500);
        assert_eq!(ticks_to_us(1811), 2012);
        assert_eq!([189, 993, 978, 983].map(ticks_to_us), [999, 1501, 1492, 1495]);
        assert_eq!(ticks_to_us(0), 881);
        assert_eq!(ticks_to_us(2047), 2159);
    }

    #[test]
    fn betaflight_capture_decodes_with_a_receiver_address_and_is_ignored_as_broadcast() {
        // Betaflight's own byte-receive test expects the 0x00-addressed capture NOT to be taken
        // as a frame: it is a broadcast, not a receiver's frame. Same here.
        let mut d = CrsfDecoder::new();
        let mut stream = Vec::new();
        stream.extend_from_slice(&BETAFLIGHT_CAPTURED[0]);
        stream.extend_from_slice(&BETAFLIGHT_CAPTURED[1]);
        assert!(feed(&mut d, &stream, 0).is_empty());
        // With the receiver's sync byte (the CRC does not cover the address) both decode.
        let mut d = CrsfDecoder::new();
        for (k, f) in BETAFLIGHT_CAPTURED.iter().enumerate() {
            let mut f = *f;
            f[0] = 0xC8;
            let out = feed(&mut d, &f, 1000 * k as u64);
            assert_eq!(out.len(), 1);
            let c = channels(&out[0]);
            assert_eq!(c.count, 16);
            let ch4 = if k == 0 { 1495 } else { ticks_to_us(981) };
            assert_eq!(&c.us[..4], &[999, 1501, 1492, ch4]);
        }
        assert_eq!(d.stats().frames, 2);
    }

    #[test]
    fn edgetx_address_and_command_frames() {
        let mut d = CrsfDecoder::new();
        let out = feed(&mut d, &ELRS_EE_FRAME, 0);
        let c = channels(&out[0]);
        assert_eq!(&c.us[..6], &[993, 988, 1063, 995, 173, 173].map(ticks_to_us));
        let out = feed(&mut d, &BETAFLIGHT_COMMAND, 10);
        assert!(out.is_empty());
        assert_eq!(d.stats().ignored, 1);
        assert_eq!(d.stats().frames, 1);
    }

    #[test]
    fn link_statistics() {
        // RSSI −45/−50 dBm, LQ 100 %, SNR 9 dB, antenna 2 active, mode 5, power 3, downlink
        // −60 dBm, LQ 98 %, SNR −3 dB.
        let f = encode_link(&[45, 50, 100, 9, 1, 5, 3, 60, 98, (-3i8) as u8]);
        let mut d = CrsfDecoder::new();
        let out = feed(&mut d, &f, 0);
        match out.as_slice() {
            [CrsfFrame::Link(l)] => {
                assert_eq!((l.uplink_rssi_ant1_dbm, l.uplink_rssi_ant2_dbm, l.rssi_dbm()), (-45, -50, -50));
                assert_eq!(
                    (l.uplink_lq, l.uplink_snr_db, l.downlink_rssi_dbm, l.downlink_snr_db),
                    (100, 9, -60, -3)
                );
            }
            o => panic!("{o:?}"),
        }
    }

    #[test]
    fn encoder_round_trips_every_value_range_end() {
        let ticks: [u16; 16] = core::array::from_fn(|i| [172, 992, 1811, 0, 2047][i % 5]);
        let f = encode_channels(&ticks);
        let mut d = CrsfDecoder::new();
        let c = channels(&feed(&mut d, &f, 0)[0]);
        assert_eq!(&c.us[..16], &ticks.map(ticks_to_us));
    }

    #[test]
    fn split_frames_byte_by_byte_and_in_chunks() {
        let a = encode_channels(&[172; 16]);
        let b = encode_channels(&[1811; 16]);
        let mut stream = Vec::new();
        stream.extend_from_slice(&a);
        stream.extend_from_slice(&b);
        for chunk in [1usize, 3, 7, 25, 26, 52] {
            let mut d = CrsfDecoder::new();
            let mut out = Vec::new();
            for (k, c) in stream.chunks(chunk).enumerate() {
                out.extend(feed(&mut d, c, 10 * k as u64));
            }
            assert_eq!(out.len(), 2, "chunk {chunk}");
            assert_eq!(channels(&out[0]).us[0], 988);
            assert_eq!(channels(&out[1]).us[15], 2012);
        }
    }

    #[test]
    fn resyncs_after_garbage_bad_crc_and_false_sync() {
        let good = encode_channels(&[992; 16]);
        let mut bad_crc = good;
        bad_crc[25] ^= 0x01;
        let mut stream = Vec::new();
        stream.extend_from_slice(&[0x00, 0x55, 0xFF, 0x16]); // line noise, no sync
        stream.extend_from_slice(&[0xC8, 0xFF]); // sync + impossible length
        stream.extend_from_slice(&[0xC8, 0x30, 0x16, 0x01]); // false sync, length 48, swallows the next frame
        stream.extend_from_slice(&good);
        stream.extend_from_slice(&bad_crc);
        stream.extend_from_slice(&good[..10]); // a frame cut off …
        let mut d = CrsfDecoder::new();
        let out = feed(&mut d, &stream, 0);
        assert_eq!(out.len(), 1, "{:?}", d.stats());
        // … then the receiver pauses longer than GAP_US: the partial frame is dropped and the
        // next whole frame decodes.
        let out = feed(&mut d, &good, GAP_US + 1);
        assert_eq!(out.len(), 1);
        let s = d.stats();
        assert!(s.crc_errors >= 2 && s.length_errors >= 1 && s.gap_resets == 1, "{s:?}");
    }

    #[test]
    fn a_frame_hidden_behind_a_false_sync_is_delivered_by_poll() {
        // A false sync whose length covers a whole good frame: the good frame is complete in the
        // buffer when the false one fails its CRC.
        let good = encode_channels(&[500; 16]);
        let mut stream = std::vec![0xC8, 28, 0x16, 0x00];
        stream.extend_from_slice(&good);
        let mut d = CrsfDecoder::new();
        let mut n = 0;
        for &b in &stream {
            if d.push(b, 0).is_some() {
                n += 1;
            }
            while d.poll().is_some() {
                n += 1;
            }
        }
        assert_eq!(n, 1, "{:?}", d.stats());
    }
}
