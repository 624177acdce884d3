//! Generated scenes whose mission the planner connects: [`generate`] is
//! [`crate::world::generate::generate_with`] with the planner (default
//! parameters, the generator's seed) as the check that a path exists.
//!
//! May import: [`crate::world::generate`], the planner ([`super`]), `crate::input`.

use crate::input::InputError;
use crate::plan::{plan, PlanProblem, PlannerParams};
use crate::world::generate::{generate_with, GenParams, Generated, PathCheck};
use crate::world::scene::Scene;

/// The planner's check: a path from the scene's start to its goal through every static
/// obstacle, mapped or not ([`PlanProblem::of_world`]; iterations, length m).
pub fn path_exists(scene: &Scene, seed: u64) -> PathCheck {
    let params = PlannerParams { seed, ..PlannerParams::default() };
    plan(&PlanProblem::of_world(scene), &params)
        .map(|path| (path.iterations, path.length_m))
        .map_err(|e| e.to_string())
}

/// Generate a scene (see [`crate::world::generate`]) whose mission the planner connects.
pub fn generate(p: &GenParams) -> Result<Generated, InputError> {
    generate_with(p, &mut path_exists)
}
