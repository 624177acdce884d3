//! `parapet run --perception …` from the command line (issue 19): the report's
//! `ranges.csv`, and bad option values naming the option, the value and what is allowed.

use std::path::PathBuf;

mod common;
use common::parapet;

fn tmp(name: &str) -> PathBuf {
    common::tmp("perception_cli", name)
}

const SCENE: &str = r#"
name = "perception_cli"
[bounds]
min = [-1, -2, 0.3]
max = [5, 2, 2.5]
[mission]
start = [0, 0, 1]
goal = [4, 0, 1]
speed = 0.5
[[obstacles]]
kind = "cylinder"
base = [2, 1.0, 0]
radius = 0.2
height = 2.5
"#;

#[test]
fn lidar_run_writes_ranges_csv_and_bad_values_exit_2() {
    let d = tmp("run");
    let scene = d.join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let sc = scene.to_str().unwrap();
    let out = d.join("report");
    let o = parapet(&[
        "run",
        "--scene",
        sc,
        "--straight",
        "--perception",
        "lidar",
        "--out",
        out.to_str().unwrap(),
    ]);
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
        let o = parapet(&[
            "run",
            "--scene",
            sc,
            "--straight",
            "--perception",
            value,
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{value}: {err}");
        assert!(err.contains("perception") && err.contains(want) && err.contains(value), "{value}: {err}");
    }
}
