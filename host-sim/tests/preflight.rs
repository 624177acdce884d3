//! Pre-flight checks, `reached_goal` and the default duration, through the built
//! `parapet` binary: a refused flight exits 2 before flying, naming the file, the
//! field / waypoint, the coordinate and what it violates.

use std::path::Path;
use std::process::Output;

mod common;
use common::parapet;

fn tmp(name: &str) -> common::TmpDir {
    common::tmp("preflight", name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Start (0, 0, 1), goal (6, 0, 1), an open line between them; a named sphere and
/// a box off the line, a walker that starts at x = 5.
const SCENE: &str = include_str!("data/scenes/preflight_cli.toml");

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

fn path_json(wps: &[[f64; 3]]) -> String {
    let w: Vec<String> = wps.iter().map(|p| format!("[{}, {}, {}]", p[0], p[1], p[2])).collect();
    format!(r#"{{"scene": "pre", "waypoints": [{}]}}"#, w.join(", "))
}

fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// `run` refuses with exit 2, nothing written; returns stderr.
fn refused(args: &[&str], out: &Path) -> String {
    let mut v = vec!["run"];
    v.extend_from_slice(args);
    v.extend_from_slice(&["--out", out.to_str().unwrap()]);
    let o = parapet(&v);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{v:?}: {e}");
    assert!(!out.join("summary.json").exists(), "{v:?} flew: {e}");
    e
}

#[test]
fn start_in_an_obstacle_or_the_ground_is_refused_before_flying() {
    let d = tmp("start");
    let out = d.join("o");
    // Start 0.2 m from the ball's surface (hull 0.2236 m): today's collision at t = 0.001 s.
    let f = write(&d, "in_ball.toml", &SCENE.replace("start = [0, 0, 1]", "start = [3, 0.7, 1]"));
    for mode in [&["--straight"][..], &[][..]] {
        let mut args = vec!["--scene", f.as_str()];
        args.extend_from_slice(mode);
        let e = refused(&args, &out);
        assert!(e.contains("in_ball.toml: [mission] field `start`"), "{e}");
        assert!(
            e.contains("obstacles[0] (ball)") && e.contains("[3, 0.7, 1]") && e.contains("0.2236"),
            "{e}"
        );
    }
    // A moving obstacle at its t = 0 position.
    let f = write(&d, "in_walker.toml", &SCENE.replace("start = [0, 0, 1]", "start = [5, 1.5, 1]"));
    let e = refused(&["--scene", &f, "--straight"], &out);
    assert!(e.contains("obstacles[2] (walker) at t = 0"), "{e}");
    // The hull's bottom below the ground (centre 0.15 m up, hull 0.2236 m).
    let f = write(&d, "ground.toml", &SCENE.replace("start = [0, 0, 1]", "start = [0, 0, 0.15]"));
    let e = refused(&["--scene", &f, "--straight"], &out);
    assert!(e.contains("ground.toml: [mission] field `start`") && e.contains("into the ground"), "{e}");
    assert!(e.contains("[0, 0, 0.15]") && e.contains("z ≥ 0.2236"), "{e}");
    // `pil` runs the same checks before it looks for the firmware.
    let o = parapet(&[
        "pil",
        "--scene",
        &f,
        "--straight",
        "--firmware",
        "no/such/elf",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("into the ground"), "{}", stderr(&o));
}

#[test]
fn bad_waypoints_are_refused_naming_the_path_file_index_and_coordinate() {
    let d = tmp("waypoints");
    let out = d.join("o");
    let scene = write(&d, "scene.toml", SCENE);
    type Case<'a> = (&'a [[f64; 3]], &'a str, &'a [&'a str]);
    let cases: [Case; 4] = [
        // Outside the bounds (y = 2.5 > 2).
        (
            &[[0.0, 0.0, 1.0], [3.0, 2.5, 1.0], [6.0, 0.0, 1.0]],
            "waypoints[1]",
            &["outside the bounds", "-2 ≤ y ≤ 2"],
        ),
        // Underground.
        (
            &[[0.0, 0.0, 1.0], [2.0, 0.0, -0.5], [6.0, 0.0, 1.0]],
            "waypoints[1]",
            &["[2, 0, -0.5]", "0.1 ≤ z ≤ 2.5"],
        ),
        // Hull into the ground, inside the bounds.
        (
            &[[0.0, 0.0, 1.0], [2.0, 0.0, 0.15], [6.0, 0.0, 1.0]],
            "waypoints[1]",
            &["into the ground", "z ≥ 0.2236"],
        ),
        // Inside the box wall.
        (
            &[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [4.2, -1.5, 1.0], [6.0, 0.0, 1.0]],
            "waypoints[2]",
            &["obstacles[1]", "[4.2, -1.5, 1]"],
        ),
    ];
    for (k, (wps, field, words)) in cases.into_iter().enumerate() {
        let p = write(&d, &format!("p{k}.json"), &path_json(wps));
        let e = refused(&["--scene", &scene, "--path", &p], &out);
        assert!(e.contains(&format!("p{k}.json: field `{field}`")), "{e}");
        for w in words {
            assert!(e.contains(w), "{w:?} missing: {e}");
        }
    }
}

#[test]
fn a_path_of_another_scene_is_refused_unless_foreign_path() {
    let d = tmp("foreign");
    let out = d.join("o");
    // The office's committed path flown in the one-sphere scene.
    let e = refused(&["--scene", "scenes/one_sphere.toml", "--path", "scenes/office_path.json"], &out);
    assert!(e.contains("scenes/office_path.json: field `waypoints[0]`"), "{e}");
    assert!(e.contains("does not belong to scene one_sphere") && e.contains("within 0.5 m"), "{e}");
    assert!(e.contains("--foreign-path"), "{e}");
    // The last waypoint 3 m short of the goal.
    let scene = write(&d, "scene.toml", SCENE);
    let short = write(&d, "short.json", &path_json(&[[0.0, 0.0, 1.0], [3.0, -0.4, 1.0]]));
    let e = refused(&["--scene", &scene, "--path", &short], &out);
    assert!(
        e.contains("short.json: field `waypoints[1]`") && e.contains("from the mission goal [6, 0, 1]"),
        "{e}"
    );
    // --foreign-path does not lift the collision checks.
    let bad = write(&d, "bad.json", &path_json(&[[0.0, 0.0, 1.0], [4.2, -1.5, 1.0]]));
    let e = refused(&["--scene", &scene, "--path", &bad, "--foreign-path"], &out);
    assert!(e.contains("bad.json: field `waypoints[1]`") && e.contains("obstacles[1]"), "{e}");
    // --foreign-path needs --path.
    let e = refused(&["--scene", &scene, "--straight", "--foreign-path"], &out);
    assert!(e.contains("option --foreign-path: only with --path"), "{e}");
}

#[test]
fn reached_goal_means_the_scene_goal_not_the_path_end() {
    let d = tmp("goal");
    let scene = write(&d, "scene.toml", SCENE);
    // A path ending 3 m short of the scene's goal, flown on purpose.
    let short = write(&d, "short.json", &path_json(&[[0.0, 0.0, 1.0], [3.0, -0.4, 1.0]]));
    let out = d.join("short");
    let o = parapet(&[
        "run",
        "--scene",
        &scene,
        "--path",
        &short,
        "--foreign-path",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = summary(&out);
    assert_eq!(s["reached_path_end"], true, "{s}");
    assert_eq!(s["reached_goal"], false, "{s}");
    assert_eq!(s["end_reason"], "path_end", "{s}");
    assert!(s["time_to_goal_s"].is_null(), "{s}");
    let to_goal = s["final_distance_to_goal_m"].as_f64().unwrap();
    assert!((to_goal - 3.03).abs() < 0.1, "{s}");
    assert!(s["final_distance_to_path_end_m"].as_f64().unwrap() < 0.1, "{s}");
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(
        table.contains("reached goal") && table.contains("false") && table.contains("path end"),
        "{table}"
    );
    // The scene's own straight line: both true, end reason goal.
    let out = d.join("straight");
    let o = parapet(&["run", "--scene", &scene, "--straight", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = summary(&out);
    assert_eq!((s["reached_goal"].clone(), s["reached_path_end"].clone()), (true.into(), true.into()), "{s}");
    assert_eq!(s["end_reason"], "goal", "{s}");
    assert!(s["final_distance_to_goal_m"].as_f64().unwrap() < 0.1, "{s}");
}

#[test]
fn default_duration_covers_the_leg_to_the_first_waypoint() {
    let d = tmp("duration");
    let scene = write(&d, "scene.toml", SCENE);
    // One waypoint, the goal, 6 m from the start: the polyline has length 0, and a
    // duration of 1.5 × 0 + 15 s stopped the flight short (at 0.5 m/s, 12 s of cruise).
    let one = write(&d, "one.json", &path_json(&[[6.0, 0.0, 1.0]]));
    let out = d.join("one");
    let o = parapet(&[
        "run",
        "--scene",
        &scene,
        "--path",
        &one,
        "--foreign-path",
        // The paper's constant-speed reference: 12 s of cruise at 0.5 m/s.
        "--guidance",
        "paper",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = summary(&out);
    assert_eq!(s["end_reason"], "goal", "{s}");
    assert_eq!(s["reached_goal"], true, "{s}");
    let t = s["time_to_goal_s"].as_f64().unwrap();
    assert!(t > 15.0 && t < 33.0, "time to goal {t} s: beyond the old 15 s limit, within 1.5 × 12 + 15 s");
}
