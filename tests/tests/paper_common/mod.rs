//! Shared helpers of the paper-experiment tests (`paper_a.rs`, `paper_b.rs`, `paper_c.rs`):
//! scenes and committed path files from `scenes/`, flights with the paper's filter variant.
#![allow(dead_code)]

use std::path::PathBuf;

use nalgebra::Vector3;
use parapet_core::cbf::FilterVariant;
use parapet_core::outer::guidance::MissionGuidance;
use parapet_sim::fc::control::run;
use parapet_sim::flight::runner::{RunConfig, RunOutput};
use parapet_sim::plan::pathfile::PathFile;
use parapet_sim::world::scene::{to_f64, Scene};

/// `scenes/<name>`.
pub fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name)
}

/// Load `scenes/<name>`.
pub fn scene(name: &str) -> Scene {
    Scene::load(&scene_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// Waypoints (NED) of the committed path file `scenes/<name>`.
pub fn path_file(name: &str) -> Vec<Vector3<f64>> {
    let f = PathFile::read(&scene_path(name)).unwrap_or_else(|e| panic!("{e}"));
    f.waypoints_ned().iter().map(to_f64).collect()
}

/// Fly `path` through `s` with the paper's filter (or none), sensor-noise `seed`,
/// noise on/off, after `tweak` adjusted the configuration.
pub fn fly(
    s: &Scene,
    path: &[Vector3<f64>],
    cbf: bool,
    seed: u64,
    noise: bool,
    tweak: impl FnOnce(&mut RunConfig),
) -> RunOutput {
    let mut cfg = RunConfig::for_scene(s, path.to_vec()).unwrap();
    cfg.variant = FilterVariant::Paper;
    // The paper's guidance: a point at constant speed along the polyline (`MIS_GUIDANCE` 0).
    cfg.guidance = MissionGuidance::Paper;
    cfg.cbf = cbf;
    cfg.seed = seed;
    cfg.sensors.noise = noise;
    tweak(&mut cfg);
    run(s, &cfg, &mut |_| {}).unwrap()
}
