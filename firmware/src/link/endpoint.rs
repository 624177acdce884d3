//! The link's public face: [`Link`] (framer + dispatcher, what a board's communication task
//! and the PIL application own), the frames decoded elsewhere ([`Received`]) and the link
//! counters ([`LinkStats`], both defined in [`crate::link::received`]). What each message does
//! is [`crate::link::router`]'s table.
//!
//! May import: the other `link` modules, [`crate::app`] (the `Autopilot` boundary), `parapet_core`.

use crate::app::autopilot::Autopilot;
use crate::link::frame_parser::{ParserStats, RawFrame};
use crate::link::inputs::{FixClock, HilSample};
use crate::link::manual_control::ManualControlStats;
use crate::link::obstacles::ObstacleStats;
use crate::link::outbound::Outbound;
pub use crate::link::received::{Framer, LinkStats, Received, ReceivedMessage};
use crate::link::router::{Router, REPLY_QUEUE_LEN, REPLY_RESERVE};

/// `true` when `needle` occurs in `text`: a plain scan of the bytes, the same answer as
/// `str::contains`, whose two-way searcher costs ≈ 700 B of the F405's flash for two
/// look-ups in setup texts of at most 50 bytes.
fn has(text: &str, needle: &str) -> bool {
    let n = needle.as_bytes();
    n.is_empty() || text.as_bytes().windows(n.len()).any(|w| w == n)
}

/// The link state machine (see the module docs).
pub struct Link {
    framer: Framer,
    router: Router,
}

impl Link {
    /// A link for vehicle `own_system`, time-stamping fixes with `fix_clock`.
    pub const fn new(own_system: u8, fix_clock: FixClock) -> Self {
        Self { framer: Framer::new(), router: Router::new(own_system, fix_clock) }
    }

    /// The vehicle's unique id for AUTOPILOT_VERSION `uid` (the board's MCU id,
    /// [`crate::link::outbound::uid_of_mcu`]; the PIL's fixed one).
    pub fn set_uid(&mut self, uid: u64) {
        self.router.uid = uid;
    }

    /// Feeds one received byte at firmware time `now_us`.
    pub fn push_byte<A: Autopilot>(&mut self, byte: u8, now_us: u64, ap: &mut A) {
        let router = &mut self.router;
        self.framer.push(byte, &mut |_| false, &mut |r| router.on_received(r, now_us, ap));
    }

    /// [`Link::push_byte`], with the frame this byte completes (if any) offered to `divert` first:
    /// `true` = taken by the caller, not dispatched (the PIL application's host-only lockstep
    /// input, `crate::pil::battery`). Counted in the framer's statistics like any other frame.
    pub fn push_byte_diverting<A: Autopilot>(
        &mut self,
        byte: u8,
        now_us: u64,
        ap: &mut A,
        divert: &mut impl FnMut(&RawFrame<'_>) -> bool,
    ) {
        let router = &mut self.router;
        self.framer.push(byte, divert, &mut |r| router.on_received(r, now_us, ap));
    }

    /// Handles what a board's receiving task framed elsewhere (its own [`Framer`]: a decoded
    /// frame or a v1 HEARTBEAT) at firmware time `now_us`; same effect as the bytes through
    /// [`Link::push_bytes`].
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
        self.router.stream_modes();
        self.router.stream_ftp();
        self.router.obstacles.poll(now_us, ap);
        self.router.poll_sources(now_us);
        if self.router.run.follow_replan(&mut self.router.mission, ap) {
            self.router.services.on_new_mission();
        }
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
            let ok = t.starts_with("[cal]") && !has(&t, "failed") && !has(&t, "denied");
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

    /// Valid MAVLink v1 HEARTBEATs received (refused, see [`crate::link::v1`]), through
    /// [`Link::push_byte`] or [`Link::receive`].
    pub fn v1_heartbeats(&self) -> u32 {
        self.router.stats.v1_heartbeats
    }

    /// Framer counters (of the bytes through [`Link::push_byte`]).
    pub fn parser_stats(&self) -> ParserStats {
        self.framer.stats()
    }

    /// Framer work so far (byte operations; see [`crate::link::frame_parser::FrameParser::work`]).
    pub fn parser_work(&self) -> u64 {
        self.framer.work()
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
        MavCmd, MavFrame, MavMissionResult, MavParamType, MavResult, COMMAND_LONG_DATA, MISSION_COUNT_DATA,
        MISSION_ITEM_INT_DATA, OBSTACLE_DISTANCE_3D_DATA, ODOMETRY_DATA,
    };
    use crate::link::framing::FrameWriter;
    use crate::link::inputs::odometry_fix;
    use crate::link::messages::DecodeError;
    use mavlink_core::MessageData;
    use parapet_core::Vec3;
    use std::string::{String, ToString};
    use std::vec::Vec;

    fn gcs() -> FrameWriter {
        FrameWriter::new(255, 190)
    }

    #[test]
    fn has_answers_as_str_contains() {
        let texts =
            ["", "f", "failed", "[cal] calibration failed: timeout", "[cal] denied", "fail", "ffailed"];
        for t in texts {
            for n in ["", "f", "failed", "denied", "[cal]", "ffa", "xyz"] {
                assert_eq!(has(t, n), t.contains(n), "{t:?} {n:?}");
            }
        }
    }

    fn send<D: MessageData>(w: &mut FrameWriter, m: &D) -> Vec<u8> {
        w.encode(m).raw_bytes().to_vec()
    }

    fn replies(l: &mut Link) -> Vec<Outbound> {
        core::iter::from_fn(|| l.pop_reply()).collect()
    }

    /// An FTP request payload (pymavlink's `FTP_OP.pack` layout) from the GCS to `target`.
    fn ftp(target: u8, seq: u16, session: u8, opcode: u8, size: u8, offset: u32, data: &[u8]) -> Vec<u8> {
        use crate::link::dialect::FILE_TRANSFER_PROTOCOL_DATA;
        let mut payload = [0u8; 251];
        payload[0..2].copy_from_slice(&seq.to_le_bytes());
        payload[2] = session;
        payload[3] = opcode;
        payload[4] = size;
        payload[8..12].copy_from_slice(&offset.to_le_bytes());
        payload[12..12 + data.len()].copy_from_slice(data);
        let req = FILE_TRANSFER_PROTOCOL_DATA {
            target_network: 0,
            target_system: target,
            target_component: 0,
            payload,
        };
        send(&mut gcs(), &req)
    }

    /// MAVProxy's FTP OpenFileRO of the parameter file, addressed to this vehicle, is answered at
    /// once with a NAK FileNotFound to the sender (so its `param fetch` falls back to the
    /// parameter protocol at once; before any answer it waited ~10 s); one addressed to another
    /// system is not answered.
    #[test]
    fn an_ftp_request_is_answered_to_the_sender() {
        use crate::link::ftp::{err, op};
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Arrival);
        for (target, answered) in [(1, true), (0, true), (2, false)] {
            l.push_bytes(&ftp(target, 7, 0, op::OPEN_FILE_RO, 15, 0, b"@PARAM/param.pc"), 0, &mut ap);
            let r = replies(&mut l);
            if !answered {
                assert!(r.is_empty(), "to system {target}: {r:?}");
                continue;
            }
            let [Outbound::Ftp(a)] = r[..] else { panic!("to system {target}: {r:?}") };
            let m = a.data();
            assert_eq!((m.target_system, m.target_component), (255, 190));
            assert_eq!(&m.payload[..6], &[8, 0, 0, op::NAK, 1, op::OPEN_FILE_RO]);
            assert_eq!(m.payload[12], err::FILE_NOT_FOUND);
        }
    }

    /// A BurstReadFile of parameters.json through the link: the packets go out over successive
    /// polls, never more than the queue's free slots above the reserve, and put together they
    /// are the file; other replies still find room meanwhile.
    #[test]
    fn an_ftp_burst_is_paced_by_the_polls_and_delivers_the_file() {
        use crate::link::ftp::op;
        use crate::link::metadata::FILES;
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Arrival);
        l.push_bytes(&ftp(1, 1, 0, op::OPEN_FILE_RO, 16, 0, b"/parameters.json"), 0, &mut ap);
        let [Outbound::Ftp(open)] = replies(&mut l)[..] else { panic!("open not answered") };
        l.push_bytes(&ftp(1, 2, open.session, op::BURST_READ_FILE, 239, 0, &[]), 0, &mut ap);
        let mut file = Vec::new();
        let mut packets = 0;
        for poll in 0..10_000u64 {
            l.poll(poll * 1000, &mut ap);
            let mut ftp_here = 0;
            let mut done = false;
            for r in replies(&mut l) {
                if let Outbound::Ftp(a) = r {
                    let m = a.data();
                    let size = usize::from(m.payload[4]);
                    file.extend_from_slice(&m.payload[12..12 + size]);
                    assert_eq!(
                        u16::from_le_bytes([m.payload[0], m.payload[1]]),
                        3 + packets,
                        "seq counts up"
                    );
                    packets += 1;
                    ftp_here += 1;
                    done = m.payload[6] == 1;
                }
            }
            assert!(ftp_here <= REPLY_QUEUE_LEN - REPLY_RESERVE, "poll {poll}: {ftp_here} packets");
            if done {
                break;
            }
        }
        assert_eq!(file, FILES[1].bytes, "{packets} packets");
        assert_eq!(usize::from(packets), FILES[1].bytes.len().div_ceil(239));
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

    /// What a board's receiving task makes of `bytes` with its own [`Framer`] (frames `divert`
    /// takes stay out), for the task that owns the link.
    fn framed_elsewhere(bytes: &[u8], mut divert: impl FnMut(u32) -> bool) -> Vec<Received> {
        let mut framer = Framer::new();
        let mut got = Vec::new();
        for &b in bytes {
            framer.push(b, &mut |f| divert(f.msg_id), &mut |r| got.push(r));
        }
        got
    }

    /// Framing in one task and dispatch in another (the board: a [`Framer`] in the link task,
    /// [`Link::receive`] in the outer task) does what the bytes through the link do; frames the
    /// board diverts (the F405's LOG_* requests) do not reach the link.
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
        assert!(framed_elsewhere(&bytes, |id| id == COMMAND_LONG_DATA::ID).is_empty(), "diverted");
        let got = framed_elsewhere(&bytes, |_| false);
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

    /// A MAVLink v1 HEARTBEAT framed by a board's receiving task reaches the link as
    /// [`Received::V1Heartbeat`] and gets the v1-framed STATUSTEXT refusal, as through
    /// [`Link::push_byte`]. Before: the boards framed v2 only ([`Received::of`] on the
    /// FrameParser's frames), so on the real boards a v1 ground station got no answer.
    #[test]
    fn a_v1_heartbeat_framed_in_another_task_gets_the_v1_refusal() {
        use crate::link::dialect::HEARTBEAT_DATA;
        use mavlink_core::{MAVLinkV1MessageRaw, MavHeader};
        let mut raw = MAVLinkV1MessageRaw::new();
        raw.serialize_message_data(
            MavHeader { system_id: 255, component_id: 190, sequence: 3 },
            &HEARTBEAT_DATA::default(),
        );
        let v1 = raw.raw_bytes().to_vec();
        let mut ap = RecordingAutopilot::new();
        let mut board = Link::new(1, FixClock::Arrival);
        for r in framed_elsewhere(&v1, |_| false) {
            board.receive(r, 7, &mut ap);
        }
        let answer = replies(&mut board);
        assert!(
            matches!(&answer[..], [Outbound::StatusTextV1(t)]
                if t.text.to_str().ok() == Some(crate::link::v1::V1_REFUSED_TEXT)),
            "{answer:?}"
        );
        assert_eq!(board.v1_heartbeats(), 1);
        assert!(!board.peer_seen(), "a v1 frame is not a MAVLink 2 peer");
        let mut bytes = Link::new(1, FixClock::Arrival);
        bytes.push_bytes(&v1, 7, &mut ap);
        assert_eq!(replies(&mut bytes), answer, "the same answer as through push_bytes");
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
        assert_eq!(ap.fixes[0].velocity, Vec3::new(0.5, 0.0, 0.0));
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

    fn texts(l: &mut Link) -> Vec<String> {
        let text = |t: &crate::link::dialect::STATUSTEXT_DATA| {
            String::from_utf8_lossy(&t.text[..]).trim_end_matches('\0').to_string()
        };
        replies(l)
            .iter()
            .filter_map(|r| if let Outbound::StatusText(t) = r { Some(text(t)) } else { None })
            .collect()
    }

    /// GPS_INPUT and VISION_POSITION_ESTIMATE reach the autopilot as local NED fixes; bad ones
    /// are refused and counted; the ground station hears the source, a switch and a loss.
    #[test]
    fn gps_input_and_vision_feed_the_fix_path_and_the_source_is_reported() {
        use crate::link::dialect::{
            GpsFixType, GpsInputIgnoreFlags, GPS_INPUT_DATA, VISION_POSITION_ESTIMATE_DATA,
        };
        use parapet_core::wire::geo::ORIGIN;
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Message);
        let mut w = gcs();
        let gps = |t: u64, alt: f32| GPS_INPUT_DATA {
            time_usec: t,
            fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
            lat: ORIGIN.0,
            lon: ORIGIN.1,
            alt,
            vn: 1.0,
            ignore_flags: GpsInputIgnoreFlags::empty(),
            ..Default::default()
        };
        let home = ORIGIN.2 as f32 / 1000.0;
        l.push_bytes(&send(&mut w, &gps(100_000, home + 2.0)), 150_000, &mut ap);
        assert_eq!(ap.fixes.len(), 1);
        assert_eq!((ap.fixes[0].t_us, ap.fixes[0].velocity), (100_000, Vec3::new(1.0, 0.0, 0.0)));
        assert!((ap.fixes[0].position.z + 2.0).abs() < 1e-3, "{:?}", ap.fixes[0].position);
        assert!(texts(&mut l).is_empty(), "the first source is not announced");
        // NaN altitude, a 2-s-old fix: refused, counted, not forwarded.
        l.push_bytes(&send(&mut w, &gps(200_000, f32::NAN)), 250_000, &mut ap);
        l.push_bytes(&send(&mut w, &gps(300_000, home)), 2_400_000, &mut ap);
        assert_eq!((ap.fixes.len(), l.stats().position_rejected), (1, 2));
        // No fix for more than a second: lost, once.
        l.poll(2_400_000, &mut ap);
        l.poll(2_500_000, &mut ap);
        assert_eq!(texts(&mut l).iter().filter(|t| t.as_str() == "Position source lost").count(), 1);
        // Vision: the second estimate goes on, with the differenced velocity; a switch.
        let vis =
            |t: u64, x: f32| VISION_POSITION_ESTIMATE_DATA { usec: t, x, yaw: 0.5, ..Default::default() };
        l.push_bytes(&send(&mut w, &vis(3_000_000, 1.0)), 3_000_000, &mut ap);
        l.push_bytes(&send(&mut w, &vis(3_100_000, 1.2)), 3_100_000, &mut ap);
        assert_eq!(ap.fixes.len(), 2);
        let f = ap.fixes[1];
        assert!((f.velocity.x - 2.0).abs() < 1e-3 && f.yaw == Some(0.5), "{f:?}");
        assert_eq!(texts(&mut l), vec!["Position source: VISION_POSITION_ESTIMATE".to_string()]);
    }

    /// HIL_SENSOR's `pressure_alt` goes to the navigation filter as a height (NED down around
    /// home) only when `fields_updated` says so; NaN and beyond `MAX_RANGE_M` are not heights.
    /// The IMU sample is taken either way.
    #[test]
    fn hil_sensor_pressure_alt_is_a_barometer_height_when_flagged() {
        use crate::link::dialect::{HilSensorUpdatedFlags, HIL_SENSOR_DATA};
        use parapet_core::wire::geo::ORIGIN;
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Message);
        let mut w = gcs();
        let home = ORIGIN.2 as f32 / 1000.0;
        let hil = |t: u64, alt: f32, flagged: bool| HIL_SENSOR_DATA {
            time_usec: t,
            zacc: -9.81,
            pressure_alt: alt,
            fields_updated: if flagged {
                HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_PRESSURE_ALT
            } else {
                HilSensorUpdatedFlags::empty()
            },
            ..Default::default()
        };
        for (t, alt, flagged) in [
            (1_000, home + 1.5, true),
            (2_000, home + 9.0, false),
            (3_000, f32::NAN, true),
            (4_000, home + 20_000.0, true),
            (5_000, home - 0.25, true),
        ] {
            l.push_bytes(&send(&mut w, &hil(t, alt, flagged)), t, &mut ap);
            assert!(l.take_hil_sample().is_some_and(|s| s.time_usec == t));
        }
        assert_eq!(ap.heights, vec![(1_000, -1.5), (5_000, 0.25)]);
        assert_eq!(l.stats().baro_heights, 2);
    }

    /// A HIL_SENSOR magnetometer field becomes a heading (tilt-compensated with the autopilot's
    /// attitude) that the next GPS_INPUT without a yaw carries; a GPS_INPUT's own yaw wins.
    #[test]
    fn the_magnetometer_heading_rides_with_a_gps_input_without_a_yaw() {
        use crate::link::dialect::{
            GpsFixType, GpsInputIgnoreFlags, HilSensorUpdatedFlags, GPS_INPUT_DATA, HIL_SENSOR_DATA,
        };
        use parapet_core::nav::mag::body_field;
        use parapet_core::wire::geo::ORIGIN;
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Message);
        let mut w = gcs();
        let a = ap.telemetry().attitude_rpy;
        let b = body_field(a.x, a.y, 0.7);
        let mag = HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_XMAG
            | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_YMAG
            | HilSensorUpdatedFlags::HIL_SENSOR_UPDATED_ZMAG;
        let hil = HIL_SENSOR_DATA {
            time_usec: 1_000,
            xmag: b.x,
            ymag: b.y,
            zmag: b.z,
            fields_updated: mag,
            ..Default::default()
        };
        let gps = |t: u64, yaw: u16| GPS_INPUT_DATA {
            time_usec: t,
            fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
            lat: ORIGIN.0,
            lon: ORIGIN.1,
            alt: ORIGIN.2 as f32 / 1000.0,
            yaw,
            ignore_flags: GpsInputIgnoreFlags::empty(),
            ..Default::default()
        };
        // Before any field: no heading.
        l.push_bytes(&send(&mut w, &gps(500, 0)), 500, &mut ap);
        assert_eq!(ap.fixes[0].yaw, None);
        l.push_bytes(&send(&mut w, &hil), 1_000, &mut ap);
        assert_eq!(l.stats().mag_headings, 1);
        l.push_bytes(&send(&mut w, &gps(2_000, 0)), 2_000, &mut ap);
        let yaw = ap.fixes[1].yaw.expect("the magnetometer's heading");
        assert!((yaw - 0.7).abs() < 1e-4, "{yaw}");
        // A GPS heading (dual antenna: 90°) is kept.
        l.push_bytes(&send(&mut w, &gps(3_000, 9_000)), 3_000, &mut ap);
        let yaw = ap.fixes[2].yaw.expect("the GPS heading");
        assert!((yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-4, "{yaw}");
        // The compass stopped: 1 s after its last field a fix goes without a heading.
        l.push_bytes(&send(&mut w, &gps(1_001_000, 0)), 1_001_000, &mut ap);
        assert!(ap.fixes[3].yaw.is_some());
        l.push_bytes(&send(&mut w, &gps(1_001_001, 0)), 1_001_001, &mut ap);
        assert_eq!(ap.fixes[4].yaw, None);
    }

    /// ODOMETRY from a VIO or vision estimator goes to the navigation filter as a relative
    /// source with the σ of its covariances; a motion capture's (and an unknown estimator's,
    /// what the PIL host sends) keeps the latest-fix path.
    #[test]
    fn vio_odometry_goes_to_the_filter_as_a_relative_source_mocap_to_the_fix_path() {
        use crate::app::autopilot::{FixKind, SourceNoise};
        use crate::link::dialect::MavEstimatorType;
        let mut ap = RecordingAutopilot::new();
        let mut l = Link::new(1, FixClock::Message);
        let mut w = gcs();
        let odo = |t: u64, estimator_type: MavEstimatorType, var: f32| {
            let mut pose_covariance = [0.0f32; 21];
            pose_covariance[0] = var;
            ODOMETRY_DATA {
                time_usec: t,
                x: 1.0,
                vx: 0.5,
                q: [1.0, 0.0, 0.0, 0.0],
                pose_covariance,
                velocity_covariance: [f32::NAN; 21],
                frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                estimator_type,
                ..Default::default()
            }
        };
        for (k, e) in [MavEstimatorType::MAV_ESTIMATOR_TYPE_VIO, MavEstimatorType::MAV_ESTIMATOR_TYPE_VISION]
            .into_iter()
            .enumerate()
        {
            let t = 100_000 * (k as u64 + 1);
            l.push_bytes(&send(&mut w, &odo(t, e, 0.04)), t, &mut ap);
        }
        let vio = SourceNoise { position: 0.2, velocity: 0.3 };
        assert_eq!(ap.nav_fixes, vec![(FixKind::Relative, vio); 2]);
        assert_eq!((ap.fixes.len(), ap.fixes[0].position.x, ap.fixes[0].velocity.x), (2, 1.0, 0.5));
        // Motion capture and unknown: the fix path, not the filter.
        for e in [MavEstimatorType::MAV_ESTIMATOR_TYPE_MOCAP, MavEstimatorType::MAV_ESTIMATOR_TYPE_UNKNOWN] {
            l.push_bytes(&send(&mut w, &odo(300_000, e, 0.04)), 300_000, &mut ap);
        }
        assert_eq!((ap.fixes.len(), ap.nav_fixes.len()), (4, 2));
        // A VIO's non-finite ODOMETRY: refused and counted as a position source's.
        let mut bad = odo(400_000, MavEstimatorType::MAV_ESTIMATOR_TYPE_VIO, 0.04);
        bad.x = f32::NAN;
        l.push_bytes(&send(&mut w, &bad), 400_000, &mut ap);
        assert_eq!((ap.fixes.len(), l.stats().position_rejected), (4, 1));
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
        let f = odometry_fix(&odo, 0).map(|f| f.velocity);
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
        // Refused as not now (the test double refuses every parameter armed): the reason as a
        // STATUSTEXT naming it, and the value still in effect.
        ap.armed = true;
        l.push_bytes(&send(&mut w, &set("CBF_MU", 0.5)), 0, &mut ap);
        match &replies(&mut l)[..] {
            [Outbound::StatusText(t), Outbound::ParamValue(v)] => {
                assert_eq!(t.text.to_str().ok(), Some("Set-up, disarm to change: CBF_MU"));
                assert_eq!(v.param_value, 0.9);
            }
            other => panic!("{other:?}"),
        }
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
