//! The SITL side of `parapet pil`: bridge the firmware's MAVLink to UDP ground-station
//! endpoints (`--gcs`, `--api`), pace the lockstep to wall time (`--realtime`) and record the
//! raw traffic as a `.tlog` ([`tlog`]).
//!
//! ## Routing (like PX4 SITL's `mavlink` instances and mavlink-router)
//! * Each endpoint is a UDP socket bound on `0.0.0.0:<ephemeral>` that **sends to** its
//!   configured remote (`udp:HOST:PORT`; 14550 for the GCS and 14540 for the API by default,
//!   as PX4 SITL's `-o 14550` / `-o 14540`). When a datagram arrives, the endpoint's remote
//!   becomes that datagram's source (PX4 SITL updates its partner the same way), so a client
//!   that connects from another port (MAVSDK's `udpout`, pymavlink `udpout:`) is answered there.
//! * Firmware → every endpoint, except the host's own lockstep traffic ([`is_lockstep`]:
//!   HIL_ACTUATOR_CONTROLS and the `ins_*` instruction counters), which stays internal. The
//!   forwarded frames are **re-sequenced** per system/component ([`Resequencer`]): the
//!   lockstep frames took ~94 % of the firmware's sequence numbers, and a ground station that
//!   saw only the rest computed 93–94 % packet loss on a loss-free link. Each endpoint thus sees
//!   one gap-free sequence space per component, as from PX4 SITL; the `.tlog` keeps the
//!   firmware's own numbers (it has every frame). MAVLink v1 frames (the firmware's answer to a
//!   v1 ground station) are forwarded as v1.
//! * Endpoint → the firmware (appended to the next step's stream, before its HIL_SENSOR) and
//!   → every other endpoint (the GCS sees the API's traffic and back, as through a router).
//! * The host's own frames to the firmware (HIL_SENSOR, ODOMETRY, obstacle batches, the raw
//!   battery readings as BATTERY_STATUS from the host's id, its start-up commands) are not sent
//!   to the endpoints; they are in the `.tlog`.
//!
//! Bounds: at most [`MAX_DATAGRAMS_PER_STEP`] datagrams per endpoint are taken per 1 ms
//! step (the rest wait in the socket buffer); datagrams longer than [`MAX_DATAGRAM`] bytes
//! are dropped and counted.
//!
//! May import: std, mavlink, `parapet-core` (wire names, parameters); [`inprocess`] (the
//! `parapet run --gcs` stack) also [`crate::flight::stack`] and [`crate::sim::sensors`].

pub mod inprocess;
pub mod tlog;

use std::io;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, MavHeader, MavlinkVersion};
use parapet_core::wire::names;

/// Default remote port of `--gcs` (QGroundControl listens there).
pub const GCS_PORT: u16 = 14550;
/// Default remote port of `--api` (MAVSDK / offboard APIs listen there).
pub const API_PORT: u16 = 14540;
/// Largest datagram accepted from an endpoint, bytes (a MAVLink v2 frame is ≤ 280).
pub const MAX_DATAGRAM: usize = 2048;
/// Datagrams taken per endpoint per lockstep step.
pub const MAX_DATAGRAMS_PER_STEP: usize = 64;

/// What the PIL link tells a tap and asks it (implemented by [`Bridge`]).
pub trait LinkTap {
    /// Before the step at firmware time `t_us` is written: pace, poll; returns the bytes
    /// to append to the step's stream (frames from the endpoints to the firmware).
    fn before_step(&mut self, t_us: u64) -> Vec<u8>;
    /// The bytes the host writes to the firmware in the current step (the last
    /// `before_step`'s; 0 before the first).
    fn host_bytes(&mut self, bytes: &[u8]);
    /// A frame from the firmware (decoded, with its MAVLink version), received during the
    /// current step.
    fn firmware_frame(&mut self, header: &MavHeader, msg: &MavMessage, version: MavlinkVersion);
}

/// A tap shared with its owner (who reads its counters and flushes it after the run).
impl<T: LinkTap> LinkTap for std::rc::Rc<std::cell::RefCell<T>> {
    fn before_step(&mut self, t_us: u64) -> Vec<u8> {
        self.borrow_mut().before_step(t_us)
    }
    fn host_bytes(&mut self, bytes: &[u8]) {
        self.borrow_mut().host_bytes(bytes)
    }
    fn firmware_frame(&mut self, header: &MavHeader, msg: &MavMessage, version: MavlinkVersion) {
        self.borrow_mut().firmware_frame(header, msg, version)
    }
}

/// `udp:HOST:PORT`, `udp:HOST`, `udp::PORT` or `udp:` (host 127.0.0.1, port `default_port`).
pub fn parse_endpoint(spec: &str, default_port: u16) -> Result<SocketAddr, String> {
    let rest = spec.strip_prefix("udp:").ok_or_else(|| format!("{spec:?}: expected udp:HOST:PORT"))?;
    let (host, port) = match rest.rsplit_once(':') {
        Some((h, p)) => (h, p.parse::<u16>().map_err(|_| format!("{spec:?}: port {p:?} is not 1-65535"))?),
        None => (rest, default_port),
    };
    if port == 0 {
        return Err(format!("{spec:?}: port 0 (allowed 1-65535)"));
    }
    let host = if host.is_empty() { "127.0.0.1" } else { host };
    (host, port)
        .to_socket_addrs()
        .map_err(|e| format!("{spec:?}: cannot resolve {host:?}: {e}"))?
        .find(|a| a.is_ipv4())
        .ok_or_else(|| format!("{spec:?}: no IPv4 address for {host:?}"))
}

/// The firmware's frames that belong to the lockstep and stay inside the host.
pub fn is_lockstep(msg: &MavMessage) -> bool {
    match msg {
        MavMessage::HIL_ACTUATOR_CONTROLS(_) => true,
        MavMessage::NAMED_VALUE_INT(n) => {
            let name = n.name.to_str().unwrap_or("");
            [names::INS_STEP, names::INS_OUTER, names::INS_MASKED, names::INS_CAL, names::INS_CAL_N]
                .contains(&name)
        }
        _ => false,
    }
}

/// `msg` as the MAVLink v2 frame with `header` (the bytes the firmware sent: it signs nothing
/// and the `mavlink` crate trims payloads the same way).
pub fn frame(header: MavHeader, msg: &MavMessage) -> Vec<u8> {
    frame_versioned(header, msg, MavlinkVersion::V2)
}

/// `msg` as the frame of MAVLink `version` with `header`.
pub fn frame_versioned(header: MavHeader, msg: &MavMessage, version: MavlinkVersion) -> Vec<u8> {
    match version {
        MavlinkVersion::V2 => {
            let mut raw = MAVLinkV2MessageRaw::new();
            raw.serialize_message(header, msg);
            raw.raw_bytes().to_vec()
        }
        MavlinkVersion::V1 => {
            let mut raw = MAVLinkV1MessageRaw::new();
            raw.serialize_message(header, msg);
            raw.raw_bytes().to_vec()
        }
    }
}

/// One sequence space per (system, component) for the frames forwarded to the endpoints: the
/// next number of each sender, counted over what the endpoints see (so the lockstep frames that
/// stay inside the host leave no gaps).
#[derive(Debug, Default)]
pub struct Resequencer {
    next: std::collections::HashMap<(u32, u8), u8>,
}

impl Resequencer {
    /// `header` with the sender's next forwarded sequence number.
    pub fn next(&mut self, header: &MavHeader) -> MavHeader {
        let n = self.next.entry((header.system_id, header.component_id)).or_insert(0);
        let h = MavHeader { sequence: *n, ..*header };
        *n = n.wrapping_add(1);
        h
    }
}

/// One UDP endpoint.
pub struct Endpoint {
    /// `gcs` or `api` (for messages).
    pub name: &'static str,
    sock: UdpSocket,
    remote: SocketAddr,
    /// Datagrams sent / received / dropped (too long or send failure).
    pub sent: u64,
    /// Datagrams received.
    pub received: u64,
    /// Datagrams dropped.
    pub dropped: u64,
}

impl Endpoint {
    /// Bind `0.0.0.0:0` (non-blocking) and send to `remote`.
    pub fn new(name: &'static str, remote: SocketAddr) -> io::Result<Self> {
        let sock = UdpSocket::bind(("0.0.0.0", 0))?;
        sock.set_nonblocking(true)?;
        Ok(Endpoint { name, sock, remote, sent: 0, received: 0, dropped: 0 })
    }

    /// Where the endpoint sends now.
    pub fn remote(&self) -> SocketAddr {
        self.remote
    }

    /// The local address (for tests and the start-up message).
    pub fn local(&self) -> io::Result<SocketAddr> {
        self.sock.local_addr()
    }

    fn send(&mut self, bytes: &[u8]) {
        // A GCS that is not (yet) listening gives ECONNREFUSED on Linux: not an error of the run.
        match self.sock.send_to(bytes, self.remote) {
            Ok(_) => self.sent += 1,
            Err(_) => self.dropped += 1,
        }
    }

    /// Datagrams waiting (at most [`MAX_DATAGRAMS_PER_STEP`]); learns the peer from each.
    fn poll(&mut self) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        let mut buf = [0u8; MAX_DATAGRAM + 1];
        while out.len() < MAX_DATAGRAMS_PER_STEP {
            match self.sock.recv_from(&mut buf) {
                Ok((n, from)) => {
                    self.received += 1;
                    self.remote = from;
                    if n > MAX_DATAGRAM {
                        self.dropped += 1;
                    } else {
                        out.push(buf[..n].to_vec());
                    }
                }
                Err(_) => break, // WouldBlock, or an ICMP error of an earlier send
            }
        }
        out
    }
}

/// The bridge: endpoints, wall-clock pacing and the `.tlog` (all optional).
pub struct Bridge {
    /// The endpoints (`--gcs`, `--api`).
    pub endpoints: Vec<Endpoint>,
    realtime: bool,
    /// First paced step: (firmware time µs, wall instant).
    pace_origin: Option<(u64, Instant)>,
    /// The `.tlog` (public for its counters).
    pub tlog: Option<tlog::TlogWriter>,
    /// Wall time slept for pacing.
    pub slept: Duration,
    now_us: u64,
    reseq: Resequencer,
}

impl Bridge {
    /// A bridge to `endpoints`; `realtime` paces firmware time to wall time.
    pub fn new(endpoints: Vec<Endpoint>, realtime: bool, tlog: Option<tlog::TlogWriter>) -> Self {
        Bridge {
            endpoints,
            realtime,
            pace_origin: None,
            tlog,
            slept: Duration::ZERO,
            now_us: 0,
            reseq: Resequencer::default(),
        }
    }

    /// Flush the `.tlog`.
    pub fn finish(&mut self) -> io::Result<()> {
        match self.tlog.as_mut() {
            Some(t) => t.flush(),
            None => Ok(()),
        }
    }

    fn pace(&mut self, t_us: u64) {
        if !self.realtime {
            return;
        }
        let (t0, w0) = *self.pace_origin.get_or_insert((t_us, Instant::now()));
        let due = w0 + Duration::from_micros(t_us.saturating_sub(t0));
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
            self.slept += due - now;
        }
    }
}

impl LinkTap for Bridge {
    fn before_step(&mut self, t_us: u64) -> Vec<u8> {
        self.now_us = t_us;
        self.pace(t_us);
        let mut to_fw = Vec::new();
        for i in 0..self.endpoints.len() {
            for d in self.endpoints[i].poll() {
                for (j, other) in self.endpoints.iter_mut().enumerate() {
                    if j != i {
                        other.send(&d);
                    }
                }
                to_fw.extend_from_slice(&d);
            }
        }
        to_fw
    }

    fn host_bytes(&mut self, bytes: &[u8]) {
        if let Some(t) = self.tlog.as_mut() {
            t.record(self.now_us, bytes);
        }
    }

    fn firmware_frame(&mut self, header: &MavHeader, msg: &MavMessage, version: MavlinkVersion) {
        if let Some(t) = self.tlog.as_mut() {
            t.record(self.now_us, &frame_versioned(*header, msg, version));
        }
        if !is_lockstep(msg) && !self.endpoints.is_empty() {
            let bytes = frame_versioned(self.reseq.next(header), msg, version);
            for e in &mut self.endpoints {
                e.send(&bytes);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{HEARTBEAT_DATA, HIL_ACTUATOR_CONTROLS_DATA};

    fn hb() -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())
    }

    #[test]
    fn endpoint_specs() {
        assert_eq!(
            parse_endpoint("udp:127.0.0.1:14551", GCS_PORT),
            Ok("127.0.0.1:14551".parse().expect("addr"))
        );
        assert_eq!(parse_endpoint("udp:", GCS_PORT), Ok("127.0.0.1:14550".parse().expect("addr")));
        assert_eq!(parse_endpoint("udp::14540", GCS_PORT), Ok("127.0.0.1:14540".parse().expect("addr")));
        assert_eq!(parse_endpoint("udp:localhost", API_PORT).map(|a| a.port()), Ok(14540));
        for bad in ["tcp:1.2.3.4:5", "udp:1.2.3.4:0", "udp:1.2.3.4:70000", "udp:1.2.3.4:x", "127.0.0.1:14550"]
        {
            assert!(parse_endpoint(bad, GCS_PORT).is_err(), "{bad}");
        }
    }

    /// Firmware frames reach the endpoint's remote (lockstep frames do not); a datagram from
    /// a client goes to the firmware and to the other endpoint, and the endpoint answers the
    /// client's address from then on (peer learning).
    #[test]
    fn routes_like_a_mavlink_router() {
        let gcs = UdpSocket::bind("127.0.0.1:0").expect("gcs socket");
        let api = UdpSocket::bind("127.0.0.1:0").expect("api socket");
        for s in [&gcs, &api] {
            s.set_read_timeout(Some(Duration::from_secs(2))).expect("timeout");
        }
        let e1 = Endpoint::new("gcs", gcs.local_addr().expect("addr")).expect("endpoint");
        let e2 = Endpoint::new("api", api.local_addr().expect("addr")).expect("endpoint");
        let mut b = Bridge::new(vec![e1, e2], false, None);
        let h = MavHeader { system_id: 1, component_id: 1, sequence: 7 };
        let v2 = MavlinkVersion::V2;
        b.firmware_frame(&h, &MavMessage::HIL_ACTUATOR_CONTROLS(HIL_ACTUATOR_CONTROLS_DATA::default()), v2);
        b.firmware_frame(&h, &hb(), v2);
        let mut buf = [0u8; 512];
        let first = MavHeader { sequence: 0, ..h };
        for s in [&gcs, &api] {
            let (n, _) = s.recv_from(&mut buf).expect("heartbeat forwarded");
            assert_eq!(
                &buf[..n],
                frame(first, &hb()).as_slice(),
                "only the heartbeat, not the lockstep frame"
            );
        }
        // A client on a third socket talks to the GCS endpoint: its datagram goes to the
        // firmware and to the API endpoint's peer, and the GCS endpoint learns the client.
        let client = UdpSocket::bind("127.0.0.1:0").expect("client");
        client.set_read_timeout(Some(Duration::from_secs(2))).expect("timeout");
        let gcs_local = b.endpoints[0].local().expect("local");
        let to_gcs_ep = std::net::SocketAddr::from(([127, 0, 0, 1], gcs_local.port()));
        client.send_to(b"\xfd-ping", to_gcs_ep).expect("send");
        let mut got = Vec::new();
        for _ in 0..200 {
            got = b.before_step(1000);
            if !got.is_empty() {
                break;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        assert_eq!(got, b"\xfd-ping");
        let (n, _) = api.recv_from(&mut buf).expect("routed to the other endpoint");
        assert_eq!(&buf[..n], b"\xfd-ping");
        assert_eq!(b.endpoints[0].remote(), client.local_addr().expect("addr"));
        b.firmware_frame(&h, &hb(), v2);
        let (n, _) = client.recv_from(&mut buf).expect("answer to the learned peer");
        assert_eq!(n, frame(h, &hb()).len());
    }

    /// The firmware's frames share one sequence space with the lockstep frames the host keeps;
    /// the endpoint sees each component's forwarded frames numbered without gaps (a ground
    /// station computes 0 % loss), other components counted apart, and a v1 frame (the v1
    /// refusal) arrives as v1. Before: the firmware's numbers were forwarded, 1 of ~16 seen.
    #[test]
    fn forwarded_frames_are_numbered_without_gaps_per_component() {
        use mavlink::dialects::ardupilotmega::{MavSeverity, STATUSTEXT_DATA};
        let gcs = UdpSocket::bind("127.0.0.1:0").expect("gcs socket");
        gcs.set_read_timeout(Some(Duration::from_secs(2))).expect("timeout");
        let e = Endpoint::new("gcs", gcs.local_addr().expect("addr")).expect("endpoint");
        let mut b = Bridge::new(vec![e], false, None);
        let lockstep = MavMessage::HIL_ACTUATOR_CONTROLS(HIL_ACTUATOR_CONTROLS_DATA::default());
        let mut fw_seq = 200u8;
        let mut sent = 0;
        for k in 0..300 {
            let h = MavHeader { system_id: 1, component_id: 1, sequence: fw_seq };
            fw_seq = fw_seq.wrapping_add(1);
            if k % 16 == 0 {
                b.firmware_frame(&h, &hb(), MavlinkVersion::V2);
                sent += 1;
            } else {
                b.firmware_frame(&h, &lockstep, MavlinkVersion::V2);
            }
        }
        let other = MavHeader { system_id: 1, component_id: 100, sequence: 99 };
        b.firmware_frame(&other, &hb(), MavlinkVersion::V2);
        let mut t = [0u8; 50];
        t[..23].copy_from_slice(b"MAVLink 1 not supported");
        let text = MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity: MavSeverity::MAV_SEVERITY_WARNING,
            text: t.into(),
            ..Default::default()
        });
        b.firmware_frame(
            &MavHeader { system_id: 1, component_id: 1, sequence: 3 },
            &text,
            MavlinkVersion::V1,
        );
        let mut buf = [0u8; 512];
        let mut seqs = Vec::new();
        for _ in 0..sent {
            let (n, _) = gcs.recv_from(&mut buf).expect("heartbeat");
            assert_eq!(buf[0], 0xFD, "v2");
            assert!(n > 4);
            seqs.push(buf[4]);
        }
        assert_eq!(seqs, (0..sent as u8).collect::<Vec<_>>(), "one gap-free space");
        let (_, _) = gcs.recv_from(&mut buf).expect("other component");
        assert_eq!((buf[4], buf[6]), (0, 100), "its own space");
        let (n, _) = gcs.recv_from(&mut buf).expect("the v1 text");
        assert_eq!((buf[0], buf[2], buf[5], n), (0xFE, sent as u8, 253, 8 + 51), "v1, next in the space");
    }

    #[test]
    fn realtime_paces_to_wall_time() {
        let mut b = Bridge::new(Vec::new(), true, None);
        let w = Instant::now();
        for k in 0..=50u64 {
            b.before_step(1_000_000 + k * 1000);
        }
        assert!(w.elapsed() >= Duration::from_millis(50), "{:?}", w.elapsed());
        let mut fast = Bridge::new(Vec::new(), false, None);
        let w = Instant::now();
        for k in 0..=50u64 {
            fast.before_step(k * 1000);
        }
        assert!(w.elapsed() < Duration::from_millis(50));
    }
}
