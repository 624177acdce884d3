//! Command-line tests: run the built `parapet` binary.

use std::path::Path;
use std::process::Output;

mod common;
use common::parapet;

fn tmp(name: &str) -> common::TmpDir {
    common::tmp("cli", name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const GOOD: &str = include_str!("data/scenes/cli_good.toml");

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
    for p in ["top_view", "clearance", "speed", "filter_activity"] {
        for ext in ["svg", "png"] {
            let file = out.join(format!("{p}.{ext}"));
            assert!(std::fs::metadata(&file).map(|m| m.len() > 1000).unwrap_or(false), "{}", file.display());
        }
    }
    // The speed plot names the run's cruise speed (its limit line).
    let speed = std::fs::read_to_string(out.join("speed.svg")).unwrap();
    let cruise = s["params"]["speed"].as_f64().unwrap();
    assert!(
        speed.contains(&format!("cruise (mission speed) {cruise} m/s")),
        "speed.svg lacks the cruise {cruise}"
    );
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
    // A path longer than the controller's 64 waypoints is flown (streamed): `long_path.rs`.
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

// ---- Hardening (issue 15): bounded runs, clear errors, help, pipes, outputs ----

use parapet_sim::input::limits;

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Library error enums as debug text: none may reach the user.
const DEBUG_TEXT: [&str; 8] = [
    "BadParams",
    "Tracking",
    "Thrust",
    "NonFiniteInput",
    "NoFreshPosition",
    "OutOfRange",
    "Arm(",
    "Waypoint(",
];

/// Exit 2, every `needles` in stderr, no debug text, no panic.
fn refused(o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{needles:?}: {e}");
    for n in needles {
        assert!(e.contains(n), "{n:?} not in: {e}");
    }
    for d in DEBUG_TEXT {
        assert!(!e.contains(d), "debug text {d:?} in: {e}");
    }
    assert!(!e.contains("panicked"), "{e}");
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn durations_beyond_the_cap_are_refused_and_memory_follows_the_flight() {
    let d = tmp("durations");
    let f = write_scene(&d, GOOD);
    let out = d.join("o");
    let o = out.to_str().unwrap();
    let cap = limits::MAX_DURATION_S.to_string();
    for dur in ["1e6", "1e20"] {
        let r = parapet(&["run", "--scene", &f, "--straight", "--duration", dur, "--out", o]);
        refused(&r, &["option --duration", &cap, "--max-duration"]);
    }
    let r = parapet(&["run", "--scene", &f, "--straight", "--speed", "1e-3", "--out", o]);
    refused(&r, &["option --duration", "default duration", &cap]);
    let long = write_scene(&d, &GOOD.replace("speed = 0.5", "speed = 0.5\n[sim]\nduration = 1e7"));
    let r = parapet(&["run", "--scene", &long, "--straight", "--out", o]);
    refused(&r, &[&long, "[sim]", "duration", "1e7", &cap]);
    let r = parapet(&["run", "--scene", &f, "--straight", "--max-duration", "1e6", "--out", o]);
    refused(&r, &["option --max-duration", &limits::MAX_DURATION_CEILING_S.to_string()]);
    // A whole simulated day allowed: the flight still ends at the goal after a few
    // seconds, without reserving memory for the day (86 400 s × 250 Hz samples).
    let day = limits::MAX_DURATION_CEILING_S.to_string();
    let r = parapet(&[
        "run",
        "--scene",
        &f,
        "--straight",
        "--no-noise",
        "--max-duration",
        &day,
        "--duration",
        &day,
        "--out",
        o,
    ]);
    assert_eq!(r.status.code(), Some(0), "{}", stderr(&r));
    let s = summary(&out);
    assert_eq!(s["end_reason"], "goal", "{s}");
    assert!(s["sim_time_s"].as_f64().unwrap() < 30.0, "{s}");
}

#[test]
fn latency_dt_and_step_caps_name_the_file_table_and_field() {
    let d = tmp("caps");
    let o = d.join("o");
    let o = o.to_str().unwrap();
    let with = |table: &str| GOOD.replacen("[[obstacles]]", &format!("{table}\n[[obstacles]]"), 1);
    let cases = [
        (with("[sensors]\nposition_latency = 1e9"), vec!["[sensors]", "position_latency", "1e9", "0.1"]),
        (with("[sensors]\nposition_latency = 10"), vec!["[sensors]", "position_latency", "10", "0.1"]),
        (with("[sim]\ndt = 1e-7"), vec!["[sim]", "`dt`", "1e-7", "1e-5"]),
        (with("[sim]\ndt = 0.002"), vec!["[sim]", "`dt`", "0.002", "1e-3"]),
    ];
    for (text, needles) in cases {
        let f = write_scene(&d, &text);
        let r = parapet(&["run", "--scene", &f, "--straight", "--out", o]);
        let mut n = needles.clone();
        n.push(&f);
        refused(&r, &n);
    }
    // duration / dt beyond the step cap, with the duration cap raised.
    let f = write_scene(&d, &with("[sim]\ndt = 1e-5"));
    let r = parapet(&[
        "run",
        "--scene",
        &f,
        "--straight",
        "--max-duration",
        "86400",
        "--duration",
        "5000",
        "--out",
        o,
    ]);
    refused(&r, &["option --duration", "plant steps"]);
}

#[test]
fn library_errors_become_named_inputs() {
    let d = tmp("clear");
    let o = d.join("o");
    let o = o.to_str().unwrap();
    let f = write_scene(&d, GOOD);
    let r = parapet(&["run", "--scene", &f, "--straight", "--speed", "200", "--out", o]);
    refused(&r, &["option --speed", "200", "100"]);
    let r = parapet(&["run", "--scene", &f, "--straight", "--kp", "1e300", "--out", o]);
    refused(&r, &["option --kp", "1e300"]);
    let r = parapet(&["run", "--scene", &f, "--straight", "--delta1", "0.01", "--out", o]);
    refused(&r, &["option --delta1", "0.01", "0.05"]);
    // δ below the squared hull radius: the option that set it, and both values.
    let r = parapet(&["run", "--scene", &f, "--straight", "--delta", "0.01", "--out", o]);
    refused(&r, &["option --delta", "0.01", "hull_radius", "0.0499"]);
    // A negative number is the option's value, refused by its range (it was "unexpected argument '-1'").
    let sweep = ["sweep", "--scene", &f, "--straight", "--mu", "0.9", "--delta1", "0.1", "--out", o];
    for (args, needles) in [
        (vec!["plan", "--scene", &f, "--time-limit", "-1", "--out", o], ["option --time-limit", "-1"]),
        ([&sweep[..], &["--duration", "-1"]].concat(), ["option --duration", "-1"]),
        ([&sweep[..], &["--speed", "-1"]].concat(), ["--speed", "-1"]),
    ] {
        refused(&parapet(&args), &needles);
    }
    let scene_cases = [
        (GOOD.replace("speed = 0.5", "speed = 200"), vec!["[mission]", "speed", "200", "100"]),
        (
            GOOD.replacen("[[obstacles]]", "[vehicle]\nmass = 1e-9\n[[obstacles]]", 1),
            vec!["[vehicle]", "mass", "1e-9"],
        ),
        (GOOD.replace("radius = 0.3", "radius = 1e300"), vec!["obstacles[0]", "radius", "1e300"]),
        (
            GOOD.replacen("[[obstacles]]", "[controller]\ndelta1 = 0.01\n[[obstacles]]", 1),
            vec!["[controller]", "delta1", "0.01", "0.05"],
        ),
        (GOOD.replace("kind = \"box\"\n", ""), vec!["obstacles[1]", "kind"]),
    ];
    for (text, needles) in scene_cases {
        let f = write_scene(&d, &text);
        let r = parapet(&["run", "--scene", &f, "--straight", "--out", o]);
        let mut n = needles.clone();
        n.push(&f);
        refused(&r, &n);
    }
    let f = write_scene(&d, GOOD);
    let path = d.join("far.json");
    std::fs::write(&path, r#"{"waypoints": [[0, 0, 1], [2e5, 0, 1], [6, 0, 1]]}"#).unwrap();
    let r = parapet(&["run", "--scene", &f, "--path", path.to_str().unwrap(), "--out", o]);
    refused(&r, &["far.json", "waypoints[1][0]", "200000", "100000"]);
}

#[test]
fn a_closed_stdout_ends_quietly() {
    use std::process::{Command, Stdio};
    let d = tmp("pipe");
    let f = write_scene(&d, GOOD);
    let csv = d.join("in.csv");
    std::fs::write(&csv, "t,w1,w2,w3,w4\n0,0,0,0,0\n0.1,0,0,0,0\n").unwrap();
    let (o, p, s) = (d.join("o"), d.join("p.json"), d.join("s.csv"));
    let cases: [Vec<&str>; 3] = [
        vec!["run", "--scene", &f, "--straight", "--duration", "2", "--out", o.to_str().unwrap()],
        vec!["plan", "--scene", &f, "--out", p.to_str().unwrap()],
        vec!["replay", "--inputs", csv.to_str().unwrap(), "--out", s.to_str().unwrap()],
    ];
    for args in cases {
        // `parapet … | true`: the reader is gone before parapet writes.
        let mut child = Command::new(env!("CARGO_BIN_EXE_parapet"))
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let r = child.wait_with_output().unwrap();
        assert_eq!(r.status.code(), Some(0), "{args:?}: {}", stderr(&r));
        assert!(stderr(&r).is_empty(), "{args:?}: {}", stderr(&r));
    }
}

#[test]
fn help_shows_defaults_limits_examples_and_exit_codes() {
    for cmd in [
        vec!["--help"],
        vec!["run", "--help"],
        vec!["pil", "--help"],
        vec!["plan", "--help"],
        vec!["replay", "--help"],
        vec!["sweep", "--help"],
        vec!["sweep-merge", "--help"],
        vec!["campaign", "--help"],
        vec!["campaign-merge", "--help"],
        vec!["scene", "generate", "--help"],
    ] {
        let r = parapet(&cmd);
        assert_eq!(r.status.code(), Some(0));
        let h = stdout(&r);
        for n in ["Exit codes:", "Examples:", "  2    bad input", "  3    no path"] {
            assert!(h.contains(n), "{cmd:?}: {n:?} missing");
        }
    }
    let h = stdout(&parapet(&["run", "--help"]));
    let ceiling = limits::MAX_DURATION_CEILING_S.to_string();
    for n in [
        "mu 1.4 s",
        "delta 0.05",
        "delta1 0.1",
        "kp 0.5",
        "kd 0.8",
        "else 1.4]",
        "duration ≤ 3600 s",
        ceiling.as_str(),
        "0.001 ≤ speed ≤ 100 m/s",
        "1e5 m",
        "65535 waypoints (the controller is given 64 at a time",
        "32 obstacles",
        "4 barriers",
        "1 s",
        "1e-3",
    ] {
        assert!(h.contains(n), "run --help lacks {n:?}:\n{h}");
    }
    let h = stdout(&parapet(&["replay", "--help"]));
    assert!(h.contains(&limits::MAX_REPLAY_ROWS.to_string()) && h.contains("--start 1,2,-1.5"), "{h}");
    // The planner's budget is --time-limit, not a fixed 1 s.
    let h = stdout(&parapet(&["plan", "--help"]));
    assert!(h.contains("stops after --time-limit (default 1 s"), "{h}");
}

#[test]
fn replay_takes_start_as_written_and_a_scene_as_vehicle_and_refuses_huge_spans() {
    let d = tmp("replay2");
    let csv = d.join("in.csv");
    std::fs::write(&csv, "t,w1,w2,w3,w4\n0,0,0,0,0\n0.01,0,0,0,0\n").unwrap();
    let out = d.join("states.csv");
    let (c, o) = (csv.to_str().unwrap(), out.to_str().unwrap());
    for (start, x) in [
        ("1,2,3", "1.000000000,2.000000000,3.000000000"),
        ("-1,2,-3", "-1.000000000,2.000000000,-3.000000000"),
    ] {
        let r = parapet(&["replay", "--inputs", c, "--out", o, "--start", start]);
        assert_eq!(r.status.code(), Some(0), "{start}: {}", stderr(&r));
        let row = std::fs::read_to_string(&out).unwrap().lines().nth(1).unwrap().to_string();
        assert!(row.starts_with(&format!("0.000000,{x},")), "{start}: {row}");
    }
    let r = parapet(&["replay", "--inputs", c, "--out", o, "--start", "1,2"]);
    assert_eq!(r.status.code(), Some(2), "{}", stderr(&r));
    let r = parapet(&["replay", "--vehicle", "scenes/office.toml", "--inputs", c, "--out", o]);
    assert_eq!(r.status.code(), Some(0), "{}", stderr(&r));
    let scene = d.join("heavy.toml");
    std::fs::write(&scene, GOOD.replacen("[[obstacles]]", "[vehicle]\nmass = -1\n[[obstacles]]", 1)).unwrap();
    let r = parapet(&["replay", "--vehicle", scene.to_str().unwrap(), "--inputs", c, "--out", o]);
    refused(&r, &["heavy.toml", "[vehicle]", "mass"]);
    std::fs::write(&csv, "t,w1,w2,w3,w4\n0,0,0,0,0\n1e9,0,0,0,0\n").unwrap();
    let t0 = std::time::Instant::now();
    let r = parapet(&["replay", "--inputs", c, "--out", o]);
    refused(&r, &["in.csv", "line 3", "`t`", "1e9", &limits::MAX_REPLAY_SPAN_S.to_string()]);
    assert!(t0.elapsed().as_secs() < 10);
    let r = parapet(&["replay", "--inputs", c, "--out", o, "--dt", "1e-7"]);
    refused(&r, &["option --dt", "1e-7"]);
    let r = parapet(&["replay", "--inputs", c, "--out", o, "--wind", "1e300,0,0"]);
    refused(&r, &["option --wind", "1e300", "50 m/s"]);
    // A negative number is a value (it was "unexpected argument '-5'"), refused by range.
    for w in ["-5", "1e300", "nan"] {
        let r = parapet(&["replay", "--inputs", c, "--out", o, "--motor-lag", "--initial-speed", w]);
        refused(&r, &["option --initial-speed", "omega_max = 1200 rad/s"]);
    }
}

#[test]
fn default_scene_outside_the_tree_is_named() {
    let d = tmp("elsewhere");
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_parapet"))
        .args(["plan", "--out", "p.json"])
        .current_dir(&d)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(0), "{}", stderr(&r));
    let e = stderr(&r);
    assert!(e.contains("note:") && e.contains("office.toml") && e.contains("--scene"), "{e}");
    assert!(d.join("p.json").is_file());
}

#[test]
fn parameters_print_as_written() {
    let d = tmp("params");
    let f = write_scene(&d, GOOD);
    let out = d.join("o");
    let r = parapet(&["run", "--scene", &f, "--straight", "--duration", "1", "--out", out.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(0), "{}", stderr(&r));
    assert!(
        stdout(&r).contains("mu 1.4 s, delta 0.05 m^2, delta1 0.1 m^2, kp 0.5 1/s^2, kd 0.8 1/s"),
        "{}",
        stdout(&r)
    );
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(text.contains("\"mu\": 1.4,") && text.contains("\"delta\": 0.05,"), "{text}");
}

#[test]
fn outputs_never_replace_inputs() {
    let d = tmp("overwrite");
    let f = write_scene(&d, GOOD);
    let before = std::fs::read_to_string(&f).unwrap();
    let r = parapet(&["plan", "--scene", &f, "--out", &f]);
    refused(&r, &["option --out", "scene file", &f]);
    assert_eq!(std::fs::read_to_string(&f).unwrap(), before);
    // An existing file that is not a path file: refused unless --force.
    let notes = d.join("notes.txt");
    std::fs::write(&notes, "keep me").unwrap();
    let r = parapet(&["plan", "--scene", &f, "--out", notes.to_str().unwrap()]);
    refused(&r, &["option --out", "notes.txt", "--force"]);
    assert_eq!(std::fs::read_to_string(&notes).unwrap(), "keep me");
    let r = parapet(&["plan", "--scene", &f, "--out", notes.to_str().unwrap(), "--force"]);
    assert_eq!(r.status.code(), Some(0), "{}", stderr(&r));
    // A previous path file is replaced.
    let r = parapet(&["plan", "--scene", &f, "--seed", "1", "--out", notes.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(0), "{}", stderr(&r));
    // run --out where the report would write over the scene file.
    let sub = d.join("rep");
    std::fs::create_dir_all(&sub).unwrap();
    let scene_as_csv = sub.join("trajectory.csv");
    std::fs::write(&scene_as_csv, GOOD).unwrap();
    let r = parapet(&[
        "run",
        "--scene",
        scene_as_csv.to_str().unwrap(),
        "--straight",
        "--out",
        sub.to_str().unwrap(),
    ]);
    refused(&r, &["option --out", "scene file", "trajectory.csv"]);
    assert_eq!(std::fs::read_to_string(&scene_as_csv).unwrap(), GOOD);
    let r = parapet(&["run", "--scene", &f, "--straight", "--out", &f]);
    refused(&r, &["option --out", "not a directory"]);
    // run --disturbances FILE where the report writes summary.json (it was replaced).
    let dist = sub.join("summary.json");
    let wind = "[wind]\nspeed = 1.0\n";
    std::fs::write(&dist, wind).unwrap();
    let (ds, so) = (dist.to_str().unwrap(), sub.to_str().unwrap());
    let r = parapet(&["run", "--scene", &f, "--straight", "--disturbances", ds, "--out", so]);
    refused(&r, &["option --out", "disturbances file", "summary.json"]);
    assert_eq!(std::fs::read_to_string(&dist).unwrap(), wind);
    // replay --out onto its own input.
    let csv = d.join("in.csv");
    let text = "t,w1,w2,w3,w4\n0,0,0,0,0\n0.01,0,0,0,0\n";
    std::fs::write(&csv, text).unwrap();
    let r = parapet(&["replay", "--inputs", csv.to_str().unwrap(), "--out", csv.to_str().unwrap()]);
    refused(&r, &["option --out", "input CSV", "in.csv"]);
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), text);
}

#[test]
fn pil_timeout_is_capped_before_any_build() {
    let d = tmp("piltimeout");
    let f = write_scene(&d, GOOD);
    let o = d.join("o");
    let r =
        parapet(&["pil", "--scene", &f, "--straight", "--timeout", "1e300", "--out", o.to_str().unwrap()]);
    refused(&r, &["option --timeout", "1e300", &limits::MAX_PIL_TIMEOUT_S.to_string()]);
    let r = parapet(&["pil", "--scene", &f, "--straight", "--timeout", "-1", "--out", o.to_str().unwrap()]);
    refused(&r, &["option --timeout", "-1"]);
    let h = stdout(&parapet(&["--help"]));
    assert!(h.contains("  4    sweep"), "{h}");
    // A file that is not firmware is refused before QEMU boots it (it died with a register dump, exit 1).
    let r = parapet(&["pil", "--scene", &f, "--straight", "--firmware", &f, "--out", o.to_str().unwrap()]);
    refused(&r, &["option --firmware", "scene.toml", "not an ELF file"]);
    assert!(!o.exists(), "no report for a refused run");
}
