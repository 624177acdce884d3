//! The `parapet` command line: `run`, `pil`, `plan`, `replay`.
//!
//! Exit codes: 0 success, 1 internal failure, 2 bad input (a file, field or
//! option named in the message), 3 no path found by the planner.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::anyhow;
use clap::{Args, Parser, Subcommand};
use nalgebra::Vector3;
use parapet_core::cbf::FilterVariant;

use crate::pathfile::PathFile;
use crate::planner::{plan, PlanProblem, PlannedPath, PlannerParams};
use crate::plant::VehicleParams;
use crate::replay::{parse_rotor_csv, replay, ReplayOptions};
use crate::report::{summary_table, write_report, RunRecord};
use crate::runner::{run, RunConfig};
use crate::scene::{to_f32, to_f64, Scene};

/// Exit codes of every `parapet` command, for `--help` (`after_help`) of the top
/// level and of each subcommand. Every command returns these and only these.
pub const EXIT_CODES_HELP: &str = "\
Exit codes:
  0    success: the command finished (a flight that collides or misses the goal still
       exits 0; its outcome is in the summary); also when stdout is closed early
       (`parapet run | head`)
  1    failure that is not the input's fault (I/O error writing a report, firmware or QEMU failure)
  2    bad input: a file, table, field or option is named with the value and the allowed range
  3    no path: the planner found no collision-free path within its budget";

/// Default scene of `parapet run` and `parapet plan`.
pub const DEFAULT_SCENE: &str = "scenes/office.toml";

/// Parapet: quadrotor flight with a closed-form CBF safety filter — simulator and tools.
#[derive(Debug, Parser)]
#[command(name = "parapet", version, about, long_about = None, after_help = EXIT_CODES_HELP)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Plan (or load) a path through a scene and fly it in closed loop on the 6-DOF
    /// simulator; write summary.json, trajectory.csv and plots.
    Run(RunArgs),
    /// Processor-in-the-loop: fly a scene like `run`, with the real firmware binary
    /// (`parapet-firmware-qemu`) in QEMU netduinoplus2 as the flight controller, in lockstep
    /// over MAVLink; same report plus PIL figures (frames, instructions per step, real-time factor).
    Pil(PilArgs),
    /// Plan a collision-free path through a scene's static obstacles and write it as JSON.
    Plan(PlanArgs),
    /// Drive the plant open loop with rotor speeds from a CSV (t,w1,w2,w3,w4 in rad/s)
    /// and write the states (t,x,y,z,vx,vy,vz,qw,qx,qy,qz,p,q,r; NED / FRD).
    Replay(ReplayArgs),
    /// Fly a scene over a grid of (μ, δ1[, speed]) × noise seeds in parallel; write sweep.csv
    /// and heatmaps of collision rate, min clearance and tracking RMS (paper Fig. 9).
    Sweep(crate::sweep::SweepArgs),
    /// Join the sweep.csv files of sharded sweeps (`--shard I/N`) and redraw the heatmaps.
    SweepMerge(crate::sweep::SweepMergeArgs),
}

#[derive(Debug, Args)]
struct RunArgs {
    /// Scene file (TOML, ENU z-up).
    #[arg(long, default_value = DEFAULT_SCENE)]
    scene: PathBuf,
    /// Fly this path file (JSON from `parapet plan`) instead of planning.
    #[arg(long)]
    path: Option<PathBuf>,
    /// Fly the straight line start → goal instead of planning (for tests and demos).
    #[arg(long, conflicts_with = "path")]
    straight: bool,
    /// [preflight] Fly a `--path` whose first/last waypoint is not within 0.5 m of the
    /// scene's mission start/goal (a path meant for elsewhere). Without it such a path is
    /// refused (exit 2). Bounds and collision checks of the start and waypoints still apply;
    /// `reached_goal` still means the scene's goal.
    #[arg(long)]
    foreign_path: bool,
    /// Disable the CBF safety filter (nominal PD tracking only).
    #[arg(long)]
    no_cbf: bool,
    /// Filter variant: paper | relative | multi | multi-relative (default: the scene's, else multi-relative).
    #[arg(long, value_parser = parse_variant)]
    filter: Option<FilterVariant>,
    /// Barrier velocity weight μ, s.
    #[arg(long, allow_negative_numbers = true)]
    mu: Option<f64>,
    /// Safety level δ, m² (hull radius squared).
    #[arg(long, allow_negative_numbers = true)]
    delta: Option<f64>,
    /// Engagement level δ1 (> δ), m².
    #[arg(long, allow_negative_numbers = true)]
    delta1: Option<f64>,
    /// PD position gain k_p, 1/s².
    #[arg(long, allow_negative_numbers = true)]
    kp: Option<f64>,
    /// PD velocity gain k_d, 1/s.
    #[arg(long, allow_negative_numbers = true)]
    kd: Option<f64>,
    /// Reference speed along the path, m/s.
    #[arg(long, allow_negative_numbers = true)]
    speed: Option<f64>,
    /// Random seed (sensor noise and planner).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Duration limit, s (default: the scene's, else 1.5 × the flown length (start → first
    /// waypoint → … → last) / speed + 15 s).
    #[arg(long, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Sensor noise on (default, unless the scene's [sensors] table says otherwise).
    #[arg(long, conflicts_with = "no_noise")]
    noise: bool,
    /// Sensor noise off.
    #[arg(long)]
    no_noise: bool,
    /// Proximity-sensor range, m (default: the scene's, else 3).
    #[arg(long, allow_negative_numbers = true)]
    sensing_range: Option<f64>,
    /// Output directory [default: out/run; `pil`: out/pil].
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Debug, Args)]
struct PilArgs {
    #[command(flatten)]
    run: RunArgs,
    /// Firmware ELF (`parapet-firmware-qemu`, the board-qemu build). Default: build it with
    /// cargo (release, thumbv7em-none-eabihf, --no-default-features --features board-qemu).
    #[arg(long)]
    firmware: Option<PathBuf>,
    /// Wall-clock seconds without an answer from the firmware before the run fails.
    #[arg(long, default_value_t = 3.0)]
    timeout: f64,
}

#[derive(Debug, Args)]
struct PlanArgs {
    /// Scene file (TOML, ENU z-up).
    #[arg(long, default_value = DEFAULT_SCENE)]
    scene: PathBuf,
    /// Planner seed (same seed, same path).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output path file (JSON, ENU z-up).
    #[arg(long, default_value = "out/path.json")]
    out: PathBuf,
}

#[derive(Debug, Args)]
struct ReplayArgs {
    /// Vehicle parameters: a TOML file with VehicleParams keys at the top level or in a
    /// [vehicle] table (a scene file works). Default: the built-in vehicle.
    #[arg(long)]
    vehicle: Option<PathBuf>,
    /// Input CSV: header t,w1,w2,w3,w4 (s, rad/s; rotor order 1..4 = FR, RL, FL, RR).
    #[arg(long)]
    inputs: PathBuf,
    /// Output CSV of states (NED position/velocity, quaternion FRD→NED, FRD body rates).
    #[arg(long)]
    out: PathBuf,
    /// Integration step, s.
    #[arg(long, default_value_t = 0.001)]
    dt: f64,
    /// Start position, NED, m, as x,y,z.
    #[arg(long, value_delimiter = ',', num_args = 3, default_values_t = [0.0, 0.0, 0.0])]
    start: Vec<f64>,
    /// Treat the speeds as commands through the first-order motor model (default: imposed directly).
    #[arg(long)]
    motor_lag: bool,
    /// Simulate the ground plane z = 0 (default off: free space).
    #[arg(long)]
    ground: bool,
}

fn parse_variant(s: &str) -> Result<FilterVariant, String> {
    s.parse().map_err(|_| format!("unknown filter {s:?}: expected paper, relative, multi or multi-relative"))
}

/// A failure with its exit code.
#[derive(Debug)]
pub enum CliError {
    /// Bad input (exit code 2): the message names the file / field / option.
    BadInput(String),
    /// No path found (exit code 3).
    NoPath(String),
    /// Anything else (exit code 1).
    Failed(anyhow::Error),
    /// `sweep` / `sweep-merge`: some runs failed, the others are written
    /// (exit code `sweep::EXIT_SOME_FAILED` = 4).
    SomeFailed(String),
}

impl CliError {
    /// Process exit code.
    pub fn exit_code(&self) -> i32 {
        match self {
            CliError::BadInput(_) => 2,
            CliError::NoPath(_) => 3,
            CliError::Failed(_) => 1,
            CliError::SomeFailed(_) => crate::sweep::EXIT_SOME_FAILED,
        }
    }
}

impl std::fmt::Display for CliError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CliError::BadInput(m) | CliError::NoPath(m) | CliError::SomeFailed(m) => f.write_str(m),
            CliError::Failed(e) => write!(f, "{e:#}"),
        }
    }
}

impl From<anyhow::Error> for CliError {
    fn from(e: anyhow::Error) -> Self {
        CliError::Failed(e)
    }
}

/// Parse the process arguments, run, print errors; returns the exit code.
pub fn main() -> i32 {
    let cli = Cli::parse();
    match dispatch(cli) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}

fn dispatch(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Run(a) => cmd_run(a),
        Command::Pil(a) => cmd_pil(a),
        Command::Plan(a) => cmd_plan(a),
        Command::Replay(a) => cmd_replay(a),
        Command::Sweep(a) => crate::sweep::cmd_sweep(a),
        Command::SweepMerge(a) => crate::sweep::cmd_sweep_merge(a),
    }
}

/// Resolve a scene path: as given, else (for the default scene only) relative
/// to the source tree this binary was built from.
fn resolve_scene(p: &Path) -> PathBuf {
    if !p.exists() && p == Path::new(DEFAULT_SCENE) {
        let alt = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(DEFAULT_SCENE);
        if alt.exists() {
            return alt;
        }
    }
    p.to_path_buf()
}

fn load_scene(p: &Path) -> Result<Scene, CliError> {
    Scene::load(&resolve_scene(p)).map_err(|e| CliError::BadInput(e.to_string()))
}

fn plan_scene(scene: &Scene, seed: u64) -> Result<PlannedPath, CliError> {
    let (mn, mx) = scene.bounds_ned();
    let problem = PlanProblem {
        bounds_min: to_f32(&mn),
        bounds_max: to_f32(&mx),
        obstacles: scene.static_shapes(),
        start: to_f32(&scene.start),
        goal: to_f32(&scene.goal),
        hull_radius: scene.vehicle.hull_radius as f32,
    };
    let params = PlannerParams { seed, ..PlannerParams::default() };
    plan(&problem, &params).map_err(|e| {
        let msg = format!("{}: planning failed: {e}", scene.source);
        if e.exit_code() == 3 {
            CliError::NoPath(msg)
        } else {
            CliError::BadInput(msg)
        }
    })
}

fn positive(name: &str, x: Option<f64>) -> Result<Option<f64>, CliError> {
    match x {
        Some(v) if !(v.is_finite() && v > 0.0) => {
            Err(CliError::BadInput(format!("option --{name}: must be finite and > 0, got {v}")))
        }
        other => Ok(other),
    }
}

/// Scene and run configuration from the `run` options (shared by `run` and `pil`).
fn run_setup(a: &RunArgs) -> Result<(Scene, RunConfig), CliError> {
    let mut scene = load_scene(&a.scene)?;
    // [preflight] the start is flyable (before planning from it); --foreign-path needs --path.
    crate::preflight::check_start(&scene).map_err(|e| CliError::BadInput(e.to_string()))?;
    if a.foreign_path && a.path.is_none() {
        return Err(CliError::BadInput("option --foreign-path: only with --path (a path file)".into()));
    }
    if let Some(s) = positive("speed", a.speed)? {
        scene.speed = s;
    }
    let (path, source, planning_ms) = if let Some(p) = &a.path {
        let f = PathFile::read(p).map_err(|e| CliError::BadInput(e.to_string()))?;
        let wps: Vec<Vector3<f64>> = f.waypoints_ned().iter().map(to_f64).collect();
        if wps.is_empty() {
            return Err(CliError::BadInput(format!("{}: field `waypoints`: empty", p.display())));
        }
        (wps, "file", None)
    } else if a.straight {
        (vec![scene.start, scene.goal], "straight", None)
    } else {
        let planned = plan_scene(&scene, a.seed)?;
        let wps = planned.waypoints.iter().map(to_f64).collect();
        (wps, "planner", Some(planned.planning_time_ms))
    };
    let capacity = parapet_core::controller::PATH_CAPACITY;
    if path.len() > capacity {
        let from =
            a.path.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "the planned path".into());
        return Err(CliError::BadInput(format!(
            "{from}: field `waypoints`: {} waypoints exceed the controller's path capacity of {capacity}",
            path.len()
        )));
    }
    let mut cfg = RunConfig::for_scene(&scene, path)
        .map_err(|e| CliError::BadInput(format!("{}: {e}", scene.source)))?;
    cfg.path_source = source.into();
    cfg.planning_time_ms = planning_ms;
    cfg.cbf = !a.no_cbf;
    if let Some(v) = a.filter {
        cfg.variant = v;
    }
    if let Some(x) = positive("mu", a.mu)? {
        cfg.params.mu = x;
    }
    if let Some(x) = positive("delta", a.delta)? {
        cfg.params.delta = x;
    }
    if let Some(x) = positive("delta1", a.delta1)? {
        cfg.params.delta1 = x;
    }
    if let Some(x) = positive("kp", a.kp)? {
        cfg.params.kp = x;
    }
    if let Some(x) = positive("kd", a.kd)? {
        cfg.params.kd = x;
    }
    if let Some(x) = positive("duration", a.duration)? {
        cfg.duration = x;
    } else if scene.sim.duration.is_none() {
        // [preflight] the default covers the whole flown path, start → first waypoint included.
        cfg.duration = crate::runner::default_duration(&scene, &cfg.path, cfg.params.speed);
    }
    if let Some(x) = positive("sensing-range", a.sensing_range)? {
        cfg.sensing_range = x;
    }
    if a.no_noise {
        cfg.sensors.noise = false;
    } else if a.noise {
        cfg.sensors.noise = true;
    }
    cfg.seed = a.seed;
    cfg.cbf_params().map_err(|e| CliError::BadInput(e.to_string()))?;
    // [preflight] start and waypoints in bounds and clear, the path belongs to the scene.
    let opts = crate::preflight::PreflightOptions {
        path_file: a.path.as_ref().map(|p| p.display().to_string()),
        foreign_path: a.foreign_path,
    };
    crate::preflight::check(&scene, &cfg, &opts).map_err(|e| CliError::BadInput(e.to_string()))?;
    Ok((scene, cfg))
}

/// Run `f` with a progress bar (simulated seconds) on a terminal.
fn with_progress<T>(duration: f64, f: impl FnOnce(&mut dyn FnMut(f64)) -> T) -> T {
    let bar = std::io::stderr().is_terminal().then(|| {
        let pb = indicatif::ProgressBar::new((duration * 10.0).ceil() as u64);
        pb.set_style(
            indicatif::ProgressStyle::with_template("{spinner} sim {msg} [{bar:40}] {elapsed_precise}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb
    });
    let mut on_progress = |t: f64| {
        if let Some(pb) = &bar {
            pb.set_position((t * 10.0) as u64);
            pb.set_message(format!("{t:6.1} s"));
        }
    };
    let r = f(&mut on_progress);
    if let Some(pb) = bar {
        pb.finish_and_clear();
    }
    r
}

fn cmd_run(a: RunArgs) -> Result<(), CliError> {
    let (scene, cfg) = run_setup(&a)?;
    let out = with_progress(cfg.duration, |p| run(&scene, &cfg, p))?;
    let dir = a.out.clone().unwrap_or_else(|| PathBuf::from("out/run"));
    let rec = RunRecord { scene: &scene, path: &cfg.path, samples: &out.samples, summary: &out.summary };
    let (files, warnings) = write_report(&dir, &rec)?;
    print!("{}", summary_table(&out.summary));
    println!("  report: {}", dir.display());
    for w in warnings {
        eprintln!("warning: {w}");
    }
    let _ = files;
    Ok(())
}

fn cmd_pil(a: PilArgs) -> Result<(), CliError> {
    use crate::pil::{add_figures_to_summary, build_firmware, run_pil, PilOptions};
    let (scene, cfg) = run_setup(&a.run)?;
    let timeout = positive("timeout", Some(a.timeout))?.unwrap_or(3.0);
    let elf = match &a.firmware {
        Some(p) if !p.is_file() => {
            return Err(CliError::BadInput(format!("option --firmware: {} is not a file", p.display())))
        }
        Some(p) => p.clone(),
        None => build_firmware()?,
    };
    let mut opts = PilOptions::new(elf);
    opts.timeout = std::time::Duration::from_secs_f64(timeout);
    opts.resend_after = opts.resend_after.min(opts.timeout / 2);
    let (out, fig) = with_progress(cfg.duration, |p| run_pil(&scene, &cfg, opts, p))?;
    let dir = a.run.out.clone().unwrap_or_else(|| PathBuf::from("out/pil"));
    let rec = RunRecord { scene: &scene, path: &cfg.path, samples: &out.samples, summary: &out.summary };
    let (_, warnings) = write_report(&dir, &rec)?;
    add_figures_to_summary(&dir, &fig)?;
    print!("{}", summary_table(&out.summary));
    let ins = &fig.instructions_per_control_step;
    println!(
        "  PIL: {} steps, real-time factor {:.3}; frames sent {}, received {}, dropped {}; \
         instructions/step mean {:.0}, max {} (≥ {:.0} µs at 168 MHz)",
        fig.flight_steps,
        fig.real_time_factor,
        fig.frames_sent,
        fig.frames_received,
        fig.frames_dropped,
        ins.mean,
        ins.max,
        ins.max_time_at_168mhz_us
    );
    println!("  report: {}", dir.display());
    for w in warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

fn cmd_plan(a: PlanArgs) -> Result<(), CliError> {
    let scene = load_scene(&a.scene)?;
    let planned = plan_scene(&scene, a.seed)?;
    let file = PathFile::from_planned(&scene.name, &planned);
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| anyhow!("cannot create {}: {e}", dir.display()))?;
    }
    file.write(&a.out).map_err(|e| anyhow!("{e}"))?;
    println!(
        "{}: {} waypoints, {:.2} m, {:.2} ms, {} iterations, seed {} -> {}",
        scene.name,
        planned.waypoints.len(),
        planned.length_m,
        planned.planning_time_ms,
        planned.iterations,
        planned.seed,
        a.out.display()
    );
    Ok(())
}

/// Load vehicle parameters from a TOML file: top-level keys, or a `[vehicle]` table.
pub fn load_vehicle(path: &Path) -> Result<VehicleParams, String> {
    let file = path.display();
    let src = std::fs::read_to_string(path).map_err(|e| format!("{file}: cannot read the file: {e}"))?;
    let value: toml::Table = toml::from_str(&src).map_err(|e| format!("{file}: {}", e.message()))?;
    let table = match value.get("vehicle") {
        Some(toml::Value::Table(t)) => t.clone(),
        Some(_) => return Err(format!("{file}: `vehicle` must be a table")),
        None => value,
    };
    let v: VehicleParams = toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| format!("{file}: [vehicle]: {}", e.message()))?;
    v.validate().map_err(|e| format!("{file}: [vehicle]: field `{}`: {}", e.field, e.reason))?;
    Ok(v)
}

fn cmd_replay(a: ReplayArgs) -> Result<(), CliError> {
    let vehicle = match &a.vehicle {
        Some(p) => load_vehicle(p).map_err(CliError::BadInput)?,
        None => VehicleParams::default(),
    };
    let src = std::fs::read_to_string(&a.inputs)
        .map_err(|e| CliError::BadInput(format!("{}: cannot read the file: {e}", a.inputs.display())))?;
    let rows =
        parse_rotor_csv(&src).map_err(|e| CliError::BadInput(format!("{}: {e}", a.inputs.display())))?;
    if !a.start.iter().all(|x| x.is_finite()) {
        return Err(CliError::BadInput("option --start: must be finite".into()));
    }
    let opts = ReplayOptions {
        dt: a.dt,
        start_ned: Vector3::new(a.start[0], a.start[1], a.start[2]),
        motor_lag: a.motor_lag,
        ground: a.ground,
    };
    let csv = replay(vehicle, &rows, &opts).map_err(|e| CliError::BadInput(format!("replay: {e}")))?;
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| anyhow!("cannot create {}: {e}", dir.display()))?;
    }
    std::fs::write(&a.out, csv).map_err(|e| anyhow!("cannot write {}: {e}", a.out.display()))?;
    println!("replayed {} samples -> {}", rows.len(), a.out.display());
    Ok(())
}
