//! `cargo xtask fuzz`: builds the libFuzzer targets of `tests/fuzz/` on the stable toolchain and
//! runs them. Owns only the fuzz build and runs; imports nothing from the project's crates.
//!
//! * `cargo xtask fuzz [TARGET|all] [--time S | --runs N]` — a campaign (default: every target,
//!   60 s each). `cargo xtask fuzz --smoke` runs exactly the step of `cargo xtask test`. Corpus growth goes to `tests/fuzz/corpus-run/TARGET` (git-ignored), crash
//!   inputs to `tests/fuzz/artifacts/TARGET/`; the committed seeds (`corpus/TARGET`) and crash
//!   regressions (`regressions/TARGET`) are read first, so an old crash fails at once.
//! * [`smoke`] — the bounded run inside `cargo xtask test` (each target [`SMOKE_SECONDS`] s
//!   from the committed seeds, fresh working corpus); any crash, hang (> [`TIMEOUT_S`] s for one
//!   input) or invariant violation fails the test command.
//!
//! The build needs no nightly and no cargo-fuzz: rustc's `-Cpasses=sancov-module` plus
//! SanitizerCoverage options give libFuzzer its coverage feedback (inline 8-bit counters, PC
//! table, comparison tracing), `--cfg fuzzing` is what cargo-fuzz sets, and debug assertions and
//! overflow checks stay on. `libfuzzer-sys` compiles libFuzzer itself with the C++ compiler
//! (g++ here). No address sanitizer: that needs nightly; the code under test has no `unsafe`
//! (safe Rust's bounds and overflow checks are the memory-safety oracle).

use std::path::PathBuf;
use std::process::Command;

use crate::{cargo, root, run};

/// The fuzz targets (binaries of `tests/fuzz`) and the largest input each gets, bytes.
pub const TARGETS: [(&str, usize); 7] = [
    ("frame_parser", 1024),
    ("link", 4096),
    ("crsf", 2048),
    ("sbus", 2048),
    ("scene_toml", 8192),
    ("path_json", 4096),
    ("replay_csv", 4096),
];
/// Seconds per target in `cargo xtask test`.
pub const SMOKE_SECONDS: u32 = 11;
/// One input running longer than this is a hang (libFuzzer `-timeout`), seconds.
pub const TIMEOUT_S: u32 = 10;

/// rustc flags of the instrumented build (what cargo-fuzz passes with `--sanitizer none`).
const RUSTFLAGS: &str = "-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks";

fn fuzz_dir() -> PathBuf {
    root().join("tests").join("fuzz")
}

fn host_triple() -> Result<String, String> {
    let out = Command::new("rustc").arg("-vV").output().map_err(|e| format!("rustc -vV: {e}"))?;
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .find_map(|l| l.strip_prefix("host: ").map(str::to_string))
        .ok_or_else(|| "rustc -vV printed no host triple".into())
}

/// Builds every target (release, instrumented) and returns the directory of the binaries.
///
/// `--target` is explicit so that RUSTFLAGS reach only the target code, not build scripts and
/// proc macros (which would not link without libFuzzer); the target dir is the fuzz crate's own.
pub fn build() -> Result<PathBuf, String> {
    let triple = host_triple()?;
    let target_dir = fuzz_dir().join("target");
    run(
        "build the fuzz targets (tests/fuzz, libFuzzer, stable toolchain)",
        cargo()
            .args(["build", "--release", "--bins", "--manifest-path"])
            .arg(fuzz_dir().join("Cargo.toml"))
            .args(["--target", &triple])
            .env("RUSTFLAGS", RUSTFLAGS)
            .env("CARGO_TARGET_DIR", &target_dir),
    )?;
    Ok(target_dir.join(triple).join("release"))
}

/// Runs one target: `-max_total_time` (`time_s`) or `-runs` (`runs`), working corpus `work`.
fn run_target(
    bin_dir: &std::path::Path,
    target: &str,
    max_len: usize,
    limit: &str,
    work: &std::path::Path,
) -> Result<(), String> {
    let dir = fuzz_dir();
    let artifacts = dir.join("artifacts").join(target);
    std::fs::create_dir_all(work).map_err(|e| format!("{}: {e}", work.display()))?;
    std::fs::create_dir_all(&artifacts).map_err(|e| format!("{}: {e}", artifacts.display()))?;
    let mut cmd = Command::new("nice");
    cmd.arg("-n").arg("10").arg(bin_dir.join(target));
    cmd.arg(limit)
        .arg(format!("-max_len={max_len}"))
        .arg(format!("-timeout={TIMEOUT_S}"))
        .arg("-print_final_stats=1")
        .arg(format!("-artifact_prefix={}/", artifacts.display()))
        .arg(work);
    for seeds in ["corpus", "regressions"] {
        let d = dir.join(seeds).join(target);
        if d.is_dir() {
            cmd.arg(d);
        }
    }
    run(&format!("fuzz {target} ({limit})"), &mut cmd).map_err(|e| {
        format!("{e}: a crash, hang or invariant violation; the input is in {}", artifacts.display())
    })
}

/// `cargo xtask fuzz [TARGET|all] [--time S | --runs N]`.
pub fn fuzz(args: &[String]) -> Result<(), String> {
    let mut which = "all".to_string();
    let mut limit = "-max_total_time=60".to_string();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--smoke" => return smoke(),
            "--time" | "--runs" => {
                let v = it.next().ok_or_else(|| format!("option {a}: needs a value"))?;
                let n: u64 = v.parse().map_err(|_| format!("option {a}: `{v}` is not a whole number ≥ 1"))?;
                if n == 0 {
                    return Err(format!("option {a}: must be ≥ 1, got 0"));
                }
                limit = if a == "--time" { format!("-max_total_time={n}") } else { format!("-runs={n}") };
            }
            t if TARGETS.iter().any(|(n, _)| *n == t) || t == "all" => which = t.to_string(),
            other => {
                let names: Vec<&str> = TARGETS.iter().map(|(n, _)| *n).collect();
                return Err(format!(
                    "unknown argument `{other}`; usage: cargo xtask fuzz [{}|all] [--time S | --runs N] | --smoke",
                    names.join("|")
                ));
            }
        }
    }
    let bins = build()?;
    for (t, max_len) in TARGETS {
        if which == "all" || which == t {
            run_target(&bins, t, max_len, &limit, &fuzz_dir().join("corpus-run").join(t))?;
        }
    }
    Ok(())
}

/// The bounded fuzz step of `cargo xtask test`: every target for [`SMOKE_SECONDS`] from the
/// committed seeds and regressions, with a fresh working corpus.
pub fn smoke() -> Result<(), String> {
    let t0 = std::time::Instant::now();
    let bins = build()?;
    let built = t0.elapsed().as_secs_f64();
    let smoke_dir = fuzz_dir().join("target").join("smoke-corpus");
    let _ = std::fs::remove_dir_all(&smoke_dir);
    for (t, max_len) in TARGETS {
        run_target(&bins, t, max_len, &format!("-max_total_time={SMOKE_SECONDS}"), &smoke_dir.join(t))?;
    }
    eprintln!(
        "xtask: fuzz smoke run passed ({} targets × {SMOKE_SECONDS} s; build {built:.0} s, total {:.0} s)",
        TARGETS.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
