//! Obstacle points from the link → [`ObstaclePoint`]s (world NED) for the safety filter.
//!
//! ## Messages
//! - **OBSTACLE_DISTANCE_3D** (id 11037, ArduPilot dialect, used by companion computers for
//!   3-D proximity): one message per obstacle point = the closest point of one obstacle's
//!   surface to the vehicle. Fields used: `time_boot_ms` (batch key), `obstacle_id`, `x, y, z`
//!   (m) in `frame`:
//!   - `MAV_FRAME_LOCAL_NED` (1): world NED, used as is;
//!   - `MAV_FRAME_LOCAL_ENU` (4): world ENU, converted with `parapet_core::frame::enu_to_ned`;
//!
//!     both world frames are **mapped** obstacles: while the vehicle flies its navigation
//!     filter's estimate (a GPS or vision source) each such point is moved towards the estimate
//!     by the filter's error bound along its direction
//!     (`parapet_core::nav::bound::ErrorBound::shift_mapped`, `docs/filter.md` § 18, as the
//!     host does), so the barrier sees it no farther than it truly is; with motion capture
//!     (no filtered source) it is used as sent;
//!   - `MAV_FRAME_BODY_FRD` (12): relative to the vehicle in body FRD, converted with the current
//!     attitude estimate: `p = p_vehicle + R_zyx(roll, pitch, yaw) · (x, y, z)` (sensed: placed
//!     around the estimate, so no margin);
//!   - other frames are rejected (counted).
//!
//!   `obstacle_id` 65535 ([`CLEAR_ID`]) is "unknown id" per the message definition: a valid
//!   point (issue 19; it used to mean "no obstacles"). The message that carries **no point**
//!   and closes the previous batch, opening an empty one ("no obstacles now"), is the one with
//!   an empty range, `min_distance > max_distance`
//!   ([`parapet_core::wire::ids::EMPTY_BATCH_RANGE`]; the host PIL sends (1, 0)).
//! - **DEBUG_VECT** named `OBV<id>` (e.g. `OBV7`): velocity of obstacle `<id>` (decimal), world
//!   NED, m/s, in `x, y, z`. OBSTACLE_DISTANCE_3D has no velocity field, so a moving obstacle's
//!   velocity travels in this companion message, sent *before* the point it belongs to; it is
//!   attached to the next point with that id (and consumed). Points without one are static
//!   (`velocity: None`).
//!
//! - **OBSTACLE_DISTANCE** (id 330, PX4 / ArduPilot proximity, e.g. a 2-D lidar or a companion's
//!   depth-image sectors): `distances[72]` (cm) in sectors of `increment_f` degrees (or the
//!   integer `increment` when `increment_f` is 0) from `angle_offset` (degrees, positive
//!   clockwise seen from above), at most `360 / increment` sectors used; a distance of
//!   `UINT16_MAX` is unknown, `> max_distance` (the standard `max_distance + 1`) is free up to
//!   `max_distance`, `< min_distance` unknown, else a return. `frame`: `MAV_FRAME_GLOBAL` (0, the
//!   default) and `MAV_FRAME_LOCAL_NED` are north aligned, `MAV_FRAME_BODY_FRD` is aligned with
//!   the vehicle heading (as PX4: the sectors are horizontal, roll and pitch are not applied);
//!   other frames are rejected. The sectors are one scan row of vertical width
//!   [`SECTOR_VERTICAL_WIDTH`] for the obstacle memory.
//! - **DISTANCE_SENSOR** (id 132): one beam; `orientation` `MAV_SENSOR_ROTATION_NONE …
//!   YAW_315` (horizontal, every 45°), `PITCH_90` (up), `PITCH_270` (down) or `CUSTOM` with
//!   `quaternion` (sensor → body); beam width `horizontal_fov` × `vertical_fov` (rad, or
//!   [`DEFAULT_BEAM_WIDTH`] when 0); `current_distance > max_distance` is free, `signal_quality`
//!   1 (invalid) unknown; `covariance` (cm², 255 / 0 unknown) makes the return conservative by
//!   two standard deviations (`r − 2σ`). Applied with the full attitude estimate.
//!
//!   Both feed the **obstacle memory** (`parapet_core::perception`, [`MEMORY_CAPACITY`] cells;
//!   QEMU board and host builds only, see [`MEMORY_ENABLED`],
//!   its `PCP_*` parameters read at every scan) with the vehicle's current estimate as the pose
//!   (the sensors' latency is not compensated); after every scan the memory's points, ranked
//!   by the controller's policy, replace the cascade's obstacle set (so a sensor that stops
//!   makes the obstacle data stale: the failsafe). A companion should send either these or
//!   OBSTACLE_DISTANCE_3D batches: each replaces the set.
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

use crate::link::dialect::{MavFrame, DEBUG_VECT_DATA, OBSTACLE_DISTANCE_3D_DATA};
use heapless::Vec as HVec;
use parapet_core::frame::{enu_to_ned, rotation_from_euler};
use parapet_core::nalgebra::{Quaternion, UnitQuaternion};
use parapet_core::obstacle::{ObstaclePoint, DEFAULT_OBSTACLE_CAPACITY};
use parapet_core::obstacle_set::{Offer, Ranking, Selector};
use parapet_core::perception::{MemoryParams, Pose, Range, Scan, ScanGeometry, SensorMount};
use parapet_core::safety::cbf::FilterVariant;
use parapet_core::wire::ids::is_empty_batch;
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
/// Whether this build feeds OBSTACLE_DISTANCE / DISTANCE_SENSOR into the obstacle memory: the
/// QEMU board (processor-in-the-loop) and the host tests. The STM32F405 image leaves it out for
/// now: the memory adds ≈ 14 KB of flash (`cargo xtask size`, 2026-12-02: 133 120 → 147 464 B)
/// and the image is already at its 128 KiB budget; there both messages are counted as
/// [`ObstacleStats::rejected_scans`].
pub const MEMORY_ENABLED: bool = cfg!(any(test, feature = "board-qemu"));
/// Cells of the firmware's obstacle memory (48 B each; 1 when [`MEMORY_ENABLED`] is off).
pub const MEMORY_CAPACITY: usize = if MEMORY_ENABLED { 64 } else { 1 };

/// The obstacle memory the firmware holds: the core's where [`MEMORY_ENABLED`]; on the flight
/// boards a stand-in that holds nothing ([`NoMemory`]), so that the memory's fixed parts
/// (tracker, frontier, free-cell map) take no RAM there.
#[cfg(any(test, feature = "board-qemu"))]
pub type Memory = parapet_core::perception::ObstacleMemory<MEMORY_CAPACITY>;
/// See the QEMU / test definition.
#[cfg(not(any(test, feature = "board-qemu")))]
pub type Memory = NoMemory;

/// The memory of a board without one ([`MEMORY_ENABLED`] off). Never reached there (every
/// entry point returns first); if it were, a scan is rejected and a selection is empty.
#[cfg(not(any(test, feature = "board-qemu")))]
pub struct NoMemory;

#[cfg(not(any(test, feature = "board-qemu")))]
impl NoMemory {
    /// The stand-in.
    pub const fn empty() -> Self {
        NoMemory
    }

    /// Takes no parameters.
    pub fn set_params(&mut self, _params: MemoryParams) -> bool {
        false
    }

    /// Rejects every scan.
    pub fn insert_scan(&mut self, _scan: &Scan) -> parapet_core::perception::ScanReport {
        parapet_core::perception::ScanReport { rejected: true, ..Default::default() }
    }

    /// Selects nothing.
    pub fn select_set<const M: usize>(
        &mut self,
        _t_us: u64,
        _p: &Vec3,
        _v: &Vec3,
        _ranking: Ranking,
        _delta1: f32,
    ) -> parapet_core::obstacle::ObstacleSet<M> {
        parapet_core::obstacle::ObstacleSet::new()
    }
}
/// Between range scans the memory's points are re-selected this often for where the vehicle
/// is now, µs (the outer loop's period).
pub const REFRESH_PERIOD_US: u64 = 4_000;
/// ... only while the last scan is at most this old, µs (a sensor down to 7 Hz; past it the
/// set ages and the obstacle-stale failsafe follows its timeout).
pub const REFRESH_WINDOW_US: u64 = 150_000;
/// Vertical width given to the OBSTACLE_DISTANCE sectors (10°), rad: a memory cell is
/// tested against a sector for see-through clearing only within ±5° of its plane.
pub const SECTOR_VERTICAL_WIDTH: f32 = 0.1745;
/// Beam width of a DISTANCE_SENSOR that reports no field of view (3°), rad.
pub const DEFAULT_BEAM_WIDTH: f32 = 0.05236;

/// `MAV_FRAME_GLOBAL`, `MAV_FRAME_LOCAL_NED`, `MAV_FRAME_BODY_FRD` codes.
const FRAME_GLOBAL: u8 = 0;
const FRAME_LOCAL_NED: u8 = 1;
const FRAME_BODY_FRD: u8 = 12;

/// Little-endian field readers over a payload zero-extended to `N` bytes (MAVLink 2 trims
/// trailing zeros).
struct Payload<const N: usize>([u8; N]);

impl<const N: usize> Payload<N> {
    fn new(p: &[u8]) -> Self {
        let mut b = [0u8; N];
        for (d, s) in b.iter_mut().zip(p.iter()) {
            *d = *s;
        }
        Payload(b)
    }
    fn u8(&self, at: usize) -> u8 {
        self.0.get(at).copied().unwrap_or(0)
    }
    fn u16(&self, at: usize) -> u16 {
        u16::from_le_bytes([self.u8(at), self.u8(at + 1)])
    }
    fn f32(&self, at: usize) -> f32 {
        f32::from_le_bytes([self.u8(at), self.u8(at + 1), self.u8(at + 2), self.u8(at + 3)])
    }
}

/// OBSTACLE_DISTANCE (id 330) with its MAVLink 2 extension fields, decoded by hand from the
/// payload (the wire layout of the message definition), so the firmware does not need the
/// `mavlink` crate's extension feature (which pulls std crates into the target build).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObstacleDistance {
    /// Distances, cm (`UINT16_MAX` unknown, `> max_distance` nothing within range).
    pub distances: [u16; 72],
    /// Minimum distance the sensor can measure, cm.
    pub min_distance: u16,
    /// Maximum distance, cm.
    pub max_distance: u16,
    /// Sector width, integer degrees (used when `increment_f` is 0).
    pub increment: u8,
    /// Sector width, degrees (extension).
    pub increment_f: f32,
    /// Angle of sector 0, degrees, positive clockwise (extension).
    pub angle_offset: f32,
    /// `MAV_FRAME` code (extension; 0 = `MAV_FRAME_GLOBAL`, north aligned).
    pub frame: u8,
}

impl ObstacleDistance {
    /// Payload length with the extensions.
    pub const LEN: usize = 167;

    /// Decodes a (possibly trimmed) payload.
    pub fn parse(p: &[u8]) -> Self {
        let b = Payload::<{ Self::LEN }>::new(p);
        let mut distances = [0u16; 72];
        for (i, d) in distances.iter_mut().enumerate() {
            *d = b.u16(8 + 2 * i);
        }
        ObstacleDistance {
            distances,
            min_distance: b.u16(152),
            max_distance: b.u16(154),
            increment: b.u8(157),
            increment_f: b.f32(158),
            angle_offset: b.f32(162),
            frame: b.u8(166),
        }
    }

    /// The payload (tests and senders; `time_usec` and `sensor_type` 0).
    pub fn to_payload(&self) -> [u8; Self::LEN] {
        let mut b = [0u8; Self::LEN];
        for (i, d) in self.distances.iter().enumerate() {
            if let Some(s) = b.get_mut(8 + 2 * i..10 + 2 * i) {
                s.copy_from_slice(&d.to_le_bytes());
            }
        }
        let mut put = |at: usize, v: &[u8]| {
            if let Some(s) = b.get_mut(at..at + v.len()) {
                s.copy_from_slice(v);
            }
        };
        put(152, &self.min_distance.to_le_bytes());
        put(154, &self.max_distance.to_le_bytes());
        put(157, &[self.increment]);
        put(158, &self.increment_f.to_le_bytes());
        put(162, &self.angle_offset.to_le_bytes());
        put(166, &[self.frame]);
        b
    }
}

/// DISTANCE_SENSOR (id 132) with its extension fields, decoded by hand like [`ObstacleDistance`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistanceSensor {
    /// Minimum distance, cm.
    pub min_distance: u16,
    /// Maximum distance, cm.
    pub max_distance: u16,
    /// Measured distance, cm.
    pub current_distance: u16,
    /// `MAV_SENSOR_ORIENTATION` code.
    pub orientation: u8,
    /// Measurement variance, cm² (`UINT8_MAX` unknown).
    pub covariance: u8,
    /// Horizontal field of view, rad (extension; 0 unknown).
    pub horizontal_fov: f32,
    /// Vertical field of view, rad (extension; 0 unknown).
    pub vertical_fov: f32,
    /// Sensor → body quaternion `w, x, y, z` for orientation `CUSTOM` (extension).
    pub quaternion: [f32; 4],
    /// 0 unknown, 1 invalid, 100 perfect (extension).
    pub signal_quality: u8,
}

impl DistanceSensor {
    /// Payload length with the extensions.
    pub const LEN: usize = 39;

    /// Decodes a (possibly trimmed) payload.
    pub fn parse(p: &[u8]) -> Self {
        let b = Payload::<{ Self::LEN }>::new(p);
        DistanceSensor {
            min_distance: b.u16(4),
            max_distance: b.u16(6),
            current_distance: b.u16(8),
            orientation: b.u8(12),
            covariance: b.u8(13),
            horizontal_fov: b.f32(14),
            vertical_fov: b.f32(18),
            quaternion: [b.f32(22), b.f32(26), b.f32(30), b.f32(34)],
            signal_quality: b.u8(38),
        }
    }
}

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
    /// OBSTACLE_DISTANCE / DISTANCE_SENSOR scans put into the memory.
    pub scans: u32,
    /// Scans rejected (bad increment, range, frame, orientation or pose).
    pub rejected_scans: u32,
}

/// Collects obstacle points into batches.
pub struct ObstacleAssembler {
    /// The open batch's selection (`None`: no batch open).
    batch: Option<Selector<DEFAULT_OBSTACLE_CAPACITY>>,
    batch_time_ms: Option<u32>,
    last_point_us: u64,
    velocities: HVec<(u16, Vec3), MAX_PENDING_VELOCITIES>,
    memory: Memory,
    /// Firmware time of the last scan the memory took, and of the last selection from it.
    last_scan_us: Option<u64>,
    last_select_us: u64,
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
            memory: Memory::empty(),
            last_scan_us: None,
            last_select_us: 0,
            stats: ObstacleStats {
                points: 0,
                rejected_frame: 0,
                rejected_non_finite: 0,
                dropped_full: 0,
                dropped_near: 0,
                batches: 0,
                scans: 0,
                rejected_scans: 0,
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
        if is_empty_batch(msg.min_distance, msg.max_distance) {
            return;
        }
        let raw = Vec3::new(msg.x, msg.y, msg.z);
        // A mapped point: the margin of the estimate's error bound (module docs).
        let margin = ap.mapped_margin();
        let mapped = |q: Vec3| match margin {
            Some(b) => b.shift_mapped(&q, &tel.position_ned),
            None => q,
        };
        let point = match msg.frame {
            MavFrame::MAV_FRAME_LOCAL_NED => mapped(raw),
            MavFrame::MAV_FRAME_LOCAL_ENU => mapped(enu_to_ned(raw)),
            MavFrame::MAV_FRAME_BODY_FRD => {
                let a = tel.attitude_rpy;
                tel.position_ned + rotation_from_euler(a.x, a.y, a.z) * raw
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
        let p = ObstaclePoint { point, velocity, id: msg.obstacle_id, normal: None };
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

    /// The obstacle memory (diagnostics, tests).
    pub fn memory(&self) -> &Memory {
        &self.memory
    }

    fn reject_scan(&mut self) {
        self.stats.rejected_scans = self.stats.rejected_scans.saturating_add(1);
    }

    /// Puts one scan into the memory and replaces the cascade's obstacle set with the memory's
    /// points (ranked by the controller's policy).
    fn feed<A: Autopilot>(
        &mut self,
        now_us: u64,
        pose: Pose,
        mount: SensorMount,
        g: ScanGeometry,
        ranges: &[Range],
        ap: &mut A,
    ) {
        let d = MemoryParams::DEFAULT;
        let get = |n: &str, v: f32| ap.get_param(n).unwrap_or(v);
        let params = MemoryParams {
            voxel: get("PCP_VOXEL", d.voxel),
            forget_s: get("PCP_FORGET", d.forget_s),
            keep_near: get("PCP_KEEP_NEAR", d.keep_near),
            clear_margin: get("PCP_CLR_MARGIN", d.clear_margin),
            track_size: get("PCP_TRK_SIZE", d.track_size),
            fov_margin: get("PCP_FOV_MARGIN", d.fov_margin),
            fov_walls: get("PCP_FOV_WALLS", f32::from(d.fov_walls)) as u8,
            ground_height: get("GND_HEIGHT", d.ground_height),
            ..d
        }
        .with_heading_held(get("MIS_YAW_MODE", 0.0) == 0.0);
        // Out-of-range values (not possible through PARAM_SET) keep the previous parameters.
        self.memory.set_params(params);
        let scan = Scan { t_us: now_us, pose, mount, geometry: g, ranges };
        if self.memory.insert_scan(&scan).rejected {
            self.reject_scan();
            return;
        }
        self.stats.scans = self.stats.scans.saturating_add(1);
        self.last_scan_us = Some(now_us);
        self.select(now_us, ap);
    }

    /// The memory's most critical points for the vehicle's current position and velocity
    /// (moving tracks extrapolated to `now_us`) replace the cascade's obstacle set.
    fn select<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        let tel = ap.telemetry();
        let (ranking, delta1) = ranking_of(ap);
        let set = self.memory.select_set::<DEFAULT_OBSTACLE_CAPACITY>(
            now_us,
            &tel.position_ned,
            &tel.velocity_ned,
            ranking,
            delta1,
        );
        ap.update_obstacles(now_us, set.as_slice());
        self.last_select_us = now_us;
    }

    /// Between scans: the memory's points re-selected every [`REFRESH_PERIOD_US`] for where the
    /// vehicle is now, as the host's memory does every outer step (a point selected at the scan
    /// is a box point nearest to where the vehicle was then, and a moving track's point where
    /// the obstacle was then: held for a 100 ms scan period, a chaser at 1 m/s is 10 cm closer
    /// than the filter's point — measured: `sphere_overtaking` in PIL collided in 5 of 5 seeds
    /// with the set held, `docs/perception.md`). Only while the last scan is at most
    /// [`REFRESH_WINDOW_US`] old: a sensor that stops still makes the obstacle data stale (the
    /// failsafe's obstacle timeout then runs from the last refresh).
    fn refresh<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        if !MEMORY_ENABLED {
            return;
        }
        let Some(last) = self.last_scan_us else { return };
        if now_us.saturating_sub(last) <= REFRESH_WINDOW_US
            && now_us.saturating_sub(self.last_select_us) >= REFRESH_PERIOD_US
        {
            self.select(now_us, ap);
        }
    }

    /// OBSTACLE_DISTANCE at `now_us` (see the module documentation).
    pub fn on_obstacle_distance<A: Autopilot>(&mut self, msg: &ObstacleDistance, now_us: u64, ap: &mut A) {
        if !MEMORY_ENABLED {
            self.reject_scan();
            return;
        }
        let inc = if msg.increment_f > 0.0 { msg.increment_f } else { f32::from(msg.increment) };
        let (min, max) = (f32::from(msg.min_distance) * 0.01, f32::from(msg.max_distance) * 0.01);
        if !(inc > 0.0 && inc <= 360.0 && msg.angle_offset.is_finite() && max > min) {
            self.reject_scan();
            return;
        }
        let tel = ap.telemetry();
        let yaw = match msg.frame {
            FRAME_GLOBAL | FRAME_LOCAL_NED => 0.0,
            FRAME_BODY_FRD => tel.attitude_rpy.z,
            _ => {
                self.reject_scan();
                return;
            }
        };
        let n = ((360.0 / inc) as usize).clamp(1, msg.distances.len());
        let mut ranges = [Range::Unknown; 72];
        for (r, &d) in ranges.iter_mut().zip(msg.distances.iter()).take(n) {
            *r = if d == u16::MAX || d < msg.min_distance {
                Range::Unknown
            } else if d > msg.max_distance {
                Range::Clear
            } else {
                Range::Hit(f32::from(d) * 0.01)
            };
        }
        let g = ScanGeometry {
            az0: msg.angle_offset.to_radians(),
            daz: inc.to_radians(),
            n_az: n as u16,
            el0: 0.0,
            del: SECTOR_VERTICAL_WIDTH,
            n_el: 1,
            min_range: min,
            // A distance equal to max_distance is a return; above it, free.
            max_range: max + 0.005,
        };
        let pose = Pose::from_rpy(tel.position_ned, 0.0, 0.0, yaw);
        self.feed(now_us, pose, SensorMount::centered(), g, ranges.get(..n).unwrap_or(&[]), ap);
    }

    /// DISTANCE_SENSOR at `now_us` (see the module documentation).
    pub fn on_distance_sensor<A: Autopilot>(&mut self, msg: &DistanceSensor, now_us: u64, ap: &mut A) {
        if !MEMORY_ENABLED {
            self.reject_scan();
            return;
        }
        let (min, max) = (f32::from(msg.min_distance) * 0.01, f32::from(msg.max_distance) * 0.01);
        let o = msg.orientation;
        let mount = match o {
            0..=7 => SensorMount::new(Vec3::zeros(), 0.0, 0.0, f32::from(o) * core::f32::consts::FRAC_PI_4),
            24 => SensorMount::new(Vec3::zeros(), 0.0, core::f32::consts::FRAC_PI_2, 0.0),
            25 => SensorMount::new(Vec3::zeros(), 0.0, -core::f32::consts::FRAC_PI_2, 0.0),
            100 => {
                let [w, x, y, z] = msg.quaternion;
                let q = Quaternion::new(w, x, y, z);
                let n = q.norm();
                if !(n.is_finite() && n > 0.5) {
                    self.reject_scan();
                    return;
                }
                let rotation = *UnitQuaternion::from_quaternion(q).to_rotation_matrix().matrix();
                SensorMount { position: Vec3::zeros(), rotation }
            }
            _ => {
                self.reject_scan();
                return;
            }
        };
        if max <= min {
            self.reject_scan();
            return;
        }
        let fov = |x: f32| if x.is_finite() && x > 0.0 && x < 3.0 { x } else { DEFAULT_BEAM_WIDTH };
        let g = ScanGeometry::grid(1, 1, fov(msg.horizontal_fov), fov(msg.vertical_fov), min, max + 0.005);
        let sigma = if msg.covariance == 0 || msg.covariance == u8::MAX {
            0.0
        } else {
            parapet_core::fmath::sqrtf(f32::from(msg.covariance)) * 0.01
        };
        let d = msg.current_distance;
        let range = if msg.signal_quality == 1 || d < msg.min_distance {
            Range::Unknown
        } else if d > msg.max_distance {
            Range::Clear
        } else {
            let r = f32::from(d) * 0.01 - 2.0 * sigma;
            Range::Hit(if r > min { r } else { min })
        };
        let tel = ap.telemetry();
        let a = tel.attitude_rpy;
        let pose = Pose::from_rpy(tel.position_ned, a.x, a.y, a.z);
        self.feed(now_us, pose, mount, g, &[range], ap);
    }

    /// Hands the open batch (if any) to the cascade and closes it; between range scans the
    /// memory's points are refreshed (see `refresh`).
    pub fn flush<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        if self.batch_time_ms.take().is_some() {
            let points = self.batch.take().map(Selector::finish);
            ap.update_obstacles(now_us, points.as_ref().map_or(&[][..], |(set, _)| set.as_slice()));
            self.stats.batches = self.stats.batches.saturating_add(1);
        }
        self.refresh(now_us, ap);
    }

    /// Flushes a batch whose last point is older than [`BATCH_TIMEOUT_US`]; refreshes the
    /// memory's points between range scans.
    pub fn poll<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        if self.batch_time_ms.is_some() && now_us.saturating_sub(self.last_point_us) >= BATCH_TIMEOUT_US {
            self.flush(now_us, ap);
        } else {
            self.refresh(now_us, ap);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;
    use parapet_core::nalgebra::Rotation3;

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
        let (lo, hi) = parapet_core::wire::ids::EMPTY_BATCH_RANGE;
        let empty = OBSTACLE_DISTANCE_3D_DATA {
            min_distance: lo,
            max_distance: hi,
            ..pt(30, CLEAR_ID, MavFrame::MAV_FRAME_LOCAL_NED, 0.0, 0.0, 0.0)
        };
        a.on_point(&empty, 0, &mut ap);
        a.poll(BATCH_TIMEOUT_US, &mut ap);
        assert_eq!(ap.obstacle_batches.len(), 3);
        assert!(ap.obstacle_batches[2].is_empty());
        // Id 65535 ("unknown id") with a range is a valid point.
        a.on_point(&pt(40, CLEAR_ID, MavFrame::MAV_FRAME_LOCAL_NED, 4.0, 2.0, -3.0), 0, &mut ap);
        a.flush(0, &mut ap);
        assert_eq!(ap.obstacle_batches[3].len(), 1);
        assert_eq!(ap.obstacle_batches[3][0].point, Vec3::new(4.0, 2.0, -3.0));
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

    /// With a filtered source (the autopilot's mapped margin: the filter's error bound) the
    /// world-frame points (LOCAL_NED, LOCAL_ENU: mapped) move towards the estimate (1, 2, −3) by
    /// the bound along their direction; a BODY_FRD point (sensed, placed around the estimate)
    /// does not; without one (motion capture) nothing moves. Fails without the margin.
    #[test]
    fn mapped_points_get_the_error_bound_margin_sensed_ones_do_not() {
        use parapet_core::nav::bound::ErrorBound;
        let bound = ErrorBound { horizontal: 0.6, vertical: 0.25 };
        let est = Vec3::new(1.0, 2.0, -3.0);
        let run = |margin: Option<ErrorBound>| {
            let mut ap = RecordingAutopilot::new();
            ap.mapped_margin = margin;
            let mut a = ObstacleAssembler::new();
            a.on_point(&pt(1, 1, MavFrame::MAV_FRAME_LOCAL_NED, 3.0, 2.0, -3.0), 0, &mut ap);
            a.on_point(&pt(1, 2, MavFrame::MAV_FRAME_LOCAL_ENU, 2.0, 1.0, 2.0), 0, &mut ap);
            a.on_point(&pt(1, 3, MavFrame::MAV_FRAME_BODY_FRD, 0.0, 0.0, 1.5), 0, &mut ap);
            a.flush(0, &mut ap);
            let mut b = ap.obstacle_batches[0].clone();
            b.sort_by_key(|o| o.id);
            b.iter().map(|o| o.point).collect::<std::vec::Vec<_>>()
        };
        let mocap = run(None);
        assert_eq!(mocap[0], Vec3::new(3.0, 2.0, -3.0));
        assert_eq!(mocap[1], Vec3::new(1.0, 2.0, -2.0));
        let gps = run(Some(bound));
        // Beside: 2 m north → 1.4 m; below: 1 m down → 0.75 m.
        assert!((gps[0] - (est + Vec3::new(1.4, 0.0, 0.0))).norm() < 1e-5, "{:?}", gps[0]);
        assert!((gps[1] - (est + Vec3::new(0.0, 0.0, 0.75))).norm() < 1e-5, "{:?}", gps[1]);
        // The body point: the same with and without the filter.
        assert_eq!(gps[2], mocap[2]);
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
        use crate::link::{FixClock, Link};
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

    /// Standard OBSTACLE_DISTANCE through the whole link into the memory: one pole-like return
    /// at a known bearing and range (body FRD: relative to the heading of the test double,
    /// yaw 0.3 rad), every other sector "nothing within max_distance". The cascade gets a point
    /// within the sector resolution of the truth: |error| ≤ r·sin(increment/2) + √3·voxel.
    #[test]
    fn obstacle_distance_round_trip_places_points_within_the_sector_resolution() {
        use crate::link::frame_parser::RawFrame;
        use crate::link::{FixClock, Link, Received};
        // Through the link's decoder and dispatcher (a trimmed MAVLink 2 payload, as on the wire).
        fn send(l: &mut Link, m: &ObstacleDistance, t: u64, ap: &mut RecordingAutopilot) {
            let full = m.to_payload();
            let len = full.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
            let f = RawFrame { msg_id: 330, sys_id: 255, comp_id: 190, seq: 0, payload: &full[..len] };
            l.receive(Received::of(&f), t, ap);
        }
        let mut ap = RecordingAutopilot::new();
        for (n, v) in [("CBF_VARIANT", 3.0), ("CBF_MU", 1.4), ("CBF_DELTA1", 0.1)] {
            ap.set_param(n, v).unwrap();
        }
        let mut l = Link::new(1, FixClock::Message);
        let vehicle = Vec3::new(1.0, 2.0, -3.0);
        let yaw = 0.3f32;
        for (inc, offset, frame) in
            [(5.0f32, -2.5f32, FRAME_BODY_FRD), (10.0, 0.0, FRAME_LOCAL_NED), (2.5, 0.0, FRAME_GLOBAL)]
        {
            for (bearing_deg, r) in [(37.0f32, 2.5f32), (-120.0, 1.2), (170.0, 4.0)] {
                let mut msg = ObstacleDistance {
                    distances: [501; 72],
                    min_distance: 10,
                    max_distance: 500,
                    increment: 0,
                    increment_f: inc,
                    angle_offset: offset,
                    frame,
                };
                let full = (360.0 / inc) as usize;
                let n = full.min(72);
                for d in msg.distances.iter_mut().skip(n) {
                    *d = u16::MAX;
                }
                let sector = (((bearing_deg - offset) / inc).round() as i32).rem_euclid(full as i32) as usize;
                if sector >= n {
                    continue; // outside the sectors of this increment (2.5° × 72 = 180°)
                }
                msg.distances[sector] = (r * 100.0) as u16;
                let heading = if frame == FRAME_BODY_FRD { yaw } else { 0.0 };
                let b = bearing_deg.to_radians() + heading;
                let truth = vehicle + Vec3::new(r * b.cos(), r * b.sin(), 0.0);
                let before = ap.obstacle_batches.len();
                send(&mut l, &msg, 1_000_000, &mut ap);
                assert_eq!(ap.obstacle_batches.len(), before + 1, "a scan replaces the obstacle set");
                let pts = ap.obstacle_batches.last().unwrap();
                let best = pts
                    .iter()
                    .filter(|o| o.id != parapet_core::perception::FRONTIER_ID)
                    .map(|o| (o.point - truth).norm())
                    .fold(f32::INFINITY, f32::min);
                let bound = r * (0.5 * inc.to_radians()).sin() + 3f32.sqrt() * 0.2;
                assert!(best <= bound, "inc {inc} bearing {bearing_deg}: {best} > {bound}");
            }
        }
        assert_eq!(l.obstacle_stats().scans, 8);
        // The next scans see through the old returns (all sectors free): they are cleared.
        // Integer increment (increment_f 0), as a sender without the extensions gives it.
        let clear = ObstacleDistance {
            distances: [501; 72],
            min_distance: 10,
            max_distance: 500,
            increment: 5,
            increment_f: 0.0,
            angle_offset: 0.0,
            frame: FRAME_LOCAL_NED,
        };
        send(&mut l, &clear, 1_100_000, &mut ap);
        assert!(ap
            .obstacle_batches
            .last()
            .unwrap()
            .iter()
            .all(|o| o.id == parapet_core::perception::FRONTIER_ID));
        // Bad increment or frame: rejected, no update.
        let before = ap.obstacle_batches.len();
        let bad = ObstacleDistance { increment: 0, increment_f: 0.0, ..clear };
        send(&mut l, &bad, 1_200_000, &mut ap);
        let bad = ObstacleDistance { frame: 4, ..clear }; // MAV_FRAME_LOCAL_ENU
        send(&mut l, &bad, 1_200_000, &mut ap);
        assert_eq!(ap.obstacle_batches.len(), before);
        assert_eq!(l.obstacle_stats().rejected_scans, 2);
    }

    /// Between scans the memory's points are re-selected every outer period while the last
    /// scan is at most `REFRESH_WINDOW_US` old, then no more (the data goes stale).
    #[test]
    fn the_memory_points_are_refreshed_between_scans_within_the_window() {
        let mut ap = RecordingAutopilot::new();
        let mut a = ObstacleAssembler::new();
        let mut msg = ObstacleDistance {
            distances: [501; 72],
            min_distance: 10,
            max_distance: 500,
            increment: 5,
            increment_f: 5.0,
            angle_offset: 0.0,
            frame: FRAME_LOCAL_NED,
        };
        msg.distances[0] = 150; // 1.5 m north
        let t0 = 1_000_000;
        // Flushes before any scan refresh nothing.
        a.flush(t0 - 10_000, &mut ap);
        assert!(ap.obstacle_batches.is_empty());
        a.on_obstacle_distance(&msg, t0, &mut ap);
        assert_eq!(ap.obstacle_batches.len(), 1);
        // The lockstep flushes every 1 ms: one refresh per outer period.
        let mut t = t0;
        while t < t0 + REFRESH_WINDOW_US {
            t += 1_000;
            a.flush(t, &mut ap);
        }
        let refreshes = ap.obstacle_batches.len() - 1;
        assert_eq!(refreshes as u64, REFRESH_WINDOW_US / REFRESH_PERIOD_US, "{refreshes} refreshes");
        assert!(
            ap.obstacle_batches.iter().all(|b| b == &ap.obstacle_batches[0]),
            "same vehicle, same points"
        );
        // Past the window (the sensor stopped): nothing more, through flush or poll.
        let n = ap.obstacle_batches.len();
        for k in 1..100 {
            a.flush(t + k * 1_000, &mut ap);
            a.poll(t + k * 1_000, &mut ap);
        }
        assert_eq!(ap.obstacle_batches.len(), n);
    }

    /// DISTANCE_SENSOR: a forward-right (yaw 45°) return at 1.5 m with σ = 5 cm lands at
    /// r − 2σ = 1.4 m along the sensor axis rotated by the full attitude; free beyond max is no point.
    #[test]
    fn distance_sensor_feeds_the_memory() {
        use crate::link::dialect::{MavSensorOrientation, DISTANCE_SENSOR_DATA};
        use mavlink_core::{MavlinkVersion, MessageData};
        let mut ap = RecordingAutopilot::new();
        let mut a = ObstacleAssembler::new();
        // The crate's encoding (without the extension fields) decodes to the same message.
        let std_msg = DISTANCE_SENSOR_DATA {
            min_distance: 5,
            max_distance: 400,
            current_distance: 150,
            orientation: MavSensorOrientation::MAV_SENSOR_ROTATION_YAW_45,
            covariance: 25,
            ..Default::default()
        };
        let mut bytes = [0u8; 64];
        let n = std_msg.ser(MavlinkVersion::V2, &mut bytes);
        let msg = DistanceSensor::parse(&bytes[..n]);
        assert_eq!((msg.current_distance, msg.orientation, msg.covariance), (150, 1, 25));
        a.on_distance_sensor(&msg, 1_000, &mut ap);
        let pts = ap.obstacle_batches.last().unwrap();
        let axis = Rotation3::from_euler_angles(0.1, -0.2, 0.3) * Vec3::new(1.0, 1.0, 0.0).normalize();
        let truth = Vec3::new(1.0, 2.0, -3.0) + axis * 1.4;
        let best = pts.iter().map(|o| (o.point - truth).norm()).fold(f32::INFINITY, f32::min);
        assert!(best < 1e-3, "{best} {pts:?}");
        let bad = DistanceSensor { orientation: 8, ..msg }; // MAV_SENSOR_ROTATION_ROLL_180
        a.on_distance_sensor(&bad, 2_000, &mut ap);
        assert_eq!(a.stats().rejected_scans, 1);
        assert_eq!(a.stats().scans, 1);
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
