//! The MAVLink link, hardware-independent: bytes in → cascade updates + replies out.
//!
//! [`Link`] owns the framer, the mission upload, the obstacle decoder and a small reply queue.
//! The board's communication task feeds it received bytes, drains [`Link::pop_reply`] to the
//! UART and calls [`Link::poll`] periodically. Inbound messages and what they do:
//!
//! | message | action |
//! |---|---|
//! | ODOMETRY (331) | `update_position`: frame_id LOCAL_NED; velocity in child_frame_id LOCAL_NED, or BODY_FRD (rotated to NED with the message's quaternion). Non-finite → rejected, counted; other frames (LOCAL_FRD, …) → rejected, counted, STATUSTEXT WARNING [`ODOMETRY_REFUSED_TEXT`] at most every 10 s |
//! | OBSTACLE_DISTANCE_3D (11037), DEBUG_VECT `OBV<id>` | obstacle points, see [`crate::link::obstacles`] |
//! | OBSTACLE_DISTANCE (330), DISTANCE_SENSOR (132) | range returns into the obstacle memory, see [`crate::link::obstacles`] |
//! | MISSION_COUNT / MISSION_ITEM_INT / MISSION_CLEAR_ALL | mission upload, see [`crate::link::mission`] |
//! | MISSION_REQUEST_LIST / MISSION_REQUEST_INT | mission download (the path the cascade took last) |
//! | COMMAND_LONG / COMMAND_INT | arm / disarm / takeoff / land / mission start / hold, see [`crate::link::command`]; REQUEST_MESSAGE(AUTOPILOT_VERSION) and REQUEST_AUTOPILOT_CAPABILITIES → ACK + AUTOPILOT_VERSION |
//! | PARAM_SET / PARAM_REQUEST_READ / PARAM_REQUEST_LIST | parameters, see [`crate::link::params`] |
//! | TIMESYNC | a request (tc1 = 0) is answered with tc1 = firmware time, ns, ts1 echoed |
//! | PING (4) | a request (target 0/0) is answered to the sender, see [`crate::link::services`] |
//! | SET_MODE (11) | legacy mode change: executed as MAV_CMD_DO_SET_MODE (base_mode, custom_mode); no ACK (the next HEARTBEAT shows the mode) |
//! | MISSION_SET_CURRENT (41) | answered with MISSION_CURRENT; jumping to another item is not supported (STATUSTEXT) |
//! | COMMAND: SET_MESSAGE_INTERVAL (511), GET_MESSAGE_INTERVAL (510), REQUEST_MESSAGE (512) | rates / one-shot of the streams of [`crate::link::services`]; REQUEST_MESSAGE also AUTOPILOT_VERSION |
//! | HIL_SENSOR (107) | simulated IMU for the lockstep PIL link, see [`crate::pil::lockstep`] |
//! | MANUAL_CONTROL (69), RC_CHANNELS_OVERRIDE (70) | pilot input → `set_rc`, see [`crate::link::manual_control`] (the QEMU/PIL board's RC channel) |
//! | SET_POSITION_TARGET_LOCAL_NED (84) | offboard setpoint → `set_offboard` ([`crate::link::offboard::decode`]; refused masks/frames counted as ignored) |
//! | HEARTBEAT | marks the peer alive |
//! | MAVLink **v1** HEARTBEAT | not dispatched (v2 only, as PX4): answered with a v1 STATUSTEXT WARNING, see [`crate::link::v1`] |
//!
//! **Addressing**: messages with target fields are handled only when `target_system` is 0 or
//! ours and `target_component` is 0 or ours ([`AUTOPILOT_COMPONENT_ID`]); others (e.g. a
//! PARAM_SET or ARM for a camera, component 154) are ignored and counted (`not_for_us`).
//! Answers are addressed to the sender's system/component.
//!
//! Replies (COMMAND_ACK, MISSION_*, PARAM_VALUE, …) go to a queue of [`REPLY_QUEUE_LEN`]; when
//! it is full the newest reply is dropped and counted (the peer retries, as the MAVLink command
//! and mission protocols require). **PARAM_REQUEST_LIST** does not fill the queue at once: it
//! starts a stream that [`Link::poll`] (and each received frame) continues with at most
//! [`PARAMS_PER_POLL`] PARAM_VALUEs while more than [`REPLY_RESERVE`] queue slots are free, in
//! table order (index 0..count−1, each once); a new PARAM_REQUEST_LIST restarts it.

use crate::link::dialect::{
    MavFrame, MavMissionResult, MavMissionType, MavParamType, MavProtocolCapability, MavResult,
    AUTOPILOT_VERSION_DATA, COMMAND_LONG_DATA, HIL_SENSOR_DATA, ODOMETRY_DATA, PARAM_VALUE_DATA,
    TIMESYNC_DATA,
};
use heapless::Deque;
use parapet_core::nalgebra::{Quaternion, UnitQuaternion};
use parapet_core::Vec3;

use crate::app::autopilot::{Autopilot, FlightMode, FlightPhase, ImuSample, PositionFix, VehicleCommand};
use crate::link::command::{addressed_to, command_long_of_int, execute};
use crate::link::frame_parser::{FrameParser, ParserStats, RawFrame};
use crate::link::framing::AUTOPILOT_COMPONENT_ID;
use crate::link::manual_control::{ManualControl, ManualControlStats};
use crate::link::messages::{decode, frame_extra_crc, DecodeError, Inbound};
use crate::link::mission::{DownloadReply, MissionReply, MissionUpload};
use crate::link::mission_run::MissionRun;
use crate::link::obstacles::{ObstacleAssembler, ObstacleStats};
use crate::link::outbound::Outbound;
use crate::link::services::{MissionProgress, Services};
use crate::link::v1::V1Detector;
use crate::setup::SetupAck;

/// Reply queue capacity.
pub const REPLY_QUEUE_LEN: usize = 8;
/// Most PARAM_VALUEs of a PARAM_REQUEST_LIST stream queued per [`Link::poll`] or frame.
pub const PARAMS_PER_POLL: usize = 2;
/// Reply-queue slots a PARAM_REQUEST_LIST stream leaves free for other replies.
pub const REPLY_RESERVE: usize = 4;
/// AUTOPILOT_VERSION capabilities: MAVLink 2, float parameters (C cast), MISSION_ITEM_INT,
/// COMMAND_INT. No fence/rally, no SET_POSITION_TARGET_* (not handled).
pub const CAPABILITIES: MavProtocolCapability = MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST)
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT)
    .union(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT);
/// MAVLink message id of AUTOPILOT_VERSION (MAV_CMD_REQUEST_MESSAGE param1).
const AUTOPILOT_VERSION_ID: f32 = 148.0;

/// One simulated IMU sample from HIL_SENSOR.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HilSample {
    /// Simulated time, µs (the firmware clock on the lockstep link).
    pub time_usec: u64,
    /// Gyro and specific force, body FRD.
    pub imu: ImuSample,
}

impl HilSample {
    /// HIL_SENSOR → sample (xgyro.. rad/s FRD, xacc.. m/s² FRD specific force).
    pub fn from_message(m: &HIL_SENSOR_DATA) -> Self {
        Self {
            time_usec: m.time_usec,
            imu: ImuSample {
                gyro_frd: Vec3::new(m.xgyro, m.ygyro, m.zgyro),
                accel_frd: Vec3::new(m.xacc, m.yacc, m.zacc),
            },
        }
    }
}

/// Link counters beyond the framer's (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// CRC-valid frames whose payload did not decode (invalid enum values).
    pub decode_errors: u32,
    /// CRC-valid frames of messages the firmware does not handle.
    pub ignored: u32,
    /// Replies dropped because the queue was full.
    pub replies_dropped: u32,
    /// ODOMETRY messages rejected (unsupported frame or non-finite values).
    pub odometry_rejected: u32,
    /// HIL_SENSOR samples received.
    pub hil_samples: u32,
    /// HIL_SENSOR samples overwritten before the control step took them.
    pub hil_overwritten: u32,
    /// PARAM_SET / PARAM_REQUEST_READ for unknown names or indices.
    pub unknown_params: u32,
    /// Messages addressed to another system or component (ignored).
    pub not_for_us: u32,
}

/// Whose clock time-stamps a position fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FixClock {
    /// The firmware's clock when the message arrived (radio link: the companion's clock is
    /// not the firmware's).
    Arrival,
    /// The message's `time_usec` (lockstep link: simulated time is the firmware clock).
    Message,
}

struct Router {
    own_system: u8,
    fix_clock: FixClock,
    mission: MissionUpload,
    /// Runs the plan's takeoff / land / return items ([`crate::link::mission_run`]).
    run: MissionRun,
    obstacles: ObstacleAssembler,
    replies: Deque<Outbound, REPLY_QUEUE_LEN>,
    hil: Option<HilSample>,
    stats: LinkStats,
    peer_seen: bool,
    /// Next index of a PARAM_REQUEST_LIST stream (`None`: no stream).
    param_stream: Option<u16>,
    services: Services,
    manual: ManualControl,
    /// When the last "ODOMETRY refused" STATUSTEXT went out.
    odometry_text_us: Option<u64>,
    /// When the last v1 refusal went out ([`crate::link::v1`]).
    v1_text_us: Option<u64>,
}

/// STATUSTEXT of an ODOMETRY refused for its frame (LOCAL_FRD, …).
pub const ODOMETRY_REFUSED_TEXT: &str = "ODOMETRY refused: frame must be LOCAL_NED";
/// Shortest interval between two such STATUSTEXTs, µs.
pub const ODOMETRY_TEXT_US: u64 = 10_000_000;

/// Converts ODOMETRY into a position fix (with the yaw of `q` when it is a valid attitude);
/// `None` for unsupported frames or non-finite data.
pub fn odometry_fix(m: &ODOMETRY_DATA, t_us: u64) -> Option<PositionFix> {
    if m.frame_id != MavFrame::MAV_FRAME_LOCAL_NED {
        return None;
    }
    let p = Vec3::new(m.x, m.y, m.z);
    let v_raw = Vec3::new(m.vx, m.vy, m.vz);
    let v = match m.child_frame_id {
        MavFrame::MAV_FRAME_LOCAL_NED => v_raw,
        MavFrame::MAV_FRAME_BODY_FRD => {
            let q = Quaternion::new(m.q[0], m.q[1], m.q[2], m.q[3]);
            let n = q.norm();
            if !n.is_finite() || n < 0.5 {
                return None;
            }
            UnitQuaternion::from_quaternion(q) * v_raw
        }
        _ => return None,
    };
    if !(p.iter().chain(v.iter()).all(|x| x.is_finite())) {
        return None;
    }
    // The heading the fix measures (as `parapet run` feeds the estimator); unknown (zero or
    // NaN quaternion) → none.
    let yaw = parapet_core::wire::codes::odometry_yaw(m.q);
    Some(PositionFix { t_us, position_ned: p, velocity_ned: v, yaw })
}

/// PARAM_VALUE for parameter `index` with `value`.
fn param_value(index: usize, value: f32) -> Outbound {
    let name = crate::link::params::TABLE.get(index).map_or("", |p| p.name);
    Outbound::ParamValue(PARAM_VALUE_DATA {
        param_value: value,
        param_count: crate::link::params::COUNT as u16,
        param_index: index as u16,
        param_id: crate::link::outbound::name(name),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    })
}

/// AUTOPILOT_VERSION of this firmware (version 0.1.0 as `major << 24 | minor << 16 | patch << 8`).
pub fn autopilot_version() -> AUTOPILOT_VERSION_DATA {
    AUTOPILOT_VERSION_DATA {
        capabilities: CAPABILITIES,
        flight_sw_version: 0x0001_0000,
        ..Default::default()
    }
}

impl Router {
    fn for_me(&mut self, target_system: u8, target_component: u8) -> bool {
        let ok = addressed_to(target_system, target_component, (self.own_system, AUTOPILOT_COMPONENT_ID));
        if !ok {
            self.stats.not_for_us = self.stats.not_for_us.saturating_add(1);
        }
        ok
    }

    /// Continues a PARAM_REQUEST_LIST stream (see the module docs).
    fn stream_params<A: Autopilot>(&mut self, ap: &mut A) {
        for _ in 0..PARAMS_PER_POLL {
            let Some(i) = self.param_stream else { return };
            if REPLY_QUEUE_LEN - self.replies.len() <= REPLY_RESERVE {
                return;
            }
            let i = usize::from(i);
            let next = i + 1;
            self.param_stream = if next < crate::link::params::COUNT { Some(next as u16) } else { None };
            self.param_reply(Some(i), ap);
        }
    }

    fn on_command<A: Autopilot>(
        &mut self,
        cmd: &COMMAND_LONG_DATA,
        sender: (u8, u8),
        now_us: u64,
        ap: &mut A,
    ) {
        if !self.for_me(cmd.target_system, cmd.target_component) {
            return;
        }
        let p = [cmd.param1, cmd.param2, cmd.param3, cmd.param4, cmd.param5, cmd.param6, cmd.param7];
        if let Some(ack) = ap.setup_command(now_us, cmd.command, p) {
            let result = match ack {
                SetupAck::Accepted => MavResult::MAV_RESULT_ACCEPTED,
                SetupAck::Denied => MavResult::MAV_RESULT_DENIED,
                SetupAck::Unsupported => MavResult::MAV_RESULT_UNSUPPORTED,
                SetupAck::TemporarilyRejected => MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
            };
            self.reply(Outbound::CommandAck(crate::link::command::ack(cmd.command, result, sender)));
            return;
        }
        #[allow(deprecated)] // REQUEST_AUTOPILOT_CAPABILITIES: still sent by ground stations
        let (result, version) = match cmd.command {
            crate::link::command::id::REQUEST_AUTOPILOT_CAPABILITIES => {
                (MavResult::MAV_RESULT_ACCEPTED, true)
            }
            crate::link::command::id::REQUEST_MESSAGE if cmd.param1 == AUTOPILOT_VERSION_ID => {
                (MavResult::MAV_RESULT_ACCEPTED, true)
            }
            crate::link::command::id::REQUEST_MESSAGE if self.services.request(cmd.param1) => {
                (MavResult::MAV_RESULT_ACCEPTED, false)
            }
            crate::link::command::id::REQUEST_MESSAGE => (MavResult::MAV_RESULT_DENIED, false),
            crate::link::command::id::SET_MESSAGE_INTERVAL => {
                (self.services.set_interval(cmd.param1, cmd.param2), false)
            }
            crate::link::command::id::GET_MESSAGE_INTERVAL => {
                let m = self.services.message_interval(cmd.param1);
                self.reply(Outbound::CommandAck(crate::link::command::ack(
                    cmd.command,
                    MavResult::MAV_RESULT_ACCEPTED,
                    sender,
                )));
                self.reply(Outbound::MessageInterval(m));
                return;
            }
            _ => {
                let r = match crate::link::command::decode_command(cmd) {
                    Ok(VehicleCommand::StartMission) => {
                        crate::link::command::result_of(self.run.start(&self.mission, now_us, ap))
                    }
                    _ => execute(cmd, now_us, ap),
                };
                self.mission_mode_flies(cmd, r, now_us, ap);
                (r, false)
            }
        };
        self.reply(Outbound::CommandAck(crate::link::command::ack(cmd.command, result, sender)));
        if version {
            self.reply(Outbound::AutopilotVersion(autopilot_version()));
        }
    }

    /// PX4's AUTO.MISSION: an accepted DO_SET_MODE to Mission (PX4 4/4, what MAVSDK's
    /// `start_mission` sends) while airborne and holding or taking off, or armed on the ground
    /// with a plan that takes off, with a mission uploaded, also starts it
    /// ([`MissionRun::start`]; a refusal leaves the mode change standing). Other commands: nothing.
    fn mission_mode_flies<A: Autopilot>(
        &mut self,
        cmd: &COMMAND_LONG_DATA,
        r: MavResult,
        now_us: u64,
        ap: &mut A,
    ) {
        let to_mission = cmd.command == crate::link::command::id::DO_SET_MODE
            && r == MavResult::MAV_RESULT_ACCEPTED
            && crate::link::command::decode_command(cmd) == Ok(VehicleCommand::SetMode(FlightMode::Mission));
        let s = ap.telemetry();
        let on_ground_takes_off = s.phase == FlightPhase::Idle && MissionRun::takes_off(&self.mission);
        if to_mission
            && self.mission.stored_len() > 0
            && s.armed
            && (matches!(s.phase, FlightPhase::Hover | FlightPhase::Takeoff) || on_ground_takes_off)
        {
            let _ = self.run.start(&self.mission, now_us, ap);
        }
    }

    /// A v1 HEARTBEAT arrived: the v1 STATUSTEXT refusal, at most once per
    /// [`crate::link::v1::V1_TEXT_US`].
    fn on_v1_heartbeat(&mut self, now_us: u64) {
        let due = self.v1_text_us.is_none_or(|t| now_us.saturating_sub(t) >= crate::link::v1::V1_TEXT_US);
        if due {
            self.v1_text_us = Some(now_us);
            let t = crate::link::telemetry::status_text(
                crate::link::dialect::MavSeverity::MAV_SEVERITY_WARNING,
                crate::link::v1::V1_REFUSED_TEXT,
                "",
            );
            self.reply(Outbound::StatusTextV1(t));
        }
    }

    /// An ODOMETRY in a frame other than LOCAL_NED (e.g. PX4's LOCAL_FRD, a vision frame of
    /// unknown heading: no conversion to NED is possible without its yaw offset) is refused:
    /// counted, and a STATUSTEXT WARNING says so, at most once per [`ODOMETRY_TEXT_US`].
    fn refuse_odometry_frame(&mut self, m: &ODOMETRY_DATA, now_us: u64) {
        let frame_ok = m.frame_id == MavFrame::MAV_FRAME_LOCAL_NED
            && matches!(m.child_frame_id, MavFrame::MAV_FRAME_LOCAL_NED | MavFrame::MAV_FRAME_BODY_FRD);
        let due = self.odometry_text_us.is_none_or(|t| now_us.saturating_sub(t) >= ODOMETRY_TEXT_US);
        if !frame_ok && due {
            self.odometry_text_us = Some(now_us);
            let t = crate::link::telemetry::status_text(
                crate::link::dialect::MavSeverity::MAV_SEVERITY_WARNING,
                ODOMETRY_REFUSED_TEXT,
                "",
            );
            self.reply(Outbound::StatusText(t));
        }
    }

    /// The accepted plan's progress (uploaded seq numbers).
    fn mission_progress<A: Autopilot>(&self, ap: &A) -> MissionProgress {
        self.run.progress(&self.mission, &ap.telemetry())
    }

    fn clear_mission<A: Autopilot>(&mut self, ap: &mut A) {
        self.mission.clear();
        ap.clear_path();
        self.run.reset();
        self.services.on_new_mission();
    }

    fn param_reply<A: Autopilot>(&mut self, index: Option<usize>, ap: &mut A) {
        let found = index.and_then(|i| {
            let p = crate::link::params::TABLE.get(i)?;
            ap.get_param(p.name).map(|v| (i, v))
        });
        match found {
            Some((i, v)) => self.reply(param_value(i, v)),
            None => self.stats.unknown_params = self.stats.unknown_params.saturating_add(1),
        }
    }

    fn reply(&mut self, m: Outbound) {
        if self.replies.push_back(m).is_err() {
            self.stats.replies_dropped = self.stats.replies_dropped.saturating_add(1);
        }
    }

    fn mission_reply<A: Autopilot>(&mut self, r: MissionReply, ap: &mut A) {
        match r {
            MissionReply::Request(q) => self.reply(Outbound::MissionRequestInt(q)),
            MissionReply::Ack(a) => self.reply(Outbound::MissionAck(a)),
            MissionReply::Clear => {
                self.clear_mission(ap);
                let ack = self.mission.ack_for(MavMissionResult::MAV_MISSION_ACCEPTED);
                self.reply(Outbound::MissionAck(ack));
            }
            MissionReply::Complete => {
                let path = self.mission.path();
                // A plan without path points (TAKEOFF then RTL/LAND) leaves the cascade no path.
                let taken = if path.is_empty() {
                    ap.clear_path();
                    Ok(())
                } else {
                    ap.set_path(&path)
                };
                let result = match taken {
                    Ok(()) => {
                        self.run.reset();
                        self.services.on_new_mission();
                        MavMissionResult::MAV_MISSION_ACCEPTED
                    }
                    Err(crate::app::autopilot::PathRejected::TooLong) => {
                        MavMissionResult::MAV_MISSION_NO_SPACE
                    }
                    Err(crate::app::autopilot::PathRejected::Invalid) => {
                        MavMissionResult::MAV_MISSION_INVALID
                    }
                };
                if result == MavMissionResult::MAV_MISSION_ACCEPTED {
                    self.mission.accept();
                }
                let ack = self.mission.ack_for(result);
                self.reply(Outbound::MissionAck(ack));
            }
        }
    }

    fn download_reply(&mut self, r: DownloadReply) {
        self.reply(match r {
            DownloadReply::Count(c) => Outbound::MissionCount(c),
            DownloadReply::Item(i) => Outbound::MissionItemInt(i),
            DownloadReply::Ack(a) => Outbound::MissionAck(a),
        });
    }

    fn on_frame<A: Autopilot>(&mut self, f: &RawFrame<'_>, now_us: u64, ap: &mut A) {
        self.on_received(Received::of(f), now_us, ap);
    }

    fn on_received<A: Autopilot>(&mut self, r: Received, now_us: u64, ap: &mut A) {
        let (msg, f) = match r {
            Received::Message(m) => (m.msg, FrameSender { sys_id: m.sys_id, comp_id: m.comp_id }),
            Received::Undecodable(DecodeError::NotHandled) => {
                self.stats.ignored = self.stats.ignored.saturating_add(1);
                return;
            }
            Received::Undecodable(DecodeError::InvalidPayload) => {
                self.stats.decode_errors = self.stats.decode_errors.saturating_add(1);
                return;
            }
        };
        self.peer_seen = true;
        match msg {
            Inbound::Heartbeat(_) | Inbound::MissionAck(_) => {}
            Inbound::HilSensor(m) => {
                self.stats.hil_samples = self.stats.hil_samples.saturating_add(1);
                if self.hil.replace(HilSample::from_message(&m)).is_some() {
                    self.stats.hil_overwritten = self.stats.hil_overwritten.saturating_add(1);
                }
            }
            Inbound::Odometry(m) => {
                let t = match self.fix_clock {
                    FixClock::Arrival => now_us,
                    FixClock::Message => m.time_usec,
                };
                match odometry_fix(&m, t) {
                    Some(fix) => ap.update_position(&fix),
                    None => {
                        self.stats.odometry_rejected = self.stats.odometry_rejected.saturating_add(1);
                        self.refuse_odometry_frame(&m, now_us);
                    }
                }
            }
            Inbound::Obstacle(m) => self.obstacles.on_point(&m, now_us, ap),
            Inbound::ObstacleDistance(m) => self.obstacles.on_obstacle_distance(&m, now_us, ap),
            Inbound::DistanceSensor(m) => self.obstacles.on_distance_sensor(&m, now_us, ap),
            Inbound::DebugVect(m) => {
                self.obstacles.on_debug_vect(&m);
            }
            Inbound::MissionCount(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    let r = self.mission.on_count(&m, f.sys_id, f.comp_id, now_us);
                    self.mission_reply(r, ap);
                }
            }
            Inbound::MissionItemInt(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    if let Some(r) = self.mission.on_item(&m, f.sys_id, f.comp_id, now_us) {
                        self.mission_reply(r, ap);
                    }
                }
            }
            Inbound::MissionClearAll(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    let result = match m.mission_type {
                        MavMissionType::MAV_MISSION_TYPE_MISSION | MavMissionType::MAV_MISSION_TYPE_ALL => {
                            self.clear_mission(ap);
                            MavMissionResult::MAV_MISSION_ACCEPTED
                        }
                        _ => MavMissionResult::MAV_MISSION_UNSUPPORTED,
                    };
                    let ack = crate::link::mission::ack(f.sys_id, f.comp_id, result, m.mission_type);
                    self.reply(Outbound::MissionAck(ack));
                }
            }
            Inbound::MissionRequestList(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    let r = self.mission.on_request_list(m.mission_type, f.sys_id, f.comp_id);
                    self.download_reply(r);
                }
            }
            Inbound::MissionRequestInt(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    let r = self.mission.on_request_item(m.seq, m.mission_type, f.sys_id, f.comp_id);
                    self.download_reply(r);
                }
            }
            Inbound::ParamRequestList(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    self.param_stream = Some(0);
                }
            }
            Inbound::ManualControl(m) => {
                if let Some(rc) =
                    self.manual.on_manual_control(&m, (self.own_system, AUTOPILOT_COMPONENT_ID), now_us)
                {
                    ap.set_rc(&rc);
                }
            }
            Inbound::SetPositionTarget(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    match crate::link::offboard::decode(&m, now_us) {
                        Ok(sp) => ap.set_offboard(&sp),
                        Err(_) => self.stats.ignored = self.stats.ignored.saturating_add(1),
                    }
                }
            }
            Inbound::RcOverride(m) => {
                let p = ap.rc_params();
                let own = (self.own_system, AUTOPILOT_COMPONENT_ID);
                if let Some(rc) = self.manual.on_override(&m, own, now_us, &p) {
                    ap.set_rc(&rc);
                }
            }
            Inbound::Timesync(m) => {
                if m.tc1 == 0 {
                    let tc1 = i64::try_from(now_us.saturating_mul(1000)).unwrap_or(i64::MAX);
                    self.reply(Outbound::Timesync(TIMESYNC_DATA {
                        tc1,
                        ts1: m.ts1,
                        target_system: f.sys_id,
                        target_component: f.comp_id,
                    }));
                }
            }
            Inbound::ParamSet(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    let name = m.param_id.to_str().unwrap_or("");
                    // Refused values are answered with the value still in effect (MAVLink
                    // parameter protocol); unknown names are not answered.
                    let _ = ap.set_param(name, m.param_value);
                    self.param_reply(crate::link::params::index_of(name), ap);
                }
            }
            Inbound::ParamRequestRead(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    let index = if m.param_index >= 0 {
                        Some(m.param_index as usize)
                    } else {
                        crate::link::params::index_of(m.param_id.to_str().unwrap_or(""))
                    };
                    self.param_reply(index, ap);
                }
            }
            Inbound::CommandLong(m) => self.on_command(&m, (f.sys_id, f.comp_id), now_us, ap),
            Inbound::Ping(m) => {
                if let Some(r) = crate::link::services::ping_reply(&m, (f.sys_id, f.comp_id)) {
                    self.reply(Outbound::Ping(r));
                }
            }
            #[allow(deprecated)] // legacy SET_MODE: still sent by ground stations
            Inbound::SetMode(m) => {
                if self.for_me(m.target_system, 0) {
                    let c = COMMAND_LONG_DATA {
                        command: crate::link::command::id::DO_SET_MODE,
                        param1: f32::from(m.base_mode),
                        param2: m.custom_mode as f32,
                        ..Default::default()
                    };
                    let _ = execute(&c, now_us, ap);
                }
            }
            #[allow(deprecated)] // MISSION_SET_CURRENT: still sent by ground stations
            Inbound::MissionSetCurrent(m) => {
                if self.for_me(m.target_system, m.target_component) {
                    let now = self.services.mission_current(self.mission_progress(ap));
                    if m.seq != now.seq {
                        let t = crate::link::telemetry::status_text(
                            crate::link::dialect::MavSeverity::MAV_SEVERITY_WARNING,
                            "MISSION_SET_CURRENT not supported",
                            "",
                        );
                        self.reply(Outbound::StatusText(t));
                    }
                    self.reply(Outbound::MissionCurrent(now));
                }
            }
            Inbound::CommandInt(m) => {
                self.on_command(&command_long_of_int(&m), (f.sys_id, f.comp_id), now_us, ap)
            }
        }
        self.stream_params(ap);
    }
}

#[derive(Clone, Copy)]
struct FrameSender {
    sys_id: u8,
    comp_id: u8,
}

/// A decoded inbound message and its sender.
#[derive(Clone, Debug, PartialEq)]
pub struct ReceivedMessage {
    /// Sender's system id.
    pub sys_id: u8,
    /// Sender's component id.
    pub comp_id: u8,
    /// The message.
    pub msg: Inbound,
}

/// One CRC-checked frame after decoding: what a board's receiving task hands to the task that
/// owns the [`Link`] ([`Link::receive`]) when framing and dispatch run in different tasks.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // one message at a time, copied once into a channel
pub enum Received {
    /// A message of the inbound set.
    Message(ReceivedMessage),
    /// A frame that is not (counted by the link).
    Undecodable(DecodeError),
}

impl Received {
    /// Decodes `f`.
    pub fn of(f: &RawFrame<'_>) -> Self {
        match decode(f) {
            Ok(msg) => Received::Message(ReceivedMessage { sys_id: f.sys_id, comp_id: f.comp_id, msg }),
            Err(e) => Received::Undecodable(e),
        }
    }
}

/// The link state machine (see the module docs).
pub struct Link {
    parser: FrameParser,
    router: Router,
    v1: V1Detector,
}

impl Link {
    /// A link for vehicle `own_system`, time-stamping fixes with `fix_clock`.
    pub const fn new(own_system: u8, fix_clock: FixClock) -> Self {
        Self {
            parser: FrameParser::new(),
            router: Router {
                own_system,
                fix_clock,
                mission: MissionUpload::new(),
                run: MissionRun::new(),
                obstacles: ObstacleAssembler::new(),
                replies: Deque::new(),
                hil: None,
                stats: LinkStats {
                    decode_errors: 0,
                    ignored: 0,
                    replies_dropped: 0,
                    odometry_rejected: 0,
                    hil_samples: 0,
                    hil_overwritten: 0,
                    unknown_params: 0,
                    not_for_us: 0,
                },
                peer_seen: false,
                param_stream: None,
                services: Services::new(),
                manual: ManualControl::new(),
                odometry_text_us: None,
                v1_text_us: None,
            },
            v1: V1Detector::new(),
        }
    }

    /// Feeds one received byte at firmware time `now_us`.
    pub fn push_byte<A: Autopilot>(&mut self, byte: u8, now_us: u64, ap: &mut A) {
        let router = &mut self.router;
        self.parser.push(byte, &frame_extra_crc, &mut |f: &RawFrame<'_>| router.on_frame(f, now_us, ap));
        if self.v1.push(byte) {
            self.router.on_v1_heartbeat(now_us);
        }
    }

    /// Handles one frame decoded elsewhere (a board's receiving task, [`Received::of`]) at
    /// firmware time `now_us`; same effect as the frame's bytes through [`Link::push_bytes`].
    pub fn receive<A: Autopilot>(&mut self, r: Received, now_us: u64, ap: &mut A) {
        self.router.on_received(r, now_us, ap);
    }

    /// Feeds received bytes at firmware time `now_us`.
    pub fn push_bytes<A: Autopilot>(&mut self, bytes: &[u8], now_us: u64, ap: &mut A) {
        for &b in bytes {
            self.push_byte(b, now_us, ap);
        }
    }

    /// Periodic work (call at ≥ 10 Hz): mission retries, obstacle batch timeout.
    pub fn poll<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        if let Some(r) = self.router.mission.poll(now_us) {
            self.router.mission_reply(r, ap);
        }
        self.router.stream_params(ap);
        self.router.obstacles.poll(now_us, ap);
        self.router.run.poll(&self.router.mission, now_us, ap);
        let free = REPLY_QUEUE_LEN - self.router.replies.len();
        let progress = self.router.mission_progress(ap);
        let thr_max = ap.get_param("THR_MAX").unwrap_or(0.0);
        let r = &mut self.router;
        let budget = free.saturating_sub(REPLY_RESERVE);
        r.services.poll(now_us, &ap.telemetry(), progress, thr_max, budget, |m| {
            let _ = r.replies.push_back(m);
        });
        // The setup services' texts (calibration progress, refusals), at most a queue's worth.
        for _ in 0..crate::setup::TEXT_QUEUE_LEN {
            let Some(t) = ap.setup_text() else { break };
            let ok = t.starts_with("[cal]") && !t.contains("failed") && !t.contains("denied");
            let severity = if ok {
                crate::link::dialect::MavSeverity::MAV_SEVERITY_INFO
            } else {
                crate::link::dialect::MavSeverity::MAV_SEVERITY_WARNING
            };
            self.router.reply(Outbound::StatusText(crate::link::telemetry::status_text(severity, "", &t)));
        }
    }

    /// Closes the open obstacle batch (lockstep: on every HIL_SENSOR).
    pub fn flush_obstacles<A: Autopilot>(&mut self, now_us: u64, ap: &mut A) {
        self.router.obstacles.flush(now_us, ap);
    }

    /// The latest HIL_SENSOR sample not yet taken.
    pub fn take_hil_sample(&mut self) -> Option<HilSample> {
        self.router.hil.take()
    }

    /// Next queued reply.
    pub fn pop_reply(&mut self) -> Option<Outbound> {
        self.router.replies.pop_front()
    }

    /// `true` once any valid frame of the inbound set arrived.
    pub fn peer_seen(&self) -> bool {
        self.router.peer_seen
    }

    /// Valid MAVLink v1 HEARTBEATs received (refused, see [`crate::link::v1`]).
    pub fn v1_heartbeats(&self) -> u32 {
        self.v1.heartbeats
    }

    /// Framer counters.
    pub fn parser_stats(&self) -> ParserStats {
        self.parser.stats()
    }

    /// Framer work so far (byte operations; see [`FrameParser::work`]).
    pub fn parser_work(&self) -> u64 {
        self.parser.work()
    }

    /// The telemetry scheduler's stream rates set through this link (SET_MESSAGE_INTERVAL,
    /// REQUEST_MESSAGE; [`crate::link::services::StreamRates`]).
    pub fn stream_rates(&self) -> crate::link::services::StreamRates {
        self.router.services.rates()
    }

    /// Link counters.
    pub fn stats(&self) -> LinkStats {
        self.router.stats
    }

    /// Obstacle decoder counters.
    pub fn obstacle_stats(&self) -> ObstacleStats {
        self.router.obstacles.stats()
    }

    /// MANUAL_CONTROL / RC_CHANNELS_OVERRIDE counters.
    pub fn manual_control_stats(&self) -> ManualControlStats {
        self.router.manual.stats()
    }

    /// The RC_CHANNELS_OVERRIDE channels in effect, mapped rest values for released ones (for
    /// RC_CHANNELS telemetry on a board without a receiver).
    pub fn override_channels(&self, p: &parapet_core::rc::map::RcParams) -> parapet_core::rc::RawChannels {
        self.router.manual.override_channels(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;
    use crate::app::autopilot::VehicleCommand;
    use crate::link::dialect::{
        MavCmd, MavResult, COMMAND_LONG_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
        OBSTACLE_DISTANCE_3D_DATA,
    };
    use crate::link::framing::FrameWriter;
    use mavlink_core::MessageData;
    use std::vec::Vec;

    fn gcs() -> FrameWriter {
        FrameWriter::new(255, 190)
    }

    fn send<D: MessageData>(w: &mut FrameWriter, m: &D) -> Vec<u8> {
        w.encode(m).raw_bytes().to_vec()
    }

    fn replies(l: &mut Link) -> Vec<Outbound> {
        core::iter::from_fn(|| l.pop_reply()).collect()
    }

    #[test]
    fn mission_upload_through_the_link_installs_the_path() {
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Arrival);
        let mut w = gcs();
        l.push_bytes(
            &send(
                &mut w,
                &MISSION_COUNT_DATA { count: 2, target_system: 1, target_component: 1, ..Default::default() },
            ),
            0,
            &mut ap,
        );
        assert!(
            matches!(replies(&mut l)[..], [Outbound::MissionRequestInt(ref r)] if r.seq == 0 && r.target_system == 255)
        );
        for seq in 0..2u16 {
            let item = MISSION_ITEM_INT_DATA {
                x: 10_000 * i32::from(seq + 1),
                y: 0,
                z: -1.0,
                seq,
                command: MavCmd::MAV_CMD_NAV_WAYPOINT as u16,
                frame: MavFrame::MAV_FRAME_LOCAL_NED,
                target_system: 1,
                target_component: 1,
                ..Default::default()
            };
            l.push_bytes(&send(&mut w, &item), 0, &mut ap);
        }
        let r = replies(&mut l);
        assert!(
            matches!(r.last(), Some(Outbound::MissionAck(a)) if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED)
        );
        assert_eq!(ap.paths, vec![vec![Vec3::new(1.0, 0.0, -1.0), Vec3::new(2.0, 0.0, -1.0)]]);
    }

    /// Framing in one task and dispatch in another (the board: [`Received::of`] in the link
    /// task, [`Link::receive`] in the outer task) does what the bytes through the link do.
    #[test]
    fn frames_decoded_elsewhere_are_dispatched_like_bytes() {
        let arm = COMMAND_LONG_DATA {
            param1: 1.0,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
            target_system: 1,
            ..Default::default()
        };
        let bytes = send(&mut gcs(), &arm);
        let (mut a, mut b) = (RecordingAutopilot::new(), RecordingAutopilot::new());
        let (mut la, mut lb) = (Link::new(1, FixClock::Message), Link::new(1, FixClock::Message));
        la.push_bytes(&bytes, 5, &mut a);
        let mut parser = FrameParser::new();
        let mut got = Vec::new();
        parser.push_bytes(&bytes, frame_extra_crc, |f| got.push(Received::of(f)));
        assert_eq!(got.len(), 1);
        for r in got {
            lb.receive(r, 5, &mut b);
        }
        assert_eq!(a.commands, b.commands);
        assert_eq!(replies(&mut la), replies(&mut lb));
        assert!(lb.peer_seen());
        // An undecodable frame is counted, not dispatched.
        lb.receive(Received::Undecodable(DecodeError::InvalidPayload), 6, &mut b);
        assert_eq!(lb.stats().decode_errors, 1);
    }

    #[test]
    fn commands_odometry_and_obstacles_reach_the_autopilot() {
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Message);
        let mut w = gcs();
        let arm = COMMAND_LONG_DATA {
            param1: 1.0,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
            target_system: 1,
            ..Default::default()
        };
        l.push_bytes(&send(&mut w, &arm), 5, &mut ap);
        assert!(
            matches!(replies(&mut l)[..], [Outbound::CommandAck(ref a)] if a.result == MavResult::MAV_RESULT_ACCEPTED)
        );
        assert_eq!(ap.commands, vec![VehicleCommand::Arm]);

        let odo = ODOMETRY_DATA {
            time_usec: 1234,
            x: 1.0,
            y: 2.0,
            z: -3.0,
            q: [1.0, 0.0, 0.0, 0.0],
            vx: 0.5,
            frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            ..Default::default()
        };
        l.push_bytes(&send(&mut w, &odo), 0, &mut ap);
        assert_eq!(ap.fixes.len(), 1);
        assert_eq!(ap.fixes[0].t_us, 1234);
        assert_eq!(ap.fixes[0].velocity_ned, Vec3::new(0.5, 0.0, 0.0));
        let mut bad = odo;
        bad.x = f32::NAN;
        l.push_bytes(&send(&mut w, &bad), 0, &mut ap);
        assert_eq!(l.stats().odometry_rejected, 1);
        assert_eq!(ap.fixes.len(), 1);

        let ob = OBSTACLE_DISTANCE_3D_DATA {
            time_boot_ms: 3,
            x: 2.0,
            obstacle_id: 4,
            frame: MavFrame::MAV_FRAME_LOCAL_NED,
            ..Default::default()
        };
        l.push_bytes(&send(&mut w, &ob), 0, &mut ap);
        l.flush_obstacles(0, &mut ap);
        assert_eq!(ap.obstacle_batches.len(), 1);
        assert_eq!(ap.obstacle_batches[0][0].id, 4);
        assert!(l.peer_seen());
    }

    #[test]
    fn odometry_carries_the_yaw_of_q_to_the_autopilot() {
        let q = parapet_core::wire::codes::odometry_quaternion(-2.0);
        let odo = |q: [f32; 4]| ODOMETRY_DATA {
            q,
            frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            ..Default::default()
        };
        let yaw = odometry_fix(&odo(q), 0).and_then(|f| f.yaw);
        assert!(yaw.is_some_and(|y| (y + 2.0).abs() < 1e-5), "{yaw:?}");
        // Unknown attitude (MAVLink: zeros or NaN): the fix still counts, without a yaw.
        assert_eq!(odometry_fix(&odo([0.0; 4]), 0).map(|f| f.yaw), Some(None));
        assert_eq!(odometry_fix(&odo([f32::NAN, 0.0, 0.0, 0.0]), 0).map(|f| f.yaw), Some(None));
        // Through the link: the recorded fix holds it.
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Message);
        let mut w = gcs();
        l.push_bytes(&send(&mut w, &odo(q)), 0, &mut ap);
        assert!(ap.fixes.last().and_then(|f| f.yaw).is_some_and(|y| (y + 2.0).abs() < 1e-5));
    }

    #[test]
    fn odometry_body_frame_velocity_is_rotated() {
        // Yaw 90°: body forward = east.
        let h = core::f32::consts::FRAC_PI_4;
        let odo = ODOMETRY_DATA {
            q: [h.cos(), 0.0, 0.0, h.sin()],
            vx: 1.0,
            frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            child_frame_id: MavFrame::MAV_FRAME_BODY_FRD,
            ..Default::default()
        };
        let f = odometry_fix(&odo, 0).map(|f| f.velocity_ned);
        assert!(f.is_some_and(|v| (v - Vec3::new(0.0, 1.0, 0.0)).norm() < 1e-5), "{f:?}");
        let mut enu = odo;
        enu.frame_id = MavFrame::MAV_FRAME_LOCAL_ENU;
        assert_eq!(odometry_fix(&enu, 0), None);
    }

    #[test]
    fn param_set_and_read_answer_param_value() {
        use crate::link::dialect::{PARAM_REQUEST_READ_DATA, PARAM_SET_DATA};
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Arrival);
        let mut w = gcs();
        let set = |name: &str, v: f32| PARAM_SET_DATA {
            param_value: v,
            target_system: 1,
            target_component: 1,
            param_id: crate::link::outbound::name(name),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        };
        l.push_bytes(&send(&mut w, &set("CBF_MU", 0.9)), 0, &mut ap);
        match &replies(&mut l)[..] {
            [Outbound::ParamValue(v)] => {
                assert_eq!(v.param_value, 0.9);
                assert_eq!(usize::from(v.param_index), crate::link::params::index_of("CBF_MU").unwrap_or(99));
                assert_eq!(usize::from(v.param_count), crate::link::params::COUNT);
            }
            other => panic!("{other:?}"),
        }
        // Armed: refused, answered with the value still in effect.
        ap.armed = true;
        l.push_bytes(&send(&mut w, &set("CBF_MU", 0.5)), 0, &mut ap);
        assert!(matches!(&replies(&mut l)[..], [Outbound::ParamValue(v)] if v.param_value == 0.9));
        // Unknown names are not answered.
        l.push_bytes(&send(&mut w, &set("NOPE", 1.0)), 0, &mut ap);
        assert!(replies(&mut l).is_empty());
        assert_eq!(l.stats().unknown_params, 1);
        let read = PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: 1,
            target_component: 1,
            param_id: crate::link::outbound::name("CBF_MU"),
        };
        l.push_bytes(&send(&mut w, &read), 0, &mut ap);
        assert!(matches!(&replies(&mut l)[..], [Outbound::ParamValue(v)] if v.param_value == 0.9));
    }

    #[test]
    fn reply_queue_overflow_is_counted() {
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Arrival);
        let mut w = gcs();
        let land = COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_NAV_LAND as u16,
            target_system: 1,
            ..Default::default()
        };
        for _ in 0..REPLY_QUEUE_LEN + 3 {
            l.push_bytes(&send(&mut w, &land), 0, &mut ap);
        }
        assert_eq!(l.stats().replies_dropped, 3);
        assert_eq!(crate::link::telemetry::ErrorCounters::from_link(&l).replies_dropped, 3);
        assert_eq!(replies(&mut l).len(), REPLY_QUEUE_LEN);
    }
}
