//! Issue 21, the failsafes of the automatic modes on the 6-DOF plant with the real flight
//! controller (`parapet_sim::pilot`, the wall scene `scenes/pilot/wall.toml`, sensor noise on),
//! each transition asserted with its reason (the controller's `last_mode_change`, what the
//! firmware sends as the "MODE <mode>: <reason>" STATUSTEXT):
//!
//! * RC loss in **Mission** (a safety pilot's RC frames at 50 Hz while a 4 m mission is flown,
//!   lost from 2 s on): `FS_RC_ACT` 0 → the mission continues to its end; `FS_RC_ACT` 1 →
//!   Return (`rc-loss`) `FS_RC_TIMEOUT` after the last frame, back along the breadcrumbs, then
//!   Land (`return-done`) near home;
//! * RC loss in **Offboard** (velocity setpoints 0.5 m/s east): `FS_RC_ACT` 0 → Offboard goes
//!   on (the companion keeps the vehicle); `FS_RC_ACT` 1 → Return (`rc-loss`), then Land;
//! * offboard **setpoint loss** → Hold (`offboard-loss`) `OFFB_TIMEOUT` after the last setpoint;
//! * **position loss** in Offboard → the failsafe machine's Brake (NoFix guidance, 0.2 s after
//!   the last fix), then Land (`brake-timeout`, 3 s later), down without a fix.
//!
//! Measured (this file, `--nocapture`): Return 2.484 s after the last RC frame at 1.98 s
//! (FS_RC_TIMEOUT 0.5 s), Land (`return-done`) at 9.59 s (Mission) / 9.62 s (Offboard), down
//! 0.08 m from home; with FS_RC_ACT 0 the mission ends 0.04 m from its last waypoint and Offboard
//! still flies 0.5 m/s east; setpoint loss → Hold at 3.452 s (last setpoint 2.95 s); position
//! loss → NoFix at 2.2 s, Land at 5.2 s.
//!
//! `cargo test -p parapet-tests --release --test mode_failsafes -- --nocapture`.

use std::path::PathBuf;

use nalgebra::Vector3;
use parapet_core::supervisor::modes::RcLossAction;
use parapet_sim::flight::runner::RunConfig;
use parapet_sim::pilot::{piloted_config, run_piloted, AssistParams, PilotMode, PilotRun, PilotScript};
use parapet_sim::world::scene::Scene;

fn scene() -> Scene {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/pilot");
    Scene::load(&dir.join("wall.toml")).unwrap_or_else(|e| panic!("{e}"))
}

fn script(text: &str) -> PilotScript {
    PilotScript::parse(text, "test script", "test").unwrap_or_else(|e| panic!("{e}"))
}

/// Fly `text` in `mode` with `FS_RC_ACT` = `action`; in Mission along start → 2 m north (towards
/// the wall, 4 m away) → 2 m east (the run's path is NED), else the start alone.
fn fly(text: &str, mode: PilotMode, action: RcLossAction) -> PilotRun {
    let s = scene();
    let sc = script(text);
    let cfg = RunConfig::for_scene(&s, vec![s.start]).unwrap_or_else(|e| panic!("{e}"));
    let mut cfg = piloted_config(&s, cfg, &sc);
    if mode == PilotMode::Mission {
        cfg.path =
            vec![s.start, s.start + Vector3::new(2.0, 0.0, 0.0), s.start + Vector3::new(2.0, 2.0, 0.0)];
        cfg.path_source = "file".into();
    }
    let assist = AssistParams { rc_loss_auto: Some(action), ..AssistParams::default() };
    run_piloted(&s, &cfg, &sc, mode, assist, &mut |_| {}).unwrap_or_else(|e| panic!("{e:#}"))
}

/// The mode changes of the log: (time, mode, reason).
fn changes(r: &PilotRun) -> Vec<(f64, String, &'static str)> {
    let mut out: Vec<(f64, String, &'static str)> = Vec::new();
    for l in &r.log {
        if out.last().is_none_or(|c| c.1 != l.flight_mode) {
            out.push((l.t, l.flight_mode.clone(), l.mode_reason.unwrap_or("")));
        }
    }
    out
}

fn at(r: &PilotRun, t: f64) -> &parapet_sim::report::Sample {
    r.out.samples.iter().find(|x| x.t >= t).unwrap_or_else(|| panic!("no sample at {t} s"))
}

fn report(label: &str, r: &PilotRun) {
    let s = &r.out.summary;
    let end = r.out.samples.last().map(|x| x.pos).unwrap_or_default();
    println!(
        "{label:<28} changes {:?}; end N {:.2} E {:.2} h {:.2} m at {:.2} s ({}), collided {} with {:?}",
        changes(r),
        end.x,
        end.y,
        -end.z,
        s.sim_time_s,
        s.end_reason,
        s.collided,
        s.collision_with
    );
}

/// The first change to `mode` after `after` s: (time, reason).
fn change_to(r: &PilotRun, mode: &str, after: f64) -> Option<(f64, &'static str)> {
    changes(r).into_iter().find(|c| c.0 > after && c.1 == mode).map(|c| (c.0, c.2))
}

/// RC frames (centred sticks) from 0 s, lost from 2 s on.
const RC_LOST_AT_2S: &str = "[[stick]]\nt = 0.0\n[[event]]\nkind = \"rc_loss\"\nt = 2.0\nuntil = 30.0\n";

/// The timeout after the last frame (1.98 s: frames every 20 ms, none from 2 s on) plus
/// two outer steps.
fn rc_loss_window() -> std::ops::Range<f64> {
    let m = parapet_core::controller::ControllerParams::default().modes;
    let t = 1.98 + f64::from(m.rc_timeout_s);
    t..t + 0.03
}

#[test]
fn rc_loss_in_mission_continues_with_fs_rc_act_0() {
    let r = fly(&format!("duration = 13.0\n{RC_LOST_AT_2S}"), PilotMode::Mission, RcLossAction::Continue);
    report("mission, rc loss, continue", &r);
    assert!(changes(&r).iter().all(|c| c.1 == "Mission"), "{:?}", changes(&r));
    // The mission's end: 2 m east, 2 m north of the start (NED N 2, E 2).
    let p = at(&r, 12.9).pos;
    assert!((p - Vector3::new(2.0, 2.0, p.z)).norm() < 0.2, "mission not flown to its end: {p:?}");
    assert!(!r.out.summary.collided);
}

#[test]
fn rc_loss_in_mission_returns_with_fs_rc_act_1() {
    let r = fly(&format!("duration = 25.0\n{RC_LOST_AT_2S}"), PilotMode::Mission, RcLossAction::Return);
    report("mission, rc loss, return", &r);
    let (t, why) = change_to(&r, "Return", 0.0).expect("Mission -> Return");
    assert!(rc_loss_window().contains(&t), "Return at {t:.3} s");
    assert_eq!(why, "rc-loss");
    // Out about 1 m north at the loss, then back home along the crumbs and down.
    assert!(at(&r, t).pos.x > 0.7, "{:?}", at(&r, t).pos);
    let (tl, why) = change_to(&r, "Land", t).expect("Return -> Land");
    assert_eq!(why, "return-done");
    let p = at(&r, tl).pos;
    assert!(p.x.hypot(p.y) < 0.15, "Land {:.2} m from home", p.x.hypot(p.y));
    let end = r.out.samples.last().expect("samples");
    assert!(-end.pos.z < 0.3, "did not come down: {:?}", end.pos);
    assert_eq!(r.out.summary.collision_with.as_deref().unwrap_or("ground"), "ground");
}

/// Velocity setpoints 0.5 m/s east (ENU) at 20 Hz, with RC frames lost from 2 s on.
fn offboard_rc_loss(duration: f64) -> String {
    format!("duration = {duration}\nsetpoint_rate_hz = 20\n[[setpoint]]\nt = 0.0\nvelocity = [0.5, 0.0, 0.0]\n{RC_LOST_AT_2S}")
}

#[test]
fn rc_loss_in_offboard_continues_with_fs_rc_act_0() {
    let r = fly(&offboard_rc_loss(7.0), PilotMode::Offboard, RcLossAction::Continue);
    report("offboard, rc loss, continue", &r);
    assert!(changes(&r).iter().all(|c| c.1 == "Offboard"), "{:?}", changes(&r));
    // Still following the companion: about 0.5 m/s east long after the loss.
    let v = at(&r, 6.5).vel;
    assert!((v - Vector3::new(0.0, 0.5, 0.0)).norm() < 0.15, "{v:?}");
}

#[test]
fn rc_loss_in_offboard_returns_with_fs_rc_act_1() {
    let r = fly(&offboard_rc_loss(20.0), PilotMode::Offboard, RcLossAction::Return);
    report("offboard, rc loss, return", &r);
    let (t, why) = change_to(&r, "Return", 0.0).expect("Offboard -> Return");
    assert!(rc_loss_window().contains(&t), "Return at {t:.3} s");
    assert_eq!(why, "rc-loss");
    let (tl, why) = change_to(&r, "Land", t).expect("Return -> Land");
    assert_eq!(why, "return-done");
    let p = at(&r, tl).pos;
    assert!(p.x.hypot(p.y) < 0.15, "Land {:.2} m from home", p.x.hypot(p.y));
}

#[test]
fn offboard_setpoint_loss_holds() {
    let text = "duration = 8.0\nsetpoint_rate_hz = 20\n[[setpoint]]\nt = 0.0\nvelocity = [0.5, 0.0, 0.0]\n\
                [[event]]\nkind = \"offboard_stop\"\nt = 3.0\n";
    let r = fly(text, PilotMode::Offboard, RcLossAction::Continue);
    report("offboard, setpoint loss", &r);
    let m = parapet_core::controller::ControllerParams::default().modes;
    let (t, why) = change_to(&r, "Hold", 0.0).expect("Offboard -> Hold");
    // The last setpoint goes at 2.95 s.
    let due = 2.95 + f64::from(m.offboard_timeout_s);
    assert!((due..due + 0.03).contains(&t), "Hold at {t:.3} s (due {due:.2} s)");
    assert_eq!(why, "offboard-loss");
    assert!(at(&r, 7.9).vel.norm() < 0.15, "not holding: {:?}", at(&r, 7.9).vel);
}

#[test]
fn position_loss_in_offboard_lands() {
    let text = "duration = 12.0\nsetpoint_rate_hz = 20\n[[setpoint]]\nt = 0.0\nvelocity = [0.5, 0.0, 0.0]\n\
                [[event]]\nkind = \"fix_loss\"\nt = 2.0\nuntil = 12.0\n";
    let r = fly(text, PilotMode::Offboard, RcLossAction::Continue);
    report("offboard, position loss", &r);
    let guidance: Vec<(f64, &str)> = r.log.iter().map(|l| (l.t, l.guidance)).collect();
    let first = guidance.iter().find(|g| g.0 > 2.0 && g.1 != guidance[0].1).copied();
    println!("  first guidance change after the loss: {first:?}; last {:?}", guidance.last());
    // The position timeout (0.2 s) after the last fix, plus one outer step.
    assert!(first.is_some_and(|g| g.0 <= 2.0 + 0.2 + 0.05), "no failsafe after the fix loss: {first:?}");
    assert!(guidance.iter().any(|g| g.1 == "Land" || g.1 == "NoFix"), "never landed");
    // The failsafe machine brakes open-loop for FS_BRAKE_T (3 s), then lands: flight mode Land.
    let (t, why) = change_to(&r, "Land", 2.0).expect("Offboard -> Land");
    assert_eq!(why, "brake-timeout");
    assert!((5.1..5.3).contains(&t), "Land at {t:.3} s");
    let end = r.out.samples.last().expect("samples");
    assert!(-end.pos.z < 0.3, "did not come down: {:?}", end.pos);
    assert_eq!(r.out.summary.collision_with.as_deref().unwrap_or("ground"), "ground");
}
