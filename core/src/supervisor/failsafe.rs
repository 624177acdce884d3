//! Failsafe state machine: arming, data-loss braking, landing, crash cut-off.
//!
//! ```text
//!              arm (checks pass)                   stale position / stale obstacles / NaN-Inf input
//!  Disarmed ───────────────────────▶ Armed ─────────────────────────────────────────────▶ Brake
//!     ▲  ▲                             │  land command                                     │
//!     │  │ landed                      ▼   ▲ data fresh again for resume_after (stale data only) │
//!     │  │                             │   └───────────────────────────────────────────────────┤
//!     │  │                             ▼                      brake timeout or land cmd    │
//!     │  └──────────────────────────  Land ◀───────────────────────────────────────────────┘
//!     │ disarm command (from any state)
//!     └─────────────────────────────  MotorsOff ◀── tilt > limit (from Armed, Brake or Land)
//! ```
//!
//! * **Armed** is nominal operation (on the ground, taking off, holding, flying the mission).
//! * **Brake**: hold position at the last good position with zero velocity
//!   (or, without a fresh position fix, level attitude at hover thrust). A Brake
//!   entered because the position fix or the obstacle data went **stale** returns to
//!   Armed (reason `data-recovered`) once every input has been fresh again for
//!   `resume_after_us` without a bad input, before the brake timeout: a short
//!   dropout (a position-fix burst just over the position timeout) is bridged by a
//!   brief hold instead of a landing. A Brake for a NaN/Inf or out-of-range input, a
//!   loss longer than the brake timeout, or `resume_after_us = 0` ends in a landing
//!   unless the operator lands/disarms first.
//! * **Land**: descend at a fixed rate; without a position fix, level attitude and
//!   thrust slightly below hover. Ends in Disarmed when landing is detected.
//! * **MotorsOff** (crash): motors stop and stay off until a disarm command.
//! * A disarm command is accepted in every state (operator kill switch).
//!
//! Every transition is returned as a [`Transition`] (from, to, reason, time) and
//! the last one is kept for telemetry. The machine itself only decides; the
//! [`crate::controller::FlightController`] measures ages, tilt and landing.

use crate::param_decl::{flag, Has, Param};

/// Failsafe state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FailsafeState {
    /// Motors off, commands other than arm ignored.
    #[default]
    Disarmed,
    /// Nominal operation.
    Armed,
    /// Data lost or corrupted: brake and hold.
    Brake,
    /// Descending to land.
    Land,
    /// Crash detected: motors off until disarmed.
    MotorsOff,
}

impl FailsafeState {
    /// `true` when the motors may spin (Armed, Brake, Land).
    pub fn motors_enabled(&self) -> bool {
        matches!(self, FailsafeState::Armed | FailsafeState::Brake | FailsafeState::Land)
    }
    /// Short name for logs.
    pub fn as_str(&self) -> &'static str {
        match self {
            FailsafeState::Disarmed => "disarmed",
            FailsafeState::Armed => "armed",
            FailsafeState::Brake => "brake",
            FailsafeState::Land => "land",
            FailsafeState::MotorsOff => "motors-off",
        }
    }
}

/// Why a transition happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TransitionReason {
    /// Operator arm command (pre-arm checks passed).
    ArmCommand,
    /// Operator disarm command.
    DisarmCommand,
    /// Operator land command.
    LandCommand,
    /// The position fix is older than the limit.
    PositionStale,
    /// The obstacle data is older than the limit.
    ObstacleStale,
    /// A NaN/Inf (or otherwise invalid) value arrived in an input.
    NonFiniteInput,
    /// Braked for longer than the brake timeout.
    BrakeTimeout,
    /// Landing detected.
    Landed,
    /// The stale data of a Brake has been fresh again for `resume_after_us`.
    DataRecovered,
    /// Tilt beyond the crash limit.
    TiltLimit,
    /// The RC kill switch (motors off at once, from any state).
    KillSwitch,
    /// The RC link was lost (timeout or receiver failsafe) — issue 21's per-mode failsafe.
    RcLoss,
    /// No offboard setpoint for the offboard timeout.
    OffboardLoss,
    /// Battery below the low threshold.
    BatteryLow,
    /// Battery below the critical threshold.
    BatteryCritical,
    /// The RC mode switch selected the mode.
    ModeSwitch,
    /// A mode command (MAVLink DO_SET_MODE, the host API).
    ModeCommand,
    /// Return reached the start.
    ReturnDone,
}

impl TransitionReason {
    /// Short name for logs.
    pub fn as_str(&self) -> &'static str {
        match self {
            TransitionReason::ArmCommand => "arm-command",
            TransitionReason::DisarmCommand => "disarm-command",
            TransitionReason::LandCommand => "land-command",
            TransitionReason::PositionStale => "position-stale",
            TransitionReason::ObstacleStale => "obstacle-stale",
            TransitionReason::NonFiniteInput => "non-finite-input",
            TransitionReason::BrakeTimeout => "brake-timeout",
            TransitionReason::Landed => "landed",
            TransitionReason::DataRecovered => "data-recovered",
            TransitionReason::TiltLimit => "tilt-limit",
            TransitionReason::KillSwitch => "kill-switch",
            TransitionReason::RcLoss => "rc-loss",
            TransitionReason::OffboardLoss => "offboard-loss",
            TransitionReason::BatteryLow => "battery-low",
            TransitionReason::BatteryCritical => "battery-critical",
            TransitionReason::ModeSwitch => "mode-switch",
            TransitionReason::ModeCommand => "mode-command",
            TransitionReason::ReturnDone => "return-done",
        }
    }
}

/// One state change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Transition {
    /// State before.
    pub from: FailsafeState,
    /// State after.
    pub to: FailsafeState,
    /// Cause.
    pub reason: TransitionReason,
    /// Time of the change, µs (controller clock).
    pub t_us: u64,
}

/// Limits of the failsafe machine.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FailsafeParams {
    /// A position fix older than this is stale, µs. Default 200 000 (0.2 s).
    pub position_timeout_us: u64,
    /// Obstacle data older than this is stale, µs. Default 500 000 (0.5 s).
    pub obstacle_timeout_us: u64,
    /// Time in Brake before landing, µs. Default 3 000 000 (3 s).
    pub brake_timeout_us: u64,
    /// A Brake entered for stale position or obstacle data returns to Armed once all
    /// data has been fresh (and no bad input seen) for this long, µs; 0 = never (every
    /// data loss ends in a landing). Default 200 000 (0.2 s).
    pub resume_after_us: u64,
    /// Tilt (angle between body z and world z) that means a crash, rad. Default 1.05 (60°).
    pub tilt_limit: f32,
    /// `true` (default): obstacle data must be fresh to arm and to stay Armed. `false`
    /// for flights without an obstacle source (bench tests, bring-up): obstacle ages
    /// are ignored and the filter only acts on the obstacles it is given.
    pub obstacles_required: bool,
}

impl Default for FailsafeParams {
    fn default() -> Self {
        FailsafeParams {
            position_timeout_us: 200_000,
            obstacle_timeout_us: 500_000,
            brake_timeout_us: 3_000_000,
            resume_after_us: 200_000,
            tilt_limit: 1.05,
            obstacles_required: true,
        }
    }
}

impl FailsafeParams {
    /// The obstacle-data failsafe's parameter (`crate::params`).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 1] {
        [
            Param::new("FS_OBST_REQ", "Failsafe", "", (0.0, 1.0), 0, flag!(obstacles_required),
                "Obstacle data must be fresh to arm and to stay armed (0 no, 1 yes)").code(|c| match c {
                    0 => Some("not required"),
                    1 => Some("required"),
                    _ => None,
                }),
        ]
    }
}

impl FailsafeParams {
    /// `true` when the timeouts are > 0 and the tilt limit is finite in (0, π].
    pub fn is_valid(&self) -> bool {
        self.position_timeout_us > 0
            && self.obstacle_timeout_us > 0
            && self.tilt_limit.is_finite()
            && self.tilt_limit > 0.0
            && self.tilt_limit <= core::f32::consts::PI
    }
}

/// Health of the inputs as measured by the controller for one check.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DataHealth {
    /// Age of the last valid position fix, µs (`None`: never received).
    pub position_age_us: Option<u64>,
    /// Age of the last valid obstacle update, µs (`None`: never received).
    pub obstacle_age_us: Option<u64>,
    /// A NaN/Inf input was seen since the last check.
    pub non_finite: bool,
    /// Id of a reported obstacle point inside the hull (distance from the
    /// position estimate below the hull radius √δ), computed when arming only
    /// (`None` otherwise): the vehicle is inside an obstacle or its data is wrong.
    pub obstacle_in_hull: Option<u16>,
}

/// The failsafe state machine (see the module documentation).
#[derive(Clone, Debug)]
pub struct Failsafe {
    params: FailsafeParams,
    state: FailsafeState,
    since_us: u64,
    last: Option<Transition>,
    count: u32,
    /// Since when all data has been fresh in a resumable Brake (`None`: not fresh).
    fresh_since_us: Option<u64>,
    /// The current Brake was entered for stale data and has seen no bad input.
    resumable: bool,
}

/// Why an arm command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ArmRefusal {
    /// Not in Disarmed (already armed, or MotorsOff awaiting a disarm).
    NotDisarmed,
    /// No position fix, or the last one is stale.
    NoFreshPosition,
    /// No obstacle update, or the last one is stale.
    NoFreshObstacles,
    /// A NaN/Inf input was seen.
    NonFiniteInput,
    /// The attitude estimate is not initialised or the tilt is beyond the limit.
    AttitudeNotReady,
    /// A reported obstacle point (this id) lies inside the hull: the vehicle
    /// would start in collision, or the position / obstacle data are wrong.
    ObstacleInsideHull {
        /// Id of the obstacle point (as reported).
        id: u16,
    },
}

impl core::fmt::Display for ArmRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ArmRefusal::NotDisarmed => {
                f.write_str("not disarmed (already armed, or motors off awaiting a disarm)")
            }
            ArmRefusal::NoFreshPosition => {
                f.write_str("no position fix, or the last one is older than the position timeout")
            }
            ArmRefusal::NoFreshObstacles => {
                f.write_str("no obstacle update, or the last one is older than the obstacle timeout")
            }
            ArmRefusal::NonFiniteInput => f.write_str("a NaN/Inf or out-of-range input was received"),
            ArmRefusal::AttitudeNotReady => {
                f.write_str("the attitude estimate is not initialised or the tilt is beyond the limit")
            }
            ArmRefusal::ObstacleInsideHull { id } => {
                write!(f, "obstacle {id} is reported inside the hull (the vehicle would start in collision)")
            }
        }
    }
}

impl Failsafe {
    /// New machine in Disarmed.
    pub fn new(params: FailsafeParams) -> Self {
        Failsafe {
            params,
            state: FailsafeState::Disarmed,
            since_us: 0,
            last: None,
            count: 0,
            fresh_since_us: None,
            resumable: false,
        }
    }

    /// Parameters in use.
    pub fn params(&self) -> &FailsafeParams {
        &self.params
    }

    /// Current state.
    pub fn state(&self) -> FailsafeState {
        self.state
    }

    /// Time of entry into the current state, µs.
    pub fn since_us(&self) -> u64 {
        self.since_us
    }

    /// Last transition, if any.
    pub fn last_transition(&self) -> Option<Transition> {
        self.last
    }

    /// Number of transitions so far (saturating).
    pub fn transition_count(&self) -> u32 {
        self.count
    }

    fn go(&mut self, to: FailsafeState, reason: TransitionReason, t_us: u64) -> Transition {
        let tr = Transition { from: self.state, to, reason, t_us };
        self.state = to;
        self.since_us = t_us;
        self.last = Some(tr);
        self.count = self.count.saturating_add(1);
        self.fresh_since_us = None;
        self.resumable = to == FailsafeState::Brake
            && matches!(reason, TransitionReason::PositionStale | TransitionReason::ObstacleStale);
        tr
    }

    fn fresh(age: Option<u64>, limit: u64) -> bool {
        age.is_some_and(|a| a <= limit)
    }

    fn obstacles_ok(&self, health: &DataHealth) -> bool {
        !self.params.obstacles_required
            || Self::fresh(health.obstacle_age_us, self.params.obstacle_timeout_us)
    }

    /// Arm command: accepted only in Disarmed with fresh position and obstacle data,
    /// no NaN/Inf input, no reported obstacle point inside the hull and an
    /// initialised attitude within the tilt limit.
    pub fn arm(
        &mut self,
        t_us: u64,
        health: &DataHealth,
        attitude_ok: bool,
        tilt: f32,
    ) -> Result<Transition, ArmRefusal> {
        self.arm_check(health, attitude_ok, tilt)?;
        Ok(self.go(FailsafeState::Armed, TransitionReason::ArmCommand, t_us))
    }

    /// The arm command's checks without arming (the pre-arm check a ground station shows:
    /// MAVLink `MAV_SYS_STATUS_PREARM_CHECK`): `Ok` when [`Failsafe::arm`] would arm.
    pub fn arm_check(&self, health: &DataHealth, attitude_ok: bool, tilt: f32) -> Result<(), ArmRefusal> {
        if self.state != FailsafeState::Disarmed {
            return Err(ArmRefusal::NotDisarmed);
        }
        if health.non_finite {
            return Err(ArmRefusal::NonFiniteInput);
        }
        if !Self::fresh(health.position_age_us, self.params.position_timeout_us) {
            return Err(ArmRefusal::NoFreshPosition);
        }
        if !self.obstacles_ok(health) {
            return Err(ArmRefusal::NoFreshObstacles);
        }
        if let Some(id) = health.obstacle_in_hull {
            return Err(ArmRefusal::ObstacleInsideHull { id });
        }
        if !attitude_ok || !tilt.is_finite() || tilt > self.params.tilt_limit {
            return Err(ArmRefusal::AttitudeNotReady);
        }
        Ok(())
    }

    /// `true` when a position fix of age `age_us` is fresh (within `position_timeout_us`).
    pub fn position_fresh(&self, age_us: Option<u64>) -> bool {
        Self::fresh(age_us, self.params.position_timeout_us)
    }

    /// Disarm command: accepted in every state except Disarmed.
    pub fn disarm(&mut self, t_us: u64) -> Option<Transition> {
        self.disarm_for(t_us, TransitionReason::DisarmCommand)
    }

    /// Disarm for `reason` (the disarm command, the kill switch): in every state but Disarmed.
    pub fn disarm_for(&mut self, t_us: u64, reason: TransitionReason) -> Option<Transition> {
        if self.state == FailsafeState::Disarmed {
            return None;
        }
        Some(self.go(FailsafeState::Disarmed, reason, t_us))
    }

    /// Land command: from Armed or Brake.
    pub fn land(&mut self, t_us: u64) -> Option<Transition> {
        self.land_for(t_us, TransitionReason::LandCommand)
    }

    /// Land for `reason` (the land command, a mode change, a per-mode failsafe): from Armed
    /// or Brake.
    pub fn land_for(&mut self, t_us: u64, reason: TransitionReason) -> Option<Transition> {
        match self.state {
            FailsafeState::Armed | FailsafeState::Brake => Some(self.go(FailsafeState::Land, reason, t_us)),
            _ => None,
        }
    }

    /// Crash check (call at the inner-loop rate): tilt above the limit (or not
    /// finite) while the motors are enabled → MotorsOff.
    pub fn check_tilt(&mut self, t_us: u64, tilt: f32) -> Option<Transition> {
        let crashed = !tilt.is_finite() || tilt > self.params.tilt_limit;
        if self.state.motors_enabled() && crashed {
            return Some(self.go(FailsafeState::MotorsOff, TransitionReason::TiltLimit, t_us));
        }
        None
    }

    /// Data check (call at the outer-loop rate): stale/invalid data in Armed →
    /// Brake; a Brake for stale data with the data fresh again for `resume_after_us`
    /// → Armed; Brake longer than the timeout → Land; Land with `landed` → Disarmed.
    /// At most one transition per call.
    pub fn check_data(&mut self, t_us: u64, health: &DataHealth, landed: bool) -> Option<Transition> {
        match self.state {
            FailsafeState::Armed => {
                let reason = if health.non_finite {
                    Some(TransitionReason::NonFiniteInput)
                } else if !Self::fresh(health.position_age_us, self.params.position_timeout_us) {
                    Some(TransitionReason::PositionStale)
                } else if !self.obstacles_ok(health) {
                    Some(TransitionReason::ObstacleStale)
                } else {
                    None
                };
                reason.map(|r| self.go(FailsafeState::Brake, r, t_us))
            }
            FailsafeState::Brake => {
                if t_us.saturating_sub(self.since_us) >= self.params.brake_timeout_us {
                    return Some(self.go(FailsafeState::Land, TransitionReason::BrakeTimeout, t_us));
                }
                if health.non_finite {
                    self.resumable = false;
                }
                let fresh = Self::fresh(health.position_age_us, self.params.position_timeout_us)
                    && self.obstacles_ok(health);
                if !(self.resumable && self.params.resume_after_us > 0 && fresh) {
                    self.fresh_since_us = None;
                    return None;
                }
                let since = *self.fresh_since_us.get_or_insert(t_us);
                if t_us.saturating_sub(since) >= self.params.resume_after_us {
                    Some(self.go(FailsafeState::Armed, TransitionReason::DataRecovered, t_us))
                } else {
                    None
                }
            }
            FailsafeState::Land if landed => {
                Some(self.go(FailsafeState::Disarmed, TransitionReason::Landed, t_us))
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use FailsafeState as S;
    use TransitionReason as R;

    fn good() -> DataHealth {
        DataHealth {
            position_age_us: Some(1_000),
            obstacle_age_us: Some(1_000),
            non_finite: false,
            obstacle_in_hull: None,
        }
    }

    fn armed() -> Failsafe {
        let mut f = Failsafe::new(FailsafeParams::default());
        f.arm(10, &good(), true, 0.0).unwrap();
        f
    }

    fn check(tr: Option<Transition>, from: S, to: S, reason: R) {
        let tr = tr.expect("a transition");
        assert_eq!((tr.from, tr.to, tr.reason), (from, to, reason));
    }

    #[test]
    fn arm_checks_and_refusals() {
        let mut f = Failsafe::new(FailsafeParams::default());
        let stale = FailsafeParams::default().position_timeout_us + 1;
        assert_eq!(
            f.arm(0, &DataHealth { position_age_us: None, ..good() }, true, 0.0),
            Err(ArmRefusal::NoFreshPosition)
        );
        assert_eq!(
            f.arm(0, &DataHealth { position_age_us: Some(stale), ..good() }, true, 0.0),
            Err(ArmRefusal::NoFreshPosition)
        );
        assert_eq!(
            f.arm(0, &DataHealth { obstacle_age_us: None, ..good() }, true, 0.0),
            Err(ArmRefusal::NoFreshObstacles)
        );
        assert_eq!(
            f.arm(0, &DataHealth { non_finite: true, ..good() }, true, 0.0),
            Err(ArmRefusal::NonFiniteInput)
        );
        assert_eq!(
            f.arm(0, &DataHealth { obstacle_in_hull: Some(7), ..good() }, true, 0.0),
            Err(ArmRefusal::ObstacleInsideHull { id: 7 })
        );
        assert_eq!(f.arm(0, &good(), false, 0.0), Err(ArmRefusal::AttitudeNotReady));
        assert_eq!(f.arm(0, &good(), true, f32::NAN), Err(ArmRefusal::AttitudeNotReady));
        assert_eq!(f.arm(0, &good(), true, 1.2), Err(ArmRefusal::AttitudeNotReady));
        assert_eq!(f.state(), S::Disarmed);
        assert_eq!(f.transition_count(), 0);
        let tr = f.arm(5, &good(), true, 0.0).unwrap();
        assert_eq!((tr.from, tr.to, tr.reason, tr.t_us), (S::Disarmed, S::Armed, R::ArmCommand, 5));
        assert_eq!(f.arm(6, &good(), true, 0.0), Err(ArmRefusal::NotDisarmed));
        assert_eq!(f.last_transition(), Some(tr));
    }

    #[test]
    fn armed_stays_armed_with_good_data() {
        let mut f = armed();
        assert!(f.check_data(100, &good(), false).is_none());
        assert!(f.check_tilt(100, 0.5).is_none());
        assert_eq!(f.state(), S::Armed);
    }

    #[test]
    fn stale_position_brakes_then_lands_then_disarms() {
        let mut f = armed();
        let h = DataHealth { position_age_us: Some(300_000), ..good() };
        check(f.check_data(1_000, &h, false), S::Armed, S::Brake, R::PositionStale);
        // Still braking before the timeout while the data stays stale.
        assert!(f.check_data(1_000 + 2_999_999, &h, false).is_none());
        check(f.check_data(1_000 + 3_000_000, &good(), false), S::Brake, S::Land, R::BrakeTimeout);
        assert!(f.check_data(5_000_000, &good(), false).is_none(), "not landed yet");
        check(f.check_data(6_000_000, &good(), true), S::Land, S::Disarmed, R::Landed);
        assert_eq!(f.transition_count(), 4);
    }

    #[test]
    fn short_dropout_resumes_after_the_data_is_fresh_again() {
        let resume = FailsafeParams::default().resume_after_us;
        for reason in [R::PositionStale, R::ObstacleStale] {
            let mut f = armed();
            let stale = match reason {
                R::PositionStale => DataHealth { position_age_us: Some(250_000), ..good() },
                _ => DataHealth { obstacle_age_us: None, ..good() },
            };
            check(f.check_data(1_000, &stale, false), S::Armed, S::Brake, reason);
            // Fresh, then stale again: the fresh time restarts.
            assert!(f.check_data(2_000, &good(), false).is_none());
            assert!(f.check_data(2_000 + resume - 1, &stale, false).is_none());
            assert!(f.check_data(3_000, &good(), false).is_none());
            assert!(f.check_data(3_000 + resume - 1, &good(), false).is_none(), "not yet");
            check(f.check_data(3_000 + resume, &good(), false), S::Brake, S::Armed, R::DataRecovered);
            assert_eq!(R::DataRecovered.as_str(), "data-recovered");
            // A bad input during such a brake: no resume, it lands at the timeout.
            let t0 = 10_000_000;
            check(f.check_data(t0, &stale, false), S::Armed, S::Brake, reason);
            let bad = DataHealth { non_finite: true, ..good() };
            assert!(f.check_data(t0 + 1_000, &bad, false).is_none());
            for t in (t0 + 2_000..t0 + 3_000_000).step_by(4_000) {
                assert!(f.check_data(t, &good(), false).is_none(), "no resume after a bad input");
            }
            check(f.check_data(t0 + 3_000_000, &good(), false), S::Brake, S::Land, R::BrakeTimeout);
        }
    }

    #[test]
    fn no_resume_after_a_bad_input_or_when_disabled() {
        let mut f = armed();
        check(
            f.check_data(1, &DataHealth { non_finite: true, ..good() }, false),
            S::Armed,
            S::Brake,
            R::NonFiniteInput,
        );
        for t in (2..3_000_000).step_by(4_000) {
            assert!(f.check_data(t, &good(), false).is_none(), "a bad input never resumes");
        }
        check(f.check_data(3_000_001, &good(), false), S::Brake, S::Land, R::BrakeTimeout);
        let mut f = Failsafe::new(FailsafeParams { resume_after_us: 0, ..FailsafeParams::default() });
        f.arm(10, &good(), true, 0.0).unwrap();
        let h = DataHealth { position_age_us: None, ..good() };
        check(f.check_data(1_000, &h, false), S::Armed, S::Brake, R::PositionStale);
        for t in (2_000..3_001_000).step_by(4_000) {
            assert!(f.check_data(t, &good(), false).is_none(), "resume off: brake until the timeout");
        }
        check(f.check_data(3_001_000, &good(), false), S::Brake, S::Land, R::BrakeTimeout);
    }

    #[test]
    fn stale_or_missing_obstacles_brake() {
        let mut f = armed();
        let h = DataHealth { obstacle_age_us: Some(600_000), ..good() };
        check(f.check_data(1, &h, false), S::Armed, S::Brake, R::ObstacleStale);
        let mut f = armed();
        let h = DataHealth { obstacle_age_us: None, ..good() };
        check(f.check_data(1, &h, false), S::Armed, S::Brake, R::ObstacleStale);
    }

    #[test]
    fn obstacles_not_required_ignores_their_age() {
        let mut f = Failsafe::new(FailsafeParams { obstacles_required: false, ..FailsafeParams::default() });
        let h = DataHealth { obstacle_age_us: None, ..good() };
        assert!(f.arm(1, &h, true, 0.0).is_ok());
        assert!(f.check_data(2, &h, false).is_none());
        assert!(f.check_data(3, &DataHealth { obstacle_age_us: Some(u64::MAX), ..good() }, false).is_none());
        // Position and bad inputs still count.
        let h = DataHealth { position_age_us: None, ..h };
        check(f.check_data(4, &h, false), S::Armed, S::Brake, R::PositionStale);
    }

    #[test]
    fn non_finite_input_brakes() {
        let mut f = armed();
        let h = DataHealth { non_finite: true, ..good() };
        check(f.check_data(1, &h, false), S::Armed, S::Brake, R::NonFiniteInput);
    }

    #[test]
    fn land_command_from_armed_and_brake() {
        let mut f = armed();
        check(f.land(20), S::Armed, S::Land, R::LandCommand);
        assert!(f.land(21).is_none(), "already landing");
        let mut f = armed();
        f.check_data(1, &DataHealth { non_finite: true, ..good() }, false);
        check(f.land(30), S::Brake, S::Land, R::LandCommand);
        let mut f = Failsafe::new(FailsafeParams::default());
        assert!(f.land(0).is_none(), "no landing while disarmed");
    }

    #[test]
    fn tilt_cuts_motors_in_every_flying_state_until_disarm() {
        for setup in 0..3 {
            let mut f = armed();
            if setup >= 1 {
                f.check_data(1, &DataHealth { non_finite: true, ..good() }, false);
            }
            if setup == 2 {
                f.land(2);
            }
            let from = f.state();
            assert!(f.check_tilt(3, 1.0).is_none());
            check(f.check_tilt(4, 1.1), from, S::MotorsOff, R::TiltLimit);
            assert!(!f.state().motors_enabled());
            // MotorsOff is latched: no data, land or arm command leaves it.
            assert!(f.check_data(5, &good(), true).is_none());
            assert!(f.land(6).is_none());
            assert_eq!(f.arm(7, &good(), true, 0.0), Err(ArmRefusal::NotDisarmed));
            check(f.disarm(8), S::MotorsOff, S::Disarmed, R::DisarmCommand);
        }
        let mut f = armed();
        check(f.check_tilt(1, f32::NAN), S::Armed, S::MotorsOff, R::TiltLimit);
        let mut f = Failsafe::new(FailsafeParams::default());
        assert!(f.check_tilt(1, 3.0).is_none(), "no crash detection while disarmed");
    }

    #[test]
    fn disarm_from_any_armed_state() {
        let mut f = armed();
        check(f.disarm(1), S::Armed, S::Disarmed, R::DisarmCommand);
        assert!(f.disarm(2).is_none());
        let mut f = armed();
        f.land(1);
        check(f.disarm(2), S::Land, S::Disarmed, R::DisarmCommand);
        let mut f = armed();
        f.check_data(1, &DataHealth { non_finite: true, ..good() }, false);
        check(f.disarm(2), S::Brake, S::Disarmed, R::DisarmCommand);
    }
}
