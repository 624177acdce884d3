//! MAV_CMD_DO_REPOSITION (192), a ground station's "Go to location" (QGroundControl's click on
//! the map, MAVSDK `action.goto_location`): fly to a global position and hold there.
//!
//! | param | use |
//! |---|---|
//! | p1 speed m/s | > 0: the path speed of this flight (capped at the vehicle's limit, `VehicleCommand::SetSpeed`); −1/NaN: `WP_SPEED` |
//! | p4 yaw rad | finite: face it (`VehicleCommand::SetYaw`); NaN: the heading unchanged |
//! | p5/p6 (x/y) | latitude / longitude: COMMAND_INT 10⁻⁷ ° exactly, COMMAND_LONG degrees; 0/0 (INT32_MAX or NaN) = here |
//! | p7 (z) | altitude: COMMAND_INT in its frame (GLOBAL/GLOBAL_INT m AMSL, GLOBAL_RELATIVE_ALT(_INT) m above home), COMMAND_LONG m AMSL; NaN = the current altitude |
//!
//! The position is converted around the origin by [`parapet_core::wire::geo`] (the one the vehicle
//! reports in GPS_GLOBAL_ORIGIN / GLOBAL_POSITION_INT); out of range → DENIED. It is flown as
//! a one-point path by the cascade's path follower (the safety filter in the loop), then held
//! — the flight mode reads Mission (PX4: AUTO.LOITER) since the follower is the Mission
//! guidance; a mission being flown is paused (MISSION_START or DO_SET_MODE Mission runs it again
//! from its start). Needs the vehicle airborne (TEMPORARILY_REJECTED on the ground, as PX4).
//!
//! May import: [`crate::app::autopilot`], [`parapet_core::wire::geo`], [`crate::link::mission`] (the
//! frames), the dialect. O(1).

use crate::app::autopilot::{Autopilot, FlightPhase, VehicleCommand};
use crate::link::dialect::{MavResult, COMMAND_INT_DATA, COMMAND_LONG_DATA};
use parapet_core::wire::geo::{self, AltRef};
use parapet_core::Vec3;

/// A decoded DO_REPOSITION.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Goto {
    /// Latitude, longitude in 10⁻⁷ °; `None`: here.
    pub lat_lon_e7: Option<(i32, i32)>,
    /// Altitude, m (NaN: the current one).
    pub alt_m: f32,
    /// What `alt_m` is above.
    pub alt_ref: AltRef,
    /// Speed, m/s (≤ 0 or NaN: `WP_SPEED`).
    pub speed: f32,
    /// Heading, rad (NaN: unchanged).
    pub yaw: f32,
}

/// COMMAND_LONG's DO_REPOSITION (degrees, m AMSL).
pub fn of_long(c: &COMMAND_LONG_DATA) -> Goto {
    let e7 = crate::link::mission_float::e7_of_degrees;
    let here = !(c.param5.is_finite() && c.param6.is_finite()) || (c.param5 == 0.0 && c.param6 == 0.0);
    Goto {
        lat_lon_e7: (!here).then(|| (e7(c.param5), e7(c.param6))),
        alt_m: c.param7,
        alt_ref: AltRef::Amsl,
        speed: c.param1,
        yaw: c.param4,
    }
}

/// COMMAND_INT's DO_REPOSITION (10⁻⁷ ° exactly, the altitude in its frame); other frames
/// UNSUPPORTED.
pub fn of_int(c: &COMMAND_INT_DATA) -> Result<Goto, MavResult> {
    let alt_ref = match crate::link::mission::alt_ref(c.frame) {
        Ok(Some(r)) => r,
        _ => return Err(MavResult::MAV_RESULT_UNSUPPORTED),
    };
    let here = (c.x == 0 && c.y == 0) || c.x == i32::MAX || c.y == i32::MAX;
    Ok(Goto {
        lat_lon_e7: (!here).then_some((c.x, c.y)),
        alt_m: c.z,
        alt_ref,
        speed: c.param1,
        yaw: c.param4,
    })
}

/// The NED point of `g` from the vehicle at `here`, or DENIED out of the local frame's range.
pub fn target(g: &Goto, here: Vec3) -> Result<Vec3, MavResult> {
    let denied = MavResult::MAV_RESULT_DENIED;
    let alt = if g.alt_m.is_finite() { g.alt_m } else { 0.0 };
    let (lat, lon) = g.lat_lon_e7.unwrap_or((geo::ORIGIN.0, geo::ORIGIN.1));
    let p = geo::global_to_ned(lat, lon, alt, g.alt_ref).map_err(|_| denied)?;
    let (n, e) = if g.lat_lon_e7.is_some() { (p.x, p.y) } else { (here.x, here.y) };
    let d = if g.alt_m.is_finite() { p.z } else { here.z };
    Ok(Vec3::new(n, e, d))
}

/// Flies to `g` and holds (see the module docs); the COMMAND_ACK result.
pub fn execute<A: Autopilot>(g: &Goto, now_us: u64, ap: &mut A) -> MavResult {
    let s = ap.telemetry();
    if !(s.armed && matches!(s.phase, FlightPhase::Hover | FlightPhase::Mission)) {
        return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
    }
    let t = match target(g, s.position_ned) {
        Ok(t) => t,
        Err(r) => return r,
    };
    if ap.set_path(&[t]).is_err() {
        return MavResult::MAV_RESULT_DENIED;
    }
    let speed = (g.speed.is_finite() && g.speed > 0.0).then_some(g.speed);
    let _ = ap.command(now_us, VehicleCommand::SetSpeed { m_s: speed });
    if g.yaw.is_finite() {
        let _ = ap.command(now_us, VehicleCommand::SetYaw { yaw_rad: g.yaw });
    }
    crate::link::command::result_of(ap.command(now_us, VehicleCommand::StartMission))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::dialect::MavFrame;

    #[test]
    fn targets_in_the_frames_and_here() {
        let here = Vec3::new(1.0, 2.0, -1.5);
        let (lat0, lon0, alt0) = geo::ORIGIN;
        let amsl = alt0 as f32 / 1000.0;
        // 10 m north, 5 m east, 2 m above home (AMSL altitude).
        let g = Goto {
            lat_lon_e7: Some((lat0 + 898, lon0 + 664)),
            alt_m: amsl + 2.0,
            alt_ref: AltRef::Amsl,
            speed: -1.0,
            yaw: f32::NAN,
        };
        let t = target(&g, here).unwrap();
        assert!((t.x - 10.0).abs() < 0.01 && (t.y - 5.0).abs() < 0.01 && (t.z + 2.0).abs() < 0.01, "{t:?}");
        // Relative altitude, NaN altitude keeps the current one, 0/0 is here.
        let rel = Goto { alt_ref: AltRef::Home, alt_m: 3.0, ..g };
        assert!((target(&rel, here).unwrap().z + 3.0).abs() < 1e-3);
        let keep = Goto { alt_m: f32::NAN, ..g };
        assert_eq!(target(&keep, here).unwrap().z, -1.5);
        let stay = Goto { lat_lon_e7: None, ..rel };
        let t = target(&stay, here).unwrap();
        assert_eq!((t.x, t.y), (1.0, 2.0));
        // Far away: denied.
        let far = Goto { lat_lon_e7: Some((lat0 + 20_000_000, lon0)), ..g };
        assert_eq!(target(&far, here), Err(MavResult::MAV_RESULT_DENIED));
        // COMMAND_INT frames.
        let c = COMMAND_INT_DATA { frame: MavFrame::MAV_FRAME_LOCAL_NED, ..Default::default() };
        assert_eq!(of_int(&c), Err(MavResult::MAV_RESULT_UNSUPPORTED));
    }
}
