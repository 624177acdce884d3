//! The report of `parapet run` / `parapet pil`: the report directory check (never an
//! existing file, never replacing an input), summary.json / trajectory.csv / plots / replay.html
//! / flight.mcap ([`crate::report::write_report`]) and `flight.ulg`, in one place for both commands.
//!
//! May import: [`crate::report`], [`crate::flight`], [`crate::world`], [`crate::input`], the
//! parent's errors and output helpers.

use std::path::Path;

use super::{refuse_overwrite, CliError};
use crate::flight::runner::{RunConfig, RunOutput};
use crate::input::InputError;
use crate::report::{report_files, write_report, RunRecord};
use crate::world::scene::Scene;

/// Write the report of `result` (flown by `stack`: `run` / `pil`) to `dir`; returns the
/// plot warnings.
pub fn write_run_report(
    dir: &Path,
    scene: &Scene,
    cfg: &RunConfig,
    result: &RunOutput,
    stack: &str,
) -> Result<Vec<String>, CliError> {
    let rec = RunRecord {
        scene,
        path: &cfg.path,
        samples: &result.samples,
        summary: &result.summary,
        ranges: &result.ranges,
        range_sensors: cfg.perception.as_deref().unwrap_or(&[]),
        filter_points: &result.filter_points,
        clock_us: crate::flight::stack::clock_us,
    };
    let (_, warnings) = write_report(dir, &rec)?;
    write_flight_log(dir, scene, cfg, &result.samples, stack)?;
    Ok(warnings)
}

/// `flight.ulg` (ULog, `crate::report::ulog`) of a run flown by `stack` (`run` / `pil`) in `dir`.
pub fn write_flight_log(
    dir: &Path,
    scene: &Scene,
    cfg: &RunConfig,
    samples: &[crate::report::Sample],
    stack: &str,
) -> Result<(), CliError> {
    let params = crate::flight::runner::controller_params(scene, cfg, cfg.cbf_params()?, cfg.variant);
    let infos = [("parapet_stack", stack.to_string()), ("parapet_scene", scene.name.clone())];
    crate::report::ulog::write_flight_ulog(
        &dir.join(crate::report::ulog::FLIGHT_LOG),
        samples,
        &params,
        &infos,
        crate::flight::stack::clock_us,
    )?;
    Ok(())
}

/// The report directory `dir` of `run` / `pil`: not an existing file, and none
/// of the report's files is the scene or the path file.
pub fn check_report_dir(
    dir: &Path,
    scene: &Scene,
    path: Option<&Path>,
    disturbances: Option<&Path>,
) -> Result<(), CliError> {
    if dir.is_file() {
        return Err(InputError::option("out", "is an existing file, not a directory")
            .value(dir.display())
            .allowed("a directory (created if missing)")
            .into());
    }
    let mut inputs: Vec<(&str, &Path)> = vec![("scene file", Path::new(&scene.source))];
    if let Some(p) = path {
        inputs.push(("path file", p));
    }
    if let Some(p) = disturbances {
        inputs.push(("disturbances file", p));
    }
    refuse_overwrite("out", &report_files(dir), &inputs)
}
