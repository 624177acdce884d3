//! Inner-loop attitude controller (PX4 / Crazyflie structure):
//! attitude error → body-rate setpoint (P, rate limits) → rate PID → body torques.
//!
//! ## Attitude loop (Euler ZYX, documented choice)
//! The setpoint comes from the thrust mapping (paper eq. 5) as roll/pitch/yaw
//! Euler angles ZYX (see [`crate::frame`]), so the attitude loop works on the
//! same angles:
//!
//! ```text
//! e      = (φ_d − φ, θ_d − θ, wrap_pi(ψ_d − ψ))          rad
//! η̇_sp   = K_att ⊙ e                                       Euler-angle rates, rad/s
//! ω_sp   = W(φ, θ) η̇_sp, clamped per axis to ±rate_max     body FRD rates, rad/s
//! W      = [[1, 0, −sθ], [0, cφ, sφ cθ], [0, −sφ, cφ cθ]]
//! ```
//!
//! `W` is the exact map from Euler-angle rates to body rates, so small errors
//! decay per axis as `ė = −K_att e`. The yaw error is wrapped to (−π, π], so the
//! vehicle always turns the short way. Euler angles are singular at θ = ±90°;
//! the thrust mapping's tilt limit keeps the setpoint far from it and the
//! estimator's attitude is only used this way while flying (a crash tilt turns
//! the motors off, see [`crate::failsafe`]).
//!
//! ## Rate loop
//! Per body axis, an angular-acceleration command
//! `α = K_p (ω_sp − ω) + I − K_d ω̇_f`, where `I` integrates `K_i (ω_sp − ω)` and
//! `ω̇_f` is the low-passed derivative of the **measured** rate (derivative on
//! measurement: a setpoint step gives no derivative kick). Torque
//! `τ = J ⊙ α` (N·m), so the gains are independent of the inertia.
//! **Anti-windup**: the integrator is clamped to `±integral_limit` and frozen
//! while the mixer reports saturation (conditional integration).
//! `α` is clamped to `±alpha_max` so a wild input cannot produce a huge torque.

use crate::fmath::sincosf;
use crate::frame::{clampf, wrap_pi};
pub use crate::msg::Euler;
use crate::Vec3;

/// Attitude and rate controller gains, limits and filter settings.
///
/// Defaults are tuned for the paper's vehicle (m = 0.5 kg, J = diag(0.0019, 0.0019, 0.0033) kg·m²)
/// with the inner loop at 1 kHz and motor time constants up to ~30 ms:
/// rate-loop bandwidth ≈ 40 rad/s (roll/pitch), attitude-loop bandwidth ≈ 6.5 rad/s,
/// close to PX4's default ratio (MC_ROLL_P 6.5).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AttitudeParams {
    /// Attitude P gain per axis (roll, pitch, yaw), 1/s. Default (6.5, 6.5, 2.8).
    pub att_p: [f32; 3],
    /// Body-rate setpoint limit per axis, rad/s. Default (3.5, 3.5, 1.5) (200, 200, 86 °/s).
    pub rate_max: [f32; 3],
    /// Rate P gain per axis: angular acceleration per rate error, 1/s. Default (40, 40, 15).
    pub rate_p: [f32; 3],
    /// Rate I gain per axis, 1/s². Default (30, 30, 10).
    pub rate_i: [f32; 3],
    /// Rate D gain per axis (on the measured rate), dimensionless (s·1/s). Default (0.02, 0.02, 0).
    pub rate_d: [f32; 3],
    /// Integrator clamp per axis (angular-acceleration contribution), rad/s². Default (20, 20, 10).
    pub integral_limit: [f32; 3],
    /// Cut-off of the first-order low-pass on the rate derivative, Hz. Default 30.
    pub d_cutoff_hz: f32,
    /// Clamp of the angular-acceleration command, rad/s². Default 400.
    pub alpha_max: f32,
    /// Largest accepted time step, s; longer or non-positive steps are P-only
    /// (no integration, derivative state reset). Default 0.02.
    pub dt_max: f32,
}

impl Default for AttitudeParams {
    fn default() -> Self {
        AttitudeParams {
            att_p: [6.5, 6.5, 2.8],
            rate_max: [3.5, 3.5, 1.5],
            rate_p: [40.0, 40.0, 15.0],
            rate_i: [30.0, 30.0, 10.0],
            rate_d: [0.02, 0.02, 0.0],
            integral_limit: [20.0, 20.0, 10.0],
            d_cutoff_hz: 30.0,
            alpha_max: 400.0,
            dt_max: 0.02,
        }
    }
}

/// Why attitude parameters were rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AttitudeError {
    /// A gain, limit or the inertia is negative or not finite (inertia, rate limits,
    /// cut-off, alpha_max and dt_max must be > 0).
    BadParams,
}

impl AttitudeParams {
    /// Check every field (finite; gains ≥ 0; limits, cut-off > 0).
    pub fn validate(&self) -> Result<(), AttitudeError> {
        let pos = |x: &f32| x.is_finite() && *x > 0.0;
        let nonneg = |x: &f32| x.is_finite() && *x >= 0.0;
        let ok = self.rate_max.iter().all(pos)
            && self.att_p.iter().all(nonneg)
            && self.rate_p.iter().all(nonneg)
            && self.rate_i.iter().all(nonneg)
            && self.rate_d.iter().all(nonneg)
            && self.integral_limit.iter().all(nonneg)
            && pos(&self.d_cutoff_hz)
            && pos(&self.alpha_max)
            && pos(&self.dt_max);
        if ok {
            Ok(())
        } else {
            Err(AttitudeError::BadParams)
        }
    }
}

/// Output of one inner-loop step.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AttitudeOutput {
    /// Body-rate setpoint after limits, rad/s FRD.
    pub rate_sp: [f32; 3],
    /// Body torque command, N·m FRD.
    pub torque: [f32; 3],
    /// An input (attitude, setpoint, rate or dt) was rejected this step.
    pub input_fault: bool,
}

/// Attitude P loop + rate PID loop (see the module documentation).
#[derive(Clone, Debug)]
pub struct AttitudeController {
    params: AttitudeParams,
    inertia: [f32; 3],
    integral: [f32; 3],
    prev_rate: Option<[f32; 3]>,
    d_filt: [f32; 3],
}

impl AttitudeController {
    /// New controller for a vehicle of principal inertia `inertia` (Jx, Jy, Jz about body
    /// FRD axes, kg·m²; the airframe's, [`crate::airframe::Airframe::inertia`]); errors on
    /// invalid parameters or an inertia that is not finite and > 0.
    pub fn new(params: AttitudeParams, inertia: [f32; 3]) -> Result<Self, AttitudeError> {
        params.validate()?;
        if !inertia.iter().all(|j| j.is_finite() && *j > 0.0) {
            return Err(AttitudeError::BadParams);
        }
        Ok(AttitudeController { params, inertia, integral: [0.0; 3], prev_rate: None, d_filt: [0.0; 3] })
    }

    /// Principal inertia in use, kg·m².
    pub fn inertia(&self) -> [f32; 3] {
        self.inertia
    }

    /// Parameters in use.
    pub fn params(&self) -> &AttitudeParams {
        &self.params
    }

    /// Clear the integrator and the derivative state (on arming, on landing).
    pub fn reset(&mut self) {
        self.integral = [0.0; 3];
        self.prev_rate = None;
        self.d_filt = [0.0; 3];
    }

    /// Integrator state, rad/s² per axis (telemetry).
    pub fn integral(&self) -> [f32; 3] {
        self.integral
    }

    /// Attitude loop: body-rate setpoint (rad/s FRD) from the setpoint and the
    /// measured attitude. Non-finite input gives a zero rate setpoint and `false`.
    pub fn rate_setpoint(&self, sp: &Euler, att: &Euler) -> ([f32; 3], bool) {
        if !sp.is_finite() || !att.is_finite() {
            return ([0.0; 3], false);
        }
        let p = &self.params;
        let e = [wrap_pi(sp.roll - att.roll), wrap_pi(sp.pitch - att.pitch), wrap_pi(sp.yaw - att.yaw)];
        let eta = [p.att_p[0] * e[0], p.att_p[1] * e[1], p.att_p[2] * e[2]];
        let (sphi, cphi) = sincosf(att.roll);
        let (sth, cth) = sincosf(att.pitch);
        let w = [
            eta[0] - sth * eta[2],
            cphi * eta[1] + sphi * cth * eta[2],
            -sphi * eta[1] + cphi * cth * eta[2],
        ];
        let mut out = [0.0; 3];
        for i in 0..3 {
            out[i] = clampf(w[i], -p.rate_max[i], p.rate_max[i]);
        }
        (out, true)
    }

    /// Rate loop: body torque (N·m FRD) from the rate setpoint and the measured
    /// body rate (rad/s FRD, gyro minus estimated bias). `dt_s` is the time since
    /// the previous call; `saturated` is the previous mixer step's saturation flag
    /// (freezes the integrator). Non-finite rates give zero torque and keep the state.
    pub fn rate_control(
        &mut self,
        rate_sp: &[f32; 3],
        rate: &[f32; 3],
        dt_s: f32,
        saturated: bool,
    ) -> ([f32; 3], bool) {
        let finite = rate_sp.iter().chain(rate.iter()).all(|x| x.is_finite());
        if !finite {
            return ([0.0; 3], false);
        }
        let p = self.params;
        let dt_ok = dt_s.is_finite() && dt_s > 0.0 && dt_s <= p.dt_max;
        // Derivative of the measured rate, first-order low-passed.
        if dt_ok {
            if let Some(prev) = self.prev_rate {
                let tau = 1.0 / (2.0 * core::f32::consts::PI * p.d_cutoff_hz);
                let k = dt_s / (tau + dt_s);
                for (i, d) in self.d_filt.iter_mut().enumerate() {
                    let raw = ((rate[i] - prev[i]) / dt_s).clamp(-1e5, 1e5);
                    *d += k * (raw - *d);
                }
            }
            self.prev_rate = Some(*rate);
        } else {
            self.prev_rate = None;
            self.d_filt = [0.0; 3];
        }
        let mut torque = [0.0; 3];
        for i in 0..3 {
            let e = (rate_sp[i] - rate[i]).clamp(-1e4, 1e4);
            if dt_ok && !saturated {
                let lim = p.integral_limit[i];
                self.integral[i] = clampf(self.integral[i] + p.rate_i[i] * e * dt_s, -lim, lim);
            }
            let alpha = p.rate_p[i] * e + self.integral[i] - p.rate_d[i] * self.d_filt[i];
            torque[i] = self.inertia[i] * clampf(alpha, -p.alpha_max, p.alpha_max);
        }
        (torque, dt_ok)
    }

    /// Both loops in one call: setpoint + measured attitude + measured body rate → torques.
    pub fn update(
        &mut self,
        sp: &Euler,
        att: &Euler,
        rate: &[f32; 3],
        dt_s: f32,
        saturated: bool,
    ) -> AttitudeOutput {
        let (rate_sp, att_ok) = self.rate_setpoint(sp, att);
        let (torque, rate_ok) = self.rate_control(&rate_sp, rate, dt_s, saturated);
        AttitudeOutput { rate_sp, torque, input_fault: !(att_ok && rate_ok) }
    }
}

/// Torque as a [`Vec3`] (N·m FRD), for the mixer.
pub fn torque_vec(o: &AttitudeOutput) -> Vec3 {
    Vec3::new(o.torque[0], o.torque[1], o.torque[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's vehicle inertia, kg·m².
    const J: [f32; 3] = [0.0019, 0.0019, 0.0033];

    fn ctl() -> AttitudeController {
        AttitudeController::new(AttitudeParams::default(), J).unwrap()
    }

    fn e(roll: f32, pitch: f32, yaw: f32) -> Euler {
        Euler { roll, pitch, yaw }
    }

    #[test]
    fn attitude_p_and_rate_limits() {
        let c = ctl();
        let p = AttitudeParams::default();
        let (w, ok) = c.rate_setpoint(&e(0.1, -0.05, 0.0), &e(0.0, 0.0, 0.0));
        assert!(ok);
        assert!((w[0] - p.att_p[0] * 0.1).abs() < 1e-6);
        assert!((w[1] + p.att_p[1] * 0.05).abs() < 1e-6);
        assert!(w[2].abs() < 1e-6);
        let (w, _) = c.rate_setpoint(&e(1.5, -1.5, 3.0), &e(0.0, 0.0, 0.0));
        assert_eq!(w, [p.rate_max[0], -p.rate_max[1], p.rate_max[2]]);
    }

    #[test]
    fn yaw_error_wraps_the_short_way() {
        let c = ctl();
        // Setpoint 3.1 rad, measured −3.1 rad: the short way is +0.083 rad (through ±π).
        let (w, _) = c.rate_setpoint(&e(0.0, 0.0, 3.1), &e(0.0, 0.0, -3.1));
        let expect = 2.8 * wrap_pi(3.1 + 3.1);
        assert!(expect < 0.0, "3.1 − (−3.1) = 6.2 wraps to −0.083");
        assert!((w[2] - expect).abs() < 1e-4, "{w:?}");
        let (w, _) = c.rate_setpoint(&e(0.0, 0.0, -3.1), &e(0.0, 0.0, 3.1));
        assert!(w[2] > 0.0 && w[2] < 0.5);
    }

    #[test]
    fn euler_rates_map_to_body_rates_when_tilted() {
        let c = ctl();
        // Rolled 0.5 rad, yaw error only: yaw about the world vertical needs both q and r.
        let phi = 0.5f32;
        let (w, _) = c.rate_setpoint(&e(phi, 0.0, 0.1), &e(phi, 0.0, 0.0));
        let eta = 2.8 * 0.1;
        assert!(w[0].abs() < 1e-6);
        assert!((w[1] - phi.sin() * eta).abs() < 1e-5);
        assert!((w[2] - phi.cos() * eta).abs() < 1e-5);
    }

    #[test]
    fn rate_pid_units_integrator_and_anti_windup() {
        let mut c = ctl();
        let p = AttitudeParams::default();
        let (t, ok) = c.rate_control(&[1.0, 0.0, 0.0], &[0.0; 3], 0.001, false);
        assert!(ok);
        // First step: P plus one integration step, no derivative yet.
        let expect = J[0] * (p.rate_p[0] * 1.0 + p.rate_i[0] * 1.0 * 0.001);
        assert!((t[0] - expect).abs() < 1e-7, "{} vs {expect}", t[0]);
        // Integrator grows under a constant error and stops at its limit.
        for _ in 0..5000 {
            c.rate_control(&[1.0, 0.0, 0.0], &[0.0; 3], 0.001, false);
        }
        assert!((c.integral()[0] - p.integral_limit[0]).abs() < 1e-4);
        // Frozen while saturated.
        c.reset();
        for _ in 0..100 {
            c.rate_control(&[1.0, 0.0, 0.0], &[0.0; 3], 0.001, true);
        }
        assert_eq!(c.integral(), [0.0; 3]);
    }

    #[test]
    fn derivative_on_measurement_has_no_setpoint_kick() {
        let mut c = ctl();
        c.rate_control(&[0.0; 3], &[0.0; 3], 0.001, false);
        let (t1, _) = c.rate_control(&[2.0, 0.0, 0.0], &[0.0; 3], 0.001, false);
        let p = AttitudeParams::default();
        // Setpoint step: only P and I act (no derivative of the setpoint).
        let pi_only = J[0] * (p.rate_p[0] * 2.0 + c.integral()[0]);
        assert!((t1[0] - pi_only).abs() < 1e-7);
        // Measurement step: the derivative opposes the change.
        let mut c = ctl();
        c.rate_control(&[0.0; 3], &[0.0; 3], 0.001, false);
        let (t2, _) = c.rate_control(&[0.0; 3], &[0.5, 0.0, 0.0], 0.001, false);
        let p_only = J[0] * (p.rate_p[0] * -0.5 + c.integral()[0]);
        assert!(t2[0] < p_only, "derivative adds damping: {} < {p_only}", t2[0]);
    }

    #[test]
    fn bad_inputs_give_finite_zero_or_p_only() {
        let mut c = ctl();
        let (t, ok) = c.rate_control(&[f32::NAN, 0.0, 0.0], &[0.0; 3], 0.001, false);
        assert!(!ok && t == [0.0; 3]);
        let (t, ok) = c.rate_control(&[1.0, 0.0, 0.0], &[0.0; 3], f32::INFINITY, false);
        assert!(!ok && t.iter().all(|x| x.is_finite()));
        assert_eq!(c.integral(), [0.0; 3], "no integration on a bad dt");
        let (t, _) = c.rate_control(&[1e30, -1e30, 1e30], &[-1e30, 1e30, 0.0], 0.001, false);
        let p = AttitudeParams::default();
        for (ti, ji) in t.iter().zip(J) {
            assert!(ti.is_finite() && ti.abs() <= ji * p.alpha_max + 1e-6);
        }
        let out = c.update(&e(f32::NAN, 0.0, 0.0), &e(0.0, 0.0, 0.0), &[0.0; 3], 0.001, false);
        assert!(out.input_fault && out.rate_sp == [0.0; 3]);
        assert!(AttitudeController::new(
            AttitudeParams { rate_p: [-1.0, 1.0, 1.0], ..Default::default() },
            J
        )
        .is_err());
    }
}
