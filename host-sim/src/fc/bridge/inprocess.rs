//! `parapet run --gcs`: the in-process controller behind the same UDP bridge as the PIL
//! ([`super::Bridge`]), so a ground station watches a `parapet run` flight as a PIL one.
//!
//! [`GcsStack`] wraps any [`FlightStack`] and speaks MAVLink v2 as system 1, component 1
//! (the firmware's ids) with what the runner gives a stack:
//!
//! * sent: HEARTBEAT (1 Hz; quadrotor, `custom_mode` = the selected flight mode in PX4's
//!   encoding as the firmware sends it (`FlightMode::px4_custom_mode`), `MAV_MODE_FLAG_CUSTOM_MODE_ENABLED`, `SAFETY_ARMED` +
//!   `AUTO_ENABLED` while armed), LOCAL_POSITION_NED (25 Hz, the latest position fix) and
//!   POSITION_TARGET_LOCAL_NED (25 Hz: the reference position, the filtered acceleration `u`
//!   in `afx..afz`), STATUSTEXT on each failsafe-state change and on each event of the
//!   on-board replanner (issue 38: `Replan: new path, N wp (D detour)` INFO, `Replan: no path,
//!   holding` / `Replan: budget exceeded, holding` WARNING);
//! * served: PARAM_REQUEST_LIST / PARAM_REQUEST_READ (the run's parameters, table order, all
//!   REAL32); PARAM_SET is refused the protocol's way (the PARAM_VALUE in effect is echoed:
//!   the run's parameters are fixed); MISSION_REQUEST_LIST / MISSION_REQUEST_INT (the path
//!   the wrapped stack flies now as MISSION_ITEM_INT — after an on-board replan the new path,
//!   issue 38 — x/y in the wire's 10⁻⁴ m, LOCAL_NED; `mission_type` is not looked at: every
//!   type gets the mission); COMMAND_LONG / COMMAND_INT → COMMAND_ACK `MAV_RESULT_UNSUPPORTED`
//!   (the host flies the mission, as in `parapet pil`);
//! * MISSION_CURRENT (1 Hz, as the firmware; at once when the path changed): `seq` the
//!   waypoint being flown to, `total` the path's waypoints, `mission_id` the path's plan id
//!   ([`plan_id`], also MISSION_COUNT's `opaque_id`), which changes with every replan, so a
//!   ground station sees that the mission changed and downloads it again.
//!
//! Not sent: ATTITUDE (the stack interface carries no attitude estimate), the firmware's
//! DEBUG_VECT diagnostics. The flight is the wrapped stack's, unchanged.
//!
//! May import: mavlink, `parapet-core` (params, wire ids), [`crate::flight::stack`],
//! [`crate::sim::sensors`], [`super`].
//!
//! MAVLink message literals end in `..Default::default()`: whether the generated `mavlink`
//! structs carry the MAVLink 2 extension fields depends on which crates share the build (the
//! firmware's `mavlink-bindgen` build-dependency turns them on, e.g. in the fuzz workspace),
//! and the code must compile both ways (hence the `needless_update` allowance).
#![allow(clippy::needless_update)]

use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavCmd, MavFrame, MavMessage, MavMissionResult, MavModeFlag, MavParamType, MavResult,
    MavSeverity, MavState, MavType, PositionTargetTypemask, COMMAND_ACK_DATA, HEARTBEAT_DATA,
    LOCAL_POSITION_NED_DATA, MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_CURRENT_DATA,
    MISSION_ITEM_INT_DATA, PARAM_VALUE_DATA, POSITION_TARGET_LOCAL_NED_DATA, STATUSTEXT_DATA,
};
use mavlink::{MavHeader, MavlinkReader, MavlinkVersion};
use nalgebra::Vector3;
use parapet_core::controller::ControllerParams;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::params::TABLE;
use parapet_core::wire::ids::{
    local_xy_to_wire, plan_id_finish, plan_id_item, AUTOPILOT_COMPONENT_ID, PLAN_ID_START, VEHICLE_SYSTEM_ID,
};
use parapet_core::wire::streams::{spec_of, Stream};

use super::{Bridge, LinkTap};
use crate::flight::stack::{clock_us, FlightStack, OuterOut};
use crate::sim::sensors::{ImuReading, PositionReading};
use parapet_core::controller::FlightMode;

/// Telemetry period of LOCAL_POSITION_NED / POSITION_TARGET_LOCAL_NED, µs (25 Hz): the
/// firmware's, from the stream registry.
pub const TELEMETRY_PERIOD_US: u64 = spec_of(Stream::Position).default_us as u64;
/// HEARTBEAT period, µs (the registry's).
pub const HEARTBEAT_PERIOD_US: u64 = spec_of(Stream::Heartbeat).default_us as u64;
// The bridge sends the setpoint with the position, at one period.
const _: () = assert!(spec_of(Stream::Target).default_us == spec_of(Stream::Position).default_us);

/// A flight stack with a ground-station link (see the module docs).
pub struct GcsStack<S: FlightStack> {
    inner: S,
    bridge: Bridge,
    params: ControllerParams,
    path: Vec<Vector3<f64>>,
    seq: u8,
    next_telemetry_us: u64,
    next_heartbeat_us: u64,
    fix: Option<PositionReading>,
    out: Option<OuterOut>,
    state: String,
    /// Replanner events already sent as STATUSTEXT.
    replan_sent: usize,
    /// The plan id of `path` (MISSION_CURRENT `mission_id`, MISSION_COUNT `opaque_id`).
    mission_id: u32,
    /// The waypoint being flown to (MISSION_CURRENT `seq`).
    mission_seq: u16,
    next_mission_current_us: u64,
}

impl<S: FlightStack> GcsStack<S> {
    /// `inner` behind `bridge`; `params` and `path` (NED) are what it flies.
    pub fn new(inner: S, bridge: Bridge, params: ControllerParams, path: Vec<Vector3<f64>>) -> Self {
        GcsStack {
            inner,
            bridge,
            params,
            seq: 0,
            next_telemetry_us: 0,
            next_heartbeat_us: 0,
            fix: None,
            out: None,
            state: String::new(),
            replan_sent: 0,
            mission_id: plan_id(&path),
            mission_seq: 0,
            next_mission_current_us: 0,
            path,
        }
    }

    /// The bridge (counters).
    pub fn bridge(&self) -> &Bridge {
        &self.bridge
    }

    fn send(&mut self, m: &MavMessage) {
        let h = MavHeader {
            system_id: VEHICLE_SYSTEM_ID.into(),
            component_id: AUTOPILOT_COMPONENT_ID,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        self.bridge.firmware_frame(&h, m, mavlink::MavlinkVersion::V2);
    }

    fn param_value(&mut self, index: usize) {
        let Some(d) = TABLE.get(index) else { return };
        let mut id = [0u8; 16];
        id.iter_mut().zip(d.name.bytes()).for_each(|(b, c)| *b = c);
        self.send(&MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: (d.get)(&self.params),
            param_count: TABLE.len() as u16,
            param_index: index as u16,
            param_id: id.into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        }));
    }

    fn for_us(&self, target_system: u8, target_component: u8) -> bool {
        (target_system == 0 || target_system == VEHICLE_SYSTEM_ID)
            && (target_component == 0 || target_component == AUTOPILOT_COMPONENT_ID)
    }

    fn handle(&mut self, h: &MavHeader, m: &MavMessage) {
        let index_of = |id: &[u8]| {
            let name = std::str::from_utf8(id).unwrap_or("").trim_end_matches('\0');
            TABLE.iter().position(|d| d.name == name)
        };
        match m {
            MavMessage::PARAM_REQUEST_LIST(r) if self.for_us(r.target_system, r.target_component) => {
                (0..TABLE.len()).for_each(|i| self.param_value(i));
            }
            MavMessage::PARAM_REQUEST_READ(r) if self.for_us(r.target_system, r.target_component) => {
                let i =
                    if r.param_index >= 0 { Some(r.param_index as usize) } else { index_of(&r.param_id[..]) };
                if let Some(i) = i {
                    self.param_value(i);
                }
            }
            MavMessage::PARAM_SET(r) if self.for_us(r.target_system, r.target_component) => {
                if let Some(i) = index_of(&r.param_id[..]) {
                    self.param_value(i); // fixed for the run: the value in effect
                }
            }
            MavMessage::MISSION_REQUEST_LIST(r) if self.for_us(r.target_system, r.target_component) => {
                self.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                    count: self.path.len() as u16,
                    target_system: h.system_id as u8,
                    target_component: h.component_id,
                    opaque_id: self.mission_id,
                    ..Default::default()
                }));
            }
            MavMessage::MISSION_REQUEST_INT(r) if self.for_us(r.target_system, r.target_component) => {
                match self.path.get(usize::from(r.seq)).copied() {
                    Some(w) => self.send(&MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                        x: local_xy_to_wire(w.x),
                        y: local_xy_to_wire(w.y),
                        z: w.z as f32,
                        seq: r.seq,
                        command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                        frame: MavFrame::MAV_FRAME_LOCAL_NED,
                        target_system: h.system_id as u8,
                        target_component: h.component_id,
                        autocontinue: 1,
                        ..Default::default()
                    })),
                    None => self.mission_ack(h, MavMissionResult::MAV_MISSION_INVALID_SEQUENCE),
                }
            }
            MavMessage::COMMAND_LONG(c) if self.for_us(c.target_system, c.target_component) => {
                self.command_ack(h, c.command)
            }
            MavMessage::COMMAND_INT(c) if self.for_us(c.target_system, c.target_component) => {
                self.command_ack(h, c.command)
            }
            _ => {}
        }
    }

    fn mission_ack(&mut self, h: &MavHeader, result: MavMissionResult) {
        self.send(&MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: h.system_id as u8,
            target_component: h.component_id,
            mavtype: result,
            ..Default::default()
        }));
    }

    fn command_ack(&mut self, _h: &MavHeader, command: MavCmd) {
        // The host's `mavlink` build has no MAVLink 2 extension fields (target_system /
        // target_component of COMMAND_ACK): the ACK is broadcast to every endpoint.
        self.send(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command,
            result: MavResult::MAV_RESULT_UNSUPPORTED,
            ..Default::default()
        }));
    }

    fn status_text(&mut self, severity: MavSeverity, line: &str) {
        let mut text = [0u8; 50];
        text.iter_mut().zip(line.bytes()).for_each(|(b, c)| *b = c);
        self.send(&MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity,
            text: text.into(),
            ..Default::default()
        }));
    }

    /// The wrapped stack's mission now (after a replan: the new path, issue 38). A changed
    /// path gets a new plan id, announced at once with a MISSION_CURRENT (the id a ground
    /// station compares with the one it downloaded, then downloads again).
    fn refresh_mission(&mut self, t_us: u64) {
        let Some((path, seq)) = self.inner.mission() else { return };
        self.mission_seq = seq;
        // Compared as sent (the wire's 10⁻⁴ m): the controller's f32 copy of the uploaded path
        // is the same mission.
        let id = plan_id(&path);
        if id != self.mission_id {
            (self.path, self.mission_id) = (path, id);
            self.next_mission_current_us = t_us;
        }
    }

    fn mission_current(&mut self, t_us: u64) {
        if t_us < self.next_mission_current_us {
            return;
        }
        self.next_mission_current_us = t_us + HEARTBEAT_PERIOD_US;
        self.send(&MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq: self.mission_seq,
            total: self.path.len() as u16,
            mission_id: self.mission_id,
            ..Default::default()
        }));
    }

    /// A STATUSTEXT for each replanner event not sent yet.
    fn replan_texts(&mut self) {
        let events = self.inner.replan_summary().replan_events;
        for e in events.iter().skip(self.replan_sent) {
            let (severity, line) = match e.outcome {
                "replanned" => (
                    MavSeverity::MAV_SEVERITY_INFO,
                    format!("Replan: new path, {} wp ({} detour)", e.waypoints, e.detour),
                ),
                "no_path" => (MavSeverity::MAV_SEVERITY_WARNING, "Replan: no path, holding".to_owned()),
                other => (MavSeverity::MAV_SEVERITY_WARNING, format!("Replan: {other}, holding")),
            };
            self.status_text(severity, &line);
        }
        self.replan_sent = self.replan_sent.max(events.len());
    }

    fn telemetry(&mut self, t_us: u64) {
        let state = self.inner.state_name();
        if state != self.state {
            self.status_text(MavSeverity::MAV_SEVERITY_INFO, &format!("state {state}"));
            self.state = state;
        }
        let time_boot_ms = (t_us / 1000) as u32;
        if t_us >= self.next_heartbeat_us {
            self.next_heartbeat_us = t_us + HEARTBEAT_PERIOD_US;
            let armed = self.out.as_ref().is_some_and(|o| o.mode.motors_on());
            let mode = self.out.as_ref().map_or(FlightMode::default(), |o| o.flight_mode);
            let mut base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
            if armed {
                base |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED | MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED;
            }
            self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: mode.px4_custom_mode(),
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
                base_mode: base,
                system_status: if armed { MavState::MAV_STATE_ACTIVE } else { MavState::MAV_STATE_STANDBY },
                mavlink_version: 3,
            }));
        }
        if t_us >= self.next_telemetry_us {
            self.next_telemetry_us = t_us + TELEMETRY_PERIOD_US;
            if let Some(f) = self.fix {
                self.send(&MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                    time_boot_ms,
                    x: f.position.x as f32,
                    y: f.position.y as f32,
                    z: f.position.z as f32,
                    vx: f.velocity.x as f32,
                    vy: f.velocity.y as f32,
                    vz: f.velocity.z as f32,
                }));
            }
            if let Some(o) = self.out.clone() {
                self.send(&MavMessage::POSITION_TARGET_LOCAL_NED(POSITION_TARGET_LOCAL_NED_DATA {
                    time_boot_ms,
                    x: o.reference.x as f32,
                    y: o.reference.y as f32,
                    z: o.reference.z as f32,
                    afx: o.u_filtered.x as f32,
                    afy: o.u_filtered.y as f32,
                    afz: o.u_filtered.z as f32,
                    coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
                    type_mask: PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VX_IGNORE
                        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VY_IGNORE
                        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VZ_IGNORE
                        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_IGNORE
                        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE,
                    ..Default::default()
                }));
            }
        }
    }
}

/// The plan id of a path of waypoints as MISSION_ITEM_INT carries them
/// ([`parapet_core::wire::ids::PLAN_ID_START`]; the firmware folds its stored items the same way).
/// 0 for no path ("no mission").
pub fn plan_id(path: &[Vector3<f64>]) -> u32 {
    if path.is_empty() {
        return 0;
    }
    let waypoint = MavCmd::MAV_CMD_NAV_WAYPOINT as u16;
    plan_id_finish(path.iter().fold(PLAN_ID_START, |a, w| {
        plan_id_item(a, waypoint, local_xy_to_wire(w.x), local_xy_to_wire(w.y), w.z as f32)
    }))
}

/// The MAVLink v2 messages in `bytes` (datagrams from the endpoints); bytes that are no
/// valid frame are skipped by the reader.
pub fn decode_all(bytes: &[u8]) -> Vec<(MavHeader, MavMessage)> {
    let mut r = MavlinkReader::new(bytes);
    let mut out = Vec::new();
    loop {
        match r.read_message::<MavMessage>(MavlinkVersion::V2) {
            Ok(m) => out.push(m),
            Err(mavlink::error::MessageReadError::Io(_)) => break,
            Err(_) => {}
        }
    }
    out
}

impl<S: FlightStack> FlightStack for GcsStack<S> {
    fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> anyhow::Result<()> {
        self.fix = Some(s.fix);
        self.inner.start(s)
    }

    fn position_fix(&mut self, fix: PositionReading) {
        self.fix = Some(fix);
        self.inner.position_fix(fix);
    }

    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        let out = self.inner.outer(t, obstacles);
        self.out = Some(out.clone());
        self.replan_texts();
        self.refresh_mission(clock_us(t));
        out
    }

    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        let t_us = clock_us(t);
        let incoming = self.bridge.before_step(t_us);
        // A changed plan's id goes out before any item of it is served.
        self.mission_current(t_us);
        for (h, m) in decode_all(&incoming) {
            self.handle(&h, &m);
        }
        self.telemetry(t_us);
        self.inner.inner(t, imu)
    }

    fn state_name(&self) -> String {
        self.inner.state_name()
    }

    fn replan_summary(&self) -> crate::report::ReplanSummary {
        self.inner.replan_summary()
    }

    fn replans(&self) -> u32 {
        self.inner.replans()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fc::bridge::{frame, Endpoint};
    use mavlink::dialects::ardupilotmega::{COMMAND_LONG_DATA, PARAM_REQUEST_LIST_DATA};
    use std::net::UdpSocket;
    use std::time::Duration;

    struct Hover;
    impl FlightStack for Hover {
        fn start(&mut self, _: &crate::flight::stack::StackStart<'_>) -> anyhow::Result<()> {
            Ok(())
        }
        fn position_fix(&mut self, _: PositionReading) {}
        fn outer(&mut self, _: f64, _: &[ObstaclePoint]) -> OuterOut {
            OuterOut {
                reference: Vector3::zeros(),
                filter: parapet_core::cbf::FilterDiagnostics::new(parapet_core::cbf::Region::NoObstacle),
                path_done: false,
                u_nominal: Vector3::zeros(),
                u_filtered: Vector3::zeros(),
                mode: parapet_core::controller::GuidanceMode::Hold,
                flight_mode: FlightMode::Mission,
                safety: Default::default(),
            }
        }
        fn inner(&mut self, _: f64, _: &ImuReading) -> [f32; 4] {
            [0.5; 4]
        }
        fn state_name(&self) -> String {
            "Armed".into()
        }
    }

    /// [`Hover`] that reports one replan and one no-path result of its replanner.
    struct Replanning;
    impl FlightStack for Replanning {
        fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> anyhow::Result<()> {
            Hover.start(s)
        }
        fn position_fix(&mut self, _: PositionReading) {}
        fn outer(&mut self, t: f64, o: &[ObstaclePoint]) -> OuterOut {
            Hover.outer(t, o)
        }
        fn inner(&mut self, t: f64, i: &ImuReading) -> [f32; 4] {
            Hover.inner(t, i)
        }
        fn state_name(&self) -> String {
            Hover.state_name()
        }
        fn replan_summary(&self) -> crate::report::ReplanSummary {
            use crate::report::{ReplanEvent, ReplanSummary};
            let replanned = ReplanEvent { t_s: 1.0, outcome: "replanned", waypoints: 7, detour: 2 };
            let no_path = ReplanEvent { t_s: 2.0, outcome: "no_path", waypoints: 0, detour: 0 };
            ReplanSummary {
                replan_enabled: true,
                replans: 1,
                replan_events: vec![replanned, no_path],
                ..Default::default()
            }
        }
    }

    /// `stack` flying `path` behind a bridge to a local GCS socket: the socket, the bridge's
    /// port, the stack.
    fn behind_a_gcs<S: FlightStack>(stack: S, path: Vec<Vector3<f64>>) -> (UdpSocket, u16, GcsStack<S>) {
        let gcs = UdpSocket::bind("127.0.0.1:0").expect("gcs");
        gcs.set_read_timeout(Some(Duration::from_millis(200))).expect("timeout");
        let ep = Endpoint::new("gcs", gcs.local_addr().expect("addr")).expect("endpoint");
        let port = ep.local().expect("local").port();
        (
            gcs,
            port,
            GcsStack::new(stack, Bridge::new(vec![ep], false, None), ControllerParams::default(), path),
        )
    }

    /// Each replanner event reaches the ground station once as a STATUSTEXT (issue 38), and
    /// the wrapped stack's replanning record is the run's.
    #[test]
    fn replan_events_are_sent_as_statustext_once() {
        let (gcs, port, mut s) = behind_a_gcs(Replanning, vec![]);
        // The endpoint learns its peer from a first datagram.
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        gcs.send_to(
            &frame(MavHeader { system_id: 250, component_id: 190, sequence: 0 }, &hb),
            ("127.0.0.1", port),
        )
        .expect("send");
        std::thread::sleep(Duration::from_millis(50));
        let imu = ImuReading { gyro: Vector3::zeros(), accel: Vector3::zeros() };
        for k in 0..3 {
            s.inner(k as f64 * 0.001, &imu);
            s.outer(k as f64 * 0.001, &[]);
        }
        let mut texts = Vec::new();
        let mut buf = [0u8; 600];
        while let Ok((n, _)) = gcs.recv_from(&mut buf) {
            for (_, m) in decode_all(&buf[..n]) {
                if let MavMessage::STATUSTEXT(t) = m {
                    let text = String::from_utf8_lossy(&t.text[..]).trim_end_matches('\0').to_owned();
                    if text.starts_with("Replan") {
                        texts.push((t.severity, text));
                    }
                }
            }
        }
        assert_eq!(
            texts,
            vec![
                (MavSeverity::MAV_SEVERITY_INFO, "Replan: new path, 7 wp (2 detour)".to_owned()),
                (MavSeverity::MAV_SEVERITY_WARNING, "Replan: no path, holding".to_owned()),
            ]
        );
        assert_eq!(s.replan_summary().replans, 1);
    }

    /// [`Hover`] whose mission is replanned at 1 s: two waypoints, then three.
    struct Replanned(f64);
    impl FlightStack for Replanned {
        fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> anyhow::Result<()> {
            Hover.start(s)
        }
        fn position_fix(&mut self, _: PositionReading) {}
        fn outer(&mut self, t: f64, o: &[ObstaclePoint]) -> OuterOut {
            self.0 = t;
            Hover.outer(t, o)
        }
        fn inner(&mut self, t: f64, i: &ImuReading) -> [f32; 4] {
            Hover.inner(t, i)
        }
        fn state_name(&self) -> String {
            Hover.state_name()
        }
        fn mission(&self) -> Option<(Vec<Vector3<f64>>, u16)> {
            let (a, b, c) =
                (Vector3::new(1.0, 0.0, -1.0), Vector3::new(1.5, 0.75, -1.0), Vector3::new(3.0, 0.0, -1.0));
            Some(if self.0 < 1.0 { (vec![a, c], 1) } else { (vec![a, b, c], 1) })
        }
    }

    /// Issue 38: the path the stack flies is the downloaded mission; when it changes, a
    /// MISSION_CURRENT with a new `mission_id` goes out at once, and MISSION_COUNT's
    /// `opaque_id` is that id.
    #[test]
    fn a_replanned_mission_gets_a_new_id_and_is_downloaded() {
        let (gcs, port, mut s) = behind_a_gcs(Replanned(0.0), vec![]);
        let imu = ImuReading { gyro: Vector3::zeros(), accel: Vector3::zeros() };
        let h = MavHeader { system_id: 250, component_id: 190, sequence: 0 };
        let list =
            MavMessage::MISSION_REQUEST_LIST(mavlink::dialects::ardupilotmega::MISSION_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
                ..Default::default()
            });
        let item = |seq| {
            MavMessage::MISSION_REQUEST_INT(mavlink::dialects::ardupilotmega::MISSION_REQUEST_INT_DATA {
                seq,
                target_system: 1,
                target_component: 1,
                ..Default::default()
            })
        };
        // At t: send `req`, step, collect what came back.
        let mut at = |t: f64, req: &[MavMessage]| {
            for m in req {
                gcs.send_to(&frame(h, m), ("127.0.0.1", port)).expect("send");
            }
            std::thread::sleep(Duration::from_millis(20));
            s.outer(t, &[]);
            s.inner(t, &imu);
            let mut got = Vec::new();
            let mut buf = [0u8; 2048];
            while let Ok((n, _)) = gcs.recv_from(&mut buf) {
                got.extend(decode_all(&buf[..n]).into_iter().map(|(_, m)| m));
            }
            got
        };
        let ids = |got: &[MavMessage]| {
            got.iter()
                .filter_map(|m| match m {
                    MavMessage::MISSION_CURRENT(c) => Some((c.mission_id, c.total, c.seq)),
                    _ => None,
                })
                .collect::<Vec<_>>()
        };
        let counts = |got: &[MavMessage]| {
            got.iter()
                .filter_map(|m| match m {
                    MavMessage::MISSION_COUNT(c) => Some((c.count, c.opaque_id)),
                    _ => None,
                })
                .collect::<Vec<_>>()
        };
        let before = at(0.0, std::slice::from_ref(&list));
        let id0 = plan_id(&[Vector3::new(1.0, 0.0, -1.0), Vector3::new(3.0, 0.0, -1.0)]);
        assert_eq!(counts(&before), vec![(2, id0)]);
        assert_eq!(ids(&before), vec![(id0, 2, 1)]);
        assert!(ids(&at(0.5, &[])).is_empty(), "MISSION_CURRENT at 1 Hz only while nothing changes");
        let after = at(1.0, &[list, item(1)]);
        let id1 = ids(&after).first().map(|c| c.0).expect("MISSION_CURRENT at the change");
        assert_ne!(id1, id0);
        assert_eq!(ids(&after), vec![(id1, 3, 1)]);
        assert_eq!(counts(&after), vec![(3, id1)]);
        let wp = after.iter().find_map(|m| match m {
            MavMessage::MISSION_ITEM_INT(i) => Some((i.seq, i.x, i.y)),
            _ => None,
        });
        assert_eq!(wp, Some((1, 15_000, 7_500)), "item 1 of the new path");
    }

    /// A GCS gets HEARTBEAT and LOCAL_POSITION_NED, the whole parameter list and a
    /// COMMAND_ACK UNSUPPORTED addressed to it; the wrapped stack's throttles pass unchanged.
    #[test]
    fn serves_heartbeat_params_and_acks() {
        let (gcs, port, mut s) = behind_a_gcs(Hover, vec![Vector3::zeros(); 3]);
        let fix = PositionReading {
            t_measured: 0.0,
            position: Vector3::new(1.0, 2.0, -3.0),
            velocity: Vector3::zeros(),
            yaw: 0.0,
        };
        s.position_fix(fix);
        let h = MavHeader { system_id: 250, component_id: 190, sequence: 0 };
        let req = [
            frame(
                h,
                &MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
                    target_system: 1,
                    target_component: 1,
                }),
            ),
            frame(
                h,
                &MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                    target_system: 1,
                    target_component: 1,
                    command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                    ..Default::default()
                }),
            ),
        ]
        .concat();
        gcs.send_to(&req, ("127.0.0.1", port)).expect("send");
        std::thread::sleep(Duration::from_millis(50));
        let imu = ImuReading { gyro: Vector3::zeros(), accel: Vector3::zeros() };
        // The runner's order: the outer step (armed, holding, Mission selected), then the inner.
        s.outer(0.0, &[]);
        assert_eq!(s.inner(0.0, &imu), [0.5; 4]);
        let mut got = Vec::new();
        let mut buf = [0u8; 600];
        while let Ok((n, _)) = gcs.recv_from(&mut buf) {
            got.extend(decode_all(&buf[..n]).into_iter().map(|(_, m)| m));
        }
        let params = got.iter().filter(|m| matches!(m, MavMessage::PARAM_VALUE(_))).count();
        assert_eq!(params, TABLE.len());
        assert!(got.iter().any(|m| matches!(m, MavMessage::HEARTBEAT(hb)
            if hb.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
                && hb.custom_mode == FlightMode::Mission.px4_custom_mode())));
        assert!(got.iter().any(|m| matches!(m, MavMessage::LOCAL_POSITION_NED(p) if p.z == -3.0)));
        assert!(got.iter().any(|m| matches!(m, MavMessage::COMMAND_ACK(a)
            if a.result == MavResult::MAV_RESULT_UNSUPPORTED && a.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM)));
    }
}
