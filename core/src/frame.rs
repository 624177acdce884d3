//! World frame, body frame, units and sign conventions — the single place
//! they are defined.
//!
//! * **World frame: NED.** x points north, y east, z **down**, origin at a
//!   fixed point on the ground. Altitude is `-z`. Gravity is `+GRAVITY` along
//!   z. This is the frame of the paper's model (eq. 1), of PX4 and of MAVLink's
//!   `LOCAL_POSITION_NED` / `ODOMETRY`.
//! * **Body frame: FRD.** x forward, y right, z down. Positive roll (φ) lowers
//!   the right side, positive pitch (θ) raises the nose, positive yaw (ψ) turns
//!   clockwise seen from above (north → east). Attitude is the rotation
//!   body → world, Euler ZYX (yaw, then pitch, then roll).
//! * **Thrust** acts along body −z (upwards when level); collective thrust `T`
//!   is a positive magnitude in newtons.
//! * **Units:** SI — metres, seconds, kilograms, newtons, radians, rad/s.
//! * **Files and plots (scenes, paths, trajectories):** ENU — x east, y north,
//!   z **up** (height above ground). Convert only at that boundary.

use crate::fmath::{maxf, minf, sincosf_exact};
use crate::Vec3;
use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion};

/// Standard gravity, m/s², acting along world +z (down).
pub const GRAVITY: f32 = 9.81;

/// ENU (x east, y north, z up; files and plots) → NED (internal world frame).
#[inline]
pub fn enu_to_ned(v: Vec3) -> Vec3 {
    Vec3::new(v.y, v.x, -v.z)
}

/// NED (internal world frame) → ENU (x east, y north, z up; files and plots).
#[inline]
pub fn ned_to_enu(v: Vec3) -> Vec3 {
    Vec3::new(v.y, v.x, -v.z)
}

/// `true` when all three components are finite.
#[inline]
pub fn is_finite3(v: &Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// `x` limited to `[lo, hi]` without ever panicking (unlike `f32::clamp`, which
/// panics when `lo > hi` or a bound is NaN — a bad parameter must not stop a
/// control loop). NaN `x` gives `lo`; NaN bounds are ignored; `lo > hi` gives `hi`.
#[inline]
pub fn clampf(x: f32, lo: f32, hi: f32) -> f32 {
    minf(maxf(x, lo), hi)
}

/// Wrap an angle to (−π, π], rad. Non-finite input is returned unchanged
/// (callers check finiteness themselves).
#[inline]
pub fn wrap_pi(a: f32) -> f32 {
    use core::f32::consts::PI;
    if a > -PI && a <= PI {
        // Already in range: remainderf(a, 2π) returns a exactly here (|a/2π| ≤ 1/2, a tie
        // at a = π rounding the quotient to even 0), so this is the same value, cheaply.
        return a;
    }
    if !a.is_finite() {
        return a;
    }
    let mut x = libm::remainderf(a, 2.0 * PI);
    if x <= -PI {
        x += 2.0 * PI;
    }
    x
}

/// The attitude of ZYX Euler angles (rad; body → world): nalgebra's
/// `UnitQuaternion::from_euler_angles`, the same arithmetic, with the half angles' sines and
/// cosines from [`sincosf_exact`] — `libm::sincosf`'s values on every build (nalgebra takes
/// the platform's `sin_cos` on a `std` host and links all of `libm::sincosf` on the boards).
pub fn quat_from_euler(roll: f32, pitch: f32, yaw: f32) -> UnitQuaternion<f32> {
    quat_with(sincosf_exact, roll, pitch, yaw)
}

/// The rotation of ZYX Euler angles (rad; body → world): nalgebra's
/// `Rotation3::from_euler_angles`, the same arithmetic, sines and cosines from
/// [`sincosf_exact`] (see [`quat_from_euler`]).
pub fn rotation_from_euler(roll: f32, pitch: f32, yaw: f32) -> Rotation3<f32> {
    rotation_with(sincosf_exact, roll, pitch, yaw)
}

/// nalgebra 0.35's `UnitQuaternion::from_euler_angles` with the sine and cosine `sin_cos`.
#[inline(always)]
fn quat_with(sin_cos: impl Fn(f32) -> (f32, f32), roll: f32, pitch: f32, yaw: f32) -> UnitQuaternion<f32> {
    let (sr, cr) = sin_cos(roll * 0.5);
    let (sp, cp) = sin_cos(pitch * 0.5);
    let (sy, cy) = sin_cos(yaw * 0.5);
    UnitQuaternion::new_unchecked(Quaternion::new(
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ))
}

/// nalgebra 0.35's `Rotation3::from_euler_angles` with the sine and cosine `sin_cos`.
#[inline(always)]
fn rotation_with(sin_cos: impl Fn(f32) -> (f32, f32), roll: f32, pitch: f32, yaw: f32) -> Rotation3<f32> {
    let (sr, cr) = sin_cos(roll);
    let (sp, cp) = sin_cos(pitch);
    let (sy, cy) = sin_cos(yaw);
    Rotation3::from_matrix_unchecked(Matrix3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enu_ned_round_trip_and_up_is_minus_z() {
        let p = Vec3::new(1.0, 2.0, 3.0);
        assert_eq!(ned_to_enu(enu_to_ned(p)), p);
        // 3 m above ground is z = -3 in NED; east (x_enu) becomes y_ned.
        assert_eq!(enu_to_ned(p), Vec3::new(2.0, 1.0, -3.0));
    }

    #[test]
    fn clampf_never_panics() {
        assert_eq!(clampf(5.0, 0.0, 1.0), 1.0);
        assert_eq!(clampf(-5.0, 0.0, 1.0), 0.0);
        assert_eq!(clampf(f32::NAN, 0.0, 1.0), 0.0);
        assert_eq!(clampf(0.5, f32::NAN, 1.0), 0.5);
        assert_eq!(clampf(0.5, 2.0, 1.0), 1.0); // lo > hi: no panic
    }

    #[test]
    fn euler_constructions_are_nalgebras_with_libms_sine() {
        // With nalgebra's own sine and cosine (its `ComplexField::sin_cos`, whichever this build
        // links) the constructions are nalgebra's bit for bit; `sincosf_exact` is libm's
        // `sincosf` (fmath tests), what nalgebra takes on the boards.
        use nalgebra::ComplexField;
        let mut seed = 0x2545_f491u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed as f32 / u32::MAX as f32 - 0.5) * 8.0
        };
        let bits = |m: &Matrix3<f32>| m.map(f32::to_bits);
        for _ in 0..100_000 {
            let (r, p, y) = (next(), next(), next());
            let q = quat_with(ComplexField::sin_cos, r, p, y);
            let n = UnitQuaternion::from_euler_angles(r, p, y);
            assert_eq!(q.coords.map(f32::to_bits), n.coords.map(f32::to_bits), "{r} {p} {y}");
            let m = rotation_with(ComplexField::sin_cos, r, p, y);
            assert_eq!(bits(m.matrix()), bits(Rotation3::from_euler_angles(r, p, y).matrix()));
            let q = quat_from_euler(r, p, y);
            assert_eq!(q.coords, quat_with(libm::sincosf, r, p, y).coords);
        }
    }

    #[test]
    fn wrap_pi_range() {
        use core::f32::consts::PI;
        assert!((wrap_pi(3.0 * PI) - PI).abs() < 1e-5);
        assert!((wrap_pi(-0.5) + 0.5).abs() < 1e-6);
        assert!((wrap_pi(2.0 * PI + 0.25) - 0.25).abs() < 1e-5);
        assert!(wrap_pi(-PI) > 0.0);
        // The in-range shortcut returns what remainderf does, bit for bit.
        for a in [0.0f32, -0.0, 1e-30, 0.5, -3.1, PI, PI - 1e-6, -3.0, 2.0, -PI + 1e-6] {
            let mut x = libm::remainderf(a, 2.0 * PI);
            if x <= -PI {
                x += 2.0 * PI;
            }
            assert_eq!(wrap_pi(a).to_bits(), x.to_bits(), "{a}");
        }
    }
}
