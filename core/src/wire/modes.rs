//! The vehicle's modes as the outside reads them: PX4's `vehicle_status.nav_state` numbers
//! (the ULog of the firmware and of the host), defined once from the core's two mode types —
//! the selected [`FlightMode`] (HEARTBEAT `custom_mode`, [`FlightMode::px4_custom_mode`]) and
//! the [`GuidanceMode`] that produced the reference in the step.
//!
//! PX4's numbering is that of `msg/VehicleStatus.msg` (`NAVIGATION_STATE_*`); Flight Review,
//! PlotJuggler and pyulog users read these numbers as PX4's modes.

use crate::outer::guidance::GuidanceMode;
use crate::supervisor::modes::FlightMode;

/// PX4 `vehicle_status.nav_state` codes (`NAVIGATION_STATE_*` of `VehicleStatus.msg`).
pub mod nav_state {
    /// MANUAL: attitude from the sticks.
    pub const MANUAL: u8 = 0;
    /// POSCTL: position control from the sticks.
    pub const POSCTL: u8 = 2;
    /// AUTO_MISSION.
    pub const AUTO_MISSION: u8 = 3;
    /// AUTO_LOITER: hold a position.
    pub const AUTO_LOITER: u8 = 4;
    /// AUTO_RTL: return to launch.
    pub const AUTO_RTL: u8 = 5;
    /// DESCEND: descend without a position estimate.
    pub const DESCEND: u8 = 12;
    /// OFFBOARD.
    pub const OFFBOARD: u8 = 14;
    /// AUTO_TAKEOFF.
    pub const AUTO_TAKEOFF: u8 = 17;
    /// AUTO_LAND.
    pub const AUTO_LAND: u8 = 18;
}

impl FlightMode {
    /// PX4 `nav_state` of the selected mode: Manual 0, Position 2, Mission 3, Hold 4, Return 5,
    /// Offboard 14, Land 18.
    pub const fn px4_nav_state(self) -> u8 {
        match self {
            FlightMode::Manual => nav_state::MANUAL,
            FlightMode::Position => nav_state::POSCTL,
            FlightMode::Mission => nav_state::AUTO_MISSION,
            FlightMode::Hold => nav_state::AUTO_LOITER,
            FlightMode::Return => nav_state::AUTO_RTL,
            FlightMode::Offboard => nav_state::OFFBOARD,
            FlightMode::Land => nav_state::AUTO_LAND,
        }
    }
}

/// PX4 `nav_state` of a step: what the vehicle does (`guidance`) where PX4 has a state for it —
/// takeoff 17, land 18, mission 3, return 5, offboard 14, position assist 2, manual 0, brake
/// (holding the last good position) 4, no position fix 12 (descend) —, and the `selected` mode's
/// state while it waits (motors off, on the ground, holding a point).
pub const fn px4_nav_state(guidance: GuidanceMode, selected: FlightMode) -> u8 {
    match guidance {
        GuidanceMode::Takeoff => nav_state::AUTO_TAKEOFF,
        GuidanceMode::Land => nav_state::AUTO_LAND,
        GuidanceMode::Mission => nav_state::AUTO_MISSION,
        GuidanceMode::Return => nav_state::AUTO_RTL,
        GuidanceMode::Offboard => nav_state::OFFBOARD,
        GuidanceMode::Assist => nav_state::POSCTL,
        GuidanceMode::Manual => nav_state::MANUAL,
        GuidanceMode::Brake => nav_state::AUTO_LOITER,
        GuidanceMode::NoFix => nav_state::DESCEND,
        GuidanceMode::Off | GuidanceMode::Ground | GuidanceMode::Hold => selected.px4_nav_state(),
    }
}

/// MAVLink's standard flight modes (`MAV_STANDARD_MODE`, common.xml; the standard modes
/// protocol: AVAILABLE_MODES, CURRENT_MODE, MAV_CMD_DO_SET_STANDARD_MODE).
pub mod standard_mode {
    /// A mode without a standard meaning (named in AVAILABLE_MODES).
    pub const NON_STANDARD: u8 = 0;
    /// Position hold with the sticks (PX4 POSCTL).
    pub const POSITION_HOLD: u8 = 1;
    /// Safe recovery: return to launch (PX4 AUTO.RTL).
    pub const SAFE_RECOVERY: u8 = 5;
    /// The uploaded mission (PX4 AUTO.MISSION).
    pub const MISSION: u8 = 6;
    /// Land here (PX4 AUTO.LAND).
    pub const LAND: u8 = 7;
}

/// `MAV_MODE_PROPERTY` bits of AVAILABLE_MODES `properties`.
pub mod mode_property {
    /// An advanced mode (a ground station may hide it from a simple mode list).
    pub const ADVANCED: u32 = 1;
    /// Not selectable by the user (entered by the vehicle or a companion only).
    pub const NOT_USER_SELECTABLE: u32 = 2;
}

/// The modes AVAILABLE_MODES lists, in `mode_index` order (index `i + 1`): every [`FlightMode`].
pub const AVAILABLE_MODES: [FlightMode; FlightMode::COUNT] = FlightMode::ALL;

impl FlightMode {
    /// Its `MAV_STANDARD_MODE` (PX4's mapping: POSCTL → POSITION_HOLD, AUTO.RTL → SAFE_RECOVERY,
    /// AUTO.MISSION → MISSION, AUTO.LAND → LAND; Manual, Hold and Offboard are PX4-specific).
    pub const fn standard_mode(self) -> u8 {
        match self {
            FlightMode::Position => standard_mode::POSITION_HOLD,
            FlightMode::Return => standard_mode::SAFE_RECOVERY,
            FlightMode::Mission => standard_mode::MISSION,
            FlightMode::Land => standard_mode::LAND,
            FlightMode::Manual | FlightMode::Hold | FlightMode::Offboard => standard_mode::NON_STANDARD,
        }
    }

    /// The mode of a standard mode (MAV_CMD_DO_SET_STANDARD_MODE param1), `None` for
    /// NON_STANDARD and the standard modes this vehicle does not fly (orbit, cruise, altitude
    /// hold, takeoff).
    pub fn from_standard_mode(mode: u8) -> Option<FlightMode> {
        if mode == standard_mode::NON_STANDARD {
            return None;
        }
        Self::ALL.into_iter().find(|m| m.standard_mode() == mode)
    }

    /// Its AVAILABLE_MODES `properties`: Offboard is entered by a companion computer streaming
    /// set-points (NOT_USER_SELECTABLE, as PX4 lists it for a ground station's mode menu);
    /// Manual is ADVANCED (no position control, no safety filter).
    pub const fn mode_properties(self) -> u32 {
        match self {
            FlightMode::Offboard => mode_property::NOT_USER_SELECTABLE,
            FlightMode::Manual => mode_property::ADVANCED,
            _ => 0,
        }
    }

    /// The name a ground station shows (AVAILABLE_MODES `mode_name`), as PX4 names its modes.
    pub const fn display_name(self) -> &'static str {
        match self {
            FlightMode::Manual => "Manual",
            FlightMode::Position => "Position",
            FlightMode::Mission => "Mission",
            FlightMode::Hold => "Hold",
            FlightMode::Return => "Return",
            FlightMode::Land => "Land",
            FlightMode::Offboard => "Offboard",
        }
    }
}

/// The guidance mode a lockstep host infers from what the firmware reports: the phase
/// (NAMED_VALUE_INT `PHASE`, [`super::codes::FlightPhase`]) and the selected mode (HEARTBEAT
/// `custom_mode`). The phase merges some guidance modes (Return flies as `Mission`, the piloted
/// modes as `Hover`); the selected mode tells them apart.
pub fn guidance_of_phase(phase: super::codes::FlightPhase, selected: Option<FlightMode>) -> GuidanceMode {
    use super::codes::FlightPhase;
    match (phase, selected) {
        (FlightPhase::Disarmed, _) => GuidanceMode::Off,
        (FlightPhase::Idle, _) => GuidanceMode::Ground,
        (FlightPhase::Takeoff, _) => GuidanceMode::Takeoff,
        (FlightPhase::Mission, Some(FlightMode::Return)) => GuidanceMode::Return,
        (FlightPhase::Mission, _) => GuidanceMode::Mission,
        (FlightPhase::Hover, Some(FlightMode::Position)) => GuidanceMode::Assist,
        (FlightPhase::Hover, Some(FlightMode::Manual)) => GuidanceMode::Manual,
        (FlightPhase::Hover, Some(FlightMode::Offboard)) => GuidanceMode::Offboard,
        (FlightPhase::Hover, _) => GuidanceMode::Hold,
        (FlightPhase::Landing, _) => GuidanceMode::Land,
        (FlightPhase::Failsafe, _) => GuidanceMode::Brake,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::codes::FlightPhase;

    #[test]
    fn the_selected_modes_have_px4_s_numbers() {
        let want = [
            (FlightMode::Manual, 0),
            (FlightMode::Position, 2),
            (FlightMode::Mission, 3),
            (FlightMode::Hold, 4),
            (FlightMode::Return, 5),
            (FlightMode::Offboard, 14),
            (FlightMode::Land, 18),
        ];
        assert_eq!(want.len(), FlightMode::COUNT);
        for (m, n) in want {
            assert_eq!(m.px4_nav_state(), n, "{}", m.as_str());
        }
    }

    #[test]
    fn standard_modes_round_trip_and_the_rest_are_named() {
        let want = [
            (FlightMode::Manual, 0),
            (FlightMode::Position, 1),
            (FlightMode::Mission, 6),
            (FlightMode::Hold, 0),
            (FlightMode::Return, 5),
            (FlightMode::Offboard, 0),
            (FlightMode::Land, 7),
        ];
        assert_eq!(want.len(), FlightMode::COUNT);
        for (m, n) in want {
            assert_eq!(m.standard_mode(), n, "{}", m.as_str());
            if n != 0 {
                assert_eq!(FlightMode::from_standard_mode(n), Some(m));
            }
            assert!(!m.display_name().is_empty() && m.display_name().len() < 35);
        }
        // NON_STANDARD, orbit (2), cruise (3), altitude hold (4), takeoff (8), unknown: not flown.
        for n in [0, 2, 3, 4, 8, 9, 255] {
            assert_eq!(FlightMode::from_standard_mode(n), None, "{n}");
        }
        assert_eq!(AVAILABLE_MODES.len(), FlightMode::COUNT);
    }

    #[test]
    fn every_guidance_mode_has_a_nav_state_and_waiting_ones_take_the_selected_mode_s() {
        for g in GuidanceMode::ALL {
            for m in FlightMode::ALL {
                let n = px4_nav_state(g, m);
                assert!([0, 2, 3, 4, 5, 12, 14, 17, 18].contains(&n), "{g:?} {m:?} → {n}");
            }
        }
        assert_eq!(px4_nav_state(GuidanceMode::Assist, FlightMode::Position), 2);
        assert_eq!(px4_nav_state(GuidanceMode::Return, FlightMode::Return), 5);
        assert_eq!(px4_nav_state(GuidanceMode::Land, FlightMode::Return), 18);
        assert_eq!(px4_nav_state(GuidanceMode::Ground, FlightMode::Position), 2);
        assert_eq!(px4_nav_state(GuidanceMode::Off, FlightMode::Mission), 3);
        assert_eq!(px4_nav_state(GuidanceMode::Hold, FlightMode::Hold), 4);
        assert_eq!(px4_nav_state(GuidanceMode::Takeoff, FlightMode::Mission), 17);
    }

    #[test]
    fn guidance_codes_and_names_round_trip() {
        for (i, g) in GuidanceMode::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(g.code()), i);
            assert_eq!(GuidanceMode::from_code(g.code()), Some(g));
            assert_eq!(GuidanceMode::from_name(g.as_str()), Some(g));
        }
        assert_eq!(GuidanceMode::from_code(GuidanceMode::COUNT as u8), None);
        assert_eq!(GuidanceMode::from_name("Loiter"), None);
    }

    #[test]
    fn a_lockstep_host_tells_the_merged_phases_apart_by_the_selected_mode() {
        let g = |p, m| guidance_of_phase(p, Some(m));
        assert_eq!(g(FlightPhase::Mission, FlightMode::Return), GuidanceMode::Return);
        assert_eq!(g(FlightPhase::Mission, FlightMode::Mission), GuidanceMode::Mission);
        assert_eq!(g(FlightPhase::Hover, FlightMode::Position), GuidanceMode::Assist);
        assert_eq!(g(FlightPhase::Hover, FlightMode::Offboard), GuidanceMode::Offboard);
        assert_eq!(g(FlightPhase::Hover, FlightMode::Hold), GuidanceMode::Hold);
        assert_eq!(guidance_of_phase(FlightPhase::Hover, None), GuidanceMode::Hold);
        assert_eq!(g(FlightPhase::Failsafe, FlightMode::Mission), GuidanceMode::Brake);
        // The nav_state the host writes for a PIL flight is the in-process one for these modes.
        for (p, m, n) in [
            (FlightPhase::Hover, FlightMode::Position, 2),
            (FlightPhase::Mission, FlightMode::Return, 5),
            (FlightPhase::Landing, FlightMode::Return, 18),
            (FlightPhase::Mission, FlightMode::Mission, 3),
            (FlightPhase::Hover, FlightMode::Offboard, 14),
        ] {
            assert_eq!(px4_nav_state(g(p, m), m), n, "{p:?} {m:?}");
        }
    }
}
