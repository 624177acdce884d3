//! Perception (issue 19): range returns → a bounded world-frame obstacle memory → the
//! obstacle points the safety filter reads.
//!
//! A range sensor (planar lidar, depth camera, multi-zone time of flight, a single distance
//! sensor, a companion computer's `OBSTACLE_DISTANCE`) delivers a [`Scan`]: a grid of beams
//! on an azimuth × elevation lattice of the sensor frame ([`ScanGeometry`]) with one
//! [`Range`] per beam, time-stamped, taken from a [`SensorMount`] on the vehicle whose
//! [`Pose`] at that time stamp the caller supplies. [`ObstacleMemory`] turns scans into
//! world-NED obstacle cells with an age ([`memory`]), tracks small moving clusters and
//! estimates their velocity ([`track`]), keeps the free range it has observed around the
//! vehicle ([`frontier`]) and hands out, for the vehicle's current position and velocity,
//! the obstacle points to offer the filter ([`ObstacleMemory::points`]): one per cell, plus
//! one virtual *frontier* point in the direction of motion when that direction has not been
//! observed free far enough ("unseen space is not free space", `docs/filter.md` § 14).
//!
//! ## Frames
//! World NED; vehicle body FRD ([`Pose`]: position and the body → world rotation);
//! sensor frame = FRD-like with x along the boresight, y right, z down ([`SensorMount`]:
//! position in the body frame and the sensor → body rotation). A beam with azimuth `a`
//! (positive to the right, i.e. about +z of the sensor) and elevation `e` (positive up)
//! points along `(cos e cos a, cos e sin a, −sin e)` in the sensor frame.
//!
//! ## Bounds
//! No allocation, no panics, every loop bounded by the memory capacity `N`, [`MAX_BEAMS`]
//! beams per scan, [`track::MAX_TRACKS`] tracks, [`frontier::SECTORS`] sectors (see
//! [`ObstacleMemory::insert_scan`] for the cost). Written by hand (no crate): a no_std,
//! fixed-capacity, bounded-time voxel store with see-through clearing is not available
//! as a well-kept crate.
//!
//! May import: `crate::obstacle` (points), `crate::fmath`, `crate::frame`, `crate::Vec3`.

mod cell_distances;
mod fov_bounds;
pub mod free_grid;
pub mod frontier;
mod key_index;
pub mod memory;
mod scan_trig;
pub mod track;

pub use memory::{CellView, MemoryStats, ObstacleMemory, ScanReport};
pub use scan_trig::{ScanTrig, TRIG_COLS, TRIG_ROWS};

use crate::param_decl::{field, u8_field, Has, Param};
use crate::Vec3;
use nalgebra::Matrix3;

/// Most beams one scan may carry (a 32 × 24 depth image, 1024 single beams); a longer scan
/// is rejected whole ([`ScanReport::rejected`]).
pub const MAX_BEAMS: usize = 1024;

/// Capacity of the memory the controller's perception uses by default (cells).
pub const DEFAULT_MEMORY_CAPACITY: usize = 128;

/// A beam counts for the free space at the flight level (the frontier's sectors, the free-cell
/// map) when its world direction is within this of horizontal, rad (15°); steeper beams count
/// for nothing there.
pub const HORIZONTAL_BAND: f32 = 0.2618;

/// Obstacle id of the virtual frontier point (unseen space ahead, see [`frontier`]).
pub const FRONTIER_ID: u16 = 65_534;
const _: () = assert!(FRONTIER_ID >= crate::obstacle::VIRTUAL_ID);

/// First obstacle id of the memory's cells: a cell's point carries `CELL_ID_BASE + slot`
/// of its track, or [`STATIC_ID`] for untracked (static) cells.
pub const CELL_ID_BASE: u16 = crate::obstacle::CLUSTER_ID_BASE;

/// Obstacle id of every untracked (static) memory cell. Cells are parts of extended
/// obstacles, so they share one id: the set policy keeps the most critical ones
/// (`crate::obstacle_set`).
pub const STATIC_ID: u16 = 59_999;

/// One beam's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// A return at this range, m (used when `min_range ≤ r < max_range`, else [`Range::Unknown`]).
    Hit(f32),
    /// No return within `max_range`: the beam is free up to `max_range` (information too).
    Clear,
    /// No information (dropout, below the minimum range, saturated): the beam neither adds
    /// nor clears anything.
    Unknown,
}

/// Where a sensor sits on the vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorMount {
    /// Sensor origin in the body frame (FRD), m.
    pub position: Vec3,
    /// Sensor frame → body frame rotation.
    pub rotation: Matrix3<f32>,
}

impl SensorMount {
    /// A sensor at `position` (body FRD, m) rotated by ZYX Euler angles `roll, pitch, yaw`
    /// (rad) from the body axes (`yaw` π/2: looking right).
    pub fn new(position: Vec3, roll: f32, pitch: f32, yaw: f32) -> Self {
        SensorMount { position, rotation: rotation_zyx(roll, pitch, yaw) }
    }

    /// At the body origin, looking forward.
    pub fn centered() -> Self {
        SensorMount { position: Vec3::zeros(), rotation: Matrix3::identity() }
    }
}

/// The vehicle pose at a scan's time stamp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Position, NED, m.
    pub position: Vec3,
    /// Body (FRD) → world (NED) rotation.
    pub rotation: Matrix3<f32>,
}

impl Pose {
    /// Position (NED, m) and ZYX Euler attitude (roll, pitch, yaw, rad).
    pub fn from_rpy(position: Vec3, roll: f32, pitch: f32, yaw: f32) -> Self {
        Pose { position, rotation: rotation_zyx(roll, pitch, yaw) }
    }
}

/// `R_z(yaw) · R_y(pitch) · R_x(roll)` (the project's ZYX convention, `crate::frame`).
pub fn rotation_zyx(roll: f32, pitch: f32, yaw: f32) -> Matrix3<f32> {
    nalgebra::Rotation3::from_euler_angles(roll, pitch, yaw).into_inner()
}

/// The beam lattice of a scan in the sensor frame. Beam `(row, col)` has azimuth
/// `az0 + col·daz` and elevation `el0 + row·del`; the ranges are row-major
/// (`row·n_az + col`). A full circle (`n_az·daz ≥ 2π`) wraps in azimuth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanGeometry {
    /// Azimuth of column 0, rad (positive to the right).
    pub az0: f32,
    /// Azimuth spacing, rad (> 0; for one column: the beam's full width).
    pub daz: f32,
    /// Columns (≥ 1).
    pub n_az: u16,
    /// Elevation of row 0, rad (positive up).
    pub el0: f32,
    /// Elevation spacing, rad (> 0; for one row: the beam's full height, e.g. the lidar's
    /// vertical divergence).
    pub del: f32,
    /// Rows (≥ 1).
    pub n_el: u16,
    /// Returns closer than this are [`Range::Unknown`], m.
    pub min_range: f32,
    /// Returns at or beyond this are [`Range::Clear`], m.
    pub max_range: f32,
}

impl ScanGeometry {
    /// A planar scan of `n` beams over the full circle, beam 0 along the boresight.
    pub fn planar_360(n: u16, vertical_width: f32, min_range: f32, max_range: f32) -> Self {
        let daz = core::f32::consts::TAU / f32::from(n.max(1));
        ScanGeometry { az0: 0.0, daz, n_az: n, el0: 0.0, del: vertical_width, n_el: 1, min_range, max_range }
    }

    /// A `w × h` grid covering `hfov × vfov` (rad), centred on the boresight (a depth camera
    /// decimated to `w × h`, a multi-zone time-of-flight sensor; `1 × 1`: a single beam of
    /// that width).
    pub fn grid(w: u16, h: u16, hfov: f32, vfov: f32, min_range: f32, max_range: f32) -> Self {
        let daz = hfov / f32::from(w.max(1));
        let del = vfov / f32::from(h.max(1));
        ScanGeometry {
            az0: -0.5 * hfov + 0.5 * daz,
            daz,
            n_az: w,
            el0: -0.5 * vfov + 0.5 * del,
            del,
            n_el: h,
            min_range,
            max_range,
        }
    }

    /// Number of beams.
    pub fn beams(&self) -> usize {
        usize::from(self.n_az) * usize::from(self.n_el)
    }

    /// Whether the columns close the circle.
    pub fn wraps(&self) -> bool {
        f32::from(self.n_az) * self.daz >= core::f32::consts::TAU - 1e-4
    }

    /// Sensor-frame unit direction of beam `(row, col)`.
    pub fn direction(&self, row: u16, col: u16) -> Vec3 {
        Self::direction_of(self.row_elevation(row), self.column_azimuth(col))
    }

    /// The beam nearest the sensor-frame direction `q` (rounded azimuth and elevation
    /// steps; the column modulo the circle when the lattice wraps): `(row, col)`, or `None`
    /// when that lies off the lattice.
    pub fn nearest_beam(&self, q: &Vec3) -> Option<(u16, u16)> {
        use crate::fmath::{atan2_approx, certain, round_i32, ATAN2_APPROX_ERROR};
        let h = crate::fmath::hypotf(q.x, q.y);
        // Column and row from approximate angles, each checked by `certain` against its
        // error (the angle's / spacing, +1 %, plus a few ulp of the steps); libm's `atan2f`
        // only when one lies too close to a half-step to tell. The same result as with
        // libm's angles throughout (test `nearest_beam_is_the_libm_angles_rounding`).
        let step = |a: f32, a0: f32, da: f32| (a - a0) / da;
        let err = |x: f32, da: f32| ATAN2_APPROX_ERROR / da * 1.01 + 8.0 * f32::EPSILON * (x.abs() + 1.0);
        let c = step(atan2_approx(q.y, q.x), self.az0, self.daz);
        let col = certain(c, err(c, self.daz), round_i32)
            .unwrap_or_else(|| round_i32(step(libm::atan2f(q.y, q.x), self.az0, self.daz)));
        let r = step(atan2_approx(-q.z, h), self.el0, self.del);
        let row = certain(r, err(r, self.del), round_i32)
            .unwrap_or_else(|| round_i32(step(libm::atan2f(-q.z, h), self.el0, self.del)));
        let mut col = col;
        if self.wraps() {
            col = col.rem_euclid(i32::from(self.n_az));
        }
        if col < 0 || col >= i32::from(self.n_az) || row < 0 || row >= i32::from(self.n_el) {
            return None;
        }
        Some((row as u16, col as u16))
    }

    /// `(sin, cos)` of row `row`'s elevation ([`ScanTrig`] tabulates them once per scan).
    pub fn row_elevation(&self, row: u16) -> (f32, f32) {
        crate::fmath::sincosf(self.el0 + f32::from(row) * self.del)
    }

    /// `(sin, cos)` of column `col`'s azimuth ([`ScanTrig`] tabulates them once per scan).
    pub fn column_azimuth(&self, col: u16) -> (f32, f32) {
        crate::fmath::sincosf(self.az0 + f32::from(col) * self.daz)
    }

    /// The unit direction of elevation `(sin, cos)` `el` and azimuth `(sin, cos)` `az`
    /// (`(cos e cos a, cos e sin a, −sin e)`, the module's frame).
    #[inline]
    pub fn direction_of(el: (f32, f32), az: (f32, f32)) -> Vec3 {
        let ((se, ce), (sa, ca)) = (el, az);
        Vec3::new(ce * ca, ce * sa, -se)
    }

    /// Finite, positive spacings and counts, `0 ≤ min_range < max_range`, at most
    /// [`MAX_BEAMS`] beams.
    pub fn valid(&self) -> bool {
        let finite = [self.az0, self.daz, self.el0, self.del, self.min_range, self.max_range]
            .iter()
            .all(|x| x.is_finite());
        finite
            && self.daz > 0.0
            && self.del > 0.0
            && self.n_az >= 1
            && self.n_el >= 1
            && self.beams() <= MAX_BEAMS
            && self.min_range >= 0.0
            && self.max_range > self.min_range
    }
}

/// One scan: its time stamp, the sensor, the vehicle pose at that time, the lattice and the
/// ranges (row-major, `geometry.beams()` of them).
#[derive(Clone, Copy, Debug)]
pub struct Scan<'a> {
    /// Time of the scan on the controller clock, µs.
    pub t_us: u64,
    /// Vehicle pose at `t_us`.
    pub pose: Pose,
    /// The sensor's mounting.
    pub mount: SensorMount,
    /// The beam lattice.
    pub geometry: ScanGeometry,
    /// One range per beam, row-major.
    pub ranges: &'a [Range],
}

/// Memory parameters (part of [`crate::config::ControllerParams`]: `PCP_*` in the parameter table).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryParams {
    /// Voxel edge, m: returns in one cell merge into one point. Default 0.2 m.
    pub voxel: f32,
    /// A cell not hit again for this long is forgotten, s. Default 5 s.
    pub forget_s: f32,
    /// A cell whose box lies within this distance of the vehicle is not forgotten by age
    /// (only by see-through clearing), m; 0 turns the rule off. Default 1 m
    /// (`memory` module docs, *Forgetting*).
    pub keep_near: f32,
    /// A beam clears a cell it passes through only when its return (or `max_range`) lies
    /// this far beyond the cell, m. Default 0.3 m.
    pub clear_margin: f32,
    /// Clusters (segments of a planar scan) at most this large are tracked for their
    /// velocity; larger ones (walls) are static, m. Default 0.8 m.
    pub track_size: f32,
    /// α of the α-β velocity tracker (β = α²/(2 − α), critically damped). Default 0.5.
    pub track_alpha: f32,
    /// A track's predicted centroid must lie within this of a cluster to take it, m. Default 0.5 m.
    pub track_gate: f32,
    /// Returns lower than this above the ground plane `z = −ground_height` are the ground
    /// (handled by the ground barrier), not obstacles, m. Default 0.1 m.
    pub ground_clip: f32,
    /// Ground height, m up (the robust layer's `ground_height`). Default 0.
    pub ground_height: f32,
    /// The frontier point lies this far beyond the observed free range (≥ the hull radius
    /// √δ, so the hull stays in observed space), m; 0 turns the frontier off. Default 0.25 m.
    pub fov_margin: f32,
    /// Where the observed free range along the direction of motion is used up
    /// (`PCP_FOV_WALLS`, [`frontier`]): [`FOV_WALLS_OFF`] the frontier point caps the speed
    /// there (a creep), [`FOV_WALLS_ON`] walls fixed in the world stop the vehicle,
    /// [`FOV_WALLS_HELD`] walls while the heading is held (`MIS_YAW_MODE` 0), the cap while it
    /// turns to the path — resolved by [`MemoryParams::with_heading_held`]; the memory treats an
    /// unresolved [`FOV_WALLS_HELD`] as walls. Default [`FOV_WALLS_HELD`].
    pub fov_walls: u8,
}

/// `fov_walls`: the frontier point caps the speed towards unseen space.
pub const FOV_WALLS_OFF: u8 = 0;
/// `fov_walls`: walls where nothing observed is left.
pub const FOV_WALLS_ON: u8 = 1;
/// `fov_walls`: walls while the heading is held, else the speed cap.
pub const FOV_WALLS_HELD: u8 = 2;

impl Default for MemoryParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl MemoryParams {
    /// The obstacle memory's parameters (issue 19; `crate::params`, MAVLink `param_index` order).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 7] {
        [
            Param::new("PCP_VOXEL", "Perception", "m", (0.02, 5.0), 3, field!(voxel),
                "Obstacle memory voxel edge: range returns in one cube merge into one point").key("mem_voxel"),
            Param::new("PCP_FORGET", "Perception", "s", (0.05, 600.0), 2, field!(forget_s),
                "An obstacle cell not seen again for this long is forgotten").key("mem_forget"),
            Param::new("PCP_KEEP_NEAR", "Perception", "m", (0.0, 5.0), 2, field!(keep_near),
                "Cells this near the vehicle are not forgotten by age, only by a beam seeing through them; 0 = off")
                .key("mem_keep_near"),
            Param::new("PCP_CLR_MARGIN", "Perception", "m", (0.0, 5.0), 3, field!(clear_margin),
                "A beam clears a cell it passes when its return lies this far beyond the cell").key("mem_clear_margin"),
            Param::new("PCP_TRK_SIZE", "Perception", "m", (0.0, 10.0), 2, field!(track_size),
                "Clusters up to this size are tracked for their velocity; larger ones are static").key("mem_track_size"),
            Param::new("PCP_FOV_MARGIN", "Perception", "m", (0.0, 5.0), 3, field!(fov_margin),
                "Frontier point beyond the observed free range (>= hull radius); 0 = off").key("fov_margin"),
            Param::new("PCP_FOV_WALLS", "Perception", "", (0.0, 2.0), 0, u8_field!(fov_walls),
                "Where the observed free range is used up: 0 cap the speed (creep), 1 walls stop the vehicle, \
                     2 walls while the heading is held (MIS_YAW_MODE 0)").key("fov_walls").code(|c| match c {
                    0 => Some("cap"),
                    1 => Some("walls"),
                    2 => Some("walls when held"),
                    _ => None,
                }),
        ]
    }
}

impl MemoryParams {
    /// The defaults (as a constant, for `const` constructors).
    pub const DEFAULT: MemoryParams = MemoryParams {
        voxel: 0.2,
        forget_s: 5.0,
        keep_near: 1.0,
        clear_margin: 0.3,
        track_size: 0.8,
        track_alpha: 0.5,
        track_gate: 0.5,
        ground_clip: 0.1,
        ground_height: 0.0,
        fov_margin: 0.25,
        fov_walls: FOV_WALLS_HELD,
    };

    /// These parameters with [`FOV_WALLS_HELD`] resolved for a vehicle whose heading is held
    /// (`held`: walls) or turns to the path (the speed cap); the other settings unchanged.
    pub const fn with_heading_held(self, held: bool) -> Self {
        let fov_walls = match self.fov_walls {
            FOV_WALLS_HELD if held => FOV_WALLS_ON,
            FOV_WALLS_HELD => FOV_WALLS_OFF,
            w => w,
        };
        MemoryParams { fov_walls, ..self }
    }

    /// Every field finite and in its range (voxel 0.02–5 m, forget 0.05–600 s, α in (0, 1], …).
    pub fn valid(&self) -> bool {
        (0.02..=5.0).contains(&self.voxel)
            && (0.05..=600.0).contains(&self.forget_s)
            && (0.0..=5.0).contains(&self.keep_near)
            && (0.0..=5.0).contains(&self.clear_margin)
            && (0.0..=10.0).contains(&self.track_size)
            && self.track_alpha > 0.0
            && self.track_alpha <= 1.0
            && (0.01..=10.0).contains(&self.track_gate)
            && (0.0..=10.0).contains(&self.ground_clip)
            && self.ground_height.is_finite()
            && (0.0..=5.0).contains(&self.fov_margin)
            && self.fov_walls <= FOV_WALLS_HELD
    }
}

/// Scan geometries for the tests: the presets' planar lidars (72, 73, 360 beams), the
/// decimated camera, multi-zone and single-beam ToF, a 32 × 24 image and a tall 4 × 17 fan
/// (the 73-beam, 360-beam, 32 × 24 and 4 × 17 ones wider or taller than [`ScanTrig`]'s tables).
#[cfg(test)]
pub(crate) fn sample_geometries() -> [ScanGeometry; 8] {
    [
        ScanGeometry::planar_360(72, 0.0175, 0.1, 12.0),
        ScanGeometry::planar_360(73, 0.0175, 0.1, 12.0),
        ScanGeometry::planar_360(360, 0.0175, 0.1, 12.0),
        ScanGeometry::grid(16, 10, 1.518, 1.012, 0.2, 6.0),
        ScanGeometry::grid(8, 8, 0.785, 0.785, 0.02, 4.0),
        ScanGeometry::grid(1, 1, 0.47, 0.47, 0.02, 4.0),
        ScanGeometry::grid(32, 24, 1.518, 1.012, 0.2, 6.0),
        ScanGeometry::grid(4, 17, 0.3, 1.2, 0.2, 6.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `nearest_beam` as first written: libm's angles, rounded.
    fn reference(g: &ScanGeometry, q: &Vec3) -> Option<(u16, u16)> {
        let az = libm::atan2f(q.y, q.x);
        let el = libm::atan2f(-q.z, crate::fmath::hypotf(q.x, q.y));
        let mut col = libm::roundf((az - g.az0) / g.daz) as i32;
        if g.wraps() {
            col = col.rem_euclid(i32::from(g.n_az));
        }
        let row = libm::roundf((el - g.el0) / g.del) as i32;
        if col < 0 || col >= i32::from(g.n_az) || row < 0 || row >= i32::from(g.n_el) {
            return None;
        }
        Some((row as u16, col as u16))
    }

    /// The approximate angles with their certainty check give libm's beam everywhere: random
    /// directions, directions a hair either side of every half-step between beams (where the
    /// fallback must decide), the poles, zero and non-finite vectors. Fails with the error
    /// bound taken 100 times too small.
    #[test]
    fn nearest_beam_is_the_libm_angles_rounding() {
        let geometries = sample_geometries();
        let mut seed = 0x5eed_0019_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        let dir = |az: f32, el: f32, r: f32| {
            let (sa, ca) = (libm::sinf(az), libm::cosf(az));
            let (se, ce) = (libm::sinf(el), libm::cosf(el));
            Vec3::new(ce * ca * r, ce * sa * r, -se * r)
        };
        let mut checked = 0u32;
        for g in &geometries {
            let mut check = |q: Vec3| {
                assert_eq!(g.nearest_beam(&q), reference(g, &q), "{g:?} q {q:?}");
                checked += 1;
            };
            for _ in 0..20_000 {
                let q = Vec3::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0);
                check(q * (0.01 + 10.0 * next()));
            }
            for col in 0..=g.n_az {
                for row in 0..=g.n_el {
                    for eps in [0.0f32, 1e-7, -1e-7, 1e-6, -1e-6, 3e-5, -3e-5, 2e-4, -2e-4] {
                        let az = g.az0 + (f32::from(col) - 0.5) * g.daz + eps;
                        let el = g.el0 + (f32::from(row) - 0.5) * g.del + eps;
                        let el_mid = g.el0 + f32::from(row.min(g.n_el - 1)) * g.del;
                        let az_mid = g.az0 + f32::from(col.min(g.n_az - 1)) * g.daz;
                        for r in [0.3f32, 2.0] {
                            check(dir(az, el_mid, r));
                            check(dir(az_mid, el, r));
                            check(dir(az, el, r));
                        }
                    }
                }
            }
            for q in [
                Vec3::zeros(),
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(0.0, 0.0, -1.0),
                Vec3::new(-1.0, 0.0, 0.0),
                Vec3::new(-1.0, -0.0, 0.0),
                Vec3::new(f32::NAN, 0.0, 0.0),
                Vec3::new(f32::INFINITY, 1.0, 0.0),
                Vec3::new(1.0, f32::NEG_INFINITY, 0.0),
            ] {
                check(q);
            }
        }
        assert!(checked > 100_000);
    }
}
