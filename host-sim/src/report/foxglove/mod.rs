//! The flight as MCAP for Foxglove (`flight.mcap`, issue 40): written with the `mcap` crate,
//! uncompressed chunks (a reader needs no decompressor), every message JSON
//! (`message_encoding = "json"`) with a JSON schema (`schema encoding = "jsonschema"`).
//!
//! ## Frames
//! Foxglove's 3D panel is z-up, so the file is in **ENU** like every other report file
//! (`trajectory.csv`, `replay.html`): x east, y north, z up, m. The frame `world` is the
//! scene's ENU frame; `base_link` is the vehicle body in ROS's FLU convention (x forward, y
//! left, z up). The simulator's NED / FRD quantities are converted here, at the boundary:
//! positions `(n, e, d) → (e, n, −d)` ([`ned_to_enu_arr`]), attitude
//! `q_world←base_link = q_ENU←NED · q_NED←FRD(roll, pitch, yaw) · q_FRD←FLU`.
//!
//! ## Time
//! Log time (and publish time, and every message's `timestamp`) of a sample's messages is the
//! controller clock of the sample, in ns: `clock(t) · 1000` with `clock` the clock of the
//! ULog (`crate::flight::stack::clock_us`: simulated time + 1 s), so the two logs line up.
//!
//! ## Topics
//! | topic | schema | messages |
//! |---|---|---|
//! | `/scene` | `foxglove.SceneUpdate` | at the first sample: every obstacle (`obstacle/<i>`: cube, sphere, cylinder; a point obstacle as a 0.1 m sphere; moving ones orange), the planned path (`path`, a line strip), the start and the goal (`start`, `goal`); then, when the scene has moving obstacles, one update of the moving ones every [`SCENE_UPDATE_PERIOD_S`] of flight |
//! | `/tf` | `foxglove.FrameTransform` | one per sample (250 Hz): `world` → `base_link`, the true position and attitude |
//! | `/vehicle/state` | `parapet.VehicleState` | one per sample: `t` (s), `position`, `velocity` (ENU), `speed`, `clearance` (m), `h_bar`, `filter_h_bar` (m²), `region`, `filter_active`, `mode` (guidance), `flight_mode` — for the Plot panel |
//! | `/ranges` | `foxglove.PointCloud` | `--perception` runs: one per scan, the returns (x, y, z `FLOAT32`, frame `world`) |
//! | `/events` | `foxglove.Log` | guidance and flight mode changes (INFO), the first collision (ERROR), the end of the run (INFO) |
//!
//! Numbers of the vehicle (positions, velocities, clearance, h̄, t) are written as
//! `trajectory.csv` prints them: 4 decimals (m, m/s, s), 5 for h̄ (m²) — the file then holds
//! the CSV's numbers and half the bytes of the doubles' shortest texts; the attitude quaternion
//! is written in full (a unit quaternion). A non-finite number (a NaN sample) is JSON `null`
//! (serde_json's rule): the file stays valid and the sample keeps its messages.
//!
//! The schemas in `schemas/` are foxglove/schemas' `schemas/jsonschema` files as published
//! (commit dd8b4f3, MIT licence, © Foxglove Technologies Inc.).
//!
//! May import: [`super`] (the record and its helpers), [`crate::world`] (obstacle shapes and
//! motion, the ENU conversion), `parapet-core`, the `mcap` crate, serde.

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::Path;

use anyhow::{Context, Result};
use mcap::records::MessageHeader;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use parapet_core::obstacle::Shape;
use serde::Serialize;

use super::{region_name, RunRecord, Sample};
use crate::decimal::with_fixed;
use crate::perception::RangeRecord;
use crate::world::frame::to_f64;
use crate::world::scene::ned_to_enu_arr;

/// File name of the MCAP log in a run's report directory.
pub const FLIGHT_MCAP: &str = "flight.mcap";

/// Period of the moving obstacles' scene updates, s of flight (10 Hz).
pub const SCENE_UPDATE_PERIOD_S: f64 = 0.1;

/// Frame of the scene (ENU).
pub const WORLD_FRAME: &str = "world";
/// Frame of the vehicle body (FLU).
pub const BODY_FRAME: &str = "base_link";

const SCENE_UPDATE_SCHEMA: &str = include_str!("schemas/SceneUpdate.json");
const FRAME_TRANSFORM_SCHEMA: &str = include_str!("schemas/FrameTransform.json");
const POINT_CLOUD_SCHEMA: &str = include_str!("schemas/PointCloud.json");
const LOG_SCHEMA: &str = include_str!("schemas/Log.json");

/// The JSON schema of `/vehicle/state` (this project's own message).
const VEHICLE_STATE_SCHEMA: &str = r#"{
  "title": "parapet.VehicleState",
  "description": "One outer-loop sample of a Parapet flight (ENU, SI units; null: not a finite number)",
  "type": "object",
  "properties": {
    "timestamp": {"type": "object", "title": "time", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
    "t": {"type": ["number", "null"], "description": "time since the mission start, s"},
    "position": {"type": "object", "description": "true position, ENU, m", "properties": {"x": {"type": ["number", "null"]}, "y": {"type": ["number", "null"]}, "z": {"type": ["number", "null"]}}},
    "velocity": {"type": "object", "description": "true velocity, ENU, m/s", "properties": {"x": {"type": ["number", "null"]}, "y": {"type": ["number", "null"]}, "z": {"type": ["number", "null"]}}},
    "speed": {"type": ["number", "null"], "description": "|velocity|, m/s"},
    "clearance": {"type": ["number", "null"], "description": "distance to the nearest surface or the ground minus the hull radius, m"},
    "h_bar": {"type": ["number", "null"], "description": "min barrier over all obstacles on the true state, m^2"},
    "filter_h_bar": {"type": ["number", "null"], "description": "the filter's own min barrier, m^2"},
    "region": {"type": "string", "description": "none, far, nominal_safe, filtering, fault"},
    "filter_active": {"type": "boolean", "description": "the filter changed the nominal input"},
    "mode": {"type": "string", "description": "guidance mode"},
    "flight_mode": {"type": "string", "description": "flight mode selected"}
  }
}
"#;

fn io_err(e: mcap::McapError) -> std::io::Error {
    std::io::Error::other(e)
}

/// Foxglove's `time`.
#[derive(Clone, Copy, Serialize)]
struct Time {
    sec: u64,
    nsec: u32,
}

impl Time {
    fn of_ns(ns: u64) -> Self {
        Time { sec: ns / 1_000_000_000, nsec: (ns % 1_000_000_000) as u32 }
    }
}

/// A number as `trajectory.csv` prints it with `D` decimals (the double nearest to that text,
/// which serde_json writes as that text or shorter); not finite: `null`.
#[derive(Clone, Copy)]
struct Dec<const D: usize>(f64);

impl<const D: usize> Serialize for Dec<D> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let x = with_fixed(self.0, D, |t| t.parse::<f64>().unwrap_or(f64::NAN));
        // serde_json writes a non-finite number as null.
        s.serialize_f64(x)
    }
}

/// A vector with the report's 4 decimals (m, m/s).
#[derive(Clone, Copy, Serialize)]
struct Vec3 {
    x: Dec<4>,
    y: Dec<4>,
    z: Dec<4>,
}

impl Vec3 {
    fn enu(v: &Vector3<f64>) -> Self {
        Vec3::arr(ned_to_enu_arr(v))
    }
    fn arr(a: [f64; 3]) -> Self {
        Vec3 { x: Dec(a[0]), y: Dec(a[1]), z: Dec(a[2]) }
    }
}

#[derive(Clone, Copy, Serialize)]
struct Quat {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}

const IDENTITY: Quat = Quat { x: 0.0, y: 0.0, z: 0.0, w: 1.0 };

#[derive(Clone, Copy, Serialize)]
struct Pose {
    position: Vec3,
    orientation: Quat,
}

impl Pose {
    fn at(p: [f64; 3]) -> Self {
        Pose { position: Vec3::arr(p), orientation: IDENTITY }
    }
}

#[derive(Clone, Copy, Serialize)]
struct Color {
    r: f64,
    g: f64,
    b: f64,
    a: f64,
}

const STATIC_COLOR: Color = Color { r: 0.55, g: 0.57, b: 0.62, a: 0.85 };
const MOVING_COLOR: Color = Color { r: 0.95, g: 0.55, b: 0.15, a: 0.9 };
const PATH_COLOR: Color = Color { r: 0.2, g: 0.5, b: 1.0, a: 1.0 };
const START_COLOR: Color = Color { r: 0.2, g: 0.8, b: 0.3, a: 1.0 };
const GOAL_COLOR: Color = Color { r: 0.9, g: 0.2, b: 0.2, a: 1.0 };

/// Cube and sphere primitives (the same fields).
#[derive(Serialize)]
struct Solid {
    pose: Pose,
    size: Vec3,
    color: Color,
}

#[derive(Serialize)]
struct Cylinder {
    pose: Pose,
    size: Vec3,
    bottom_scale: f64,
    top_scale: f64,
    color: Color,
}

#[derive(Serialize)]
struct Line {
    /// 0: LINE_STRIP.
    #[serde(rename = "type")]
    kind: u8,
    pose: Pose,
    thickness: f64,
    scale_invariant: bool,
    points: Vec<Vec3>,
    color: Color,
    colors: [Color; 0],
    indices: [u32; 0],
}

#[derive(Serialize)]
struct KeyValue {
    key: &'static str,
    value: String,
}

/// `foxglove.SceneEntity`, with every primitive list present (empty where unused).
#[derive(Serialize)]
struct Entity {
    timestamp: Time,
    frame_id: &'static str,
    id: String,
    lifetime: Time,
    frame_locked: bool,
    metadata: Vec<KeyValue>,
    arrows: [u8; 0],
    cubes: Vec<Solid>,
    spheres: Vec<Solid>,
    cylinders: Vec<Cylinder>,
    lines: Vec<Line>,
    triangles: [u8; 0],
    texts: [u8; 0],
    models: [u8; 0],
}

impl Entity {
    fn new(ts: Time, id: String) -> Self {
        Entity {
            timestamp: ts,
            frame_id: WORLD_FRAME,
            id,
            lifetime: Time { sec: 0, nsec: 0 },
            frame_locked: false,
            metadata: Vec::new(),
            arrows: [],
            cubes: Vec::new(),
            spheres: Vec::new(),
            cylinders: Vec::new(),
            lines: Vec::new(),
            triangles: [],
            texts: [],
            models: [],
        }
    }
}

#[derive(Serialize)]
struct SceneUpdate {
    deletions: [u8; 0],
    entities: Vec<Entity>,
}

#[derive(Serialize)]
struct FrameTransform {
    timestamp: Time,
    parent_frame_id: &'static str,
    child_frame_id: &'static str,
    translation: Vec3,
    rotation: Quat,
}

#[derive(Serialize)]
struct VehicleState {
    timestamp: Time,
    t: Dec<4>,
    position: Vec3,
    velocity: Vec3,
    speed: Dec<4>,
    clearance: Dec<4>,
    h_bar: Dec<5>,
    filter_h_bar: Dec<5>,
    region: &'static str,
    filter_active: bool,
    mode: &'static str,
    flight_mode: &'static str,
}

#[derive(Serialize)]
struct Field {
    name: &'static str,
    offset: u32,
    /// 7: FLOAT32.
    #[serde(rename = "type")]
    kind: u8,
}

#[derive(Serialize)]
struct PointCloud<'a> {
    timestamp: Time,
    frame_id: &'static str,
    pose: Pose,
    point_stride: u32,
    fields: [Field; 3],
    data: &'a str,
}

#[derive(Serialize)]
struct Log<'a> {
    timestamp: Time,
    /// 2 INFO, 3 WARNING, 4 ERROR.
    level: u8,
    message: &'a str,
    name: &'static str,
    file: &'static str,
    line: u32,
}

/// The attitude of `base_link` (FLU) in `world` (ENU) from roll, pitch, yaw of FRD w.r.t. NED.
fn enu_flu(rpy: [f64; 3]) -> Quat {
    let ned_frd = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]).to_rotation_matrix();
    let enu_ned =
        Rotation3::from_matrix_unchecked(Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0));
    let frd_flu =
        Rotation3::from_matrix_unchecked(Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0));
    let q = UnitQuaternion::from_rotation_matrix(&(enu_ned * ned_frd * frd_flu));
    let q = if q.w < 0.0 { UnitQuaternion::new_unchecked(-q.into_inner()) } else { q };
    Quat { x: q.i, y: q.j, z: q.k, w: q.w }
}

/// The MCAP writer with its channels and sequence numbers.
struct Out<W: Write + Seek> {
    w: mcap::Writer<W>,
    /// Channel ids of `/scene`, `/tf`, `/vehicle/state`, `/ranges`, `/events`.
    ch: [u16; 5],
    seq: [u32; 5],
    buf: Vec<u8>,
}

const SCENE: usize = 0;
const TF: usize = 1;
const STATE: usize = 2;
const RANGES: usize = 3;
const EVENTS: usize = 4;

/// Topics in channel order, with their schema name and text.
pub const TOPICS: [(&str, &str); 5] = [
    ("/scene", "foxglove.SceneUpdate"),
    ("/tf", "foxglove.FrameTransform"),
    ("/vehicle/state", "parapet.VehicleState"),
    ("/ranges", "foxglove.PointCloud"),
    ("/events", "foxglove.Log"),
];

impl<W: Write + Seek> Out<W> {
    fn new(w: W) -> std::io::Result<Self> {
        let opts = mcap::WriteOptions::new().compression(None).profile("").library(concat!(
            "parapet-sim ",
            env!("CARGO_PKG_VERSION"),
            " (mcap crate)"
        ));
        let mut w = opts.create(w).map_err(io_err)?;
        let texts = [
            SCENE_UPDATE_SCHEMA,
            FRAME_TRANSFORM_SCHEMA,
            VEHICLE_STATE_SCHEMA,
            POINT_CLOUD_SCHEMA,
            LOG_SCHEMA,
        ];
        let mut ch = [0u16; 5];
        for (c, ((topic, name), text)) in ch.iter_mut().zip(TOPICS.iter().zip(texts)) {
            let schema = w.add_schema(name, "jsonschema", text.as_bytes()).map_err(io_err)?;
            *c = w.add_channel(schema, topic, "json", &BTreeMap::new()).map_err(io_err)?;
        }
        Ok(Out { w, ch, seq: [0; 5], buf: Vec::with_capacity(1024) })
    }

    fn put<T: Serialize>(&mut self, k: usize, ns: u64, msg: &T) -> std::io::Result<()> {
        self.buf.clear();
        serde_json::to_writer(&mut self.buf, msg).map_err(std::io::Error::other)?;
        let header =
            MessageHeader { channel_id: self.ch[k], sequence: self.seq[k], log_time: ns, publish_time: ns };
        self.seq[k] = self.seq[k].wrapping_add(1);
        self.w.write_to_known_channel(&header, &self.buf).map_err(io_err)
    }
}

/// The entity of obstacle `i` with shape `shape` (NED).
fn obstacle_entity(ts: Time, i: usize, name: Option<&str>, shape: &Shape, moving: bool) -> Entity {
    let mut e = Entity::new(ts, format!("obstacle/{i}"));
    let color = if moving { MOVING_COLOR } else { STATIC_COLOR };
    let enu = |a: &[f32; 3]| ned_to_enu_arr(&to_f64(&(*a).into()));
    match shape {
        Shape::Point { center } => {
            e.spheres.push(Solid { pose: Pose::at(enu(center)), size: Vec3::arr([0.1; 3]), color })
        }
        Shape::Sphere { center, radius } => {
            let d = 2.0 * f64::from(*radius);
            e.spheres.push(Solid { pose: Pose::at(enu(center)), size: Vec3::arr([d; 3]), color })
        }
        Shape::Box { min, max } => {
            let (a, b) = (enu(min), enu(max));
            let c = [0, 1, 2].map(|k| 0.5 * (a[k] + b[k]));
            let s = [0, 1, 2].map(|k| (b[k] - a[k]).abs());
            e.cubes.push(Solid { pose: Pose::at(c), size: Vec3::arr(s), color })
        }
        Shape::Cylinder { base, radius, height } => {
            let b = enu(base);
            let h = f64::from(*height);
            let d = 2.0 * f64::from(*radius);
            e.cylinders.push(Cylinder {
                pose: Pose::at([b[0], b[1], b[2] + 0.5 * h]),
                size: Vec3::arr([d, d, h]),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color,
            })
        }
    }
    if let Some(n) = name {
        e.metadata.push(KeyValue { key: "name", value: n.to_string() });
    }
    e
}

/// Base64 (RFC 4648, with padding) of `bytes` into `out`.
fn base64(bytes: &[u8], out: &mut String) {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    out.clear();
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(c.get(1).copied().unwrap_or(0)) << 8)
            | u32::from(c.get(2).copied().unwrap_or(0));
        for k in 0..4 {
            if k <= c.len() {
                out.push(char::from(A[((n >> (18 - 6 * k)) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
}

/// The range beams still to send and the buffers of one scan.
struct Scans<I: Iterator<Item = RangeRecord>> {
    beams: std::iter::Peekable<I>,
    points: Vec<u8>,
    text: String,
}

impl<I: Iterator<Item = RangeRecord>> Scans<I> {
    /// Send every scan at or before `until` (s) as a point cloud of its returns (ENU).
    fn send<W: Write + Seek>(
        &mut self,
        out: &mut Out<W>,
        until: f64,
        ns: impl Fn(f64) -> u64,
    ) -> std::io::Result<()> {
        while let Some(first) = self.beams.peek() {
            if first.t > until || (first.t.is_nan() && until.is_finite()) {
                break;
            }
            let (t, sensor) = (first.t, first.sensor);
            self.points.clear();
            // At least the first beam is taken (a NaN time equals nothing).
            let mut n = 0usize;
            while let Some(b) = self.beams.next_if(|b| n == 0 || (b.t == t && b.sensor == sensor)) {
                n += 1;
                if let Some(p) = b.point {
                    // NED → ENU: (y, x, −z).
                    for v in [p[1], p[0], -p[2]] {
                        self.points.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
            base64(&self.points, &mut self.text);
            let ts = ns(t);
            let msg = PointCloud {
                timestamp: Time::of_ns(ts),
                frame_id: WORLD_FRAME,
                pose: Pose::at([0.0; 3]),
                point_stride: 12,
                fields: [
                    Field { name: "x", offset: 0, kind: 7 },
                    Field { name: "y", offset: 4, kind: 7 },
                    Field { name: "z", offset: 8, kind: 7 },
                ],
                data: &self.text,
            };
            out.put(RANGES, ts, &msg)?;
        }
        Ok(())
    }
}

/// Write `rec` as MCAP to `path`; `clock` maps a sample's time (s) to the controller clock (µs)
/// as for the ULog (`crate::flight::stack::clock_us`).
pub fn write_flight_mcap(path: &Path, rec: &RunRecord, clock: fn(f64) -> u64) -> Result<()> {
    let file = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut out = Out::new(std::io::BufWriter::new(file))
        .with_context(|| format!("cannot write {}", path.display()))?;
    write_messages(&mut out, rec, clock).with_context(|| format!("cannot write {}", path.display()))?;
    out.w.finish().map_err(io_err).with_context(|| format!("cannot write {}", path.display()))?;
    let mut inner = out.w.into_inner();
    inner.flush().with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

fn write_messages<W: Write + Seek>(
    out: &mut Out<W>,
    rec: &RunRecord,
    clock: fn(f64) -> u64,
) -> std::io::Result<()> {
    let ns = |t: f64| clock(t).saturating_mul(1000);
    let t0 = rec.samples.first().map_or(0.0, |s| s.t);
    let ns0 = ns(t0);
    let ts0 = Time::of_ns(ns0);
    let scene = rec.scene;
    // The whole scene at the first sample.
    let mut entities: Vec<Entity> = scene
        .obstacles
        .iter()
        .enumerate()
        .map(|(i, o)| obstacle_entity(ts0, i, o.name.as_deref(), &o.at(t0).0, !o.is_static()))
        .collect();
    let mut path = Entity::new(ts0, "path".into());
    path.lines.push(Line {
        kind: 0,
        pose: Pose::at([0.0; 3]),
        thickness: 0.04,
        scale_invariant: false,
        points: rec.path.iter().map(Vec3::enu).collect(),
        color: PATH_COLOR,
        colors: [],
        indices: [],
    });
    entities.push(path);
    for (id, p, color) in [("start", scene.start, START_COLOR), ("goal", scene.goal, GOAL_COLOR)] {
        let mut e = Entity::new(ts0, id.into());
        e.spheres.push(Solid { pose: Pose::at(ned_to_enu_arr(&p)), size: Vec3::arr([0.2; 3]), color });
        entities.push(e);
    }
    out.put(SCENE, ns0, &SceneUpdate { deletions: [], entities })?;

    let moving: Vec<usize> =
        scene.obstacles.iter().enumerate().filter(|(_, o)| !o.is_static()).map(|(i, _)| i).collect();
    let mut next_update = t0 + SCENE_UPDATE_PERIOD_S;
    // Scans in time order, grouped by (t, sensor); sent before the first sample at or after them.
    let mut scans = Scans { beams: rec.ranges.iter().peekable(), points: Vec::new(), text: String::new() };
    let mut last: Option<&Sample> = None;
    let collision = rec.summary.first_collision_time_s;
    let mut collision_sent = false;
    let mut msg = String::new();
    for s in rec.samples {
        scans.send(out, s.t, ns)?;
        let ts_ns = ns(s.t);
        let ts = Time::of_ns(ts_ns);
        out.put(
            TF,
            ts_ns,
            &FrameTransform {
                timestamp: ts,
                parent_frame_id: WORLD_FRAME,
                child_frame_id: BODY_FRAME,
                translation: Vec3::enu(&s.pos),
                rotation: enu_flu(s.rpy),
            },
        )?;
        out.put(
            STATE,
            ts_ns,
            &VehicleState {
                timestamp: ts,
                t: Dec(s.t),
                position: Vec3::enu(&s.pos),
                velocity: Vec3::enu(&s.vel),
                speed: Dec(s.vel.norm()),
                clearance: Dec(s.clearance),
                h_bar: Dec(s.h_bar),
                filter_h_bar: Dec(f64::from(s.filter.h_bar)),
                region: region_name(s.filter.region),
                filter_active: s.filter.intervened,
                mode: s.mode.as_str(),
                flight_mode: s.flight_mode.as_str(),
            },
        )?;
        let event = |out: &mut Out<W>, level: u8, text: &str| {
            out.put(
                EVENTS,
                ts_ns,
                &Log { timestamp: ts, level, message: text, name: "parapet", file: "", line: 0 },
            )
        };
        match last {
            None => {
                msg.clear();
                msg.push_str(&format!(
                    "start: flight mode {}, guidance {}",
                    s.flight_mode.as_str(),
                    s.mode.as_str()
                ));
                event(out, 2, &msg)?;
            }
            Some(p) => {
                if p.flight_mode != s.flight_mode {
                    msg = format!("flight mode {} -> {}", p.flight_mode.as_str(), s.flight_mode.as_str());
                    event(out, 2, &msg)?;
                }
                if p.mode != s.mode {
                    msg = format!("guidance {} -> {}", p.mode.as_str(), s.mode.as_str());
                    event(out, 2, &msg)?;
                }
            }
        }
        if let Some(tc) = collision {
            if !collision_sent && s.t >= tc {
                collision_sent = true;
                let with = rec.summary.collision_with.as_deref().unwrap_or("?");
                msg = format!("collision with {with} at t = {tc:.4} s");
                event(out, 4, &msg)?;
            }
        }
        if !moving.is_empty() && s.t >= next_update {
            while next_update <= s.t {
                next_update += SCENE_UPDATE_PERIOD_S;
            }
            let entities = moving
                .iter()
                .map(|&i| {
                    let o = &scene.obstacles[i];
                    obstacle_entity(ts, i, o.name.as_deref(), &o.at(s.t).0, true)
                })
                .collect();
            out.put(SCENE, ts_ns, &SceneUpdate { deletions: [], entities })?;
        }
        last = Some(s);
    }
    scans.send(out, f64::INFINITY, ns)?;
    if let Some(s) = last {
        let ts_ns = ns(s.t);
        let text = format!("end: {}", rec.summary.end_reason);
        out.put(
            EVENTS,
            ts_ns,
            &Log {
                timestamp: Time::of_ns(ts_ns),
                level: 2,
                message: &text,
                name: "parapet",
                file: "",
                line: 0,
            },
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_pads_like_rfc_4648() {
        let mut s = String::new();
        for (input, want) in
            [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foobar", "Zm9vYmFy")]
        {
            base64(input.as_bytes(), &mut s);
            assert_eq!(s, want, "{input}");
        }
    }

    /// Level flight heading north (yaw 0 in NED) is base_link's x along world y (ENU north);
    /// yaw 90° (east) puts it along world x.
    #[test]
    fn attitude_is_flu_in_enu() {
        let rot = |q: Quat| UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
        let q = rot(enu_flu([0.0, 0.0, 0.0]));
        assert!((q * Vector3::x() - Vector3::y()).norm() < 1e-12);
        assert!((q * Vector3::z() - Vector3::z()).norm() < 1e-12);
        let q = rot(enu_flu([0.0, 0.0, std::f64::consts::FRAC_PI_2]));
        assert!((q * Vector3::x() - Vector3::x()).norm() < 1e-12);
        // Nose-up pitch (FRD about y): forward tilts up (ENU +z).
        let q = rot(enu_flu([0.0, 0.3, 0.0]));
        assert!((q * Vector3::x()).z > 0.2);
    }
}
