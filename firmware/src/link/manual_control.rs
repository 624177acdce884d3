//! Pilot input over MAVLink: MANUAL_CONTROL (69, a ground station's joystick — QGroundControl's
//! virtual or USB joystick, MAVSDK's ManualControl) and RC_CHANNELS_OVERRIDE (70) →
//! [`RcInput`], and RC_CHANNELS (65) out. This is the QEMU/PIL board's RC channel (it has no
//! receiver UART); on the F405 it works next to the receiver (the mode machine takes the latest
//! input of either).
//!
//! The mappings are core's (`parapet_core::rc::manual`: axes ÷ 1000, buttons bit 0 arm, bit 1
//! kill, bits 2–3 mode; override ignore/release rules). Here only the addressing (MANUAL_CONTROL
//! `target` = our system id or 0; RC_CHANNELS_OVERRIDE `target_system`/`target_component` as every
//! addressed message, [`crate::link::command::addressed_to`]) and the counters. No allocation,
//! no panics.
//!
//! May import: `parapet_core::rc`, [`crate::link::dialect`], [`crate::link::command`].

use parapet_core::rc::manual::{from_manual_control, RcOverride};
use parapet_core::rc::map::RcParams;
use parapet_core::rc::{RawChannels, RcInput, MAX_CHANNELS};

use crate::link::command::addressed_to;
use crate::link::dialect::{MANUAL_CONTROL_DATA, RC_CHANNELS_DATA, RC_CHANNELS_OVERRIDE_DATA};

/// Counters (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ManualControlStats {
    /// MANUAL_CONTROL messages taken.
    pub manual: u32,
    /// RC_CHANNELS_OVERRIDE messages taken.
    pub overrides: u32,
    /// Messages for another system / component, ignored.
    pub not_for_us: u32,
}

/// The link's pilot-input state: the RC_CHANNELS_OVERRIDE values in effect and counters.
#[derive(Clone, Copy, Debug, Default)]
pub struct ManualControl {
    overrides: RcOverride,
    stats: ManualControlStats,
}

impl ManualControl {
    /// Nothing received yet.
    pub const fn new() -> Self {
        Self {
            overrides: RcOverride::new(),
            stats: ManualControlStats { manual: 0, overrides: 0, not_for_us: 0 },
        }
    }

    /// Counters.
    pub fn stats(&self) -> ManualControlStats {
        self.stats
    }

    /// MANUAL_CONTROL received at `now_us` → the input, or `None` when it is for another
    /// system (`own` = our system and component id).
    pub fn on_manual_control(
        &mut self,
        m: &MANUAL_CONTROL_DATA,
        own: (u8, u8),
        now_us: u64,
    ) -> Option<RcInput> {
        if m.target != 0 && m.target != own.0 {
            self.stats.not_for_us = self.stats.not_for_us.saturating_add(1);
            return None;
        }
        self.stats.manual = self.stats.manual.saturating_add(1);
        Some(from_manual_control(m.x, m.y, m.z, m.r, m.buttons, now_us))
    }

    /// RC_CHANNELS_OVERRIDE received at `now_us` → the input from the channels now in effect
    /// (mapped with `p`, the live `RC_*` parameters), or `None` when it is for someone else.
    pub fn on_override(
        &mut self,
        m: &RC_CHANNELS_OVERRIDE_DATA,
        own: (u8, u8),
        now_us: u64,
        p: &RcParams,
    ) -> Option<RcInput> {
        if !addressed_to(m.target_system, m.target_component, own) {
            self.stats.not_for_us = self.stats.not_for_us.saturating_add(1);
            return None;
        }
        self.stats.overrides = self.stats.overrides.saturating_add(1);
        let fields: [u16; MAX_CHANNELS] = [
            m.chan1_raw,
            m.chan2_raw,
            m.chan3_raw,
            m.chan4_raw,
            m.chan5_raw,
            m.chan6_raw,
            m.chan7_raw,
            m.chan8_raw,
            m.chan9_raw,
            m.chan10_raw,
            m.chan11_raw,
            m.chan12_raw,
            m.chan13_raw,
            m.chan14_raw,
            m.chan15_raw,
            m.chan16_raw,
            m.chan17_raw,
            m.chan18_raw,
        ];
        Some(self.overrides.apply(&fields, now_us, p))
    }

    /// The override channels in effect (for RC_CHANNELS when no receiver is fitted).
    pub fn override_channels(&self, p: &RcParams) -> RawChannels {
        self.overrides.channels(p)
    }
}

/// RC_CHANNELS (65) from a receiver's (or the override's) channels at `time_boot_ms`:
/// unused channels `UINT16_MAX`, `chancount` 0 when there are none; `rssi` = link quality
/// scaled to MAVLink's 0..254 (255 = unknown).
pub fn rc_channels(
    raw: Option<&RawChannels>,
    link_quality: Option<u8>,
    time_boot_ms: u32,
) -> RC_CHANNELS_DATA {
    let mut ch = [u16::MAX; MAX_CHANNELS];
    let mut count = 0u8;
    if let Some(r) = raw {
        count = r.count.min(MAX_CHANNELS as u8);
        for (o, v) in ch.iter_mut().zip(r.us.iter()).take(usize::from(count)) {
            *o = *v;
        }
    }
    let rssi = link_quality.map_or(u8::MAX, |lq| (u16::from(lq.min(100)) * 254 / 100) as u8);
    let [c1, c2, c3, c4, c5, c6, c7, c8, c9, c10, c11, c12, c13, c14, c15, c16, c17, c18] = ch;
    RC_CHANNELS_DATA {
        time_boot_ms,
        chancount: count,
        chan1_raw: c1,
        chan2_raw: c2,
        chan3_raw: c3,
        chan4_raw: c4,
        chan5_raw: c5,
        chan6_raw: c6,
        chan7_raw: c7,
        chan8_raw: c8,
        chan9_raw: c9,
        chan10_raw: c10,
        chan11_raw: c11,
        chan12_raw: c12,
        chan13_raw: c13,
        chan14_raw: c14,
        chan15_raw: c15,
        chan16_raw: c16,
        chan17_raw: c17,
        chan18_raw: c18,
        rssi,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::rc::{RcSource, SwitchPosition};

    const OWN: (u8, u8) = (1, 1);

    #[test]
    fn manual_control_addressing_and_mapping() {
        let mut mc = ManualControl::new();
        let m = MANUAL_CONTROL_DATA {
            target: 1,
            x: 500,
            y: -1000,
            z: 800,
            r: 0,
            buttons: 0b0101,
            ..Default::default()
        };
        let i = mc.on_manual_control(&m, OWN, 7).unwrap();
        assert_eq!((i.pitch, i.roll, i.throttle, i.yaw), (0.5, -1.0, 0.8, 0.0));
        assert_eq!(
            (i.arm, i.kill, i.mode, i.source, i.t_us),
            (true, false, SwitchPosition::Mid, RcSource::Mavlink, 7)
        );
        assert!(mc.on_manual_control(&MANUAL_CONTROL_DATA { target: 0, ..m }, OWN, 8).is_some());
        assert!(mc.on_manual_control(&MANUAL_CONTROL_DATA { target: 2, ..m }, OWN, 9).is_none());
        assert_eq!(mc.stats(), ManualControlStats { manual: 2, overrides: 0, not_for_us: 1 });
    }

    #[test]
    fn override_keeps_and_releases_channels() {
        let p = RcParams::default();
        let mut mc = ManualControl::new();
        let m = RC_CHANNELS_OVERRIDE_DATA {
            target_system: 1,
            target_component: 1,
            chan1_raw: 2000,
            chan3_raw: 1500,
            chan5_raw: 2000,
            chan2_raw: u16::MAX,
            chan4_raw: u16::MAX,
            chan6_raw: u16::MAX,
            chan7_raw: u16::MAX,
            chan8_raw: u16::MAX,
            ..Default::default()
        };
        let i = mc.on_override(&m, OWN, 1, &p).unwrap();
        assert_eq!((i.roll, i.throttle, i.arm, i.kill), (1.0, 0.5, true, false));
        // Everything "ignore": the values stay.
        let keep =
            RC_CHANNELS_OVERRIDE_DATA { chan1_raw: u16::MAX, chan3_raw: u16::MAX, chan5_raw: u16::MAX, ..m };
        let i = mc.on_override(&keep, OWN, 2, &p).unwrap();
        assert_eq!((i.roll, i.throttle, i.arm), (1.0, 0.5, true));
        // Another component: ignored.
        assert!(mc
            .on_override(&RC_CHANNELS_OVERRIDE_DATA { target_component: 154, ..m }, OWN, 3, &p)
            .is_none());
        assert_eq!(mc.stats().not_for_us, 1);
        let out = rc_channels(Some(&mc.override_channels(&p)), Some(100), 5);
        assert_eq!(
            (out.chancount, out.chan1_raw, out.chan3_raw, out.rssi, out.time_boot_ms),
            (18, 2000, 1500, 254, 5)
        );
    }

    /// RC_CHANNELS of MAVLink pilot input: the channels the map gives back, LQ as rssi.
    #[test]
    fn rc_channels_of_mavlink_pilot_input() {
        use parapet_core::rc::map::channels_of;
        let input = RcInput { pitch: -1.0, throttle: 0.7, arm: true, link_quality: 50, ..RcInput::default() };
        let out = rc_channels(Some(&channels_of(&input, &RcParams::default())), Some(50), 9);
        assert_eq!(
            (out.chancount, out.chan2_raw, out.chan3_raw, out.chan5_raw, out.rssi),
            (7, 1000, 1700, 2000, 127)
        );
    }

    #[test]
    fn rc_channels_without_a_receiver() {
        let out = rc_channels(None, None, 0);
        assert_eq!((out.chancount, out.chan1_raw, out.chan18_raw, out.rssi), (0, u16::MAX, u16::MAX, 255));
    }
}
