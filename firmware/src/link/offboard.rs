//! Offboard setpoints over MAVLink (issue 21): `SET_POSITION_TARGET_LOCAL_NED` (84) in, decoded
//! honouring `type_mask` into the core's `OffboardSetpoint` (the cascade flies it in Offboard
//! mode through the safety filter, [`crate::app::autopilot::Autopilot::set_offboard`]), and
//! `POSITION_TARGET_LOCAL_NED` (85) out, the setpoint the outer loop flies (as PX4 reports it).
//!
//! `type_mask` (POSITION_TARGET_TYPEMASK): each of position, velocity and acceleration is used
//! when none of its three IGNORE bits is set, ignored when all three are; a group with only
//! some axes ignored is refused ([`OffboardRejected::PartialMask`]: Parapet does not mix
//! position and velocity per axis), as are FORCE_SET (force, not acceleration), a message with
//! every group ignored, and frames other than `MAV_FRAME_LOCAL_NED` / `MAV_FRAME_LOCAL_ENU`
//! (converted to NED here). Yaw and yaw rate follow their own IGNORE bits. NaN/Inf values reach
//! the core, which rejects and counts them (`Telemetry::offboard_rejected`).
//!
//! May import: [`crate::link::dialect`], [`crate::app::autopilot`], `parapet_core`.

use crate::app::autopilot::{OffboardSetpoint, TelemetrySnapshot};
use crate::link::dialect::{
    MavFrame, PositionTargetTypemask as M, POSITION_TARGET_LOCAL_NED_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use parapet_core::Vec3;

/// Why a SET_POSITION_TARGET_LOCAL_NED was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OffboardRejected {
    /// A coordinate frame other than LOCAL_NED / LOCAL_ENU.
    Frame,
    /// Only some axes of position, velocity or acceleration ignored.
    PartialMask,
    /// FORCE_SET (a force setpoint) is not supported.
    Force,
    /// Position, velocity and acceleration all ignored.
    Empty,
}

fn group(mask: M, bits: [M; 3], v: Vec3) -> Result<Option<Vec3>, OffboardRejected> {
    let n = bits.iter().filter(|b| mask.contains(**b)).count();
    match n {
        0 => Ok(Some(v)),
        3 => Ok(None),
        _ => Err(OffboardRejected::PartialMask),
    }
}

/// ENU (x east, y north, z up) → NED.
fn enu(v: Vec3) -> Vec3 {
    Vec3::new(v.y, v.x, -v.z)
}

/// The setpoint of `m`, received at `now_us` (controller clock).
pub fn decode(
    m: &SET_POSITION_TARGET_LOCAL_NED_DATA,
    now_us: u64,
) -> Result<OffboardSetpoint, OffboardRejected> {
    let frame: fn(Vec3) -> Vec3 = match m.coordinate_frame {
        MavFrame::MAV_FRAME_LOCAL_NED => |v| v,
        MavFrame::MAV_FRAME_LOCAL_ENU => enu,
        _ => return Err(OffboardRejected::Frame),
    };
    let mask = m.type_mask;
    if mask.contains(M::POSITION_TARGET_TYPEMASK_FORCE_SET) {
        return Err(OffboardRejected::Force);
    }
    let position = group(
        mask,
        [
            M::POSITION_TARGET_TYPEMASK_X_IGNORE,
            M::POSITION_TARGET_TYPEMASK_Y_IGNORE,
            M::POSITION_TARGET_TYPEMASK_Z_IGNORE,
        ],
        Vec3::new(m.x, m.y, m.z),
    )?
    .map(frame);
    let velocity = group(
        mask,
        [
            M::POSITION_TARGET_TYPEMASK_VX_IGNORE,
            M::POSITION_TARGET_TYPEMASK_VY_IGNORE,
            M::POSITION_TARGET_TYPEMASK_VZ_IGNORE,
        ],
        Vec3::new(m.vx, m.vy, m.vz),
    )?
    .map(frame);
    let acceleration = group(
        mask,
        [
            M::POSITION_TARGET_TYPEMASK_AX_IGNORE,
            M::POSITION_TARGET_TYPEMASK_AY_IGNORE,
            M::POSITION_TARGET_TYPEMASK_AZ_IGNORE,
        ],
        Vec3::new(m.afx, m.afy, m.afz),
    )?
    .map(frame);
    if position.is_none() && velocity.is_none() && acceleration.is_none() {
        return Err(OffboardRejected::Empty);
    }
    let enu_frame = m.coordinate_frame == MavFrame::MAV_FRAME_LOCAL_ENU;
    // ENU yaw is measured from east, counter-clockwise: NED yaw = π/2 − yaw_enu.
    let yaw = (!mask.contains(M::POSITION_TARGET_TYPEMASK_YAW_IGNORE)).then_some(if enu_frame {
        core::f32::consts::FRAC_PI_2 - m.yaw
    } else {
        m.yaw
    });
    let yaw_rate = (!mask.contains(M::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE)).then_some(if enu_frame {
        -m.yaw_rate
    } else {
        m.yaw_rate
    });
    Ok(OffboardSetpoint { t_us: now_us, position, velocity, acceleration, yaw, yaw_rate })
}

/// POSITION_TARGET_LOCAL_NED of the snapshot: the reference position and velocity and the
/// filtered acceleration the outer loop flies (NED; yaw rate ignored).
pub fn position_target(s: &TelemetrySnapshot, time_boot_ms: u32) -> POSITION_TARGET_LOCAL_NED_DATA {
    let sp = &s.setpoint;
    POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms,
        x: sp.position_ned.x,
        y: sp.position_ned.y,
        z: sp.position_ned.z,
        vx: sp.velocity_ned.x,
        vy: sp.velocity_ned.y,
        vz: sp.velocity_ned.z,
        afx: sp.accel_filtered_ned.x,
        afy: sp.accel_filtered_ned.y,
        afz: sp.accel_filtered_ned.z,
        yaw: s.attitude_rpy.z,
        yaw_rate: 0.0,
        type_mask: M::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(mask: u16) -> SET_POSITION_TARGET_LOCAL_NED_DATA {
        SET_POSITION_TARGET_LOCAL_NED_DATA {
            x: 1.0,
            y: 2.0,
            z: -3.0,
            vx: 0.5,
            vy: -0.5,
            vz: 0.1,
            afx: 0.2,
            afy: 0.0,
            afz: 0.0,
            yaw: 0.3,
            yaw_rate: 0.1,
            type_mask: M::from_bits_truncate(mask),
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            ..Default::default()
        }
    }

    // MAVSDK's masks: position only 0x0DF8 (+yaw), velocity only 0x0DC7, acceleration only 0x0C3F.
    #[test]
    fn type_mask_selects_position_velocity_or_acceleration() {
        let p = decode(&msg(0x09F8), 7).unwrap_or_default();
        assert_eq!(p.position, Some(Vec3::new(1.0, 2.0, -3.0)));
        assert_eq!((p.velocity, p.acceleration, p.yaw, p.yaw_rate, p.t_us), (None, None, Some(0.3), None, 7));
        let v = decode(&msg(0x0DC7), 0).unwrap_or_default();
        assert_eq!((v.position, v.velocity, v.acceleration), (None, Some(Vec3::new(0.5, -0.5, 0.1)), None));
        assert_eq!((v.yaw, v.yaw_rate), (None, None));
        let a = decode(&msg(0x0C3F), 0).unwrap_or_default();
        assert_eq!((a.position, a.velocity, a.acceleration), (None, None, Some(Vec3::new(0.2, 0.0, 0.0))));
        let pv = decode(&msg(0x0DC0), 0).unwrap_or_default();
        assert!(pv.position.is_some() && pv.velocity.is_some() && pv.acceleration.is_none());
    }

    #[test]
    fn partial_masks_force_empty_and_other_frames_are_refused() {
        assert_eq!(decode(&msg(0x0DFC), 0), Err(OffboardRejected::PartialMask), "x, y only");
        assert_eq!(decode(&msg(0x01FF), 0), Err(OffboardRejected::Empty));
        assert_eq!(decode(&msg(0x0200), 0), Err(OffboardRejected::Force));
        let body = SET_POSITION_TARGET_LOCAL_NED_DATA {
            coordinate_frame: MavFrame::MAV_FRAME_BODY_FRD,
            ..msg(0x0DC7)
        };
        assert_eq!(decode(&body, 0), Err(OffboardRejected::Frame));
        let e = SET_POSITION_TARGET_LOCAL_NED_DATA {
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_ENU,
            ..msg(0x0DC7)
        };
        let v = decode(&e, 0).unwrap_or_default();
        assert_eq!(v.velocity, Some(Vec3::new(-0.5, 0.5, -0.1)), "ENU → NED");
    }

    #[test]
    fn position_target_reports_the_flown_setpoint() {
        let mut s = TelemetrySnapshot::BOOT;
        s.setpoint.position_ned = Vec3::new(1.0, 2.0, -1.0);
        s.setpoint.accel_filtered_ned = Vec3::new(0.1, 0.0, 0.0);
        let m = position_target(&s, 42);
        assert_eq!((m.time_boot_ms, m.x, m.y, m.z, m.afx), (42, 1.0, 2.0, -1.0, 0.1));
        assert_eq!(m.coordinate_frame, MavFrame::MAV_FRAME_LOCAL_NED);
    }
}
