//! The inner loop (default 1 kHz): attitude estimator → attitude P → rate PID → mixer,
//! producing the motor outputs.
//!
//! ```text
//!  ImuSample ─▶ estimator (Mahony) ─φ̂,θ̂,ψ̂, ω̂─▶ attitude P (Euler, wrapped yaw) ─ω_sp─▶ rate PID ─τ─▶ mixer ─▶ MotorOutput
//!  EstimatorAid (fix yaw, acceleration) ─┘                ▲ AttitudeCommand (φ_d, θ_d, ψ_d, T, stage) from the outer loop
//!  StateEstimate (attitude, tilt, bad samples, tilt trip) ─▶ outer loop
//! ```
//!
//! Owns [`estimator`] (Mahony attitude estimator with gyro-bias calibration),
//! [`attitude`] (attitude P and rate PID), [`mixer`] (thrust and torque → rotor thrusts and
//! throttles) and [`InnerLoop`], which runs them on every IMU sample. It reads the outer loop
//! only through the [`AttitudeCommand`] and [`EstimatorAid`] messages and publishes the
//! [`StateEstimate`]; so the two loops can run in different tasks. The crash cut-off is
//! here, so that it acts in the same step: a tilt beyond the limit while the motors are
//! enabled stops them at once and stays latched (reported as [`StateEstimate::tilt_trip`])
//! until a command with the motors off arrives. While the motors are off the estimator runs
//! its at-rest gyro-bias calibration.
//!
//! May import: the crate root foundation ([`crate::frame`], [`crate::fmath`],
//! [`crate::airframe`], [`crate::Vec3`]) and [`crate::msg`]. Never [`crate::outer`],
//! [`crate::safety`], [`crate::supervisor`] or the facade: what it needs from the outer loop
//! arrives as a message.

pub mod attitude;
pub mod estimator;
pub mod mixer;

use crate::airframe::Airframe;
use crate::msg::{
    AttitudeCommand, EstimatorAid, Euler, ImuSample, ImuStatus, MotorOutput, MotorStage, StateEstimate,
    TiltTrip,
};
use crate::Vec3;
use attitude::{torque_vec, AttitudeController, AttitudeError, AttitudeParams};
use estimator::{AttitudeEstimator, EstimatorError, EstimatorParams};
use mixer::{Mixer, MixerError, MixerOutput};

/// The inner loop's parameters (a part of [`crate::controller::ControllerParams`], see
/// `ControllerParams::inner_params`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InnerParams {
    /// Vehicle (inertia for the rate loop, rotor layout and limits for the mixer).
    pub airframe: Airframe,
    /// Attitude estimator.
    pub estimator: EstimatorParams,
    /// Attitude and rate loops.
    pub attitude: AttitudeParams,
    /// Nominal rate, Hz (the step's `dt` when there is no previous step).
    pub rate_hz: f32,
    /// Motor command while armed on the ground, 0..1.
    pub idle_throttle: f32,
    /// The estimator uses the fix aids only while the fix is at most this old, µs.
    pub position_timeout_us: u64,
    /// Tilt that means a crash, rad: the motors are cut at once.
    pub tilt_limit: f32,
}

/// Why the inner loop could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InnerError {
    /// Attitude/rate parameters.
    Attitude(AttitudeError),
    /// Estimator parameters.
    Estimator(EstimatorError),
    /// Airframe unusable by the mixer.
    Mixer(MixerError),
}

/// The inner loop's part of the telemetry (updated by every inner step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InnerTelemetry {
    /// Time of the last inner step, µs.
    pub t_us: u64,
    /// Estimated attitude (Euler ZYX, rad).
    pub attitude: Euler,
    /// Estimated gyro bias, rad/s FRD.
    pub gyro_bias: Vec3,
    /// Estimator status of the last IMU sample.
    pub imu_status: ImuStatus,
    /// Body-rate setpoint, rad/s FRD.
    pub rate_sp: [f32; 3],
    /// Torque command, N·m FRD.
    pub torque: [f32; 3],
    /// Motor output of the last inner step.
    pub motors: MotorOutput,
    /// Mixer saturation flags of the last inner step.
    pub mixer: MixerOutput,
    /// Inner steps run.
    pub count: u32,
}

/// The inner loop (see the module documentation).
#[derive(Clone, Debug)]
pub struct InnerLoop {
    params: InnerParams,
    estimator: AttitudeEstimator,
    attitude: AttitudeController,
    mixer: Mixer,
    command: AttitudeCommand,
    aid: EstimatorAid,
    last_us: Option<u64>,
    mix_saturated: bool,
    rejected: u32,
    tilt: f32,
    tilt_trip: Option<TiltTrip>,
    telemetry: InnerTelemetry,
}

fn age(now: u64, t: u64) -> u64 {
    now.saturating_sub(t)
}

impl InnerLoop {
    /// An inner loop with the motors off, no aid, an uninitialised estimator.
    pub fn new(params: InnerParams) -> Result<Self, InnerError> {
        let estimator = AttitudeEstimator::new(params.estimator).map_err(InnerError::Estimator)?;
        let telemetry = InnerTelemetry {
            t_us: 0,
            attitude: Euler::default(),
            gyro_bias: Vec3::zeros(),
            imu_status: ImuStatus::BadDt,
            rate_sp: [0.0; 3],
            torque: [0.0; 3],
            motors: MotorOutput::default(),
            mixer: MixerOutput::default(),
            count: 0,
        };
        Ok(InnerLoop {
            attitude: AttitudeController::new(params.attitude, params.airframe.inertia)
                .map_err(InnerError::Attitude)?,
            mixer: Mixer::new(&params.airframe).map_err(InnerError::Mixer)?,
            tilt: estimator.tilt(),
            estimator,
            command: AttitudeCommand::default(),
            aid: EstimatorAid::default(),
            last_us: None,
            mix_saturated: false,
            rejected: 0,
            tilt_trip: None,
            telemetry,
            params,
        })
    }

    /// Parameters in use.
    pub fn params(&self) -> &InnerParams {
        &self.params
    }

    /// The telemetry of the inner loop.
    pub fn telemetry(&self) -> &InnerTelemetry {
        &self.telemetry
    }

    /// The attitude estimator (read-only).
    pub fn estimator(&self) -> &AttitudeEstimator {
        &self.estimator
    }

    /// Take the outer loop's latest command. A command that is not [`MotorStage::Fly`]
    /// clears the attitude/rate controller state (disarm, motors off, arming); one with the
    /// motors off also acknowledges a tilt trip.
    pub fn set_command(&mut self, command: AttitudeCommand) {
        if command.stage != MotorStage::Fly {
            self.attitude.reset();
        }
        if command.stage == MotorStage::Off {
            self.tilt_trip = None;
        }
        self.command = command;
    }

    /// Take the latest estimator aid from the position fixes.
    pub fn set_aid(&mut self, aid: EstimatorAid) {
        self.aid = aid;
    }

    /// The state estimate for the outer loop: publish it after every [`Self::step`].
    pub fn estimate(&self) -> StateEstimate {
        StateEstimate {
            t_us: self.last_us,
            attitude: self.telemetry.attitude,
            tilt: self.tilt,
            initialised: self.estimator.is_initialised(),
            rate: self.estimator.rate(),
            gyro_bias: self.telemetry.gyro_bias,
            imu_status: self.telemetry.imu_status,
            rejected_samples: self.rejected,
            tilt_trip: self.tilt_trip,
        }
    }

    /// One inner step at `now_us`: estimator, crash check, attitude P, rate PID, mixer.
    /// `imu`: gyro rad/s FRD, specific force m/s² FRD. Returns the motor commands — always
    /// finite and in range; all zero unless the command allows the motors.
    pub fn step(&mut self, now_us: u64, imu: &ImuSample) -> MotorOutput {
        let nominal_dt = 1.0 / self.params.rate_hz;
        let dt = match self.last_us {
            Some(t) if now_us >= t => age(now_us, t) as f32 * 1e-6,
            Some(_) => 0.0,
            None => nominal_dt,
        };
        self.last_us = Some(now_us);
        self.telemetry.t_us = now_us;
        self.telemetry.count = self.telemetry.count.wrapping_add(1);

        // Estimator aids: with a fresh fix, the acceleration from the fix velocities and
        // the fix yaw. Flying without a fix, the commanded acceleration (p̈ ≈ u): the
        // accelerometer of a multirotor sees mostly the thrust direction, so without any
        // acceleration aid a commanded tilt would be mistaken for level.
        let fix_fresh = self.aid.fix_t_us.is_some_and(|t| age(now_us, t) <= self.params.position_timeout_us);
        let enabled = self.command.stage != MotorStage::Off && self.tilt_trip.is_none();
        let accel_world = if fix_fresh {
            Some(self.aid.accel_ned)
        } else if enabled && self.command.stage == MotorStage::Fly {
            Some(self.command.accel_ned)
        } else {
            None
        };
        let yaw_ext = if fix_fresh { self.aid.yaw } else { None };
        // Motors off: the vehicle is taken as at rest for the gyro-bias calibration.
        self.estimator.set_at_rest(!enabled);
        let status = self.estimator.update(imu, dt, accel_world, yaw_ext);
        if status == ImuStatus::RejectedNonFinite {
            self.rejected = self.rejected.wrapping_add(1);
        }
        if self.estimator.is_initialised() {
            // Crash check: tilt above the limit (or not finite) while the motors are enabled
            // cuts them in this step; the supervisor turns the trip into MotorsOff.
            self.tilt = self.estimator.tilt();
            let crashed = !self.tilt.is_finite() || self.tilt > self.params.tilt_limit;
            if enabled && crashed {
                self.tilt_trip = Some(TiltTrip { t_us: now_us, tilt: self.tilt });
            }
        }
        let att = self.estimator.euler();
        let tel = &mut self.telemetry;
        tel.imu_status = status;
        tel.attitude = att;
        tel.gyro_bias = self.estimator.gyro_bias();

        let enabled = self.command.stage != MotorStage::Off && self.tilt_trip.is_none();
        let out = if !enabled {
            self.attitude.reset();
            self.mix_saturated = false;
            self.telemetry.rate_sp = [0.0; 3];
            self.telemetry.torque = [0.0; 3];
            self.telemetry.mixer = MixerOutput::default();
            MotorOutput::default()
        } else if self.command.stage == MotorStage::Idle {
            self.attitude.reset();
            self.mix_saturated = false;
            let c = self.params.idle_throttle;
            let f = c * c * self.params.airframe.rotor_thrust_max;
            self.telemetry.rate_sp = [0.0; 3];
            self.telemetry.torque = [0.0; 3];
            MotorOutput { throttle: [c; 4], thrust_n: [f; 4], armed: true }
        } else {
            let sp = self.command.setpoint;
            let sp_euler = Euler { roll: sp.roll, pitch: sp.pitch, yaw: sp.yaw };
            let rate = self.estimator.rate();
            let a = self.attitude.update(&sp_euler, &att, &[rate.x, rate.y, rate.z], dt, self.mix_saturated);
            let mix = self.mixer.mix(sp.thrust, &torque_vec(&a));
            self.mix_saturated = mix.saturated();
            let tel = &mut self.telemetry;
            tel.rate_sp = a.rate_sp;
            tel.torque = a.torque;
            tel.mixer = mix;
            MotorOutput { throttle: mix.throttle, thrust_n: mix.thrust_n, armed: true }
        };
        // Last line of defence: never emit a non-finite or out-of-range command.
        let fm = self.params.airframe.rotor_thrust_max;
        let sane = out.throttle.iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c))
            && out.thrust_n.iter().all(|f| f.is_finite() && (0.0..=fm).contains(f));
        let out = if sane { out } else { MotorOutput { armed: out.armed, ..MotorOutput::default() } };
        self.telemetry.motors = out;
        out
    }
}
