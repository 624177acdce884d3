//! `parapet sweep` / `parapet sweep-merge` on a tiny grid (one_sphere scene, straight path,
//! 2 × 2 grid, one seed, 12 s runs): outputs, determinism, shard/merge = unsharded, bad input.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::parapet;

fn tmp(name: &str) -> PathBuf {
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
