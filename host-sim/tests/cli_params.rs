//! `--param NAME=VALUE` and `--params FILE` (issue 37): any parameter of the table set on a
//! simulated flight by its name, checked like every other input.

use std::path::Path;
use std::process::Output;

mod common;
use common::parapet;

fn tmp(name: &str) -> common::TmpDir {
    common::tmp("cli-params", name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Open ground north of the start (ENU: the vehicle faces +y): 40 m to fly at full stick.
const OPEN: &str = include_str!("data/scenes/cli_params_open.toml");

const FORWARD: &str = "name = \"forward\"\nduration = 9.0\n[[stick]]\nt = 0.0\npitch = 1.0\n";

fn setup(dir: &Path) -> (String, String) {
    let scene = dir.join("open.toml");
    std::fs::write(&scene, OPEN).unwrap();
    let script = dir.join("forward.pilot.toml");
    std::fs::write(&script, FORWARD).unwrap();
    (scene.display().to_string(), script.display().to_string())
}

/// Mean horizontal speed of a report's `trajectory.csv` from 4 s on (the stick is held from
/// 0 s; the speed has settled by then), m/s.
fn cruise_speed(report: &Path) -> f64 {
    let text = std::fs::read_to_string(report.join("trajectory.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
    let (t, vx, vy) = (col("t"), col("vx"), col("vy"));
    let v: Vec<f64> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap_or(f64::NAN)).collect::<Vec<f64>>())
        .filter(|f| f[t] >= 4.0)
        .map(|f| f[vx].hypot(f[vy]))
        .collect();
    assert!(v.len() > 100, "{} samples after 4 s", v.len());
    v.iter().sum::<f64>() / v.len() as f64
}

fn summary(report: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(report.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn pa_speed_max_set_by_name_flies_the_pilot_at_that_speed() {
    let d = tmp("pa-speed");
    let (scene, script) = setup(&d);
    let fly = |out: &Path, extra: &[&str]| {
        let mut args = vec!["run", "--scene", &scene, "--pilot", &script, "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = parapet(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    };
    let (slow, fast, file_run) = (d.join("default"), d.join("fast"), d.join("file"));
    fly(&slow, &[]);
    fly(&fast, &["--param", "PA_SPEED_MAX=3"]);
    let params = d.join("fast.params");
    std::fs::write(&params, "# Onboard parameters for Vehicle 1\n1\t1\tPA_SPEED_MAX\t3\t9\n").unwrap();
    fly(&file_run, &["--params", params.to_str().unwrap()]);
    let (v1, v3, vf) = (cruise_speed(&slow), cruise_speed(&fast), cruise_speed(&file_run));
    println!("full stick, mean from 4 s: default {v1:.2} m/s, --param PA_SPEED_MAX=3 {v3:.2} m/s, --params file {vf:.2} m/s");
    assert!((0.95..1.05).contains(&v1), "default PA_SPEED_MAX 1 m/s: flew {v1}");
    assert!((2.85..3.15).contains(&v3), "PA_SPEED_MAX=3: flew {v3}");
    assert_eq!(v3.to_bits(), vf.to_bits(), "the .params file flies as --param");
    assert_eq!(summary(&fast)["params_set"]["PA_SPEED_MAX"], 3.0);
    assert!(summary(&slow).get("params_set").is_none(), "nothing set by name");
}

#[test]
fn a_keyed_parameter_acts_as_its_scene_key_and_its_option_wins() {
    let d = tmp("keyed");
    let (scene, _) = setup(&d);
    let run = |extra: &[&str]| {
        let out = d.join(format!("o{}", extra.len()));
        let mut args = vec!["run", "--scene", &scene, "--straight", "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = parapet(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        summary(&out)
    };
    let s = run(&["--param", "CBF_MU=0.9", "--param", "WP_SPEED=0.8"]);
    assert_eq!(s["params"]["mu"], 0.9);
    assert_eq!(s["params"]["speed"], 0.8);
    assert!(s.get("params_set").is_none(), "keyed parameters are the run's own fields");
    let s = run(&["--param", "CBF_MU=0.9", "--mu", "1.1", "--param", "CBF_VARIANT=0"]);
    assert_eq!(s["params"]["mu"], 1.1, "--mu wins over --param CBF_MU");
    assert_eq!(s["filter"], "paper", "a code parameter by its number");
}

#[test]
fn bad_names_values_and_files_exit_2_naming_them() {
    let d = tmp("bad");
    let (scene, _) = setup(&d);
    let bad_file = d.join("bad.params");
    std::fs::write(&bad_file, "1\t1\tPA_SPEED_MAX\t30\t9\n").unwrap();
    let missing = d.join("missing.params");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["--param".into(), "NO_SUCH=1".into()], "NO_SUCH"),
        (vec!["--param".into(), "PA_SPEED_MAX=99".into()], "0.1 ≤ PA_SPEED_MAX ≤ 10"),
        (vec!["--param".into(), "PA_SPEED_MAX=fast".into()], "PA_SPEED_MAX"),
        (vec!["--param".into(), "PA_SPEED_MAX".into()], "NAME=VALUE"),
        (vec!["--param".into(), "CBF_VARIANT=1.5".into()], "whole number"),
        (vec!["--params".into(), bad_file.display().to_string()], "line 1"),
        (vec!["--params".into(), missing.display().to_string()], "option --params"),
        // The cross-parameter rules: a hover needs more than the vehicle's weight in thrust.
        (vec!["--param".into(), "VEH_MASS=5".into()], "inconsistent"),
        // A braking deceleration beyond what the filter may command (issue 36).
        (vec!["--param".into(), "CBF_BRAKE_ACC=10".into()], "brake_accel must be finite, > 0 and <= u_max"),
        (vec!["--param".into(), "CBF_BRAKE_DLY=0".into()], "0.01 ≤ CBF_BRAKE_DLY ≤ 1 s"),
    ];
    let out = d.join("o");
    for (extra, want) in cases {
        let mut args: Vec<String> =
            vec!["run".into(), "--scene".into(), scene.clone(), "--straight".into(), "--out".into()];
        args.push(out.display().to_string());
        args.extend(extra);
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = parapet(&refs);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(want), "{args:?}: {e:?} does not name {want:?}");
    }
    assert!(!out.exists(), "a refused run writes no report");
}

/// A run says what it was (issue 37): a piloted or offboard run's summary has no path, goal or
/// path-end rows from a mission it never had, and lists the parameters set by name.
#[test]
fn a_piloted_or_offboard_run_reports_no_mission_and_the_parameters_set() {
    let d = tmp("what");
    let (scene, script) = setup(&d);
    let o = d.join("pilot");
    let r = parapet(&[
        "run",
        "--scene",
        &scene,
        "--pilot",
        &script,
        "--param",
        "PA_SPEED_MAX=2.5",
        "--out",
        o.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&r.stdout).into_owned();
    assert!(r.status.success(), "{}", stderr(&r));
    assert!(text.contains("none (pilot flight: no path, goal or path end)"), "{text}");
    let row = |t: &str, k: &str| t.lines().any(|l| l.trim_start().starts_with(k));
    assert!(!row(&text, "path end") && !row(&text, "reached goal") && !row(&text, "path "), "{text}");
    assert!(text.contains("params set") && text.contains("PA_SPEED_MAX 2.5"), "{text}");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/pilot");
    let o = d.join("offboard");
    let r = parapet(&[
        "run",
        "--scene",
        root.join("wall.toml").to_str().unwrap(),
        "--offboard",
        root.join("offboard_wall.offboard.toml").to_str().unwrap(),
        "--out",
        o.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&r.stdout).into_owned();
    assert!(r.status.success(), "{}", stderr(&r));
    assert!(text.contains("none (offboard flight"), "{text}");
    assert_eq!(summary(&o)["path_source"], "offboard");
    // A mission run keeps its rows.
    let o = d.join("mission");
    let r = parapet(&["run", "--scene", &scene, "--straight", "--out", o.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&r.stdout).into_owned();
    assert!(row(&text, "reached goal") && row(&text, "path end") && !row(&text, "params set"), "{text}");
}

/// `--guidance trajectory` (issue 35) is `--param MIS_GUIDANCE=1`: listed among the parameters
/// set, and a straight 3 m mission at 2 m/s on it reaches the goal; an unknown name exits 2.
#[test]
fn guidance_trajectory_sets_mis_guidance_and_flies_the_mission() {
    let d = tmp("guidance");
    let (scene, _) = setup(&d);
    let out = d.join("o");
    let o = parapet(&[
        "run",
        "--scene",
        &scene,
        "--straight",
        "--speed",
        "2",
        "--guidance",
        "trajectory",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = summary(&out);
    assert_eq!(s["params_set"]["MIS_GUIDANCE"], 1.0, "{s}");
    assert_eq!(s["reached_goal"], true, "{s}");
    assert_eq!(s["collided"], false, "{s}");
    let bad = d.join("bad");
    let o = parapet(&[
        "run",
        "--scene",
        &scene,
        "--straight",
        "--guidance",
        "fast",
        "--out",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("expected one of paper, trajectory"), "{}", stderr(&o));
}
