use nalgebra::Vector3;
use parapet_core::cbf::{FilterDiagnostics, Region};
use parapet_core::controller::{FlightMode, GuidanceMode};

use super::*;
use crate::report::{RunParams, SafetyFlags, SafetySteps, Summary};
use crate::world::scene::Scene;

const SCENE: &str = include_str!("../../../tests/data/scenes/replay_unit.toml");

fn summary(scene: &Scene, n: usize) -> Summary {
    Summary {
        scene: scene.name.clone(),
        scene_file: "t.toml".into(),
        filter: "multi-relative".into(),
        yaw_mode: "hold".into(),
        cbf_enabled: true,
        collided: false,
        first_collision_time_s: None,
        collision_obstacle: None,
        collision_with: None,
        min_clearance_m: 0.123456789,
        min_h_bar: if n == 0 { f64::INFINITY } else { 0.05 },
        min_filter_h_bar: None,
        reached_goal: false,
        time_to_goal_s: None,
        final_distance_to_goal_m: 6.0,
        reached_path_end: false,
        final_distance_to_path_end_m: 6.0,
        tracking_rms_m: 0.1,
        filter_active_fraction: 0.25,
        end_reason: "duration".into(),
        sim_time_s: 0.0,
        wall_time_s: 0.0,
        steps: 0,
        planning_time_ms: None,
        path_length_m: 6.0,
        path_source: "straight".into(),
        path_waypoints: 2,
        params: RunParams { mu: 1.4, delta: 0.05, delta1: 0.1, kp: 0.5, kd: 0.8, speed: 0.5 },
        params_set: Default::default(),
        final_controller_state: "Armed".into(),
        seed: 0,
        noise: false,
        safety_steps: SafetySteps::default(),
        unmapped_obstacles: scene.unmapped_count(),
        replan: Default::default(),
        coverage_gaps: Vec::new(),
        speed_limited_by: None,
        pace: None,
    }
}

/// Sample `k` of a test flight (4 ms apart); `crate::report::speed_limit`'s tests use it too.
pub(crate) fn sample(k: usize) -> Sample {
    let t = k as f64 * 0.004;
    let mut filter = FilterDiagnostics::new(Region::Far);
    filter.intervened = k % 7 < 3;
    filter.active_id = filter.intervened.then_some(1);
    Sample {
        t,
        ref_pos: Vector3::new(0.0, t, -1.0),
        pos: Vector3::new(-0.00001, t, -1.0),
        vel: Vector3::new(0.0, 0.5, 0.0),
        rpy: [0.0, 0.0, 0.0],
        filter,
        clearance: 1.0 - (k as f64 - 500.0).abs() * 1e-3,
        ref_clearance: 1.0,
        h_bar: if k == 10 { f64::NAN } else { 0.5 },
        u_nominal: Vector3::zeros(),
        u_filtered: Vector3::zeros(),
        mode: if k < 100 { GuidanceMode::Takeoff } else { GuidanceMode::Mission },
        flight_mode: FlightMode::Mission,
        wind: Vector3::zeros(),
        safety: SafetyFlags::default(),
        motors: [0.5; 4],
    }
}

fn page_of(samples: &[Sample]) -> String {
    let scene = Scene::parse(SCENE, "t.toml").unwrap();
    let s = summary(&scene, samples.len());
    let path = [scene.start, scene.goal];
    let ranges = crate::perception::RangeLog::default();
    let rec = RunRecord {
        scene: &scene,
        path: &path,
        samples,
        summary: &s,
        ranges: &ranges,
        range_sensors: &[],
        filter_points: &Default::default(),
        clock_us: |t| (t.max(0.0) * 1e6).round() as u64,
    };
    page(&rec).unwrap()
}

/// The embedded JSON of a page.
fn data_of(page: &str) -> serde_json::Value {
    let start = page.find("<script id=\"data\" type=\"application/json\">").unwrap();
    let rest = &page[start..];
    let body = &rest[rest.find('>').unwrap() + 1..rest.find("</script>").unwrap()];
    serde_json::from_str(body).unwrap()
}

#[test]
fn three_is_wrapped() {
    let w = wrap_three(THREE_MODULE).unwrap();
    assert!(!w.contains("export{"));
    assert!(w.contains("WebGLRenderer:") && w.contains("Mesh:") && w.contains("Vector3:"));
    assert!(w.trim_end().ends_with('}') || w.trim_end().ends_with("};"), "{}", &w[w.len() - 40..]);
    assert_eq!(wrap_three("const a=1;export{a as B,c};").unwrap(), "const a=1;return{B:a,c:c};");
    assert!(wrap_three("no module").is_err());
}

#[test]
fn display_keeps_the_last_and_the_worst_samples_and_is_bounded() {
    let samples: Vec<Sample> = (0..10_001).map(sample).collect();
    let idx = display_indices(&samples, 3000);
    assert!(idx.len() <= 3003 && idx.len() >= 2500, "{}", idx.len());
    assert!(idx.windows(2).all(|w| w[0] < w[1]));
    assert_eq!(idx[0], 0);
    assert_eq!(*idx.last().unwrap(), 10_000);
    assert!(idx.contains(&500), "min clearance sample kept");
    assert!(display_indices(&[], 3000).is_empty());
    assert_eq!(display_indices(&samples[..5], 3000), vec![0, 1, 2, 3, 4]);
}

#[test]
fn the_page_holds_the_files_digits_and_escapes_its_strings() {
    let samples: Vec<Sample> = (0..1200).map(sample).collect();
    let page = page_of(&samples);
    // The scene's name cannot end the script: one data script, closed once.
    assert_eq!(page.matches("</script>").count(), 4, "error catcher, data, three, app");
    assert!(page.contains("<title>Parapet replay — replay &lt;/script&gt; test</title>"));
    let d = data_of(&page);
    assert_eq!(d["scene"], "replay </script> test");
    assert_eq!(d["obstacles"].as_array().unwrap().len(), 3);
    assert_eq!(d["obstacles"][1]["name"], "crate <b>");
    assert_eq!(d["obstacles"][1]["kind"], "box");
    assert_eq!(d["obstacles"][2]["kind"], "cylinder");
    assert_eq!(d["obstacles"][2]["height"], 2.5);
    assert_eq!(d["obstacles"][2]["velocity"][1], 0.1);
    assert_eq!(d["obstacles"][0]["center"], serde_json::json!([3, 1.2, 1]));
    // The CSV's texts: -0.00001 north is "-0.0000" (the sign kept), NaN is the string "NaN".
    let csv = crate::report::trajectory_csv(&samples);
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    let s = &d["s"];
    let n = s["t"].as_array().unwrap().len();
    assert_eq!(n, 1200);
    let data_text = page[page.find("\"s\":{").unwrap()..].to_string();
    assert!(data_text.contains("\"y\":[-0.0000,"), "{}", &data_text[..200]);
    assert_eq!(s["h"][10], "NaN");
    assert_eq!(rows[10][17], "NaN");
    for k in [0usize, 1, 599, 1199] {
        let i = s["i"][k].as_u64().unwrap() as usize;
        assert_eq!(format!("{:.4}", s["t"][k].as_f64().unwrap()), rows[i][0]);
        assert_eq!(format!("{:.4}", s["y"][k].as_f64().unwrap()), rows[i][5]);
        assert_eq!(format!("{:.4}", s["c"][k].as_f64().unwrap()), rows[i][16]);
    }
    // Mode changes and intervention intervals come from every sample.
    assert_eq!(d["modes"], serde_json::json!(["Takeoff", "Mission"]));
    assert_eq!(d["mode_changes"], serde_json::json!([[0.0, 0], [0.4, 1]]));
    assert_eq!(d["interventions"].as_array().unwrap().len(), 1200 / 7 + 1);
    // summary.json's texts.
    let pairs = d["summary"].as_array().unwrap();
    let find = |k: &str| pairs.iter().find(|p| p[0] == k).map(|p| p[1].as_str().unwrap().to_string());
    assert_eq!(find("min_clearance_m").as_deref(), Some("0.123456789"));
    assert_eq!(find("params.mu").as_deref(), Some("1.4"));
    assert_eq!(find("scene").as_deref(), Some("replay </script> test"));
    assert_eq!(find("time_to_goal_s").as_deref(), Some("null"));
}

#[test]
fn an_empty_flight_still_makes_a_page() {
    let page = page_of(&[]);
    let d = data_of(&page);
    assert_eq!(d["n_samples"], 0);
    assert_eq!(d["s"]["t"].as_array().unwrap().len(), 0);
    assert_eq!(d["obstacles"].as_array().unwrap().len(), 3);
    assert!(page.contains("nothing to replay"));
    assert!(page.ends_with("</html>\n"));
}
