//! Issue 21, the simulated pilot with the real firmware: the pilot script's RC frames go over
//! the lockstep link as MANUAL_CONTROL into the `board-qemu` firmware in QEMU
//! (`parapet_sim::pilot::run_piloted_pil`), which flies Position-assist against the 6-DOF
//! plant; the same script flies the in-process controller entering the mode the same way
//! (mode switch Mid → Low, `run_piloted_via_switch`). Full forward + 0.3 right stick at the wall
//! of `scenes/pilot/wall.toml` for 5 s, then the kill switch.
//!
//! * PIL: no contact, the vehicle stops at the wall, motors zero within one inner step of the
//!   kill frame;
//! * PIL and in-process agree within the PIL tolerance of `pil_flight` (0.05 m) until the kill.
//!
//! Offboard (`offboard_script_flies_the_firmware_like_the_host`): the companion's velocity
//! setpoints as SET_POSITION_TARGET_LOCAL_NED at 20 Hz, Offboard entered with DO_SET_MODE (PX4
//! main mode 6), into the same wall: 1 m/s east for 2 s, then 1.5 m/s north at the wall, then
//! the stream stops at 5 s.
//!
//! * PIL: no contact (the soft default PD gains lag the setpoint: 0.83 m/s north, 1.3 m from the
//!   face when the stream stops; the Hold then brakes it 0.30 m from the face), "MODE Offboard: mode-command", then
//!   Offboard → Hold on the setpoint timeout ("MODE Hold: offboard-loss", 0.5 s after the last
//!   setpoint), holding;
//! * PIL and in-process (`run_piloted`, Offboard by `set_mode`) agree within 0.05 m over the
//!   whole flight, the Hold included, and switch to Hold in the same outer step.
//!
//! ELF and QEMU as `pil_flight` (`PARAPET_FIRMWARE_QEMU_ELF`, else built; SKIP without QEMU
//! outside CI). `cargo test -p parapet-tests --release --test pil_pilot -- --nocapture`.

use std::path::PathBuf;

use parapet_sim::fc::pil::PilOptions;
use parapet_sim::flight::runner::RunConfig;
use parapet_sim::pilot::{
    piloted_config, run_piloted, run_piloted_pil, run_piloted_via_switch, AssistParams, PilotMode, PilotRun,
    PilotScript,
};
use parapet_sim::world::scene::Scene;
use parapet_tests::pil_support::firmware;

const SCRIPT: &str = "duration = 5.6\n[[stick]]\nt = 0\npitch = 1.0\nroll = 0.3\n\
                      [[event]]\nkind = \"kill\"\nt = 5.0\n";

#[test]
fn pilot_script_flies_the_firmware_like_the_host() {
    let Some(elf) = firmware() else { return };
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/pilot");
    let scene = Scene::load(&dir.join("wall.toml")).unwrap_or_else(|e| panic!("{e}"));
    let script =
        PilotScript::parse(SCRIPT, "pil_pilot script", "pil_pilot").unwrap_or_else(|e| panic!("{e}"));
    let cfg = RunConfig::for_scene(&scene, vec![scene.start]).unwrap_or_else(|e| panic!("{e}"));
    let cfg = piloted_config(&scene, cfg, &script);
    let pil = run_piloted_pil(&scene, &cfg, &script, PilotMode::Position, PilOptions::new(elf), &mut |_| {})
        .expect("PIL flight");
    let host =
        run_piloted_via_switch(&scene, &cfg, &script, AssistParams::default(), &mut |_| {}).expect("host");
    let at =
        |r: &parapet_sim::pilot::PilotRun, t: f64| r.out.samples.iter().find(|x| x.t >= t).map(|x| x.pos);
    let n = pil.out.samples.iter().take_while(|x| x.t < 5.0).count().min(host.out.samples.len());
    let dev = pil.out.samples[..n]
        .iter()
        .zip(&host.out.samples[..n])
        .map(|(a, b)| (a.pos - b.pos).norm())
        .fold(0.0, f64::max);
    let (k, off) = (pil.kill_sent_at, pil.motors_off_at);
    println!(
        "PIL: min clearance {:.3} m (host {:.3}), at 4.9 s {:?} (host {:?}); max deviation until the kill {dev:.4} m over {n} samples; \
         kill frame {k:?} s, motors zero {off:?} s; state {}",
        pil.out.summary.min_clearance_m,
        host.out.summary.min_clearance_m,
        at(&pil, 4.9),
        at(&host, 4.9),
        pil.out.summary.final_controller_state
    );
    let before_kill =
        pil.out.samples.iter().filter(|x| x.t < 5.0).map(|x| x.clearance).fold(f64::INFINITY, f64::min);
    assert!(before_kill > 0.0, "PIL: contact before the kill");
    let p = at(&pil, 4.9).expect("sample");
    assert!(p.x > 3.0 && p.x < 4.0 - 0.224, "PIL: not stopped at the wall: {p:?}");
    let (k, off) = (k.expect("kill sent"), off.expect("motors stopped"));
    assert!(off - k <= 1e-3 + 1e-9, "PIL: motors off {:.4} s after the kill frame", off - k);
    assert!(n > 1000);
    assert!(dev < 0.05, "PIL and in-process differ by {dev} m");
}

const OFFBOARD: &str = "name = \"pil_offboard\"\ninterpolation = \"hold\"\nsetpoint_rate_hz = 20\n\
                        duration = 7.0\n[[setpoint]]\nt = 0.0\nvelocity = [1.0, 0.0, 0.0]\n\
                        [[setpoint]]\nt = 2.0\nvelocity = [0.0, 1.5, 0.0]\n\
                        [[event]]\nkind = \"offboard_stop\"\nt = 5.0\n";

/// First time the log shows `mode`, s.
fn entered(r: &PilotRun, mode: &str) -> Option<f64> {
    r.log.iter().find(|l| l.flight_mode == mode).map(|l| l.t)
}

#[test]
fn offboard_script_flies_the_firmware_like_the_host() {
    let Some(elf) = firmware() else { return };
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/pilot");
    let scene = Scene::load(&dir.join("wall.toml")).unwrap_or_else(|e| panic!("{e}"));
    let script =
        PilotScript::parse(OFFBOARD, "pil_offboard script", "pil_offboard").unwrap_or_else(|e| panic!("{e}"));
    let cfg = RunConfig::for_scene(&scene, vec![scene.start]).unwrap_or_else(|e| panic!("{e}"));
    let cfg = piloted_config(&scene, cfg, &script);
    let pil = run_piloted_pil(&scene, &cfg, &script, PilotMode::Offboard, PilOptions::new(elf), &mut |_| {})
        .expect("PIL flight");
    let host = run_piloted(&scene, &cfg, &script, PilotMode::Offboard, AssistParams::default(), &mut |_| {})
        .expect("host");
    let (dev, n) = parapet_sim::fc::pil::max_deviation(&pil.out, &host.out);
    let at = |r: &PilotRun, t: f64| r.out.samples.iter().find(|x| x.t >= t).map(|x| (x.pos, x.vel));
    let (hold_pil, hold_host) = (entered(&pil, "Hold"), entered(&host, "Hold"));
    println!(
        "PIL offboard: min clearance {:.3} m (host {:.3}); at 4.9 s {:?} (host {:?}); max deviation {dev:.4} m over {n} \
         samples; Offboard from {:?} s (host {:?}), Hold from {hold_pil:?} s (host {hold_host:?}); texts {:?}",
        pil.out.summary.min_clearance_m,
        host.out.summary.min_clearance_m,
        at(&pil, 4.9),
        at(&host, 4.9),
        entered(&pil, "Offboard"),
        entered(&host, "Offboard"),
        pil.status_texts
    );
    assert!(!pil.out.summary.collided, "PIL: contact at {:?}", pil.out.summary.first_collision_time_s);
    assert!(pil.out.summary.min_clearance_m > 0.0);
    let has = |t: &str| pil.status_texts.iter().any(|s| s.ends_with(t));
    assert!(has("MODE Offboard: mode-command"), "{:?}", pil.status_texts);
    assert!(has("MODE Hold: offboard-loss"), "{:?}", pil.status_texts);
    assert!(entered(&pil, "Offboard").is_some_and(|t| t < 0.01), "Offboard from the first step");
    let hold = hold_pil.expect("PIL: Offboard -> Hold on the setpoint timeout");
    // The last setpoint goes at 4.95 s (20 Hz); OFFB_TIMEOUT 0.5 s.
    assert!((5.4..5.6).contains(&hold), "PIL: Hold at {hold:.3} s");
    let h = hold_host.expect("host: Hold");
    assert!((hold - h).abs() <= 0.004 + 1e-9, "PIL Hold {hold:.3} s, host {h:.3} s");
    let (_, v) = at(&pil, 6.9).expect("sample");
    assert!(v.norm() < 0.3, "PIL: not holding: {v:?}");
    assert!(n > 1500);
    assert!(dev < 0.05, "PIL and in-process differ by {dev} m");
}
