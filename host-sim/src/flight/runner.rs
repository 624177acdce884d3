//! Closed-loop runner: plant (1 kHz RK4) → sensors → the flight controller of
//! `parapet-core` (inner loop 1 kHz, outer loop 250 Hz) → motor commands → plant.
//!
//! ## Sequence
//! The vehicle starts hovering at the mission start (level, heading north,
//! rotors at the hover speed), the controller is armed, given the path and its
//! mission is started at t = 0. The run stops at the first of:
//! * **collision**: the hull sphere intersects an obstacle (signed distance
//!   from the centre of mass to a surface < hull radius), checked every plant step;
//! * **path end**: the path is done, the vehicle within [`GOAL_TOLERANCE_M`] of
//!   the path's last waypoint and slower than [`GOAL_SPEED_MPS`]. The goal is
//!   **reached** (`reached_goal`, end reason `goal`) when the vehicle is then
//!   also within [`GOAL_TOLERANCE_M`] of the **scene's** mission goal (or the
//!   path ends there up to [`PATH_END_ROUNDOFF_M`]); a path
//!   ending elsewhere (`--foreign-path`) ends with `reached_path_end` only
//!   (end reason `path_end`);
//! * the **duration** limit (default [`default_duration`]: 1.5 × the flown
//!   length start → first waypoint → … → last at the reference speed, at most 1 m/s, + 15 s;
//!   under the default a run still making progress along the path goes on until
//!   [`STALL_WINDOW_S`] after its last progress, at most [`EXTEND_FACTOR`] × the limit:
//!   [`ProgressWatchdog`]).
//!
//! ## What the controller is told
//! * Position fixes at the outer rate from [`crate::sim::sensors`] (noise, latency).
//! * IMU samples at the inner rate.
//! * Obstacles at the outer rate, as a proximity sensor would report them: for
//!   each obstacle whose surface is within the sensing range of the true
//!   centre of mass, its closest surface point (moving obstacles at their
//!   current position) and its velocity, id = a track id
//!   ([`crate::sim::track_ids`]: the scene index for scenes of at most 65,535
//!   obstacles; never two equal ids in view, never `CLEAR_ID`).
//!
//! ## Metrics (true state, every outer step unless said otherwise)
//! clearance = signed distance to the nearest obstacle surface or the ground
//! plane − hull radius (every plant step for the minimum; touching the ground
//! with the hull is a collision too); h̄ = min over all obstacles of the filter's
//! barrier `|d|² + μ dᵀḋ − δ` (ḋ relative for the relative variants);
//! tracking error = |p − p_ref|; filter active = the filter changed `u*`.
//!
//! ## Cost
//! The distance queries (clearance every plant step, proximity report and h̄
//! every outer step, the reference's clearance) go through
//! [`NearestTracker`]: obstacles that provably cannot matter are skipped, the
//! results are the same as the full scans' ([`nearest_with_ground`],
//! [`sense_obstacles`], [`true_h_bar`]) bit for bit.
//!
//! May import: `parapet-core`, [`crate::input`], [`crate::sim`], [`crate::world`],
//! [`crate::report`] (samples, summary), [`super::stack`], [`super::sensing`] (the
//! ground-truth report and h̄, re-exported here).

use std::time::Instant;

use anyhow::{anyhow, Result};
use nalgebra::Vector3;
use parapet_core::cbf::{CbfParams, FilterVariant, SafetyFilter};
use parapet_core::controller::ControllerParams;
use parapet_core::outer::guidance::{GuidanceParams, MissionGuidance};
use parapet_core::outer::trajectory::TrajectoryParams;
use parapet_core::outer::{path_yaw::PathYawParams, path_yaw::YawMode};
use parapet_core::perception::MemoryParams;
use parapet_core::schedule::OuterSchedule;
use parapet_core::thrust::ThrustParams;
use parapet_core::tracking::TrackingParams;
use parapet_core::waypoint::WaypointParams;

use crate::flight::sensing::to_estimate_frame;
pub use crate::flight::sensing::{bound_report, sense_and_h_bar, sense_obstacles, true_h_bar, OuterScratch};
use crate::flight::stack::{clock_us, FlightStack, StackStart};
use crate::input::f32_as_f64;
use crate::input::limits;
use crate::perception::Perception;
use crate::report::{RunParams, SafetySteps, Sample, Summary};
use crate::sim::plant::Plant;
use crate::sim::sensors::{SensorParams, Sensors};
use crate::sim::INNER_DT;
use crate::world::scene::Scene;
use crate::world::NearestTracker;

/// Goal reached: distance to the goal below this, m.
pub const GOAL_TOLERANCE_M: f64 = 0.1;
/// Goal reached: speed below this, m/s.
pub const GOAL_SPEED_MPS: f64 = 0.1;
/// A path whose last waypoint is this close to the scene's goal (m) ends at the
/// goal: covers the `f32` round-off of path coordinates (under 1 mm up to 10 km).
pub const PATH_END_ROUNDOFF_M: f64 = 1e-3;
/// Inner-loop rate, Hz (times are computed as step / rate, exact in decimal).
const INNER_HZ: f64 = parapet_core::wire::rates::INNER_RATE_HZ as f64;
/// The built-in default of the controller setting with scene/option key `key`: the
/// parameter table's ([`parapet_core::params`], = `ControllerParams::default()`), as its
/// shortest decimal (1.4, not 1.399999976158142). NaN for a key the table does not have
/// (refused by the run check).
pub fn table_default(key: &str) -> f64 {
    parapet_core::params::by_key(key).map_or(f64::NAN, |p| f32_as_f64(p.default_value()))
}
/// Default proximity-sensor range, m.
pub const DEFAULT_SENSING_RANGE: f64 = 3.0;

/// How much longer than its latency a filtered position source (not motion capture) is
/// primed before the start, s: the navigation filter initialises from several agreeing fixes
/// (`parapet_core::nav::NavParams::init_fixes`, 3 by default), 1 s gives the slowest preset
/// (`gps`, 10 Hz) 10 of them, room for an outlier among them. A real vehicle gets them
/// standing on the ground before it arms.
pub const NAV_WARMUP_S: f64 = 1.0;

/// Everything a run needs besides the scene.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// Path to fly, NED, m, start first (at least one waypoint).
    pub path: Vec<Vector3<f64>>,
    /// Where the path came from: "planner", "file" or "straight".
    pub path_source: String,
    /// Planning time, ms, if planned.
    pub planning_time_ms: Option<f64>,
    /// Safety filter on.
    pub cbf: bool,
    /// Filter variant.
    pub variant: FilterVariant,
    /// Yaw along the path (`MIS_YAW_MODE`; `--yaw-mode`, `[controller] yaw_mode`).
    pub yaw_mode: YawMode,
    /// Mission guidance (`MIS_GUIDANCE`; `[controller] guidance`; `--guidance` and
    /// `--param MIS_GUIDANCE=…` override it).
    pub guidance: MissionGuidance,
    /// Controller parameters as flown (scene/CLI overrides already applied).
    pub params: RunParams,
    /// Bound on unknown obstacle acceleration, m/s² (relative variants).
    pub accel_bound: f64,
    /// Velocity-uncertainty margin ε_v of the filter, m/s.
    pub velocity_margin: f64,
    /// Sensor parameters (noise flag included).
    pub sensors: SensorParams,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// Duration limit, s.
    pub duration: f64,
    /// The default rule's limit ([`default_duration`]) when `duration` came from it. While
    /// `duration` still equals it, a run still making progress at it goes on
    /// ([`ProgressWatchdog`], at most [`EXTEND_FACTOR`] × `duration`); a duration set
    /// otherwise (`--duration`, `[sim] duration`, a caller's own) ends the run.
    pub default_duration_s: Option<f64>,
    /// Proximity-sensor range, m.
    pub sensing_range: f64,
    /// Plant integration step, s (≤ 1 ms; the plant takes round(1 ms / dt) steps per inner step).
    pub dt: f64,
    /// Wind, plant vehicle (mismatch) and faults (the scene's, or overridden).
    pub disturbances: crate::sim::disturbance::Disturbances,
    /// Range sensors whose scans, through the obstacle memory, replace the
    /// true closest points (`--perception`, [`crate::perception`]); `None` = ground truth.
    pub perception: Option<Vec<crate::sim::range::RangeSensor>>,
    /// Battery model (the scene's `[battery]`), `None`: no battery simulated (issue 22).
    pub battery: Option<crate::sim::battery::BatteryModelParams>,
    /// Obstacle memory parameters (`PCP_*`; the scene's `[controller]` `mem_*` and
    /// `fov_margin`, else the core's defaults): used by range-sensor perception only.
    pub memory: MemoryParams,
    /// Parameters set by name (`--param NAME=VALUE`, `--params FILE`) that have no field of
    /// their own here: written through the parameter table onto [`controller_params`]'s set,
    /// in order (each value checked against its range when it was given).
    pub param_overrides: Vec<(&'static str, f32)>,
}

impl RunConfig {
    /// Defaults for `scene` with the given path: scene controller overrides,
    /// the scene's sensor table (or defaults), duration `[sim] duration` or
    /// [`default_duration`] at the scene's speed.
    pub fn for_scene(scene: &Scene, path: Vec<Vector3<f64>>) -> Result<RunConfig> {
        let c = &scene.controller;
        let variant = match &c.filter {
            Some(name) => name.parse().map_err(|_| anyhow!("unknown filter variant {name:?}"))?,
            None => FilterVariant::default(),
        };
        let yaw_mode = c.yaw_mode.as_deref().map_or(Ok(YawMode::default()), str::parse::<YawMode>);
        let yaw_mode = yaw_mode.map_err(|()| anyhow!("unknown yaw mode {:?}", c.yaw_mode))?;
        let guidance =
            c.guidance.as_deref().map_or(Ok(MissionGuidance::default()), str::parse::<MissionGuidance>);
        let guidance = guidance.map_err(|()| anyhow!("unknown guidance {:?}", c.guidance))?;
        // The table's f32 defaults as their shortest decimals: the same f32 values reach
        // the filter, and reports print them as written.
        let d = table_default;
        let params = RunParams {
            mu: c.mu.unwrap_or_else(|| d("mu")),
            delta: c.delta.unwrap_or_else(|| default_delta(scene.vehicle.hull_radius)),
            delta1: c.delta1.unwrap_or_else(|| d("delta1")),
            kp: c.kp.unwrap_or_else(|| d("kp")),
            kd: c.kd.unwrap_or_else(|| d("kd")),
            speed: scene.speed,
        };
        let rule = default_duration(scene, &path, scene.speed);
        Ok(RunConfig {
            duration: scene.sim.duration.unwrap_or(rule),
            default_duration_s: scene.sim.duration.is_none().then_some(rule),
            path,
            path_source: "straight".into(),
            planning_time_ms: None,
            cbf: true,
            variant,
            yaw_mode,
            guidance,
            params,
            accel_bound: c.accel_bound.unwrap_or_else(|| d("accel_bound")),
            velocity_margin: c.velocity_margin.unwrap_or_else(|| d("velocity_margin")),
            sensors: scene.sensors.clone().unwrap_or_default(),
            seed: 0,
            sensing_range: scene.sim.sensing_range.unwrap_or(DEFAULT_SENSING_RANGE),
            dt: scene.sim.dt.unwrap_or(INNER_DT),
            disturbances: scene.disturbances.clone(),
            perception: None,
            battery: scene.battery.clone(),
            memory: memory_params(c)?,
            param_overrides: Vec::new(),
        })
    }

    /// The CBF parameters of this run (validated).
    pub fn cbf_params(&self) -> Result<CbfParams> {
        let p = CbfParams {
            mu: self.params.mu as f32,
            delta: self.params.delta as f32,
            delta1: self.params.delta1 as f32,
            accel_bound: self.accel_bound as f32,
            velocity_margin: self.velocity_margin as f32,
            ..CbfParams::default()
        };
        p.validate().map_err(|e| anyhow!("controller parameters: {e}"))?;
        Ok(p)
    }
}

/// The obstacle memory's parameters: the core's defaults with the scene's `[controller]`
/// `mem_*` / `fov_margin` values (checked against the parameter table by the scene loader and
/// [`crate::flight::validate`]), each written through the parameter table
/// (`parapet_core::params::set`, the firmware's `PCP_*` path), so that a key names the same
/// field everywhere; a value the table refuses is an error naming the key.
fn memory_params(c: &crate::world::schema::ControllerOverrides) -> Result<MemoryParams> {
    let mut p = ControllerParams::default();
    for (key, x) in c.numbers() {
        if let (Some(x), Some(param)) = (x, parapet_core::params::by_key(key)) {
            if param.group == "Perception" {
                parapet_core::params::set(&mut p, param.name, x as f32)
                    .map_err(|e| anyhow!("[controller] {key} = {x}: {e:?} (range {})", param.range()))?;
            }
        }
    }
    Ok(p.perception)
}

/// The yaw mode of a run whose options and scene name none (`--yaw-mode`, `[controller]
/// yaw_mode`): **travel** when the range sensors all look forward (none sees the rear half,
/// e.g. `--perception camera`): heading held, such a vehicle could only ever move where it
/// does not look, and the unobserved-space walls (`PCP_FOV_WALLS` 2) stop it where its view
/// ends; facing the direction of travel is how it observes where it goes (`docs/perception.md`
/// § Unseen space). **hold** otherwise (ground truth, a 360° lidar, a ToF ring).
pub fn default_yaw_mode(perception: Option<&[crate::sim::range::RangeSensor]>) -> YawMode {
    match perception {
        Some(s) if !s.is_empty() && s.iter().all(|s| s.forward_only()) => YawMode::Travel,
        _ => YawMode::Hold,
    }
}

/// δ when the scene does not set it: the squared hull radius (margin 0; issue 17),
/// written as the core's default 0.05 for the default hull √0.05.
pub fn default_delta(hull_radius: f64) -> f64 {
    let sq = hull_radius * hull_radius;
    let d = f32_as_f64(CbfParams::default().delta);
    if (sq - d).abs() <= 1e-9 * d {
        d
    } else {
        sq
    }
}

/// The controller parameters of a run: defaults of the core with the scene's
/// vehicle and the run's tracking / filter / speed settings, then the parameters set by name
/// ([`RunConfig::param_overrides`]).
///
/// See also [`coverage_gaps`], the pre-flight coverage check of the run's range sensors.
pub fn controller_params(
    scene: &Scene,
    cfg: &RunConfig,
    cbf: CbfParams,
    variant: FilterVariant,
) -> ControllerParams {
    let mut p = run_controller_params(scene, cfg, cbf, variant);
    for (name, v) in &cfg.param_overrides {
        // Checked against the parameter's range when given (`cli::params::parse_assignment`),
        // so the table takes it; a name or value it refuses would leave the set unchanged.
        let _ = parapet_core::params::set(&mut p, name, *v);
    }
    p
}

/// What the run's range sensors cannot see of the hull's sweep at the mission speed
/// ([`crate::sim::coverage`], with the braking barrier's deceleration and delay of the
/// parameters flown); empty for ground truth. [`crate::sim::coverage::Gap::refuses`] tells
/// which of them the run's assumptions (`cfg.sensors.assume`) leave refused.
pub fn coverage_gaps(scene: &Scene, cfg: &RunConfig) -> Result<Vec<crate::sim::coverage::Gap>> {
    let Some(sensors) = cfg.perception.as_deref() else { return Ok(Vec::new()) };
    let cbf = cfg.cbf_params()?;
    let p = controller_params(scene, cfg, cbf, cfg.variant);
    let braking = crate::sim::coverage::Braking {
        accel: f64::from(p.cbf.brake_accel),
        delay: f64::from(p.cbf.brake_delay),
    };
    Ok(crate::sim::coverage::gaps(sensors, scene.vehicle.hull_radius, cfg.params.speed, braking))
}

fn run_controller_params(
    scene: &Scene,
    cfg: &RunConfig,
    cbf: CbfParams,
    variant: FilterVariant,
) -> ControllerParams {
    let af = scene.vehicle.airframe();
    let d = ControllerParams::default();
    ControllerParams {
        airframe: af,
        // The core's tracking defaults (vertical integral off: with the paper's soft
        // gains a z integrator is badly damped, and unstable once ki_z > kp·kd) with
        // the run's kp, kd on every axis.
        tracking: TrackingParams {
            kp: [cfg.params.kp as f32; 3],
            kd: [cfg.params.kd as f32; 3],
            ..d.tracking
        },
        cbf,
        filter_variant: variant,
        // The scene's hull bounds δ from below; the lag model uses its motor (issue 17).
        hull_radius: scene.vehicle.hull_radius as f32,
        plant_aware: parapet_core::plant_aware::PlantAwareParams {
            motor_tau: scene.vehicle.motor_tau as f32,
            ..d.plant_aware
        },
        thrust: ThrustParams {
            // 90 % of the rotors' total, leaving attitude authority (the core's default rule).
            thrust_max: 0.9 * 4.0 * af.rotor_thrust_max,
            ..d.thrust
        },
        waypoint: WaypointParams { cruise_speed: cfg.params.speed as f32, ..d.waypoint },
        guidance: GuidanceParams {
            path_yaw: PathYawParams { mode: cfg.yaw_mode, ..d.guidance.path_yaw },
            mission: cfg.guidance,
            ..d.guidance
        },
        // A simulated pack's cells and resistance (BatteryModelParams::estimator_params).
        battery: cfg.battery.as_ref().map_or(d.battery, |b| b.estimator_params(d.battery)),
        perception: cfg.memory,
        governor: governor_sensing(cfg, d.governor),
        ..d
    }
}

/// The governor's sensing range and latency from the run's sensors: the longest range of the
/// range sensors (the memory's frontier limits each direction further) and at least their
/// largest latency; with ground truth the truth range (`sensing_range`). `GOV_RANGE` /
/// `GOV_DELAY` set by name override them.
fn governor_sensing(
    cfg: &RunConfig,
    d: parapet_core::governor::GovernorParams,
) -> parapet_core::governor::GovernorParams {
    let (range, latency) = match cfg.perception.as_deref() {
        Some(s) => (
            s.iter().map(|x| x.max_range).fold(0.0, f64::max),
            s.iter().map(|x| x.latency).fold(0.0, f64::max),
        ),
        None => (cfg.sensing_range, 0.0),
    };
    parapet_core::governor::GovernorParams {
        range: range.clamp(0.5, 100.0) as f32,
        delay: d.delay.max(latency.min(1.0) as f32),
        ..d
    }
}

/// Samples reserved up front by [`run_with`] (one minute at the outer rate); more
/// are added as the flight goes.
const SAMPLES_RESERVED: u64 = 15_000;

/// The caps that keep one run's time and memory bounded (the CLI refuses the same
/// values earlier, naming the option or the file): duration finite, > 0 and ≤
/// [`limits::MAX_DURATION_CEILING_S`]; dt in [[`limits::MIN_DT_S`], [`INNER_DT`]];
/// at most [`limits::MAX_PLANT_STEPS`] plant steps; position latency in [0,
/// [`limits::MAX_POSITION_LATENCY_S`]] (the start-up primes one fix per outer step of it).
pub fn check_bounded(cfg: &RunConfig) -> Result<()> {
    let d = cfg.duration;
    if !(d.is_finite() && d > 0.0 && d <= limits::MAX_DURATION_CEILING_S) {
        return Err(anyhow!("duration must be in (0, {}] s, got {d}", limits::MAX_DURATION_CEILING_S));
    }
    if !(cfg.dt.is_finite() && cfg.dt >= limits::MIN_DT_S && cfg.dt <= INNER_DT) {
        return Err(anyhow!("plant step dt must be in [{}, {INNER_DT}] s, got {}", limits::MIN_DT_S, cfg.dt));
    }
    if d / cfg.dt > limits::MAX_PLANT_STEPS {
        return Err(anyhow!(
            "duration / dt = {:.3e} plant steps exceed the cap of {:.0e}",
            d / cfg.dt,
            limits::MAX_PLANT_STEPS
        ));
    }
    let lat = cfg.sensors.position_latency;
    let lat_cap = limits::max_position_latency_s(cfg.sensors.position_source.is_mocap());
    if !(lat.is_finite() && (0.0..=lat_cap).contains(&lat)) {
        return Err(anyhow!("position latency must be in [0, {lat_cap}] s, got {lat}"));
    }
    Ok(())
}

use super::paths::{contact, with_ground};
pub use super::paths::{
    default_duration, flown_length, nearest_with_ground, path_length, remaining_length, ProgressWatchdog,
    EXTEND_FACTOR, STALL_WINDOW_S,
};

/// `cfg`'s duration is the default rule's ([`RunConfig::default_duration_s`]): the run goes on
/// while it makes progress.
pub fn extends_while_progressing(cfg: &RunConfig) -> bool {
    cfg.default_duration_s == Some(cfg.duration)
}

/// The longest a run with `cfg` can last, s: `duration`, or under the default rule's watchdog
/// [`EXTEND_FACTOR`] × it, within the caps of [`check_bounded`] (never below `duration`).
pub fn hard_duration(cfg: &RunConfig) -> f64 {
    if extends_while_progressing(cfg) {
        let cap = limits::MAX_DURATION_CEILING_S.min(limits::MAX_PLANT_STEPS * cfg.dt);
        (cfg.duration * EXTEND_FACTOR).min(cap).max(cfg.duration)
    } else {
        cfg.duration
    }
}

/// The outcome of a run: samples at the outer rate and the summary.
#[derive(Clone, Debug)]
pub struct RunOutput {
    /// Recorded samples.
    pub samples: Vec<Sample>,
    /// Summary.
    pub summary: Summary,
    /// Every beam of the range sensors (empty without `perception`), for `ranges.csv`.
    pub ranges: crate::perception::RangeLog,
    /// The obstacle points given to the controller, at 10 Hz (`crate::report::points`).
    pub filter_points: crate::report::points::FilterPointLog,
}

/// Fly `scene` with `cfg` and any [`FlightStack`] (in-process: `crate::fc::control::run`;
/// firmware in the loop: `crate::fc::pil`).
pub fn run_with(
    scene: &Scene,
    cfg: &RunConfig,
    ctrl: &mut dyn FlightStack,
    progress: &mut dyn FnMut(f64),
) -> Result<RunOutput> {
    // The world's spatial index is built with the world, like loading the scene,
    // before the flight's wall clock starts (40 ms of CPU for 10^5 obstacles).
    let world_tracker = NearestTracker::new(scene);
    let wall = Instant::now();
    if cfg.path.is_empty() {
        return Err(anyhow!("empty path"));
    }
    check_bounded(cfg)?;
    let substeps = (INNER_DT / cfg.dt).round().max(1.0) as usize;
    let dt = INNER_DT / substeps as f64;
    let cbf = cfg.cbf_params()?;
    let filter = SafetyFilter::new(cbf, cfg.variant).map_err(|e| anyhow!("filter: {e}"))?;
    // The core's one outer-loop schedule (250 Hz: every 4th inner step) of the parameters flown.
    let schedule = OuterSchedule::new(&controller_params(scene, cfg, cbf, cfg.variant));
    let divider = schedule.divider();
    let hull = scene.vehicle.hull_radius;

    // The plant flies the `[plant]` vehicle (mismatch), the controller knows the scene's.
    let plant_vehicle = cfg.disturbances.plant_vehicle(&scene.vehicle);
    let mut plant = Plant::new(plant_vehicle).map_err(|e| anyhow!("plant vehicle: {e}"))?;
    plant.set_hover(scene.start, 0.0);
    // A ground station's flight (`FlightStack::ground_start`): at rest on the ground below the start.
    let ground = ctrl.ground_start();
    if ground {
        plant.set_hover(Vector3::new(scene.start.x, scene.start.y, 0.0), 0.0);
        plant.set_rotor_speeds([0.0; 4]);
    }
    let mut sensors = Sensors::with_faults(cfg.sensors.clone(), cfg.disturbances.faults.clone(), cfg.seed);
    let mut battery = cfg
        .battery
        .as_ref()
        .map(|b| crate::sim::battery::BatteryModel::new(b.clone(), cfg.seed, "[battery]"))
        .transpose()
        .map_err(|e| anyhow!("{e}"))?;
    let mut live = crate::sim::disturbance::Live::new(&cfg.disturbances, cfg.seed);
    // Start-up: the vehicle has been hovering at the start; prime the position
    // measurement's latency buffer with that hover, then arm and start. A filtered source
    // (not motion capture) is primed NAV_WARMUP_S longer: its filter initialises from
    // several agreeing fixes (parapet_core::nav, *Initialisation*), so the warm-up's fixes
    // go to the stack before the last one.
    let warm = if cfg.sensors.position_source.is_mocap() { 0.0 } else { NAV_WARMUP_S };
    let mut fixes = Vec::new();
    let prime = ((cfg.sensors.position_latency + warm) / (INNER_DT * divider as f64)).ceil() as i64 + 1;
    for j in (0..=prime).rev() {
        let tj = -(j as f64) * INNER_DT * divider as f64;
        if let Some(f) = sensors.position(tj, &plant) {
            fixes.push(f);
        }
    }
    let fix = fixes.pop().ok_or_else(|| anyhow!("no position fix at start-up"))?;
    let mut seen0 = sense_obstacles(scene, 0.0, &plant.state.pos, cfg.sensing_range, &mut sensors);
    // Range sensors (`--perception`): their memory's points replace the true ones.
    let mut perception = cfg.perception.as_ref().map(|list| {
        let params = controller_params(scene, cfg, cbf, cfg.variant);
        let critical =
            cfg.variant.is_multi().then(|| (cfg.params.mu as f32, cfg.variant.uses_relative_velocity()));
        Perception::for_run(
            scene,
            list,
            cfg.seed,
            cfg.sensors.noise,
            params.memory_params(),
            critical,
            cfg.params.delta1 as f32,
        )
    });
    // A stack that takes the sensors' scans itself (the PIL firmware fed by OBSTACLE_DISTANCE)
    // gets them instead of the host memory's points.
    let forwarding = match (cfg.perception.as_deref(), perception.as_mut()) {
        (Some(list), Some(p)) if ctrl.take_proximity_scans(list) => p.forward_scans(|_| true) > 0,
        _ => false,
    };
    if let Some(p) = perception.as_mut() {
        p.step_plant(scene, 0.0, &plant.state, plant.state.euler(), clock_us, &mut seen0);
    }
    let imu0 = sensors.imu(&plant);
    // Motion capture starts from the last fix alone, as before the warm-up existed.
    let warmup = if warm > 0.0 { &fixes[..] } else { &[] };
    ctrl.start(&StackStart { t: 0.0, start: scene.start, warmup, fix, obstacles: &seen0, imu: &imu0 })?;

    // Exact distance queries along the vehicle's and the reference's paths (see NearestTracker).
    let mut tracker = world_tracker;
    let mut ref_tracker = NearestTracker::with_index(scene, tracker.index());
    let mut scratch = OuterScratch::default();
    // Signed distance to the nearest obstacle or the ground at the current plant state.
    let mut sd_now = contact(ground, tracker.nearest(scene, &plant.state.pos, 0.0), &plant.state.pos).0;

    let n_inner = ((if ground { cfg.duration } else { hard_duration(cfg) }) / INNER_DT).ceil() as u64;
    let mut watchdog = ProgressWatchdog::default();
    // New paths flown so far (an on-board replan restarts the watchdog's measure).
    let mut replans_seen = 0;
    // A ground station's flight flies what the station uploads, not `cfg.path`: its limit stands.
    let extend = extends_while_progressing(cfg) && !ground;
    // Memory grows with the time flown, not with the duration limit: reserve at
    // most a minute of samples up front.
    let mut samples = Vec::with_capacity((n_inner / divider + 1).min(SAMPLES_RESERVED) as usize);
    let mut filter_points = crate::report::points::FilterPointLog::default();
    let (mut collided_at, mut collision_obstacle) = (None, None);
    let mut goal_at = None;
    // A ground station's flight ended: landed and disarmed (`FlightStack::finished`).
    let mut landed_at = None;
    let mut min_clear = f64::INFINITY;
    let (mut sq_err, mut n_outer, mut n_active) = (0.0, 0u64, 0u64);
    let mut steps = 0u64;
    let mut t = 0.0;
    let mut next_progress = 0.0;
    // Throttles of the last inner step (0 before the first), recorded with each sample.
    let mut last_throttle = [0.0f32; 4];
    // The path's end (where the run stops) and the scene's goal (what `reached_goal` means).
    let path_end = *cfg.path.last().unwrap_or(&scene.goal);

    let mut ended_at = None;
    for k in 0..n_inner {
        t = k as f64 / INNER_HZ;
        if extend && t >= cfg.duration && t >= watchdog.end(cfg.duration) {
            ended_at = Some(t);
            break;
        }
        if schedule.is_outer_step(k) {
            // Euler angles of the true state, once for the position fix and the sample.
            let (roll, pitch, yaw) = plant.state.euler();
            if let Some(fix) = sensors.position_with_yaw(t, &plant, yaw) {
                if cfg.sensors.position_source.has_magnetometer() {
                    let field = parapet_core::nav::mag::body_field(roll as f32, pitch as f32, fix.yaw as f32);
                    ctrl.mag_fix(t, field);
                }
                ctrl.position_fix(fix);
            }
            if let Some(down) = sensors.baro(t, &plant) {
                ctrl.height_fix(t, down);
            }
            let (pos, vel) = (plant.state.pos, plant.state.vel);
            let h_bar = sense_and_h_bar(
                scene,
                &mut tracker,
                &filter,
                t,
                &pos,
                &vel,
                cfg.sensing_range,
                &mut sensors,
                &mut scratch,
            );
            sensors.obstacle_report(t, &mut scratch.seen);
            if let Some(p) = perception.as_mut() {
                p.step_plant(scene, t, &plant.state, (roll, pitch, yaw), clock_us, &mut scratch.seen);
                if forwarding {
                    for f in p.take_forwarded() {
                        if let Some(spec) = p.sensor(f.sensor) {
                            ctrl.proximity_scan(t, f.t, spec, &f.ranges);
                        }
                    }
                }
            }
            if let Some((est, bound)) = ctrl.navigation(t) {
                to_estimate_frame(&mut scratch.seen, &(est - pos), &est, &bound, perception.is_some());
            }
            let out = ctrl.outer(t, &scratch.seen);
            if n_outer % crate::report::points::FILTER_POINTS_PERIOD == 0 {
                filter_points.record(t, &scratch.seen, &plant.state.pos);
            }
            let sd = sd_now;
            let ref_clear =
                with_ground(ref_tracker.nearest(scene, &out.reference, t), &out.reference).0 - hull;
            let err = (plant.state.pos - out.reference).norm();
            sq_err += err * err;
            n_outer += 1;
            if out.filter.intervened {
                n_active += 1;
            }
            samples.push(Sample {
                t,
                ref_pos: out.reference,
                pos: plant.state.pos,
                vel: plant.state.vel,
                rpy: [roll, pitch, yaw],
                filter: out.filter,
                clearance: sd - hull,
                ref_clearance: ref_clear,
                h_bar,
                u_nominal: out.u_nominal,
                u_filtered: out.u_filtered,
                mode: out.mode,
                flight_mode: out.flight_mode,
                wind: live.wind(),
                safety: out.safety,
                motors: last_throttle,
            });
            if goal_at.is_none()
                && (plant.state.pos - path_end).norm() < GOAL_TOLERANCE_M
                && plant.state.vel.norm() < GOAL_SPEED_MPS
                && out.path_done
            {
                goal_at = Some(t);
                if !ground {
                    break;
                }
            }
            if ground && ctrl.finished() {
                landed_at = Some(t);
                break;
            }
            if t >= next_progress {
                progress(t);
                next_progress = t + 0.1;
                if extend {
                    let replans = ctrl.replans();
                    if replans != replans_seen {
                        replans_seen = replans;
                        watchdog.new_path(t);
                    }
                }
                watchdog.observe(t, remaining_length(&scene.start, &cfg.path, &plant.state.pos));
            }
        }
        let imu = sensors.imu(&plant);
        let throttle = ctrl.inner(t, &imu);
        last_throttle = throttle;
        plant.set_throttles(throttle);
        if let Some(b) = battery.as_mut() {
            if let Some(r) = b.step(INNER_DT, &throttle) {
                ctrl.battery(t, &r);
            }
        }
        live.apply(t, INNER_DT, &mut plant);
        for _ in 0..substeps {
            plant.step(dt);
            steps += 1;
        }
        let t_next = (k + 1) as f64 / INNER_HZ;
        let pos = plant.state.pos;
        tracker.move_to(&pos);
        // The exact distance is needed for the next outer step's sample, and
        // whenever it may be a new minimum or a collision (min_clear ≥ 0: a
        // collision ends the run); otherwise a lower bound rules both out.
        let skip =
            !schedule.is_outer_step(k + 1) && tracker.nearest_lower_bound().min(-pos.z) - hull > min_clear;
        if !skip {
            let (sd, idx) = contact(ground, tracker.nearest(scene, &pos, t_next), &pos);
            sd_now = sd;
            min_clear = min_clear.min(sd - hull);
            if sd < hull {
                collided_at = Some(t_next);
                collision_obstacle = idx;
                t = t_next;
                break;
            }
        }
        if !plant.state.pos.iter().all(|x| x.is_finite()) {
            return Err(anyhow!("the plant state became non-finite at t = {t:.3} s"));
        }
    }
    if collided_at.is_none() && goal_at.is_none() && landed_at.is_none() {
        t = ended_at.unwrap_or(n_inner as f64 / INNER_HZ);
    }
    let reached_path_end = goal_at.is_some();
    let goal_dist = (plant.state.pos - scene.goal).norm();
    // A path ending at the goal up to the f32 round-off of its waypoints counts as
    // ending there (the path-end test decides); otherwise the scene goal's own test.
    let ends_at_goal = (path_end - scene.goal).norm() <= PATH_END_ROUNDOFF_M;
    let goal_at = goal_at.filter(|_| ends_at_goal || goal_dist < GOAL_TOLERANCE_M);
    let min_h_bar = samples.iter().map(|s| s.h_bar).fold(f64::INFINITY, f64::min);
    let summary = Summary {
        scene: scene.name.clone(),
        scene_file: scene.source.clone(),
        filter: if cfg.cbf { cfg.variant.as_str().to_string() } else { "none".into() },
        yaw_mode: cfg.yaw_mode.as_str().into(),
        cbf_enabled: cfg.cbf,
        collided: collided_at.is_some(),
        first_collision_time_s: collided_at,
        collision_obstacle,
        collision_with: collided_at.map(|_| match collision_obstacle {
            Some(i) => scene.obstacle_label(i),
            None => "ground".to_string(),
        }),
        min_clearance_m: min_clear.min(samples.iter().map(|s| s.clearance).fold(f64::INFINITY, f64::min)),
        min_h_bar,
        min_filter_h_bar: Some(
            samples.iter().map(|s| f64::from(s.filter.h_bar)).fold(f64::INFINITY, f64::min),
        )
        .filter(|x| x.is_finite()),
        reached_goal: goal_at.is_some(),
        time_to_goal_s: goal_at,
        final_distance_to_goal_m: goal_dist,
        reached_path_end,
        final_distance_to_path_end_m: (plant.state.pos - path_end).norm(),
        tracking_rms_m: if n_outer > 0 { (sq_err / n_outer as f64).sqrt() } else { 0.0 },
        filter_active_fraction: if n_outer > 0 { n_active as f64 / n_outer as f64 } else { 0.0 },
        end_reason: if collided_at.is_some() {
            "collision"
        } else if goal_at.is_some() {
            "goal"
        } else if reached_path_end {
            "path_end"
        } else if landed_at.is_some() {
            "landed"
        } else {
            "duration"
        }
        .into(),
        sim_time_s: t,
        wall_time_s: wall.elapsed().as_secs_f64(),
        steps,
        planning_time_ms: cfg.planning_time_ms,
        path_length_m: path_length(&cfg.path),
        path_source: cfg.path_source.clone(),
        path_waypoints: cfg.path.len(),
        params: cfg.params.clone(),
        params_set: cfg.param_overrides.iter().map(|(n, v)| ((*n).to_string(), *v)).collect(),
        final_controller_state: ctrl.state_name(),
        seed: cfg.seed,
        noise: cfg.sensors.noise,
        safety_steps: SafetySteps::of(&samples),
        speed_limited_by: crate::report::speed_limit::SpeedLimitedBy::of(&samples),
        pace: mission_pace(scene, cfg, goal_at, &samples)?,
        unmapped_obstacles: scene.unmapped_count(),
        replan: ctrl.replan_summary(),
        coverage_gaps: coverage_gaps(scene, cfg)?
            .into_iter()
            .map(|g| match g.accepted_by().filter(|a| cfg.sensors.assume.contains(a)) {
                Some(a) => format!("{} (assumed away: {})", g.text, a.as_str()),
                None => g.text,
            })
            .collect(),
    };
    let ranges = perception.map(|mut p| p.take_records()).unwrap_or_default();
    Ok(RunOutput { samples, summary, ranges, filter_points })
}

/// The pace of a mission flown on the trajectory guidance (`summary.json` `pace`,
/// [`crate::report::pace`]); `None` for the paper's guidance.
fn mission_pace(
    scene: &Scene,
    cfg: &RunConfig,
    goal_at: Option<f64>,
    samples: &[Sample],
) -> Result<Option<crate::report::pace::Pace>> {
    let p = controller_params(scene, cfg, cfg.cbf_params()?, cfg.variant);
    if p.guidance.mission != MissionGuidance::Trajectory {
        return Ok(None);
    }
    let trajectory = TrajectoryParams { cruise_speed: p.waypoint.cruise_speed, ..p.guidance.trajectory };
    let governed = crate::report::speed_limit::SpeedLimitedBy::of(samples).is_some();
    Ok(crate::report::pace::Pace::of(&cfg.path, &trajectory, goal_at, governed))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fc::control::run;
    use crate::world::scene::{to_f32, Motion, SceneObstacle};
    use parapet_core::obstacle::{ObstaclePoint, Shape};
    use parapet_core::Vec3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The office with a walking obstacle added (waypoints), so the proximity
    /// report draws velocity noise.
    fn office_with_walker() -> Scene {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
        let mut s = Scene::load(&dir.join("office.toml")).unwrap_or_else(|e| panic!("{e}"));
        let a = s.start + Vector3::new(0.5, 0.5, 0.0);
        s.obstacles.push(SceneObstacle {
            name: Some("walker".into()),
            shape: Shape::sphere(to_f32(&a), 0.3),
            motion: Motion::Waypoints(vec![(0.0, a), (20.0, a + Vector3::new(4.0, 1.0, 0.0))]),
            mapped: true,
        });
        s
    }

    #[test]
    fn the_report_is_bounded_and_keeps_the_nearest_in_order() {
        let n = limits::MAX_OBSTACLES_REPORTED + 100;
        // Points at distance 1 + (i·7919 mod n)/n from the origin, so the nearest are scattered.
        let mut seen: Vec<ObstaclePoint> = (0..n)
            .map(|i| {
                let r = 1.0 + ((i * 7919) % n) as f32 / n as f32;
                ObstaclePoint::fixed(Vec3::new(r, 0.0, 0.0), i as u16)
            })
            .collect();
        let all = seen.clone();
        bound_report(&mut seen, &Vec3::zeros());
        assert_eq!(seen.len(), limits::MAX_OBSTACLES_REPORTED);
        let far = seen.iter().map(|o| o.point.x).fold(0.0, f32::max);
        assert!(all.iter().filter(|o| !seen.contains(o)).all(|o| o.point.x >= far));
        assert!(seen.windows(2).all(|w| w[0].id < w[1].id), "report order kept");
        let mut short = all[..10].to_vec();
        bound_report(&mut short, &Vec3::zeros());
        assert_eq!(short, all[..10]);
    }

    /// A 1 m leg at 0.5 m/s in an empty room, without noise; its default configuration.
    fn one_metre_leg() -> (Scene, RunConfig) {
        let src = "name = \"m\"\n[bounds]\nmin = [-1, -1, 0]\nmax = [3, 1, 2]\n\
                   [mission]\nstart = [0, 0, 1]\ngoal = [1, 0, 1]\nspeed = 0.5\n[sensors]\nnoise = false\n";
        let scene = Scene::parse(src, "m.toml").unwrap_or_else(|e| panic!("{e}"));
        let cfg =
            RunConfig::for_scene(&scene, vec![scene.start, scene.goal]).unwrap_or_else(|e| panic!("{e}"));
        (scene, cfg)
    }

    #[test]
    fn a_run_still_making_progress_at_the_default_limit_goes_on_a_given_limit_ends_it() {
        let (scene, mut cfg) = one_metre_leg();
        assert!(extends_while_progressing(&cfg), "no [sim] duration: the default rule");
        // A limit the 1 m leg at 0.5 m/s cannot meet: the vehicle is still on its way at it.
        (cfg.duration, cfg.default_duration_s) = (1.0, Some(1.0));
        let out = run(&scene, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(out.summary.end_reason, "goal");
        assert!(
            out.summary.time_to_goal_s.is_some_and(|t| t > 1.0 && t <= 4.0),
            "{:?}",
            out.summary.time_to_goal_s
        );
        // A limit set otherwise (`--duration`, a caller's own) ends the run there.
        cfg.default_duration_s = Some(25.0);
        assert!(!extends_while_progressing(&cfg));
        let out = run(&scene, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(out.summary.end_reason, "duration");
        assert!(out.samples.last().is_some_and(|s| s.t < 1.0), "ends at 1 s");
    }

    #[test]
    fn memory_follows_the_flight_not_the_duration_limit() {
        let (scene, mut cfg) = one_metre_leg();
        // A whole simulated day allowed (21.6 M samples if reserved up front).
        cfg.duration = limits::MAX_DURATION_CEILING_S;
        let out = run(&scene, &cfg, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(out.summary.end_reason, "goal");
        assert!(out.samples.capacity() <= SAMPLES_RESERVED as usize, "{}", out.samples.capacity());
    }

    /// The scene's `[controller]` obstacle-memory settings reach the controller (and so the
    /// perception's memory and, in PIL, the firmware's `PCP_*`); without them, the defaults.
    #[test]
    fn the_scenes_memory_settings_reach_the_controller() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
        let mut s = Scene::load(&dir.join("office.toml")).unwrap_or_else(|e| panic!("{e}"));
        let plain = RunConfig::for_scene(&s, vec![s.start, s.goal]).unwrap_or_else(|e| panic!("{e}"));
        let cbf = plain.cbf_params().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(controller_params(&s, &plain, cbf, plain.variant).perception, MemoryParams::default());
        s.controller.mem_track_size = Some(0.0);
        s.controller.mem_voxel = Some(0.25);
        s.controller.fov_margin = Some(0.4);
        let cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).unwrap_or_else(|e| panic!("{e}"));
        let m = controller_params(&s, &cfg, cbf, cfg.variant).perception;
        assert_eq!((m.track_size, m.voxel, m.fov_margin), (0.0, 0.25, 0.4));
        assert_eq!(m.forget_s, MemoryParams::default().forget_s);
        assert!(m.valid());
    }

    /// A memory value the parameter table refuses (the scene loader checks first) is an error
    /// naming the key and the range, never silently the default.
    #[test]
    fn a_refused_memory_value_is_an_error_naming_the_key() {
        let c = crate::world::schema::ControllerOverrides { mem_forget: Some(1e4), ..Default::default() };
        let e = memory_params(&c).unwrap_err().to_string();
        assert!(e.contains("mem_forget") && e.contains("600"), "{e}");
        let ok =
            crate::world::schema::ControllerOverrides { mem_clear_margin: Some(0.5), ..Default::default() };
        let m = memory_params(&ok).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m, MemoryParams { clear_margin: 0.5, ..MemoryParams::default() });
    }

    #[test]
    fn runs_beyond_the_caps_are_refused_before_any_step() {
        let scene = office_with_walker();
        let base =
            RunConfig::for_scene(&scene, vec![scene.start, scene.goal]).unwrap_or_else(|e| panic!("{e}"));
        assert!(check_bounded(&base).is_ok());
        type Edit = fn(&mut RunConfig);
        let cases: [(&str, Edit); 6] = [
            ("duration", |c| c.duration = 1e20),
            ("duration", |c| c.duration = f64::NAN),
            ("dt", |c| c.dt = 1e-7),
            ("dt", |c| c.dt = 0.002),
            ("plant steps", |c| {
                c.duration = limits::MAX_DURATION_CEILING_S;
                c.dt = limits::MIN_DT_S;
            }),
            ("latency", |c| c.sensors.position_latency = 1e9),
        ];
        for (what, f) in cases {
            let mut cfg = base.clone();
            f(&mut cfg);
            let e = run(&scene, &cfg, &mut |_| {}).unwrap_err().to_string();
            assert!(e.contains(what), "{what}: {e}");
        }
    }

    #[test]
    fn shared_sensing_and_barrier_equal_the_full_scans() {
        let scene = office_with_walker();
        let params = SensorParams { obstacle_velocity_noise: 0.05, ..SensorParams::default() };
        for variant in [FilterVariant::default(), FilterVariant::Paper] {
            let filter = SafetyFilter::new(CbfParams::default(), variant).expect("default filter");
            let (mut full_sensors, mut fast_sensors) =
                (Sensors::new(params.clone(), 5), Sensors::new(params.clone(), 5));
            let mut tracker = NearestTracker::new(&scene);
            let mut scratch = OuterScratch::default();
            let mut rng = ChaCha8Rng::seed_from_u64(11);
            let (lo, hi) = scene.bounds_ned();
            let mut p = scene.start;
            let mut v = Vector3::zeros();
            let n = 20_000;
            let (mut skipped_some, mut reported) = (0, 0);
            for k in 0..n {
                let t = k as f64 * 0.004;
                // Mostly a flight (velocity changes slowly), sometimes a jump or a fast vehicle.
                let r: f64 = rng.random();
                if r < 0.005 {
                    p = Vector3::from_fn(|i, _| rng.random_range(lo[i]..hi[i]));
                } else if r < 0.02 {
                    v = Vector3::from_fn(|_, _| rng.random_range(-3.0..3.0));
                } else {
                    v += Vector3::from_fn(|_, _| rng.random_range(-0.05..0.05));
                    v = v.cap_magnitude(1.5);
                }
                p += v * 0.004;
                let full = sense_obstacles(&scene, t, &p, 3.0, &mut full_sensors);
                let h_full = true_h_bar(&scene, &filter, t, &p, &v);
                let before = tracker.evaluations;
                let h_fast = sense_and_h_bar(
                    &scene,
                    &mut tracker,
                    &filter,
                    t,
                    &p,
                    &v,
                    3.0,
                    &mut fast_sensors,
                    &mut scratch,
                );
                assert_eq!(scratch.seen, full, "step {k} at {p:?}");
                assert_eq!(h_fast.to_bits(), h_full.to_bits(), "step {k} at {p:?}: {h_fast} vs {h_full}");
                skipped_some += usize::from(tracker.evaluations - before < scene.obstacles.len() as u64);
                reported += scratch.seen.len();
            }
            // The noise streams stayed in step, and the test saw reports and skips.
            assert_eq!(
                full_sensors.obstacle_velocity(Vector3::zeros()),
                fast_sensors.obstacle_velocity(Vector3::zeros())
            );
            assert!(reported > n && skipped_some > n / 2, "reported {reported}, skipped in {skipped_some}");
        }
    }
}
