//! Shared set-up of the processor-in-the-loop tests (`tests/tests/pil_*.rs`): the short
//! scene they fly and the QEMU firmware ELF they fly it with.

use std::io::Write;
use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;

use parapet_sim::fc::pil::firmware_from_env_or_build;
use parapet_sim::flight::runner::RunConfig;
use parapet_sim::world::scene::Scene;

/// One sphere (r 0.2 m) 5 cm off the straight start → goal line: without the filter the hull
/// (r 0.224 m) hits it. The vehicle is not the default one (heavier, larger, stronger rotors)
/// and the filter has a velocity margin, so the PIL flight checks that the firmware receives
/// the scene's airframe and settings over PARAM_SET (`parapet_sim::fc::pil::firmware_params`).
pub const SCENE: &str = r#"
name = "pil_short"
[bounds]
min = [-1.0, -1.5, 0.3]
max = [3.5, 1.5, 2.0]
[mission]
start = [0.0, 0.0, 1.0]
goal = [2.4, 0.0, 1.0]
speed = 0.4
[sensors]
noise = false
[vehicle]
mass = 0.62
inertia = [0.0024, 0.0025, 0.0041]
arm_length = 0.15
k_f = 2.6e-6
k_m = 4.3e-8
[controller]
velocity_margin = 0.02
[[obstacles]]
kind = "sphere"
center = [1.2, 0.05, 1.0]
radius = 0.2
"#;

pub fn scene() -> Scene {
    Scene::parse(SCENE, "pil_short (parapet_tests::pil_support)").expect("scene parses")
}

/// The straight start → goal run of `scene`, `duration` s at most.
pub fn config(scene: &Scene, duration: f64) -> RunConfig {
    let mut cfg = RunConfig::for_scene(scene, vec![scene.start, scene.goal]).expect("config");
    cfg.duration = duration;
    cfg
}

/// The firmware ELF: `PARAPET_FIRMWARE_QEMU_ELF` (set by `cargo xtask test`: QEMU must then be
/// installed), else built with cargo when QEMU is installed; `None` (loud SKIP) without QEMU and
/// without the variable.
pub fn firmware() -> Option<PathBuf> {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    let have_qemu = Command::new("qemu-system-arm").arg("--version").output().is_ok();
    let from_env = std::env::var_os("PARAPET_FIRMWARE_QEMU_ELF").is_some();
    if !have_qemu {
        if from_env {
            panic!(
                "qemu-system-arm is missing: sudo apt-get update && sudo apt-get install -y qemu-system-arm"
            );
        }
        // Straight to stderr: libtest does not capture this, so the SKIP is visible.
        let _ = writeln!(
            std::io::stderr(),
            "\n*** SKIP: qemu-system-arm not installed and PARAPET_FIRMWARE_QEMU_ELF unset: \
             processor-in-the-loop NOT TESTED (cargo xtask test runs it) ***\n"
        );
        return None;
    }
    Some(ELF.get_or_init(|| firmware_from_env_or_build().expect("QEMU firmware ELF")).clone())
}
