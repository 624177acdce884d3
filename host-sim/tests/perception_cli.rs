//! `parapet run --perception …` from the command line (issue 19): the report's
//! `ranges.csv`, and bad option values naming the option, the value and what is allowed.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::parapet;

fn tmp(name: &str) -> common::TmpDir {
    common::tmp("perception_cli", name)
}

const SCENE: &str = include_str!("data/scenes/perception_cli.toml");

/// `parapet run --scene SCENE --straight ARGS --out OUT`.
fn run_straight(scene: &str, args: &[&str], out: &Path) -> Output {
    parapet(&[&["run", "--scene", scene, "--straight"], args, &["--out", out.to_str().unwrap()]].concat())
}

#[test]
fn lidar_run_writes_ranges_csv_and_bad_values_exit_2() {
    let d = tmp("run");
    let scene = d.join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let sc = scene.to_str().unwrap();
    let out = d.join("report");
    let o = run_straight(sc, &["--perception", "lidar", "--assume", "no-overhangs,no-low-obstacles"], &out);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("ranges.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("t,sensor,beam,range,x,y,z"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.len() >= 72 * 10, "{} rows", rows.len());
    assert!(rows.iter().all(|r| r.len() == 7 && r[1] == "lidar"));
    // Some beams see the pole (ENU x 2, y 1, radius 0.2), the others nothing within 12 m.
    let on_pole = rows
        .iter()
        .filter(|r| !r[3].is_empty())
        .filter(|r| {
            let (x, y): (f64, f64) = (r[4].parse().unwrap(), r[5].parse().unwrap());
            ((x - 2.0).powi(2) + (y - 1.0).powi(2)).sqrt() < 0.3
        })
        .count();
    assert!(on_pole > 10, "{on_pole} returns on the pole");
    assert!(rows.iter().any(|r| r[3].is_empty()));

    for (value, want) in
        [("sonar", "unknown sensor set"), ("scene", "no [[sensor]] table"), ("lidar,lidar", "twice")]
    {
        let o = run_straight(sc, &["--perception", value], &out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{value}: {err}");
        assert!(err.contains("perception") && err.contains(want) && err.contains(value), "{value}: {err}");
    }
}

/// `--yaw-mode` and `[controller] yaw_mode` (MIS_YAW_MODE): the path east is flown facing
/// north (the heading at arming) with hold, facing east with travel; the option wins over the
/// scene; bad values name the option or the file, table and field, with the allowed values.
#[test]
fn yaw_mode_from_the_option_and_the_scene() {
    let d = tmp("yaw");
    let plain = d.join("scene.toml");
    std::fs::write(&plain, SCENE).unwrap();
    let travel = d.join("travel.toml");
    std::fs::write(&travel, format!("{SCENE}[controller]\nyaw_mode = \"travel\"\n")).unwrap();
    let out = d.join("report");
    let fly = |scene: &PathBuf, extra: &[&str]| {
        let mut args = vec!["run", "--scene", scene.to_str().unwrap(), "--straight", "--out"];
        args.push(out.to_str().unwrap());
        args.extend_from_slice(extra);
        let o = parapet(&args);
        assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
        let (cx, cy) = (col("x"), col("yaw"));
        // The heading half way (ENU x = 2 m; past the goal a vehicle that overshot it turns back).
        let mid = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap_or(f64::NAN)).collect::<Vec<_>>())
            .find(|r| r[cx] >= 2.0)
            .map_or(f64::NAN, |r| r[cy]);
        (s["yaw_mode"].as_str().unwrap().to_string(), s["reached_goal"].as_bool().unwrap(), mid)
    };
    let (mode, goal, yaw) = fly(&plain, &[]);
    assert_eq!((mode.as_str(), goal), ("hold", true));
    assert!(yaw.abs() < 0.05, "hold keeps the heading at arming: {yaw}");
    for (scene, extra) in [(&plain, &["--yaw-mode", "travel"][..]), (&travel, &[][..])] {
        let (mode, goal, yaw) = fly(scene, extra);
        assert_eq!((mode.as_str(), goal), ("travel", true));
        assert!((yaw - std::f64::consts::FRAC_PI_2).abs() < 0.05, "travel faces east: {yaw}");
    }
    let (mode, _, _) = fly(&travel, &["--yaw-mode", "hold"]);
    assert_eq!(mode, "hold", "the option wins over the scene");
    // Without either: travel when every range sensor looks forward (the camera), else hold.
    // (The sets' coverage gaps assumed away: `coverage_cli.rs`.)
    let assume = ["--assume", "no-overhangs,no-low-obstacles,forward-flight"];
    for (perception, want) in
        [("camera", "travel"), ("lidar", "hold"), ("tof", "hold"), ("camera,lidar", "hold")]
    {
        let (mode, _, _) = fly(&plain, &[&["--perception", perception][..], &assume].concat());
        assert_eq!(mode, want, "--perception {perception}");
    }
    let (mode, _, _) =
        fly(&plain, &["--perception", "camera", "--yaw-mode", "hold", "--assume", "forward-flight"]);
    assert_eq!(mode, "hold", "the option wins over the sensors");
    let hold = d.join("hold.toml");
    std::fs::write(&hold, format!("{SCENE}[controller]\nyaw_mode = \"hold\"\n")).unwrap();
    let (mode, _, _) = fly(&hold, &["--perception", "camera", "--assume", "forward-flight"]);
    assert_eq!(mode, "hold", "the scene wins over the sensors");

    let o = parapet(&["run", "--scene", plain.to_str().unwrap(), "--straight", "--yaw-mode", "north"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--yaw-mode") && err.contains("north") && err.contains("travel"), "{err}");
    let bad = d.join("bad.toml");
    std::fs::write(&bad, format!("{SCENE}[controller]\nyaw_mode = \"north\"\n")).unwrap();
    let o = parapet(&["run", "--scene", bad.to_str().unwrap(), "--straight"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for want in ["bad.toml", "[controller]", "yaw_mode", "\"north\"", "hold", "travel"] {
        assert!(err.contains(want), "{want}: {err}");
    }
}
