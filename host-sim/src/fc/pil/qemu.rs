//! The QEMU process: start `qemu-system-arm -machine netduinoplus2 -icount shift=0`
//! with the firmware, its serial port a TCP client of a listener we hold, keep its
//! stderr, kill it on drop; the thread that decodes the firmware's MAVLink stream.
//!
//! May import: std, anyhow, mavlink, [`super`] (options).

use std::io::Read;
use std::net::{TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MavHeader, MavlinkReader, MavlinkVersion};

use super::PilOptions;

/// Debian/Ubuntu package (and binary) of the emulator.
pub const QEMU_PACKAGE: &str = "qemu-system-arm";

/// Kills QEMU when dropped.
pub(super) struct QemuGuard {
    pub(super) child: Child,
    stderr: Arc<Mutex<String>>,
}

impl Drop for QemuGuard {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl QemuGuard {
    pub(super) fn stderr_text(&self) -> String {
        self.stderr.lock().map(|s| s.trim().to_string()).unwrap_or_default()
    }
}

/// What the reader thread got from the firmware.
pub(super) enum Inbound {
    Msg(MavHeader, Box<MavMessage>),
    DecodeError,
    Closed(String),
}

/// Decode the firmware's MAVLink v2 stream into `tx` until the socket closes.
pub(super) fn reader_thread(sock: TcpStream, tx: mpsc::Sender<Inbound>) {
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

/// Start QEMU with its serial port connected to a listener this process holds.
///
/// The host binds `127.0.0.1:0` and keeps the listener open; QEMU's chardev is a
/// socket *client* (`server=off`) to that port, and the host accepts the one
/// connection. Nothing else can take the port between probe and use (the old
/// "bind 0, drop, let QEMU bind" probe raced parallel runs and could even
/// self-connect: a test then talked to another test's emulator and saw
/// "connection reset by peer"), and the peer is checked to be local.
pub(super) fn start_qemu(opts: &PilOptions) -> Result<(QemuGuard, TcpStream)> {
    let listener = TcpListener::bind("127.0.0.1:0").context("cannot listen on a localhost port")?;
    let port = listener.local_addr().context("listener address")?.port();
    listener.set_nonblocking(true).context("non-blocking listener")?;
    let mut cmd = Command::new(&opts.qemu);
    cmd.args(["-machine", "netduinoplus2", "-nographic", "-monitor", "none", "-icount", "shift=0"])
        .arg("-kernel")
        .arg(&opts.firmware)
        .args([
            "-chardev",
            &format!("socket,id=c0,host=127.0.0.1,port={port},server=off,nodelay=on"),
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
        match listener.accept() {
            Ok((sock, peer)) => {
                if !peer.ip().is_loopback() {
                    continue;
                }
                sock.set_nonblocking(false).context("blocking serial socket")?;
                return Ok((guard, sock));
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) => bail!("cannot accept QEMU's serial connection on port {port}: {e}"),
        }
        if let Ok(Some(status)) = guard.child.try_wait() {
            // Give the stderr thread a moment to collect QEMU's last words.
            std::thread::sleep(Duration::from_millis(50));
            bail!("QEMU exited before connecting its serial port ({status}): {}", guard.stderr_text());
        }
        if t0.elapsed() > Duration::from_secs(20) {
            bail!("QEMU did not connect its serial port to 127.0.0.1:{port} within 20 s");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}
