//! The accelerations the vehicle can realise: the thrust map's saturation (specific thrust
//! range, tilt limit, vertical priority) as one function, used by the thrust map
//! (`crate::outer::thrust::limit_acceleration`) and by the plant-aware wrapper's lag model,
//! whose input must be what the vehicle is asked to realise, not the filter's raw command:
//! a command beyond the limits fed to the lag model reads, in the disturbance observer, as a
//! disturbance of the size of the shortfall (measured: a 21–66 m/s² one-step command at the
//! dog-leg's end gave d̂ ≈ 3 m/s² and the vehicle sank to the ground).
//!
//! May import: `crate::fmath`, `crate::frame`, [`crate::Vec3`].

use crate::fmath::{hypotf, maxf, minf, sqrtf, tanf};
use crate::frame::{clampf, GRAVITY};
use crate::Vec3;

/// Acceleration limits of the thrust map.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AccelLimits {
    /// Largest tilt from level, rad.
    pub tilt_max: f32,
    /// Smallest specific thrust (collective thrust / mass), m/s².
    pub a_min: f32,
    /// Largest specific thrust, m/s².
    pub a_max: f32,
}

impl AccelLimits {
    /// The acceleration (NED, m/s², gravity excluded) realised for command `u` after
    /// saturation, and whether it saturated: first `g − u_z` is clamped to the specific-thrust
    /// range (vertical priority), then the horizontal part is scaled down to the tilt limit and
    /// to what the largest thrust leaves. Non-finite `u`: zero, saturated.
    pub fn realised(&self, u: &Vec3) -> (Vec3, bool) {
        if !(u.x.is_finite() && u.y.is_finite() && u.z.is_finite()) {
            return (Vec3::zeros(), true);
        }
        let (a_min, a_max) = (self.a_min, self.a_max);
        let gz = clampf(GRAVITY - u.z, maxf(a_min, 1e-3), maxf(a_max, maxf(a_min, 1e-3)));
        let mut sat = (GRAVITY - u.z - gz).abs() > 1e-6;
        let xy = hypotf(u.x, u.y);
        let by_tilt = gz * tanf(self.tilt_max.clamp(0.0, 1.5));
        let by_thrust = sqrtf(maxf(a_max * a_max - gz * gz, 0.0));
        let xy_max = minf(by_tilt, by_thrust);
        let (mut ux, mut uy) = (u.x, u.y);
        if xy > xy_max {
            sat = true;
            let s = if xy > 0.0 { xy_max / xy } else { 0.0 };
            ux *= s;
            uy *= s;
        }
        (Vec3::new(ux, uy, GRAVITY - gz), sat)
    }
}
