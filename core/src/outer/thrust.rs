//! Acceleration command → collective thrust and attitude reference (paper eq. 4-5),
//! with a tilt limit and thrust limits; saturation keeps vertical priority.
//!
//! World NED, body FRD (see [`crate::frame`]). With `u` the commanded
//! acceleration (gravity excluded) and `ψ` the yaw reference:
//!
//! ```text
//! T   = m (g − u_z) / (cφ cθ)                       (4)  φ, θ measured
//! θ_d = atan( (u_x cψ + u_y sψ) / (u_z − g) )
//! φ_d = atan( cθ_d (u_x sψ − u_y cψ) / (u_z − g) )  (5)
//! ```
//!
//! Saturation order: first `u_z` is clamped to what the thrust range can give
//! when level (vertical priority), then the horizontal part is scaled down so
//! the tilt stays within `tilt_max` and the total thrust within `thrust_max`.

use crate::fmath::{cosf, maxf, sincosf};
use crate::frame::{clampf, wrap_pi, GRAVITY};
pub use crate::msg::AttitudeSetpoint;
use crate::param_decl::{field, Has, Param};
use crate::plant_aware::limits::AccelLimits;
use crate::Vec3;

/// Limits of the thrust/attitude mapping.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThrustParams {
    /// Largest commanded tilt from level, rad. Default 0.61 (35°).
    pub tilt_max: f32,
    /// Smallest collective thrust commanded in flight, N. Default 0.6.
    pub thrust_min: f32,
    /// Largest collective thrust, N. Default 11.0 (90 % of 4 × 3.07 N, leaving attitude authority).
    pub thrust_max: f32,
}

impl Default for ThrustParams {
    fn default() -> Self {
        ThrustParams { tilt_max: 0.61, thrust_min: 0.6, thrust_max: 11.0 }
    }
}

impl ThrustParams {
    /// The collective thrust limit (`crate::params`).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 1] {
        [
            Param::new("THR_MAX", "Vehicle", "N", (0.5, 2000.0), 2, field!(thrust_max),
                "Largest collective thrust commanded; above VEH_MASS*g, at most 4*VEH_ROTOR_TMAX"),
        ]
    }
}

/// The acceleration actually realised by [`map_acceleration`] after saturation
/// (NED, m/s²), for a vehicle of `mass` kg whose attitude equals the returned setpoint
/// ([`AccelLimits::realised`] with the specific-thrust range `thrust_{min,max} / mass`).
pub fn limit_acceleration(p: &ThrustParams, mass: f32, u: &Vec3) -> (Vec3, bool) {
    match accel_limits(p, mass) {
        Some(l) => l.realised(u),
        None => (Vec3::zeros(), true),
    }
}

/// The acceleration limits of the thrust map for a vehicle of `mass` kg (`None` for a mass that
/// is not finite and positive).
pub fn accel_limits(p: &ThrustParams, mass: f32) -> Option<AccelLimits> {
    (mass.is_finite() && mass > 0.0).then(|| AccelLimits {
        tilt_max: p.tilt_max,
        a_min: p.thrust_min / mass,
        a_max: p.thrust_max / mass,
    })
}

/// Map the acceleration command `u` (NED, m/s²) to an attitude/thrust setpoint
/// (eq. 4-5) for a vehicle of `mass` kg (the airframe's,
/// [`crate::airframe::Airframe::mass`]). `yaw_ref` is the desired yaw (rad); `roll_meas`, `pitch_meas` the
/// estimated attitude used in eq. 4 (non-finite ones are taken as level).
/// Bad input gives a level hover setpoint flagged `saturated`.
pub fn map_acceleration(
    p: &ThrustParams,
    mass: f32,
    u: &Vec3,
    yaw_ref: f32,
    roll_meas: f32,
    pitch_meas: f32,
) -> AttitudeSetpoint {
    let (a, sat) = limit_acceleration(p, mass, u);
    let yaw = if yaw_ref.is_finite() { wrap_pi(yaw_ref) } else { 0.0 };
    let (sy, cy) = sincosf(yaw);
    let den = a.z - GRAVITY; // < 0: thrust points up
    let pitch = libm::atanf((a.x * cy + a.y * sy) / den);
    let roll = libm::atanf(cosf(pitch) * (a.x * sy - a.y * cy) / den);
    let (r, q) =
        if roll_meas.is_finite() && pitch_meas.is_finite() { (roll_meas, pitch_meas) } else { (0.0, 0.0) };
    // Guard eq. 4 against large measured tilt: never compensate beyond the tilt limit.
    let tilt_cos = maxf(cosf(r) * cosf(q), cosf(p.tilt_max.clamp(0.0, 1.5)));
    let thrust = clampf(mass * (GRAVITY - a.z) / tilt_cos, p.thrust_min, p.thrust_max);
    AttitudeSetpoint { roll, pitch, yaw, thrust, saturated: sat || !u.iter().all(|x| x.is_finite()) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Vector3};

    /// The paper's vehicle mass, kg.
    const M: f32 = 0.5;

    fn thrust_direction_world(s: &AttitudeSetpoint) -> Vector3<f32> {
        // Body → world rotation, ZYX Euler; thrust along body −z.
        Rotation3::from_euler_angles(s.roll, s.pitch, s.yaw) * Vector3::new(0.0, 0.0, -1.0)
    }

    #[test]
    fn hover_is_level_at_mg() {
        let p = ThrustParams::default();
        let s = map_acceleration(&p, M, &Vec3::zeros(), 0.0, 0.0, 0.0);
        assert!((s.thrust - 0.5 * GRAVITY).abs() < 1e-5);
        assert!(s.roll.abs() < 1e-7 && s.pitch.abs() < 1e-7);
        assert!(!s.saturated);
    }

    #[test]
    fn plus_x_command_tilts_thrust_towards_plus_x_for_any_yaw() {
        let p = ThrustParams::default();
        for yaw in [0.0f32, 0.7, -2.0, 3.0] {
            let s0 = map_acceleration(&p, M, &Vec3::new(1.0, 0.0, 0.0), yaw, 0.0, 0.0);
            // Steady state: the measured attitude equals the setpoint (eq. 4 uses the measured one).
            let s = map_acceleration(&p, M, &Vec3::new(1.0, 0.0, 0.0), yaw, s0.roll, s0.pitch);
            let f = thrust_direction_world(&s);
            assert!(f.x > 0.05, "yaw {yaw}: {f}");
            assert!(f.y.abs() < 1e-4 && f.z < 0.0);
            // The realised horizontal acceleration matches the command: T·f/m + g.
            let acc = f * s.thrust / M + Vector3::new(0.0, 0.0, GRAVITY);
            assert!((acc - Vector3::new(1.0, 0.0, 0.0)).norm() < 0.05, "{acc}");
        }
        // +y (east) rolls right.
        let s = map_acceleration(&p, M, &Vec3::new(0.0, 1.0, 0.0), 0.0, 0.0, 0.0);
        assert!(s.roll > 0.0 && thrust_direction_world(&s).y > 0.05);
    }

    #[test]
    fn eq4_compensates_measured_tilt() {
        let p = ThrustParams::default();
        let s = map_acceleration(&p, M, &Vec3::zeros(), 0.0, 0.2, 0.1);
        assert!((s.thrust - 0.5 * GRAVITY / (0.2f32.cos() * 0.1f32.cos())).abs() < 1e-4);
    }

    #[test]
    fn saturation_keeps_vertical_priority_and_tilt_limit() {
        let p = ThrustParams::default();
        let s0 = map_acceleration(&p, M, &Vec3::new(50.0, 0.0, -3.0), 0.0, 0.0, 0.0);
        let s = map_acceleration(&p, M, &Vec3::new(50.0, 0.0, -3.0), 0.0, s0.roll, s0.pitch);
        assert!(s.saturated);
        assert!(s.pitch.abs() <= p.tilt_max + 1e-5);
        // Vertical command −3 m/s² is kept: T cosθ = m (g + 3).
        let vz = s.thrust * libm::cosf(s.pitch) / M;
        assert!((vz - (GRAVITY + 3.0)).abs() < 1e-3, "{vz}");
        // Bad input: level hover-ish setpoint, finite.
        let s = map_acceleration(&p, M, &Vec3::new(f32::NAN, 0.0, 0.0), f32::INFINITY, f32::NAN, 0.0);
        assert!(s.saturated && s.roll == 0.0 && s.pitch == 0.0 && s.thrust.is_finite());
    }
}
