//! The long help texts of the `parapet` command line (`after_help` of the top
//! level and of `run`, `pil`, `plan`, `replay`, `campaign`, `campaign-merge`, `scene generate`): built-in defaults, limits,
//! examples and exit codes. Every number comes from the constant that the code
//! enforces ([`crate::input::limits`], the core's defaults), never retyped.
//!
//! May import: `cli` (exit codes), `input`, `flight::{validate, runner}`.

use crate::cli::{DEFAULT_SCENE, EXIT_CODES_HELP};
use crate::input::limits as l;

/// The ranges of the controller settings a scene or an option may give: every
/// parameter-table entry with a key (`parapet_core::params::TABLE`), codes excluded.
fn controller_ranges() -> String {
    let ranges: Vec<String> = parapet_core::params::TABLE
        .iter()
        .filter(|p| p.key.is_some() && !p.integer)
        .map(|p| p.range().to_string())
        .collect();
    ranges.join(", ")
}

/// Limits that apply to every flight (`run`, `pil`, and the runs of `sweep`).
pub fn flight_limits() -> String {
    format!(
        "\
Limits (refused with exit 2, naming the option or file, table and field):
  duration ≤ {dur} s (--duration, [sim] duration, or the default; --max-duration raises the cap up to {ceil} s)
  [sim] dt in [{mindt:e}, {maxdt:e}] s; duration / dt ≤ {steps:e} plant steps
  controller settings (scene [controller], options): {ranges}
  coordinates (bounds, mission, obstacles, path waypoints) |x| ≤ {coord:e} m
  [sensors] position_latency ≤ {lat} s (the controller's position timeout is {timeout} s); noise ≤ {noise}
  a path has at most {wps} waypoints (the controller is given 64 at a time as it flies); the sensor reports up to {rep} obstacles in range at once (the
  nearest beyond that) and the controller keeps the most critical {obs} obstacles;
  the multi filters enforce at most {bars} barriers at once; the planner's search budget is {budget} s
  input files ≤ {bytes} bytes",
        dur = l::MAX_DURATION_S,
        ceil = l::MAX_DURATION_CEILING_S,
        mindt = l::MIN_DT_S,
        maxdt = l::MAX_DT_S,
        steps = l::MAX_PLANT_STEPS,
        ranges = controller_ranges(),
        coord = l::MAX_COORDINATE_M,
        lat = l::MAX_POSITION_LATENCY_S,
        timeout = crate::input::num(l::position_timeout_s()),
        noise = l::MAX_SENSOR_NOISE,
        wps = l::MAX_WAYPOINTS,
        obs = l::MAX_OBSTACLES_SENSED,
        rep = l::MAX_OBSTACLES_REPORTED,
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
  {some}    sweep, sweep-merge, campaign: some runs failed (their rows say why; see their --help)",
        some = crate::cli::EXIT_SOME_FAILED
    )
}

/// `parapet run --help`.
pub fn run() -> String {
    format!(
        "\
{defaults}
  speed: the scene's [controller] speed, else its [mission] speed; sensing range {range} m;
  yaw_mode: --yaw-mode, else the scene's, else travel when every --perception sensor looks
    forward only (camera), else hold;
  duration: [sim] duration, else the default from the flown length and the speed (see --duration)

{limits}

Examples:
  parapet run
  parapet run --scene scenes/one_sphere.toml --straight --no-noise --duration 30 --out out/sphere
  parapet run --scene scenes/office.toml --path scenes/office_path.json --filter multi --kp 0.6
  parapet run --scene scenes/outdoor_static.toml --speed 1.5 --max-duration 7200 --duration 5000

{EXIT_CODES_HELP}",
        defaults = crate::flight::validate::defaults_help(),
        range = crate::flight::runner::DEFAULT_SENSING_RANGE,
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
        defaults = crate::flight::validate::defaults_help(),
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

/// `parapet campaign --help`.
pub fn campaign() -> String {
    format!(
        "\
Limits: 1 ≤ flights ≤ {flights} per campaign file; every flight is checked like `parapet run`
  (its limits apply; a flight whose drawn values are refused is a row with end_reason error);
  --jobs ≤ 256; --shard I/N with 1 ≤ I ≤ N ≤ 100000. --out never replaces an input.
  The file format (distributions fixed | uniform | normal | log_uniform per quantity) is in
  docs/robustness.md; examples in scenes/campaigns/.

Examples:
  parapet campaign scenes/campaigns/ci.toml --out out/campaign
  parapet campaign scenes/campaigns/robustness.toml --jobs 2
  parapet campaign scenes/campaigns/ci.toml --shard 2/4 --out out/shard2   # then campaign-merge
  parapet campaign scenes/campaigns/navigation.toml --shard 6581/10000      # flight 6580 alone (N = flights)

{codes}",
        flights = l::CAMPAIGN_MAX_FLIGHTS,
        codes = crate::cli::exit_codes_help(
            "campaign: some flights could not be flown (end_reason error in campaign.csv); the others are kept"
        ),
    )
}

/// `parapet campaign-merge --help`.
pub fn campaign_merge() -> String {
    format!(
        "\
Refuses (exit 2) shards of another campaign (file, seed, flights), a shard given twice and
  missing shards, naming them. The merged outputs are byte-identical to one process's.

Examples:
  parapet campaign-merge --campaign scenes/campaigns/ci.toml out/shard1 out/shard2 out/shard3 out/shard4 --out out/merged

{EXIT_CODES_HELP}"
    )
}

/// `parapet scene generate --help`.
pub fn scene_generate() -> String {
    format!(
        "\
Limits: 1 ≤ --obstacles ≤ 1,000,000; the mission must fit the scene (--mission-length at most
  80 % of its side); the planner must connect start and goal through every obstacle (mapped or
  not), else no file is written. 0 ≤ --unmapped ≤ 1: that share of the obstacles gets
  `mapped = false` (the sensors and collisions see them, the planner does not); the seed picks
  them, the world and mission are those of --unmapped 0.
  --out never replaces an existing file unless --force.

Examples:
  parapet scene generate --kind forest --obstacles 10000 --density 0.05 --seed 1 --out out/forest.toml
  parapet scene generate --kind city --street 8 --out out/city.toml
  parapet scene generate --kind forest --obstacles 2000 --unmapped 0.3 --out out/forest_unmapped.toml
  parapet run --scene out/forest.toml --out out/forest_run

{EXIT_CODES_HELP}"
    )
}
