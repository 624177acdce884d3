//! Flights with a filtered position source (issue 39): the navigation filter bridges a 1 s
//! fix dropout, a 5 s one triggers the failsafe (`host-sim/src/fc/nav.rs`), and the small
//! CI subset of `outdoor_static` with `gps` and the lidar does not collide (1 m/s, and 3 m/s on
//! the trajectory guidance)
//! (`docs/navigation.md` has the full table); two flights of the navigation campaign that
//! collided without a flag before the mapped obstacles' margin bounded the unobserved drifts
//! (`docs/filter.md` § 18) do not collide.

use std::path::PathBuf;

use nalgebra::Vector3;
use parapet_core::controller::GuidanceMode;
use parapet_core::outer::guidance::MissionGuidance;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{default_duration, default_yaw_mode, RunConfig, RunOutput};
use parapet_sim::plan::pathfile::PathFile;
use parapet_sim::sim::source::PositionSource;
use parapet_sim::world::scene::Scene;

fn scene(name: &str) -> Scene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name);
    Scene::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

fn config(s: &Scene, path: Vec<Vector3<f64>>, source: PositionSource, speed: f64, seed: u64) -> RunConfig {
    let mut cfg = RunConfig::for_scene(s, path).unwrap();
    cfg.sensors.position_source = source;
    cfg.sensors.apply_source_preset(&[]);
    cfg.params.speed = speed;
    cfg.seed = seed;
    cfg.duration = default_duration(s, &cfg.path, speed);
    cfg
}

/// `one_sphere` straight through the sphere at 3 m/s with `gps`, fixes dropped from 2 s for
/// `length` s.
fn sphere_with_dropout(length: f64) -> RunOutput {
    let s = scene("one_sphere.toml");
    let mut cfg = config(&s, vec![s.start, s.goal], PositionSource::Gps, 3.0, 0);
    cfg.sensors.dropout_start = 2.0;
    cfg.sensors.dropout_length = length;
    run(&s, &cfg, &mut |_| {}).unwrap()
}

/// `true` when some outer step flew the brake or the landing.
fn braked(out: &RunOutput) -> bool {
    out.samples.iter().any(|s| matches!(s.mode, GuidanceMode::Brake | GuidanceMode::Land))
}

/// `true` when some outer step flew a failsafe of the position loss: the brake, the landing,
/// or the descent without a position (`NoFix`, MAVLink's DESCEND), which a vehicle that has
/// drifted low during the dead reckoning may end on the ground before it lands.
fn failsafe(out: &RunOutput) -> bool {
    braked(out) || out.samples.iter().any(|s| s.mode == GuidanceMode::NoFix)
}

#[test]
fn a_one_second_fix_dropout_at_3_mps_is_bridged_without_a_brake() {
    let out = sphere_with_dropout(1.0);
    let sum = &out.summary;
    assert!(!sum.collided, "{sum:?}");
    assert!(sum.reached_goal, "{sum:?}");
    assert!(!braked(&out), "the dropout was not bridged: {sum:?}");
}

#[test]
fn a_five_second_fix_dropout_triggers_the_failsafe() {
    let out = sphere_with_dropout(5.0);
    assert!(failsafe(&out), "{:?}", out.summary);
    assert!(!out.summary.reached_goal, "{:?}", out.summary);
}

/// `outdoor_static` on its committed path with `gps` and the 72-beam lidar at `speed`.
fn outdoor_static_gps_lidar(speed: f64, seed: u64) -> RunConfig {
    let s = scene("outdoor_static.toml");
    let file = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/outdoor_static_path.json");
    let path = PathFile::read(&file).unwrap_or_else(|e| panic!("{e}"));
    let wps: Vec<Vector3<f64>> =
        path.waypoints.iter().map(|w| Vector3::new(w[1] as f64, w[0] as f64, -(w[2] as f64))).collect();
    let mut cfg = config(&s, wps, PositionSource::Gps, speed, seed);
    cfg.perception = parapet_sim::sim::range::preset("lidar");
    cfg.yaw_mode = default_yaw_mode(cfg.perception.as_deref());
    cfg
}

#[test]
fn outdoor_static_with_gps_and_the_lidar_does_not_collide() {
    let s = scene("outdoor_static.toml");
    let sum = run(&s, &outdoor_static_gps_lidar(1.0, 0), &mut |_| {}).unwrap().summary;
    assert!(!sum.collided, "{sum:?}");
}

/// At speed with the trajectory guidance (`MIS_GUIDANCE 1`, named: it passes under either
/// default): `gps` + lidar at 3 m/s, seed 0, does not collide and keeps the hull clear
/// (measured 0.138 m; the paper's guidance collides on this flight at 10.7 s, so the test
/// fails with `MissionGuidance::Paper`: checked). `docs/navigation.md` § No collision at speed.
#[test]
fn outdoor_static_with_gps_and_the_lidar_at_3_mps_on_the_trajectory_does_not_collide() {
    let s = scene("outdoor_static.toml");
    let mut cfg = outdoor_static_gps_lidar(3.0, 0);
    cfg.guidance = MissionGuidance::Trajectory;
    let sum = run(&s, &cfg, &mut |_| {}).unwrap().summary;
    assert!(!sum.collided, "{sum:?}");
    assert!(sum.min_clearance_m > 0.05, "{sum:?}");
}

/// Flight `i` of `scenes/campaigns/NAME`, flown as the campaign flies it.
fn campaign_flight(name: &str, i: u64) -> parapet_sim::report::Summary {
    let file = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/campaigns").join(name);
    let c = parapet_sim::campaign::spec::Campaign::load(&file).unwrap_or_else(|e| panic!("{e}"));
    let (s, cfg) = parapet_sim::campaign::flight_config(&c, i).unwrap_or_else(|(_, e)| panic!("{e}"));
    run(&s, &cfg, &mut |_| {}).unwrap().summary
}

/// `vio` in the office: the odometry's drift reached 0.37 m (4.3 σ of its random walk at
/// 8 s) towards the coat stand while the vehicle was pressed against the margin of 3σ
/// (0.26 m); it collided at 8.3 s, unflagged. The margin now holds the drift's bound over the
/// whole flight (`parapet_core::nav::bound::drift_bound`).
#[test]
fn the_vio_office_flight_6580_of_the_navigation_campaign_does_not_collide() {
    let sum = campaign_flight("navigation.toml", 6580);
    assert!(!sum.collided, "{sum:?}");
}

/// `gps` on `outdoor_static`: the height followed the barometer, whose drift the filter does
/// not model, 0.40 m off (σ_z 0.06 m): the shed's wall point level with the vehicle appeared
/// diagonally above the estimate, farther than it was, and the margin of 3σ_h (0.31 m) did not
/// cover an error along that direction of 0.44 m; it collided at 57.9 s, unflagged. The margin
/// now takes the vertical σ and the barometer's drift on the vertical.
#[test]
fn the_gps_outdoor_static_flight_9201_of_the_navigation_campaign_does_not_collide() {
    let sum = campaign_flight("navigation.toml", 9201);
    assert!(!sum.collided, "{sum:?}");
}

/// `gps` on `one_sphere` (flight 150 of `navigation_gps_vio.toml`): the ground barrier took the
/// estimate's height as the truth; the height followed the barometer's drift and the vehicle,
/// held below the sphere's widened margin, touched the ground at 20.4 s, unflagged. The ground
/// and ceiling now keep the vertical error bound (`FlightController::set_boundary_margin`).
#[test]
fn the_gps_one_sphere_flight_150_does_not_touch_the_ground() {
    let sum = campaign_flight("navigation_gps_vio.toml", 150);
    assert!(!sum.collided, "{sum:?}");
}

/// The drift bound holds over the whole flight where the random walk's 3σ at each time does
/// not: 400 3-D walks of the `vio` preset's 0.03 m/√s at its 30 Hz over 60 s. Along one axis,
/// 3σ(s) is exceeded at some s ≥ 1 s by about 5 % of the walks (the mechanism of the `vio`
/// collisions: numpy, 1,000 walks: 5.3 %), while the walk's norm never leaves
/// `drift_bound(0.03, s, 3)` (probability ≤ 10⁻⁴ per flight).
#[test]
fn the_drift_bound_holds_over_the_flight_where_three_sigma_at_each_time_does_not() {
    use parapet_core::nav::bound::drift_bound;
    let (rate, dt, n): (f64, f64, u32) = (0.03, 1.0 / 30.0, 1800);
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let (mut beyond_3sigma, mut beyond_bound) = (0, 0);
    for _ in 0..400 {
        let (mut w, mut out3, mut outb) = ([0.0f64; 3], false, false);
        for k in 1..=n {
            for x in w.iter_mut() {
                // Box–Muller.
                let (u1, u2) = (uniform(), uniform());
                *x += rate * dt.sqrt() * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            }
            let s = f64::from(k) * dt;
            out3 |= s >= 1.0 && w[0].abs() > 3.0 * rate * s.sqrt();
            outb |= (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt() > drift_bound(rate, s, 3.0);
        }
        beyond_3sigma += usize::from(out3);
        beyond_bound += usize::from(outb);
    }
    assert!(beyond_3sigma >= 8, "3 sigma(s) exceeded by {beyond_3sigma} of 400 walks");
    assert_eq!(beyond_bound, 0, "the bound exceeded by {beyond_bound} of 400 walks");
}
