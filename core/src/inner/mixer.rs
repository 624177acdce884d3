//! Mixer for the X quadrotor of [`crate::airframe`]: collective thrust and body
//! torques → four rotor thrusts (N) and normalised motor commands.
//!
//! ## Allocation
//! With the rotor layout of [`crate::airframe`] (rotor `i` at `(x_i, y_i) = a·(ux_i, uy_i)`,
//! `a = arm_length/√2`, thrust `f_i` along body −z, drag torque `s_i κ f_i` about body z):
//!
//! ```text
//! T  = Σ f_i
//! τx = Σ −y_i f_i      (roll,  N·m, FRD)
//! τy = Σ  x_i f_i      (pitch, N·m, FRD)
//! τz = Σ  s_i κ f_i    (yaw,   N·m, FRD)
//! ```
//!
//! The four rows are orthogonal, so the exact inverse is
//! `f_i = T/4 − uy_i τx/(4a) + ux_i τy/(4a) + s_i τz/(4κ)`.
//!
//! ## Saturation policy (each rotor thrust must lie in `[0, f_max]`)
//! 1. **Roll/pitch first.** If the roll/pitch differential alone spans more than
//!    `f_max`, the roll and pitch torques are scaled down together (direction
//!    kept) until it fits.
//! 2. **Then collective thrust.** The collective is shifted (up or down, as
//!    little as possible) so that collective + roll/pitch differential fits in
//!    `[0, f_max]`. This deliberately changes the thrust to keep roll/pitch
//!    authority (so a zero-thrust command with a torque demand still spins
//!    rotors; the controller commands all-zero outputs itself when disarmed).
//! 3. **Yaw last.** The yaw differential is scaled by the largest factor in
//!    `[0, 1]` that keeps every rotor in range; yaw never changes roll, pitch
//!    or thrust.
//!
//! Non-finite inputs are replaced by zero (and flagged), so the output is always
//! finite and in range. Motor command `c_i = √(f_i / f_max)` ∈ [0, 1] (see
//! [`crate::airframe`]: `ω = c·ω_max`, `f = c² f_max`).

use crate::airframe::{Airframe, ROTOR_XY_UNIT, ROTOR_YAW_SIGN};
use crate::fmath::{maxf, minf, sqrtf};
use crate::frame::clampf;
use crate::Vec3;

/// Result of one mixing step.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MixerOutput {
    /// Rotor thrusts, N, each in `[0, rotor_thrust_max]` (index 0..4 = rotors 1..4).
    pub thrust_n: [f32; 4],
    /// Motor commands `√(f_i/f_max)`, each in `[0, 1]`.
    pub throttle: [f32; 4],
    /// Roll/pitch torques were scaled down (step 1 of the policy).
    pub roll_pitch_limited: bool,
    /// Collective thrust was changed to fit (step 2).
    pub thrust_limited: bool,
    /// Yaw torque was scaled down (step 3).
    pub yaw_limited: bool,
    /// An input was NaN/Inf and replaced by zero.
    pub input_fault: bool,
}

impl MixerOutput {
    /// `true` when any part of the demand could not be met (for integrator anti-windup).
    pub fn saturated(&self) -> bool {
        self.roll_pitch_limited || self.thrust_limited || self.yaw_limited
    }

    /// Achieved (collective thrust N, body torque N·m FRD) for `airframe`.
    pub fn wrench(&self, airframe: &Airframe) -> (f32, Vec3) {
        let a = airframe.arm_length * core::f32::consts::FRAC_1_SQRT_2;
        let mut t = 0.0;
        let mut tau = Vec3::zeros();
        for i in 0..4 {
            let f = self.thrust_n[i];
            t += f;
            tau.x -= ROTOR_XY_UNIT[i][1] * a * f;
            tau.y += ROTOR_XY_UNIT[i][0] * a * f;
            tau.z += ROTOR_YAW_SIGN[i] * airframe.torque_to_thrust * f;
        }
        (t, tau)
    }
}

/// X-quadrotor mixer (see the module documentation for the policy).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mixer {
    /// `a = arm_length/√2`, m.
    a: f32,
    /// Drag-torque ratio κ, m.
    kappa: f32,
    /// Per-rotor maximum thrust, N.
    f_max: f32,
}

/// Why an airframe cannot be mixed for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MixerError {
    /// Arm length, torque ratio or rotor thrust not finite and positive.
    BadAirframe,
}

impl Mixer {
    /// Mixer for `airframe`; errors when a geometric or thrust parameter is not finite and > 0.
    pub fn new(airframe: &Airframe) -> Result<Self, MixerError> {
        let ok = |x: f32| x.is_finite() && x > 0.0;
        if !(ok(airframe.arm_length) && ok(airframe.torque_to_thrust) && ok(airframe.rotor_thrust_max)) {
            return Err(MixerError::BadAirframe);
        }
        Ok(Mixer {
            a: airframe.arm_length * core::f32::consts::FRAC_1_SQRT_2,
            kappa: airframe.torque_to_thrust,
            f_max: airframe.rotor_thrust_max,
        })
    }

    /// Maximum thrust of one rotor, N.
    pub fn rotor_thrust_max(&self) -> f32 {
        self.f_max
    }

    /// Mix collective thrust `thrust` (N, ≥ 0 meaningful) and body torque `torque`
    /// (N·m, FRD) into rotor thrusts and motor commands. Always finite, in range.
    pub fn mix(&self, thrust: f32, torque: &Vec3) -> MixerOutput {
        let mut fault = false;
        let mut clean = |x: f32| {
            if x.is_finite() {
                x
            } else {
                fault = true;
                0.0
            }
        };
        let t = maxf(clean(thrust), 0.0);
        let (tx, ty, tz) = (clean(torque.x), clean(torque.y), clean(torque.z));
        let fm = self.f_max;

        // 1. Roll/pitch differential, scaled to fit in a span of f_max.
        let mut rp = [0.0f32; 4];
        for (i, d) in rp.iter_mut().enumerate() {
            *d = (-ROTOR_XY_UNIT[i][1] * tx + ROTOR_XY_UNIT[i][0] * ty) / (4.0 * self.a);
        }
        let (lo, hi) = min_max(&rp);
        let span = hi - lo;
        let mut rp_limited = false;
        if span > fm {
            let k = fm / span;
            rp.iter_mut().for_each(|d| *d *= k);
            rp_limited = true;
        }
        let (lo, hi) = min_max(&rp);

        // 2. Collective: shift as little as possible so that base + rp ∈ [0, f_max].
        let want = t / 4.0;
        let base = clampf(want, -lo, maxf(fm - hi, -lo));
        let thrust_limited = (base - want).abs() > 1e-6 * maxf(fm, 1.0);

        // 3. Yaw: largest scale λ ∈ [0, 1] keeping every rotor in range.
        let mut lambda = 1.0f32;
        let mut yaw = [0.0f32; 4];
        for i in 0..4 {
            yaw[i] = ROTOR_YAW_SIGN[i] * tz / (4.0 * self.kappa);
            let f0 = base + rp[i];
            let y = yaw[i];
            if y > 0.0 && f0 + y > fm {
                lambda = minf(lambda, maxf((fm - f0) / y, 0.0));
            } else if y < 0.0 && f0 + y < 0.0 {
                lambda = minf(lambda, maxf(f0 / -y, 0.0));
            }
        }
        let yaw_limited = lambda < 1.0;

        let mut out = MixerOutput {
            roll_pitch_limited: rp_limited,
            thrust_limited,
            yaw_limited,
            input_fault: fault,
            ..MixerOutput::default()
        };
        for i in 0..4 {
            let f = clampf(base + rp[i] + lambda * yaw[i], 0.0, fm);
            // clamp() of a NaN stays NaN; the inputs are clean so f is finite, but be explicit.
            let f = if f.is_finite() { f } else { 0.0 };
            out.thrust_n[i] = f;
            out.throttle[i] = sqrtf(f / fm).clamp(0.0, 1.0);
        }
        out
    }
}

fn min_max(x: &[f32; 4]) -> (f32, f32) {
    x.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (minf(lo, v), maxf(hi, v)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mixer() -> (Mixer, Airframe) {
        let af = Airframe::default();
        (Mixer::new(&af).unwrap(), af)
    }

    #[test]
    fn unsaturated_mixing_is_exact_inverse() {
        let (m, af) = mixer();
        let tau = Vec3::new(0.05, -0.03, 0.01);
        let out = m.mix(4.905, &tau);
        assert!(!out.saturated() && !out.input_fault);
        let (t, w) = out.wrench(&af);
        assert!((t - 4.905).abs() < 1e-5);
        assert!((w - tau).norm() < 1e-6, "{w:?}");
        for i in 0..4 {
            assert!((out.throttle[i] * out.throttle[i] * af.rotor_thrust_max - out.thrust_n[i]).abs() < 1e-5);
        }
    }

    #[test]
    fn hover_throttle_and_signs() {
        let (m, af) = mixer();
        let out = m.mix(af.mass * crate::frame::GRAVITY, &Vec3::zeros());
        let f = af.mass * crate::frame::GRAVITY / 4.0;
        for i in 0..4 {
            assert!((out.thrust_n[i] - f).abs() < 1e-6);
            assert!((out.throttle[i] - libm::sqrtf(f / af.rotor_thrust_max)).abs() < 1e-6);
        }
        // Positive roll (right side down): the right rotors (1 and 4, indices 0 and 3) slow down.
        let r = m.mix(4.0, &Vec3::new(0.1, 0.0, 0.0));
        assert!(r.thrust_n[0] < 1.0 && r.thrust_n[3] < 1.0 && r.thrust_n[1] > 1.0 && r.thrust_n[2] > 1.0);
        // Positive pitch (nose up): the front rotors (1 and 3, indices 0 and 2) speed up.
        let p = m.mix(4.0, &Vec3::new(0.0, 0.1, 0.0));
        assert!(p.thrust_n[0] > 1.0 && p.thrust_n[2] > 1.0 && p.thrust_n[1] < 1.0 && p.thrust_n[3] < 1.0);
        // Positive yaw: CCW rotors (yaw sign +1, indices 0 and 1) speed up.
        let y = m.mix(4.0, &Vec3::new(0.0, 0.0, 0.01));
        assert!(y.thrust_n[0] > 1.0 && y.thrust_n[1] > 1.0 && y.thrust_n[2] < 1.0 && y.thrust_n[3] < 1.0);
    }

    #[test]
    fn saturation_keeps_roll_pitch_then_thrust_then_yaw() {
        let (m, af) = mixer();
        let fm = af.rotor_thrust_max;
        let a = af.arm_length * core::f32::consts::FRAC_1_SQRT_2;
        // (a) Huge thrust + moderate roll: roll kept exactly, thrust reduced, yaw dropped.
        let tau = Vec3::new(0.2, 0.0, 0.05);
        let out = m.mix(100.0, &tau);
        let (t, w) = out.wrench(&af);
        assert!((w.x - 0.2).abs() < 1e-5, "roll kept: {w:?}");
        assert!(w.y.abs() < 1e-5);
        assert!(out.thrust_limited && !out.roll_pitch_limited);
        assert!(t < 4.0 * fm && t > 3.0 * fm, "thrust as high as roll allows: {t}");
        assert!(out.yaw_limited && w.z.abs() < 0.05, "yaw sacrificed: {}", w.z);
        // (b) Low thrust + roll demand: thrust raised to keep roll authority.
        let out = m.mix(0.0, &Vec3::new(0.1, 0.0, 0.0));
        let (t, w) = out.wrench(&af);
        assert!((w.x - 0.1).abs() < 1e-5 && out.thrust_limited && t > 0.0);
        // (c) Roll/pitch beyond authority: scaled together keeping their ratio, thrust at mid range.
        let out = m.mix(2.0 * fm, &Vec3::new(3.0, 1.5, 0.0));
        let (t, w) = out.wrench(&af);
        assert!(out.roll_pitch_limited);
        assert!((w.x / w.y - 2.0).abs() < 1e-4, "direction kept: {w:?}");
        assert!(w.x > 0.9 * fm * a && w.x <= 2.0 * fm * a + 1e-5);
        assert!((t - 2.0 * fm).abs() < 1e-4, "mid-range collective unchanged: {t}");
        // (d) Yaw within what is left: scaled, roll and thrust untouched.
        let out = m.mix(2.0, &Vec3::new(0.05, 0.0, 10.0));
        let (t, w) = out.wrench(&af);
        assert!(out.yaw_limited && !out.thrust_limited && !out.roll_pitch_limited);
        assert!((t - 2.0).abs() < 1e-5 && (w.x - 0.05).abs() < 1e-5 && w.z > 0.0);
        // Some rotor hits a limit (the largest feasible yaw).
        assert!(out.thrust_n.iter().any(|&f| f < 1e-5 || f > fm - 1e-5));
    }

    #[test]
    fn non_finite_inputs_give_finite_in_range_outputs() {
        let (m, af) = mixer();
        for (t, tau) in [
            (f32::NAN, Vec3::zeros()),
            (4.0, Vec3::new(f32::INFINITY, 0.0, 0.0)),
            (f32::NEG_INFINITY, Vec3::new(f32::NAN, f32::NAN, f32::NAN)),
            (1e30, Vec3::new(-1e30, 1e30, 1e30)),
            (-5.0, Vec3::new(0.0, 0.0, -1e-30)),
        ] {
            let out = m.mix(t, &tau);
            for i in 0..4 {
                assert!(
                    out.thrust_n[i].is_finite() && (0.0..=af.rotor_thrust_max).contains(&out.thrust_n[i])
                );
                assert!(out.throttle[i].is_finite() && (0.0..=1.0).contains(&out.throttle[i]));
            }
        }
        assert!(m.mix(f32::NAN, &Vec3::zeros()).input_fault);
        assert!(Mixer::new(&Airframe { arm_length: 0.0, ..Airframe::default() }).is_err());
    }
}
