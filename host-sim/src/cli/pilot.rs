//! `parapet run --pilot FILE` (the simulated pilot in Position-assist) and `--offboard FILE`
//! (a companion's setpoints in Offboard): loading the script, the piloted run, and its part
//! of the report — `pilot.csv` (per outer step: time, sticks, setpoint, flight and guidance
//! mode, filter intervention) and the `pilot` object of `summary.json` (script, mode, time
//! and filter interventions per flight mode, kill-switch latency).
//!
//! May import: [`crate::pilot`], [`crate::flight`], [`crate::world`], [`crate::input`], the
//! parent's errors.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context};

use super::CliError;
use crate::flight::runner::RunConfig;
use crate::pilot::script::switch_name;
use crate::pilot::{piloted_config, run_piloted, AssistParams, PilotMode, PilotRun, PilotScript};
use crate::world::frame::ned_to_enu_arr;
use crate::world::scene::Scene;

/// The pilot options of `parapet run`.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct PilotArgs {
    /// Fly a pilot script (TOML, scenes/README.md § Pilot scripts) in Position-assist instead
    /// of the mission: stick timeline or goal-seeking pilot, RC loss / kill / mode events.
    /// The run ends at the script's duration (or a collision); pilot.csv is added to the report.
    #[arg(long, value_name = "FILE")]
    pub pilot: Option<PathBuf>,
    /// Fly an offboard script (TOML, [[setpoint]] position/velocity/acceleration keyframes,
    /// ENU) in Offboard, as a companion computer would stream them.
    #[arg(long, value_name = "FILE", conflicts_with = "pilot")]
    pub offboard: Option<PathBuf>,
}

impl PilotArgs {
    /// Whether a script is given.
    pub fn is_set(&self) -> bool {
        self.pilot.is_some() || self.offboard.is_some()
    }

    /// The script and its mode, `None` without either option. Errors name the option or file.
    pub fn load(&self) -> Result<Option<(PilotScript, PilotMode)>, CliError> {
        let (file, mode, name) = match (&self.pilot, &self.offboard) {
            (Some(p), _) => (p, PilotMode::Position, "pilot"),
            (None, Some(p)) => (p, PilotMode::Offboard, "offboard"),
            (None, None) => return Ok(None),
        };
        if !file.is_file() {
            return Err(CliError::BadInput(format!("option --{name}: {} is not a file", file.display())));
        }
        let s = PilotScript::load(file)?;
        match mode {
            PilotMode::Position if !s.has_sticks() => {
                return Err(crate::input::InputError::file(file.display(), "a --pilot script needs sticks")
                    .allowed("[[stick]] keyframes or a [goal] table")
                    .into())
            }
            PilotMode::Offboard if s.setpoints.is_empty() => {
                return Err(crate::input::InputError::file(
                    file.display(),
                    "an --offboard script needs setpoints",
                )
                .allowed("[[setpoint]] keyframes")
                .into())
            }
            _ => {}
        }
        Ok(Some((s, mode)))
    }
}

/// Fly `scene` with the script; `cfg` is the run's (made piloted here).
pub fn fly(
    scene: &Scene,
    cfg: RunConfig,
    script: &PilotScript,
    mode: PilotMode,
    progress: &mut dyn FnMut(f64),
) -> Result<(RunConfig, PilotRun), CliError> {
    let cfg = piloted_config(scene, cfg, script);
    crate::flight::runner::check_bounded(&cfg)
        .map_err(|e| CliError::BadInput(format!("pilot script: {e}")))?;
    let r = run_piloted(scene, &cfg, script, mode, AssistParams::default(), progress)?;
    Ok((cfg, r))
}

fn opt(x: Option<f64>) -> String {
    x.map_or(String::new(), |v| format!("{v:.4}"))
}

/// Write `pilot.csv` and add the `pilot` object to `summary.json` in `dir`.
pub fn write_outputs(
    dir: &Path,
    script: &PilotScript,
    mode: PilotMode,
    r: &PilotRun,
) -> Result<(), CliError> {
    let path = dir.join("pilot.csv");
    let write = || -> std::io::Result<()> {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&path)?);
        writeln!(
            w,
            "t,rc,roll,pitch,yaw,throttle,arm,kill,mode_switch,sp_px,sp_py,sp_pz,sp_vx,sp_vy,sp_vz,sp_ax,sp_ay,sp_az,flight_mode,guidance,filter_active"
        )?;
        for l in &r.log {
            let (rc, sticks) = match &l.sticks {
                Some(s) => (
                    1,
                    format!(
                        "{:.4},{:.4},{:.4},{:.4},{},{},{}",
                        s.roll,
                        s.pitch,
                        s.yaw,
                        s.throttle,
                        u8::from(s.arm),
                        u8::from(s.kill),
                        switch_name(s.mode)
                    ),
                ),
                None => (0, ",,,,,,".to_string()),
            };
            // Setpoints in ENU, like trajectory.csv.
            let enu = |v: Option<nalgebra::Vector3<f64>>| match v {
                Some(v) => {
                    let a = ned_to_enu_arr(&v);
                    format!("{},{},{}", opt(Some(a[0])), opt(Some(a[1])), opt(Some(a[2])))
                }
                None => ",,".into(),
            };
            let sp = l.setpoint.unwrap_or_default();
            writeln!(
                w,
                "{:.3},{rc},{sticks},{},{},{},{},{},{}",
                l.t,
                enu(sp.position),
                enu(sp.velocity),
                enu(sp.acceleration),
                l.flight_mode,
                l.guidance,
                u8::from(l.filter_active)
            )?;
        }
        w.flush()
    };
    write().with_context(|| format!("cannot write {}", path.display()))?;
    // Time and filter interventions per flight mode.
    let dt = match r.log.as_slice() {
        [a, b, ..] => b.t - a.t,
        _ => 0.0,
    };
    let mut per_mode: BTreeMap<String, (f64, u64, u64)> = BTreeMap::new();
    for l in &r.log {
        let e = per_mode.entry(l.flight_mode.clone()).or_default();
        e.0 += dt;
        e.1 += 1;
        e.2 += u64::from(l.filter_active);
    }
    let modes: serde_json::Map<String, serde_json::Value> = per_mode
        .into_iter()
        .map(|(m, (t, n, k))| {
            (m, serde_json::json!({ "time_s": t, "outer_steps": n, "filter_active_steps": k }))
        })
        .collect();
    let pilot = serde_json::json!({
        "script": script.source,
        "name": script.name,
        "mode": match mode {
            PilotMode::Position => "Position",
            PilotMode::Offboard => "Offboard",
            PilotMode::Mission => "Mission",
        },
        "rc_rate_hz": script.rc_rate_hz,
        "setpoint_rate_hz": script.setpoint_rate_hz,
        "modes": modes,
        "kill_sent_at_s": r.kill_sent_at,
        "motors_off_at_s": r.motors_off_at,
    });
    let sp = dir.join("summary.json");
    let text = std::fs::read_to_string(&sp).with_context(|| format!("cannot read {}", sp.display()))?;
    let mut v: serde_json::Value = serde_json::from_str(&text).context("summary.json")?;
    v.as_object_mut().ok_or_else(|| anyhow!("summary.json is not an object"))?.insert("pilot".into(), pilot);
    std::fs::write(&sp, serde_json::to_string_pretty(&v).context("summary.json")? + "\n")
        .with_context(|| format!("cannot write {}", sp.display()))?;
    Ok(())
}
