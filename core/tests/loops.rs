//! The two loops taken apart ([`FlightController::into_loops`]) and driven through their
//! messages, as a firmware with one task per loop does: they fly exactly like the facade,
//! and the inner loop's crash cut-off acts without the outer loop.

#[allow(dead_code)] // the closed-loop `Sim` of the plant module is not used here
mod plant;

use parapet_core::controller::{ControllerParams, FlightController, MotorOutput};
use parapet_core::estimator::ImuSample;
use parapet_core::failsafe::{FailsafeState, TransitionReason};
use parapet_core::frame::GRAVITY;
use parapet_core::inner::InnerLoop;
use parapet_core::msg::{AttitudeCommand, MotorStage};
use parapet_core::outer::OuterLoop;
use parapet_core::schedule::OuterSchedule;
use parapet_core::Vec3;
use plant::{Quad, INNER_PERIOD_US};

/// The outer and inner loop with the facade's hand-overs written out.
struct Split {
    outer: OuterLoop,
    inner: InnerLoop,
}

impl Split {
    fn fix(&mut self, q: &Quad, t: u64) {
        self.outer.update_position(q.fix(t));
        self.inner.set_aid(self.outer.aid());
    }
    fn inner_step(&mut self, t: u64, imu: &ImuSample) -> MotorOutput {
        let out = self.inner.step(t, imu);
        if self.outer.on_estimate(&self.inner.estimate()) {
            self.inner.set_command(self.outer.command());
        }
        out
    }
    fn outer_step(&mut self, t: u64) {
        let c = self.outer.step(t);
        self.inner.set_command(c);
    }
}

#[test]
fn loops_driven_through_their_messages_fly_bit_for_bit_like_the_facade() {
    let params = ControllerParams::default();
    let schedule = OuterSchedule::new(&params);
    let mut fc = FlightController::new(params).unwrap();
    let (outer, inner) = FlightController::new(params).unwrap().into_loops();
    let mut split = Split { outer, inner };
    let (mut qa, mut qb) = (Quad::new(Vec3::zeros()), Quad::new(Vec3::zeros()));
    let path = [Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.5, -1.2)];
    fc.set_path(&path).unwrap();
    split.outer.set_path(&path).unwrap();
    let mut t = 1_000_000u64;
    let mut flew = false;
    for k in 0..20_000u64 {
        t += INNER_PERIOD_US;
        if k % 10 == 0 {
            fc.update_position(qa.fix(t));
            split.fix(&qb, t);
            fc.update_obstacles(t, &[]);
            split.outer.update_obstacles(t, &[]);
        }
        match k {
            100 => {
                fc.arm(t).unwrap();
                split.outer.arm(t).unwrap();
                split.inner.set_command(split.outer.command());
            }
            200 => {
                fc.takeoff(t, 1.0).unwrap();
                split.outer.takeoff(t, 1.0).unwrap();
            }
            5_000 => {
                fc.start_mission(t).unwrap();
                split.outer.start_mission(t).unwrap();
            }
            15_000 => {
                fc.land(t).unwrap();
                split.outer.land(t).unwrap();
                split.inner.set_command(split.outer.command());
            }
            _ => {}
        }
        if schedule.is_outer_step(k) {
            fc.step_outer(t);
            split.outer_step(t);
        }
        let a = fc.step_inner(t, &qa.imu());
        let b = split.inner_step(t, &qb.imu());
        assert_eq!(a, b, "motor output at step {k}");
        flew |= a.throttle[0] > 0.3;
        qa.step(&a.throttle, 1e-3);
        qb.step(&b.throttle, 1e-3);
    }
    assert!(flew, "the comparison covers flight, not only the ground");
    assert_eq!(qa.p, qb.p);
    let tel = fc.telemetry();
    assert_eq!(tel.state, split.outer.state());
    assert_eq!(tel.filter, split.outer.telemetry().filter);
    assert_eq!(tel.attitude, split.inner.telemetry().attitude);
}

#[test]
fn the_inner_loop_cuts_the_motors_on_a_tilt_trip_until_told_they_are_off() {
    let params = ControllerParams::default();
    let (_, mut inner) = FlightController::new(params).unwrap().into_loops();
    let level = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -GRAVITY) };
    // Specific force of a vehicle rolled 70° (beyond the 60° limit).
    let (s, c) = libm::sincosf(70f32.to_radians());
    let tilted = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, -GRAVITY * s, -GRAVITY * c) };
    let idle = AttitudeCommand { stage: MotorStage::Idle, ..AttitudeCommand::default() };
    let off = AttitudeCommand { stage: MotorStage::Off, ..AttitudeCommand::default() };
    inner.set_command(idle);
    let out = inner.step(1_000_000, &level);
    assert!(out.armed && out.throttle == [0.1; 4], "idle while level: {out:?}");
    assert!(inner.estimate().tilt_trip.is_none());
    // The estimator initialises from the accelerometer: a new one sees the tilt at once.
    let (_, mut inner) = FlightController::new(params).unwrap().into_loops();
    inner.set_command(idle);
    let out = inner.step(1_000_000, &tilted);
    assert_eq!(out, MotorOutput::default(), "cut in the same step");
    let trip = inner.estimate().tilt_trip.expect("a tilt trip");
    assert_eq!(trip.t_us, 1_000_000);
    assert!((trip.tilt - 70f32.to_radians()).abs() < 1e-3, "{}", trip.tilt);
    // The cut holds while the command still allows the motors (the outer loop has not
    // seen the trip yet), and is cleared only by a command with the motors off.
    inner.set_command(idle);
    assert_eq!(inner.step(1_001_000, &tilted), MotorOutput::default());
    assert!(inner.estimate().tilt_trip.is_some());
    inner.set_command(off);
    assert!(inner.estimate().tilt_trip.is_none());
    assert_eq!(inner.step(1_002_000, &tilted), MotorOutput::default());
    assert!(inner.estimate().tilt_trip.is_none(), "motors off: no trip");
}

#[test]
fn the_outer_loop_turns_a_reported_tilt_trip_into_motors_off() {
    let params = ControllerParams::default();
    let (mut outer, mut inner) = FlightController::new(params).unwrap().into_loops();
    let q = Quad::new(Vec3::new(0.0, 0.0, -1.0));
    let t = 1_000_000;
    outer.update_position(q.fix(t));
    inner.set_aid(outer.aid());
    outer.update_obstacles(t, &[]);
    let level = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -GRAVITY) };
    inner.step(t, &level);
    assert!(!outer.on_estimate(&inner.estimate()));
    outer.arm(t).unwrap();
    inner.set_command(outer.command());
    // A roll kick the inner loop sees: 25 rad/s for 50 ms ≈ 72°.
    let kick = ImuSample { gyro: Vec3::new(25.0, 0.0, 0.0), accel: level.accel };
    let mut t_cut = None;
    for k in 1..=50u64 {
        let out = inner.step(t + k * 1000, &kick);
        if out == MotorOutput::default() && t_cut.is_none() {
            t_cut = Some(t + k * 1000);
        }
    }
    let t_cut = t_cut.expect("the inner loop cut the motors");
    assert_eq!(outer.state(), FailsafeState::Armed, "the outer loop has not seen it yet");
    assert!(outer.on_estimate(&inner.estimate()), "the command changes");
    assert_eq!(outer.state(), FailsafeState::MotorsOff);
    let tr = outer.telemetry().last_transition.unwrap();
    assert_eq!((tr.reason, tr.t_us), (TransitionReason::TiltLimit, t_cut));
    assert_eq!(outer.command().stage, MotorStage::Off);
}
