//! The world a flight happens in: scene files, obstacle motion, the spatial
//! index of a scene's static obstacles, the nearest-obstacle tracker built on
//! it, scene checks, and the procedural scene generator.
//!
//! * [`scene`]: [`scene::Scene`], a loaded scene file (TOML, ENU z-up) → NED obstacles,
//!   mission, overrides; the f64 ↔ f32 and ENU ↔ NED conversions.
//! * [`schema`]: the file's tables as serde reads them, per-table checks, error texts.
//! * [`frame`]: f64 ↔ f32 vectors, ENU arrays ↔ NED.
//! * [`obstacle`]: [`obstacle::SceneObstacle`] and its [`obstacle::Motion`].
//! * [`index`]: [`index::StaticIndex`], a BVH (parry3d-f64) over the static
//!   obstacles' bounding boxes with exact nearest / within-radius / box queries
//!   (the narrow phase is the core's `Shape::closest_point`, so results equal
//!   full scans bit for bit).
//! * [`tracker`]: [`tracker::NearestTracker`], the exact nearest-obstacle and
//!   proximity queries along a moving point (the simulator's vehicle and
//!   reference): a local candidate set from the index plus the moving
//!   obstacles, and per-obstacle Lipschitz bounds.
//! * [`raycast`]: exact ray casts on the obstacles (index + moving ones) and the
//!   ground, for the simulated range sensors.
//! * [`check`]: scene-loader checks for duplicated and degenerate obstacles.
//! * [`generate`]: `parapet scene generate` — forest, city, warehouse and
//!   clutter scenes, seeded, with a mission the planner connects.
//!
//! May import: `parapet-core`, parry3d-f64, and of host-sim [`crate::input`]
//! (errors, limits) and [`crate::sim`] (the vehicle, sensor and disturbance
//! settings a scene file overrides).
pub mod check;
pub mod frame;
pub mod generate;
pub mod index;
pub mod obstacle;
pub mod raycast;
pub mod scene;
pub mod schema;
pub mod tracker;

pub use index::StaticIndex;
pub use tracker::NearestTracker;
