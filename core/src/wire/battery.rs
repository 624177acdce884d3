//! The raw battery reading on the lockstep link (`parapet pil` with a scene `[battery]`): the
//! host's simulated pack, sampled as `parapet run` samples it, goes to the firmware as a
//! **BATTERY_STATUS (147) from the host's system/component id** ([`super::ids::HOST_SYSTEM_ID`],
//! [`super::ids::HOST_COMPONENT_ID`]), host → firmware only, in the lockstep stream before the
//! next step's HIL_SENSOR. Only the PIL application takes it (`firmware/src/pil/battery.rs`); the
//! boards measure their pack with their ADC, and the vehicle's own BATTERY_STATUS (system 1) is
//! the estimator's output, not this raw input.
//!
//! Fields (the message's own units and "unknown" values):
//! - `voltages[0]`: pack voltage, mV; `u16::MAX` ([`UNKNOWN_MV`]) = unknown. A pack above
//!   65.534 V puts 65 534 there and the rest in `voltages[1]`, as the message specifies.
//! - `current_battery`: current, cA; −1 ([`NOT_MEASURED_CA`]) = not measured.
//!
//! Quantisation: 1 mV and 10 mA (rounded). A measured current that rounds to −1 cA (−0.015 A
//! to −0.005 A) is sent as 0 (−1 means "not measured"). A reading with a non-finite or negative
//! voltage or a non-finite current is sent with the voltage unknown: the firmware's estimator
//! refuses the whole sample, as it refuses the reading itself in `parapet run`.
//!
//! May import: nothing of the crate (`libm` for rounding).

/// `voltages[i]` of an unknown (or unused) cell.
pub const UNKNOWN_MV: u16 = u16::MAX;
/// `current_battery` of a pack whose current is not measured.
pub const NOT_MEASURED_CA: i16 = -1;
/// Largest value of one `voltages[i]` (65 534 mV; the next element continues).
pub const MAX_MV: u16 = 65_534;

/// The wire fields of one reading: `voltages[0..2]` and `current_battery`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BatteryWire {
    /// `voltages[0]`, `voltages[1]`, mV.
    pub voltages_mv: [u16; 2],
    /// `current_battery`, cA.
    pub current_ca: i16,
}

/// A reading (pack volts, amps when measured) → the wire fields (see the module docs).
pub fn battery_to_wire(voltage_v: f32, current_a: Option<f32>) -> BatteryWire {
    let current_ok = current_a.is_none_or(f32::is_finite);
    let current_ca = match current_a {
        Some(a) if a.is_finite() => {
            let ca = libm::roundf(a * 100.0).clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16;
            if ca == NOT_MEASURED_CA {
                0
            } else {
                ca
            }
        }
        _ => NOT_MEASURED_CA,
    };
    if !(voltage_v.is_finite() && voltage_v >= 0.0 && current_ok) {
        return BatteryWire { voltages_mv: [UNKNOWN_MV, UNKNOWN_MV], current_ca };
    }
    let mv = libm::roundf(voltage_v * 1000.0);
    let voltages_mv = if mv < f32::from(MAX_MV) {
        [mv as u16, UNKNOWN_MV]
    } else {
        [MAX_MV, (mv - f32::from(MAX_MV)).min(f32::from(MAX_MV)) as u16]
    };
    BatteryWire { voltages_mv, current_ca }
}

/// The wire fields → pack volts (NaN when unknown: the estimator refuses it) and amps (`None`
/// when not measured).
pub fn battery_from_wire(w: BatteryWire) -> (f32, Option<f32>) {
    let [v0, v1] = w.voltages_mv;
    let mv = match (v0, v1) {
        (UNKNOWN_MV, _) => return (f32::NAN, current(w.current_ca)),
        (MAX_MV, rest) if rest != UNKNOWN_MV => u32::from(MAX_MV) + u32::from(rest),
        (v, _) => u32::from(v),
    };
    (mv as f32 / 1000.0, current(w.current_ca))
}

fn current(ca: i16) -> Option<f32> {
    (ca != NOT_MEASURED_CA).then(|| f32::from(ca) / 100.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_round_trip_to_the_wire_resolution() {
        let w = battery_to_wire(11.1234, Some(7.456));
        assert_eq!(w, BatteryWire { voltages_mv: [11_123, UNKNOWN_MV], current_ca: 746 });
        assert_eq!(battery_from_wire(w), (11.123, Some(7.46)));
        assert_eq!(battery_from_wire(battery_to_wire(16.8, None)), (16.8, None));
        // −0.01 A would read "not measured": sent as 0.
        assert_eq!(battery_to_wire(12.0, Some(-0.01)).current_ca, 0);
        assert_eq!(battery_to_wire(12.0, Some(-0.02)).current_ca, -2);
        assert_eq!(battery_to_wire(12.0, Some(1e6)).current_ca, i16::MAX);
    }

    #[test]
    fn a_pack_above_65_volts_continues_in_the_second_element() {
        let w = battery_to_wire(70.0, Some(1.0));
        assert_eq!(w.voltages_mv, [MAX_MV, 4_466]);
        assert_eq!(battery_from_wire(w).0, 70.0);
        // Beyond the two elements: clamped (the estimator refuses anything above 100 V anyway).
        let (v, _) = battery_from_wire(battery_to_wire(500.0, None));
        assert_eq!(v, 131.068);
    }

    #[test]
    fn bad_readings_go_out_unknown_and_come_back_nan() {
        for (v, i) in [(f32::NAN, None), (-1.0, Some(1.0)), (f32::INFINITY, None), (12.0, Some(f32::NAN))] {
            let w = battery_to_wire(v, i);
            assert_eq!(w.voltages_mv[0], UNKNOWN_MV, "{v} {i:?}");
            assert!(battery_from_wire(w).0.is_nan());
        }
        let raw = BatteryWire { voltages_mv: [UNKNOWN_MV, 5], current_ca: 120 };
        let (v, i) = battery_from_wire(raw);
        assert!(v.is_nan());
        assert_eq!(i, Some(1.2));
    }
}
