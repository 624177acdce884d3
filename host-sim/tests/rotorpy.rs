//! The plant's aerodynamics against RotorPy 3.0's `Multirotor`: the Crazyflie
//! vehicle (`tests/data/rotorpy/crazyflie.toml`), aerodynamics on (rotor drag
//! k_d, k_z with its moments, quadratic parasitic drag), a steady wind, 3 s of
//! rotor-speed commands through the motor lag (`inputs.csv`). The reference
//! (`reference.csv`) was recorded with `tests/data/rotorpy/make_reference.py`.

use std::path::PathBuf;

use nalgebra::Vector3;
use parapet_sim::cli::load_vehicle;
use parapet_sim::sim::replay::{parse_rotor_csv, replay, ReplayOptions};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/rotorpy").join(name)
}

fn rows(csv: &str) -> Vec<Vec<f64>> {
    csv.lines()
        .skip(1)
        .filter(|l| !l.is_empty())
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// Max position error (m) and max attitude error (rad, quaternion angle) of the replay.
fn deviation(states: &str, reference: &[Vec<f64>]) -> (f64, f64) {
    let ours = rows(states);
    assert_eq!(ours.len(), reference.len());
    let (mut dp, mut da) = (0.0f64, 0.0f64);
    for (a, b) in ours.iter().zip(reference) {
        assert!((a[0] - b[0]).abs() < 1e-9, "row times {} vs {}", a[0], b[0]);
        let d = Vector3::new(a[1] - b[1], a[2] - b[2], a[3] - b[3]).norm();
        let dot: f64 = (7..11).map(|k| a[k] * b[k]).sum();
        dp = dp.max(d);
        da = da.max(2.0 * dot.abs().min(1.0).acos());
    }
    (dp, da)
}

#[test]
fn replay_with_aerodynamics_agrees_with_rotorpy_within_1_cm() {
    let vehicle = load_vehicle(&data("crazyflie.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert!(vehicle.has_aero());
    let inputs = parse_rotor_csv(&std::fs::read_to_string(data("inputs.csv")).unwrap()).unwrap();
    let reference = rows(&std::fs::read_to_string(data("reference.csv")).unwrap());
    // RotorPy's wind (1, 0.5, -0.2) in its z-up world is (1, -0.5, 0.2) here.
    let opts =
        ReplayOptions { motor_lag: true, wind_ned: Vector3::new(1.0, -0.5, 0.2), ..ReplayOptions::default() };
    let states = replay(vehicle.clone(), &inputs, &opts).unwrap();
    let (dp, da) = deviation(&states, &reference);
    eprintln!("aero on: max position error {dp:.3e} m, attitude {da:.3e} rad");
    assert!(dp < 0.01, "position error {dp} m");
    assert!(da < 0.01, "attitude error {da} rad");
    // The check has teeth: without the aerodynamic terms (or the wind) the same
    // inputs end far from RotorPy.
    let plain = parapet_sim::sim::plant::VehicleParams {
        rotor_drag_kd: 0.0,
        rotor_drag_kz: 0.0,
        parasitic_drag: [0.0; 3],
        ..vehicle.clone()
    };
    let (dp_off, _) = deviation(&replay(plain, &inputs, &opts).unwrap(), &reference);
    let still = ReplayOptions { wind_ned: Vector3::zeros(), ..opts };
    let (dp_still, _) = deviation(&replay(vehicle, &inputs, &still).unwrap(), &reference);
    eprintln!("aero off: {dp_off:.3} m; no wind: {dp_still:.3} m");
    assert!(dp_off > 0.1 && dp_still > 0.1, "{dp_off} {dp_still}");
}
