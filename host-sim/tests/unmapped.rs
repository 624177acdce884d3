//! Unmapped obstacles (issue 38): `mapped = false` in scene files and
//! `parapet scene generate --unmapped`. The planner and the mission never see an
//! unmapped obstacle; the sensors, the collision check and the reports do; bad
//! input is exit 2 naming the file, the field and the value.

mod common;

use common::{parapet, tmp};
use parapet_sim::plan::generate::generate;
use parapet_sim::plan::{path_is_valid, plan, PlanProblem, PlannerParams, DEFAULT_MARGIN_M};
use parapet_sim::world::generate::{GenParams, Kind};
use parapet_sim::world::scene::Scene;

const HALL: &str = include_str!("data/scenes/unmapped_hall.toml");

fn scene(mapped: &str) -> Result<Scene, String> {
    Scene::parse(&HALL.replace("MAPPED", mapped), "hall.toml").map_err(|e| e.to_string())
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn the_planner_sees_the_map_not_the_world() {
    let mapped = scene("").unwrap();
    let unmapped = scene("mapped = false").unwrap();
    assert_eq!(scene("mapped = true").unwrap(), mapped);
    assert!(mapped.obstacles.iter().all(|o| o.mapped) && !unmapped.obstacles[2].mapped);
    assert_eq!((mapped.unmapped_count(), unmapped.unmapped_count()), (0, 1));
    assert_eq!(unmapped.obstacle_label(2), "obstacles[2] (crate, unmapped)");
    // With the crate mapped the only door is closed: no path (exit 3).
    let e = plan(&PlanProblem::from_scene(&mapped), &PlannerParams::default()).unwrap_err();
    assert_eq!(e.exit_code(), 3, "{e}");
    // Unmapped, the planner does not see it and plans straight through the door.
    let problem = PlanProblem::from_scene(&unmapped);
    assert_eq!(problem.obstacles.len(), 2);
    let path = plan(&problem, &PlannerParams::default()).unwrap();
    assert_eq!(path.waypoints, vec![problem.start, problem.goal]);
    // The world (what the generator checks) has the crate.
    let world = PlanProblem::of_world(&unmapped);
    assert_eq!(world.obstacles.len(), 3);
    assert!(!path_is_valid(&world, DEFAULT_MARGIN_M, &path.waypoints));
}

#[test]
fn bad_mapped_values_are_named() {
    for (value, shown) in [("\"no\"", "\"no\""), ("0", "0"), ("[false]", "sequence")] {
        let e = scene(&format!("mapped = {value}")).unwrap_err();
        assert!(e.starts_with("hall.toml: ") && e.contains("obstacles[2]"), "{value}: {e}");
        assert!(e.contains("mapped") && e.contains(shown) && e.contains("bool"), "{value}: {e}");
    }
    // An unmapped obstacle over the start: named with its field and the distance.
    let over_start = HALL.replace("MAPPED", "").replace(
        "[[obstacles]]\nname = \"crate\"",
        "[[obstacles]]\nkind = \"sphere\"\ncenter = [1.2, 3.5, 1.2]\nradius = 0.3\nmapped = false\n[[obstacles]]\nname = \"crate\"",
    );
    let e = Scene::parse(&over_start, "hall.toml").unwrap_err().to_string();
    assert!(e.starts_with("hall.toml: obstacles[2]: field `mapped`: false"), "{e}");
    assert!(e.contains("covers the mission start") && e.contains("hull radius"), "{e}");
    // A mapped one there is the planner's (start in collision), not the loader's.
    assert!(Scene::parse(&over_start.replace("mapped = false\n", ""), "hall.toml").is_ok());
    // Through the command line: exit 2, the file named.
    let d = tmp("unmapped", "bad");
    for (name, text) in
        [("bad_value.toml", HALL.replace("MAPPED", "mapped = \"no\"")), ("over_start.toml", over_start)]
    {
        let f = d.join(name);
        std::fs::write(&f, text).unwrap();
        let out = d.join("p.json");
        for cmd in ["plan", "run"] {
            let o = parapet(&[cmd, "--scene", f.to_str().unwrap(), "--out", out.to_str().unwrap()]);
            assert_eq!(o.status.code(), Some(2), "{cmd} {name}: {}", stderr(&o));
            assert!(
                stderr(&o).contains(name) && stderr(&o).contains("mapped"),
                "{cmd} {name}: {}",
                stderr(&o)
            );
        }
    }
}

#[test]
fn generated_unmapped_share_is_seeded_and_keeps_the_world() {
    let base = GenParams { kind: Kind::Forest, obstacles: 800, seed: 5, ..GenParams::default() };
    let all = generate(&base).unwrap();
    let some = generate(&GenParams { unmapped: 0.3, ..base.clone() }).unwrap();
    let again = generate(&GenParams { unmapped: 0.3, ..base.clone() }).unwrap();
    let other = generate(&GenParams { unmapped: 0.3, seed: 6, ..base.clone() }).unwrap();
    assert_eq!(some.toml, again.toml, "same seed, same file");
    let n = all.scene.obstacles.len();
    assert_eq!(some.scene.unmapped_count(), (0.3 * n as f64).round() as usize);
    assert_eq!(all.scene.unmapped_count(), 0);
    // Same world and mission; only the flags differ.
    assert_eq!((some.scene.start, some.scene.goal), (all.scene.start, all.scene.goal));
    let shapes = |s: &Scene| s.obstacles.iter().map(|o| o.shape).collect::<Vec<_>>();
    assert_eq!(shapes(&some.scene), shapes(&all.scene));
    let flags = |s: &Scene| s.obstacles.iter().map(|o| o.mapped).collect::<Vec<_>>();
    assert_ne!(flags(&some.scene), flags(&other.scene), "another seed picks other obstacles");
    assert_eq!(PlanProblem::from_scene(&some.scene).obstacles.len(), n - some.scene.unmapped_count());
    assert!(some.toml.contains("mapped = false") && !all.toml.contains("mapped"));
    // The option's range.
    let d = tmp("unmapped", "gen");
    let out = d.join("f.toml");
    for bad in ["1.5", "-0.1", "nan"] {
        let o = parapet(&[
            "scene",
            "generate",
            "--obstacles",
            "100",
            "--unmapped",
            bad,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("--unmapped") && stderr(&o).contains("0 ≤ unmapped ≤ 1"),
            "{bad}: {}",
            stderr(&o)
        );
    }
}

/// The shipped two-door scene: the planned path runs through the unmapped crate,
/// the flight with truth sensing and without the on-board replanner (`RPL_ENABLE` 0; with it,
/// the default, the vehicle goes round: `tests/replan.rs`) meets it without contact, and the
/// reports mark it.
#[test]
fn two_doors_blocked_is_flown_into_the_crate_without_contact() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let s = Scene::load(&root.join("scenes/two_doors_blocked.toml")).unwrap();
    assert_eq!(s.unmapped_count(), 1);
    let crate_shape = s.obstacles.iter().find(|o| !o.mapped).unwrap().shape;
    let path = plan(&PlanProblem::from_scene(&s), &PlannerParams::default()).unwrap();
    let through = path.waypoints.windows(2).any(|w| {
        (0..=100).any(|k| crate_shape.signed_distance(&(w[0] + (w[1] - w[0]) * (k as f32 / 100.0))) < 0.0)
    });
    assert!(through, "the planned path should run through the unmapped crate: {:?}", path.waypoints);
    let d = tmp("unmapped", "fly");
    let out = d.join("run");
    let o = parapet(&[
        "run",
        "--scene",
        "scenes/two_doors_blocked.toml",
        "--no-noise",
        "--param",
        "RPL_ENABLE=0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(v["unmapped_obstacles"], 1);
    assert_eq!(v["collided"], false, "{v}");
    // The vehicle stopped short of the crate: it never passed the wall.
    let goal_dist = v["final_distance_to_goal_m"].as_f64().unwrap();
    assert!(goal_dist > 4.0, "{goal_dist}");
    let page = std::fs::read_to_string(out.join("replay.html")).unwrap();
    assert_eq!(page.matches("\"mapped\":false").count(), 1);
}
