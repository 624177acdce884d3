//! The ground-station side of the link: what the host sends the firmware and
//! how (MAVLink messages of the wire contract `parapet_core::wire`), and the
//! settings it uploads: the parameters ([`firmware_params`]), the mission as the
//! firmware stores it ([`quantised_path`]), the start-up timing (`preroll_start`).
//!
//! May import: `parapet-core` (params, wire contract), mavlink, [`crate::fc::nav`] (the σ the
//! in-process filter is told),
//! [`crate::flight`] (run settings, validation messages), [`crate::sim::sensors`] and
//! [`crate::sim::battery`] (readings), [`crate::world::scene`].
//!
//! MAVLink message literals end in `..Default::default()`: whether the generated `mavlink`
//! structs carry the MAVLink 2 extension fields depends on which crates share the build (the
//! firmware's `mavlink-bindgen` build-dependency turns them on, e.g. in the fuzz workspace),
//! and the code must compile both ways (hence the `needless_update` allowance).
#![allow(clippy::needless_update)]

use anyhow::{anyhow, Result};
use mavlink::dialects::ardupilotmega::{
    GpsFixType, GpsInputIgnoreFlags, HilSensorUpdatedFlags, MavBatteryFunction, MavBatteryType, MavCmd,
    MavEstimatorType, MavFrame, MavMessage, MavParamType, BATTERY_STATUS_DATA, COMMAND_LONG_DATA,
    DEBUG_VECT_DATA, GPS_INPUT_DATA, HIL_SENSOR_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
    OBSTACLE_DISTANCE_3D_DATA, ODOMETRY_DATA, PARAM_SET_DATA,
};
use nalgebra::Vector3;
use parapet_core::controller::ControllerParams;
use parapet_core::controller::PositionFix;
use parapet_core::nav::aid::SourceNoise;
use parapet_core::nav::FixKind;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::params;
use parapet_core::schedule::OuterSchedule;
use parapet_core::wire::battery::{battery_to_wire, UNKNOWN_MV};
use parapet_core::wire::codes::{gps_input_yaw, odometry_quaternion, odometry_yaw, sigma_of_variance};
use parapet_core::wire::geo::{altitude_m, down_m, global_to_ned, ned_to_global, AltRef};
use parapet_core::wire::ids::{
    local_xy_from_wire, local_xy_to_wire, AUTOPILOT_COMPONENT_ID, CLEAR_ID, EMPTY_BATCH_RANGE,
    VEHICLE_SYSTEM_ID,
};
use parapet_core::wire::names::OBSTACLE_VELOCITY_PREFIX;
use parapet_core::Vec3;

use crate::flight::runner::RunConfig;
use crate::sim::battery::BatteryReading;
use crate::sim::sensors::{ImuReading, PositionReading};
use crate::world::scene::{to_f32, Scene};

/// Warm-up of the estimator before arming, steps (1 ms).
pub(super) const WARMUP_STEPS: u64 = 300;

/// The controller parameters the firmware flies with for `scene` and `cfg`: exactly those of
/// `parapet run` ([`crate::flight::runner::controller_params`]: the scene's vehicle, the run's CBF,
/// tracking and speed settings), with the PARAM_SETs that take the firmware from its boot
/// defaults (`ControllerParams::default()`) there: every entry of the parameter table
/// ([`parapet_core::params::TABLE`]) whose value differs, in table order. No order is needed:
/// the firmware checks each value against its own range only and flies the stored set once it
/// is consistent, which it is after the last one. Errors: the set is invalid (in words), a value
/// is outside its parameter's range, or a setting differs in a field no parameter sets.
pub fn firmware_params(
    scene: &Scene,
    cfg: &RunConfig,
) -> Result<(ControllerParams, Vec<(&'static str, f32)>)> {
    let p = crate::flight::runner::controller_params(scene, cfg, cfg.cbf_params()?, cfg.variant);
    p.validate().map_err(|e| anyhow!("{}", crate::flight::validate::describe_param_error(scene, &p, e)))?;
    let mut fw = ControllerParams::default();
    let mut updates = Vec::new();
    for d in &params::TABLE {
        let v = (d.get)(&p);
        if v.to_bits() == (d.get)(&fw).to_bits() {
            continue;
        }
        params::set(&mut fw, d.name, v).map_err(|_| {
            anyhow!("the run's {} = {v} is outside the firmware's parameter range ({})", d.name, d.range())
        })?;
        updates.push((d.name, v));
    }
    if fw != p {
        return Err(anyhow!(
            "the run's controller settings differ from the firmware's defaults in a field no \
             parameter sets (e.g. per-axis gains or loop rates)"
        ));
    }
    Ok((p, updates))
}

/// The path as the firmware stores it after MISSION_ITEM_INT (x, y quantised to 0.1 mm), NED.
pub fn quantised_path(path: &[Vector3<f64>]) -> Vec<Vec3> {
    path.iter()
        .map(|w| {
            let (x, y) = mission_xy(w);
            Vec3::new(local_xy_from_wire(x), local_xy_from_wire(y), w.z as f32)
        })
        .collect()
}

fn mission_xy(w: &Vector3<f64>) -> (i32, i32) {
    (local_xy_to_wire(w.x), local_xy_to_wire(w.y))
}

/// First pre-roll step time, µs, for a path of `n_wp` waypoints (a multiple of the outer period
/// before `t0_us`).
pub(super) fn preroll_start(t0_us: u64, n_params: usize, n_wp: usize, sched: &OuterSchedule) -> u64 {
    let div = sched.divider();
    let steps = (n_params + 2 * n_wp + 8) as u64 + WARMUP_STEPS + div;
    let steps = steps.div_ceil(div) * div;
    t0_us.saturating_sub(steps * 1000)
}

/// ODOMETRY with a fix measured at `t_us`: position, velocity (NED), the heading as the
/// level quaternion of the wire contract, and the position source's noise `std_m` (1σ per
/// axis, m) as the pose covariance's x, y, z variances (MAVLink's upper-triangle layout:
/// indices 0, 6, 11; the rotation variances and the velocity covariance unknown: NaN first
/// element). The firmware reports it as GPS_RAW_INT's accuracy.
pub(super) fn odometry(t_us: u64, fix: &PositionReading, std_m: f64) -> MavMessage {
    MavMessage::ODOMETRY(odometry_data(t_us, fix, std_m))
}

fn odometry_data(t_us: u64, fix: &PositionReading, std_m: f64) -> ODOMETRY_DATA {
    let var = (std_m * std_m) as f32;
    let mut pose_covariance = [0.0f32; 21];
    (pose_covariance[0], pose_covariance[6], pose_covariance[11]) = (var, var, var);
    (pose_covariance[15], pose_covariance[18], pose_covariance[20]) = (f32::NAN, f32::NAN, f32::NAN);
    let mut velocity_covariance = [0.0f32; 21];
    velocity_covariance[0] = f32::NAN;
    ODOMETRY_DATA {
        pose_covariance,
        velocity_covariance,
        time_usec: t_us,
        x: fix.position.x as f32,
        y: fix.position.y as f32,
        z: fix.position.z as f32,
        vx: fix.velocity.x as f32,
        vy: fix.velocity.y as f32,
        vz: fix.velocity.z as f32,
        q: odometry_quaternion(fix.yaw as f32),
        frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
        child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
        ..Default::default()
    }
}

/// ODOMETRY of a `vio` fix measured at `t_us` (issue 39): [`odometry`]'s fields with
/// `estimator_type` VIO — the firmware's navigation filter takes it as a relative source
/// (`firmware/src/link/position_sources.rs`, `odometry_is_vision`) — and the σ `noise` as the
/// x, y, z variances of the pose and of the velocity covariance (`odometry_noise` decodes them).
pub(super) fn vio_odometry(t_us: u64, fix: &PositionReading, noise: SourceNoise) -> ODOMETRY_DATA {
    let mut m = odometry_data(t_us, fix, f64::from(noise.position));
    let var = noise.position * noise.position;
    (m.pose_covariance[0], m.pose_covariance[6], m.pose_covariance[11]) = (var, var, var);
    let vvar = noise.velocity * noise.velocity;
    (m.velocity_covariance[0], m.velocity_covariance[6], m.velocity_covariance[11]) = (vvar, vvar, vvar);
    m.estimator_type = MavEstimatorType::MAV_ESTIMATOR_TYPE_VIO;
    m
}

/// The message carrying a fix measured at `t_us` for the run's filtered source `nav`
/// ([`filtered_source`]): GPS_INPUT (absolute; `None` beyond the link's range), a VIO's
/// ODOMETRY (relative), or without a filtered source ODOMETRY with the noise `std_m`.
pub(super) fn fix_message(
    t_us: u64,
    fix: &PositionReading,
    nav: Option<(FixKind, SourceNoise)>,
    std_m: f64,
) -> Option<MavMessage> {
    match nav {
        Some((FixKind::Absolute, noise)) => gps_input(t_us, fix, noise).map(MavMessage::GPS_INPUT),
        Some((FixKind::Relative, noise)) => Some(MavMessage::ODOMETRY(vio_odometry(t_us, fix, noise))),
        None => Some(odometry(t_us, fix, std_m)),
    }
}

/// The fix and σ the firmware takes from a [`vio_odometry`] message (`odometry_fix` and
/// `odometry_noise` there): the message's f32 fields, the quaternion's yaw, the variances' σ
/// ([`sigma_of_variance`], `noise` standing in for the firmware's defaults, never used: the
/// host always states them).
pub(super) fn vio_decoded(m: &ODOMETRY_DATA, noise: SourceNoise) -> (PositionFix, SourceNoise) {
    let fix = PositionFix {
        t_us: m.time_usec,
        position: Vec3::new(m.x, m.y, m.z),
        velocity: Vec3::new(m.vx, m.vy, m.vz),
        yaw: odometry_yaw(m.q),
    };
    let stated = SourceNoise {
        position: sigma_of_variance(m.pose_covariance[0], noise.position),
        velocity: sigma_of_variance(m.velocity_covariance[0], noise.velocity),
    };
    (fix, stated)
}

/// How the PIL host sends the run's filtered position source to the firmware's navigation
/// filter: its kind (`gps`, `rtk`: absolute, as GPS_INPUT; `vio`: relative, as a VIO's
/// ODOMETRY) and the σ it states (the scene's noise floored as the in-process filter is told
/// it, `crate::fc::nav::NavAid::noise_of`); `None` for motion capture (ODOMETRY without an
/// estimator type, the latest-fix path).
pub fn filtered_source(cfg: &RunConfig) -> Option<(FixKind, SourceNoise)> {
    let src = cfg.sensors.position_source;
    (!src.is_mocap())
        .then(|| (crate::fc::nav::NavAid::kind_of(src), crate::fc::nav::NavAid::noise_of(&cfg.sensors)))
}

/// GPS_INPUT with a fix measured at `t_us` (a `gps` / `rtk` source, issue 39): the position as
/// latitude/longitude (1e-7 °, [`ned_to_global`] around the wire contract's origin) and
/// altitude (m AMSL), the velocity NED, no heading (0: the compass's goes as HIL_SENSOR's field) and the σ
/// `noise` as `horiz_accuracy` / `vert_accuracy` / `speed_accuracy` — what the firmware's
/// `link::position_sources` decodes. `None` when the position is beyond the link's range.
pub(super) fn gps_input(t_us: u64, fix: &PositionReading, noise: SourceNoise) -> Option<GPS_INPUT_DATA> {
    let p = to_f32(&fix.position);
    let (lat, lon, _) = ned_to_global(p)?;
    Some(GPS_INPUT_DATA {
        time_usec: t_us,
        lat,
        lon,
        alt: altitude_m(p.z, AltRef::Amsl),
        vn: fix.velocity.x as f32,
        ve: fix.velocity.y as f32,
        vd: fix.velocity.z as f32,
        horiz_accuracy: noise.position,
        vert_accuracy: noise.position,
        speed_accuracy: noise.velocity,
        fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
        satellites_visible: 12,
        // No heading: the compass's goes as HIL_SENSOR's magnetometer field ([`hil_sensor`]).
        yaw: 0,
        ignore_flags: GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_HDOP
            | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VDOP,
        ..Default::default()
    })
}

/// The fix the firmware takes from `m` (`firmware/src/link/position_sources.rs`, `gps_input_fix`,
/// for a message [`gps_input`] made): the same [`global_to_ned`] and yaw decoding, so the
/// firmware twin fuses bit for bit what the firmware fuses.
pub(super) fn gps_input_decoded(m: &GPS_INPUT_DATA) -> Option<PositionFix> {
    let position = global_to_ned(m.lat, m.lon, m.alt, AltRef::Amsl).ok()?;
    let velocity = Vec3::new(m.vn, m.ve, m.vd);
    Some(PositionFix { t_us: m.time_usec, position, velocity, yaw: gps_input_yaw(m.yaw) })
}

/// The obstacle batch of an outer step: per point its velocity (`DEBUG_VECT OBV<id>`, moving
/// obstacles only) then the point (OBSTACLE_DISTANCE_3D); an empty batch is one
/// OBSTACLE_DISTANCE_3D with the empty range [`EMPTY_BATCH_RANGE`].
pub(super) fn obstacle_batch(t_us: u64, shown: &[ObstaclePoint]) -> Vec<MavMessage> {
    let time_boot_ms = (t_us / 1000) as u32;
    if shown.is_empty() {
        return vec![MavMessage::OBSTACLE_DISTANCE_3D(OBSTACLE_DISTANCE_3D_DATA {
            time_boot_ms,
            obstacle_id: CLEAR_ID,
            frame: MavFrame::MAV_FRAME_LOCAL_NED,
            // The empty-batch marker: an empty range (id 65535 alone is a valid point).
            min_distance: EMPTY_BATCH_RANGE.0,
            max_distance: EMPTY_BATCH_RANGE.1,
            ..Default::default()
        })];
    }
    let mut out = Vec::with_capacity(2 * shown.len());
    for o in shown {
        if let Some(v) = o.velocity.filter(|v| v.iter().any(|c| *c != 0.0)) {
            out.push(MavMessage::DEBUG_VECT(DEBUG_VECT_DATA {
                time_usec: t_us,
                x: v.x,
                y: v.y,
                z: v.z,
                name: char_array(&format!("{OBSTACLE_VELOCITY_PREFIX}{}", o.id)),
            }));
        }
        out.push(MavMessage::OBSTACLE_DISTANCE_3D(OBSTACLE_DISTANCE_3D_DATA {
            time_boot_ms,
            obstacle_id: o.id,
            frame: MavFrame::MAV_FRAME_LOCAL_NED,
            x: o.point.x,
            y: o.point.y,
            z: o.point.z,
            ..Default::default()
        }));
    }
    out
}

/// COMMAND_LONG `command` with parameters `p` to the vehicle's autopilot.
pub(super) fn command_long(command: MavCmd, p: [f32; 7]) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        param5: p[4],
        param6: p[5],
        param7: p[6],
        command,
        target_system: VEHICLE_SYSTEM_ID,
        target_component: AUTOPILOT_COMPONENT_ID,
        confirmation: 0,
    })
}

/// PARAM_SET `name = value` (REAL32).
pub(super) fn param_set(name: &str, value: f32) -> MavMessage {
    MavMessage::PARAM_SET(PARAM_SET_DATA {
        param_value: value,
        target_system: VEHICLE_SYSTEM_ID,
        target_component: AUTOPILOT_COMPONENT_ID,
        param_id: char_array(name),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    })
}

/// MISSION_COUNT of a path of `n` waypoints.
pub(super) fn mission_count(n: usize) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: n as u16,
        target_system: VEHICLE_SYSTEM_ID,
        target_component: AUTOPILOT_COMPONENT_ID,
        ..Default::default()
    })
}

/// MISSION_ITEM_INT `seq` at waypoint `w` (NED; x, y in the wire's 10⁻⁴ m).
pub(super) fn mission_item(seq: u16, w: &Vector3<f64>) -> MavMessage {
    let (x, y) = mission_xy(w);
    MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
        x,
        y,
        z: w.z as f32,
        seq,
        command: MavCmd::MAV_CMD_NAV_WAYPOINT,
        frame: MavFrame::MAV_FRAME_LOCAL_NED,
        target_system: VEHICLE_SYSTEM_ID,
        target_component: AUTOPILOT_COMPONENT_ID,
        autocontinue: 1,
        ..Default::default()
    })
}

/// HIL_SENSOR of the step at `t_us` (the lockstep trigger); with a barometer height
/// `baro_down` (NED down, m) its `pressure_alt` (m AMSL, [`altitude_m`]) and the
/// `HIL_SENSOR_UPDATED_PRESSURE_ALT` bit of `fields_updated` (the firmware's
/// `link::inputs::hil_baro_down`; [`baro_decoded`] is what it takes); with a magnetometer
/// field `mag` (body FRD, gauss) `xmag`..`zmag` and their bits (`link::inputs::hil_mag`).
pub(super) fn hil_sensor(
    t_us: u64,
    imu: &ImuReading,
    baro_down: Option<f64>,
    mag: Option<Vec3>,
) -> MavMessage {
    let mut fields_updated = HilSensorUpdatedFlags::empty();
    let pressure_alt = baro_down.map_or(0.0, |d| {
        fields_updated |= HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_PRESSURE_ALT;
        altitude_m(d as f32, AltRef::Amsl)
    });
    let b = mag.unwrap_or_else(Vec3::zeros);
    if mag.is_some() {
        fields_updated |= HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_XMAG
            | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_YMAG
            | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_ZMAG;
    }
    MavMessage::HIL_SENSOR(HIL_SENSOR_DATA {
        pressure_alt,
        fields_updated,
        xmag: b.x,
        ymag: b.y,
        zmag: b.z,
        time_usec: t_us,
        xgyro: imu.gyro.x as f32,
        ygyro: imu.gyro.y as f32,
        zgyro: imu.gyro.z as f32,
        xacc: imu.accel.x as f32,
        yacc: imu.accel.y as f32,
        zacc: imu.accel.z as f32,
        ..Default::default()
    })
}

/// The height (NED down, m) the firmware takes from the `pressure_alt` [`hil_sensor`] sends for
/// `down`: the same f32 conversions both ways (`wire::geo`).
pub(super) fn baro_decoded(down: f64) -> f32 {
    down_m(altitude_m(down as f32, AltRef::Amsl), AltRef::Amsl)
}

/// The raw reading `r` of the scene's pack as the host sends it to the firmware (host → firmware
/// only, `parapet_core::wire::battery`): BATTERY_STATUS with the pack voltage in `voltages[0]`
/// (mV), the current in `current_battery` (cA, −1 without a current sensor); consumption,
/// temperature and remaining charge unknown (the firmware's estimator computes the charge).
pub(super) fn battery_status(r: &BatteryReading) -> MavMessage {
    let w = battery_to_wire(r.voltage_v, r.current_a);
    let mut voltages = [UNKNOWN_MV; 10];
    voltages[..2].copy_from_slice(&w.voltages_mv);
    MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
        current_consumed: -1,
        energy_consumed: -1,
        temperature: i16::MAX,
        voltages,
        current_battery: w.current_ca,
        id: 0,
        battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
        mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
        battery_remaining: -1,
        ..Default::default()
    })
}

fn char_array<const N: usize>(s: &str) -> mavlink::types::CharArray<N> {
    let mut b = [0u8; N];
    for (d, c) in b.iter_mut().zip(s.bytes()) {
        *d = c;
    }
    b.into()
}
