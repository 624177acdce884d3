//! [`PilLink`]: the firmware in QEMU behind the [`FlightStack`] interface. Owns
//! the lockstep exchange (queued frames, HIL_SENSOR, wait for the step's
//! HIL_ACTUATOR_CONTROLS, re-send, time out), the handshake and the start-up
//! sequence (parameters, mission upload, warm-up, arming), and the latching of
//! failures (see the module docs of [`super`]).
//!
//! May import: `parapet-core` (wire contract, schedule, waypoint follower),
//! mavlink, the other [`super`] modules, [`crate::flight`], [`crate::sim::sensors`],
//! [`crate::sim::battery`] (its readings),
//! [`crate::world::scene`], [`crate::fc::bridge`] (the `LinkTap` of a ground-station bridge).

use std::io::Write;
use std::process::ChildStdin;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use mavlink::dialects::ardupilotmega::{
    MavCmd, MavMessage, MavMissionResult, MavModeFlag, MavResult, HEARTBEAT_DATA,
};
use mavlink::{MAVLinkV2MessageRaw, MavHeader};
use nalgebra::Vector3;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::perception::Range;
use parapet_core::schedule::OuterSchedule;
use parapet_core::waypoint::WaypointFollower;
use parapet_core::wire::codes::FlightPhase;
use parapet_core::wire::ids::{HOST_COMPONENT_ID, HOST_SYSTEM_ID, VEHICLE_SYSTEM_ID};
use parapet_core::wire::lockstep::MotorCommand;
use parapet_core::wire::names::{self, PANIC_TEXT, PIL_READY_TEXT};

use super::faults::Injector;
use super::firmware::firmware_build_command;
use super::gcs::{
    battery_status, command_long, filtered_source, firmware_params, fix_message, hil_sensor, mission_count,
    mission_item, obstacle_batch, param_set, preroll_start, quantised_path, WARMUP_STEPS,
};
use super::proximity::{is_planar_lidar, obstacle_distance};
use super::qemu::{reader_thread, start_qemu, Inbound, LinkPipes, QemuGuard};
use super::telemetry::{figures, observe, FirmwareTelemetry, PilFigures};
use super::PilOptions;
use crate::fc::bridge::LinkTap;
use crate::flight::runner::RunConfig;
use crate::flight::stack::{clock_us, FlightStack, OuterOut};
use crate::sim::battery::BatteryReading;
use crate::sim::range::RangeSensor;
use crate::sim::sensors::{ImuReading, PositionReading};
use crate::world::scene::{to_f32, Scene};

/// Answer of one lockstep step.
#[derive(Debug, Default)]
struct StepAnswer {
    throttle: [f32; 4],
    replies: Vec<MavMessage>,
}

/// The firmware in QEMU behind the [`FlightStack`] interface.
pub struct PilLink {
    qemu: QemuGuard,
    /// QEMU's stdin: host → firmware (`None` once closed).
    to_fw: Option<ChildStdin>,
    rx: Receiver<Inbound>,
    opts: PilOptions,
    seq: u8,
    queue: Vec<Vec<u8>>,
    injector: Injector,
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
    follower: WaypointFollower<{ parapet_core::wire::ids::MISSION_ITEM_CAPACITY }>,
    mission_t0_us: Option<u64>,
    mission_start_pending: bool,
    telemetry: FirmwareTelemetry,
    /// The firmware's outer-loop schedule (from its parameters).
    schedule: OuterSchedule,
    last_t_us: u64,
    /// Firmware time of the step whose answer is being read (0 in the handshake).
    rx_t_us: u64,
    fault: Option<String>,
    flight_wall: Duration,
    flight_sim_steps: u64,
    /// Ground-station bridge / `.tlog` (`crate::fc::bridge`), if set.
    tap: Option<Box<dyn LinkTap>>,
    /// `--gcs-control`: the GCS's reference (POSITION_TARGET_LOCAL_NED), whether the last item
    /// was reached (MISSION_ITEM_REACHED) and whether the vehicle has been armed.
    gcs: GcsFlight,
    /// The range scans go to the firmware as `OBSTACLE_DISTANCE` ([`super::proximity`]) and
    /// no obstacle batches are sent in flight.
    proximity: bool,
    /// The position source's noise, 1σ per axis, m (the run's sensor model; 0 without noise):
    /// sent as ODOMETRY's pose covariance.
    fix_std_m: f64,
    /// The mission flies the trajectory guidance (`MIS_GUIDANCE` 1): the reference recorded is
    /// the firmware's own ([`FirmwareTarget`]), not the host's replay of the paper's point.
    trajectory: bool,
    /// The firmware's latest POSITION_TARGET_LOCAL_NED (25 Hz).
    target: Option<FirmwareTarget>,
    /// The firmware reported the path's last item reached (MISSION_ITEM_REACHED).
    target_done: bool,
    /// `RPL_ENABLE` of the flight's parameters (the firmware's on-board replanner, issue 38).
    replan_enabled: bool,
    /// The σ of a `gps` / `rtk` source's GPS_INPUTs; `None`: ODOMETRY (motion capture).
    nav_source: Option<(parapet_core::nav::FixKind, parapet_core::nav::aid::SourceNoise)>,
    /// A barometer height (NED down, m) and a magnetometer field (FRD, gauss) for the next HIL_SENSOR.
    baro: Option<f64>,
    mag: Option<parapet_core::Vec3>,
}

/// The set-point the firmware last reported (POSITION_TARGET_LOCAL_NED), with the firmware
/// time of the step that carried it.
#[derive(Clone, Copy, Debug)]
struct FirmwareTarget {
    t_us: u64,
    position: Vector3<f64>,
    velocity: Vector3<f64>,
}

impl FirmwareTarget {
    /// The reference at firmware time `t_us`, extrapolated along the reported velocity (the
    /// stream's 40 ms: at most ½·a·(40 ms)² = 2.4 mm off at the trajectory's 3 m/s²).
    fn at(&self, t_us: u64) -> Vector3<f64> {
        self.position + self.velocity * (t_us.saturating_sub(self.t_us) as f64 * 1e-6)
    }
}

/// What a ground station's flight (`PilOptions::gcs_control`) reports back to the host.
#[derive(Clone, Copy, Debug, Default)]
struct GcsFlight {
    reference: Option<Vector3<f64>>,
    done: bool,
    /// The vehicle has left the ground armed (a phase past Idle: takeoff, flying, landing,
    /// failsafe). Arming and disarming on the ground does not end the run (issue 41).
    flew: bool,
    /// Firmware time of the step that first saw the vehicle disarmed after it flew.
    disarmed_us: Option<u64>,
}

impl GcsFlight {
    /// Takes the firmware's latest armed state and phase code at firmware time `t_us`.
    fn observe(&mut self, armed: bool, phase: u32, t_us: u64) {
        let on_ground =
            matches!(FlightPhase::from_code(phase), Some(FlightPhase::Disarmed | FlightPhase::Idle));
        self.flew |= armed && !on_ground;
        if self.flew && !armed && self.disarmed_us.is_none() {
            self.disarmed_us = Some(t_us);
        }
    }
}

/// The run goes on this long after the vehicle disarmed (µs), so that the ground station sees
/// it disarmed (two 1 Hz heartbeats) before the vehicle goes away.
const GCS_AFTER_DISARM_US: u64 = 2_500_000;

impl PilLink {
    /// Start QEMU with the firmware, connect, handshake. `scene` and `cfg` give the parameters
    /// (see [`firmware_params`]) and the path (sent in [`FlightStack::start`]).
    pub fn spawn(scene: &Scene, cfg: &RunConfig, opts: PilOptions) -> Result<PilLink> {
        let (params, param_updates) = firmware_params(scene, cfg)?;
        let (n, capacity) = (cfg.path.len(), parapet_core::wire::ids::MISSION_ITEM_CAPACITY);
        if n > capacity {
            bail!("the path has {n} waypoints; the firmware's mission stores at most {capacity} items");
        }
        if !opts.firmware.is_file() {
            bail!(
                "firmware ELF {} not found; build it with: {:?} (or omit --firmware to build it)",
                opts.firmware.display(),
                firmware_build_command()
            );
        }
        let wall = Instant::now();
        let (qemu, LinkPipes { to_fw, from_fw }) = start_qemu(&opts)?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || reader_thread(from_fw, tx));
        let mut follower = WaypointFollower::new(params.waypoint).map_err(|e| {
            anyhow!("waypoint parameters: {}", crate::flight::validate::describe_path_error(e))
        })?;
        follower
            .set_path(&quantised_path(&cfg.path))
            .map_err(|e| anyhow!("path rejected: {}", crate::flight::validate::describe_path_error(e)))?;
        let mut link = PilLink {
            qemu,
            to_fw: Some(to_fw),
            rx,
            seq: 0,
            queue: Vec::new(),
            injector: Injector::new(opts.faults.clone()),
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
            telemetry: FirmwareTelemetry::default(),
            schedule: OuterSchedule::new(&params),
            last_t_us: 0,
            rx_t_us: 0,
            fault: None,
            flight_wall: Duration::ZERO,
            flight_sim_steps: 0,
            tap: None,
            gcs: GcsFlight::default(),
            proximity: false,
            fix_std_m: if cfg.sensors.noise { cfg.sensors.position_noise } else { 0.0 },
            trajectory: params.guidance.mission == parapet_core::outer::guidance::MissionGuidance::Trajectory,
            target: None,
            target_done: false,
            replan_enabled: params.replan.enable,
            nav_source: filtered_source(cfg),
            baro: None,
            mag: None,
        };
        link.fig.firmware = link.opts.firmware.display().to_string();
        link.handshake().map_err(|e| link.with_qemu_log(e))?;
        link.fig.startup_wall_s = wall.elapsed().as_secs_f64();
        Ok(link)
    }

    /// Bridge the link to ground stations / record it (`crate::fc::bridge`): the tap sees every
    /// byte the host writes and every frame the firmware sends, and its frames (from the
    /// endpoints) go into each step's stream before the HIL_SENSOR.
    pub fn set_tap(&mut self, tap: Box<dyn LinkTap>) {
        self.tap = Some(tap);
    }

    /// Process id of QEMU (for fault-injection tests: SIGSTOP / kill).
    pub fn qemu_pid(&self) -> u32 {
        self.qemu.child.id()
    }

    /// The latched failure, if the link failed during the flight.
    pub fn fault(&self) -> Option<&str> {
        self.fault.as_deref()
    }

    fn with_qemu_log(&self, e: anyhow::Error) -> anyhow::Error {
        let log = self.qemu.stderr_text();
        if log.is_empty() {
            e
        } else {
            e.context(format!("QEMU stderr: {log}"))
        }
    }

    /// Figures so far.
    pub fn figures(&self) -> PilFigures {
        figures(&self.fig, &self.ins, &self.ins_outer, self.flight_wall, self.flight_sim_steps)
    }

    fn header(&mut self) -> MavHeader {
        let h = MavHeader {
            system_id: u32::from(HOST_SYSTEM_ID),
            component_id: HOST_COMPONENT_ID,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        h
    }

    /// Queue `m` for the next step (sent before its HIL_SENSOR).
    /// Send `m` with the next control step (pilot input, `crate::pilot`).
    pub fn send(&mut self, m: &MavMessage) {
        if self.fault.is_none() {
            self.queue(m);
        }
    }

    fn queue(&mut self, m: &MavMessage) {
        let bytes = self.frame(m);
        self.queue.push(bytes);
    }

    /// The firmware's flight mode as it last reported it (HEARTBEAT `custom_mode`, mode-change
    /// STATUSTEXT), `None` before the first report.
    pub fn flight_mode(&self) -> Option<parapet_core::controller::FlightMode> {
        self.telemetry.mode
    }

    /// `m` as a MAVLink v2 frame with the next sequence number.
    fn frame(&mut self, m: &MavMessage) -> Vec<u8> {
        let mut raw = MAVLinkV2MessageRaw::new();
        let h = self.header();
        raw.serialize_message(h, m);
        raw.raw_bytes().to_vec()
    }

    fn write_all(&mut self, bytes: &[u8]) -> Result<()> {
        // One `write(2)` per batch (the firmware reads what arrived with one `SYS_READ`). A pipe
        // has no write timeout; the host writes at most one step ahead of the answers and a
        // step is far below the pipe's 64 KiB, so a stalled firmware is found by the answer
        // timeout, not here.
        let Some(pipe) = self.to_fw.as_mut() else { bail!("the link to QEMU is closed") };
        pipe.write_all(bytes).context("QEMU closed the link (cannot write to its stdin)")
    }

    /// Next inbound message within `timeout`.
    fn recv(&mut self, timeout: Duration) -> Result<Option<MavMessage>> {
        match self.rx.recv_timeout(timeout) {
            Ok(Inbound::Msg(h, m, version)) => {
                if h.system_id == u32::from(VEHICLE_SYSTEM_ID) {
                    if let Some(last) = self.last_fw_seq {
                        self.fig.host_sequence_gaps +=
                            u64::from(h.sequence.wrapping_sub(last.wrapping_add(1)));
                    }
                    self.last_fw_seq = Some(h.sequence);
                }
                self.fig.frames_received += 1;
                if let Some(tap) = self.tap.as_mut() {
                    tap.firmware_frame(&h, &m, version);
                }
                observe(&m, self.rx_t_us, &mut self.telemetry, &mut self.fig);
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
        self.queue(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
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
                bail!("no \"{PIL_READY_TEXT}\" within 10 s of the host HEARTBEAT");
            }
            if let Some(MavMessage::STATUSTEXT(s)) = self.recv(left.min(Duration::from_millis(200)))? {
                ready = String::from_utf8_lossy(&s.text[..]).contains(PIL_READY_TEXT);
            }
        }
        let i = &self.fig.instructions_per_control_step;
        if i.calibration_ticks <= 0 || i.calibration_instructions <= 0 {
            bail!(
                "the firmware sent no instruction calibration ({}, {}) before \"{PIL_READY_TEXT}\"",
                names::INS_CAL,
                names::INS_CAL_N
            );
        }
        Ok(())
    }

    /// One lockstep step at firmware time `t_us`: queued frames, HIL_SENSOR, wait for the answer.
    fn step(&mut self, t_us: u64, imu: &ImuReading) -> Result<StepAnswer> {
        let inject = self.in_flight;
        self.rx_t_us = t_us;
        if let Some(tap) = self.tap.as_mut() {
            let external = tap.before_step(t_us);
            if !external.is_empty() {
                self.queue.push(external);
            }
        }
        let frames = std::mem::take(&mut self.queue);
        let mut out = self.injector.frames(frames, inject, &mut self.fig);
        let (baro, mag) = (self.baro.take(), self.mag.take());
        let trigger = self.frame(&hil_sensor(t_us, imu, baro, mag));
        if self.injector.lose_trigger(inject, self.flight_sim_steps + 1) {
            self.fig.injected_dropped += 1;
        } else {
            out.extend_from_slice(&trigger);
            self.fig.frames_sent += 1;
        }
        if let Some(tap) = self.tap.as_mut() {
            tap.host_bytes(&out);
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
                    let armed = c.mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                    ans.throttle = MotorCommand::from_actuator_controls(&c.controls, armed).throttle;
                    break;
                }
                MavMessage::HIL_ACTUATOR_CONTROLS(_) => {} // answer to a re-sent older step
                MavMessage::NAMED_VALUE_INT(n)
                    if n.name.to_str().unwrap_or("") == names::INS_OUTER
                        && n.time_boot_ms as u64 == t_us / 1000
                        && self.in_flight =>
                {
                    self.pending_outer = Some((t_us, n.value.max(0) as u64));
                }
                MavMessage::NAMED_VALUE_INT(n)
                    if n.name.to_str().unwrap_or("") == names::INS_MASKED
                        && n.time_boot_ms as u64 == t_us / 1000
                        && self.in_flight =>
                {
                    let i = &mut self.fig.instructions_per_control_step;
                    i.max_masked = i.max_masked.max(n.value.max(0) as u64);
                    i.masked_steps += 1;
                }
                MavMessage::NAMED_VALUE_INT(n)
                    if n.name.to_str().unwrap_or("") == names::INS_STEP
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
                | MavMessage::PARAM_VALUE(_)
                | MavMessage::POSITION_TARGET_LOCAL_NED(_)
                | MavMessage::MISSION_ITEM_REACHED(_)) => ans.replies.push(m),
                MavMessage::STATUSTEXT(s) if String::from_utf8_lossy(&s.text[..]).contains(PANIC_TEXT) => {
                    bail!("the firmware panicked (STATUSTEXT PANIC) at t = {t_us} µs");
                }
                _ => {}
            }
        }
        self.last_t_us = t_us;
        Ok(ans)
    }

    /// A fix: ODOMETRY, with a `gps` / `rtk` source GPS_INPUT, with `vio` a VIO's ODOMETRY
    /// (`super` § Position source).
    fn queue_odometry(&mut self, t_us: u64, fix: &PositionReading) {
        if let Some(m) = fix_message(t_us, fix, self.nav_source, self.fix_std_m) {
            self.queue(&m);
        }
    }

    fn queue_obstacles(&mut self, t_us: u64, obstacles: &[ObstaclePoint]) {
        let shown: &[ObstaclePoint] = if self.cbf { obstacles } else { &[] };
        for m in obstacle_batch(t_us, shown) {
            self.queue(&m);
        }
    }

    fn command(&mut self, command: MavCmd, p: [f32; 7]) {
        self.queue(&command_long(command, p));
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
        let sched = self.schedule;
        let (period, div) = (sched.period_us(), sched.divider());
        let mut t = preroll_start(t0_us, table.len(), path.len(), &sched);
        let mut steps = 0u64;
        // Parameters, one per step, each checked.
        for (name, value) in table {
            self.queue(&param_set(name, value));
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
        if self.opts.gcs_control {
            return self.gcs_warmup(t, t0_us, fix, obstacles, imu, steps);
        }
        // Mission upload.
        self.queue(&mission_count(path.len()));
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
                        self.queue(&mission_item(r.seq, w));
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
        let warmup_from = t0_us - (WARMUP_STEPS + div) * 1000;
        if t > warmup_from {
            bail!("internal: pre-roll too short for the start-up");
        }
        // Warm-up with fixes and obstacles at the outer rate; arm and hold the start at T0 − 4 ms.
        while t < t0_us {
            if (t0_us - t).is_multiple_of(period) && t > warmup_from {
                self.queue_odometry(t, fix);
                self.queue_obstacles(t, obstacles);
            }
            let arm_step = t == t0_us - period;
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
        (self.telemetry.armed, self.telemetry.phase) = (true, FlightPhase::Mission.code());
        self.follower
            .start(to_f32(&start))
            .map_err(|e| anyhow!("follower: {}", crate::flight::validate::describe_path_error(e)))?;
        self.in_flight = true;
        Ok(())
    }

    /// `--gcs-control` start-up after the parameters: fixes and obstacle batches at the outer
    /// rate until `t0_us`, disarmed; the ground station uploads, arms and starts.
    fn gcs_warmup(
        &mut self,
        mut t: u64,
        t0_us: u64,
        fix: &PositionReading,
        obstacles: &[ObstaclePoint],
        imu: &ImuReading,
        mut steps: u64,
    ) -> Result<()> {
        let period = self.schedule.period_us();
        while t < t0_us {
            if (t0_us - t).is_multiple_of(period) {
                self.queue_odometry(t, fix);
                self.queue_obstacles(t, obstacles);
            }
            self.step(t, imu)?;
            steps += 1;
            t += 1000;
        }
        self.fig.startup_steps = steps;
        self.in_flight = true;
        Ok(())
    }

    /// `--gcs-control`: what the firmware's answers of a flight step tell about the GCS's flight.
    fn observe_gcs(&mut self, replies: &[MavMessage]) {
        let last = self.path.len().saturating_sub(1);
        for m in replies {
            match m {
                MavMessage::POSITION_TARGET_LOCAL_NED(p) => {
                    self.gcs.reference = Some(Vector3::new(p.x, p.y, p.z).cast())
                }
                MavMessage::MISSION_ITEM_REACHED(r) => self.gcs.done |= usize::from(r.seq) >= last,
                _ => {}
            }
        }
        self.gcs.observe(self.telemetry.armed, self.telemetry.phase, self.last_t_us);
    }

    fn latch(&mut self, e: anyhow::Error) {
        if self.fault.is_none() {
            self.fault = Some(format!("{:#}", self.with_qemu_log(e)));
        }
    }
}

impl Drop for PilLink {
    fn drop(&mut self) {
        // Closing QEMU's stdin ends the firmware (end of input → semihosting exit); the guard
        // kills QEMU anyway.
        drop(self.to_fw.take());
    }
}

impl FlightStack for PilLink {
    fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> Result<()> {
        let r = self.startup(clock_us(s.t), s.start, &s.fix, s.obstacles, s.imu);
        r.map_err(|e| self.with_qemu_log(e))
    }

    fn position_fix(&mut self, fix: PositionReading) {
        if self.fault.is_none() {
            self.queue_odometry(clock_us(fix.t_measured), &fix);
        }
    }

    // The runner gives a field only for `gps`/`rtk` and heights only for filtered sources.
    fn mag_fix(&mut self, _t: f64, field: parapet_core::Vec3) {
        self.mag = self.fault.is_none().then_some(field);
    }

    fn height_fix(&mut self, _t: f64, down: f64) {
        self.baro = self.fault.is_none().then_some(down);
    }

    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        let now = clock_us(t);
        if self.fault.is_none() {
            if !self.proximity {
                self.queue_obstacles(now, obstacles);
            }
            if self.mission_start_pending {
                self.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7]);
            }
        }
        let age = now.saturating_sub(self.mission_t0_us.unwrap_or(now));
        let mut s = self.follower.sample(age as f32 * 1e-6);
        if self.opts.gcs_control {
            // The GCS flies: the firmware's own reference and progress, not the host's replay.
            s.position = self.gcs.reference.map_or(s.position, |r| to_f32(&r));
            s.progress.done = self.gcs.done;
        } else if let Some(target) = self.target.filter(|_| self.trajectory) {
            // The trajectory's clock waits for the vehicle: only the firmware knows its reference.
            s.position = to_f32(&target.at(now));
            s.progress.done = self.target_done;
        }
        self.telemetry.outer_out(&s)
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
                let last = self.path.len().saturating_sub(1);
                for m in &ans.replies {
                    match m {
                        MavMessage::POSITION_TARGET_LOCAL_NED(p) => {
                            self.target = Some(FirmwareTarget {
                                t_us: clock_us(t),
                                position: Vector3::new(p.x, p.y, p.z).cast(),
                                velocity: Vector3::new(p.vx, p.vy, p.vz).cast(),
                            })
                        }
                        MavMessage::MISSION_ITEM_REACHED(r) => self.target_done |= usize::from(r.seq) >= last,
                        _ => {}
                    }
                }
                if self.opts.gcs_control {
                    self.observe_gcs(&ans.replies);
                }
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

    fn battery(&mut self, _t: f64, reading: &BatteryReading) {
        // Sent with the next step, before its HIL_SENSOR: the firmware measures it at this
        // step's time, where `parapet run` measures it (`super::gcs::battery_status`).
        if self.fault.is_none() {
            self.queue(&battery_status(reading));
            self.fig.battery.readings_sent += 1;
        }
    }

    fn take_proximity_scans(&mut self, sensors: &[RangeSensor]) -> bool {
        // Every sensor a planar 360° lidar (OBSTACLE_DISTANCE describes it exactly), the filter
        // on (without it the host shows the firmware nothing).
        self.proximity = self.cbf && !sensors.is_empty() && sensors.iter().all(is_planar_lidar);
        self.proximity
    }

    fn proximity_scan(&mut self, _t: f64, t_scan: f64, spec: &RangeSensor, ranges: &[Range]) {
        if self.fault.is_some() || !self.proximity {
            return;
        }
        if let Some(m) = obstacle_distance(clock_us(t_scan), spec, ranges) {
            self.queue(&m);
            self.fig.obstacle_distance_scans += 1;
        }
    }

    fn ground_start(&self) -> bool {
        self.opts.gcs_control
    }

    fn finished(&self) -> bool {
        let after = |t: u64| self.last_t_us.saturating_sub(t) >= GCS_AFTER_DISARM_US;
        self.opts.gcs_control && !self.telemetry.armed && self.gcs.disarmed_us.is_some_and(after)
    }

    fn replan_summary(&self) -> crate::report::ReplanSummary {
        super::telemetry::replan_summary(self.replan_enabled, &self.fig.replan_texts)
    }

    fn state_name(&self) -> String {
        if let Some(f) = &self.fault {
            return format!("LinkFailed: {f}");
        }
        self.telemetry.state_name().into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--gcs-control`: arming and disarming on the ground keeps the session (the client stops
    /// it or the flight ends); a disarm after a flight ends it. Before: the first disarm did.
    #[test]
    fn the_run_ends_at_the_disarm_after_a_flight_not_on_the_ground() {
        let mut g = GcsFlight::default();
        let (idle, off, takeoff) =
            (FlightPhase::Idle.code(), FlightPhase::Disarmed.code(), FlightPhase::Takeoff.code());
        g.observe(true, idle, 1);
        g.observe(false, off, 2);
        assert_eq!(g.disarmed_us, None, "armed and disarmed on the ground");
        g.observe(true, idle, 3);
        g.observe(true, takeoff, 4);
        g.observe(true, idle, 5);
        g.observe(false, off, 6);
        assert_eq!(g.disarmed_us, Some(6));
    }
}
