//! The simulated pilot and the offboard companion (issue 21): script files
//! ([`script`]: stick timelines, a goal-seeking pilot, offboard setpoint timelines, scripted
//! RC loss / kill / mode switch / setpoint stop), the wrapper that feeds them to a flight
//! stack as RC frames and setpoints ([`stack`]), the in-process controller's pilot input
//! ([`inprocess`]), the firmware's over the PIL link ([`pil`], MANUAL_CONTROL and
//! SET_POSITION_TARGET_LOCAL_NED) and
//! [`run_piloted`] / [`run_piloted_pil`], which fly a scene with them (`parapet run --pilot
//! FILE` in Position-assist, `--offboard FILE` in Offboard).
//!
//! May import: `parapet-core`, [`crate::input`], [`crate::sim`], [`crate::world`],
//! [`crate::flight`], [`crate::fc`]; the children only downwards (inprocess, pil → stack → script).

pub mod inprocess;
pub mod pil;
pub mod script;
pub mod stack;

use anyhow::Result;

pub use inprocess::{AssistParams, PilotedController};
pub use script::{PilotScript, Setpoint, Sticks};
pub use stack::{PilotMode, PilotRecord, PilotSink, Piloted};

use crate::flight::runner::{run_with, RunConfig, RunOutput};
use crate::world::scene::Scene;

/// Seconds flown after the script's last keyframe or event when neither the script nor the
/// scene sets a duration.
pub const AFTER_SCRIPT_S: f64 = 5.0;

/// A piloted flight: the run as `parapet run` reports it, and the pilot's log.
#[derive(Clone, Debug)]
pub struct PilotRun {
    /// Samples and summary.
    pub out: RunOutput,
    /// One record per outer step.
    pub log: Vec<PilotRecord>,
    /// First RC frame with the kill switch on, s.
    pub kill_sent_at: Option<f64>,
    /// First inner step with every motor at zero at or after it, s.
    pub motors_off_at: Option<f64>,
    /// The firmware's STATUSTEXTs ("severity: text"; PIL only, empty in process).
    pub status_texts: Vec<String>,
}

/// `cfg` made for a piloted flight: the path is the start alone (the mission only holds it
/// until the pilot's mode is entered; the path source `pilot` for a stick script, `offboard`
/// for a setpoint one: no mission, [`crate::report::NO_MISSION_SOURCES`]), the duration the
/// script's, else the scene's `[sim] duration`, else the script's end + [`AFTER_SCRIPT_S`].
pub fn piloted_config(scene: &Scene, mut cfg: RunConfig, script: &PilotScript) -> RunConfig {
    cfg.path = vec![scene.start];
    cfg.path_source = if script.has_sticks() { "pilot" } else { "offboard" }.into();
    cfg.duration = script.duration.or(scene.sim.duration).unwrap_or(script.end_time() + AFTER_SCRIPT_S);
    // A pilot flight ends at its script's time: no mission progress to extend it by.
    cfg.default_duration_s = None;
    cfg
}

/// Fly `scene` with `cfg` (made by [`piloted_config`]), the in-process controller and
/// `script` in `mode`.
pub fn run_piloted(
    scene: &Scene,
    cfg: &RunConfig,
    script: &PilotScript,
    mode: PilotMode,
    assist: AssistParams,
    progress: &mut dyn FnMut(f64),
) -> Result<PilotRun> {
    let mut pc = PilotedController::new(scene, cfg, assist)?;
    fly_in_process(scene, cfg, &mut pc, script, mode, progress)
}

/// The closed loop of the in-process runs: `pc` piloted by `script` in `mode`.
fn fly_in_process(
    scene: &Scene,
    cfg: &RunConfig,
    pc: &mut PilotedController,
    script: &PilotScript,
    mode: PilotMode,
    progress: &mut dyn FnMut(f64),
) -> Result<PilotRun> {
    let mut p = Piloted::new(pc, script, mode);
    let out = run_with(scene, cfg, &mut p, progress)?;
    Ok(PilotRun {
        out,
        log: p.log,
        kill_sent_at: p.kill_sent_at,
        motors_off_at: p.motors_off_at,
        status_texts: Vec::new(),
    })
}

/// Fly `scene` with `cfg` (made by [`piloted_config`]), the firmware in QEMU and `script` in
/// `mode`: Position-assist (entered with the mode switch) or Offboard (setpoints as
/// SET_POSITION_TARGET_LOCAL_NED, entered with DO_SET_MODE; [`pil`]).
pub fn run_piloted_pil(
    scene: &Scene,
    cfg: &RunConfig,
    script: &PilotScript,
    mode: PilotMode,
    opts: crate::fc::pil::PilOptions,
    progress: &mut dyn FnMut(f64),
) -> Result<PilotRun> {
    let link = crate::fc::pil::PilLink::spawn(scene, cfg, opts)?;
    let mut pp = pil::PilotedPil::new(link);
    let mut p = Piloted::new(&mut pp, script, mode);
    let out = run_with(scene, cfg, &mut p, progress);
    let (log, kill_sent_at, motors_off_at) = (p.log, p.kill_sent_at, p.motors_off_at);
    if let Some(f) = pp.link.fault() {
        anyhow::bail!("processor-in-the-loop link failed: {f}");
    }
    let status_texts = pp.link.figures().status_texts;
    Ok(PilotRun { out: out?, log, kill_sent_at, motors_off_at, status_texts })
}

/// [`run_piloted`] entering Position-assist with the mode switch as [`run_piloted_pil`] does
/// (the in-process reference of the PIL comparison).
pub fn run_piloted_via_switch(
    scene: &Scene,
    cfg: &RunConfig,
    script: &PilotScript,
    assist: AssistParams,
    progress: &mut dyn FnMut(f64),
) -> Result<PilotRun> {
    let mut pc = PilotedController::new(scene, cfg, assist)?;
    pc.via_switch = true;
    fly_in_process(scene, cfg, &mut pc, script, PilotMode::Position, progress)
}
