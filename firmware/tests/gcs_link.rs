//! The MAVLink microservices a ground station needs (QGroundControl, MAVProxy, MAVSDK), end to
//! end on the host: frames through the firmware's `Link` into the real `Cascade`, driven by the
//! lockstep scheduler the PIL firmware runs. Each test is one defect of issue 20 that failed
//! before: PARAM_REQUEST_LIST unanswered, no mission download, MISSION_CLEAR_ALL / MISSION_COUNT 0
//! not clearing (a later mission start flew the "cleared" path), `mission_type` ignored,
//! COMMAND_INT unanswered, COMMAND_ACK not addressed, messages for another component applied,
//! heartbeat mode flags, no SYS_STATUS / EXTENDED_SYS_STATE / AUTOPILOT_VERSION / TIMESYNC.

use mavlink_core::MessageData;
use parapet_core::controller::ControllerParams;
use parapet_core::params::{COUNT, TABLE};
use parapet_firmware::app::autopilot::{Autopilot, FlightMode, FlightPhase};
use parapet_firmware::app::cascade::Cascade;
use parapet_firmware::link::command::command_long;
use parapet_firmware::link::dialect::{
    MavCmd, MavFrame, MavLandedState, MavMissionResult, MavMissionType, MavModeFlag, MavParamType,
    MavProtocolCapability, MavResult, COMMAND_INT_DATA, COMMAND_LONG_DATA, HEARTBEAT_DATA, HIL_SENSOR_DATA,
    MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
    MISSION_REQUEST_LIST_DATA, OBSTACLE_DISTANCE_3D_DATA, ODOMETRY_DATA, PARAM_REQUEST_LIST_DATA,
    PARAM_SET_DATA, TIMESYNC_DATA,
};
use parapet_firmware::link::framing::FrameWriter;
use parapet_firmware::link::obstacles::CLEAR_ID;
use parapet_firmware::link::outbound::{autopilot_version, name, Outbound};
use parapet_firmware::link::telemetry::TelemetryScheduler;
use parapet_firmware::link::{FixClock, Link, REPLY_QUEUE_LEN};
use parapet_firmware::pil::lockstep::LockstepScheduler;

const GCS: (u8, u8) = (255, 190);

/// A ground station on the lockstep link of the real cascade at rest on the ground at the origin.
struct Sim {
    link: Link,
    ap: Cascade,
    sched: LockstepScheduler,
    w: FrameWriter,
    k: u64,
}

impl Sim {
    fn new() -> Self {
        let ap = Cascade::new(ControllerParams::default()).expect("default parameters");
        Sim {
            link: Link::new(1, FixClock::Message),
            ap,
            sched: LockstepScheduler::default(),
            w: FrameWriter::new(GCS.0, GCS.1),
            k: 0,
        }
    }

    fn t(&self) -> u64 {
        1_000_000 + self.k * 1000
    }

    fn frame<D: MessageData>(&mut self, m: &D) -> Vec<u8> {
        self.w.encode(m).raw_bytes().to_vec()
    }

    /// One 1 ms lockstep step (a fix and an empty obstacle batch every 4 ms) with `msgs` sent
    /// before its HIL_SENSOR; the replies of the step.
    fn step(&mut self, msgs: &[Vec<u8>]) -> Vec<Outbound> {
        let t = self.t();
        if self.k.is_multiple_of(4) {
            let odo = ODOMETRY_DATA {
                time_usec: t,
                q: [1.0, 0.0, 0.0, 0.0],
                frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                ..Default::default()
            };
            let clear = OBSTACLE_DISTANCE_3D_DATA {
                time_boot_ms: (t / 1000) as u32,
                obstacle_id: CLEAR_ID,
                frame: MavFrame::MAV_FRAME_LOCAL_NED,
                // "No obstacle now": id 65535 and an empty range (min > max).
                min_distance: 1.0,
                max_distance: 0.0,
                ..Default::default()
            };
            let (a, b) = (self.frame(&odo), self.frame(&clear));
            self.link.push_bytes(&a, t, &mut self.ap);
            self.link.push_bytes(&b, t, &mut self.ap);
        }
        for m in msgs {
            self.link.push_bytes(m, t, &mut self.ap);
        }
        let hil = HIL_SENSOR_DATA { time_usec: t, zacc: -9.81, ..Default::default() };
        let h = self.frame(&hil);
        self.link.push_bytes(&h, t, &mut self.ap);
        let Some(sample) = self.link.take_hil_sample() else { panic!("HIL_SENSOR not decoded at {t}") };
        self.sched.step(&sample, &mut self.link, &mut self.ap);
        self.k += 1;
        core::iter::from_fn(|| self.link.pop_reply()).collect()
    }

    /// Sends `m` in one step; the replies.
    fn send<D: MessageData>(&mut self, m: &D) -> Vec<Outbound> {
        let f = self.frame(m);
        self.step(&[f])
    }

    fn run(&mut self, steps: u64) {
        for _ in 0..steps {
            self.step(&[]);
        }
    }

    /// Uploads `path` (NED, m) with the mission protocol; the final MISSION_ACK result.
    fn upload(&mut self, path: &[[f32; 3]]) -> MavMissionResult {
        let count = MISSION_COUNT_DATA {
            count: path.len() as u16,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        };
        let mut r = self.send(&count);
        loop {
            match r.as_slice() {
                [Outbound::MissionRequestInt(q)] => {
                    let p = path[usize::from(q.seq)];
                    let item = MISSION_ITEM_INT_DATA {
                        x: (p[0] * 1e4) as i32,
                        y: (p[1] * 1e4) as i32,
                        z: p[2],
                        seq: q.seq,
                        command: MavCmd::MAV_CMD_NAV_WAYPOINT as u16,
                        frame: MavFrame::MAV_FRAME_LOCAL_NED,
                        target_system: 1,
                        target_component: 1,
                        ..Default::default()
                    };
                    r = self.send(&item);
                }
                [Outbound::MissionAck(a)] => return a.mavtype,
                other => panic!("upload: {other:?}"),
            }
        }
    }

    /// Downloads the mission: MISSION_REQUEST_LIST, then every item; x, y, z per item.
    fn download(&mut self) -> Vec<[f32; 3]> {
        let list = MISSION_REQUEST_LIST_DATA { target_system: 1, target_component: 1, ..Default::default() };
        let n = match self.send(&list).as_slice() {
            [Outbound::MissionCount(c)] => {
                assert_eq!((c.target_system, c.target_component), GCS);
                assert_eq!(c.mission_type, MavMissionType::MAV_MISSION_TYPE_MISSION);
                c.count
            }
            other => panic!("MISSION_REQUEST_LIST: {other:?}"),
        };
        (0..n)
            .map(|seq| {
                let q = MISSION_REQUEST_INT_DATA {
                    seq,
                    target_system: 1,
                    target_component: 1,
                    ..Default::default()
                };
                match self.send(&q).as_slice() {
                    [Outbound::MissionItemInt(i)] => {
                        assert_eq!(
                            (i.seq, i.command, i.frame),
                            (seq, MavCmd::MAV_CMD_NAV_WAYPOINT as u16, MavFrame::MAV_FRAME_LOCAL_NED)
                        );
                        assert_eq!((i.target_system, i.target_component), GCS);
                        [i.x as f32 / 1e4, i.y as f32 / 1e4, i.z]
                    }
                    other => panic!("MISSION_REQUEST_INT {seq}: {other:?}"),
                }
            })
            .collect()
    }

    fn command(&mut self, command: MavCmd, p: [f32; 7], target_component: u8) -> Vec<Outbound> {
        let c = command_long(command as u16, p, (1, target_component));
        self.send(&c)
    }

    /// The one COMMAND_ACK of `r`: result and its target.
    fn ack(r: &[Outbound]) -> (MavResult, (u8, u8)) {
        match r {
            [Outbound::CommandAck(a), ..] => (a.result, (a.target_system, a.target_component)),
            other => panic!("no COMMAND_ACK: {other:?}"),
        }
    }

    /// Arms after 0.5 s of samples and holds 1 m above the origin.
    fn airborne(&mut self) {
        self.run(500);
        let r = self.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
        assert_eq!(
            Self::ack(&r).0,
            MavResult::MAV_RESULT_ACCEPTED,
            "{:?} {:?}",
            self.ap.telemetry(),
            self.link.obstacle_stats()
        );
        let r = self.command(MavCmd::MAV_CMD_OVERRIDE_GOTO, [0.0, 3.0, 1.0, 0.0, 0.0, 0.0, -1.0], 1);
        assert_eq!(Self::ack(&r).0, MavResult::MAV_RESULT_ACCEPTED);
        self.run(20);
    }
}

#[test]
fn param_request_list_streams_every_parameter_once_broadcast_and_addressed() {
    for (sys, comp) in [(0u8, 0u8), (1, 1)] {
        let mut g = Sim::new();
        let req = PARAM_REQUEST_LIST_DATA { target_system: sys, target_component: comp };
        let mut got = g.send(&req);
        for _ in 0..50 {
            // Paced: never more than the reply queue in one step.
            let r = g.step(&[]);
            assert!(r.len() <= REPLY_QUEUE_LEN);
            got.extend(r);
        }
        let values: Vec<_> = got
            .into_iter()
            .filter_map(|o| match o {
                Outbound::ParamValue(v) => Some(v),
                _ => None,
            })
            .collect();
        assert_eq!(values.len(), COUNT, "one PARAM_VALUE per parameter ({sys}, {comp})");
        for (i, (v, p)) in values.iter().zip(TABLE.iter()).enumerate() {
            assert_eq!(usize::from(v.param_index), i);
            assert_eq!(usize::from(v.param_count), COUNT);
            assert_eq!(v.param_id.to_str().unwrap_or(""), p.name);
            assert_eq!(v.param_value, p.default_value(), "{}", p.name);
            assert_eq!(v.param_type, MavParamType::MAV_PARAM_TYPE_REAL32);
        }
    }
}

#[test]
fn a_command_reply_gets_through_while_the_parameter_list_streams() {
    let mut g = Sim::new();
    let req = PARAM_REQUEST_LIST_DATA { target_system: 1, target_component: 1 };
    let f1 = g.frame(&req);
    let land = COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_NAV_LAND as u16,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let f2 = g.frame(&land);
    let r = g.step(&[f1, f2]);
    assert!(r.iter().any(|o| matches!(o, Outbound::CommandAck(_))), "{r:?}");
    assert_eq!(g.link.stats().replies_dropped, 0);
}

#[test]
fn messages_for_another_component_or_system_are_ignored() {
    let mut g = Sim::new();
    // A camera's parameter (component 154): not applied, not answered.
    let set = PARAM_SET_DATA {
        param_value: 0.9,
        target_system: 1,
        target_component: 154,
        param_id: name("CBF_MU"),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    };
    assert!(g.send(&set).is_empty());
    assert_eq!(
        g.ap.get_param("CBF_MU"),
        Some(TABLE.iter().find(|p| p.name == "CBF_MU").map_or(0.0, |p| p.default_value()))
    );
    g.run(500);
    // An ARM for component 154 or system 2: no action, no answer.
    assert!(g
        .command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 154)
        .is_empty());
    let other_sys = COMMAND_LONG_DATA {
        param1: 1.0,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
        target_system: 2,
        target_component: 1,
        ..Default::default()
    };
    assert!(g.send(&other_sys).is_empty());
    assert!(!g.ap.telemetry().armed);
    let list = PARAM_REQUEST_LIST_DATA { target_system: 1, target_component: 154 };
    g.send(&list);
    assert!(g.step(&[]).is_empty());
    assert!(g.link.stats().not_for_us >= 4);
    // Addressed to us (component 1 or broadcast 0): applied.
    let r = g.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0);
    assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_ACCEPTED, GCS));
    assert!(g.ap.telemetry().armed);
}

#[test]
fn command_int_is_answered_like_command_long_and_acks_are_addressed_to_the_sender() {
    let mut g = Sim::new();
    g.run(500);
    let arm = COMMAND_INT_DATA {
        param1: 1.0,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let r = g.send(&arm);
    assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_ACCEPTED, GCS));
    assert!(g.ap.telemetry().armed);
    // Hold a local NED point given in COMMAND_INT's x/y (m × 10⁴) and z.
    let hold = COMMAND_INT_DATA {
        param1: 0.0,
        param2: 3.0,
        param3: 1.0,
        x: 5_000,
        y: -2_500,
        z: -1.0,
        command: MavCmd::MAV_CMD_OVERRIDE_GOTO as u16,
        frame: MavFrame::MAV_FRAME_LOCAL_NED,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let r = g.send(&hold);
    assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_ACCEPTED, GCS));
    g.run(8);
    let sp = g.ap.telemetry().setpoint.position_ned;
    assert!((sp.x - 0.5).abs() < 1e-3 && (sp.y + 0.25).abs() < 1e-3, "{sp:?}");
    // Unsupported: still answered, addressed.
    let r = g.command(MavCmd::MAV_CMD_DO_SET_SERVO, [0.0; 7], 1);
    assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_UNSUPPORTED, GCS));
}

/// A command id outside MAV_CMD (a newer or vendor command) decodes and is answered
/// UNSUPPORTED with its own id; before, the enum-typed `command` field failed to decode and the
/// sender got no COMMAND_ACK at all.
#[test]
fn an_unknown_command_id_is_answered_unsupported_with_its_id() {
    let mut g = Sim::new();
    let unknown =
        COMMAND_LONG_DATA { command: 60_123, target_system: 1, target_component: 1, ..Default::default() };
    let r = g.send(&unknown);
    assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_UNSUPPORTED, GCS));
    assert!(matches!(r.as_slice(), [Outbound::CommandAck(a), ..] if a.command == 60_123), "{r:?}");
}

#[test]
fn mission_download_returns_the_accepted_path() {
    let mut g = Sim::new();
    let path = [[1.0, 0.5, -1.0], [2.0, -1.25, -1.5]];
    assert_eq!(g.upload(&path), MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(g.download(), path.to_vec());
    // Out of range: refused with INVALID_SEQUENCE.
    let q = MISSION_REQUEST_INT_DATA { seq: 2, target_system: 1, target_component: 1, ..Default::default() };
    assert!(matches!(g.send(&q).as_slice(),
        [Outbound::MissionAck(a)] if a.mavtype == MavMissionResult::MAV_MISSION_INVALID_SEQUENCE));
}

#[test]
fn mission_clear_all_really_clears_and_a_later_start_is_refused() {
    let mut g = Sim::new();
    g.airborne();
    assert_eq!(g.upload(&[[1.0, 0.0, -1.0]]), MavMissionResult::MAV_MISSION_ACCEPTED);
    let clear = MISSION_CLEAR_ALL_DATA { target_system: 1, target_component: 1, ..Default::default() };
    match g.send(&clear).as_slice() {
        [Outbound::MissionAck(a)] => {
            assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_ACCEPTED);
            assert_eq!((a.target_system, a.target_component), GCS);
        }
        other => panic!("{other:?}"),
    }
    assert!(g.download().is_empty());
    let r = g.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7], 1);
    assert_ne!(Sim::ack(&r).0, MavResult::MAV_RESULT_ACCEPTED, "the cleared mission must not fly");
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Hover);
}

#[test]
fn clearing_while_flying_the_mission_holds_and_count_zero_clears() {
    let mut g = Sim::new();
    g.airborne();
    assert_eq!(g.upload(&[[3.0, 0.0, -1.0]]), MavMissionResult::MAV_MISSION_ACCEPTED);
    let r = g.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7], 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_ACCEPTED);
    g.run(100);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Mission);
    // MISSION_COUNT 0 = clear (accepted): the vehicle holds where its reference is.
    let zero = MISSION_COUNT_DATA { count: 0, target_system: 1, target_component: 1, ..Default::default() };
    assert!(matches!(g.send(&zero).as_slice(),
        [Outbound::MissionAck(a)] if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED));
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Hover);
    assert!(g.download().is_empty());
    let r = g.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7], 1);
    assert_ne!(Sim::ack(&r).0, MavResult::MAV_RESULT_ACCEPTED);
}

#[test]
fn fence_and_rally_are_refused_without_touching_the_mission() {
    let mut g = Sim::new();
    let path = [[1.0, 0.0, -1.0]];
    assert_eq!(g.upload(&path), MavMissionResult::MAV_MISSION_ACCEPTED);
    for t in [MavMissionType::MAV_MISSION_TYPE_FENCE, MavMissionType::MAV_MISSION_TYPE_RALLY] {
        let count = MISSION_COUNT_DATA {
            count: 3,
            target_system: 1,
            target_component: 1,
            mission_type: t,
            opaque_id: 0,
        };
        let clear = MISSION_CLEAR_ALL_DATA { target_system: 1, target_component: 1, mission_type: t };
        let list = MISSION_REQUEST_LIST_DATA { target_system: 1, target_component: 1, mission_type: t };
        for r in [g.send(&count), g.send(&clear), g.send(&list)] {
            match r.as_slice() {
                [Outbound::MissionAck(a)] => {
                    assert_eq!((a.mavtype, a.mission_type), (MavMissionResult::MAV_MISSION_UNSUPPORTED, t));
                }
                other => panic!("{t:?}: {other:?}"),
            }
        }
    }
    assert_eq!(g.download(), path.to_vec());
}

/// HEARTBEAT: custom_mode = the PX4 custom mode of the flight mode (Mission, the default, from
/// boot through the hold and the mission), AUTO | GUIDED | STABILIZE as PX4 sets them for its auto
/// modes, SAFETY_ARMED only when armed; the phase goes beside it (NAMED_VALUE_INT PHASE).
#[test]
fn heartbeat_flags_follow_arming_and_mode() {
    let auto = MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED
        | MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED
        | MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED
        | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
    let mut g = Sim::new();
    let hb = |g: &Sim| parapet_firmware::link::telemetry::heartbeat(&g.ap.telemetry());
    let h: HEARTBEAT_DATA = hb(&g);
    assert_eq!(h.base_mode, auto, "disarmed in Mission");
    assert_eq!(h.custom_mode, FlightMode::Mission.px4_custom_mode());
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Disarmed);
    g.airborne();
    let h = hb(&g);
    assert_eq!(h.base_mode, auto | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
    assert_eq!(h.custom_mode, FlightMode::Mission.px4_custom_mode());
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Hover);
    assert_eq!(g.upload(&[[3.0, 0.0, -1.0]]), MavMissionResult::MAV_MISSION_ACCEPTED);
    g.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7], 1);
    g.run(8);
    let h = hb(&g);
    assert_eq!(h.base_mode, auto | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
    assert_eq!(h.custom_mode, FlightMode::Mission.px4_custom_mode());
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Mission);
}

#[test]
fn do_set_mode_switches_between_the_phases() {
    let mut g = Sim::new();
    g.airborne();
    assert_eq!(g.upload(&[[3.0, 0.0, -1.0]]), MavMissionResult::MAV_MISSION_ACCEPTED);
    // PX4's main/sub modes (what MAVProxy's `mode MISSION` / `mode LOITER` send).
    let mode = |m: FlightMode| {
        let (main, sub) = m.px4_main_sub();
        [1.0, f32::from(main), f32::from(sub), 0.0, 0.0, 0.0, 0.0]
    };
    let r = g.command(MavCmd::MAV_CMD_DO_SET_MODE, mode(FlightMode::Mission), 1);
    assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_ACCEPTED, GCS));
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Mission);
    let r = g.command(MavCmd::MAV_CMD_DO_SET_MODE, mode(FlightMode::Hold), 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_ACCEPTED);
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Hover);
    // Without the custom-mode flag, or a mode that cannot be commanded: denied, no change.
    let r = g.command(MavCmd::MAV_CMD_DO_SET_MODE, [0.0, 4.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_DENIED);
    let r = g.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 9.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_DENIED);
    // PX4's OFFBOARD main mode: refused without a fresh setpoint stream (issue 21).
    let r = g.command(MavCmd::MAV_CMD_DO_SET_MODE, mode(FlightMode::Offboard), 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_TEMPORARILY_REJECTED);
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Hover);
}

#[test]
fn sys_status_and_extended_sys_state_come_with_the_heartbeat() {
    let mut g = Sim::new();
    let mut tel = TelemetryScheduler::new();
    let mut out = Vec::new();
    let inputs = |g: &Sim| parapet_firmware::link::telemetry::TelemetryInputs {
        snapshot: g.ap.telemetry(),
        inner: parapet_firmware::app::loop_timing::LoopReport::ZERO,
        outer: parapet_firmware::app::loop_timing::LoopReport::ZERO,
        parser: g.link.parser_stats(),
        counters: Default::default(),
    };
    tel.poll(g.t(), &inputs(&g), |m| out.push(m));
    let ss = out.iter().find_map(|m| match m {
        Outbound::SysStatus(s) => Some(s.clone()),
        _ => None,
    });
    let Some(ss) = ss else { panic!("no SYS_STATUS: {out:?}") };
    assert_eq!((ss.voltage_battery, ss.current_battery, ss.battery_remaining), (u16::MAX, -1, -1));
    assert!(!ss.onboard_control_sensors_present.is_empty());
    // No fix yet: the fix (vision position, GPS) and the pre-arm check are unhealthy, the rest is.
    use parapet_firmware::link::dialect::MavSysStatusSensor as S;
    let fix = S::MAV_SYS_STATUS_SENSOR_VISION_POSITION | S::MAV_SYS_STATUS_SENSOR_GPS;
    assert_eq!(
        ss.onboard_control_sensors_health,
        ss.onboard_control_sensors_present - fix - S::MAV_SYS_STATUS_PREARM_CHECK
    );
    g.run(500);
    let (mut out2, t) = (Vec::new(), g.t() + 1_000_000);
    tel.poll(t, &inputs(&g), |m| out2.push(m));
    let ss = out2.iter().find_map(|m| match m {
        Outbound::SysStatus(s) => Some(s.clone()),
        _ => None,
    });
    let ss = ss.expect("SYS_STATUS");
    assert_eq!(
        ss.onboard_control_sensors_health, ss.onboard_control_sensors_present,
        "fixes and obstacles: all healthy, armable"
    );
    let landed = |out: &[Outbound]| {
        out.iter().find_map(|m| match m {
            Outbound::ExtendedSysState(e) => Some(e.landed_state),
            _ => None,
        })
    };
    assert_eq!(landed(&out), Some(MavLandedState::MAV_LANDED_STATE_ON_GROUND));
    g.airborne();
    out.clear();
    tel.poll(g.t() + 2_000_000, &inputs(&g), |m| out.push(m));
    assert_eq!(landed(&out), Some(MavLandedState::MAV_LANDED_STATE_IN_AIR));
}

#[test]
fn autopilot_version_timesync_on_request() {
    let mut g = Sim::new();
    g.link.set_uid(0xABCD_0123);
    #[allow(deprecated)] // still sent by ground stations
    let old = MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES;
    for (cmd, p1) in [(MavCmd::MAV_CMD_REQUEST_MESSAGE, 148.0), (old, 1.0)] {
        let r = g.command(cmd, [p1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
        assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_ACCEPTED, GCS));
        match r.as_slice() {
            [_, Outbound::AutopilotVersion(uid)] => {
                assert_eq!(*uid, 0xABCD_0123, "the uid the board set");
                let v = autopilot_version(*uid);
                assert_eq!(v.uid, 0xABCD_0123);
                let need = MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2
                    | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT
                    | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
                    | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                    | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                    | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
                    | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_FTP;
                assert!(v.capabilities.contains(need), "{:?}", v.capabilities);
                assert!(!v.capabilities.intersects(
                    MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                        | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
                        | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
                ));
            }
            other => panic!("{other:?}"),
        }
    }
    // COMPONENT_METADATA (397): ACCEPTED, then the general metadata's mftp URI and CRC (issue 41:
    // was DENIED; the files are served by MAVLink FTP, link::ftp).
    let r = g.command(MavCmd::MAV_CMD_REQUEST_MESSAGE, [397.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_ACCEPTED, GCS));
    match r.as_slice() {
        [_, Outbound::ComponentMetadata(_)] => {}
        other => panic!("{other:?}"),
    }
    // A message id the firmware cannot send on request: denied.
    let r = g.command(MavCmd::MAV_CMD_REQUEST_MESSAGE, [9999.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_DENIED);
    let t = g.t();
    let ts = TIMESYNC_DATA { tc1: 0, ts1: 42, ..Default::default() };
    match g.send(&ts).as_slice() {
        [Outbound::Timesync(a)] => {
            assert_eq!((a.tc1, a.ts1), (t as i64 * 1000, 42));
            assert_eq!((a.target_system, a.target_component), GCS);
        }
        other => panic!("{other:?}"),
    }
    // An answer (tc1 ≠ 0) is not answered again.
    assert!(g.send(&TIMESYNC_DATA { tc1: 5, ts1: 42, ..Default::default() }).is_empty());
}

/// Link-level services (issue 20): SYSTEM_TIME, GLOBAL_POSITION_INT, MISSION_CURRENT and
/// HOME_POSITION streams from `Link::poll`, their rates through MAV_CMD_SET_MESSAGE_INTERVAL /
/// GET_MESSAGE_INTERVAL, one-shots through MAV_CMD_REQUEST_MESSAGE. Before, none of these
/// messages was sent and the three commands were answered DENIED / UNSUPPORTED.
#[test]
#[allow(deprecated)] // MAV_CMD_GET_MESSAGE_INTERVAL: superseded, still sent by ground stations
fn message_intervals_requests_and_the_global_position_streams() {
    use parapet_firmware::link::services::ORIGIN;
    let mut g = Sim::new();
    g.airborne();
    assert_eq!(g.upload(&[[3.0, 0.0, -1.0], [3.0, 2.0, -1.0]]), MavMissionResult::MAV_MISSION_ACCEPTED);
    let poll = |g: &mut Sim| {
        let t = g.t();
        g.link.poll(t, &mut g.ap);
        core::iter::from_fn(|| g.link.pop_reply()).collect::<Vec<_>>()
    };
    let r = poll(&mut g);
    assert!(
        matches!(r.as_slice(), [Outbound::SystemTime(_), Outbound::GlobalPositionInt(_), Outbound::MissionCurrent(m), Outbound::HomePosition(h)]
        if m.total == 2 && (h.latitude, h.longitude, h.altitude) == ORIGIN),
        "{r:?}"
    );
    let Outbound::GlobalPositionInt(p) = &r[1] else { unreachable!() };
    let pos = g.ap.telemetry().position_ned;
    assert!((p.relative_alt as f32 + pos.z * 1000.0).abs() < 2.0, "{p:?} vs {pos:?}");
    assert!((p.lat - ORIGIN.0) as f32 / 89.83 - pos.x < 0.02, "{p:?} vs {pos:?}");
    // 50 Hz global position; GET answers it; SYSTEM_TIME stopped.
    let r = g.command(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [33.0, 20_000.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r), (MavResult::MAV_RESULT_ACCEPTED, GCS));
    let r = g.command(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [2.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_ACCEPTED);
    let r = g.command(MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL, [33.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert!(
        matches!(r.as_slice(), [Outbound::CommandAck(_), Outbound::MessageInterval(m)]
        if m.message_id == 33 && m.interval_us == 20_000),
        "{r:?}"
    );
    let mut seen = 0;
    for _ in 0..100 {
        g.step(&[]);
        for m in poll(&mut g) {
            assert!(!matches!(m, Outbound::SystemTime(_)), "stopped stream sent");
            seen += usize::from(matches!(m, Outbound::GlobalPositionInt(_)));
        }
    }
    assert!((4..=6).contains(&seen), "{seen} GLOBAL_POSITION_INT in 100 ms at 50 Hz");
    // A one-shot HOME_POSITION; an interval too short or for a stream not served here: refused.
    let r = g.command(MavCmd::MAV_CMD_REQUEST_MESSAGE, [242.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_ACCEPTED);
    assert!(poll(&mut g).iter().any(|m| matches!(m, Outbound::HomePosition(_))));
    let r = g.command(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [33.0, 500.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_DENIED);
    let r = g.command(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [31.0, 20_000.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(Sim::ack(&r).0, MavResult::MAV_RESULT_UNSUPPORTED);
}

/// PING requests are answered to the sender; SET_MODE (legacy) changes the mode like
/// DO_SET_MODE; MISSION_SET_CURRENT is answered with MISSION_CURRENT (and a STATUSTEXT, as
/// jumping is not supported). Before, all three were ignored.
#[test]
#[allow(deprecated)] // PING, SET_MODE, MISSION_SET_CURRENT: deprecated, still sent by ground stations
fn ping_set_mode_and_mission_set_current_are_served() {
    use parapet_firmware::link::dialect::{MISSION_SET_CURRENT_DATA, PING_DATA, SET_MODE_DATA};
    let mut g = Sim::new();
    let r = g.send(&PING_DATA { time_usec: 77, seq: 9, target_system: 0, target_component: 0 });
    assert!(
        matches!(r.as_slice(), [Outbound::Ping(p)]
        if (p.time_usec, p.seq, p.target_system, p.target_component) == (77, 9, GCS.0, GCS.1)),
        "{r:?}"
    );
    g.airborne();
    assert_eq!(g.upload(&[[3.0, 0.0, -1.0]]), MavMissionResult::MAV_MISSION_ACCEPTED);
    // custom_mode in PX4's encoding, as the HEARTBEAT's (AUTO.MISSION flies the mission).
    let set_mode =
        SET_MODE_DATA { custom_mode: FlightMode::Mission.px4_custom_mode(), target_system: 1, base_mode: 1 };
    g.send(&set_mode);
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Mission);
    let other =
        SET_MODE_DATA { target_system: 2, custom_mode: FlightMode::Hold.px4_custom_mode(), ..set_mode };
    g.send(&other);
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Mission, "SET_MODE for system 2 applied");
    let r = g.send(&MISSION_SET_CURRENT_DATA { seq: 0, target_system: 1, target_component: 1 });
    assert!(matches!(r.as_slice(), [Outbound::MissionCurrent(m)] if m.total == 1), "{r:?}");
    let r = g.send(&MISSION_SET_CURRENT_DATA { seq: 5, target_system: 1, target_component: 1 });
    assert!(matches!(r.as_slice(), [Outbound::StatusText(_), Outbound::MissionCurrent(_)]), "{r:?}");
}
