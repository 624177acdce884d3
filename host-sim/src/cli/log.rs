//! `parapet log list|pull`: the vehicle's onboard flight logs (ULog) over the MAVLink log
//! protocol (LOG_REQUEST_LIST → LOG_ENTRY, LOG_REQUEST_DATA → LOG_DATA, LOG_REQUEST_END), as
//! QGroundControl's "Log Download" does it.
//!
//! `--port` is one of
//! * `udpin:HOST:PORT` — listen (e.g. `udpin:0.0.0.0:14550`, where a vehicle or `parapet pil
//!   --gcs udp:127.0.0.1:14550` sends); requests go to the address the first HEARTBEAT came from;
//! * `udp:HOST:PORT` / `udpout:HOST:PORT` — send to that address from an ephemeral port (the
//!   vehicle answers to it);
//! * a path (`/dev/ttyACM0`, `/dev/ttyUSB0`): a serial device read and written as a file;
//!   `--baud N` sets its speed with `stty -F PATH N raw -echo` first (USB CDC-ACM ports, as the
//!   flight controller's USB, ignore the speed).
//!
//! The vehicle is the first autopilot (component 1) whose HEARTBEAT arrives. `pull` writes the
//! log byte-exact (chunks placed by their `ofs`, gaps re-requested one by one; it gives up after
//! [`RETRIES`] requests in a row that brought nothing) and never replaces an existing file
//! without `--force`; the file is checked before anything is downloaded. A log still being
//! written (the vehicle armed) is pulled as listed: its first `size` bytes of LOG_ENTRY; what it
//! grew since is left for the next pull (a log only grows at its end, so those bytes are final).
//! Exit codes: 2 for a bad `--port`/`--out`/`--id` (named with the value and what is allowed),
//! 1 when the vehicle does not answer or a log does not arrive complete.
//!
//! May import: [`super`] (errors, output), [`crate::fc::bridge`] (frame splitting and decoding),
//! [`crate::input`], `mavlink`, std.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

use anyhow::anyhow;
use mavlink::dialects::ardupilotmega::{
    MavMessage, HEARTBEAT_DATA, LOG_ENTRY_DATA, LOG_REQUEST_DATA_DATA, LOG_REQUEST_END_DATA,
    LOG_REQUEST_LIST_DATA,
};
use mavlink::{MAVLinkV2MessageRaw, MavHeader};

use super::CliError;
use crate::fc::bridge::inprocess::decode_all as decode;
use crate::fc::bridge::tlog::frame_len;
use crate::input::InputError;

/// Re-requests of missing parts of a log before `pull` gives up.
pub const RETRIES: u32 = 20;
/// Our MAVLink system / component ids (a ground station's).
const OWN: (u8, u8) = (255, 190);
/// Bytes of one LOG_DATA.
const CHUNK: u32 = 90;

/// `parapet log --help` after the options: examples and exit codes.
pub fn help() -> String {
    "\
Examples:
  parapet log list --port /dev/ttyUSB0 --baud 921600           the logs of a vehicle on a serial port
  parapet log pull --port /dev/ttyUSB0 --baud 921600 --out flight.ulg      the newest log
  parapet log list --port udpin:0.0.0.0:14550                  listen where the vehicle sends (parapet pil --gcs)
  parapet log pull --port udp:192.168.4.1:14550 --id 0 --out first.ulg --force

Limits: --timeout 0.1-600 s (default 10) per wait; a download re-requests missing parts and
gives up after 20 requests in a row that brought nothing.

Exit codes:
  0    success
  1    the vehicle did not answer (no HEARTBEAT, no LOG_ENTRY) or a log did not arrive complete;
       also an I/O error writing --out
  2    bad input: --port, --baud, --timeout, --id or --out is named with the value and what is allowed
       (an existing --out without --force)"
        .into()
}

/// `parapet log …`.
#[derive(Debug, clap::Args)]
pub struct LogArgs {
    #[command(subcommand)]
    command: LogCommand,
}

#[derive(Debug, clap::Args)]
struct PortArgs {
    /// `udpin:HOST:PORT` (listen), `udp:HOST:PORT` / `udpout:HOST:PORT` (send to), or a serial
    /// device path (`/dev/ttyACM0`).
    #[arg(long)]
    port: String,
    /// Serial speed, Bd (set with `stty`; serial paths only).
    #[arg(long)]
    baud: Option<u32>,
    /// Seconds to wait for the vehicle's HEARTBEAT and for each answer (0.1-600).
    #[arg(long, default_value_t = 10.0)]
    timeout: f64,
}

#[derive(Debug, clap::Subcommand)]
enum LogCommand {
    /// List the vehicle's logs: id, size (bytes), UTC start time.
    List {
        #[command(flatten)]
        port: PortArgs,
    },
    /// Download one log to a file (the vehicle's ULog, `.ulg`).
    Pull {
        #[command(flatten)]
        port: PortArgs,
        /// Log id as `list` shows it (default: the newest).
        #[arg(long)]
        id: Option<u16>,
        /// Output file (e.g. flight.ulg).
        #[arg(long)]
        out: PathBuf,
        /// Replace `--out` if it exists.
        #[arg(long)]
        force: bool,
    },
}

enum Transport {
    Udp { sock: UdpSocket, peer: Option<SocketAddr> },
    Serial { file: File, rx: Receiver<Vec<u8>> },
}

/// A MAVLink connection to one vehicle.
pub struct Conn {
    t: Transport,
    buf: Vec<u8>,
    seq: u8,
    timeout: Duration,
    /// The vehicle (system, component) once its HEARTBEAT arrived.
    pub target: Option<(u8, u8)>,
}

fn bad_port(spec: &str, why: impl Into<String>) -> CliError {
    InputError::option("port", why)
        .value(spec)
        .allowed("udpin:HOST:PORT, udp:HOST:PORT, udpout:HOST:PORT or a serial device path")
        .into()
}

fn resolve(spec: &str, hostport: &str) -> Result<SocketAddr, CliError> {
    let Some((_, p)) = hostport.rsplit_once(':') else {
        return Err(bad_port(spec, "no :PORT"));
    };
    match p.parse::<u16>() {
        Ok(n) if n > 0 => {}
        _ => return Err(bad_port(spec, format!("port {p:?} is not 1-65535"))),
    }
    hostport
        .to_socket_addrs()
        .map_err(|e| bad_port(spec, format!("cannot resolve: {e}")))?
        .find(|a| a.is_ipv4())
        .ok_or_else(|| bad_port(spec, "no IPv4 address"))
}

impl Conn {
    /// Opens `spec` (see the module doc); `timeout` bounds every wait.
    pub fn open(spec: &str, baud: Option<u32>, timeout: Duration) -> Result<Self, CliError> {
        let t = if let Some(hp) = spec.strip_prefix("udpin:") {
            let addr = resolve(spec, hp)?;
            let sock = UdpSocket::bind(addr).map_err(|e| bad_port(spec, format!("cannot listen: {e}")))?;
            Transport::Udp { sock, peer: None }
        } else if let Some(hp) = spec.strip_prefix("udpout:").or_else(|| spec.strip_prefix("udp:")) {
            let addr = resolve(spec, hp)?;
            let sock = UdpSocket::bind(("0.0.0.0", 0)).map_err(|e| anyhow!("UDP socket: {e}"))?;
            Transport::Udp { sock, peer: Some(addr) }
        } else if spec.starts_with('/') || spec.starts_with('.') {
            if let Some(b) = baud {
                let ok = std::process::Command::new("stty")
                    .args(["-F", spec, &b.to_string(), "raw", "-echo"])
                    .status()
                    .is_ok_and(|s| s.success());
                if !ok {
                    return Err(InputError::option(
                        "baud",
                        format!("stty could not set {spec} to this speed"),
                    )
                    .value(b)
                    .allowed("a speed the device supports (e.g. 57600, 115200, 921600)")
                    .into());
                }
            }
            let file = OpenOptions::new()
                .read(true)
                .write(true)
                .open(spec)
                .map_err(|e| bad_port(spec, format!("cannot open: {e}")))?;
            let mut reader = file.try_clone().map_err(|e| anyhow!("{spec}: {e}"))?;
            let (tx, rx) = mpsc::channel();
            std::thread::spawn(move || {
                let mut b = [0u8; 512];
                while let Ok(n) = reader.read(&mut b) {
                    if n == 0 || tx.send(b[..n].to_vec()).is_err() {
                        break;
                    }
                }
            });
            Transport::Serial { file, rx }
        } else {
            return Err(bad_port(spec, "unknown kind of port"));
        };
        Ok(Self { t, buf: Vec::new(), seq: 0, timeout, target: None })
    }

    /// Sends one message (UDP without a known peer: dropped until a HEARTBEAT arrived).
    pub fn send(&mut self, msg: &MavMessage) -> anyhow::Result<()> {
        let header = MavHeader { system_id: u32::from(OWN.0), component_id: OWN.1, sequence: self.seq };
        self.seq = self.seq.wrapping_add(1);
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message(header, msg);
        match &mut self.t {
            Transport::Udp { sock, peer: Some(p) } => {
                sock.send_to(raw.raw_bytes(), *p)?;
            }
            Transport::Udp { peer: None, .. } => {}
            Transport::Serial { file, .. } => file.write_all(raw.raw_bytes())?,
        }
        Ok(())
    }

    fn fill(&mut self, until: Instant) -> anyhow::Result<bool> {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Ok(false);
        }
        match &mut self.t {
            Transport::Udp { sock, peer } => {
                sock.set_read_timeout(Some(left.max(Duration::from_millis(1))))?;
                let mut b = [0u8; 2048];
                match sock.recv_from(&mut b) {
                    Ok((n, from)) => {
                        if peer.is_none() {
                            // The first datagram with a HEARTBEAT decides (checked by the caller).
                            if decode(&b[..n]).iter().any(|(_, m)| matches!(m, MavMessage::HEARTBEAT(_))) {
                                *peer = Some(from);
                            }
                        }
                        self.buf.extend_from_slice(&b[..n]);
                        Ok(true)
                    }
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) =>
                    {
                        Ok(false)
                    }
                    Err(e) => Err(e.into()),
                }
            }
            Transport::Serial { rx, .. } => match rx.recv_timeout(left) {
                Ok(b) => {
                    self.buf.extend_from_slice(&b);
                    Ok(true)
                }
                Err(mpsc::RecvTimeoutError::Timeout) => Ok(false),
                Err(mpsc::RecvTimeoutError::Disconnected) => Err(anyhow!("the serial port closed")),
            },
        }
    }

    /// The next message from the vehicle (or any sender before the vehicle is known), or
    /// `None` at `until`.
    pub fn recv(&mut self, until: Instant) -> anyhow::Result<Option<(MavHeader, MavMessage)>> {
        loop {
            while let Some(&b0) = self.buf.first() {
                if b0 != 0xFD && b0 != 0xFE {
                    self.buf.remove(0);
                    continue;
                }
                let Some(n) = frame_len(&self.buf) else {
                    // Incomplete: a longer frame header than bytes so far (or garbage).
                    if self.buf.len() > 300 {
                        self.buf.remove(0);
                        continue;
                    }
                    break;
                };
                let frame: Vec<u8> = self.buf.drain(..n).collect();
                if let Some((h, m)) = decode(&frame).into_iter().next() {
                    let from = (h.system_id as u8, h.component_id);
                    if self.target.is_none() || self.target == Some(from) {
                        return Ok(Some((h, m)));
                    }
                }
            }
            if !self.fill(until)? {
                return Ok(None);
            }
        }
    }

    /// Waits for the vehicle's HEARTBEAT (an autopilot, component 1).
    pub fn connect(&mut self, port: &str) -> anyhow::Result<(u8, u8)> {
        let until = Instant::now() + self.timeout;
        while let Some((h, m)) = self.recv(until)? {
            if let MavMessage::HEARTBEAT(HEARTBEAT_DATA { .. }) = m {
                if h.component_id == 1 {
                    let t = (h.system_id as u8, h.component_id);
                    self.target = Some(t);
                    return Ok(t);
                }
            }
        }
        Err(anyhow!("no HEARTBEAT from a vehicle on {port} within {:.1} s", self.timeout.as_secs_f64()))
    }

    fn target(&self) -> (u8, u8) {
        self.target.unwrap_or((1, 1))
    }

    /// Lists the logs (LOG_REQUEST_LIST, up to 3 attempts).
    pub fn list(&mut self) -> anyhow::Result<Vec<LOG_ENTRY_DATA>> {
        let (ts, tc) = self.target();
        for _ in 0..3 {
            self.send(&MavMessage::LOG_REQUEST_LIST(LOG_REQUEST_LIST_DATA {
                start: 0,
                end: 0xFFFF,
                target_system: ts,
                target_component: tc,
            }))?;
            let mut got: Vec<LOG_ENTRY_DATA> = Vec::new();
            let mut until = Instant::now() + self.timeout;
            while let Some((_, m)) = self.recv(until)? {
                if let MavMessage::LOG_ENTRY(e) = m {
                    if e.num_logs == 0 {
                        return Ok(Vec::new());
                    }
                    let num_logs = usize::from(e.num_logs);
                    if !got.iter().any(|g| g.id == e.id) {
                        got.push(e);
                    }
                    if got.len() >= num_logs {
                        got.sort_by_key(|e| e.id);
                        return Ok(got);
                    }
                    until = Instant::now() + Duration::from_millis(500).min(self.timeout);
                }
            }
        }
        Err(anyhow!("no complete LOG_ENTRY list within 3 × {:.1} s", self.timeout.as_secs_f64()))
    }

    /// Downloads log `id` of `size` bytes.
    pub fn pull(&mut self, id: u16, size: u32) -> anyhow::Result<Vec<u8>> {
        let (ts, tc) = self.target();
        let mut data = vec![0u8; size as usize];
        let mut have = vec![false; size.div_ceil(CHUNK) as usize];
        let mut stalled = 0;
        // First the whole log, then each gap: the requested range in chunks [first, last).
        let mut whole = true;
        while let Some(first) = have.iter().position(|h| !*h) {
            let last = have[first..].iter().position(|h| *h).map_or(have.len(), |k| first + k);
            let range = if whole { (0, have.len()) } else { (first, last) };
            whole = false;
            let ofs = range.0 as u32 * CHUNK;
            let count = if range.1 == have.len() { u32::MAX } else { range.1 as u32 * CHUNK - ofs };
            self.send(&MavMessage::LOG_REQUEST_DATA(LOG_REQUEST_DATA_DATA {
                ofs,
                count,
                id,
                target_system: ts,
                target_component: tc,
            }))?;
            let missing_before = have.iter().filter(|h| !**h).count();
            let stall = Duration::from_millis(700).min(self.timeout);
            let mut until = Instant::now() + stall;
            while let Some((_, m)) = self.recv(until)? {
                let MavMessage::LOG_DATA(d) = m else { continue };
                if d.id != id {
                    continue;
                }
                // A log still being written has grown past its listed size: the chunk that
                // straddles the listed end is kept up to it (the download is of the log as
                // listed; the log only grows at its end).
                let at = d.ofs as usize;
                let n = usize::from(d.count).min(90).min(data.len().saturating_sub(at));
                if n > 0 && at.is_multiple_of(CHUNK as usize) {
                    data[at..at + n].copy_from_slice(&d.data[..n]);
                    if let Some(h) = have.get_mut(at / CHUNK as usize) {
                        *h = true;
                    }
                }
                until = Instant::now() + stall;
                if have[range.0..range.1].iter().all(|h| *h) {
                    break;
                }
            }
            if have.iter().filter(|h| !**h).count() == missing_before {
                stalled += 1;
                if stalled > RETRIES {
                    return Err(anyhow!(
                        "log {id}: {missing_before} of {} chunks of 90 bytes missing, no progress after {RETRIES} re-requests",
                        have.len()
                    ));
                }
            } else {
                stalled = 0;
            }
        }
        self.send(&MavMessage::LOG_REQUEST_END(LOG_REQUEST_END_DATA {
            target_system: ts,
            target_component: tc,
        }))?;
        Ok(data)
    }
}

fn open(p: &PortArgs) -> Result<Conn, CliError> {
    if !(0.1..=600.0).contains(&p.timeout) {
        return Err(InputError::option("timeout", "out of range")
            .value(p.timeout)
            .allowed("0.1-600 s")
            .into());
    }
    let mut c = Conn::open(&p.port, p.baud, Duration::from_secs_f64(p.timeout))?;
    c.connect(&p.port)?;
    Ok(c)
}

/// The `list` table.
pub fn list_text(entries: &[LOG_ENTRY_DATA]) -> String {
    if entries.is_empty() {
        return "no logs on the vehicle\n".into();
    }
    let mut s = String::from("id\tsize_bytes\ttime_utc\n");
    for e in entries {
        s.push_str(&format!("{}\t{}\t{}\n", e.id, e.size, e.time_utc));
    }
    s
}

fn check_out(out: &Path, force: bool) -> Result<(), CliError> {
    if out.exists() && !force {
        return Err(InputError::option("out", "exists (add --force to replace it)")
            .value(out.display())
            .allowed("a path that does not exist, or --force")
            .into());
    }
    Ok(())
}

/// `parapet log …`: returns what to print.
pub fn cmd_log(a: LogArgs) -> Result<String, CliError> {
    match a.command {
        LogCommand::List { port } => {
            let mut c = open(&port)?;
            Ok(list_text(&c.list()?))
        }
        LogCommand::Pull { port, id, out, force } => {
            check_out(&out, force)?;
            let mut c = open(&port)?;
            let entries = c.list()?;
            let entry = match id {
                None => entries.last().cloned().ok_or_else(|| anyhow!("no logs on the vehicle"))?,
                Some(i) => entries.iter().find(|e| e.id == i).cloned().ok_or_else(|| {
                    CliError::from(
                        InputError::option("id", "no such log on the vehicle").value(i).allowed(format!(
                            "one of {:?}",
                            entries.iter().map(|e| e.id).collect::<Vec<_>>()
                        )),
                    )
                })?,
            };
            let bytes = c.pull(entry.id, entry.size)?;
            check_out(&out, force)?;
            std::fs::write(&out, &bytes).map_err(|e| anyhow!("cannot write {}: {e}", out.display()))?;
            Ok(format!("log {}: {} bytes -> {}\n", entry.id, bytes.len(), out.display()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::LOG_DATA_DATA;

    /// A fake vehicle on UDP: HEARTBEATs, one log of `log.len()` bytes, LOG_DATA chunks with
    /// every `drop_every`-th first-time chunk lost.
    fn vehicle(log: Vec<u8>, drop_every: usize) -> (SocketAddr, std::thread::JoinHandle<()>) {
        let listed = log.len();
        vehicle_listing(log, listed, drop_every)
    }

    /// [`vehicle`] whose LOG_ENTRY lists `listed` bytes while LOG_DATA streams all of `log`
    /// (a log still being written grows between the listing and the download).
    fn vehicle_listing(
        log: Vec<u8>,
        listed: usize,
        drop_every: usize,
    ) -> (SocketAddr, std::thread::JoinHandle<()>) {
        let sock = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let addr = sock.local_addr().expect("addr");
        let h = std::thread::spawn(move || {
            sock.set_read_timeout(Some(Duration::from_millis(50))).expect("timeout");
            let mut peer = None;
            let mut sent = 0usize;
            let end = Instant::now() + Duration::from_secs(20);
            let send = |s: &UdpSocket, p: SocketAddr, m: &MavMessage| {
                let mut raw = MAVLinkV2MessageRaw::new();
                raw.serialize_message(MavHeader { system_id: 1, component_id: 1, sequence: 0 }, m);
                let _ = s.send_to(raw.raw_bytes(), p);
            };
            while Instant::now() < end {
                let mut b = [0u8; 2048];
                if let Ok((n, from)) = sock.recv_from(&mut b) {
                    peer = Some(from);
                    for (_, m) in decode(&b[..n]) {
                        match m {
                            MavMessage::LOG_REQUEST_LIST(_) => send(
                                &sock,
                                from,
                                &MavMessage::LOG_ENTRY(LOG_ENTRY_DATA {
                                    time_utc: 0,
                                    size: listed as u32,
                                    id: 0,
                                    num_logs: 1,
                                    last_log_num: 0,
                                }),
                            ),
                            MavMessage::LOG_REQUEST_DATA(r) => {
                                let stop = r.ofs.saturating_add(r.count).min(log.len() as u32);
                                let mut ofs = r.ofs;
                                while ofs < stop {
                                    let n = (stop - ofs).min(90) as usize;
                                    let mut data = [0u8; 90];
                                    data[..n].copy_from_slice(&log[ofs as usize..ofs as usize + n]);
                                    sent += 1;
                                    if drop_every == 0 || !sent.is_multiple_of(drop_every) {
                                        send(
                                            &sock,
                                            from,
                                            &MavMessage::LOG_DATA(LOG_DATA_DATA {
                                                ofs,
                                                id: 0,
                                                count: n as u8,
                                                data,
                                            }),
                                        );
                                    }
                                    ofs += n as u32;
                                }
                            }
                            MavMessage::LOG_REQUEST_END(_) => return,
                            _ => {}
                        }
                    }
                } else if let Some(p) = peer {
                    send(&sock, p, &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
                }
                if peer.is_none() {
                    // Nobody yet: nothing to send to.
                }
            }
        });
        (addr, h)
    }

    #[test]
    fn pull_reassembles_a_lossy_download_byte_exact() {
        let log: Vec<u8> = (0..10_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let (addr, h) = vehicle(log.clone(), 5);
        let mut c = Conn::open(&format!("udp:{addr}"), None, Duration::from_secs(5)).expect("open");
        // The fake vehicle learns our address from the first request: poke it.
        c.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())).expect("poke");
        c.connect("test").expect("heartbeat");
        let entries = c.list().expect("list");
        assert_eq!(entries.len(), 1);
        assert!(list_text(&entries).contains("0\t10000\t0"));
        let got = c.pull(0, 10_000).expect("pull");
        assert_eq!(got, log);
        h.join().expect("vehicle");
    }

    /// The log grew between LOG_ENTRY and LOG_REQUEST_DATA (a flight still logging): the chunk
    /// across the listed end is full-length on the wire; the pull keeps the listed bytes.
    #[test]
    fn pull_of_a_log_that_grew_since_listing_returns_the_listed_bytes() {
        let log: Vec<u8> = (0..10_500u32).map(|i| (i * 13 % 251) as u8).collect();
        let listed = 10_000; // not a multiple of 90: the last listed chunk straddles the end
        let (addr, h) = vehicle_listing(log.clone(), listed, 7);
        let mut c = Conn::open(&format!("udp:{addr}"), None, Duration::from_secs(5)).expect("open");
        c.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())).expect("poke");
        c.connect("test").expect("heartbeat");
        let entries = c.list().expect("list");
        assert_eq!(entries[0].size, listed as u32);
        let got = c.pull(0, listed as u32).expect("pull");
        assert_eq!(got, log[..listed]);
        h.join().expect("vehicle");
    }

    #[test]
    fn bad_ports_and_existing_outputs_are_refused_by_name() {
        for spec in ["tcp:1.2.3.4:5", "udp:127.0.0.1", "udp:127.0.0.1:0", "udpin:127.0.0.1:99999"] {
            let Err(e) = Conn::open(spec, None, Duration::from_secs(1)) else { panic!("{spec} accepted") };
            assert_eq!(e.exit_code(), 2, "{spec}");
            assert!(e.to_string().contains("--port") && e.to_string().contains(spec), "{e}");
        }
        let f = std::env::temp_dir().join(format!("parapet-log-exists-{}", std::process::id()));
        std::fs::write(&f, b"x").expect("write");
        let e = check_out(&f, false).expect_err("exists");
        assert!(e.to_string().contains("--out") && e.to_string().contains("--force"), "{e}");
        assert!(check_out(&f, true).is_ok());
        let _ = std::fs::remove_file(&f);
    }
}
