//! MAVLink pilot input → [`RcInput`]: MANUAL_CONTROL (69, a ground station's joystick) and
//! RC_CHANNELS_OVERRIDE (70, channel values in µs). Plain integers here (the firmware's
//! `link::manual_control` unpacks the MAVLink messages), so core stays free of MAVLink types.
//!
//! ## MANUAL_CONTROL mapping (fixed)
//! | field | → | rule |
//! |---|---|---|
//! | `x` −1000..1000 | pitch | x / 1000 (forward +) |
//! | `y` | roll | y / 1000 (right +) |
//! | `r` | yaw | r / 1000 (clockwise +) |
//! | `z` | throttle | z / 1000 clamped to [0, 1] (PX4 / QGroundControl send 0..1000) |
//! | any axis = `INT16_MAX` | | "invalid" (MAVLink): stick 0, throttle 0.5 (hold) |
//! | `buttons` bit 0 | arm | pressed = arm switch on |
//! | `buttons` bit 1 | kill | pressed = kill on |
//! | `buttons` bits 2–3 | mode | 0 Low, 1 Mid, 2 or 3 High |
//!
//! Out-of-range values clamp. Link quality 100, no RSSI, source [`RcSource::Mavlink`].
//!
//! ## RC_CHANNELS_OVERRIDE ([`RcOverride`])
//! Keeps the overridden value of each channel. Channels 1–8: `UINT16_MAX` = ignore this field
//! (keep), 0 = release; channels 9–18: 0 or `UINT16_MAX` = ignore, `UINT16_MAX − 1` = release
//! (MAVLink common.xml). A released channel has no radio behind it on these boards, so it reads
//! as the "nothing commanded" value: [`RcParams::trim_us`] for the roll / pitch / yaw channels,
//! [`RcParams::min_us`] for every other one (throttle low, switches low: arm off, kill off,
//! mode Low). The result goes through [`map_channels`] like a receiver frame.
//!
//! May import: [`crate::rc`] (its types), [`crate::rc::map`].

use super::map::{map_channels, RcParams};
use super::{RawChannels, RcInput, RcSource, SwitchPosition, MAX_CHANNELS};

/// MANUAL_CONTROL's "axis invalid" value.
pub const AXIS_INVALID: i16 = i16::MAX;

fn axis(v: i16) -> Option<f32> {
    (v != AXIS_INVALID).then(|| (f32::from(v) / 1000.0).clamp(-1.0, 1.0))
}

/// One MANUAL_CONTROL message received at `t_us` → [`RcInput`] (module docs' table).
pub fn from_manual_control(x: i16, y: i16, z: i16, r: i16, buttons: u16, t_us: u64) -> RcInput {
    let mode = match (buttons >> 2) & 0b11 {
        0 => SwitchPosition::Low,
        1 => SwitchPosition::Mid,
        _ => SwitchPosition::High,
    };
    RcInput {
        t_us,
        roll: axis(y).unwrap_or(0.0),
        pitch: axis(x).unwrap_or(0.0),
        yaw: axis(r).unwrap_or(0.0),
        throttle: axis(z).map_or(0.5, |v| v.clamp(0.0, 1.0)),
        arm: buttons & 0b01 != 0,
        kill: buttons & 0b10 != 0,
        mode,
        link_quality: 100,
        rssi_dbm: None,
        failsafe: false,
        lost: None,
        source: RcSource::Mavlink,
    }
}

/// The inverse of [`from_manual_control`] for a valid input (the simulated pilot's sender).
/// Returns `(x, y, z, r, buttons)`.
pub fn to_manual_control(i: &RcInput) -> (i16, i16, i16, i16, u16) {
    let q = |v: f32, lo: f32| libm::roundf(v.clamp(lo, 1.0) * 1000.0) as i16;
    let mode = match i.mode {
        SwitchPosition::Low => 0,
        SwitchPosition::Mid => 1,
        SwitchPosition::High => 2,
    };
    let buttons = u16::from(i.arm) | (u16::from(i.kill) << 1) | (mode << 2);
    (q(i.pitch, -1.0), q(i.roll, -1.0), q(i.throttle, 0.0), q(i.yaw, -1.0), buttons)
}

/// RC_CHANNELS_OVERRIDE state: the overridden value of each channel (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RcOverride {
    us: [Option<u16>; MAX_CHANNELS],
}

/// What one channel field of RC_CHANNELS_OVERRIDE asks for.
fn field(index: usize, v: u16) -> Option<Option<u16>> {
    let release = if index < 8 { v == 0 } else { v == u16::MAX - 1 };
    let ignore = if index < 8 { v == u16::MAX } else { v == 0 || v == u16::MAX };
    if ignore {
        None
    } else if release {
        Some(None)
    } else {
        Some(Some(v))
    }
}

impl RcOverride {
    /// No channel overridden.
    pub const fn new() -> Self {
        Self { us: [None; MAX_CHANNELS] }
    }

    /// Applies one message's 18 channel fields (`chan1_raw..chan18_raw`) received at `t_us` and
    /// returns the resulting input.
    pub fn apply(&mut self, fields: &[u16; MAX_CHANNELS], t_us: u64, p: &RcParams) -> RcInput {
        for (i, (slot, &v)) in self.us.iter_mut().zip(fields).enumerate() {
            if let Some(new) = field(i, v) {
                *slot = new;
            }
        }
        self.input(t_us, p)
    }

    /// The channels now in effect, released ones at their "nothing commanded" value.
    pub fn channels(&self, p: &RcParams) -> RawChannels {
        let centred = [p.map_roll, p.map_pitch, p.map_yaw];
        let mut us = [0u16; MAX_CHANNELS];
        for (i, (o, v)) in us.iter_mut().zip(&self.us).enumerate() {
            let n = i as u8 + 1;
            let rest = if centred.contains(&n) { p.trim_us } else { p.min_us };
            *o = v.unwrap_or(rest as u16);
        }
        RawChannels { us, count: MAX_CHANNELS as u8, failsafe: false, frame_lost: false }
    }

    /// The input at `t_us` from the channels in effect.
    pub fn input(&self, t_us: u64, p: &RcParams) -> RcInput {
        map_channels(&self.channels(p), p, t_us, 100, None, RcSource::Mavlink)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manual_control_axes_buttons_and_invalid_axes() {
        let i = from_manual_control(1000, -500, 250, 2000, 0b0111, 42);
        assert_eq!((i.pitch, i.roll, i.throttle, i.yaw), (1.0, -0.5, 0.25, 1.0));
        assert_eq!((i.arm, i.kill, i.mode, i.t_us), (true, true, SwitchPosition::Mid, 42));
        let i = from_manual_control(AXIS_INVALID, AXIS_INVALID, AXIS_INVALID, AXIS_INVALID, 0b1100, 0);
        assert_eq!((i.pitch, i.roll, i.throttle, i.yaw), (0.0, 0.0, 0.5, 0.0));
        assert_eq!((i.arm, i.kill, i.mode), (false, false, SwitchPosition::High));
        assert_eq!(from_manual_control(0, 0, -1000, -32768, 0, 0).throttle, 0.0);
        assert_eq!(from_manual_control(0, 0, 0, -32768, 0, 0).yaw, -1.0);
    }

    #[test]
    fn manual_control_round_trips() {
        for b in 0..16u16 {
            let i = from_manual_control(-731, 402, 613, 999, b & 0b1011, 5);
            let (x, y, z, r, buttons) = to_manual_control(&i);
            assert_eq!(from_manual_control(x, y, z, r, buttons, 5), i);
        }
    }

    #[test]
    fn override_ignore_release_and_keep() {
        let p = RcParams::default();
        let mut o = RcOverride::new();
        let mut f = [u16::MAX; MAX_CHANNELS];
        f[8..].fill(0);
        // Nothing overridden: sticks centred, throttle low, switches low.
        let i = o.apply(&f, 0, &p);
        assert_eq!((i.roll, i.pitch, i.yaw, i.throttle, i.arm, i.kill), (0.0, 0.0, 0.0, 0.0, false, false));
        f[0] = 2000; // roll right
        f[2] = 1500; // throttle half
        f[4] = 2000; // arm
        f[6] = 2000; // kill
        let i = o.apply(&f, 1, &p);
        assert_eq!((i.roll, i.throttle, i.arm, i.kill), (1.0, 0.5, true, true));
        // UINT16_MAX on 1..8: ignored, the old values stay.
        let i = o.apply(&[u16::MAX; MAX_CHANNELS], 2, &p);
        assert_eq!((i.roll, i.throttle, i.arm, i.kill), (1.0, 0.5, true, true));
        // 0 releases 1..8: back to the resting values.
        let mut rel = [u16::MAX; MAX_CHANNELS];
        rel[6] = 0;
        rel[0] = 0;
        let i = o.apply(&rel, 3, &p);
        assert_eq!((i.roll, i.kill, i.arm), (0.0, false, true));
        // Channels 9..18: UINT16_MAX − 1 releases, 0 and UINT16_MAX ignore.
        let p9 = RcParams { map_kill: 9, ..p };
        let mut f = [u16::MAX; MAX_CHANNELS];
        f[8] = 2000;
        assert!(o.apply(&f, 4, &p9).kill);
        f[8] = 0;
        assert!(o.apply(&f, 5, &p9).kill);
        f[8] = u16::MAX - 1;
        assert!(!o.apply(&f, 6, &p9).kill);
        assert_eq!(o.input(7, &p9).source, RcSource::Mavlink);
    }
}
