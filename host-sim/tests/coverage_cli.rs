//! The pre-flight coverage refusal from the command line (issue 36, `parapet_sim::sim::coverage`):
//! a sensor set that cannot see the volume the hull sweeps (a planar lidar: above and below its
//! plane; a forward camera: behind) is refused with exit 2, naming the gap and the `--assume`
//! value that accepts it, unless that world assumption is given (`--assume` or the scene's
//! `[sensors] assume`); bad sensor descriptions and unknown assumptions exit 2 naming the field
//! or option, the value and the allowed values.

use std::process::Output;

mod common;
use common::parapet;

const SCENE: &str = include_str!("data/scenes/coverage_cli.toml");

/// `parapet run --straight --duration 0.5` of `scene` (text) with `extra`; the output and the
/// test's directory (the report is in its `report/`).
fn run(name: &str, scene: &str, extra: &[&str]) -> (Output, common::TmpDir) {
    let d = common::tmp("coverage_cli", name);
    let file = d.join("scene.toml");
    std::fs::write(&file, scene).unwrap();
    let out = d.join("report");
    let args = ["run", "--scene", file.to_str().unwrap(), "--straight", "--duration", "0.5"];
    let o = parapet(&[&args[..], extra, &["--out", out.to_str().unwrap()]].concat());
    (o, d)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_planar_lidar_is_refused_until_both_vertical_assumptions_are_given() {
    let (o, _) = run("lidar-none", SCENE, &["--perception", "lidar"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for want in [
        "--perception",
        "lidar",
        "cannot see the volume the hull sweeps",
        "above",
        "below",
        "--assume no-overhangs",
        "--assume no-low-obstacles",
        "forward-flight",
    ] {
        assert!(err.contains(want), "{want}: {err}");
    }
    // One of the two: the other gap still refuses, and only it is named as refused.
    let (o, _) = run("lidar-one", SCENE, &["--perception", "lidar", "--assume", "no-overhangs"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--assume no-low-obstacles") && !err.contains("--assume no-overhangs"), "{err}");
    // Both (comma list): flies; the gaps are printed and kept in summary.json as assumed away.
    let (o, out) =
        run("lidar-both", SCENE, &["--perception", "lidar", "--assume", "no-overhangs,no-low-obstacles"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(err.contains("(assumed away: no-overhangs)"), "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report/summary.json")).unwrap()).unwrap();
    let gaps = s["coverage_gaps"].as_array().unwrap();
    assert_eq!(gaps.len(), 2, "{gaps:?}");
    assert!(gaps.iter().all(|g| g.as_str().unwrap().contains("assumed away")), "{gaps:?}");
}

#[test]
fn the_scene_can_state_the_assumption_and_a_camera_needs_forward_flight() {
    let assumed = format!("{SCENE}[sensors]\nassume = [\"no-overhangs\", \"no-low-obstacles\"]\n");
    let (o, _) = run("scene-assume", &assumed, &["--perception", "lidar"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // The camera sees 87° ahead: refused for the bearings behind, not for its vertical field.
    let (o, _) = run("camera", SCENE, &["--perception", "camera"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("bearings 44°–316°") && err.contains("--assume forward-flight"), "{err}");
    let (o, _) = run("camera-fwd", SCENE, &["--perception", "camera", "--assume", "forward-flight"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // Sets that cover the sweep fly without any assumption; so does ground truth.
    for p in ["lidar3d", "tof", "truth"] {
        let (o, _) = run(&format!("ok-{p}"), SCENE, &["--perception", p]);
        assert_eq!(o.status.code(), Some(0), "{p}: {}", stderr(&o));
    }
}

#[test]
fn bad_assumptions_and_sensors_that_cover_nothing_exit_2_naming_them() {
    let (o, _) = run("bad-option", SCENE, &["--perception", "lidar", "--assume", "flat-earth"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for want in ["--assume", "flat-earth", "no-overhangs", "no-low-obstacles", "forward-flight"] {
        assert!(err.contains(want), "{want}: {err}");
    }
    let bad = format!("{SCENE}[sensors]\nassume = [\"flat-earth\"]\n");
    let (o, _) = run("bad-scene", &bad, &["--perception", "lidar"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for want in ["scene.toml", "sensors", "assume", "flat-earth", "no-overhangs"] {
        assert!(err.contains(want), "{want}: {err}");
    }
    for (table, field, want) in [
        ("min_range = 12.0\nmax_range = 12.0", "min_range", "covers nothing"),
        ("dropout = 1.0", "dropout", "covers nothing"),
        ("latency = -0.05", "latency", "0 ≤ latency"),
    ] {
        let s = format!("{SCENE}[[sensor]]\nkind = \"lidar\"\n{table}\n");
        let (o, _) = run(&format!("bad-{field}"), &s, &["--perception", "scene"]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{field}: {err}");
        assert!(err.contains(&format!("`{field}`")) && err.contains(want), "{field}: {err}");
    }
    // Every sensor looking up: the set covers nothing of the sweep, whatever is assumed.
    let up = format!("{SCENE}[[sensor]]\nkind = \"tof\"\npitch = 90.0\n");
    let (o, _) = run("blind", &up, &["--perception", "scene", "--assume", "forward-flight"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("covers nothing") && err.contains("--perception"), "{err}");
}
