//! The MAVLink dispatcher, hardware-independent: decoded messages in → cascade updates +
//! replies out ([`crate::link::endpoint::Link`] is its public face; the inputs' conversions are
//! [`crate::link::inputs`]).
//!
//! [`Link`] owns the framer, the mission upload, the obstacle decoder and a small reply queue.
//! The board's communication task feeds it received bytes, drains [`Link::pop_reply`] to the
//! UART and calls [`Link::poll`] periodically. Inbound messages and what they do:
//!
//! | message | action |
//! |---|---|
//! | ODOMETRY (331) | from a VIO / vision estimator (`estimator_type`): to the navigation filter as a relative source, like VISION_POSITION_ESTIMATE ([`crate::link::position_sources::odometry_is_vision`]; refused fixes counted in `position_rejected`); otherwise (motion capture, unknown) `update_position`: frame_id LOCAL_NED; velocity in child_frame_id LOCAL_NED, or BODY_FRD (rotated to NED with the message's quaternion). Non-finite → rejected, counted; other frames (LOCAL_FRD, …) → rejected, counted, STATUSTEXT WARNING [`ODOMETRY_REFUSED_TEXT`] at most every 10 s |
//! | GPS_INPUT (232), VISION_POSITION_ESTIMATE (102) | `update_position` after the conversion to local NED and the checks of [`crate::link::position_sources`]; refused fixes counted (`position_rejected`). Any accepted fix (ODOMETRY too): STATUSTEXT INFO [`crate::link::position_sources::POSITION_SOURCE_TEXT`] + the message name when the source changes (not for the first); none for 1 s: WARNING [`crate::link::position_sources::POSITION_LOST_TEXT`] once |
//! | OBSTACLE_DISTANCE_3D (11037), DEBUG_VECT `OBV<id>` | obstacle points, see [`crate::link::obstacles`] |
//! | OBSTACLE_DISTANCE (330), DISTANCE_SENSOR (132) | range returns into the obstacle memory, see [`crate::link::obstacles`] |
//! | MISSION_COUNT / MISSION_ITEM_INT / MISSION_CLEAR_ALL | mission upload, see [`crate::link::mission`] |
//! | MISSION_REQUEST_LIST / MISSION_REQUEST_INT | mission download (the path the cascade took last) |
//! | MISSION_ITEM (39) / MISSION_REQUEST (40), deprecated float items | an upload item like MISSION_ITEM_INT; a download answered in MISSION_ITEM, see [`crate::link::mission_float`] |
//! | COMMAND_LONG / COMMAND_INT | arm / disarm / takeoff / land / mission start / hold, see [`crate::link::command`] (a takeoff refused for its height: STATUSTEXT, [`crate::link::takeoff_limit`]); REQUEST_MESSAGE(AUTOPILOT_VERSION) and REQUEST_AUTOPILOT_CAPABILITIES → ACK + AUTOPILOT_VERSION |
//! | PARAM_SET / PARAM_REQUEST_READ / PARAM_REQUEST_LIST | parameters, see [`crate::link::params`] |
//! | TIMESYNC | a request (tc1 = 0) is answered with tc1 = firmware time, ns, ts1 echoed |
//! | PING (4) | a request (target 0/0) is answered to the sender, see [`crate::link::services`] |
//! | SET_MODE (11) | legacy mode change: executed as MAV_CMD_DO_SET_MODE (base_mode, custom_mode); no ACK (the next HEARTBEAT shows the mode) |
//! | MISSION_SET_CURRENT (41) | answered with MISSION_CURRENT; jumping to another item is not supported (STATUSTEXT) |
//! | COMMAND: SET_MESSAGE_INTERVAL (511), GET_MESSAGE_INTERVAL (510), REQUEST_MESSAGE (512) | rates / one-shot of the streams of [`crate::link::services`]; REQUEST_MESSAGE also AUTOPILOT_VERSION, COMPONENT_METADATA ([`crate::link::metadata`]) and AVAILABLE_MODES (param2 = mode index, 0 = all; streamed after the ACK, [`crate::link::standard_modes`]) |
//! | FILE_TRANSFER_PROTOCOL (110) | the read-only FTP server of [`crate::link::ftp`]; a BurstReadFile's packets are paced like the parameter stream (one per poll or frame while more than [`REPLY_RESERVE`] queue slots are free) |
//! | HIL_SENSOR (107) | simulated IMU for the lockstep PIL link, see [`crate::pil::lockstep`]; with the XMAG, YMAG, ZMAG bits its magnetometer field (gauss, FRD) becomes a heading (tilt-compensated with the attitude estimate, `parapet_core::nav::mag`) that a GPS_INPUT without a yaw carries to the estimator (counted in `mag_headings`); with `fields_updated` bit `HIL_SENSOR_UPDATED_PRESSURE_ALT` its `pressure_alt` (m AMSL) to the navigation filter as a barometer height ([`crate::link::inputs::hil_baro_down`], counted in `baro_heights`) |
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
    MavFrame, MavMissionResult, MavMissionType, MavParamType, MavResult, COMMAND_LONG_DATA,
    MISSION_ITEM_INT_DATA, ODOMETRY_DATA, PARAM_VALUE_DATA, TIMESYNC_DATA,
};
use heapless::Deque;

use crate::app::autopilot::{Autopilot, CommandRejected, FlightMode, FlightPhase, VehicleCommand};
use crate::link::command::{addressed_to, command_long_of_int, execute};
use crate::link::framing::AUTOPILOT_COMPONENT_ID;
use crate::link::inputs::{
    hil_baro_down, hil_mag, odometry_fix, FixClock, HilSample, ODOMETRY_REFUSED_TEXT, ODOMETRY_TEXT_US,
};
use crate::link::manual_control::ManualControl;
use crate::link::messages::{DecodeError, Inbound};
use crate::link::mission::{DownloadReply, MissionReply, MissionUpload};
use crate::link::mission_run::MissionRun;
use crate::link::obstacles::ObstacleAssembler;
use crate::link::outbound::Outbound;
use crate::link::position_sources::{
    gps_input_fix, gps_input_noise, odometry_is_vision, odometry_noise, vision_noise, FixRefusal, Source,
    SourceMonitor, VisionVelocity,
};
use crate::link::received::{LinkStats, Received};
use crate::link::services::FixAccuracy;
use crate::link::services::{MissionProgress, Services};
use crate::link::standard_modes;
use crate::setup::SetupAck;

/// Reply queue capacity.
pub const REPLY_QUEUE_LEN: usize = 8;
/// Most PARAM_VALUEs of a PARAM_REQUEST_LIST stream queued per [`Link::poll`] or frame.
pub const PARAMS_PER_POLL: usize = 2;
/// Reply-queue slots a PARAM_REQUEST_LIST stream leaves free for other replies.
pub const REPLY_RESERVE: usize = 4;
/// MAVLink message id of AUTOPILOT_VERSION (MAV_CMD_REQUEST_MESSAGE param1).
const AUTOPILOT_VERSION_ID: f32 = 148.0;

/// The dispatcher's state (owned by [`Link`]).
pub(crate) struct Router {
    pub(crate) own_system: u8,
    pub(crate) fix_clock: FixClock,
    pub(crate) mission: MissionUpload,
    /// Runs the plan's takeoff / land / return items ([`crate::link::mission_run`]).
    pub(crate) run: MissionRun,
    pub(crate) obstacles: ObstacleAssembler,
    pub(crate) replies: Deque<Outbound, REPLY_QUEUE_LEN>,
    pub(crate) hil: Option<HilSample>,
    /// The time (µs) and heading of the last HIL_SENSOR magnetometer field (tilt-compensated with
    /// the attitude estimate, `parapet_core::nav::mag`), given to a GPS_INPUT without a yaw for 1 s.
    pub(crate) mag_heading: Option<(u64, f32)>,
    pub(crate) stats: LinkStats,
    pub(crate) peer_seen: bool,
    /// Next index of a PARAM_REQUEST_LIST stream (`None`: no stream).
    pub(crate) param_stream: Option<u16>,
    /// AVAILABLE_MODES still to send: the next and the last mode index (from 1), as the
    /// parameter stream ([`crate::link::standard_modes`]).
    pub(crate) modes_stream: Option<(u8, u8)>,
    pub(crate) services: Services,
    pub(crate) manual: ManualControl,
    /// When the last "ODOMETRY refused" STATUSTEXT went out.
    pub(crate) odometry_text_us: Option<u64>,
    /// VISION_POSITION_ESTIMATE's velocity by differences.
    pub(crate) vision: VisionVelocity,
    /// Which source feeds the fixes (STATUSTEXT on a switch or a loss).
    pub(crate) sources: SourceMonitor,
    /// When the last v1 refusal went out ([`crate::link::v1`]).
    pub(crate) v1_text_us: Option<u64>,
    /// AUTOPILOT_VERSION `uid` ([`crate::link::Link::set_uid`]; 0 until set).
    pub(crate) uid: u64,
    /// The MAVLink FTP server ([`crate::link::ftp`]).
    pub(crate) ftp: crate::link::ftp::FtpServer,
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

impl Router {
    /// A dispatcher for vehicle `own_system`, time-stamping fixes with `fix_clock`.
    pub(crate) const fn new(own_system: u8, fix_clock: FixClock) -> Self {
        Self {
            own_system,
            fix_clock,
            mission: MissionUpload::new(),
            run: MissionRun::new(),
            obstacles: ObstacleAssembler::new(),
            replies: Deque::new(),
            hil: None,
            mag_heading: None,
            stats: LinkStats::ZERO,
            peer_seen: false,
            param_stream: None,
            modes_stream: None,
            services: Services::new(),
            manual: ManualControl::new(),
            odometry_text_us: None,
            vision: VisionVelocity::new(),
            sources: SourceMonitor::new(),
            v1_text_us: None,
            uid: 0,
            ftp: crate::link::ftp::FtpServer::new(),
        }
    }

    fn for_me(&mut self, target_system: u8, target_component: u8) -> bool {
        let ok = addressed_to(target_system, target_component, (self.own_system, AUTOPILOT_COMPONENT_ID));
        if !ok {
            self.stats.not_for_us = self.stats.not_for_us.saturating_add(1);
        }
        ok
    }

    /// Continues a PARAM_REQUEST_LIST stream (see the module docs).
    pub(crate) fn stream_params<A: Autopilot>(&mut self, ap: &mut A) {
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

    /// Continues an AVAILABLE_MODES answer: one mode per call while more than
    /// [`REPLY_RESERVE`] queue slots are free.
    pub(crate) fn stream_modes(&mut self) {
        let Some((next, last)) = self.modes_stream else { return };
        if REPLY_QUEUE_LEN - self.replies.len() <= REPLY_RESERVE {
            return;
        }
        self.reply(Outbound::AvailableMode(next));
        self.modes_stream = (next < last).then_some((next + 1, last));
    }

    /// Continues an FTP burst: one packet per call while more than [`REPLY_RESERVE`] queue
    /// slots are free.
    pub(crate) fn stream_ftp(&mut self) {
        if REPLY_QUEUE_LEN - self.replies.len() <= REPLY_RESERVE {
            return;
        }
        if let Some(r) = self.ftp.next_burst() {
            self.reply(Outbound::Ftp(r));
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
        let version = Some(Outbound::AutopilotVersion(self.uid));
        let (result, then) = match cmd.command {
            crate::link::command::id::REQUEST_AUTOPILOT_CAPABILITIES => {
                (MavResult::MAV_RESULT_ACCEPTED, version)
            }
            crate::link::command::id::REQUEST_MESSAGE if cmd.param1 == AUTOPILOT_VERSION_ID => {
                (MavResult::MAV_RESULT_ACCEPTED, version)
            }
            crate::link::command::id::REQUEST_MESSAGE
                if cmd.param1 == crate::link::metadata::COMPONENT_METADATA_ID =>
            {
                let ms = u32::try_from(now_us / 1000).unwrap_or(u32::MAX);
                (MavResult::MAV_RESULT_ACCEPTED, Some(Outbound::ComponentMetadata(ms)))
            }
            crate::link::command::id::REQUEST_MESSAGE if cmd.param1 == standard_modes::AVAILABLE_MODES_ID => {
                match standard_modes::requested(cmd.param2) {
                    Some(range) => {
                        self.modes_stream = Some(range);
                        (MavResult::MAV_RESULT_ACCEPTED, None)
                    }
                    None => (MavResult::MAV_RESULT_DENIED, None),
                }
            }
            crate::link::command::id::REQUEST_MESSAGE
                if !self.services.can_send(cmd.param1, &ap.telemetry()) =>
            {
                (MavResult::MAV_RESULT_DENIED, None)
            }
            crate::link::command::id::REQUEST_MESSAGE if self.services.request(cmd.param1) => {
                (MavResult::MAV_RESULT_ACCEPTED, None)
            }
            crate::link::command::id::REQUEST_MESSAGE => (MavResult::MAV_RESULT_DENIED, None),
            crate::link::command::id::GET_HOME_POSITION => {
                let known = self.services.home().is_some()
                    && self.services.request(crate::link::services::HOME_POSITION_ID as f32);
                let r = if known {
                    MavResult::MAV_RESULT_ACCEPTED
                } else {
                    MavResult::MAV_RESULT_TEMPORARILY_REJECTED
                };
                (r, None)
            }
            crate::link::command::id::DO_SET_HOME => {
                // p1 = 1: here; else p5/p6 latitude/longitude (degrees), p7 altitude AMSL (m).
                let e7 = crate::link::mission_float::e7_of_degrees;
                (self.do_set_home(cmd.param1 == 1.0, e7(cmd.param5), e7(cmd.param6), cmd.param7, ap), None)
            }
            crate::link::command::id::DO_REPOSITION => {
                (self.reposition(&crate::link::reposition::of_long(cmd), now_us, ap), None)
            }
            crate::link::command::id::SET_MESSAGE_INTERVAL => {
                (self.services.set_interval(cmd.param1, cmd.param2), None)
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
                (r, None)
            }
        };
        self.reply(Outbound::CommandAck(crate::link::command::ack(cmd.command, result, sender)));
        if let Some(m) = then {
            self.reply(m);
        }
        let asked = match cmd.command {
            crate::link::command::id::TAKEOFF => Some(cmd.param7),
            crate::link::command::id::MISSION_START => self.mission.plan().takeoff.map(|t| t.1),
            _ => None,
        };
        if result == MavResult::MAV_RESULT_DENIED {
            self.takeoff_refused(asked);
        }
    }

    /// MAV_CMD_DO_SET_HOME: home here (`here`) or at latitude/longitude (10⁻⁷ °) and altitude
    /// AMSL (m) ([`crate::link::services::Services::set_home`]: refused while armed, or out of
    /// the local frame's range).
    fn do_set_home<A: Autopilot>(
        &mut self,
        here: bool,
        lat_e7: i32,
        lon_e7: i32,
        alt_m: f32,
        ap: &mut A,
    ) -> MavResult {
        let s = ap.telemetry();
        let home = if here {
            Some(s.position_ned)
        } else {
            parapet_core::wire::geo::global_to_ned(
                lat_e7,
                lon_e7,
                alt_m,
                parapet_core::wire::geo::AltRef::Amsl,
            )
            .ok()
        };
        home.map_or(MavResult::MAV_RESULT_DENIED, |h| self.services.set_home(h, s.armed))
    }

    /// MAV_CMD_DO_REPOSITION ([`crate::link::reposition`]): an accepted one pauses the mission.
    fn reposition<A: Autopilot>(
        &mut self,
        g: &crate::link::reposition::Goto,
        now_us: u64,
        ap: &mut A,
    ) -> MavResult {
        let r = crate::link::reposition::execute(g, now_us, ap);
        if r == MavResult::MAV_RESULT_ACCEPTED {
            self.run.stop();
        }
        r
    }

    /// A takeoff to `height_m` was refused Invalid: the STATUSTEXT of
    /// [`crate::link::takeoff_limit`] when that was for its height.
    fn takeoff_refused(&mut self, height_m: Option<f32>) {
        if crate::link::takeoff_limit::refused_for_height(height_m) {
            self.reply(Outbound::StatusText(crate::link::takeoff_limit::text()));
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
        let to_mission = matches!(
            cmd.command,
            crate::link::command::id::DO_SET_MODE | crate::link::command::id::DO_SET_STANDARD_MODE
        ) && r == MavResult::MAV_RESULT_ACCEPTED
            && crate::link::command::decode_command(cmd) == Ok(VehicleCommand::SetMode(FlightMode::Mission));
        let s = ap.telemetry();
        let on_ground_takes_off = s.phase == FlightPhase::Idle && MissionRun::takes_off(&self.mission);
        let flies = to_mission
            && self.mission.stored_len() > 0
            && s.armed
            && (matches!(s.phase, FlightPhase::Hover | FlightPhase::Takeoff) || on_ground_takes_off);
        if flies && self.run.start(&self.mission, now_us, ap) == Err(CommandRejected::Invalid) {
            self.takeoff_refused(self.mission.plan().takeoff.map(|t| t.1));
        }
    }

    /// A v1 HEARTBEAT arrived: the v1 STATUSTEXT refusal, at most once per
    /// [`crate::link::v1::V1_TEXT_US`].
    fn on_v1_heartbeat(&mut self, now_us: u64) {
        self.stats.v1_heartbeats = self.stats.v1_heartbeats.saturating_add(1);
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
    /// The time stamp of a fix whose message says `msg_us` ([`FixClock`]).
    pub(crate) fn fix_time(&self, msg_us: u64, now_us: u64) -> u64 {
        match self.fix_clock {
            FixClock::Arrival => now_us,
            FixClock::Message => msg_us,
        }
    }

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
    pub(crate) fn mission_progress<A: Autopilot>(&self, ap: &A) -> MissionProgress {
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

    pub(crate) fn reply(&mut self, m: Outbound) {
        if self.replies.push_back(m).is_err() {
            self.stats.replies_dropped = self.stats.replies_dropped.saturating_add(1);
        }
    }

    pub(crate) fn mission_reply<A: Autopilot>(&mut self, r: MissionReply, ap: &mut A) {
        match r {
            MissionReply::Request(q) => self.reply(Outbound::MissionRequestInt(q)),
            MissionReply::Ack(a) => self.reply(Outbound::MissionAck(a)),
            MissionReply::Clear => {
                self.clear_mission(ap);
                let ack = self.mission.ack_for(MavMissionResult::MAV_MISSION_ACCEPTED);
                self.reply(Outbound::MissionAck(ack));
            }
            MissionReply::Complete => {
                let path = self.mission.path(); // more than the cascade holds: the rest streams
                let first = path.get(..path.len().min(parapet_core::controller::PATH_CAPACITY));
                let taken = match first.filter(|p| !p.is_empty()) {
                    Some(p) => ap.set_path(p),
                    None => {
                        ap.clear_path();
                        Ok(())
                    }
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

    /// Sends a download answer; `float`: an item goes out as MISSION_ITEM (the request was the
    /// deprecated MISSION_REQUEST, [`crate::link::mission_float`]).
    fn download_reply(&mut self, r: DownloadReply, float: bool) {
        self.reply(match r {
            DownloadReply::Count(c) => Outbound::MissionCount(c),
            DownloadReply::Item(i) if float => {
                Outbound::MissionItem(crate::link::mission_float::float_item(&i))
            }
            DownloadReply::Item(i) => Outbound::MissionItemInt(i),
            DownloadReply::Ack(a) => Outbound::MissionAck(a),
        });
    }

    /// A mission item of an upload (MISSION_ITEM_INT, or a MISSION_ITEM converted to one).
    fn on_mission_item<A: Autopilot>(
        &mut self,
        m: &MISSION_ITEM_INT_DATA,
        f: FrameSender,
        now_us: u64,
        ap: &mut A,
    ) {
        if self.for_me(m.target_system, m.target_component) {
            let takeoff_max = ap
                .get_param("MIS_TKO_ALT_MAX")
                .unwrap_or(parapet_core::outer::guidance::TAKEOFF_HEIGHT_MAX_DEFAULT);
            if let Some(r) = self.mission.on_item(m, f.sys_id, f.comp_id, now_us, takeoff_max) {
                self.mission_reply(r, ap);
            }
        }
    }

    /// A mission download request for item `seq` (`float`: MISSION_REQUEST, answered in MISSION_ITEM).
    fn on_mission_request(
        &mut self,
        seq: u16,
        target: (u8, u8),
        mission_type: MavMissionType,
        f: FrameSender,
        float: bool,
    ) {
        if self.for_me(target.0, target.1) {
            let r = self.mission.on_request_item(seq, mission_type, f.sys_id, f.comp_id);
            self.download_reply(r, float);
        }
    }

    pub(crate) fn on_received<A: Autopilot>(&mut self, r: Received, now_us: u64, ap: &mut A) {
        let (msg, f) = match r {
            Received::Message(m) => (m.msg, FrameSender { sys_id: m.sys_id, comp_id: m.comp_id }),
            Received::V1Heartbeat => {
                self.on_v1_heartbeat(now_us);
                return;
            }
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
                if let Some(down) = hil_baro_down(&m) {
                    ap.navigation_height(self.fix_time(m.time_usec, now_us), down);
                    self.stats.baro_heights = self.stats.baro_heights.saturating_add(1);
                }
                if let Some(b) = hil_mag(&m) {
                    let a = ap.telemetry().attitude_rpy;
                    if let Some(h) = parapet_core::nav::mag::heading(&b, a.x, a.y) {
                        self.mag_heading = Some((self.fix_time(m.time_usec, now_us), h));
                        self.stats.mag_headings = self.stats.mag_headings.saturating_add(1);
                    }
                }
            }
            Inbound::Odometry(m) if odometry_is_vision(&m) => {
                let fix = odometry_fix(&m, self.fix_time(m.time_usec, now_us)).ok_or(FixRefusal::NonFinite);
                self.external_fix(fix.map(Some), Source::Odometry, odometry_noise(&m), now_us, ap);
            }
            Inbound::Odometry(m) => match odometry_fix(&m, self.fix_time(m.time_usec, now_us)) {
                Some(fix) => {
                    ap.update_position(&fix);
                    self.source_accepted(Source::Odometry, now_us);
                    self.services.on_fix(FixAccuracy::from_pose_covariance(&m.pose_covariance));
                }
                None => {
                    self.stats.odometry_rejected = self.stats.odometry_rejected.saturating_add(1);
                    self.refuse_odometry_frame(&m, now_us);
                }
            },
            Inbound::GpsInput(m) => {
                let t = self.fix_time(m.time_usec, now_us);
                // A GPS without a heading (yaw 0): the magnetometer's, as the estimator takes it.
                let mag = parapet_core::nav::mag::fresh_heading(self.mag_heading, t);
                let fix = gps_input_fix(&m, t)
                    .map(|f| Some(crate::app::autopilot::PositionFix { yaw: f.yaw.or(mag), ..f }));
                self.external_fix(fix, Source::Gps, gps_input_noise(&m), now_us, ap);
            }
            Inbound::VisionPosition(m) => {
                let t = self.fix_time(m.usec, now_us);
                let fix = self.vision.fix(&m, t);
                self.external_fix(fix, Source::Vision, vision_noise(&m), now_us, ap);
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
            Inbound::MissionItemInt(m) => self.on_mission_item(&m, f, now_us, ap),
            #[allow(deprecated)] // MISSION_ITEM: still sent by old ground stations
            Inbound::MissionItem(m) => {
                self.on_mission_item(&crate::link::mission_float::int_item(&m), f, now_us, ap)
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
                    self.download_reply(r, false);
                }
            }
            Inbound::MissionRequestInt(m) => self.on_mission_request(
                m.seq,
                (m.target_system, m.target_component),
                m.mission_type,
                f,
                false,
            ),
            #[allow(deprecated)] // MISSION_REQUEST: still sent by old ground stations
            Inbound::MissionRequest(m) => {
                self.on_mission_request(m.seq, (m.target_system, m.target_component), m.mission_type, f, true)
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
                    // parameter protocol); unknown names are not answered. Armed, only the
                    // in-flight tunables change (parapet_core::params::IN_FLIGHT); the others
                    // are refused with a STATUSTEXT saying why.
                    if ap.set_param(name, m.param_value) == Err(crate::link::params::ParamRejected::NotNow) {
                        let t = crate::link::telemetry::status_text(
                            crate::link::dialect::MavSeverity::MAV_SEVERITY_WARNING,
                            crate::link::params::PARAM_ARMED_TEXT,
                            name,
                        );
                        self.reply(Outbound::StatusText(t));
                    }
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
            Inbound::FtpRequest(r) => {
                if self.for_me(r.target_system, r.target_component) {
                    if let Some(a) = self.ftp.on_request(&r, (f.sys_id, f.comp_id)) {
                        self.reply(Outbound::Ftp(a));
                    }
                }
            }
            Inbound::Ping(m) => {
                if let Some(r) = crate::link::services::ping_reply(&m, (f.sys_id, f.comp_id)) {
                    self.reply(Outbound::Ping(r));
                }
            }
            #[allow(deprecated)] // legacy SET_MODE: still sent by ground stations
            Inbound::SetMode(m) => {
                if self.for_me(m.target_system, 0) {
                    // custom_mode in PX4's encoding (main << 16 | sub << 24), as PX4 reads it.
                    let c = COMMAND_LONG_DATA {
                        command: crate::link::command::id::DO_SET_MODE,
                        param1: f32::from(m.base_mode),
                        param2: f32::from((m.custom_mode >> 16) as u8),
                        param3: f32::from((m.custom_mode >> 24) as u8),
                        ..Default::default()
                    };
                    let r = execute(&c, now_us, ap);
                    self.mission_mode_flies(&c, r, now_us, ap);
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
            Inbound::CommandInt(m) if m.command == crate::link::command::id::DO_SET_HOME => {
                // x, y in 10⁻⁷ ° taken exactly (COMMAND_LONG's f32 of them is not).
                if self.for_me(m.target_system, m.target_component) {
                    let r = self.do_set_home(m.param1 == 1.0, m.x, m.y, m.z, ap);
                    self.reply(Outbound::CommandAck(crate::link::command::ack(
                        m.command,
                        r,
                        (f.sys_id, f.comp_id),
                    )));
                }
            }
            Inbound::CommandInt(m) if m.command == crate::link::command::id::DO_REPOSITION => {
                // x, y in 10⁻⁷ ° taken exactly, z in the command's frame.
                if self.for_me(m.target_system, m.target_component) {
                    let r = crate::link::reposition::of_int(&m)
                        .map_or_else(|r| r, |g| self.reposition(&g, now_us, ap));
                    self.reply(Outbound::CommandAck(crate::link::command::ack(
                        m.command,
                        r,
                        (f.sys_id, f.comp_id),
                    )));
                }
            }
            Inbound::CommandInt(m) => {
                self.on_command(&command_long_of_int(&m), (f.sys_id, f.comp_id), now_us, ap)
            }
        }
        self.stream_params(ap);
        self.stream_modes();
        self.stream_ftp();
    }
}

#[derive(Clone, Copy)]
pub(crate) struct FrameSender {
    sys_id: u8,
    comp_id: u8,
}
