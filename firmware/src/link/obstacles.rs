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
//! Capacity: [`parapet_core::obstacle::DEFAULT_OBSTACLE_CAPACITY`] points per batch. Each point is
//! streamed through the controller's own set policy ([`parapet_core::obstacle_set::Selector`],
//! opened with the vehicle's position and velocity estimate when the batch opens and the ranking
//! the controller uses for the configured `CBF_VARIANT`: most critical first with the relative
//! velocity for the multi variants, nearest first for the closest-obstacle ones), so a closing
//! wall is not dropped behind nearer side points before the controller ranks them (issue 17).
//! Points the policy drops are counted in [`ObstacleStats::dropped_full`] (and `dropped_near` when
//! their barrier was within `CBF_DELTA1`).

use heapless::Vec as HVec;
use mavlink::dialects::ardupilotmega::{MavFrame, DEBUG_VECT_DATA, OBSTACLE_DISTANCE_3D_DATA};
use parapet_core::frame::enu_to_ned;
use parapet_core::nalgebra::Rotation3;
use parapet_core::obstacle::{ObstaclePoint, DEFAULT_OBSTACLE_CAPACITY};
use parapet_core::obstacle_set::{Offer, Ranking, Selector};
use parapet_core::safety::cbf::FilterVariant;
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
    /// Points dropped because the batch was full of more critical points.
    pub dropped_full: u32,
    /// Of those, points whose barrier was within `CBF_DELTA1` (the filter would have used them).
    pub dropped_near: u32,
    /// Batches handed to the cascade.
    pub batches: u32,
}

/// Collects obstacle points into batches.
pub struct ObstacleAssembler {
    /// The open batch's selection (`None`: no batch open).
    batch: Option<Selector<DEFAULT_OBSTACLE_CAPACITY>>,
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

/// The controller's ranking for the configured filter (`CBF_VARIANT`, `CBF_MU`) and its
/// `CBF_DELTA1`, as `parapet_core::outer` ranks its set; the defaults when a parameter is absent.
fn ranking_of<A: Autopilot>(ap: &A) -> (Ranking, f32) {
    let variant = match ap.get_param("CBF_VARIANT").map(|v| v as i32) {
        Some(0) => FilterVariant::Paper,
        Some(1) => FilterVariant::Relative,
        Some(2) => FilterVariant::Multi,
        _ => FilterVariant::MultiRelative,
    };
    let mu = ap.get_param("CBF_MU").unwrap_or(1.4);
    let delta1 = ap.get_param("CBF_DELTA1").unwrap_or(0.1);
    let ranking = if variant.is_multi() {
        Ranking::Critical { mu, relative: variant.uses_relative_velocity() }
    } else {
        Ranking::Nearest
    };
    (ranking, delta1)
}

impl ObstacleAssembler {
    /// Empty, no batch open.
    pub const fn new() -> Self {
        Self {
            batch: None,
            batch_time_ms: None,
            last_point_us: 0,
            velocities: HVec::new(),
            stats: ObstacleStats {
                points: 0,
                rejected_frame: 0,
                rejected_non_finite: 0,
                dropped_full: 0,
                dropped_near: 0,
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
        let tel = ap.telemetry();
        if self.batch.is_none() {
            let (ranking, delta1) = ranking_of(ap);
            self.batch = Some(Selector::new(ranking, delta1, &tel.position_ned, &tel.velocity_ned));
        }
        self.batch_time_ms = Some(msg.time_boot_ms);
        self.last_point_us = now_us;
        if msg.obstacle_id == CLEAR_ID {
            return;
        }
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
        let Some(sel) = self.batch.as_mut() else { return };
        let before = sel.report();
        let outcome = sel.offer(&p);
        let after = sel.report();
        let s = &mut self.stats;
        // A kept point may displace a less critical one: count every drop the policy made.
        s.dropped_full =
            s.dropped_full.saturating_add(u32::from(after.dropped.saturating_sub(before.dropped)));
        s.dropped_near =
            s.dropped_near.saturating_add(u32::from(after.dropped_near.saturating_sub(before.dropped_near)));
        match outcome {
            Offer::Kept => s.points = s.points.saturating_add(1),
            Offer::Dropped => {}
            Offer::Rejected => s.rejected_non_finite = s.rejected_non_finite.saturating_add(1),
        }
    }

    /// Hands the open batch (if any) to the cascade and closes it.
    pub fn flush<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        if self.batch_time_ms.take().is_some() {
            let points = self.batch.take().map(Selector::finish);
            ap.update_obstacles(now_us, points.as_ref().map_or(&[][..], |(set, _)| set.as_slice()));
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

    /// Through the whole link: 32 static points 1.8 m beside the vehicle, then one obstacle
    /// 2.5 m ahead closing at 1 m/s. Nearest-first would drop it (it is the farthest point);
    /// the controller's policy (multi-relative, μ 1.4 s: h = 6.25 − 1.4·2.5·1 = 2.75 m² <
    /// 3.24 m²) keeps it and drops a side point, and the drop is counted.
    #[test]
    fn link_keeps_a_closing_obstacle_behind_nearer_side_points() {
        use crate::link::framing::FrameWriter;
        use crate::link::router::{FixClock, Link};
        let mut ap = RecordingAutopilot::new();
        for (n, v) in [("CBF_VARIANT", 3.0), ("CBF_MU", 1.4), ("CBF_DELTA1", 0.1)] {
            ap.set_param(n, v).unwrap();
        }
        let mut l = Link::new(1, FixClock::Message);
        let mut w = FrameWriter::new(255, 190);
        let vehicle = Vec3::new(1.0, 2.0, -3.0); // the test double's position
        for k in 0..32u16 {
            let a = f32::from(k) * core::f32::consts::TAU / 32.0;
            let q = vehicle + Vec3::new(0.0, 1.8 * a.cos(), 1.8 * a.sin());
            let m = pt(7, k, MavFrame::MAV_FRAME_LOCAL_NED, q.x, q.y, q.z);
            l.push_bytes(w.encode(&m).raw_bytes(), 0, &mut ap);
        }
        l.push_bytes(w.encode(&vel(99, [-1.0, 0.0, 0.0])).raw_bytes(), 0, &mut ap);
        let wall = vehicle + Vec3::new(2.5, 0.0, 0.0);
        l.push_bytes(
            w.encode(&pt(7, 99, MavFrame::MAV_FRAME_LOCAL_NED, wall.x, wall.y, wall.z)).raw_bytes(),
            0,
            &mut ap,
        );
        l.flush_obstacles(0, &mut ap);
        let b = &ap.obstacle_batches[0];
        assert_eq!(b.len(), DEFAULT_OBSTACLE_CAPACITY);
        assert!(b.iter().any(|o| o.id == 99 && o.velocity == Some(Vec3::new(-1.0, 0.0, 0.0))));
        assert_eq!(l.obstacle_stats().dropped_full, 1);
        assert_eq!(l.obstacle_stats().dropped_near, 0);

        // The closest-obstacle variants keep the published nearest-first policy.
        ap.set_param("CBF_VARIANT", 1.0).unwrap();
        for k in 0..32u16 {
            let a = f32::from(k) * core::f32::consts::TAU / 32.0;
            let q = vehicle + Vec3::new(0.0, 1.8 * a.cos(), 1.8 * a.sin());
            l.push_bytes(
                w.encode(&pt(8, k, MavFrame::MAV_FRAME_LOCAL_NED, q.x, q.y, q.z)).raw_bytes(),
                0,
                &mut ap,
            );
        }
        l.push_bytes(
            w.encode(&pt(8, 99, MavFrame::MAV_FRAME_LOCAL_NED, wall.x, wall.y, wall.z)).raw_bytes(),
            0,
            &mut ap,
        );
        l.flush_obstacles(0, &mut ap);
        assert!(ap.obstacle_batches[1].iter().all(|o| o.id != 99));
        assert_eq!(l.obstacle_stats().dropped_full, 2);
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
