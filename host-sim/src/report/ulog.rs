//! Flight logs in PX4's ULog format (`flight.ulg`), readable by `pyulog`
//! (`ulog_info`), PlotJuggler and PX4 Flight Review.
//!
//! The encoding and the topics are the firmware's onboard log's, defined once in the core:
//! `parapet_core::wire::ulog` (the `no_std` writer: header, `B` flags, `F` formats, `I` infos,
//! `P` parameters — every entry of the parameter table as `float NAME` —, `A` subscriptions,
//! `D` data) and `parapet_core::wire::log_topics` (the six topics and their records); this
//! module fills a record per sample from the true state and writes it to a file. Timestamps are the caller's clock (µs; the CLI
//! passes the controller clock `crate::flight::stack::clock_us`: simulated time + 1 s, as in
//! the firmware's MAVLink).
//!
//! ## Topics of a flight ([`write_flight_ulog`]), one record set per outer step (250 Hz)
//! As tabulated in `parapet_core::wire::log_topics`, with the host's values:
//! `vehicle_local_position` is the true state, `cbf_status.h_bar` the true min h̄ and
//! `clearance` the true clearance; `vehicle_attitude_setpoint` is recomputed from the filtered
//! `u` with the controller's thrust map (eq. 4-5, `parapet_core::thrust::map_acceleration`) at
//! the measured yaw.
//!
//! May import: `parapet-core` (parameters, thrust map), [`super`] (the samples).

use std::io::{self, Write};
use std::path::Path;

use anyhow::{Context, Result};
use nalgebra::{UnitQuaternion, Vector3};
use parapet_core::controller::ControllerParams;
use parapet_core::params::TABLE;
use parapet_core::thrust::map_acceleration;
use parapet_core::wire::log_topics::{write_definitions, write_records, FlightRecord};
use parapet_core::wire::ulog::ULogSink;

use super::Sample;

/// File name of the flight log in a run's report directory.
pub const FLIGHT_LOG: &str = "flight.ulg";

/// A file as the core ULog writer's sink.
struct IoSink<W: Write>(W);

impl<W: Write> ULogSink for IoSink<W> {
    type Error = anyhow::Error;
    fn write(&mut self, bytes: &[u8]) -> Result<()> {
        Ok(self.0.write_all(bytes)?)
    }
}

fn quat(roll: f64, pitch: f64, yaw: f64) -> [f32; 4] {
    let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
    [q.w as f32, q.i as f32, q.j as f32, q.k as f32]
}

fn v3(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// The log record of sample `s` at `t_us` (flown with `params`).
fn record(s: &Sample, t_us: u64, params: &ControllerParams) -> FlightRecord {
    let [roll, pitch, yaw] = s.rpy;
    let u = parapet_core::Vec3::new(s.u_filtered.x as f32, s.u_filtered.y as f32, s.u_filtered.z as f32);
    let sp =
        map_acceleration(&params.thrust, params.airframe.mass, &u, yaw as f32, roll as f32, pitch as f32);
    FlightRecord {
        t_us,
        position: v3(&s.pos),
        velocity: v3(&s.vel),
        heading: yaw as f32,
        attitude_q: quat(roll, pitch, yaw),
        setpoint_rpy: [sp.roll, sp.pitch, sp.yaw],
        setpoint_q: quat(f64::from(sp.roll), f64::from(sp.pitch), f64::from(sp.yaw)),
        thrust_norm: sp.thrust / params.thrust.thrust_max,
        motors: s.motors,
        armed: s.mode.motors_on(),
        guidance: s.mode,
        mode: s.flight_mode,
        h_bar_true: s.h_bar as f32,
        clearance: s.clearance as f32,
        filter: s.filter,
        u_nominal: v3(&s.u_nominal),
        u: v3(&s.u_filtered),
        governor_limit: s.safety.governor_limit.unwrap_or(f32::NAN),
        governor_cause: s.safety.governor_cause as u8,
    }
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
    let t0 = samples.first().map(|s| clock(s.t)).unwrap_or(0);
    let write = || -> Result<()> {
        let mut w = IoSink(io::BufWriter::new(file));
        let infos = infos.iter().map(|(k, v)| (*k, v.as_str()));
        let values = TABLE.iter().map(|p| (p.name, (p.get)(params)));
        write_definitions(&mut w, t0, env!("CARGO_PKG_VERSION"), infos, values)?;
        for s in samples {
            write_records(&mut w, &record(s, clock(s.t), params))?;
        }
        w.0.flush()?;
        Ok(())
    };
    write().with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn attitude_quaternion_is_px4_s_body_to_ned() {
        // The attitude quaternion is PX4's (w, x, y, z), body → NED: yaw 90° about +z (down).
        let q = quat(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        assert!((q[0] - q[3]).abs() < 1e-6 && q[1] == 0.0 && q[2] == 0.0 && q[3] > 0.0, "{q:?}");
    }
}
