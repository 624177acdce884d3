//! The PIL's battery measurement: the host's simulated pack (`parapet pil` with a scene
//! `[battery]`) arrives as a raw reading on the lockstep link — BATTERY_STATUS (147) from the
//! host's system and component id, `voltages[0]` mV, `current_battery` cA (the wire contract
//! `parapet_core::wire::battery`) — and is measured the way a board's battery task measures its
//! ADC (`src/bin/fc/mod.rs` `battery_task`): `parapet_core::battery::BatteryEstimator` with the `BAT_*`
//! parameters as set (followed with `set_params` when they change, which keeps the filter and
//! the level reached), armed from the cascade's telemetry, and every resulting state to the
//! cascade's `set_battery` (low → Return, critical → Land). Bad readings (unknown or non-finite
//! voltage, out of range) are the estimator's to refuse: counted, the state unchanged.
//!
//! The frame is taken out of the byte stream before the link dispatches it
//! ([`is_host_reading`], `Link::push_byte_diverting`), so only the PIL application ever sees it
//! as a reading; on a board a BATTERY_STATUS from anyone is an ignored message. The reading is
//! stamped with the firmware clock of the last answered step (the lockstep link's clock: the
//! host sends it in the step after the one it was sampled in, so that is the sample's time).
//!
//! May import: `parapet_core` (battery, wire contract), [`crate::app`] (the `Autopilot`
//! boundary), [`crate::link`] (frames, dialect). Not drivers or boards.

use mavlink_core::{MavlinkVersion, MessageData};
use parapet_core::battery::{BatteryEstimator, BatteryParams, BatterySample};
use parapet_core::wire::battery::{battery_from_wire, BatteryWire};
use parapet_core::wire::ids::{HOST_COMPONENT_ID, HOST_SYSTEM_ID};

use crate::app::autopilot::Autopilot;
use crate::link::dialect::BATTERY_STATUS_DATA;
use crate::link::frame_parser::RawFrame;

/// One raw reading from the host: pack volts (NaN when unknown), amps when measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HostReading {
    /// Pack voltage, V.
    pub voltage_v: f32,
    /// Current, A, when the pack's current is measured.
    pub current_a: Option<f32>,
}

/// Counters of the PIL battery input (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PilBatteryStats {
    /// Readings taken from the host.
    pub readings: u32,
    /// Readings the estimator refused (unknown, non-finite or out-of-range values).
    pub refused: u32,
    /// Readings dropped because the stack has no battery parameters (`battery_params` `None`).
    pub no_params: u32,
    /// Host BATTERY_STATUS frames whose payload did not decode.
    pub undecodable: u32,
}

/// `true` for a frame that is the host's raw battery reading (BATTERY_STATUS from the host's
/// system and component id).
pub fn is_host_reading(f: &RawFrame<'_>) -> bool {
    f.msg_id == BATTERY_STATUS_DATA::ID && f.sys_id == HOST_SYSTEM_ID && f.comp_id == HOST_COMPONENT_ID
}

/// The reading a BATTERY_STATUS payload carries (see the module docs); `None` when it does not
/// decode.
pub fn reading_of(payload: &[u8]) -> Option<HostReading> {
    let m = BATTERY_STATUS_DATA::deser(MavlinkVersion::V2, payload).ok()?;
    let wire = BatteryWire { voltages_mv: [m.voltages[0], m.voltages[1]], current_ca: m.current_battery };
    let (voltage_v, current_a) = battery_from_wire(wire);
    Some(HostReading { voltage_v, current_a })
}

/// The estimator of the host-fed pack (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct PilBattery {
    estimator: Option<(BatteryParams, BatteryEstimator)>,
    stats: PilBatteryStats,
}

impl PilBattery {
    /// No reading yet.
    pub const fn new() -> Self {
        Self {
            estimator: None,
            stats: PilBatteryStats { readings: 0, refused: 0, no_params: 0, undecodable: 0 },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> PilBatteryStats {
        self.stats
    }

    /// Cells of the estimator (0 before the first reading or until detected).
    pub fn cells(&self) -> u8 {
        self.estimator.as_ref().map_or(0, |(_, e)| e.cells())
    }

    /// Counts a host BATTERY_STATUS that did not decode.
    pub fn undecodable(&mut self) {
        self.stats.undecodable = self.stats.undecodable.saturating_add(1);
    }

    /// Measures `r` at firmware time `now_us` and hands the state to `ap` (as the boards'
    /// battery task does); returns what the estimator made of it, `None` when `ap` has no
    /// battery parameters.
    pub fn take<A: Autopilot>(&mut self, now_us: u64, r: HostReading, ap: &mut A) -> Option<BatterySample> {
        let Some(p) = ap.battery_params() else {
            self.stats.no_params = self.stats.no_params.saturating_add(1);
            return None;
        };
        let (params, estimator) = self.estimator.get_or_insert_with(|| (p, BatteryEstimator::new(p)));
        if *params != p {
            *params = p;
            estimator.set_params(p);
        }
        let armed = ap.telemetry().armed;
        let s = estimator.update(now_us, r.voltage_v, r.current_a, armed);
        self.stats.readings = self.stats.readings.saturating_add(1);
        if matches!(s, BatterySample::Rejected(_)) {
            self.stats.refused = self.stats.refused.saturating_add(1);
        }
        ap.set_battery(&s.state());
        Some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;
    use crate::link::framing::FrameWriter;
    use parapet_core::battery::BatteryLevel;
    use parapet_core::wire::battery::{battery_to_wire, UNKNOWN_MV};

    fn status(w: BatteryWire) -> BATTERY_STATUS_DATA {
        let mut voltages = [UNKNOWN_MV; 10];
        voltages[..2].copy_from_slice(&w.voltages_mv);
        BATTERY_STATUS_DATA { voltages, current_battery: w.current_ca, ..Default::default() }
    }

    fn payload(m: &BATTERY_STATUS_DATA) -> std::vec::Vec<u8> {
        let mut w = FrameWriter::new(HOST_SYSTEM_ID, HOST_COMPONENT_ID);
        let raw = w.encode(m);
        let bytes = raw.raw_bytes();
        // MAVLink 2 header: 10 bytes; payload length at byte 1; then the 2-byte CRC.
        bytes[10..10 + usize::from(bytes[1])].to_vec()
    }

    #[test]
    fn the_payload_carries_the_reading_of_the_wire_contract() {
        let r = reading_of(&payload(&status(battery_to_wire(11.4, Some(6.25))))).expect("decodes");
        assert_eq!(r, HostReading { voltage_v: 11.4, current_a: Some(6.25) });
        let r = reading_of(&payload(&status(battery_to_wire(16.0, None)))).expect("decodes");
        assert_eq!(r.current_a, None);
        let r = reading_of(&payload(&status(battery_to_wire(f32::NAN, None)))).expect("decodes");
        assert!(r.voltage_v.is_nan());
    }

    #[test]
    fn without_battery_parameters_nothing_is_measured() {
        let mut ap = RecordingAutopilot::new();
        let mut b = PilBattery::new();
        assert_eq!(b.take(1_000, HostReading { voltage_v: 12.0, current_a: None }, &mut ap), None);
        assert_eq!(b.stats().no_params, 1);
        assert_eq!(b.stats().readings, 0);
        assert_eq!(ap.battery, None);
    }

    #[test]
    fn readings_feed_the_estimator_and_bad_ones_are_refused() {
        let mut ap = RecordingAutopilot::new();
        ap.battery_params = Some(BatteryParams { cells: 3, ..BatteryParams::default() });
        ap.armed = true;
        let mut b = PilBattery::new();
        let ok = b.take(1_000_000, HostReading { voltage_v: 12.0, current_a: Some(5.0) }, &mut ap);
        let Some(BatterySample::Accepted(s)) = ok else { panic!("{ok:?}") };
        assert_eq!(
            (s.t_us, s.voltage_v, s.current_a, s.level),
            (1_000_000, 12.0, Some(5.0), BatteryLevel::Ok)
        );
        assert_eq!(ap.battery, Some(s), "the cascade got the state");
        for bad in [f32::NAN, 150.0, -3.0, f32::INFINITY] {
            let r = b.take(1_100_000, HostReading { voltage_v: bad, current_a: Some(5.0) }, &mut ap);
            assert!(matches!(r, Some(BatterySample::Rejected(x)) if x == s), "{bad}: {r:?}");
            assert_eq!(ap.battery, Some(s), "{bad}: the last accepted state, unchanged");
        }
        let r = b.take(1_100_000, HostReading { voltage_v: 12.0, current_a: Some(f32::NAN) }, &mut ap);
        assert!(matches!(r, Some(BatterySample::Rejected(_))));
        assert_eq!(b.stats(), PilBatteryStats { readings: 6, refused: 5, no_params: 0, undecodable: 0 });
        // 3.45 V per cell (BAT_LOW_V 3.5) for longer than the debounce: Low; then a parameter
        // change is followed (BAT_CRIT_V 3.5: Critical) from the level reached.
        let mut t = 1_200_000;
        for _ in 0..40 {
            b.take(t, HostReading { voltage_v: 3.0 * 3.45, current_a: None }, &mut ap);
            t += 100_000;
        }
        assert_eq!(ap.battery.map(|s| s.level), Some(BatteryLevel::Low));
        ap.battery_params = Some(BatteryParams {
            cells: 3,
            critical_cell_v: 3.5,
            low_cell_v: 3.6,
            ..BatteryParams::default()
        });
        for _ in 0..30 {
            b.take(t, HostReading { voltage_v: 3.0 * 3.45, current_a: None }, &mut ap);
            t += 100_000;
        }
        assert_eq!(ap.battery.map(|s| s.level), Some(BatteryLevel::Critical));
        assert_eq!(b.cells(), 3);
    }
}
