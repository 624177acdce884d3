//! Link-level services a ground station expects from a PX4-like autopilot, beyond the
//! telemetry scheduler's streams ([`crate::link::telemetry`]): PING answers, and the streams
//! below at rates a ground station may change (MAV_CMD_SET_MESSAGE_INTERVAL 511), each also sent
//! once on MAV_CMD_REQUEST_MESSAGE (512), with MESSAGE_INTERVAL answers
//! (MAV_CMD_GET_MESSAGE_INTERVAL 510).
//!
//! | stream | id | default | content |
//! |---|---|---|---|
//! | SYSTEM_TIME | 2 | 1 Hz | `time_unix_usec` 0 (no wall clock on board), `time_boot_ms` firmware clock |
//! | GLOBAL_POSITION_INT | 33 | 5 Hz | the local NED position around [`ORIGIN`] by [`parapet_core::wire::geo::ned_to_global`] (flat earth, WGS-84 equatorial radius): lat/lon 1e-7°, alt AMSL / relative to home mm, velocity cm/s, heading cdeg (65535 unknown). Not sent while the position is not finite (or beyond i32 lat/lon) |
//! | MISSION_CURRENT | 42 | 1 Hz | [`Services::mission_current`]: seq = the uploaded seq of the item being flown ([`crate::link::mission_run::MissionRun::progress`]; 0 before the mission was started), total = items of the accepted plan, mission_state NO_MISSION / NOT_STARTED / ACTIVE / PAUSED / COMPLETE, mission_id = the accepted plan's id ([`crate::link::mission::MissionUpload::plan_id`]: new with every upload and every replanned path, issue 38) |
//! | ATTITUDE_TARGET | 83 | 10 Hz | the outer loop's attitude setpoint as a quaternion (ZYX roll, pitch, yaw; body FRD → NED), thrust = collective thrust / `THR_MAX` (0..1); body rates ignored |
//! | BATTERY_STATUS | 147 | 1 Hz | [`battery_status`] of the cascade's last battery measurement; not sent before the first |
//! | HOME_POSITION | 242 | 0.5 Hz, and at once when home changes | [`Services::home`]: where the vehicle armed (before the first arming: its first position; MAV_CMD_DO_SET_HOME while disarmed), as latitude/longitude/altitude around [`ORIGIN`] and as the local x, y, z; quaternion identity; not sent before a position is known. MAV_CMD_GET_HOME_POSITION sends it once |
//! | GPS_GLOBAL_ORIGIN | 49 | on request only (MAV_CMD_REQUEST_MESSAGE) | [`ORIGIN`]: the local frame's origin |
//! | GPS_RAW_INT | 24 | 1 Hz | [`gps_raw_int`]: the external position fix as the vehicle's "GPS": 3D fix while fresh, eph/epv = its stated 1σ accuracy (ODOMETRY's pose covariance, [`FixAccuracy`]) in cm, h_acc/v_acc mm, satellites unknown (255) |
//! | VFR_HUD | 74 | 4 Hz | [`vfr_hud`]: airspeed = groundspeed (horizontal speed), heading, throttle %, alt AMSL, climb |
//!
//! MAV_CMD_REQUEST_MESSAGE for BATTERY_STATUS without a battery measurement (no battery) or for
//! HOME_POSITION before a position is answered DENIED and nothing is sent ([`Services::can_send`]).
//!
//! **MISSION_ITEM_REACHED** (46): once per item, in order, up to the progress's last item done
//! (uploaded seq numbers, [`crate::link::mission_run`]).
//!
//! The telemetry scheduler's ATTITUDE (30), LOCAL_POSITION_NED (32),
//! POSITION_TARGET_LOCAL_NED (85), HEARTBEAT (0), SYS_STATUS (1) and EXTENDED_SYS_STATE (245)
//! are set here too ([`StreamRates`], which the scheduler reads through
//! [`crate::link::telemetry::ErrorCounters::rates`]): same interval rules, a request sends the
//! message with the scheduler's next poll.
//!
//! Intervals: −1 stops a stream, 0 restores its default, > 0 is the period in µs (at least
//! [`MIN_INTERVAL_US`]; shorter is refused DENIED). **HEARTBEAT** is never stopped and never
//! slower than its default 1 Hz ([`HEARTBEAT_MAX_INTERVAL_US`]; −1 or a longer period: DENIED).
//! Other message ids are answered UNSUPPORTED. The tables are fixed (one slot per stream above).
//!
//! **Origin and home**: the origin is fixed at PX4 SITL's default home (Zurich, 47.397742° N, 8.545594° E, 488 m AMSL):
//! Parapet flies in a local NED frame and has no GNSS; GLOBAL_POSITION_INT and HOME_POSITION
//! exist so that map-based ground stations (QGroundControl, MAVSDK) show the vehicle. The
//! conversion is [`parapet_core::wire::geo`] (the same one global-frame mission items use).
//!
//! May import: `parapet_core`, the dialect, [`crate::app::autopilot`] (telemetry snapshot), [`parapet_core::wire::geo`],
//! [`crate::link::outbound`]. No allocation; every call is bounded (at most one message per
//! stream per [`Services::poll`]).
#![allow(deprecated)] // PING: deprecated by MAVLink for TIMESYNC, still sent by tools (PX4 answers it)

use crate::app::autopilot::TelemetrySnapshot;
use crate::link::dialect::{
    AttitudeTargetTypemask, GpsFixType, MavBatteryChargeState, MavBatteryFunction, MavBatteryType, MavResult,
    ATTITUDE_TARGET_DATA, BATTERY_STATUS_DATA, GLOBAL_POSITION_INT_DATA, GPS_GLOBAL_ORIGIN_DATA,
    GPS_RAW_INT_DATA, HOME_POSITION_DATA, MESSAGE_INTERVAL_DATA, MISSION_CURRENT_DATA,
    MISSION_ITEM_REACHED_DATA, PING_DATA, SYSTEM_TIME_DATA, VFR_HUD_DATA,
};
pub use crate::link::mission_run::MissionProgress;
use crate::link::outbound::Outbound;
use parapet_core::battery::{BatteryLevel, BatteryState};
use parapet_core::wire::streams::{HEARTBEAT_ID, SETTABLE, SETTABLE_COUNT};
use parapet_core::Vec3;

pub use parapet_core::wire::geo::ORIGIN;
/// Shortest settable interval, µs (100 Hz).
pub const MIN_INTERVAL_US: u32 = 10_000;

/// The streams served here, in table order.
/// A default period of 0: sent on request only.
const STREAMS: [(u32, u32); 9] = [
    (SYSTEM_TIME_DATA_ID, 1_000_000),
    (GLOBAL_POSITION_INT_ID, 200_000),
    (MISSION_CURRENT_ID, 1_000_000),
    (HOME_POSITION_ID, 2_000_000),
    (ATTITUDE_TARGET_ID, 100_000),
    (BATTERY_STATUS_ID, 1_000_000),
    (GPS_GLOBAL_ORIGIN_ID, 0),
    (GPS_RAW_INT_ID, 1_000_000),
    (VFR_HUD_ID, 250_000),
];
const _: () = assert!(STREAMS.len() <= 16, "Services::requested holds one bit per stream");
/// GPS_RAW_INT's message id.
pub const GPS_RAW_INT_ID: u32 = 24;
/// VFR_HUD's message id.
pub const VFR_HUD_ID: u32 = 74;
const GPS_GLOBAL_ORIGIN_ID: u32 = 49;
const SYSTEM_TIME_DATA_ID: u32 = 2;
const GLOBAL_POSITION_INT_ID: u32 = 33;
const MISSION_CURRENT_ID: u32 = 42;
/// HOME_POSITION's message id (MAV_CMD_GET_HOME_POSITION requests it).
pub const HOME_POSITION_ID: u32 = 242;
const ATTITUDE_TARGET_ID: u32 = 83;
/// BATTERY_STATUS's message id.
pub const BATTERY_STATUS_ID: u32 = 147;

/// The telemetry scheduler's streams whose rates are set here (HEARTBEAT, SYS_STATUS,
/// EXTENDED_SYS_STATE, ATTITUDE, LOCAL_POSITION_NED, POSITION_TARGET_LOCAL_NED) as
/// `(message id, default period µs)`, in [`StreamRates`] slot order: the stream registry's
/// settable entries (`parapet_core::wire::streams`).
pub const SCHEDULED: [(u32, u32); SETTABLE_COUNT] = SETTABLE;
/// Longest HEARTBEAT interval a ground station may set, µs: its default 1 Hz. HEARTBEAT is never
/// stopped nor slowed (−1 or a longer period: DENIED): the heartbeat protocol requires a
/// component to broadcast it regularly, ground stations and MAVSDK declare the vehicle lost after
/// a few missed 1 Hz heartbeats, and the one link feeds every client at once (PX4 refuses any
/// HEARTBEAT interval; faster is harmless and allowed here).
pub const HEARTBEAT_MAX_INTERVAL_US: u32 = 1_000_000;

/// Intervals and one-shot requests of the telemetry scheduler's [`SCHEDULED`] streams, as set
/// through the link (a `Copy` value the scheduler reads; on a board it travels with the link
/// counters to the task that runs the scheduler).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamRates {
    /// Per slot: 0 = the default period, −1 = stopped, > 0 = period, µs.
    pub interval_us: [i32; SCHEDULED.len()],
    /// Per slot: incremented (wrapping) by each REQUEST_MESSAGE; a change = send once.
    pub requests: [u8; SCHEDULED.len()],
}

impl StreamRates {
    /// Every stream at its default rate, nothing requested.
    pub const DEFAULT: Self = Self { interval_us: [0; SCHEDULED.len()], requests: [0; SCHEDULED.len()] };

    /// Period of slot `k`, µs; `None` when stopped (or `k` out of range).
    pub fn period_us(&self, k: usize) -> Option<u64> {
        let (iv, d) = (*self.interval_us.get(k)?, SCHEDULED.get(k)?.1);
        match iv {
            0 => Some(u64::from(d)),
            v if v > 0 => Some(v as u64),
            _ => None,
        }
    }
}

/// Interval table, due times and one-shot requests of the streams, and the mission-progress
/// state of MISSION_CURRENT / MISSION_ITEM_REACHED (see the module docs).
#[derive(Clone, Debug)]
pub struct Services {
    /// Period per stream, µs; `None` = stopped.
    interval_us: [Option<u32>; STREAMS.len()],
    next_due_us: [u64; STREAMS.len()],
    /// One-shot requests (REQUEST_MESSAGE), one bit per stream (16 bits: at most 16 streams,
    /// checked at compile time below).
    requested: u16,
    /// The scheduler's streams.
    rates: StreamRates,
    /// Last item reported by MISSION_ITEM_REACHED since the upload.
    reached: Option<u16>,
    /// Home, local NED ([`Services::home`]).
    home: Option<Vec3>,
    /// The vehicle was armed at the last poll (home is set on arming).
    was_armed: bool,
    /// The last position fix's accuracy ([`Services::on_fix`]).
    fix: FixAccuracy,
}

/// The accuracy of the position fix as its source states it (ODOMETRY's pose covariance):
/// 1σ, m; `None` unknown.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FixAccuracy {
    /// Horizontal: √max(σx², σy²) (as PX4's estimator reports `eph`).
    pub horizontal_m: Option<f32>,
    /// Vertical: σz.
    pub vertical_m: Option<f32>,
}

impl FixAccuracy {
    /// From ODOMETRY's `pose_covariance` (upper triangle of the 6×6 x, y, z, roll, pitch, yaw
    /// matrix, row-major: x² at 0, y² at 6, z² at 11; a NaN first element = unknown, as
    /// MAVLink specifies). Negative or non-finite variances are unknown.
    pub fn from_pose_covariance(c: &[f32; 21]) -> Self {
        let std = |v: f32| (v.is_finite() && v >= 0.0).then(|| libm::sqrtf(v));
        if c[0].is_nan() {
            return Self::default();
        }
        let horizontal_m = std(c[0]).zip(std(c[6])).map(|(x, y)| x.max(y));
        Self { horizontal_m, vertical_m: std(c[11]) }
    }
}

impl Default for Services {
    fn default() -> Self {
        Self::new()
    }
}

fn slot(msg_id: u32) -> Option<usize> {
    STREAMS.iter().position(|(id, _)| *id == msg_id)
}

/// `x` m/s as cm/s clamped into `i16` (0 when not finite).
fn cm_s(x: f32) -> i16 {
    if x.is_finite() {
        (x * 100.0).clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16
    } else {
        0
    }
}

/// GLOBAL_POSITION_INT of the snapshot's local NED state around [`ORIGIN`], the relative
/// altitude above `home_alt_mm` (AMSL); `None` when the position is not finite.
pub fn global_position(
    time_boot_ms: u32,
    s: &TelemetrySnapshot,
    home_alt_mm: i32,
) -> Option<GLOBAL_POSITION_INT_DATA> {
    let (lat, lon, alt) = parapet_core::wire::geo::ned_to_global(s.position_ned)?;
    let hdg = heading_deg(s.attitude_rpy.z).map_or(u16::MAX, |d| ((d * 100.0) as u16).min(35_999));
    Some(GLOBAL_POSITION_INT_DATA {
        time_boot_ms,
        lat,
        lon,
        alt,
        relative_alt: alt.saturating_sub(home_alt_mm),
        vx: cm_s(s.velocity_ned.x),
        vy: cm_s(s.velocity_ned.y),
        vz: cm_s(s.velocity_ned.z),
        hdg,
    })
}

/// HOME_POSITION of `home` (local NED): global around [`ORIGIN`] and local; `None` when not
/// finite.
pub fn home_position(time_usec: u64, home: Vec3) -> Option<HOME_POSITION_DATA> {
    let (latitude, longitude, altitude) = parapet_core::wire::geo::ned_to_global(home)?;
    Some(HOME_POSITION_DATA {
        latitude,
        longitude,
        altitude,
        x: home.x,
        y: home.y,
        z: home.z,
        q: [1.0, 0.0, 0.0, 0.0],
        time_usec,
        ..Default::default()
    })
}

/// Heading of yaw `yaw` (rad) in [0, 360) degrees; `None` when not finite.
fn heading_deg(yaw: f32) -> Option<f32> {
    if !yaw.is_finite() {
        return None;
    }
    let deg = libm::fmodf(yaw.to_degrees(), 360.0);
    Some(if deg < 0.0 { deg + 360.0 } else { deg }.min(359.99))
}

/// `x` × `scale` rounded up into `0..=max` (an accuracy is never reported better than it is).
fn scaled_up(x: f32, scale: f32, max: f32) -> f32 {
    libm::ceilf(x * scale).clamp(0.0, max)
}

/// GPS_RAW_INT of the position fix the vehicle navigates by (the external fix: Parapet has no
/// GNSS receiver; ground stations and MAVSDK's `gps_info` / `health()` want this message):
/// fix type 3D while the fix is fresh (the failsafe's position timeout), NO_FIX otherwise; the
/// position and ground velocity of the estimate as latitude/longitude/altitude around
/// [`ORIGIN`]; `eph` / `epv` = the fix's stated 1σ accuracy in cm (the convention of HIL_GPS as
/// PX4's simulator reads it: eph/100 m), `h_acc` / `v_acc` in mm, UINT16_MAX / 0 when the source
/// does not state it; course over ground cdeg (UINT16_MAX below 0.1 m/s); satellites_visible
/// UINT8_MAX (MAVLink's "unknown": the fix is not a satellite one); yaw 0 (not sent).
/// `None` while the position is not finite.
pub fn gps_raw_int(time_usec: u64, s: &TelemetrySnapshot, fix: FixAccuracy) -> Option<GPS_RAW_INT_DATA> {
    let (lat, lon, alt) = parapet_core::wire::geo::ned_to_global(s.position_ned)?;
    let v = s.velocity_ned;
    let ground = libm::sqrtf(v.x * v.x + v.y * v.y);
    let (vel, cog) = if ground.is_finite() {
        let cog = if ground >= 0.1 { heading_deg(libm::atan2f(v.y, v.x)) } else { None };
        ((ground * 100.0).min(65_534.0) as u16, cog.map_or(u16::MAX, |d| (d * 100.0) as u16))
    } else {
        (u16::MAX, u16::MAX)
    };
    let cm = |a: Option<f32>| a.map_or(u16::MAX, |m| scaled_up(m, 100.0, 65_534.0) as u16);
    let mm = |a: Option<f32>| a.map_or(0, |m| scaled_up(m, 1000.0, 4.0e9) as u32);
    Some(GPS_RAW_INT_DATA {
        time_usec,
        lat,
        lon,
        alt,
        eph: cm(fix.horizontal_m),
        epv: cm(fix.vertical_m),
        vel,
        cog,
        fix_type: if s.position_fresh {
            GpsFixType::GPS_FIX_TYPE_3D_FIX
        } else {
            GpsFixType::GPS_FIX_TYPE_NO_FIX
        },
        satellites_visible: u8::MAX,
        h_acc: mm(fix.horizontal_m),
        v_acc: mm(fix.vertical_m),
        ..Default::default()
    })
}

/// VFR_HUD: airspeed = groundspeed = the horizontal speed of the estimate (no airspeed sensor;
/// indoors there is no wind to tell them apart), heading deg (0..359) of the estimated yaw,
/// throttle % = the collective thrust setpoint / `thr_max` (as ATTITUDE_TARGET's thrust), alt m
/// AMSL around [`ORIGIN`], climb m/s (up positive). `None` while the position is not finite.
pub fn vfr_hud(s: &TelemetrySnapshot, thr_max: f32) -> Option<VFR_HUD_DATA> {
    let (_, _, alt_mm) = parapet_core::wire::geo::ned_to_global(s.position_ned)?;
    let v = s.velocity_ned;
    let ground = libm::sqrtf(v.x * v.x + v.y * v.y);
    let ground = if ground.is_finite() { ground } else { 0.0 };
    let thrust = s.attitude_sp.thrust;
    let throttle =
        if thr_max > 0.0 && thrust.is_finite() { (100.0 * thrust / thr_max).clamp(0.0, 100.0) } else { 0.0 };
    Some(VFR_HUD_DATA {
        airspeed: ground,
        groundspeed: ground,
        alt: alt_mm as f32 / 1000.0,
        climb: if v.z.is_finite() { -v.z } else { 0.0 },
        heading: heading_deg(s.attitude_rpy.z).map_or(0, |d| d as i16),
        throttle: libm::roundf(throttle) as u16,
    })
}

/// GPS_GLOBAL_ORIGIN: [`ORIGIN`].
pub fn global_origin(time_usec: u64) -> GPS_GLOBAL_ORIGIN_DATA {
    GPS_GLOBAL_ORIGIN_DATA { latitude: ORIGIN.0, longitude: ORIGIN.1, altitude: ORIGIN.2, time_usec }
}

/// The answer to a PING request (`target_system` and `target_component` 0) from `sender`;
/// `None` for a ping answer or one addressed elsewhere.
pub fn ping_reply(m: &PING_DATA, sender: (u8, u8)) -> Option<PING_DATA> {
    (m.target_system == 0 && m.target_component == 0).then_some(PING_DATA {
        time_usec: m.time_usec,
        seq: m.seq,
        target_system: sender.0,
        target_component: sender.1,
    })
}

/// mV of `v` volts for a BATTERY_STATUS cell field (at most 65 534; NaN → 0).
fn millivolts(v: f32) -> u16 {
    (v * 1000.0).clamp(0.0, 65_534.0) as u16
}

/// BATTERY_STATUS of battery measurement `b`: one pack (id 0, function ALL, LiPo); the pack
/// voltage in `voltages[0]` (cells not measured one by one: the others UINT16_MAX; a pack over
/// 65.534 V continues in `voltages[1]`, as the message specifies), current cA (−1 unknown),
/// remaining % (−1 unknown), charge state OK / LOW / CRITICAL from the level; consumption,
/// temperature and time remaining unknown.
pub fn battery_status(b: &BatteryState) -> BATTERY_STATUS_DATA {
    let mut voltages = [u16::MAX; 10];
    voltages[0] = millivolts(b.voltage_v);
    if voltages[0] == 65_534 {
        voltages[1] = millivolts(b.voltage_v - 65.534);
    }
    let current_battery = b
        .current_a
        .filter(|a| a.is_finite())
        .map_or(-1, |a| (a * 100.0).clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16);
    let battery_remaining =
        b.remaining.filter(|r| r.is_finite()).map_or(-1, |r| (r * 100.0).clamp(0.0, 100.0) as i8);
    let charge_state = match b.level {
        BatteryLevel::Ok => MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK,
        BatteryLevel::Low => MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_LOW,
        BatteryLevel::Critical => MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_CRITICAL,
    };
    BATTERY_STATUS_DATA {
        current_consumed: -1,
        energy_consumed: -1,
        temperature: i16::MAX,
        voltages,
        current_battery,
        id: 0,
        battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
        mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
        battery_remaining,
        charge_state,
        ..Default::default()
    }
}

/// ATTITUDE_TARGET of the snapshot's attitude setpoint; `thr_max` = `THR_MAX`, N.
pub fn attitude_target(time_boot_ms: u32, s: &TelemetrySnapshot, thr_max: f32) -> ATTITUDE_TARGET_DATA {
    let a = &s.attitude_sp;
    let q = parapet_core::frame::quat_from_euler(a.roll, a.pitch, a.yaw);
    let thrust =
        if thr_max > 0.0 && a.thrust.is_finite() { (a.thrust / thr_max).clamp(0.0, 1.0) } else { 0.0 };
    ATTITUDE_TARGET_DATA {
        time_boot_ms,
        q: [q.w, q.i, q.j, q.k],
        thrust,
        type_mask: AttitudeTargetTypemask::ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE
            | AttitudeTargetTypemask::ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE
            | AttitudeTargetTypemask::ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE,
        ..Default::default()
    }
}

/// An interval request (−1 stop, 0 default, > 0 period µs) as the table's `Option`:
/// `Err(())` for a refused value.
fn interval_of(interval_us: f32, default_us: u32) -> Result<Option<u32>, ()> {
    if interval_us == -1.0 {
        Ok(None)
    } else if interval_us == 0.0 {
        Ok(Some(default_us).filter(|d| *d > 0))
    } else if interval_us.is_finite() && interval_us >= MIN_INTERVAL_US as f32 && interval_us <= 1e9 {
        Ok(Some(interval_us as u32))
    } else {
        Err(())
    }
}

fn scheduled_slot(msg_id: u32) -> Option<usize> {
    SCHEDULED.iter().position(|(id, _)| *id == msg_id)
}

impl Services {
    /// Every stream at its default rate, due at once.
    pub const fn new() -> Self {
        let mut interval_us = [None; STREAMS.len()];
        let mut k = 0;
        while k < STREAMS.len() {
            interval_us[k] = if STREAMS[k].1 > 0 { Some(STREAMS[k].1) } else { None };
            k += 1;
        }
        Self {
            interval_us,
            next_due_us: [0; STREAMS.len()],
            requested: 0,
            rates: StreamRates::DEFAULT,
            reached: None,
            home: None,
            was_armed: false,
            fix: FixAccuracy { horizontal_m: None, vertical_m: None },
        }
    }

    /// A position fix arrived with accuracy `a` (GPS_RAW_INT reports the last one).
    pub fn on_fix(&mut self, a: FixAccuracy) {
        self.fix = a;
    }

    /// `false` for a message the vehicle cannot send now (BATTERY_STATUS before a battery
    /// measurement: no battery; HOME_POSITION before a position): MAV_CMD_REQUEST_MESSAGE for
    /// it is answered DENIED and nothing is sent.
    pub fn can_send(&self, msg_id: f32, s: &TelemetrySnapshot) -> bool {
        match msg_id_of(msg_id) {
            Some(BATTERY_STATUS_ID) => s.battery.is_some(),
            Some(HOME_POSITION_ID) => self.home.is_some(),
            _ => true,
        }
    }

    /// Home, local NED: where the vehicle last armed; before the first arming its first finite
    /// position, or what MAV_CMD_DO_SET_HOME set while disarmed. `None` before a position.
    pub fn home(&self) -> Option<Vec3> {
        self.home
    }

    /// MAV_CMD_DO_SET_HOME: home at `home` (local NED), sent at once. Refused (DENIED) while
    /// armed: Return flies the breadcrumb trail back to where the vehicle armed
    /// (`parapet_core::outer::return_path`), and HOME_POSITION shows where Return goes.
    pub fn set_home(&mut self, home: Vec3, armed: bool) -> MavResult {
        if armed || !home.iter().all(|c| c.is_finite()) {
            return MavResult::MAV_RESULT_DENIED;
        }
        self.home = Some(home);
        let _ = self.request(HOME_POSITION_ID as f32);
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// Home follows the vehicle: set where it arms, and at its first position.
    fn track_home(&mut self, s: &TelemetrySnapshot) {
        let p = s.position_ned;
        let finite = p.iter().all(|c| c.is_finite());
        let arming = s.armed && !self.was_armed;
        self.was_armed = s.armed;
        if finite && (arming || self.home.is_none()) {
            self.home = Some(p);
            let _ = self.request(HOME_POSITION_ID as f32);
        }
    }

    /// MAV_CMD_SET_MESSAGE_INTERVAL: `interval_us` −1 stop, 0 default, > 0 period (HEARTBEAT:
    /// never stopped, at most [`HEARTBEAT_MAX_INTERVAL_US`]).
    pub fn set_interval(&mut self, msg_id: f32, interval_us: f32) -> MavResult {
        let id = msg_id_of(msg_id);
        if let Some(k) = id.and_then(scheduled_slot) {
            let iv = interval_of(interval_us, SCHEDULED[k].1);
            let heartbeat_ok = |iv: Option<u32>| iv.is_some_and(|p| p <= HEARTBEAT_MAX_INTERVAL_US);
            if id == Some(HEARTBEAT_ID) && !iv.is_ok_and(heartbeat_ok) {
                return MavResult::MAV_RESULT_DENIED;
            }
            return match iv {
                Ok(iv) => {
                    // The scheduler restarts a stream whose interval changed.
                    self.rates.interval_us[k] = match iv {
                        None => -1,
                        Some(_) if interval_us == 0.0 => 0,
                        Some(u) => u.min(i32::MAX as u32) as i32,
                    };
                    MavResult::MAV_RESULT_ACCEPTED
                }
                Err(()) => MavResult::MAV_RESULT_DENIED,
            };
        }
        let Some(k) = id.and_then(slot) else { return MavResult::MAV_RESULT_UNSUPPORTED };
        match interval_of(interval_us, STREAMS[k].1) {
            Ok(iv) => self.interval_us[k] = iv,
            Err(()) => return MavResult::MAV_RESULT_DENIED,
        }
        self.next_due_us[k] = 0;
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// MAV_CMD_REQUEST_MESSAGE for a stream served here or by the scheduler: sent at the next
    /// poll. `false` for other ids.
    pub fn request(&mut self, msg_id: f32) -> bool {
        let id = msg_id_of(msg_id);
        if let Some(k) = id.and_then(scheduled_slot) {
            self.rates.requests[k] = self.rates.requests[k].wrapping_add(1);
            return true;
        }
        match id.and_then(slot) {
            Some(k) => {
                self.requested |= 1 << k;
                true
            }
            None => false,
        }
    }

    /// The scheduler's stream rates (see [`StreamRates`]).
    pub fn rates(&self) -> StreamRates {
        self.rates
    }

    /// MESSAGE_INTERVAL for `msg_id` (MAV_CMD_GET_MESSAGE_INTERVAL): −1 stopped, 0 not
    /// available (not served here).
    pub fn message_interval(&self, msg_id: f32) -> MESSAGE_INTERVAL_DATA {
        let id = msg_id_of(msg_id);
        let interval_us = if let Some(k) = id.and_then(scheduled_slot) {
            self.rates.period_us(k).map_or(-1, |u| u.min(i32::MAX as u64) as i32)
        } else {
            match id.and_then(slot) {
                Some(k) => self.interval_us[k].map_or(-1, |u| u.min(i32::MAX as u32) as i32),
                None => 0,
            }
        };
        MESSAGE_INTERVAL_DATA { interval_us, message_id: id.map_or(0, |i| i.min(u32::from(u16::MAX)) as u16) }
    }

    /// A new mission was accepted, or the mission was cleared: MISSION_CURRENT starts again at
    /// item 0, NOT_STARTED, and MISSION_ITEM_REACHED from the first item.
    pub fn on_new_mission(&mut self) {
        self.reached = None;
    }

    /// MISSION_CURRENT of the mission's progress `m` ([`crate::link::mission_run`]).
    pub fn mission_current(&self, m: MissionProgress) -> MISSION_CURRENT_DATA {
        MISSION_CURRENT_DATA {
            seq: m.current,
            total: m.total,
            mission_state: m.state,
            mission_id: m.mission_id,
            ..Default::default()
        }
    }

    /// The next MISSION_ITEM_REACHED due (each item once, in order, up to `m.reached`).
    fn next_reached(&mut self, m: MissionProgress) -> Option<MISSION_ITEM_REACHED_DATA> {
        let next = self.reached.map_or(0, |r| r.saturating_add(1));
        if m.total == 0 || m.reached? < next || self.reached == Some(m.total - 1) {
            return None;
        }
        self.reached = Some(next);
        Some(MISSION_ITEM_REACHED_DATA { seq: next })
    }

    /// Emits MISSION_ITEM_REACHED when due, the streams due at `now_us` and the requested
    /// ones; at most `budget` messages (the caller's free reply slots); a stream over budget
    /// stays due. `thr_max`: `THR_MAX` (N) for ATTITUDE_TARGET's normalised thrust.
    pub fn poll(
        &mut self,
        now_us: u64,
        s: &TelemetrySnapshot,
        mission: MissionProgress,
        thr_max: f32,
        budget: usize,
        mut emit: impl FnMut(Outbound),
    ) {
        let mut left = budget;
        let ms = (now_us / 1000) as u32;
        self.track_home(s);
        let home_alt_mm =
            self.home.and_then(parapet_core::wire::geo::ned_to_global).map_or(ORIGIN.2, |g| g.2);
        if left > 0 {
            if let Some(r) = self.next_reached(mission) {
                emit(Outbound::MissionItemReached(r));
                left -= 1;
            }
        }
        for (k, (id, _)) in STREAMS.iter().enumerate() {
            let requested = self.requested & (1 << k) != 0;
            let periodic = self.interval_us[k].filter(|_| now_us >= self.next_due_us[k]);
            if !requested && periodic.is_none() {
                continue;
            }
            if left == 0 {
                return;
            }
            let m = match *id {
                SYSTEM_TIME_DATA_ID => {
                    Some(Outbound::SystemTime(SYSTEM_TIME_DATA { time_unix_usec: 0, time_boot_ms: ms }))
                }
                GLOBAL_POSITION_INT_ID => {
                    global_position(ms, s, home_alt_mm).map(Outbound::GlobalPositionInt)
                }
                MISSION_CURRENT_ID => Some(Outbound::MissionCurrent(self.mission_current(mission))),
                ATTITUDE_TARGET_ID => Some(Outbound::AttitudeTarget(attitude_target(ms, s, thr_max))),
                BATTERY_STATUS_ID => s.battery.as_ref().map(|b| Outbound::BatteryStatus(battery_status(b))),
                GPS_GLOBAL_ORIGIN_ID => Some(Outbound::GpsGlobalOrigin(global_origin(now_us))),
                GPS_RAW_INT_ID => gps_raw_int(now_us, s, self.fix).map(Outbound::GpsRawInt),
                VFR_HUD_ID => vfr_hud(s, thr_max).map(Outbound::VfrHud),
                _ => self.home.and_then(|h| home_position(now_us, h)).map(Outbound::HomePosition),
            };
            if let Some(m) = m {
                emit(m);
                left -= 1;
            }
            self.requested &= !(1 << k);
            if let Some(p) = periodic {
                self.next_due_us[k] = now_us.saturating_add(u64::from(p));
            }
        }
    }
}

/// A message id from a command's float parameter (whole, 0..2^24).
fn msg_id_of(p: f32) -> Option<u32> {
    ((0.0..16_777_216.0).contains(&p) && p == (p as u32) as f32).then_some(p as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::Vec3;

    fn snap(p: Vec3, yaw: f32) -> TelemetrySnapshot {
        TelemetrySnapshot {
            position_ned: p,
            velocity_ned: Vec3::new(1.0, -2.0, 0.5),
            attitude_rpy: Vec3::new(0.0, 0.0, yaw),
            ..TelemetrySnapshot::BOOT
        }
    }

    fn ids(s: &mut Services, t: u64, snap: &TelemetrySnapshot, budget: usize) -> Vec<u32> {
        let mut out = Vec::new();
        s.poll(t, snap, MissionProgress::NONE, 1000.0, budget, |m| {
            out.push(match m {
                Outbound::SystemTime(_) => 2,
                Outbound::GlobalPositionInt(_) => 33,
                Outbound::MissionCurrent(_) => 42,
                Outbound::HomePosition(_) => 242,
                Outbound::AttitudeTarget(_) => 83,
                Outbound::BatteryStatus(_) => 147,
                Outbound::MissionItemReached(_) => 46,
                Outbound::GpsRawInt(_) => 24,
                Outbound::VfrHud(_) => 74,
                _ => 0,
            })
        });
        out
    }

    #[test]
    fn global_position_is_the_local_position_around_home() {
        // 100 m north, 50 m east, 10 m up, heading west (-90°).
        let at = |p, yaw| global_position(5, &snap(p, yaw), ORIGIN.2);
        let g = at(Vec3::new(100.0, 50.0, -10.0), -core::f32::consts::FRAC_PI_2).expect("finite");
        assert_eq!(g.lat - ORIGIN.0, 8983, "100 m north = 8983e-7 deg");
        assert_eq!(g.lon - ORIGIN.1, 6635, "50 m east at 47.4 N = 6635e-7 deg");
        assert_eq!((g.alt, g.relative_alt), (ORIGIN.2 + 10_000, 10_000));
        assert_eq!((g.vx, g.vy, g.vz, g.hdg), (100, -200, 50, 27_000));
        assert!(at(Vec3::new(f32::NAN, 0.0, 0.0), 0.0).is_none());
        assert_eq!(at(Vec3::zeros(), f32::NAN).map(|g| g.hdg), Some(u16::MAX));
        let above_home = global_position(5, &snap(Vec3::new(0.0, 0.0, -10.0), 0.0), ORIGIN.2 + 2_000);
        assert_eq!(above_home.map(|g| g.relative_alt), Some(8_000), "relative to home's altitude");
    }

    /// Home: the first position, then where the vehicle arms (sent at once each time, in local
    /// and global coordinates); MAV_CMD_DO_SET_HOME only while disarmed; GPS_GLOBAL_ORIGIN on
    /// request only, the origin. Before: HOME_POSITION was the origin whatever the vehicle did.
    #[test]
    fn home_is_where_the_vehicle_armed_and_the_origin_on_request() {
        let mut s = Services::new();
        for k in [2.0, 33.0, 42.0, 83.0] {
            s.set_interval(k, -1.0);
        }
        let mut homes = Vec::new();
        let mut origin = Vec::new();
        let mut poll = |s: &mut Services, t: u64, sn: &TelemetrySnapshot| {
            let mut out = Vec::new();
            s.poll(t, sn, MissionProgress::NONE, 1000.0, 8, |m| out.push(m));
            for m in out {
                match m {
                    Outbound::HomePosition(h) => homes.push((h.x, h.y, h.z, h.latitude - ORIGIN.0)),
                    Outbound::GpsGlobalOrigin(o) => origin.push((o.latitude, o.longitude, o.altitude)),
                    _ => {}
                }
            }
            (homes.clone(), origin.clone())
        };
        let mut sn = snap(Vec3::new(1.0, 1.0, 0.0), 0.0);
        poll(&mut s, 1_000_000, &sn);
        poll(&mut s, 1_001_000, &sn);
        sn.position_ned = Vec3::new(2.0, 1.0, 0.0);
        let (homes, _) = poll(&mut s, 1_002_000, &sn);
        assert_eq!(homes, vec![(1.0, 1.0, 0.0, 90)], "the first position, once until the period");
        sn.armed = true;
        let (homes, _) = poll(&mut s, 1_003_000, &sn);
        assert_eq!(homes.last(), Some(&(2.0, 1.0, 0.0, 180)), "where it armed, at once");
        sn.position_ned = Vec3::new(5.0, 1.0, -3.0);
        poll(&mut s, 1_004_000, &sn);
        assert_eq!(s.home(), Some(Vec3::new(2.0, 1.0, 0.0)), "not while flying");
        assert_eq!(s.set_home(Vec3::new(0.0, 0.0, 0.0), true), MavResult::MAV_RESULT_DENIED);
        sn.armed = false;
        poll(&mut s, 1_005_000, &sn);
        assert_eq!(s.set_home(Vec3::new(-1.0, 0.5, 0.0), false), MavResult::MAV_RESULT_ACCEPTED);
        let (homes, origin) = poll(&mut s, 1_006_000, &sn);
        assert_eq!(homes.last().map(|h| (h.0, h.1)), Some((-1.0, 0.5)));
        assert_eq!(s.set_home(Vec3::new(f32::NAN, 0.0, 0.0), false), MavResult::MAV_RESULT_DENIED);
        assert!(origin.is_empty(), "not streamed");
        assert_eq!(s.message_interval(49.0).interval_us, -1);
        assert!(s.request(49.0));
        let (_, origin) = poll(&mut s, 9_000_000, &sn);
        assert_eq!(origin, vec![ORIGIN]);
    }

    #[test]
    fn streams_follow_their_intervals_and_requests() {
        let mut s = Services::new();
        let sn = snap(Vec3::zeros(), 0.0);
        assert_eq!(ids(&mut s, 1_000_000, &sn, 8), vec![2, 33, 42, 242, 83, 24, 74], "no battery: no 147");
        assert_eq!(s.set_interval(83.0, -1.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.set_interval(24.0, -1.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.set_interval(74.0, -1.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(ids(&mut s, 1_100_000, &sn, 8), Vec::<u32>::new());
        assert_eq!(ids(&mut s, 1_200_000, &sn, 8), vec![33]);
        // 50 Hz global position, system time stopped, home requested once.
        assert_eq!(s.set_interval(33.0, 20_000.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.set_interval(2.0, -1.0), MavResult::MAV_RESULT_ACCEPTED);
        assert!(s.request(242.0));
        assert_eq!(ids(&mut s, 1_210_000, &sn, 8), vec![33, 242]);
        assert_eq!(ids(&mut s, 1_230_000, &sn, 8), vec![33]);
        assert_eq!(ids(&mut s, 5_000_000, &sn, 8), vec![33, 42, 242]);
        assert_eq!(s.message_interval(2.0).interval_us, -1);
        assert_eq!(s.message_interval(33.0).interval_us, 20_000);
        // Refused: too fast, not finite, not a stream served here; default restores.
        assert_eq!(s.set_interval(33.0, 100.0), MavResult::MAV_RESULT_DENIED);
        assert_eq!(s.set_interval(33.0, f32::NAN), MavResult::MAV_RESULT_DENIED);
        assert_eq!(s.set_interval(31.0, 20_000.0), MavResult::MAV_RESULT_UNSUPPORTED);
        assert_eq!(s.set_interval(33.5, 20_000.0), MavResult::MAV_RESULT_UNSUPPORTED);
        assert!(!s.request(148.0));
        assert_eq!(s.set_interval(33.0, 0.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.message_interval(33.0).interval_us, 200_000);
        assert_eq!(s.message_interval(31.0).interval_us, 0);
    }

    /// The [`StreamRates`] slot of a scheduler stream's message id (the registry's order).
    fn slot_of(msg_id: u32) -> usize {
        scheduled_slot(msg_id).expect("a scheduler stream")
    }

    #[test]
    fn the_schedulers_streams_are_set_here() {
        let mut s = Services::new();
        let (att, pos, target) = (slot_of(30), slot_of(32), slot_of(85));
        // ATTITUDE 10 Hz, LOCAL_POSITION_NED stopped, POSITION_TARGET_LOCAL_NED requested once.
        assert_eq!(s.message_interval(30.0).interval_us, 20_000);
        assert_eq!(s.set_interval(30.0, 100_000.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.set_interval(32.0, -1.0), MavResult::MAV_RESULT_ACCEPTED);
        assert!(s.request(85.0));
        let r = s.rates();
        assert_eq!(
            (r.period_us(att), r.period_us(pos), r.period_us(target)),
            (Some(100_000), None, Some(40_000))
        );
        assert_eq!((r.requests[target], r.requests.iter().sum::<u8>()), (1, 1));
        assert_eq!(s.message_interval(30.0).interval_us, 100_000);
        assert_eq!(s.message_interval(32.0).interval_us, -1);
        assert_eq!(s.set_interval(85.0, 5_000.0), MavResult::MAV_RESULT_DENIED, "faster than 100 Hz");
        assert_eq!(s.set_interval(30.0, 0.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.rates().period_us(att), Some(20_000));
        assert_eq!(StreamRates::default().period_us(target), Some(40_000), "the default is the default rate");
    }

    /// HEARTBEAT, SYS_STATUS and EXTENDED_SYS_STATE are the scheduler's too; HEARTBEAT is never
    /// stopped nor slower than 1 Hz.
    #[test]
    fn heartbeat_status_and_landed_state_rates() {
        let mut s = Services::new();
        assert_eq!(s.set_interval(1.0, 200_000.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.set_interval(245.0, -1.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.set_interval(0.0, 100_000.0), MavResult::MAV_RESULT_ACCEPTED);
        let r = s.rates();
        let (hb, status, landed) = (slot_of(0), slot_of(1), slot_of(245));
        assert_eq!(
            (r.period_us(hb), r.period_us(status), r.period_us(landed)),
            (Some(100_000), Some(200_000), None)
        );
        for refused in [-1.0, 1_000_001.0, 5_000_000.0, 5_000.0, f32::NAN] {
            assert_eq!(s.set_interval(0.0, refused), MavResult::MAV_RESULT_DENIED, "HEARTBEAT {refused}");
        }
        assert_eq!(s.message_interval(0.0).interval_us, 100_000, "a refusal keeps the rate");
        assert_eq!(s.set_interval(0.0, 1_000_000.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.set_interval(0.0, 0.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.message_interval(0.0).interval_us, 1_000_000);
        assert_eq!(s.message_interval(245.0).interval_us, -1);
        assert!(s.request(245.0) && s.request(0.0));
        let r = s.rates().requests;
        assert_eq!((r[hb], r[landed], r.iter().sum::<u8>()), (1, 1, 2));
    }

    /// MISSION_ITEM_REACHED reports each item once, in order, up to the progress's last item
    /// done (one per poll), and starts again after a new mission.
    #[test]
    fn items_reached_once_each_in_order() {
        let mut s = Services::new();
        for k in [2.0, 33.0, 42.0, 242.0, 83.0] {
            s.set_interval(k, -1.0);
        }
        let m = |reached| MissionProgress {
            total: 4,
            current: 0,
            reached,
            state: crate::link::dialect::MissionState::MISSION_STATE_ACTIVE,
            mission_id: 1,
        };
        let mut reached = Vec::new();
        let mut t = 1_000_000;
        for r in [None, Some(0), Some(2), Some(2), Some(2), Some(1), Some(3), Some(3)] {
            t += 1000;
            s.poll(t, &TelemetrySnapshot::BOOT, m(r), 1000.0, 8, |o| {
                if let Outbound::MissionItemReached(r) = o {
                    reached.push(r.seq);
                }
            });
        }
        assert_eq!(reached, vec![0, 1, 2, 3]);
        assert_eq!(s.mission_current(m(Some(1))).seq, 0);
        s.on_new_mission();
        let mut again = Vec::new();
        s.poll(t + 1000, &TelemetrySnapshot::BOOT, m(Some(3)), 1000.0, 8, |o| {
            if let Outbound::MissionItemReached(r) = o {
                again.push(r.seq);
            }
        });
        assert_eq!(again, vec![0]);
    }

    #[test]
    fn battery_status_of_a_measurement() {
        let b = BatteryState {
            t_us: 5,
            voltage_v: 15.2,
            current_a: Some(12.34),
            remaining: Some(0.57),
            level: BatteryLevel::Low,
        };
        let m = battery_status(&b);
        assert_eq!(m.voltages[0], 15_200);
        assert!(m.voltages[1..].iter().all(|v| *v == u16::MAX));
        assert_eq!((m.current_battery, m.battery_remaining), (1234, 57));
        assert_eq!(m.charge_state, MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_LOW);
        let unknown =
            battery_status(&BatteryState { current_a: None, remaining: None, voltage_v: f32::NAN, ..b });
        assert_eq!((unknown.voltages[0], unknown.current_battery, unknown.battery_remaining), (0, -1, -1));
        let big = battery_status(&BatteryState { voltage_v: 70.0, ..b });
        assert_eq!((big.voltages[0], big.voltages[1]), (65_534, 4_466));
        // Sent once a measurement is known.
        let mut s = Services::new();
        let sn = TelemetrySnapshot { battery: Some(b), ..TelemetrySnapshot::BOOT };
        assert!(ids(&mut s, 1_000_000, &sn, 8).contains(&147));
    }

    #[test]
    fn attitude_target_is_the_setpoint_quaternion_and_normalised_thrust() {
        let sn = TelemetrySnapshot {
            attitude_sp: parapet_core::msg::AttitudeSetpoint {
                roll: 0.0,
                pitch: 0.0,
                yaw: core::f32::consts::FRAC_PI_2,
                thrust: 6.0,
                saturated: false,
            },
            ..TelemetrySnapshot::BOOT
        };
        let a = attitude_target(7, &sn, 12.0);
        let h = core::f32::consts::FRAC_1_SQRT_2;
        assert!((a.q[0] - h).abs() < 1e-6 && (a.q[3] - h).abs() < 1e-6 && a.q[1].abs() < 1e-6, "{:?}", a.q);
        assert_eq!((a.time_boot_ms, a.thrust), (7, 0.5));
        assert_eq!(attitude_target(7, &sn, 0.0).thrust, 0.0, "no THR_MAX: 0, never a division by 0");
    }

    #[test]
    fn a_full_queue_defers_streams() {
        let mut s = Services::new();
        s.set_interval(83.0, -1.0);
        let sn = snap(Vec3::zeros(), 0.0);
        assert_eq!(ids(&mut s, 1_000_000, &sn, 1), vec![2]);
        assert_eq!(ids(&mut s, 1_000_001, &sn, 0), Vec::<u32>::new());
        assert_eq!(ids(&mut s, 1_000_002, &sn, 8), vec![33, 42, 242, 24, 74]);
    }

    #[test]
    fn ping_requests_are_answered_to_the_sender() {
        let req = PING_DATA { time_usec: 42, seq: 7, target_system: 0, target_component: 0 };
        let r = ping_reply(&req, (255, 190)).expect("a request");
        assert_eq!((r.time_usec, r.seq, r.target_system, r.target_component), (42, 7, 255, 190));
        assert!(ping_reply(&PING_DATA { target_system: 1, ..req }, (255, 190)).is_none());
    }

    /// GPS_RAW_INT: the fix as a 3D "GPS" while fresh (NO_FIX when stale), the position around
    /// the origin, the stated accuracy rounded up (cm, mm; unknown: UINT16_MAX / 0), the course
    /// over ground, satellites unknown. Before: never sent (MAVSDK's `gps_info` never arrived).
    #[test]
    fn gps_raw_int_reports_the_fix_and_its_accuracy() {
        let mut sn = snap(Vec3::new(100.0, 50.0, -10.0), 0.0);
        sn.velocity_ned = Vec3::new(0.0, -2.0, 0.5);
        sn.position_fresh = true;
        // The PIL's sensor model: 5 mm per axis (variance 2.5e-5 m²).
        let mut cov = [0.0f32; 21];
        (cov[0], cov[6], cov[11]) = (2.5e-5, 2.5e-5, 2.5e-5);
        let a = FixAccuracy::from_pose_covariance(&cov);
        assert!((a.horizontal_m.unwrap_or(0.0) - 0.005).abs() < 1e-6 && a.vertical_m.is_some());
        let g = gps_raw_int(7, &sn, a).expect("finite");
        assert_eq!(g.fix_type, GpsFixType::GPS_FIX_TYPE_3D_FIX);
        assert_eq!((g.lat - ORIGIN.0, g.lon - ORIGIN.1, g.alt), (8983, 6635, ORIGIN.2 + 10_000));
        assert_eq!((g.eph, g.epv, g.h_acc, g.v_acc), (1, 1, 5, 5), "5 mm: 1 cm, 5 mm");
        assert_eq!((g.vel, g.cog, g.satellites_visible), (200, 27_000, u8::MAX), "2 m/s west");
        // Unknown accuracy (NaN first element), stale fix, standing still.
        cov[0] = f32::NAN;
        sn.position_fresh = false;
        sn.velocity_ned = Vec3::zeros();
        let g = gps_raw_int(7, &sn, FixAccuracy::from_pose_covariance(&cov)).expect("finite");
        assert_eq!(g.fix_type, GpsFixType::GPS_FIX_TYPE_NO_FIX);
        assert_eq!((g.eph, g.epv, g.h_acc, g.v_acc, g.vel, g.cog), (u16::MAX, u16::MAX, 0, 0, 0, u16::MAX));
        sn.position_ned.x = f32::NAN;
        assert!(gps_raw_int(7, &sn, a).is_none());
        // A larger sigma on one axis is the horizontal accuracy; a negative variance is unknown.
        (cov[0], cov[6], cov[11]) = (0.04, 0.01, -1.0);
        let a = FixAccuracy::from_pose_covariance(&cov);
        assert_eq!((a.horizontal_m, a.vertical_m), (Some(0.2), None));
    }

    /// VFR_HUD: airspeed = groundspeed = horizontal speed, heading of the yaw, throttle % of
    /// the thrust setpoint, altitude AMSL, climb up-positive.
    #[test]
    fn vfr_hud_reports_speed_heading_throttle_altitude_and_climb() {
        let mut sn = snap(Vec3::new(0.0, 0.0, -2.0), -core::f32::consts::FRAC_PI_2);
        sn.velocity_ned = Vec3::new(3.0, 4.0, -0.5);
        sn.attitude_sp.thrust = 4.0;
        let h = vfr_hud(&sn, 10.0).expect("finite");
        assert_eq!((h.airspeed, h.groundspeed, h.heading, h.throttle), (5.0, 5.0, 270, 40));
        assert!((h.alt - (ORIGIN.2 as f32 / 1000.0 + 2.0)).abs() < 1e-3 && h.climb == 0.5);
        sn.attitude_sp.thrust = f32::NAN;
        assert_eq!(vfr_hud(&sn, 10.0).map(|h| h.throttle), Some(0));
        sn.position_ned.z = f32::INFINITY;
        assert!(vfr_hud(&sn, 10.0).is_none());
    }

    /// REQUEST_MESSAGE for BATTERY_STATUS without a battery (or HOME_POSITION before a
    /// position) cannot be served: the router answers DENIED. Before: ACCEPTED, never sent.
    #[test]
    fn no_battery_no_battery_status() {
        let mut s = Services::new();
        let mut sn = snap(Vec3::zeros(), 0.0);
        assert!(!s.can_send(147.0, &sn), "no battery");
        assert!(!s.can_send(242.0, &sn), "no home before the first poll");
        assert!(s.can_send(24.0, &sn) && s.can_send(33.0, &sn));
        s.poll(1, &sn, MissionProgress::NONE, 1000.0, 8, |_| {});
        assert!(s.can_send(242.0, &sn), "home known");
        sn.battery = Some(BatteryState {
            voltage_v: 12.0,
            current_a: None,
            remaining: None,
            level: BatteryLevel::Ok,
            t_us: 0,
        });
        assert!(s.can_send(147.0, &sn));
    }
}
