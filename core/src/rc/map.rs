//! Receiver channels (µs) → [`RcInput`], the two receivers (decoder → [`RcFrame`]) and the
//! RC-loss detector [`RcMonitor`].
//!
//! ## Channel map and ranges ([`RcParams`], parameters `RC_*` in `crate::params`)
//! Channels are numbered from 1. Defaults follow the ExpressLRS / Betaflight "AETR" order:
//! roll 1, pitch 2, throttle 3, yaw 4, arm 5 (AUX1), mode 6, kill 7. One range for every
//! channel: `RC_MIN_US` / `RC_TRIM_US` / `RC_MAX_US` (default 1000 / 1500 / 2000 µs); the ranges
//! of the three do not overlap, so every in-range set is usable (no cross-parameter rule).
//!
//! * roll / pitch / yaw: 0 inside `trim ± RC_DEADBAND_US`, then linear to ±1 at min / max
//!   (the deadband is taken out, so the output is continuous), clamped to [−1, 1]. Higher µs =
//!   right / forward / clockwise.
//! * throttle: (µs − min) / (max − min), clamped to [0, 1].
//! * mode: below `RC_SW_LOW_US` Low, above `RC_SW_HIGH_US` High, else Mid.
//! * arm: on only **above** `RC_SW_HIGH_US` (clearly high). kill: on unless **below**
//!   `RC_SW_LOW_US` (clearly low) — a kill switch in an ambiguous middle position counts as on.
//! * a map entry of 0 (switches only) = not used: arm off, kill off, mode Low. A channel number
//!   the frame does not carry (e.g. 17 on CRSF): sticks 0, throttle 0, arm off, mode Low and
//!   **kill on** (a misconfigured kill channel keeps the motors off, visibly).
//!
//! ## RC loss ([`RcMonitor`])
//! Lost when no *valid* frame came for the loss timeout (the mode machine's `FS_RC_TIMEOUT`,
//! passed in: one timeout parameter for the whole vehicle) or none since start, the receiver flags
//! failsafe (SBUS failsafe bit; CRSF link quality 0), or the link quality is below
//! `RC_LQ_MIN`. A valid frame has finite sticks in range and no failsafe flag; others are
//! counted ([`RcMonitor::rejected`]) and never refresh the timeout. While lost the output is:
//! roll = pitch = yaw = 0, throttle = 0.5 (hold height in Position mode), **arm, mode and kill
//! as in the last valid frame** (a kill seen on stays on until a valid frame shows it off; the
//! switch values of failsafe frames — the receiver's, not the pilot's — are never used), and
//! `lost = Some(reason)`. The mode machine decides what a loss does (hold, land, return).
//!
//! May import: [`crate::rc`] (its types), [`crate::rc::crsf`], [`crate::rc::sbus`].

use super::crsf::{CrsfDecoder, CrsfFrame, LinkStats};
use super::sbus::SbusDecoder;
use super::{RawChannels, RcInput, RcLost, RcSource, SwitchPosition, MAX_CHANNELS};
use crate::param_decl::{field, u8_field, Access, Has, Param};

/// Channel map, ranges, switch thresholds and loss limits (see the module docs; the parameter
/// table `crate::params` holds their names, units, defaults and ranges).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RcParams {
    /// Roll channel, 1..18 (`RC_MAP_ROLL`, default 1).
    pub map_roll: u8,
    /// Pitch channel (`RC_MAP_PITCH`, default 2).
    pub map_pitch: u8,
    /// Throttle channel (`RC_MAP_THR`, default 3).
    pub map_throttle: u8,
    /// Yaw channel (`RC_MAP_YAW`, default 4).
    pub map_yaw: u8,
    /// Arm switch channel, 0 = none (`RC_MAP_ARM`, default 5).
    pub map_arm: u8,
    /// Mode switch channel, 0 = none (`RC_MAP_MODE`, default 6).
    pub map_mode: u8,
    /// Kill switch channel, 0 = none (`RC_MAP_KILL`, default 7).
    pub map_kill: u8,
    /// Stick / throttle low end, µs (`RC_MIN_US`, default 1000).
    pub min_us: f32,
    /// Stick centre, µs (`RC_TRIM_US`, default 1500).
    pub trim_us: f32,
    /// Stick / throttle high end, µs (`RC_MAX_US`, default 2000).
    pub max_us: f32,
    /// Stick deadband around the centre, µs (`RC_DEADBAND_US`, default 20).
    pub deadband_us: f32,
    /// Switch low threshold, µs (`RC_SW_LOW_US`, default 1300).
    pub switch_low_us: f32,
    /// Switch high threshold, µs (`RC_SW_HIGH_US`, default 1700).
    pub switch_high_us: f32,
    /// Link quality below this = RC lost, percent (`RC_LQ_MIN`, default 10).
    pub lq_min: f32,
}

impl Default for RcParams {
    fn default() -> Self {
        Self {
            map_roll: 1,
            map_pitch: 2,
            map_throttle: 3,
            map_yaw: 4,
            map_arm: 5,
            map_mode: 6,
            map_kill: 7,
            min_us: 1000.0,
            trim_us: 1500.0,
            max_us: 2000.0,
            deadband_us: 20.0,
            switch_low_us: 1300.0,
            switch_high_us: 1700.0,
            lq_min: 10.0,
        }
    }
}

impl RcParams {
    /// The receiver's channel map and ranges (issue 21; `crate::params`, MAVLink `param_index`
    /// order; the loss timeout is `FS_RC_TIMEOUT`, `crate::supervisor::modes`).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 14] {
        [
            rc_map("RC_MAP_ROLL", 1.0, u8_field!(map_roll),
                "RC channel of the roll stick"),
            rc_map("RC_MAP_PITCH", 1.0, u8_field!(map_pitch),
                "RC channel of the pitch stick"),
            rc_map("RC_MAP_THR", 1.0, u8_field!(map_throttle),
                "RC channel of the throttle stick"),
            rc_map("RC_MAP_YAW", 1.0, u8_field!(map_yaw),
                "RC channel of the yaw stick"),
            rc_map("RC_MAP_ARM", 0.0, u8_field!(map_arm),
                "RC channel of the arm switch (on above RC_SW_HIGH_US); 0 none"),
            rc_map("RC_MAP_MODE", 0.0, u8_field!(map_mode),
                "RC channel of the mode switch (MODE_SW_LOW/MID/HIGH); 0 none"),
            rc_map("RC_MAP_KILL", 0.0, u8_field!(map_kill),
                "RC channel of the kill switch (on unless below RC_SW_LOW_US); 0 none"),
            rc_us("RC_MIN_US", (700.0, 1400.0), field!(min_us),
                "RC stick low end (throttle 0, stick -1)"),
            rc_us("RC_TRIM_US", (1410.0, 1590.0), field!(trim_us),
                "RC stick centre (Futaba SBUS: 1520)"),
            rc_us("RC_MAX_US", (1600.0, 2300.0), field!(max_us),
                "RC stick high end (throttle 1, stick +1)"),
            rc_us("RC_DEADBAND_US", (0.0, 100.0), field!(deadband_us),
                "RC roll/pitch/yaw deadband around RC_TRIM_US"),
            rc_us("RC_SW_LOW_US", (800.0, 1500.0), field!(switch_low_us),
                "RC switch: below this = low position"),
            rc_us("RC_SW_HIGH_US", (1500.0, 2200.0), field!(switch_high_us),
                "RC switch: above this = high position"),
            Param::new("RC_LQ_MIN", "RC", "%", (0.0, 100.0), 0, field!(lq_min),
                "RC link quality below this = RC lost (CRSF link statistics)"),
        ]
    }
}

/// An `RC_MAP_*` parameter: a whole channel number from `min` up to 18.
const fn rc_map<P>(name: &'static str, min: f32, access: Access<P>, description: &'static str) -> Param<P> {
    Param::new(name, "RC", "", (min, 18.0), 0, access, description).whole()
}

/// An RC pulse-width parameter (`RC_*_US`), µs.
const fn rc_us<P>(
    name: &'static str,
    range: (f32, f32),
    access: Access<P>,
    description: &'static str,
) -> Param<P> {
    Param::new(name, "RC", "us", range, 0, access, description)
}

impl RcParams {
    /// What the map needs (every in-range parameter set has it; `ControllerParams::validate`
    /// reports a set without it as `ParamError::Failsafe`): finite values, min < trim < max,
    /// deadband ≥ 0, switch low ≤ high, channels ≤ 18 (sticks ≥ 1), link quality 0..=100 %.
    pub fn is_valid(&self) -> bool {
        let f = [
            self.min_us,
            self.trim_us,
            self.max_us,
            self.deadband_us,
            self.switch_low_us,
            self.switch_high_us,
        ];
        let sticks = [self.map_roll, self.map_pitch, self.map_throttle, self.map_yaw];
        f.iter().all(|v| v.is_finite())
            && self.min_us < self.trim_us
            && self.trim_us < self.max_us
            && self.deadband_us >= 0.0
            && self.switch_low_us <= self.switch_high_us
            && sticks.iter().all(|&c| (1..=18).contains(&c))
            && [self.map_arm, self.map_mode, self.map_kill].iter().all(|&c| c <= 18)
            && (0.0..=100.0).contains(&self.lq_min)
    }
}

/// A stick: 0 inside the deadband, then linear to ±1 at the range ends, clamped.
fn stick(us: f32, p: &RcParams) -> f32 {
    let d = us - p.trim_us;
    let db = p.deadband_us.max(0.0);
    let s = if d > db {
        (d - db) / (p.max_us - p.trim_us - db).max(1.0)
    } else if d < -db {
        (d + db) / (p.trim_us - p.min_us - db).max(1.0)
    } else {
        0.0
    };
    s.clamp(-1.0, 1.0)
}

fn switch(us: f32, p: &RcParams) -> SwitchPosition {
    if us < p.switch_low_us {
        SwitchPosition::Low
    } else if us > p.switch_high_us {
        SwitchPosition::High
    } else {
        SwitchPosition::Mid
    }
}

/// Raw channels → [`RcInput`] with the module docs' rules. `link_quality` / `rssi_dbm` come
/// from the receiver's link statistics (100 / `None` when the protocol has none). The result
/// has `lost = Some(ReceiverFailsafe)` for a failsafe frame and `Some(LowLinkQuality)` below
/// `RC_LQ_MIN`; the timeout is [`RcMonitor`]'s.
pub fn map_channels(
    raw: &RawChannels,
    p: &RcParams,
    t_us: u64,
    link_quality: u8,
    rssi_dbm: Option<i16>,
    source: RcSource,
) -> RcInput {
    let ch = |n: u8| raw.channel(n).map(f32::from);
    let throttle =
        ch(p.map_throttle).map_or(0.0, |v| ((v - p.min_us) / (p.max_us - p.min_us).max(1.0)).clamp(0.0, 1.0));
    let sw = |n: u8, missing: bool, on: fn(f32, &RcParams) -> bool| {
        if n == 0 {
            false
        } else {
            ch(n).map_or(missing, |v| on(v, p))
        }
    };
    let arm = sw(p.map_arm, false, |v, p| v > p.switch_high_us);
    let kill = sw(p.map_kill, true, |v, p| v >= p.switch_low_us);
    let mode = if p.map_mode == 0 {
        SwitchPosition::Low
    } else {
        ch(p.map_mode).map_or(SwitchPosition::Low, |v| switch(v, p))
    };
    let lost = if raw.failsafe {
        Some(RcLost::ReceiverFailsafe)
    } else if f32::from(link_quality) < p.lq_min {
        Some(RcLost::LowLinkQuality)
    } else {
        None
    };
    RcInput {
        t_us,
        roll: ch(p.map_roll).map_or(0.0, |v| stick(v, p)),
        pitch: ch(p.map_pitch).map_or(0.0, |v| stick(v, p)),
        yaw: ch(p.map_yaw).map_or(0.0, |v| stick(v, p)),
        throttle,
        arm,
        kill,
        mode,
        link_quality,
        rssi_dbm,
        failsafe: raw.failsafe,
        lost,
        source,
    }
}

/// The channels a receiver would have sent for `i` under the channel map `p` (the inverse of
/// [`map_channels`], rounded to µs): what RC_CHANNELS reports for MAVLink
/// pilot input, which has no channels of its own. Sticks from the trim through the deadband to
/// the range ends, throttle over the range, arm and kill at the range ends (on = max), the mode
/// switch at min / trim / max. `count` = the highest mapped channel; unmapped channels below it
/// read trim.
pub fn channels_of(i: &RcInput, p: &RcParams) -> RawChannels {
    let db = p.deadband_us.max(0.0);
    let stick = |s: f32| {
        let s = if s.is_finite() { s.clamp(-1.0, 1.0) } else { 0.0 };
        if s > 0.0 {
            p.trim_us + db + s * (p.max_us - p.trim_us - db)
        } else if s < 0.0 {
            p.trim_us - db + s * (p.trim_us - p.min_us - db)
        } else {
            p.trim_us
        }
    };
    let thr = if i.throttle.is_finite() { i.throttle.clamp(0.0, 1.0) } else { 0.0 };
    let switch = |on: bool| if on { p.max_us } else { p.min_us };
    let mode = match i.mode {
        SwitchPosition::Low => p.min_us,
        SwitchPosition::Mid => p.trim_us,
        SwitchPosition::High => p.max_us,
    };
    let values = [
        (p.map_roll, stick(i.roll)),
        (p.map_pitch, stick(i.pitch)),
        (p.map_yaw, stick(i.yaw)),
        (p.map_throttle, p.min_us + thr * (p.max_us - p.min_us)),
        (p.map_arm, switch(i.arm)),
        (p.map_kill, switch(i.kill)),
        (p.map_mode, mode),
    ];
    // Rounded (the values are ≥ 0); saturating float → int casts: any value lands in 0..=u16::MAX.
    let mut us = [(p.trim_us + 0.5) as u16; MAX_CHANNELS];
    let mut count = 0u8;
    for (ch, v) in values {
        if let Some(slot) = usize::from(ch).checked_sub(1).and_then(|k| us.get_mut(k)) {
            *slot = (v + 0.5) as u16;
            count = count.max(ch);
        }
    }
    RawChannels { us, count, failsafe: i.failsafe, frame_lost: false }
}

/// One receiver frame before the map: channels in µs plus the link state at its arrival. The
/// receiver task produces it; whoever holds the live parameters maps it ([`RcFrame::input`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RcFrame {
    /// Channels and the receiver's failsafe flag.
    pub raw: RawChannels,
    /// Arrival time, µs, controller clock.
    pub t_us: u64,
    /// Link quality, percent (100 when the protocol has none and the frame is good).
    pub link_quality: u8,
    /// RSSI, dBm, when reported.
    pub rssi_dbm: Option<i16>,
    /// The protocol.
    pub source: RcSource,
}

impl RcFrame {
    /// The frame through the channel map ([`map_channels`]).
    pub fn input(&self, p: &RcParams) -> RcInput {
        map_channels(&self.raw, p, self.t_us, self.link_quality, self.rssi_dbm, self.source)
    }
}

/// A CRSF receiver: decoder + the latest link statistics.
#[derive(Clone, Debug, Default)]
pub struct CrsfReceiver {
    /// The byte-stream decoder (its counters: [`CrsfDecoder::stats`]).
    pub decoder: CrsfDecoder,
    link: Option<LinkStats>,
    last: Option<RawChannels>,
}

impl CrsfReceiver {
    /// Feeds bytes read at `t_us`; hands an [`RcFrame`] to `f` for every RC frame (link
    /// statistics update the link quality of the following ones; a link frame with LQ 0 —
    /// the receiver's link-lost report — also yields a failsafe frame from the last channels).
    pub fn push_frames(&mut self, bytes: &[u8], t_us: u64, mut f: impl FnMut(RcFrame)) {
        for &b in bytes {
            let mut next = self.decoder.push(b, t_us);
            while let Some(frame) = next {
                match frame {
                    CrsfFrame::Channels(raw) => {
                        self.last = Some(raw);
                        f(self.frame(&raw, t_us));
                    }
                    CrsfFrame::Link(l) => {
                        self.link = Some(l);
                        if let (0, Some(raw)) = (l.uplink_lq, self.last) {
                            f(self.frame(&RawChannels { failsafe: true, ..raw }, t_us));
                        }
                    }
                }
                next = self.decoder.poll();
            }
        }
    }

    /// [`CrsfReceiver::push_frames`] through the map `p`.
    pub fn push_slice(&mut self, bytes: &[u8], t_us: u64, p: &RcParams, mut f: impl FnMut(RcInput)) {
        self.push_frames(bytes, t_us, |fr| f(fr.input(p)));
    }

    fn frame(&self, raw: &RawChannels, t_us: u64) -> RcFrame {
        let lq = self.link.map_or(100, |l| l.uplink_lq).min(100);
        let raw = RawChannels { failsafe: raw.failsafe || lq == 0, ..*raw };
        RcFrame {
            raw,
            t_us,
            link_quality: lq,
            rssi_dbm: self.link.map(|l| l.rssi_dbm()),
            source: RcSource::Crsf,
        }
    }

    /// The latest link statistics.
    pub fn link(&self) -> Option<LinkStats> {
        self.link
    }

    /// The latest RC frame's channels (for RC_CHANNELS telemetry).
    pub fn channels(&self) -> Option<RawChannels> {
        self.last
    }
}

/// An SBUS receiver: the decoder. Link quality 100 for a good frame, 0 for a failsafe one.
#[derive(Clone, Debug, Default)]
pub struct SbusReceiver {
    /// The byte-stream decoder (its counters: [`SbusDecoder::stats`]).
    pub decoder: SbusDecoder,
    last: Option<RawChannels>,
}

impl SbusReceiver {
    /// Feeds bytes read at `t_us`; hands an [`RcFrame`] to `f` for every frame.
    pub fn push_frames(&mut self, bytes: &[u8], t_us: u64, mut f: impl FnMut(RcFrame)) {
        for &b in bytes {
            if let Some(raw) = self.decoder.push(b, t_us) {
                self.last = Some(raw);
                let link_quality = if raw.failsafe { 0 } else { 100 };
                f(RcFrame { raw, t_us, link_quality, rssi_dbm: None, source: RcSource::Sbus });
            }
        }
    }

    /// [`SbusReceiver::push_frames`] through the map `p`.
    pub fn push_slice(&mut self, bytes: &[u8], t_us: u64, p: &RcParams, mut f: impl FnMut(RcInput)) {
        self.push_frames(bytes, t_us, |fr| f(fr.input(p)));
    }

    /// The latest frame's channels (for RC_CHANNELS telemetry).
    pub fn channels(&self) -> Option<RawChannels> {
        self.last
    }
}

/// The RC-loss detector (see the module docs): fed every produced [`RcInput`], asked at the
/// consumer's rate for the input to use.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RcMonitor {
    latest: Option<RcInput>,
    last_valid: Option<RcInput>,
    rejected: u32,
}

/// Whether a frame's values are usable: finite, in range, not failsafe.
pub fn is_valid(i: &RcInput) -> bool {
    let stick_ok = |v: f32| (-1.0..=1.0).contains(&v);
    !i.failsafe
        && stick_ok(i.roll)
        && stick_ok(i.pitch)
        && stick_ok(i.yaw)
        && (0.0..=1.0).contains(&i.throttle)
        && i.link_quality <= 100
}

impl RcMonitor {
    /// A monitor that has seen nothing (lost: [`RcLost::NoSignal`]).
    pub const fn new() -> Self {
        Self { latest: None, last_valid: None, rejected: 0 }
    }

    /// Takes a produced input (a frame). Invalid ones (non-finite, out of range, failsafe) are
    /// counted and kept only for the failsafe / link-quality state.
    pub fn on_input(&mut self, input: &RcInput) {
        self.latest = Some(*input);
        if is_valid(input) {
            self.last_valid = Some(*input);
        } else {
            self.rejected = self.rejected.wrapping_add(1);
        }
    }

    /// Frames refused as invalid.
    pub fn rejected(&self) -> u32 {
        self.rejected
    }

    /// Why RC is lost at `now_us` with the loss timeout `timeout_s` (`FS_RC_TIMEOUT`), `None`
    /// when it is not.
    pub fn lost(&self, now_us: u64, timeout_s: f32, p: &RcParams) -> Option<RcLost> {
        let Some(latest) = self.latest else {
            return Some(RcLost::NoSignal);
        };
        if latest.failsafe {
            return Some(RcLost::ReceiverFailsafe);
        }
        if f32::from(latest.link_quality) < p.lq_min {
            return Some(RcLost::LowLinkQuality);
        }
        if latest.lost == Some(RcLost::ReceiverFailsafe) || latest.lost == Some(RcLost::LowLinkQuality) {
            return latest.lost;
        }
        let Some(valid) = self.last_valid else {
            return Some(RcLost::NoSignal);
        };
        // A NaN or negative timeout: always lost. The cast saturates for +∞.
        let timeout_us = (timeout_s * 1e6) as u64;
        if timeout_s.is_nan() || timeout_s < 0.0 || now_us.saturating_sub(valid.t_us) > timeout_us {
            return Some(RcLost::Timeout);
        }
        None
    }

    /// The input to use at `now_us`: the last valid frame while RC is not lost, else the loss
    /// output of the module docs with `lost = Some(reason)`.
    pub fn input(&self, now_us: u64, timeout_s: f32, p: &RcParams) -> RcInput {
        let lost = self.lost(now_us, timeout_s, p);
        let valid = self.last_valid.unwrap_or_default();
        match lost {
            None => RcInput { lost: None, ..valid },
            Some(reason) => {
                let latest = self.latest.unwrap_or_default();
                RcInput {
                    t_us: valid.t_us,
                    roll: 0.0,
                    pitch: 0.0,
                    yaw: 0.0,
                    throttle: 0.5,
                    arm: valid.arm,
                    kill: valid.kill,
                    mode: valid.mode,
                    link_quality: latest.link_quality,
                    rssi_dbm: latest.rssi_dbm,
                    failsafe: latest.failsafe,
                    lost: Some(reason),
                    source: latest.source,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::rc::{crsf, sbus, MAX_CHANNELS};
    use std::vec::Vec;

    /// The synthesized channels map back to the same input (sticks within 1 µs of rounding),
    /// with the default and a remapped channel set.
    #[test]
    fn channels_of_an_input_map_back_to_it() {
        let input = RcInput {
            roll: 0.5,
            pitch: -1.0,
            yaw: 0.02,
            throttle: 0.7,
            arm: true,
            kill: false,
            mode: SwitchPosition::High,
            link_quality: 100,
            ..RcInput::default()
        };
        let remapped =
            RcParams { map_roll: 3, map_throttle: 1, map_kill: 12, map_mode: 0, ..RcParams::default() };
        for p in [RcParams::default(), remapped] {
            let raw = channels_of(&input, &p);
            let back = map_channels(&raw, &p, 0, 100, None, RcSource::Mavlink);
            for (a, b) in
                [(back.roll, input.roll), (back.pitch, input.pitch), (back.throttle, input.throttle)]
            {
                assert!((a - b).abs() < 3e-3, "{a} vs {b} ({p:?})");
            }
            assert!(back.yaw.abs() < 0.05);
            assert_eq!((back.arm, back.kill), (input.arm, input.kill));
            let mode = if p.map_mode == 0 { SwitchPosition::Low } else { input.mode };
            assert_eq!(back.mode, mode);
        }
        assert_eq!(channels_of(&input, &RcParams::default()).count, 7);
        assert_eq!(channels_of(&input, &remapped).count, 12);
    }

    fn raw(vals: &[u16]) -> RawChannels {
        let mut us = [1500u16; MAX_CHANNELS];
        us[..vals.len()].copy_from_slice(vals);
        RawChannels { us, count: 16, failsafe: false, frame_lost: false }
    }

    fn map(vals: &[u16]) -> RcInput {
        map_channels(&raw(vals), &RcParams::default(), 7, 100, None, RcSource::Sim)
    }

    #[test]
    fn default_params_are_valid_and_broken_ones_are_not() {
        let p = RcParams::default();
        assert!(p.is_valid());
        for bad in [
            RcParams { trim_us: f32::NAN, ..p },
            RcParams { min_us: 1600.0, ..p },
            RcParams { deadband_us: -1.0, ..p },
            RcParams { switch_low_us: 1800.0, ..p },
            RcParams { map_roll: 0, ..p },
            RcParams { map_kill: 19, ..p },
            RcParams { lq_min: 101.0, ..p },
        ] {
            assert!(!bad.is_valid(), "{bad:?}");
        }
    }

    #[test]
    fn sticks_throttle_and_deadband() {
        let i = map(&[2000, 1000, 1000, 1500]);
        assert_eq!((i.roll, i.pitch, i.throttle, i.yaw), (1.0, -1.0, 0.0, 0.0));
        let i = map(&[1519, 1481, 1750, 1760]);
        assert_eq!((i.roll, i.pitch), (0.0, 0.0), "inside the 20 µs deadband");
        assert_eq!(i.throttle, 0.75);
        assert!((i.yaw - 240.0 / 480.0).abs() < 1e-6, "{}", i.yaw);
        // Beyond the range: clamped.
        let i = map(&[2100, 800, 2200, 900]);
        assert_eq!((i.roll, i.pitch, i.throttle, i.yaw), (1.0, -1.0, 1.0, -1.0));
        // Continuous at the deadband edge.
        let i = map(&[1521]);
        assert!(i.roll > 0.0 && i.roll < 0.003);
        assert_eq!(i.t_us, 7);
    }

    #[test]
    fn switches_and_their_safe_readings() {
        let at = |arm: u16, mode: u16, kill: u16| {
            let mut v = [1500u16; 7];
            v[4] = arm;
            v[5] = mode;
            v[6] = kill;
            map(&v)
        };
        let i = at(1000, 1000, 1000);
        assert_eq!((i.arm, i.mode, i.kill), (false, SwitchPosition::Low, false));
        let i = at(2000, 1500, 2000);
        assert_eq!((i.arm, i.mode, i.kill), (true, SwitchPosition::Mid, true));
        let i = at(1600, 2000, 1400);
        assert_eq!(
            (i.arm, i.mode, i.kill),
            (false, SwitchPosition::High, true),
            "ambiguous: arm off, kill on"
        );
        // A kill channel the frame does not carry: kill on. Unused (0): off.
        let p = RcParams { map_kill: 17, ..RcParams::default() };
        assert!(map_channels(&raw(&[]), &p, 0, 100, None, RcSource::Sim).kill);
        let p = RcParams { map_kill: 0, map_arm: 0, map_mode: 0, ..RcParams::default() };
        let i =
            map_channels(&raw(&[1500, 1500, 1500, 1500, 2000, 2000, 2000]), &p, 0, 100, None, RcSource::Sim);
        assert_eq!((i.arm, i.mode, i.kill), (false, SwitchPosition::Low, false));
    }

    #[test]
    fn remapped_channels_and_extreme_ranges_stay_bounded() {
        let p = RcParams {
            map_roll: 4,
            map_yaw: 1,
            min_us: 700.0,
            trim_us: 1410.0,
            max_us: 1600.0,
            deadband_us: 100.0,
            ..RcParams::default()
        };
        for v in [0u16, 700, 1410, 1500, 1511, 1600, 2500, u16::MAX] {
            let i = map_channels(&raw(&[v, v, v, v]), &p, 0, 100, None, RcSource::Sim);
            for s in [i.roll, i.pitch, i.yaw] {
                assert!((-1.0..=1.0).contains(&s), "{v}: {s}");
            }
            assert!((0.0..=1.0).contains(&i.throttle));
        }
    }

    #[test]
    fn failsafe_and_low_link_quality_are_flagged() {
        let mut r = raw(&[]);
        r.failsafe = true;
        let p = RcParams::default();
        assert_eq!(map_channels(&r, &p, 0, 100, None, RcSource::Sbus).lost, Some(RcLost::ReceiverFailsafe));
        assert_eq!(
            map_channels(&raw(&[]), &p, 0, 9, None, RcSource::Crsf).lost,
            Some(RcLost::LowLinkQuality)
        );
        assert_eq!(map_channels(&raw(&[]), &p, 0, 10, None, RcSource::Crsf).lost, None);
    }

    #[test]
    fn crsf_receiver_uses_link_statistics() {
        let p = RcParams::default();
        let mut rx = CrsfReceiver::default();
        let mut out = Vec::new();
        // Sticks: roll full right (1811 ticks = 2012 µs), the rest centred, arm high.
        let mut ticks = [992u16; 16];
        ticks[0] = 1811;
        ticks[4] = 1811;
        ticks[6] = 172;
        rx.push_slice(&crsf::encode_link(&[60, 70, 87, 5, 0, 4, 2, 50, 99, 3]), 0, &p, |i| out.push(i));
        rx.push_slice(&crsf::encode_channels(&ticks), 10, &p, |i| out.push(i));
        assert_eq!(out.len(), 1);
        let i = out[0];
        assert_eq!((i.roll, i.arm, i.kill, i.link_quality, i.rssi_dbm), (1.0, true, false, 87, Some(-60)));
        assert_eq!((i.source, i.lost), (RcSource::Crsf, None));
        // LQ 0 = link lost: a failsafe input from the last channels.
        rx.push_slice(&crsf::encode_link(&[120, 120, 0, 0, 0, 4, 2, 0, 0, 0]), 20, &p, |i| out.push(i));
        assert_eq!(out.len(), 2);
        assert!(out[1].failsafe);
        assert_eq!(out[1].lost, Some(RcLost::ReceiverFailsafe));
    }

    #[test]
    fn sbus_receiver_maps_and_flags_failsafe() {
        let p = RcParams { trim_us: 1520.0, ..RcParams::default() };
        let mut rx = SbusReceiver::default();
        let mut out = Vec::new();
        // Futaba centre 1024 = 1520 µs: sticks 0 with the trim at 1520.
        rx.push_slice(&sbus::encode(&[1024; 16], 0, 0), 0, &p, |i| out.push(i));
        rx.push_slice(&sbus::encode(&[1024; 16], sbus::FLAG_FAILSAFE, 0), 20_000, &p, |i| out.push(i));
        assert_eq!(out.len(), 2);
        assert_eq!((out[0].roll, out[0].lost, out[0].link_quality), (0.0, None, 100));
        assert_eq!((out[1].lost, out[1].link_quality), (Some(RcLost::ReceiverFailsafe), 0));
    }

    /// The loss timeout of the tests, s (the `FS_RC_TIMEOUT` default).
    const T: f32 = 0.5;

    fn good(t_us: u64, kill: bool) -> RcInput {
        RcInput {
            t_us,
            roll: 0.3,
            pitch: -0.2,
            yaw: 0.1,
            throttle: 0.7,
            arm: true,
            kill,
            mode: SwitchPosition::High,
            link_quality: 90,
            ..RcInput::default()
        }
    }

    #[test]
    fn loss_timing_and_the_loss_output() {
        let p = RcParams::default();
        let mut m = RcMonitor::new();
        assert_eq!(m.lost(0, T, &p), Some(RcLost::NoSignal));
        assert!(!m.input(0, T, &p).arm);
        m.on_input(&good(1_000_000, false));
        assert_eq!(m.lost(1_000_000, T, &p), None);
        assert_eq!(m.input(1_400_000, T, &p), good(1_000_000, false));
        // Exactly the timeout after the frame: still valid; 1 µs later: lost.
        assert_eq!(m.lost(1_500_000, T, &p), None);
        assert_eq!(m.lost(1_500_001, T, &p), Some(RcLost::Timeout));
        let o = m.input(2_000_000, T, &p);
        assert_eq!((o.roll, o.pitch, o.yaw, o.throttle), (0.0, 0.0, 0.0, 0.5));
        assert_eq!(
            (o.arm, o.kill, o.mode, o.lost),
            (true, false, SwitchPosition::High, Some(RcLost::Timeout))
        );
        // A fresh frame ends the loss. A clock before the frame counts as age 0.
        m.on_input(&good(2_000_000, false));
        assert_eq!(m.lost(2_000_000, T, &p), None);
        assert_eq!(m.lost(1_000_000, T, &p), None);
    }

    #[test]
    fn kill_seen_on_stays_on_through_a_loss_and_failsafe_switches_are_ignored() {
        let p = RcParams::default();
        let mut m = RcMonitor::new();
        m.on_input(&good(0, true));
        // The receiver's failsafe frame has kill off (its failsafe setting): ignored.
        let fs = RcInput {
            failsafe: true,
            kill: false,
            arm: false,
            lost: Some(RcLost::ReceiverFailsafe),
            ..good(10_000, false)
        };
        m.on_input(&fs);
        let o = m.input(10_000, T, &p);
        assert_eq!((o.kill, o.arm, o.lost), (true, true, Some(RcLost::ReceiverFailsafe)));
        assert_eq!(m.rejected(), 1);
        // A valid frame with kill off releases it.
        m.on_input(&good(20_000, false));
        assert!(!m.input(20_000, T, &p).kill);
    }

    #[test]
    fn invalid_values_never_refresh_the_timeout() {
        let p = RcParams::default();
        let mut m = RcMonitor::new();
        m.on_input(&good(0, false));
        for (k, bad) in [f32::NAN, f32::INFINITY, 1.5, -3.0].into_iter().enumerate() {
            m.on_input(&RcInput { roll: bad, ..good(100_000 * (k as u64 + 1), false) });
        }
        m.on_input(&RcInput { throttle: f32::NAN, ..good(450_000, false) });
        assert_eq!(m.rejected(), 5);
        assert_eq!(m.lost(600_000, T, &p), Some(RcLost::Timeout));
        assert_eq!(m.lost(0, f32::NAN, &p), Some(RcLost::Timeout));
    }

    #[test]
    fn low_link_quality_is_a_loss() {
        let p = RcParams::default();
        let mut m = RcMonitor::new();
        m.on_input(&good(0, false));
        m.on_input(&RcInput { link_quality: 5, ..good(10_000, false) });
        assert_eq!(m.lost(10_000, T, &p), Some(RcLost::LowLinkQuality));
        assert_eq!(m.input(10_000, T, &p).throttle, 0.5);
    }
}
