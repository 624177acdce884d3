//! Processor-in-the-loop (PIL): the real firmware binary (`parapet-firmware-qemu`, the
//! `board-qemu` build of `firmware/`) runs in `qemu-system-arm -machine netduinoplus2
//! -icount shift=0` and flies the scene against the 6-DOF plant of [`crate::flight::runner`].
//!
//! The link follows the "QEMU lockstep protocol" of `firmware/README.md` exactly: the byte
//! stream on QEMU's stdin/stdout (the firmware's ARM semihosting console), the HEARTBEAT handshake,
//! the instruction calibration (`ins_cal_n`, `ins_cal`), then per 1 ms control period the host
//! sends (the previous step's battery reading when the scene's `[battery]` took one, ODOMETRY
//! and the obstacle batch at the outer rate, commands, then HIL_SENSOR) and waits for the
//! HIL_ACTUATOR_CONTROLS of that period; simulated time advances only then.
//! MAVLink v2 encoding/decoding is the `mavlink` crate (the firmware's version and dialect).
//!
//! [`PilLink`] implements [`FlightStack`](crate::flight::stack::FlightStack), so [`crate::flight::runner::run_with`] drives the firmware
//! exactly like the in-process controller and the report is the same as `parapet run`'s.
//!
//! ## Start-up (before simulated t = 0, plant frozen in hover at the start)
//! Firmware clock = [`clock_us`](crate::flight::stack::clock_us) (simulated time + 1 s). Pre-roll steps from
//! `T0 − preroll` (a multiple of the 4 ms outer period, so the firmware's outer steps fall on
//! the runner's outer steps): PARAM_SET of the run's controller settings (each checked against
//! its PARAM_VALUE), mission upload (MISSION_COUNT / MISSION_ITEM_INT per request /
//! MISSION_ACK ACCEPTED), ≈ 300 ms of warm-up with ODOMETRY and obstacle batches, ARM and
//! OVERRIDE_GOTO(start) in the step `T0 − 4 ms` (its outer step makes the reference the
//! start), and MISSION_START with the first flight step `T0` (processed at the previous step's
//! time, `T0 − 1 ms`).
//!
//! ## What the report gets from the firmware
//! Motor throttles every step (the only thing that drives the plant). For the recorder: the
//! filter diagnostics (`DEBUG_VECT CBF`, `NAMED_VALUE_INT CBF_FLAGS`), the nominal and the
//! filtered acceleration (`DEBUG_VECT U_NOM`, POSITION_TARGET_LOCAL_NED `afx..afz`), all 25 Hz
//! and held between reports (NaN before the first), and the phase (HEARTBEAT, 1 Hz). The
//! reference position and `path_done` are recomputed on the host with the same
//! `parapet_core::waypoint::WaypointFollower`, path (as quantised by MISSION_ITEM_INT) and
//! mission start time (exact, every outer step).
//!
//! ## Failure handling
//! QEMU runs in a guard that kills it on drop (every exit path). No answer to a HIL_SENSOR
//! within [`PilOptions::resend_after`] → the HIL_SENSOR is re-sent (same t; the firmware
//! answers it); no answer within [`PilOptions::timeout`] → error. As `FlightStack` cannot
//! return errors, a failure latches: the link outputs zero throttle from then on (the run
//! ends quickly with a ground contact) and [`run_pil`] returns the error.
//!
//! ## Files
//! * [`link`]: [`PilLink`], the lockstep exchange, handshake and start-up sequence.
//! * [`gcs`]: the messages the host sends and the settings it uploads ([`firmware_params`]).
//! * [`proximity`]: `OBSTACLE_DISTANCE` from a planar lidar's scan (`--perception lidar`: the
//!   firmware's own obstacle memory builds the set; other sensors: the host's memory's points).
//! * [`telemetry`]: what the host reads back (filter diagnostics, phase, counters) and [`PilFigures`].
//! * [`faults`]: [`FaultInjection`] into the host → firmware stream.
//! * [`qemu`]: the QEMU process and the reader thread.
//! * [`firmware`]: building / finding the QEMU firmware ELF.
//! * [`twin`]: [`FirmwareTwin`], the same sequence on the host.
//!
//! Message names, ids, scalings, codes, the lockstep rule and the motor-command sanitiser
//! are the wire contract `parapet_core::wire`, shared with the firmware.
//!
//! ## Position source
//! With `[sensors] position_source` `mocap` (the default) each fix goes as ODOMETRY (the
//! firmware's latest-fix path); with `gps` or `rtk` as GPS_INPUT ([`gcs::gps_input`]: lat/lon
//! 1e-7 °, altitude AMSL, velocity NED, heading cdeg, the σ as accuracies), at the source's
//! rate and latency (the time it describes is `time_usec`), into the firmware's navigation
//! filter (issue 39). The warm-up sends the start's fix the same way at the outer rate. The
//! firmware reports the filter in ESTIMATOR_STATUS and its estimate in LOCAL_POSITION_NED
//! (recorded in [`PilFigures`]); [`FirmwareTwin`] runs the same filter on the same decoded
//! fixes. The source's barometer (50 Hz) rides on the next step's HIL_SENSOR as `pressure_alt`
//! (m AMSL, the `HIL_SENSOR_UPDATED_PRESSURE_ALT` bit set; [`gcs::hil_sensor`]), which the
//! firmware fuses as a height. `vio` goes as a VIO's ODOMETRY ([`gcs::vio_odometry`]: estimator
//! type VIO, the σ as covariances), a relative source of the firmware's filter.
//!
//! ## Battery
//! With a scene `[battery]`, the runner samples the pack exactly as for `parapet run` (same
//! model, seed and motor commands, after each inner step) and [`PilLink`] sends each reading as
//! BATTERY_STATUS from the host's id (`parapet_core::wire::battery`: mV, cA) with the next step,
//! before its HIL_SENSOR, so the firmware's estimator takes it at the step's time as the
//! in-process controller does. Host → firmware only: never sent to a bridge endpoint, recorded
//! in the `.tlog`. [`FirmwareTwin`] takes the same quantised reading.
//!
//! May import: `parapet-core`, mavlink, [`crate::flight`], [`crate::sim::sensors`], [`crate::sim::battery`],
//! [`crate::world::scene`]; the children import each other
//! only downwards (link → gcs, proximity, telemetry, faults, qemu, firmware; twin → gcs).

pub mod faults;
pub mod firmware;
pub mod gcs;
pub mod link;
pub mod proximity;
pub mod qemu;
pub mod telemetry;
pub mod twin;

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{anyhow, bail, Context, Result};

pub use faults::FaultInjection;
pub use firmware::{
    build_firmware, default_firmware_path, firmware_build_command, firmware_from_env_or_build, is_elf,
    workspace_root, ELF_ENV, FIRMWARE_BIN, FIRMWARE_TARGET,
};
pub use gcs::{filtered_source, firmware_params, quantised_path};
pub use link::PilLink;
pub use qemu::QEMU_PACKAGE;
pub use telemetry::{InstructionFigures, PilFigures};
pub use twin::{run_twin, run_twin_with_fixes, FirmwareTwin};

use crate::flight::runner::{run_with, RunConfig, RunOutput};
use crate::world::scene::Scene;

/// How to run the firmware.
#[derive(Clone, Debug)]
pub struct PilOptions {
    /// The `parapet-firmware-qemu` ELF.
    pub firmware: PathBuf,
    /// Emulator binary (default `qemu-system-arm` on PATH).
    pub qemu: String,
    /// No answer to a step within this wall time → the firmware is declared dead.
    pub timeout: Duration,
    /// No answer within this wall time → re-send the step's HIL_SENSOR (same t).
    pub resend_after: Duration,
    /// Fault injection (none by default).
    pub faults: FaultInjection,
    /// A ground station flies (`parapet pil --gcs-control`): the vehicle waits disarmed on the
    /// ground below the start; the host sends the parameters and the sensor data only, the GCS
    /// uploads the mission, arms, starts, lands; the run ends when it is disarmed after a flight
    /// (or at the duration limit). Default `false`.
    pub gcs_control: bool,
}

impl PilOptions {
    /// Defaults: timeout 3 s, re-send after 1 s, no faults, the host flies the mission.
    pub fn new(firmware: PathBuf) -> Self {
        PilOptions {
            firmware,
            qemu: QEMU_PACKAGE.into(),
            timeout: Duration::from_secs(3),
            resend_after: Duration::from_secs(1),
            faults: FaultInjection::default(),
            gcs_control: false,
        }
    }
}

/// Fly `scene` with the firmware in QEMU; returns the run (as `parapet run`) and the PIL figures.
pub fn run_pil(
    scene: &Scene,
    cfg: &RunConfig,
    opts: PilOptions,
    progress: &mut dyn FnMut(f64),
) -> Result<(RunOutput, PilFigures)> {
    let mut link = PilLink::spawn(scene, cfg, opts)?;
    let out = run_with(scene, cfg, &mut link, progress);
    if let Some(f) = link.fault() {
        bail!("processor-in-the-loop link failed: {f}");
    }
    let out = out?;
    let fig = link.figures();
    drop(link);
    Ok((out, fig))
}

/// Add the PIL figures to `summary.json` in `dir` (object `pil`), written by `report::write_report`.
pub fn add_figures_to_summary(dir: &Path, fig: &PilFigures) -> Result<()> {
    let path = dir.join("summary.json");
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut v: serde_json::Value = serde_json::from_str(&text).context("summary.json")?;
    let obj = v.as_object_mut().ok_or_else(|| anyhow!("summary.json is not an object"))?;
    obj.insert("pil".into(), serde_json::to_value(fig)?);
    std::fs::write(&path, serde_json::to_string_pretty(&v)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// Largest distance (m) between the positions of two runs at the same sample times (over the
/// common prefix), and the number of samples compared.
pub fn max_deviation(a: &RunOutput, b: &RunOutput) -> (f64, usize) {
    let n = a.samples.len().min(b.samples.len());
    let d =
        a.samples[..n].iter().zip(&b.samples[..n]).map(|(x, y)| (x.pos - y.pos).norm()).fold(0.0, f64::max);
    (d, n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::controller::ControllerParams;
    use parapet_core::params;

    fn scene(extra: &str) -> Scene {
        let text = format!(
            "name = \"t\"\n[bounds]\nmin = [-1.0, -1.0, 0.3]\nmax = [3.0, 1.0, 2.0]\n\
             [mission]\nstart = [0.0, 0.0, 1.0]\ngoal = [2.0, 0.0, 1.0]\nspeed = 0.4\n{extra}"
        );
        Scene::parse(&text, "test scene").expect("scene parses")
    }

    /// The firmware gets exactly `parapet run`'s parameters: the PARAM_SETs, each within its
    /// parameter's range, reach them from its boot defaults in table order and in any other
    /// order (no intermediate set needs to be consistent).
    #[test]
    fn firmware_flies_the_scenes_vehicle_and_settings() {
        let s = scene(
            "[vehicle]\nmass = 1.2\ninertia = [0.004, 0.0045, 0.007]\narm_length = 0.2\nk_f = 6.0e-6\n\
             [controller]\nvelocity_margin = 0.03\nmem_track_size = 0.0\nfov_margin = 0.4\n",
        );
        let cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).expect("config");
        let (p, updates) = firmware_params(&s, &cfg).expect("representable");
        assert_eq!(
            p,
            crate::flight::runner::controller_params(&s, &cfg, cfg.cbf_params().expect("cbf"), cfg.variant)
        );
        assert_eq!(p.airframe.mass, 1.2);
        assert_eq!(p.cbf.velocity_margin, 0.03);
        assert_eq!((p.perception.track_size, p.perception.fov_margin), (0.0, 0.4));
        let index = |n: &str| params::index_of(n).expect("table name");
        assert!(updates.windows(2).all(|w| index(w[0].0) < index(w[1].0)), "table order: {updates:?}");
        let mut in_order = ControllerParams::default();
        let mut inconsistent_on_the_way = false;
        for (name, v) in &updates {
            assert_eq!(params::set(&mut in_order, name, *v), Ok(*v), "{name}");
            inconsistent_on_the_way |= in_order.validate().is_err();
        }
        assert_eq!(in_order, p);
        // 1.2 kg hovers on 11.8 N, above the boot THR_MAX (11 N), which comes later in the table.
        assert!(inconsistent_on_the_way);
        let mut reversed = ControllerParams::default();
        for (name, v) in updates.iter().rev() {
            assert_eq!(params::set(&mut reversed, name, *v), Ok(*v), "{name}");
        }
        assert_eq!(reversed, p);
    }

    #[test]
    fn default_scene_and_invalid_settings() {
        let s = scene("");
        let cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).expect("config");
        let (p, _) = firmware_params(&s, &cfg).expect("default scene");
        assert_eq!(p.airframe, s.vehicle.airframe());
        let mut bad = cfg.clone();
        bad.params.mu = -1.0;
        let err = firmware_params(&s, &bad).expect_err("invalid mu");
        println!("{err:#}");
        assert!(format!("{err:#}").contains("mu"), "{err:#}");
    }
}
