//! The magnetometer: the Earth's field at home, the field a level or tilted vehicle measures
//! (for the simulator's HIL_SENSOR) and the tilt-compensated heading the firmware takes from it
//! (issue 39). The heading goes to the attitude estimator with the next position fix, as the
//! simulator's compass does (`docs/navigation.md` § Magnetometer).
//!
//! **Field** ([`EARTH_FIELD_NED_G`]): the World Magnetic Model at the wire contract's origin
//! (`crate::wire::geo::ORIGIN`, 47.40° N 8.55° E, 488 m; WMM2025 for 2026): declination
//! [`DECLINATION_RAD`] (+3.3°, east), inclination 63.6° (down), 0.48 G. A vehicle flown far
//! from home would need its own declination (PX4 looks it up in a table); the local frame of
//! this stack ends at `MAX_RANGE_M` (10 km), where the declination changes by < 0.1°.
//!
//! **Heading** ([`heading`]): the body field rotated by roll and pitch into the level frame,
//! `ψ_m = atan2(−h_y, h_x)`, plus the declination; `None` for a non-finite or a field without
//! a horizontal part (< 0.05 G). A field made by [`body_field`] gives back its yaw to f32
//! rounding (test).
//!
//! A heading is given to fixes for [`HEADING_TIMEOUT_US`] (1 s) after its field
//! ([`fresh_heading`]); a compass that stops leaves the fixes without one.
//!
//! Owns: the field constants, [`body_field`], [`heading`], [`fresh_heading`]. May import: [`crate::frame`],
//! [`crate::fmath`], [`crate::Vec3`].

use crate::frame::{rotation_from_euler, wrap_pi};
use crate::Vec3;

/// Magnetic declination at home, rad (east of true north positive).
pub const DECLINATION_RAD: f32 = 0.0576;
/// Horizontal intensity at home, gauss.
const HORIZONTAL_G: f32 = 0.2135;
/// Vertical (down) intensity at home, gauss.
const DOWN_G: f32 = 0.4303;
/// The Earth's field at home in the world frame (NED), gauss.
pub const EARTH_FIELD_NED_G: Vec3 = Vec3::new(HORIZONTAL_G * 0.998_342, HORIZONTAL_G * 0.057_568, DOWN_G);
/// Smallest horizontal field a heading is taken from, gauss.
pub const MIN_HORIZONTAL_G: f32 = 0.05;
/// A heading older than this is not given to a fix (a compass that stopped), µs.
pub const HEADING_TIMEOUT_US: u64 = 1_000_000;

/// The heading (measured at `t_us`, rad) to attach to a fix arriving at `now_us`: `None` once
/// older than [`HEADING_TIMEOUT_US`].
pub fn fresh_heading(h: Option<(u64, f32)>, now_us: u64) -> Option<f32> {
    h.filter(|(t, _)| now_us.saturating_sub(*t) <= HEADING_TIMEOUT_US).map(|(_, y)| y)
}

/// The field (body FRD, gauss) of a vehicle at roll, pitch and yaw (rad): `Rᵀ · B_NED`.
pub fn body_field(roll: f32, pitch: f32, yaw: f32) -> Vec3 {
    rotation_from_euler(roll, pitch, yaw).inverse() * EARTH_FIELD_NED_G
}

/// The true heading (rad, in (−π, π]) of a body field `b` (FRD, gauss) measured at roll and
/// pitch (rad, the attitude estimate): tilt-compensated, plus [`DECLINATION_RAD`].
pub fn heading(b: &Vec3, roll: f32, pitch: f32) -> Option<f32> {
    if !(b.iter().all(|x| x.is_finite()) && roll.is_finite() && pitch.is_finite()) {
        return None;
    }
    // The level frame: undo roll, then pitch (R = Rz·Ry·Rx, so Rz·h = Ry·Rx·b).
    let level = rotation_from_euler(roll, pitch, 0.0) * b;
    if crate::fmath::hypotf(level.x, level.y) < MIN_HORIZONTAL_G {
        return None;
    }
    let psi = libm::atan2f(-level.y, level.x) + DECLINATION_RAD;
    Some(wrap_pi(psi))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The field's magnitude and inclination are the model's; a field made at any attitude
    /// gives back its yaw within 1e-5 rad; NaN and a vertical field give none.
    #[test]
    fn a_made_field_gives_back_its_heading() {
        let b = EARTH_FIELD_NED_G;
        assert!((b.norm() - 0.4803).abs() < 1e-3, "{}", b.norm());
        let incl = libm::atan2f(b.z, b.x.hypot(b.y));
        assert!((incl.to_degrees() - 63.6).abs() < 0.1, "{}", incl.to_degrees());
        let mut n = 0;
        for r in [-0.5f32, -0.1, 0.0, 0.2, 0.6] {
            for p in [-0.5f32, 0.0, 0.3] {
                for y in [-3.1f32, -1.0, 0.0, 0.5, 2.0, 3.1] {
                    let h = heading(&body_field(r, p, y), r, p).expect("a heading");
                    assert!(wrap_pi(h - y).abs() < 1e-5, "r {r} p {p} y {y}: {h}");
                    n += 1;
                }
            }
        }
        assert_eq!(n, 90);
        // A roll error of the estimate turns into a heading error (the inclination's tan).
        let off = heading(&body_field(0.1, 0.0, 0.0), 0.0, 0.0).expect("a heading");
        assert!(off.abs() > 0.1, "{off}");
        assert_eq!(heading(&Vec3::new(f32::NAN, 0.0, 0.4), 0.0, 0.0), None);
        assert_eq!(heading(&Vec3::new(0.0, 0.0, 0.48), 0.0, 0.0), None);
        assert_eq!(fresh_heading(Some((1_000, 0.5)), 1_001_000), Some(0.5));
        assert_eq!(fresh_heading(Some((1_000, 0.5)), 1_001_001), None);
        assert_eq!(fresh_heading(None, 0), None);
    }
}
