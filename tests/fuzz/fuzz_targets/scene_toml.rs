//! Fuzz target `scene_toml`: arbitrary text into `parapet_sim::world::scene::Scene::parse`.
//!
//! Invariants: no panic; an accepted scene has finite bounds with min < max on every axis,
//! finite start and goal, a finite positive speed and finite obstacle data (as the loader
//! documents in `scenes/README.md`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use parapet_sim::world::scene::Scene;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(scene) = Scene::parse(text, "fuzz.toml") else { return };
    let (lo, hi) = scene.bounds_enu;
    for k in 0..3 {
        assert!(lo[k].is_finite() && hi[k].is_finite() && lo[k] < hi[k], "bounds {lo:?} {hi:?}");
    }
    assert!(scene.start.iter().chain(scene.goal.iter()).all(|x| x.is_finite()));
    assert!(scene.speed.is_finite() && scene.speed > 0.0, "speed {}", scene.speed);
    let debug = format!("{:?}", scene.obstacles);
    assert!(!debug.contains("NaN") && !debug.contains("inf"), "non-finite obstacle: {debug}");
});
