//! Closed-loop flights with the simulated battery (`[battery]`, host-sim/src/sim/battery.rs):
//! the pack's readings go through core's battery estimator into the flight controller, whose
//! mode machine returns on Low and lands on Critical (issue 22). Fixed seeds.

use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{RunConfig, RunOutput};
use parapet_sim::world::scene::Scene;

/// An obstacle-free 6 m flight at 0.3 m/s with a 3S pack starting at `soc`.
fn fly(soc: Option<f64>) -> RunOutput {
    let battery = soc.map_or(String::new(), |s| format!("[battery]\ncells = 3\ninitial_soc = {s}\n"));
    let src = format!(
        "name = \"battery\"\n[bounds]\nmin = [-2.0, -2.0, 0.0]\nmax = [8.0, 2.0, 3.0]\n\
         [mission]\nstart = [0.0, 0.0, 1.0]\ngoal = [6.0, 0.0, 1.0]\nspeed = 0.3\n{battery}"
    );
    let s = Scene::parse(&src, "battery.toml").unwrap_or_else(|e| panic!("{e:?}"));
    let mut cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).unwrap();
    cfg.seed = 5;
    cfg.duration = 30.0;
    run(&s, &cfg, &mut |_| {}).unwrap()
}

fn first(out: &RunOutput, mode: &str) -> Option<f64> {
    out.samples.iter().find(|x| x.mode.as_str() == mode).map(|x| x.t)
}

#[test]
fn a_charged_pack_changes_nothing() {
    let with = fly(Some(1.0));
    assert!(with.summary.reached_goal, "{:?}", with.summary);
    assert_eq!(first(&with, "Return"), None);
    assert_eq!(first(&with, "Land"), None);
    let without = fly(None);
    assert!(without.summary.reached_goal);
}

#[test]
fn a_low_pack_returns_and_an_empty_pack_lands() {
    // 3.61 V/cell resting, drained by the hover current and sagging under it: Low (3.5 V/cell
    // after 2 s) during the flight → Return; never Land before Return.
    let low = fly(Some(0.05));
    let ret = first(&low, "Return").unwrap_or_else(|| panic!("no Return: modes {:?}", modes(&low)));
    assert!(ret > 2.0, "Return at {ret} s");
    assert!(!low.summary.reached_goal, "flew on to the goal with a low battery");
    // Return ends in a landing at home; the only ground contact is that touchdown.
    let land = first(&low, "Land").unwrap_or_else(|| panic!("no Land after Return: {:?}", modes(&low)));
    assert!(land > ret);
    touched_down_after(&low, land);
    // Empty: 3.27 V/cell, below critical from the start → Land after the debounce.
    let empty = fly(Some(0.0));
    let land = first(&empty, "Land").unwrap_or_else(|| panic!("no Land: modes {:?}", modes(&empty)));
    assert!((2.0..4.0).contains(&land), "Land at {land} s");
    assert_eq!(first(&empty, "Return"), None);
    touched_down_after(&empty, land);
}

/// No contact but the landing's touchdown (the runner ends a flight at ground contact).
fn touched_down_after(out: &RunOutput, land: f64) {
    if out.summary.collided {
        assert_eq!(out.summary.collision_with.as_deref(), Some("ground"), "{:?}", out.summary);
        assert!(out.summary.first_collision_time_s.is_some_and(|t| t > land), "{:?}", out.summary);
    }
}

fn modes(out: &RunOutput) -> Vec<(f64, &'static str)> {
    let mut v: Vec<(f64, &'static str)> = Vec::new();
    for s in &out.samples {
        if v.last().is_none_or(|l| l.1 != s.mode.as_str()) {
            v.push((s.t, s.mode.as_str()));
        }
    }
    v
}

#[test]
fn a_bad_battery_table_names_the_field() {
    let src = "name = \"b\"\n[bounds]\nmin = [-2.0, -2.0, 0.0]\nmax = [8.0, 2.0, 3.0]\n\
               [mission]\nstart = [0.0, 0.0, 1.0]\ngoal = [6.0, 0.0, 1.0]\nspeed = 0.3\n\
               [battery]\ncapacity_mah = -5.0\n";
    let e = format!("{:?}", Scene::parse(src, "b.toml").unwrap_err());
    assert!(e.contains("capacity_mah") && e.contains("-5"), "{e}");
}
