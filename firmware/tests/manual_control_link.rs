//! Pilot input over MAVLink end to end on the host: MANUAL_CONTROL and RC_CHANNELS_OVERRIDE
//! frames through the firmware's link (`link::manual_control`) into the real cascade's mode
//! machine — the QEMU/PIL board's RC channel (issue 21, `docs/rc.md`).

use mavlink_core::MessageData;
use parapet_core::controller::{ControllerParams, FlightMode};
use parapet_firmware::app::autopilot::Autopilot;
use parapet_firmware::app::cascade::Cascade;
use parapet_firmware::link::dialect::{MANUAL_CONTROL_DATA, RC_CHANNELS_OVERRIDE_DATA};
use parapet_firmware::link::framing::FrameWriter;
use parapet_firmware::link::{FixClock, Link};

struct Gcs {
    link: Link,
    ap: Cascade,
    w: FrameWriter,
}

impl Gcs {
    fn new() -> Self {
        let ap = Cascade::new(ControllerParams::default()).expect("default parameters");
        Gcs { link: Link::new(1, FixClock::Message), ap, w: FrameWriter::new(255, 190) }
    }

    fn send<D: MessageData>(&mut self, m: &D, now_us: u64) {
        let bytes = self.w.encode(m).raw_bytes().to_vec();
        self.link.push_bytes(&bytes, now_us, &mut self.ap);
        while self.link.pop_reply().is_some() {}
    }
}

/// MANUAL_CONTROL with mode bits `mode` (0 Low, 1 Mid, 2 High) and sticks centred.
fn manual(target: u8, mode: u16) -> MANUAL_CONTROL_DATA {
    MANUAL_CONTROL_DATA { target, x: 0, y: 0, z: 500, r: 0, buttons: mode << 2, ..Default::default() }
}

#[test]
fn manual_control_reaches_the_mode_machine() {
    // Disarmed, the mode switch selects the mode (MODE_SW_LOW/MID/HIGH = Position/Hold/Mission).
    let mut g = Gcs::new();
    assert_eq!(g.ap.telemetry().mode, FlightMode::Mission);
    g.send(&manual(1, 0), 1_000);
    assert_eq!(g.ap.telemetry().mode, FlightMode::Position);
    g.send(&manual(0, 2), 2_000);
    assert_eq!(g.ap.telemetry().mode, FlightMode::Mission);
    // For another vehicle: ignored.
    g.send(&manual(7, 0), 3_000);
    assert_eq!(g.ap.telemetry().mode, FlightMode::Mission);
    let s = g.link.manual_control_stats();
    assert_eq!((s.manual, s.not_for_us), (2, 1));
}

#[test]
fn rc_channels_override_goes_through_the_channel_map() {
    let mut g = Gcs::new();
    let mut m = RC_CHANNELS_OVERRIDE_DATA { target_system: 1, target_component: 1, ..Default::default() };
    // Channels 1..8: UINT16_MAX = keep; 9..18 (0) keep. Mode switch (channel 6) low → Position.
    m.chan1_raw = 1500;
    m.chan2_raw = 1500;
    m.chan3_raw = 1500;
    m.chan4_raw = 1500;
    m.chan5_raw = 1000;
    m.chan6_raw = 1000;
    m.chan7_raw = 1000;
    m.chan8_raw = u16::MAX;
    g.send(&m, 1_000);
    assert_eq!(g.ap.telemetry().mode, FlightMode::Position);
    // Remap the mode switch to channel 8 and move it high (Mission) there.
    assert_eq!(g.ap.set_param("RC_MAP_MODE", 8.0), Ok(8.0));
    m.chan8_raw = 2000;
    g.send(&m, 2_000);
    assert_eq!(g.ap.telemetry().mode, FlightMode::Mission);
    assert_eq!(g.link.manual_control_stats().overrides, 2);
}
