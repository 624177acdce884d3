//! `flight.mcap` (issue 40) read back with the `mcap` Python package
//! (`tests/python/check_mcap.py`) and checked message by message against the same report's
//! `trajectory.csv` (and `ranges.csv`): flights written by `write_report` as `parapet run`
//! writes them —
//!
//! * a person walking head-on (a moving obstacle: scene updates) with a lidar (`/ranges`);
//! * the same record with a diverged sample (position NaN, h̄ ∞): the file stays readable, the
//!   sample's `/tf` translation is null where `trajectory.csv` says NaN;
//! * a record without samples: the scene alone.
//!
//! Needs the venv's python with `mcap` (`cargo xtask venv`); SKIPs loudly without it, fails in
//! CI (`venv_python`).

use std::path::{Path, PathBuf};
use std::process::Command;

use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::RunConfig;
use parapet_sim::flight::stack::clock_us;
use parapet_sim::report::{write_report, RunRecord};
use parapet_sim::sim::range::preset;
use parapet_sim::world::scene::Scene;
use parapet_tests::pil_support::{venv_python, workspace_root};

fn check(py: &Path, dir: &Path, obstacles: usize, ranges: bool) -> String {
    let mut cmd = Command::new(py);
    cmd.arg(workspace_root().join("tests/python/check_mcap.py"))
        .arg(dir.join("flight.mcap"))
        .arg(dir.join("trajectory.csv"))
        .arg(obstacles.to_string());
    if ranges {
        cmd.arg(dir.join("ranges.csv"));
    }
    let o = cmd.output().expect("python runs");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{}: {text}", dir.display());
    assert!(o.status.success(), "{}: {text}", dir.display());
    text
}

#[test]
fn mcap_matches_the_trajectory_message_by_message() {
    let Some(py) = venv_python("mcap", "flight.mcap read back") else { return };
    let root: PathBuf = std::env::temp_dir().join(format!("parapet-flight-mcap-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let scene =
        Scene::load(&workspace_root().join("scenes/person_headon.toml")).unwrap_or_else(|e| panic!("{e}"));
    let mut cfg =
        RunConfig::for_scene(&scene, vec![scene.start, scene.goal]).unwrap_or_else(|e| panic!("{e}"));
    cfg.duration = 3.0;
    cfg.perception = Some(preset("lidar").expect("lidar preset"));
    let out = run(&scene, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(out.samples.len() > 500 && !out.ranges.is_empty(), "{} samples", out.samples.len());
    let rec = RunRecord {
        scene: &scene,
        path: &cfg.path,
        samples: &out.samples,
        summary: &out.summary,
        ranges: &out.ranges,
        range_sensors: cfg.perception.as_deref().unwrap_or(&[]),
        filter_points: &out.filter_points,
        clock_us,
    };
    let dir = root.join("flight");
    write_report(&dir, &rec).unwrap_or_else(|e| panic!("{e:#}"));
    let text = check(&py, &dir, scene.obstacles.len(), true);
    // The moving person: 10 Hz scene updates after the first (3 s of flight).
    let scenes: usize = text
        .split("/scene ")
        .nth(1)
        .and_then(|r| r.split(',').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!((28..=32).contains(&scenes), "{scenes} scene updates: {text}");

    // A diverged sample between good ones.
    let mut samples = out.samples[..3].to_vec();
    samples[1].pos.x = f64::NAN;
    samples[1].h_bar = f64::INFINITY;
    samples[1].rpy[0] = f64::NAN;
    let dir = root.join("nan");
    let empty = parapet_sim::perception::RangeLog::default();
    write_report(&dir, &RunRecord { samples: &samples, ranges: &empty, range_sensors: &[], ..rec })
        .unwrap_or_else(|e| panic!("{e:#}"));
    let csv = std::fs::read_to_string(dir.join("trajectory.csv")).expect("csv");
    assert!(csv.lines().nth(2).is_some_and(|l| l.contains("NaN")), "{csv}");
    check(&py, &dir, scene.obstacles.len(), false);

    // No samples: the scene alone.
    let dir = root.join("empty");
    write_report(&dir, &RunRecord { samples: &[], ranges: &empty, range_sensors: &[], ..rec })
        .unwrap_or_else(|e| panic!("{e:#}"));
    check(&py, &dir, scene.obstacles.len(), false);
    let _ = std::fs::remove_dir_all(&root);
}
