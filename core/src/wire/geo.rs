//! Global ↔ local conversion at the link boundary: the one world frame is local NED around
//! [`ORIGIN`]; the firmware's GLOBAL_POSITION_INT, HOME_POSITION, global-frame mission items and
//! GPS_INPUT all go through [`ned_to_global`] / [`global_to_ned`], so what the vehicle reports
//! and what a ground station plans agree. Part of the wire contract (moved here from the
//! firmware's `link::geo`, issue 39): the host's processor-in-the-loop link encodes its GPS
//! fixes with [`ned_to_global`] and its firmware twin decodes them with [`global_to_ned`], bit
//! for bit as the firmware does.
//!
//! **Projection**: flat earth (equirectangular) around [`ORIGIN`] on a sphere of the WGS-84
//! equatorial radius (6,378,137 m): north = Δlat · R, east = Δlon · R · cos(lat₀), with the two
//! scales [`LAT_E7_PER_M`] and [`LON_E7_PER_M`] precomputed for [`ORIGIN`] (no trigonometry on the
//! vehicle). Down = −(altitude − home altitude).
//!
//! **Error bound**: the two directions are exact inverses up to rounding (1e-7° ≈ 1.1 cm north,
//! 0.75 cm east at 47.4° N; f32 carries the *difference* to home in 1e-7° integers, exact below
//! 2²⁴ units ≈ 186 km, so the conversion adds < 1 mm within [`MAX_RANGE_M`]). Against the WGS-84
//! ellipsoid (what a ground station's map shows) the flat-earth scale is off by ≤ 0.2 % (meridian
//! and prime-vertical radii at 47.4° N vs the equatorial radius) plus ≤ 0.2 % from the fixed
//! cos(lat₀) at 10 km north/south of home: ≤ 0.4 % of the distance from home (≤ 4 m at 1 km,
//! ≤ 40 m at [`MAX_RANGE_M`]). Positions farther than [`MAX_RANGE_M`] from home are refused.
//!
//! May import: [`crate::Vec3`], `libm`. No allocation, no panics; f32 only (F405 flash).

use crate::Vec3;

/// The local frame's origin (GPS_GLOBAL_ORIGIN; PX4 SITL's default home, Zurich): latitude and
/// longitude 1e-7 °, altitude mm AMSL. The vehicle's home (HOME_POSITION, where it armed) is a
/// point of this frame (the firmware's `link::services`).
pub const ORIGIN: (i32, i32, i32) = (473_977_420, 85_455_940, 488_000);
/// 1e-7 ° of latitude per metre north (WGS-84 equatorial radius 6,378,137 m).
pub const LAT_E7_PER_M: f32 = 89.831_53;
/// 1e-7 ° of longitude per metre east at [`ORIGIN`]'s latitude (89.83153 / cos 47.397742°).
pub const LON_E7_PER_M: f32 = 132.709_22;
/// Farthest horizontal offset from home (north or east) a global position may have, m.
pub const MAX_RANGE_M: f32 = 10_000.0;

/// Why a global position was refused (maps to MISSION_ACK INVALID_PARAM5/6/7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeoError {
    /// Latitude outside ±90° or farther than [`MAX_RANGE_M`] north/south of home.
    Latitude,
    /// Longitude outside ±180° or farther than [`MAX_RANGE_M`] east/west of home.
    Longitude,
    /// Altitude not finite or more than [`MAX_RANGE_M`] from home's.
    Altitude,
}

/// Altitude reference of a global position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AltRef {
    /// Metres above mean sea level (home is [`ORIGIN`].2 mm AMSL).
    Amsl,
    /// Metres above home.
    Home,
}

fn home_alt_m() -> f32 {
    ORIGIN.2 as f32 / 1000.0
}

/// NED metres around home → (lat 1e-7 °, lon 1e-7 °, altitude mm AMSL); `None` when not finite
/// or out of `i32`.
pub fn ned_to_global(p: Vec3) -> Option<(i32, i32, i32)> {
    let dlat = round_i32(p.x * LAT_E7_PER_M)?;
    let dlon = round_i32(p.y * LON_E7_PER_M)?;
    let down_mm = round_i32(p.z * 1000.0)?;
    Some((ORIGIN.0.checked_add(dlat)?, ORIGIN.1.checked_add(dlon)?, ORIGIN.2.checked_sub(down_mm)?))
}

/// The altitude of NED `down` (m) in `alt_ref`, m.
pub fn altitude_m(down: f32, alt_ref: AltRef) -> f32 {
    match alt_ref {
        AltRef::Amsl => home_alt_m() - down,
        AltRef::Home => -down,
    }
}

/// The NED `down` (m) of an altitude `alt_m` in `alt_ref` (the inverse of [`altitude_m`]).
pub fn down_m(alt_m: f32, alt_ref: AltRef) -> f32 {
    match alt_ref {
        AltRef::Amsl => home_alt_m() - alt_m,
        AltRef::Home => -alt_m,
    }
}

/// (lat 1e-7 °, lon 1e-7 °, altitude m in `alt_ref`) → NED metres around home.
pub fn global_to_ned(lat_e7: i32, lon_e7: i32, alt_m: f32, alt_ref: AltRef) -> Result<Vec3, GeoError> {
    if !(-900_000_000..=900_000_000).contains(&lat_e7) {
        return Err(GeoError::Latitude);
    }
    if !(-1_800_000_000..=1_800_000_000).contains(&lon_e7) {
        return Err(GeoError::Longitude);
    }
    // Differences in i64 1e-7 ° (exact), then to metres.
    let north = (i64::from(lat_e7) - i64::from(ORIGIN.0)) as f32 / LAT_E7_PER_M;
    let east = (i64::from(lon_e7) - i64::from(ORIGIN.1)) as f32 / LON_E7_PER_M;
    if north.abs() > MAX_RANGE_M {
        return Err(GeoError::Latitude);
    }
    if east.abs() > MAX_RANGE_M {
        return Err(GeoError::Longitude);
    }
    let down = down_m(alt_m, alt_ref);
    if !down.is_finite() || down.abs() > MAX_RANGE_M {
        return Err(GeoError::Altitude);
    }
    Ok(Vec3::new(north, east, down))
}

fn round_i32(x: f32) -> Option<i32> {
    let r = libm::roundf(x);
    (r.is_finite() && r >= i32::MIN as f32 && r < i32::MAX as f32).then_some(r as i32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn home_is_the_origin_both_ways() {
        assert_eq!(ned_to_global(Vec3::zeros()), Some(ORIGIN));
        let p = global_to_ned(ORIGIN.0, ORIGIN.1, 0.0, AltRef::Home).unwrap();
        assert_eq!(p, Vec3::zeros());
        let p = global_to_ned(ORIGIN.0, ORIGIN.1, 488.0, AltRef::Amsl).unwrap();
        assert!(p.norm() < 1e-6, "{p:?}");
    }

    #[test]
    fn offsets_round_trip_to_the_same_integers() {
        for (dlat, dlon) in [(8983, 6635), (-1, 1), (450_000, -900_000), (-898_315, 1_327_092), (7, -3)] {
            let p = global_to_ned(ORIGIN.0 + dlat, ORIGIN.1 + dlon, 12.5, AltRef::Home).unwrap();
            let (lat, lon, alt) = ned_to_global(p).unwrap();
            assert_eq!((lat - ORIGIN.0, lon - ORIGIN.1), (dlat, dlon), "{p:?}");
            assert_eq!(alt, ORIGIN.2 + 12_500);
        }
        // 100 m north, 50 m east within 1 cm.
        let p = global_to_ned(ORIGIN.0 + 8983, ORIGIN.1 + 6635, 10.0, AltRef::Home).unwrap();
        assert!((p - Vec3::new(100.0, 50.0, -10.0)).norm() < 0.01, "{p:?}");
    }

    #[test]
    fn bad_positions_are_refused() {
        assert_eq!(global_to_ned(900_000_001, ORIGIN.1, 0.0, AltRef::Home), Err(GeoError::Latitude));
        assert_eq!(global_to_ned(ORIGIN.0 + 900_000, ORIGIN.1, 0.0, AltRef::Home), Err(GeoError::Latitude));
        assert_eq!(global_to_ned(ORIGIN.0, i32::MIN, 0.0, AltRef::Home), Err(GeoError::Longitude));
        assert_eq!(global_to_ned(ORIGIN.0, ORIGIN.1, f32::NAN, AltRef::Amsl), Err(GeoError::Altitude));
        assert_eq!(global_to_ned(ORIGIN.0, ORIGIN.1, f32::INFINITY, AltRef::Home), Err(GeoError::Altitude));
        assert_eq!(ned_to_global(Vec3::new(f32::NAN, 0.0, 0.0)), None);
    }
}
