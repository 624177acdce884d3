//! Ground-station services of issue 20 that MAVSDK and QGroundControl rely on, end to end on the
//! host: frames through the firmware's `Link` into the real `Cascade`, driven by the lockstep
//! scheduler the PIL firmware runs. Each test failed before its fix:
//! * MISSION_CURRENT `seq` was always 0 and MISSION_ITEM_REACHED was never sent (MAVSDK's
//!   mission progress never advanced);
//! * BATTERY_STATUS was never sent and SYS_STATUS said "no battery" with a measurement;
//! * ATTITUDE, LOCAL_POSITION_NED and POSITION_TARGET_LOCAL_NED had fixed rates
//!   (SET_MESSAGE_INTERVAL answered UNSUPPORTED), ATTITUDE_TARGET was never sent; so had
//!   HEARTBEAT, SYS_STATUS and EXTENDED_SYS_STATE (one 1 Hz group);
//! * global-frame mission items (QGroundControl, MAVSDK's `mission` plugin) were refused
//!   MAV_MISSION_UNSUPPORTED_FRAME.
//! * NAV_TAKEOFF / NAV_LAND / NAV_RETURN_TO_LAUNCH items (QGroundControl's default plan) were
//!   refused MAV_MISSION_UNSUPPORTED, and DO_* items were dropped (the seq numbers shifted).

use mavlink_core::MessageData;
use parapet_core::battery::{BatteryLevel, BatteryState};
use parapet_core::controller::ControllerParams;
use parapet_core::wire::geo::ORIGIN;
use parapet_firmware::app::autopilot::{Autopilot, FlightPhase};
use parapet_firmware::app::cascade::Cascade;
use parapet_firmware::link::command::command_long;
use parapet_firmware::link::dialect::{
    MavBatteryChargeState, MavCmd, MavFrame, MavMissionResult, MavParamType, MavResult, MavSysStatusSensor,
    MissionState, COMMAND_INT_DATA, COMMAND_LONG_DATA, HIL_SENSOR_DATA, MISSION_COUNT_DATA,
    MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA, OBSTACLE_DISTANCE_3D_DATA,
    ODOMETRY_DATA, PARAM_SET_DATA,
};
use parapet_firmware::link::framing::FrameWriter;
use parapet_firmware::link::obstacles::CLEAR_ID;
use parapet_firmware::link::outbound::Outbound;
use parapet_firmware::link::telemetry::{ErrorCounters, TelemetryInputs, TelemetryScheduler};
use parapet_firmware::link::{FixClock, Link};
use parapet_firmware::pil::lockstep::LockstepScheduler;

/// A ground station on the lockstep link of the real cascade at rest on the ground at the origin
/// (the same harness as `gcs_link.rs`), with the telemetry scheduler the PIL application runs.
struct Sim {
    link: Link,
    ap: Cascade,
    sched: LockstepScheduler,
    tel: TelemetryScheduler,
    w: FrameWriter,
    k: u64,
    /// Where the fixes put the vehicle (NED, m; the origin unless a test moves it).
    at: [f32; 3],
    /// The fixes follow the reference (down to the ground at z = 0) and the attitude setpoint's
    /// heading (a perfect tracker).
    follow: bool,
    /// The fixes' heading, rad.
    yaw: f32,
}

impl Sim {
    fn new() -> Self {
        Sim {
            link: Link::new(1, FixClock::Message),
            ap: Cascade::new(ControllerParams::default()).expect("default parameters"),
            sched: LockstepScheduler::default(),
            tel: TelemetryScheduler::new(),
            w: FrameWriter::new(255, 190),
            k: 0,
            at: [0.0; 3],
            follow: false,
            yaw: 0.0,
        }
    }

    fn t(&self) -> u64 {
        1_000_000 + self.k * 1000
    }

    fn frame<D: MessageData>(&mut self, m: &D) -> Vec<u8> {
        self.w.encode(m).raw_bytes().to_vec()
    }

    /// One 1 ms step as the PIL application runs it (a fix and an empty obstacle batch every
    /// 4 ms, `msgs`, HIL_SENSOR, the control step, `Link::poll`, the telemetry scheduler); every
    /// message the vehicle sent in it.
    fn step(&mut self, msgs: &[Vec<u8>]) -> Vec<Outbound> {
        let t = self.t();
        if self.k.is_multiple_of(4) {
            if self.follow {
                let s = self.ap.telemetry();
                let p = s.setpoint.position_ned;
                (self.at, self.yaw) = ([p.x, p.y, p.z.min(0.0)], s.attitude_sp.yaw);
            }
            let (sin, cos) = (self.yaw / 2.0).sin_cos();
            let odo = ODOMETRY_DATA {
                time_usec: t,
                x: self.at[0],
                y: self.at[1],
                z: self.at[2],
                q: [cos, 0.0, 0.0, sin],
                frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                ..Default::default()
            };
            let clear = OBSTACLE_DISTANCE_3D_DATA {
                time_boot_ms: (t / 1000) as u32,
                obstacle_id: CLEAR_ID,
                frame: MavFrame::MAV_FRAME_LOCAL_NED,
                min_distance: 1.0,
                max_distance: 0.0,
                ..Default::default()
            };
            let (a, b) = (self.frame(&odo), self.frame(&clear));
            self.link.push_bytes(&a, t, &mut self.ap);
            self.link.push_bytes(&b, t, &mut self.ap);
        }
        let mut out = Vec::new();
        for m in msgs {
            self.link.push_bytes(m, t, &mut self.ap);
            out.extend(core::iter::from_fn(|| self.link.pop_reply()));
        }
        let hil = HIL_SENSOR_DATA { time_usec: t, zacc: -9.81, ..Default::default() };
        let h = self.frame(&hil);
        self.link.push_bytes(&h, t, &mut self.ap);
        let Some(sample) = self.link.take_hil_sample() else { panic!("HIL_SENSOR not decoded at {t}") };
        self.sched.step(&sample, &mut self.link, &mut self.ap);
        self.link.poll(t, &mut self.ap);
        out.extend(core::iter::from_fn(|| self.link.pop_reply()));
        let inputs = TelemetryInputs {
            snapshot: self.ap.telemetry(),
            inner: Default::default(),
            outer: Default::default(),
            parser: self.link.parser_stats(),
            counters: ErrorCounters::from_link(&self.link),
        };
        self.tel.poll(t, &inputs, |m| out.push(m));
        self.k += 1;
        out
    }

    fn run(&mut self, steps: u64) -> Vec<Outbound> {
        (0..steps).flat_map(|_| self.step(&[])).collect()
    }

    fn send<D: MessageData>(&mut self, m: &D) -> Vec<Outbound> {
        let f = self.frame(m);
        self.step(&[f])
    }

    fn command(&mut self, command: MavCmd, p: [f32; 7]) -> MavResult {
        let c = command_long(command as u16, p, (1, 1));
        let r = self.send(&c);
        match r.iter().find_map(|m| match m {
            Outbound::CommandAck(a) if a.command == command as u16 => Some(a.result),
            _ => None,
        }) {
            Some(res) => res,
            None => panic!("no COMMAND_ACK for {command:?}: {r:?}"),
        }
    }

    fn interval(&mut self, msg_id: f32, us: f32) -> MavResult {
        self.command(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [msg_id, us, 0.0, 0.0, 0.0, 0.0, 0.0])
    }

    fn upload(&mut self, path: &[[f32; 3]]) -> MavMissionResult {
        let count = MISSION_COUNT_DATA {
            count: path.len() as u16,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        };
        let mut r = self.send(&count);
        loop {
            let reply = r.iter().find_map(|m| match m {
                Outbound::MissionRequestInt(q) => Some(Ok(q.seq)),
                Outbound::MissionAck(a) => Some(Err(a.mavtype)),
                _ => None,
            });
            match reply {
                Some(Ok(seq)) => {
                    let p = path[usize::from(seq)];
                    let item = MISSION_ITEM_INT_DATA {
                        x: (p[0] * 1e4) as i32,
                        y: (p[1] * 1e4) as i32,
                        z: p[2],
                        seq,
                        command: MavCmd::MAV_CMD_NAV_WAYPOINT as u16,
                        frame: MavFrame::MAV_FRAME_LOCAL_NED,
                        target_system: 1,
                        target_component: 1,
                        ..Default::default()
                    };
                    r = self.send(&item);
                }
                Some(Err(result)) => return result,
                None => r = self.step(&[]),
            }
        }
    }

    /// Uploads `items` as they are (seq set here); the final MISSION_ACK result.
    fn upload_items(&mut self, items: &[MISSION_ITEM_INT_DATA]) -> MavMissionResult {
        let count = MISSION_COUNT_DATA {
            count: items.len() as u16,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        };
        let mut r = self.send(&count);
        loop {
            let reply = r.iter().find_map(|m| match m {
                Outbound::MissionRequestInt(q) => Some(Ok(q.seq)),
                Outbound::MissionAck(a) => Some(Err(a.mavtype)),
                _ => None,
            });
            match reply {
                Some(Ok(seq)) => {
                    let item = MISSION_ITEM_INT_DATA { seq, ..items[usize::from(seq)].clone() };
                    r = self.send(&item);
                }
                Some(Err(result)) => return result,
                None => r = self.step(&[]),
            }
        }
    }

    /// Downloads the mission: MISSION_REQUEST_LIST, then MISSION_REQUEST_INT per item.
    fn download(&mut self) -> Vec<MISSION_ITEM_INT_DATA> {
        let list = MISSION_REQUEST_LIST_DATA { target_system: 1, target_component: 1, ..Default::default() };
        let r = self.send(&list);
        let Some(n) = r.iter().find_map(|m| match m {
            Outbound::MissionCount(c) => Some(c.count),
            _ => None,
        }) else {
            panic!("no MISSION_COUNT: {r:?}")
        };
        (0..n)
            .map(|seq| {
                let q = MISSION_REQUEST_INT_DATA {
                    seq,
                    target_system: 1,
                    target_component: 1,
                    ..Default::default()
                };
                self.answer(&q, |m| match m {
                    Outbound::MissionItemInt(i) => Some(i.clone()),
                    _ => None,
                })
            })
            .collect()
    }

    /// Sends `m` in one step; the first reply `pick` takes (panics, naming `m`, without one).
    fn answer<D: MessageData + core::fmt::Debug, T>(
        &mut self,
        m: &D,
        pick: impl Fn(&Outbound) -> Option<T>,
    ) -> T {
        let r = self.send(m);
        match r.iter().find_map(pick) {
            Some(t) => t,
            None => panic!("no answer to {m:?}: {r:?}"),
        }
    }

    /// Arms after 0.5 s of samples and holds 1 m above the origin.
    fn airborne(&mut self) {
        self.run(500);
        assert_eq!(
            self.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
            MavResult::MAV_RESULT_ACCEPTED
        );
        let hold = [0.0, 3.0, 1.0, 0.0, 0.0, 0.0, -1.0];
        assert_eq!(self.command(MavCmd::MAV_CMD_OVERRIDE_GOTO, hold), MavResult::MAV_RESULT_ACCEPTED);
        self.run(20);
    }
}

fn count(out: &[Outbound], f: impl Fn(&Outbound) -> bool) -> usize {
    out.iter().filter(|m| f(m)).count()
}

/// MISSION_CURRENT carries the item being flown and MISSION_ITEM_REACHED reports each item once,
/// in order, then the mission is COMPLETE (MAVSDK's `mission_progress` and "reached the goal").
#[test]
fn mission_current_and_item_reached_follow_the_mission() {
    let mut g = Sim::new();
    g.airborne();
    // A vehicle that follows the reference (the trajectory's clock waits for it).
    g.follow = true;
    let path = [[1.0, 0.0, -1.0], [1.0, 1.0, -1.0], [0.0, 1.0, -1.0]];
    assert_eq!(g.upload(&path), MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(g.interval(42.0, 50_000.0), MavResult::MAV_RESULT_ACCEPTED);
    let before = g.run(100);
    assert!(before.iter().any(|m| matches!(m, Outbound::MissionCurrent(c)
        if c.seq == 0 && c.total == 3 && c.mission_state == MissionState::MISSION_STATE_NOT_STARTED)));
    assert_eq!(count(&before, |m| matches!(m, Outbound::MissionItemReached(_))), 0);
    assert_eq!(g.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
    let mut seqs = Vec::new();
    let mut reached = Vec::new();
    let mut complete = false;
    for _ in 0..20_000 {
        for m in g.step(&[]) {
            match m {
                Outbound::MissionCurrent(c) => {
                    if seqs.last() != Some(&c.seq) {
                        seqs.push(c.seq);
                    }
                    complete |= c.mission_state == MissionState::MISSION_STATE_COMPLETE;
                }
                Outbound::MissionItemReached(r) => reached.push(r.seq),
                _ => {}
            }
        }
        if complete {
            break;
        }
    }
    assert_eq!(seqs, vec![0, 1, 2], "MISSION_CURRENT seq over the flight");
    assert_eq!(reached, vec![0, 1, 2], "MISSION_ITEM_REACHED, each item once");
    assert!(complete, "mission_state COMPLETE at the end ({:?})", g.ap.telemetry().phase);
    assert_eq!(count(&g.run(300), |m| matches!(m, Outbound::MissionItemReached(_))), 0, "not repeated");
}

/// With a battery measurement the cascade took, SYS_STATUS carries its voltage, current and
/// remaining charge and BATTERY_STATUS streams at 1 Hz; the battery's health bit drops at Low.
/// Issue 41: a vehicle standing at (1, 1, 0) reports that position from power-on
/// (LOCAL_POSITION_NED, GLOBAL_POSITION_INT), not the origin until arming (was (0, 0, 0) and a
/// 1.4 m jump at ARM); HOME_POSITION is its position, then where it armed, sent at once;
/// MAV_CMD_GET_HOME_POSITION answers with it; MAV_CMD_DO_SET_HOME moves it while disarmed
/// (COMMAND_INT, exact 10⁻⁷ °) and is DENIED armed; GPS_GLOBAL_ORIGIN comes on request.
#[test]
#[allow(deprecated)] // MAV_CMD_GET_HOME_POSITION: still sent by ground stations (MAVSDK, QGC)
fn position_from_power_on_and_home_where_the_vehicle_armed() {
    let mut g = Sim::new();
    g.at = [1.0, 1.0, 0.0];
    let out = g.run(300);
    let local: Vec<_> = out
        .iter()
        .filter_map(|m| match m {
            Outbound::LocalPositionNed(p) => Some((p.x, p.y, p.z)),
            _ => None,
        })
        .collect();
    assert_eq!(local.last(), Some(&(1.0, 1.0, 0.0)), "disarmed, where it stands: {local:?}");
    let global = out.iter().rev().find_map(|m| match m {
        Outbound::GlobalPositionInt(p) => Some((p.lat - ORIGIN.0, p.lon - ORIGIN.1, p.relative_alt)),
        _ => None,
    });
    assert_eq!(global, Some((90, 133, 0)), "1 m north and east of the origin, on home's altitude");
    let home = |out: &[Outbound]| {
        out.iter().rev().find_map(|m| match m {
            Outbound::HomePosition(h) => Some((h.x, h.y, h.latitude - ORIGIN.0, h.longitude - ORIGIN.1)),
            _ => None,
        })
    };
    assert_eq!(home(&out), Some((1.0, 1.0, 90, 133)), "home: its first position");
    // Moved on the ground, then armed there: home follows, at once.
    g.at = [2.0, 1.0, 0.0];
    g.run(20);
    let arm = COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
        param1: 1.0,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let mut out = g.send(&arm);
    out.extend(g.run(5));
    assert!(g.ap.telemetry().armed);
    assert_eq!(home(&out), Some((2.0, 1.0, 180, 133)), "home where it armed, at once");
    let asked = |g: &mut Sim| {
        let c = COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_GET_HOME_POSITION as u16,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        };
        let mut out = g.send(&c);
        out.extend(g.run(2));
        out
    };
    let out = asked(&mut g);
    assert!(out
        .iter()
        .any(|m| matches!(m, Outbound::CommandAck(a) if a.result == MavResult::MAV_RESULT_ACCEPTED)));
    assert_eq!(home(&out), Some((2.0, 1.0, 180, 133)), "GET_HOME_POSITION");
    // DO_SET_HOME: denied armed, accepted disarmed (exact integers by COMMAND_INT).
    assert_eq!(
        g.command(MavCmd::MAV_CMD_DO_SET_HOME, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_DENIED
    );
    assert_eq!(g.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
    let set = COMMAND_INT_DATA {
        command: MavCmd::MAV_CMD_DO_SET_HOME as u16,
        frame: MavFrame::MAV_FRAME_GLOBAL,
        x: ORIGIN.0 + 8983,
        y: ORIGIN.1 - 1327,
        z: 488.0,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let out = g.send(&set);
    assert!(
        out.iter()
            .any(|m| matches!(m, Outbound::CommandAck(a) if a.result == MavResult::MAV_RESULT_ACCEPTED)),
        "{out:?}"
    );
    let out = asked(&mut g);
    assert_eq!(home(&out).map(|h| (h.2, h.3)), Some((8983, -1327)), "exactly where it was set");
    // GPS_GLOBAL_ORIGIN on request.
    let req = COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_REQUEST_MESSAGE as u16,
        param1: 49.0,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let mut out = g.send(&req);
    out.extend(g.run(2));
    assert!(out.iter().any(
        |m| matches!(m, Outbound::GpsGlobalOrigin(o) if (o.latitude, o.longitude, o.altitude) == ORIGIN)
    ));
}

#[test]
fn battery_status_and_sys_status_report_the_measurement() {
    let mut g = Sim::new();
    let sys = |out: &[Outbound]| {
        out.iter().rev().find_map(|m| match m {
            Outbound::SysStatus(s) => Some(s.clone()),
            _ => None,
        })
    };
    let first = g.run(1000);
    let s = sys(&first).expect("SYS_STATUS");
    assert_eq!((s.voltage_battery, s.current_battery, s.battery_remaining), (u16::MAX, -1, -1));
    assert_eq!(count(&first, |m| matches!(m, Outbound::BatteryStatus(_))), 0, "no measurement yet");
    // No battery: a BATTERY_STATUS request is DENIED and nothing is sent (before: ACCEPTED, and
    // the message never came).
    let p = [147.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_eq!(g.command(MavCmd::MAV_CMD_REQUEST_MESSAGE, p), MavResult::MAV_RESULT_DENIED);
    assert_eq!(count(&g.run(100), |m| matches!(m, Outbound::BatteryStatus(_))), 0);
    let b = BatteryState {
        t_us: g.t(),
        voltage_v: 16.4,
        current_a: Some(2.5),
        remaining: Some(0.9),
        level: BatteryLevel::Ok,
    };
    g.ap.set_battery(&b);
    let out = g.run(2000);
    let s = sys(&out).expect("SYS_STATUS");
    assert_eq!((s.voltage_battery, s.current_battery, s.battery_remaining), (16_400, 250, 90));
    assert_eq!(g.command(MavCmd::MAV_CMD_REQUEST_MESSAGE, p), MavResult::MAV_RESULT_ACCEPTED, "a battery");
    assert!(s.onboard_control_sensors_present.contains(MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_BATTERY));
    assert!(s.onboard_control_sensors_health.contains(MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_BATTERY));
    let bs: Vec<_> = out
        .iter()
        .filter_map(|m| match m {
            Outbound::BatteryStatus(b) => Some(b.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(bs.len(), 2, "1 Hz over 2 s");
    assert_eq!((bs[0].voltages[0], bs[0].current_battery, bs[0].battery_remaining), (16_400, 250, 90));
    g.ap.set_battery(&BatteryState { level: BatteryLevel::Low, voltage_v: 14.0, ..b });
    let out = g.run(1000);
    let s = sys(&out).expect("SYS_STATUS");
    assert!(!s.onboard_control_sensors_health.contains(MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_BATTERY));
    assert!(out.iter().any(|m| matches!(m, Outbound::BatteryStatus(b)
        if b.charge_state == MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_LOW)));
}

/// SET_MESSAGE_INTERVAL sets the rates of ATTITUDE, LOCAL_POSITION_NED, POSITION_TARGET_LOCAL_NED
/// (the telemetry scheduler's streams) and ATTITUDE_TARGET; REQUEST_MESSAGE sends one at once.
#[test]
fn scheduler_stream_rates_are_settable() {
    let mut g = Sim::new();
    let rates = |out: &[Outbound]| {
        (
            count(out, |m| matches!(m, Outbound::Attitude(_))),
            count(out, |m| matches!(m, Outbound::LocalPositionNed(_))),
            count(out, |m| matches!(m, Outbound::PositionTargetLocalNed(_))),
            count(out, |m| matches!(m, Outbound::AttitudeTarget(_))),
        )
    };
    assert_eq!(rates(&g.run(1000)), (50, 25, 25, 10), "the defaults");
    assert_eq!(g.interval(30.0, 100_000.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.interval(32.0, -1.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.interval(85.0, 10_000.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.interval(83.0, 50_000.0), MavResult::MAV_RESULT_ACCEPTED);
    let (att, pos, target, att_target) = rates(&g.run(1000));
    assert!((10..=11).contains(&att), "ATTITUDE at 10 Hz: {att}");
    assert_eq!(pos, 0, "LOCAL_POSITION_NED stopped");
    assert!((100..=101).contains(&target), "POSITION_TARGET_LOCAL_NED at 100 Hz: {target}");
    assert!((20..=21).contains(&att_target), "ATTITUDE_TARGET at 20 Hz: {att_target}");
    let req = COMMAND_LONG_DATA {
        param1: 32.0,
        command: MavCmd::MAV_CMD_REQUEST_MESSAGE as u16,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let mut out = g.send(&req);
    assert!(out
        .iter()
        .any(|m| matches!(m, Outbound::CommandAck(a) if a.result == MavResult::MAV_RESULT_ACCEPTED)));
    out.extend(g.run(10));
    assert_eq!(rates(&out).1, 1, "one LOCAL_POSITION_NED on request while stopped");
    assert_eq!(g.interval(30.0, 0.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.interval(32.0, 0.0), MavResult::MAV_RESULT_ACCEPTED);
    let (att, pos, _, _) = rates(&g.run(1000));
    assert!((50..=51).contains(&att) && (25..=26).contains(&pos), "defaults restored: {att} {pos}");
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Disarmed);
}

/// SET_MESSAGE_INTERVAL sets HEARTBEAT, SYS_STATUS and EXTENDED_SYS_STATE too (issue 20: the
/// three were one fixed 1 Hz group, their interval answered UNSUPPORTED): SYS_STATUS at 5 Hz,
/// EXTENDED_SYS_STATE off (one on REQUEST_MESSAGE), HEARTBEAT at 2 Hz; HEARTBEAT is never turned
/// off nor slowed below 1 Hz (DENIED), and 0 restores the defaults.
#[test]
#[allow(deprecated)] // MAV_CMD_GET_MESSAGE_INTERVAL: superseded, still sent by ground stations
fn heartbeat_sys_status_and_extended_sys_state_rates_are_settable() {
    let mut g = Sim::new();
    let rates = |out: &[Outbound]| {
        (
            count(out, |m| matches!(m, Outbound::Heartbeat(_))),
            count(out, |m| matches!(m, Outbound::SysStatus(_))),
            count(out, |m| matches!(m, Outbound::ExtendedSysState(_))),
        )
    };
    assert_eq!(rates(&g.run(1000)), (1, 1, 1), "the defaults");
    assert_eq!(g.interval(1.0, 200_000.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.interval(245.0, -1.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.interval(0.0, 500_000.0), MavResult::MAV_RESULT_ACCEPTED);
    let (hb, sys, ext) = rates(&g.run(1000));
    assert!((2..=3).contains(&hb), "HEARTBEAT at 2 Hz: {hb}");
    assert!((5..=6).contains(&sys), "SYS_STATUS at 5 Hz: {sys}");
    assert_eq!(ext, 0, "EXTENDED_SYS_STATE stopped");
    assert_eq!(g.interval(0.0, -1.0), MavResult::MAV_RESULT_DENIED, "HEARTBEAT never off");
    assert_eq!(g.interval(0.0, 5_000_000.0), MavResult::MAV_RESULT_DENIED, "nor below 1 Hz");
    let get = COMMAND_LONG_DATA {
        param1: 0.0,
        command: MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL as u16,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let r = g.send(&get);
    assert!(
        r.iter().any(
            |m| matches!(m, Outbound::MessageInterval(i) if i.message_id == 0 && i.interval_us == 500_000)
        ),
        "{r:?}"
    );
    let req = COMMAND_LONG_DATA { param1: 245.0, command: MavCmd::MAV_CMD_REQUEST_MESSAGE as u16, ..get };
    let mut out = g.send(&req);
    out.extend(g.run(10));
    assert_eq!(rates(&out).2, 1, "one EXTENDED_SYS_STATE on request while stopped");
    for id in [0.0, 1.0, 245.0] {
        assert_eq!(g.interval(id, 0.0), MavResult::MAV_RESULT_ACCEPTED);
    }
    let (hb, sys, ext) = rates(&g.run(2000));
    assert!(hb == 2 && sys == 2 && ext == 2, "defaults restored: {hb} {sys} {ext}");
}

/// MAVSDK's `mission_raw.start_mission()` is DO_SET_MODE with PX4's AUTO.MISSION (base mode
/// CUSTOM | SAFETY_ARMED, main 4, sub 4). Like PX4 it flies the uploaded mission when the vehicle
/// is airborne and holding; before, it was ACCEPTED but the vehicle kept holding (Mission is the
/// default mode, so the mode change was a no-op).
#[test]
fn do_set_mode_auto_mission_flies_the_uploaded_mission() {
    let mut g = Sim::new();
    g.airborne();
    let px4_mission = [129.0, 4.0, 4.0, 0.0, 0.0, 0.0, 0.0];
    // No mission uploaded: the mode change stands, nothing is flown.
    assert_eq!(g.command(MavCmd::MAV_CMD_DO_SET_MODE, px4_mission), MavResult::MAV_RESULT_ACCEPTED);
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Hover);
    assert_eq!(g.upload(&[[1.0, 0.0, -1.0], [1.0, 1.0, -1.0]]), MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(g.command(MavCmd::MAV_CMD_DO_SET_MODE, px4_mission), MavResult::MAV_RESULT_ACCEPTED);
    g.run(8);
    assert_eq!(g.ap.telemetry().phase, FlightPhase::Mission, "flies the mission");
}

/// ODOMETRY in PX4's LOCAL_FRD (a vision frame of unknown heading) is refused cleanly: not taken
/// as a fix, counted, and a STATUSTEXT says why (at most every 10 s). Before: refused silently
/// (only a counter in DEBUG_VECT LINK_DROP), so a companion never learnt why it was ignored.
#[test]
fn odometry_in_local_frd_is_refused_with_a_statustext() {
    use parapet_firmware::link::ODOMETRY_REFUSED_TEXT;
    let mut g = Sim::new();
    g.run(100);
    let frd = ODOMETRY_DATA {
        time_usec: g.t(),
        x: 5.0,
        q: [1.0, 0.0, 0.0, 0.0],
        frame_id: MavFrame::MAV_FRAME_LOCAL_FRD,
        child_frame_id: MavFrame::MAV_FRAME_BODY_FRD,
        ..Default::default()
    };
    let before = g.link.stats().odometry_rejected;
    let texts = |out: &[Outbound]| {
        out.iter()
            .filter(|m| matches!(m, Outbound::StatusText(t) if t.text.to_str().ok() == Some(ODOMETRY_REFUSED_TEXT)))
            .count()
    };
    let out = g.send(&frd);
    assert_eq!(texts(&out), 1, "{out:?}");
    assert_eq!(g.link.stats().odometry_rejected, before + 1);
    g.run(8);
    assert!(g.ap.telemetry().position_ned.x.abs() < 0.1, "the FRD x = 5 m was not taken");
    let again = ODOMETRY_DATA { time_usec: g.t(), ..frd };
    assert_eq!(texts(&g.send(&again)), 0, "at most one text per 10 s");
    assert_eq!(g.link.stats().odometry_rejected, before + 2);
}

/// A ground station speaking MAVLink **v1** (0xFE frames) is told that only MAVLink 2 is
/// spoken — a STATUSTEXT WARNING framed in v1, which it can read — at most every 5 s; its frames
/// are not dispatched. Before: v1 frames were dropped silently (a v1 GCS "cannot even start").
#[test]
fn a_v1_heartbeat_is_answered_with_a_v1_statustext() {
    use mavlink_core::{MAVLinkV1MessageRaw, MavHeader};
    use parapet_firmware::link::dialect::{HEARTBEAT_DATA, STATUSTEXT_DATA};
    use parapet_firmware::link::v1::V1_REFUSED_TEXT;
    let mut g = Sim::new();
    let v1 = |seq: u8| {
        let mut raw = MAVLinkV1MessageRaw::new();
        let h = MavHeader { system_id: 255, component_id: 190, sequence: seq };
        raw.serialize_message_data(h, &HEARTBEAT_DATA::default());
        raw.raw_bytes().to_vec()
    };
    let out = g.step(&[v1(0)]);
    let answers: Vec<_> = out.iter().filter(|m| matches!(m, Outbound::StatusTextV1(_))).collect();
    assert_eq!(answers.len(), 1, "{out:?}");
    assert_eq!(g.link.v1_heartbeats(), 1);
    // On the wire: a v1 frame a v1 parser accepts, with the text.
    let mut w = FrameWriter::new(1, 1);
    let bytes = answers[0].encode(&mut w).raw_bytes().to_vec();
    assert_eq!(bytes[0], 0xFE, "v1 start byte");
    let mut arr = [0u8; 263];
    arr[..bytes.len()].copy_from_slice(&bytes);
    let frame = MAVLinkV1MessageRaw::from_bytes_unparsed(arr);
    assert_eq!((frame.message_id(), frame.system_id(), frame.component_id()), (253, 1, 1));
    assert!(frame.has_valid_crc_with_extra_crc(STATUSTEXT_DATA::EXTRA_CRC));
    let text = String::from_utf8_lossy(&frame.payload()[1..]).trim_end_matches('\0').to_string();
    assert_eq!(text, V1_REFUSED_TEXT);
    // Rate limit: the next v1 heartbeats within 5 s get no answer; the v2 link is unaffected.
    for k in 1..4 {
        let out = g.step(&[v1(k)]);
        assert!(!out.iter().any(|m| matches!(m, Outbound::StatusTextV1(_))));
    }
    assert_eq!(g.link.v1_heartbeats(), 4);
    assert!(g.run(1000).iter().any(|m| matches!(m, Outbound::Heartbeat(_))), "v2 telemetry goes on");
}

/// A global-frame plan as MAVSDK's `mission` plugin and QGroundControl send it
/// (GLOBAL_RELATIVE_ALT_INT waypoints, a DO_CHANGE_SPEED item) is accepted through the link,
/// and downloads with the same lat/lon integers and frames (the flight to it is
/// `gcs_clients::mavsdk_mission_plugin_flies_a_global_plan_on_the_pil`: this harness's odometry
/// stays at the origin). On the ground at the origin GLOBAL_POSITION_INT is HOME_POSITION; a latitude beyond 90° is
/// refused INVALID_PARAM5_X and leaves the accepted mission in place.
#[test]
#[allow(deprecated)] // MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, as ground stations send it
fn a_global_frame_mission_is_flown_where_the_ground_station_planned_it() {
    let mut g = Sim::new();
    let at_rest = g.run(400);
    let gp = at_rest.iter().rev().find_map(|m| match m {
        Outbound::GlobalPositionInt(p) => Some(p.clone()),
        _ => None,
    });
    let Some(gp) = gp else { panic!("no GLOBAL_POSITION_INT at rest") };
    assert_eq!((gp.lat, gp.lon, gp.relative_alt), (ORIGIN.0, ORIGIN.1, 0), "at the origin: home");
    g.airborne();
    let rel = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
    let wp = |lat: i32, lon: i32, z: f32| MISSION_ITEM_INT_DATA {
        x: lat,
        y: lon,
        z,
        command: MavCmd::MAV_CMD_NAV_WAYPOINT as u16,
        frame: rel,
        target_system: 1,
        target_component: 1,
        autocontinue: 1,
        ..Default::default()
    };
    let speed = MISSION_ITEM_INT_DATA {
        command: MavCmd::MAV_CMD_DO_CHANGE_SPEED as u16,
        frame: MavFrame::MAV_FRAME_MISSION,
        param2: 1.0,
        param3: -1.0,
        ..wp(0, 0, 0.0)
    };
    // 1 m north at 1 m, then 1 m north and 1 m east at 1.5 m above home.
    let goal = (ORIGIN.0 + 90, ORIGIN.1 + 133);
    let plan = [wp(ORIGIN.0 + 90, ORIGIN.1, 1.0), speed, wp(goal.0, goal.1, 1.5)];
    assert_eq!(g.upload_items(&plan), MavMissionResult::MAV_MISSION_ACCEPTED);
    let down = g.download();
    assert_eq!(down.len(), 3, "every item, the DO_CHANGE_SPEED too, with its seq");
    for (k, (d, p)) in down.iter().zip(&plan).enumerate() {
        assert_eq!((d.seq, d.frame, d.x, d.y, d.command), (k as u16, p.frame, p.x, p.y, p.command));
        assert!((d.z - p.z).abs() < 1e-3, "{} vs {}", d.z, p.z);
    }
    assert_eq!(
        g.upload_items(&[wp(900_000_001, ORIGIN.1, 1.0)]),
        MavMissionResult::MAV_MISSION_INVALID_PARAM5_X
    );
    assert_eq!(g.download().len(), 3, "a refused upload keeps the accepted mission");
}

/// A ground station that speaks the deprecated float mission messages: it answers the vehicle's
/// MISSION_REQUEST_INT with MISSION_ITEM (lat/lon in degrees; a LOCAL_NED waypoint in metres),
/// which is accepted like MISSION_ITEM_INT (PX4 does), and downloads with MISSION_REQUEST, answered
/// with MISSION_ITEM (degrees, the *_INT frames as the float ones); MISSION_REQUEST_INT still gets
/// MISSION_ITEM_INT. Before: both messages were ignored (the upload was cancelled after its
/// retries, the download never answered).
#[test]
#[allow(deprecated)] // MISSION_ITEM, MISSION_REQUEST, the float frames: what an old ground station sends
fn float_mission_items_upload_and_download_for_old_ground_stations() {
    use parapet_firmware::link::dialect::{MISSION_ITEM_DATA, MISSION_REQUEST_DATA};
    let mut g = Sim::new();
    let deg = |e7: i32| (f64::from(e7) * 1e-7) as f32;
    let rel = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
    let to_us =
        MISSION_ITEM_DATA { target_system: 1, target_component: 1, autocontinue: 1, ..Default::default() };
    let item = |command: MavCmd, frame: MavFrame, x: f32, y: f32, z: f32| MISSION_ITEM_DATA {
        x,
        y,
        z,
        command: command as u16,
        frame,
        ..to_us.clone()
    };
    let north = ORIGIN.0 + 180; // 2 m north
    let plan = [
        item(MavCmd::MAV_CMD_NAV_TAKEOFF, rel, 0.0, 0.0, 1.5),
        item(MavCmd::MAV_CMD_NAV_WAYPOINT, rel, deg(north), deg(ORIGIN.1), 1.5),
        MISSION_ITEM_DATA {
            param2: 1.0,
            ..item(MavCmd::MAV_CMD_DO_CHANGE_SPEED, MavFrame::MAV_FRAME_MISSION, 0.0, 0.0, 0.0)
        },
        item(MavCmd::MAV_CMD_NAV_WAYPOINT, MavFrame::MAV_FRAME_LOCAL_NED, 2.0, 2.0, -1.5),
        item(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, MavFrame::MAV_FRAME_MISSION, 0.0, 0.0, 0.0),
    ];
    let count = MISSION_COUNT_DATA { count: 5, target_system: 1, target_component: 1, ..Default::default() };
    let mut r = g.send(&count);
    let result = loop {
        let reply = r.iter().find_map(|m| match m {
            Outbound::MissionRequestInt(q) => Some(Ok(q.seq)),
            Outbound::MissionAck(a) => Some(Err(a.mavtype)),
            _ => None,
        });
        match reply {
            Some(Ok(seq)) => r = g.send(&MISSION_ITEM_DATA { seq, ..plan[usize::from(seq)].clone() }),
            Some(Err(result)) => break result,
            None => r = g.step(&[]),
        }
    };
    assert_eq!(result, MavMissionResult::MAV_MISSION_ACCEPTED, "a MISSION_ITEM upload");
    let int = g.download();
    assert_eq!(int.len(), 5);
    assert!((int[1].x - north).abs() <= 20 && (int[1].y - ORIGIN.1).abs() <= 5, "{:?}", int[1]);
    assert_eq!((int[3].frame, int[3].x, int[3].y), (MavFrame::MAV_FRAME_LOCAL_NED, 20_000, 20_000));
    assert_eq!(int[0].command, MavCmd::MAV_CMD_NAV_TAKEOFF as u16);
    // The download in MISSION_ITEM: degrees, the *_INT frame reported as the float one.
    let float: Vec<MISSION_ITEM_DATA> = (0..5u16)
        .map(|seq| {
            let q = MISSION_REQUEST_DATA { seq, target_system: 1, target_component: 1, ..Default::default() };
            g.answer(&q, |m| match m {
                Outbound::MissionItem(i) => Some(i.clone()),
                _ => None,
            })
        })
        .collect();
    for (k, (d, p)) in float.iter().zip(&plan).enumerate() {
        assert_eq!((d.seq, d.command, d.frame), (k as u16, p.command, p.frame), "item {k}");
        assert!(
            (d.x - p.x).abs() <= 4e-6 && (d.y - p.y).abs() <= 4e-6 && (d.z - p.z).abs() < 1e-3,
            "{d:?} vs {p:?}"
        );
    }
    // An integer upload downloads in MISSION_ITEM too, its GLOBAL_RELATIVE_ALT_INT as GLOBAL_RELATIVE_ALT.
    assert_eq!(
        g.upload_items(&[qgc_item(MavCmd::MAV_CMD_NAV_WAYPOINT, 1.0, 0.0, 1.0)]),
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    let q = MISSION_REQUEST_DATA { seq: 0, target_system: 1, target_component: 1, ..Default::default() };
    let r = g.send(&q);
    assert!(
        r.iter().any(|m| matches!(m, Outbound::MissionItem(i) if i.frame == rel && (i.x - deg(ORIGIN.0 + 89)).abs() < 4e-6)),
        "{r:?}"
    );
}

/// A QGroundControl-style item (GLOBAL_RELATIVE_ALT_INT) `lat_m`/`lon_m` metres from home
/// (0, 0: "here" for TAKEOFF/LAND/RTL and DO items).
fn qgc_item(command: MavCmd, north_m: f32, east_m: f32, alt_m: f32) -> MISSION_ITEM_INT_DATA {
    let (x, y) = if north_m == 0.0 && east_m == 0.0 {
        (0, 0)
    } else {
        (ORIGIN.0 + (north_m * 89.831_53) as i32, ORIGIN.1 + (east_m * 132.709_22) as i32)
    };
    #[allow(deprecated)] // the *_INT frame, as QGroundControl sends it
    let frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
    MISSION_ITEM_INT_DATA {
        x,
        y,
        z: alt_m,
        command: command as u16,
        frame,
        target_system: 1,
        target_component: 1,
        autocontinue: 1,
        ..Default::default()
    }
}

/// What a plan's flight showed: MISSION_CURRENT seqs (changes), MISSION_ITEM_REACHED seqs,
/// COMPLETE seen, the flight modes seen, the reference positions, armed at the end.
struct Flown {
    current: Vec<u16>,
    reached: Vec<u16>,
    complete: bool,
    modes: Vec<parapet_firmware::app::autopilot::FlightMode>,
    refs: Vec<parapet_core::Vec3>,
    /// The attitude setpoints' heading, rad.
    yaws: Vec<f32>,
    armed: bool,
}

/// Arms on the ground, MISSION_START, and runs until disarmed (at most `max_steps` ms).
fn fly_from_ground(g: &mut Sim, max_steps: usize) -> Flown {
    // The fixes follow the reference: the mission's trajectory (the default guidance) waits for
    // a vehicle that does not follow it.
    g.follow = true;
    g.run(500);
    assert_eq!(
        g.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(g.interval(42.0, 50_000.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
    let mut f = Flown {
        current: vec![],
        reached: vec![],
        complete: false,
        modes: vec![],
        refs: vec![],
        yaws: vec![],
        armed: true,
    };
    for _ in 0..max_steps {
        for m in g.step(&[]) {
            match m {
                Outbound::MissionCurrent(c) => {
                    if f.current.last() != Some(&c.seq) {
                        f.current.push(c.seq);
                    }
                    f.complete |= c.mission_state == MissionState::MISSION_STATE_COMPLETE;
                }
                Outbound::MissionItemReached(r) => f.reached.push(r.seq),
                _ => {}
            }
        }
        let s = g.ap.telemetry();
        if f.modes.last() != Some(&s.mode) {
            f.modes.push(s.mode);
        }
        if s.armed {
            f.refs.push(s.setpoint.position_ned);
            f.yaws.push(s.attitude_sp.yaw);
        } else {
            f.armed = false;
            g.run(300).iter().for_each(|m| match m {
                Outbound::MissionItemReached(r) => f.reached.push(r.seq),
                Outbound::MissionCurrent(c) => {
                    f.complete |= c.mission_state == MissionState::MISSION_STATE_COMPLETE
                }
                _ => {}
            });
            break;
        }
    }
    f
}

/// QGroundControl's default plan — TAKEOFF, waypoints, a DO_CHANGE_SPEED, RTL — is accepted,
/// downloads as uploaded, and flies from the ground: takeoff, path, Return mode, landing and
/// disarm, with MISSION_CURRENT / MISSION_ITEM_REACHED in the uploaded seq numbers. Before: the
/// TAKEOFF item was refused MAV_MISSION_UNSUPPORTED (and DO items shifted the seq numbers).
#[test]
fn qgc_default_plan_takes_off_flies_returns_and_lands() {
    use parapet_firmware::app::autopilot::FlightMode;
    let mut g = Sim::new();
    let plan = [
        qgc_item(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 1.5),
        qgc_item(MavCmd::MAV_CMD_NAV_WAYPOINT, 2.0, 0.0, 1.5),
        MISSION_ITEM_INT_DATA { param2: 1.0, ..qgc_item(MavCmd::MAV_CMD_DO_CHANGE_SPEED, 0.0, 0.0, 0.0) },
        qgc_item(MavCmd::MAV_CMD_NAV_WAYPOINT, 2.0, 2.0, 1.5),
        qgc_item(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, 0.0, 0.0, 0.0),
    ];
    assert_eq!(g.upload_items(&plan), MavMissionResult::MAV_MISSION_ACCEPTED);
    let down = g.download();
    let got: Vec<_> = down.iter().map(|i| (i.seq, i.command, i.x, i.y)).collect();
    let want: Vec<_> = plan.iter().enumerate().map(|(k, i)| (k as u16, i.command, i.x, i.y)).collect();
    assert_eq!(got, want, "the download is the upload");
    let f = fly_from_ground(&mut g, 60_000);
    assert!(!f.armed, "landed and disarmed ({:?})", g.ap.telemetry().phase);
    assert_eq!(f.reached, vec![0, 1, 2, 3, 4], "MISSION_ITEM_REACHED in the uploaded seqs");
    assert!(f.complete, "COMPLETE at the end");
    for seq in [0, 1, 3, 4] {
        assert!(f.current.contains(&seq), "MISSION_CURRENT {seq} shown: {:?}", f.current);
    }
    assert!(f.current.windows(2).all(|w| w[0] < w[1]), "MISSION_CURRENT in order: {:?}", f.current);
    assert!(f.modes.contains(&FlightMode::Return), "RTL is Return mode: {:?}", f.modes);
    let top = f.refs.iter().map(|p| -p.z).fold(f32::MIN, f32::max);
    assert!((top - 1.5).abs() < 0.1, "the takeoff climbs to the item's 1.5 m: {top}");
    assert!(f.refs.iter().any(|p| (p.x - 2.0).abs() < 0.1 && (p.y - 2.0).abs() < 0.1), "the path is flown");
}

/// A plan without a TAKEOFF item started armed on the ground takes off by itself (the cascade's
/// default 1 m), then flies the path and lands (issue 41, as PX4). Before: MISSION_START was
/// refused on the ground (MAVSDK's `start_mission` did nothing).
#[test]
fn a_plan_without_takeoff_started_on_the_ground_takes_off_by_itself() {
    let mut g = Sim::new();
    let plan = [
        qgc_item(MavCmd::MAV_CMD_NAV_WAYPOINT, 2.0, 0.0, 1.5),
        qgc_item(MavCmd::MAV_CMD_NAV_LAND, 0.0, 0.0, 0.0),
    ];
    assert_eq!(g.upload_items(&plan), MavMissionResult::MAV_MISSION_ACCEPTED);
    let f = fly_from_ground(&mut g, 60_000);
    assert!(!f.armed, "landed and disarmed ({:?})", g.ap.telemetry().phase);
    assert_eq!(f.reached, vec![0, 1], "MISSION_ITEM_REACHED in the uploaded seqs");
    assert!(f.complete, "COMPLETE at the end");
    assert!(
        f.refs.iter().any(|p| (p.x - 2.0).abs() < 0.05 && (p.z + 1.5).abs() < 0.05),
        "the waypoint is flown"
    );
}

/// A mission whose first item is TAKEOFF, started while the vehicle is already in the air
/// (holding 1 m up), first goes straight up or down to the item's altitude where the vehicle is
/// (TAKEOFF reached there), then flies on. Before: the climb was skipped and the first leg flew
/// diagonally to the next waypoint's altitude (the reference never reached the item's 2 m).
#[test]
fn a_takeoff_item_started_in_the_air_goes_to_its_altitude_first() {
    for alt in [2.0, 0.5] {
        let mut g = Sim::new();
        g.airborne();
        g.follow = true;
        let plan = [
            qgc_item(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, alt),
            qgc_item(MavCmd::MAV_CMD_NAV_WAYPOINT, 2.0, 0.0, 1.0),
        ];
        assert_eq!(g.upload_items(&plan), MavMissionResult::MAV_MISSION_ACCEPTED);
        assert_eq!(g.interval(42.0, 50_000.0), MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(g.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
        let (mut refs, mut reached) = (Vec::new(), Vec::new());
        for _ in 0..20_000 {
            for m in g.step(&[]) {
                if let Outbound::MissionItemReached(r) = m {
                    reached.push((r.seq, refs.len()));
                }
            }
            refs.push(g.ap.telemetry().setpoint.position_ned);
            if refs.last().is_some_and(|p| p.x > 1.95) {
                break;
            }
        }
        let at_alt = refs.iter().position(|p| (p.z + alt).abs() < 0.02);
        let Some(at_alt) = at_alt else {
            panic!("{alt} m: the reference never reached the TAKEOFF altitude")
        };
        assert!(
            refs[..=at_alt].iter().all(|p| p.x.abs() < 0.02 && p.y.abs() < 0.02),
            "{alt} m: straight up/down"
        );
        assert!(refs.last().is_some_and(|p| p.x > 1.95), "{alt} m: then the path is flown");
        let takeoff_reached = reached.iter().find(|r| r.0 == 0).map(|r| r.1);
        assert!(
            takeoff_reached.is_some_and(|k| k >= at_alt),
            "{alt} m: TAKEOFF reached at its altitude: {reached:?}"
        );
    }
}

/// QGroundControl's default plan takes off to 50 m: the takeoff limit is now 120 m, so the plan
/// is accepted and MISSION_START on the ground starts the climb. Above the limit (the parameter
/// `MIS_TKO_ALT_MAX`) the upload is refused INVALID_PARAM7; a limit lowered under a stored plan
/// makes MISSION_START DENIED, and a NAV_TAKEOFF command above it is DENIED, each with a
/// STATUSTEXT saying why. Before: the limit was a fixed 10 m, QGroundControl's plan got
/// MISSION_START DENIED, without a reason; then a fixed 120 m, a higher plan was accepted and
/// only its start refused.
#[test]
fn qgroundcontrols_50_m_takeoff_flies_and_higher_is_refused_with_a_reason() {
    use parapet_firmware::link::takeoff_limit::TOO_HIGH_TEXT;
    let plan = |alt: f32| {
        [
            qgc_item(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, alt),
            qgc_item(MavCmd::MAV_CMD_NAV_WAYPOINT, 2.0, 0.0, alt),
            qgc_item(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, 0.0, 0.0, 0.0),
        ]
    };
    let texts = |out: &[Outbound]| {
        count(out, |m| matches!(m, Outbound::StatusText(t) if t.text.to_str().ok() == Some(TOO_HIGH_TEXT)))
    };
    let arm = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut g = Sim::new();
    assert_eq!(g.upload_items(&plan(50.0)), MavMissionResult::MAV_MISSION_ACCEPTED);
    g.run(500);
    assert_eq!(g.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, arm), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.command(MavCmd::MAV_CMD_MISSION_START, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
    g.run(2000);
    let s = g.ap.telemetry();
    assert_eq!(s.phase, FlightPhase::Takeoff, "climbing to 50 m");
    assert!(s.setpoint.position_ned.z < -0.5, "{:?}", s.setpoint.position_ned);
    // Above the limit: the upload is refused.
    let mut g = Sim::new();
    assert_eq!(g.upload_items(&plan(150.0)), MavMissionResult::MAV_MISSION_INVALID_PARAM7);
    // The 50 m plan, then the limit set to 40 m by PARAM_SET: its start is refused, with the reason.
    assert_eq!(g.upload_items(&plan(50.0)), MavMissionResult::MAV_MISSION_ACCEPTED);
    let limit = PARAM_SET_DATA {
        param_value: 40.0,
        target_system: 1,
        target_component: 1,
        param_id: parapet_firmware::link::outbound::name("MIS_TKO_ALT_MAX"),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    };
    g.send(&limit);
    assert_eq!(g.ap.get_param("MIS_TKO_ALT_MAX"), Some(40.0));
    assert_eq!(g.upload_items(&plan(45.0)), MavMissionResult::MAV_MISSION_INVALID_PARAM7, "40 m now");
    g.run(500);
    assert_eq!(g.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, arm), MavResult::MAV_RESULT_ACCEPTED);
    let start = COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_MISSION_START as u16,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let denied = |out: &[Outbound]| {
        out.iter().any(|m| matches!(m, Outbound::CommandAck(a) if a.result == MavResult::MAV_RESULT_DENIED))
    };
    let out = g.send(&start);
    assert!(denied(&out) && texts(&out) == 1, "MISSION_START: {out:?}");
    let takeoff = COMMAND_LONG_DATA { param7: 41.0, command: MavCmd::MAV_CMD_NAV_TAKEOFF as u16, ..start };
    let out = g.send(&takeoff);
    assert!(denied(&out) && texts(&out) == 1, "NAV_TAKEOFF: {out:?}");
    let ok = COMMAND_LONG_DATA { param7: 39.0, ..takeoff };
    let out = g.send(&ok);
    assert!(!denied(&out) && texts(&out) == 0, "39 m is within the limit: {out:?}");
}

/// TAKEOFF then LAND at a position: the vehicle climbs, flies to the landing point at the
/// takeoff altitude, lands and disarms; MISSION_ITEM_REACHED 0 then 1 (at the landing). Before:
/// both items were refused MAV_MISSION_UNSUPPORTED.
#[test]
fn land_item_flies_to_its_position_and_lands() {
    let mut g = Sim::new();
    let plan = [
        qgc_item(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 1.0),
        qgc_item(MavCmd::MAV_CMD_NAV_LAND, -1.5, 1.0, 0.0),
    ];
    assert_eq!(g.upload_items(&plan), MavMissionResult::MAV_MISSION_ACCEPTED);
    let f = fly_from_ground(&mut g, 40_000);
    assert!(!f.armed, "landed and disarmed ({:?})", g.ap.telemetry().phase);
    assert_eq!(f.reached, vec![0, 1]);
    assert!(f.complete);
    let at = f.refs.iter().position(|p| (p.x + 1.5).abs() < 0.05 && (p.y - 1.0).abs() < 0.05);
    let at = at.expect("the reference reaches the landing point");
    assert!((f.refs[at].z + 1.0).abs() < 0.1, "at the takeoff altitude: {:?}", f.refs[at]);
    // (The landing itself descends from the position estimate, which this harness pins at the
    // origin; the PIL client test lands where the vehicle is.)
}

/// TAKEOFF then LAND "here" (no path at all): climbs, lands where it took off, disarms.
#[test]
fn takeoff_then_land_here_needs_no_path() {
    let mut g = Sim::new();
    let plan = [
        qgc_item(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 1.0),
        qgc_item(MavCmd::MAV_CMD_NAV_LAND, 0.0, 0.0, 0.0),
    ];
    assert_eq!(g.upload_items(&plan), MavMissionResult::MAV_MISSION_ACCEPTED);
    let f = fly_from_ground(&mut g, 30_000);
    assert!(!f.armed, "landed and disarmed ({:?})", g.ap.telemetry().phase);
    assert_eq!(f.reached, vec![0, 1]);
    let top = f.refs.iter().map(|p| -p.z).fold(f32::MIN, f32::max);
    assert!((top - 1.0).abs() < 0.1, "climbed to 1 m: {top}");
}

/// Issue 41: the items of a QGroundControl plan besides takeoff, waypoints and the end are
/// flown as PX4 flies them — a waypoint's hold time after its acceptance radius, LOITER_TIME at
/// its position, NAV_DELAY where the vehicle is, DO_CHANGE_SPEED for the following legs,
/// CONDITION_YAW (the heading reference turns, the mission waits for it), then RTL. Before:
/// LOITER_TIME, NAV_DELAY and CONDITION_YAW were refused UNSUPPORTED, the hold time and the
/// speed change were stored and ignored.
#[test]
fn holds_loiter_delay_speed_and_yaw_items_are_flown() {
    let mut g = Sim::new();
    g.follow = true;
    let with = |mut it: MISSION_ITEM_INT_DATA, p: [f32; 4]| {
        [it.param1, it.param2, it.param3, it.param4] = p;
        it
    };
    let plan = [
        qgc_item(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, 1.0),
        with(qgc_item(MavCmd::MAV_CMD_NAV_WAYPOINT, 1.0, 0.0, 1.0), [2.0, 0.2, 0.0, f32::NAN]),
        with(qgc_item(MavCmd::MAV_CMD_NAV_LOITER_TIME, 1.0, 1.0, 1.0), [1.5, 0.0, 0.0, f32::NAN]),
        with(qgc_item(MavCmd::MAV_CMD_NAV_DELAY, 0.0, 0.0, 0.0), [1.0, -1.0, -1.0, -1.0]),
        with(qgc_item(MavCmd::MAV_CMD_DO_CHANGE_SPEED, 0.0, 0.0, 0.0), [1.0, 0.5, -1.0, 0.0]),
        with(qgc_item(MavCmd::MAV_CMD_CONDITION_YAW, 0.0, 0.0, 0.0), [90.0, 30.0, 1.0, 0.0]),
        qgc_item(MavCmd::MAV_CMD_NAV_WAYPOINT, 3.0, 1.0, 1.0),
        qgc_item(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, 0.0, 0.0, 0.0),
    ];
    assert_eq!(g.upload_items(&plan), MavMissionResult::MAV_MISSION_ACCEPTED);
    let down = g.download();
    let key = |i: &MISSION_ITEM_INT_DATA| (i.command, i.x, i.y, i.param1.to_bits(), i.param2.to_bits());
    assert_eq!(down.iter().map(key).collect::<Vec<_>>(), plan.iter().map(key).collect::<Vec<_>>());
    let f = fly_from_ground(&mut g, 120_000);
    assert!(!f.armed, "landed and disarmed ({:?})", g.ap.telemetry().phase);
    assert_eq!(f.reached, (0..8).collect::<Vec<u16>>(), "MISSION_ITEM_REACHED in the uploaded seqs");
    assert!(f.complete, "COMPLETE at the end");
    // The reference stays at each held point (1 ms per step).
    let near =
        |n: f32, e: f32| f.refs.iter().filter(|p| (p.x - n).abs() < 0.01 && (p.y - e).abs() < 0.01).count();
    let (at_wp, at_loiter) = (near(1.0, 0.0), near(1.0, 1.0));
    println!("held {at_wp} ms at the waypoint, {at_loiter} ms at the loiter point");
    assert!((2000..2600).contains(&at_wp), "waypoint hold 2 s: {at_wp} ms");
    // Loiter 1.5 s, delay 1 s, then the turn of 90° (the heading estimate follows the fixes'
    // in ~2 s here).
    assert!((2500..6000).contains(&at_loiter), "loiter 1.5 s + delay 1 s + the turn: {at_loiter} ms");
    // The last leg (1, 1) → (3, 1), 2 m at 0.5 m/s (WP_SPEED 0.25 before): 4 s.
    let end = f.refs.iter().position(|p| p.x > 2.99).expect("the last waypoint is flown");
    let leg = f.refs[..end].iter().filter(|p| p.x > 1.01 && (p.y - 1.0).abs() < 0.01).count();
    assert!((3700..4300).contains(&leg), "2 m at the changed 0.5 m/s: {leg} ms");
    assert!(f.modes.contains(&parapet_firmware::app::autopilot::FlightMode::Return), "{:?}", f.modes);
    let yaw = f.yaws.iter().map(|y| y.to_degrees()).fold(f32::MIN, f32::max);
    assert!((yaw - 90.0).abs() < 1.0, "CONDITION_YAW 90°: the heading reference reached {yaw}°");
}

/// Issue 41: MAV_CMD_DO_REPOSITION (QGroundControl's "Go to location", MAVSDK's
/// `goto_location`) flies to the global position (COMMAND_INT exact, altitude in the command's
/// frame; COMMAND_LONG in degrees and m AMSL) and holds there; refused on the ground. Before:
/// UNSUPPORTED.
#[test]
fn do_reposition_flies_to_the_global_position_and_holds() {
    let mut g = Sim::new();
    g.run(500);
    let int = |x: i32, y: i32, z: f32| {
        #[allow(deprecated)] // the *_INT frame, as MAVSDK sends it
        let frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
        COMMAND_INT_DATA {
            param1: -1.0,
            param4: f32::NAN,
            x,
            y,
            z,
            command: MavCmd::MAV_CMD_DO_REPOSITION as u16,
            target_system: 1,
            target_component: 1,
            frame,
            ..Default::default()
        }
    };
    let ack = |out: Vec<Outbound>| {
        out.iter().find_map(|m| match m {
            Outbound::CommandAck(a) if a.command == MavCmd::MAV_CMD_DO_REPOSITION as u16 => Some(a.result),
            _ => None,
        })
    };
    let goal = int(ORIGIN.0 + 90, ORIGIN.1 + 133, 2.0); // ≈ 1 m north, 1 m east, 2 m up
    assert_eq!(ack(g.send(&goal)), Some(MavResult::MAV_RESULT_TEMPORARILY_REJECTED), "on the ground");
    g.follow = true;
    g.airborne();
    assert_eq!(ack(g.send(&goal)), Some(MavResult::MAV_RESULT_ACCEPTED));
    g.run(15_000);
    let r = g.ap.telemetry().setpoint.position_ned;
    assert!((r.x - 1.0).abs() < 0.02 && (r.y - 1.0).abs() < 0.02 && (r.z + 2.0).abs() < 0.01, "{r:?}");
    g.run(2_000);
    assert_eq!(g.ap.telemetry().setpoint.position_ned, r, "held there");
    // COMMAND_LONG: degrees, m AMSL; NaN altitude keeps the current one.
    let deg = |e7: i32| e7 as f32 * 1e-7;
    let p = [-1.0, 0.0, 0.0, f32::NAN, deg(ORIGIN.0), deg(ORIGIN.1), f32::NAN];
    assert_eq!(g.command(MavCmd::MAV_CMD_DO_REPOSITION, p), MavResult::MAV_RESULT_ACCEPTED);
    g.run(15_000);
    let r = g.ap.telemetry().setpoint.position_ned;
    assert!(r.x.abs() < 0.3 && r.y.abs() < 0.3 && (r.z + 2.0).abs() < 0.01, "back above the origin: {r:?}");
    let far = int(ORIGIN.0 + 20_000_000, ORIGIN.1, 2.0);
    assert_eq!(ack(g.send(&far)), Some(MavResult::MAV_RESULT_DENIED), "beyond the local frame");
}

/// Issue 41: PARAM_SET in flight, as PX4 allows in-flight tuning. While armed and flying, an
/// in-flight tunable (TRK_KP, WP_SPEED, …: `parapet_core::params::IN_FLIGHT`) is taken and
/// echoed, the flight goes on (still hovering, the reference where it was: no rebuilt
/// controller); a set-up parameter (VEH_MASS) is refused — PARAM_VALUE with the old value and
/// a STATUSTEXT naming it. Before: every PARAM_SET was refused while armed, silently.
#[test]
fn param_set_in_flight_takes_the_tunables_and_refuses_set_up_with_a_reason() {
    let mut g = Sim::new();
    g.follow = true;
    g.airborne();
    g.run(3000);
    let before = g.ap.telemetry();
    assert_eq!(before.phase, FlightPhase::Hover);
    let set = |name: &str, v: f32| PARAM_SET_DATA {
        param_value: v,
        target_system: 1,
        target_component: 1,
        param_id: parapet_firmware::link::outbound::name(name),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    };
    let echo = |out: &[Outbound]| {
        out.iter().find_map(|m| match m {
            Outbound::ParamValue(p) => Some(p.param_value),
            _ => None,
        })
    };
    let text = |out: &[Outbound]| {
        out.iter().find_map(|m| match m {
            Outbound::StatusText(t) => {
                Some(String::from_utf8_lossy(&t.text.to_vec()).trim_end_matches('\0').to_string())
            }
            _ => None,
        })
    };
    let out = g.send(&set("TRK_KP", 0.8));
    assert_eq!(echo(&out), Some(0.8), "{out:?}");
    assert_eq!(text(&out), None);
    assert_eq!(g.ap.flown_params().tracking.kp, [0.8; 3], "flown at once");
    let out = g.send(&set("WP_SPEED", 0.5));
    assert_eq!(echo(&out), Some(0.5));
    g.run(100);
    let after = g.ap.telemetry();
    assert!(after.armed && after.phase == FlightPhase::Hover, "the flight goes on: {:?}", after.phase);
    assert_eq!(after.setpoint.position_ned, before.setpoint.position_ned, "the hold point is kept");
    // Set-up: refused with the value in effect and the reason.
    let out = g.send(&set("VEH_MASS", 0.7));
    assert_eq!(echo(&out), Some(ControllerParams::default().airframe.mass));
    assert_eq!(text(&out).as_deref(), Some("Set-up, disarm to change: VEH_MASS"));
    assert_eq!(g.ap.get_param("VEH_MASS"), Some(ControllerParams::default().airframe.mass));
}

/// The standard modes protocol (issue 41; QGroundControl 4.4+ and MAVSDK list modes from it):
/// AVAILABLE_MODES on request (all after the ACK, one by index, a bad index DENIED),
/// CURRENT_MODE and AVAILABLE_MODES_MONITOR with each HEARTBEAT and CURRENT_MODE at a mode
/// change, MAV_CMD_DO_SET_STANDARD_MODE switching the mode.
#[test]
fn standard_modes_are_listed_reported_and_set() {
    use parapet_firmware::app::autopilot::FlightMode;
    use parapet_firmware::link::dialect::MavStandardMode;
    let mut g = Sim::new();
    let out = g.run(2500);
    let beats = count(&out, |m| matches!(m, Outbound::Heartbeat(_)));
    assert!(beats >= 2, "{beats}");
    assert_eq!(count(&out, |m| matches!(m, Outbound::CurrentMode(_))), beats);
    assert_eq!(count(&out, |m| matches!(m, Outbound::AvailableModesMonitor)), beats);
    let request = |index: f32| COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_REQUEST_MESSAGE as u16,
        param1: 435.0,
        param2: index,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let listed = |out: &[Outbound]| -> Vec<u8> {
        out.iter()
            .filter_map(|m| match m {
                Outbound::AvailableMode(i) => Some(*i),
                _ => None,
            })
            .collect()
    };
    let ack = |out: &[Outbound]| {
        out.iter().position(
            |m| matches!(m, Outbound::CommandAck(a) if a.command == MavCmd::MAV_CMD_REQUEST_MESSAGE as u16),
        )
    };
    let mut out = g.send(&request(0.0));
    out.extend(g.run(20));
    assert_eq!(listed(&out), (1..=FlightMode::COUNT as u8).collect::<Vec<_>>());
    let first = out.iter().position(|m| matches!(m, Outbound::AvailableMode(_)));
    assert!(ack(&out) < first, "the ACK first: {out:?}");
    let mut out = g.send(&request(4.0));
    out.extend(g.run(5));
    assert_eq!(listed(&out), vec![4]);
    let mut out = g.send(&request(99.0));
    out.extend(g.run(5));
    assert!(listed(&out).is_empty());
    assert!(out
        .iter()
        .any(|m| matches!(m, Outbound::CommandAck(a) if a.result == MavResult::MAV_RESULT_DENIED)));

    // DO_SET_STANDARD_MODE: LAND (7) lands; a standard mode not flown (ORBIT 2) and
    // NON_STANDARD are DENIED.
    g.airborne();
    let set = |n: f32| [n, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_eq!(g.command(MavCmd::MAV_CMD_DO_SET_STANDARD_MODE, set(2.0)), MavResult::MAV_RESULT_DENIED);
    assert_eq!(g.command(MavCmd::MAV_CMD_DO_SET_STANDARD_MODE, set(0.0)), MavResult::MAV_RESULT_DENIED);
    let before = g.ap.telemetry().mode;
    g.run(2);
    assert_eq!(g.ap.telemetry().mode, before, "unchanged");
    let mut out = g.send(&COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_DO_SET_STANDARD_MODE as u16,
        param1: 7.0,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    });
    out.extend(g.run(5));
    assert!(out
        .iter()
        .any(|m| matches!(m, Outbound::CommandAck(a) if a.result == MavResult::MAV_RESULT_ACCEPTED)));
    let current = out.iter().find_map(|m| match m {
        Outbound::CurrentMode(c) => Some(c.clone()),
        _ => None,
    });
    let Some(c) = current else { panic!("no CURRENT_MODE at the mode change: {out:?}") };
    assert_eq!(c.standard_mode, MavStandardMode::MAV_STANDARD_MODE_LAND);
    assert_eq!(
        (c.custom_mode, c.intended_custom_mode),
        (FlightMode::Land.px4_custom_mode(), FlightMode::Land.px4_custom_mode())
    );
    assert_eq!(g.ap.telemetry().mode, FlightMode::Land);
}
