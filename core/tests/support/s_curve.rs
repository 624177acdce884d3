//! The textbook S-curve time the trajectory's timing tests compare against, written once: the
//! unit tests (`core/src/outer/trajectory/tests.rs`) and `core/tests/trajectory_properties.rs`
//! include this file by path.

/// Rest-to-rest time over `len` with speed `v`, acceleration `a` and jerk `j`, computed from the
/// textbook S-curve (not from the generator's code): reaching `v` from rest takes `v/a + a/j`
/// when `v ≥ a²/j` (else `2√(v/j)`) over `v/2` times that distance; if the two ramps do not fit,
/// the peak speed is lowered by bisection until they do.
pub fn s_curve_time(len: f64, v: f64, a: f64, j: f64) -> f64 {
    let ramp_t = |v: f64| if v >= a * a / j { v / a + a / j } else { 2.0 * libm::sqrt(v / j) };
    let ramp_d = |v: f64| 0.5 * v * ramp_t(v);
    if 2.0 * ramp_d(v) <= len {
        return 2.0 * ramp_t(v) + (len - 2.0 * ramp_d(v)) / v;
    }
    let (mut lo, mut hi) = (0.0f64, v);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if 2.0 * ramp_d(mid) <= len {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    2.0 * ramp_t(lo)
}
