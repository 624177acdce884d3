//! MAVLink's standard modes protocol (<https://mavlink.io/en/services/standard_modes.html>),
//! as PX4 serves it beside its `custom_mode` encoding: AVAILABLE_MODES (435) on request
//! (MAV_CMD_REQUEST_MESSAGE, param2 = mode index from 1, 0 = all), CURRENT_MODE (436) and
//! AVAILABLE_MODES_MONITOR (437) with each HEARTBEAT and CURRENT_MODE at once on a mode change,
//! and MAV_CMD_DO_SET_STANDARD_MODE (262, [`crate::link::command`]). QGroundControl 4.4+ and
//! MAVSDK list a vehicle's modes from AVAILABLE_MODES.
//!
//! The modes, their standard numbers, properties and names are the core's
//! (`parapet_core::wire::modes`: [`AVAILABLE_MODES`], `FlightMode::standard_mode`, …): defined
//! once. The list never changes in flight, so the monitor's `seq` is always 0.
//!
//! May import: the dialect, `app::autopilot` (the snapshot), `parapet_core::wire::modes`.

use crate::app::autopilot::{FlightMode, TelemetrySnapshot};
use crate::link::dialect::{
    MavModeProperty, MavStandardMode, AVAILABLE_MODES_DATA, AVAILABLE_MODES_MONITOR_DATA, CURRENT_MODE_DATA,
};
use parapet_core::wire::modes::{standard_mode, AVAILABLE_MODES};

/// MAVLink message id of AVAILABLE_MODES (MAV_CMD_REQUEST_MESSAGE param1).
pub const AVAILABLE_MODES_ID: f32 = 435.0;

/// The wire enum of a standard mode number (those the core maps modes to).
fn standard(mode: FlightMode) -> MavStandardMode {
    match mode.standard_mode() {
        standard_mode::POSITION_HOLD => MavStandardMode::MAV_STANDARD_MODE_POSITION_HOLD,
        standard_mode::SAFE_RECOVERY => MavStandardMode::MAV_STANDARD_MODE_SAFE_RECOVERY,
        standard_mode::MISSION => MavStandardMode::MAV_STANDARD_MODE_MISSION,
        standard_mode::LAND => MavStandardMode::MAV_STANDARD_MODE_LAND,
        _ => MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD,
    }
}

/// The modes a REQUEST_MESSAGE(AVAILABLE_MODES, `param2`) asks for, as an inclusive range of
/// mode indices (from 1): 0 = all, k = the k-th; `None` for any other value (DENIED).
pub fn requested(param2: f32) -> Option<(u8, u8)> {
    let n = AVAILABLE_MODES.len() as u8;
    if param2 == 0.0 {
        return Some((1, n));
    }
    let whole = param2 >= 1.0 && param2 <= f32::from(n) && f32::from(param2 as u8) == param2;
    whole.then_some((param2 as u8, param2 as u8))
}

/// AVAILABLE_MODES for mode index `index` (from 1; `None` outside the list).
pub fn available_mode(index: u8) -> Option<AVAILABLE_MODES_DATA> {
    let mode = *AVAILABLE_MODES.get(usize::from(index).checked_sub(1)?)?;
    let mut name = [0u8; 35];
    for (d, c) in name.iter_mut().zip(mode.display_name().bytes()) {
        *d = c;
    }
    Some(AVAILABLE_MODES_DATA {
        custom_mode: mode.px4_custom_mode(),
        properties: MavModeProperty::from_bits_truncate(mode.mode_properties()),
        number_modes: AVAILABLE_MODES.len() as u8,
        mode_index: index,
        standard_mode: standard(mode),
        mode_name: name.into(),
    })
}

/// CURRENT_MODE: the mode flown (`reported`, as HEARTBEAT's `custom_mode`) and the mode last
/// selected (`intended_custom_mode`; differs while a failsafe lands or brakes).
pub fn current_mode(reported: FlightMode, s: &TelemetrySnapshot) -> CURRENT_MODE_DATA {
    CURRENT_MODE_DATA {
        custom_mode: reported.px4_custom_mode(),
        intended_custom_mode: s.mode.px4_custom_mode(),
        standard_mode: standard(reported),
    }
}

/// AVAILABLE_MODES_MONITOR: the list never changes, `seq` 0.
pub fn monitor() -> AVAILABLE_MODES_MONITOR_DATA {
    AVAILABLE_MODES_MONITOR_DATA { seq: 0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::telemetry::name_is;

    #[test]
    fn every_mode_is_listed_once_with_its_px4_number_standard_mode_and_name() {
        let n = AVAILABLE_MODES.len() as u8;
        assert_eq!(requested(0.0), Some((1, n)));
        assert_eq!(requested(3.0), Some((3, 3)));
        for bad in [f32::NAN, -1.0, 0.5, f32::from(n) + 1.0, f32::INFINITY] {
            assert_eq!(requested(bad), None, "{bad}");
        }
        assert!(available_mode(0).is_none() && available_mode(n + 1).is_none());
        let mut seen = [false; 7];
        for i in 1..=n {
            let Some(m) = available_mode(i) else { panic!("index {i}") };
            assert_eq!((m.mode_index, m.number_modes), (i, n));
            let Some(mode) = FlightMode::from_px4_custom_mode(m.custom_mode) else { panic!("{i}") };
            assert!(!seen[mode as usize], "{} twice", mode.as_str());
            seen[mode as usize] = true;
            assert!(name_is(&m.mode_name, mode.display_name()), "{}", mode.as_str());
            let want = match mode {
                FlightMode::Position => MavStandardMode::MAV_STANDARD_MODE_POSITION_HOLD,
                FlightMode::Mission => MavStandardMode::MAV_STANDARD_MODE_MISSION,
                FlightMode::Return => MavStandardMode::MAV_STANDARD_MODE_SAFE_RECOVERY,
                FlightMode::Land => MavStandardMode::MAV_STANDARD_MODE_LAND,
                _ => MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD,
            };
            assert_eq!(m.standard_mode, want, "{}", mode.as_str());
        }
        assert!(seen.iter().all(|s| *s));
    }
}
