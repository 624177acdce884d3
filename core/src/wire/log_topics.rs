//! The topics of a flight log and their records, defined once for the firmware's onboard log
//! and the host's `flight.ulg` (so the same tools plot both), written with [`super::ulog`].
//!
//! Names and fields follow PX4's uORB messages where one exists; frame NED, SI units. One
//! record set ([`FlightRecord`], six `D` messages in [`FLIGHT_TOPICS`] order) per logged step.
//!
//! | topic | fields |
//! |---|---|
//! | `vehicle_local_position` | `x y z` (m), `vx vy vz` (m/s), `heading` (rad), `xy_valid z_valid v_xy_valid v_z_valid` (always 1) |
//! | `vehicle_attitude` | `q[4]` (w, x, y, z; body FRD → NED) |
//! | `vehicle_attitude_setpoint` | `roll_body pitch_body yaw_body` (rad), `q_d[4]`, `thrust_body[3]` (`[0, 0, −thrust/THR_MAX]`) |
//! | `actuator_motors` | `timestamp_sample`, `control[12]` (throttle 0..1 of rotors 1-4, NaN for unused outputs as in PX4) |
//! | `vehicle_status` | `arming_state` (1 disarmed, 2 armed), `nav_state` (PX4's, [`super::modes`]), `parapet_mode` ([`GuidanceMode::code`]) |
//! | `cbf_status` | `h_bar` (true min h̄, m²; NaN without ground truth), `h_bar_filter` (the filter's own, m²), `clearance` (m; NaN without ground truth), `region` ([`crate::cbf::Region::code`]), `active_id` (−1 none), `n_constraints`, `intervened`, `unavoidable`, `infeasible`, `u_nominal[3]` (u*, m/s²), `u[3]` (m/s²), `gov_limit` (the speed governor's limit along the motion, m/s; NaN none), `gov_cause` ([`crate::governor::GovernorCause`]) |
//!
//! A log is [`write_definitions`] once (header, formats, infos, parameters, subscriptions),
//! then [`write_records`] per step. May import: [`super::ulog`], [`super::modes`] and the types
//! it names ([`crate::cbf::FilterDiagnostics`], the mode types).

use super::ulog::{
    write_data, write_format, write_header, write_info, write_param_f32, write_subscription, Record, Topic,
    ULogSink,
};
use crate::cbf::FilterDiagnostics;
use crate::outer::guidance::GuidanceMode;
use crate::supervisor::modes::FlightMode;

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
        ("float", "gov_limit"),
        ("uint8_t", "gov_cause"),
    ],
};

/// Every topic of a flight log, in message-id order.
pub const FLIGHT_TOPICS: [Topic; 6] =
    [LOCAL_POSITION, ATTITUDE, ATTITUDE_SETPOINT, MOTORS, STATUS, CBF_STATUS];

/// One logged step: what the six records of [`FLIGHT_TOPICS`] carry (NED, SI units). Each side
/// fills it from its own state (the host from the true state, the firmware from its estimate).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlightRecord {
    /// Timestamp of every record of the set, µs.
    pub t_us: u64,
    /// Position, m.
    pub position: [f32; 3],
    /// Velocity, m/s.
    pub velocity: [f32; 3],
    /// Heading (yaw), rad.
    pub heading: f32,
    /// Attitude quaternion (w, x, y, z), body FRD → NED.
    pub attitude_q: [f32; 4],
    /// Attitude setpoint roll, pitch, yaw, rad.
    pub setpoint_rpy: [f32; 3],
    /// Attitude setpoint quaternion (w, x, y, z).
    pub setpoint_q: [f32; 4],
    /// Collective thrust normalised by `THR_MAX` (0..1).
    pub thrust_norm: f32,
    /// Throttles 0..1 of rotors 1-4 (PX4 numbering).
    pub motors: [f32; 4],
    /// Motors armed.
    pub armed: bool,
    /// The guidance mode of the step.
    pub guidance: GuidanceMode,
    /// The selected flight mode.
    pub mode: FlightMode,
    /// True minimum h̄ over the obstacles, m² (NaN without ground truth).
    pub h_bar_true: f32,
    /// Clearance to the nearest obstacle, m (NaN without ground truth).
    pub clearance: f32,
    /// The filter's report of the step.
    pub filter: FilterDiagnostics,
    /// Nominal acceleration u*, m/s².
    pub u_nominal: [f32; 3],
    /// Filtered acceleration u, m/s².
    pub u: [f32; 3],
    /// The speed governor's limit along the motion, m/s (NaN: none).
    pub governor_limit: f32,
    /// What sets it ([`crate::governor::GovernorCause`] as `u8`).
    pub governor_cause: u8,
}

/// Header (start `t0_us`), the formats of [`FLIGHT_TOPICS`], the infos `sys_name` (Parapet),
/// `ver_sw` and `infos`, a `float` parameter per `params` entry, and the subscriptions
/// (message id = index in [`FLIGHT_TOPICS`]).
pub fn write_definitions<'a, S: ULogSink>(
    sink: &mut S,
    t0_us: u64,
    ver_sw: &str,
    infos: impl IntoIterator<Item = (&'a str, &'a str)>,
    params: impl IntoIterator<Item = (&'a str, f32)>,
) -> Result<(), S::Error> {
    write_header(sink, t0_us)?;
    for t in &FLIGHT_TOPICS {
        write_format(sink, t)?;
    }
    write_info(sink, "sys_name", "Parapet")?;
    write_info(sink, "ver_sw", ver_sw)?;
    for (k, v) in infos {
        write_info(sink, k, v)?;
    }
    for (name, v) in params {
        write_param_f32(sink, name, v)?;
    }
    for (id, t) in (0u16..).zip(FLIGHT_TOPICS.iter()) {
        write_subscription(sink, id, t.name)?;
    }
    Ok(())
}

/// The six records of one step (`D` messages, ids in [`FLIGHT_TOPICS`] order).
pub fn write_records<S: ULogSink>(sink: &mut S, r: &FlightRecord) -> Result<(), S::Error> {
    let ts = r.t_us;
    let (p, v) = (r.position, r.velocity);
    let pos = Record::at(ts).f32s(&[p[0], p[1], p[2], v[0], v[1], v[2], r.heading]).u8(1).u8(1).u8(1).u8(1);
    write_data(sink, 0, &pos)?;
    write_data(sink, 1, &Record::at(ts).f32s(&r.attitude_q))?;
    let sp = Record::at(ts).f32s(&r.setpoint_rpy).f32s(&r.setpoint_q).f32s(&[0.0, 0.0, -r.thrust_norm]);
    write_data(sink, 2, &sp)?;
    let mut control = [f32::NAN; 12];
    for (c, m) in control.iter_mut().zip(r.motors) {
        *c = m;
    }
    write_data(sink, 3, &Record::at(ts).u64(ts).f32s(&control))?;
    let arming = if r.armed { 2 } else { 1 };
    let nav_state = super::modes::px4_nav_state(r.guidance, r.mode);
    write_data(sink, 4, &Record::at(ts).u8(arming).u8(nav_state).u8(r.guidance.code()))?;
    let f = &r.filter;
    let status = Record::at(ts)
        .f32s(&[r.h_bar_true, f.h_bar, r.clearance])
        .u8(f.region.code())
        .i32(f.active_id.map(i32::from).unwrap_or(-1))
        .u8(f.n_constraints)
        .u8(u8::from(f.intervened))
        .u8(u8::from(f.unavoidable))
        .u8(u8::from(f.infeasible))
        .f32s(&r.u_nominal)
        .f32s(&r.u)
        .f32s(&[r.governor_limit])
        .u8(r.governor_cause);
    write_data(sink, 5, &status)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::super::ulog::tests::{parse, VecSink};
    use super::*;
    use crate::cbf::Region;
    use std::vec::Vec;

    fn record() -> FlightRecord {
        FlightRecord {
            t_us: 5,
            position: [1.0, 2.0, -3.0],
            velocity: [0.5, 0.0, 0.0],
            heading: 0.25,
            attitude_q: [1.0, 0.0, 0.0, 0.0],
            setpoint_rpy: [0.0; 3],
            setpoint_q: [1.0, 0.0, 0.0, 0.0],
            thrust_norm: 0.5,
            motors: [0.4, 0.41, 0.42, 0.43],
            armed: true,
            guidance: GuidanceMode::Return,
            mode: FlightMode::Return,
            h_bar_true: f32::NAN,
            clearance: 2.0,
            filter: FilterDiagnostics::new(Region::Far),
            u_nominal: [0.0; 3],
            u: [0.0, 0.0, 1.0],
            governor_limit: 2.5,
            governor_cause: 3,
        }
    }

    #[test]
    fn every_record_matches_its_topic_format() {
        let mut s = VecSink(Vec::new());
        write_definitions(&mut s, 1, "0.1.0", [("parapet_board", "test")], [("CBF_MU", 1.0)]).unwrap();
        write_records(&mut s, &record()).unwrap();
        let msgs = parse(&s.0);
        let types: Vec<u8> = msgs.iter().map(|m| m.0).collect();
        assert_eq!(types, b"BFFFFFFIIIPAAAAAADDDDDD".to_vec());
        let data: Vec<_> = msgs.iter().filter(|m| m.0 == b'D').collect();
        for (id, (t, d)) in FLIGHT_TOPICS.iter().zip(&data).enumerate() {
            assert_eq!(u16::from_le_bytes([d.1[0], d.1[1]]) as usize, id);
            assert_eq!(d.1.len() - 2, t.size().unwrap(), "{}", t.name);
        }
        // vehicle_status: armed, PX4's AUTO_RTL (5), the guidance code.
        assert_eq!(&data[4].1[10..], &[2, 5, GuidanceMode::Return.code()]);
        // thrust_body z is −thrust/THR_MAX; unused motor outputs NaN.
        assert_eq!(f32::from_le_bytes(data[2].1[2 + 8 + 36..][..4].try_into().unwrap()), -0.5);
        assert!(f32::from_le_bytes(data[3].1[2 + 16 + 16..][..4].try_into().unwrap()).is_nan());
        // cbf_status ends with the governor's limit and cause.
        let st = &data[5].1;
        assert_eq!(f32::from_le_bytes(st[st.len() - 5..][..4].try_into().unwrap()), 2.5);
        assert_eq!(st[st.len() - 1], 3);
    }
}
