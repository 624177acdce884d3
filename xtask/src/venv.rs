//! The Python venv of the ground-station client tests (`tests/tests/gcs_clients.rs`):
//! `<target>/venv` created with `python3 -m venv` and the pinned clients of
//! `tests/python/requirements.txt` (pymavlink, pyulog, MAVProxy, mavsdk) installed with pip,
//! `--no-deps` (the file pins every package the clients import, dependencies included; see its
//! header for what MAVProxy's own requirements would add) and `--no-cache-dir` (no second copy of
//! the wheels on disk).
//! On a fresh Debian/Ubuntu machine `python3-venv` (and `python3-pip`'s ensurepip) may be
//! missing: installed with apt-get when root, as QEMU is; otherwise the command to run is
//! printed. Re-used when the requirements are already installed (a stamp file holds the
//! requirements the venv was made from).
//!
//! A second venv, `<target>/venv-mavsdk4`, holds MAVSDK-Python 4 (`tests/python/requirements-mavsdk4.txt`:
//! the native binding, another API than the 3.x gRPC wrapper of the first venv, same package
//! name, so the two cannot share one venv): the docs' MAVSDK 4 snippet is run by
//! `gcs_clients::mavsdk4_snippet_of_the_docs_runs_as_written`.
//!
//! May import: std, [`super`] (run, root, target dir).

use std::path::PathBuf;
use std::process::Command;

use super::{is_root, root, run, target_dir};

/// The requirements file (pinned versions).
const REQUIREMENTS: &str = "tests/python/requirements.txt";

/// MAVSDK-Python 4's requirements (pinned).
const REQUIREMENTS_MAVSDK4: &str = "tests/python/requirements-mavsdk4.txt";

/// The venv's python, created and filled when needed.
pub fn ensure() -> Result<PathBuf, String> {
    make("venv", REQUIREMENTS)
}

/// The MAVSDK-Python 4 venv's python, created and filled when needed.
pub fn ensure_mavsdk4() -> Result<PathBuf, String> {
    make("venv-mavsdk4", REQUIREMENTS_MAVSDK4)
}

/// `<target>/NAME` with the pinned packages of `requirements` (see the module docs).
fn make(name: &str, requirements: &str) -> Result<PathBuf, String> {
    let venv = target_dir().join(name);
    let py = venv.join("bin/python");
    let req_path = root().join(requirements);
    let req =
        std::fs::read_to_string(&req_path).map_err(|e| format!("cannot read {}: {e}", req_path.display()))?;
    let stamp = venv.join("parapet-requirements.txt");
    if py.is_file() && std::fs::read_to_string(&stamp).is_ok_and(|s| s == req) {
        return Ok(py);
    }
    let have_venv = || {
        Command::new("python3")
            .args(["-c", "import venv, ensurepip"])
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if !have_venv() {
        if !is_root() {
            return Err("python3 with venv/ensurepip is missing; run: sudo apt-get update && sudo apt-get \
                        install -y python3 python3-venv"
                .into());
        }
        run("apt-get update", Command::new("apt-get").args(["update", "-qq"]))?;
        run(
            "install python3-venv",
            Command::new("apt-get").args([
                "install",
                "-y",
                "-qq",
                "--no-install-recommends",
                "python3",
                "python3-venv",
            ]),
        )?;
    }
    // `--clear`: a venv made from other requirements starts empty (no stale packages).
    run("create the Python venv", Command::new("python3").args(["-m", "venv", "--clear"]).arg(&venv))?;
    run(
        "pip install the ground-station clients",
        Command::new(venv.join("bin/pip"))
            .args(["install", "-q", "--no-deps", "--no-cache-dir", "--disable-pip-version-check", "-r"])
            .arg(&req_path),
    )?;
    std::fs::write(&stamp, req).map_err(|e| format!("cannot write {}: {e}", stamp.display()))?;
    Ok(py)
}
