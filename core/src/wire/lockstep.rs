//! The lockstep rule of the processor-in-the-loop link and the motor command it answers with.
//!
//! For each HIL_SENSOR with simulated time `t` (µs) the firmware closes the open obstacle batch
//! at `t`, runs the inner step at `t`, then the outer step at `t` when [`LockstepClock::tick`]
//! says it is due, and answers HIL_ACTUATOR_CONTROLS with `time_usec = t`,
//! `controls[0..4]` = the [`MotorCommand::sanitized`] throttles (rotor order of
//! [`crate::airframe`]), `controls[4..16] = 0`, `mode` = HIL_ENABLED (+ SAFETY_ARMED when armed),
//! `flags` = LOCKSTEP. The host's firmware twin replays exactly this.

/// Motor command for the four rotors (order and spin directions: [`crate::airframe`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorCommand {
    /// Normalised throttle per rotor, 0..1 (rotor speed ω = throttle · ω_max).
    pub throttle: [f32; 4],
    /// `false`: motors must be stopped (disarmed or motors-off failsafe).
    pub armed: bool,
}

impl MotorCommand {
    /// Motors stopped.
    pub const OFF: Self = Self { throttle: [0.0; 4], armed: false };

    /// The command a motor output may apply: disarmed → all zero; each throttle clamped to
    /// 0..1; a non-finite throttle stops every motor (disarmed) because the mixer is broken.
    pub fn sanitized(self) -> Self {
        if !self.armed || self.throttle.iter().any(|t| !t.is_finite()) {
            return Self::OFF;
        }
        Self { throttle: self.throttle.map(|t| t.clamp(0.0, 1.0)), armed: true }
    }

    /// HIL_ACTUATOR_CONTROLS `controls` of this command (sanitised first).
    pub fn to_actuator_controls(self) -> [f32; ACTUATOR_CHANNELS] {
        let m = self.sanitized();
        let mut c = [0.0; ACTUATOR_CHANNELS];
        for (d, s) in c.iter_mut().zip(m.throttle) {
            *d = s;
        }
        c
    }

    /// The command a receiver of HIL_ACTUATOR_CONTROLS applies: `controls[0..4]`, zero unless
    /// `armed` (the SAFETY_ARMED bit of `mode`), sanitised.
    pub fn from_actuator_controls(controls: &[f32; ACTUATOR_CHANNELS], armed: bool) -> Self {
        let [a, b, c, d, ..] = *controls;
        Self { throttle: [a, b, c, d], armed }.sanitized()
    }
}

/// Channels of HIL_ACTUATOR_CONTROLS `controls`.
pub const ACTUATOR_CHANNELS: usize = 16;

/// What [`LockstepClock::tick`] decided for one sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LockstepTick {
    /// The outer step runs after the inner step of this sample.
    pub run_outer: bool,
    /// The sample's time did not increase (it is answered anyway; the outer phase restarts).
    pub non_monotonic: bool,
}

/// Which HIL_SENSOR samples run the outer step, by simulated time: the first sample, then
/// whenever `t ≥ next`, with `next += period` (or `t + period` when more than one period was
/// skipped, so a time jump restarts the phase instead of running a burst). Time going backwards
/// also restarts it. Saturating: `t` is the host's (any `u64`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LockstepClock {
    period_us: u64,
    next_outer_us: Option<u64>,
    last_t_us: Option<u64>,
}

impl LockstepClock {
    /// Outer step every `period_us` of simulated time (≥ 1).
    pub const fn new(period_us: u64) -> Self {
        Self { period_us: if period_us == 0 { 1 } else { period_us }, next_outer_us: None, last_t_us: None }
    }

    /// Outer period, µs.
    pub const fn period_us(&self) -> u64 {
        self.period_us
    }

    /// The time from which the next outer step is due (`None`: the next sample runs it).
    pub const fn next_outer_us(&self) -> Option<u64> {
        self.next_outer_us
    }

    /// A clock whose next outer step is due at `next_outer_us` (a replay that starts mid-way).
    pub const fn with_next_outer(mut self, next_outer_us: u64) -> Self {
        self.next_outer_us = Some(next_outer_us);
        self
    }

    /// Advances to the sample at `t_us` and says whether its outer step runs.
    pub fn tick(&mut self, t_us: u64) -> LockstepTick {
        let non_monotonic = self.last_t_us.is_some_and(|last| t_us <= last);
        if non_monotonic {
            self.next_outer_us = None;
        }
        self.last_t_us = Some(t_us);
        let run_outer = self.next_outer_us.is_none_or(|n| t_us >= n);
        if run_outer {
            self.next_outer_us = Some(match self.next_outer_us {
                Some(n) if t_us - n < self.period_us => n.saturating_add(self.period_us),
                _ => t_us.saturating_add(self.period_us),
            });
        }
        LockstepTick { run_outer, non_monotonic }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sanitised_motor_command() {
        let c = MotorCommand { throttle: [0.5, 1.5, -0.2, 0.0], armed: true }.sanitized();
        assert_eq!(c.throttle, [0.5, 1.0, 0.0, 0.0]);
        assert!(c.armed);
        let c = MotorCommand { throttle: [0.5, f32::NAN, 0.1, 0.0], armed: true }.sanitized();
        assert_eq!(c, MotorCommand::OFF);
        assert_eq!(MotorCommand { throttle: [0.5; 4], armed: false }.sanitized(), MotorCommand::OFF);
    }

    #[test]
    fn actuator_controls_round_trip() {
        let m = MotorCommand { throttle: [0.1, 0.2, 1.3, 0.4], armed: true };
        let c = m.to_actuator_controls();
        assert_eq!(&c[..5], &[0.1, 0.2, 1.0, 0.4, 0.0]);
        assert_eq!(MotorCommand::from_actuator_controls(&c, true), m.sanitized());
        assert_eq!(MotorCommand::from_actuator_controls(&c, false), MotorCommand::OFF);
        assert_eq!(MotorCommand::OFF.to_actuator_controls(), [0.0; 16]);
    }

    #[test]
    fn outer_every_fourth_millisecond_phase_restarts_on_jumps_and_backwards_time() {
        let mut c = LockstepClock::new(4000);
        for k in 0..20u64 {
            let t = c.tick(1_000_000 + k * 1000);
            assert_eq!(t.run_outer, k % 4 == 0, "step {k}");
            assert!(!t.non_monotonic);
        }
        assert!(c.tick(1_030_000).run_outer);
        assert!(!c.tick(1_031_000).run_outer);
        assert!(c.tick(1_034_000).run_outer);
        let back = c.tick(10);
        assert!(back.run_outer && back.non_monotonic);
        let mut c = LockstepClock::new(4000).with_next_outer(8000);
        assert!(!c.tick(5000).run_outer);
        assert!(c.tick(8000).run_outer);
        assert_eq!(c.next_outer_us(), Some(12_000));
    }

    #[test]
    fn times_near_u64_max_do_not_overflow() {
        let mut c = LockstepClock::new(4000);
        assert!(c.tick(u64::MAX - 1000).run_outer);
        assert!(!c.tick(u64::MAX - 10).run_outer);
        assert!(c.tick(u64::MAX).run_outer);
        assert_eq!(LockstepClock::new(0).period_us(), 1);
    }
}
