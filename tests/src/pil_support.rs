//! Shared set-up of the processor-in-the-loop tests (`tests/tests/pil_*.rs`): the short
//! scene they fly and the QEMU firmware ELF they fly it with.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use parapet_sim::fc::pil::firmware_from_env_or_build;
use parapet_sim::flight::runner::RunConfig;
use parapet_sim::world::scene::Scene;

/// One sphere (r 0.2 m) 5 cm off the straight start → goal line: without the filter the hull
/// (r 0.224 m) hits it. The vehicle is not the default one (heavier, larger, stronger rotors)
/// and the filter has a velocity margin, so the PIL flight checks that the firmware receives
/// the scene's airframe and settings over PARAM_SET (`parapet_sim::fc::pil::firmware_params`).
pub const SCENE: &str = include_str!("../data/scenes/pil_short.toml");

pub fn scene() -> Scene {
    Scene::parse(SCENE, "pil_short (parapet_tests::pil_support)").expect("scene parses")
}

/// The straight start → goal run of `scene`, `duration` s at most.
pub fn config(scene: &Scene, duration: f64) -> RunConfig {
    let mut cfg = RunConfig::for_scene(scene, vec![scene.start, scene.goal]).expect("config");
    cfg.duration = duration;
    cfg
}

/// What a test that needs `qemu-system-arm` and the QEMU firmware ELF does.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PilPrerequisites {
    /// Everything is there (or the ELF will be built with cargo): run the test.
    Run,
    /// Missing, outside CI and without `PARAPET_FIRMWARE_QEMU_ELF`: return early with this
    /// loud reason (a developer's machine without QEMU).
    Skip(String),
    /// Missing where the test must run (`CI` set, or `PARAPET_FIRMWARE_QEMU_ELF` set, as by
    /// `cargo xtask test`): fail with this reason, never pass green.
    Fail(String),
}

/// `true` when the environment variable `CI` says this is a CI run: set, not empty, not `0` or
/// `false` (any case). CI services set `CI=true`; so does this project's CI (`.ci/run` runs
/// with `CI=true`).
pub fn is_ci(ci: Option<&std::ffi::OsStr>) -> bool {
    ci.and_then(|v| v.to_str()).is_some_and(|v| {
        let v = v.trim();
        !v.is_empty() && v != "0" && !v.eq_ignore_ascii_case("false")
    })
}

/// The rule of [`firmware`], from what it found: is `qemu-system-arm` runnable, the value of
/// `PARAPET_FIRMWARE_QEMU_ELF` and whether that file exists, and [`is_ci`].
pub fn pil_prerequisites(have_qemu: bool, elf_env: Option<(&Path, bool)>, ci: bool) -> PilPrerequisites {
    let install = "sudo apt-get update && sudo apt-get install -y qemu-system-arm";
    if let Some((elf, false)) = elf_env {
        return PilPrerequisites::Fail(format!(
            "PARAPET_FIRMWARE_QEMU_ELF={} does not exist (build it with cargo xtask test, or unset it \
             to let the test build the firmware)",
            elf.display()
        ));
    }
    if have_qemu {
        return PilPrerequisites::Run;
    }
    if ci || elf_env.is_some() {
        let why = if ci { "CI is set" } else { "PARAPET_FIRMWARE_QEMU_ELF is set" };
        return PilPrerequisites::Fail(format!(
            "qemu-system-arm is missing and {why}: processor-in-the-loop cannot be skipped here; install it: {install}"
        ));
    }
    PilPrerequisites::Skip(format!(
        "qemu-system-arm not installed, PARAPET_FIRMWARE_QEMU_ELF and CI unset: processor-in-the-loop \
         NOT TESTED (cargo xtask test installs QEMU and runs it; or: {install})"
    ))
}

/// The firmware ELF: `PARAPET_FIRMWARE_QEMU_ELF` (set by `cargo xtask test`), else built with
/// cargo when QEMU is installed. Without QEMU (or with a missing ELF file) it panics when `CI` or
/// the variable is set, and returns `None` (loud SKIP on stderr) otherwise
/// ([`pil_prerequisites`]).
pub fn firmware() -> Option<PathBuf> {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    let have_qemu =
        Command::new("qemu-system-arm").arg("--version").output().is_ok_and(|o| o.status.success());
    let env_elf = std::env::var_os("PARAPET_FIRMWARE_QEMU_ELF").map(PathBuf::from);
    let elf_env = env_elf.as_deref().map(|p| (p, p.is_file()));
    match pil_prerequisites(have_qemu, elf_env, is_ci(std::env::var_os("CI").as_deref())) {
        PilPrerequisites::Run => {}
        PilPrerequisites::Fail(why) => panic!("{why}"),
        PilPrerequisites::Skip(why) => {
            // Straight to stderr: libtest does not capture this, so the SKIP is visible.
            let _ = writeln!(std::io::stderr(), "\n*** SKIP: {why} ***\n");
            return None;
        }
    }
    Some(ELF.get_or_init(|| firmware_from_env_or_build().expect("QEMU firmware ELF")).clone())
}

/// The workspace root (the folder of the workspace `Cargo.toml`).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace root").to_path_buf()
}

/// The venv's python (`PARAPET_PYTHON`, else `$CARGO_TARGET_DIR/venv/bin/python`, which
/// `cargo xtask test` / `cargo xtask venv` create) if it imports every module of `modules`
/// (e.g. `"pymavlink, pyulog"`). Otherwise it panics when `CI` or `PARAPET_PYTHON` is set — the
/// clients cannot be skipped there — and returns `None` with a loud SKIP naming `what` (the
/// part left untested).
pub fn venv_python(modules: &str, what: &str) -> Option<PathBuf> {
    let env = std::env::var_os("PARAPET_PYTHON").map(PathBuf::from);
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("target"));
    let py = env.clone().unwrap_or_else(|| target.join("venv/bin/python"));
    let ok = Command::new(&py)
        .args(["-c", &format!("import {modules}")])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        return Some(py);
    }
    let why = format!(
        "no python with {modules} at {} (cargo xtask test creates it, or cargo xtask venv)",
        py.display()
    );
    if is_ci(std::env::var_os("CI").as_deref()) || env.is_some() {
        panic!("{why}; CI or PARAPET_PYTHON is set: {what} cannot be skipped here");
    }
    let _ = writeln!(std::io::stderr(), "\n*** SKIP: {why}: {what} NOT TESTED ***\n");
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::OsStr;

    #[test]
    fn ci_is_a_set_non_false_variable() {
        for v in ["true", "1", "yes", "TRUE"] {
            assert!(is_ci(Some(OsStr::new(v))), "{v}");
        }
        for v in ["", " ", "0", "false", "False"] {
            assert!(!is_ci(Some(OsStr::new(v))), "{v:?}");
        }
        assert!(!is_ci(None));
    }

    #[test]
    fn missing_qemu_fails_in_ci_and_with_the_elf_variable_and_skips_otherwise() {
        let elf = Path::new("/x/parapet-firmware-qemu");
        use PilPrerequisites::*;
        assert_eq!(pil_prerequisites(true, None, false), Run);
        assert_eq!(pil_prerequisites(true, None, true), Run, "builds the ELF itself");
        assert_eq!(pil_prerequisites(true, Some((elf, true)), true), Run);
        assert!(matches!(pil_prerequisites(false, None, false), Skip(w) if w.contains("NOT TESTED")));
        for (env, ci) in [(None, true), (Some((elf, true)), false), (Some((elf, true)), true)] {
            let d = pil_prerequisites(false, env, ci);
            assert!(matches!(&d, Fail(w) if w.contains("apt-get install -y qemu-system-arm")), "{d:?}");
        }
        // A variable naming no file fails, with or without QEMU and CI.
        for (q, ci) in [(true, false), (false, false), (true, true)] {
            let d = pil_prerequisites(q, Some((elf, false)), ci);
            assert!(matches!(&d, Fail(w) if w.contains("/x/parapet-firmware-qemu")), "{d:?}");
        }
    }
}
