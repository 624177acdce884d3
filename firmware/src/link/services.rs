//! Link-level services a ground station expects from a PX4-like autopilot, beyond the
//! telemetry scheduler's streams ([`crate::link::telemetry`]): PING answers, and the streams
//! SYSTEM_TIME, HOME_POSITION, GLOBAL_POSITION_INT and MISSION_CURRENT at rates a ground station
//! may change (MAV_CMD_SET_MESSAGE_INTERVAL 511), each also sent once on MAV_CMD_REQUEST_MESSAGE
//! (512), with MESSAGE_INTERVAL answers (MAV_CMD_GET_MESSAGE_INTERVAL 510).
//!
//! | stream | id | default | content |
//! |---|---|---|---|
//! | SYSTEM_TIME | 2 | 1 Hz | `time_unix_usec` 0 (no wall clock on board), `time_boot_ms` firmware clock |
//! | GLOBAL_POSITION_INT | 33 | 5 Hz | the local NED position around [`HOME`] on a flat earth (WGS-84 equatorial radius): lat/lon 1e-7°, alt AMSL / relative mm, velocity cm/s, heading cdeg (65535 unknown). Not sent while the position or yaw is not finite |
//! | MISSION_CURRENT | 42 | 1 Hz | seq = waypoint being flown, total = waypoints of the accepted mission (0 none) |
//! | HOME_POSITION | 242 | 0.5 Hz | [`HOME`], local position 0, quaternion identity |
//!
//! Intervals: −1 stops a stream, 0 restores its default, > 0 is the period in µs (at least
//! [`MIN_INTERVAL_US`]; shorter is refused DENIED). Other message ids are answered UNSUPPORTED
//! (the telemetry scheduler's rates are fixed). The table is fixed (one slot per stream above).
//!
//! **Home**: fixed at PX4 SITL's default home (Zurich, 47.397742° N, 8.545594° E, 488 m AMSL):
//! Parapet flies in a local NED frame and has no GNSS; GLOBAL_POSITION_INT and HOME_POSITION
//! exist so that map-based ground stations (QGroundControl, MAVSDK) show the vehicle.
//!
//! May import: `parapet_core`, the dialect, [`crate::app::autopilot`] (telemetry snapshot),
//! [`crate::link::outbound`]. No allocation; every call is bounded (at most one message per
//! stream per [`Services::poll`]).
#![allow(deprecated)] // PING: deprecated by MAVLink for TIMESYNC, still sent by tools (PX4 answers it)

use crate::app::autopilot::TelemetrySnapshot;
use crate::link::dialect::{
    MavResult, GLOBAL_POSITION_INT_DATA, HOME_POSITION_DATA, MESSAGE_INTERVAL_DATA, MISSION_CURRENT_DATA,
    PING_DATA, SYSTEM_TIME_DATA,
};
use crate::link::outbound::Outbound;

/// Home of the global position (PX4 SITL default): latitude and longitude 1e-7 °, altitude mm
/// AMSL.
pub const HOME: (i32, i32, i32) = (473_977_420, 85_455_940, 488_000);
/// 1e-7 ° of latitude per metre north (WGS-84 equatorial radius 6,378,137 m).
const LAT_E7_PER_M: f32 = 89.831_53;
/// 1e-7 ° of longitude per metre east at [`HOME`]'s latitude.
const LON_E7_PER_M: f32 = 132.709_22;
/// Shortest settable interval, µs (100 Hz).
pub const MIN_INTERVAL_US: u32 = 10_000;

/// The streams served here, in table order.
const STREAMS: [(u32, u32); 4] = [
    (SYSTEM_TIME_DATA_ID, 1_000_000),
    (GLOBAL_POSITION_INT_ID, 200_000),
    (MISSION_CURRENT_ID, 1_000_000),
    (HOME_POSITION_ID, 2_000_000),
];
const SYSTEM_TIME_DATA_ID: u32 = 2;
const GLOBAL_POSITION_INT_ID: u32 = 33;
const MISSION_CURRENT_ID: u32 = 42;
const HOME_POSITION_ID: u32 = 242;

/// Mission progress for MISSION_CURRENT.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MissionProgress {
    /// Waypoint being flown (index into the mission).
    pub seq: u16,
    /// Waypoints of the accepted mission.
    pub total: u16,
}

/// Interval table, due times and one-shot requests of the streams (see the module docs).
#[derive(Clone, Debug)]
pub struct Services {
    /// Period per stream, µs; `None` = stopped.
    interval_us: [Option<u32>; STREAMS.len()],
    next_due_us: [u64; STREAMS.len()],
    /// One-shot requests (REQUEST_MESSAGE), one bit per stream.
    requested: u8,
}

impl Default for Services {
    fn default() -> Self {
        Self::new()
    }
}

fn slot(msg_id: u32) -> Option<usize> {
    STREAMS.iter().position(|(id, _)| *id == msg_id)
}

/// `x` rounded and clamped into `i32`; `None` when not finite.
fn to_i32(x: f32) -> Option<i32> {
    x.is_finite().then(|| x.clamp(i32::MIN as f32, i32::MAX as f32) as i32)
}

/// `x` m/s as cm/s clamped into `i16` (0 when not finite).
fn cm_s(x: f32) -> i16 {
    if x.is_finite() {
        (x * 100.0).clamp(f32::from(i16::MIN), f32::from(i16::MAX)) as i16
    } else {
        0
    }
}

/// GLOBAL_POSITION_INT of the snapshot's local NED state around [`HOME`]; `None` when the
/// position is not finite.
pub fn global_position(time_boot_ms: u32, s: &TelemetrySnapshot) -> Option<GLOBAL_POSITION_INT_DATA> {
    let p = s.position_ned;
    let lat = HOME.0.saturating_add(to_i32(p.x * LAT_E7_PER_M)?);
    let lon = HOME.1.saturating_add(to_i32(p.y * LON_E7_PER_M)?);
    let down_mm = to_i32(p.z * 1000.0)?;
    let yaw = s.attitude_rpy.z;
    let hdg = if yaw.is_finite() {
        let deg = libm::fmodf(yaw.to_degrees(), 360.0);
        let deg = if deg < 0.0 { deg + 360.0 } else { deg };
        ((deg * 100.0) as u16).min(35_999)
    } else {
        u16::MAX
    };
    Some(GLOBAL_POSITION_INT_DATA {
        time_boot_ms,
        lat,
        lon,
        alt: HOME.2.saturating_sub(down_mm),
        relative_alt: down_mm.saturating_neg(),
        vx: cm_s(s.velocity_ned.x),
        vy: cm_s(s.velocity_ned.y),
        vz: cm_s(s.velocity_ned.z),
        hdg,
    })
}

/// HOME_POSITION: [`HOME`] at the local origin.
pub fn home_position(time_usec: u64) -> HOME_POSITION_DATA {
    HOME_POSITION_DATA {
        latitude: HOME.0,
        longitude: HOME.1,
        altitude: HOME.2,
        q: [1.0, 0.0, 0.0, 0.0],
        time_usec,
        ..Default::default()
    }
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

impl Services {
    /// Every stream at its default rate, due at once.
    pub const fn new() -> Self {
        Self {
            interval_us: [Some(STREAMS[0].1), Some(STREAMS[1].1), Some(STREAMS[2].1), Some(STREAMS[3].1)],
            next_due_us: [0; STREAMS.len()],
            requested: 0,
        }
    }

    /// MAV_CMD_SET_MESSAGE_INTERVAL: `interval_us` −1 stop, 0 default, > 0 period.
    pub fn set_interval(&mut self, msg_id: f32, interval_us: f32) -> MavResult {
        let Some(k) = msg_id_of(msg_id).and_then(slot) else { return MavResult::MAV_RESULT_UNSUPPORTED };
        self.interval_us[k] = if interval_us == -1.0 {
            None
        } else if interval_us == 0.0 {
            Some(STREAMS[k].1)
        } else if interval_us.is_finite() && interval_us >= MIN_INTERVAL_US as f32 && interval_us <= 1e9 {
            Some(interval_us as u32)
        } else {
            return MavResult::MAV_RESULT_DENIED;
        };
        self.next_due_us[k] = 0;
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// MAV_CMD_REQUEST_MESSAGE for a stream served here: sent at the next poll. `false` for
    /// other ids.
    pub fn request(&mut self, msg_id: f32) -> bool {
        match msg_id_of(msg_id).and_then(slot) {
            Some(k) => {
                self.requested |= 1 << k;
                true
            }
            None => false,
        }
    }

    /// MESSAGE_INTERVAL for `msg_id` (MAV_CMD_GET_MESSAGE_INTERVAL): −1 stopped, 0 not
    /// available (not served here).
    pub fn message_interval(&self, msg_id: f32) -> MESSAGE_INTERVAL_DATA {
        let id = msg_id_of(msg_id);
        let interval_us = match id.and_then(slot) {
            Some(k) => self.interval_us[k].map_or(-1, |u| u.min(i32::MAX as u32) as i32),
            None => 0,
        };
        MESSAGE_INTERVAL_DATA { interval_us, message_id: id.map_or(0, |i| i.min(u32::from(u16::MAX)) as u16) }
    }

    /// Emits the streams due at `now_us` and the requested ones; at most `budget` messages
    /// (the caller's free reply slots); a stream over budget stays due.
    pub fn poll(
        &mut self,
        now_us: u64,
        s: &TelemetrySnapshot,
        mission: MissionProgress,
        budget: usize,
        mut emit: impl FnMut(Outbound),
    ) {
        let mut left = budget;
        let ms = (now_us / 1000) as u32;
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
                GLOBAL_POSITION_INT_ID => global_position(ms, s).map(Outbound::GlobalPositionInt),
                MISSION_CURRENT_ID => Some(Outbound::MissionCurrent(MISSION_CURRENT_DATA {
                    seq: mission.seq,
                    total: mission.total,
                    ..Default::default()
                })),
                _ => Some(Outbound::HomePosition(home_position(now_us))),
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
        s.poll(t, snap, MissionProgress { seq: 1, total: 3 }, budget, |m| {
            out.push(match m {
                Outbound::SystemTime(_) => 2,
                Outbound::GlobalPositionInt(_) => 33,
                Outbound::MissionCurrent(_) => 42,
                Outbound::HomePosition(_) => 242,
                _ => 0,
            })
        });
        out
    }

    #[test]
    fn global_position_is_the_local_position_around_home() {
        // 100 m north, 50 m east, 10 m up, heading west (-90°).
        let g = global_position(5, &snap(Vec3::new(100.0, 50.0, -10.0), -core::f32::consts::FRAC_PI_2))
            .expect("finite");
        assert_eq!(g.lat - HOME.0, 8983, "100 m north = 8983e-7 deg");
        assert_eq!(g.lon - HOME.1, 6635, "50 m east at 47.4 N = 6635e-7 deg");
        assert_eq!((g.alt, g.relative_alt), (HOME.2 + 10_000, 10_000));
        assert_eq!((g.vx, g.vy, g.vz, g.hdg), (100, -200, 50, 27_000));
        assert!(global_position(5, &snap(Vec3::new(f32::NAN, 0.0, 0.0), 0.0)).is_none());
        assert_eq!(global_position(5, &snap(Vec3::zeros(), f32::NAN)).map(|g| g.hdg), Some(u16::MAX));
    }

    #[test]
    fn streams_follow_their_intervals_and_requests() {
        let mut s = Services::new();
        let sn = snap(Vec3::zeros(), 0.0);
        assert_eq!(ids(&mut s, 1_000_000, &sn, 8), vec![2, 33, 42, 242]);
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
        assert_eq!(s.set_interval(30.0, 20_000.0), MavResult::MAV_RESULT_UNSUPPORTED);
        assert_eq!(s.set_interval(33.5, 20_000.0), MavResult::MAV_RESULT_UNSUPPORTED);
        assert!(!s.request(148.0));
        assert_eq!(s.set_interval(33.0, 0.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(s.message_interval(33.0).interval_us, 200_000);
        assert_eq!(s.message_interval(30.0).interval_us, 0);
    }

    #[test]
    fn a_full_queue_defers_streams() {
        let mut s = Services::new();
        let sn = snap(Vec3::zeros(), 0.0);
        assert_eq!(ids(&mut s, 1_000_000, &sn, 1), vec![2]);
        assert_eq!(ids(&mut s, 1_000_001, &sn, 0), Vec::<u32>::new());
        assert_eq!(ids(&mut s, 1_000_002, &sn, 8), vec![33, 42, 242]);
    }

    #[test]
    fn ping_requests_are_answered_to_the_sender() {
        let req = PING_DATA { time_usec: 42, seq: 7, target_system: 0, target_component: 0 };
        let r = ping_reply(&req, (255, 190)).expect("a request");
        assert_eq!((r.time_usec, r.seq, r.target_system, r.target_component), (42, 7, 255, 190));
        assert!(ping_reply(&PING_DATA { target_system: 1, ..req }, (255, 190)).is_none());
    }
}
