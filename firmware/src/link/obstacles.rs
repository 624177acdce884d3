//! Obstacle points from the link → [`ObstaclePoint`]s (world NED) for the safety filter.
//!
//! ## Messages
//! - **OBSTACLE_DISTANCE_3D** (id 11037, ArduPilot dialect, used by companion computers for
//!   3-D proximity): one message per obstacle point = the closest point of one obstacle's
//!   surface to the vehicle. Fields used: `time_boot_ms` (batch key), `obstacle_id`, `x, y, z`
//!   (m) in `frame`:
//!   - `MAV_FRAME_LOCAL_NED` (1): world NED, used as is;
//!   - `MAV_FRAME_LOCAL_ENU` (4): world ENU, converted with `parapet_core::frame::enu_to_ned`;
//!   - `MAV_FRAME_BODY_FRD` (12): relative to the vehicle in body FRD, converted with the current
//!     attitude estimate: `p = p_vehicle + R_zyx(roll, pitch, yaw) · (x, y, z)`;
//!   - other frames are rejected (counted).
//!
//!   `obstacle_id` 65535 ([`CLEAR_ID`]) carries no point: it closes the previous batch and opens
//!   an empty one, i.e. "no obstacles now".
//! - **DEBUG_VECT** named `OBV<id>` (e.g. `OBV7`): velocity of obstacle `<id>` (decimal), world
//!   NED, m/s, in `x, y, z`. OBSTACLE_DISTANCE_3D has no velocity field, so a moving obstacle's
//!   velocity travels in this companion message, sent *before* the point it belongs to; it is
//!   attached to the next point with that id (and consumed). Points without one are static
//!   (`velocity: None`).
//!
//! ## Batches
//! All points with the same `time_boot_ms` form one batch (one sensor scan / one outer step). A
//! batch is handed to the cascade (`update_obstacles`, replacing the previous set) when a point
//! with a different `time_boot_ms` arrives or when [`ObstacleAssembler::flush`] is called (the
//! lockstep link flushes on HIL_SENSOR; the radio link after [`BATCH_TIMEOUT_US`] without a point).
//! Capacity: [`parapet_core::obstacle::DEFAULT_OBSTACLE_CAPACITY`] points per batch; when full the
//! points nearest the vehicle are kept (`ObstacleSet::insert_nearest`).

use heapless::Vec as HVec;
use mavlink::dialects::ardupilotmega::{MavFrame, DEBUG_VECT_DATA, OBSTACLE_DISTANCE_3D_DATA};
use parapet_core::frame::enu_to_ned;
use parapet_core::nalgebra::Rotation3;
use parapet_core::obstacle::{InsertOutcome, ObstaclePoint, ObstacleSet};
use parapet_core::Vec3;

use crate::app::autopilot::Autopilot;

/// `obstacle_id` that marks an empty batch ("no obstacles").
pub use parapet_core::wire::ids::CLEAR_ID;
/// Name prefix of the DEBUG_VECT carrying an obstacle velocity.
pub const VELOCITY_PREFIX: &[u8] = parapet_core::wire::names::OBSTACLE_VELOCITY_PREFIX.as_bytes();
/// Pending velocities kept (oldest dropped when full).
pub const MAX_PENDING_VELOCITIES: usize = 16;
/// The radio link flushes a batch this long after its last point, µs.
pub const BATCH_TIMEOUT_US: u64 = 20_000;

/// Counters of the obstacle decoder (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObstacleStats {
    /// Points stored in a batch.
    pub points: u32,
    /// Points in an unsupported frame.
    pub rejected_frame: u32,
    /// Points (or the vehicle state needed to convert them) not finite.
    pub rejected_non_finite: u32,
    /// Points dropped because the batch was full of nearer points.
    pub dropped_full: u32,
    /// Batches handed to the cascade.
    pub batches: u32,
}

/// Collects obstacle points into batches.
pub struct ObstacleAssembler {
    batch: ObstacleSet,
    batch_time_ms: Option<u32>,
    last_point_us: u64,
    velocities: HVec<(u16, Vec3), MAX_PENDING_VELOCITIES>,
    stats: ObstacleStats,
}

impl Default for ObstacleAssembler {
    fn default() -> Self {
        Self::new()
    }
}

/// Parses `OBV<decimal id>` (NUL-padded) into the id.
fn velocity_id(name: &[u8]) -> Option<u16> {
    let digits = name.strip_prefix(VELOCITY_PREFIX)?;
    let end = digits.iter().position(|&b| b == 0).unwrap_or(digits.len());
    let digits = digits.get(..end)?;
    if digits.is_empty() || digits.len() > 5 {
        return None;
    }
    let mut v: u32 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        v = v * 10 + u32::from(d - b'0');
    }
    u16::try_from(v).ok()
}

impl ObstacleAssembler {
    /// Empty, no batch open.
    pub const fn new() -> Self {
        Self {
            batch: ObstacleSet::new(),
            batch_time_ms: None,
            last_point_us: 0,
            velocities: HVec::new(),
            stats: ObstacleStats {
                points: 0,
                rejected_frame: 0,
                rejected_non_finite: 0,
                dropped_full: 0,
                batches: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> ObstacleStats {
        self.stats
    }

    /// DEBUG_VECT: stores an `OBV<id>` velocity; returns `false` for other names.
    pub fn on_debug_vect(&mut self, msg: &DEBUG_VECT_DATA) -> bool {
        let Some(id) = velocity_id(&msg.name[..]) else {
            return false;
        };
        let v = Vec3::new(msg.x, msg.y, msg.z);
        if let Some(slot) = self.velocities.iter_mut().find(|(i, _)| *i == id) {
            slot.1 = v;
        } else {
            if self.velocities.is_full() {
                self.velocities.remove(0);
            }
            // Cannot fail: a slot was freed above.
            let _ = self.velocities.push((id, v));
        }
        true
    }

    /// OBSTACLE_DISTANCE_3D at `now_us`: adds the point to its batch (closing the previous
    /// batch first when `time_boot_ms` changed).
    pub fn on_point<A: Autopilot>(&mut self, msg: &OBSTACLE_DISTANCE_3D_DATA, now_us: u64, ap: &mut A) {
        if self.batch_time_ms.is_some_and(|t| t != msg.time_boot_ms) {
            self.flush(now_us, ap);
        }
        self.batch_time_ms = Some(msg.time_boot_ms);
        self.last_point_us = now_us;
        if msg.obstacle_id == CLEAR_ID {
            return;
        }
        let tel = ap.telemetry();
        let raw = Vec3::new(msg.x, msg.y, msg.z);
        let point = match msg.frame {
            MavFrame::MAV_FRAME_LOCAL_NED => raw,
            MavFrame::MAV_FRAME_LOCAL_ENU => enu_to_ned(raw),
            MavFrame::MAV_FRAME_BODY_FRD => {
                let a = tel.attitude_rpy;
                tel.position_ned + Rotation3::from_euler_angles(a.x, a.y, a.z) * raw
            }
            _ => {
                self.stats.rejected_frame = self.stats.rejected_frame.saturating_add(1);
                return;
            }
        };
        let velocity = self
            .velocities
            .iter()
            .position(|(i, _)| *i == msg.obstacle_id)
            .map(|k| self.velocities.remove(k).1);
        let p = ObstaclePoint { point, velocity, id: msg.obstacle_id };
        match self.batch.insert_nearest(&tel.position_ned, p) {
            InsertOutcome::Added | InsertOutcome::ReplacedFarthest => {
                self.stats.points = self.stats.points.saturating_add(1)
            }
            InsertOutcome::DroppedFarther => {
                self.stats.dropped_full = self.stats.dropped_full.saturating_add(1)
            }
            InsertOutcome::RejectedNonFinite => {
                self.stats.rejected_non_finite = self.stats.rejected_non_finite.saturating_add(1)
            }
        }
    }

    /// Hands the open batch (if any) to the cascade and closes it.
    pub fn flush<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        if self.batch_time_ms.take().is_some() {
            ap.update_obstacles(now_us, self.batch.as_slice());
            self.batch.clear();
            self.stats.batches = self.stats.batches.saturating_add(1);
        }
    }

    /// Flushes a batch whose last point is older than [`BATCH_TIMEOUT_US`].
    pub fn poll<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        if self.batch_time_ms.is_some() && now_us.saturating_sub(self.last_point_us) >= BATCH_TIMEOUT_US {
            self.flush(now_us, ap);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;

    fn pt(t: u32, id: u16, frame: MavFrame, x: f32, y: f32, z: f32) -> OBSTACLE_DISTANCE_3D_DATA {
        OBSTACLE_DISTANCE_3D_DATA { time_boot_ms: t, x, y, z, obstacle_id: id, frame, ..Default::default() }
    }

    fn vel(id: u16, v: [f32; 3]) -> DEBUG_VECT_DATA {
        let mut name = [0u8; 10];
        let s = std::format!("OBV{id}");
        name[..s.len()].copy_from_slice(s.as_bytes());
        DEBUG_VECT_DATA { time_usec: 0, x: v[0], y: v[1], z: v[2], name: name.into() }
    }

    #[test]
    fn batches_close_on_new_time_and_on_flush() {
        let mut ap = RecordingAutopilot::new();
        let mut a = ObstacleAssembler::new();
        a.on_point(&pt(10, 1, MavFrame::MAV_FRAME_LOCAL_NED, 1.0, 2.0, -1.0), 0, &mut ap);
        a.on_point(&pt(10, 2, MavFrame::MAV_FRAME_LOCAL_NED, 3.0, 2.0, -1.0), 0, &mut ap);
        assert!(ap.obstacle_batches.is_empty());
        a.on_point(&pt(20, 1, MavFrame::MAV_FRAME_LOCAL_NED, 1.5, 2.0, -1.0), 0, &mut ap);
        assert_eq!(ap.obstacle_batches.len(), 1);
        assert_eq!(ap.obstacle_batches[0].len(), 2);
        a.flush(0, &mut ap);
        assert_eq!(ap.obstacle_batches.len(), 2);
        assert_eq!(ap.obstacle_batches[1][0].point, Vec3::new(1.5, 2.0, -1.0));
        a.flush(0, &mut ap); // nothing open: no empty batch
        assert_eq!(ap.obstacle_batches.len(), 2);
        a.on_point(&pt(30, CLEAR_ID, MavFrame::MAV_FRAME_LOCAL_NED, 0.0, 0.0, 0.0), 0, &mut ap);
        a.poll(BATCH_TIMEOUT_US, &mut ap);
        assert_eq!(ap.obstacle_batches.len(), 3);
        assert!(ap.obstacle_batches[2].is_empty());
    }

    #[test]
    fn frames_are_converted_to_world_ned() {
        // Test double: position (1, 2, -3), attitude roll 0.1, pitch -0.2, yaw 0.3.
        let mut ap = RecordingAutopilot::new();
        let mut a = ObstacleAssembler::new();
        a.on_point(&pt(1, 1, MavFrame::MAV_FRAME_LOCAL_ENU, 1.0, 2.0, 3.0), 0, &mut ap);
        a.on_point(&pt(1, 2, MavFrame::MAV_FRAME_BODY_FRD, 1.0, 0.0, 0.0), 0, &mut ap);
        a.on_point(&pt(1, 3, MavFrame::MAV_FRAME_GLOBAL, 1.0, 0.0, 0.0), 0, &mut ap);
        a.on_point(&pt(1, 4, MavFrame::MAV_FRAME_LOCAL_NED, f32::NAN, 0.0, 0.0), 0, &mut ap);
        a.flush(0, &mut ap);
        let b = &ap.obstacle_batches[0];
        assert_eq!(b.len(), 2);
        assert_eq!(b[0].point, Vec3::new(2.0, 1.0, -3.0));
        // Body x axis in NED for (roll, pitch, yaw) = (0.1, −0.2, 0.3): (cψcθ, sψcθ, −sθ).
        let (th, psi) = (-0.2f32, 0.3f32);
        let fwd = Vec3::new(psi.cos() * th.cos(), psi.sin() * th.cos(), -th.sin());
        assert!((b[1].point - (Vec3::new(1.0, 2.0, -3.0) + fwd)).norm() < 1e-5);
        assert_eq!(a.stats().rejected_frame, 1);
        assert_eq!(a.stats().rejected_non_finite, 1);
    }

    #[test]
    fn velocity_companion_attaches_to_its_obstacle_once() {
        let mut ap = RecordingAutopilot::new();
        let mut a = ObstacleAssembler::new();
        assert!(a.on_debug_vect(&vel(7, [0.3, -0.1, 0.0])));
        let mut other = vel(7, [0.0; 3]);
        other.name = (*b"CBF\0\0\0\0\0\0\0").into();
        assert!(!a.on_debug_vect(&other));
        a.on_point(&pt(1, 7, MavFrame::MAV_FRAME_LOCAL_NED, 1.0, 0.0, 0.0), 0, &mut ap);
        a.on_point(&pt(1, 8, MavFrame::MAV_FRAME_LOCAL_NED, 2.0, 0.0, 0.0), 0, &mut ap);
        a.on_point(&pt(2, 7, MavFrame::MAV_FRAME_LOCAL_NED, 1.0, 0.0, 0.0), 0, &mut ap);
        a.flush(0, &mut ap);
        assert_eq!(ap.obstacle_batches[0][0].velocity, Some(Vec3::new(0.3, -0.1, 0.0)));
        assert_eq!(ap.obstacle_batches[0][1].velocity, None);
        assert_eq!(ap.obstacle_batches[1][0].velocity, None);
    }

    #[test]
    fn velocity_names() {
        assert_eq!(velocity_id(b"OBV12\0\0\0\0\0"), Some(12));
        assert_eq!(velocity_id(b"OBV65535\0\0"), Some(65535));
        assert_eq!(velocity_id(b"OBV65536\0\0"), None);
        assert_eq!(velocity_id(b"OBV\0\0\0\0\0\0\0"), None);
        assert_eq!(velocity_id(b"OBVx\0\0\0\0\0\0"), None);
        assert_eq!(velocity_id(b"OBV1234567"), None);
    }
}
