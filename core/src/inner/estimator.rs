//! Attitude estimator: Mahony complementary filter on SO(3) from a 3-axis gyro
//! and accelerometer, with gyro-bias estimation and an optional external yaw.
//!
//! (The `ahrs` crate was considered; its current release depends on nalgebra
//! 0.34, not the workspace's 0.35, so the filter is written here — it is short.)
//!
//! ## Filter
//! Attitude `q` is the rotation body FRD → world NED. Each step, with gyro `ω_m`
//! (rad/s, FRD) and accelerometer specific force `f` (m/s², FRD; `(0, 0, −g)`
//! at rest and level):
//!
//! ```text
//! v_meas = −f/|f|                                   measured "down" in body axes
//! v_est  = R(q)ᵀ (g e₃ − a_w) / |g e₃ − a_w|        predicted "down" (a_w: known world accel.)
//! e      = v_meas × v_est                           tilt error, rad (small angle)
//! e_ψ    = wrap_pi(ψ_ext − ψ) · R(q)ᵀ e₃            external-yaw error about world down
//! ω      = ω_m − b + k_p e + k_ψ e_ψ
//! b     ← clamp(b − (k_i e + k_iψ e_ψ) dt, ±bias_max)
//! q     ← q ⊗ exp(ω dt / 2)
//! ```
//!
//! The first external yaw sets the yaw at once (at start-up, or the first one after a
//! start without it); later ones correct it through `k_ψ`, `k_iψ`.
//!
//! `a_w` (world NED acceleration, m/s²) is optional: without it the filter
//! assumes the vehicle is not accelerating, which in sustained accelerated
//! flight pulls the tilt estimate towards level (the accelerometer of a
//! multirotor mostly sees the thrust direction). The
//! [`crate::controller::FlightController`] passes the acceleration obtained
//! from the external velocity fixes. The accelerometer is ignored (gyro and bias
//! integration only) when `|f|` differs from the expected `|g e₃ − a_w|` by more than
//! `accel_gate·g` (bumps, free fall, an acceleration the aid does not explain).
//!
//! **At rest** ([`AttitudeEstimator::set_at_rest`], set by the controller while the
//! motors are off) the vehicle is assumed not to rotate: while the bias-corrected
//! rate stays below `rest_rate_max` and the accelerometer is usable, the bias is
//! also pulled straight to the gyro reading with time constant `rest_bias_tau_s`
//! (the start-up gyro calibration of PX4/Betaflight). The Mahony integral alone
//! learns a bias with a time constant of ≈ 1/k_i·k_p ≈ 20 s.
//!
//! Position and velocity are **not** estimated here: they come from outside
//! (motion capture, VIO or the simulator) as a position fix.
//!
//! ## Bad samples
//! A sample with a NaN/Inf component, or beyond [`GYRO_LIMIT`] / [`ACCEL_LIMIT`], is rejected: the state is kept, the
//! rejection counted and reported in the returned [`ImuStatus`]. A time step
//! that is not finite, ≤ 0 or above `dt_max` is not integrated (the
//! accelerometer/yaw correction is still not applied; state kept).

use crate::attitude::Euler;
use crate::fmath::{norm3, sincosf, sqrtf};
use crate::frame::{clampf, is_finite3, quat_from_euler, wrap_pi, GRAVITY};
pub use crate::msg::{ImuSample, ImuStatus};
use crate::Vec3;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Largest plausible gyro component, rad/s (MEMS gyros saturate near 35 rad/s).
pub const GYRO_LIMIT: f32 = 100.0;

/// Largest plausible accelerometer component, m/s² (≈ 100 g; MEMS parts saturate at 16–32 g).
pub const ACCEL_LIMIT: f32 = 1000.0;

/// Estimator gains and limits.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimatorParams {
    /// Proportional tilt-correction gain, rad/s per rad. Default 1.0 (time constant ≈ 1 s).
    pub kp: f32,
    /// Integral (gyro-bias) gain for the tilt error, rad/s² per rad. Default 0.05.
    pub ki: f32,
    /// Proportional external-yaw gain, rad/s per rad. Default 1.0.
    pub kp_yaw: f32,
    /// Integral external-yaw (z-bias) gain, rad/s² per rad. Default 0.05.
    pub ki_yaw: f32,
    /// The accelerometer is used only when `|f|` is within `accel_gate·g` of the expected
    /// `|g e₃ − a_w|` (`g` without an acceleration aid). Default 0.25.
    pub accel_gate: f32,
    /// Clamp of each gyro-bias component, rad/s. Default 0.2.
    pub bias_max: f32,
    /// Largest time step integrated, s. Default 0.02.
    pub dt_max: f32,
    /// Time constant of the at-rest gyro-bias calibration, s. Default 1.0.
    pub rest_bias_tau_s: f32,
    /// Largest bias-corrected rate still taken as "not rotating" at rest, rad/s. Default 0.2.
    pub rest_rate_max: f32,
}

impl Default for EstimatorParams {
    fn default() -> Self {
        EstimatorParams {
            kp: 1.0,
            ki: 0.05,
            kp_yaw: 1.0,
            ki_yaw: 0.05,
            accel_gate: 0.25,
            bias_max: 0.2,
            dt_max: 0.02,
            rest_bias_tau_s: 1.0,
            rest_rate_max: 0.2,
        }
    }
}

/// Why estimator parameters were rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EstimatorError {
    /// A gain is negative or not finite, or `accel_gate`, `bias_max`, `dt_max`,
    /// `rest_bias_tau_s`, `rest_rate_max` not > 0.
    BadParams,
}

impl EstimatorParams {
    /// Check every field.
    pub fn validate(&self) -> Result<(), EstimatorError> {
        let nonneg = |x: f32| x.is_finite() && x >= 0.0;
        let pos = |x: f32| x.is_finite() && x > 0.0;
        if nonneg(self.kp)
            && nonneg(self.ki)
            && nonneg(self.kp_yaw)
            && nonneg(self.ki_yaw)
            && pos(self.accel_gate)
            && pos(self.bias_max)
            && pos(self.dt_max)
            && pos(self.rest_bias_tau_s)
            && pos(self.rest_rate_max)
        {
            Ok(())
        } else {
            Err(EstimatorError::BadParams)
        }
    }
}

/// Mahony attitude estimator (see the module documentation).
#[derive(Clone, Debug)]
pub struct AttitudeEstimator {
    params: EstimatorParams,
    q: UnitQuaternion<f32>,
    bias: Vec3,
    rate: Vec3,
    initialised: bool,
    yaw_aligned: bool,
    at_rest: bool,
    rejected: u32,
    last: ImuStatus,
}

impl AttitudeEstimator {
    /// New estimator (level, zero bias, not initialised); errors on invalid parameters.
    pub fn new(params: EstimatorParams) -> Result<Self, EstimatorError> {
        params.validate()?;
        Ok(AttitudeEstimator {
            params,
            q: UnitQuaternion::identity(),
            bias: Vec3::zeros(),
            rate: Vec3::zeros(),
            initialised: false,
            yaw_aligned: false,
            at_rest: false,
            rejected: 0,
            last: ImuStatus::BadDt,
        })
    }

    /// Tell the estimator whether the vehicle is at rest (motors off, on the ground):
    /// enables the fast at-rest gyro-bias calibration (see the module documentation).
    pub fn set_at_rest(&mut self, at_rest: bool) {
        self.at_rest = at_rest;
    }

    /// Forget the attitude and bias (next valid sample re-initialises).
    pub fn reset(&mut self) {
        self.q = UnitQuaternion::identity();
        self.bias = Vec3::zeros();
        self.rate = Vec3::zeros();
        self.initialised = false;
        self.yaw_aligned = false;
    }

    /// Attitude quaternion, body FRD → world NED.
    pub fn quaternion(&self) -> UnitQuaternion<f32> {
        self.q
    }

    /// Attitude as Euler ZYX angles, rad.
    ///
    /// nalgebra's `euler_angles` (same branches), except that away from gimbal lock the two
    /// `atan2` arguments are not both divided by `cos θ` (> 0 there, so the angle is the
    /// same up to round-off): that saves libm's `cosf`, which works in `f64` and costs
    /// ≈ 1,100 instructions on the Cortex-M4F.
    pub fn euler(&self) -> Euler {
        use core::f32::consts::FRAC_PI_2;
        let r = self.q.to_rotation_matrix();
        let m = r.matrix();
        let r20 = m[(2, 0)];
        let (roll, pitch, yaw) = if r20.abs() < 1.0 {
            (libm::atan2f(m[(2, 1)], m[(2, 2)]), -libm::asinf(r20), libm::atan2f(m[(1, 0)], m[(0, 0)]))
        } else if r20 <= -1.0 {
            (libm::atan2f(m[(0, 1)], m[(0, 2)]), FRAC_PI_2, 0.0)
        } else {
            (-libm::atan2f(-m[(0, 1)], -m[(0, 2)]), -FRAC_PI_2, 0.0)
        };
        Euler { roll, pitch, yaw }
    }

    /// [`Self::euler`]'s yaw alone (rad; 0 at gimbal lock, as there), without the roll and
    /// pitch it would also compute.
    pub fn yaw(&self) -> f32 {
        let r = self.q.to_rotation_matrix();
        let m = r.matrix();
        if m[(2, 0)].abs() < 1.0 {
            libm::atan2f(m[(1, 0)], m[(0, 0)])
        } else {
            0.0
        }
    }

    /// Tilt: angle between body z and world z (down), rad, in [0, π].
    pub fn tilt(&self) -> f32 {
        let r22 = self.q.to_rotation_matrix().matrix()[(2, 2)];
        libm::acosf(r22.clamp(-1.0, 1.0))
    }

    /// Bias-corrected body rate of the last accepted sample, rad/s FRD.
    pub fn rate(&self) -> Vec3 {
        self.rate
    }

    /// Estimated gyro bias, rad/s FRD.
    pub fn gyro_bias(&self) -> Vec3 {
        self.bias
    }

    /// `true` after the first valid sample.
    pub fn is_initialised(&self) -> bool {
        self.initialised
    }

    /// Number of samples rejected as non-finite since creation.
    pub fn rejected_count(&self) -> u32 {
        self.rejected
    }

    /// Status of the last [`update`](Self::update).
    pub fn last_status(&self) -> ImuStatus {
        self.last
    }

    /// Set the attitude directly (e.g. a test or a ground alignment), keeping the bias.
    pub fn set_attitude(&mut self, q: UnitQuaternion<f32>) {
        if q.coords.iter().all(|c| c.is_finite()) {
            self.q = q;
            self.initialised = true;
        }
    }

    fn accel_usable(&self, f: &Vec3, a_w: &Vec3) -> bool {
        let expected = norm3(&(Vec3::new(0.0, 0.0, GRAVITY) - a_w));
        let n = norm3(f);
        // Near free fall the direction of f is meaningless (and 1/|f| unbounded).
        n >= 0.5 * GRAVITY && (n - expected).abs() <= self.params.accel_gate * GRAVITY
    }

    /// Process one sample taken `dt_s` seconds after the previous one.
    /// `accel_world`: known world NED acceleration of the vehicle (m/s²) to
    /// compensate, if any; `yaw_ext`: external yaw measurement (rad), if any.
    pub fn update(
        &mut self,
        imu: &ImuSample,
        dt_s: f32,
        accel_world: Option<Vec3>,
        yaw_ext: Option<f32>,
    ) -> ImuStatus {
        let status = self.update_inner(imu, dt_s, accel_world, yaw_ext);
        if status == ImuStatus::RejectedNonFinite {
            self.rejected = self.rejected.saturating_add(1);
        }
        self.last = status;
        status
    }

    fn update_inner(
        &mut self,
        imu: &ImuSample,
        dt_s: f32,
        accel_world: Option<Vec3>,
        yaw_ext: Option<f32>,
    ) -> ImuStatus {
        let in_range = |v: &Vec3, lim: f32| is_finite3(v) && v.amax() <= lim;
        if !in_range(&imu.gyro, GYRO_LIMIT) || !in_range(&imu.accel, ACCEL_LIMIT) {
            return ImuStatus::RejectedNonFinite;
        }
        // Non-finite aids are ignored rather than rejecting a good IMU sample.
        let a_w = accel_world.filter(is_finite3).unwrap_or_else(Vec3::zeros);
        let yaw_ext = yaw_ext.filter(|y| y.is_finite());
        let p = self.params;
        if !self.initialised {
            if !self.accel_usable(&imu.accel, &a_w) {
                // Cannot level yet: keep identity and wait for a usable sample.
                self.rate = imu.gyro;
                return ImuStatus::AccelIgnored;
            }
            let f = imu.accel;
            let pitch = libm::atan2f(f.x, sqrtf(f.y * f.y + f.z * f.z));
            let roll = libm::atan2f(-f.y, -f.z);
            self.q = quat_from_euler(roll, pitch, yaw_ext.unwrap_or(0.0));
            self.rate = imu.gyro - self.bias;
            self.initialised = true;
            self.yaw_aligned = yaw_ext.is_some();
            return ImuStatus::Initialised;
        }
        if let (false, Some(psi)) = (self.yaw_aligned, yaw_ext) {
            // First external yaw after a start without one: take it at once (keep roll, pitch).
            let e = self.euler();
            self.q = quat_from_euler(e.roll, e.pitch, psi);
            self.yaw_aligned = true;
        }
        if !(dt_s.is_finite() && dt_s > 0.0 && dt_s <= p.dt_max) {
            return ImuStatus::BadDt;
        }
        let r_t = self.q.to_rotation_matrix().matrix().transpose();
        let e3 = Vector3::new(0.0, 0.0, 1.0);
        let mut corr = Vec3::zeros();
        let mut bias_dot = Vec3::zeros();
        let use_acc = self.accel_usable(&imu.accel, &a_w);
        if use_acc {
            let v_meas = -imu.accel / norm3(&imu.accel);
            let g_w = e3 * GRAVITY - a_w;
            let n = norm3(&g_w);
            // A compensation that cancels gravity would leave no reference: fall back to level.
            let v_est = if n > 0.5 * GRAVITY { r_t * (g_w / n) } else { r_t * e3 };
            let e = v_meas.cross(&v_est);
            corr += e * p.kp;
            bias_dot -= e * p.ki;
        }
        if let Some(psi) = yaw_ext {
            let e_psi = wrap_pi(psi - self.yaw());
            let axis = r_t * e3;
            corr += axis * (p.kp_yaw * e_psi);
            bias_dot -= axis * (p.ki_yaw * e_psi);
        }
        if !is_finite3(&corr) || !is_finite3(&bias_dot) {
            // Cannot happen with the guards above; never let a NaN into the state.
            return ImuStatus::RejectedNonFinite;
        }
        self.bias += bias_dot * dt_s;
        if self.at_rest && use_acc && (imu.gyro - self.bias).amax() < p.rest_rate_max {
            let k = dt_s / (p.rest_bias_tau_s + dt_s);
            self.bias += (imu.gyro - self.bias) * k;
        }
        let bm = p.bias_max;
        self.bias = self.bias.map(|b| clampf(b, -bm, bm));
        self.rate = imu.gyro - self.bias;
        let omega = self.rate + corr;
        let dq = quat_from_scaled_axis(&(omega * dt_s));
        let q = self.q * dq;
        // Renormalise (from_scaled_axis and the product keep unit norm up to rounding).
        let q = normalize_quat(q.into_inner());
        if q.coords.iter().all(|c| c.is_finite()) {
            self.q = q;
        }
        if use_acc {
            ImuStatus::Ok
        } else {
            ImuStatus::AccelIgnored
        }
    }
}

/// `UnitQuaternion::from_scaled_axis(w)` (rotation vector `w`, rad) with nalgebra 0.35's
/// arithmetic (`exp` of the pure quaternion `w/2`, identity below `ε²`), its square root
/// taken by [`sqrtf`] (the FPU instruction on the Cortex-M4F; the same value) and its
/// sine and cosine by [`sincosf`] (single precision; within one ulp of libm's).
fn quat_from_scaled_axis(w: &Vec3) -> UnitQuaternion<f32> {
    let v = w / 2.0;
    let nn = v.norm_squared();
    if nn <= f32::EPSILON * f32::EPSILON {
        return UnitQuaternion::identity();
    }
    let n = sqrtf(nn);
    let (s, c) = sincosf(n);
    let nv = v * (s / n);
    UnitQuaternion::new_unchecked(Quaternion::from_parts(c, nv))
}

/// `UnitQuaternion::new_normalize(q)` with the norm's square root taken by [`sqrtf`].
fn normalize_quat(q: Quaternion<f32>) -> UnitQuaternion<f32> {
    let n = sqrtf(q.coords.norm_squared());
    UnitQuaternion::new_unchecked(Quaternion::from(q.coords.map(|c| c / n)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Specific force seen at rest with attitude q.
    fn at_rest(q: &UnitQuaternion<f32>) -> Vec3 {
        q.inverse() * Vec3::new(0.0, 0.0, -GRAVITY)
    }

    fn est() -> AttitudeEstimator {
        AttitudeEstimator::new(EstimatorParams::default()).unwrap()
    }

    #[test]
    fn euler_equals_nalgebra_up_to_round_off() {
        let mut e = AttitudeEstimator::new(EstimatorParams::default()).unwrap();
        let cases = [
            (0.2f32, -0.3f32, 1.0f32),
            (-1.2, 0.7, -2.9),
            (0.0, 1.5, 0.3),
            (3.0, -1.4, 3.1),
            (0.0, 0.0, 0.0),
        ];
        for (r, p, y) in cases {
            let q = UnitQuaternion::from_euler_angles(r, p, y);
            e.set_attitude(q);
            let (nr, np, ny) = q.euler_angles();
            let a = e.euler();
            assert!((a.roll - nr).abs() < 2e-6 && (a.pitch - np).abs() < 2e-6, "{a:?} vs {nr} {np}");
            assert!(wrap_pi(a.yaw - ny).abs() < 2e-6, "{a:?} vs {ny}");
            assert_eq!(e.yaw().to_bits(), a.yaw.to_bits(), "yaw() is euler().yaw");
        }
        // At gimbal lock both give 0.
        for p in [core::f32::consts::FRAC_PI_2, -core::f32::consts::FRAC_PI_2] {
            e.set_attitude(UnitQuaternion::from_euler_angles(0.3, p, 1.0));
            assert_eq!(e.yaw().to_bits(), e.euler().yaw.to_bits(), "pitch {p}");
        }
    }

    #[test]
    fn initialises_roll_pitch_from_accelerometer() {
        let mut e = est();
        let q = UnitQuaternion::from_euler_angles(0.2, -0.3, 1.0);
        let s = e.update(&ImuSample { gyro: Vec3::zeros(), accel: at_rest(&q) }, 0.001, None, Some(1.0));
        assert_eq!(s, ImuStatus::Initialised);
        let a = e.euler();
        assert!((a.roll - 0.2).abs() < 1e-5 && (a.pitch + 0.3).abs() < 1e-5 && (a.yaw - 1.0).abs() < 1e-5);
        assert!((e.tilt() - libm::acosf(0.2f32.cos() * 0.3f32.cos())).abs() < 1e-4);
    }

    #[test]
    fn converges_from_wrong_attitude_and_learns_gyro_bias() {
        let mut e = est();
        let truth = UnitQuaternion::from_euler_angles(0.1, 0.05, 0.5);
        let bias = Vec3::new(0.02, -0.015, 0.01);
        e.set_attitude(UnitQuaternion::from_euler_angles(-0.2, 0.2, 0.0));
        let dt = 0.001;
        for _ in 0..120_000 {
            let imu = ImuSample { gyro: bias, accel: at_rest(&truth) };
            assert_eq!(e.update(&imu, dt, None, Some(0.5)), ImuStatus::Ok);
        }
        let a = e.euler();
        assert!((a.roll - 0.1).abs() < 2e-3 && (a.pitch - 0.05).abs() < 2e-3, "{a:?}");
        assert!(wrap_pi(a.yaw - 0.5).abs() < 2e-3, "{a:?}");
        assert!((e.gyro_bias() - bias).norm() < 2e-3, "bias {:?}", e.gyro_bias());
        assert!(e.rate().norm() < 2e-3);
    }

    #[test]
    fn at_rest_calibration_learns_the_bias_in_seconds() {
        let bias = Vec3::new(0.03, -0.02, 0.01);
        let imu = ImuSample { gyro: bias, accel: Vec3::new(0.0, 0.0, -GRAVITY) };
        let run = |rest: bool| {
            let mut e = est();
            e.set_attitude(UnitQuaternion::identity());
            e.set_at_rest(rest);
            for _ in 0..3000 {
                e.update(&imu, 0.001, None, None);
            }
            (e.gyro_bias() - bias).norm()
        };
        let (fast, slow) = (run(true), run(false));
        assert!(fast < 0.06 * bias.norm(), "3 s at rest: residual {fast}");
        assert!(slow > 0.5 * bias.norm(), "Mahony integral alone is slow: residual {slow}");
        // Rotating faster than rest_rate_max: no at-rest update.
        let mut e = est();
        e.set_attitude(UnitQuaternion::identity());
        e.set_at_rest(true);
        let spin = ImuSample { gyro: Vec3::new(0.0, 0.0, 1.0), accel: Vec3::new(0.0, 0.0, -GRAVITY) };
        for _ in 0..100 {
            e.update(&spin, 0.001, None, None);
        }
        assert!(e.gyro_bias().norm() < 0.01, "{:?}", e.gyro_bias());
    }

    #[test]
    fn first_external_yaw_aligns_at_once() {
        let mut e = est();
        let level = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -GRAVITY) };
        assert_eq!(e.update(&level, 0.001, None, None), ImuStatus::Initialised);
        assert!(e.euler().yaw.abs() < 1e-6);
        e.update(&level, 0.001, None, Some(2.5));
        assert!((e.euler().yaw - 2.5).abs() < 1e-3, "{:?}", e.euler());
        // Later yaw measurements only correct slowly (k_ψ = 1 rad/s per rad).
        e.update(&level, 0.001, None, Some(2.6));
        assert!((e.euler().yaw - 2.5).abs() < 1e-3);
    }

    #[test]
    fn tracks_rotation_from_gyro() {
        let mut e = est();
        e.set_attitude(UnitQuaternion::identity());
        // Pure roll at 1 rad/s for 0.3 s, accelerometer consistent with the motion at rest.
        let dt = 0.001;
        let mut truth = UnitQuaternion::identity();
        let w = Vec3::new(1.0, 0.0, 0.0);
        for _ in 0..300 {
            truth *= UnitQuaternion::from_scaled_axis(w * dt);
            e.update(&ImuSample { gyro: w, accel: at_rest(&truth) }, dt, None, None);
        }
        assert!((e.euler().roll - 0.3).abs() < 1e-3, "{:?}", e.euler());
    }

    #[test]
    fn acceleration_compensation_keeps_tilt_in_accelerated_flight() {
        // Vehicle tilted 0.2 rad in pitch, accelerating north at g·tan(0.2) with thrust along body −z.
        let truth = UnitQuaternion::from_euler_angles(0.0, -0.2, 0.0);
        let a_w = Vec3::new(GRAVITY * 0.2f32.tan(), 0.0, 0.0);
        let f = truth.inverse() * (a_w - Vec3::new(0.0, 0.0, GRAVITY));
        assert!(f.x.abs() < 1e-4, "specific force along body z only");
        let run = |comp: Option<Vec3>| {
            let mut e = est();
            e.set_attitude(truth);
            for _ in 0..5000 {
                e.update(&ImuSample { gyro: Vec3::zeros(), accel: f }, 0.001, comp, None);
            }
            e.euler().pitch
        };
        assert!((run(Some(a_w)) + 0.2).abs() < 1e-3);
        // A hard climb (|f| = 1.4 g) passes the gate when the aid explains it, not without it.
        let climb = Vec3::new(0.0, 0.0, -4.0);
        let f_climb = Vec3::new(0.0, 0.0, -GRAVITY - 4.0);
        let mut e = est();
        e.set_attitude(UnitQuaternion::identity());
        let imu = ImuSample { gyro: Vec3::zeros(), accel: f_climb };
        assert_eq!(e.update(&imu, 0.001, Some(climb), None), ImuStatus::Ok);
        assert_eq!(e.update(&imu, 0.001, None, None), ImuStatus::AccelIgnored);
        assert!(run(None) > -0.15, "without compensation the estimate drifts towards level");
    }

    #[test]
    fn rejects_non_finite_and_bad_dt_keeping_state() {
        let mut e = est();
        let q = UnitQuaternion::from_euler_angles(0.1, 0.0, 0.0);
        e.update(&ImuSample { gyro: Vec3::zeros(), accel: at_rest(&q) }, 0.001, None, None);
        let before = e.quaternion();
        for bad in [
            ImuSample { gyro: Vec3::new(f32::NAN, 0.0, 0.0), accel: at_rest(&q) },
            ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, f32::INFINITY, 0.0) },
            ImuSample { gyro: Vec3::new(0.0, 0.0, 1e3), accel: at_rest(&q) },
            ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(-1e30, 0.0, 0.0) },
        ] {
            assert_eq!(e.update(&bad, 0.001, None, None), ImuStatus::RejectedNonFinite);
        }
        assert_eq!(e.quaternion(), before);
        assert_eq!(e.rejected_count(), 4);
        let good = ImuSample { gyro: Vec3::new(1.0, 0.0, 0.0), accel: at_rest(&q) };
        for dt in [0.0, -1.0, f32::NAN, 10.0] {
            assert_eq!(e.update(&good, dt, None, None), ImuStatus::BadDt);
        }
        assert_eq!(e.quaternion(), before);
        // Non-finite aids are ignored, the sample still used.
        let s = e.update(&good, 0.001, Some(Vec3::new(f32::NAN, 0.0, 0.0)), Some(f32::INFINITY));
        assert_eq!(s, ImuStatus::Ok);
        // Free fall (|f| ≈ 0): accelerometer ignored, also when the aid predicts free fall.
        let s = e.update(&ImuSample { gyro: Vec3::zeros(), accel: Vec3::zeros() }, 0.001, None, None);
        assert_eq!(s, ImuStatus::AccelIgnored);
        let fall = Some(Vec3::new(0.0, 0.0, GRAVITY));
        let s = e.update(&ImuSample { gyro: Vec3::zeros(), accel: Vec3::zeros() }, 0.001, fall, None);
        assert_eq!(s, ImuStatus::AccelIgnored);
        assert!(
            e.gyro_bias().iter().all(|b| b.is_finite())
                && e.quaternion().coords.iter().all(|c| c.is_finite())
        );
        assert!(AttitudeEstimator::new(EstimatorParams { kp: -1.0, ..Default::default() }).is_err());
    }
}
