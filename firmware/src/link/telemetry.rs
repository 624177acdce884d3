//! Telemetry streams: what is sent, how often, and how the cascade's state maps onto MAVLink.
//!
//! | stream | message | rate | content |
//! |---|---|---|---|
//! | heartbeat | HEARTBEAT | 1 Hz (settable: faster, never off or slower) | type QUADROTOR, autopilot PX4 (`MAV_AUTOPILOT_PX4`: the `custom_mode` is PX4's encoding, and ground stations — MAVProxy, MAVSDK, QGroundControl — pick the mode decoder from this field); custom_mode = PX4's encoding (`main << 16 \| sub << 24`, [`FlightMode::px4_custom_mode`]) of the mode flown ([`reported_mode`]: the selected flight mode, Land while the failsafe machine lands, Hold while it brakes): Manual 1/0, Position 3/0, Mission 4/4, Hold 4/3, Return 4/5, Land 4/6, Offboard 6/0; base_mode as PX4 sets it: CUSTOM_MODE_ENABLED always, SAFETY_ARMED when armed, MANUAL_INPUT + STABILIZE in Manual, MANUAL_INPUT + STABILIZE + GUIDED in Position, AUTO + STABILIZE + GUIDED in Mission, Hold, Return, Land and Offboard; system_status STANDBY/ACTIVE/CRITICAL (failsafe) |
//! | phase | NAMED_VALUE_INT `PHASE` | 1 Hz (with the heartbeat) | [`FlightPhase`] code (0 disarmed, 1 idle (armed, on the ground), 2 takeoff, 3 hover/hold, 4 mission, 5 landing, 6 failsafe): the guidance phase, which the heartbeat carried before it carried the mode |
//! | standard modes | CURRENT_MODE, AVAILABLE_MODES_MONITOR | 1 Hz (with the heartbeat); CURRENT_MODE also at once on a mode change | the mode flown (as HEARTBEAT's `custom_mode`) with its `MAV_STANDARD_MODE` and the selected mode (`intended_custom_mode`); the monitor's `seq` 0 (the list never changes); [`crate::link::standard_modes`] |
//! | status | SYS_STATUS | 1 Hz (settable) | sensors present = enabled: 3D gyro, 3D accel, vision position and GPS (both the external position fix: ground stations and MAVSDK derive "global position ok" from the GPS bit, and GPS_RAW_INT reports that fix), angular-rate, attitude, z and xy control, motor outputs, `MAV_SYS_STATUS_PREARM_CHECK`, and the battery once a measurement arrived; health: all, without vision position and xy control while a failsafe is active, without vision position and GPS while the fix is not fresh (the failsafe's position timeout), without PREARM_CHECK while the arm command would be refused (the cascade's arm checks, an inconsistent parameter set; healthy while armed), without the battery while its level is Low or Critical; load = outer loop max execution / period (‰ of the window); battery: the last measurement's voltage mV, current cA (−1 not measured), remaining % (−1 unknown); before one: voltage 65535, current −1, remaining −1; errors_comm = CRC errors (saturating) |
//! | landed state | EXTENDED_SYS_STATE | 1 Hz (settable) | ON_GROUND (disarmed, idle), TAKEOFF, IN_AIR (hover, mission, failsafe while armed), LANDING |
//! | attitude | ATTITUDE | 50 Hz (settable) | roll, pitch, yaw (rad, FRD w.r.t. NED, ZYX); body rates FRD rad/s |
//! | position | LOCAL_POSITION_NED | 25 Hz (settable) | position NED m, velocity NED m/s |
//! | filter | DEBUG_VECT `CBF` | 25 Hz | x = h̄ (m², min over obstacles; +∞ none), y = region code (0 none, 1 far, 2 nominal-safe, 3 perpendicular/intervening, 4 fault), z = active obstacle id (−1 none) |
//! | filter flags | NAMED_VALUE_INT `CBF_FLAGS` | 25 Hz | bit0 intervened, bit1 unavoidable, bit2 infeasible, bits 8..15 active constraints |
//! | setpoint | POSITION_TARGET_LOCAL_NED | 25 Hz (settable) | frame LOCAL_NED; x, y, z = reference position m; vx, vy, vz = reference velocity m/s; afx, afy, afz = filtered acceleration u m/s² (gravity excluded); type_mask ignores yaw and yaw rate |
//! | nominal command | DEBUG_VECT `U_NOM` | 25 Hz | x, y, z = nominal acceleration u* NED m/s² (before the filter) |
//! | speed governor | DEBUG_VECT `GOV` | 25 Hz | x = speed limit along the motion m/s (−1 none), y = cause code (0 none, 1 range, 2 obstacle, 3 unseen, 4 data age), z = 1 when it changed the command |
//! | inner loop | DEBUG_VECT `LOOP_IN` | 2 Hz | x = mean period µs, y = max period µs, z = max execution µs (window since last report) |
//! | outer loop | DEBUG_VECT `LOOP_OUT` | 2 Hz | same for the position + CBF loop |
//! | overruns | NAMED_VALUE_INT `OVR_IN` / `OVR_OUT` | 2 Hz | overruns since boot |
//! | link | DEBUG_VECT `LINK` | 1 Hz | x = frames ok, y = CRC errors, z = malformed frames |
//! | drops | DEBUG_VECT `LINK_DROP` | 1 Hz | x = replies dropped (queue full), y = inbound messages rejected, z = obstacle points rejected/dropped |
//! | hardware | DEBUG_VECT `HW_ERR` | 1 Hz | x = IMU read errors, y = UART receive errors |
//! | failsafe | STATUSTEXT + NAMED_VALUE_INT `FAILSAFE` | on every transition | severity CRITICAL on entry ("FAILSAFE: reason"), NOTICE on exit ("FAILSAFE cleared") |
//! | flight mode | STATUSTEXT | on every mode change (issue 21) | "MODE Position: mode-switch"; severity WARNING when a failsafe chose the mode (rc-loss, offboard-loss, battery-low, battery-critical, kill-switch), INFO otherwise |
//! | RC | RC_CHANNELS (65) | 5 Hz once a pilot input arrived (issue 21) | the latest frame's channels µs (a receiver's as received; MAVLink pilot input as the channel map gives it back, `parapet_core::rc::map::channels_of`), unused `UINT16_MAX`, chancount, rssi = link quality × 254 / 100 (0 when no frame came for [`RC_STALE_US`]) |
//!
//! The periodic streams, their messages, default rates and which are settable are one registry,
//! `parapet_core::wire::streams::STREAMS` (shared with the host's ground-station bridge); the
//! scheduler walks it in order and encodes each entry by its `Stream` below.
//!
//! "Settable": MAV_CMD_SET_MESSAGE_INTERVAL / REQUEST_MESSAGE through the link
//! ([`crate::link::services::StreamRates`], read from [`ErrorCounters::rates`]); a changed
//! interval restarts the stream at once, a request sends the message once more.
//!
//! Times: `time_boot_ms` / `time_usec` are the firmware clock (simulated time on the PIL link).

use crate::link::dialect::{
    EstimatorStatusFlags, MavAutopilot, MavFrame, MavLandedState, MavModeFlag, MavSeverity, MavState,
    MavSysStatusSensor, MavType, MavVtolState, PositionTargetTypemask, ATTITUDE_DATA, ESTIMATOR_STATUS_DATA,
    EXTENDED_SYS_STATE_DATA, HEARTBEAT_DATA, LOCAL_POSITION_NED_DATA, POSITION_TARGET_LOCAL_NED_DATA,
    STATUSTEXT_DATA, SYS_STATUS_DATA,
};

use crate::app::autopilot::{Failsafe, FlightMode, FlightPhase, TelemetrySnapshot};
use crate::app::loop_timing::LoopReport;
use crate::app::replanner::event_text;
use crate::link::frame_parser::ParserStats;
use crate::link::manual_control::rc_channels;
use crate::link::outbound::{debug_vect, named_int, Outbound};
use crate::link::services::StreamRates;
use crate::link::standard_modes;
use parapet_core::replan::onboard::ReplanEvent;
use parapet_core::replan::ReplanOutcome;
use parapet_core::safety::governor::GovernorCause;
use parapet_core::wire::streams::{Stream, SLOTS, STREAMS};
use parapet_core::wire::{codes, names};

/// Everything the telemetry streams read.
#[derive(Clone, Copy, Debug)]
pub struct TelemetryInputs {
    /// Cascade state.
    pub snapshot: TelemetrySnapshot,
    /// Inner loop timing (window since the last `LOOP_IN`).
    pub inner: LoopReport,
    /// Outer loop timing.
    pub outer: LoopReport,
    /// Framer counters.
    pub parser: ParserStats,
    /// Error counters.
    pub counters: ErrorCounters,
}

/// Error counters reported at 1 Hz (`DEBUG_VECT LINK_DROP` and `HW_ERR`), all since boot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ErrorCounters {
    /// Replies dropped because the reply queue was full.
    pub replies_dropped: u32,
    /// Inbound messages rejected: undecodable payloads, bad ODOMETRY, unknown parameters.
    pub inputs_rejected: u32,
    /// Obstacle points rejected (unsupported frame, non-finite) or dropped (batch full).
    pub obstacles_rejected: u32,
    /// IMU read failures (board) — each fed the cascade a NaN sample.
    pub imu_errors: u32,
    /// UART receive errors (board: overrun, framing, noise).
    pub uart_errors: u32,
    /// Not a counter: the scheduler's stream rates as set through the link (SET_MESSAGE_INTERVAL,
    /// REQUEST_MESSAGE), carried here from the task that owns the [`crate::link::Link`].
    pub rates: StreamRates,
}

impl ErrorCounters {
    /// The link's counters (board counters zero).
    pub fn from_link(link: &crate::link::Link) -> Self {
        let l = link.stats();
        let o = link.obstacle_stats();
        Self {
            replies_dropped: l.replies_dropped,
            inputs_rejected: l
                .decode_errors
                .saturating_add(l.odometry_rejected)
                .saturating_add(l.position_rejected)
                .saturating_add(l.unknown_params),
            obstacles_rejected: o
                .rejected_frame
                .saturating_add(o.rejected_non_finite)
                .saturating_add(o.dropped_full),
            imu_errors: 0,
            uart_errors: 0,
            rates: link.stream_rates(),
        }
    }
}

/// Messages one [`TelemetryScheduler::poll`] emits at most (callers size their queue by it).
pub const MAX_PER_POLL: usize = 26;
/// RC_CHANNELS period, µs (5 Hz).
const RC_CHANNELS_US: u64 = 200_000;
/// No pilot input for this long: RC_CHANNELS reports rssi 0, µs.
pub const RC_STALE_US: u64 = 1_000_000;

/// The RC_CHANNELS stream (its own period; sent once a pilot input arrived).
#[derive(Clone, Copy, Debug, Default)]
struct RcChannelsStream {
    next_due_us: u64,
}

impl RcChannelsStream {
    fn poll(&mut self, now_us: u64, s: &TelemetrySnapshot, mut emit: impl FnMut(Outbound)) {
        let Some(rc) = s.rc else { return };
        if now_us < self.next_due_us {
            return;
        }
        self.next_due_us = now_us.saturating_add(RC_CHANNELS_US);
        let fresh = now_us.saturating_sub(rc.t_us) <= RC_STALE_US;
        let lq = if fresh { rc.link_quality } else { 0 };
        emit(Outbound::RcChannels(rc_channels(Some(&rc.channels), Some(lq), (now_us / 1000) as u32)));
    }
}

/// Decides which telemetry messages are due and builds them.
pub struct TelemetryScheduler {
    next_due_us: [u64; STREAMS.len()],
    /// The rates of the last poll (a change restarts / requests a stream).
    rates: StreamRates,
    last_failsafe: Option<Failsafe>,
    last_mode_changes: u32,
    /// The replanner's event count at the last poll (issue 38).
    last_replan_events: u16,
    rc: RcChannelsStream,
    /// `true` when the loop-timing stream fired in the last [`TelemetryScheduler::poll`] (the
    /// caller then starts new loop-timing windows).
    pub loops_reported: bool,
}

impl Default for TelemetryScheduler {
    fn default() -> Self {
        Self::new()
    }
}

/// The flight mode the HEARTBEAT reports: the selected mode, or Land while the failsafe machine
/// lands (a failsafe or a commanded landing) and Hold while it brakes, as PX4's navigation state
/// shows its failsafe modes.
pub fn reported_mode(s: &TelemetrySnapshot) -> FlightMode {
    match s.phase {
        FlightPhase::Landing => FlightMode::Land,
        FlightPhase::Failsafe => FlightMode::Hold,
        _ => s.mode,
    }
}

/// HEARTBEAT for the state in `s` (mode flags and custom-mode map in the module docs).
pub fn heartbeat(s: &TelemetrySnapshot) -> HEARTBEAT_DATA {
    use MavModeFlag as F;
    let mode = reported_mode(s);
    let mut base = F::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        | match mode {
            FlightMode::Manual => F::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | F::MAV_MODE_FLAG_STABILIZE_ENABLED,
            FlightMode::Position => {
                F::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
                    | F::MAV_MODE_FLAG_STABILIZE_ENABLED
                    | F::MAV_MODE_FLAG_GUIDED_ENABLED
            }
            FlightMode::Mission
            | FlightMode::Hold
            | FlightMode::Return
            | FlightMode::Land
            | FlightMode::Offboard => {
                F::MAV_MODE_FLAG_AUTO_ENABLED
                    | F::MAV_MODE_FLAG_STABILIZE_ENABLED
                    | F::MAV_MODE_FLAG_GUIDED_ENABLED
            }
        };
    if s.armed {
        base |= F::MAV_MODE_FLAG_SAFETY_ARMED;
    }
    let system_status = if s.failsafe.is_some() {
        MavState::MAV_STATE_CRITICAL
    } else if s.armed {
        MavState::MAV_STATE_ACTIVE
    } else {
        MavState::MAV_STATE_STANDBY
    };
    HEARTBEAT_DATA {
        custom_mode: mode.px4_custom_mode(),
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: base,
        system_status,
        mavlink_version: 3,
    }
}

/// Landed state of the phase (EXTENDED_SYS_STATE).
pub fn landed_state(s: &TelemetrySnapshot) -> MavLandedState {
    match s.phase {
        FlightPhase::Disarmed | FlightPhase::Idle => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
        FlightPhase::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
        FlightPhase::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
        FlightPhase::Hover | FlightPhase::Mission => MavLandedState::MAV_LANDED_STATE_IN_AIR,
        FlightPhase::Failsafe if s.armed => MavLandedState::MAV_LANDED_STATE_IN_AIR,
        FlightPhase::Failsafe => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
    }
}

/// SYS_STATUS for the state in `inp` (fields in the module docs).
pub fn sys_status(inp: &TelemetryInputs) -> SYS_STATUS_DATA {
    use MavSysStatusSensor as S;
    let present = S::MAV_SYS_STATUS_SENSOR_3D_GYRO
        | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL
        | S::MAV_SYS_STATUS_SENSOR_VISION_POSITION
        | S::MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
        | S::MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
        | S::MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
        | S::MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
        | S::MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        | S::MAV_SYS_STATUS_SENSOR_GPS
        | S::MAV_SYS_STATUS_PREARM_CHECK;
    let mut health = present;
    if inp.snapshot.failsafe.is_some() {
        health
            .remove(S::MAV_SYS_STATUS_SENSOR_VISION_POSITION | S::MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL);
    }
    if !inp.snapshot.position_fresh {
        health.remove(S::MAV_SYS_STATUS_SENSOR_VISION_POSITION | S::MAV_SYS_STATUS_SENSOR_GPS);
    }
    if !inp.snapshot.armable {
        health.remove(S::MAV_SYS_STATUS_PREARM_CHECK);
    }
    let battery = inp.snapshot.battery;
    let mut present = present;
    if let Some(b) = battery {
        present |= S::MAV_SYS_STATUS_SENSOR_BATTERY;
        if b.level == parapet_core::battery::BatteryLevel::Ok {
            health |= S::MAV_SYS_STATUS_SENSOR_BATTERY;
        }
    }
    let o = &inp.outer;
    // ‰, at most 1000; the float → int cast maps negative and NaN to 0.
    let load =
        if o.period_mean_us > 0.0 { (1000.0 * o.exec_max_us / o.period_mean_us).min(1000.0) } else { 0.0 };
    SYS_STATUS_DATA {
        onboard_control_sensors_present: present,
        onboard_control_sensors_enabled: present,
        onboard_control_sensors_health: health,
        load: load as u16,
        voltage_battery: battery.map_or(u16::MAX, |b| (b.voltage_v * 1000.0).clamp(0.0, 65_534.0) as u16),
        current_battery: battery
            .and_then(|b| b.current_a)
            .filter(|a| a.is_finite())
            .map_or(-1, |a| (a * 100.0).clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16),
        errors_comm: inp.parser.crc_errors.min(u32::from(u16::MAX)) as u16,
        battery_remaining: battery
            .and_then(|b| b.remaining)
            .filter(|r| r.is_finite())
            .map_or(-1, |r| (r * 100.0).clamp(0.0, 100.0) as i8),
        ..Default::default()
    }
}

/// STATUSTEXT of a flight-mode change: "MODE <mode>: <reason>" (truncated to 50 bytes).
pub fn mode_text(s: &TelemetrySnapshot) -> STATUSTEXT_DATA {
    let reason = s.mode_reason.unwrap_or("");
    let failsafe =
        matches!(reason, "rc-loss" | "offboard-loss" | "battery-low" | "battery-critical" | "kill-switch");
    let severity = if failsafe { MavSeverity::MAV_SEVERITY_WARNING } else { MavSeverity::MAV_SEVERITY_INFO };
    let mut buf = [0u8; 50];
    let text = "MODE ".bytes().chain(s.mode.as_str().bytes()).chain(": ".bytes()).chain(reason.bytes());
    for (d, c) in buf.iter_mut().zip(text) {
        *d = c;
    }
    STATUSTEXT_DATA { severity, text: buf.into(), ..Default::default() }
}

/// STATUSTEXT of an on-board replanner event (issue 38): INFO for a new path, WARNING for a
/// no-path or budget result (the vehicle holds).
pub fn replan_text(e: &ReplanEvent) -> STATUSTEXT_DATA {
    let mut buf = [0u8; 50];
    event_text(e, &mut buf);
    let severity = match e.outcome {
        ReplanOutcome::Replanned { .. } => MavSeverity::MAV_SEVERITY_INFO,
        _ => MavSeverity::MAV_SEVERITY_WARNING,
    };
    STATUSTEXT_DATA { severity, text: buf.into(), ..Default::default() }
}

/// ESTIMATOR_STATUS of the navigation filter's report `n` at `now_us` (`docs/navigation.md`
/// § Firmware: test ratios = NIS / χ² gate, > 1 gated; horizontal and vertical position share
/// the one 3-D test; no magnetometer, height-above-ground or airspeed fusion: their ratios 0).
pub fn estimator_status(now_us: u64, n: &crate::app::navigation::NavReport) -> ESTIMATOR_STATUS_DATA {
    ESTIMATOR_STATUS_DATA {
        time_usec: now_us,
        vel_ratio: n.vel_ratio,
        pos_horiz_ratio: n.pos_ratio,
        pos_vert_ratio: n.pos_ratio,
        mag_ratio: 0.0,
        hagl_ratio: 0.0,
        tas_ratio: 0.0,
        pos_horiz_accuracy: n.pos_horiz_accuracy,
        pos_vert_accuracy: n.pos_vert_accuracy,
        flags: EstimatorStatusFlags::from_bits_truncate(n.flags),
    }
}

/// STATUSTEXT with `text` (truncated to 50 bytes).
pub fn status_text(severity: MavSeverity, prefix: &str, text: &str) -> STATUSTEXT_DATA {
    let mut buf = [0u8; 50];
    for (d, c) in buf.iter_mut().zip(prefix.bytes().chain(text.bytes())) {
        *d = c;
    }
    STATUSTEXT_DATA { severity, text: buf.into(), ..Default::default() }
}

impl TelemetryScheduler {
    /// Every stream due immediately.
    pub const fn new() -> Self {
        Self {
            next_due_us: [0; STREAMS.len()],
            rates: StreamRates::DEFAULT,
            last_failsafe: None,
            last_mode_changes: 0,
            last_replan_events: 0,
            rc: RcChannelsStream { next_due_us: 0 },
            loops_reported: false,
        }
    }

    /// Emits the messages due at `now_us` (and a STATUSTEXT on a failsafe transition) through
    /// `emit`. Bounded: at most [`MAX_PER_POLL`] messages per call (2 failsafe, 2 mode, 1 replan, 1 RC, 4 heartbeat + 1 status + 1 landed state, 1 + 1 streams, 4 filter, 4 loops, 3 link, 1 estimator).
    pub fn poll(&mut self, now_us: u64, inp: &TelemetryInputs, mut emit: impl FnMut(Outbound)) {
        let ms = (now_us / 1000) as u32;
        let s = &inp.snapshot;
        self.loops_reported = false;
        if s.failsafe != self.last_failsafe {
            match s.failsafe {
                Some(f) => {
                    emit(Outbound::StatusText(status_text(
                        MavSeverity::MAV_SEVERITY_CRITICAL,
                        "FAILSAFE: ",
                        f.reason,
                    )));
                    emit(named_int(ms, names::FAILSAFE, i32::from(f.code)));
                }
                None => {
                    emit(Outbound::StatusText(status_text(
                        MavSeverity::MAV_SEVERITY_NOTICE,
                        "FAILSAFE cleared",
                        "",
                    )));
                    emit(named_int(ms, names::FAILSAFE, 0));
                }
            }
            self.last_failsafe = s.failsafe;
        }
        self.rc.poll(now_us, s, &mut emit);
        if s.mode_changes != self.last_mode_changes {
            self.last_mode_changes = s.mode_changes;
            emit(Outbound::StatusText(mode_text(s)));
            emit(Outbound::CurrentMode(standard_modes::current_mode(reported_mode(s), s)));
        }
        if s.replan.events != self.last_replan_events {
            self.last_replan_events = s.replan.events;
            if let Some(e) = s.replan.last {
                emit(Outbound::StatusText(replan_text(&e)));
            }
        }
        let rates = inp.counters.rates;
        for (k, (spec, slot)) in STREAMS.iter().zip(SLOTS).enumerate() {
            let mut requested = false;
            let period = match slot {
                Some(r) => {
                    if rates.interval_us[r] != self.rates.interval_us[r] {
                        self.next_due_us[k] = 0;
                    }
                    requested = rates.requests[r] != self.rates.requests[r];
                    rates.period_us(r)
                }
                None => Some(u64::from(spec.default_us)),
            };
            let due = period.is_some_and(|_| now_us >= self.next_due_us[k]);
            if !due && !requested {
                continue;
            }
            if let Some(period) = period.filter(|_| due) {
                // Keep the phase, but never try to catch up on missed periods.
                // Saturating: on the lockstep link the time comes from the host (any u64).
                self.next_due_us[k] = if now_us - self.next_due_us[k] >= period || self.next_due_us[k] == 0 {
                    now_us.saturating_add(period)
                } else {
                    self.next_due_us[k].saturating_add(period)
                };
            }
            // The stream's encoder.
            match spec.stream {
                Stream::Heartbeat => {
                    emit(Outbound::Heartbeat(heartbeat(s)));
                    emit(named_int(ms, names::PHASE, s.phase.code() as i32));
                    emit(Outbound::CurrentMode(standard_modes::current_mode(reported_mode(s), s)));
                    emit(Outbound::AvailableModesMonitor);
                }
                Stream::SysStatus => emit(Outbound::SysStatus(sys_status(inp))),
                Stream::LandedState => emit(Outbound::ExtendedSysState(EXTENDED_SYS_STATE_DATA {
                    vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
                    landed_state: landed_state(s),
                })),
                Stream::Attitude => emit(Outbound::Attitude(ATTITUDE_DATA {
                    time_boot_ms: ms,
                    roll: s.attitude_rpy.x,
                    pitch: s.attitude_rpy.y,
                    yaw: s.attitude_rpy.z,
                    rollspeed: s.body_rates_frd.x,
                    pitchspeed: s.body_rates_frd.y,
                    yawspeed: s.body_rates_frd.z,
                })),
                Stream::Position => emit(Outbound::LocalPositionNed(LOCAL_POSITION_NED_DATA {
                    time_boot_ms: ms,
                    x: s.position_ned.x,
                    y: s.position_ned.y,
                    z: s.position_ned.z,
                    vx: s.velocity_ned.x,
                    vy: s.velocity_ned.y,
                    vz: s.velocity_ned.z,
                })),
                Stream::Filter => {
                    let f = &s.filter;
                    let (region, id) =
                        (codes::region_to_wire(f.region), codes::active_id_to_wire(f.active_id));
                    emit(debug_vect(now_us, names::CBF, f.h_bar, region, id));
                    let flags = codes::CbfFlags {
                        intervened: f.intervened,
                        unavoidable: f.unavoidable,
                        infeasible: f.infeasible,
                        n_constraints: f.n_constraints,
                    };
                    emit(named_int(ms, names::CBF_FLAGS, flags.encode()));
                    let u = &s.setpoint.accel_nominal_ned;
                    emit(debug_vect(now_us, names::U_NOM, u.x, u.y, u.z));
                    let cause = GovernorCause::from_code(s.governor_cause).unwrap_or_default();
                    let (x, y, z) = codes::governor_to_wire(s.governor_limit, cause, s.governor_active);
                    emit(debug_vect(now_us, names::GOV, x, y, z));
                }
                Stream::Loops => {
                    let (i, o) = (&inp.inner, &inp.outer);
                    emit(debug_vect(
                        now_us,
                        names::LOOP_IN,
                        i.period_mean_us,
                        i.period_max_us,
                        i.exec_max_us,
                    ));
                    emit(debug_vect(
                        now_us,
                        names::LOOP_OUT,
                        o.period_mean_us,
                        o.period_max_us,
                        o.exec_max_us,
                    ));
                    emit(named_int(ms, names::OVR_IN, i.overruns.min(i32::MAX as u32) as i32));
                    emit(named_int(ms, names::OVR_OUT, o.overruns.min(i32::MAX as u32) as i32));
                    self.loops_reported = true;
                }
                Stream::Link => {
                    let p = &inp.parser;
                    emit(debug_vect(
                        now_us,
                        names::LINK,
                        p.frames_ok as f32,
                        p.crc_errors as f32,
                        p.malformed as f32,
                    ));
                    let c = &inp.counters;
                    emit(debug_vect(
                        now_us,
                        names::LINK_DROP,
                        c.replies_dropped as f32,
                        c.inputs_rejected as f32,
                        c.obstacles_rejected as f32,
                    ));
                    emit(debug_vect(now_us, names::HW_ERR, c.imu_errors as f32, c.uart_errors as f32, 0.0));
                }
                Stream::Estimator => {
                    if let Some(n) = &s.nav {
                        emit(Outbound::EstimatorStatus(estimator_status(now_us, n)));
                    }
                }
                Stream::Target => {
                    let sp = &s.setpoint;
                    emit(Outbound::PositionTargetLocalNed(POSITION_TARGET_LOCAL_NED_DATA {
                        time_boot_ms: ms,
                        x: sp.position_ned.x,
                        y: sp.position_ned.y,
                        z: sp.position_ned.z,
                        vx: sp.velocity_ned.x,
                        vy: sp.velocity_ned.y,
                        vz: sp.velocity_ned.z,
                        afx: sp.accel_filtered_ned.x,
                        afy: sp.accel_filtered_ned.y,
                        afz: sp.accel_filtered_ned.z,
                        yaw: 0.0,
                        yaw_rate: 0.0,
                        type_mask: PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_IGNORE
                            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE,
                        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
                    }));
                }
            }
        }
        self.rates = rates;
    }
}

/// Name check helper for tests and the host tools: `true` when a MAVLink name field equals `key`.
pub fn name_is<const N: usize>(field: &mavlink_core::types::CharArray<N>, key: &str) -> bool {
    names::name_is(&field[..], key)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;
    use crate::app::autopilot::Autopilot;
    use std::vec::Vec;

    fn inputs(ap: &RecordingAutopilot) -> TelemetryInputs {
        TelemetryInputs {
            snapshot: ap.telemetry(),
            inner: LoopReport::default(),
            outer: LoopReport::default(),
            parser: ParserStats::default(),
            counters: ErrorCounters::default(),
        }
    }

    #[test]
    fn times_near_u64_max_do_not_overflow() {
        // Found by the `link` fuzz target: a HIL_SENSOR time_usec near u64::MAX overflowed the
        // next due time (a panic with overflow checks, a wrapped schedule without).
        let ap = RecordingAutopilot::new();
        let mut t = TelemetryScheduler::new();
        let mut n = 0;
        for now in [u64::MAX - 5, u64::MAX - 1, u64::MAX] {
            t.poll(now, &inputs(&ap), |_| n += 1);
        }
        assert!(n > 0);
    }

    #[test]
    fn rates_over_one_second() {
        let ap = RecordingAutopilot::new();
        let mut t = TelemetryScheduler::new();
        let mut out = Vec::new();
        // 1 kHz calls for exactly one second.
        for k in 0..1000u64 {
            t.poll(1 + k * 1000, &inputs(&ap), |m| out.push(m));
        }
        let count = |f: &dyn Fn(&Outbound) -> bool| out.iter().filter(|m| f(m)).count();
        assert_eq!(count(&|m| matches!(m, Outbound::Heartbeat(_))), 1);
        assert_eq!(count(&|m| matches!(m, Outbound::Attitude(_))), 50);
        assert_eq!(count(&|m| matches!(m, Outbound::LocalPositionNed(_))), 25);
        assert_eq!(count(&|m| matches!(m, Outbound::DebugVect(d) if name_is(&d.name, "CBF"))), 25);
        assert_eq!(count(&|m| matches!(m, Outbound::DebugVect(d) if name_is(&d.name, "U_NOM"))), 25);
        assert_eq!(count(&|m| matches!(m, Outbound::PositionTargetLocalNed(_))), 25);
        let sp = out.iter().find_map(|m| match m {
            Outbound::PositionTargetLocalNed(p) => Some(p.clone()),
            _ => None,
        });
        let sp = sp.expect("a setpoint");
        assert_eq!((sp.x, sp.vx, sp.afx, sp.afy), (1.5, 0.25, -0.5, 0.5));
        assert_eq!(sp.coordinate_frame, MavFrame::MAV_FRAME_LOCAL_NED);
        assert_eq!(count(&|m| matches!(m, Outbound::DebugVect(d) if name_is(&d.name, "LOOP_IN"))), 2);
        assert_eq!(count(&|m| matches!(m, Outbound::StatusText(_))), 0);
        assert_eq!(count(&|m| matches!(m, Outbound::DebugVect(d) if name_is(&d.name, "LINK_DROP"))), 1);
        assert_eq!(count(&|m| matches!(m, Outbound::DebugVect(d) if name_is(&d.name, "HW_ERR"))), 1);
    }

    #[test]
    fn failsafe_transitions_send_statustext_once() {
        let mut ap = RecordingAutopilot::new();
        let mut t = TelemetryScheduler::new();
        let mut out = Vec::new();
        t.poll(1, &inputs(&ap), |m| out.push(m));
        ap.failsafe = Some(Failsafe { code: 3, reason: "position stale" });
        out.clear();
        t.poll(2, &inputs(&ap), |m| out.push(m));
        t.poll(3, &inputs(&ap), |m| out.push(m));
        let texts: Vec<_> = out
            .iter()
            .filter_map(|m| match m {
                Outbound::StatusText(s) => Some(s),
                _ => None,
            })
            .collect();
        assert_eq!(texts.len(), 1);
        assert_eq!(texts[0].severity, MavSeverity::MAV_SEVERITY_CRITICAL);
        assert_eq!(texts[0].text.to_str().ok(), Some("FAILSAFE: position stale"));
        ap.failsafe = None;
        out.clear();
        t.poll(4, &inputs(&ap), |m| out.push(m));
        assert!(out
            .iter()
            .any(|m| matches!(m, Outbound::StatusText(s) if s.severity == MavSeverity::MAV_SEVERITY_NOTICE)));
    }

    #[test]
    fn mode_changes_send_statustext_once_each() {
        use crate::app::autopilot::FlightMode;
        let mut ap = RecordingAutopilot::new();
        let mut sched = TelemetryScheduler::new();
        let texts = |sched: &mut TelemetryScheduler, ap: &RecordingAutopilot, t| {
            let mut v = std::vec::Vec::new();
            sched.poll(t, &inputs(ap), |o| {
                if let Outbound::StatusText(m) = o {
                    v.push((m.severity, m.text.to_str().unwrap_or("").to_owned()));
                }
            });
            v
        };
        assert!(texts(&mut sched, &ap, 1_000).is_empty());
        ap.mode = FlightMode::Hold;
        ap.mode_changes = 1;
        ap.mode_reason = Some("rc-loss");
        let v = texts(&mut sched, &ap, 2_000);
        assert_eq!(v, [(MavSeverity::MAV_SEVERITY_WARNING, "MODE Hold: rc-loss".to_owned())]);
        assert!(texts(&mut sched, &ap, 3_000).is_empty(), "once");
        ap.mode = FlightMode::Position;
        ap.mode_changes = 2;
        ap.mode_reason = Some("mode-switch");
        let v = texts(&mut sched, &ap, 4_000);
        assert_eq!(v, [(MavSeverity::MAV_SEVERITY_INFO, "MODE Position: mode-switch".to_owned())]);
    }

    /// HEARTBEAT custom_mode and base_mode per flight mode (PX4's encoding and flags), the
    /// failsafe machine's Land / Brake shown as Land / Hold, and the phase beside it.
    #[test]
    fn heartbeat_reports_the_px4_mode_and_flags() {
        use MavModeFlag as F;
        let mut ap = RecordingAutopilot::new();
        ap.armed = true;
        let manual = F::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | F::MAV_MODE_FLAG_STABILIZE_ENABLED;
        let auto = F::MAV_MODE_FLAG_AUTO_ENABLED
            | F::MAV_MODE_FLAG_STABILIZE_ENABLED
            | F::MAV_MODE_FLAG_GUIDED_ENABLED;
        let cases = [
            (FlightMode::Manual, 1 << 16, manual),
            (FlightMode::Position, 3 << 16, manual | F::MAV_MODE_FLAG_GUIDED_ENABLED),
            (FlightMode::Mission, (4 << 16) | (4 << 24), auto),
            (FlightMode::Hold, (4 << 16) | (3 << 24), auto),
            (FlightMode::Return, (4 << 16) | (5 << 24), auto),
            (FlightMode::Land, (4 << 16) | (6 << 24), auto),
            (FlightMode::Offboard, 6 << 16, auto),
        ];
        for (mode, custom, flags) in cases {
            ap.mode = mode;
            let h = heartbeat(&ap.telemetry());
            assert_eq!(h.custom_mode, custom, "{}", mode.as_str());
            assert_eq!(FlightMode::from_px4_custom_mode(h.custom_mode), Some(mode));
            let all = flags | F::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | F::MAV_MODE_FLAG_SAFETY_ARMED;
            assert_eq!(h.base_mode, all, "{}", mode.as_str());
        }
        let mut s =
            TelemetrySnapshot { mode: FlightMode::Position, phase: FlightPhase::Landing, ..ap.telemetry() };
        assert_eq!(heartbeat(&s).custom_mode, FlightMode::Land.px4_custom_mode());
        s.phase = FlightPhase::Failsafe;
        assert_eq!(heartbeat(&s).custom_mode, FlightMode::Hold.px4_custom_mode());
        // The phase goes beside the heartbeat.
        let mut sched = TelemetryScheduler::new();
        let mut phase = None;
        sched.poll(1, &inputs(&ap), |m| {
            if let Outbound::NamedValueInt(n) = m {
                if name_is(&n.name, names::PHASE) {
                    phase = Some(n.value);
                }
            }
        });
        assert_eq!(phase, Some(FlightPhase::Idle.code() as i32));
    }

    /// RC_CHANNELS: none before a pilot input, then 5 Hz with the frame's channels and link
    /// quality, rssi 0 once the input is stale; no poll emits more than MAX_PER_POLL.
    #[test]
    fn rc_channels_stream_once_a_pilot_input_arrived() {
        use crate::app::autopilot::RcReport;
        use parapet_core::rc::RawChannels;
        let ap = RecordingAutopilot::new();
        let mut inp = inputs(&ap);
        let mut sched = TelemetryScheduler::new();
        let mut rc = Vec::new();
        let mut most = 0;
        let mut run = |sched: &mut TelemetryScheduler, inp: &TelemetryInputs, from: u64, rc: &mut Vec<_>| {
            for k in 0..1000u64 {
                let mut n = 0;
                sched.poll(from + k * 1000, inp, |m| {
                    n += 1;
                    if let Outbound::RcChannels(c) = m {
                        rc.push(c);
                    }
                });
                most = most.max(n);
            }
        };
        run(&mut sched, &inp, 1, &mut rc);
        assert!(rc.is_empty(), "no RC source");
        let mut us = [1500u16; parapet_core::rc::MAX_CHANNELS];
        us[2] = 1100;
        let channels = RawChannels { us, count: 16, failsafe: false, frame_lost: false };
        inp.snapshot.rc = Some(RcReport { channels, link_quality: 80, t_us: 1_000_000 });
        inp.snapshot.failsafe = Some(Failsafe { code: 3, reason: "x" });
        run(&mut sched, &inp, 1_000_001, &mut rc);
        assert_eq!(rc.len(), 5, "5 Hz");
        assert_eq!(
            (rc[0].chancount, rc[0].chan3_raw, rc[0].chan17_raw, rc[0].rssi),
            (16, 1100, u16::MAX, 203)
        );
        assert_eq!(rc.last().map(|c| c.rssi), Some(203), "fresh within {RC_STALE_US} us");
        run(&mut sched, &inp, 2_100_001, &mut rc);
        assert_eq!(rc.last().map(|c| c.rssi), Some(0), "stale");
        assert!(most <= MAX_PER_POLL, "{most}");
    }

    #[test]
    fn heartbeat_reflects_arming() {
        let mut ap = RecordingAutopilot::new();
        let h = heartbeat(&ap.telemetry());
        assert_eq!(h.autopilot, MavAutopilot::MAV_AUTOPILOT_PX4, "clients decode custom_mode as PX4's");
        assert!(!h.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
        assert_eq!(h.system_status, MavState::MAV_STATE_STANDBY);
        ap.armed = true;
        let h = heartbeat(&ap.telemetry());
        assert!(h.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
        assert_eq!(h.system_status, MavState::MAV_STATE_ACTIVE);
    }

    /// SYS_STATUS: GPS and PREARM_CHECK present and enabled, GPS healthy while the fix is fresh,
    /// PREARM_CHECK healthy while the arm command would pass; no battery: voltage UINT16_MAX,
    /// current and remaining −1 (MAVLink's "unknown"), the battery bit absent. Before: no GPS
    /// or pre-arm bit (MAVSDK's `is_global_position_ok` / `is_armable` stayed False).
    #[test]
    fn sys_status_reports_gps_and_prearm_health_and_no_battery() {
        use MavSysStatusSensor as S;
        let ap = RecordingAutopilot::new();
        let mut inp = inputs(&ap);
        let m = sys_status(&inp);
        let bits = S::MAV_SYS_STATUS_SENSOR_GPS | S::MAV_SYS_STATUS_PREARM_CHECK;
        assert!(m.onboard_control_sensors_present.contains(bits));
        assert!(m.onboard_control_sensors_enabled.contains(bits));
        assert!(m.onboard_control_sensors_health.contains(bits), "fresh fix, armable");
        assert!(!m.onboard_control_sensors_present.contains(S::MAV_SYS_STATUS_SENSOR_BATTERY));
        assert_eq!((m.voltage_battery, m.current_battery, m.battery_remaining), (u16::MAX, -1, -1));
        inp.snapshot.position_fresh = false;
        let m = sys_status(&inp);
        assert!(!m.onboard_control_sensors_health.contains(S::MAV_SYS_STATUS_SENSOR_GPS));
        assert!(!m.onboard_control_sensors_health.contains(S::MAV_SYS_STATUS_SENSOR_VISION_POSITION));
        assert!(m.onboard_control_sensors_health.contains(S::MAV_SYS_STATUS_PREARM_CHECK));
        inp.snapshot.armable = false;
        let m = sys_status(&inp);
        assert!(!m.onboard_control_sensors_health.contains(S::MAV_SYS_STATUS_PREARM_CHECK));
        assert!(m.onboard_control_sensors_present.contains(S::MAV_SYS_STATUS_PREARM_CHECK));
    }
}
