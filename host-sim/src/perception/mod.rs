//! Perception in the loop (`parapet run --perception …`, issue 19): the
//! vehicle's simulated range sensors ([`crate::sim::range`]) scan the scene by
//! exact ray casts ([`crate::world::raycast`]), their scans reach the core's
//! obstacle memory (`parapet_core::perception::ObstacleMemory`) late by their
//! latency, and the memory's points — instead of the true closest points —
//! are what the controller's safety filter is told.
//!
//! ## Timing
//! Every outer step (250 Hz) at time `t`: each sensor whose next scan time has
//! come scans the scene **at `t`** (moving obstacles where they are at `t`)
//! from the vehicle's true pose at `t`; the scan is delivered at the first
//! outer step at or after `t + latency`, with its time stamp `t` and the pose
//! at `t` (a companion computer stamps and poses its scans; the memory places
//! the returns with that pose). Scan times are `k / rate` (k = 0, 1, …), each
//! taken at the first outer step at or after it.
//!
//! ## Determinism
//! Each sensor draws its noise and dropouts from its own ChaCha8 generator
//! seeded from the run's seed and the sensor's position in the list, so a run
//! is the same for the same seed, and adding a sensor does not change the
//! others' streams. `noise = false` (the `[sensors]` master switch) turns the
//! range noise off; dropouts stay (they are a property of the sensor, like latency).
//!
//! ## Memory
//! One `ObstacleMemory<`[`MEMORY_CELLS`]`>` with the controller's memory
//! parameters (`ControllerParams::memory_params`, `PCP_*`). Its points for the
//! vehicle's true position and velocity (one per cell, moving tracks with their
//! estimated velocity, and the field-of-view frontier point), the
//! [`SELECTED`] most critical by the controller's own ranking, go to the controller.
//!
//! Owns: [`Perception`], [`RangeLog`], [`RangeRecord`], [`ForwardedScan`]. May import: `parapet-core`,
//! [`crate::sim`] (sensor models, plant state), [`crate::world`] (scene, ray casts).

use std::collections::VecDeque;

use nalgebra::{UnitQuaternion, Vector3};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::obstacle_set::Ranking;
use parapet_core::perception::{MemoryParams, ObstacleMemory, Pose, Range, Scan, ScanGeometry, SensorMount};
use parapet_core::Vec3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::decimal::push_fixed;
use crate::sim::plant::PlantState;
use crate::sim::range::{RangeSensor, Return};
use crate::world::raycast::{Cone, RayWorld};
use crate::world::scene::Scene;

/// Cells of the host's obstacle memory (the core's default capacity).
pub const MEMORY_CELLS: usize = parapet_core::perception::DEFAULT_MEMORY_CAPACITY;

/// Points handed to the controller per outer step: the memory's most critical
/// by the controller's own set policy (`MemoryParams`' `select`), as a companion
/// computer's batch of 32 `OBSTACLE_DISTANCE_3D` points to the firmware.
pub const SELECTED: usize = 32;

/// Vertical width (rad) given to a single-row sensor's beams (a planar lidar's
/// divergence, about 1°), for the memory's lattice.
pub const PLANAR_BEAM_WIDTH_RAD: f64 = 0.0175;

/// One beam of one scan, as `ranges.csv` records it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RangeRecord {
    /// Scan time, s.
    pub t: f64,
    /// Sensor index (position in the list).
    pub sensor: u16,
    /// Beam index (row-major, row 0 the bottom row).
    pub beam: u16,
    /// Measured range, m (`None`: no return — nothing within range, or a dropout).
    pub range: Option<f32>,
    /// World point of the return, NED, m.
    pub point: Option<[f32; 3]>,
}

/// Every beam of a run's scans, compactly: per scan its time, sensor and the sensor's world
/// pose, per beam the measured range (8 bytes; a fifth of a 40-byte [`RangeRecord`] with its point,
/// so recording costs the flight loop little). [`RangeLog::iter`] gives each beam's
/// [`RangeRecord`], its world point from the same `f64` arithmetic the scan's ray used.
#[derive(Clone, Debug, Default)]
pub struct RangeLog {
    /// Per sensor, its body-frame unit beam directions.
    dirs: Vec<Vec<Vector3<f64>>>,
    scans: Vec<ScanLog>,
    /// Per beam, the range, m; NaN: no return (a return's range is finite, `min ≤ r ≤ max`).
    ranges: Vec<f64>,
}

#[derive(Clone, Debug)]
struct ScanLog {
    t: f64,
    sensor: u16,
    /// The sensor's origin (NED, m) and the vehicle's attitude (body → NED) at `t`.
    origin: Vector3<f64>,
    att: UnitQuaternion<f64>,
    /// Index of the scan's first beam in `ranges`.
    first: usize,
}

impl RangeLog {
    /// Beams recorded.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// No beam recorded.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Every beam in scan order (each scan's beams row-major).
    pub fn iter(&self) -> impl Iterator<Item = RangeRecord> + '_ {
        self.scans.iter().enumerate().flat_map(move |(i, s)| {
            let end = self.scans.get(i + 1).map_or(self.ranges.len(), |n| n.first);
            let dirs = self.dirs.get(usize::from(s.sensor)).map_or(&[][..], Vec::as_slice);
            let ranges = self.ranges.get(s.first..end).unwrap_or(&[]);
            ranges.iter().zip(dirs).enumerate().map(move |(b, (&r, d))| {
                let hit = !r.is_nan();
                RangeRecord {
                    t: s.t,
                    sensor: s.sensor,
                    beam: b as u16,
                    range: hit.then_some(r as f32),
                    point: hit.then(|| {
                        let p = s.origin + (s.att * d) * r;
                        [p.x as f32, p.y as f32, p.z as f32]
                    }),
                }
            })
        })
    }
}

struct Live {
    spec: RangeSensor,
    /// Body-frame unit beam directions.
    dirs: Vec<Vector3<f64>>,
    /// The cone of `dirs` (body frame), `None` for a wide fan.
    cone: Option<Cone>,
    geometry: ScanGeometry,
    mount: SensorMount,
    rng: ChaCha8Rng,
    /// Index of the next scan (its time is `next / rate`).
    next: u64,
}

struct Pending {
    deliver: f64,
    sensor: usize,
    t: f64,
    pose: Pose,
    ranges: Vec<Range>,
}

/// A delivered scan handed out instead of the host memory ([`Perception::forward_scans`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ForwardedScan {
    /// Sensor index (position in the list).
    pub sensor: usize,
    /// Scan time, s.
    pub t: f64,
    /// One value per beam (row-major, row 0 the bottom row).
    pub ranges: Vec<Range>,
}

/// The range sensors, their scans in flight and the obstacle memory of one run.
pub struct Perception {
    sensors: Vec<Live>,
    /// Per sensor: its delivered scans go to [`Perception::take_forwarded`], not the memory.
    forward: Vec<bool>,
    forwarded: Vec<ForwardedScan>,
    world: RayWorld,
    pending: VecDeque<Pending>,
    memory: Box<ObstacleMemory<MEMORY_CELLS>>,
    ranking: Ranking,
    delta1: f32,
    noise_on: bool,
    record: bool,
    records: RangeLog,
    scans: u64,
    rejected: u64,
}

fn f32v(v: &Vector3<f64>) -> Vec3 {
    Vec3::new(v.x as f32, v.y as f32, v.z as f32)
}

/// The memory's beam lattice of a sensor (the same directions as
/// [`RangeSensor::beam_directions`], in `f32`).
pub fn geometry_of(s: &RangeSensor) -> ScanGeometry {
    let mut g = centred_geometry_of(s);
    if s.elevation != 0.0 {
        // The field's centre above the mounting plane (a 3D lidar's −7°…+52°).
        g.el0 = (f64::from(g.el0) + s.elevation.to_radians()) as f32;
    }
    g
}

/// [`geometry_of`] with the vertical field centred on the mounting plane.
fn centred_geometry_of(s: &RangeSensor) -> ScanGeometry {
    let (min, max) = (s.min_range as f32, s.max_range as f32);
    let (nc, nr) = (s.columns as u16, s.rows as u16);
    if s.fov_h >= 360.0 {
        let del = if s.rows == 1 { PLANAR_BEAM_WIDTH_RAD.max(s.fov_v.to_radians()) } else { 0.0 };
        let mut g = ScanGeometry::planar_360(nc, del as f32, min, max);
        if s.rows > 1 {
            let step = s.fov_v.to_radians() / f64::from(s.rows);
            g.n_el = nr;
            g.del = step as f32;
            g.el0 = (-0.5 * s.fov_v.to_radians() + 0.5 * step) as f32;
        }
        g
    } else {
        let vfov =
            if s.rows == 1 { PLANAR_BEAM_WIDTH_RAD.max(s.fov_v.to_radians()) } else { s.fov_v.to_radians() };
        let mut g = ScanGeometry::grid(nc, nr, s.fov_h.to_radians() as f32, vfov as f32, min, max);
        if s.rows == 1 {
            g.el0 = 0.0;
        }
        g
    }
}

impl Perception {
    /// The sensors `sensors` on the vehicle of `scene`, seeded with `seed`,
    /// range noise on when `noise_on`; the memory with `params`, its points
    /// selected with the controller's `ranking` and engagement level `delta1`
    /// (m²). `record`: keep every beam for `ranges.csv`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: &Scene,
        sensors: &[RangeSensor],
        seed: u64,
        noise_on: bool,
        params: MemoryParams,
        ranking: Ranking,
        delta1: f32,
        record: bool,
    ) -> Self {
        let sensors: Vec<Live> = sensors
            .iter()
            .enumerate()
            .map(|(i, s)| Live {
                dirs: s.beam_directions(),
                cone: Cone::of(&s.beam_directions()),
                geometry: geometry_of(s),
                mount: SensorMount::new(
                    f32v(&Vector3::from(s.offset)),
                    0.0,
                    s.pitch.to_radians() as f32,
                    s.yaw.to_radians() as f32,
                ),
                rng: ChaCha8Rng::seed_from_u64(
                    seed ^ 0x5241_4e47_4500_0000 ^ (i as u64).wrapping_mul(0x9e37_79b9),
                ),
                next: 0,
                spec: s.clone(),
            })
            .collect();
        Perception {
            forward: vec![false; sensors.len()],
            forwarded: Vec::new(),
            sensors,
            world: RayWorld::new(scene),
            pending: VecDeque::new(),
            memory: Box::new(ObstacleMemory::new(params)),
            ranking,
            delta1,
            noise_on,
            record,
            records: RangeLog::default(),
            scans: 0,
            rejected: 0,
        }
    }

    /// The perception of a closed-loop run: the sensors `sensors` of `scene` with
    /// beam records kept for `ranges.csv`, and the memory's points ranked as the
    /// controller ranks them — by criticality with the CBF's `(mu, relative velocity)`
    /// when `critical` is given (the multi-barrier filters), else nearest first.
    pub fn for_run(
        scene: &Scene,
        sensors: &[RangeSensor],
        seed: u64,
        noise_on: bool,
        params: MemoryParams,
        critical: Option<(f32, bool)>,
        delta1: f32,
    ) -> Self {
        let ranking = match critical {
            Some((mu, relative)) => Ranking::Critical { mu, relative },
            None => Ranking::Nearest,
        };
        Perception::new(scene, sensors, seed, noise_on, params, ranking, delta1, true)
    }

    /// [`Perception::step`] from the plant's true state `st` (Euler angles `rpy`) at `t`.
    pub fn step_plant(
        &mut self,
        scene: &Scene,
        t: f64,
        st: &PlantState,
        rpy: (f64, f64, f64),
        to_us: impl Fn(f64) -> u64,
        out: &mut Vec<ObstaclePoint>,
    ) {
        let t_us = to_us(t);
        self.step(scene, t, t_us, &st.pos, &st.vel, &st.att, rpy, to_us, out);
    }

    /// One outer step at time `t` (s; `t_us` on the controller clock): scan
    /// with the sensors that are due, from the vehicle's true pose (`pos`,
    /// `att` body → NED, `rpy` its Euler angles), deliver the scans whose
    /// latency has passed into the memory, and replace `out` by the memory's
    /// points for the vehicle at `pos` moving at `vel`.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        scene: &Scene,
        t: f64,
        t_us: u64,
        pos: &Vector3<f64>,
        vel: &Vector3<f64>,
        att: &UnitQuaternion<f64>,
        rpy: (f64, f64, f64),
        to_us: impl Fn(f64) -> u64,
        out: &mut Vec<ObstaclePoint>,
    ) {
        let mut moving = None;
        for (si, s) in self.sensors.iter_mut().enumerate() {
            if (s.next as f64) / s.spec.rate > t + 1e-9 {
                continue;
            }
            // Catch up: one scan now, the next at the first k / rate after t.
            s.next = (t * s.spec.rate + 1e-9).floor() as u64 + 1;
            let moving = moving.get_or_insert_with(|| self.world.moving_at(scene, t));
            let origin = pos + att * Vector3::from(s.spec.offset);
            let mut ranges = Vec::with_capacity(s.dirs.len());
            let cone = s.cone.map(|k| Cone { axis: att * k.axis, half: k.half });
            let view = self.world.scan_view(moving, &origin, s.spec.max_range, cone.as_ref());
            if self.record {
                let log = &mut self.records;
                if log.dirs.len() <= si {
                    log.dirs.resize(si + 1, Vec::new());
                }
                if let Some(d) = log.dirs.get_mut(si).filter(|d| d.is_empty()) {
                    d.clone_from(&s.dirs);
                }
                log.scans.push(ScanLog { t, sensor: si as u16, origin, att: *att, first: log.ranges.len() });
            }
            for d in s.dirs.iter() {
                let dir = att * d;
                let hit = view.cast(&dir, s.spec.max_range).map(|h| h.range);
                let m = s.spec.measure(hit, &mut s.rng, self.noise_on);
                if self.record {
                    self.records.ranges.push(m.range().unwrap_or(f64::NAN));
                }
                ranges.push(match m {
                    Return::Hit(r) => Range::Hit(r as f32),
                    Return::Clear => Range::Clear,
                    Return::Unknown => Range::Unknown,
                });
            }
            let pose = Pose::from_rpy(f32v(pos), rpy.0 as f32, rpy.1 as f32, rpy.2 as f32);
            let deliver = t + s.spec.latency;
            // Keep the queue in delivery order (sensors differ in latency).
            let at = self.pending.partition_point(|p| p.deliver <= deliver);
            self.pending.insert(at, Pending { deliver, sensor: si, t, pose, ranges });
        }
        while self.pending.front().is_some_and(|p| p.deliver <= t + 1e-9) {
            let Some(p) = self.pending.pop_front() else { break };
            if self.forward.get(p.sensor).copied().unwrap_or(false) {
                self.forwarded.push(ForwardedScan { sensor: p.sensor, t: p.t, ranges: p.ranges });
                continue;
            }
            let s = &self.sensors[p.sensor];
            let scan = Scan {
                t_us: to_us(p.t),
                pose: p.pose,
                mount: s.mount,
                geometry: s.geometry,
                ranges: &p.ranges,
            };
            let rep = self.memory.insert_scan(&scan);
            self.scans += 1;
            self.rejected += u64::from(rep.rejected);
        }
        out.clear();
        let set = self.memory.select_set::<SELECTED>(t_us, &f32v(pos), &f32v(vel), self.ranking, self.delta1);
        out.extend_from_slice(set.as_slice());
    }

    /// From now on the delivered scans of the sensors for which `which` is true are handed
    /// out by [`Perception::take_forwarded`] instead of entering the host's memory (a flight
    /// stack that builds its own obstacle set from them: the PIL firmware fed by
    /// `OBSTACLE_DISTANCE`). Returns how many sensors forward.
    pub fn forward_scans(&mut self, which: impl Fn(&RangeSensor) -> bool) -> usize {
        for (f, s) in self.forward.iter_mut().zip(&self.sensors) {
            *f = which(&s.spec);
        }
        self.forward.iter().filter(|f| **f).count()
    }

    /// The forwarded scans delivered since the last call, in delivery order.
    pub fn take_forwarded(&mut self) -> Vec<ForwardedScan> {
        std::mem::take(&mut self.forwarded)
    }

    /// Sensor `i`'s description.
    pub fn sensor(&self, i: usize) -> Option<&RangeSensor> {
        self.sensors.get(i).map(|s| &s.spec)
    }

    /// Every beam recorded (when recording).
    pub fn records(&self) -> &RangeLog {
        &self.records
    }

    /// Take the records out.
    pub fn take_records(&mut self) -> RangeLog {
        std::mem::take(&mut self.records)
    }

    /// Scans delivered to the memory and of them rejected.
    pub fn scans(&self) -> (u64, u64) {
        (self.scans, self.rejected)
    }

    /// The sensors.
    pub fn sensors(&self) -> impl Iterator<Item = &RangeSensor> {
        self.sensors.iter().map(|s| &s.spec)
    }
}

/// `ranges.csv`: `t,sensor,beam,range,x,y,z` — time (s), sensor name, beam
/// index, measured range (m, empty = no return) and the return's world point
/// (ENU, m, empty without a return).
pub fn write_ranges_csv(
    w: &mut dyn std::io::Write,
    sensors: &[RangeSensor],
    records: &RangeLog,
) -> std::io::Result<()> {
    writeln!(w, "t,sensor,beam,range,x,y,z")?;
    // Each line built in one buffer (the numbers as `{:.4}` would write them: crate::decimal).
    let mut line = Vec::with_capacity(96);
    for r in records.iter() {
        let name = sensors.get(r.sensor as usize).map_or("?", |s| s.name.as_str());
        line.clear();
        push_fixed(&mut line, r.t, 4);
        line.push(b',');
        line.extend_from_slice(name.as_bytes());
        std::io::Write::write_fmt(&mut line, format_args!(",{},", r.beam))?;
        match (r.range, r.point) {
            (Some(d), Some(p)) => {
                // NED → ENU: (y, x, −z).
                for (i, v) in [d, p[1], p[0], -p[2]].into_iter().enumerate() {
                    if i > 0 {
                        line.push(b',');
                    }
                    push_fixed(&mut line, f64::from(v), 4);
                }
            }
            _ => line.extend_from_slice(b",,,"),
        }
        line.push(b'\n');
        w.write_all(&line)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::range::{kind_defaults, preset, RangeKind};

    fn scene(text: &str) -> Scene {
        let src = format!(
            "name = \"t\"\n[bounds]\nmin = [-20, -20, 0]\nmax = [20, 20, 10]\n[mission]\nstart = [0, 0, 1]\ngoal = [1, 0, 1]\nspeed = 0.5\n{text}"
        );
        Scene::parse(&src, "t.toml").unwrap()
    }

    #[test]
    fn geometry_matches_the_beam_directions() {
        for name in crate::sim::range::PRESETS {
            for s in preset(name).unwrap() {
                let g = geometry_of(&s);
                assert!(g.valid(), "{name}: {g:?}");
                let dirs = s.beam_directions();
                let m = s.mount();
                for r in 0..g.n_el {
                    for c in 0..g.n_az {
                        let d = g.direction(r, c);
                        let body = m * Vector3::new(d.x as f64, d.y as f64, d.z as f64);
                        let want = dirs[(r as usize) * g.n_az as usize + c as usize];
                        assert!((body - want).norm() < 1e-5, "{name} beam {r},{c}: {body:?} vs {want:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_wall_ahead_is_measured_at_its_distance_and_reaches_the_memory_after_the_latency() {
        // A wall 3 m north (ENU y = 3, NED x = 3) in front of the vehicle (heading north).
        let sc = scene("[[obstacles]]\nkind = \"box\"\nmin = [-5, 3, 0]\nmax = [5, 3.5, 4]\n");
        let lidar =
            RangeSensor { noise: 0.0, dropout: 0.0, latency: 0.02, ..kind_defaults(RangeKind::Lidar) };
        let mut p =
            Perception::new(&sc, &[lidar], 1, true, MemoryParams::default(), Ranking::Nearest, 0.1, true);
        let pos = Vector3::new(0.0, 0.0, -1.0);
        let (att, mut out) = (UnitQuaternion::identity(), Vec::new());
        let us = |t: f64| (t * 1e6) as u64;
        p.step(&sc, 0.0, 0, &pos, &Vector3::zeros(), &att, (0.0, 0.0, 0.0), us, &mut out);
        let r: Vec<RangeRecord> = p.records().iter().collect();
        assert_eq!((r.len(), p.records().len()), (72, 72));
        // Beam 0 (forward, north) hits the wall at 3 m.
        assert!((r[0].range.unwrap() - 3.0).abs() < 1e-6, "{:?}", r[0]);
        // Each record: its beam, and its point on the wall (north face y = 3 ENU = x 3 NED)
        // at its range along its beam from the sensor; no return, no point.
        for (b, rec) in r.iter().enumerate() {
            assert_eq!((rec.t, rec.sensor, usize::from(rec.beam)), (0.0, 0, b));
            assert_eq!(rec.range.is_some(), rec.point.is_some(), "{rec:?}");
            if let (Some(d), Some(q)) = (rec.range, rec.point) {
                let q = Vector3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2]));
                assert!((q - pos).norm() - f64::from(d) < 1e-5, "{rec:?}");
                assert!((q.x - 3.0).abs() < 1e-5 || (q.z + 0.0).abs() < 1e-5, "{rec:?}");
                let want = pos + p.sensors[0].dirs[b] * f64::from(d);
                assert!((q - want).norm() < 1e-5, "{rec:?} vs {want:?}");
            }
        }
        assert!(r.iter().any(|x| x.range.is_none()), "beams away from the wall see nothing");
        // Not delivered yet: the latency is 20 ms.
        assert!(out.iter().all(|o| o.id == parapet_core::perception::FRONTIER_ID));
        for k in 1..=5 {
            let t = k as f64 * 0.004;
            p.step(&sc, t, us(t), &pos, &Vector3::zeros(), &att, (0.0, 0.0, 0.0), us, &mut out);
        }
        assert_eq!(p.scans(), (1, 0));
        let wall: Vec<_> = out.iter().filter(|o| o.id != parapet_core::perception::FRONTIER_ID).collect();
        assert!(!wall.is_empty());
        let nearest = wall.iter().map(|o| (o.point - f32v(&pos)).norm()).fold(f32::INFINITY, f32::min);
        assert!((nearest - 3.0).abs() < 0.25, "nearest wall point {nearest}");
        // 10 Hz: no second scan before 0.1 s.
        assert_eq!(p.records().len(), 72);
    }

    #[test]
    fn same_seed_same_scans() {
        let sc = scene("[[obstacles]]\nkind = \"sphere\"\ncenter = [1, 2, 1]\nradius = 0.5\n");
        let run = |seed| {
            let mut p = Perception::new(
                &sc,
                &preset("tof").unwrap(),
                seed,
                true,
                MemoryParams::default(),
                Ranking::Nearest,
                0.1,
                true,
            );
            let mut out = Vec::new();
            for k in 0..100 {
                let t = k as f64 * 0.004;
                let pos = Vector3::new(0.01 * k as f64, 0.0, -1.0);
                p.step(
                    &sc,
                    t,
                    (t * 1e6) as u64,
                    &pos,
                    &Vector3::zeros(),
                    &UnitQuaternion::identity(),
                    (0.0, 0.0, 0.0),
                    |t| (t * 1e6) as u64,
                    &mut out,
                );
            }
            p.take_records().iter().collect::<Vec<_>>()
        };
        let (a, b, c) = (run(3), run(3), run(4));
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.iter().any(|r| r.range.is_some()));
    }

    #[test]
    fn sensor_tables_load_and_bad_ones_name_table_field_value_and_range() {
        let sc = scene("[[sensor]]\nkind = \"camera\"\nname = \"front\"\nrate = 15\n[[sensor]]\nkind = \"tof\"\nyaw = 180\n");
        assert_eq!(sc.range_sensors.len(), 2);
        assert_eq!((sc.range_sensors[0].name.as_str(), sc.range_sensors[0].rate), ("front", 15.0));
        assert_eq!((sc.range_sensors[1].name.as_str(), sc.range_sensors[1].yaw), ("tof1", 180.0));
        let err = |t: &str| {
            let src = format!(
                "name = \"t\"\n[bounds]\nmin = [-20, -20, 0]\nmax = [20, 20, 10]\n[mission]\nstart = [0, 0, 1]\ngoal = [1, 0, 1]\nspeed = 0.5\n{t}"
            );
            Scene::parse(&src, "t.toml").unwrap_err().message
        };
        let e = err("[[sensor]]\nkind = \"lidar\"\n[[sensor]]\nkind = \"lidar\"\nlatency = 2.0\n");
        assert!(
            e.contains("sensor[1]") && e.contains("`latency`") && e.contains("2.0") && e.contains("≤ 1"),
            "{e}"
        );
        let e = err("[[sensor]]\nkind = \"lidar\"\nname = \"a\"\n[[sensor]]\nkind = \"tof\"\nname = \"a\"\n");
        assert!(e.contains("sensor[1]") && e.contains("`name`"), "{e}");
        let e = err("[[sensor]]\nkind = \"radar\"\n");
        assert!(e.contains("radar"), "{e}");
    }
}
