//! `parapet scene …`: the command line of the scene tools (`scene generate`).
//!
//! May import: [`crate::world::generate`] (parameters), [`crate::plan::generate`]
//! (the generator with the planner's check), [`super`] (errors), `crate::input`.

use super::CliError;
use crate::input::InputError;
use crate::world::generate::{GenParams, Kind};

/// `parapet scene …`.
#[derive(Debug, clap::Args)]
pub struct SceneArgs {
    #[command(subcommand)]
    command: SceneCommand,
}

#[derive(Debug, clap::Subcommand)]
enum SceneCommand {
    /// Generate a procedural scene (forest, city, warehouse, clutter), seeded, with a mission
    /// the planner connects, and write it as a scene TOML.
    #[command(after_help = crate::cli::help::scene_generate())]
    Generate(GenerateArgs),
}

/// `parapet scene generate` options (defaults: [`GenParams::default`]).
#[derive(Debug, clap::Args)]
pub struct GenerateArgs {
    /// Kind of scene.
    #[arg(long, value_enum, default_value = "forest")]
    kind: Kind,
    /// Number of obstacles (1 ≤ n ≤ 1,000,000).
    #[arg(long, default_value_t = 1000)]
    obstacles: usize,
    /// RNG seed (same options and seed, same file).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// forest: trunks per m²; clutter: obstacles per m² of floor (0 < d ≤ 2).
    #[arg(long, default_value_t = 0.05)]
    density: f64,
    /// forest: smallest trunk radius, m.
    #[arg(long, default_value_t = 0.1)]
    radius_min: f64,
    /// forest: largest trunk radius, m.
    #[arg(long, default_value_t = 0.4)]
    radius_max: f64,
    /// city: street width, m.
    #[arg(long, default_value_t = 8.0)]
    street: f64,
    /// city: block side, m.
    #[arg(long, default_value_t = 20.0)]
    block: f64,
    /// warehouse: aisle width, m.
    #[arg(long, default_value_t = 3.0)]
    aisle: f64,
    /// Distance from the mission start to the goal, m (at most 80 % of the scene's side).
    #[arg(long, default_value_t = 60.0)]
    mission_length: f64,
    /// Height of the flight volume, m.
    #[arg(long, default_value_t = 5.0)]
    ceiling: f64,
    /// Mission reference speed, m/s.
    #[arg(long, default_value_t = 0.5)]
    speed: f64,
    /// Share of the obstacles written with `mapped = false` (in the world, not in the map the
    /// planner sees), 0 ≤ FRACTION ≤ 1; chosen by the seed, the world and mission unchanged.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.0, allow_negative_numbers = true)]
    unmapped: f64,
    /// Output scene file (TOML); an existing file only with --force.
    #[arg(long)]
    out: std::path::PathBuf,
    /// Replace an existing --out file.
    #[arg(long)]
    force: bool,
}

impl GenerateArgs {
    fn params(&self) -> GenParams {
        GenParams {
            kind: self.kind,
            seed: self.seed,
            obstacles: self.obstacles,
            density: self.density,
            radius_min: self.radius_min,
            radius_max: self.radius_max,
            street: self.street,
            block: self.block,
            aisle: self.aisle,
            mission_length: self.mission_length,
            ceiling: self.ceiling,
            speed: self.speed,
            unmapped: self.unmapped,
        }
    }
}

/// Run `parapet scene …`: returns the line to print.
pub fn cmd_scene(a: SceneArgs) -> Result<String, CliError> {
    let SceneCommand::Generate(g) = a.command;
    if g.out.is_dir() {
        return Err(InputError::option("out", "is a directory, not a file").value(g.out.display()).into());
    }
    if g.out.exists() && !g.force {
        return Err(InputError::option("out", "the file exists")
            .value(g.out.display())
            .allowed("a new file, or --force to replace it")
            .into());
    }
    let t0 = std::time::Instant::now();
    let made = crate::plan::generate::generate(&g.params())?;
    if let Some(dir) = g.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| CliError::Failed(anyhow::anyhow!("cannot create {}: {e}", dir.display())))?;
    }
    std::fs::write(&g.out, &made.toml)
        .map_err(|e| CliError::Failed(anyhow::anyhow!("cannot write {}: {e}", g.out.display())))?;
    Ok(format!(
        "{}: {} obstacles ({} unmapped), bounds {:?} .. {:?} m, mission {:.1} m apart, path {:.1} m ({} iterations), {:.0} ms -> {}\n",
        made.scene.name,
        made.scene.obstacles.len(),
        made.scene.unmapped_count(),
        made.scene.bounds_enu.0,
        made.scene.bounds_enu.1,
        (made.scene.goal - made.scene.start).norm(),
        made.plan_length_m,
        made.plan_iterations,
        t0.elapsed().as_secs_f64() * 1e3,
        g.out.display()
    ))
}
