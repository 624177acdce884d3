//! Host tests of the setup commands (storage, calibration, motor test) without a link.

use super::*;
use parapet_core::calibration::accel::Face;
use parapet_core::frame::GRAVITY;
use std::string::ToString;
use std::vec::Vec;

fn texts(s: &mut Setup) -> Vec<std::string::String> {
    core::iter::from_fn(|| s.pop_text()).map(|t| t.as_str().to_string()).collect()
}

fn motor(instance: f32, pct: f32, timeout: f32) -> [f32; 7] {
    [instance, 0.0, pct, timeout, 0.0, 0.0, 0.0]
}

const P: fn() -> ControllerParams = ControllerParams::default;

#[test]
fn motor_test_runs_disarmed_and_any_other_command_stops_it() {
    let mut s = Setup::new();
    assert_eq!(s.command(0, CMD_DO_MOTOR_TEST, motor(2.0, 10.0, 1.0), false, &P()), Some(SetupAck::Accepted));
    assert_eq!(s.motor_output(1, None), Some([0.0, 0.1, 0.0, 0.0]));
    // An unrelated command (e.g. 400 ARM) is not answered here but stops the motors.
    assert_eq!(s.command(2, 400, [0.0; 7], false, &P()), None);
    assert_eq!(s.motor_output(3, None), None);
    // Timeout.
    s.command(0, CMD_DO_MOTOR_TEST, motor(1.0, 10.0, 1.0), false, &P());
    assert!(s.motor_output(999_999, None).is_some());
    assert_eq!(s.motor_output(1_000_000, None), None);
    // Link loss / RC arm.
    s.command(0, CMD_DO_MOTOR_TEST, motor(1.0, 10.0, 1.0), false, &P());
    s.stop_motors();
    assert_eq!(s.motor_output(1, None), None);
    texts(&mut s);
    // Armed: DENIED with the reason.
    assert_eq!(s.command(0, CMD_DO_MOTOR_TEST, motor(1.0, 10.0, 1.0), true, &P()), Some(SetupAck::Denied));
    assert_eq!(texts(&mut s), ["Motor test refused: vehicle armed"]);
    assert_eq!(s.motor_output(1, None), None);
    // Unknown order: UNSUPPORTED.
    let mut p = motor(1.0, 10.0, 1.0);
    p[5] = 9.0;
    assert_eq!(s.command(0, CMD_DO_MOTOR_TEST, p, false, &P()), Some(SetupAck::Unsupported));
}

#[test]
fn storage_commands_are_queued_for_the_storage_task_and_refused_armed() {
    let mut s = Setup::new();
    for (code, req) in
        [(0.0, StorageRequest::Read), (1.0, StorageRequest::Write), (2.0, StorageRequest::Reset)]
    {
        let mut p = [0.0; 7];
        p[0] = code;
        assert_eq!(s.command(0, CMD_PREFLIGHT_STORAGE, p, false, &P()), Some(SetupAck::Accepted));
        assert_eq!(s.command(0, CMD_PREFLIGHT_STORAGE, p, false, &P()), Some(SetupAck::TemporarilyRejected));
        assert_eq!(s.take_storage(), Some(req));
        assert_eq!(s.take_storage(), None);
    }
    assert_eq!(
        s.command(0, CMD_PREFLIGHT_STORAGE, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], true, &P()),
        Some(SetupAck::Denied)
    );
    assert_eq!(s.take_storage(), None);
    assert_eq!(
        s.command(0, CMD_PREFLIGHT_STORAGE, [3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], false, &P()),
        Some(SetupAck::Unsupported)
    );
}

fn sample(accel: Vec3) -> ImuSample {
    ImuSample { gyro: Vec3::zeros(), accel }
}

#[test]
fn six_position_calibration_writes_the_parameters_and_schedules_a_save() {
    let offset = Vec3::new(0.3, -0.2, 0.4);
    let scale = Vec3::new(1.02, 0.98, 1.01);
    let mut s = Setup::new();
    let mut params = P();
    let cmd = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0];
    assert_eq!(s.command(0, CMD_PREFLIGHT_CALIBRATION, cmd, false, &params), Some(SetupAck::Accepted));
    assert_eq!(
        s.command(0, CMD_PREFLIGHT_CALIBRATION, cmd, false, &params),
        Some(SetupAck::TemporarilyRejected)
    );
    let faces =
        [Face::Down, Face::Up, Face::Back, Face::Front, Face::Left, Face::Right].map(Face::specific_force);
    let mut t = 0u64;
    let mut all = Vec::new();
    let mut wrote = false;
    for f in faces {
        for _ in 0..1000 {
            wrote |= s.imu(t, &sample(f.component_div(&scale) + offset), &mut params);
            t += 5_000;
        }
        for k in 0..100 {
            s.imu(t, &sample(f + Vec3::new((k as f32).sin() * 5.0, 3.0, 0.0)), &mut params);
            t += 5_000;
        }
        all.extend(texts(&mut s));
    }
    assert!(wrote, "{all:?}");
    assert!(!s.calibrating());
    assert_eq!(all.first().map(|x| x.as_str()), Some("[cal] calibration started: 2 accel"));
    assert!(all.iter().any(|x| x == "[cal] down orientation detected"));
    assert!(all.iter().any(|x| x == "[cal] calibration done: accel"), "{all:?}");
    assert_eq!(s.texts_dropped(), 0);
    let got = Vec3::new(
        params.sensors.accel_offset.x,
        params.sensors.accel_offset.y,
        params.sensors.accel_offset.z,
    );
    assert!((got - offset).norm() < 0.02, "{got:?}");
    assert!((params.sensors.accel_scale - scale).norm() < 0.005);
    // Saved 1 s after the result, disarmed.
    assert!(!s.save_due(t, false));
    assert!(s.save_due(t + 1_000_000, false));
}

#[test]
fn level_trim_and_gyro_check() {
    let mut s = Setup::new();
    let mut params = P();
    assert_eq!(
        s.command(0, CMD_PREFLIGHT_CALIBRATION, [0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0], false, &params),
        Some(SetupAck::Accepted)
    );
    // Board 2° nose-up on a level vehicle.
    let tilt = 2f32.to_radians();
    let meas = Vec3::new(GRAVITY * tilt.sin(), 0.0, -GRAVITY * tilt.cos());
    let mut wrote = false;
    for k in 0..=400 {
        wrote |= s.imu(k * 5_000, &sample(meas), &mut params);
    }
    assert!(wrote);
    assert!((params.sensors.trim_pitch - tilt).abs() < 1e-3 && params.sensors.trim_roll.abs() < 1e-4);
    let t = texts(&mut s);
    assert_eq!(t.first().map(|x| x.as_str()), Some("[cal] calibration started: 2 level"));
    assert_eq!(t.last().map(|x| x.as_str()), Some("[cal] calibration done: level"));
    assert!(t.iter().any(|x| x.starts_with("[cal] progress <")));

    // Gyro: rotating fails, still passes; nothing is written either way.
    let before = params;
    s.command(0, CMD_PREFLIGHT_CALIBRATION, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], false, &params);
    s.imu(0, &ImuSample { gyro: Vec3::new(0.3, 0.0, 0.0), accel: meas }, &mut params);
    assert_eq!(texts(&mut s).last().map(|x| x.as_str()), Some("[cal] calibration failed: gyro motion"));
    s.command(0, CMD_PREFLIGHT_CALIBRATION, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], false, &params);
    for k in 0..=400 {
        s.imu(k * 5_000, &sample(meas), &mut params);
    }
    assert_eq!(texts(&mut s).last().map(|x| x.as_str()), Some("[cal] calibration done: gyro"));
    assert_eq!(params, before);
}

#[test]
fn calibration_is_refused_armed_unsupported_kinds_and_can_be_cancelled() {
    let mut s = Setup::new();
    let accel = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0];
    assert_eq!(s.command(0, CMD_PREFLIGHT_CALIBRATION, accel, true, &P()), Some(SetupAck::Denied));
    assert_eq!(texts(&mut s), ["[cal] calibration denied: vehicle armed"]);
    // Magnetometer (param2) and simple accel (param5 = 4): not here.
    assert_eq!(
        s.command(0, CMD_PREFLIGHT_CALIBRATION, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0], false, &P()),
        Some(SetupAck::Unsupported)
    );
    assert_eq!(
        s.command(0, CMD_PREFLIGHT_CALIBRATION, [0.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0], false, &P()),
        Some(SetupAck::Unsupported)
    );
    assert!(!s.calibrating());
    s.command(0, CMD_PREFLIGHT_CALIBRATION, accel, false, &P());
    assert!(s.calibrating());
    // A motor test during a calibration is refused.
    assert_eq!(
        s.command(0, CMD_DO_MOTOR_TEST, motor(1.0, 10.0, 1.0), false, &P()),
        Some(SetupAck::TemporarilyRejected)
    );
    assert_eq!(s.command(0, CMD_PREFLIGHT_CALIBRATION, [0.0; 7], false, &P()), Some(SetupAck::Accepted));
    assert!(!s.calibrating());
    assert_eq!(texts(&mut s).last().map(|x| x.as_str()), Some("[cal] calibration cancelled"));
}

#[test]
fn the_text_queue_drops_the_oldest_when_full() {
    let mut s = Setup::new();
    for _ in 0..(TEXT_QUEUE_LEN + 3) {
        s.command(0, CMD_DO_MOTOR_TEST, motor(1.0, 10.0, 1.0), true, &P());
    }
    assert_eq!(s.texts_dropped(), 3);
    assert_eq!(texts(&mut s).len(), TEXT_QUEUE_LEN);
}
