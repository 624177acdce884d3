//! The in-flight speed governor (issue 36, `parapet_core::governor`, `GOV_ENABLE` 1):
//! * with exact sensing (`truth`, 3 m range) a 40 m open leg at a cruise of 8 m/s is flown at
//!   the braking-limited ceiling `v* = √((aτ)² + 2a(R − r − m)) − aτ`, at least 85 % of it and
//!   not above it (the governor, not the trajectory, sets the speed; without it the leg is flown
//!   at the cruise), and `summary.json`'s `speed_limited_by` names the range as the cause;
//! * a pilot at full forward stick in Position mode with `PA_SPEED_MAX` 5 m/s and the planar
//!   `lidar` stops in front of the wall without contact.
//!
//! Figures: `docs/filter.md` § Speed governor.

use std::path::PathBuf;

use parapet_core::governor::stop_speed;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{RunConfig, RunOutput};
use parapet_sim::pilot::{piloted_config, run_piloted, AssistParams, PilotMode, PilotScript};
use parapet_sim::sim::range::preset;
use parapet_sim::world::scene::Scene;

const OPEN_LEG: &str = include_str!("../data/scenes/open_leg.toml");

fn open_leg(governor: bool) -> RunOutput {
    let s = Scene::parse(OPEN_LEG, "open_leg").unwrap_or_else(|e| panic!("{e}"));
    let mut cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).unwrap();
    cfg.param_overrides.push(("GOV_ENABLE", f32::from(u8::from(governor))));
    cfg.param_overrides.push(("MIS_GUIDANCE", 1.0));
    run(&s, &cfg, &mut |_| {}).unwrap()
}

#[test]
fn an_open_leg_is_flown_at_the_braking_limited_ceiling_with_truth() {
    // Defaults: R = 3 m (the truth range), hull √0.05 m, GOV_MARGIN 0.1 m, a = CBF_BRAKE_ACC
    // 3 m/s², τ = CBF_BRAKE_DLY 0.1 s + GOV_DELAY 0.05 s (the data age, one outer period, adds
    // a few mm/s less).
    let v_star = f64::from(stop_speed(3.0 - 0.05f32.sqrt() - 0.1, 3.0, 0.15));
    let out = open_leg(true);
    let s = &out.summary;
    assert!(!s.collided && s.reached_goal, "{}", s.end_reason);
    let start = out.samples[0].pos;
    let leg: Vec<f64> = out
        .samples
        .iter()
        .filter(|k| (10.0..30.0).contains(&(k.pos - start).norm()))
        .map(|k| k.vel.xy().norm())
        .collect();
    assert!(!leg.is_empty());
    let mean = leg.iter().sum::<f64>() / leg.len() as f64;
    let max = leg.iter().copied().fold(0.0, f64::max);
    println!("v* {v_star:.3} m/s: open leg mean {mean:.3}, max {max:.3} m/s");
    assert!(mean >= 0.85 * v_star, "mean {mean:.3} m/s < 85 % of v* {v_star:.3}");
    assert!(max <= 1.05 * v_star, "max {max:.3} m/s above v* {v_star:.3}");
    assert!(s.safety_steps.governor_active > 0);
    let lim = s.safety_steps.governor_min_limit.unwrap_or(f64::NAN);
    assert!((lim - v_star).abs() < 0.05, "reported limit {lim} vs v* {v_star}");
    // summary.json says why the flight went slower than its cruise: the sensing range, most of it.
    let by = s.speed_limited_by.as_ref().expect("speed_limited_by with the governor limiting");
    println!("speed_limited_by {by:?}");
    assert_eq!(by.cause, "range", "{by:?}");
    assert!(by.fraction > 0.5 && by.cause_s > 0.9 * by.limited_s, "{by:?}");
    // Without it, the trajectory flies the cruise: the governor sets the speed above.
    let off = open_leg(false);
    assert_eq!(off.summary.speed_limited_by, None);
    let fastest = off.samples.iter().map(|k| k.vel.xy().norm()).fold(0.0, f64::max);
    assert!(fastest > 1.5 * v_star, "without the governor {fastest:.2} m/s");
}

#[test]
fn full_stick_at_a_wall_at_5_m_s_with_the_lidar_stops_without_contact() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/pilot");
    let s = Scene::load(&dir.join("wall.toml")).unwrap_or_else(|e| panic!("{e}"));
    let script = PilotScript::load(&dir.join("wall_forward.pilot.toml")).unwrap_or_else(|e| panic!("{e}"));
    let cfg = RunConfig::for_scene(&s, vec![s.start]).unwrap();
    let mut cfg = piloted_config(&s, cfg, &script);
    cfg.perception = Some(preset("lidar").unwrap());
    cfg.param_overrides.push(("GOV_ENABLE", 1.0));
    let assist = AssistParams { max_speed: Some(5.0), ..AssistParams::default() };
    let r = run_piloted(&s, &cfg, &script, PilotMode::Position, assist, &mut |_| {}).unwrap();
    let su = &r.out.summary;
    println!(
        "min clearance {:.3} m, governor {:.2} s",
        su.min_clearance_m, su.safety_steps.governor_limited_s
    );
    assert!(!su.collided && su.min_clearance_m > 0.05, "{}", su.min_clearance_m);
    assert!(su.safety_steps.governor_active > 0);
}
