//! The messages between the cascade's stages: small `Copy` values, so each loop can run in
//! its own task and exchange them through a mailbox (a signal, a watch, a channel) instead of
//! sharing state.
//!
//! ```text
//!  position fix ──PositionFix──▶ outer loop ──AttitudeCommand──▶ inner loop ──MotorOutput──▶ motors
//!                                   │   ▲                         ▲   │
//!                                   │   └────StateEstimate────────┼───┘   (attitude, tilt, trips)
//!                                   └──────EstimatorAid───────────┘       (fix time, yaw, acceleration)
//!  IMU ──ImuSample──▶ inner loop
//! ```
//!
//! * [`AttitudeCommand`]: the outer loop's product (attitude/thrust setpoint, the output stage
//!   the supervisor allows, the commanded acceleration). Published after every outer step and
//!   after every command that changes the stage (arm, disarm, land, failsafe transitions).
//! * [`EstimatorAid`]: what the estimator may use from the position fix. Published on every
//!   accepted fix.
//! * [`StateEstimate`]: the inner loop's attitude estimate and what the supervisor must react
//!   to (bad IMU samples, a tilt trip). Published after every inner step.
//!
//! May import: the crate root foundation only ([`crate::Vec3`]). Every stage imports this module.

use crate::Vec3;

/// External position/velocity estimate (motion capture, VIO, simulator).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionFix {
    /// Time of validity, µs, on the controller clock.
    pub t_us: u64,
    /// Position, world NED, m.
    pub position: Vec3,
    /// Velocity, world NED, m/s.
    pub velocity: Vec3,
    /// Yaw, rad (FRD ZYX), if the source measures it; corrects the estimator's yaw drift.
    pub yaw: Option<f32>,
}

/// One inertial measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuSample {
    /// Angular rate, rad/s, body FRD.
    pub gyro: Vec3,
    /// Specific force (acceleration minus gravity), m/s², body FRD; `(0, 0, −9.81)` at rest and level.
    pub accel: Vec3,
}

impl ImuSample {
    /// `true` when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.gyro.iter().chain(self.accel.iter()).all(|x| x.is_finite())
    }
}

/// What the estimator did with a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImuStatus {
    /// Integrated, accelerometer correction applied.
    Ok,
    /// Integrated; accelerometer outside the gate, so gyro only.
    AccelIgnored,
    /// First valid sample: attitude initialised from the accelerometer (and external yaw).
    Initialised,
    /// Time step not finite, ≤ 0 or above `dt_max`: nothing integrated.
    BadDt,
    /// NaN/Inf in the sample, or a reading beyond [`crate::estimator::GYRO_LIMIT`] /
    /// [`crate::estimator::ACCEL_LIMIT`] (no real sensor reports it: corrupt data): rejected,
    /// state kept.
    RejectedNonFinite,
}

/// Roll, pitch, yaw (Euler ZYX, rad) — measured attitude or setpoint.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Euler {
    /// Roll φ, rad.
    pub roll: f32,
    /// Pitch θ, rad.
    pub pitch: f32,
    /// Yaw ψ, rad.
    pub yaw: f32,
}

impl Euler {
    /// `true` when all three angles are finite.
    pub fn is_finite(&self) -> bool {
        self.roll.is_finite() && self.pitch.is_finite() && self.yaw.is_finite()
    }
}

/// Attitude and thrust reference for the inner loop.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AttitudeSetpoint {
    /// φ_d, rad (FRD, positive right side down).
    pub roll: f32,
    /// θ_d, rad (FRD, positive nose up).
    pub pitch: f32,
    /// ψ_d, rad in (−π, π] (0 = north, positive towards east).
    pub yaw: f32,
    /// Collective thrust T, N (along body −z).
    pub thrust: f32,
    /// `true` when the acceleration command was limited (tilt, thrust, or bad input).
    pub saturated: bool,
}

/// What the inner loop does with the motors (decided by the outer loop and the supervisor).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MotorStage {
    /// Motors off (Disarmed, MotorsOff).
    #[default]
    Off,
    /// Armed on the ground: every motor at the idle throttle, no control.
    Idle,
    /// Flying: attitude and rate control of [`AttitudeCommand::setpoint`].
    Fly,
}

/// The outer loop's product, read by the inner loop.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AttitudeCommand {
    /// Output stage.
    pub stage: MotorStage,
    /// Attitude and collective-thrust setpoint (used in [`MotorStage::Fly`]).
    pub setpoint: AttitudeSetpoint,
    /// Commanded (filtered) acceleration `u`, world NED, m/s²: the estimator's acceleration
    /// aid while flying without a fresh position fix.
    pub accel_ned: Vec3,
}

/// What the attitude estimator may use from the position fix.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct EstimatorAid {
    /// Time of the last accepted fix, µs (`None` before the first one). The inner loop uses
    /// the aid only while the fix is fresh (age ≤ the position timeout).
    pub fix_t_us: Option<u64>,
    /// World acceleration from successive fix velocities (low-passed), NED, m/s².
    pub accel_ned: Vec3,
    /// Yaw of the last fix, rad, if the source measures it.
    pub yaw: Option<f32>,
}

/// A tilt beyond the crash limit seen by the inner loop while the motors were enabled.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TiltTrip {
    /// Time of the inner step that saw it, µs.
    pub t_us: u64,
    /// The tilt, rad (may be non-finite).
    pub tilt: f32,
}

/// The inner loop's state estimate and events, read by the outer loop and the supervisor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateEstimate {
    /// Time of the inner step that produced it, µs (`None` before the first step): part of
    /// the controller clock that rejects inputs time-stamped in the future.
    pub t_us: Option<u64>,
    /// Estimated attitude (Euler ZYX, rad).
    pub attitude: Euler,
    /// Tilt (angle between body z and world z), rad.
    pub tilt: f32,
    /// The estimator has been initialised by a valid sample.
    pub initialised: bool,
    /// Bias-corrected body rate, rad/s FRD.
    pub rate: Vec3,
    /// Estimated gyro bias, rad/s FRD.
    pub gyro_bias: Vec3,
    /// Status of the last IMU sample.
    pub imu_status: ImuStatus,
    /// IMU samples rejected as NaN/Inf or out of range since start (wrapping): the supervisor
    /// counts each new one as a bad input.
    pub rejected_samples: u32,
    /// Set from the inner step that cut the motors for a tilt beyond the limit until the inner
    /// loop receives a command with the motors off; the supervisor turns it into MotorsOff.
    pub tilt_trip: Option<TiltTrip>,
}

/// Motor commands of one inner step.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorOutput {
    /// Normalised commands in [0, 1], `ω = throttle·ω_max` (index 0..4 = rotors 1..4, see [`crate::airframe`]).
    pub throttle: [f32; 4],
    /// Rotor thrusts, N (= throttle² · rotor_thrust_max).
    pub thrust_n: [f32; 4],
    /// `true` when the motors may spin (Armed, Brake, Land).
    pub armed: bool,
}
