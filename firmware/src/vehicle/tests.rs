//! Host tests of [`SetupVehicle`] around a recording cascade: the IMU correction, a six-position
//! calibration through the control steps, the motor test on the motor output, storage.

use super::*;
use crate::setup::{CMD_DO_MOTOR_TEST, CMD_PREFLIGHT_CALIBRATION, CMD_PREFLIGHT_STORAGE};
use crate::storage::ram::RamFlash;
use embassy_futures::block_on;
use parapet_core::calibration::accel::Face;
use parapet_core::frame::GRAVITY;
use std::vec::Vec;

/// A cascade that records the IMU samples it gets and keeps the parameters it is given.
struct Rec {
    imu: Vec<ImuSample>,
    params: ControllerParams,
    armed: bool,
}

impl Autopilot for Rec {
    fn update_position(&mut self, _fix: &PositionFix) {}
    fn navigation_fix(&mut self, _fix: &PositionFix, _kind: FixKind, _noise: SourceNoise) {}
    fn navigation_height(&mut self, _t_us: u64, _down: f32) {}
    fn update_obstacles(&mut self, _now_us: u64, _obstacles: &[ObstaclePoint]) {}
    fn set_path(&mut self, _w: &[Vec3]) -> Result<(), PathRejected> {
        Ok(())
    }
    fn clear_path(&mut self) {}
    fn command(&mut self, _now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected> {
        if cmd == VehicleCommand::Arm {
            self.armed = true;
        }
        Ok(())
    }
    fn telemetry(&self) -> TelemetrySnapshot {
        TelemetrySnapshot::BOOT
    }
    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        params::set(&mut self.params, name, value)
    }
    fn get_param(&self, name: &str) -> Option<f32> {
        params::get(&self.params, name)
    }
}

impl ControlSteps for Rec {
    fn step_inner(&mut self, _now_us: u64, imu: &ImuSample) -> MotorCommand {
        self.imu.push(*imu);
        MotorCommand { throttle: [0.0; 4], armed: self.armed }
    }
    fn step_outer(&mut self, _now_us: u64) {}
}

fn vehicle() -> SetupVehicle<Rec> {
    let p = ControllerParams::default();
    SetupVehicle::new(Rec { imu: Vec::new(), params: p, armed: false }, p)
}

fn imu(accel: Vec3) -> ImuSample {
    ImuSample { gyro: Vec3::new(0.01, 0.0, 0.0), accel }
}

#[test]
fn board_rotation_and_calibration_parameters_correct_every_sample() {
    let mut v = vehicle();
    v.set_param("SENS_BOARD_ROT", 4.0).unwrap(); // yaw 180
    v.set_param("CAL_ACC0_ZOFF", 0.5).unwrap();
    v.step_inner(0, &imu(Vec3::new(1.0, 2.0, -9.3)));
    let got = v.inner().imu[0];
    assert!((got.accel - Vec3::new(-1.0, -2.0, -9.8)).norm() < 1e-5, "{got:?}");
    assert!((got.gyro - Vec3::new(-0.01, 0.0, 0.0)).norm() < 1e-6);
    // The cascade got the parameters too, and a save is scheduled.
    assert_eq!(v.get_param("SENS_BOARD_ROT"), Some(4.0));
    assert!(v.setup().save_due(2_000_000, false));
}

#[test]
fn six_position_calibration_through_the_control_steps() {
    let (offset, scale) = (Vec3::new(0.25, -0.3, 0.2), Vec3::new(0.99, 1.02, 1.01));
    let mut v = vehicle();
    assert_eq!(
        v.setup_command(0, CMD_PREFLIGHT_CALIBRATION, [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]),
        Some(SetupAck::Accepted)
    );
    let faces =
        [Face::Down, Face::Up, Face::Back, Face::Front, Face::Left, Face::Right].map(Face::specific_force);
    let mut t = 0;
    let mut texts = Vec::new();
    for f in faces {
        // Held 6 s per face: after a turn the stillness filter needs ~2-3 s, then 2 s of averaging.
        for _ in 0..6000 {
            v.step_inner(t, &imu(f.component_div(&scale) + offset));
            t += 1000;
            texts.extend(core::iter::from_fn(|| v.setup_text()).map(|x| (t, x)));
        }
        for k in 0..300 {
            v.step_inner(t, &imu(f + Vec3::new((k as f32 * 0.05).sin() * 5.0, 3.0, 0.0)));
            t += 1000;
            texts.extend(core::iter::from_fn(|| v.setup_text()).map(|x| (t, x)));
        }
    }
    let texts: Vec<_> = texts.into_iter().map(|(t, x)| (t / 1000, x)).collect();
    assert!(texts.iter().any(|x| x.1.as_str() == "[cal] calibration done: accel"), "{texts:?}");
    let cal = v.get_param("CAL_ACC0_XOFF").unwrap();
    assert!((cal - offset.x).abs() < 0.02, "{cal}");
    // From now on the cascade sees calibrated samples.
    v.step_inner(t, &imu(Vec3::new(0.0, 0.0, -GRAVITY).component_div(&scale) + offset));
    let last = v.inner().imu.last().copied().unwrap();
    assert!((last.accel - Vec3::new(0.0, 0.0, -GRAVITY)).norm() < 0.03, "{last:?}");
}

#[test]
fn the_motor_test_drives_the_output_and_arming_stops_it() {
    let mut v = vehicle();
    let test = [2.0, 0.0, 20.0, 3.0, 0.0, 0.0, 0.0];
    assert_eq!(v.setup_command(0, CMD_DO_MOTOR_TEST, test), Some(SetupAck::Accepted));
    let out = v.step_inner(1, &imu(Vec3::new(0.0, 0.0, -GRAVITY)));
    assert_eq!(out, MotorCommand { throttle: [0.0, 0.2, 0.0, 0.0], armed: true });
    // Any vehicle command (here the arm request) stops it at once.
    v.command(2, VehicleCommand::Arm).unwrap();
    let out = v.step_inner(3, &imu(Vec3::new(0.0, 0.0, -GRAVITY)));
    assert_eq!(out.throttle, [0.0; 4]);
    // Armed: refused.
    assert_eq!(v.setup_command(4, CMD_DO_MOTOR_TEST, test), Some(SetupAck::Denied));
    // An RC arm switch stops a test too.
    let mut v = vehicle();
    v.setup_command(0, CMD_DO_MOTOR_TEST, test);
    v.set_rc(&RcInput { arm: true, ..Default::default() });
    assert!(!v.step_inner(1, &imu(Vec3::new(0.0, 0.0, -GRAVITY))).armed);
}

#[test]
fn boot_load_storage_requests_and_the_debounced_save() {
    type F = RamFlash<8192, 4096>;
    let mut store = ParamStore::new(F::new(), 0..8192).unwrap();
    let mut v = vehicle();
    assert_eq!(block_on(v.boot_load(&mut store)), Loaded::Empty);
    v.step_inner(10, &imu(Vec3::new(0.0, 0.0, -GRAVITY)));
    v.set_param("CBF_MU", 2.0).unwrap();
    // Not yet (debounce), not while armed, then saved.
    assert!(!block_on(v.storage_step(500_000, &mut store)), "no flash use before the debounce");
    let mut p = ControllerParams::default();
    assert_eq!(block_on(store.load(&mut p)), Loaded::Empty);
    assert!(block_on(v.storage_step(1_100_000, &mut store)));
    assert!(!block_on(v.storage_step(1_200_000, &mut store)), "saved once");
    assert_eq!(block_on(store.load(&mut p)), Loaded::Stored);
    assert_eq!(params::get(&p, "CBF_MU"), Some(2.0));
    // A fresh boot loads it into the cascade.
    let mut w = vehicle();
    assert_eq!(block_on(w.boot_load(&mut store)), Loaded::Stored);
    assert_eq!(w.get_param("CBF_MU"), Some(2.0));
    assert_eq!(w.inner().params.cbf.mu, 2.0);
    // PREFLIGHT_STORAGE reset: defaults in the cascade and an empty store.
    assert_eq!(
        w.setup_command(0, CMD_PREFLIGHT_STORAGE, [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        Some(SetupAck::Accepted)
    );
    assert!(block_on(w.storage_step(0, &mut store)));
    assert_eq!(w.get_param("CBF_MU"), Some(ControllerParams::default().cbf.mu));
    assert_eq!(block_on(store.load(&mut p)), Loaded::Empty);
}
