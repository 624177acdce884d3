//! What the host reads from the firmware: the telemetry decoded with the wire
//! contract's names and codes (`parapet_core::wire`) — filter diagnostics, the
//! nominal and filtered acceleration, the flight phase (NAMED_VALUE_INT `PHASE`),
//! the flight mode (HEARTBEAT `custom_mode` in PX4's encoding, and the "MODE <mode>:
//! <reason>" STATUSTEXT of every change, with its time), the link counters, the instruction
//! counts, the battery the firmware reports (BATTERY_STATUS, SYS_STATUS) — and the PIL figures
//! of `summary.json`.
//!
//! May import: `parapet-core` (wire contract, filter types), mavlink, serde,
//! [`crate::flight::stack`] (what an outer step reports).

use std::time::Duration;

use mavlink::dialects::ardupilotmega::{
    MavBatteryChargeState, MavMessage, MavModeFlag, MavState, BATTERY_STATUS_DATA,
};
use nalgebra::Vector3;
use parapet_core::cbf::{FilterDiagnostics, Region};
use parapet_core::controller::{FlightMode, GuidanceMode};
use parapet_core::safety::governor::GovernorCause;
use parapet_core::waypoint::PathSample;
use parapet_core::wire::battery::{battery_from_wire, BatteryWire};
use parapet_core::wire::codes::{
    active_id_from_wire, governor_from_wire, region_from_wire, CbfFlags, FlightPhase,
};
use parapet_core::wire::modes::guidance_of_phase;
use parapet_core::wire::names;
use serde::Serialize;

use crate::flight::stack::{OuterOut, CLOCK_OFFSET_S};
use crate::world::scene::to_f64;

/// Instructions per control step (firmware's `ins_step`: inner step + outer step when due +
/// obstacle batch, counted by the `-icount shift=0` SysTick and calibrated by the firmware with
/// `ins_cal_n` instructions = `ins_cal` ticks).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct InstructionFigures {
    /// Mean over the flight steps.
    pub mean: f64,
    /// Max over the flight steps.
    pub max: u64,
    /// Mean over the steps with an outer step.
    pub mean_outer_steps: f64,
    /// Mean over the inner-only steps.
    pub mean_inner_only_steps: f64,
    /// The outer step alone (`step_outer`: waypoint, PD, CBF filter, thrust mapping; the
    /// firmware's `ins_outer`), mean over the outer steps.
    pub mean_outer_loop: f64,
    /// The outer step alone, max.
    pub max_outer_loop: u64,
    /// Longest section with interrupts masked in any flight step (the firmware's
    /// `ins_masked`: its critical sections, i.e. mailbox message copies), instructions.
    pub max_masked: u64,
    /// Flight steps that reported `ins_masked`.
    pub masked_steps: u64,
    /// Steps counted.
    pub steps: u64,
    /// Calibration: instructions of the calibration loop (`ins_cal_n`).
    pub calibration_instructions: i64,
    /// Calibration: SysTick ticks they took (`ins_cal`).
    pub calibration_ticks: i64,
    /// Lower bound of the worst step on a 168 MHz Cortex-M4 (max / 168), µs.
    pub max_time_at_168mhz_us: f64,
}

/// PIL figures added to `summary.json` (object `pil`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PilFigures {
    /// Firmware ELF flown.
    pub firmware: String,
    /// MAVLink frames the host sent (injected drops not counted; re-sent HIL_SENSORs counted).
    pub frames_sent: u64,
    /// CRC-valid MAVLink frames received from the firmware.
    pub frames_received: u64,
    /// Frames lost on the link: host-side (firmware frames missing by sequence number, or
    /// undecodable) + the firmware's counters (CRC errors + malformed, last `DEBUG_VECT LINK`;
    /// replies dropped + inbound messages rejected, last `DEBUG_VECT LINK_DROP`).
    pub frames_dropped: u64,
    /// Firmware frames the host found missing (sequence gaps).
    pub host_sequence_gaps: u64,
    /// Firmware frames the host could not decode.
    pub host_decode_errors: u64,
    /// Firmware's count of host frames with a bad CRC (last `LINK` report; 1 Hz).
    pub firmware_crc_errors: u64,
    /// Firmware's count of malformed host frames (last `LINK` report).
    pub firmware_malformed: u64,
    /// Firmware's count of good host frames (last `LINK` report).
    pub firmware_frames_ok: u64,
    /// Firmware's replies dropped because its reply queue was full (last `LINK_DROP`, 1 Hz).
    pub firmware_replies_dropped: u64,
    /// Firmware's count of rejected inbound messages (undecodable, bad ODOMETRY, unknown
    /// parameter; last `LINK_DROP`).
    pub firmware_inputs_rejected: u64,
    /// Firmware's count of obstacle points rejected or dropped (batch full; last `LINK_DROP`).
    pub firmware_obstacles_rejected: u64,
    /// Host frames corrupted on purpose (fault injection).
    pub injected_corrupted: u64,
    /// Host frames dropped on purpose (fault injection, HIL_SENSORs included).
    pub injected_dropped: u64,
    /// HIL_SENSORs re-sent after [`PilOptions::resend_after`](super::PilOptions::resend_after) without an answer.
    pub steps_resent: u64,
    /// Lockstep steps of the flight (after the start-up).
    pub flight_steps: u64,
    /// Lockstep steps of the start-up (parameters, mission upload, warm-up, arming).
    pub startup_steps: u64,
    /// Instructions per control step.
    pub instructions_per_control_step: InstructionFigures,
    /// Simulated time flown / wall time of the flight steps.
    pub real_time_factor: f64,
    /// Mean wall time per flight step, ms.
    pub wall_per_step_ms: f64,
    /// Wall time of the handshake and start-up, s.
    pub startup_wall_s: f64,
    /// Firmware failsafe / status messages seen (STATUSTEXT).
    pub status_texts: Vec<String>,
    /// Range scans sent as `OBSTACLE_DISTANCE` (`--perception lidar`: the firmware builds its
    /// own obstacle set from them; 0 when the host sends obstacle points).
    pub obstacle_distance_scans: u64,
    /// The firmware's "MODE <mode>: <reason>" STATUSTEXTs with the simulated time of the step
    /// they came with (the first 64).
    pub mode_changes: Vec<TimedText>,
    /// The scene's battery over the link.
    pub battery: BatteryFigures,
    /// The firmware's on-board replanner (issue 38): its "Replan: …" STATUSTEXTs with the
    /// simulated time of the step they came with (the first 256).
    pub replan_texts: Vec<TimedText>,
    /// Instructions of each plan the firmware served (NAMED_VALUE_INT `ins_rpl`; the first 256).
    pub replan_instructions: Vec<u64>,
    /// ESTIMATOR_STATUS messages received (the navigation filter's, issue 39: sent once a
    /// filtered source such as GPS_INPUT initialised it) and the last one's `flags`.
    pub estimator_status: u64,
    /// `flags` of the last ESTIMATOR_STATUS (0 before the first).
    pub estimator_flags: u16,
    /// Every LOCAL_POSITION_NED (`time_boot_ms`, NED m): the outer loop's position, with a
    /// filtered source the filter's estimate. Not in `summary.json`.
    #[serde(skip)]
    pub local_positions: Vec<(u32, [f32; 3])>,
}

/// How the firmware's replanner STATUSTEXTs begin (`parapet_firmware::app::replanner::event_text`).
const REPLAN_PREFIX: &str = "Replan: ";

/// The firmware's replanning record from its STATUSTEXTs (`summary.json`'s `replans`, … of a PIL
/// run; `replan_checks` is not reported by the firmware: 0).
pub(super) fn replan_summary(enabled: bool, texts: &[TimedText]) -> crate::report::ReplanSummary {
    let events: Vec<crate::report::ReplanEvent> = texts.iter().filter_map(replan_event).collect();
    let count = |o: &str| events.iter().filter(|e| e.outcome == o).count() as u32;
    crate::report::ReplanSummary {
        replan_enabled: enabled,
        replan_checks: 0,
        replans: count("replanned"),
        replan_no_path: count("no_path"),
        replan_budget: count("budget"),
        replan_events: events,
    }
}

/// One "Replan: new path, N wp (D detour)" / "Replan: no path, holding" / "Replan: budget,
/// holding" text as an event.
fn replan_event(t: &TimedText) -> Option<crate::report::ReplanEvent> {
    let rest = t.text.strip_prefix(REPLAN_PREFIX)?;
    let number = |s: &str| s.trim().parse::<usize>().ok();
    let (outcome, waypoints, detour) = if let Some(r) = rest.strip_prefix("new path, ") {
        let (wp, d) = r.split_once(" wp (")?;
        ("replanned", number(wp)?, number(d.strip_suffix(" detour)")?)?)
    } else if rest.starts_with("no path") {
        ("no_path", 0, 0)
    } else {
        ("budget", 0, 0)
    };
    Some(crate::report::ReplanEvent { t_s: t.t_s, outcome, waypoints, detour })
}

/// A STATUSTEXT and the simulated time of the lockstep step it came with.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TimedText {
    /// Simulated time, s (firmware clock − [`CLOCK_OFFSET_S`]).
    pub t_s: f64,
    /// The text.
    pub text: String,
}

/// The scene's `[battery]` over the PIL link (`summary.json` `pil.battery`): the raw readings the
/// host sent (BATTERY_STATUS from the host's id, `parapet_core::wire::battery`) and what the
/// firmware's estimator reported back (its own BATTERY_STATUS, SYS_STATUS).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BatteryFigures {
    /// Raw readings sent to the firmware.
    pub readings_sent: u64,
    /// BATTERY_STATUS messages the firmware sent (1 Hz once it has a measurement).
    pub status_received: u64,
    /// Simulated time of the firmware's first BATTERY_STATUS, s.
    pub first_status_s: Option<f64>,
    /// First BATTERY_STATUS with charge state LOW or worse, s.
    pub low_s: Option<f64>,
    /// First BATTERY_STATUS with charge state CRITICAL or worse, s.
    pub critical_s: Option<f64>,
    /// The last BATTERY_STATUS: pack voltage, V.
    pub last_voltage_v: Option<f64>,
    /// The last BATTERY_STATUS: current, A (`None`: not measured).
    pub last_current_a: Option<f64>,
    /// The last BATTERY_STATUS: remaining charge, % (`None`: unknown).
    pub last_remaining_pct: Option<i8>,
    /// The last BATTERY_STATUS: charge state (`MAV_BATTERY_CHARGE_STATE_*`).
    pub last_charge_state: Option<String>,
    /// The last SYS_STATUS: battery voltage, V (`None`: 65 535, no measurement).
    pub sys_status_voltage_v: Option<f64>,
    /// The last SYS_STATUS: battery current, A (`None`: −1, not measured).
    pub sys_status_current_a: Option<f64>,
    /// The last SYS_STATUS: remaining charge, % (`None`: −1, unknown).
    pub sys_status_remaining_pct: Option<i8>,
}

/// Latest filter report of the firmware.
#[derive(Clone, Copy, Debug)]
pub(super) struct FilterTelemetry {
    /// Smallest h̄ (`DEBUG_VECT CBF.x`), m²; +∞ before the first report.
    pub(super) h_bar: f32,
    /// Region (`CBF.y`).
    pub(super) region: Region,
    /// Active obstacle (`CBF.z`).
    pub(super) active: Option<u16>,
    /// `NAMED_VALUE_INT CBF_FLAGS`.
    pub(super) flags: CbfFlags,
    /// Nominal acceleration u* (`DEBUG_VECT U_NOM`), NED m/s²; NaN before the first report.
    pub(super) u_nominal: Vector3<f64>,
    /// Filtered acceleration u (POSITION_TARGET_LOCAL_NED afx..afz), NED m/s²; NaN before.
    pub(super) u_filtered: Vector3<f64>,
    /// The speed governor (`DEBUG_VECT GOV`): limit along the motion (m/s), cause, acted.
    pub(super) governor: (Option<f32>, GovernorCause, bool),
}

impl Default for FilterTelemetry {
    fn default() -> Self {
        FilterTelemetry {
            h_bar: f32::INFINITY,
            region: Region::NoObstacle,
            active: None,
            flags: CbfFlags::default(),
            u_nominal: Vector3::repeat(f64::NAN),
            u_filtered: Vector3::repeat(f64::NAN),
            governor: (None, GovernorCause::None, false),
        }
    }
}

/// The firmware's latest reports: filter, flight phase (`PHASE`), flight mode (HEARTBEAT
/// `custom_mode`, `FlightMode::from_px4_custom_mode`, and the mode-change STATUSTEXT, which
/// arrives at once), armed, critical.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct FirmwareTelemetry {
    pub(super) filter: FilterTelemetry,
    pub(super) phase: u32,
    pub(super) mode: Option<FlightMode>,
    pub(super) armed: bool,
    pub(super) critical: bool,
}

/// The flight mode of a "MODE <mode>: <reason>" STATUSTEXT.
pub(super) fn mode_of_text(text: &str) -> Option<FlightMode> {
    let name = text.strip_prefix("MODE ")?.split(':').next()?;
    FlightMode::ALL.into_iter().find(|m| m.as_str() == name)
}

impl FirmwareTelemetry {
    /// What the recorder gets from an outer step: the firmware's latest filter report and
    /// phase, with the reference `s` recomputed on the host.
    pub(super) fn outer_out(&self, s: &PathSample) -> OuterOut {
        let f = self.filter;
        OuterOut {
            reference: to_f64(&s.position),
            // The fields the firmware reports (CBF, CBF_FLAGS); it sends neither n_near nor
            // the fault kind (the region says Fault), which keep the core's initial values.
            filter: FilterDiagnostics {
                active_id: f.active,
                h_bar: f.h_bar,
                intervened: f.flags.intervened,
                n_constraints: f.flags.n_constraints,
                unavoidable: f.flags.unavoidable,
                infeasible: f.flags.infeasible,
                ..FilterDiagnostics::new(f.region)
            },
            path_done: s.progress.done,
            u_nominal: f.u_nominal,
            u_filtered: f.u_filtered,
            mode: FlightPhase::from_code(self.phase)
                .map_or(GuidanceMode::Off, |p| guidance_of_phase(p, self.mode)),
            flight_mode: self.mode.unwrap_or_default(),
            // The governor's (`DEBUG_VECT GOV`); deadlock and the obstacle set's drops are not
            // carried by the link.
            safety: crate::report::SafetyFlags {
                governor_limit: f.governor.0,
                governor_cause: f.governor.1,
                governor_active: f.governor.2,
                ..Default::default()
            },
        }
    }

    /// Failsafe state name for the summary (as the host controller's).
    pub(super) fn state_name(&self) -> &'static str {
        match (self.armed, self.critical, FlightPhase::from_code(self.phase)) {
            (_, true, _) => "Failsafe",
            (false, _, _) => "Disarmed",
            (true, _, Some(FlightPhase::Failsafe)) => "Failsafe",
            (true, _, _) => "Armed",
        }
    }
}

/// Telemetry bookkeeping for every inbound message, received with the lockstep step at firmware
/// time `t_us`.
pub(super) fn observe(m: &MavMessage, t_us: u64, t: &mut FirmwareTelemetry, fig: &mut PilFigures) {
    let t_s = (t_us as f64 - CLOCK_OFFSET_S * 1e6) / 1e6;
    match m {
        MavMessage::DEBUG_VECT(d) => match d.name.to_str().unwrap_or("") {
            names::U_NOM => t.filter.u_nominal = Vector3::new(d.x, d.y, d.z).cast(),
            names::GOV => t.filter.governor = governor_from_wire(d.x, d.y, d.z),
            names::CBF => {
                t.filter.h_bar = d.x;
                t.filter.region = region_from_wire(d.y);
                t.filter.active = active_id_from_wire(d.z);
            }
            names::LINK => {
                fig.firmware_frames_ok = d.x.max(0.0) as u64;
                fig.firmware_crc_errors = d.y.max(0.0) as u64;
                fig.firmware_malformed = d.z.max(0.0) as u64;
            }
            names::LINK_DROP => {
                fig.firmware_replies_dropped = d.x.max(0.0) as u64;
                fig.firmware_inputs_rejected = d.y.max(0.0) as u64;
                fig.firmware_obstacles_rejected = d.z.max(0.0) as u64;
            }
            _ => {}
        },
        MavMessage::NAMED_VALUE_INT(n) => {
            let name = n.name.to_str().unwrap_or("");
            match name {
                names::CBF_FLAGS => t.filter.flags = CbfFlags::decode(n.value),
                names::PHASE => t.phase = u32::try_from(n.value).unwrap_or(u32::MAX),
                names::INS_CAL => fig.instructions_per_control_step.calibration_ticks = n.value.into(),
                names::INS_CAL_N => {
                    fig.instructions_per_control_step.calibration_instructions = n.value.into()
                }
                names::INS_REPLAN if fig.replan_instructions.len() < 256 => {
                    fig.replan_instructions.push(u64::try_from(n.value).unwrap_or(0))
                }
                _ => {}
            }
        }
        MavMessage::POSITION_TARGET_LOCAL_NED(p) => {
            t.filter.u_filtered = Vector3::new(p.afx, p.afy, p.afz).cast();
        }
        MavMessage::ESTIMATOR_STATUS(e) => {
            fig.estimator_status += 1;
            fig.estimator_flags = e.flags.bits();
        }
        MavMessage::LOCAL_POSITION_NED(p) => fig.local_positions.push((p.time_boot_ms, [p.x, p.y, p.z])),
        MavMessage::BATTERY_STATUS(b) => battery_status(b, t_s, &mut fig.battery),
        MavMessage::SYS_STATUS(s) => {
            let f = &mut fig.battery;
            f.sys_status_voltage_v =
                (s.voltage_battery != u16::MAX).then(|| f64::from(s.voltage_battery) / 1000.0);
            f.sys_status_current_a = (s.current_battery != -1).then(|| f64::from(s.current_battery) / 100.0);
            f.sys_status_remaining_pct = (s.battery_remaining != -1).then_some(s.battery_remaining);
        }
        MavMessage::HEARTBEAT(h) => {
            // A mode the map does not know keeps the last one (only PX4's encoding is sent).
            if let Some(m) = FlightMode::from_px4_custom_mode(h.custom_mode) {
                t.mode = Some(m);
            }
            t.armed = h.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
            t.critical = h.system_status == MavState::MAV_STATE_CRITICAL;
        }
        MavMessage::STATUSTEXT(s) => {
            let text = String::from_utf8_lossy(&s.text[..]).trim_end_matches('\0').to_string();
            if let Some(m) = mode_of_text(&text) {
                t.mode = Some(m);
                if fig.mode_changes.len() < 64 {
                    fig.mode_changes.push(TimedText { t_s, text: text.clone() });
                }
            }
            if text.starts_with(REPLAN_PREFIX) && fig.replan_texts.len() < 256 {
                fig.replan_texts.push(TimedText { t_s, text: text.clone() });
            }
            if fig.status_texts.len() < 64 {
                fig.status_texts.push(format!("{:?}: {text}", s.severity));
            }
        }
        _ => {}
    }
}

/// The firmware's BATTERY_STATUS at simulated time `t_s` into `f`.
fn battery_status(b: &BATTERY_STATUS_DATA, t_s: f64, f: &mut BatteryFigures) {
    use MavBatteryChargeState as C;
    f.status_received += 1;
    f.first_status_s.get_or_insert(t_s);
    let rank = |c: C| match c {
        C::MAV_BATTERY_CHARGE_STATE_LOW => 1,
        C::MAV_BATTERY_CHARGE_STATE_CRITICAL => 2,
        C::MAV_BATTERY_CHARGE_STATE_EMERGENCY | C::MAV_BATTERY_CHARGE_STATE_FAILED => 3,
        _ => 0,
    };
    if rank(b.charge_state) >= 1 {
        f.low_s.get_or_insert(t_s);
    }
    if rank(b.charge_state) >= 2 {
        f.critical_s.get_or_insert(t_s);
    }
    let (v, _) =
        battery_from_wire(BatteryWire { voltages_mv: [b.voltages[0], b.voltages[1]], current_ca: 0 });
    // The wire's mV in f64 (the f32 volts would read 10.449999809 for 10 450 mV).
    f.last_voltage_v = v.is_finite().then(|| (f64::from(v) * 1e3).round() / 1e3);
    f.last_current_a = (b.current_battery != -1).then(|| f64::from(b.current_battery) / 100.0);
    f.last_remaining_pct = (b.battery_remaining != -1).then_some(b.battery_remaining);
    f.last_charge_state = Some(format!("{:?}", b.charge_state));
}

/// The figures of a flight: the counters in `fig` with the totals, the rates over the
/// flight's `steps` (wall time `wall`) and the instruction statistics of `ins`
/// (`ins_step`, outer step ran) and `ins_outer`.
pub(super) fn figures(
    fig: &PilFigures,
    ins: &[(u64, bool)],
    ins_outer: &[u64],
    wall: Duration,
    steps: u64,
) -> PilFigures {
    let mut f = fig.clone();
    f.frames_dropped = f.host_sequence_gaps
        + f.host_decode_errors
        + f.firmware_crc_errors
        + f.firmware_malformed
        + f.firmware_replies_dropped
        + f.firmware_inputs_rejected;
    f.flight_steps = steps;
    let wall = wall.as_secs_f64();
    if wall > 0.0 {
        f.real_time_factor = steps as f64 * 1e-3 / wall;
        f.wall_per_step_ms = wall * 1e3 / steps.max(1) as f64;
    }
    let mean = |v: &mut dyn Iterator<Item = u64>| {
        let (s, n) = v.fold((0.0, 0u64), |(s, n), x| (s + x as f64, n + 1));
        if n > 0 {
            s / n as f64
        } else {
            0.0
        }
    };
    let i = &mut f.instructions_per_control_step;
    i.steps = ins.len() as u64;
    i.mean = mean(&mut ins.iter().map(|x| x.0));
    i.max = ins.iter().map(|x| x.0).max().unwrap_or(0);
    i.mean_outer_steps = mean(&mut ins.iter().filter(|x| x.1).map(|x| x.0));
    i.mean_inner_only_steps = mean(&mut ins.iter().filter(|x| !x.1).map(|x| x.0));
    i.mean_outer_loop = mean(&mut ins_outer.iter().copied());
    i.max_outer_loop = ins_outer.iter().copied().max().unwrap_or(0);
    i.max_time_at_168mhz_us = i.max as f64 / 168.0;
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{DEBUG_VECT_DATA, HEARTBEAT_DATA, NAMED_VALUE_INT_DATA};
    use parapet_core::wire::codes::{active_id_to_wire, region_to_wire};

    fn name<const N: usize>(s: &str) -> mavlink::types::CharArray<N> {
        let mut b = [0u8; N];
        b[..s.len()].copy_from_slice(s.as_bytes());
        b.into()
    }

    /// The firmware's CBF / CBF_FLAGS / HEARTBEAT reports decode into the core's diagnostics
    /// type with the wire contract's codes.
    #[test]
    fn filter_reports_decode_into_the_core_diagnostics() {
        let (mut t, mut fig) = (FirmwareTelemetry::default(), PilFigures::default());
        let cbf = DEBUG_VECT_DATA {
            name: name(names::CBF),
            x: 0.25,
            y: region_to_wire(Region::Perpendicular),
            z: active_id_to_wire(Some(7)),
            ..Default::default()
        };
        observe(&MavMessage::DEBUG_VECT(cbf), 0, &mut t, &mut fig);
        let flags = CbfFlags { intervened: true, unavoidable: false, infeasible: true, n_constraints: 2 };
        let nv = NAMED_VALUE_INT_DATA {
            name: name(names::CBF_FLAGS),
            value: flags.encode(),
            ..Default::default()
        };
        observe(&MavMessage::NAMED_VALUE_INT(nv), 0, &mut t, &mut fig);
        let phase = NAMED_VALUE_INT_DATA {
            name: name(names::PHASE),
            value: FlightPhase::Mission.code() as i32,
            ..Default::default()
        };
        observe(&MavMessage::NAMED_VALUE_INT(phase), 0, &mut t, &mut fig);
        let hb = HEARTBEAT_DATA { custom_mode: FlightMode::Return.px4_custom_mode(), ..Default::default() };
        observe(&MavMessage::HEARTBEAT(hb), 0, &mut t, &mut fig);
        assert_eq!(t.mode, Some(FlightMode::Return), "custom_mode is the PX4 flight mode");
        let z = parapet_core::Vec3::zeros();
        let s = PathSample { position: z, velocity: z, acceleration: z, progress: Default::default() };
        let out = t.outer_out(&s);
        assert_eq!(out.filter.region, Region::Perpendicular);
        assert_eq!(out.filter.active_id, Some(7));
        assert_eq!(out.filter.h_bar, 0.25);
        assert!(out.filter.intervened && out.filter.infeasible && !out.filter.unavoidable);
        assert_eq!(out.filter.n_constraints, 2);
        // Phase Mission with Return selected: flying back (the phase merges the two).
        assert_eq!(out.mode, GuidanceMode::Return);
        // A non-finite region code is a fault, never a benign region.
        let bad = DEBUG_VECT_DATA { name: name(names::CBF), y: f32::NAN, z: -1.0, ..Default::default() };
        observe(&MavMessage::DEBUG_VECT(bad), 0, &mut t, &mut fig);
        assert_eq!(t.outer_out(&s).filter.region, Region::Fault);
        assert_eq!(t.outer_out(&s).filter.active_id, None);
    }

    /// The mode-change STATUSTEXT sets the mode at once; other texts and unknown custom modes
    /// leave it.
    #[test]
    #[allow(clippy::needless_update)] // the extension fields exist with MAVLink 2 extensions on
    fn mode_from_statustext_and_heartbeat() {
        use mavlink::dialects::ardupilotmega::{MavSeverity, STATUSTEXT_DATA};
        let (mut t, mut fig) = (FirmwareTelemetry::default(), PilFigures::default());
        let text = |s: &str| {
            let mut b = [0u8; 50];
            b[..s.len()].copy_from_slice(s.as_bytes());
            MavMessage::STATUSTEXT(STATUSTEXT_DATA {
                severity: MavSeverity::MAV_SEVERITY_WARNING,
                text: b.into(),
                ..Default::default()
            })
        };
        observe(&text("MODE Hold: offboard-loss"), 3_500_000, &mut t, &mut fig);
        assert_eq!(t.mode, Some(FlightMode::Hold));
        assert_eq!(fig.mode_changes, vec![TimedText { t_s: 2.5, text: "MODE Hold: offboard-loss".into() }]);
        observe(&text("FAILSAFE: position stale"), 3_600_000, &mut t, &mut fig);
        assert_eq!(fig.mode_changes.len(), 1, "not a mode change");
        assert_eq!(t.mode, Some(FlightMode::Hold));
        let hb = HEARTBEAT_DATA { custom_mode: 99 << 16, ..Default::default() };
        observe(&MavMessage::HEARTBEAT(hb), 0, &mut t, &mut fig);
        assert_eq!(t.mode, Some(FlightMode::Hold));
        assert_eq!(mode_of_text("MODE Offboard: mode-command"), Some(FlightMode::Offboard));
        assert_eq!(mode_of_text("MODE Nonsense: x"), None);
    }

    /// The host's raw reading goes out as BATTERY_STATUS in mV / cA (`gcs::battery_status`); the
    /// firmware's BATTERY_STATUS and SYS_STATUS come back into the battery figures with the
    /// time of their step.
    #[test]
    #[allow(clippy::needless_update)] // the extension fields exist with MAVLink 2 extensions on
    fn battery_readings_go_out_in_mv_and_ca_and_the_reports_come_back() {
        use crate::sim::battery::BatteryReading;
        use mavlink::dialects::ardupilotmega::{MavBatteryChargeState, SYS_STATUS_DATA};
        let out = super::super::gcs::battery_status(&BatteryReading {
            t: 0.1,
            voltage_v: 11.1234,
            current_a: Some(7.456),
        });
        let MavMessage::BATTERY_STATUS(b) = out else { panic!("{out:?}") };
        assert_eq!(
            (b.voltages[0], b.voltages[1], b.current_battery, b.battery_remaining),
            (11_123, u16::MAX, 746, -1)
        );
        let no_sensor =
            super::super::gcs::battery_status(&BatteryReading { t: 0.1, voltage_v: 12.0, current_a: None });
        assert!(matches!(no_sensor, MavMessage::BATTERY_STATUS(b) if b.current_battery == -1));

        let (mut t, mut fig) = (FirmwareTelemetry::default(), PilFigures::default());
        assert_eq!(fig.battery.first_status_s, None);
        let status = |state: MavBatteryChargeState| {
            let mut voltages = [u16::MAX; 10];
            voltages[0] = 10_450;
            MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
                voltages,
                current_battery: 912,
                battery_remaining: 3,
                charge_state: state,
                ..Default::default()
            })
        };
        observe(&status(MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK), 1_500_000, &mut t, &mut fig);
        observe(&status(MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_LOW), 2_500_000, &mut t, &mut fig);
        observe(&status(MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_LOW), 3_500_000, &mut t, &mut fig);
        let sys = SYS_STATUS_DATA {
            voltage_battery: 10_450,
            current_battery: 912,
            battery_remaining: 3,
            ..Default::default()
        };
        observe(&MavMessage::SYS_STATUS(sys), 3_500_000, &mut t, &mut fig);
        let f = &fig.battery;
        assert_eq!(
            (f.status_received, f.first_status_s, f.low_s, f.critical_s),
            (3, Some(0.5), Some(1.5), None)
        );
        assert_eq!(
            (f.last_voltage_v, f.last_current_a, f.last_remaining_pct),
            (Some(10.45), Some(9.12), Some(3))
        );
        assert_eq!(f.last_charge_state.as_deref(), Some("MAV_BATTERY_CHARGE_STATE_LOW"));
        assert_eq!(
            (f.sys_status_voltage_v, f.sys_status_current_a, f.sys_status_remaining_pct),
            (Some(10.45), Some(9.12), Some(3))
        );
        let none = SYS_STATUS_DATA {
            voltage_battery: u16::MAX,
            current_battery: -1,
            battery_remaining: -1,
            ..Default::default()
        };
        observe(&MavMessage::SYS_STATUS(none), 4_500_000, &mut t, &mut fig);
        assert_eq!((fig.battery.sys_status_voltage_v, fig.battery.sys_status_current_a), (None, None));
    }
}
