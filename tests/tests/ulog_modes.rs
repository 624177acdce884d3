//! The flight log names the modes as PX4 does (issue 37): `vehicle_status.nav_state` of the
//! host's `flight.ulg`, read with pyulog (`tests/python/check_ulog_modes.py`, PX4's numbers from
//! `VehicleStatus.msg` written there on their own), on real flights:
//!
//! * a pilot in Position-assist at a wall with a nearly empty pack: Position (2) → Return (5) →
//!   Land (18) — before the fix the log said 4, 4, 18;
//! * a mission with a low pack: Mission (3) → Return (5) → Land (18);
//! * a companion computer in Offboard (14).
//!
//! The firmware's onboard log is checked the same way (`parapet-firmware`,
//! `log::logger::tests::pyulog_reads_px4_s_nav_state_for_every_mode`). Needs the venv's python
//! with pyulog (`cargo xtask venv`); SKIPs loudly without it, fails in CI (`venv_python`).

use std::path::{Path, PathBuf};
use std::process::Command;

use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{controller_params, RunConfig};
use parapet_sim::flight::stack::clock_us;
use parapet_sim::pilot::{piloted_config, run_piloted, AssistParams, PilotMode, PilotScript};
use parapet_sim::report::ulog::write_flight_ulog;
use parapet_sim::report::Sample;
use parapet_sim::world::scene::Scene;
use parapet_tests::pil_support::{venv_python, workspace_root};

fn pilot_dir() -> PathBuf {
    workspace_root().join("scenes/pilot")
}

/// Writes `samples` (flown over `scene` with `cfg`) as a ULog and runs the pyulog check with the
/// `expected` nav_state sequence.
fn check(name: &str, scene: &Scene, cfg: &RunConfig, samples: &[Sample], expected: &str) {
    let Some(py) = venv_python("pyulog", "the ULog's nav_state") else { return };
    let dir = std::env::temp_dir().join(format!("parapet-ulog-modes-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("out dir");
    let path = dir.join("flight.ulg");
    let params = controller_params(scene, cfg, cfg.cbf_params().expect("cbf"), cfg.variant);
    write_flight_ulog(&path, samples, &params, &[], clock_us).expect("ulog");
    let script = workspace_root().join("tests/python/check_ulog_modes.py");
    let o = Command::new(py).arg(script).arg(&path).arg(expected).output().expect("python runs");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{name}: {text}");
    assert!(o.status.success(), "{name}: {text}");
    let _ = std::fs::remove_dir_all(&dir);
}

fn scene_with_battery(path: &Path, battery: &str) -> Scene {
    let src = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{e}"));
    Scene::parse(&format!("{src}\n{battery}"), &path.display().to_string()).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn position_return_land_are_px4_s_2_5_18() {
    let s = scene_with_battery(
        &pilot_dir().join("wall.toml"),
        "[battery]\ncapacity_mah = 300\ninitial_soc = 0.12\n",
    );
    let script =
        PilotScript::parse("duration = 30.0\n[[stick]]\nt = 0\npitch = 0.6\n", "test script", "test")
            .unwrap_or_else(|e| panic!("{e}"));
    let cfg = RunConfig::for_scene(&s, vec![s.start]).unwrap_or_else(|e| panic!("{e}"));
    let cfg = piloted_config(&s, cfg, &script);
    let r = run_piloted(&s, &cfg, &script, PilotMode::Position, AssistParams::default(), &mut |_| {})
        .unwrap_or_else(|e| panic!("{e:#}"));
    check("pilot", &s, &cfg, &r.out.samples, "2,5,18");
}

#[test]
fn mission_return_land_are_px4_s_3_5_18() {
    let src = "name = \"battery\"\n[bounds]\nmin = [-2.0, -2.0, 0.0]\nmax = [8.0, 2.0, 3.0]\n\
               [mission]\nstart = [0.0, 0.0, 1.0]\ngoal = [6.0, 0.0, 1.0]\nspeed = 0.3\n\
               [battery]\ncells = 3\ninitial_soc = 0.05\n";
    let s = Scene::parse(src, "battery.toml").unwrap_or_else(|e| panic!("{e:?}"));
    let mut cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).unwrap_or_else(|e| panic!("{e}"));
    cfg.seed = 5;
    cfg.duration = 30.0;
    let out = run(&s, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{e:#}"));
    check("mission", &s, &cfg, &out.samples, "3,5,18");
}

#[test]
fn offboard_is_px4_s_14() {
    let s = Scene::load(&pilot_dir().join("wall.toml")).unwrap_or_else(|e| panic!("{e}"));
    let script =
        PilotScript::load(&pilot_dir().join("offboard_wall.offboard.toml")).unwrap_or_else(|e| panic!("{e}"));
    let cfg = RunConfig::for_scene(&s, vec![s.start]).unwrap_or_else(|e| panic!("{e}"));
    let cfg = piloted_config(&s, cfg, &script);
    let r = run_piloted(&s, &cfg, &script, PilotMode::Offboard, AssistParams::default(), &mut |_| {})
        .unwrap_or_else(|e| panic!("{e:#}"));
    check("offboard", &s, &cfg, &r.out.samples, "14");
}
