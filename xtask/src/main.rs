//! `cargo xtask <command>`: project automation that does its own set-up.
//!
//! * `cargo xtask test` — the README's test command: installs what it needs
//!   (the `thumbv7em-none-eabihf` target via rustup; `qemu-system-arm` and `chromium` (the
//!   headless browser of the replay-page test) via apt-get when missing and root), runs every
//!   host test, builds
//!   `parapet-core` and the firmware for Cortex-M4F in release, checks the
//!   firmware's flash/RAM budget (F405 ≤ 242 KiB / 64 KiB, with the excess over the 128 KiB target printed; the MATEKH743 image ≤ 256 KiB /
//!   64 KiB), checks `parapet_core::fmath` on the Cortex-M4F in QEMU bit for
//!   bit against the host (`tests/cortex-m4`, see `m4.rs`), and runs the processor-in-the-loop flight and the
//!   Slurm job-array campaign test (`host-sim/slurm/ci_test.sh`; installs slurmctld,
//!   slurmd and munge via apt-get when missing); creates the Python venv of the ground-station
//!   client tests (`target/venv`, pinned pymavlink/pyulog/MAVProxy/mavsdk, see `venv.rs`).
//!   After the host tests, a bounded coverage-guided fuzz run of every `tests/fuzz` target
//!   (see `fuzz.rs`).
//! * `cargo xtask fuzz [TARGET|all] [--time S | --runs N]` — a fuzz campaign (see `fuzz.rs`
//!   and `docs/reliability.md`).
//! * `cargo xtask size [ELF] [--flash-max BYTES] [--ram-max BYTES] [--by-source] [--features LIST]`
//!   — print the flash and static-RAM use of the F405 board image (or of `ELF`); exit 1 over a
//!   limit; `--by-source`: the code bytes per source area from the line table (`by_source.rs`);
//!   `--features`: the image built with these cargo features added (e.g. `onboard-log`).
//! * `cargo xtask m4` — only the Cortex-M4F fmath bit-exactness step of `cargo xtask test`
//!   (`tests/cortex-m4` in QEMU, see `m4.rs`).
//! * `cargo xtask venv` — only the Python venv of the ground-station client tests (`venv.rs`).
//! * `cargo xtask params [--out FILE | --firmware]` — the parameter table as ground-station metadata JSON
//!   (see `core/src/params/`; `--firmware`: the copy the firmware serves by MAVLink FTP).
//! * `cargo xtask bench [--long]` — run every criterion benchmark (short
//!   measurement times unless `--long`) and print one summary table (see `bench.rs`).
//!
//! Environment: `PARAPET_PROPTEST_CASES` (default 10000 here) sets the number of
//! cases of each safety-invariant property; `PROPTEST_RNG_SEED` (proptest's own variable,
//! default [`PROPTEST_SEED`] here) their seed, so a landing never depends on the draw. A
//! large randomized run is `PROPTEST_RNG_SEED=<any> PARAPET_PROPTEST_CASES=<n> cargo test ...`.

mod bench;
mod by_source;
mod elf;
mod fuzz;
mod m4;
mod params;
mod venv;

use std::path::{Path, PathBuf};

use std::process::{Command, ExitCode};

const TARGET: &str = "thumbv7em-none-eabihf";

/// The seed of every proptest property in `cargo xtask test` (CI) unless `PROPTEST_RNG_SEED`
/// is set: the properties draw the same cases on every machine and every run.
const PROPTEST_SEED: u64 = 20261204;

/// Flash target of the F405 image, bytes (issue 22: ≤ 128 KiB). Reported by `size` and `test`
/// with the excess; NOT met since the flight modes, RC input, parameter storage, calibration,
/// motor test, battery and the onboard log landed (2026-12-02: 155,608 B before the size cuts
/// b293c3d / b2cfb1e / 8ed014b / f3a779e (-15.3 KB), 181,656 B at f3a779e, after the setup
/// services were wired in (storage task + sequential-storage, calibration, battery ADC: ≈ +38 KB)).
const FLASH_TARGET: u64 = 128 * 1024;
/// Flash limit CI enforces on the F405 image, bytes: a regression guard ≤ 2 KiB above today's
/// size — 219,472 B on 2026-12-06 with the jerk-limited trajectory guidance (issue 35, +≈ 26 KB
/// of code over 193,492 B; `cargo xtask size`). The product budget (DEVELOPERS.md) is 512 KiB,
/// half of the STM32F405RG's 1 MiB; the 128 KiB target of issue 22 is missed (`firmware/README.md`
/// § Budgets). Raised to 218 KiB on 2026-12-06 (issue 41): 221,160 B before → 222,480 B with
/// GPS_RAW_INT, VFR_HUD, the pre-arm check and missions stored field for field (+1,320 B).
/// Raised to 221 KiB the same day: 224,476 B with the braking-distance filter variant (issue
/// 36) and the trajectory's tracking cascade. Raised to 225 KiB (230,400 B) the same day (issue
/// 41): 228,468 B with the mission items flown (holds, loiters, delay, yaw, speed; the segmented
/// executor), DO_REPOSITION and in-flight PARAM_SET (+3,992 B), 229,492 B on main at 31a9b08
/// (the trajectory tracking's speed limits, the braking filter's shortcut). Raised to 227 KiB
/// (232,448 B) the same day: 229,220 B after the board trait and the one-line parameter entries
/// (issue 37, −288 B), 230,408 B with the standard modes protocol (issue 41: AVAILABLE_MODES,
/// CURRENT_MODE, AVAILABLE_MODES_MONITOR, DO_SET_STANDARD_MODE, +1,188 B). Raised to 230 KiB
/// (235,520 B) the same day (issue 36): 233,688 B with the speed governor (`GOV_*`, its
/// projection, the governed mission clock and the log fields; +3,280 B over 230,408 B).
/// Raised to 233 KiB (238,592 B) the same day (issue 39): 236,848 B with the GPS_INPUT and
/// VISION_POSITION_ESTIMATE inputs and the position-source monitor (+2,432 B over 234,416 B on
/// main at 4977cec; static RAM 37,520 B, +48 B). Raised to 270 KiB (276,480 B) the same day
/// (issue 41): 274,288 B with the component metadata served by MAVLink FTP — the parameter
/// metadata JSON in flash (`firmware/metadata/parameters.json`, 34,499 B for 97 parameters;
/// not xz-compressed, `docs/ground-station.md` § Component metadata by MAVLink FTP), the
/// read-only FTP server and COMPONENT_METADATA (static RAM 37,680 B). Raised to 280 KiB (286,720 B) the same day
/// (issue 38): 282,996 B (+8,708 B) with the on-board replanner (its grid A*, the replanner task, its
/// STATUSTEXT and log string). Raised to 288 KiB (294,912 B) the same day (issue 39): 293,468 B
/// on main at 2a580b7 plus the navigation filter run on the vehicle (`core::nav` in the outer
/// stage, its sample mailbox, ESTIMATOR_STATUS; +9,816 B measured before that rebase).
/// Raised to 290 KiB (296,960 B) on 2026-12-07 (issue 35): 295,860 B (+1,608 B over 294,252 B
/// on main at 6c486f4; static RAM 68,772 B, +24 B) with Return and offboard position
/// set-points flown on the mission's trajectory (`core::outer::guidance::lent`). Raised to
/// 292 KiB (299,008 B) the same day (issue 38): 296,948 B on main at 5b5dba5 (+1,012 B over
/// 295,936 B) with the replanned path served as the downloadable mission (the plan id in
/// MISSION_CURRENT / MISSION_COUNT, the stored plan rewritten on a replan) and the unproven
/// track's closing-in estimate (issue 36), 12 B under the old guard. Raised to 296 KiB (303,104 B)
/// on 2026-12-07 (issues 38, 39): 300,340 B on main at 0bfcfe9 (+3,392 B over 296,948 B) with the
/// firmware's position-reset hand-over and VIO ODOMETRY into the navigation filter (+1,488 B) and
/// the replanner's 2.5-D grid and flight levels (+1,920 B), 1,332 B over the old guard.
/// Raised to 300 KiB (307,200 B) on 2026-12-07 (issue 39): 303,312 B (+2,972 B over 300,340 B) with
/// the mapped-obstacle margin on the vehicle — the error bound's `f64` drift bound (`libm` `log1p`
/// and `sqrt`, soft-float division; rewriting its comparisons and conversion saved nothing).
/// Raised to 304 KiB (311,296 B) on 2026-12-07 (issues 36, 39): 307,336 B (+2,864 B over
/// 304,472 B on main at 6230de9) with the barometer height from HIL_SENSOR into the navigation
/// filter (the router's decoding, the height update now linked in, the drift in the bound) and
/// `PCP_KEEP_NEAR` (its code and its entry in the served parameter metadata).
/// Raised to 308 KiB (315,392 B) on 2026-12-08 (issue 38): 312,840 B (+4,056 B over 308,784 B
/// on main at 4e2c138) with a replan spliced into a plan with holds and actions, and paths
/// longer than the cascade's 64 waypoints streamed in (`Trajectory::extend`, the guidance's
/// `stream_path`, the executor's windows).
const FLASH_BUDGET: u64 = 308 * 1024;
/// Static RAM limit CI enforces (.data + .bss), bytes: a regression guard above today's
/// 36,968 B (2026-12-06: the mission trajectory, `Trajectory<64>`, 3.3 KB, joined the outer
/// stage; mission items kept field for field). The product budget (DEVELOPERS.md) is 96 KiB of the F405's 128 KiB SRAM; issue 22's
/// 32 KiB guard held until then. Raised to 64 KiB (2026-12-06, issue 38): 63,176 B counted
/// (every NOBITS section): 37,880 B of SRAM (.data 80 + .bss and .uninit 37,800) and 25,296 B of the
/// F405's 64 KiB CCM (`.ccmram`: the on-board replanner's planner and request,
/// `firmware/src/board/ccm.rs`), which the 96 KiB SRAM budget does not include. Raised to 68 KiB
/// the same day (issue 39): 68,708 B counted after the rebase on 2a580b7 (+5,444 B in SRAM: the navigation filter's state in
/// the outer stage — its 128-entry history, the 9×9 covariance — and the 16-sample mailbox), so
/// ≈ 43.3 KiB of SRAM, within the 96 KiB budget. Raised to 76 KiB on 2026-12-07 (issue 38): 76,980 B
/// with the replanner's 2.5-D grid (+8,196 B of height columns, all in the CCM: 33,504 B of its 64 KiB).
/// Raised to 82 KiB on 2026-12-08 (issue 38): 81,828 B with the mission store doubled to 128
/// items (+4,608 B of SRAM: the upload and the accepted plan, 36 B an item each), so a mission
/// longer than the cascade's 64 waypoints is flown; ≈ 48 KiB of SRAM, within the 96 KiB budget.
const RAM_BUDGET: u64 = 82 * 1024;
/// Flash budget of the MATEKH743 image (`board-h743`), bytes: 256 KiB of its 2 MiB (issue 22:
/// the second board's budget, stated; twice the F405's, for the larger H7 HAL). Raised to
/// 272 KiB (278,528 B) on 2026-12-06 (issue 41): 263,684 B with the component metadata served
/// by MAVLink FTP (the same ~37 KB as on the F405). Raised to 276 KiB (282,624 B) the same day
/// (issue 39): 281,184 B with the navigation filter on the vehicle (on main at 2a580b7).
/// Raised to 280 KiB (286,720 B) on 2026-12-07 (issue 35): 283,612 B in CI on main at 697e8ae,
/// with Return and offboard position set-points flown on the mission's trajectory (the F405's
/// guard went to 290 KiB for the same code; the H743's was left at 276 KiB and CI failed on it).
/// Raised to 284 KiB (290,816 B) on 2026-12-07 (issues 38, 39): 288,216 B on main at 0bfcfe9
/// (built with CI's path remapping), the same reset hand-over, VIO routing and 2.5-D replanner as
/// the F405's 296 KiB. Raised to 288 KiB (294,912 B) on 2026-12-07 (issue 39): 291,156 B with the
/// mapped-obstacle margin on the vehicle (+2,916 B over 288,240 B; the F405's 300 KiB).
/// Raised to 292 KiB (299,008 B) on 2026-12-07 (issues 36, 39): 294,892 B (+2,568 B over
/// 292,324 B), 20 B under the old guard, with the same barometer input and `PCP_KEEP_NEAR` as
/// the F405's 304 KiB. Raised to 296 KiB (303,104 B) on 2026-12-08 (issue 38): 300,588 B (+4,456 B
/// over 296,132 B) with the same replan splicing and path streaming as the F405's 308 KiB.
const H743_FLASH_BUDGET: u64 = 296 * 1024;
/// Static RAM budget of the MATEKH743 image, bytes: 64 KiB of its 512 KiB AXI SRAM; 68 KiB since
/// issue 39's navigation filter (65,660 B counted at 2a580b7; 60,160 B before the filter); 76 KiB
/// since the replanner's 2.5-D grid (issue 38: 73,932 B, +8,196 B of height columns, of 512 KiB);
/// 80 KiB since the 128-item mission store (issue 38: 78,772 B, +4,608 B).
const H743_RAM_BUDGET: u64 = 80 * 1024;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("test") => test(),
        Some("size") => size_cmd(&args[1..]),
        Some("bench") => bench::bench(&args[1..]),
        Some("fuzz") => fuzz::fuzz(&args[1..]),
        Some("params") => params::params(&args[1..]),
        Some("venv") => venv::ensure()
            .map(|py| eprintln!("xtask: ground-station clients in {}", py.display()))
            .and_then(|()| venv::ensure_mavsdk4())
            .map(|py| eprintln!("xtask: MAVSDK-Python 4 in {}", py.display())),
        Some("m4") => ensure_target().and_then(|()| ensure_qemu()).and_then(|()| m4::check()),
        _ => {
            eprintln!(
                "usage: cargo xtask <test|size [ELF] [--flash-max B] [--ram-max B] [--by-source] [--features LIST]|bench [--long]|fuzz [TARGET|all] [--time S | --runs N]|params [--out FILE | --firmware]|venv|m4>"
            );
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

fn run(what: &str, cmd: &mut Command) -> Result<(), String> {
    eprintln!("\n== xtask: {what}\n   $ {cmd:?}");
    let status = cmd.current_dir(root()).status().map_err(|e| format!("{what}: cannot start: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed ({status})"))
    }
}

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

fn ensure_target() -> Result<(), String> {
    let out = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .map_err(|e| format!("rustup not found ({e}); install the {TARGET} target by hand"))?;
    if String::from_utf8_lossy(&out.stdout).lines().any(|l| l.trim() == TARGET) {
        return Ok(());
    }
    run("install the Cortex-M4F target", Command::new("rustup").args(["target", "add", TARGET]))
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false)
}

/// Make sure `qemu-system-arm` is on PATH: apt-get install it when root, else stop
/// with the exact command to run.
fn ensure_qemu() -> Result<(), String> {
    ensure_apt("qemu-system-arm", "qemu-system-arm")
}

/// Make sure Debian's `chromium` runs (the headless browser of `host-sim/tests/replay_page.rs`,
/// which looks at the report's `replay.html`): apt-get install it when root, else stop with the
/// exact command to run. Returns the binary for `PARAPET_CHROMIUM`.
fn ensure_chromium() -> Result<PathBuf, String> {
    ensure_apt("chromium", "chromium")?;
    let usr = PathBuf::from("/usr/bin/chromium");
    Ok(if usr.is_file() { usr } else { PathBuf::from("chromium") })
}

/// Make sure `program --version` runs: apt-get install `package` when root, else stop with the
/// exact command to run.
fn ensure_apt(program: &str, package: &str) -> Result<(), String> {
    let have = || Command::new(program).arg("--version").output().is_ok_and(|o| o.status.success());
    if have() {
        return Ok(());
    }
    if !is_root() {
        return Err(format!(
            "{program} is missing; run: sudo apt-get update && sudo apt-get install -y {package}"
        ));
    }
    run("apt-get update", Command::new("apt-get").args(["update", "-qq"]))?;
    run(
        &format!("install {package}"),
        Command::new("apt-get")
            .args(["install", "-y", "-qq", "--no-install-recommends", package])
            .env("DEBIAN_FRONTEND", "noninteractive"),
    )?;
    if have() {
        Ok(())
    } else {
        Err(format!("{program} still not runnable after apt-get install"))
    }
}

/// The Slurm test (`host-sim/slurm/ci_test.sh`): a one-node cluster on localhost flies a
/// small campaign as a 4-task job array; the merged result must be byte-identical to
/// the single-process run. Needs root (it installs slurmctld/slurmd/munge when missing
/// and starts the daemons); the `parapet` binary is the one the host tests built.
fn slurm_test() -> Result<(), String> {
    if !is_root() {
        return Err("the Slurm test needs root (apt-get, daemons): run \
                    sudo host-sim/slurm/ci_test.sh target/debug/parapet"
            .into());
    }
    // The host tests have just built it (parapet-sim's CLI tests run the binary); build it
    // only when it is not there, so the step does not rebuild with other features.
    let bin = target_dir().join("debug").join("parapet");
    if !bin.is_file() {
        run(
            "build parapet (test profile)",
            cargo().args(["build", "--profile", "test", "-p", "parapet-sim", "--bin", "parapet"]),
        )?;
    }
    run("Slurm job-array campaign test", Command::new(root().join("host-sim/slurm/ci_test.sh")).arg(bin))
}

/// Cargo's target directory: `CARGO_TARGET_DIR` when set, else `target/` of the workspace.
/// Every path to a built artifact goes through it.
pub(crate) fn target_dir() -> PathBuf {
    std::env::var("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|_| root().join("target"))
}

/// The QEMU build is `--release`; the STM32F405 image is the `firmware` profile (release with the
/// core size-optimised, see the workspace Cargo.toml).
fn firmware_elf(features: Option<&str>) -> PathBuf {
    if features == Some("board-qemu") {
        target_dir().join(TARGET).join("release").join("parapet-firmware-qemu")
    } else if features == Some("board-h743") {
        target_dir().join(TARGET).join("firmware").join("parapet-firmware-h743")
    } else {
        target_dir().join(TARGET).join("firmware").join("parapet-firmware")
    }
}

/// `--remap-path-prefix` for the crates.io sources: the panic locations of dependencies name
/// their files by absolute path (`$CARGO_HOME/registry/src/index.crates.io-…/crate-x.y/src/…`,
/// ~100 bytes each, ~2.7 KB of the F405 image); remapped they read `/cargo/crate-x.y/src/…`.
/// Only the `firmware` profile build (this image) gets the flag, through the target's
/// RUSTFLAGS variable, so the other builds keep their caches.
fn registry_remap_flags() -> String {
    let home = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo")));
    let Some(src) = home.map(|h| h.join("registry").join("src")) else { return String::new() };
    let Ok(dirs) = std::fs::read_dir(&src) else { return String::new() };
    let mut flags: Vec<String> =
        dirs.flatten().map(|d| format!("--remap-path-prefix={}=/cargo", d.path().display())).collect();
    flags.sort();
    flags.join(" ")
}

fn build_firmware() -> Result<PathBuf, String> {
    build_firmware_with(None)
}

/// The F405 image with the cargo `features` added (`cargo xtask size --features …`).
fn build_firmware_with(features: Option<&str>) -> Result<PathBuf, String> {
    let mut extra = vec!["--bin", "parapet-firmware"];
    if let Some(f) = features {
        extra.extend(["--features", f]);
    }
    build_image("STM32F405", &extra)?;
    Ok(firmware_elf(None))
}

/// The MATEKH743 image (profile firmware, `board-h743`): the same tasks on the second board.
fn build_h743_firmware() -> Result<PathBuf, String> {
    build_image(
        "MATEKH743",
        &["--no-default-features", "--features", "board-h743", "--bin", "parapet-firmware-h743"],
    )?;
    Ok(firmware_elf(Some("board-h743")))
}

/// `cargo build --profile firmware` of the firmware crate for the Cortex-M target with the
/// registry path remapping, plus `extra` arguments (board features, binary).
fn build_image(board: &str, extra: &[&str]) -> Result<(), String> {
    let mut c = cargo();
    c.env("CARGO_TARGET_THUMBV7EM_NONE_EABIHF_RUSTFLAGS", registry_remap_flags())
        .args(["build", "--profile", "firmware", "-p", "parapet-firmware", "--target", TARGET])
        .args(extra);
    run(&format!("build the firmware (profile firmware, {board})"), &mut c)
}

/// `cargo xtask size [ELF] [--flash-max BYTES] [--ram-max BYTES]`.
fn size_cmd(args: &[String]) -> Result<(), String> {
    let a = elf::parse_args(args)?;
    let elf = match &a.elf {
        Some(p) => p.clone(),
        None => {
            ensure_target()?;
            build_firmware_with(a.features.as_deref())?
        }
    };
    let s = print_size(&elf)?;
    if a.by_source {
        by_source::print(&elf, 40)?;
    }
    let over = elf::over_limits(&s, &a);
    if over.is_empty() {
        Ok(())
    } else {
        Err(format!("{}: over the limit: {}", elf.display(), over.join(", ")))
    }
}

fn size() -> Result<(u64, u64), String> {
    ensure_target()?;
    let elf = build_firmware()?;
    let s = print_size(&elf)?;
    Ok((s.flash, s.ram()))
}

/// Print the flash and static-RAM use of `elf`.
fn print_size(elf: &Path) -> Result<elf::Sizes, String> {
    print_size_of(elf, FLASH_BUDGET, RAM_BUDGET)
}

/// Print the flash and static-RAM use of `elf` against the given budgets (bytes).
fn print_size_of(elf: &Path, flash_budget: u64, ram_budget: u64) -> Result<elf::Sizes, String> {
    let bytes = std::fs::read(elf).map_err(|e| format!("{}: {e}", elf.display()))?;
    let s = elf::sizes(&bytes).map_err(|e| format!("{}: {e}", elf.display()))?;
    println!(
        "firmware {}: flash {} B ({:.1} KiB of {} KiB), static RAM {} B ({:.1} KiB of {} KiB; .data {} + .bss {})",
        elf.display(),
        s.flash,
        s.flash as f64 / 1024.0,
        flash_budget / 1024,
        s.ram(),
        s.ram() as f64 / 1024.0,
        ram_budget / 1024,
        s.data,
        s.bss
    );
    Ok(s)
}

/// Build the `board-qemu` firmware (QEMU netduinoplus2, processor-in-the-loop) and return its ELF.
fn build_qemu_firmware() -> Result<PathBuf, String> {
    run(
        "build the QEMU firmware (release, board-qemu, for processor-in-the-loop)",
        cargo().args([
            "build",
            "--release",
            "-p",
            "parapet-firmware",
            "--target",
            TARGET,
            "--no-default-features",
            "--features",
            "board-qemu",
            "--bin",
            "parapet-firmware-qemu",
        ]),
    )?;
    let elf = firmware_elf(Some("board-qemu"));
    if elf.is_file() {
        Ok(elf)
    } else {
        Err(format!("the QEMU firmware build succeeded but {} is missing", elf.display()))
    }
}

fn test() -> Result<(), String> {
    ensure_target()?;
    // The processor-in-the-loop tests (tests/tests/pil_*.rs, run with the host tests) fly this
    // ELF in qemu-system-arm: both are needed first.
    ensure_qemu()?;
    let qemu_elf = build_qemu_firmware()?;
    // The headless browser that looks at the report's replay.html (host-sim/tests/replay_page.rs).
    let chromium = ensure_chromium()?;
    // The ground-station clients (pymavlink, pyulog, MAVProxy, mavsdk) of tests/tests/gcs_clients.rs.
    let python = venv::ensure()?;
    // MAVSDK-Python 4 (the docs' snippet), a venv of its own.
    let mavsdk4 = venv::ensure_mavsdk4()?;
    let cases = std::env::var("PARAPET_PROPTEST_CASES").unwrap_or_else(|_| "10000".into());
    let seed = std::env::var("PROPTEST_RNG_SEED").unwrap_or_else(|_| PROPTEST_SEED.to_string());
    run(
        "host tests (workspace, processor-in-the-loop and ground-station clients included)",
        cargo()
            .args(["test", "--workspace", "--exclude", "parapet-firmware"])
            .env("PARAPET_PROPTEST_CASES", &cases)
            .env("PROPTEST_RNG_SEED", &seed)
            .env("PARAPET_FIRMWARE_QEMU_ELF", &qemu_elf)
            .env("PARAPET_PYTHON", &python)
            .env("PARAPET_MAVSDK4_PYTHON", &mavsdk4)
            .env("PARAPET_CHROMIUM", &chromium),
    )?;
    slurm_test()?;
    // The library's unit tests and the host-side link tests of firmware/tests (gcs_services,
    // gcs_link, …; qemu_pil's test is #[ignore]d there and run below with the ELF).
    run("firmware host tests", cargo().args(["test", "-p", "parapet-firmware", "--lib", "--tests"]))?;
    fuzz::smoke()?;
    run(
        "firmware QEMU smoke test",
        cargo()
            .args(["test", "-p", "parapet-firmware", "--test", "qemu_pil", "--", "--ignored"])
            .env("PARAPET_QEMU_ELF", &qemu_elf),
    )?;
    // fmath (VSQRT.F32, sincosf, ...) on the Cortex-M4F, bit for bit against the host build.
    m4::check()?;
    run(
        "build parapet-core for Cortex-M4F",
        cargo().args(["build", "--release", "-p", "parapet-core", "--target", TARGET]),
    )?;
    let (flash, ram) = size()?;
    if flash > FLASH_TARGET {
        println!(
            "F405 flash {flash} B is over the issue's {} KiB target by {} B (CI limit {} KiB)",
            FLASH_TARGET / 1024,
            flash - FLASH_TARGET,
            FLASH_BUDGET / 1024
        );
    }
    if flash > FLASH_BUDGET || ram > RAM_BUDGET {
        return Err(format!(
            "firmware over budget: flash {flash} B (max {FLASH_BUDGET}), RAM {ram} B (max {RAM_BUDGET})"
        ));
    }
    // The second board: same tasks, its own budget.
    let h743 = build_h743_firmware()?;
    let s = print_size_of(&h743, H743_FLASH_BUDGET, H743_RAM_BUDGET)?;
    if s.flash > H743_FLASH_BUDGET || s.ram() > H743_RAM_BUDGET {
        return Err(format!(
            "MATEKH743 firmware over budget: flash {} B (max {H743_FLASH_BUDGET}), RAM {} B (max {H743_RAM_BUDGET})",
            s.flash,
            s.ram()
        ));
    }
    eprintln!("\nxtask: all checks passed");
    Ok(())
}
