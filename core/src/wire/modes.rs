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
