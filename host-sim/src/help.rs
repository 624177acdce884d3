//! The long help texts of the `parapet` command line (`after_help` of the top
//! level and of `run`, `pil`, `plan`, `replay`): built-in defaults, limits,
//! examples and exit codes. Every number comes from the constant that the code
//! enforces ([`crate::input::limits`], the core's defaults), never retyped.
//!
//! May import: `cli` (exit codes), `input`, `validate`, `runner`.

use crate::cli::{DEFAULT_SCENE, EXIT_CODES_HELP};
use crate::input::limits as l;

/// Limits that apply to every flight (`run`, `pil`, and the runs of `sweep`).
pub fn flight_limits() -> String {
    format!(
        "\
Limits (refused with exit 2, naming the option or file, table and field):
  duration ≤ {dur} s (--duration, [sim] duration, or the default; --max-duration raises the cap up to {ceil} s)
  [sim] dt in [{mindt:e}, {maxdt:e}] s; duration / dt ≤ {steps:e} plant steps
  speed in (0, {speed}] m/s; coordinates (bounds, mission, obstacles, path waypoints) |x| ≤ {coord:e} m
  [sensors] position_latency ≤ {lat} s (the controller's position timeout is {timeout} s); noise ≤ {noise}
  a path has at most {wps} waypoints; the controller is told about the nearest {obs} obstacles at once;
  the multi filters enforce at most {bars} barriers at once; the planner's search budget is {budget} s
  input files ≤ {bytes} bytes",
        dur = l::MAX_DURATION_S,
        ceil = l::MAX_DURATION_CEILING_S,
        mindt = l::MIN_DT_S,
        maxdt = l::MAX_DT_S,
        steps = l::MAX_PLANT_STEPS,
        speed = l::MAX_SPEED_MPS,
        coord = l::MAX_COORDINATE_M,
        lat = l::MAX_POSITION_LATENCY_S,
        timeout = crate::input::num(l::position_timeout_s()),
        noise = l::MAX_SENSOR_NOISE,
        wps = l::MAX_WAYPOINTS,
        obs = l::MAX_OBSTACLES_SENSED,
        bars = l::MAX_BARRIERS,
        budget = l::PLANNER_BUDGET_S,
        bytes = l::MAX_INPUT_FILE_BYTES,
    )
}

/// `parapet --help`.
pub fn top() -> String {
    format!(
        "\
The default scene is ./{DEFAULT_SCENE}; without it, the source tree's copy is used and a note names it.
Every subcommand's --help lists its defaults, limits and examples.

Examples:
  parapet run                                   # fly the office scene, report in out/run/
  parapet run --scene scenes/one_sphere.toml --straight --filter paper --mu 1.0
  parapet plan --scene scenes/office.toml --out out/path.json
  parapet run --scene scenes/office.toml --path out/path.json --out out/from_file
  parapet replay --inputs rotors.csv --out states.csv --start 0,0,-1

{EXIT_CODES_HELP}
  {some}    sweep, sweep-merge: some runs failed (their rows say why; see their --help)",
        some = crate::sweep::EXIT_SOME_FAILED
    )
}

/// `parapet run --help`.
pub fn run() -> String {
    format!(
        "\
{defaults}
  speed: the scene's [controller] speed, else its [mission] speed; sensing range {range} m;
  duration: [sim] duration, else the default from the flown length and the speed (see --duration)

{limits}

Examples:
  parapet run
  parapet run --scene scenes/one_sphere.toml --straight --no-noise --duration 30 --out out/sphere
  parapet run --scene scenes/office.toml --path scenes/office_path.json --filter multi --kp 0.6
  parapet run --scene scenes/outdoor_static.toml --speed 1.5 --max-duration 7200 --duration 5000

{EXIT_CODES_HELP}",
        defaults = crate::validate::defaults_help(),
        range = crate::runner::DEFAULT_SENSING_RANGE,
        limits = flight_limits(),
    )
}

/// `parapet pil --help`.
pub fn pil() -> String {
    format!(
        "\
{defaults}

{limits}

--timeout ≤ {timeout} s.

Examples:
  parapet pil --scene scenes/one_sphere.toml --straight --duration 10
  parapet pil --firmware target/thumbv7em-none-eabihf/release/parapet-firmware-qemu --out out/pil

{EXIT_CODES_HELP}",
        defaults = crate::validate::defaults_help(),
        limits = flight_limits(),
        timeout = l::MAX_PIL_TIMEOUT_S,
    )
}

/// `parapet plan --help`.
pub fn plan() -> String {
    format!(
        "\
Limits: the tree search stops after --time-limit (default {budget} s, wall clock, at most 3600 s) or
  --max-iterations (then exit 3);
  a path has at most {wps} waypoints; coordinates |x| ≤ {coord:e} m.
--out never replaces the scene file, nor an existing file that is not a parapet path file
  (unless --force).

Examples:
  parapet plan
  parapet plan --scene scenes/narrow_passage.toml --seed 3 --out out/narrow.json

{EXIT_CODES_HELP}",
        budget = l::PLANNER_BUDGET_S,
        wps = l::MAX_WAYPOINTS,
        coord = l::MAX_COORDINATE_M,
    )
}

/// `parapet replay --help`.
pub fn replay() -> String {
    format!(
        "\
Limits: at most {rows} data rows spanning at most {span} s (last t − first t); --dt in [{mindt:e}, {maxdt:e}] s;
  at most {steps:e} integration steps; input files ≤ {bytes} bytes. --out never replaces an input.

Examples:
  parapet replay --inputs rotors.csv --out states.csv
  parapet replay --vehicle scenes/office.toml --inputs rotors.csv --out states.csv --start 1,2,-1.5 --motor-lag

{EXIT_CODES_HELP}",
        rows = l::MAX_REPLAY_ROWS,
        span = l::MAX_REPLAY_SPAN_S,
        mindt = l::MIN_DT_S,
        maxdt = l::MAX_DT_S,
        steps = l::MAX_PLANT_STEPS,
        bytes = l::MAX_INPUT_FILE_BYTES,
    )
}
