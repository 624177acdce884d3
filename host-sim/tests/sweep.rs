//! `parapet sweep` / `parapet sweep-merge` on a tiny grid (one_sphere scene, straight path,
//! 2 × 2 grid, one seed, 12 s runs): outputs, determinism, shard/merge = unsharded, bad input.

use std::path::Path;
use std::process::Output;

mod common;
use common::parapet;

fn tmp(name: &str) -> common::TmpDir {
    common::tmp("sweep", name)
}

const GRID: [&str; 14] = [
    "sweep",
    "--scene",
    "scenes/one_sphere.toml",
    "--straight",
    "--mu",
    "0.5:1.4:2",
    "--delta1",
    "0.06:0.3:2",
    "--seeds",
    "1",
    "--duration",
    "12",
    "--filter",
    "paper",
];

fn sweep(out: &Path, extra: &[&str]) -> Output {
    let mut args: Vec<&str> = GRID.to_vec();
    let o = out.display().to_string();
    args.extend_from_slice(&["--out", &o]);
    args.extend_from_slice(extra);
    let r = parapet(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    r
}

#[test]
fn tiny_grid_writes_csv_and_heatmaps_and_shards_merge_to_the_same_csv() {
    let d = tmp("grid");
    let full = d.join("full");
    let r = sweep(&full, &["--jobs", "2"]);
    // Not a terminal: no progress bar drawn.
    assert!(String::from_utf8_lossy(&r.stderr).trim().is_empty(), "{}", String::from_utf8_lossy(&r.stderr));
    let csv = std::fs::read_to_string(full.join("sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 5, "{csv}");
    assert!(lines[0].starts_with("index,scene,filter,mu,delta,delta1,"));
    let col = |name: &str| lines[0].split(',').position(|c| c == name).unwrap();
    let (cm, cd, cf, cs) = (col("mu"), col("delta1"), col("filter"), col("sim_time_s"));
    let rows: Vec<Vec<&str>> = lines[1..].iter().map(|l| l.split(',').collect()).collect();
    let params: Vec<(&str, &str)> = rows.iter().map(|r| (r[cm], r[cd])).collect();
    assert_eq!(params, vec![("0.5", "0.06"), ("0.5", "0.3"), ("1.4", "0.06"), ("1.4", "0.3")]);
    for r in &rows {
        assert_eq!(r[cf], "paper");
        let t: f64 = r[cs].parse().unwrap();
        assert!(t > 1.0 && t <= 12.001, "sim time {t}");
    }
    // Different parameters fly differently.
    assert_ne!(rows[0][col("min_clearance_m")], rows[3][col("min_clearance_m")]);
    for stem in ["heatmap_collision_rate", "heatmap_min_clearance", "heatmap_tracking_rms"] {
        for ext in ["png", "svg"] {
            let f = full.join(format!("{stem}.{ext}"));
            assert!(std::fs::metadata(&f).map(|m| m.len() > 500).unwrap_or(false), "{} missing", f.display());
        }
    }
    // Deterministic: the same sweep on one thread gives the same CSV.
    let again = d.join("again");
    sweep(&again, &["--jobs", "1"]);
    assert_eq!(std::fs::read_to_string(again.join("sweep.csv")).unwrap(), csv);
    // Shards 1/3 .. 3/3, merged, equal the unsharded CSV.
    let mut shard_csvs = Vec::new();
    let mut n_rows = 0;
    for i in 1..=3 {
        let o = d.join(format!("shard{i}"));
        sweep(&o, &["--shard", &format!("{i}/3"), "--jobs", "1"]);
        let f = o.join("sweep.csv");
        n_rows += std::fs::read_to_string(&f).unwrap().lines().count() - 1;
        shard_csvs.push(f.display().to_string());
    }
    assert_eq!(n_rows, 4);
    let merged = d.join("merged");
    let m = merged.display().to_string();
    let mut args = vec!["sweep-merge", &shard_csvs[2], &shard_csvs[0], &shard_csvs[1]];
    args.extend_from_slice(&["--out", &m]);
    let r = parapet(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(std::fs::read_to_string(merged.join("sweep.csv")).unwrap(), csv);
    assert!(merged.join("heatmap_collision_rate.png").exists());
}

#[test]
fn bad_ranges_and_options_exit_2_with_a_clear_message() {
    let d = tmp("bad");
    let o = d.display().to_string();
    let cases: [(&[&str], &str); 7] = [
        (&["--mu", "1.4:0.5:3", "--delta1", "0.1:0.2:2"], "--mu"),
        (&["--mu", "0.5:1.4", "--delta1", "0.1:0.2:2"], "A:B:N"),
        (&["--mu", "0.5:1.4:0", "--delta1", "0.1:0.2:2"], "count"),
        (&["--mu", "0.5:1.4:2", "--delta1", "0.01:0.2:2"], "delta1"),
        (&["--mu", "0.5:1.4:2", "--delta1", "0.1:0.2:2", "--shard", "3/2"], "--shard"),
        (&["--mu", "0.5:1.4:2", "--delta1", "0.1:0.2:2", "--seeds", "0"], "--seeds"),
        (&["--mu", "x:1.4:2", "--delta1", "0.1:0.2:2"], "not a number"),
    ];
    for (extra, needle) in cases {
        let mut args = vec!["sweep", "--scene", "scenes/one_sphere.toml", "--straight", "--out", &o];
        args.extend_from_slice(extra);
        let r = parapet(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(needle), "{extra:?}: {err}");
    }
    let bad_csv = d.join("bad.csv");
    std::fs::write(&bad_csv, "not,a,sweep\n").unwrap();
    let r = parapet(&["sweep-merge", &bad_csv.display().to_string(), "--out", &o]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("bad.csv"));
}

fn err(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A copy of one_sphere.toml with `edit` applied, written to `dir/name`.
fn scene_copy(dir: &Path, name: &str, edit: &dyn Fn(String) -> String) -> String {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/one_sphere.toml"))
            .unwrap();
    let edited = edit(text.clone());
    assert_ne!(edited, text, "edit changed nothing");
    let p = dir.join(name);
    std::fs::write(&p, edited).unwrap();
    p.display().to_string()
}

/// A small sweep (2 runs by default) with `args` after the scene.
fn sweep_any(scene: &str, out: &Path, args: &[&str]) -> Output {
    let o = out.display().to_string();
    let mut v = vec!["sweep", "--scene", scene, "--straight", "--out", &o];
    for (opt, default) in [("--filter", "paper"), ("--duration", "12")] {
        if !args.contains(&opt) {
            v.extend_from_slice(&[opt, default]);
        }
    }
    v.extend_from_slice(args);
    parapet(&v)
}

fn read_csv(p: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(p).unwrap();
    let h = r.headers().unwrap().iter().map(str::to_string).collect();
    let rows = r.records().map(|x| x.unwrap().iter().map(str::to_string).collect()).collect();
    (h, rows)
}

#[test]
fn oversized_grids_are_refused_before_anything_is_allocated() {
    let d = tmp("size");
    let o = d.join("o");
    let t0 = std::time::Instant::now();
    // 2^64 - 1 seeds: over the seed cap, named with the cap.
    let r = sweep_any(
        "scenes/one_sphere.toml",
        &o,
        &["--mu", "0.9", "--delta1", "0.2", "--seeds", "18446744073709551615"],
    );
    assert_eq!(r.status.code(), Some(2), "{}", err(&r));
    assert!(err(&r).contains("--seeds") && err(&r).contains("10000"), "{}", err(&r));
    // 10,000 × 10,000 × 1,000 grid: over the per-invocation cap; the message names the
    // cap and the option that splits the grid.
    let huge = ["--mu", "0.5:1.4:10000", "--delta1", "0.06:0.3:10000", "--speed", "0.1:1:1000"];
    let r = sweep_any("scenes/one_sphere.toml", &o, &huge);
    let e = err(&r);
    assert_eq!(r.status.code(), Some(2), "{e}");
    assert!(e.contains("100000000000 runs") && e.contains("1000000") && e.contains("--shard"), "{e}");
    // 10,100 runs: over the --yes threshold; the refusal gives the count and an estimate.
    let r = sweep_any("scenes/one_sphere.toml", &o, &["--mu", "0.5:1.4:101", "--delta1", "0.06:0.3:100"]);
    let e = err(&r);
    assert_eq!(r.status.code(), Some(2), "{e}");
    assert!(e.contains("--yes") && e.contains("10100 runs") && e.contains("estimated time"), "{e}");
    // With --yes (and with the huge grid split into 100,000 shards) the size checks pass:
    // the next check (δ1 must exceed δ = 0.05) is what refuses these.
    let low = ["--mu", "0.5:1.4:101", "--delta1", "0.01:0.3:100", "--yes"];
    let mut split: Vec<&str> = huge.to_vec();
    split[3] = "0.01:0.3:10000";
    split.extend_from_slice(&["--shard", "1/100000", "--yes"]);
    for args in [&low[..], &split[..]] {
        let r = sweep_any("scenes/one_sphere.toml", &o, args);
        assert_eq!(r.status.code(), Some(2), "{}", err(&r));
        assert!(err(&r).contains("--delta1") && err(&r).contains("0.01"), "{}", err(&r));
    }
    assert!(!o.join("sweep.csv").exists(), "a refused sweep wrote a CSV");
    // Nothing proportional to the grid was allocated or flown: all of this is fast.
    assert!(t0.elapsed().as_secs_f64() < 20.0, "{:?}", t0.elapsed());
}

#[test]
fn a_failing_point_is_a_failed_row_and_the_others_are_kept() {
    let d = tmp("failing");
    let o = d.join("o");
    // Speed 200 m/s is beyond what the waypoint follower accepts; 0.3 flies.
    let r =
        sweep_any("scenes/one_sphere.toml", &o, &["--mu", "0.9", "--delta1", "0.2", "--speed", "0.3:200:2"]);
    let e = err(&r);
    assert_eq!(r.status.code(), Some(4), "{e}");
    assert!(e.contains("1 of 2 runs failed") && e.contains("sweep.csv"), "{e}");
    let (h, rows) = read_csv(&o.join("sweep.csv"));
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!((rows[0][col("speed")].as_str(), rows[0][col("status")].as_str()), ("0.3", "ok"));
    assert_eq!(rows[0][col("error")], "");
    assert!(rows[0][col("sim_time_s")].parse::<f64>().unwrap() > 1.0);
    assert_eq!(rows[1][col("speed")].parse::<f64>(), Ok(200.0));
    assert_eq!(rows[1][col("status")], "failed");
    // The error names the option, the value and the allowed range.
    let e = &rows[1][col("error")];
    assert!(e.contains("option --speed") && e.contains("200") && e.contains("100 m/s"), "{e:?}");
    assert_eq!(rows[1][col("min_clearance_m")], "");
    // Heatmaps drawn from the flown row; the manifest counts the failure.
    assert!(o.join("heatmap_min_clearance.png").exists());
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(o.join("sweep.json")).unwrap()).unwrap();
    assert_eq!((m["rows"].as_u64(), m["failed"].as_u64()), (Some(2), Some(1)));
}

#[test]
fn a_base_configuration_that_fails_preflight_is_refused_up_front() {
    let d = tmp("preflight");
    let o = d.join("o");
    // The start inside the sphere.
    let s =
        scene_copy(&d, "inside.toml", &|t| t.replace("start = [0.0, 0.0, 1.0]", "start = [3.0, 0.1, 1.0]"));
    let r = sweep_any(&s, &o, &["--mu", "0.9", "--delta1", "0.2"]);
    assert_eq!(r.status.code(), Some(2), "{}", err(&r));
    assert!(err(&r).contains("inside.toml"), "{}", err(&r));
    assert!(!o.join("sweep.csv").exists());
}

#[test]
fn csv_strings_are_quoted() {
    let d = tmp("quoted");
    let o = d.join("o");
    let s = scene_copy(&d, "q.toml", &|t| {
        t.replace("name = \"one_sphere\"", "name = \"one, \\\"quoted\\\" sphere\"")
    });
    let r = sweep_any(&s, &o, &["--mu", "0.9", "--delta1", "0.2"]);
    assert!(r.status.success(), "{}", err(&r));
    let (h, rows) = read_csv(&o.join("sweep.csv"));
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].len(), h.len());
    assert_eq!(rows[0][1], "one, \"quoted\" sphere");
}

/// Shards `1..=n` of `which` of a 4-run grid into `d/<tag><i>`; returns the directories.
fn shards(d: &Path, tag: &str, scene: &str, n: u64, which: &[u64], extra: &[&str]) -> Vec<String> {
    which
        .iter()
        .map(|i| {
            let o = d.join(format!("{tag}{i}"));
            let shard = format!("{i}/{n}");
            let mut args =
                vec!["--mu", "0.5:1.4:2", "--delta1", "0.06:0.3:2", "--shard", &shard, "--jobs", "1"];
            args.extend_from_slice(extra);
            let r = sweep_any(scene, &o, &args);
            assert!(r.status.success(), "{}", err(&r));
            o.display().to_string()
        })
        .collect()
}

fn merge(args: &[&str]) -> Output {
    let mut v = vec!["sweep-merge"];
    v.extend_from_slice(args);
    parapet(&v)
}

#[test]
fn sweep_merge_refuses_shards_that_do_not_belong_together() {
    let d = tmp("mixup");
    let out = d.join("merged").display().to_string();
    let base = shards(&d, "a", "scenes/one_sphere.toml", 2, &[1, 2], &[]);
    // Same scene name, other contents (a moved sphere); other filter; other grid; other N.
    let moved =
        scene_copy(&d, "moved.toml", &|t| t.replace("center = [3.0, 0.1, 1.0]", "center = [3.0, 0.2, 1.0]"));
    let other_scene = shards(&d, "s", &moved, 2, &[2], &[]);
    let other_filter = shards(&d, "f", "scenes/one_sphere.toml", 2, &[2], &["--filter", "multi"]);
    let other_n = shards(&d, "n", "scenes/one_sphere.toml", 3, &[2], &[]);
    let o = d.join("g");
    let r = sweep_any(
        "scenes/one_sphere.toml",
        &o,
        &["--mu", "0.5:1.4:2", "--delta1", "0.06:0.3:3", "--shard", "2/2", "--jobs", "1"],
    );
    assert!(r.status.success(), "{}", err(&r));
    let other_grid = o.display().to_string();
    let cases: [(&str, &str); 4] = [
        (&other_scene[0], "scene_fnv1a64"),
        (&other_filter[0], "filter"),
        (&other_grid, "delta1"),
        (&other_n[0], "shards"),
    ];
    for (second, needle) in cases {
        let r = merge(&[&base[0], second, "--out", &out]);
        let e = err(&r);
        assert_eq!(r.status.code(), Some(2), "{second}: {e}");
        assert!(e.contains(second) && e.contains(needle), "{second}: {e}");
    }
    // The same shard twice.
    let r = merge(&[&base[0], &base[0], "--out", &out]);
    assert_eq!(r.status.code(), Some(2));
    assert!(err(&r).contains("shard 1/2 is given twice"), "{}", err(&r));
    assert!(!d.join("merged").join("sweep.csv").exists(), "a refused merge wrote a CSV");
    // A plain CSV without its manifest.
    let lone = d.join("lone");
    std::fs::create_dir_all(&lone).unwrap();
    std::fs::copy(Path::new(&base[0]).join("sweep.csv"), lone.join("sweep.csv")).unwrap();
    let r = merge(&[&lone.join("sweep.csv").display().to_string(), "--out", &out]);
    assert_eq!(r.status.code(), Some(2));
    assert!(err(&r).contains("sweep.json"), "{}", err(&r));
}

#[test]
fn sweep_merge_reports_missing_shards_and_damaged_rows() {
    let d = tmp("missing");
    let sh = shards(&d, "p", "scenes/one_sphere.toml", 4, &[1, 3, 4], &[]);
    let out = d.join("merged");
    let o = out.display().to_string();
    let r = merge(&[&sh[0], &sh[2], "--out", &o]);
    let e = err(&r);
    assert_eq!(r.status.code(), Some(2), "{e}");
    assert!(e.contains("2 of 4 shards are missing: 2/4, 3/4") && e.contains("--allow-partial"), "{e}");
    // --allow-partial: the rows of the shards given, and the manifest says which.
    let r = merge(&[&sh[2], &sh[0], "--allow-partial", "--out", &o]);
    assert!(r.status.success(), "{}", err(&r));
    let (h, rows) = read_csv(&out.join("sweep.csv"));
    let idx: Vec<&str> = rows.iter().map(|r| r[0].as_str()).collect();
    assert_eq!((h[0].as_str(), idx), ("index", vec!["0", "3"]));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sweep.json")).unwrap()).unwrap();
    assert_eq!(m["shards"], serde_json::json!([1, 4]));
    // The partial result merges on with shard 3 (2/4 still missing): rows 0, 2, 3.
    let full = d.join("full");
    let r = merge(&[&o, &sh[1], "--allow-partial", "--out", &full.display().to_string()]);
    assert!(r.status.success(), "{}", err(&r));
    let idx: Vec<String> = read_csv(&full.join("sweep.csv")).1.iter().map(|r| r[0].clone()).collect();
    assert_eq!(idx, vec!["0", "2", "3"]);
    // Merging the partial result with itself: its shards given twice.
    let r = merge(&[&o, &o, "--allow-partial", "--out", &full.display().to_string()]);
    assert_eq!(r.status.code(), Some(2));
    assert!(err(&r).contains("given twice"), "{}", err(&r));
    // A truncated shard (last row cut) and a tampered row are refused, naming the file;
    // the output directory keeps what it had (the partial merge above).
    let kept =
        (std::fs::read(out.join("sweep.csv")).unwrap(), std::fs::read(out.join("sweep.json")).unwrap());
    let csv = Path::new(&sh[1]).join("sweep.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let header = text.lines().next().unwrap().to_string();
    std::fs::write(&csv, format!("{header}\n")).unwrap();
    let r = merge(&[&sh[0], &sh[1], &sh[2], "--allow-partial", "--out", &o]);
    assert_eq!(r.status.code(), Some(2));
    assert!(err(&r).contains(&csv.display().to_string()) && err(&r).contains("0 rows"), "{}", err(&r));
    let row = text.lines().nth(1).unwrap();
    std::fs::write(&csv, format!("{header}\n{}\n", row.replacen(",0.06,", ",0.07,", 1))).unwrap();
    let r = merge(&[&sh[0], &sh[1], &sh[2], "--allow-partial", "--out", &o]);
    assert_eq!(r.status.code(), Some(2));
    assert!(err(&r).contains("line 2") && err(&r).contains("does not match grid point 2"), "{}", err(&r));
    std::fs::write(&csv, format!("{header}\n{}\n", row.replacen(",0.06,", ",sixty,", 1))).unwrap();
    let r = merge(&[&sh[0], &sh[1], &sh[2], "--allow-partial", "--out", &o]);
    assert_eq!(r.status.code(), Some(2));
    let e = err(&r);
    assert!(
        e.contains("line 2") && e.contains("delta1") && e.contains("sixty") && e.contains("column 6"),
        "{e}"
    );
    assert_eq!(
        (std::fs::read(out.join("sweep.csv")).unwrap(), std::fs::read(out.join("sweep.json")).unwrap()),
        kept
    );
    assert!(!out.join("sweep.csv.partial").exists());
}

#[test]
fn outputs_never_overwrite_inputs() {
    let d = tmp("overwrite");
    let sh = shards(&d, "w", "scenes/one_sphere.toml", 2, &[1, 2], &[]);
    let before = std::fs::read(Path::new(&sh[0]).join("sweep.csv")).unwrap();
    // Merging into a shard's own directory.
    let r = merge(&[&sh[0], &sh[1], "--out", &sh[0]]);
    assert_eq!(r.status.code(), Some(2), "{}", err(&r));
    assert!(err(&r).contains("--out") && err(&r).contains("overwrite"), "{}", err(&r));
    assert_eq!(std::fs::read(Path::new(&sh[0]).join("sweep.csv")).unwrap(), before);
    // A sweep whose output would replace its scene file.
    let s = scene_copy(&d, "sweep.json", &|t| t.replace("one_sphere", "in_out"));
    let scene_before = std::fs::read(&s).unwrap();
    let r = sweep_any(&s, &d, &["--mu", "0.9", "--delta1", "0.2"]);
    assert_eq!(r.status.code(), Some(2), "{}", err(&r));
    assert!(err(&r).contains("overwrite"), "{}", err(&r));
    assert_eq!(std::fs::read(&s).unwrap(), scene_before);
    // sweep-merge's default output folder is its own, not sweep's.
    let r = parapet(&["sweep-merge", "--help"]);
    let help = String::from_utf8_lossy(&r.stdout);
    assert!(help.contains("[default: out/sweep-merge]"), "{help}");
    let r = parapet(&["sweep", "--help"]);
    assert!(String::from_utf8_lossy(&r.stdout).contains("[default: out/sweep]"));
}

#[test]
fn help_documents_seeds_ranges_limits_examples_and_exit_codes() {
    for cmd in ["sweep", "sweep-merge"] {
        let r = parapet(&[cmd, "--help"]);
        assert!(r.status.success());
        let h = String::from_utf8_lossy(&r.stdout);
        for needle in ["Examples:", "Exit codes:", "  2 ", "  4 "] {
            assert!(h.contains(needle), "{cmd} --help lacks {needle:?}: {h}");
        }
    }
    let h = String::from_utf8_lossy(&parapet(&["sweep", "--help"]).stdout).into_owned();
    for needle in
        ["seeds 0..K-1", "or one value", "10000 values per range", "256 threads", "1000000 runs", "--yes"]
    {
        assert!(h.contains(needle), "sweep --help lacks {needle:?}: {h}");
    }
    // `--seeds` is a count: a range is refused with the hint.
    let d = tmp("help");
    let r = sweep_any("scenes/one_sphere.toml", &d, &["--mu", "0.9", "--delta1", "0.2", "--seeds", "0..4"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(err(&r).contains("--seeds") && err(&r).contains("count"), "{}", err(&r));
    // One value per range, and --seeds 2: 2 runs with seeds 0 and 1.
    let r = sweep_any("scenes/one_sphere.toml", &d, &["--mu", "0.9", "--delta1", "0.2", "--seeds", "2"]);
    assert!(r.status.success(), "{}", err(&r));
    let (h, rows) = read_csv(&d.join("sweep.csv"));
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    let got: Vec<(&str, &str, &str)> = rows
        .iter()
        .map(|r| (r[col("mu")].as_str(), r[col("delta1")].as_str(), r[col("seed")].as_str()))
        .collect();
    assert_eq!(got, vec![("0.9", "0.2", "0"), ("0.9", "0.2", "1")]);
}

#[test]
fn durations_beyond_the_cap_are_refused_or_failed_rows() {
    let d = tmp("duration");
    let o = d.join("o");
    // An explicit --duration beyond the cap: refused up front, naming the option that raises it.
    let r = sweep_any("scenes/one_sphere.toml", &o, &["--mu", "0.9", "--delta1", "0.2", "--duration", "1e6"]);
    let e = err(&r);
    assert_eq!(r.status.code(), Some(2), "{e}");
    assert!(e.contains("option --duration") && e.contains("3600") && e.contains("--max-duration"), "{e}");
    let r = sweep_any(
        "scenes/one_sphere.toml",
        &o,
        &["--mu", "0.9", "--delta1", "0.2", "--duration", "1e6", "--max-duration", "1e6"],
    );
    assert_eq!(r.status.code(), Some(2), "{}", err(&r));
    assert!(err(&r).contains("--max-duration") && err(&r).contains("86400"), "{}", err(&r));
    assert!(!o.join("sweep.csv").exists());
    // A grid speed whose default duration is beyond the cap (6 m at 1 mm/s, the parameter
    // table's lowest WP_SPEED): that run is a failed row, the other (0.3 m/s, 45 s) flies.
    let out = o.display().to_string();
    let r = parapet(&[
        "sweep",
        "--scene",
        "scenes/one_sphere.toml",
        "--straight",
        "--filter",
        "paper",
        "--mu",
        "0.9",
        "--delta1",
        "0.2",
        "--speed",
        "0.001:0.3:2",
        "--out",
        &out,
    ]);
    assert_eq!(r.status.code(), Some(4), "{}", err(&r));
    let (h, rows) = read_csv(&o.join("sweep.csv"));
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    assert_eq!(rows[0][col("status")], "failed");
    assert!(
        rows[0][col("error")].contains("duration") && rows[0][col("error")].contains("3600"),
        "{:?}",
        rows[0]
    );
    assert_eq!(rows[1][col("status")], "ok");
}

#[test]
fn bad_jobs_and_output_directories_exit_2() {
    let d = tmp("jobs");
    let o = d.join("o");
    for jobs in ["0", "100000"] {
        let r = sweep_any("scenes/one_sphere.toml", &o, &["--mu", "0.9", "--delta1", "0.2", "--jobs", jobs]);
        assert_eq!(r.status.code(), Some(2), "{}", err(&r));
        assert!(err(&r).contains("option --jobs") && err(&r).contains("256"), "{}", err(&r));
    }
    // --out is an existing file: nothing written over it.
    let f = d.join("file");
    std::fs::write(&f, "keep").unwrap();
    let r = sweep_any("scenes/one_sphere.toml", &f.join("sub"), &["--mu", "0.9", "--delta1", "0.2"]);
    assert_eq!(r.status.code(), Some(2), "{}", err(&r));
    assert!(err(&r).contains("option --out"), "{}", err(&r));
    assert_eq!(std::fs::read_to_string(&f).unwrap(), "keep");
}

#[test]
fn a_closed_stdout_is_not_a_panic() {
    use std::process::{Command, Stdio};
    let d = tmp("pipe");
    let o = d.display().to_string();
    for args in [
        vec!["sweep", "--scene", "scenes/one_sphere.toml", "--straight", "--mu", "0.9", "--delta1", "0.2"],
        vec!["sweep-merge", &o],
    ] {
        let mut args = args.clone();
        let merged = d.join("merged").display().to_string();
        args.extend_from_slice(&["--out", if args[0] == "sweep" { &o } else { &merged }]);
        let mut child = Command::new(env!("CARGO_BIN_EXE_parapet"))
            .args(&args)
            .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Close the reading end before the report line is printed (`parapet sweep … | true`).
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let e = err(&out);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
    assert!(d.join("merged").join("sweep.csv").exists());
}

/// `--guidance paper|trajectory` (issue 35) flies every run with that mission guidance, as
/// `--param MIS_GUIDANCE=0|1` does (the same rows), changes the rows against the other
/// guidance, and an unknown guidance exits 2 naming the option and the allowed names.
#[test]
fn guidance_option_sets_the_mission_guidance_of_every_run() {
    let d = tmp("guidance");
    let paper = shards(&d, "p", "scenes/one_sphere.toml", 2, &[2], &["--guidance", "paper"]);
    let by_param = shards(&d, "q", "scenes/one_sphere.toml", 2, &[2], &["--param", "MIS_GUIDANCE=0"]);
    let traj = shards(&d, "t", "scenes/one_sphere.toml", 2, &[2], &["--guidance", "trajectory"]);
    let rows = |dir: &str| read_csv(&Path::new(dir).join("sweep.csv"));
    let ((head, a), (_, b), (_, c)) = (rows(&paper[0]), rows(&by_param[0]), rows(&traj[0]));
    let rms = head.iter().position(|c| c == "tracking_rms_m").unwrap();
    assert_eq!(a, b, "--guidance paper and --param MIS_GUIDANCE=0 differ");
    assert!(a.iter().zip(&c).all(|(x, y)| x[rms] != y[rms]), "the guidance changed no run");
    let o = d.join("bad");
    let r =
        sweep_any("scenes/one_sphere.toml", &o, &["--mu", "0.9", "--delta1", "0.1", "--guidance", "fast"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(err(&r).contains("--guidance") && err(&r).contains("paper"), "{}", err(&r));
}

/// `--param NAME=VALUE` sets a parameter for every run (issue 37): the rows change, the manifest
/// records it, shards flown with other parameters do not merge, bad names exit 2.
#[test]
fn a_parameter_set_by_name_applies_to_every_run_and_decides_the_identity() {
    let d = tmp("param");
    let plain = shards(&d, "a", "scenes/one_sphere.toml", 2, &[1, 2], &[]);
    let heavy = shards(&d, "h", "scenes/one_sphere.toml", 2, &[2], &["--param", "VEH_MASS=0.55"]);
    let rows = |dir: &str| read_csv(&Path::new(dir).join("sweep.csv"));
    let ((head, a), (_, b)) = (rows(&plain[1]), rows(&heavy[0]));
    let rms = head.iter().position(|c| c == "tracking_rms_m").unwrap();
    assert_eq!(a.len(), b.len());
    assert!(a.iter().zip(&b).all(|(x, y)| x[rms] != y[rms]), "the controller's mass changed no run");
    let manifest = std::fs::read_to_string(Path::new(&heavy[0]).join("sweep.json")).unwrap();
    assert!(manifest.contains("\"VEH_MASS\""), "{manifest}");
    let out = d.join("merged").display().to_string();
    let r = merge(&[&plain[0], &heavy[0], "--out", &out]);
    assert_eq!(r.status.code(), Some(2), "{}", err(&r));
    assert!(err(&r).contains("params"), "{}", err(&r));
    let o = d.join("bad");
    let r =
        sweep_any("scenes/one_sphere.toml", &o, &["--mu", "0.9", "--delta1", "0.1", "--param", "NO_SUCH=1"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(err(&r).contains("NO_SUCH"), "{}", err(&r));
}

/// `--grid NAME=A:B:N` (issue 37) grids any continuous parameter by name: `sweep.csv` gets a
/// column per axis with the value each run's controller flew (read back from its parameter
/// set), the flights change with it (a slower trajectory acceleration reaches the goal later; the
/// summary's k_p is the gridded TRK_KP), shards merge to the same CSV, and a bad axis exits 2
/// naming the option, the parameter, the value and the range.
#[test]
fn a_gridded_parameter_changes_the_runs_and_gets_its_column() {
    let d = tmp("gridparam");
    let scene = "host-sim/tests/data/scenes/cli_params_open.toml";
    let axes = ["--mu", "1.4", "--delta1", "0.1", "--grid", "TRJ_ACC=0.1:2:2", "--grid", "TRK_KP=0.5:1:2"];
    let fly = |out: &Path, extra: &[&str]| {
        let mut args = axes.to_vec();
        args.extend_from_slice(&["--duration", "20", "--jobs", "1"]);
        args.extend_from_slice(extra);
        let r = sweep_any(scene, out, &args);
        assert!(r.status.success(), "{}", err(&r));
        read_csv(&out.join("sweep.csv"))
    };
    let full = d.join("full");
    let (head, rows) = fly(&full, &[]);
    assert_eq!(&head[head.len() - 2..], ["TRJ_ACC", "TRK_KP"], "{head:?}");
    let col = |n: &str| head.iter().position(|h| h == n).unwrap();
    let (acc, kp_axis, kp, t) = (col("TRJ_ACC"), col("TRK_KP"), col("kp"), col("time_to_goal_s"));
    let num = |r: &Vec<String>, c: usize| r[c].parse::<f64>().unwrap();
    let got: Vec<(f64, f64)> = rows.iter().map(|r| (num(r, acc), num(r, kp_axis))).collect();
    assert_eq!(got, [(0.1, 0.5), (0.1, 1.0), (2.0, 0.5), (2.0, 1.0)], "grid order, values flown");
    for r in &rows {
        assert_eq!(r[col("status")], "ok", "{r:?}");
        assert_eq!(num(r, kp), num(r, kp_axis), "the run's k_p");
    }
    let time = |i: usize| rows[i][t].parse::<f64>().unwrap();
    println!("time to goal: TRJ_ACC 0.1: {} {}, TRJ_ACC 2: {} {}", time(0), time(1), time(2), time(3));
    assert!(time(0) > time(2) + 2.0 && time(1) > time(3) + 2.0, "{rows:?}");
    let manifest = std::fs::read_to_string(full.join("sweep.json")).unwrap();
    assert!(
        manifest.contains("\"TRJ_ACC=0.1:2:2\"") && manifest.contains("\"TRK_KP=0.5:1:2\""),
        "{manifest}"
    );
    let (s1, s2) = (d.join("s1"), d.join("s2"));
    fly(&s1, &["--shard", "1/2"]);
    fly(&s2, &["--shard", "2/2"]);
    let out = d.join("merged");
    let r = merge(&[s1.to_str().unwrap(), s2.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(r.status.success(), "{}", err(&r));
    assert_eq!(
        std::fs::read_to_string(out.join("sweep.csv")).unwrap(),
        std::fs::read_to_string(full.join("sweep.csv")).unwrap()
    );
    let bad = d.join("bad");
    for (axis, extra, want) in [
        ("NO_SUCH=1:2:2", "", "NO_SUCH"),
        ("TRJ_ACC=0.05:1:2", "", "0.1 ≤ TRJ_ACC ≤ 15"),
        ("CBF_MU=0.5:1:2", "", "already set by --mu"),
        ("WP_SPEED=0.5:1:2", "", "already set by --speed"),
        ("TRJ_ACC=1:2:2", "TRJ_ACC=1", "already set by --param"),
        ("MIS_YAW_MODE=0:1:2", "", "a code parameter cannot be gridded"),
        ("CBF_VARIANT=0:3:4", "", "already set by --filter"),
    ] {
        let mut args = vec!["--mu", "1.4", "--delta1", "0.1", "--grid", axis];
        if !extra.is_empty() {
            args.extend_from_slice(&["--param", extra]);
        }
        let r = sweep_any(scene, &bad, &args);
        assert_eq!(r.status.code(), Some(2), "{axis}: {}", err(&r));
        assert!(err(&r).contains("--grid") && err(&r).contains(want), "{axis}: {}", err(&r));
    }
    assert!(!bad.join("sweep.csv").exists(), "nothing flown");
}
