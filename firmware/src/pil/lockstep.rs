//! Lockstep processor-in-the-loop step: one HIL_SENSOR in → one HIL_ACTUATOR_CONTROLS out.
//!
//! For each HIL_SENSOR with simulated time `t` (µs), the firmware
//! 1. closes the open obstacle batch (`update_obstacles(t, …)`, see [`crate::link::obstacles`]),
//! 2. runs the inner loop `step_inner(t, imu)` (estimator, attitude, rate control, mixer),
//! 3. runs the outer loop `step_outer(t)` when it is due by simulated time (the wire contract's
//!    rule, `parapet_core::wire::lockstep::LockstepClock`, with the period of
//!    `parapet_core::schedule::OuterSchedule`),
//! 4. answers HIL_ACTUATOR_CONTROLS with `time_usec = t`, `controls` = the sanitised motor
//!    command (`parapet_core::wire::lockstep::MotorCommand::to_actuator_controls`),
//!    `mode` = HIL_ENABLED (+ SAFETY_ARMED when armed), `flags` = LOCKSTEP.
//!
//! Simulated time only advances when the host got the answer, so results do not depend on how
//! fast QEMU runs. The instruction count of steps 1-3 is measured with SysTick under
//! `qemu -icount shift=0` and calibrated with [`InstructionCalibration`].

use crate::link::outbound::HilControls;

use parapet_core::schedule::OuterSchedule;
use parapet_core::wire::lockstep::LockstepClock;

use crate::app::autopilot::{ControlSteps, MotorCommand};
use crate::link::{HilSample, Link};
use crate::pil::TickCounter;

/// A clock that never advances (untimed steps).
struct NoTicks;

impl TickCounter for NoTicks {
    fn now(&self) -> u32 {
        0
    }
    fn since(&self, _start: u32) -> u32 {
        0
    }
}

/// Counters of the lockstep scheduler (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LockstepStats {
    /// Control steps run.
    pub steps: u32,
    /// Outer steps run.
    pub outer_steps: u32,
    /// Samples whose time did not increase (answered anyway; the outer schedule restarts).
    pub non_monotonic: u32,
}

/// Outer-loop scheduling by simulated time.
#[derive(Clone, Debug)]
pub struct LockstepScheduler {
    clock: LockstepClock,
    stats: LockstepStats,
}

impl Default for LockstepScheduler {
    /// The default parameters' schedule (250 Hz).
    fn default() -> Self {
        Self::new(OuterSchedule::DEFAULT)
    }
}

/// The answer of one step.
#[derive(Clone, Debug, PartialEq)]
pub struct StepOutcome {
    /// The HIL_ACTUATOR_CONTROLS to send.
    pub controls: HilControls,
    /// The sanitised motor command behind it.
    pub motors: MotorCommand,
    /// The outer loop ran in this step.
    pub ran_outer: bool,
    /// Ticks of the outer step alone (`step_outer`), when it ran and the step was timed
    /// ([`LockstepScheduler::step_timed`]); `None` otherwise.
    pub outer_ticks: Option<u32>,
}

/// HIL_ACTUATOR_CONTROLS for `motors` at simulated time `t_us` (the first four of
/// `MotorCommand::to_actuator_controls`, the rest are 0).
pub fn actuator_controls(t_us: u64, motors: &MotorCommand) -> HilControls {
    let [a, b, c, d, ..] = motors.to_actuator_controls();
    HilControls { time_usec: t_us, throttle: [a, b, c, d], armed: motors.armed }
}

impl LockstepScheduler {
    /// Outer loop every `schedule.period_us()` of simulated time.
    pub const fn new(schedule: OuterSchedule) -> Self {
        Self { clock: schedule.clock(), stats: LockstepStats { steps: 0, outer_steps: 0, non_monotonic: 0 } }
    }

    /// Counters so far.
    pub fn stats(&self) -> LockstepStats {
        self.stats
    }

    /// Runs one control step for `sample` (see the module docs).
    pub fn step<A: ControlSteps>(&mut self, sample: &HilSample, link: &mut Link, ap: &mut A) -> StepOutcome {
        let mut o = self.step_timed(sample, link, ap, &NoTicks);
        o.outer_ticks = None;
        o
    }

    /// [`Self::step`], with the outer step timed on `ticks` ([`StepOutcome::outer_ticks`]).
    pub fn step_timed<A: ControlSteps>(
        &mut self,
        sample: &HilSample,
        link: &mut Link,
        ap: &mut A,
        ticks: &impl TickCounter,
    ) -> StepOutcome {
        let t = sample.time_usec;
        let tick = self.clock.tick(t);
        if tick.non_monotonic {
            self.stats.non_monotonic = self.stats.non_monotonic.saturating_add(1);
        }
        link.flush_obstacles(t, ap);
        let motors = ap.step_inner(t, &sample.imu).sanitized();
        let ran_outer = tick.run_outer;
        let mut outer_ticks = None;
        if ran_outer {
            let t0 = ticks.now();
            ap.step_outer(t);
            outer_ticks = Some(ticks.since(t0));
            self.stats.outer_steps = self.stats.outer_steps.saturating_add(1);
        }
        self.stats.steps = self.stats.steps.saturating_add(1);
        StepOutcome { controls: actuator_controls(t, &motors), motors, ran_outer, outer_ticks }
    }
}

/// Ticks elapsed on SysTick (a 24-bit *down*-counter reloading to `reload`) from `start` to `end`,
/// assuming less than one wrap in between.
pub fn systick_elapsed(start: u32, end: u32, reload: u32) -> u32 {
    let (start, end) = (start & 0x00FF_FFFF, end & 0x00FF_FFFF);
    if start >= end {
        start - end
    } else {
        start + (reload & 0x00FF_FFFF) + 1 - end
    }
}

/// SysTick ticks measured for a loop of a known instruction count (`qemu -icount shift=0`:
/// one instruction = 1 ns of virtual time; SysTick counts virtual time).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InstructionCalibration {
    /// Instructions executed by the calibration loop.
    pub instructions: u32,
    /// SysTick ticks it took.
    pub ticks: u32,
}

impl InstructionCalibration {
    /// Instructions corresponding to `ticks` (rounded); 0 when the calibration is degenerate.
    pub fn instructions_for(&self, ticks: u32) -> u32 {
        if self.ticks == 0 {
            return 0;
        }
        let v = (u64::from(ticks) * u64::from(self.instructions) + u64::from(self.ticks) / 2)
            / u64::from(self.ticks);
        v.min(u64::from(u32::MAX)) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;
    use crate::link::dialect::{HilActuatorControlsFlags, MavModeFlag};
    use crate::link::FixClock;
    use parapet_core::Vec3;

    fn sample(t: u64) -> HilSample {
        HilSample {
            time_usec: t,
            imu: crate::app::autopilot::ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -9.81) },
        }
    }

    #[test]
    fn outer_loop_runs_every_fourth_millisecond_by_simulated_time() {
        let mut ap = RecordingAutopilot::new();
        let mut link = Link::new(1, FixClock::Message);
        let mut s = LockstepScheduler::new(OuterSchedule::from_rates(250.0, 1000.0));
        for k in 0..20u64 {
            let o = s.step(&sample(1_000_000 + k * 1000), &mut link, &mut ap);
            assert_eq!(o.controls.time_usec, 1_000_000 + k * 1000);
            assert_eq!(o.ran_outer, k % 4 == 0, "step {k}");
        }
        assert_eq!(ap.inner_steps.len(), 20);
        assert_eq!(ap.outer_steps.len(), 5);
        // A jump of 10 ms restarts the phase instead of running a burst of outer steps.
        let o = s.step(&sample(1_030_000), &mut link, &mut ap);
        assert!(o.ran_outer);
        assert!(!s.step(&sample(1_031_000), &mut link, &mut ap).ran_outer);
        assert!(s.step(&sample(1_034_000), &mut link, &mut ap).ran_outer);
        // Time going backwards is answered and counted.
        assert!(s.step(&sample(10), &mut link, &mut ap).ran_outer);
        assert_eq!(s.stats().non_monotonic, 1);
    }

    #[test]
    fn times_near_u64_max_do_not_overflow() {
        // Found by the `link` fuzz target (HIL_SENSOR time_usec is the host's, any u64).
        let mut ap = RecordingAutopilot::new();
        let mut link = Link::new(1, FixClock::Message);
        let mut s = LockstepScheduler::new(OuterSchedule::from_rates(250.0, 1000.0));
        assert!(s.step(&sample(u64::MAX - 1000), &mut link, &mut ap).ran_outer);
        assert!(!s.step(&sample(u64::MAX - 10), &mut link, &mut ap).ran_outer);
        let o = s.step(&sample(u64::MAX), &mut link, &mut ap);
        assert_eq!(o.controls.time_usec, u64::MAX);
        assert_eq!(ap.inner_steps.len(), 3);
    }

    #[test]
    fn controls_carry_throttles_and_arming() {
        let mut ap = RecordingAutopilot::new();
        let mut link = Link::new(1, FixClock::Message);
        let mut s = LockstepScheduler::default();
        let o = s.step(&sample(5), &mut link, &mut ap).controls.data();
        assert_eq!(o.controls, [0.0; 16]);
        assert!(!o.mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
        ap.armed = true;
        let o = s.step(&sample(6), &mut link, &mut ap).controls.data();
        assert_eq!(&o.controls[..5], &[0.5, 0.5, 0.5, 0.5, 0.0]);
        assert!(o
            .mode
            .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED | MavModeFlag::MAV_MODE_FLAG_HIL_ENABLED));
        assert!(o.flags.contains(HilActuatorControlsFlags::HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP));
    }

    #[test]
    fn systick_arithmetic() {
        assert_eq!(systick_elapsed(1000, 400, 0xFF_FFFF), 600);
        assert_eq!(systick_elapsed(100, 0xFF_FF00, 0xFF_FFFF), 100 + 0x100);
        let cal = InstructionCalibration { instructions: 200_000, ticks: 33_600 };
        assert_eq!(cal.instructions_for(168), 1000);
        assert_eq!(InstructionCalibration { instructions: 1, ticks: 0 }.instructions_for(5), 0);
    }
}
