//! Closed-loop tests of the flight modes (issue 21) on the core's test plant (`plant/`):
//! Position assist into a wall (stop, slide), the kill switch (motors off on the very next
//! inner step), RC loss per mode, offboard setpoints and their timeout, the battery
//! failsafes, Return along the breadcrumbs, NaN sticks and setpoints, Manual without filter.
//! Every run is deterministic (no noise); the numbers printed are in `docs/cascade.md`.

mod plant;

use parapet_core::battery::{BatteryLevel, BatteryState};
use parapet_core::controller::{CommandError, ControllerParams, FlightMode, GuidanceMode, OffboardSetpoint};
use parapet_core::failsafe::{FailsafeState, TransitionReason};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::params;
use parapet_core::rc::{RcInput, SwitchPosition};
use parapet_core::Vec3;
use plant::Sim;

const HOVER: Vec3 = Vec3::new(0.0, 0.0, -1.0);
/// The default hull radius √δ, m: a vehicle centre closer than this to a surface is a contact.
const HULL_R: f32 = 0.223_606_8;

fn sticks(t_us: u64, roll: f32, pitch: f32) -> RcInput {
    RcInput { t_us, roll, pitch, throttle: 0.5, arm: true, link_quality: 100, ..RcInput::default() }
}

/// Armed, hovering at `HOVER` in Mission (hold), with `p` applied.
fn hovering(p: ControllerParams) -> Sim {
    let mut sim = Sim::new(p, HOVER);
    sim.ctl.arm(sim.t_us).unwrap();
    sim.ctl.hold_position(sim.t_us, HOVER).unwrap();
    sim.run(1.0, |_, _| {});
    sim
}

/// How a wall `x = X` is reported to the filter.
#[derive(Clone, Copy, PartialEq)]
enum Wall {
    /// Fixed surface points every 0.1 m along y (the 13 nearest the vehicle): static obstacle
    /// points, which is what the filter's point model assumes.
    Grid(f32),
    /// Its single closest point with the wall's normal (a source that knows the surface, as the
    /// host simulator's truth perception), measured 10 ms before each 100 Hz update and held
    /// until the next: the point lags 10-20 ms behind a vehicle sliding along the wall.
    Closest(f32),
    /// Its single closest point without a normal, measured at the update's time stamp (a
    /// source that stamps its report with the measurement time) and held 10 ms.
    ClosestPoint(f32),
    /// As `ClosestPoint`, but measured 10 ms before the time stamp it is delivered with (an
    /// unreported 10 ms latency) and held 10 ms.
    ClosestPointLate(f32),
}

/// Runs `seconds` in 10 ms chunks: before each, the wall (if any) is reported and `each(t)`
/// may feed the controller. (The plant delivers the reported points with the update at the
/// end of the chunk, a multiple of 10 ms.)
fn fly_wall(sim: &mut Sim, seconds: f32, wall: Option<Wall>, mut each: impl FnMut(&mut Sim, u64)) {
    for _ in 0..(seconds * 100.0) as u32 {
        sim.obstacles.clear();
        let p = sim.quad.p;
        match wall {
            Some(Wall::Grid(x)) => {
                let j0 = (p.y * 10.0).round() as i32;
                for (k, j) in (j0 - 6..=j0 + 6).enumerate() {
                    let pt = Vec3::new(x, j as f32 * 0.1, p.z);
                    let _ = sim.obstacles.push(ObstaclePoint::fixed(pt, k as u16));
                }
            }
            Some(Wall::Closest(x)) => {
                let n = Vec3::new(-1.0, 0.0, 0.0);
                let _ = sim.obstacles.push(ObstaclePoint::surface(Vec3::new(x, p.y, p.z), n, 1));
            }
            Some(Wall::ClosestPointLate(x)) => {
                let _ = sim.obstacles.push(ObstaclePoint::fixed(Vec3::new(x, p.y, p.z), 1));
            }
            Some(Wall::ClosestPoint(_)) | None => {}
        }
        let t = sim.t_us;
        each(sim, t);
        if let Some(Wall::ClosestPoint(x)) = wall {
            // Measured 1 ms before the update (the plant's resolution), as stamped.
            sim.run(0.009, |_, _| {});
            let p = sim.quad.p;
            sim.obstacles.clear();
            let _ = sim.obstacles.push(ObstaclePoint::fixed(Vec3::new(x, p.y, p.z), 1));
            sim.run(0.001, |_, _| {});
        } else {
            sim.run(0.01, |_, _| {});
        }
    }
}

fn fly(sim: &mut Sim, seconds: f32, wall_x: Option<f32>, each: impl FnMut(&mut Sim, u64)) {
    fly_wall(sim, seconds, wall_x.map(Wall::Grid), each);
}

/// Position assist, full stick towards the wall `x = 2` at `speed` (with `roll` to the right):
/// the closest approach (m) and the final y.
fn stick_into_wall(speed: f32, roll: f32, wall: Wall) -> (f32, Sim) {
    let mut p = ControllerParams::default();
    params::set(&mut p, "PA_SPEED_MAX", speed).unwrap();
    let mut sim = in_position_mode(p);
    let mut max_x = f32::MIN;
    fly_wall(&mut sim, 15.0, Some(wall), |s, t| {
        s.ctl.set_rc(&sticks(t, roll, 1.0));
        max_x = max_x.max(s.quad.p.x);
    });
    (2.0 - max_x, sim)
}

fn in_position_mode(p: ControllerParams) -> Sim {
    let mut sim = hovering(p);
    sim.ctl.set_rc(&sticks(sim.t_us, 0.0, 0.0));
    sim.ctl.set_mode(sim.t_us, FlightMode::Position).unwrap();
    assert_eq!(sim.ctl.mode(), FlightMode::Position);
    sim
}

#[test]
fn full_stick_into_a_wall_stops_without_contact_and_slides_with_a_tangential_part() {
    for speed in [0.5f32, 1.0, 2.0, 3.0] {
        for roll in [0.0f32, 0.5] {
            let (gap, sim) = stick_into_wall(speed, roll, Wall::Grid(2.0));
            let tel = sim.ctl.telemetry();
            println!(
                "assist {speed} m/s, roll {roll}: closest {gap:.3} m to the wall, y {:.2} m, filter active in {} steps",
                sim.quad.p.y,
                tel.filter_interventions[FlightMode::Position as usize]
            );
            assert!(gap > HULL_R, "{speed} m/s roll {roll}: contact (gap {gap} m)");
            assert!(gap < 1.0, "{speed} m/s: the pilot's command was not followed (gap {gap})");
            assert!(tel.filter_interventions[FlightMode::Position as usize] > 0);
            assert_eq!(tel.mode, GuidanceMode::Assist);
            if roll > 0.0 {
                assert!(sim.quad.p.y > 1.0, "{speed} m/s: no slide along the wall (y {})", sim.quad.p.y);
            } else {
                assert!(sim.quad.v.norm() < 0.1, "stopped at the wall: {:?}", sim.quad.v);
                assert!(sim.quad.p.y.abs() < 0.1);
            }
        }
    }
}

/// Issue 21's wall finding: a wall given as its single closest point and held between 100 Hz
/// updates was crossed by a vehicle sliding along it at 2 m/s (gap −0.094 m): the filter
/// re-aimed the point's normal from the current position, so the held point's barrier read the
/// tangential speed as a retreat (`docs/filter.md` §9). Fixed by the tangent half-space: the
/// normal the source reports, or else the one aimed from where the vehicle was at the report.
#[test]
fn closest_point_wall_while_sliding_fast() {
    for wall in [Wall::Closest(2.0), Wall::ClosestPoint(2.0)] {
        for speed in [1.0f32, 2.0, 3.0] {
            let (gap, sim) = stick_into_wall(speed, 0.5, wall);
            let kind = if wall == Wall::Closest(2.0) { "with normal" } else { "point, stamped" };
            println!(
                "closest-point wall ({kind}), assist {speed} m/s, roll 0.5: closest {gap:.3} m, y {:.2} m",
                sim.quad.p.y
            );
            assert!(gap > HULL_R, "{kind}, {speed} m/s: contact (gap {gap} m)");
            assert!(sim.quad.p.y > 1.0, "{kind}, {speed} m/s: no slide along the wall (y {})", sim.quad.p.y);
        }
    }
}

/// What remains, kept as a failing (ignored) test: the closest point without a normal,
/// delivered with a time stamp 10 ms later than its measurement. The normal aimed from the
/// position at the stamp is tilted by (tangential speed × 10 ms)/gap, and the tangential speed
/// again reads partly as a retreat (measured: 0.248 m at 1 m/s, 0.188 m at 2 m/s, through the
/// wall at 3 m/s). Sources must stamp closest points with their measurement time or report the
/// surface normal. Run with `cargo test -p parapet-core --release --test modes -- --ignored`.
#[test]
#[ignore = "known limitation: closest point without normal and unreported latency (docs/filter.md §9)"]
fn closest_point_wall_with_unreported_latency() {
    for speed in [1.0f32, 2.0, 3.0] {
        let (gap, _) = stick_into_wall(speed, 0.5, Wall::ClosestPointLate(2.0));
        println!("closest point, 10 ms unreported latency, assist {speed} m/s, roll 0.5: closest {gap:.3} m");
        assert!(gap > HULL_R, "{speed} m/s: contact (gap {gap} m)");
    }
}

#[test]
fn centred_sticks_hold_position_and_yaw_stick_turns() {
    let mut sim = in_position_mode(ControllerParams::default());
    fly(&mut sim, 2.0, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 1.0)));
    fly(&mut sim, 6.0, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 0.0)));
    let here = sim.quad.p;
    fly(&mut sim, 3.0, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 0.0)));
    let drift = (sim.quad.p - here).norm();
    println!("assist hold: drift over 3 s after centring {drift:.4} m");
    assert!(drift < 0.05 && sim.quad.p.x > 1.0, "drift {drift}, x {}", sim.quad.p.x);
    fly(&mut sim, 1.0, None, |s, t| s.ctl.set_rc(&RcInput { yaw: 1.0, ..sticks(t, 0.0, 0.0) }));
    let yaw = sim.ctl.telemetry().attitude.yaw;
    assert!(yaw > 0.6, "yaw after 1 s of full right yaw stick: {yaw}");
}

#[test]
fn kill_switch_stops_the_motors_on_the_very_next_inner_step() {
    for mode in [FlightMode::Position, FlightMode::Mission, FlightMode::Manual] {
        let mut sim = in_position_mode(ControllerParams::default());
        if mode != FlightMode::Position {
            sim.ctl.set_mode(sim.t_us, mode).unwrap();
        }
        fly(&mut sim, 0.5, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 0.0)));
        let t = sim.t_us;
        sim.ctl.set_rc(&RcInput { kill: true, ..sticks(t, 0.0, 0.0) });
        let out = sim.ctl.step_inner(t + 1000, &sim.quad.imu());
        assert_eq!(out.throttle, [0.0; 4], "{mode:?}: motors not off on the next inner step");
        assert!(!out.armed);
        let tr = sim.ctl.telemetry().last_transition.unwrap();
        assert_eq!((tr.to, tr.reason), (FailsafeState::Disarmed, TransitionReason::KillSwitch));
        // Kill held: the arm switch cannot re-arm.
        sim.ctl.set_rc(&RcInput { kill: true, arm: false, ..sticks(t + 2000, 0.0, 0.0) });
        sim.ctl.set_rc(&RcInput { kill: true, arm: true, ..sticks(t + 3000, 0.0, 0.0) });
        assert_eq!(sim.ctl.state(), FailsafeState::Disarmed);
    }
}

#[test]
fn rc_loss_in_position_holds_then_lands() {
    let mut p = ControllerParams::default();
    params::set(&mut p, "FS_RC_LAND_T", 2.0).unwrap();
    let mut sim = in_position_mode(p);
    let mut t_loss = 0;
    fly(&mut sim, 1.0, None, |s, t| {
        s.ctl.set_rc(&sticks(t, 0.3, 0.0));
        t_loss = t;
    });
    fly(&mut sim, 0.6, None, |_, _| {});
    let tel = sim.ctl.telemetry();
    assert_eq!(tel.flight_mode, FlightMode::Hold);
    let mc = tel.last_mode_change.unwrap();
    assert_eq!(
        (mc.from, mc.to, mc.reason),
        (FlightMode::Position, FlightMode::Hold, TransitionReason::RcLoss)
    );
    assert!(mc.t_us > t_loss + 500_000 && mc.t_us < t_loss + 520_000, "{}", mc.t_us - t_loss);
    fly(&mut sim, 2.0, None, |_, _| {});
    assert_eq!(sim.ctl.state(), FailsafeState::Land);
    assert_eq!(sim.ctl.telemetry().last_transition.unwrap().reason, TransitionReason::RcLoss);
    fly(&mut sim, 8.0, None, |_, _| {});
    assert_eq!(sim.ctl.state(), FailsafeState::Disarmed, "landed");
    assert!(sim.quad.on_ground());
}

#[test]
fn rc_loss_in_mission_continues_or_returns_by_parameter() {
    for act in [0.0f32, 1.0] {
        let mut p = ControllerParams::default();
        params::set(&mut p, "FS_RC_ACT", act).unwrap();
        params::set(&mut p, "WP_SPEED", 1.0).unwrap();
        let mut sim = Sim::new(p, Vec3::zeros());
        let high = |t| RcInput { mode: SwitchPosition::High, ..sticks(t, 0.0, 0.0) };
        sim.ctl.set_rc(&RcInput { mode: SwitchPosition::High, ..sticks(sim.t_us, 0.0, 0.0) });
        sim.ctl.arm(sim.t_us).unwrap();
        sim.ctl.takeoff(sim.t_us, 1.0).unwrap();
        fly(&mut sim, 4.0, None, |s, t| s.ctl.set_rc(&high(t)));
        let path = [Vec3::new(3.0, 0.0, -1.0), Vec3::new(3.0, 3.0, -1.0), Vec3::new(0.0, 6.0, -1.0)];
        sim.ctl.set_path(&path).unwrap();
        sim.ctl.start_mission(sim.t_us).unwrap();
        fly(&mut sim, 5.0, None, |s, t| s.ctl.set_rc(&high(t)));
        // RC lost from here on.
        fly(&mut sim, 40.0, None, |_, _| {});
        let tel = sim.ctl.telemetry();
        if act == 0.0 {
            assert_eq!(tel.flight_mode, FlightMode::Mission);
            assert!(tel.progress.done && (sim.quad.p - path[2]).norm() < 0.1, "{:?}", sim.quad.p);
        } else {
            assert_eq!(tel.state, FailsafeState::Disarmed, "returned and landed");
            let home_err = (sim.quad.p.xy()).norm();
            println!("rc loss → return: landed {home_err:.3} m from home");
            assert!(home_err < 0.15, "{:?}", sim.quad.p);
            assert!(sim.quad.on_ground());
        }
    }
}

#[test]
fn battery_low_returns_and_critical_lands() {
    let mut sim = in_position_mode(ControllerParams::default());
    fly(&mut sim, 3.0, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 1.0)));
    fly(&mut sim, 3.0, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 0.0)));
    let away = sim.quad.p;
    assert!(away.x > 2.0);
    let b = |t_us, level| BatteryState { t_us, voltage_v: 10.5, level, ..BatteryState::default() };
    sim.ctl.set_battery(&b(sim.t_us, BatteryLevel::Low));
    fly(&mut sim, 0.1, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 0.0)));
    let mc = sim.ctl.telemetry().last_mode_change.unwrap();
    assert_eq!((mc.to, mc.reason), (FlightMode::Return, TransitionReason::BatteryLow));
    fly(&mut sim, 3.0, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 0.0)));
    assert!(sim.quad.p.x < away.x - 0.5, "flying back: {:?}", sim.quad.p);
    sim.ctl.set_battery(&b(sim.t_us, BatteryLevel::Critical));
    fly(&mut sim, 0.1, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 0.0)));
    let tr = sim.ctl.telemetry().last_transition.unwrap();
    assert_eq!((tr.to, tr.reason), (FailsafeState::Land, TransitionReason::BatteryCritical));
    assert_eq!(sim.ctl.mode(), FlightMode::Land);
}

#[test]
fn offboard_velocity_into_a_wall_is_filtered_and_the_setpoint_timeout_holds() {
    let mut sim = hovering(ControllerParams::default());
    let v = |t_us| OffboardSetpoint { t_us, velocity: Some(Vec3::new(1.0, 0.0, 0.0)), ..Default::default() };
    assert_eq!(sim.ctl.set_mode(sim.t_us, FlightMode::Offboard), Err(CommandError::ModeUnavailable));
    sim.ctl.set_offboard(&v(sim.t_us));
    sim.ctl.set_mode(sim.t_us, FlightMode::Offboard).unwrap();
    let mut max_x = f32::MIN;
    fly(&mut sim, 10.0, Some(2.0), |s, t| {
        s.ctl.set_offboard(&v(t));
        max_x = max_x.max(s.quad.p.x);
    });
    println!("offboard 1 m/s into a wall: closest {:.3} m", 2.0 - max_x);
    assert!(2.0 - max_x > HULL_R && max_x > 1.0, "x {max_x}");
    assert_eq!(sim.ctl.telemetry().mode, GuidanceMode::Offboard);
    // Position setpoint where it is safe: followed.
    let target = Vec3::new(0.5, 1.0, -1.2);
    fly(&mut sim, 10.0, Some(2.0), |s, t| {
        s.ctl.set_offboard(&OffboardSetpoint { t_us: t, position: Some(target), ..Default::default() })
    });
    assert!((sim.quad.p - target).norm() < 0.05, "{:?}", sim.quad.p);
    // The stream stops (and NaN setpoints do not count): Hold after OFFB_TIMEOUT.
    let t_stop = sim.t_us;
    fly(&mut sim, 1.0, Some(2.0), |s, t| {
        s.ctl.set_offboard(&OffboardSetpoint {
            t_us: t,
            velocity: Some(Vec3::new(f32::NAN, 0.0, 0.0)),
            ..Default::default()
        })
    });
    let tel = sim.ctl.telemetry();
    let mc = tel.last_mode_change.unwrap();
    assert_eq!((mc.to, mc.reason), (FlightMode::Hold, TransitionReason::OffboardLoss));
    assert!(mc.t_us - t_stop <= 520_000, "{}", mc.t_us - t_stop);
    assert!(tel.offboard_rejected >= 90, "{}", tel.offboard_rejected);
    fly(&mut sim, 3.0, Some(2.0), |_, _| {});
    assert!(sim.quad.v.norm() < 0.05 && (sim.quad.p - target).norm() < 0.1);
}

#[test]
fn offboard_acceleration_setpoint_is_the_filtered_nominal_command() {
    let mut sim = hovering(ControllerParams::default());
    let a =
        |t_us| OffboardSetpoint { t_us, acceleration: Some(Vec3::new(0.5, 0.0, 0.0)), ..Default::default() };
    sim.ctl.set_offboard(&a(sim.t_us));
    sim.ctl.set_mode(sim.t_us, FlightMode::Offboard).unwrap();
    let mut max_x = f32::MIN;
    fly(&mut sim, 8.0, Some(1.5), |s, t| {
        s.ctl.set_offboard(&a(t));
        max_x = max_x.max(s.quad.p.x);
    });
    let tel = sim.ctl.telemetry();
    println!("offboard 0.5 m/s² into a wall: closest {:.3} m", 1.5 - max_x);
    assert!(1.5 - max_x > HULL_R, "x {max_x}");
    assert!(tel.filter_interventions[FlightMode::Offboard as usize] > 0);
}

#[test]
fn nan_sticks_are_rejected_counted_and_end_in_rc_loss() {
    let mut sim = in_position_mode(ControllerParams::default());
    fly(&mut sim, 1.0, None, |s, t| {
        s.ctl.set_rc(&RcInput { roll: f32::NAN, pitch: 1.0, ..sticks(t, 0.0, 0.0) })
    });
    let tel = sim.ctl.telemetry();
    assert!(tel.rc_rejected >= 99, "{}", tel.rc_rejected);
    assert_eq!(tel.flight_mode, FlightMode::Hold, "bad frames are no RC: RC loss");
    assert_eq!(tel.last_mode_change.unwrap().reason, TransitionReason::RcLoss);
    assert!((sim.quad.p - HOVER).norm() < 0.1, "no stick acted: {:?}", sim.quad.p);
    assert_eq!(tel.state, FailsafeState::Armed, "no data-fault brake for a bad RC frame");
}

#[test]
fn manual_flies_attitude_without_the_filter() {
    let mut sim = in_position_mode(ControllerParams::default());
    sim.ctl.set_mode(sim.t_us, FlightMode::Manual).unwrap();
    let mut pitch = 0.0;
    fly(&mut sim, 0.6, Some(0.6), |s, t| {
        s.ctl.set_rc(&sticks(t, 0.0, 0.5));
        pitch = s.ctl.telemetry().attitude.pitch;
    });
    let tel = sim.ctl.telemetry();
    assert_eq!(tel.mode, GuidanceMode::Manual);
    assert!((pitch + 0.175).abs() < 0.03, "pitch {pitch} for half forward stick");
    assert_eq!(tel.filter_interventions[FlightMode::Manual as usize], 0);
    assert!(!tel.filter_active);
}

#[test]
fn mode_switch_positions_select_the_parameter_modes() {
    let mut sim = in_position_mode(ControllerParams::default());
    fly(&mut sim, 0.2, None, |s, t| s.ctl.set_rc(&sticks(t, 0.0, 0.0)));
    fly(&mut sim, 0.2, None, |s, t| {
        s.ctl.set_rc(&RcInput { mode: SwitchPosition::Mid, ..sticks(t, 0.0, 0.0) })
    });
    let mc = sim.ctl.telemetry().last_mode_change.unwrap();
    assert_eq!((mc.to, mc.reason), (FlightMode::Hold, TransitionReason::ModeSwitch));
    fly(&mut sim, 0.2, None, |s, t| {
        s.ctl.set_rc(&RcInput { mode: SwitchPosition::High, ..sticks(t, 0.0, 0.0) })
    });
    assert_eq!(sim.ctl.mode(), FlightMode::Mission);
    fly(&mut sim, 0.2, None, |s, t| {
        s.ctl.set_rc(&RcInput { mode: SwitchPosition::Low, ..sticks(t, 0.0, 0.0) })
    });
    assert_eq!(sim.ctl.mode(), FlightMode::Position);
    assert_eq!(sim.ctl.state(), FailsafeState::Armed);
    assert!((sim.quad.p - HOVER).norm() < 0.1);
}
