//! The run set-up of `parapet run` (and of `pil` and `campaign`, which fly through it): the
//! command line's options checked ([`given`], [`positive`]), the range sensors of
//! `--perception` and the scene plus [`RunConfig`] a run flies ([`run_setup`],
//! [`run_config_from_args`]).
//!
//! May import: the rest of `cli` (its argument structs and errors), `flight`, `world`, `plan`,
//! `sim`, `input`.

use super::*;

pub(super) fn positive(name: &str, x: Option<f64>) -> Result<Option<f64>, CliError> {
    match x {
        Some(v) if !(v.is_finite() && v > 0.0) => {
            Err(InputError::option(name, "must be finite and > 0").value(num(v)).allowed("> 0").into())
        }
        other => Ok(other),
    }
}

/// The options of `a` given on the command line and the duration cap, for
/// [`crate::flight::validate::check_run`].
fn given(a: &RunArgs) -> Result<crate::flight::validate::Given, CliError> {
    let mut options = Vec::new();
    for (name, x) in [
        ("mu", a.mu),
        ("delta", a.delta),
        ("delta1", a.delta1),
        ("kp", a.kp),
        ("kd", a.kd),
        ("speed", a.speed),
        ("duration", a.duration),
        ("sensing-range", a.sensing_range),
    ] {
        if x.is_some() {
            options.push(name);
        }
    }
    let ceiling = limits::MAX_DURATION_CEILING_S;
    let max_duration = match positive("max-duration", a.max_duration)? {
        Some(m) if m > ceiling => {
            return Err(InputError::option("max-duration", "beyond the largest duration cap")
                .value(num(m))
                .allowed(format!("0 < max-duration ≤ {ceiling} s"))
                .into())
        }
        Some(m) => m,
        None => limits::MAX_DURATION_S,
    };
    Ok(crate::flight::validate::Given { options, max_duration })
}

/// Scene and run configuration from the `run` options (shared by `run` and `pil`).
/// The range sensors of `--perception` (`None` = `truth`); errors name the option,
/// the value and what is allowed.
fn perception_sensors(
    value: &str,
    scene: &Scene,
) -> Result<Option<Vec<crate::sim::range::RangeSensor>>, CliError> {
    use crate::sim::range::{preset, PRESETS};
    if value == "truth" {
        return Ok(None);
    }
    let allowed = format!("truth, scene, one of {} or a comma list of them", PRESETS.join(", "));
    let mut out: Vec<crate::sim::range::RangeSensor> = Vec::new();
    for name in value.split(',').map(str::trim) {
        let add = if name == "scene" {
            if scene.range_sensors.is_empty() {
                return Err(InputError::option("perception", "the scene has no [[sensor]] table")
                    .value(value)
                    .allowed(format!("scene only with [[sensor]] tables in {}", scene.source))
                    .into());
            }
            scene.range_sensors.clone()
        } else {
            preset(name).ok_or_else(|| {
                CliError::from(
                    InputError::option("perception", "unknown sensor set").value(value).allowed(&allowed),
                )
            })?
        };
        for s in add {
            if out.iter().any(|o| o.name == s.name) {
                return Err(InputError::option("perception", "a sensor is listed twice")
                    .value(value)
                    .allowed(format!("each sensor once ({} repeats)", s.name))
                    .into());
            }
            out.push(s);
        }
    }
    if out.len() > crate::sim::range::MAX_SENSORS {
        return Err(InputError::option("perception", "too many range sensors")
            .value(out.len())
            .allowed(format!("at most {}", crate::sim::range::MAX_SENSORS))
            .into());
    }
    Ok(Some(out))
}

pub(super) fn run_setup(a: &RunArgs) -> Result<(Scene, RunConfig), CliError> {
    let mut scene = load_scene(&a.scene)?;
    // [preflight] the start is flyable (before planning from it); --foreign-path needs --path.
    crate::flight::preflight::check_start(&scene).map_err(|e| CliError::BadInput(e.to_string()))?;
    if a.foreign_path && a.path.is_none() {
        return Err(CliError::BadInput("option --foreign-path: only with --path (a path file)".into()));
    }
    // --params FILE, then --param NAME=VALUE: the keyed ones as the scene's [controller] keys.
    let mut overrides =
        params::split_assignments(&mut scene, &params::assignments(a.params_file.as_deref(), &a.param)?)?;
    if let Some(g) = a.guidance {
        overrides.retain(|(n, _)| *n != "MIS_GUIDANCE");
        overrides.push(("MIS_GUIDANCE", g.code() as f32));
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
    let capacity = limits::MAX_WAYPOINTS;
    if path.len() > capacity {
        let from =
            a.path.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "the planned path".into());
        return Err(InputError::file(from, "more waypoints than a mission holds")
            .field("waypoints")
            .value(path.len())
            .allowed(format!("at most {capacity} waypoints"))
            .into());
    }
    let mut cfg = RunConfig::for_scene(&scene, path)
        .map_err(|e| CliError::BadInput(format!("{}: {e}", scene.source)))?;
    // [disturbances] --disturbances FILE, --wind, --turbulence, --gust over the scene's tables.
    a.disturb.apply(&mut cfg.disturbances, &scene.vehicle)?;
    cfg.path_source = source.into();
    cfg.planning_time_ms = planning_ms;
    cfg.param_overrides = overrides;
    cfg.cbf = !a.no_cbf;
    if let Some(v) = a.filter {
        cfg.variant = v;
    }
    if let Some(m) = a.yaw_mode {
        cfg.yaw_mode = m;
    }
    // Controller options: their ranges are the parameter table's, checked (naming the
    // option, the value and the range) by check_run below with the scene's values.
    for (x, field) in [
        (a.mu, &mut cfg.params.mu),
        (a.delta, &mut cfg.params.delta),
        (a.delta1, &mut cfg.params.delta1),
        (a.kp, &mut cfg.params.kp),
        (a.kd, &mut cfg.params.kd),
    ] {
        if let Some(x) = x {
            *field = x;
        }
    }
    if let Some(x) = positive("duration", a.duration)? {
        (cfg.duration, cfg.default_duration_s) = (x, None);
    } else if scene.sim.duration.is_none() {
        // [preflight] the default covers the whole flown path, start → first waypoint included.
        cfg.duration = crate::flight::runner::default_duration(&scene, &cfg.path, cfg.params.speed);
        cfg.default_duration_s = Some(cfg.duration);
    }
    cfg.perception = perception_sensors(&a.perception, &scene)?;
    for x in &a.assume {
        if !cfg.sensors.assume.contains(x) {
            cfg.sensors.assume.push(*x);
        }
    }
    if a.yaw_mode.is_none() && scene.controller.yaw_mode.is_none() {
        cfg.yaw_mode = crate::flight::runner::default_yaw_mode(cfg.perception.as_deref());
    }
    if let Some(x) = positive("sensing-range", a.sensing_range)? {
        cfg.sensing_range = x;
    }
    if a.no_noise {
        cfg.sensors.noise = false;
    } else if a.noise {
        cfg.sensors.noise = true;
    }
    if let Some(src) = a.position_source {
        cfg.sensors.position_source = src;
        cfg.sensors.apply_source_preset(&scene.sensors_keys.iter().map(String::as_str).collect::<Vec<_>>());
    }
    cfg.seed = a.seed;
    if let (false, Ok(cbf)) = (cfg.param_overrides.is_empty(), cfg.cbf_params()) {
        // The cross-parameter rules (docs/cascade.md) on the whole set the controller gets,
        // before the checks below name the scene for what a --param changed.
        let set = crate::flight::runner::controller_params(&scene, &cfg, cbf, cfg.variant);
        set.validate().map_err(|e| {
            InputError::option("param", "the parameter set is inconsistent")
                .value(e.to_string())
                .allowed("a consistent set (docs/cascade.md, the parameter table's cross-parameter rules)")
        })?;
    }
    // Every setting against the core's limits and the caps, naming its origin.
    crate::flight::validate::check_run(&scene, &cfg, &given(a)?)?;
    cfg.cbf_params().map_err(|e| CliError::BadInput(e.to_string()))?;
    // [preflight] start and waypoints in bounds and clear, the path belongs to the scene.
    let opts = crate::flight::preflight::PreflightOptions {
        path_file: a.path.as_ref().map(|p| p.display().to_string()),
        foreign_path: a.foreign_path,
    };
    crate::flight::preflight::check(&scene, &cfg, &opts).map_err(|e| CliError::BadInput(e.to_string()))?;
    Ok((scene, cfg))
}

/// [preflight] What the range sensors of `cfg` cannot see of the hull's sweep, on stderr
/// (`summary.json` keeps it too); a set that covers nothing, and a bearing or vertical gap that
/// no given assumption accepts, refuse the flight (exit 2, naming the gap and the `--assume`
/// value that would accept it; `crate::sim::coverage`). `parapet run` and `pil` call it; a campaign's flights, which go
/// through [`run_setup`] too, do not.
pub(super) fn check_coverage(scene: &Scene, cfg: &RunConfig, perception: &str) -> Result<(), CliError> {
    let gaps =
        crate::flight::runner::coverage_gaps(scene, cfg).map_err(|e| CliError::BadInput(e.to_string()))?;
    let assumed = &cfg.sensors.assume;
    let mut refused = Vec::new();
    for gap in &gaps {
        let accept = gap.accepted_by();
        if gap.refuses(assumed) {
            refused.push(match accept {
                Some(a) => format!("{} (accept it with --assume {})", gap.text, a.as_str()),
                None => gap.text.clone(),
            });
        } else if let Some(a) = accept {
            eprintln!("preflight: --perception {perception}: {} (assumed away: {})", gap.text, a.as_str());
        } else {
            eprintln!("preflight: --perception {perception}: {}", gap.text);
        }
    }
    if refused.is_empty() {
        return Ok(());
    }
    Err(InputError::option("perception", "the sensors cannot see the volume the hull sweeps")
        .value(format!("{perception}: {}", refused.join("; ")))
        .allowed(format!(
            "a sensor set that covers the sweep (lidar3d, tof), or a world assumption given with \
             --assume or the scene's [sensors] assume = [...] ({}; docs/perception.md § Coverage check)",
            crate::sim::coverage::Assumption::names()
        ))
        .into())
}

/// The scene and run configuration of a `parapet run` command line (`args`: the
/// options after `run`), exactly as `parapet run` flies it (`parapet campaign`
/// flies its flights through this, so a flight's command reproduces it).
pub fn run_config_from_args(args: &[String]) -> Result<(Scene, RunConfig), CliError> {
    let argv = ["parapet run".to_string()].into_iter().chain(args.iter().cloned());
    match RunCommandLine::try_parse_from(argv) {
        Ok(RunCommandLine { run }) => run_setup(&run),
        Err(e) => Err(CliError::BadInput(e.to_string())),
    }
}

/// The options of `parapet run` alone (the binary's parser has every subcommand).
#[derive(Debug, Parser)]
#[command(name = "parapet run", bin_name = "parapet run", allow_negative_numbers = true)]
struct RunCommandLine {
    #[command(flatten)]
    run: RunArgs,
}
