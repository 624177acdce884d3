//! The `parapet` commands `run`, `pil`, `plan`, `replay`, `scene` ([`scene`]) and `log` ([`log`]),
//! the shared command plumbing (errors and exit codes, run options, output) and
//! the help texts ([`help`]). The `parapet` parser and dispatch is the binary
//! (`src/main.rs`), above this module, [`crate::sweep`] and [`crate::campaign`]
//! (which use [`CliError`] and [`run_config_from_args`]).
//!
//! Exit codes ([`EXIT_CODES_HELP`]): 0 success, 1 internal failure, 2 bad input
//! (a file, table, field or option named in the message with the value and the
//! allowed range), 3 no path found by the planner. Bad input is an
//! [`InputError`]; library error enums are never shown as debug text.
//!
//! Standard output goes through [`out`] ([`crate::cli::output`]): a closed pipe
//! (`parapet run | head`) ends the command quietly with exit 0, never a panic.
//! Outputs never replace an input file ([`refuse_overwrite`]).
//!
//! May import: every host-sim module except [`crate::sweep`] and [`crate::campaign`].

pub mod help;
pub mod log;
pub mod output;
pub mod params;
pub mod pilot;
pub mod report_out;
pub mod scene;
mod setup;
pub mod sitl;
pub(crate) mod values;

pub use setup::run_config_from_args;
use setup::{positive, run_setup};

use values::{
    default_help, parse_assumption, parse_guidance, parse_variant, parse_vec3, parse_yaw_mode, speed_help,
};

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::anyhow;
use clap::{Args, Parser};
use nalgebra::Vector3;
use parapet_core::cbf::FilterVariant;
use parapet_core::outer::guidance::MissionGuidance;
use parapet_core::outer::path_yaw::YawMode;

pub use crate::cli::output::{out, refuse_overwrite};
pub use crate::sim::replay::load_vehicle;

use crate::fc::control::run;
use crate::flight::runner::RunConfig;
use crate::input::{limits, num, InputError};
use crate::plan::pathfile::PathFile;
use crate::plan::{plan, plan_with_index, PlanMethod, PlanProblem, PlannedPath, PlannerParams};
use crate::report::summary_table;
use crate::sim::plant::VehicleParams;
use crate::sim::replay::{parse_rotor_csv, replay, ReplayOptions};
use crate::world::scene::{to_f64, Scene};
use report_out::{check_report_dir, write_run_report};

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

/// Exit code of `parapet sweep`, `sweep-merge` and `campaign` when some runs failed (their rows say why; the
/// others are complete).
pub const EXIT_SOME_FAILED: i32 = 4;

/// The shared exit-code text, with code [`EXIT_SOME_FAILED`] explained by `what`
/// unless the shared text already lists it.
pub fn exit_codes_help(what: &str) -> String {
    let shared = EXIT_CODES_HELP;
    if shared.contains(&format!("\n  {EXIT_SOME_FAILED} ")) {
        shared.to_string()
    } else {
        format!("{shared}\n  {EXIT_SOME_FAILED}    {what}")
    }
}

/// Default scene of `parapet run` and `parapet plan`.
pub const DEFAULT_SCENE: &str = "scenes/office.toml";

#[derive(Debug, Args)]
pub struct RunArgs {
    /// `--gcs`, `--api`, `--realtime` (ground stations; `parapet pil` and `parapet run`).
    #[command(flatten)]
    sitl: sitl::SitlArgs,
    /// `--pilot`, `--offboard` (the simulated pilot / companion; `parapet run`).
    #[command(flatten)]
    pilot: pilot::PilotArgs,
    /// Scene file (TOML, ENU z-up; see scenes/README.md).
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
    /// Filter variant: paper | relative | multi | multi-relative | braking (the braking-distance
    /// barrier, CBF_BRAKE_*; docs/filter.md §16) (default: the scene's, else multi-relative).
    #[arg(long, value_parser = parse_variant)]
    filter: Option<FilterVariant>,
    /// Yaw along the path (MIS_YAW_MODE): hold (the heading at arming) | travel (face the direction
    /// of travel, turning at MIS_YAW_RATE; the path waits while the heading is more than
    /// 12° off) [default: the scene's [controller] yaw_mode, else travel when every range
    /// sensor of --perception looks forward (camera), else hold]. See docs/cascade.md.
    #[arg(long, value_parser = parse_yaw_mode)]
    yaw_mode: Option<YawMode>,
    /// Mission guidance (MIS_GUIDANCE): trajectory (the default: jerk-limited, corner-blended,
    /// its clock waits for the vehicle; limits TRJ_*, cruise --speed) | paper (the paper's
    /// constant-speed point, s = V·t, as the paper flies it). Same as `--param
    /// MIS_GUIDANCE=1|0`. See docs/cascade.md.
    #[arg(long, value_parser = parse_guidance)]
    guidance: Option<MissionGuidance>,
    /// Where the position fix comes from, as the scene's `[sensors] position_source`: mocap |
    /// gps | rtk | vio (their preset rate, noise and latency under the keys the scene's
    /// `[sensors]` table sets; docs/navigation.md) [default: the scene's, else mocap].
    #[arg(long, value_parser = values::parse_position_source)]
    position_source: Option<crate::sim::source::PositionSource>,
    #[arg(long, allow_negative_numbers = true, help = default_help("Barrier velocity weight μ, s", "mu"))]
    mu: Option<f64>,
    #[arg(long, allow_negative_numbers = true, help = default_help("Safety level δ, m² (hull radius squared)", "delta"))]
    delta: Option<f64>,
    #[arg(long, allow_negative_numbers = true, help = default_help("Engagement level δ1 (> δ), m²", "delta1"))]
    delta1: Option<f64>,
    #[arg(long, allow_negative_numbers = true, help = default_help("PD position gain k_p, 1/s²", "kp"))]
    kp: Option<f64>,
    #[arg(long, allow_negative_numbers = true, help = default_help("PD velocity gain k_d, 1/s", "kd"))]
    kd: Option<f64>,
    #[arg(long, allow_negative_numbers = true, help = speed_help())]
    speed: Option<f64>,
    /// Random seed (sensor noise and planner).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Duration limit, s (default: the scene's, else 1.5 × the flown length (start → first
    /// waypoint → … → last) / min(speed, 1 m/s) + 15 s, extended while the vehicle still makes
    /// progress along the path: 15 s after the last 0.25 m of it or the last on-board replan,
    /// at most 4 × the limit).
    #[arg(long, allow_negative_numbers = true)]
    duration: Option<f64>,
    #[arg(long, allow_negative_numbers = true, help = format!(
        "Raise the duration cap, s [default: {} s; at most {} s]",
        limits::MAX_DURATION_S, limits::MAX_DURATION_CEILING_S))]
    max_duration: Option<f64>,
    /// Sensor noise on (default, unless the scene's [sensors] table says otherwise).
    #[arg(long, conflicts_with = "no_noise")]
    noise: bool,
    /// Sensor noise off.
    #[arg(long)]
    no_noise: bool,
    /// Proximity-sensor range, m (default: the scene's, else 3).
    #[arg(long, allow_negative_numbers = true)]
    sensing_range: Option<f64>,
    /// What the safety filter sees: `truth` (the exact closest points in range, default), or
    /// range sensors through the obstacle memory: `lidar` (72 beams, 10 Hz), `lidar360`, `lidar3d` (Mid-360-like, 360° × −7…52°, 40 m),
    /// `camera` (forward depth camera 87°×58°, 16×10, 30 Hz), `tof` (ten 8×8 ToF, 45°×45°, 4 m:
    /// eight every 45°, one up, one down), `tof4` (four: forward, right, back, left), `tof8` (the
    /// eight), `scene` (the scene's [[sensor]] tables), or a comma list (`lidar,camera`).
    /// `pil`: planar 360° lidars → each scan to the firmware as OBSTACLE_DISTANCE (its own
    /// obstacle memory); others → the host memory's points as OBSTACLE_DISTANCE_3D (docs/perception.md).
    #[arg(long, default_value = "truth")]
    perception: String,
    /// [preflight] World assumptions that let a `--perception` set with a coverage gap fly (comma
    /// list or repeated; added to the scene's `[sensors] assume`): `no-overhangs` (a gap above
    /// the sensors' band), `no-low-obstacles` (below it; a planar lidar needs both),
    /// `forward-flight` (bearings no sensor sees: a forward camera). A gap without its assumption
    /// is refused (exit 2); range gaps are the speed governor's. docs/perception.md § Coverage check.
    #[arg(long, value_delimiter = ',', value_parser = parse_assumption)]
    assume: Vec<crate::sim::coverage::Assumption>,
    /// Output directory [default: out/run; `pil`: out/pil]; must not hold an input file.
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    disturb: crate::sim::disturbance::args::DisturbanceArgs,
    /// Set any controller parameter by name (repeatable), e.g. `--param PA_SPEED_MAX=3`: the
    /// names, units and ranges are `parapet params export`'s and `cargo xtask params`' (docs/
    /// cascade.md). A parameter with a scene key (CBF_MU: `mu`, WP_SPEED: `speed`, …) acts as
    /// that `[controller]` key, over the scene's value; its own option (`--mu`, `--speed`) wins
    /// over both. Unknown name or out-of-range value: exit 2 naming it and the range.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    param: Vec<String>,
    /// A QGroundControl parameter file (`.params`, as `parapet params export` or QGC's "Save to
    /// file" writes it), applied like `--param` for each line before the `--param` options.
    #[arg(long = "params", value_name = "FILE")]
    params_file: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct PilArgs {
    #[command(flatten)]
    run: RunArgs,
    /// Firmware ELF (`parapet-firmware-qemu`, the board-qemu build). Default: build it with
    /// cargo (release, thumbv7em-none-eabihf, --no-default-features --features board-qemu).
    #[arg(long)]
    firmware: Option<PathBuf>,
    /// Wall-clock seconds without an answer from the firmware before the run fails.
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
    timeout: f64,
    /// A ground station flies the vehicle (use with --gcs/--api, usually --realtime): it waits
    /// disarmed on the ground below the scene's start; the GCS uploads the mission, arms, takes
    /// off, starts, lands and disarms. The run ends when the vehicle is disarmed after a
    /// flight, or at --duration (docs/ground-station.md).
    #[arg(long)]
    gcs_control: bool,
}

#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Scene file (TOML, ENU z-up).
    #[arg(long, default_value = DEFAULT_SCENE)]
    scene: PathBuf,
    /// Planner seed (same seed, same path).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output path file (JSON, ENU z-up); never the scene file, and an existing file only
    /// if it is a parapet path file (or with --force).
    #[arg(long, default_value = "out/path.json")]
    out: PathBuf,
    /// Replace an existing --out file even if it is not a path file (never an input).
    #[arg(long)]
    force: bool,
    /// Wall-clock budget of the search (grid and RRT-Connect), s (0 < t ≤ 3600).
    #[arg(long, default_value_t = crate::input::limits::PLANNER_BUDGET_S)]
    time_limit: f64,
    /// RRT-Connect iteration budget (1 ≤ n ≤ 100000000; the grid search is bounded by --time-limit).
    #[arg(long, default_value_t = PlannerParams::default().max_iterations)]
    max_iterations: u32,
}

#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// Vehicle parameters: a TOML file with VehicleParams keys at the top level or in a
    /// [vehicle] table; a scene file works (its [vehicle] table, defaults for missing keys).
    /// Default: the built-in vehicle.
    #[arg(long)]
    vehicle: Option<PathBuf>,
    /// Input CSV: header t,w1,w2,w3,w4 (s, rad/s; rotor order 1..4 = FR, RL, FL, RR).
    #[arg(long)]
    inputs: PathBuf,
    /// Output CSV of states (NED position/velocity, quaternion FRD→NED, FRD body rates);
    /// must not be an input file.
    #[arg(long)]
    out: PathBuf,
    /// Integration step, s.
    #[arg(long, default_value_t = 0.001, allow_negative_numbers = true)]
    dt: f64,
    /// Start position, NED, m, as x,y,z (e.g. `--start 1,2,-1.5`: 1.5 m up).
    #[arg(long, value_parser = parse_vec3, default_value = "0,0,0", allow_hyphen_values = true)]
    start: [f64; 3],
    /// Treat the speeds as commands through the first-order motor model (default: imposed directly).
    #[arg(long)]
    motor_lag: bool,
    /// With --motor-lag: every rotor's speed at the first row's time, rad/s (default: the
    /// first row's speeds).
    #[arg(long, requires = "motor_lag", allow_negative_numbers = true)]
    initial_speed: Option<f64>,
    /// Steady wind, NED, m/s, as x,y,z (default 0,0,0: still air).
    #[arg(long, value_parser = parse_vec3, default_value = "0,0,0", allow_hyphen_values = true)]
    wind: [f64; 3],
    /// Simulate the ground plane z = 0 (default off: free space).
    #[arg(long)]
    ground: bool,
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
    /// (exit code [`EXIT_SOME_FAILED`] = 4).
    SomeFailed(String),
    /// Standard output was closed by the reader (`| head`): stop quietly, exit 0.
    StdoutClosed,
}

impl CliError {
    /// Process exit code.
    pub fn exit_code(&self) -> i32 {
        match self {
            CliError::BadInput(_) => 2,
            CliError::NoPath(_) => 3,
            CliError::Failed(_) => 1,
            CliError::StdoutClosed => 0,
            CliError::SomeFailed(_) => EXIT_SOME_FAILED,
        }
    }
}

impl std::fmt::Display for CliError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CliError::BadInput(m) | CliError::NoPath(m) | CliError::SomeFailed(m) => f.write_str(m),
            CliError::Failed(e) => write!(f, "{e:#}"),
            CliError::StdoutClosed => f.write_str("standard output closed"),
        }
    }
}

impl From<InputError> for CliError {
    fn from(e: InputError) -> Self {
        CliError::BadInput(e.to_string())
    }
}

impl From<anyhow::Error> for CliError {
    fn from(e: anyhow::Error) -> Self {
        CliError::Failed(e)
    }
}

/// Resolve a scene path: as given; for the default scene missing from the
/// current directory, the source tree's copy (this binary's build tree), with a
/// note on stderr naming the file used; refused when that is missing too.
fn resolve_scene(p: &Path) -> Result<PathBuf, CliError> {
    if p.exists() || p != Path::new(DEFAULT_SCENE) {
        return Ok(p.to_path_buf());
    }
    let cwd = std::env::current_dir().map(|d| d.display().to_string()).unwrap_or_else(|_| "?".into());
    let alt = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(DEFAULT_SCENE);
    match alt.canonicalize() {
        Ok(file) if file.is_file() => {
            eprintln!(
                "note: {DEFAULT_SCENE} is not in the current directory ({cwd}); using {} \
                 (pass --scene FILE to choose)",
                file.display()
            );
            Ok(file)
        }
        _ => Err(InputError::option(
            "scene",
            format!(
                "the default scene {DEFAULT_SCENE} is neither in the current directory ({cwd}) nor at {}; \
                 pass --scene FILE",
                alt.display()
            ),
        )
        .into()),
    }
}

fn load_scene(p: &Path) -> Result<Scene, CliError> {
    Scene::load(&resolve_scene(p)?).map_err(|e| CliError::BadInput(e.to_string()))
}

fn plan_scene(scene: &Scene, seed: u64) -> Result<PlannedPath, CliError> {
    plan_scene_with(scene, PlannerParams { seed, ..PlannerParams::default() })
}

fn plan_scene_with(scene: &Scene, params: PlannerParams) -> Result<PlannedPath, CliError> {
    let problem = PlanProblem::from_scene(scene);
    plan(&problem, &params).map_err(|e| plan_error(scene, e))
}

/// A planner error as the CLI reports it (exit 3 for no path, else 2).
fn plan_error(scene: &Scene, e: crate::plan::PlanError) -> CliError {
    let msg = format!("{}: planning failed: {e}", scene.source);
    if e.exit_code() == 3 {
        CliError::NoPath(msg)
    } else {
        CliError::BadInput(msg)
    }
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

pub fn cmd_run(mut a: RunArgs) -> Result<(), CliError> {
    let piloted = a.pilot.load()?;
    if piloted.is_some() {
        // The pilot replaces the mission: nothing to plan.
        a.straight = true;
    }
    let (scene, mut cfg) = run_setup(&a)?;
    setup::check_coverage(&scene, &cfg, &a.perception)?;
    let dir = a.out.clone().unwrap_or_else(|| PathBuf::from("out/run"));
    check_report_dir(&dir, &scene, a.path.as_deref(), a.disturb.disturbances.as_deref())?;
    let mut pilot_run = None;
    let result = if let Some((script, mode)) = &piloted {
        if a.sitl.is_set() {
            return Err(CliError::BadInput("option --pilot/--offboard: not with --gcs/--api".into()));
        }
        let (c, r) = with_progress(cfg.duration, |p| pilot::fly(&scene, cfg.clone(), script, *mode, p))?;
        cfg = c;
        let out = r.out.clone();
        pilot_run = Some(r);
        out
    } else if a.sitl.is_set() {
        let bridge = sitl::bridge(&a.sitl, &dir, false)?;
        let (r, note) =
            with_progress(cfg.duration, |p| sitl::run_inprocess_bridged(&scene, &cfg, bridge, p))?;
        eprintln!("{note}");
        r
    } else {
        with_progress(cfg.duration, |p| run(&scene, &cfg, p))?
    };
    let warnings = write_run_report(&dir, &scene, &cfg, &result, "run")?;
    if let (Some((script, mode)), Some(r)) = (&piloted, &pilot_run) {
        pilot::write_outputs(&dir, script, *mode, r)?;
    }
    for w in warnings {
        eprintln!("warning: {w}");
    }
    out(&format!("{}  report: {}\n", summary_table(&result.summary), dir.display()))
}

pub fn cmd_pil(a: PilArgs) -> Result<(), CliError> {
    use crate::fc::pil::{add_figures_to_summary, build_firmware, PilOptions};
    let (scene, cfg) = run_setup(&a.run)?;
    setup::check_coverage(&scene, &cfg, &a.run.perception)?;
    let timeout = positive("timeout", Some(a.timeout))?.unwrap_or(3.0);
    if timeout > limits::MAX_PIL_TIMEOUT_S {
        return Err(InputError::option("timeout", "longer than the largest firmware timeout")
            .value(num(timeout))
            .allowed(format!("0 < timeout ≤ {} s", limits::MAX_PIL_TIMEOUT_S))
            .into());
    }
    let elf = match &a.firmware {
        Some(p) if !p.is_file() => {
            return Err(CliError::BadInput(format!("option --firmware: {} is not a file", p.display())))
        }
        // QEMU would boot any bytes and die with a register dump (exit 1).
        Some(p) if !crate::fc::pil::is_elf(p) => {
            return Err(CliError::BadInput(format!(
                "option --firmware: {} is not an ELF file (it does not start with 0x7f 'E' 'L' 'F'); \
                 give the `parapet-firmware-qemu` build",
                p.display()
            )))
        }
        Some(p) => p.clone(),
        None => build_firmware()?,
    };
    let mut opts = PilOptions::new(elf);
    opts.timeout = std::time::Duration::from_secs_f64(timeout);
    opts.resend_after = opts.resend_after.min(opts.timeout / 2);
    opts.gcs_control = a.gcs_control;
    let dir = a.run.out.clone().unwrap_or_else(|| PathBuf::from("out/pil"));
    check_report_dir(&dir, &scene, a.run.path.as_deref(), a.run.disturb.disturbances.as_deref())?;
    let bridge = sitl::bridge(&a.run.sitl, &dir, true)?;
    let (result, fig) =
        with_progress(cfg.duration, |p| sitl::run_pil_bridged(&scene, &cfg, opts, bridge.clone(), p))?;
    let sitl_note = sitl::finish(&bridge, &dir)?;
    let warnings = write_run_report(&dir, &scene, &cfg, &result, "pil")?;
    add_figures_to_summary(&dir, &fig)?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    eprintln!("{sitl_note}");
    let ins = &fig.instructions_per_control_step;
    out(&format!(
        "{}  PIL: {} steps, real-time factor {:.3}; frames sent {}, received {}, dropped {}; \
         instructions/step mean {:.0}, max {} (≥ {:.0} µs at 168 MHz)\n  report: {}\n",
        summary_table(&result.summary),
        fig.flight_steps,
        fig.real_time_factor,
        fig.frames_sent,
        fig.frames_received,
        fig.frames_dropped,
        ins.mean,
        ins.max,
        ins.max_time_at_168mhz_us,
        dir.display()
    ))
}

pub fn cmd_plan(a: PlanArgs) -> Result<(), CliError> {
    let scene_file = resolve_scene(&a.scene)?;
    refuse_overwrite("out", std::slice::from_ref(&a.out), &[("scene file", scene_file.as_path())])?;
    if a.out.is_dir() {
        return Err(InputError::option("out", "is a directory, not a file").value(a.out.display()).into());
    }
    if a.out.exists() && !a.force && PathFile::read(&a.out).is_err() {
        return Err(InputError::option("out", "the file exists and is not a parapet path file")
            .value(a.out.display())
            .allowed("a new file, a path file written by parapet, or --force to replace it")
            .into());
    }
    if !(a.time_limit.is_finite() && a.time_limit > 0.0 && a.time_limit <= 3600.0) {
        return Err(InputError::option("time-limit", "planner wall-clock budget out of range")
            .value(num(a.time_limit))
            .allowed("0 < time-limit ≤ 3600 s")
            .into());
    }
    if !(1..=100_000_000).contains(&a.max_iterations) {
        return Err(InputError::option("max-iterations", "planner iteration budget out of range")
            .value(a.max_iterations)
            .allowed("1 ≤ max-iterations ≤ 100000000")
            .into());
    }
    let scene = load_scene(&scene_file)?;
    let params = PlannerParams {
        seed: a.seed,
        time_budget_ms: a.time_limit * 1e3,
        max_iterations: a.max_iterations,
        ..PlannerParams::default()
    };
    // The spatial index of a large scene is built first and timed apart: the
    // planning time is the planner's call on the loaded world.
    let problem = PlanProblem::from_scene(&scene);
    let t_index = std::time::Instant::now();
    let index = crate::plan::index_for(&problem);
    let index_ms = t_index.elapsed().as_secs_f64() * 1e3;
    let planned = plan_with_index(&problem, index.as_ref(), &params).map_err(|e| plan_error(&scene, e))?;
    let file = PathFile::from_planned(&scene.name, &planned);
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| anyhow!("cannot create {}: {e}", dir.display()))?;
    }
    file.write(&a.out).map_err(|e| anyhow!("{e}"))?;
    let index_note = match index {
        Some(_) => format!(" (index build {index_ms:.2} ms apart)"),
        None => String::new(),
    };
    let what = if planned.method == PlanMethod::Grid { "expansions" } else { "iterations" };
    out(&format!(
        "{}: {} waypoints, {:.2} m, {:.2} ms{index_note}, {}, {} {what}, seed {} -> {}\n",
        scene.name,
        planned.waypoints.len(),
        planned.length_m,
        planned.planning_time_ms,
        planned.method.as_str(),
        planned.iterations,
        planned.seed,
        a.out.display()
    ))
}

pub fn cmd_replay(a: ReplayArgs) -> Result<(), CliError> {
    let mut inputs: Vec<(&str, &Path)> = vec![("input CSV", a.inputs.as_path())];
    if let Some(v) = &a.vehicle {
        inputs.push(("vehicle file", v.as_path()));
    }
    refuse_overwrite("out", std::slice::from_ref(&a.out), &inputs)?;
    if !(limits::MIN_DT_S..=limits::MAX_DT_S).contains(&a.dt) {
        return Err(InputError::option("dt", "integration step out of range")
            .value(num(a.dt))
            .allowed(format!("{:e} ≤ dt ≤ {:e} s", limits::MIN_DT_S, limits::MAX_DT_S))
            .into());
    }
    if let Some(k) = a.start.iter().position(|x| x.abs() > limits::MAX_COORDINATE_M) {
        return Err(InputError::option("start", "coordinate out of range")
            .value(num(a.start[k]))
            .allowed(format!("|x| ≤ {} m", limits::MAX_COORDINATE_M))
            .into());
    }
    // The same cap as `run --wind` (a 1e300 m/s wind flew to 1e302 m).
    let max_wind = crate::sim::disturbance::wind::MAX_WIND_MPS;
    if let Some(k) = a.wind.iter().position(|x| x.abs() > max_wind) {
        return Err(InputError::option("wind", "wind component out of range")
            .value(num(a.wind[k]))
            .allowed(format!("|x| ≤ {max_wind} m/s"))
            .into());
    }
    let vehicle = match &a.vehicle {
        Some(p) => load_vehicle(p)?,
        None => VehicleParams::default(),
    };
    if let Some(w) = a.initial_speed.filter(|w| !(0.0..=vehicle.omega_max).contains(w)) {
        return Err(InputError::option("initial-speed", "rotor speed out of the vehicle's range")
            .value(num(w))
            .allowed(format!("0 ≤ initial-speed ≤ omega_max = {} rad/s", num(vehicle.omega_max)))
            .into());
    }
    let src = crate::input::read_text(&a.inputs)?;
    let rows =
        parse_rotor_csv(&src).map_err(|e| CliError::BadInput(format!("{}: {e}", a.inputs.display())))?;
    let opts = ReplayOptions {
        dt: a.dt,
        start_ned: Vector3::new(a.start[0], a.start[1], a.start[2]),
        motor_lag: a.motor_lag,
        ground: a.ground,
        initial_speed: a.initial_speed.map(|w| [w; 4]),
        wind_ned: Vector3::from(a.wind),
    };
    let csv = replay(vehicle, &rows, &opts)
        .map_err(|e| CliError::BadInput(format!("{}: {e}", a.inputs.display())))?;
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| anyhow!("cannot create {}: {e}", dir.display()))?;
    }
    std::fs::write(&a.out, csv).map_err(|e| anyhow!("cannot write {}: {e}", a.out.display()))?;
    out(&format!("replayed {} samples -> {}\n", rows.len(), a.out.display()))
}
