//! Processor-in-the-loop (PIL): the real firmware binary (`parapet-firmware-qemu`, the
//! `board-qemu` build of `firmware/`) runs in `qemu-system-arm -machine netduinoplus2
//! -icount shift=0` and flies the scene against the 6-DOF plant of [`crate::runner`].
//!
//! The link follows the "QEMU lockstep protocol" of `firmware/README.md` exactly: a TCP
//! chardev on a free localhost port (TCP_NODELAY on both sides), the HEARTBEAT handshake,
//! the instruction calibration (`ins_cal_n`, `ins_cal`), then per 1 ms control period the host
//! sends (ODOMETRY and the obstacle batch at the outer rate, commands, then HIL_SENSOR) and
//! waits for the HIL_ACTUATOR_CONTROLS of that period; simulated time advances only then.
//! MAVLink v2 encoding/decoding is the `mavlink` crate (the firmware's version and dialect).
//!
//! [`PilLink`] implements [`Autopilot`], so [`crate::runner::run_with`] drives the firmware
//! exactly like the in-process controller and the report is the same as `parapet run`'s.
//!
//! ## Start-up (before simulated t = 0, plant frozen in hover at the start)
//! Firmware clock = [`clock_us`] (simulated time + 1 s). Pre-roll steps from
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
//! answers it); no answer within [`PilOptions::timeout`] → error. As [`Autopilot`] cannot
//! return errors, a failure latches: the link outputs zero throttle from then on (the run
//! ends quickly with a ground contact) and [`run_pil`] returns the error.

use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use mavlink::dialects::ardupilotmega::{
    MavCmd, MavFrame, MavMessage, MavMissionResult, MavModeFlag, MavParamType, MavResult, MavState,
    COMMAND_LONG_DATA, DEBUG_VECT_DATA, HEARTBEAT_DATA, HIL_SENSOR_DATA, MISSION_COUNT_DATA,
    MISSION_ITEM_INT_DATA, OBSTACLE_DISTANCE_3D_DATA, ODOMETRY_DATA, PARAM_SET_DATA,
};
use mavlink::{MAVLinkV2MessageRaw, MavHeader, MavlinkReader, MavlinkVersion, MessageData};
use nalgebra::Vector3;
use parapet_core::controller::{ControllerParams, FlightController, PositionFix};
use parapet_core::estimator::ImuSample;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::params;
use parapet_core::waypoint::WaypointFollower;
use parapet_core::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::control::{clock_us, region_name, Autopilot, OuterOut};
use crate::runner::{run_with, RunConfig, RunOutput, OUTER_DIVIDER};
use crate::scene::{to_f32, to_f64, Scene};
use crate::sensors::{ImuReading, PositionReading};

/// Debian/Ubuntu package (and binary) of the emulator.
pub const QEMU_PACKAGE: &str = "qemu-system-arm";
/// Firmware binary of the `board-qemu` build.
pub const FIRMWARE_BIN: &str = "parapet-firmware-qemu";
/// Rust target of the firmware.
pub const FIRMWARE_TARGET: &str = "thumbv7em-none-eabihf";
/// Environment variable with the path of a prebuilt QEMU firmware ELF (set by `cargo xtask test`).
pub const ELF_ENV: &str = "PARAPET_FIRMWARE_QEMU_ELF";
/// Outer period of the firmware's lockstep schedule, µs.
const OUTER_US: u64 = 4_000;
/// `obstacle_id` of the empty obstacle batch.
const CLEAR_ID: u16 = 65_535;
/// MISSION_ITEM_INT x, y scale in `MAV_FRAME_LOCAL_NED` (metres × 10⁴).
const LOCAL_XY_SCALE: f64 = 1e4;
/// Host system / component id on the link.
const HOST_SYS: u32 = 255;
const HOST_COMP: u8 = 190;
/// Warm-up of the estimator before arming, steps (1 ms).
const WARMUP_STEPS: u64 = 300;

/// Faults injected into the host → firmware stream during the flight (not the start-up).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultInjection {
    /// Probability that a frame other than HIL_SENSOR is sent with one payload byte flipped (CRC error).
    pub corrupt_rate: f64,
    /// Probability that a frame other than HIL_SENSOR is not sent at all.
    pub drop_rate: f64,
    /// Lose the HIL_SENSOR of every n-th flight step (the host must time out and re-send it).
    pub lose_trigger_every: Option<u64>,
    /// Seed of the injection draws.
    pub seed: u64,
}

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
}

impl PilOptions {
    /// Defaults: timeout 3 s, re-send after 1 s, no faults.
    pub fn new(firmware: PathBuf) -> Self {
        PilOptions {
            firmware,
            qemu: QEMU_PACKAGE.into(),
            timeout: Duration::from_secs(3),
            resend_after: Duration::from_secs(1),
            faults: FaultInjection::default(),
        }
    }
}

/// Instructions per control step (firmware's `ins_step`: inner step + outer step when due +
/// obstacle batch, counted by the `-icount shift=0` SysTick and calibrated by the firmware with
/// `ins_cal_n` instructions = `ins_cal` ticks).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct InstructionFigures {
    /// Mean over the flight steps.
    pub mean: f64,
    /// Max over the flight steps.
    pub max: u64,
    /// Mean over the steps with an outer step.
    pub mean_outer_steps: f64,
    /// Mean over the inner-only steps.
    pub mean_inner_only_steps: f64,
    /// The outer step alone (`step_outer`: waypoint, PD, CBF filter, thrust mapping; the
    /// firmware's `ins_outer`), mean over the outer steps.
    pub mean_outer_loop: f64,
    /// The outer step alone, max.
    pub max_outer_loop: u64,
    /// Steps counted.
    pub steps: u64,
    /// Calibration: instructions of the calibration loop (`ins_cal_n`).
    pub calibration_instructions: i64,
    /// Calibration: SysTick ticks they took (`ins_cal`).
    pub calibration_ticks: i64,
    /// Lower bound of the worst step on a 168 MHz Cortex-M4 (max / 168), µs.
    pub max_time_at_168mhz_us: f64,
}

/// PIL figures added to `summary.json` (object `pil`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PilFigures {
    /// Firmware ELF flown.
    pub firmware: String,
    /// MAVLink frames the host sent (injected drops not counted; re-sent HIL_SENSORs counted).
    pub frames_sent: u64,
    /// CRC-valid MAVLink frames received from the firmware.
    pub frames_received: u64,
    /// Frames lost on the link: host-side (firmware frames missing by sequence number, or
    /// undecodable) + the firmware's counters (CRC errors + malformed, last `DEBUG_VECT LINK`;
    /// replies dropped + inbound messages rejected, last `DEBUG_VECT LINK_DROP`).
    pub frames_dropped: u64,
    /// Firmware frames the host found missing (sequence gaps).
    pub host_sequence_gaps: u64,
    /// Firmware frames the host could not decode.
    pub host_decode_errors: u64,
    /// Firmware's count of host frames with a bad CRC (last `LINK` report; 1 Hz).
    pub firmware_crc_errors: u64,
    /// Firmware's count of malformed host frames (last `LINK` report).
    pub firmware_malformed: u64,
    /// Firmware's count of good host frames (last `LINK` report).
    pub firmware_frames_ok: u64,
    /// Firmware's replies dropped because its reply queue was full (last `LINK_DROP`, 1 Hz).
    pub firmware_replies_dropped: u64,
    /// Firmware's count of rejected inbound messages (undecodable, bad ODOMETRY, unknown
    /// parameter; last `LINK_DROP`).
    pub firmware_inputs_rejected: u64,
    /// Firmware's count of obstacle points rejected or dropped (batch full; last `LINK_DROP`).
    pub firmware_obstacles_rejected: u64,
    /// Host frames corrupted on purpose (fault injection).
    pub injected_corrupted: u64,
    /// Host frames dropped on purpose (fault injection, HIL_SENSORs included).
    pub injected_dropped: u64,
    /// HIL_SENSORs re-sent after [`PilOptions::resend_after`] without an answer.
    pub steps_resent: u64,
    /// Lockstep steps of the flight (after the start-up).
    pub flight_steps: u64,
    /// Lockstep steps of the start-up (parameters, mission upload, warm-up, arming).
    pub startup_steps: u64,
    /// Instructions per control step.
    pub instructions_per_control_step: InstructionFigures,
    /// Simulated time flown / wall time of the flight steps.
    pub real_time_factor: f64,
    /// Mean wall time per flight step, ms.
    pub wall_per_step_ms: f64,
    /// Wall time of the handshake and start-up, s.
    pub startup_wall_s: f64,
    /// Firmware failsafe / status messages seen (STATUSTEXT).
    pub status_texts: Vec<String>,
}

/// Where `cargo build` puts the QEMU firmware ELF (`CARGO_TARGET_DIR` or `<workspace>/target`).
pub fn default_firmware_path() -> PathBuf {
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("target"));
    target_dir.join(FIRMWARE_TARGET).join("release").join(FIRMWARE_BIN)
}

/// The workspace this crate was built from.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_else(|| ".".into())
}

/// The `cargo build` command of the QEMU firmware (run in the workspace root).
pub fn firmware_build_command() -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.args(["build", "--release", "-p", "parapet-firmware", "--target", FIRMWARE_TARGET])
        .args(["--no-default-features", "--features", "board-qemu", "--bin", FIRMWARE_BIN])
        .current_dir(workspace_root());
    c
}

/// `true` when `path` starts with the ELF magic (0x7f 'E' 'L' 'F').
pub fn is_elf(path: &Path) -> bool {
    let mut magic = [0u8; 4];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)).is_ok() && magic == *b"\x7fELF"
}

/// Build the QEMU firmware (cargo: a no-op when up to date) and return the ELF path.
pub fn build_firmware() -> Result<PathBuf> {
    let mut cmd = firmware_build_command();
    eprintln!("parapet pil: building the firmware: {cmd:?}");
    let status = cmd.status().context("cannot start cargo to build the firmware")?;
    if !status.success() {
        bail!("building the QEMU firmware failed ({status}); command: {cmd:?}");
    }
    let elf = default_firmware_path();
    if !elf.exists() {
        bail!("the firmware build succeeded but {} does not exist", elf.display());
    }
    Ok(elf)
}

/// The firmware ELF: `$PARAPET_FIRMWARE_QEMU_ELF` when set, else built with [`build_firmware`].
pub fn firmware_from_env_or_build() -> Result<PathBuf> {
    match std::env::var_os(ELF_ENV) {
        Some(p) => Ok(PathBuf::from(p)),
        None => build_firmware(),
    }
}

/// The controller parameters the firmware flies with for `scene` and `cfg`: exactly those of
/// `parapet run` ([`crate::control::controller_params`]: the scene's vehicle, the run's CBF,
/// tracking and speed settings), with the PARAM_SET sequence that takes the firmware from its
/// boot defaults (`ControllerParams::default()`) there, in an order in which every intermediate
/// set validates ([`parapet_core::params::plan_updates`]). Errors name a setting the firmware
/// has no parameter for.
pub fn firmware_params(
    scene: &Scene,
    cfg: &RunConfig,
) -> Result<(ControllerParams, Vec<(&'static str, f32)>)> {
    let p = crate::control::controller_params(scene, cfg, cfg.cbf_params()?, cfg.variant);
    let mut out = [("", 0.0f32); params::COUNT];
    let n = params::plan_updates(&ControllerParams::default(), &p, &mut out).map_err(|e| match e {
        params::PlanError::InvalidTarget => match p.validate() {
            Err(e) => anyhow!("{}", crate::validate::describe_param_error(scene, &p, e)),
            Ok(()) => anyhow!("controller parameters rejected by the firmware's parameter plan"),
        },
        params::PlanError::NotSettable(field) => {
            anyhow!("the run's controller `{field}` settings cannot be given to the firmware (no parameter for them)")
        }
        params::PlanError::NoValidOrder(name) => {
            anyhow!("no order of PARAM_SETs keeps the firmware's parameters valid (stuck at {name})")
        }
    })?;
    Ok((p, out[..n].to_vec()))
}

/// The path as the firmware stores it after MISSION_ITEM_INT (x, y quantised to 0.1 mm), NED.
pub fn quantised_path(path: &[Vector3<f64>]) -> Vec<Vec3> {
    path.iter()
        .map(|w| {
            let (x, y) = mission_xy(w);
            Vec3::new((x as f64 / LOCAL_XY_SCALE) as f32, (y as f64 / LOCAL_XY_SCALE) as f32, w.z as f32)
        })
        .collect()
}

fn mission_xy(w: &Vector3<f64>) -> (i32, i32) {
    ((w.x * LOCAL_XY_SCALE).round() as i32, (w.y * LOCAL_XY_SCALE).round() as i32)
}

/// First pre-roll step time, µs, for a path of `n_wp` waypoints (a multiple of the outer period
/// before `t0_us`).
fn preroll_start(t0_us: u64, n_params: usize, n_wp: usize) -> u64 {
    let steps = (n_params + 2 * n_wp + 8) as u64 + WARMUP_STEPS + OUTER_DIVIDER;
    let steps = steps.div_ceil(OUTER_DIVIDER) * OUTER_DIVIDER;
    t0_us.saturating_sub(steps * 1000)
}

/// Kills QEMU when dropped.
struct QemuGuard {
    child: Child,
    stderr: Arc<Mutex<String>>,
}

impl Drop for QemuGuard {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl QemuGuard {
    fn stderr_text(&self) -> String {
        self.stderr.lock().map(|s| s.trim().to_string()).unwrap_or_default()
    }
}

enum Inbound {
    Msg(MavHeader, Box<MavMessage>),
    DecodeError,
    Closed(String),
}

/// Answer of one lockstep step.
#[derive(Debug, Default)]
struct StepAnswer {
    throttle: [f32; 4],
    replies: Vec<MavMessage>,
}

/// Latest filter report of the firmware.
#[derive(Clone, Copy, Debug)]
struct FilterTelemetry {
    h_bar: f64,
    region_code: u8,
    active: Option<u16>,
    flags: i32,
    /// Nominal acceleration u* (`DEBUG_VECT U_NOM`), NED m/s²; NaN before the first report.
    u_nominal: Vector3<f64>,
    /// Filtered acceleration u (POSITION_TARGET_LOCAL_NED afx..afz), NED m/s²; NaN before.
    u_filtered: Vector3<f64>,
}

/// The firmware in QEMU behind the [`Autopilot`] interface.
pub struct PilLink {
    qemu: QemuGuard,
    sock: TcpStream,
    rx: Receiver<Inbound>,
    opts: PilOptions,
    seq: u8,
    queue: Vec<Vec<u8>>,
    rng: ChaCha8Rng,
    in_flight: bool,
    last_fw_seq: Option<u8>,
    fig: PilFigures,
    ins: Vec<(u64, bool)>,
    /// `ins_outer` of the flight steps, and the one of the step being answered.
    ins_outer: Vec<u64>,
    pending_outer: Option<(u64, u64)>,
    /// PARAM_SETs of the start-up (name, value), in order.
    param_updates: Vec<(&'static str, f32)>,
    path: Vec<Vector3<f64>>,
    cbf: bool,
    follower: WaypointFollower<{ parapet_core::controller::PATH_CAPACITY }>,
    mission_t0_us: Option<u64>,
    mission_start_pending: bool,
    filter: FilterTelemetry,
    phase: u32,
    armed: bool,
    critical: bool,
    last_t_us: u64,
    fault: Option<String>,
    flight_wall: Duration,
    flight_sim_steps: u64,
}

impl PilLink {
    /// Start QEMU with the firmware, connect, handshake. `scene` and `cfg` give the parameters
    /// (see [`firmware_params`]) and the path (sent in [`Autopilot::start`]).
    pub fn spawn(scene: &Scene, cfg: &RunConfig, opts: PilOptions) -> Result<PilLink> {
        let (params, param_updates) = firmware_params(scene, cfg)?;
        if cfg.path.len() > parapet_core::controller::PATH_CAPACITY {
            bail!("the path has {} waypoints; the firmware stores at most 64", cfg.path.len());
        }
        if !opts.firmware.is_file() {
            bail!(
                "firmware ELF {} not found; build it with: {:?} (or omit --firmware to build it)",
                opts.firmware.display(),
                firmware_build_command()
            );
        }
        let wall = Instant::now();
        let (qemu, sock) = start_qemu(&opts)?;
        sock.set_nodelay(true).context("TCP_NODELAY")?;
        sock.set_write_timeout(Some(opts.timeout)).context("socket write timeout")?;
        let read_half = sock.try_clone().context("socket clone")?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || reader_thread(read_half, tx));
        let mut follower = WaypointFollower::new(params.waypoint)
            .map_err(|e| anyhow!("waypoint parameters: {}", crate::validate::describe_path_error(e)))?;
        follower
            .set_path(&quantised_path(&cfg.path))
            .map_err(|e| anyhow!("path rejected: {}", crate::validate::describe_path_error(e)))?;
        let mut link = PilLink {
            qemu,
            sock,
            rx,
            seq: 0,
            queue: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(opts.faults.seed),
            opts,
            in_flight: false,
            last_fw_seq: None,
            fig: PilFigures::default(),
            ins: Vec::new(),
            ins_outer: Vec::new(),
            pending_outer: None,
            param_updates,
            path: cfg.path.clone(),
            cbf: cfg.cbf,
            follower,
            mission_t0_us: None,
            mission_start_pending: false,
            filter: FilterTelemetry {
                h_bar: f64::INFINITY,
                region_code: 0,
                active: None,
                flags: 0,
                u_nominal: Vector3::repeat(f64::NAN),
                u_filtered: Vector3::repeat(f64::NAN),
            },
            phase: 0,
            armed: false,
            critical: false,
            last_t_us: 0,
            fault: None,
            flight_wall: Duration::ZERO,
            flight_sim_steps: 0,
        };
        link.fig.firmware = link.opts.firmware.display().to_string();
        link.handshake().map_err(|e| link.with_qemu_log(e))?;
        link.fig.startup_wall_s = wall.elapsed().as_secs_f64();
        Ok(link)
    }

    /// Process id of QEMU (for fault-injection tests: SIGSTOP / kill).
    pub fn qemu_pid(&self) -> u32 {
        self.qemu.child.id()
    }

    /// The latched failure, if the link failed during the flight.
    pub fn fault(&self) -> Option<&str> {
        self.fault.as_deref()
    }

    /// Figures so far.
    pub fn figures(&self) -> PilFigures {
        let mut f = self.fig.clone();
        f.frames_dropped = f.host_sequence_gaps
            + f.host_decode_errors
            + f.firmware_crc_errors
            + f.firmware_malformed
            + f.firmware_replies_dropped
            + f.firmware_inputs_rejected;
        f.flight_steps = self.flight_sim_steps;
        let wall = self.flight_wall.as_secs_f64();
        if wall > 0.0 {
            f.real_time_factor = self.flight_sim_steps as f64 * 1e-3 / wall;
            f.wall_per_step_ms = wall * 1e3 / self.flight_sim_steps.max(1) as f64;
        }
        let mean = |v: &mut dyn Iterator<Item = u64>| {
            let (s, n) = v.fold((0.0, 0u64), |(s, n), x| (s + x as f64, n + 1));
            if n > 0 {
                s / n as f64
            } else {
                0.0
            }
        };
        let i = &mut f.instructions_per_control_step;
        i.steps = self.ins.len() as u64;
        i.mean = mean(&mut self.ins.iter().map(|x| x.0));
        i.max = self.ins.iter().map(|x| x.0).max().unwrap_or(0);
        i.mean_outer_steps = mean(&mut self.ins.iter().filter(|x| x.1).map(|x| x.0));
        i.mean_inner_only_steps = mean(&mut self.ins.iter().filter(|x| !x.1).map(|x| x.0));
        i.mean_outer_loop = mean(&mut self.ins_outer.iter().copied());
        i.max_outer_loop = self.ins_outer.iter().copied().max().unwrap_or(0);
        i.max_time_at_168mhz_us = i.max as f64 / 168.0;
        f
    }

    fn with_qemu_log(&self, e: anyhow::Error) -> anyhow::Error {
        let log = self.qemu.stderr_text();
        if log.is_empty() {
            e
        } else {
            e.context(format!("QEMU stderr: {log}"))
        }
    }

    fn header(&mut self) -> MavHeader {
        let h = MavHeader { system_id: HOST_SYS, component_id: HOST_COMP, sequence: self.seq };
        self.seq = self.seq.wrapping_add(1);
        h
    }

    /// Queue `m` for the next step (sent before its HIL_SENSOR).
    fn queue<D: MessageData>(&mut self, m: &D) {
        let mut raw = MAVLinkV2MessageRaw::new();
        let h = self.header();
        raw.serialize_message_data(h, m);
        self.queue.push(raw.raw_bytes().to_vec());
    }

    fn write_all(&mut self, bytes: &[u8]) -> Result<()> {
        self.sock
            .write_all(bytes)
            .context("cannot write to QEMU's serial socket (firmware stalled or QEMU gone)")
    }

    /// Next inbound message within `timeout`.
    fn recv(&mut self, timeout: Duration) -> Result<Option<MavMessage>> {
        match self.rx.recv_timeout(timeout) {
            Ok(Inbound::Msg(h, m)) => {
                if h.system_id == 1 {
                    if let Some(last) = self.last_fw_seq {
                        self.fig.host_sequence_gaps +=
                            u64::from(h.sequence.wrapping_sub(last.wrapping_add(1)));
                    }
                    self.last_fw_seq = Some(h.sequence);
                }
                self.fig.frames_received += 1;
                self.observe(&m);
                Ok(Some(*m))
            }
            Ok(Inbound::DecodeError) => {
                self.fig.host_decode_errors += 1;
                Ok(None)
            }
            Ok(Inbound::Closed(why)) => Err(self.with_qemu_log(anyhow!("QEMU closed the link: {why}"))),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(anyhow!("link reader stopped")),
        }
    }

    /// Telemetry bookkeeping for every inbound message.
    fn observe(&mut self, m: &MavMessage) {
        match m {
            MavMessage::DEBUG_VECT(d) => match d.name.to_str().unwrap_or("") {
                "U_NOM" => self.filter.u_nominal = Vector3::new(d.x, d.y, d.z).cast(),
                "CBF" => {
                    self.filter.h_bar = d.x as f64;
                    self.filter.region_code = if d.y.is_finite() { d.y.clamp(0.0, 4.0) as u8 } else { 4 };
                    self.filter.active = (d.z >= 0.0 && d.z.is_finite()).then_some(d.z as u16);
                }
                "LINK" => {
                    self.fig.firmware_frames_ok = d.x.max(0.0) as u64;
                    self.fig.firmware_crc_errors = d.y.max(0.0) as u64;
                    self.fig.firmware_malformed = d.z.max(0.0) as u64;
                }
                "LINK_DROP" => {
                    self.fig.firmware_replies_dropped = d.x.max(0.0) as u64;
                    self.fig.firmware_inputs_rejected = d.y.max(0.0) as u64;
                    self.fig.firmware_obstacles_rejected = d.z.max(0.0) as u64;
                }
                _ => {}
            },
            MavMessage::NAMED_VALUE_INT(n) => {
                let name = n.name.to_str().unwrap_or("");
                match name {
                    "CBF_FLAGS" => self.filter.flags = n.value,
                    "ins_cal" => self.fig.instructions_per_control_step.calibration_ticks = n.value.into(),
                    "ins_cal_n" => {
                        self.fig.instructions_per_control_step.calibration_instructions = n.value.into()
                    }
                    _ => {}
                }
            }
            MavMessage::POSITION_TARGET_LOCAL_NED(p) => {
                self.filter.u_filtered = Vector3::new(p.afx, p.afy, p.afz).cast();
            }
            MavMessage::HEARTBEAT(h) => {
                self.phase = h.custom_mode;
                self.armed = h.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                self.critical = h.system_status == MavState::MAV_STATE_CRITICAL;
            }
            MavMessage::STATUSTEXT(s) => {
                let text = String::from_utf8_lossy(&s.text[..]).trim_end_matches('\0').to_string();
                if self.fig.status_texts.len() < 64 {
                    self.fig.status_texts.push(format!("{:?}: {text}", s.severity));
                }
            }
            _ => {}
        }
    }

    fn handshake(&mut self) -> Result<()> {
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!("no HEARTBEAT from the firmware within 20 s of connecting");
            }
            if let Some(MavMessage::HEARTBEAT(_)) = self.recv(left.min(Duration::from_millis(200)))? {
                break;
            }
        }
        self.queue(&HEARTBEAT_DATA::default());
        let frames = std::mem::take(&mut self.queue);
        for f in &frames {
            self.write_all(f)?;
            self.fig.frames_sent += 1;
        }
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut ready = false;
        while !ready {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!("no \"parapet PIL ready\" within 10 s of the host HEARTBEAT");
            }
            if let Some(MavMessage::STATUSTEXT(s)) = self.recv(left.min(Duration::from_millis(200)))? {
                ready = String::from_utf8_lossy(&s.text[..]).contains("PIL ready");
            }
        }
        let i = &self.fig.instructions_per_control_step;
        if i.calibration_ticks <= 0 || i.calibration_instructions <= 0 {
            bail!("the firmware sent no instruction calibration (ins_cal, ins_cal_n) before \"PIL ready\"");
        }
        Ok(())
    }

    /// One lockstep step at firmware time `t_us`: queued frames, HIL_SENSOR, wait for the answer.
    fn step(&mut self, t_us: u64, imu: &ImuReading) -> Result<StepAnswer> {
        let inject = self.in_flight;
        let frames = std::mem::take(&mut self.queue);
        let mut out = Vec::new();
        for mut f in frames {
            if inject
                && self.opts.faults.drop_rate > 0.0
                && self.rng.random::<f64>() < self.opts.faults.drop_rate
            {
                self.fig.injected_dropped += 1;
                continue;
            }
            if inject
                && self.opts.faults.corrupt_rate > 0.0
                && self.rng.random::<f64>() < self.opts.faults.corrupt_rate
            {
                // Flip one payload byte (header is 10 bytes, CRC the last 2): a CRC error.
                let n = f.len();
                let i = 10 + self.rng.random_range(0..(n - 12).max(1));
                f[i.min(n - 3)] ^= 0x5A;
                self.fig.injected_corrupted += 1;
            }
            out.extend_from_slice(&f);
            self.fig.frames_sent += 1;
        }
        let hil = HIL_SENSOR_DATA {
            time_usec: t_us,
            xgyro: imu.gyro.x as f32,
            ygyro: imu.gyro.y as f32,
            zgyro: imu.gyro.z as f32,
            xacc: imu.accel.x as f32,
            yacc: imu.accel.y as f32,
            zacc: imu.accel.z as f32,
            ..Default::default()
        };
        let mut raw = MAVLinkV2MessageRaw::new();
        let h = self.header();
        raw.serialize_message_data(h, &hil);
        let trigger = raw.raw_bytes().to_vec();
        let lose = inject
            && self
                .opts
                .faults
                .lose_trigger_every
                .is_some_and(|n| n > 0 && (self.flight_sim_steps + 1).is_multiple_of(n));
        if lose {
            self.fig.injected_dropped += 1;
        } else {
            out.extend_from_slice(&trigger);
            self.fig.frames_sent += 1;
        }
        self.write_all(&out)?;
        let sent = Instant::now();
        let mut last_send = sent;
        let mut ans = StepAnswer::default();
        loop {
            let now = Instant::now();
            if now.duration_since(sent) >= self.opts.timeout {
                bail!(
                    "the firmware stopped answering: no HIL_ACTUATOR_CONTROLS for t = {t_us} µs within {:.1} s",
                    self.opts.timeout.as_secs_f64()
                );
            }
            if now.duration_since(last_send) >= self.opts.resend_after {
                self.write_all(&trigger)?;
                self.fig.frames_sent += 1;
                self.fig.steps_resent += 1;
                last_send = now;
            }
            let wait = (sent + self.opts.timeout)
                .min(last_send + self.opts.resend_after)
                .saturating_duration_since(now)
                .max(Duration::from_millis(1));
            let Some(m) = self.recv(wait)? else { continue };
            match m {
                MavMessage::HIL_ACTUATOR_CONTROLS(c) if c.time_usec == t_us => {
                    ans.throttle = [c.controls[0], c.controls[1], c.controls[2], c.controls[3]];
                    if !c.mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED) {
                        ans.throttle = [0.0; 4];
                    }
                    break;
                }
                MavMessage::HIL_ACTUATOR_CONTROLS(_) => {} // answer to a re-sent older step
                MavMessage::NAMED_VALUE_INT(n)
                    if n.name.to_str().unwrap_or("") == "ins_outer"
                        && n.time_boot_ms as u64 == t_us / 1000
                        && self.in_flight =>
                {
                    self.pending_outer = Some((t_us, n.value.max(0) as u64));
                }
                MavMessage::NAMED_VALUE_INT(n)
                    if n.name.to_str().unwrap_or("") == "ins_step"
                        && n.time_boot_ms as u64 == t_us / 1000
                        && self.in_flight =>
                {
                    // `ins_outer` comes first in the answer of a step that ran the outer loop.
                    let outer = self.pending_outer.take().filter(|p| p.0 == t_us).map(|p| p.1);
                    self.ins_outer.extend(outer);
                    self.ins.push((n.value.max(0) as u64, outer.is_some()));
                }
                m @ (MavMessage::COMMAND_ACK(_)
                | MavMessage::MISSION_REQUEST_INT(_)
                | MavMessage::MISSION_ACK(_)
                | MavMessage::PARAM_VALUE(_)) => ans.replies.push(m),
                MavMessage::STATUSTEXT(s) if String::from_utf8_lossy(&s.text[..]).contains("PANIC") => {
                    bail!("the firmware panicked (STATUSTEXT PANIC) at t = {t_us} µs");
                }
                _ => {}
            }
        }
        self.last_t_us = t_us;
        Ok(ans)
    }

    fn queue_odometry(&mut self, t_us: u64, fix: &PositionReading) {
        let q = fix_quaternion(fix.yaw);
        self.queue(&ODOMETRY_DATA {
            time_usec: t_us,
            x: fix.position.x as f32,
            y: fix.position.y as f32,
            z: fix.position.z as f32,
            vx: fix.velocity.x as f32,
            vy: fix.velocity.y as f32,
            vz: fix.velocity.z as f32,
            q,
            frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            ..Default::default()
        });
    }

    fn queue_obstacles(&mut self, t_us: u64, obstacles: &[ObstaclePoint]) {
        let time_boot_ms = (t_us / 1000) as u32;
        let shown: &[ObstaclePoint] = if self.cbf { obstacles } else { &[] };
        if shown.is_empty() {
            self.queue(&OBSTACLE_DISTANCE_3D_DATA {
                time_boot_ms,
                obstacle_id: CLEAR_ID,
                frame: MavFrame::MAV_FRAME_LOCAL_NED,
                ..Default::default()
            });
            return;
        }
        for o in shown {
            if let Some(v) = o.velocity.filter(|v| v.iter().any(|c| *c != 0.0)) {
                self.queue(&DEBUG_VECT_DATA {
                    time_usec: t_us,
                    x: v.x,
                    y: v.y,
                    z: v.z,
                    name: char_array(&format!("OBV{}", o.id)),
                });
            }
            self.queue(&OBSTACLE_DISTANCE_3D_DATA {
                time_boot_ms,
                obstacle_id: o.id,
                frame: MavFrame::MAV_FRAME_LOCAL_NED,
                x: o.point.x,
                y: o.point.y,
                z: o.point.z,
                ..Default::default()
            });
        }
    }

    fn command(&mut self, command: MavCmd, p: [f32; 7]) {
        self.queue(&COMMAND_LONG_DATA {
            param1: p[0],
            param2: p[1],
            param3: p[2],
            param4: p[3],
            param5: p[4],
            param6: p[5],
            param7: p[6],
            command,
            target_system: 1,
            target_component: 1,
            confirmation: 0,
        });
    }

    /// Start-up before `t0_us` (see the module docs).
    fn startup(
        &mut self,
        t0_us: u64,
        start: Vector3<f64>,
        fix: &PositionReading,
        obstacles: &[ObstaclePoint],
        imu: &ImuReading,
    ) -> Result<()> {
        let table = self.param_updates.clone();
        let path = self.path.clone();
        let mut t = preroll_start(t0_us, table.len(), path.len());
        let mut steps = 0u64;
        // Parameters, one per step, each checked.
        for (name, value) in table {
            self.queue(&PARAM_SET_DATA {
                param_value: value,
                target_system: 1,
                target_component: 1,
                param_id: char_array(name),
                param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
            });
            let ans = self.step(t, imu)?;
            t += 1000;
            steps += 1;
            let got = ans.replies.iter().find_map(|m| match m {
                MavMessage::PARAM_VALUE(v) if v.param_id.to_str().unwrap_or("") == name => {
                    Some(v.param_value)
                }
                _ => None,
            });
            match got {
                Some(v) if v == value => {}
                Some(v) => bail!("the firmware refused parameter {name} = {value} (value in effect {v})"),
                None => bail!("no PARAM_VALUE answer to PARAM_SET {name}"),
            }
        }
        // Mission upload.
        self.queue(&MISSION_COUNT_DATA { count: path.len() as u16, target_system: 1, target_component: 1 });
        let mut accepted = false;
        for _ in 0..(4 * path.len() + 8) {
            let ans = self.step(t, imu)?;
            t += 1000;
            steps += 1;
            for m in &ans.replies {
                match m {
                    MavMessage::MISSION_REQUEST_INT(r) => {
                        let w = path
                            .get(r.seq as usize)
                            .ok_or_else(|| anyhow!("the firmware requested mission item {}", r.seq))?;
                        let (x, y) = mission_xy(w);
                        self.queue(&MISSION_ITEM_INT_DATA {
                            x,
                            y,
                            z: w.z as f32,
                            seq: r.seq,
                            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                            frame: MavFrame::MAV_FRAME_LOCAL_NED,
                            target_system: 1,
                            target_component: 1,
                            autocontinue: 1,
                            ..Default::default()
                        });
                    }
                    MavMessage::MISSION_ACK(a) if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED => {
                        accepted = true
                    }
                    MavMessage::MISSION_ACK(a) => bail!("the firmware refused the mission: {:?}", a.mavtype),
                    _ => {}
                }
            }
            if accepted {
                break;
            }
        }
        if !accepted {
            bail!("mission upload did not complete");
        }
        let warmup_from = t0_us - (WARMUP_STEPS + OUTER_DIVIDER) * 1000;
        if t > warmup_from {
            bail!("internal: pre-roll too short for the start-up");
        }
        // Warm-up with fixes and obstacles at the outer rate; arm and hold the start at T0 − 4 ms.
        while t < t0_us {
            if (t0_us - t).is_multiple_of(OUTER_US) && t > warmup_from {
                self.queue_odometry(t, fix);
                self.queue_obstacles(t, obstacles);
            }
            let arm_step = t == t0_us - OUTER_US;
            if arm_step {
                self.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
                let s = to_f32(&start);
                self.command(MavCmd::MAV_CMD_OVERRIDE_GOTO, [0.0, 3.0, 1.0, 0.0, s.x, s.y, s.z]);
            }
            let ans = self.step(t, imu)?;
            steps += 1;
            if arm_step {
                let acks: Vec<_> = ans
                    .replies
                    .iter()
                    .filter_map(|m| match m {
                        MavMessage::COMMAND_ACK(a) => Some((a.command, a.result)),
                        _ => None,
                    })
                    .collect();
                for cmd in [MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, MavCmd::MAV_CMD_OVERRIDE_GOTO] {
                    match acks.iter().find(|a| a.0 == cmd) {
                        Some((_, MavResult::MAV_RESULT_ACCEPTED)) => {}
                        Some((_, r)) => bail!("the firmware refused {cmd:?}: {r:?}"),
                        None => bail!("no COMMAND_ACK for {cmd:?}"),
                    }
                }
            }
            t += 1000;
        }
        self.fig.startup_steps = steps;
        // MISSION_START goes with the first flight step (processed at T0 − 1 ms).
        self.mission_start_pending = true;
        self.mission_t0_us = Some(t0_us - 1000);
        // Armed and holding (both acknowledged); the 1 Hz HEARTBEAT takes over from here.
        (self.armed, self.phase) = (true, 4);
        self.follower
            .start(to_f32(&start))
            .map_err(|e| anyhow!("follower: {}", crate::validate::describe_path_error(e)))?;
        self.in_flight = true;
        Ok(())
    }

    fn latch(&mut self, e: anyhow::Error) {
        if self.fault.is_none() {
            self.fault = Some(format!("{:#}", self.with_qemu_log(e)));
        }
    }
}

impl Drop for PilLink {
    fn drop(&mut self) {
        let _ = self.sock.shutdown(Shutdown::Both);
    }
}

impl Autopilot for PilLink {
    fn start(
        &mut self,
        t: f64,
        start: Vector3<f64>,
        fix: PositionReading,
        obstacles: &[ObstaclePoint],
        imu: &ImuReading,
    ) -> Result<()> {
        let r = self.startup(clock_us(t), start, &fix, obstacles, imu);
        r.map_err(|e| self.with_qemu_log(e))
    }

    fn position_fix(&mut self, fix: PositionReading) {
        if self.fault.is_none() {
            self.queue_odometry(clock_us(fix.t_measured), &fix);
        }
    }

    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        let now = clock_us(t);
        if self.fault.is_none() {
            self.queue_obstacles(now, obstacles);
            if self.mission_start_pending {
                self.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7]);
            }
        }
        let age = now.saturating_sub(self.mission_t0_us.unwrap_or(now));
        let s = self.follower.sample(age as f32 * 1e-6);
        let f = self.filter;
        let region = region_from_code(f.region_code);
        OuterOut {
            reference: to_f64(&s.position),
            region: region.map(region_name).unwrap_or("fault"),
            region_code: f.region_code,
            active_obstacle: f.active,
            filter_active: f.flags & 1 != 0,
            path_done: s.progress.done,
            u_nominal: f.u_nominal,
            u_filtered: f.u_filtered,
            filter_h_bar: f.h_bar,
            n_constraints: ((f.flags >> 8) & 0xFF) as u8,
            unavoidable: f.flags & 2 != 0,
            infeasible: f.flags & 4 != 0,
            mode: phase_mode(self.phase),
            // Not carried by the link's filter message.
            safety: crate::report::SafetyFlags::default(),
        }
    }

    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        if self.fault.is_some() {
            return [0.0; 4];
        }
        let wall = Instant::now();
        let r = self.step(clock_us(t), imu);
        self.flight_wall += wall.elapsed();
        self.flight_sim_steps += 1;
        match r {
            Ok(ans) => {
                if self.mission_start_pending {
                    self.mission_start_pending = false;
                    let ok = ans.replies.iter().any(|m| {
                        matches!(m, MavMessage::COMMAND_ACK(a) if a.command == MavCmd::MAV_CMD_MISSION_START
                            && a.result == MavResult::MAV_RESULT_ACCEPTED)
                    });
                    if !ok {
                        self.latch(anyhow!("the firmware did not accept MISSION_START: {:?}", ans.replies));
                        return [0.0; 4];
                    }
                }
                ans.throttle
            }
            Err(e) => {
                self.latch(e);
                [0.0; 4]
            }
        }
    }

    fn state_name(&self) -> String {
        if let Some(f) = &self.fault {
            return format!("LinkFailed: {f}");
        }
        match (self.armed, self.critical, self.phase) {
            (_, true, _) => "Failsafe".into(),
            (false, _, _) => "Disarmed".into(),
            (true, _, 6) => "Failsafe".into(),
            (true, _, _) => "Armed".into(),
        }
    }
}

/// Guidance mode name (as the host controller's `GuidanceMode`) for a HEARTBEAT phase.
fn phase_mode(phase: u32) -> &'static str {
    match phase {
        0 => "Off",
        1 => "Ground",
        2 => "Takeoff",
        3 => "Hold",
        4 => "Mission",
        5 => "Land",
        6 => "Brake",
        _ => "Unknown",
    }
}

fn region_from_code(code: u8) -> Option<parapet_core::cbf::Region> {
    use parapet_core::cbf::Region;
    [Region::NoObstacle, Region::Far, Region::NominalSafe, Region::Perpendicular, Region::Fault]
        .into_iter()
        .find(|r| r.code() == code)
}

/// Attitude quaternion [w, x, y, z] of a level vehicle with heading `yaw` (body → NED).
fn fix_quaternion(yaw: f64) -> [f32; 4] {
    [(yaw / 2.0).cos() as f32, 0.0, 0.0, (yaw / 2.0).sin() as f32]
}

fn char_array<const N: usize>(s: &str) -> mavlink::types::CharArray<N> {
    let mut b = [0u8; N];
    for (d, c) in b.iter_mut().zip(s.bytes()) {
        *d = c;
    }
    b.into()
}

fn reader_thread(sock: TcpStream, tx: mpsc::Sender<Inbound>) {
    let mut reader = MavlinkReader::new(sock);
    loop {
        let ev = match reader.read_message::<MavMessage>(MavlinkVersion::V2) {
            Ok((h, m)) => Inbound::Msg(h, Box::new(m)),
            Err(mavlink::error::MessageReadError::Io(e)) => {
                let _ = tx.send(Inbound::Closed(e.to_string()));
                return;
            }
            Err(_) => Inbound::DecodeError,
        };
        if tx.send(ev).is_err() {
            return;
        }
    }
}

/// Start QEMU on a free port and connect to its serial socket.
fn start_qemu(opts: &PilOptions) -> Result<(QemuGuard, TcpStream)> {
    let mut last_err = None;
    for _attempt in 0..3 {
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .context("no free localhost port")?
            .port();
        let mut cmd = Command::new(&opts.qemu);
        cmd.args(["-machine", "netduinoplus2", "-nographic", "-monitor", "none", "-icount", "shift=0"])
            .arg("-kernel")
            .arg(&opts.firmware)
            .args([
                "-chardev",
                &format!("socket,id=c0,host=127.0.0.1,port={port},server=on,wait=off,nodelay=on"),
                "-serial",
                "chardev:c0",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        let mut child = match cmd.spawn() {
            Ok(c) => c,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!(
                "`{}` not found: QEMU is needed for processor-in-the-loop runs. Install the Debian/Ubuntu \
                 package {QEMU_PACKAGE}: sudo apt-get update && sudo apt-get install -y {QEMU_PACKAGE}",
                opts.qemu
            ),
            Err(e) => bail!("cannot start {}: {e}", opts.qemu),
        };
        let stderr = Arc::new(Mutex::new(String::new()));
        if let Some(mut pipe) = child.stderr.take() {
            let sink = stderr.clone();
            std::thread::spawn(move || {
                let mut buf = [0u8; 1024];
                while let Ok(n) = pipe.read(&mut buf) {
                    if n == 0 {
                        break;
                    }
                    if let Ok(mut s) = sink.lock() {
                        if s.len() < 16 * 1024 {
                            s.push_str(&String::from_utf8_lossy(&buf[..n]));
                        }
                    }
                }
            });
        }
        let mut guard = QemuGuard { child, stderr };
        let t0 = Instant::now();
        loop {
            if let Ok(Some(status)) = guard.child.try_wait() {
                // Port taken between our probe and QEMU's bind, or a bad ELF: retry once more.
                std::thread::sleep(Duration::from_millis(50));
                last_err = Some(anyhow!("QEMU exited ({status}): {}", guard.stderr_text()));
                break;
            }
            match TcpStream::connect(("127.0.0.1", port)) {
                Ok(s) => return Ok((guard, s)),
                Err(_) if t0.elapsed() < Duration::from_secs(10) => {
                    std::thread::sleep(Duration::from_millis(20))
                }
                Err(e) => bail!("cannot connect to QEMU's serial socket on port {port} within 10 s: {e}"),
            }
        }
    }
    Err(last_err.unwrap_or_else(|| anyhow!("QEMU did not start")))
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

/// The pure-host counterpart of [`PilLink`]: the same `parapet-core` `FlightController`, built
/// with the firmware's parameters ([`firmware_params`]), driven with the firmware's lockstep
/// sequence (pre-roll, commands at the previous step's time, obstacle batch closed at the step,
/// inner step before the outer step, fixes without yaw, quantised path). Flying a scene with
/// this and with [`PilLink`] isolates what the ARM build and the link change.
pub struct FirmwareTwin {
    fc: FlightController,
    cbf: bool,
    path: Vec<Vector3<f64>>,
    n_params: usize,
    pending_obstacles: Option<Vec<ObstaclePoint>>,
    next_outer: Option<u64>,
    last_t_us: u64,
    mission_start_pending: bool,
}

impl FirmwareTwin {
    /// Controller with the firmware's parameters for `scene` and `cfg`.
    pub fn new(scene: &Scene, cfg: &RunConfig) -> Result<Self> {
        let (p, updates) = firmware_params(scene, cfg)?;
        let n_params = updates.len();
        let mut fc = FlightController::new(p)
            .map_err(|e| anyhow!("{}", crate::validate::describe_param_error(scene, &p, e)))?;
        fc.set_path(&quantised_path(&cfg.path))
            .map_err(|e| anyhow!("{}", crate::validate::describe_command_error(e)))?;
        Ok(FirmwareTwin {
            fc,
            cbf: cfg.cbf,
            path: cfg.path.clone(),
            n_params,
            pending_obstacles: None,
            next_outer: None,
            last_t_us: 0,
            mission_start_pending: false,
        })
    }

    fn fix(&mut self, t_us: u64, fix: &PositionReading) {
        self.fc.update_position(PositionFix {
            t_us,
            position: to_f32(&fix.position),
            velocity: to_f32(&fix.velocity),
            yaw: None,
        });
    }

    fn obstacles(&mut self, obstacles: &[ObstaclePoint]) {
        self.pending_obstacles = Some(if self.cbf { obstacles.to_vec() } else { Vec::new() });
    }

    /// The firmware's lockstep step (`firmware/src/lockstep.rs`).
    fn step(&mut self, t_us: u64, imu: &ImuReading) -> [f32; 4] {
        if let Some(o) = self.pending_obstacles.take() {
            self.fc.update_obstacles(t_us, &o);
        }
        let m = self.fc.step_inner(t_us, &ImuSample { gyro: to_f32(&imu.gyro), accel: to_f32(&imu.accel) });
        if self.next_outer.is_none_or(|n| t_us >= n) {
            self.fc.step_outer(t_us);
            self.next_outer = Some(match self.next_outer {
                Some(n) if t_us - n < OUTER_US => n + OUTER_US,
                _ => t_us + OUTER_US,
            });
        }
        self.last_t_us = t_us;
        if !m.armed || m.throttle.iter().any(|x| !x.is_finite()) {
            return [0.0; 4];
        }
        m.throttle.map(|x| x.clamp(0.0, 1.0))
    }
}

impl Autopilot for FirmwareTwin {
    fn start(
        &mut self,
        t: f64,
        start: Vector3<f64>,
        fix: PositionReading,
        obstacles: &[ObstaclePoint],
        imu: &ImuReading,
    ) -> Result<()> {
        let t0 = clock_us(t);
        let t_pre = preroll_start(t0, self.n_params, self.path.len());
        // The firmware rebuilds the cascade at each PARAM_SET (processed before the step's
        // HIL_SENSOR): its history starts with the step of the last one. Its outer schedule
        // started at the first pre-roll step.
        let mut tk = t_pre + (self.n_params.max(1) as u64 - 1) * 1000;
        self.next_outer = Some(t_pre + (tk - t_pre).div_ceil(OUTER_US) * OUTER_US);
        let warmup_from = t0 - (WARMUP_STEPS + OUTER_DIVIDER) * 1000;
        while tk < t0 {
            if (t0 - tk).is_multiple_of(OUTER_US) && tk > warmup_from {
                self.fix(tk, &fix);
                self.obstacles(obstacles);
            }
            if tk == t0 - OUTER_US {
                let prev = self.last_t_us;
                self.fc.arm(prev).map_err(|e| anyhow!("{}", crate::validate::describe_command_error(e)))?;
                self.fc
                    .hold_position(prev, to_f32(&start))
                    .map_err(|e| anyhow!("hold refused: {}", crate::validate::describe_command_error(e)))?;
            }
            self.step(tk, imu);
            tk += 1000;
        }
        self.mission_start_pending = true;
        Ok(())
    }

    fn position_fix(&mut self, fix: PositionReading) {
        self.fix(clock_us(fix.t_measured), &fix);
    }

    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        self.obstacles(obstacles);
        if self.mission_start_pending {
            self.mission_start_pending = false;
            let _ = self.fc.start_mission(self.last_t_us);
        }
        let _ = t;
        OuterOut::from_telemetry(&self.fc.telemetry())
    }

    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        self.step(clock_us(t), imu)
    }

    fn state_name(&self) -> String {
        format!("{:?}", self.fc.state())
    }
}

/// Fly `scene` with the [`FirmwareTwin`] (pure host, firmware parameters and sequence).
pub fn run_twin(scene: &Scene, cfg: &RunConfig) -> Result<RunOutput> {
    let mut twin = FirmwareTwin::new(scene, cfg)?;
    run_with(scene, cfg, &mut twin, &mut |_| {})
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

    fn scene(extra: &str) -> Scene {
        let text = format!(
            "name = \"t\"\n[bounds]\nmin = [-1.0, -1.0, 0.3]\nmax = [3.0, 1.0, 2.0]\n\
             [mission]\nstart = [0.0, 0.0, 1.0]\ngoal = [2.0, 0.0, 1.0]\nspeed = 0.4\n{extra}"
        );
        Scene::parse(&text, "test scene").expect("scene parses")
    }

    /// The firmware gets exactly `parapet run`'s parameters: applying the PARAM_SETs in order to
    /// its boot defaults, each step validating as the firmware requires, gives them.
    #[test]
    fn firmware_flies_the_scenes_vehicle_and_settings() {
        let s = scene(
            "[vehicle]\nmass = 1.2\ninertia = [0.004, 0.0045, 0.007]\narm_length = 0.2\nk_f = 6.0e-6\n\
             [controller]\nvelocity_margin = 0.03\n",
        );
        let cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).expect("config");
        let (p, updates) = firmware_params(&s, &cfg).expect("representable");
        assert_eq!(
            p,
            crate::control::controller_params(&s, &cfg, cfg.cbf_params().expect("cbf"), cfg.variant)
        );
        assert_eq!(p.airframe.mass, 1.2);
        assert_eq!(p.cbf.velocity_margin, 0.03);
        let mut fw = ControllerParams::default();
        for (name, v) in &updates {
            params::set(&mut fw, name, *v).expect("known parameter");
            assert!(fw.validate().is_ok(), "the firmware would refuse {name} = {v}");
        }
        assert_eq!(fw, p);
        // 1.2 kg hovers on 11.8 N, above the boot THR_MAX (11 N): the limit must go first.
        let pos = |n: &str| updates.iter().position(|(m, _)| *m == n).expect("sent");
        assert!(pos("THR_MAX") < pos("VEH_MASS"));
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
