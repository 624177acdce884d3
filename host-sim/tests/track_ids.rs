//! Obstacle ids in scenes of more than 65,535 obstacles (issue 18): the proximity report gives
//! the flight controller `u16` ids (`parapet_sim::sim::track_ids`), never two equal ones for
//! obstacles in view and never `CLEAR_ID` (65,535, "no obstacle" on the wire), stable while in
//! view. With the scene index cast to `u16`, obstacle 65,539 would be reported as 3 (the id of
//! obstacle 3, also in view) and obstacle 65,535 as `CLEAR_ID`.

use nalgebra::Vector3;
use parapet_core::cbf::{CbfParams, FilterVariant, SafetyFilter};
use parapet_core::obstacle::Shape;
use parapet_core::wire::ids::CLEAR_ID;
use parapet_sim::flight::runner::{sense_and_h_bar, sense_obstacles, OuterScratch};
use parapet_sim::sim::sensors::{SensorParams, Sensors};
use parapet_sim::world::obstacle::{Motion, SceneObstacle};
use parapet_sim::world::scene::{to_f32, Scene};
use parapet_sim::world::NearestTracker;

/// Obstacles of the scene: 65,540, so indices 3 and 65,539 are 65,536 apart.
const N: usize = 65_540;
/// The obstacles near the start (index, offset from the start NED, m).
const NEAR: [(usize, [f64; 3]); 3] =
    [(3, [1.0, 0.0, 0.0]), (65_535, [0.0, 1.0, 0.0]), (65_539, [-1.0, 0.0, 0.0])];

/// A scene of [`N`] spheres: the three of [`NEAR`] 1 m from the start, the others on a
/// 1 m grid 20 m and more away (out of the 3 m sensing range).
fn big_scene() -> Scene {
    let src = "name = \"big\"\n[bounds]\nmin = [-30, -30, 0]\nmax = [300, 300, 3]\n\
               [mission]\nstart = [0, 0, 1]\ngoal = [1, 1, 1]\nspeed = 0.5\n[sensors]\nnoise = false\n";
    let mut s = Scene::parse(src, "big.toml").unwrap_or_else(|e| panic!("{e}"));
    for i in 0..N {
        let c = match NEAR.iter().find(|(j, _)| *j == i) {
            Some((_, d)) => s.start + Vector3::new(d[0], d[1], d[2]),
            None => s.start + Vector3::new(20.0 + (i % 256) as f64, 20.0 + (i / 256) as f64, 0.0),
        };
        s.obstacles.push(SceneObstacle {
            name: None,
            shape: Shape::sphere(to_f32(&c), 0.2),
            motion: Motion::Static,
            mapped: true,
        });
    }
    s
}

/// The scene index of the obstacle whose closest point is `q` (the nearest of [`NEAR`]).
fn which(scene: &Scene, q: &parapet_core::Vec3) -> usize {
    let d = |(_, o): &(usize, [f64; 3])| {
        let c = scene.start + Vector3::new(o[0], o[1], o[2]);
        (to_f32(&c) - q).norm()
    };
    NEAR.iter().min_by(|a, b| d(a).total_cmp(&d(b))).map(|(i, _)| *i).unwrap_or(usize::MAX)
}

#[test]
fn obstacles_65536_apart_in_view_get_different_ids_and_none_is_clear_id() {
    let scene = big_scene();
    assert_eq!(scene.obstacles.len(), N);
    let filter = SafetyFilter::new(CbfParams::default(), FilterVariant::default()).expect("filter");
    let mut sensors = Sensors::new(SensorParams::default(), 1);
    let mut tracker = NearestTracker::new(&scene);
    let mut scratch = OuterScratch::default();
    let mut first: Option<Vec<(usize, u16)>> = None;
    for k in 0..40 {
        // The vehicle drifts 2 cm per step around the start: the three stay in view.
        let p = scene.start + Vector3::new(0.02 * (k % 7) as f64, -0.01 * (k % 5) as f64, 0.0);
        let v = Vector3::new(0.1, 0.0, 0.0);
        let t = k as f64 * 0.004;
        sense_and_h_bar(&scene, &mut tracker, &filter, t, &p, &v, 3.0, &mut sensors, &mut scratch);
        let mut seen: Vec<(usize, u16)> =
            scratch.seen.iter().map(|o| (which(&scene, &o.point), o.id)).collect();
        seen.sort_unstable();
        assert_eq!(seen.iter().map(|s| s.0).collect::<Vec<_>>(), [3, 65_535, 65_539], "step {k}");
        let mut ids: Vec<u16> = seen.iter().map(|s| s.1).collect();
        assert!(!ids.contains(&CLEAR_ID), "step {k}: {seen:?}");
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), 3, "step {k}: two obstacles in view share an id: {seen:?}");
        assert_eq!(seen[0], (3, 3), "an index below 65,535 keeps its index as id");
        match &first {
            None => {
                // The full scan reports the same first pass.
                let mut full_sensors = Sensors::new(SensorParams::default(), 1);
                let full = sense_obstacles(&scene, t, &p, 3.0, &mut full_sensors);
                assert_eq!(full, scratch.seen, "full scan vs shared sensing");
                first = Some(seen);
            }
            Some(f) => assert_eq!(&seen, f, "step {k}: ids change while in view"),
        }
    }
}
