//! The Cortex-M4F program `tests/cortex-m4` (a workspace of its own): build it for
//! `thumbv7em-none-eabihf`, run it in `qemu-system-arm -machine netduinoplus2 -icount shift=0`,
//! collect what it prints by semihosting and judge the run.
//!
//! It first checks `parapet_core::fmath` on the target bit for bit against the host build of the
//! same source and against the target's libm (`tests/cortex-m4/src/check.rs`), then counts
//! instructions. `cargo xtask test` requires the checks ([`verify`]); `cargo xtask bench` also
//! prints the counts. Owns only this build-and-run; imports `crate::{cargo, root, TARGET}`.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use crate::{cargo, root, TARGET};

/// Longest run of the program in QEMU (it takes well under a second), s.
const TIMEOUT_S: u64 = 600;

/// Summary lines of the two fmath checks (prefixes, as `check.rs` prints them).
pub const CHECK_LINES: [&str; 2] = ["fmath check vs host:", "fmath check vs target libm:"];

/// The program's ELF (its own target dir under the workspace's `target/`, git-ignored).
fn elf() -> PathBuf {
    target_dir().join(TARGET).join("release").join("parapet-bench-m4")
}

fn target_dir() -> PathBuf {
    std::env::var("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| root().join("target"))
        .join("cortex-m4")
}

/// Builds `tests/cortex-m4` (release, the firmware's settings) and runs it in QEMU: its output
/// lines and QEMU's exit status. QEMU and the target must be installed.
pub fn build_and_run() -> Result<(Vec<String>, ExitStatus), String> {
    let dir = root().join("tests").join("cortex-m4");
    let mut build = cargo();
    build.args(["build", "--release", "--target-dir"]).arg(target_dir()).current_dir(&dir);
    eprintln!("\n== xtask: build the Cortex-M4F check and instruction-count program (tests/cortex-m4)\n   $ {build:?}");
    let status = build.status().map_err(|e| format!("cargo build in {}: {e}", dir.display()))?;
    if !status.success() {
        return Err(format!("building tests/cortex-m4 failed ({status})"));
    }
    eprintln!("== xtask: run it in qemu-system-arm -machine netduinoplus2 -icount shift=0");
    let mut child = Command::new("qemu-system-arm")
        .args(["-machine", "netduinoplus2", "-nographic", "-monitor", "none", "-icount", "shift=0"])
        .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
        .arg(elf())
        .stdout(Stdio::null())
        // QEMU writes the semihosting console to its stderr.
        .stderr(Stdio::piped())
        .stdin(Stdio::null())
        .spawn()
        .map_err(|e| format!("qemu-system-arm: {e}"))?;
    let out = child.stderr.take();
    let reader = std::thread::spawn(move || {
        out.map(|o| BufReader::new(o).lines().map_while(Result::ok).collect::<Vec<_>>()).unwrap_or_default()
    });
    let deadline = Instant::now() + Duration::from_secs(TIMEOUT_S);
    let status = loop {
        if let Some(st) = child.try_wait().map_err(|e| format!("qemu: {e}"))? {
            break st;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("the Cortex-M4F program did not finish within {TIMEOUT_S} s"));
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let lines = reader.join().map_err(|_| "reading QEMU's output failed".to_string())?;
    Ok((lines, status))
}

/// A passing run: exit status 0 (the program exits with a failure on any mismatch, hard fault
/// or panic), the last line `done`, and each check's summary line present with 0 mismatches.
pub fn verify(lines: &[String], exit_ok: bool) -> Result<(), String> {
    let fail = |why: &str| {
        let shown: Vec<&str> = lines.iter().rev().take(20).rev().map(String::as_str).collect();
        Err(format!("the Cortex-M4F program failed: {why}; its last lines:\n  {}", shown.join("\n  ")))
    };
    if !exit_ok {
        return fail("non-zero exit");
    }
    if lines.last().map(String::as_str) != Some("done") {
        return fail("it did not print `done` last");
    }
    for prefix in CHECK_LINES {
        let Some(line) = lines.iter().find(|l| l.starts_with(prefix)) else {
            return fail(&format!("no `{prefix}` line"));
        };
        if !line.ends_with(", 0 mismatches") || line.contains(" 0 comparisons") {
            return fail(&format!("`{line}`"));
        }
    }
    Ok(())
}

/// The step of `cargo xtask test`: build, run, [`verify`]; prints the check lines.
pub fn check() -> Result<(), String> {
    let t0 = Instant::now();
    let (lines, status) = build_and_run()?;
    verify(&lines, status.success())?;
    for l in lines.iter().filter(|l| CHECK_LINES.iter().any(|p| l.starts_with(p))) {
        eprintln!("   {l}");
    }
    eprintln!("xtask: Cortex-M4F fmath bit-exactness passed ({:.0} s)", t0.elapsed().as_secs_f64());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    const HOST_OK: &str = "fmath check vs host: 22078 comparisons (sqrtf, ...), 0 mismatches";
    const LIBM_OK: &str = "fmath check vs target libm: 58036 comparisons (sqrtf = libm::sqrtf), 0 mismatches";

    #[test]
    fn a_clean_run_passes() {
        assert_eq!(verify(&lines(&["calibration", HOST_OK, LIBM_OK, "x: mean 3", "done"]), true), Ok(()));
    }

    #[test]
    fn mismatches_exit_codes_and_missing_lines_fail() {
        let bad = "fmath check vs host: 22078 comparisons (sqrtf, ...), 1 mismatches";
        for (v, ok) in [
            (lines(&[bad, LIBM_OK, "done"]), true),
            (lines(&[HOST_OK, LIBM_OK, "done"]), false),
            (lines(&[HOST_OK, "done"]), true),
            (lines(&[HOST_OK, LIBM_OK]), true),
            (lines(&[HOST_OK, LIBM_OK, "PANIC: x", "done", "HARD FAULT"]), true),
            (lines(&["fmath check vs host: 0 comparisons (), 0 mismatches", LIBM_OK, "done"]), true),
            (lines(&[]), true),
        ] {
            assert!(verify(&v, ok).is_err(), "{v:?} {ok}");
        }
        let e = verify(&lines(&[bad, LIBM_OK, "done"]), true).unwrap_err();
        assert!(e.contains("1 mismatches") && e.contains("last lines"), "{e}");
    }
}
