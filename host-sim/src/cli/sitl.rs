//! `parapet pil|run --gcs/--api/--realtime`: the command-line side of the SITL bridge
//! ([`crate::fc::bridge`]): the options, the bridge and `.tlog` of a PIL run, the run with the
//! bridge tapped into the link, and `parapet run`'s in-process controller behind the same
//! bridge ([`crate::fc::bridge::inprocess`]). See docs/ground-station.md.
//!
//! May import: [`crate::fc`] (bridge, PIL link), [`crate::flight::runner`],
//! [`crate::world::scene`], [`super`] (errors), `crate::input`.

use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;

use anyhow::anyhow;

use super::CliError;
use crate::fc::bridge::inprocess::GcsStack;
use crate::fc::bridge::{parse_endpoint, tlog::TlogWriter, Bridge, Endpoint, API_PORT, GCS_PORT};
use crate::fc::pil::{PilFigures, PilLink, PilOptions};
use crate::flight::runner::{run_with, RunConfig, RunOutput};
use crate::input::InputError;
use crate::world::scene::Scene;

/// File name of the PIL's raw MAVLink log in its report directory.
pub const TLOG: &str = "flight.tlog";

/// Ground-station options of `parapet pil`.
#[derive(Debug, clap::Args)]
pub struct SitlArgs {
    /// Bridge the firmware's MAVLink to a ground station over UDP: the vehicle sends to
    /// udp:HOST:PORT (QGroundControl listens on 14550) and answers whoever sends to it
    /// (docs/ground-station.md). `--gcs` alone = udp:127.0.0.1:14550.
    #[arg(long, num_args = 0..=1, default_missing_value = "udp:127.0.0.1:14550", value_name = "udp:HOST:PORT")]
    pub gcs: Option<String>,
    /// Second endpoint for an offboard API (MAVSDK listens on 14540). `--api` alone =
    /// udp:127.0.0.1:14540.
    #[arg(long, num_args = 0..=1, default_missing_value = "udp:127.0.0.1:14540", value_name = "udp:HOST:PORT")]
    pub api: Option<String>,
    /// Pace simulated time to wall time (lockstep underneath), to watch the flight live;
    /// default: as fast as possible.
    #[arg(long)]
    pub realtime: bool,
}

impl SitlArgs {
    /// Any ground-station option given.
    pub fn is_set(&self) -> bool {
        self.gcs.is_some() || self.api.is_some() || self.realtime
    }
}

/// The bridge of a run (endpoints of `a`, pacing, with `tlog` the `.tlog` in `dir`).
pub fn bridge(a: &SitlArgs, dir: &Path, tlog: bool) -> Result<Rc<RefCell<Bridge>>, CliError> {
    let mut endpoints = Vec::new();
    for (name, spec, port) in [("gcs", &a.gcs, GCS_PORT), ("api", &a.api, API_PORT)] {
        if let Some(spec) = spec {
            let remote = parse_endpoint(spec, port).map_err(|e| {
                InputError::option(name, "bad UDP endpoint")
                    .value(e)
                    .allowed("udp:HOST:PORT (e.g. udp:127.0.0.1:14550)")
            })?;
            let ep = Endpoint::new(name, remote)
                .map_err(|e| anyhow!("option --{name}: cannot open a UDP socket: {e}"))?;
            endpoints.push(ep);
        }
    }
    let tlog = if tlog {
        std::fs::create_dir_all(dir).map_err(|e| anyhow!("cannot create {}: {e}", dir.display()))?;
        let path = dir.join(TLOG);
        Some(TlogWriter::create(&path).map_err(|e| anyhow!("cannot create {}: {e}", path.display()))?)
    } else {
        None
    };
    Ok(Rc::new(RefCell::new(Bridge::new(endpoints, a.realtime, tlog))))
}

/// `crate::fc::pil::run_pil` with `bridge` tapped into the link.
pub fn run_pil_bridged(
    scene: &Scene,
    cfg: &RunConfig,
    opts: PilOptions,
    bridge: Rc<RefCell<Bridge>>,
    progress: &mut dyn FnMut(f64),
) -> anyhow::Result<(RunOutput, PilFigures)> {
    let mut link = PilLink::spawn(scene, cfg, opts)?;
    link.set_tap(Box::new(bridge));
    let out = run_with(scene, cfg, &mut link, progress);
    if let Some(f) = link.fault() {
        anyhow::bail!("processor-in-the-loop link failed: {f}");
    }
    let out = out?;
    Ok((out, link.figures()))
}

/// `parapet run --gcs …`: the in-process controller behind `bridge`
/// ([`crate::fc::bridge::inprocess::GcsStack`]); the run and the line for stderr.
pub fn run_inprocess_bridged(
    scene: &Scene,
    cfg: &RunConfig,
    bridge: Rc<RefCell<Bridge>>,
    progress: &mut dyn FnMut(f64),
) -> anyhow::Result<(RunOutput, String)> {
    let cbf = cfg.cbf_params()?;
    let ctrl = crate::fc::control::Controller::new(scene, cfg, cbf)?;
    let params = crate::flight::runner::controller_params(scene, cfg, cbf, cfg.variant);
    let b = Rc::try_unwrap(bridge).map_err(|_| anyhow!("internal: the bridge is shared"))?.into_inner();
    let mut stack = GcsStack::new(ctrl, b, params, cfg.path.clone());
    let out = run_with(scene, cfg, &mut stack, progress)?;
    let b = stack.bridge();
    let mut s = String::from("ground stations:");
    for e in &b.endpoints {
        s.push_str(&format!(
            " --{} sending to {} (datagrams sent {}, received {}, dropped {});",
            e.name,
            e.remote(),
            e.sent,
            e.received,
            e.dropped
        ));
    }
    Ok((out, s))
}

/// Flush the `.tlog`; the line for stderr (endpoints and their counters, tlog frames).
pub fn finish(bridge: &Rc<RefCell<Bridge>>, dir: &Path) -> Result<String, CliError> {
    let mut b = bridge.borrow_mut();
    b.finish().map_err(|e| anyhow!("cannot write {}: {e}", dir.join(TLOG).display()))?;
    let mut s = format!("{TLOG}: {} frames", b.tlog.as_ref().map_or(0, |t| t.frames));
    for e in &b.endpoints {
        s.push_str(&format!(
            "; --{} sending to {} (datagrams sent {}, received {}, dropped {})",
            e.name,
            e.remote(),
            e.sent,
            e.received,
            e.dropped
        ));
    }
    if b.slept > std::time::Duration::ZERO {
        s.push_str(&format!("; --realtime slept {:.1} s", b.slept.as_secs_f64()));
    }
    Ok(s)
}
