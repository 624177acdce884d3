//! Command-line tests: run the built `parapet` binary.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::parapet;

fn tmp(name: &str) -> PathBuf {
    common::tmp("cli", name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const GOOD: &str = r#"
name = "cli"
[bounds]
min = [-1, -2, 0.3]
max = [7, 2, 2.5]
[mission]
start = [0, 0, 1]
goal = [6, 0, 1]
speed = 0.5
[[obstacles]]
kind = "sphere"
center = [3, 1.2, 1]
radius = 0.3
[[obstacles]]
kind = "box"
min = [4, -2, 0]
max = [4.5, -1, 2]
"#;

fn write_scene(dir: &Path, text: &str) -> String {
    let p = dir.join("scene.toml");
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

#[test]
fn malformed_scenes_exit_2_naming_file_obstacle_and_field() {
    let d = tmp("malformed");
    let cases = [
        (GOOD.replace("radius = 0.3", "radius = -0.3"), "obstacles[0]", "radius"),
        (GOOD.replace("max = [4.5, -1, 2]", "maxx = [4.5, -1, 2]"), "obstacles[1]", "maxx"),
        (GOOD.replace("kind = \"box\"", "kind = \"pyramid\""), "obstacles[1]", "kind"),
        (GOOD.replace("speed = 0.5", "speed = \"fast\""), "[mission]", "speed"),
        (
            GOOD.replace("[[obstacles]]\nkind = \"sphere\"", "[[obstacles]]\nkind = \"sphere\"\nheight = 2"),
            "obstacles[0]",
            "height",
        ),
    ];
    for (text, place, field) in cases {
        let f = write_scene(&d, &text);
        for cmd in ["run", "plan"] {
            let o = parapet(&[cmd, "--scene", &f, "--out", d.join("o").to_str().unwrap()]);
            let e = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{cmd} {place} {field}: {e}");
            assert!(e.contains(&f), "file not named: {e}");
            assert!(e.contains(place), "{place} not named: {e}");
            assert!(e.contains(field), "{field} not named: {e}");
        }
    }
    let o = parapet(&["run", "--scene", "no/such/scene.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no/such/scene.toml"));
    let f = write_scene(&d, GOOD);
    let o = parapet(&["run", "--scene", &f, "--mu", "-1"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--mu"));
    let o = parapet(&["run", "--scene", &f, "--filter", "fancy"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn run_writes_the_report() {
    let d = tmp("run");
    let f = write_scene(&d, GOOD);
    let out = d.join("report");
    let o = parapet(&["run", "--scene", &f, "--seed", "2", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("min clearance"), "{stdout}");
    // Not a terminal: no progress bar, and no warning (e.g. a plot that failed).
    assert!(stderr(&o).is_empty(), "stderr: {}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for key in [
        "scene",
        "filter",
        "collided",
        "first_collision_time_s",
        "min_clearance_m",
        "min_h_bar",
        "reached_goal",
        "time_to_goal_s",
        "tracking_rms_m",
        "filter_active_fraction",
        "sim_time_s",
        "wall_time_s",
        "steps",
        "planning_time_ms",
        "path_length_m",
        "params",
    ] {
        assert!(s.get(key).is_some(), "summary.json lacks {key}");
    }
    assert_eq!(s["scene"], "cli");
    assert_eq!(s["path_source"], "planner");
    assert_eq!(s["reached_goal"], true, "{s}");
    assert_eq!(s["collided"], false);
    assert!(s["planning_time_ms"].as_f64().unwrap() > 0.0);
    assert!(s["path_length_m"].as_f64().unwrap() >= 6.0);
    for k in ["mu", "delta", "delta1", "kp", "kd", "speed"] {
        assert!(s["params"][k].as_f64().is_some(), "params.{k}");
    }
    let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(header.starts_with("t,ref_x,ref_y,ref_z,x,y,z,"), "{header}");
    assert!(header.contains("region") && header.contains("clearance") && header.contains("h_bar"));
    // Rows are ENU: the flight level is z = +1 (up).
    let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    assert!((row[6].parse::<f64>().unwrap() - 1.0).abs() < 0.05, "{row:?}");
    for p in ["top_view", "clearance", "filter_activity"] {
        for ext in ["svg", "png"] {
            let file = out.join(format!("{p}.{ext}"));
            assert!(std::fs::metadata(&file).map(|m| m.len() > 1000).unwrap_or(false), "{}", file.display());
        }
    }
}

#[test]
fn plan_then_run_the_path_file_and_no_path_exits_3() {
    let d = tmp("plan");
    let f = write_scene(&d, GOOD);
    let path = d.join("path.json");
    let o = parapet(&["plan", "--scene", &f, "--seed", "5", "--out", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = parapet(&[
        "run",
        "--scene",
        &f,
        "--path",
        path.to_str().unwrap(),
        "--out",
        d.join("r").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("r/summary.json")).unwrap()).unwrap();
    assert_eq!(s["path_source"], "file");
    // A path longer than the controller's capacity is refused, naming the file.
    let wps: Vec<String> = (0..70).map(|k| format!("[{}, 0, 1]", k as f64 * 0.08)).collect();
    let long = d.join("long.json");
    std::fs::write(
        &long,
        format!(
            r#"{{"scene": "cli", "waypoints": [{}], "length_m": 5.52, "planning_time_ms": 1.0, "iterations": 1, "seed": 0}}"#,
            wps.join(", ")
        ),
    )
    .unwrap();
    let o = parapet(&[
        "run",
        "--scene",
        &f,
        "--path",
        long.to_str().unwrap(),
        "--out",
        d.join("l").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("long.json") && stderr(&o).contains("waypoints"), "{}", stderr(&o));
    // A goal sealed inside a closed box: no path, exit code 3.
    let sealed = GOOD.to_string()
        + r#"
[[obstacles]]
kind = "box"
min = [5.0, -1.0, 0.0]
max = [7.0, -0.8, 2.5]
[[obstacles]]
kind = "box"
min = [5.0, 0.8, 0.0]
max = [7.0, 1.0, 2.5]
[[obstacles]]
kind = "box"
min = [5.0, -1.0, 0.0]
max = [5.2, 1.0, 2.5]
[[obstacles]]
kind = "box"
min = [6.8, -1.0, 0.0]
max = [7.0, 1.0, 2.5]
[[obstacles]]
kind = "box"
min = [5.0, -1.0, 1.7]
max = [7.0, 1.0, 2.5]
"#;
    let f = write_scene(&d, &sealed);
    let o = parapet(&["plan", "--scene", &f, "--out", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
}

#[test]
fn replay_hover_and_bad_csv() {
    let d = tmp("replay");
    let w = (0.5f64 * 9.81 / (4.0 * 3.07 / 1200f64.powi(2))).sqrt();
    let csv = d.join("in.csv");
    std::fs::write(&csv, format!("t,w1,w2,w3,w4\n0,{w},{w},{w},{w}\n1,{w},{w},{w},{w}\n2,0,0,0,0\n"))
        .unwrap();
    let out = d.join("states.csv");
    let o = parapet(&["replay", "--inputs", csv.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with("t,x,y,z,vx,vy,vz,qw,qx,qy,qz,p,q,r\n"));
    let last: Vec<f64> = text.lines().last().unwrap().split(',').map(|x| x.parse().unwrap()).collect();
    assert!(last[3].abs() < 1e-4, "hover drifted: z = {}", last[3]);
    std::fs::write(&csv, "t,w1,w2,w3,w4\n0,1,1,1\n").unwrap();
    let o = parapet(&["replay", "--inputs", csv.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("line 2"), "{}", stderr(&o));
    let veh = d.join("vehicle.toml");
    std::fs::write(&veh, "mass = 0.5\nmotor_tau = -1\n").unwrap();
    let o = parapet(&[
        "replay",
        "--vehicle",
        veh.to_str().unwrap(),
        "--inputs",
        csv.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("motor_tau") && stderr(&o).contains("vehicle.toml"), "{}", stderr(&o));
}
