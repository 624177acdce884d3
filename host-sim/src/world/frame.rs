//! The `f64` simulator vectors ↔ the core's `f32` [`Vec3`], and the file frame
//! (ENU arrays) ↔ the internal NED frame, in `f64` (the core's
//! `parapet_core::frame` does the same in `f32`).
//!
//! May import: `parapet-core`, nalgebra.

use nalgebra::Vector3;
use parapet_core::Vec3;

/// f64 NED vector → core `Vec3` (f32).
pub fn to_f32(v: &Vector3<f64>) -> Vec3 {
    Vec3::new(v.x as f32, v.y as f32, v.z as f32)
}

/// core `Vec3` (f32) → f64.
pub fn to_f64(v: &Vec3) -> Vector3<f64> {
    Vector3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// ENU array (file) → NED vector: the `f64` twin of
/// [`parapet_core::frame::enu_to_ned`] (same axis mapping, checked in the tests).
pub fn enu_arr_to_ned(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[1], a[0], -a[2])
}

/// NED vector → ENU array (file, plots): the `f64` twin of
/// [`parapet_core::frame::ned_to_enu`].
pub fn ned_to_enu_arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.y, v.x, -v.z]
}
