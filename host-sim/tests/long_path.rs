//! Issue 38: a path that needs more waypoints than the controller holds (64) is flown, not
//! refused: the controller is given it in windows as it flies (`core::outer::path_stream`),
//! extending its trajectory in place, so a long path flies as fast as a short one through the
//! same curve.

mod common;

use common::{parapet, tmp};

const SCENE: &str = r#"name = "open_long"
description = "An empty field for the streamed path"
[bounds]
min = [0.0, 0.0, 0.3]
max = [100.0, 20.0, 3.0]
[mission]
start = [1.0, 10.0, 1.5]
goal = [99.0, 10.0, 1.5]
speed = 1.0
"#;

/// `n` waypoints along a sine (amplitude 3 m, 31 m period) from the start to `length` m
/// further east, tapering to the line at both ends.
fn curve(n: usize, length: f64) -> String {
    let w: Vec<String> = (0..n)
        .map(|k| {
            let x = length * k as f64 / (n - 1) as f64;
            let y = 10.0 + 3.0 * (x / 5.0).sin() * (std::f64::consts::PI * x / length).sin();
            format!("[{}, {y}, 1.5]", 1.0 + x)
        })
        .collect();
    format!("{{\"scene\": \"scene.toml\", \"waypoints\": [{}]}}", w.join(", "))
}

/// `parapet <command>` of `n` waypoints over `length` m with `extra` options; the summary.
fn fly_with(command: &str, name: &str, n: usize, length: f64, extra: &[&str]) -> serde_json::Value {
    let d = tmp("long_path", name);
    let scene = SCENE.replace("goal = [99.0, 10.0, 1.5]", &format!("goal = [{}, 10.0, 1.5]", 1.0 + length));
    std::fs::write(d.join("scene.toml"), scene).unwrap();
    std::fs::write(d.join("path.json"), curve(n, length)).unwrap();
    let (scene, path, out) = (d.join("scene.toml"), d.join("path.json"), d.join("out"));
    let mut args = vec![
        command,
        "--scene",
        scene.to_str().unwrap(),
        "--path",
        path.to_str().unwrap(),
        "--speed",
        "5",
        "--no-noise",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = parapet(&args);
    assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

fn fly(name: &str, n: usize) -> serde_json::Value {
    fly_with("run", name, n, 98.0, &[])
}

/// 200 and 400 waypoints (the controller holds 64): goal, no contact, and as fast as 64
/// waypoints through the same curve (measured 34.1 / 34.0 s against 34.4 s): no stop where a
/// window ends. The pace report streams the generator the same way.
#[test]
fn a_path_of_hundreds_of_waypoints_is_flown_as_fast_as_one_of_64() {
    let short = fly("64", 64);
    let t64 = short["time_to_goal_s"].as_f64().unwrap();
    for n in [200, 400] {
        let s = fly(&n.to_string(), n);
        assert_eq!(s["reached_goal"], true, "{n}: {s}");
        assert_eq!(s["collided"], false, "{n}");
        let t = s["time_to_goal_s"].as_f64().unwrap();
        eprintln!(
            "{n} waypoints: goal {t} s (64: {t64} s), tracking RMS {} m (64: {} m), generator {} s (64: {} s)",
            s["tracking_rms_m"], short["tracking_rms_m"], s["pace"]["trajectory_s"], short["pace"]["trajectory_s"]
        );
        assert!(t < 1.05 * t64, "{n} waypoints: {t} s against {t64} s with 64");
        assert!(s["tracking_rms_m"].as_f64().unwrap() < 0.1, "{n}: {s}");
        assert!(s["pace"]["trajectory_s"].as_f64().is_some(), "{n}: {}", s["pace"]);
    }
}

/// More waypoints than a mission holds (65,535): refused, naming the file, the field and the
/// allowed count.
#[test]
fn a_path_beyond_what_a_mission_holds_is_refused_naming_it() {
    let d = tmp("long_path", "too-long");
    std::fs::write(d.join("scene.toml"), SCENE).unwrap();
    std::fs::write(d.join("path.json"), curve(65_536, 98.0)).unwrap();
    let path = d.join("path.json");
    let o = parapet(&[
        "run",
        "--scene",
        d.join("scene.toml").to_str().unwrap(),
        "--path",
        path.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for want in ["path.json", "waypoints", "65536", "at most 65535"] {
        assert!(err.contains(want), "missing {want:?}: {err}");
    }
}

/// PIL (the QEMU firmware, `PARAPET_FIRMWARE_QEMU_ELF`; skipped without it): a mission of 100
/// waypoints (the cascade holds 64, the firmware's mission 128 items) is uploaded, and the
/// executor streams its segment to the cascade: goal, no contact, within 10 % of the
/// in-process flight (measured: 120 waypoints over 98 m, 36.0 s against 34.3 s).
#[test]
fn pil_a_mission_of_100_waypoints_is_streamed_by_the_firmware() {
    let Some(elf) = std::env::var_os("PARAPET_FIRMWARE_QEMU_ELF") else {
        eprintln!("\n*** SKIP: PARAPET_FIRMWARE_QEMU_ELF not set ***\n");
        return;
    };
    let elf = elf.to_string_lossy().into_owned();
    let pil = fly_with("pil", "pil-100", 100, 40.0, &["--firmware", &elf]);
    let run = fly_with("run", "run-100", 100, 40.0, &[]);
    let (tp, tr) = (pil["time_to_goal_s"].as_f64().unwrap(), run["time_to_goal_s"].as_f64().unwrap());
    eprintln!("100 waypoints: PIL goal {tp} s, in-process {tr} s");
    assert_eq!(pil["reached_goal"], true, "{pil}");
    assert_eq!(pil["collided"], false);
    assert!(tp < 1.1 * tr, "PIL {tp} s against {tr} s in process");
}
