//! Issue 10 scene experiments: a person (vertical cylinder r 0.25 m, h 1.8 m) walking
//! along the vehicle's path, head-on, at 0.2, 0.3 and 0.5 m/s with lateral offsets
//! 0 … 0.4 m (15 cases), flown on the 6-DOF simulator with the real flight controller.
//!
//! The cases are built from the template `scenes/person_headon.toml` by replacing its
//! person's `base` (offset) and `velocity` (speed) lines and parsing the text, so a case
//! is reproduced on the command line with the same two edits (see `docs/results.md`).
//!
//! **Noise.** The default sensor model is on (IMU noise and bias, 5 mm / 0.02 m/s fix
//! noise, 10 ms fix latency): the claims must hold with the estimator in the loop, not
//! only for perfect state. The person's velocity is reported exactly (the simulator's
//! default, `obstacle_velocity_noise = 0`, a tracker that knows the walking velocity);
//! a separate test repeats the cases with 0.1 m/s white noise on it (half the slowest
//! walking speed), where only safety is asserted (see that test for why).
//!
//! **ε = 2·10⁻³ m²** as in the double-integrator properties: the relative barrier
//! `h̄ = |d|² + μ dᵀ(ṗ − v̄) − δ` on the true state must stay ≥ −ε (measured ≥ 0.19 m²
//! with these parameters: the experiment-B δ1 = 0.4 engages early).

use std::path::PathBuf;

use nalgebra::Vector3;
use parapet_core::cbf::{FilterVariant, SafetyFilter};
use parapet_core::obstacle::ObstaclePoint;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{sense_obstacles, RunConfig, RunOutput};
use parapet_sim::sim::sensors::{SensorParams, Sensors};
use parapet_sim::world::scene::{to_f32, Scene};

const SPEEDS: [f64; 3] = [0.2, 0.3, 0.5];
const OFFSETS: [f64; 5] = [0.0, 0.1, 0.2, 0.3, 0.4];
const EPS: f64 = 2e-3;
const TEMPLATE_BASE: &str = "base = [12.0, 5.1, 0.0]";
const TEMPLATE_VELOCITY: &str = "velocity = [-0.3, 0.0, 0.0]";

/// The template with the person walking west at `speed` (m/s), its axis `offset` (m) north of the path.
fn person_scene(speed: f64, offset: f64) -> Scene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/person_headon.toml");
    let src = std::fs::read_to_string(&p).unwrap();
    assert!(src.contains(TEMPLATE_BASE) && src.contains(TEMPLATE_VELOCITY), "template changed");
    let src = src
        .replace(TEMPLATE_BASE, &format!("base = [12.0, {:.1}, 0.0]", 5.0 + offset))
        .replace(TEMPLATE_VELOCITY, &format!("velocity = [{:.1}, 0.0, 0.0]", -speed));
    Scene::parse(&src, &p.display().to_string()).unwrap_or_else(|e| panic!("{e}"))
}

/// The filter law alone, as issue 10 measured it: the speed governor (`GOV_ENABLE`, on by
/// default since stop 51) is off, because it limits the approach to the walking person by
/// its relative velocity and so also stops the `paper` variant's head-on collisions that
/// these cases exist to show (`paper_variant_is_walked_into_head_on`).
fn config(s: &Scene, variant: FilterVariant, seed: u64) -> RunConfig {
    let mut cfg = RunConfig::for_scene(s, vec![s.start, s.goal]).unwrap();
    cfg.variant = variant;
    cfg.seed = seed;
    cfg.param_overrides.push(("GOV_ENABLE", 0.0));
    cfg
}

/// Min over the flight (outer-loop samples, true state) of the relative-velocity
/// barrier h̄ (m²) against the person, whatever variant flew.
fn min_rel_h_bar(s: &Scene, cfg: &RunConfig, out: &RunOutput) -> f64 {
    let f = SafetyFilter::new(cfg.cbf_params().unwrap(), FilterVariant::Relative).unwrap();
    let delta = f.params.delta as f64;
    let mut m = f64::INFINITY;
    for k in &out.samples {
        for (i, o) in s.obstacles.iter().enumerate() {
            let (shape, v) = o.at(k.t);
            let p = to_f32(&k.pos);
            let (q, _) = shape.closest_point(&p);
            let op = ObstaclePoint { point: q, velocity: Some(to_f32(&v)), id: i as u16, normal: None };
            let h = f.barrier(&p, &to_f32(&k.vel), &op).map_or(-delta, |b| b.h as f64 - delta);
            m = m.min(h);
        }
    }
    m
}

struct Case {
    speed: f64,
    offset: f64,
    out: RunOutput,
    rel_h_bar: f64,
}

fn fly_case(
    speed: f64,
    offset: f64,
    variant: FilterVariant,
    seed: u64,
    obstacle_velocity_noise: f64,
) -> Case {
    let s = person_scene(speed, offset);
    let mut cfg = config(&s, variant, seed);
    cfg.sensors.obstacle_velocity_noise = obstacle_velocity_noise;
    let out = run(&s, &cfg, &mut |_| {}).unwrap();
    let rel_h_bar = min_rel_h_bar(&s, &cfg, &out);
    Case { speed, offset, out, rel_h_bar }
}

fn all_cases(variant: FilterVariant, seed: u64, obstacle_velocity_noise: f64) -> Vec<Case> {
    let mut v = Vec::new();
    for &sp in &SPEEDS {
        for &off in &OFFSETS {
            v.push(fly_case(sp, off, variant, seed, obstacle_velocity_noise));
        }
    }
    v
}

/// Check the relative-velocity claims on one flight; `Err` names what failed.
fn check_relative(c: &Case) -> Result<(), String> {
    let su = &c.out.summary;
    let tag = format!("person {} m/s, offset {} m, seed {}", c.speed, c.offset, su.seed);
    if su.collided {
        return Err(format!("{tag}: collided at {:?} s", su.first_collision_time_s));
    }
    if c.rel_h_bar < -EPS {
        return Err(format!("{tag}: min relative h̄ {} < −ε", c.rel_h_bar));
    }
    if c.offset >= 0.1 && !su.reached_goal {
        return Err(format!(
            "{tag}: goal not reached ({}, {:.2} m left)",
            su.end_reason, su.final_distance_to_goal_m
        ));
    }
    // The person's closing speed is at most 0.5 + ~0.35 m/s, so the constraint asks for
    // at most (2/μ)·0.85 ≈ 1.9 m/s² along the normal, well within u_max = 6 m/s².
    if c.out.samples.iter().any(|k| k.filter.unavoidable) {
        return Err(format!("{tag}: the filter flagged `unavoidable`"));
    }
    if su.filter_active_fraction <= 0.0 {
        return Err(format!("{tag}: the filter never acted (the case tests nothing)"));
    }
    Ok(())
}

#[test]
fn relative_variants_never_collide_and_pass_the_person_when_offset() {
    let mut failures = Vec::new();
    for variant in [FilterVariant::Relative, FilterVariant::MultiRelative] {
        for seed in 0..3 {
            for c in all_cases(variant, seed, 0.0) {
                if let Err(e) = check_relative(&c) {
                    failures.push(format!("{}: {e}", variant.as_str()));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// With 0.1 m/s white noise on the reported person velocity: still no collision and
/// h̄ ≥ −ε. The goal is not asserted: with the paper's soft k_p = 0.32, the
/// accelerometer bias of a seed leaves a steady offset b/k_p of up to ~0.13 m, and the
/// simulator's goal test (within 0.1 m) then depends on the approach transient
/// (measured: 4 of 90 flights hover 0.13 m from the goal, all seed 0, unrelated to the person).
#[test]
fn obstacle_velocity_noise_keeps_the_relative_filters_safe() {
    let mut failures = Vec::new();
    for variant in [FilterVariant::Relative, FilterVariant::MultiRelative] {
        for seed in 0..2 {
            for c in all_cases(variant, seed, 0.1) {
                if c.out.summary.collided || c.rel_h_bar < -EPS {
                    failures.push(format!(
                        "{} {} m/s offset {} seed {seed}: collided {} min h̄ {}",
                        variant.as_str(),
                        c.speed,
                        c.offset,
                        c.out.summary.collided,
                        c.rel_h_bar
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The paper's law uses the vehicle's own velocity: against the person it can only
/// brake, so head-on the person walks into the (nearly) stopped vehicle. Prints the
/// issue-10 table of `docs/results.md` (seed 0, `--nocapture`).
#[test]
fn paper_variant_is_walked_into_head_on() {
    println!("| person speed (m/s) | offset (m) | variant | collided | min clearance (m) | min h̄ (m²) | reached goal | time to goal (s) |");
    println!("|---|---|---|---|---|---|---|---|");
    let paper = all_cases(FilterVariant::Paper, 0, 0.0);
    let relative = all_cases(FilterVariant::Relative, 0, 0.0);
    for (p, r) in paper.iter().zip(&relative) {
        for (name, c) in [("paper", p), ("relative", r)] {
            let su = &c.out.summary;
            println!(
                "| {:.1} | {:.1} | {name} | {} | {:.3} | {:.3} | {} | {} |",
                c.speed,
                c.offset,
                match su.first_collision_time_s {
                    Some(t) => format!("yes ({t:.1} s)"),
                    None => "no".into(),
                },
                su.min_clearance_m,
                c.rel_h_bar,
                if su.reached_goal { "yes" } else { "no" },
                su.time_to_goal_s.map_or("—".into(), |t| format!("{t:.1}")),
            );
        }
    }
    let mut n_collided = 0;
    for c in &paper {
        let su = &c.out.summary;
        if su.collided {
            n_collided += 1;
            // The relative barrier saw the danger that the paper's own barrier did not.
            assert!(
                c.rel_h_bar < 0.0,
                "{} m/s offset {}: collided with relative h̄ {}",
                c.speed,
                c.offset,
                c.rel_h_bar
            );
            // Hit while braking/stopped: the vehicle never backs away faster than a crawl.
            let last = c.out.samples.last().unwrap();
            let closing_from_vehicle = last.vel.y; // NED y = east, the direction of flight
            assert!(
                closing_from_vehicle > -0.1,
                "{} m/s offset {}: the vehicle was retreating at {:.2} m/s",
                c.speed,
                c.offset,
                -closing_from_vehicle
            );
        }
        if c.offset == 0.0 {
            assert!(su.collided, "paper, {} m/s head-on at offset 0 did not collide: {su:?}", c.speed);
        }
    }
    assert!(n_collided >= 5, "paper collided in only {n_collided} of 15 cases");
}

/// The simulator reports the person's true velocity (NED) with its closest surface
/// point; `obstacle_velocity_noise` adds white noise of the stated size, and only then.
#[test]
fn simulator_reports_the_true_obstacle_velocity() {
    let s = person_scene(0.5, 0.2);
    let t = 10.0;
    let (shape, v_true) = s.obstacles[0].at(t);
    assert_eq!(v_true, Vector3::new(0.0, -0.5, 0.0)); // ENU west 0.5 m/s = NED −y
    let p = s.start + Vector3::new(0.0, 3.0, 0.0);
    let mut exact = Sensors::new(SensorParams::default(), 3);
    let seen = sense_obstacles(&s, t, &p, 5.0, &mut exact);
    assert_eq!(seen.len(), 1);
    assert_eq!(seen[0].velocity, Some(to_f32(&v_true)));
    assert_eq!(seen[0].point, shape.closest_point(&to_f32(&p)).0);

    let sigma = 0.1;
    let mut noisy =
        Sensors::new(SensorParams { obstacle_velocity_noise: sigma, ..SensorParams::default() }, 3);
    let n = 4000;
    let (mut sum, mut sq) = (Vector3::<f64>::zeros(), Vector3::<f64>::zeros());
    for _ in 0..n {
        let w = sense_obstacles(&s, t, &p, 5.0, &mut noisy)[0].velocity.unwrap();
        let e = Vector3::new(w.x as f64, w.y as f64, w.z as f64) - v_true;
        sum += e;
        sq += e.component_mul(&e);
    }
    for i in 0..3 {
        let mean = sum[i] / n as f64;
        let std = (sq[i] / n as f64 - mean * mean).sqrt();
        assert!(mean.abs() < 0.01, "axis {i}: mean error {mean}");
        assert!((std - sigma).abs() < 0.1 * sigma, "axis {i}: std {std}");
    }
    let mut off =
        Sensors::new(SensorParams { noise: false, obstacle_velocity_noise: sigma, ..Default::default() }, 3);
    assert_eq!(sense_obstacles(&s, t, &p, 5.0, &mut off)[0].velocity, Some(to_f32(&v_true)));
}

/// Where the guarantee ends (issue 10: "an obstacle approaching faster than the vehicle
/// can retreat cannot be avoided"). The constraint asks for c = (2/μ)·(closing speed)
/// along the normal; above u_max = 6 m/s², i.e. closing faster than μ·u_max/2 = 2.7 m/s at
/// μ = 0.9, the filter raises `unavoidable`. Measured, head-on at offset 0 (relative):
/// 2.0 m/s → no flag, min h̄ +0.025 m²; 2.5 m/s → flag, h̄ −0.17 m² but no contact (the
/// flag is a sufficient condition: the vehicle still backs off and sidesteps); from
/// ≈ 3.5 m/s the obstacle is first sensed (3 m range) with h̄ already < 0; 6 m/s → flag
/// from 1.28 s, collision at 1.80 s.
#[test]
fn unavoidable_flag_marks_where_the_guarantee_ends() {
    let ok = fly_case(2.0, 0.0, FilterVariant::Relative, 0, 0.0);
    assert!(!ok.out.summary.collided && ok.rel_h_bar >= -EPS, "2 m/s: {:?}", ok.out.summary);
    assert!(ok.out.samples.iter().all(|k| !k.filter.unavoidable), "2 m/s is within u_max");

    let fast = fly_case(6.0, 0.0, FilterVariant::Relative, 0, 0.0);
    let su = &fast.out.summary;
    assert!(su.collided, "6 m/s head-on: expected the collision the flag predicts: {su:?}");
    let flagged = fast.out.samples.iter().find(|k| k.filter.unavoidable).map(|k| k.t);
    let hit = su.first_collision_time_s.unwrap_or(0.0);
    assert!(flagged.is_some_and(|t| t < hit - 0.1), "flag at {flagged:?}, collision at {hit} s");
}
