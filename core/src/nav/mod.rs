//! Navigation filter: where the vehicle is from the IMU and delayed, noisy position sources
//! (GPS position and velocity, external vision / VIO position, motion capture, barometric
//! height) — issue 39. Derivation: `docs/cascade.md` § Navigation filter.
//!
//! An error-state extended Kalman filter (Solà, "Quaternion kinematics for the error-state
//! Kalman filter", 2017, §5 and §6) on **9 error states**: position `δp`, velocity `δv` (world
//! NED) and the accelerometer bias `δb_a` (body FRD). The attitude is *not* a state of this
//! filter: it comes from the inner loop's Mahony estimator ([`crate::estimator`], which also
//! takes the external / magnetometer yaw), so the 15-state formulation of the issue is cut to
//! 9 states; an attitude error shows up here as a slowly varying accelerometer bias.
//!
//! * **Predict** ([`NavFilter::predict`], every IMU sample, inner rate): nominal state
//!   `a = R(f − b_a) + g e₃`, `p += v dt + ½a dt²`, `v += a dt`; covariance
//!   `P ← F P Fᵀ + Q` with `F = I + [[0, I, 0], [0, 0, −R], [0, 0, 0]] dt`.
//! * **Delayed fixes** are fused at the time they describe, as PX4 EKF2's delayed horizon
//!   does, but without re-running the filter: a ring buffer ([`history`]) keeps the nominal
//!   position/velocity of the last 0.5 s; the innovation is the fix minus the state the filter
//!   had at the fix's time, and the correction is carried to now through the error transition
//!   `Φ(now, t_m)` (the measurement Jacobian becomes `H Φ(t_m, now)`; the process noise over
//!   the delay is added to the measurement noise). The same correction is carried back into
//!   the buffer, which plays the part of EKF2's output-predictor history.
//! * **Gating**: the normalised innovation squared `yᵀ S⁻¹ y` is tested against the χ²
//!   quantile at 1 − 10⁻⁴ ([`CHI2_GATE`]); rejected fixes are counted. NaN/Inf, beyond
//!   ±[`crate::cbf::INPUT_LIMIT`], a non-positive σ or a time outside the buffer are invalid
//!   and counted too.
//! * **Initialisation** from [`NavParams::init_fixes`] (default 3) consecutive position
//!   fixes that agree — each within the χ² gate of the one before (`|z₂ − z₁| ≤
//!   √(χ²₃·(σ₁² + σ₂²)) +` [`INIT_SPEED_M_S`]`·Δt`, `Δt ≤` [`INIT_GAP_US`]; a longer gap
//!   starts the count again) — from the last of them. A single first
//!   fix may be a multipath outlier (the `gps` preset draws 5 m ones at 1 %): initialised on
//!   it, the filter's σ said 0.5 m for an error of 6 m, the next fixes were gated as
//!   outliers until the reset, and the reset's delta moved the guidance's reference 6 m
//!   down, into the ground (navigation campaign flights 4655 and 9418,
//!   `docs/robustness.md` § Position sources). EKF2 likewise waits for its GPS checks to
//!   pass over a period before it uses GPS (`EKF2_GPS_CHECK`, `EKF2_REQ_*`).
//! * **Jumps** (a VIO reset, a GPS re-acquisition): after [`NavParams::reset_after`]
//!   consecutive rejected position fixes the source is re-initialised — a relative source
//!   (vision) by shifting its frame offset (the vehicle's estimate does not move, so the
//!   commanded acceleration does not jump), an absolute one (GPS) by resetting the position
//!   (the delta is reported with a reset counter, as EKF2's, for the guidance to shift).
//!
//! Fixed size, `f32`, no allocation, no panic, bounded time: one predict is one 9×9
//! covariance product; one update a 3×3 Cholesky and a pass over the 128-entry buffer.
//!
//! How a flight controller runs it (IMU-rate predict, fixes in, the controller's fix out, the
//! dropout failsafe) is [`aid::NavAid`], shared by the host and the firmware; the bound on its
//! error that the mapped obstacles' margin takes is [`bound`].
//!
//! Owns: [`NavFilter`], [`NavParams`], [`NavStatus`], [`FixKind`], [`Fusion`],
//! [`NAV_MAX_SIGMA_M`]. May import: the crate root foundation ([`crate::Vec3`], [`crate::frame`],
//! [`crate::fmath`]) and, in [`aid`], the stages' messages ([`crate::msg`]).

pub mod aid;
pub mod bound;
pub mod history;
pub mod mag;
mod update;

#[cfg(test)]
mod tests;

use nalgebra::{Matrix3, Rotation3, SMatrix};

use crate::fmath::sqrtf;
use crate::frame::GRAVITY;
use crate::Vec3;
use history::{History, Past};

/// 9×9 covariance of the error state `[δp, δv, δb_a]`.
pub type Cov9 = SMatrix<f32, 9, 9>;

/// Largest horizontal position σ the estimate is flown with, m ([`aid`]'s failsafe; the error
/// bound's cap, [`bound`]).
pub const NAV_MAX_SIGMA_M: f32 = 3.0;

/// χ² quantiles at 1 − 10⁻⁴ for 1, 2 and 3 degrees of freedom: the innovation gate.
pub const CHI2_GATE: [f32; 3] = [15.14, 18.42, 21.11];

/// The speed the vehicle may have while the filter initialises, m/s (module docs:
/// *Initialisation*): consecutive fixes may differ by this times their interval beyond
/// their noise. A vehicle initialises on the ground or hovering; a source lost and regained
/// in flight is a reset, not an initialisation.
pub const INIT_SPEED_M_S: f32 = 2.0;

/// The longest interval between two initialising fixes, µs (module docs: *Initialisation*).
/// The agreement bound grows with [`INIT_SPEED_M_S`]`·Δt`, so an old candidate would accept
/// almost any fix after a long gap (10 s: 20 m); a fix more than this after the candidate
/// starts the count again.
pub const INIT_GAP_US: u64 = 1_000_000;

/// Filter parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavParams {
    /// Acceleration process noise (IMU noise, attitude error, vibration), m/s²/√Hz.
    pub accel_noise: f32,
    /// Accelerometer bias random walk, m/s²/√s.
    pub accel_bias_walk: f32,
    /// Initial velocity σ, m/s.
    pub init_velocity_sigma: f32,
    /// Initial accelerometer-bias σ, m/s².
    pub init_bias_sigma: f32,
    /// One history entry at least every this many µs (4 ms: 0.512 s of past).
    pub history_period_us: u64,
    /// Consecutive gated position fixes after which the source is re-initialised.
    pub reset_after: u8,
    /// Consecutive agreeing position fixes the filter initialises from (module docs:
    /// *Initialisation*); 1: the first valid fix.
    pub init_fixes: u8,
    /// Largest IMU step integrated, s (a longer gap is skipped and counted).
    pub dt_max_s: f32,
}

impl Default for NavParams {
    fn default() -> Self {
        NavParams {
            accel_noise: 0.35,
            accel_bias_walk: 0.01,
            init_velocity_sigma: 1.0,
            init_bias_sigma: 0.2,
            history_period_us: 4_000,
            reset_after: 5,
            init_fixes: 3,
            dt_max_s: 0.05,
        }
    }
}

/// How a position source relates to the world frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FixKind {
    /// World frame (GPS, RTK, motion capture): a jump resets the position.
    Absolute,
    /// Its own frame, which may jump (visual odometry): a jump shifts the frame offset.
    Relative,
}

/// What the filter did with a fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fusion {
    /// Fused.
    Fused,
    /// The position fix that completes the initialisation: the filter is initialised from it.
    Initialised,
    /// A position fix before the initialisation that does not complete it (module docs:
    /// *Initialisation*): held as the candidate, not fused.
    Pending,
    /// Outside the innovation gate: not fused (counted).
    Gated,
    /// NaN/Inf, out of range, σ ≤ 0, older than the history or from the future: rejected.
    Invalid,
    /// No position yet: velocity/height fixes wait for the first position fix.
    NotInitialised,
    /// The source jumped: re-initialised (see the module docs).
    Reset,
}

/// Counters and the uncertainty the filter reports.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct NavStatus {
    /// Fixes fused (position, velocity, height).
    pub fused: u32,
    /// Fixes outside the gate.
    pub gated: u32,
    /// Fixes invalid (NaN/Inf, range, time) and IMU samples skipped.
    pub invalid: u32,
    /// Source re-initialisations (jumps).
    pub resets: u32,
    /// The last reset's delta (fix − estimate), NED, m.
    pub last_reset_delta: Vec3,
    /// Position σ per axis, m.
    pub sigma_p: Vec3,
    /// Velocity σ per axis, m/s.
    pub sigma_v: Vec3,
    /// Normalised innovation squared of the last position fix (fused or gated; compare with
    /// [`CHI2_GATE`]`[2]`).
    pub last_nis: f32,
    /// Normalised innovation squared of the last velocity fix (gate [`CHI2_GATE`]`[2]`).
    pub last_velocity_nis: f32,
    /// Normalised innovation squared of the last height fix (gate [`CHI2_GATE`]`[0]`).
    pub last_height_nis: f32,
}

/// The navigation filter (see the module documentation).
#[derive(Clone, Debug)]
pub struct NavFilter {
    params: NavParams,
    /// Time of the state, µs (`None` before the first IMU sample).
    t_us: Option<u64>,
    p: Vec3,
    v: Vec3,
    /// Accelerometer bias, body FRD, m/s².
    ba: Vec3,
    /// Body → world rotation of the last IMU sample.
    rot: Rotation3<f32>,
    cov: Cov9,
    initialised: bool,
    /// Offset of the relative (vision) frame: fix = p + offset.
    offset: Vec3,
    history: History,
    /// Consecutive gated position fixes.
    consecutive_gated: u8,
    /// Before the initialisation: the last valid position fix (time, position, σ) and how
    /// many consecutive fixes up to it agreed.
    candidate: Option<(u64, Vec3, f32, u8)>,
    /// Time of the last fused position fix, µs.
    last_position_us: Option<u64>,
    /// The normalised innovation squared of the last update (fused or gated).
    nis: f32,
    status: NavStatus,
}

fn finite3(v: &Vec3) -> bool {
    let l = crate::cbf::INPUT_LIMIT;
    v.x.abs() <= l && v.y.abs() <= l && v.z.abs() <= l
}

impl NavFilter {
    /// Not initialised: waits for an IMU sample and a position fix.
    pub fn new(params: NavParams) -> Self {
        NavFilter {
            params,
            t_us: None,
            p: Vec3::zeros(),
            v: Vec3::zeros(),
            ba: Vec3::zeros(),
            rot: Rotation3::identity(),
            cov: Cov9::zeros(),
            initialised: false,
            offset: Vec3::zeros(),
            history: History::new(),
            consecutive_gated: 0,
            candidate: None,
            last_position_us: None,
            nis: 0.0,
            status: NavStatus::default(),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &NavParams {
        &self.params
    }

    /// `true` once a position fix has initialised the filter.
    pub fn is_initialised(&self) -> bool {
        self.initialised
    }

    /// Counters and σ.
    pub fn status(&self) -> NavStatus {
        let d = self.cov.diagonal();
        let s = |i: usize| sqrtf(d[i].max(0.0));
        NavStatus {
            sigma_p: Vec3::new(s(0), s(1), s(2)),
            sigma_v: Vec3::new(s(3), s(4), s(5)),
            ..self.status
        }
    }

    /// The covariance of `[δp, δv, δb_a]`.
    pub fn covariance(&self) -> &Cov9 {
        &self.cov
    }

    /// Estimated accelerometer bias, body FRD, m/s².
    pub fn accel_bias(&self) -> Vec3 {
        self.ba
    }

    /// Position and velocity (NED) at `now_us`, extrapolated from the state's time with the
    /// velocity; `None` before initialisation.
    pub fn estimate(&self, now_us: u64) -> Option<(Vec3, Vec3)> {
        let t = self.t_us?;
        if !self.initialised {
            return None;
        }
        let dt = if now_us >= t { (now_us - t) as f32 * 1e-6 } else { -((t - now_us) as f32) * 1e-6 };
        Some((self.p + self.v * dt, self.v))
    }

    /// Position fixes gated in a row (0 after a fused one): a source that disagrees with the
    /// prediction (EKF2's GPS glitch).
    pub fn consecutive_gated(&self) -> u8 {
        self.consecutive_gated
    }

    /// Age of the last fused position fix at `now_us`, µs.
    pub fn position_age_us(&self, now_us: u64) -> Option<u64> {
        self.last_position_us.map(|t| now_us.saturating_sub(t))
    }

    /// Propagate with one IMU sample at `t_us`: specific force `accel` (body FRD, m/s²) and the
    /// attitude `rot` (body → world) from the attitude estimator. Returns `false` when the
    /// sample was skipped (non-finite, or a time step ≤ 0 or above `dt_max_s`).
    pub fn predict(&mut self, t_us: u64, accel: &Vec3, rot: &Rotation3<f32>) -> bool {
        let ok_in = finite3(accel) && rot.matrix().iter().all(|x| x.is_finite());
        let Some(t0) = self.t_us else {
            if ok_in {
                self.t_us = Some(t_us);
                self.rot = *rot;
            }
            return ok_in;
        };
        let dt = if t_us > t0 { (t_us - t0) as f32 * 1e-6 } else { 0.0 };
        if !ok_in || dt <= 0.0 || dt > self.params.dt_max_s {
            self.status.invalid = self.status.invalid.wrapping_add(1);
            if ok_in && dt > self.params.dt_max_s {
                self.t_us = Some(t_us); // resume from here
            }
            return false;
        }
        self.t_us = Some(t_us);
        self.rot = *rot;
        if !self.initialised {
            return true;
        }
        let a = rot * (accel - self.ba) + Vec3::new(0.0, 0.0, GRAVITY);
        self.p += self.v * dt + a * (0.5 * dt * dt);
        self.v += a * dt;
        self.propagate_covariance(dt, rot.matrix());
        let due = self.history.newest_t_us().is_none_or(|t| t_us >= t + self.params.history_period_us);
        if due {
            self.history.push(Past { t_us, p: self.p, v: self.v });
        }
        true
    }

    /// `P ← F P Fᵀ + Q` (block form of the 9×9 product).
    fn propagate_covariance(&mut self, dt: f32, r: &Matrix3<f32>) {
        let mut f = Cov9::identity();
        f.fixed_view_mut::<3, 3>(0, 3).copy_from(&(Matrix3::identity() * dt));
        f.fixed_view_mut::<3, 3>(3, 6).copy_from(&(-r * dt));
        let mut p = f * self.cov * f.transpose();
        let qa = self.params.accel_noise * self.params.accel_noise * dt;
        let qb = self.params.accel_bias_walk * self.params.accel_bias_walk * dt;
        for i in 0..3 {
            p[(3 + i, 3 + i)] += qa;
            p[(6 + i, 6 + i)] += qb;
        }
        self.cov = (p + p.transpose()) * 0.5;
    }

    /// (Re)initialise at `z` (NED, m) with σ `sigma` m.
    fn initialise(&mut self, t_us: u64, z: Vec3, sigma: f32) {
        self.p = z;
        self.v = Vec3::zeros();
        self.ba = Vec3::zeros();
        self.offset = Vec3::zeros();
        let pr = &self.params;
        let mut d = [0.0f32; 9];
        for i in 0..3 {
            d[i] = sigma * sigma;
            d[3 + i] = pr.init_velocity_sigma * pr.init_velocity_sigma;
            d[6 + i] = pr.init_bias_sigma * pr.init_bias_sigma;
        }
        self.cov = Cov9::from_diagonal(&SMatrix::<f32, 9, 1>::from_row_slice(&d));
        // The first entry is at the fix's time, so the next (delayed) fixes find it.
        self.t_us = Some(self.t_us.map_or(t_us, |t| t.max(t_us)));
        self.history.clear();
        self.history.push(Past { t_us, p: self.p, v: self.v });
        self.initialised = true;
        self.consecutive_gated = 0;
        self.last_position_us = Some(t_us);
    }
}
