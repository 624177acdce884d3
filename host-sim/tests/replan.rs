//! On-board replanning (issue 38, `parapet_core::replan`, `RPL_*`): worlds the map got wrong
//! are crossed when the vehicle replans by itself; without it the flight stalls in front of
//! the unmapped obstacle. `summary.json` counts the replans and lists the events.

mod common;

use common::{parapet, tmp};

fn summary(dir: &std::path::Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn fly(name: &str, args: &[&str]) -> serde_json::Value {
    let out = tmp("replan", name);
    let mut all = vec!["run"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--out", out.to_str().unwrap()]);
    let o = parapet(&all);
    assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
    summary(&out)
}

/// Goal, no contact, at least `min_replans` replans, each reported as an event.
fn assert_goal_without_contact(s: &serde_json::Value, what: &str, min_replans: u64) {
    assert_eq!(s["end_reason"], "goal", "{what}: {s}");
    assert_eq!(s["collided"], false, "{what}");
    assert!(s["min_clearance_m"].as_f64().unwrap() > 0.0, "{what}");
    assert!(s["replans"].as_u64().unwrap() >= min_replans, "{what}");
    assert_eq!(s["replan_enabled"], true, "{what}");
    let events = s["replan_events"].as_array().unwrap();
    let replanned = events.iter().filter(|e| e["outcome"] == "replanned").count() as u64;
    assert_eq!(replanned, s["replans"].as_u64().unwrap(), "{what}");
    assert!(events.iter().all(|e| e["outcome"] != "replanned" || e["waypoints"].as_u64().unwrap() >= 1));
}

/// The planned door is blocked by an unmapped crate: with ground truth's closest points the
/// vehicle feels its way along the wall (replanning as it senses it) to the open door and on to
/// the goal — with `parapet run`'s defaults (replanning on, the default duration limit, whose
/// watchdog counts each new path as progress); without replanning it stalls in front of the
/// crate.
#[test]
fn two_doors_with_truth_reaches_the_goal_by_replanning() {
    let scene = "scenes/two_doors_blocked.toml";
    let on = fly("td-truth", &["--scene", scene]);
    assert_goal_without_contact(&on, "truth", 1);
    let off = fly("td-truth-off", &["--guidance", "trajectory", "--scene", scene, "--param", "RPL_ENABLE=0"]);
    assert_eq!(off["end_reason"], "duration", "{off}");
    assert_eq!((off["replans"].as_u64(), off["replan_enabled"].as_bool()), (Some(0), Some(false)));
    assert!(off["final_distance_to_goal_m"].as_f64().unwrap() > 4.0);
}

/// The 360° lidar with replanning on; a planar lidar flies under the assumption that nothing
/// stands or hangs out of its plane (`docs/perception.md` § Coverage check).
const LIDAR360: [&str; 6] =
    ["--perception", "lidar360", "--assume", "no-overhangs,no-low-obstacles", "--param", "RPL_ENABLE=1"];

/// The same with the 360° lidar through the obstacle memory, with the trajectory guidance (under
/// the first trigger this flight ended in no-path results from 32.5 s; the 3D trigger, which
/// ignores the virtual frontier point, reaches the goal).
#[test]
fn two_doors_with_lidar360_reaches_the_goal_by_replanning() {
    let args = [
        &["--guidance", "trajectory", "--scene", "scenes/two_doors_blocked.toml"][..],
        &LIDAR360,
        &["--duration", "120"],
    ]
    .concat();
    assert_goal_without_contact(&fly("td-lidar360", &args), "lidar360", 1);
}

/// A generated forest with 30 % of its trunks unmapped, crossed at 3 m/s with the 360° lidar
/// (seed 0; seeds 0–4 in docs/perception.md § On-board replanning): goal, no contact, the
/// replans counted (none on this seed since the trigger allows for the memory's points: the
/// filter alone slips between the thin unmapped trunks; one before, at 45.8 s against 43.9 s).
#[test]
fn an_unmapped_forest_is_crossed_at_3_m_s_with_replanning() {
    let dir = tmp("replan", "forest");
    let scene = dir.join("forest.toml");
    let gen = parapet(&[
        "scene",
        "generate",
        "--kind",
        "forest",
        "--seed",
        "0",
        "--unmapped",
        "0.3",
        "--speed",
        "3",
        "--out",
        scene.to_str().unwrap(),
    ]);
    assert!(gen.status.success(), "{}", String::from_utf8_lossy(&gen.stderr));
    let s = fly(
        "forest-lidar360",
        &[&["--guidance", "trajectory", "--scene", scene.to_str().unwrap()][..], &LIDAR360].concat(),
    );
    assert_goal_without_contact(&s, "forest seed 0", 0);
    assert_eq!(s["unmapped_obstacles"], 300);
}

/// The mapped office (nothing unmapped): its planned path passes over desks and plants and
/// near door posts, which the trigger leaves alone — no replan, the goal as without
/// replanning (docs/perception.md § On-board replanning). Seeds 4 (truth), 3 (lidar) and 0
/// (lidar3d) lost the goal to 10–12 replan / no-path events each while the trigger walked the
/// path from the vehicle and took memory points for surfaces.
#[test]
fn the_mapped_office_flies_without_a_replan() {
    for (perception, seed) in
        [("truth", "0"), ("lidar", "0"), ("truth", "4"), ("lidar", "3"), ("lidar3d", "0")]
    {
        let s = fly(
            &format!("office-{perception}-{seed}"),
            &[
                "--guidance",
                "trajectory",
                "--scene",
                "scenes/office.toml",
                "--perception",
                perception,
                "--assume",
                "no-overhangs,no-low-obstacles",
                "--speed",
                "1",
                "--seed",
                seed,
                "--param",
                "RPL_ENABLE=1",
            ],
        );
        assert_eq!(s["end_reason"], "goal", "{perception}: {s}");
        assert_eq!(s["replan_enabled"], true);
        assert_eq!(
            (s["replans"].as_u64(), s["replan_no_path"].as_u64()),
            (Some(0), Some(0)),
            "{perception}: {s}"
        );
    }
}

/// The office with its first west door blocked by an unmapped box: with ground truth's
/// closest points the vehicle replans along the partition to the second door and on to the goal
/// (with lidar360: the next test).
#[test]
fn the_blocked_office_with_truth_reaches_the_goal_by_replanning() {
    let s = fly(
        "office-blocked-truth",
        &[
            "--guidance",
            "trajectory",
            "--scene",
            "scenes/office_blocked.toml",
            "--param",
            "RPL_ENABLE=1",
            "--duration",
            "200",
        ],
    );
    assert_goal_without_contact(&s, "office_blocked truth", 1);
}

/// The same with the 360° lidar (seed 0): the way on from room B to room C passes over printer
/// B, closed at the vehicle's height; the replanner's plan at the height the remaining path
/// flies there (its 2.5-D grid, `parapet_core::replan`) climbs over it. With the 2-D grid this
/// flight ended at the duration limit 6.2 m short, 76 no-path results (docs/perception.md).
#[test]
fn the_blocked_office_with_lidar360_reaches_the_goal_over_the_printer() {
    let args = [
        &["--guidance", "trajectory", "--scene", "scenes/office_blocked.toml"][..],
        &LIDAR360,
        &["--duration", "200"],
    ]
    .concat();
    assert_goal_without_contact(&fly("office-blocked-lidar360", &args), "office_blocked lidar360", 1);
}
