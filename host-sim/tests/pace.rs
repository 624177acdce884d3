//! A mission's pace in `summary.json` (issue 35, `parapet_sim::report::pace`): the time to
//! goal against the time-optimal time for the same path and limits, and the reason when a
//! flight is slower than 1.3 times it.

mod common;

use common::{parapet, tmp};

fn fly(name: &str, args: &[&str]) -> serde_json::Value {
    let out = tmp("pace", name);
    let mut all = vec!["run", "--no-noise"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--out", out.to_str().unwrap()]);
    let o = parapet(&all);
    assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The office at 3 m/s: the optimum is below the generator's time, which is below the
/// flight's; the flight is slower than 1.3× the optimum (measured 2.8×, docs/cascade.md §
/// Pace) and says why. Without the filter nothing but the trajectory can slow it.
#[test]
fn the_office_at_3_m_s_reports_its_pace_and_what_slowed_it() {
    let s = fly("office3", &["--speed", "3"]);
    assert_eq!(s["reached_goal"], true, "{s}");
    let p = &s["pace"];
    let (opt, gen, goal) = (
        p["time_optimal_s"].as_f64().unwrap(),
        p["trajectory_s"].as_f64().unwrap(),
        s["time_to_goal_s"].as_f64().unwrap(),
    );
    assert!(opt > 0.0 && opt < gen && gen < goal, "{p}");
    assert!((p["ratio"].as_f64().unwrap() - goal / opt).abs() < 1e-9);
    assert!(p["ratio"].as_f64().unwrap() > 1.3 && p["slowed_by"] != "none", "{p}");
    let free = fly("office3_nocbf", &["--speed", "3", "--no-cbf"]);
    let q = &free["pace"];
    assert_eq!(q["time_optimal_s"], p["time_optimal_s"], "same path, same limits");
    assert!(q["slowed_by"] == "trajectory" || q["slowed_by"] == "none", "{q}");
    // The paper's guidance has no trajectory: no pace.
    let paper = fly("office_paper", &["--guidance", "paper", "--duration", "2"]);
    assert!(paper["pace"].is_null(), "{}", paper["pace"]);
}
