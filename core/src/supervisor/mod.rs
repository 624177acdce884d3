//! The supervisor: failsafe state machine, arming, bad-input accounting, braking and landing.
//!
//! Owns [`failsafe`] (Disarmed / Armed / Brake / Land / MotorsOff and the arm checks) and
//! [`Supervisor`], which runs the machine for the outer loop: it counts bad inputs (NaN/Inf
//! or out-of-range fixes, obstacle points and IMU samples) until the next data check, keeps
//! the brake point, the landing reference and the landing detector, and computes the
//! open-loop stop used while flying without a position fix. It runs with the outer loop, at
//! the outer rate (default 250 Hz), and on every command.
//!
//! Modes:
//! * **Brake**: hold the last good position estimate with zero velocity (the CBF filter stays
//!   on). Without a fresh fix: stop the last good velocity open-loop (constant deceleration
//!   `blind_brake_accel` for `|v|/blind_brake_accel` seconds), then level attitude at hover thrust.
//!   A Brake for stale data returns to Armed (the mission goes on) once the data has been fresh
//!   again for `resume_after_us` ([`failsafe`]): a short fix dropout is a brief hold, not a landing.
//! * **Land**: the reference descends at `land_speed` from the position at entry (leading the
//!   vehicle by at most `land_lead`); landed when the reference is pinned `land_lead` below
//!   the vehicle and the vehicle is still for `landed_time_us`. Without a fresh fix: the same
//!   open-loop stop, then level attitude and `land_thrust_factor` × hover thrust; landed after
//!   `land_no_fix_time_us` without a fix. A fix that returns re-seeds the descent where the
//!   vehicle is. A vehicle that never took off is landed at once.
//!
//! [`modes`] is the flight-mode machine of issue 21 (Manual, Position, Mission, Offboard, Hold,
//! Return, Land; RC-loss, offboard-loss and battery failsafes per mode).
//!
//! May import: the crate root foundation ([`crate::frame`], [`crate::fmath`],
//! [`crate::Vec3`]), [`crate::msg`], [`crate::rc`] and [`crate::battery`] (the mode machine's
//! inputs). Never the loops.

pub mod failsafe;
pub mod modes;

use crate::fmath::{minf, norm3};
use crate::frame::GRAVITY;
use crate::Vec3;
use failsafe::{ArmRefusal, DataHealth, Failsafe, FailsafeParams, FailsafeState, Transition};

/// Landing and braking (the `landing` part of [`crate::controller::ControllerParams`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LandingParams {
    /// Descent speed when landing with a position fix, m/s. Default 0.3.
    pub land_speed: f32,
    /// Largest lead of the landing reference below the vehicle, m. Default 0.3.
    pub land_lead: f32,
    /// Speed below which a pinned landing reference means "landed", m/s. Default 0.1.
    pub landed_speed: f32,
    /// Time the landed condition must hold, µs. Default 1 000 000.
    pub landed_time_us: u64,
    /// Thrust as a fraction of hover thrust when landing without a fix. Default 0.9.
    pub land_thrust_factor: f32,
    /// Time in Land without a position fix after which the vehicle is taken as landed, µs.
    /// Default 10 000 000.
    pub land_no_fix_time_us: u64,
    /// Deceleration used to stop the last good velocity when the position fix is lost
    /// (Brake/Land without a fix), m/s², in (0, 5]. Default 1.0.
    pub blind_brake_accel: f32,
}

impl Default for LandingParams {
    fn default() -> Self {
        LandingParams {
            land_speed: 0.3,
            land_lead: 0.3,
            landed_speed: 0.1,
            landed_time_us: 1_000_000,
            land_thrust_factor: 0.9,
            land_no_fix_time_us: 10_000_000,
            blind_brake_accel: 1.0,
        }
    }
}

/// The supervisor's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupervisorParams {
    /// Failsafe limits.
    pub failsafe: FailsafeParams,
    /// Landing and braking.
    pub landing: LandingParams,
}

/// Where the vehicle is when the supervisor enters a state (for the brake point and the
/// landing reference).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EntryContext {
    /// Fresh position estimate at the transition time, if any.
    pub position: Option<Vec3>,
    /// Position of the last accepted fix (stale or not), if any.
    pub last_fix: Option<Vec3>,
    /// The vehicle is on the ground (guidance *Ground*: never took off).
    pub on_ground: bool,
}

/// The supervisor (see the module documentation).
#[derive(Clone, Debug)]
pub struct Supervisor {
    params: SupervisorParams,
    failsafe: Failsafe,
    pending_fault: bool,
    non_finite_inputs: u32,
    brake_point: Vec3,
    land_ref: Vec3,
    land_ref_valid: bool,
    land_from_ground: bool,
    landed_since_us: Option<u64>,
    no_fix_since_us: Option<u64>,
    last_fresh_velocity: Vec3,
    blind_velocity: Option<Vec3>,
}

fn age(now: u64, t: u64) -> u64 {
    now.saturating_sub(t)
}

impl Supervisor {
    /// A supervisor in Disarmed.
    pub fn new(params: SupervisorParams) -> Self {
        Supervisor {
            failsafe: Failsafe::new(params.failsafe),
            params,
            pending_fault: false,
            non_finite_inputs: 0,
            brake_point: Vec3::zeros(),
            land_ref: Vec3::zeros(),
            land_ref_valid: false,
            land_from_ground: false,
            landed_since_us: None,
            no_fix_since_us: None,
            last_fresh_velocity: Vec3::zeros(),
            blind_velocity: None,
        }
    }

    /// Parameters in use.
    pub fn params(&self) -> &SupervisorParams {
        &self.params
    }

    /// Failsafe state.
    pub fn state(&self) -> FailsafeState {
        self.failsafe.state()
    }

    /// Number of failsafe transitions so far.
    pub fn transition_count(&self) -> u32 {
        self.failsafe.transition_count()
    }

    /// Count `n` bad inputs (NaN/Inf or out of range); the next data check brakes.
    pub fn note_faults(&mut self, n: u32) {
        if n > 0 {
            self.pending_fault = true;
            self.non_finite_inputs = self.non_finite_inputs.saturating_add(n);
        }
    }

    /// Bad inputs since start.
    pub fn non_finite_inputs(&self) -> u32 {
        self.non_finite_inputs
    }

    /// A bad input is waiting for the next data check.
    pub fn fault_pending(&self) -> bool {
        self.pending_fault
    }

    /// The brake point (last good position at the entry into Brake).
    pub fn brake_point(&self) -> Vec3 {
        self.brake_point
    }

    /// The vehicle was on the ground when Land was entered.
    pub fn land_from_ground(&self) -> bool {
        self.land_from_ground
    }

    /// Arm: the failsafe checks with `health`, the estimator's readiness and tilt.
    pub fn arm(
        &mut self,
        now_us: u64,
        health: &DataHealth,
        attitude_ok: bool,
        tilt: f32,
    ) -> Result<Transition, ArmRefusal> {
        self.failsafe.arm(now_us, health, attitude_ok, tilt)
    }

    /// The arm checks without arming ([`Failsafe::arm_check`]).
    pub fn arm_check(&self, health: &DataHealth, attitude_ok: bool, tilt: f32) -> Result<(), ArmRefusal> {
        self.failsafe.arm_check(health, attitude_ok, tilt)
    }

    /// `true` when a fix of age `age_us` is fresh (the failsafe's position timeout).
    pub fn position_fresh(&self, age_us: Option<u64>) -> bool {
        self.failsafe.position_fresh(age_us)
    }

    /// Disarm (operator kill), from any state but Disarmed.
    pub fn disarm(&mut self, now_us: u64) -> Option<Transition> {
        self.failsafe.disarm(now_us)
    }

    /// Land command (from Armed or Brake).
    pub fn land(&mut self, now_us: u64) -> Option<Transition> {
        self.failsafe.land(now_us)
    }

    /// Land for `reason` (a mode change or a per-mode failsafe; from Armed or Brake).
    pub fn land_for(&mut self, now_us: u64, reason: failsafe::TransitionReason) -> Option<Transition> {
        self.failsafe.land_for(now_us, reason)
    }

    /// Disarm for `reason` (the kill switch), from any state but Disarmed.
    pub fn disarm_for(&mut self, now_us: u64, reason: failsafe::TransitionReason) -> Option<Transition> {
        self.failsafe.disarm_for(now_us, reason)
    }

    /// Crash check with a tilt the inner loop reported at `t_us`.
    pub fn check_tilt(&mut self, t_us: u64, tilt: f32) -> Option<Transition> {
        self.failsafe.check_tilt(t_us, tilt)
    }

    /// Start of an outer step: track how long the fix has been missing and the last good
    /// velocity (`fresh`: the position estimate at `now_us`, if fresh).
    pub fn track_fix(&mut self, now_us: u64, fresh: Option<(Vec3, Vec3)>) {
        match fresh {
            None => {
                self.no_fix_since_us.get_or_insert(now_us);
                self.blind_velocity.get_or_insert(self.last_fresh_velocity);
            }
            Some((_, v)) => {
                self.no_fix_since_us = None;
                self.blind_velocity = None;
                self.last_fresh_velocity = v;
            }
        }
    }

    /// The data check of one outer step: consumes the pending bad input, runs the landing
    /// detector and the failsafe machine. Returns the transition, if any.
    pub fn check_data(
        &mut self,
        now_us: u64,
        health: &DataHealth,
        fresh: Option<(Vec3, Vec3)>,
    ) -> Option<Transition> {
        self.pending_fault = false;
        let landed = self.landed(now_us, fresh);
        self.failsafe.check_data(now_us, health, landed)
    }

    /// Side effects of entering a state (brake point, landing reference).
    pub fn on_enter(&mut self, tr: Transition, at: &EntryContext) {
        match tr.to {
            FailsafeState::Brake => {
                self.brake_point = at.position.unwrap_or_else(|| at.last_fix.unwrap_or_else(Vec3::zeros));
            }
            FailsafeState::Land => {
                self.land_ref = at.position.unwrap_or(self.brake_point);
                self.land_ref_valid = at.position.is_some();
                self.land_from_ground = at.on_ground;
                self.landed_since_us = None;
            }
            FailsafeState::Disarmed | FailsafeState::MotorsOff | FailsafeState::Armed => {}
        }
    }

    /// Landing detector (used in Land).
    fn landed(&mut self, now_us: u64, fresh: Option<(Vec3, Vec3)>) -> bool {
        if self.failsafe.state() != FailsafeState::Land {
            return false;
        }
        if self.land_from_ground {
            return true;
        }
        let entered = self.failsafe.since_us();
        match fresh {
            Some((p, v)) => {
                self.no_fix_since_us = None;
                let pinned = self.land_ref.z - p.z >= 0.9 * self.params.landing.land_lead;
                if pinned && norm3(&v) < self.params.landing.landed_speed {
                    let since = *self.landed_since_us.get_or_insert(now_us);
                    age(now_us, since) >= self.params.landing.landed_time_us
                } else {
                    self.landed_since_us = None;
                    false
                }
            }
            None => {
                let since = (*self.no_fix_since_us.get_or_insert(now_us)).max(entered);
                age(now_us, since) >= self.params.landing.land_no_fix_time_us
            }
        }
    }

    /// The landing target of one outer step in Land, `dt` s after the previous one: descends
    /// at `land_speed`, leading the vehicle by at most `land_lead` (`fresh` as in
    /// [`Self::track_fix`]).
    pub fn land_target(&mut self, dt: f32, fresh: Option<(Vec3, Vec3)>) -> Vec3 {
        if let Some((p, _)) = fresh {
            if !self.land_ref_valid {
                // First fix after landing blind: descend from where the vehicle is now
                // (it may have dropped or drifted), never climb back.
                self.land_ref = p;
                self.land_ref_valid = true;
            }
            // Descend at land_speed, leading the vehicle by at most land_lead.
            self.land_ref.z = minf(
                self.land_ref.z + self.params.landing.land_speed * dt,
                p.z + self.params.landing.land_lead,
            );
        } else {
            self.land_ref_valid = false;
        }
        self.land_ref
    }

    /// The open-loop acceleration command without a position fix, NED m/s²: stop the last
    /// good velocity v0 at `blind_brake_accel` (for |v0|/a seconds, the double-integrator
    /// stopping time), then level attitude at hover thrust (or slightly less when landing).
    pub fn blind_accel(&self, now_us: u64) -> Vec3 {
        let factor = if self.failsafe.state() == FailsafeState::Land {
            self.params.landing.land_thrust_factor
        } else {
            1.0
        };
        let mut u = Vec3::new(0.0, 0.0, (1.0 - factor) * GRAVITY);
        let v0 = self.blind_velocity.unwrap_or_else(Vec3::zeros);
        let speed = norm3(&v0);
        let a_b = self.params.landing.blind_brake_accel;
        let blind_s = self.no_fix_since_us.map_or(0.0, |t| age(now_us, t) as f32 * 1e-6);
        if speed > 1e-3 && blind_s < speed / a_b {
            u -= v0 * (a_b / speed);
        }
        u
    }
}
