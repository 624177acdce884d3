//! Flight logs in PX4's ULog format (`flight.ulg`), readable by `pyulog`
//! (`ulog_info`), PlotJuggler and PX4 Flight Review.
//!
//! Written by hand: crates.io has ULog *parsers* (`ulog-rs`, `px4-ulog`, `yule_log`) but no
//! writer, and the format is small. What is written, per the ULog file format spec
//! (docs.px4.io, "ULog File Format", version 1):
//!
//! * header: magic `ULog\x01\x12\x35`, version 1, start timestamp (µs, u64 LE);
//! * `B` flag bits (no compat/incompat flags, no appended data);
//! * definitions: `F` formats (`name:type field;…`, `timestamp` first), `I` infos
//!   (`sys_name`, `ver_sw`, …), `P` parameters (every entry of the parameter table as
//!   `float NAME`);
//! * data: one `A` subscription per topic (multi id 0), then `D` data messages in time order.
//!
//! All multi-byte values are little-endian, fields packed without padding (the format message
//! describes exactly the bytes that follow). Timestamps are the caller's clock (µs; the CLI
//! passes the controller clock `crate::flight::stack::clock_us`: simulated time + 1 s, as in
//! the firmware's MAVLink).
//!
//! ## Topics of a flight ([`write_flight_ulog`]), one record per outer step (250 Hz)
//! Names and fields follow PX4's uORB messages where one exists; frame NED, SI units.
//!
//! | topic | fields |
//! |---|---|
//! | `vehicle_local_position` | `x y z` (m), `vx vy vz` (m/s), `heading` (rad), `xy_valid z_valid v_xy_valid v_z_valid` — the true state |
//! | `vehicle_attitude` | `q[4]` (w, x, y, z; body FRD → NED) |
//! | `vehicle_attitude_setpoint` | `roll_body pitch_body yaw_body` (rad), `q_d[4]`, `thrust_body[3]` (normalised by `THR_MAX`): recomputed from the filtered `u` with the controller's thrust map (eq. 4-5, `parapet_core::thrust::map_acceleration`) at the measured yaw |
//! | `actuator_motors` | `timestamp_sample`, `control[12]` (throttle 0..1 of rotors 1-4, NaN for unused outputs as in PX4) |
//! | `vehicle_status` | `arming_state` (1 disarmed, 2 armed), `nav_state` (PX4's codes of the flight and guidance mode, `parapet_core::wire::modes::px4_nav_state`: 0 manual, 2 position, 3 mission, 4 hold/brake, 5 return, 12 descend (no fix), 14 offboard, 17 takeoff, 18 land), `parapet_mode` (the guidance mode's code, `GuidanceMode::code`: its index in `GuidanceMode::ALL`) |
//! | `cbf_status` | `h_bar` (true min h̄, m²), `h_bar_filter` (the filter's own, m²), `clearance` (m), `region` (`Region::code`, [`REGIONS`] index), `active_id` (−1 none), `n_constraints`, `intervened`, `unavoidable`, `infeasible`, `u_nominal[3]` (u*, m/s²), `u[3]` (m/s²) |
//!
//! May import: `parapet-core` (parameters, thrust map), [`super`] (the samples).

use std::io::{self, Write};
use std::path::Path;

use anyhow::{Context, Result};
use nalgebra::{UnitQuaternion, Vector3};
use parapet_core::controller::ControllerParams;
use parapet_core::params::TABLE;
use parapet_core::thrust::map_acceleration;
use parapet_core::wire::modes::px4_nav_state;

use super::Sample;

/// File name of the flight log in a run's report directory.
pub const FLIGHT_LOG: &str = "flight.ulg";

/// ULog file magic (7 bytes) and the version byte.
pub const MAGIC: [u8; 8] = [0x55, 0x4c, 0x6f, 0x67, 0x01, 0x12, 0x35, 0x01];

/// One topic: its name and fields as `(type, name)`; the first field must be
/// `("uint64_t", "timestamp")`. Types: `uint8_t int8_t uint16_t int16_t uint32_t int32_t
/// uint64_t int64_t float double bool char`, each optionally as an array `T[N]`.
#[derive(Clone, Copy, Debug)]
pub struct Topic {
    /// uORB-style name, e.g. `vehicle_local_position`.
    pub name: &'static str,
    /// `(type, field)` pairs, `timestamp` first.
    pub fields: &'static [(&'static str, &'static str)],
}

impl Topic {
    /// Size of one record in bytes; `None` for an unknown type.
    pub fn size(&self) -> Option<usize> {
        self.fields.iter().map(|(t, _)| type_size(t)).sum()
    }
}

fn type_size(t: &str) -> Option<usize> {
    let (base, n) = match t.split_once('[') {
        Some((b, rest)) => (b, rest.strip_suffix(']')?.parse::<usize>().ok()?),
        None => (t, 1),
    };
    let s = match base {
        "uint8_t" | "int8_t" | "bool" | "char" => 1,
        "uint16_t" | "int16_t" => 2,
        "uint32_t" | "int32_t" | "float" => 4,
        "uint64_t" | "int64_t" | "double" => 8,
        _ => return None,
    };
    Some(s * n)
}

/// One data record, built field by field in the topic's order (little-endian).
#[derive(Default)]
pub struct Record(Vec<u8>);

impl Record {
    /// A record starting with its timestamp (µs).
    pub fn at(timestamp_us: u64) -> Self {
        Record(timestamp_us.to_le_bytes().to_vec())
    }
    /// `float` fields.
    pub fn f32s(mut self, v: &[f32]) -> Self {
        v.iter().for_each(|x| self.0.extend_from_slice(&x.to_le_bytes()));
        self
    }
    /// A `uint8_t` / `bool` field.
    pub fn u8(mut self, v: u8) -> Self {
        self.0.push(v);
        self
    }
    /// An `int32_t` field.
    pub fn i32(mut self, v: i32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// A `uint64_t` field.
    pub fn u64(mut self, v: u64) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
}

/// Streaming ULog writer: [`ULogWriter::new`] writes the header and flag bits; then the
/// definitions ([`ULogWriter::info`], [`ULogWriter::param_f32`], [`ULogWriter::subscribe`]
/// writes the format); [`ULogWriter::data`] starts the data section (all subscriptions are
/// written before the first data message).
pub struct ULogWriter<W: Write> {
    w: W,
    topics: Vec<(Topic, usize)>,
    data_started: bool,
}

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

impl<W: Write> ULogWriter<W> {
    /// Header (start time `t0_us`) and flag bits.
    pub fn new(mut w: W, t0_us: u64) -> io::Result<Self> {
        w.write_all(&MAGIC)?;
        w.write_all(&t0_us.to_le_bytes())?;
        let mut me = ULogWriter { w, topics: Vec::new(), data_started: false };
        me.message(b'B', &[0u8; 40])?;
        Ok(me)
    }

    fn message(&mut self, ty: u8, payload: &[u8]) -> io::Result<()> {
        let n = u16::try_from(payload.len())
            .map_err(|_| invalid(format!("ULog message of {} bytes (at most 65535)", payload.len())))?;
        self.w.write_all(&n.to_le_bytes())?;
        self.w.write_all(&[ty])?;
        self.w.write_all(payload)
    }

    fn definition(&self, what: &str) -> io::Result<()> {
        if self.data_started {
            return Err(invalid(format!("ULog {what} after the first data message")));
        }
        Ok(())
    }

    /// `I` message: a string info `key` (e.g. `sys_name`).
    pub fn info(&mut self, key: &str, value: &str) -> io::Result<()> {
        self.definition("info")?;
        self.key_value(b'I', &format!("char[{}] {key}", value.len()), value.as_bytes())
    }

    /// `P` message: a `float` parameter.
    pub fn param_f32(&mut self, name: &str, value: f32) -> io::Result<()> {
        self.definition("parameter")?;
        self.key_value(b'P', &format!("float {name}"), &value.to_le_bytes())
    }

    fn key_value(&mut self, ty: u8, key: &str, value: &[u8]) -> io::Result<()> {
        let k = u8::try_from(key.len()).map_err(|_| invalid(format!("ULog key {key:?} longer than 255")))?;
        let mut p = vec![k];
        p.extend_from_slice(key.as_bytes());
        p.extend_from_slice(value);
        self.message(ty, &p)
    }

    /// `F` message of `topic`; returns its message id (for [`ULogWriter::data`]).
    pub fn subscribe(&mut self, topic: Topic) -> io::Result<u16> {
        self.definition("format")?;
        if topic.fields.first() != Some(&("uint64_t", "timestamp")) {
            return Err(invalid(format!(
                "ULog topic {}: the first field must be uint64_t timestamp",
                topic.name
            )));
        }
        let size =
            topic.size().ok_or_else(|| invalid(format!("ULog topic {}: unknown field type", topic.name)))?;
        let mut f = format!("{}:", topic.name);
        for (t, n) in topic.fields {
            f.push_str(&format!("{t} {n};"));
        }
        self.message(b'F', f.as_bytes())?;
        let id = u16::try_from(self.topics.len()).map_err(|_| invalid("too many ULog topics".into()))?;
        self.topics.push((topic, size));
        Ok(id)
    }

    /// `D` message of topic `id` (the `A` subscriptions are written before the first one).
    pub fn data(&mut self, id: u16, rec: &Record) -> io::Result<()> {
        if !self.data_started {
            self.data_started = true;
            for i in 0..self.topics.len() {
                let mut p = vec![0u8];
                p.extend_from_slice(&(i as u16).to_le_bytes());
                p.extend_from_slice(self.topics[i].0.name.as_bytes());
                self.message(b'A', &p)?;
            }
        }
        let (topic, size) =
            self.topics.get(usize::from(id)).ok_or_else(|| invalid(format!("no ULog topic {id}")))?;
        if rec.0.len() != *size {
            return Err(invalid(format!(
                "ULog {}: record of {} bytes, format has {size}",
                topic.name,
                rec.0.len()
            )));
        }
        let mut p = id.to_le_bytes().to_vec();
        p.extend_from_slice(&rec.0);
        self.message(b'D', &p)
    }

    /// Flush and return the inner writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.w.flush()?;
        Ok(self.w)
    }
}

/// Filter regions in `cbf_status.region` order.
pub const REGIONS: [&str; 5] = parapet_core::cbf::Region::NAMES;

const LOCAL_POSITION: Topic = Topic {
    name: "vehicle_local_position",
    fields: &[
        ("uint64_t", "timestamp"),
        ("float", "x"),
        ("float", "y"),
        ("float", "z"),
        ("float", "vx"),
        ("float", "vy"),
        ("float", "vz"),
        ("float", "heading"),
        ("bool", "xy_valid"),
        ("bool", "z_valid"),
        ("bool", "v_xy_valid"),
        ("bool", "v_z_valid"),
    ],
};
const ATTITUDE: Topic =
    Topic { name: "vehicle_attitude", fields: &[("uint64_t", "timestamp"), ("float[4]", "q")] };
const ATTITUDE_SETPOINT: Topic = Topic {
    name: "vehicle_attitude_setpoint",
    fields: &[
        ("uint64_t", "timestamp"),
        ("float", "roll_body"),
        ("float", "pitch_body"),
        ("float", "yaw_body"),
        ("float[4]", "q_d"),
        ("float[3]", "thrust_body"),
    ],
};
const MOTORS: Topic = Topic {
    name: "actuator_motors",
    fields: &[("uint64_t", "timestamp"), ("uint64_t", "timestamp_sample"), ("float[12]", "control")],
};
const STATUS: Topic = Topic {
    name: "vehicle_status",
    fields: &[
        ("uint64_t", "timestamp"),
        ("uint8_t", "arming_state"),
        ("uint8_t", "nav_state"),
        ("uint8_t", "parapet_mode"),
    ],
};
const CBF_STATUS: Topic = Topic {
    name: "cbf_status",
    fields: &[
        ("uint64_t", "timestamp"),
        ("float", "h_bar"),
        ("float", "h_bar_filter"),
        ("float", "clearance"),
        ("uint8_t", "region"),
        ("int32_t", "active_id"),
        ("uint8_t", "n_constraints"),
        ("bool", "intervened"),
        ("bool", "unavoidable"),
        ("bool", "infeasible"),
        ("float[3]", "u_nominal"),
        ("float[3]", "u"),
    ],
};

/// Every topic of a flight log, in message-id order.
pub const FLIGHT_TOPICS: [Topic; 6] =
    [LOCAL_POSITION, ATTITUDE, ATTITUDE_SETPOINT, MOTORS, STATUS, CBF_STATUS];

fn quat(roll: f64, pitch: f64, yaw: f64) -> [f32; 4] {
    let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
    [q.w as f32, q.i as f32, q.j as f32, q.k as f32]
}

fn v3(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// Write the flight log of `samples` (flown with `params`) to `path`; `infos` are extra
/// `I` string infos (e.g. `("parapet_stack", "pil")`); `clock` maps a sample's time (s) to
/// the log's timestamps (µs; the controller clock `crate::flight::stack::clock_us`).
pub fn write_flight_ulog(
    path: &Path,
    samples: &[Sample],
    params: &ControllerParams,
    infos: &[(&str, String)],
    clock: fn(f64) -> u64,
) -> Result<()> {
    let file = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let t_us = clock;
    let t0 = samples.first().map(|s| t_us(s.t)).unwrap_or(0);
    let write = || -> io::Result<()> {
        let mut w = ULogWriter::new(io::BufWriter::new(file), t0)?;
        let mut ids = [0u16; FLIGHT_TOPICS.len()];
        for (id, t) in ids.iter_mut().zip(FLIGHT_TOPICS) {
            *id = w.subscribe(t)?;
        }
        w.info("sys_name", "Parapet")?;
        w.info("ver_sw", env!("CARGO_PKG_VERSION"))?;
        for (k, v) in infos {
            w.info(k, v)?;
        }
        for p in &TABLE {
            w.param_f32(p.name, (p.get)(params))?;
        }
        for s in samples {
            let ts = t_us(s.t);
            let [roll, pitch, yaw] = s.rpy;
            w.data(
                ids[0],
                &Record::at(ts)
                    .f32s(&v3(&s.pos))
                    .f32s(&v3(&s.vel))
                    .f32s(&[yaw as f32])
                    .u8(1)
                    .u8(1)
                    .u8(1)
                    .u8(1),
            )?;
            w.data(ids[1], &Record::at(ts).f32s(&quat(roll, pitch, yaw)))?;
            let u =
                parapet_core::Vec3::new(s.u_filtered.x as f32, s.u_filtered.y as f32, s.u_filtered.z as f32);
            let sp = map_acceleration(
                &params.thrust,
                params.airframe.mass,
                &u,
                yaw as f32,
                roll as f32,
                pitch as f32,
            );
            let thrust_norm = sp.thrust / params.thrust.thrust_max;
            w.data(
                ids[2],
                &Record::at(ts)
                    .f32s(&[sp.roll, sp.pitch, sp.yaw])
                    .f32s(&quat(f64::from(sp.roll), f64::from(sp.pitch), f64::from(sp.yaw)))
                    .f32s(&[0.0, 0.0, -thrust_norm]),
            )?;
            let mut control = [f32::NAN; 12];
            control[..4].copy_from_slice(&s.motors);
            w.data(ids[3], &Record::at(ts).u64(ts).f32s(&control))?;
            let armed = if s.mode.motors_on() { 2 } else { 1 };
            let nav_state = px4_nav_state(s.mode, s.flight_mode);
            w.data(ids[4], &Record::at(ts).u8(armed).u8(nav_state).u8(s.mode.code()))?;
            let f = &s.filter;
            w.data(
                ids[5],
                &Record::at(ts)
                    .f32s(&[s.h_bar as f32, f.h_bar, s.clearance as f32])
                    .u8(f.region.code())
                    .i32(f.active_id.map(i32::from).unwrap_or(-1))
                    .u8(f.n_constraints)
                    .u8(u8::from(f.intervened))
                    .u8(u8::from(f.unavoidable))
                    .u8(u8::from(f.infeasible))
                    .f32s(&v3(&s.u_nominal))
                    .f32s(&v3(&s.u_filtered)),
            )?;
        }
        w.finish()?;
        Ok(())
    };
    write().with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Minimal ULog reader for the tests: (formats, data messages (msg_id, bytes)).
    fn parse(bytes: &[u8]) -> (Vec<String>, Vec<(u8, Vec<u8>)>) {
        assert_eq!(&bytes[..8], &MAGIC);
        let mut i = 16;
        let mut msgs = Vec::new();
        let mut formats = Vec::new();
        while i < bytes.len() {
            let n = u16::from_le_bytes([bytes[i], bytes[i + 1]]) as usize;
            let ty = bytes[i + 2];
            let p = bytes[i + 3..i + 3 + n].to_vec();
            if ty == b'F' {
                formats.push(String::from_utf8(p.clone()).expect("ascii"));
            }
            msgs.push((ty, p));
            i += 3 + n;
        }
        assert_eq!(i, bytes.len(), "messages tile the file");
        (formats, msgs)
    }

    #[test]
    fn writer_layout_follows_the_spec() {
        let t =
            Topic { name: "t", fields: &[("uint64_t", "timestamp"), ("float[2]", "v"), ("uint8_t", "k")] };
        assert_eq!(t.size(), Some(17));
        let mut w = ULogWriter::new(Vec::new(), 7).expect("header");
        let id = w.subscribe(t).expect("format");
        w.info("sys_name", "X").expect("info");
        w.param_f32("CBF_MU", 1.5).expect("param");
        w.data(id, &Record::at(9).f32s(&[1.0, 2.0]).u8(3)).expect("data");
        // Wrong record size and definitions after data are refused.
        assert!(w.data(id, &Record::at(9).u8(3)).is_err());
        assert!(w.info("late", "x").is_err());
        let bytes = w.finish().expect("finish");
        assert_eq!(u64::from_le_bytes(bytes[8..16].try_into().expect("8")), 7);
        let (formats, msgs) = parse(&bytes);
        let types: Vec<u8> = msgs.iter().map(|m| m.0).collect();
        assert_eq!(types, b"BFIPAD".to_vec());
        assert_eq!(msgs[0].1.len(), 40);
        assert_eq!(formats, ["t:uint64_t timestamp;float[2] v;uint8_t k;"]);
        assert_eq!(msgs[2].1, [b"\x10char[1] sys_nameX".as_slice()].concat());
        assert_eq!(&msgs[3].1[..13], b"\x0cfloat CBF_MU");
        assert_eq!(msgs[4].1, [0u8, 0, 0, b't']);
        let d = &msgs[5].1;
        assert_eq!(d.len(), 2 + 17);
        assert_eq!(f32::from_le_bytes(d[14..18].try_into().expect("4")), 2.0);
        assert_eq!(d[18], 3);
    }

    #[test]
    fn bad_topics_are_refused() {
        let mut w = ULogWriter::new(Vec::new(), 0).expect("header");
        assert!(w.subscribe(Topic { name: "a", fields: &[("float", "x")] }).is_err());
        assert!(w
            .subscribe(Topic { name: "b", fields: &[("uint64_t", "timestamp"), ("quat", "q")] })
            .is_err());
        assert!(w.data(3, &Record::at(0)).is_err());
    }

    #[test]
    fn flight_topics_have_px4_names_and_valid_types() {
        for t in FLIGHT_TOPICS {
            assert!(t.size().is_some(), "{}", t.name);
        }
        let names: Vec<_> = FLIGHT_TOPICS.iter().map(|t| t.name).collect();
        for n in [
            "vehicle_local_position",
            "vehicle_attitude",
            "vehicle_attitude_setpoint",
            "actuator_motors",
            "vehicle_status",
            "cbf_status",
        ] {
            assert!(names.contains(&n), "{n}");
        }
        // The attitude quaternion is PX4's (w, x, y, z), body → NED: yaw 90° about +z (down).
        let q = quat(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        assert!((q[0] - q[3]).abs() < 1e-6 && q[1] == 0.0 && q[2] == 0.0 && q[3] > 0.0, "{q:?}");
    }
}
