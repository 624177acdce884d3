//! Issue 21, the simulated pilot on the 6-DOF plant with the real flight controller
//! (`parapet_sim::pilot`, scripts in `scenes/pilot/`), default filter (`multi-relative`),
//! sensor noise as the scene sets it (on by default), seed 0 unless a row says otherwise:
//!
//! * full stick at a wall, commanded 0.5, 1, 2, 3 m/s: no contact, the vehicle stops in
//!   front of the wall (having flown most of the way to it);
//! * full forward + half right stick: no contact, and the vehicle slides along the wall
//!   (tangential progress measured while the filter holds it off the wall);
//! * diagonal full stick into a box corner: no contact, stops in the corner;
//! * half stick at a person walking towards the vehicle at 0.3 m/s: no contact;
//! * the goal-seeking pilot through a slalom of pillars: no contact;
//! * full stick at 5 m/s at a sphere hanging above the flight level, with the 3D lidar and the
//!   ToF set (issue 36): no contact;
//! * RC loss: the vehicle stops flying at the wall (hold), then lands; kill switch: motors
//!   off within one inner step of the frame carrying it;
//! * position loss (scripted `fix_loss`): the failsafe takes over within the position timeout
//!   (NoFix guidance, flight mode Land) and the vehicle comes down without wall contact
//!   (measured: it drifts 1.2 m open-loop before touching down, 4.5 s after the loss);
//! * low battery (a 300 mAh pack at 12 %): Position → Return (measured at 11.3 s, flies back
//!   from the wall, N 3.71 → 2.18 m) → Land when the pack goes critical (14.4 s).
//!
//! Longer matrices (`#[ignore]`; wall: speeds 0.25–4 m/s × stick angles 0–80° × seeds 0–2 ×
//! calm / 3 m/s wind + 0.5 m/s turbulence, 210 flights; person: 0.2–0.6 m/s × offset 0–0.3 m ×
//! stick 0.25–1 × seeds 0–2, 108 flights; no contact in either on 6326b28):
//! `cargo test -p parapet-tests --release --test pilot_flights -- --ignored --nocapture`.

use std::path::PathBuf;

use parapet_sim::flight::runner::RunConfig;
use parapet_sim::pilot::{piloted_config, run_piloted, AssistParams, PilotMode, PilotRun, PilotScript};
use parapet_sim::world::scene::Scene;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/pilot")
}

fn scene(name: &str) -> Scene {
    Scene::load(&dir().join(format!("{name}.toml"))).unwrap_or_else(|e| panic!("{e}"))
}

fn script_file(name: &str) -> PilotScript {
    PilotScript::load(&dir().join(name)).unwrap_or_else(|e| panic!("{e}"))
}

fn script_text(text: &str) -> PilotScript {
    PilotScript::parse(text, "test script", "test").unwrap_or_else(|e| panic!("{e}"))
}

/// Fly `script` over `scene` in `mode` with `assist`, `edit` applied to the run settings.
fn fly(
    scene: &Scene,
    script: &PilotScript,
    mode: PilotMode,
    assist: AssistParams,
    edit: impl FnOnce(&mut RunConfig),
) -> PilotRun {
    let cfg = RunConfig::for_scene(scene, vec![scene.start]).unwrap_or_else(|e| panic!("{e}"));
    let mut cfg = piloted_config(scene, cfg, script);
    edit(&mut cfg);
    run_piloted(scene, &cfg, script, mode, assist, &mut |_| {}).unwrap_or_else(|e| panic!("{e:#}"))
}

fn assist(max_speed: f32) -> AssistParams {
    AssistParams { max_speed: Some(max_speed), ..AssistParams::default() }
}

/// The wall's near face, NED north (x), m, and the hull radius.
const WALL_X: f64 = 4.0;

fn row(label: &str, r: &PilotRun) {
    let s = &r.out.summary;
    let last = r.out.samples.last().map(|x| (x.pos, x.vel));
    let (p, v) = last.unwrap_or_default();
    println!(
        "{label:<34} collided {:<5} min clearance {:>6.3} m  end N {:>6.3} E {:>6.3} m  v {:>5.2} {:>5.2} m/s  filter {:>5.1} %  state {}",
        s.collided,
        s.min_clearance_m,
        p.x,
        p.y,
        v.x,
        v.y,
        100.0 * s.filter_active_fraction,
        s.final_controller_state
    );
}

/// Full stick at the wall at `speed`: the flight's result and the assertions.
/// `wind`: (speed m/s, from degrees, turbulence σ m/s).
fn wall_at(speed: f32, angle_deg: f64, seed: u64, wind: Option<(f64, f64, f64)>) -> PilotRun {
    let s = scene("wall");
    let (sn, cs) = angle_deg.to_radians().sin_cos();
    // The stick at `angle` from straight ahead, the larger axis at full deflection.
    let k = 1.0 / cs.abs().max(sn.abs());
    let script =
        script_text(&format!("duration = 10.0\n[[stick]]\nt = 0\npitch = {}\nroll = {}\n", cs * k, sn * k));
    let r = fly(&s, &script, PilotMode::Position, assist(speed), |c| {
        c.seed = seed;
        if let Some((v, from, sigma)) = wind {
            c.disturbances.wind.speed = v;
            c.disturbances.wind.direction_deg = from;
            c.disturbances.wind.sigma = Some(sigma);
        }
    });
    row(
        &format!("wall {speed} m/s {angle_deg}° seed {seed}{}", if wind.is_some() { " wind" } else { "" }),
        &r,
    );
    r
}

#[test]
fn full_stick_at_a_wall_stops_without_contact() {
    for speed in [0.5, 1.0, 2.0, 3.0] {
        let r = wall_at(speed, 0.0, 0, None);
        let s = &r.out.summary;
        assert!(!s.collided, "{speed} m/s: collided at {:?}", s.first_collision_time_s);
        assert!(s.min_clearance_m > 0.0, "{speed} m/s: clearance {}", s.min_clearance_m);
        let end = r.out.samples.last().expect("samples");
        // It flew up to the wall (not a trivial hover) and stopped there.
        assert!(end.pos.x > WALL_X - 1.2, "{speed} m/s: stopped {:.2} m short", WALL_X - end.pos.x);
        assert!(end.vel.x.abs() < 0.1, "{speed} m/s: still moving at {:.2} m/s", end.vel.x);
        assert!(r.log.iter().any(|l| l.filter_active), "{speed} m/s: the filter never intervened");
    }
}

/// Issue 36: full stick at 5 m/s (`PA_SPEED_MAX` 5) at a sphere hanging across the way, its
/// lowest point 0.1 m above the flight level (`scenes/pilot/hanging_sphere.toml`), seen through
/// the obstacle memory by the 3D lidar and by the ToF set (whose ring looks ±22.5° up and down
/// and whose up sensor looks straight up): no contact while the filter takes the vehicle past it
/// (it came within 0.5 m of the surface: the sphere was in the way). The planar lidar cannot see it (above its plane): the coverage check refuses that
/// set here unless `no-overhangs` is assumed, and with the (false) assumption it meets the
/// sphere (docs/filter.md § 17).
#[test]
fn full_stick_at_a_hanging_sphere_passes_without_contact_with_3d_sensing() {
    let s = scene("hanging_sphere");
    let script = script_file("wall_forward.pilot.toml");
    for p in ["lidar3d", "tof"] {
        let r = fly(&s, &script, PilotMode::Position, assist(5.0), |c| {
            c.perception = Some(parapet_sim::sim::range::preset(p).expect("preset"));
        });
        row(&format!("hanging sphere 5 m/s {p}"), &r);
        let sum = &r.out.summary;
        assert!(!sum.collided, "{p}: collided at {:?}", sum.first_collision_time_s);
        assert!(sum.min_clearance_m > 0.0 && sum.min_clearance_m < 0.5, "{p}: {}", sum.min_clearance_m);
        let end = r.out.samples.last().expect("samples");
        // The sphere's centre is 4 m north (NED x): the vehicle is past it.
        assert!(end.pos.x > 4.0, "{p}: ended at N {:.2} m", end.pos.x);
    }
}

/// East (NED y) progress while the vehicle is held off the wall: from the first sample
/// within 0.6 m of the wall face (centre) to the last one before the wall's end; and the
/// time between them.
fn slide_progress(r: &PilotRun) -> (f64, f64) {
    // Up to 0.5 m before the wall's east end (E 6 m), where it could fly around it.
    let at_wall: Vec<_> = r.out.samples.iter().filter(|x| x.pos.x > WALL_X - 0.6 && x.pos.y < 5.5).collect();
    match (at_wall.first(), at_wall.last()) {
        (Some(a), Some(b)) => (b.pos.y - a.pos.y, b.t - a.t),
        _ => (0.0, 0.0),
    }
}

#[test]
fn stick_with_a_tangential_part_slides_along_the_wall() {
    let s = scene("wall");
    let r = fly(&s, &script_file("wall_slide.pilot.toml"), PilotMode::Position, assist(2.0), |_| {});
    row("wall_slide 2 m/s (tangential 1 m/s)", &r);
    let (east, time) = slide_progress(&r);
    println!(
        "  tangential progress at the wall: {east:.2} m in {time:.2} s = {:.2} m/s",
        east / time.max(1e-9)
    );
    assert!(!r.out.summary.collided && r.out.summary.min_clearance_m > 0.0);
    // Commanded tangential speed 1 m/s: at least half of it is kept while sliding.
    assert!(time > 2.0 && east > 0.5 * time, "slid {east:.2} m in {time:.2} s");
}

#[test]
fn diagonal_stick_into_a_box_corner_stops_without_contact() {
    let s = scene("corner");
    for speed in [1.0, 2.0] {
        let r = fly(&s, &script_file("corner.pilot.toml"), PilotMode::Position, assist(speed), |_| {});
        row(&format!("corner {speed} m/s"), &r);
        let end = r.out.samples.last().expect("samples");
        assert!(!r.out.summary.collided && r.out.summary.min_clearance_m > 0.0, "{speed} m/s");
        // In the corner (walls' faces at N 3, E 3): near both, stopped.
        assert!(end.pos.x > 2.0 && end.pos.y > 2.0, "{speed} m/s: ended at {:?}", end.pos);
        assert!(end.vel.norm() < 0.1, "{speed} m/s: still moving {:?}", end.vel);
    }
}

#[test]
fn stick_at_a_person_walking_towards_the_vehicle() {
    let s = scene("person");
    let r = fly(&s, &script_file("person.pilot.toml"), PilotMode::Position, assist(1.0), |_| {});
    row("person 0.3 m/s, stick 0.5 m/s", &r);
    assert!(!r.out.summary.collided, "collided at {:?}", r.out.summary.first_collision_time_s);
    assert!(r.out.summary.min_clearance_m > 0.0);
}

#[test]
fn goal_seeking_pilot_through_a_slalom() {
    let s = scene("slalom");
    let r = fly(&s, &script_file("slalom.pilot.toml"), PilotMode::Position, assist(1.0), |_| {});
    row("slalom, goal pilot 1 m/s", &r);
    assert!(!r.out.summary.collided, "collided at {:?}", r.out.summary.first_collision_time_s);
    assert!(r.out.summary.min_clearance_m > 0.0);
}

#[test]
fn rc_loss_holds_then_lands() {
    let s = scene("wall");
    let r = fly(&s, &script_file("rc_loss.pilot.toml"), PilotMode::Position, assist(1.0), |_| {});
    row("rc_loss at 2 s", &r);
    let m = parapet_core::controller::ControllerParams::default().modes;
    // Last frame at 2 s, loss after FS_RC_TIMEOUT; Land FS_RC_LAND_T later.
    let (lost, land) = (2.0 + m.rc_timeout_s as f64, 2.0 + (m.rc_timeout_s + m.rc_loss_land_s) as f64);
    let at = |t: f64| r.out.samples.iter().find(|x| x.t >= t).expect("sample");
    let mode_at = |t: f64| r.log.iter().find(|l| l.t >= t).map(|l| l.flight_mode.clone()).unwrap_or_default();
    println!(
        "  modes: 1 s {}, {:.2} s {}, {:.2} s {}; N at loss {:.2}, 1.5 s later {:.2}; height at {:.1} s {:.2} m, end {:.2} s ({})",
        mode_at(1.0),
        lost + 0.1,
        mode_at(lost + 0.1),
        land + 0.1,
        mode_at(land + 0.1),
        at(lost).pos.x,
        at(lost + 1.5).pos.x,
        land,
        -at(land).pos.z,
        r.out.summary.sim_time_s,
        r.out.summary.end_reason
    );
    assert_eq!(mode_at(1.0), "Position");
    assert_eq!(mode_at(lost + 0.1), "Hold");
    // It stops and stays within a metre of where the loss was detected, and is at rest
    // before the landing starts.
    let x0 = at(lost).pos.x;
    let drift = r
        .out
        .samples
        .iter()
        .filter(|x| x.t >= lost && x.t <= land)
        .map(|x| (x.pos.x - x0).abs())
        .fold(0.0, f64::max);
    println!(
        "  largest distance from the loss point in Hold {drift:.2} m; speed before Land {:.3} m/s",
        at(land - 0.1).vel.norm()
    );
    assert!(drift < 1.0, "kept flying after the RC loss: {drift:.2} m");
    assert!(at(land - 0.1).vel.norm() < 0.15, "still moving in Hold");
    assert_eq!(mode_at(land + 0.1), "Land");
    // The run ends when the hull touches the ground (the runner counts that as a contact).
    let end = r.out.samples.last().expect("samples");
    assert!(-end.pos.z < 0.3, "did not come down: height {:.2} m", -end.pos.z);
    assert_eq!(r.out.summary.collision_with.as_deref().unwrap_or("ground"), "ground");
}

#[test]
fn kill_switch_stops_the_motors_within_one_inner_step() {
    let s = scene("wall");
    let r = fly(&s, &script_file("kill.pilot.toml"), PilotMode::Position, assist(1.0), |_| {});
    let (k, off) = (r.kill_sent_at.expect("kill sent"), r.motors_off_at.expect("motors stopped"));
    println!("kill frame at {k:.4} s, motors all zero at {off:.4} s");
    assert!(off - k <= 1e-3 + 1e-9, "motors off {:.4} s after the kill", off - k);
}

/// The longer matrix (not in CI): speeds 0.25–4 m/s × stick angles 0–80° from straight at
/// the wall × seeds 0–2, noise on; plus a 3 m/s wind with 0.5 m/s turbulence blowing at the
/// wall. Prints every row and fails listing the collisions (none allowed).
/// `cargo test -p parapet-tests --release --test pilot_flights -- --ignored --nocapture`.
#[test]
#[ignore]
fn wall_matrix() {
    let mut bad = Vec::new();
    let mut n = 0;
    for speed in [0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0] {
        for angle in [0.0, 20.0, 45.0, 60.0, 80.0] {
            for seed in 0..3 {
                for wind in [None, Some((3.0, 180.0, 0.5))] {
                    let r = wall_at(speed, angle, seed, wind);
                    n += 1;
                    if r.out.summary.collided || r.out.summary.min_clearance_m <= 0.0 {
                        bad.push(format!(
                            "{speed} m/s {angle}° seed {seed} wind {wind:?}: clearance {:.3} m",
                            r.out.summary.min_clearance_m
                        ));
                    }
                }
            }
        }
    }
    println!("{} of {n} flights with contact", bad.len());
    assert!(bad.is_empty(), "contacts:\n{}", bad.join("\n"));
}

/// The person case beyond 0.3 m/s (not in CI): the person at 0.2–0.6 m/s, the stick at
/// 0.25–1 (assist speed 1 m/s), the person's axis 0–0.3 m beside the line, seeds 0–2.
/// Prints every contact; fails listing them.
/// `cargo test -p parapet-tests --release --test pilot_flights -- --ignored --nocapture person_matrix`.
#[test]
#[ignore]
fn person_matrix() {
    let p = dir().join("person.toml");
    let src = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{e}"));
    let (mut bad, mut n) = (Vec::new(), 0);
    for v in [0.2, 0.3, 0.45, 0.6] {
        for off in [0.0, 0.15, 0.3] {
            let text = src
                .replace("velocity = [0.0, -0.3, 0.0]", &format!("velocity = [0.0, -{v}, 0.0]"))
                .replace("base = [0.0, 6.0, 0.0]", &format!("base = [{off}, 6.0, 0.0]"));
            let s = Scene::parse(&text, &p.display().to_string()).unwrap_or_else(|e| panic!("{e}"));
            for stick in [0.25, 0.5, 1.0] {
                let script = script_text(&format!("duration = 16.0\n[[stick]]\nt = 0\npitch = {stick}\n"));
                for seed in 0..3 {
                    let r = fly(&s, &script, PilotMode::Position, assist(1.0), |c| c.seed = seed);
                    n += 1;
                    if r.out.summary.collided || r.out.summary.min_clearance_m <= 0.0 {
                        let line = format!(
                            "person {v} m/s offset {off} m stick {stick} seed {seed}: clearance {:.3} m at {:?} s",
                            r.out.summary.min_clearance_m, r.out.summary.first_collision_time_s
                        );
                        println!("{line}");
                        bad.push(line);
                    }
                }
            }
        }
    }
    println!("{} of {n} flights with contact", bad.len());
    assert!(bad.is_empty(), "contacts:\n{}", bad.join("\n"));
}

#[test]
fn position_loss_brakes_then_lands() {
    let s = scene("wall");
    let r = fly(&s, &script_file("fix_loss.pilot.toml"), PilotMode::Position, assist(1.0), |_| {});
    row("fix_loss at 2 s", &r);
    let guidance: Vec<(f64, &str)> = r.log.iter().map(|l| (l.t, l.guidance)).collect();
    let mut changes = vec![];
    for w in guidance.windows(2) {
        if w[0].1 != w[1].1 {
            changes.push(format!("{:.3} s {} -> {}", w[1].0, w[0].1, w[1].1));
        }
    }
    let modes: Vec<String> = {
        let mut m: Vec<String> = vec![];
        for l in &r.log {
            if m.last() != Some(&l.flight_mode) {
                m.push(l.flight_mode.clone());
            }
        }
        m
    };
    println!(
        "  guidance changes: {changes:?}; flight modes: {modes:?}; end {} at {:.2} s, collision with {:?}",
        r.out.summary.end_reason, r.out.summary.sim_time_s, r.out.summary.collision_with
    );
    // No wall contact: the loss stops the flight towards the wall.
    assert_ne!(r.out.summary.collision_with.as_deref(), Some("obstacles[0] (wall)"));
    // Within the position timeout (0.2 s) + one outer step of the last fix, the guidance leaves
    // Position-assist for the failsafe, and later lands.
    let first_change = guidance.iter().find(|g| g.0 > 2.0 && g.1 != guidance[0].1).map(|g| g.0);
    assert!(
        first_change.is_some_and(|t| t <= 2.0 + 0.2 + 0.05),
        "no failsafe after the fix loss: {changes:?}"
    );
    assert!(guidance.iter().any(|g| g.1 == "Land" || g.1 == "NoFix"), "never landed: {changes:?}");
}

#[test]
fn low_battery_in_position_assist_returns() {
    let p = dir().join("wall.toml");
    let src = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{e}"));
    // A small, nearly empty pack: it reaches the Low threshold under the hover current.
    let text = format!("{src}\n[battery]\ncapacity_mah = 300\ninitial_soc = 0.12\n");
    let s = Scene::parse(&text, &p.display().to_string()).unwrap_or_else(|e| panic!("{e}"));
    let script = script_text("duration = 30.0\n[[stick]]\nt = 0\npitch = 0.6\n");
    let r = fly(&s, &script, PilotMode::Position, assist(1.0), |_| {});
    row("low battery, stick at the wall", &r);
    let mut modes: Vec<(f64, String)> = vec![];
    for l in &r.log {
        if modes.last().map(|m| &m.1) != Some(&l.flight_mode) {
            modes.push((l.t, l.flight_mode.clone()));
        }
    }
    println!(
        "  flight modes: {modes:?}; end {} at {:.2} s",
        r.out.summary.end_reason, r.out.summary.sim_time_s
    );
    assert_ne!(r.out.summary.collision_with.as_deref(), Some("obstacles[0] (wall)"));
    let ret = modes.iter().find(|m| m.1 == "Return").map(|m| m.0);
    assert!(ret.is_some(), "no Return on low battery: {modes:?}");
    // Return flies back towards the start (N 0) from the wall.
    let at = |t: f64| r.out.samples.iter().find(|x| x.t >= t).map(|x| x.pos);
    let (a, b) =
        (at(ret.unwrap_or(0.0)).unwrap_or_default(), r.out.samples.last().map(|x| x.pos).unwrap_or_default());
    println!("  at Return N {:.2} m, at the end N {:.2} m", a.x, b.x);
    assert!(b.x < a.x - 0.5 || b.x.abs() < 0.5, "did not return: from N {:.2} to {:.2}", a.x, b.x);
}
