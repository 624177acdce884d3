//! Parameter sweeps: `parapet sweep` and `parapet sweep-merge`.
//!
//! A sweep flies one scene over the grid speed × μ × δ1 × `--grid` axes × seed
//! (any continuous parameter by name, at most `input::limits::SWEEP_MAX_GRID_PARAMS`
//! axes; sensor-noise seeds `0..K`) on one fixed path (a path file, the straight line, or the
//! planner's path for planner seed `--plan-seed`, planned once), in parallel on a
//! local rayon pool of `--jobs` threads. Every run is deterministic for its seed,
//! so the grid can be split: `--shard I/N` (I = 1..=N) flies only the runs whose
//! grid index `k` satisfies `k mod N = I − 1`, and `sweep-merge` joins the shards
//! into the same `sweep.csv` the unsharded sweep writes.
//!
//! Before anything is flown (or allocated for the grid) the sizes are checked
//! against `input::limits` (values per range, seeds, runs per invocation, the
//! `--yes` threshold) and the base configuration passes `preflight::check`
//! (exit 2 otherwise). A run that fails on its own parameters (pre-flight or in
//! flight) becomes a `failed` row with its error; the other rows are kept and the
//! command exits with [`crate::cli::EXIT_SOME_FAILED`]. Rows stream to `sweep.csv` in grid
//! order as chunks of runs finish; memory is one chunk of rows plus one small
//! record per heatmap cell.
//!
//! Outputs in `--out` (default `out/sweep`; `sweep-merge`: `out/sweep-merge`):
//! `sweep.csv` ([`record`]), `sweep.json` ([`manifest`], written last: the
//! sweep's identity and which shards the CSV holds) and the heatmaps
//! ([`heatmap`]). No output ever replaces an input file (refused, exit 2).
//!
//! Submodules: [`grid`] (ranges, shards, sizes), [`record`] (the CSV),
//! [`manifest`] (`sweep.json`, merge checks), [`merge`] (`sweep-merge`),
//! [`heatmap`] (aggregation, plots), [`setup`] (a run's configuration, checks and
//! row). This file: `parapet sweep` (options, checks, flying the runs).
//! May import: `crate::{cli, fc, flight, input, plan, world}`,
//! clap, rayon, indicatif, anyhow.

pub mod grid;
pub mod heatmap;
pub mod manifest;
pub mod merge;
pub mod record;
pub mod setup;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use clap::Args;
use nalgebra::Vector3;
use parapet_core::cbf::FilterVariant;
use rayon::prelude::*;

pub use grid::{Grid, GridPoint, GridRange, Shard};
pub use heatmap::{Aggregator, Cell};
pub use manifest::{Identity, Manifest};
pub use merge::{cmd_sweep_merge, SweepMergeArgs};
pub use record::{SweepRecord, COLUMNS};
pub use setup::SweepSetup;

use crate::cli::{exit_codes_help, CliError};
use crate::flight::preflight::PreflightOptions;
use crate::flight::runner::{default_duration, RunConfig};
use crate::flight::validate::Given;
use crate::input::limits::{
    MAX_DURATION_CEILING_S, MAX_DURATION_S, SWEEP_CONFIRM_RUNS, SWEEP_MAX_GRID_PARAMS, SWEEP_MAX_JOBS,
    SWEEP_MAX_RUNS, SWEEP_MAX_SEEDS, SWEEP_MAX_VALUES,
};
use crate::input::InputError;
use crate::plan::pathfile::PathFile;
use crate::plan::{plan, PlanProblem, PlannerParams};
use crate::world::scene::{to_f64, Scene};

/// Simulated seconds per wall-clock second and thread, for the `--yes` estimate:
/// release build (office sweep in `docs/performance.md`: 96 flights of ~61 s in
/// 4.1 s on one thread) or debug build (one office flight, 61.3 s in 1.73 s).
const SIM_RATE_PER_THREAD: f64 = if cfg!(debug_assertions) { 35.0 } else { 1400.0 };
const BUILD: &str = if cfg!(debug_assertions) { "debug" } else { "release" };

/// Runs flown between two writes to `sweep.csv` (per thread).
const CHUNK_PER_JOB: usize = 64;

fn sweep_help() -> String {
    format!(
        "\
Grid: every combination speed × μ × δ1 × --grid axes × seed, index k speed-major (seed fastest).
  A range is A:B:N (N evenly spaced values from A to B) or one value A.
  --grid NAME=A:B:N grids any continuous parameter by name (at most {SWEEP_MAX_GRID_PARAMS} axes; its range is
  the parameter's; not a code parameter, nor one --mu, --delta1, --speed, --filter, --guidance or a --param
  sets); sweep.csv gets a column NAME with the value each run's controller flew.
  --seeds K flies the sensor-noise seeds 0, 1, …, K-1 at every grid point (a count, not a range).

Limits (input::limits):
  at most {SWEEP_MAX_VALUES} values per range, {SWEEP_MAX_SEEDS} seeds and {SWEEP_MAX_JOBS} threads (--jobs);
  at most {SWEEP_MAX_RUNS} runs per invocation: split a larger grid with --shard I/N;
  more than {SWEEP_CONFIRM_RUNS} runs need --yes (the refusal states the count and the estimated time);
  a run's duration at most --max-duration (default {MAX_DURATION_S} s, at most {MAX_DURATION_CEILING_S} s);
  heatmaps are drawn for at most {} μ and {} δ1 values.

Outputs (--out): sweep.csv (one row per run; status ok | failed, and the error of a failed run),
  sweep.json (the sweep's identity and shards, for sweep-merge), heatmap_*.png/svg
  (μ × δ1; each cell aggregates every speed, --grid value and seed; failed runs left out).
  The scene and path files are never overwritten.

Examples:
  parapet sweep --scene scenes/office.toml --path scenes/office_path.json --filter paper \\
      --mu 0.5:1.4:4 --delta1 0.051:0.3:4 --seeds 2 --out out/fig9
  parapet sweep --scene scenes/one_sphere.toml --straight --mu 0.9 --delta1 0.06:0.3:3 --speed 0.25:1:4
  parapet sweep --scene S --straight --mu 1.4 --delta1 0.1 --grid TRJ_ACC=0.5:2:4 --grid TRK_KP=0.5:1:2
  parapet sweep … --shard 1/2 --out out/s1   # and --shard 2/2 --out out/s2, then sweep-merge

{}",
        heatmap::MAX_AXIS_CELLS,
        heatmap::MAX_AXIS_CELLS,
        exit_codes_help(
            "sweep: some runs failed (status failed in sweep.csv, with the error); the others are kept"
        )
    )
}

fn parse_range(s: &str) -> Result<GridRange, String> {
    GridRange::parse(s)
}
fn parse_shard(s: &str) -> Result<Shard, String> {
    Shard::parse(s)
}
fn parse_variant(s: &str) -> Result<FilterVariant, String> {
    s.parse().map_err(|_| format!("unknown filter {s:?}: expected paper, relative, multi or multi-relative"))
}

/// Options of `parapet sweep`.
#[derive(Debug, Args)]
#[command(after_help = sweep_help())]
pub struct SweepArgs {
    /// Scene file (TOML, ENU z-up).
    #[arg(long)]
    pub scene: PathBuf,
    /// μ values, s: A:B:N (N values from A to B, e.g. 0.5:1.4:4) or one value (e.g. 0.9).
    #[arg(long, value_parser = parse_range)]
    pub mu: GridRange,
    /// δ1 values, m²: A:B:N or one value; each must exceed δ.
    #[arg(long, value_parser = parse_range)]
    pub delta1: GridRange,
    /// Reference speeds, m/s: A:B:N or one value [default: the scene's speed].
    #[arg(long, value_parser = parse_range)]
    pub speed: Option<GridRange>,
    /// Number K of sensor-noise seeds per grid point: seeds 0..K-1 (e.g. 4 → 0, 1, 2, 3).
    #[arg(long, value_name = "K", default_value = "1", value_parser = grid::parse_seed_count)]
    pub seeds: u64,
    /// Parallel runs (threads) [default: the number of CPUs].
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Filter variant: paper | relative | multi | multi-relative [default: the scene's, else multi-relative].
    #[arg(long, value_parser = parse_variant)]
    pub filter: Option<FilterVariant>,
    /// Sensor noise off.
    #[arg(long)]
    pub no_noise: bool,
    /// Fly this path file (JSON from `parapet plan`) instead of planning.
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// The path file may start and end away from the scene's start and goal.
    #[arg(long, requires = "path")]
    pub foreign_path: bool,
    /// Fly the straight line start → goal instead of planning.
    #[arg(long, conflicts_with = "path")]
    pub straight: bool,
    /// Planner seed of the one path every run flies (when planning).
    #[arg(long, default_value_t = 0)]
    pub plan_seed: u64,
    /// Duration limit of each run, s [default: the scene's [sim] duration, else 1.5 × flown path length / min(speed, 1 m/s) + 15 s].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Duration cap of each run, s (see Limits).
    #[arg(long, value_name = "S", default_value_t = MAX_DURATION_S)]
    pub max_duration: f64,
    /// Run only slice I of N (1 <= I <= N; grid index k with k mod N = I - 1).
    #[arg(long, value_parser = parse_shard)]
    pub shard: Option<Shard>,
    /// Fly more than the --yes threshold of runs (see Limits).
    #[arg(long)]
    pub yes: bool,
    /// Output directory.
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
    /// Set any controller parameter by name for every run (repeatable), as `parapet run
    /// --param NAME=VALUE`; the grid's μ, δ1 and speed win over CBF_MU, CBF_DELTA1, WP_SPEED.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub param: Vec<String>,
    /// A QGroundControl `.params` file for every run, as `parapet run --params`.
    #[arg(long = "params", value_name = "FILE")]
    pub params_file: Option<PathBuf>,
    /// Mission guidance of every run (MIS_GUIDANCE), as `parapet run --guidance`: trajectory
    /// (the default) | paper (the paper's constant-speed point; the paper's sweeps name it).
    /// Wins over `--param MIS_GUIDANCE`.
    #[arg(long, value_parser = crate::cli::values::parse_guidance)]
    pub guidance: Option<parapet_core::outer::guidance::MissionGuidance>,
    /// Grid a parameter by name (repeatable, see Grid): NAME=A:B:N or NAME=A.
    #[arg(long = "grid", value_name = "NAME=A:B:N")]
    pub grid: Vec<String>,
}

fn bad(m: impl Into<String>) -> CliError {
    CliError::BadInput(m.into())
}

pub(crate) fn bad_input(e: InputError) -> CliError {
    CliError::BadInput(e.to_string())
}

/// The path every run of a sweep flies (NED, start first).
fn sweep_path(scene: &Scene, a: &SweepArgs) -> Result<(Vec<Vector3<f64>>, &'static str), CliError> {
    if let Some(p) = &a.path {
        let f = PathFile::read(p).map_err(|err| bad(err.to_string()))?;
        let wps: Vec<Vector3<f64>> = f.waypoints_ned().iter().map(to_f64).collect();
        if wps.is_empty() {
            return Err(bad(format!("{}: field `waypoints`: empty", p.display())));
        }
        return Ok((wps, "file"));
    }
    if a.straight {
        return Ok((vec![scene.start, scene.goal], "straight"));
    }
    let problem = PlanProblem::from_scene(scene);
    let params = PlannerParams { seed: a.plan_seed, ..PlannerParams::default() };
    let planned = plan(&problem, &params).map_err(|err| {
        let msg = format!("{}: planning failed: {err}", scene.source);
        if err.exit_code() == 3 {
            CliError::NoPath(msg)
        } else {
            bad(msg)
        }
    })?;
    Ok((planned.waypoints.iter().map(to_f64).collect(), "planner"))
}

/// Fly the runs `shard` holds of `grid` on `jobs` threads, in chunks; each chunk's
/// rows go to `sink` in grid order. `tick` is called after each run.
pub fn run_shard(
    setup: &SweepSetup,
    grid: &Grid,
    shard: Shard,
    jobs: usize,
    sink: &mut dyn FnMut(&SweepRecord) -> Result<()>,
    tick: &(dyn Fn() + Sync),
) -> Result<()> {
    let total = grid.size().ok_or_else(|| anyhow!("grid size overflows"))?;
    let n = shard.len(total);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.max(1))
        .build()
        .map_err(|err| anyhow!("cannot start the thread pool: {err}"))?;
    let chunk = (CHUNK_PER_JOB * jobs.max(1)) as u64;
    let mut j = 0;
    while j < n {
        let end = n.min(j + chunk);
        let points: Vec<GridPoint> = (j..end).map(|i| grid.point(shard.nth(i))).collect();
        let rows: Vec<SweepRecord> = pool.install(|| {
            points
                .par_iter()
                .map(|p| {
                    let r = setup.fly(p);
                    tick();
                    r
                })
                .collect()
        });
        for r in &rows {
            sink(r)?;
        }
        j = end;
    }
    Ok(())
}

/// Refuse writing any of `outputs` over one of `inputs` (same file after resolving).
pub(crate) fn refuse_overwrite(
    outputs: &[PathBuf],
    inputs: &[PathBuf],
    option: &str,
) -> Result<(), CliError> {
    let canon = |p: &Path| -> Option<PathBuf> {
        if let Ok(c) = p.canonicalize() {
            return Some(c);
        }
        // Not there yet: its directory resolved, plus the name.
        let dir = p.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        Some(dir.canonicalize().ok()?.join(p.file_name()?))
    };
    let ins: Vec<(PathBuf, &PathBuf)> = inputs.iter().filter_map(|p| Some((canon(p)?, p))).collect();
    for o in outputs {
        let Some(oc) = canon(o) else { continue };
        if let Some((_, i)) = ins.iter().find(|(c, _)| *c == oc) {
            return Err(bad_input(
                InputError::option(
                    option,
                    format!("the output {} would overwrite the input {}", o.display(), i.display()),
                )
                .value(o.display())
                .allowed("a directory that holds none of the inputs"),
            ));
        }
    }
    Ok(())
}

/// Print a line of the report on stdout; a closed stdout (`parapet sweep … | head`)
/// is not an error: the outputs are written either way.
pub(crate) fn say(line: std::fmt::Arguments) {
    use std::io::Write;
    let _ = writeln!(std::io::stdout().lock(), "{line}");
}

/// Create the output directory; failing that is a bad `--out` (exit 2).
pub(crate) fn create_out(dir: &Path) -> Result<(), CliError> {
    std::fs::create_dir_all(dir).map_err(|e| {
        bad_input(
            InputError::option("out", format!("cannot create the output directory: {e}"))
                .value(dir.display())
                .allowed("a directory that can be created and written"),
        )
    })
}

pub(crate) fn output_files(dir: &Path) -> Vec<PathBuf> {
    let mut v = vec![dir.join("sweep.csv"), dir.join("sweep.json"), dir.join("sweep.csv.partial")];
    v.extend(heatmap::file_names().into_iter().map(|n| dir.join(n)));
    v
}

fn human_duration(s: f64) -> String {
    if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 2.0 * 3600.0 {
        format!("{:.0} min", s / 60.0)
    } else if s < 2.0 * 86400.0 {
        format!("{:.1} h", s / 3600.0)
    } else {
        format!("{:.1} days", s / 86400.0)
    }
}

/// Check the sizes against the caps; returns this invocation's number of runs.
/// `duration(speed)` is a run's simulated duration, for the time estimate.
fn check_size(
    grid: &Grid,
    a: &SweepArgs,
    duration: &dyn Fn(f64) -> f64,
    jobs: usize,
) -> Result<u64, CliError> {
    let shard = a.shard.unwrap_or(Shard::ALL);
    let options = "options --mu, --delta1, --speed, --grid, --seeds";
    let Some(total) = grid.size() else {
        return Err(bad_input(
            InputError::file(
                options,
                format!("the grid ({}) has more runs than fit in 64 bits", grid.describe()),
            )
            .allowed(format!("at most {SWEEP_MAX_RUNS} runs per invocation")),
        ));
    };
    let runs = shard.len(total);
    if runs > SWEEP_MAX_RUNS {
        let need = total.div_ceil(SWEEP_MAX_RUNS);
        return Err(bad_input(
            InputError::file(
                options,
                format!(
                    "the sweep would fly {runs} runs (grid {} = {total}{}), more than the cap of {SWEEP_MAX_RUNS} \
                     runs per invocation (input::limits::SWEEP_MAX_RUNS); split it with --shard I/N, N ≥ {need}",
                    grid.describe(),
                    a.shard.map(|s| format!(", shard {}/{}", s.index, s.count)).unwrap_or_default()
                ),
            )
            .value(runs)
            .allowed(format!("≤ {SWEEP_MAX_RUNS} runs")),
        ));
    }
    if runs > SWEEP_CONFIRM_RUNS && !a.yes {
        // Estimated simulated time: each speed's share of the runs at its duration.
        let per_speed: f64 =
            grid.speeds.iter().map(|&v| duration(v)).sum::<f64>() / grid.speeds.len().max(1) as f64;
        let wall = runs as f64 * per_speed / (SIM_RATE_PER_THREAD * jobs.max(1) as f64);
        return Err(bad_input(
            InputError::option(
                "yes",
                format!(
                    "the sweep would fly {runs} runs (grid {}), more than {SWEEP_CONFIRM_RUNS} \
                     (input::limits::SWEEP_CONFIRM_RUNS); estimated time ≈ {} on {jobs} threads \
                     ({BUILD} build, ~{SIM_RATE_PER_THREAD:.0}× real time per thread, ~{per_speed:.0} s simulated per run); \
                     add --yes to fly it, or split it with --shard I/N",
                    grid.describe(),
                    human_duration(wall)
                ),
            )
            .value(runs)
            .allowed(format!("≤ {SWEEP_CONFIRM_RUNS} runs without --yes")),
        ));
    }
    Ok(runs)
}

/// `parapet sweep`.
pub fn cmd_sweep(a: SweepArgs) -> Result<(), CliError> {
    if let Some(j) = a.jobs.filter(|&j| j == 0 || j > SWEEP_MAX_JOBS) {
        return Err(bad_input(
            InputError::option("jobs", "thread count out of range (input::limits::SWEEP_MAX_JOBS)")
                .value(j)
                .allowed(format!("1 ≤ jobs ≤ {SWEEP_MAX_JOBS}")),
        ));
    }
    if let Some(d) = a.duration.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(bad_input(
            InputError::option("duration", "must be finite and > 0").value(d).allowed("> 0 s"),
        ));
    }
    let max_duration = a.max_duration;
    if !(max_duration > 0.0 && max_duration <= MAX_DURATION_CEILING_S) {
        return Err(bad_input(
            InputError::option("max-duration", "out of range")
                .value(max_duration)
                .allowed(format!("0 < max-duration ≤ {MAX_DURATION_CEILING_S} s")),
        ));
    }
    if let Some(d) = a.duration.filter(|&d| d > max_duration) {
        return Err(bad_input(
            InputError::option(
                "duration",
                format!(
                    "beyond the duration cap (input::limits::MAX_DURATION_S){}",
                    if max_duration < MAX_DURATION_CEILING_S {
                        format!("; --max-duration raises it up to {MAX_DURATION_CEILING_S} s")
                    } else {
                        String::new()
                    }
                ),
            )
            .value(d)
            .allowed(format!("0 < duration ≤ {max_duration} s")),
        ));
    }
    let cpus = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let jobs = a.jobs.unwrap_or(cpus.min(SWEEP_MAX_JOBS));
    // Loaded first: the loader checks the file (size cap included) before we hash it.
    let mut scene = Scene::load(&a.scene).map_err(|err| bad(err.to_string()))?;
    // --params FILE, then --param NAME=VALUE, as `parapet run` applies them.
    let mut given = a.param.clone();
    if let Some(g) = a.guidance {
        given.push(format!("MIS_GUIDANCE={}", g.code()));
    }
    let assigned = crate::cli::params::assignments(a.params_file.as_deref(), &given)?;
    let overrides = crate::cli::params::split_assignments(&mut scene, &assigned)?;
    let scene_bytes = std::fs::read(&a.scene)
        .map_err(|err| bad(format!("{}: cannot read the file: {err}", a.scene.display())))?;
    let speed = a.speed.clone().unwrap_or(GridRange { start: scene.speed, end: scene.speed, n: 1 });
    let taken = grid::Taken { params: &a.param, filter: a.filter.is_some(), guidance: a.guidance.is_some() };
    let axes = grid::parse_axes(&a.grid, &taken).map_err(bad_input)?;
    let grid_params: Vec<grid::ParamAxis> = axes.iter().map(|x| x.1.clone()).collect();
    let grid = Grid::new(&a.mu, &a.delta1, &speed, a.seeds).with_axes(&grid_params);
    let fixed_duration = a.duration.or(scene.sim.duration);
    // A first size check with the straight-line length (the path is not known yet):
    // refuses absurd grids before planning.
    let rule = |path: &[Vector3<f64>], v: f64| {
        scene
            .sim
            .duration
            .unwrap_or_else(|| a.duration.unwrap_or(f64::INFINITY).min(default_duration(&scene, path, v)))
    };
    let straight = [scene.goal];
    check_size(&grid, &a, &|v| rule(&straight, v), jobs)?;
    // The start must be flyable before the planner is asked for a path from it.
    crate::flight::preflight::check_start(&scene).map_err(bad_input)?;

    let (path, source) = sweep_path(&scene, &a)?;
    if path.len() > crate::input::limits::MAX_WAYPOINTS {
        let from =
            a.path.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "the planned path".into());
        return Err(bad(format!(
            "{from}: field `waypoints`: {} waypoints exceed what a mission holds ({})",
            path.len(),
            crate::input::limits::MAX_WAYPOINTS
        )));
    }
    let mut base =
        RunConfig::for_scene(&scene, path).map_err(|err| bad(format!("{}: {err:#}", scene.source)))?;
    base.path_source = source.into();
    base.param_overrides = overrides;
    if let Some(v) = a.filter {
        base.variant = v;
    }
    if a.no_noise {
        base.sensors.noise = false;
    }
    if let Some(d) = fixed_duration {
        base.duration = d;
    }
    let scene_duration = scene.sim.duration.is_some();
    let runs = check_size(&grid, &a, &|v| rule(&base.path, v), jobs)?;
    let delta = base.params.delta;
    if let Some(d1) = grid.delta1.iter().find(|&&d1| d1 <= delta) {
        return Err(bad_input(
            InputError::option("delta1", "every value must exceed δ")
                .value(d1)
                .allowed(format!("> δ = {delta} m² (the scene's [controller] delta, else the default)")),
        ));
    }
    let preflight = PreflightOptions {
        path_file: a.path.as_ref().map(|p| p.display().to_string()),
        foreign_path: a.foreign_path,
    };
    crate::flight::preflight::check(&scene, &base, &preflight).map_err(bad_input)?;
    let mut options = vec!["mu", "delta1", "speed"];
    if a.duration.is_some() {
        options.push("duration");
    }
    let given = Given { options, max_duration };
    let mut inputs = vec![a.scene.clone()];
    inputs.extend(a.path.clone());
    refuse_overwrite(&output_files(&a.out), &inputs, "out")?;

    let shard = a.shard.unwrap_or(Shard::ALL);
    let mut hash_bytes = Vec::with_capacity(base.path.len() * 24);
    for w in &base.path {
        for x in w.iter() {
            hash_bytes.extend_from_slice(&x.to_le_bytes());
        }
    }
    let filter = if base.cbf { base.variant.as_str().to_string() } else { "none".into() };
    let identity = Identity {
        format: manifest::FORMAT,
        parapet_version: env!("CARGO_PKG_VERSION").into(),
        scene: scene.name.clone(),
        scene_fnv1a64: manifest::fnv1a64(&scene_bytes),
        path_source: source.into(),
        plan_seed: (source == "planner").then_some(a.plan_seed),
        path_fnv1a64: manifest::fnv1a64(&hash_bytes),
        foreign_path: a.foreign_path,
        filter,
        noise: base.sensors.noise,
        duration_s: fixed_duration,
        max_duration_s: max_duration,
        mu: a.mu.clone(),
        delta1: a.delta1.clone(),
        speed,
        seeds: a.seeds,
        params: assigned.iter().map(|(p, x)| (p.name.to_string(), *x)).collect(),
        grid_params,
    };
    let axes = axes.iter().map(|x| x.0).collect();
    let setup =
        SweepSetup { scene, base, preflight, scene_duration, duration_limit: a.duration, given, axes };
    // What the grid does not change must pass for the first run; a refusal about
    // a grid option (or the duration its speed implies) is that run's failed row.
    if let Err(e) = setup.check(&grid.point(0)) {
        let per_run =
            ["option --mu", "option --delta1", "option --speed", "option --duration", "option --grid"];
        if !per_run.contains(&e.origin.as_str()) {
            return Err(bad_input(e));
        }
    }

    create_out(&a.out)?;
    let json = a.out.join("sweep.json");
    // An old manifest would vouch for the new, unfinished CSV.
    if json.exists() {
        std::fs::remove_file(&json).with_context(|| format!("cannot remove the old {}", json.display()))?;
    }
    let csv_path = a.out.join("sweep.csv");
    let names: Vec<String> = grid.params.iter().map(|(n, _)| n.clone()).collect();
    let mut csv = record::CsvSink::create(&csv_path, &names)
        .with_context(|| format!("cannot write {}", csv_path.display()))?;
    let bar = std::io::stderr().is_terminal().then(|| {
        let pb = indicatif::ProgressBar::new(runs);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "sweep [{bar:40}] {pos}/{len} runs {elapsed_precise} eta {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb
    });
    let tick = || {
        if let Some(pb) = &bar {
            pb.inc(1);
        }
    };
    let mut agg = Aggregator::default();
    let mut sink = |r: &SweepRecord| -> Result<()> {
        agg.add(r);
        csv.push(r).with_context(|| format!("cannot write {}", csv_path.display()))
    };
    run_shard(&setup, &grid, shard, jobs, &mut sink, &tick)?;
    if let Some(pb) = bar {
        pb.finish_and_clear();
    }
    csv.finish().with_context(|| format!("cannot write {}", csv_path.display()))?;
    let total = grid.size().unwrap_or(0);
    let m = Manifest {
        identity,
        scene_file: a.scene.display().to_string(),
        path_file: a.path.as_ref().map(|p| p.display().to_string()),
        grid_runs: total,
        shard_count: shard.count,
        shards: vec![shard.index],
        rows: agg.rows(),
        failed: agg.failed(),
    };
    m.write(&json).with_context(|| format!("cannot write {}", json.display()))?;
    let (_, warnings) = heatmap::write_heatmaps(&a.out, &setup.scene.name, &agg.aggregate());
    for w in warnings {
        eprintln!("warning: {w}");
    }
    say(format_args!(
        "{}: {} of {} runs{}, {} collided, {} failed -> {}",
        setup.scene.name,
        agg.rows(),
        total,
        a.shard.map(|s| format!(" (shard {}/{})", s.index, s.count)).unwrap_or_default(),
        agg.collided(),
        agg.failed(),
        csv_path.display()
    ));
    some_failed(agg.failed(), agg.rows(), &csv_path)
}

pub(crate) fn some_failed(failed: u64, rows: u64, csv: &Path) -> Result<(), CliError> {
    if failed == 0 {
        return Ok(());
    }
    Err(CliError::SomeFailed(format!(
        "{failed} of {rows} runs failed (rows with status `failed` in {}, column `error` says why); the other rows are complete",
        csv.display()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_code_4_is_listed_exactly_once() {
        let h = exit_codes_help("some runs failed");
        assert_eq!(h.matches(&format!("\n  {} ", crate::cli::EXIT_SOME_FAILED)).count(), 1, "{h}");
        assert!(h.starts_with(crate::cli::EXIT_CODES_HELP));
    }
}
