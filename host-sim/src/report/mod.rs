//! Run report: `summary.json`, `trajectory.csv`, plots (SVG and PNG), the 3D replay page
//! `replay.html` ([`replay`]), the flight as MCAP for Foxglove `flight.mcap` ([`foxglove`]) and
//! a short summary table on stdout.
//!
//! Everything written here is in the file/plot frame **ENU** (x east, y
//! north, z up, m; accelerations m/s² in ENU too); attitude angles are the
//! vehicle's true roll/pitch/yaw of FRD relative to NED (rad).
//!
//! `trajectory.csv` columns (one row per outer step, 250 Hz): `t` (s since the
//! mission start); `ref_*` reference (planned) position; `x,y,z` true position;
//! `v*` true velocity; `roll,pitch,yaw`; `region` (none, far, nominal_safe,
//! filtering, fault); `active_obstacle` (the track id of the obstacle the
//! filter acted on — its scene index in scenes of at most 65,535 obstacles, see
//! `crate::sim::track_ids` — or empty);
//! `filter_active` (0/1); `clearance` (m, true, nearest obstacle or ground
//! minus hull radius); `h_bar` (m², true state, min over all obstacles);
//! `u_nom_*` PD output u*; `u_*` filter output; `filter_h_bar` (the
//! controller's own min h̄ from its estimate and the sensed obstacles);
//! `n_constraints`, `unavoidable`, `infeasible` (filter diagnostics); `mode`
//! (controller guidance mode); `wind_x,wind_y,wind_z` the wind at the vehicle (m/s,
//! ENU; 0 in still air, see `crate::sim::disturbance`); `deadlock` (0/1, the controller's
//! stall flag), `obstacles_dropped` and `obstacles_dropped_near` (points the
//! controller's obstacle set dropped at capacity in that step, and of them those with
//! `h ≤ δ1`; `parapet_core::obstacle_set`); `gov_limit` (m/s, the speed governor's limit
//! along the direction of motion, empty without one), `gov_cause` (none, range, obstacle,
//! unseen, data_age) and `gov_active` (0/1, the governor changed u*;
//! `parapet_core::governor`). `summary.json`'s `safety_steps` counts the outer steps with
//! each flag, `governor` the limited time and the limit's minimum and mean.
//!
//! `ranges.csv` (runs with `--perception`): one row per beam of every scan,
//! `t,sensor,beam,range,x,y,z` (see `crate::perception::write_ranges_csv`).
//!
//! `filter_points.csv`: the obstacle points given to the controller, at 10 Hz, `t,id,x,y,z`
//! ([`points`]).
//!
//! Owns the report files and the run's record types ([`Sample`], [`Summary`]).
//! May import: `parapet-core`, [`crate::input`], [`crate::perception`] and
//! [`crate::sim::range`] (range records), [`crate::world`] (the scene
//! drawn in the plots and the replay page), [`crate::decimal`] (the files' number text),
//! plotters, serde, the `mcap` crate ([`foxglove`]).

pub mod foxglove;
pub mod pace;
mod plots;
pub mod points;
pub mod replay;
pub mod speed_limit;
pub mod ulog;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use nalgebra::Vector3;
use parapet_core::cbf::{FilterDiagnostics, Region};
use parapet_core::controller::{FlightMode, GuidanceMode};
use parapet_core::governor::GovernorCause;
use serde::Serialize;

use crate::input::Fixed;
use crate::world::scene::{ned_to_enu_arr, Scene};

/// Controller parameters of a run, as flown.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunParams {
    /// Barrier velocity weight μ, s.
    pub mu: f64,
    /// Safety level δ, m².
    pub delta: f64,
    /// Engagement level δ1, m².
    pub delta1: f64,
    /// PD position gain, 1/s².
    pub kp: f64,
    /// PD velocity gain, 1/s.
    pub kd: f64,
    /// Reference speed along the path, m/s.
    pub speed: f64,
}

impl RunParams {
    /// The flown value of the parameter-table entry with scene/option key `key`
    /// ([`parapet_core::params::Param::key`]), if the run records it.
    pub fn value(&self, key: &str) -> Option<f64> {
        Some(match key {
            "mu" => self.mu,
            "delta" => self.delta,
            "delta1" => self.delta1,
            "kp" => self.kp,
            "kd" => self.kd,
            "speed" => self.speed,
            _ => return None,
        })
    }

    /// The recorded values in parameter-table order with their units, e.g.
    /// `mu 1.4 s, delta 0.05 m^2, …, speed 0.25 m/s`.
    pub fn listed(&self) -> String {
        let items: Vec<String> = parapet_core::params::TABLE
            .iter()
            .filter_map(|p| p.key.and_then(|k| self.value(k).map(|v| format!("{k} {v} {}", p.unit))))
            .collect();
        items.join(", ")
    }
}

/// The machine-readable summary of a run (`summary.json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Scene name.
    pub scene: String,
    /// Scene file.
    pub scene_file: String,
    /// Filter variant name, or `"none"` with `--no-cbf`.
    pub filter: String,
    /// Yaw along the path: `"hold"` or `"travel"` (`MIS_YAW_MODE`).
    pub yaw_mode: String,
    /// Whether the safety filter was on.
    pub cbf_enabled: bool,
    /// The hull sphere intersected an obstacle.
    pub collided: bool,
    /// Time of the first collision, s (null if none).
    pub first_collision_time_s: Option<f64>,
    /// Index (0-based, scene file order) of the obstacle hit first (null if none or the ground).
    pub collision_obstacle: Option<usize>,
    /// What was hit first: `"obstacles[i] (name)"` or `"ground"` (null if nothing).
    pub collision_with: Option<String>,
    /// Minimum over the flight of (distance from the centre of mass to the
    /// nearest obstacle surface or the ground − hull radius), m. Negative = collision.
    pub min_clearance_m: f64,
    /// Minimum over the flight and over all obstacles of the barrier
    /// `h̄ = |d|² + μ dᵀḋ − δ` (m²) on the true state, with the filter's notion of ḋ.
    pub min_h_bar: f64,
    /// Minimum over the flight of the controller's own h̄ (its position/velocity
    /// estimate, the obstacles it was told about), m²; null when it never saw one.
    pub min_filter_h_bar: Option<f64>,
    /// The **scene's** mission goal reached: the path done, the vehicle slow and
    /// within the tolerance of `[mission] goal` (not merely of the path's end).
    pub reached_goal: bool,
    /// Time from mission start to reaching the scene's goal, s (null if not reached).
    pub time_to_goal_s: Option<f64>,
    /// Distance from the vehicle to the scene's mission goal at the end of the run, m.
    pub final_distance_to_goal_m: f64,
    /// The path's last waypoint reached (path done, slow, within the tolerance);
    /// equals `reached_goal` for a path of the scene, differs for a `--foreign-path`.
    pub reached_path_end: bool,
    /// Distance from the vehicle to the path's last waypoint at the end of the run, m.
    pub final_distance_to_path_end_m: f64,
    /// RMS of |actual − reference position| over the flight, m.
    pub tracking_rms_m: f64,
    /// Share of outer-loop steps where the filter changed the nominal input.
    pub filter_active_fraction: f64,
    /// Why the run ended: "goal" (the scene's), "path_end" (the path's end, away
    /// from the scene's goal), "collision", "landed" (a ground station's flight,
    /// `parapet pil --gcs-control`, landed and disarmed without reaching the goal) or "duration".
    pub end_reason: String,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Wall-clock time of the simulation (without planning and report), s.
    pub wall_time_s: f64,
    /// Plant integration steps.
    pub steps: u64,
    /// Planning time, ms (null when the path came from a file or was a straight line).
    pub planning_time_ms: Option<f64>,
    /// Length of the planned path (start → goal), m.
    pub path_length_m: f64,
    /// Where the path came from: "planner", "file" or "straight".
    pub path_source: String,
    /// Number of waypoints of the path.
    pub path_waypoints: usize,
    /// Controller parameters.
    pub params: RunParams,
    /// Parameters set by name (`--param`, `--params`) beyond `params` and the scene's
    /// `[controller]` keys: name → value flown (absent when none was set).
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub params_set: std::collections::BTreeMap<String, f32>,
    /// Failsafe state of the controller at the end of the run (normally "Armed").
    pub final_controller_state: String,
    /// Random seed (sensor noise; planner).
    pub seed: u64,
    /// Whether sensor noise was on.
    pub noise: bool,
    /// Outer steps with each safety flag (unavoidable, infeasible, deadlock, dropped obstacles).
    pub safety_steps: SafetySteps,
    /// Obstacles of the scene with `mapped = false`: in the world (sensed, collided
    /// with) but not in the map the path was planned on.
    pub unmapped_obstacles: usize,
    /// What the range sensors cannot see of the hull's sweep at the mission speed, one sentence
    /// per gap (the pre-flight coverage check, `crate::sim::coverage`); empty with ground truth
    /// or a set that covers it.
    pub coverage_gaps: Vec<String>,
    /// Where the speed governor limited the flight and why: the cause that limited longest and
    /// the fraction of the flight ([`speed_limit::SpeedLimitedBy`]; null when it never acted).
    pub speed_limited_by: Option<speed_limit::SpeedLimitedBy>,
    /// A mission trajectory's pace: time to goal against the time-optimal time for the same
    /// path and limits, the generator's own time, and what slowed the flight
    /// ([`pace::Pace`]; null without a mission trajectory).
    pub pace: Option<pace::Pace>,
    /// On-board replanning (issue 38): `replans`, `replan_no_path`, … at the top level.
    #[serde(flatten)]
    pub replan: ReplanSummary,
}

/// What the on-board replanner did in a run (`summary.json`; `parapet_core::replan`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ReplanSummary {
    /// Replanning was on (`RPL_ENABLE`; stacks without an on-board replanner: false).
    pub replan_enabled: bool,
    /// Plans run (checks due and out of cooldown).
    pub replan_checks: u32,
    /// New paths flown.
    pub replans: u32,
    /// Plans that found no path (the vehicle kept its path; the filter holds it).
    pub replan_no_path: u32,
    /// Plans that hit the search's cap or a capacity (handled as no path).
    pub replan_budget: u32,
    /// Every plan that was not `NotNeeded`, in order.
    pub replan_events: Vec<ReplanEvent>,
}

/// One replanning event.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReplanEvent {
    /// Simulated time, s.
    pub t_s: f64,
    /// "replanned", "no_path" or "budget".
    pub outcome: &'static str,
    /// Waypoints of the new path (0 unless replanned).
    pub waypoints: usize,
    /// Detour waypoints before the rejoined mission (0 unless replanned).
    pub detour: usize,
}

/// Safety flags of one outer step beyond the filter's own (issue 17).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SafetyFlags {
    /// The controller's stall detector reports a deadlock.
    pub deadlock: bool,
    /// Obstacle points dropped by the controller's set at capacity.
    pub obstacles_dropped: u16,
    /// Of those, points whose barrier had `h ≤ δ1` (the filter would have considered them).
    pub obstacles_dropped_near: u16,
    /// The speed governor's limit along the direction of motion, m/s (`None`: no limit: off,
    /// at rest, or a PIL flight, whose link does not carry it).
    pub governor_limit: Option<f32>,
    /// What sets it (`parapet_core::governor::GovernorCause`).
    #[serde(serialize_with = "cause_name")]
    pub governor_cause: GovernorCause,
    /// The governor changed the nominal command in that step.
    pub governor_active: bool,
}

/// A governor cause's name in reports.
pub fn governor_cause_name(c: GovernorCause) -> &'static str {
    match c {
        GovernorCause::None => "none",
        GovernorCause::Range => "range",
        GovernorCause::Obstacle => "obstacle",
        GovernorCause::Unseen => "unseen",
        GovernorCause::DataAge => "data_age",
    }
}

fn cause_name<S: serde::Serializer>(c: &GovernorCause, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(governor_cause_name(*c))
}

/// Outer steps of a run with each safety flag (`summary.json`, `safety_steps`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SafetySteps {
    /// Outer steps flown.
    pub outer: u64,
    /// Steps where the filter changed the nominal input.
    pub filter_active: u64,
    /// Steps with the `unavoidable` flag (a constraint needs more than u_max).
    pub unavoidable: u64,
    /// Steps with the `infeasible` flag (the enforced constraints had no common solution).
    pub infeasible: u64,
    /// Steps with the `deadlock` flag.
    pub deadlock: u64,
    /// Steps where the obstacle set dropped at least one point.
    pub obstacles_dropped: u64,
    /// Steps where it dropped at least one point with `h ≤ δ1`.
    pub obstacles_dropped_near: u64,
    /// Most points dropped in one step.
    pub max_obstacles_dropped: u16,
    /// Time of the first `unavoidable` step, s (null if none).
    pub first_unavoidable_time_s: Option<f64>,
    /// Time of the first `deadlock` step, s (null if none).
    pub first_deadlock_time_s: Option<f64>,
    /// Steps where the speed governor changed the nominal command.
    pub governor_active: u64,
    /// Time those steps cover, s (the samples' spacing summed).
    pub governor_limited_s: f64,
    /// Smallest speed limit along the motion the governor reported, m/s (null: none).
    pub governor_min_limit: Option<f64>,
    /// Mean over the steps with a limit, m/s (null: none).
    pub governor_mean_limit: Option<f64>,
}

impl SafetySteps {
    /// The counts over `samples`.
    pub fn of(samples: &[Sample]) -> Self {
        let mut c = SafetySteps::default();
        let (mut sum, mut n, mut prev_t) = (0.0, 0u64, None::<f64>);
        for k in samples {
            if k.safety.governor_active {
                c.governor_active += 1;
                c.governor_limited_s += prev_t.map_or(0.0, |t0| (k.t - t0).max(0.0));
            }
            prev_t = Some(k.t);
            if let Some(l) = k.safety.governor_limit {
                let l = f64::from(l);
                c.governor_min_limit = Some(c.governor_min_limit.map_or(l, |m: f64| m.min(l)));
                sum += l;
                n += 1;
            }
            c.outer += 1;
            c.filter_active += u64::from(k.filter.intervened);
            c.unavoidable += u64::from(k.filter.unavoidable);
            c.infeasible += u64::from(k.filter.infeasible);
            c.deadlock += u64::from(k.safety.deadlock);
            c.obstacles_dropped += u64::from(k.safety.obstacles_dropped > 0);
            c.obstacles_dropped_near += u64::from(k.safety.obstacles_dropped_near > 0);
            c.max_obstacles_dropped = c.max_obstacles_dropped.max(k.safety.obstacles_dropped);
            if k.filter.unavoidable && c.first_unavoidable_time_s.is_none() {
                c.first_unavoidable_time_s = Some(k.t);
            }
            if k.safety.deadlock && c.first_deadlock_time_s.is_none() {
                c.first_deadlock_time_s = Some(k.t);
            }
        }
        c.governor_mean_limit = (n > 0).then(|| sum / n as f64);
        c
    }
}

/// One recorded sample (outer-loop rate). Vectors NED.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Time since mission start, s.
    pub t: f64,
    /// Reference position, NED, m.
    pub ref_pos: Vector3<f64>,
    /// True position, NED, m.
    pub pos: Vector3<f64>,
    /// True velocity, NED, m/s.
    pub vel: Vector3<f64>,
    /// Roll, pitch, yaw (FRD w.r.t. NED), rad.
    pub rpy: [f64; 3],
    /// The safety filter's diagnostics of the step (region, active obstacle, intervened,
    /// the controller's own min h̄ from its estimate and the sensed obstacles, constraints
    /// enforced, unavoidable / infeasible flags): the core's one type.
    pub filter: FilterDiagnostics,
    /// True clearance (distance to nearest surface − hull radius), m.
    pub clearance: f64,
    /// Clearance of the reference position, m.
    pub ref_clearance: f64,
    /// Min h̄ over all obstacles on the true state, m².
    pub h_bar: f64,
    /// Nominal acceleration u* (PD), NED, m/s².
    pub u_nominal: Vector3<f64>,
    /// Filtered acceleration u, NED, m/s².
    pub u_filtered: Vector3<f64>,
    /// Controller guidance mode.
    pub mode: GuidanceMode,
    /// Flight mode selected (the ULog's `nav_state` with `mode`).
    pub flight_mode: FlightMode,
    /// Wind at the vehicle, NED, m/s.
    pub wind: Vector3<f64>,
    /// Deadlock and obstacle-set flags.
    pub safety: SafetyFlags,
    /// Motor throttles (0..1, rotors 1-4) commanded in the last inner step before the sample.
    pub motors: [f32; 4],
}

/// Everything the report needs.
pub struct RunRecord<'a> {
    /// The scene flown.
    pub scene: &'a Scene,
    /// Planned path, NED, start first.
    pub path: &'a [Vector3<f64>],
    /// Flown samples.
    pub samples: &'a [Sample],
    /// The summary.
    pub summary: &'a Summary,
    /// Range-sensor beams (`--perception`; empty for ground truth): written to
    /// `ranges.csv` and drawn on the top view.
    pub ranges: &'a crate::perception::RangeLog,
    /// The range sensors (names for `ranges.csv`).
    pub range_sensors: &'a [crate::sim::range::RangeSensor],
    /// The obstacle points given to the controller, logged at 10 Hz ([`points`]):
    /// `filter_points.csv` and the replay page.
    pub filter_points: &'a points::FilterPointLog,
    /// The controller clock: a sample's time (s) → the logs' timestamps (µs), as for the ULog
    /// (`crate::flight::stack::clock_us`); `flight.mcap`'s log times are these in ns.
    pub clock_us: fn(f64) -> u64,
}

/// Plots of the report: each is written as `<name>.svg` and `<name>.png`.
pub const PLOTS: [&str; 4] = ["top_view", "clearance", "speed", "filter_activity"];

/// The range-sensor beams of a `--perception` run (`crate::perception::write_ranges_csv`).
pub const RANGES_CSV: &str = "ranges.csv";

/// Every file [`write_report`] may write into its directory (so the CLI can
/// refuse an output directory where one of them is an input).
pub fn report_files(dir: &Path) -> Vec<PathBuf> {
    let mut v = vec![
        dir.join("summary.json"),
        dir.join("trajectory.csv"),
        dir.join(ulog::FLIGHT_LOG),
        dir.join(RANGES_CSV),
        dir.join(points::FILTER_POINTS_CSV),
        dir.join(replay::REPLAY_HTML),
        dir.join(foxglove::FLIGHT_MCAP),
    ];
    for name in PLOTS {
        v.push(dir.join(format!("{name}.svg")));
        v.push(dir.join(format!("{name}.png")));
    }
    v
}

/// Write `summary.json`, `trajectory.csv`, `filter_points.csv`, `replay.html`, `flight.mcap` and the plots into `dir` (created if
/// needed). Returns the files written; a plot that fails (e.g. no usable font)
/// is reported in the returned warnings instead of failing the run.
pub fn write_report(dir: &Path, rec: &RunRecord) -> Result<(Vec<PathBuf>, Vec<String>)> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut files = Vec::new();
    let summary_path = dir.join("summary.json");
    let json = serde_json::to_string_pretty(rec.summary)? + "\n";
    std::fs::write(&summary_path, json)
        .with_context(|| format!("cannot write {}", summary_path.display()))?;
    files.push(summary_path);
    let csv_path = dir.join("trajectory.csv");
    // Streamed row by row: no second copy of the flight in memory.
    std::fs::File::create(&csv_path)
        .map(std::io::BufWriter::new)
        .and_then(|mut w| {
            write_trajectory_csv(&mut w, rec.samples)?;
            std::io::Write::flush(&mut w)
        })
        .with_context(|| format!("cannot write {}", csv_path.display()))?;
    files.push(csv_path);
    if !rec.ranges.is_empty() {
        let path = dir.join(RANGES_CSV);
        std::fs::File::create(&path)
            .map(std::io::BufWriter::new)
            .and_then(|mut w| {
                crate::perception::write_ranges_csv(&mut w, rec.range_sensors, rec.ranges)?;
                std::io::Write::flush(&mut w)
            })
            .with_context(|| format!("cannot write {}", path.display()))?;
        files.push(path);
    }
    let path = dir.join(points::FILTER_POINTS_CSV);
    std::fs::File::create(&path)
        .map(std::io::BufWriter::new)
        .and_then(|mut w| {
            points::write_filter_points_csv(&mut w, rec.filter_points)?;
            std::io::Write::flush(&mut w)
        })
        .with_context(|| format!("cannot write {}", path.display()))?;
    files.push(path);
    let page_path = dir.join(replay::REPLAY_HTML);
    replay::write_replay(&page_path, rec).with_context(|| format!("cannot write {}", page_path.display()))?;
    files.push(page_path);
    let mcap_path = dir.join(foxglove::FLIGHT_MCAP);
    // Its errors name the file.
    foxglove::write_flight_mcap(&mcap_path, rec, rec.clock_us)?;
    files.push(mcap_path);
    let mut warnings = Vec::new();
    for name in PLOTS {
        match plots::plot_both(dir, name, rec) {
            Ok(mut v) => files.append(&mut v),
            Err(e) => warnings.push(format!("plot {name}: {e:#}")),
        }
    }
    Ok((files, warnings))
}

/// The trajectory CSV text (ENU).
pub fn trajectory_csv(samples: &[Sample]) -> String {
    let mut v = Vec::new();
    // Writing into a Vec cannot fail; the text is ASCII.
    let _ = write_trajectory_csv(&mut v, samples);
    String::from_utf8_lossy(&v).into_owned()
}

/// One row of `trajectory.csv` (columns in the module docs; ENU).
#[derive(Serialize)]
struct TrajectoryRow {
    t: Fixed<4>,
    ref_x: Fixed<4>,
    ref_y: Fixed<4>,
    ref_z: Fixed<4>,
    x: Fixed<4>,
    y: Fixed<4>,
    z: Fixed<4>,
    vx: Fixed<4>,
    vy: Fixed<4>,
    vz: Fixed<4>,
    roll: Fixed<5>,
    pitch: Fixed<5>,
    yaw: Fixed<5>,
    region: &'static str,
    active_obstacle: Option<u16>,
    filter_active: u8,
    clearance: Fixed<4>,
    h_bar: Fixed<5>,
    u_nom_x: Fixed<4>,
    u_nom_y: Fixed<4>,
    u_nom_z: Fixed<4>,
    u_x: Fixed<4>,
    u_y: Fixed<4>,
    u_z: Fixed<4>,
    filter_h_bar: Fixed<5>,
    n_constraints: u8,
    unavoidable: u8,
    infeasible: u8,
    mode: &'static str,
    wind_x: Fixed<4>,
    wind_y: Fixed<4>,
    wind_z: Fixed<4>,
    deadlock: u8,
    obstacles_dropped: u16,
    obstacles_dropped_near: u16,
    gov_limit: Option<Fixed<3>>,
    gov_cause: &'static str,
    gov_active: u8,
}

impl TrajectoryRow {
    fn of(k: &Sample) -> Self {
        let [ref_x, ref_y, ref_z] = ned_to_enu_arr(&k.ref_pos).map(Fixed);
        let [x, y, z] = ned_to_enu_arr(&k.pos).map(Fixed);
        let [vx, vy, vz] = ned_to_enu_arr(&k.vel).map(Fixed);
        let [roll, pitch, yaw] = k.rpy.map(Fixed);
        let [u_nom_x, u_nom_y, u_nom_z] = ned_to_enu_arr(&k.u_nominal).map(Fixed);
        let [u_x, u_y, u_z] = ned_to_enu_arr(&k.u_filtered).map(Fixed);
        let [wind_x, wind_y, wind_z] = ned_to_enu_arr(&k.wind).map(Fixed);
        let f = &k.filter;
        TrajectoryRow {
            t: Fixed(k.t),
            ref_x,
            ref_y,
            ref_z,
            x,
            y,
            z,
            vx,
            vy,
            vz,
            roll,
            pitch,
            yaw,
            region: region_name(f.region),
            active_obstacle: f.active_id,
            filter_active: u8::from(f.intervened),
            clearance: Fixed(k.clearance),
            h_bar: Fixed(k.h_bar),
            u_nom_x,
            u_nom_y,
            u_nom_z,
            u_x,
            u_y,
            u_z,
            filter_h_bar: Fixed(f64::from(f.h_bar)),
            n_constraints: f.n_constraints,
            unavoidable: u8::from(f.unavoidable),
            infeasible: u8::from(f.infeasible),
            mode: k.mode.as_str(),
            wind_x,
            wind_y,
            wind_z,
            deadlock: u8::from(k.safety.deadlock),
            obstacles_dropped: k.safety.obstacles_dropped,
            obstacles_dropped_near: k.safety.obstacles_dropped_near,
            gov_limit: k.safety.governor_limit.map(|v| Fixed(f64::from(v))),
            gov_cause: governor_cause_name(k.safety.governor_cause),
            gov_active: u8::from(k.safety.governor_active),
        }
    }
}

/// Write the trajectory CSV (ENU) to `w`, one row at a time (csv crate, serde records).
pub fn write_trajectory_csv(w: &mut dyn std::io::Write, samples: &[Sample]) -> std::io::Result<()> {
    let mut out = csv::Writer::from_writer(w);
    for k in samples {
        out.serialize(TrajectoryRow::of(k)).map_err(std::io::Error::other)?;
    }
    if samples.is_empty() {
        // The header of an empty file (serde writes it with the first record).
        out.write_record(TRAJECTORY_COLUMNS).map_err(std::io::Error::other)?;
    }
    out.flush()
}

/// Column names of `trajectory.csv`.
pub const TRAJECTORY_COLUMNS: [&str; 38] = [
    "t",
    "ref_x",
    "ref_y",
    "ref_z",
    "x",
    "y",
    "z",
    "vx",
    "vy",
    "vz",
    "roll",
    "pitch",
    "yaw",
    "region",
    "active_obstacle",
    "filter_active",
    "clearance",
    "h_bar",
    "u_nom_x",
    "u_nom_y",
    "u_nom_z",
    "u_x",
    "u_y",
    "u_z",
    "filter_h_bar",
    "n_constraints",
    "unavoidable",
    "infeasible",
    "mode",
    "wind_x",
    "wind_y",
    "wind_z",
    "deadlock",
    "obstacles_dropped",
    "obstacles_dropped_near",
    "gov_limit",
    "gov_cause",
    "gov_active",
];

/// Region name for reports and `trajectory.csv` (the core's [`Region::name`]).
pub fn region_name(r: Region) -> &'static str {
    r.name()
}

/// Path sources of runs without a mission (a pilot's sticks, a companion's setpoints): their
/// summary table has no path, goal or path-end rows ([`summary_table`]); `summary.json` keeps
/// the fields (the goal's distance is still the scene's).
pub const NO_MISSION_SOURCES: [&str; 2] = ["pilot", "offboard"];

/// The short summary table printed after a run.
pub fn summary_table(s: &Summary) -> String {
    let opt = |x: Option<f64>, unit: &str| x.map(|v| format!("{v:.2} {unit}")).unwrap_or_else(|| "-".into());
    let mission = !NO_MISSION_SOURCES.contains(&s.path_source.as_str());
    let mut rows: Vec<(&str, String)> = vec![
        ("scene", format!("{} ({})", s.scene, s.scene_file)),
        ("filter", s.filter.clone()),
        ("yaw mode", s.yaw_mode.clone()),
        ("params", s.params.listed()),
        ("mission", String::new()),
        ("end", s.end_reason.clone()),
        (
            "collided",
            format!(
                "{} (t = {}{})",
                s.collided,
                opt(s.first_collision_time_s, "s"),
                s.collision_with.as_ref().map(|w| format!(", {w}")).unwrap_or_default()
            ),
        ),
        ("min clearance", format!("{:.3} m", s.min_clearance_m)),
        ("min h_bar", format!("{:.4} m²", s.min_h_bar)),
        ("tracking RMS", format!("{:.3} m", s.tracking_rms_m)),
        ("filter active", format!("{:.1} % of outer steps", 100.0 * s.filter_active_fraction)),
        (
            "safety flags",
            format!(
                "steps unavoidable {}, infeasible {}, deadlock {}, obstacles dropped {} (near {})",
                s.safety_steps.unavoidable,
                s.safety_steps.infeasible,
                s.safety_steps.deadlock,
                s.safety_steps.obstacles_dropped,
                s.safety_steps.obstacles_dropped_near
            ),
        ),
        ("simulated", {
            // The flight loop's speed, as docs/perception.md § Cost states it.
            let factor = if s.wall_time_s > 0.0 {
                format!(" ({:.0}× real time)", s.sim_time_s / s.wall_time_s)
            } else {
                String::new()
            };
            format!("{:.2} s in {:.3} s wall{factor}, {} steps", s.sim_time_s, s.wall_time_s, s.steps)
        }),
    ];
    // A mission's path, goal and path end (the path row before the end, as always); a piloted or
    // offboard run flew none.
    let at = rows.iter().position(|r| r.0 == "mission").unwrap_or(rows.len());
    let mission_rows: Vec<(&str, String)> = if mission {
        vec![
            (
                "path",
                format!(
                    "{} : {} waypoints, {:.2} m, planning {}",
                    s.path_source,
                    s.path_waypoints,
                    s.path_length_m,
                    opt(s.planning_time_ms, "ms")
                ),
            ),
            (
                "reached goal",
                format!(
                    "{} (t = {}; scene goal, final distance {:.3} m)",
                    s.reached_goal,
                    opt(s.time_to_goal_s, "s"),
                    s.final_distance_to_goal_m
                ),
            ),
            (
                "path end",
                format!(
                    "{} (last waypoint, final distance {:.3} m)",
                    if s.reached_path_end { "reached" } else { "not reached" },
                    s.final_distance_to_path_end_m
                ),
            ),
        ]
    } else {
        vec![("mission", format!("none ({} flight: no path, goal or path end)", s.path_source))]
    };
    rows.splice(at..(at + 1).min(rows.len()), mission_rows);
    if !s.params_set.is_empty() {
        let set: Vec<String> = s.params_set.iter().map(|(k, v)| format!("{k} {v}")).collect();
        let at = rows.iter().position(|r| r.0 == "params").map_or(0, |i| i + 1);
        rows.insert(at, ("params set", set.join(", ")));
    }
    let w = rows.iter().map(|r| r.0.len()).max().unwrap_or(0);
    let mut out = String::new();
    for (k, v) in rows {
        let _ = writeln!(out, "  {k:<w$}  {v}");
    }
    out
}

pub(crate) fn e<E: std::fmt::Display>(err: E) -> anyhow::Error {
    anyhow!("{err}")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every recorded run parameter is a parameter-table key, listed with its unit.
    #[test]
    fn run_parameters_come_from_the_table() {
        let p = RunParams { mu: 1.4, delta: 0.05, delta1: 0.1, kp: 0.5, kd: 0.8, speed: 0.25 };
        let json = serde_json::to_value(&p).unwrap();
        let fields = json.as_object().unwrap();
        for (k, v) in fields {
            let entry = parapet_core::params::by_key(k).unwrap_or_else(|| panic!("{k} not in the table"));
            assert_eq!(p.value(k), v.as_f64(), "{k}");
            assert!(p.listed().contains(&format!("{k} {} {}", v, entry.unit)), "{}", p.listed());
        }
        assert_eq!(
            p.listed(),
            "mu 1.4 s, delta 0.05 m^2, delta1 0.1 m^2, kp 0.5 1/s^2, kd 0.8 1/s, speed 0.25 m/s"
        );
    }
}
