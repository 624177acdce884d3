//! Property tests of the cascade: no sequence of inputs makes a step or a command panic or
//! the inner loop emit a non-finite / out-of-range motor command.

use parapet_core::airframe::Airframe;
use parapet_core::attitude::{torque_vec, AttitudeController, AttitudeParams, Euler};
use parapet_core::controller::{
    ControllerParams, FlightController, MotorOutput, PositionFix, OBSTACLE_CAPACITY,
};
use parapet_core::estimator::{AttitudeEstimator, EstimatorParams, ImuSample};
use parapet_core::frame::{is_finite3, GRAVITY};
use parapet_core::mixer::Mixer;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::Vec3;
use proptest::prelude::*;

#[path = "support/wild.rs"]
mod wild;

fn wild() -> impl Strategy<Value = f32> {
    wild::wild(8, -20.0..20.0)
}

fn wild3() -> impl Strategy<Value = Vec3> {
    (wild(), wild(), wild()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// Accelerometer samples: arbitrary, plus exact free fall and rest.
fn accel() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        3 => wild3(),
        1 => Just(Vec3::zeros()),
        1 => Just(Vec3::new(0.0, 0.0, -GRAVITY)),
    ]
}

/// Acceleration aids: none, arbitrary, or exactly cancelling gravity (predicted free fall).
fn aid() -> impl Strategy<Value = Option<Vec3>> {
    prop_oneof![
        1 => Just(None),
        3 => wild3().prop_map(Some),
        1 => Just(Some(Vec3::new(0.0, 0.0, GRAVITY))),
    ]
}

/// Time step: mostly nominal, sometimes zero, backwards, huge or saturating.
#[derive(Clone, Copy, Debug)]
enum Dt {
    Fwd(u64),
    Back(u64),
}

fn dt() -> impl Strategy<Value = Dt> {
    prop_oneof![
        8 => (0u64..5_000).prop_map(Dt::Fwd),
        1 => (0u64..10_000_000_000).prop_map(Dt::Fwd),
        1 => any::<u64>().prop_map(Dt::Fwd),
        1 => (0u64..1_000_000).prop_map(Dt::Back),
    ]
}

#[derive(Clone, Debug)]
enum Op {
    Fix(Dt, Vec3, Vec3, Option<f32>),
    Obstacles(Dt, Vec<(Vec3, Option<Vec3>)>),
    Inner(Dt, Vec3, Vec3),
    Outer(Dt),
    Arm,
    Disarm,
    Takeoff(f32),
    Hold(Vec3),
    Mission,
    Land,
    Path(Vec<Vec3>),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        3 => (dt(), wild3(), wild3(), proptest::option::of(wild())).prop_map(|(d, p, v, y)| Op::Fix(d, p, v, y)),
        2 => (dt(), proptest::collection::vec((wild3(), proptest::option::of(wild3())), 0..40))
            .prop_map(|(d, o)| Op::Obstacles(d, o)),
        6 => (dt(), wild3(), wild3()).prop_map(|(d, g, a)| Op::Inner(d, g, a)),
        3 => dt().prop_map(Op::Outer),
        1 => Just(Op::Arm),
        1 => Just(Op::Disarm),
        1 => wild().prop_map(Op::Takeoff),
        1 => wild3().prop_map(Op::Hold),
        1 => Just(Op::Mission),
        1 => Just(Op::Land),
        1 => proptest::collection::vec(wild3(), 0..70).prop_map(Op::Path),
    ]
}

fn advance(t: u64, d: Dt) -> u64 {
    match d {
        Dt::Fwd(x) => t.saturating_add(x),
        Dt::Back(x) => t.saturating_sub(x),
    }
}

fn check(out: &MotorOutput, fm: f32) -> Result<(), TestCaseError> {
    for i in 0..4 {
        prop_assert!(out.throttle[i].is_finite() && (0.0..=1.0).contains(&out.throttle[i]), "{out:?}");
        prop_assert!(out.thrust_n[i].is_finite() && (0.0..=fm).contains(&out.thrust_n[i]), "{out:?}");
    }
    if !out.armed {
        prop_assert_eq!(out.throttle, [0.0; 4]);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// No sequence of inputs (NaN, ±Inf, 1e30, empty or over-long paths, time
    /// going backwards or jumping by up to u64::MAX) makes a step function or a
    /// command panic, or the inner loop emit a non-finite / out-of-range command.
    /// Each case starts from a flying vehicle so the flying code paths are reached.
    #[test]
    fn no_input_panics_or_gives_non_finite_motor_commands(ops in proptest::collection::vec(op(), 1..60)) {
        let params = ControllerParams::default();
        let fm = params.airframe.rotor_thrust_max;
        let mut ctl = FlightController::new(params).unwrap();
        let mut t = 1_000_000u64;
        let level = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -GRAVITY) };
        let hover = Vec3::new(0.0, 0.0, -1.0);
        for _ in 0..10 {
            t += 1000;
            ctl.update_position(PositionFix { t_us: t, position: hover, velocity: Vec3::zeros(), yaw: Some(0.0) });
            ctl.update_obstacles(t, &[ObstaclePoint::fixed(Vec3::new(1.0, 0.0, -1.0), 1)]);
            ctl.step_outer(t);
            check(&ctl.step_inner(t, &level), fm)?;
        }
        ctl.set_path(&[hover, Vec3::new(1.0, 1.0, -1.0)]).unwrap();
        ctl.arm(t).unwrap();
        ctl.takeoff(t, 1.0).unwrap();
        ctl.step_outer(t);
        ctl.start_mission(t).unwrap();
        for op in ops {
            match op {
                Op::Fix(d, p, v, yaw) => {
                    t = advance(t, d);
                    ctl.update_position(PositionFix { t_us: t, position: p, velocity: v, yaw });
                }
                Op::Obstacles(d, pts) => {
                    t = advance(t, d);
                    let pts: Vec<ObstaclePoint> = pts
                        .iter()
                        .enumerate()
                        .map(|(i, (p, v))| ObstaclePoint { point: *p, velocity: *v, id: i as u16, normal: None })
                        .collect();
                    ctl.update_obstacles(t, &pts);
                    prop_assert!(ctl.obstacles().len() <= OBSTACLE_CAPACITY);
                }
                Op::Inner(d, g, a) => {
                    t = advance(t, d);
                    check(&ctl.step_inner(t, &ImuSample { gyro: g, accel: a }), fm)?;
                }
                Op::Outer(d) => {
                    t = advance(t, d);
                    ctl.step_outer(t);
                }
                Op::Arm => { let _ = ctl.arm(t); }
                Op::Disarm => { let _ = ctl.disarm(t); }
                Op::Takeoff(h) => { let _ = ctl.takeoff(t, h); }
                Op::Hold(p) => { let _ = ctl.hold_position(t, p); }
                Op::Mission => { let _ = ctl.start_mission(t); }
                Op::Land => { let _ = ctl.land(t); }
                Op::Path(p) => { let _ = ctl.set_path(&p); }
            }
            // The inner loop after every operation, with a plausible sample.
            t = t.saturating_add(1000);
            check(&ctl.step_inner(t, &level), fm)?;
            let tel = ctl.telemetry();
            prop_assert!(tel.attitude_sp.thrust.is_finite());
            prop_assert!(tel.rate_sp.iter().chain(tel.torque.iter()).all(|x| x.is_finite()));
        }
    }

    /// The inner-loop chain alone (estimator → attitude → mixer) on arbitrary
    /// samples, setpoints and time steps: finite, in-range rotor commands.
    #[test]
    fn inner_chain_is_finite_for_any_input(
        steps in proptest::collection::vec((wild3(), accel(), aid(), wild3(), wild(), wild()), 1..40),
    ) {
        let af = Airframe::default();
        let mut est = AttitudeEstimator::new(EstimatorParams::default()).unwrap();
        let mut att = AttitudeController::new(AttitudeParams::default(), af.inertia).unwrap();
        let mixer = Mixer::new(&af).unwrap();
        let mut sat = false;
        for (g, a, aid, sp, thrust, dt) in steps {
            est.update(&ImuSample { gyro: g, accel: a }, dt, aid, Some(thrust));
            let e = est.euler();
            prop_assert!(e.is_finite() && est.tilt().is_finite());
            prop_assert!(is_finite3(&est.gyro_bias()) && is_finite3(&est.rate()));
            let sp = Euler { roll: sp.x, pitch: sp.y, yaw: sp.z };
            let r = est.rate();
            let o = att.update(&sp, &e, &[r.x, r.y, r.z], dt, sat);
            let m = mixer.mix(thrust, &torque_vec(&o));
            sat = m.saturated();
            for i in 0..4 {
                prop_assert!(m.thrust_n[i].is_finite() && (0.0..=af.rotor_thrust_max).contains(&m.thrust_n[i]));
                prop_assert!(m.throttle[i].is_finite() && (0.0..=1.0).contains(&m.throttle[i]));
            }
        }
    }
}
