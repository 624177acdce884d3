//! `cargo xtask bench [--long]`: run every criterion benchmark with short
//! measurement times (`--warm-up-time 1 --measurement-time 2`; `--long` keeps
//! criterion's defaults, 3 s + 5 s) and print one summary table from
//! criterion's `<target>/criterion/**/new/{benchmark,estimates}.json`.
//!
//! Benchmarks: `parapet-tests` — `cbf_filter` (closed-form filter vs CBF-QP
//! with clarabel), `cascade` (outer/inner steps of `FlightController`),
//! `plant` (RK4 step, whole office flight); `parapet-sim` — `planner`; and,
//! the speed-up of `parapet sweep` from `--jobs 1` to `--jobs 2`; and,
//! when `qemu-system-arm` is installed, the Cortex-M4F instruction counts of
//! `tests/cortex-m4` (QEMU `-icount`, see its README), checked against the
//! issue's goals (filter ≤ 2,000 instructions at K = 16, cascade ≤ 5,000).
//! The benches print their own detail tables (agreement with the QP, planner
//! statistics, flight summary) as they run; the summary adds the ratios:
//! QP time / filter time per obstacle count, real-time factor of the flight,
//! share of a 4 ms control period the host cascade uses.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Instant, SystemTime};

use crate::{cargo, root};

/// One benchmark result read from criterion's files.
#[derive(Clone, Debug)]
struct Estimate {
    /// `group/function/value` as criterion names it.
    id: String,
    group: String,
    function: String,
    value: Option<String>,
    /// Median time per iteration, ns, and its 95 % confidence interval.
    median_ns: f64,
    ci_ns: (f64, f64),
    /// Median absolute deviation of the samples, ns.
    mad_ns: f64,
}

fn target_dir() -> PathBuf {
    std::env::var("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|_| root().join("target"))
}

/// Run a cargo command, echoing its stdout line by line, and return the lines.
fn run_tee(what: &str, cmd: &mut Command) -> Result<Vec<String>, String> {
    eprintln!("\n== xtask: {what}\n   $ {cmd:?}");
    let mut child = cmd
        .current_dir(root())
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| format!("{what}: cannot start: {e}"))?;
    let mut lines = Vec::new();
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines() {
            let line = line.map_err(|e| format!("{what}: reading output: {e}"))?;
            println!("{line}");
            lines.push(line);
        }
    }
    let status = child.wait().map_err(|e| format!("{what}: {e}"))?;
    if status.success() {
        Ok(lines)
    } else {
        Err(format!("{what} failed ({status})"))
    }
}

/// The text of the JSON object that follows `"key":` in `s` (balanced braces).
fn object<'a>(s: &'a str, key: &str) -> Option<&'a str> {
    let start = s.find(&format!("\"{key}\":"))? + key.len() + 3;
    let rest = s[start..].trim_start();
    if !rest.starts_with('{') {
        return None;
    }
    let mut depth = 0usize;
    for (i, ch) in rest.char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    return Some(&rest[..=i]);
                }
            }
            _ => {}
        }
    }
    None
}

/// The number that follows `"key":` in `s`.
fn number(s: &str, key: &str) -> Option<f64> {
    let start = s.find(&format!("\"{key}\":"))? + key.len() + 3;
    let rest = s[start..].trim_start();
    let end = rest.find([',', '}']).unwrap_or(rest.len());
    rest[..end].trim().parse().ok()
}

/// The string that follows `"key":` in `s` (`None` for `null`).
fn string(s: &str, key: &str) -> Option<String> {
    let start = s.find(&format!("\"{key}\":"))? + key.len() + 3;
    let rest = s[start..].trim_start().strip_prefix('"')?;
    let mut out = String::new();
    let mut chars = rest.chars();
    while let Some(c) = chars.next() {
        match c {
            '"' => return Some(out),
            '\\' => out.push(chars.next()?),
            c => out.push(c),
        }
    }
    None
}

fn read_estimate(dir: &Path) -> Option<Estimate> {
    let bench = std::fs::read_to_string(dir.join("benchmark.json")).ok()?;
    let est = std::fs::read_to_string(dir.join("estimates.json")).ok()?;
    let median = object(&est, "median")?;
    let ci = object(median, "confidence_interval")?;
    Some(Estimate {
        id: string(&bench, "full_id")?,
        group: string(&bench, "group_id")?,
        function: string(&bench, "function_id").unwrap_or_default(),
        value: string(&bench, "value_str"),
        median_ns: number(median, "point_estimate")?,
        ci_ns: (number(ci, "lower_bound")?, number(ci, "upper_bound")?),
        mad_ns: number(object(&est, "median_abs_dev")?, "point_estimate")?,
    })
}

/// Every `new/` result directory under `dir` written after `since`.
fn collect(dir: &Path, since: SystemTime, out: &mut Vec<Estimate>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        if !p.is_dir() {
            continue;
        }
        if p.file_name().is_some_and(|n| n == "new") {
            let fresh = std::fs::metadata(p.join("estimates.json"))
                .and_then(|m| m.modified())
                .is_ok_and(|t| t >= since);
            if fresh {
                if let Some(est) = read_estimate(&p) {
                    out.push(est);
                }
            }
        } else if p.file_name().is_some_and(|n| n != "report" && n != "base" && n != "change") {
            collect(&p, since, out);
        }
    }
}

fn fmt_time(ns: f64) -> String {
    if ns >= 1e9 {
        format!("{:.3} s", ns / 1e9)
    } else if ns >= 1e6 {
        format!("{:.3} ms", ns / 1e6)
    } else if ns >= 1e3 {
        format!("{:.2} µs", ns / 1e3)
    } else {
        format!("{ns:.1} ns")
    }
}

/// Simulated seconds of the benchmark flight, from the line the `plant` bench prints.
fn flight_sim_seconds(lines: &[String]) -> Option<f64> {
    let line = lines.iter().find(|l| l.starts_with("office flight:"))?;
    let before = line.split(" s simulated").next()?;
    before.rsplit(' ').next()?.parse().ok()
}

/// What to say about one result in the summary's last column.
fn note(e: &Estimate, all: &[Estimate], flight_s: Option<f64>) -> String {
    match (e.group.as_str(), e.function.as_str()) {
        ("cbf_filter", "multi" | "paper") => {
            let qp = all
                .iter()
                .find(|q| q.group == "cbf_filter" && q.function == "qp_clarabel" && q.value == e.value);
            match qp {
                Some(q) => format!("QP (clarabel, all K) / this = {:.0}x", q.median_ns / e.median_ns),
                None => String::new(),
            }
        }
        ("plant", "office_flight") => match flight_s {
            Some(s) => format!("{s:.2} s simulated: {:.0}x real time", s / (e.median_ns * 1e-9)),
            None => String::new(),
        },
        ("cascade", "period_4ms") => format!("{:.3} % of the 4 ms period", 100.0 * e.median_ns / 4e6),
        _ => String::new(),
    }
}

/// Instruction-count goals of the issue: (line prefix printed by the M4 bench, goal).
const M4_GOALS: [(&str, u64); 2] =
    [("filter multi-relative K=16:", 2_000), ("cascade: 1 ms step with the outer loop", 5_000)];

/// The `mean N` figure of a line printed by the M4 bench.
fn m4_mean(line: &str) -> Option<u64> {
    line.split("mean ").nth(1)?.split_whitespace().next()?.parse().ok()
}

/// Build `tests/cortex-m4` and run it in QEMU ([`crate::m4`]); its output lines (`None` without
/// QEMU). A failed check fails the benchmark too.
fn cortex_m4() -> Result<Option<Vec<String>>, String> {
    let qemu_ok = Command::new("qemu-system-arm").arg("--version").output().is_ok_and(|o| o.status.success());
    if !qemu_ok {
        eprintln!("xtask: qemu-system-arm not found: Cortex-M4F instruction counts skipped");
        return Ok(None);
    }
    crate::ensure_target()?;
    let (lines, status) = crate::m4::build_and_run()?;
    crate::m4::verify(&lines, status.success())?;
    Ok(Some(lines))
}

/// `parapet sweep` scaling: wall time of the same sweep with `--jobs 1` and `--jobs 2`
/// (3 repetitions each, alternating); `None` when the binary has no `sweep` command.
fn sweep_scaling() -> Result<Option<(f64, f64)>, String> {
    let status = cargo()
        .args(["build", "--profile", "bench", "-p", "parapet-sim", "--bin", "parapet"])
        .current_dir(root())
        .status()
        .map_err(|e| format!("cargo build parapet: {e}"))?;
    if !status.success() {
        return Err(format!("building parapet failed ({status})"));
    }
    let exe = target_dir().join("release").join("parapet");
    let has_sweep = Command::new(&exe).args(["sweep", "--help"]).output().is_ok_and(|o| o.status.success());
    if !has_sweep {
        eprintln!("xtask: `parapet sweep` not available: sweep scaling skipped");
        return Ok(None);
    }
    let out = std::env::temp_dir().join(format!("parapet-xtask-sweep-{}", std::process::id()));
    let root = root();
    let mut walls: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for _ in 0..3 {
        for (i, jobs) in ["1", "2"].iter().enumerate() {
            let t0 = Instant::now();
            let o = Command::new(&exe)
                .args(["sweep", "--scene"])
                .arg(root.join("scenes/office.toml"))
                .arg("--path")
                .arg(root.join("scenes/office_path.json"))
                .args([
                    "--mu",
                    "1.0:1.4:4",
                    "--delta1",
                    "0.08:0.12:3",
                    "--seeds",
                    "4",
                    "--jobs",
                    jobs,
                    "--out",
                ])
                .arg(&out)
                .output()
                .map_err(|e| format!("parapet sweep: {e}"))?;
            if !o.status.success() {
                return Err(format!("parapet sweep failed: {}", String::from_utf8_lossy(&o.stderr)));
            }
            walls[i].push(t0.elapsed().as_secs_f64());
        }
    }
    let _ = std::fs::remove_dir_all(&out);
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (w1, w2) = (median(&mut walls[0]), median(&mut walls[1]));
    Ok(Some((w1, w2)))
}

/// `cargo xtask bench`.
pub fn bench(args: &[String]) -> Result<(), String> {
    let long = args.iter().any(|a| a == "--long");
    let times: &[&str] = if long { &[] } else { &["--warm-up-time", "1", "--measurement-time", "2"] };
    let since = SystemTime::now();
    let mut lines = run_tee(
        "benchmarks of parapet-tests (cbf_filter, cascade, plant)",
        cargo()
            .args(["bench", "-p", "parapet-tests", "--bench", "cbf_filter", "--bench", "cascade"])
            .args(["--bench", "plant", "--"])
            .args(times),
    )?;
    lines.extend(run_tee(
        "planner benchmark of parapet-sim",
        cargo().args(["bench", "-p", "parapet-sim", "--bench", "planner", "--"]).args(times),
    )?);

    eprintln!("\n== xtask: parapet sweep scaling (office, 48 runs, --jobs 1 vs 2, 3 repetitions)");
    let sweep = sweep_scaling()?;
    let m4 = cortex_m4()?;

    let mut all = Vec::new();
    collect(&target_dir().join("criterion"), since, &mut all);
    if all.is_empty() {
        return Err(format!("no criterion results found under {}", target_dir().join("criterion").display()));
    }
    let order = ["cbf_filter", "cascade", "plant", "plan"];
    all.sort_by_key(|e| {
        let g = order.iter().position(|g| *g == e.group).unwrap_or(order.len());
        let k: u64 = e.value.as_deref().and_then(|v| v.parse().ok()).unwrap_or(0);
        (g, k, e.function.clone(), e.id.clone())
    });
    let flight_s = flight_sim_seconds(&lines);
    let cpu = Command::new("sh")
        .args(["-c", "lscpu | sed -n 's/^Model name: *//p' | head -1"])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(0);
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "\n## Summary ({}; machine: {cores} cores, {cpu}; load average {})\n",
        if long { "criterion default times" } else { "short runs: warm-up 1 s, measurement 2 s" },
        load.split_whitespace().take(3).collect::<Vec<_>>().join(" ")
    );
    println!("| benchmark | median | MAD | 95 % CI of the median | note |");
    println!("|---|---:|---:|---|---|");
    for e in &all {
        println!(
            "| {} | {} | {} | {} – {} | {} |",
            e.id,
            fmt_time(e.median_ns),
            fmt_time(e.mad_ns),
            fmt_time(e.ci_ns.0),
            fmt_time(e.ci_ns.1),
            note(e, &all, flight_s)
        );
    }
    if let Some((w1, w2)) = sweep {
        println!(
            "\n`parapet sweep` (office, 4 μ × 3 δ1 × 4 seeds = 48 flights; median of 3): --jobs 1 {w1:.2} s, \
             --jobs 2 {w2:.2} s: speed-up {:.2}x",
            w1 / w2
        );
    }
    if let Some(lines) = m4 {
        println!(
            "\n## Cortex-M4F instruction counts (QEMU netduinoplus2, -icount shift=0; tests/cortex-m4)\n"
        );
        for l in &lines {
            println!("    {l}");
        }
        println!();
        for (prefix, goal) in M4_GOALS {
            match lines.iter().find(|l| l.starts_with(prefix)).and_then(|l| m4_mean(l)) {
                Some(n) => println!(
                    "goal {prefix} mean {n} instructions vs ≤ {goal}: {}",
                    if n <= goal { "met" } else { "NOT met" }
                ),
                None => println!("goal {prefix} ≤ {goal}: no figure found"),
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const EST: &str = r#"{"mean":{"confidence_interval":{"confidence_level":0.95,"lower_bound":10.0,"upper_bound":12.0},"point_estimate":11.0,"standard_error":0.5},"median":{"confidence_interval":{"confidence_level":0.95,"lower_bound":9.5,"upper_bound":10.5},"point_estimate":10.0,"standard_error":0.2},"median_abs_dev":{"confidence_interval":{"confidence_level":0.95,"lower_bound":0.1,"upper_bound":0.3},"point_estimate":0.2,"standard_error":0.05},"slope":null,"std_dev":{"confidence_interval":{"confidence_level":0.95,"lower_bound":1.0,"upper_bound":2.0},"point_estimate":1.5,"standard_error":0.1}}"#;
    const BENCH: &str = r#"{"group_id":"cbf_filter","function_id":"multi","value_str":"16","throughput":null,"full_id":"cbf_filter/multi/16","directory_name":"cbf_filter/multi/16","title":"cbf_filter/multi/16"}"#;

    #[test]
    fn parses_criterion_files() {
        let m = object(EST, "median").unwrap();
        assert_eq!(number(m, "point_estimate"), Some(10.0));
        assert_eq!(number(object(m, "confidence_interval").unwrap(), "upper_bound"), Some(10.5));
        assert_eq!(number(object(EST, "median_abs_dev").unwrap(), "point_estimate"), Some(0.2));
        assert_eq!(string(BENCH, "full_id").as_deref(), Some("cbf_filter/multi/16"));
        assert_eq!(string(BENCH, "value_str").as_deref(), Some("16"));
        assert_eq!(object(EST, "slope"), None);
    }

    #[test]
    fn reads_a_result_directory_and_notes_ratios() {
        let dir = std::env::temp_dir().join(format!("xtask-bench-test-{}", std::process::id()));
        let new = dir.join("cbf_filter/multi/16/new");
        std::fs::create_dir_all(&new).unwrap();
        std::fs::write(new.join("estimates.json"), EST).unwrap();
        std::fs::write(new.join("benchmark.json"), BENCH).unwrap();
        let mut all = Vec::new();
        collect(&dir, SystemTime::UNIX_EPOCH, &mut all);
        assert_eq!(all.len(), 1);
        assert_eq!((all[0].median_ns, all[0].ci_ns, all[0].mad_ns), (10.0, (9.5, 10.5), 0.2));
        let mut qp = all[0].clone();
        qp.function = "qp_clarabel".into();
        qp.median_ns = 2500.0;
        all.push(qp);
        assert_eq!(note(&all[0], &all, None), "QP (clarabel, all K) / this = 250x");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn reads_m4_means() {
        assert_eq!(
            m4_mean("filter multi K=16: mean 14248 min 5998 max 15397 instructions (n = 64)"),
            Some(14248)
        );
        assert_eq!(
            m4_mean("cascade: 1 ms step with the outer loop (update_obstacles + step_outer + step_inner): mean 36823 max 40921 instructions"),
            Some(36823)
        );
        assert_eq!(m4_mean("done"), None);
    }

    #[test]
    fn finds_the_flight_time() {
        let lines =
            vec!["x".to_string(), "office flight: end goal, 59.28 s simulated, 59280 plant steps".into()];
        assert_eq!(flight_sim_seconds(&lines), Some(59.28));
        assert_eq!(fmt_time(1500.0), "1.50 µs");
    }
}
