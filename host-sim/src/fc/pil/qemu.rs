//! The QEMU process: start `qemu-system-arm -machine netduinoplus2 -icount shift=0`
//! with the firmware on a free localhost port (TCP chardev), connect, keep its
//! stderr, kill it on drop; the thread that decodes the firmware's MAVLink stream.
//!
//! May import: std, anyhow, mavlink, [`super`] (options).

use std::io::Read;
use std::net::{TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
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

/// Start QEMU on a free port and connect to its serial socket.
pub(super) fn start_qemu(opts: &PilOptions) -> Result<(QemuGuard, TcpStream)> {
    let mut last_err = None;
    for _attempt in 0..3 {
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .context("no free localhost port")?
            .port();
        let mut cmd = Command::new(&opts.qemu);
        cmd.args(["-machine", "netduinoplus2", "-nographic", "-monitor", "none", "-icount", "shift=0"])
            .arg("-kernel")
            .arg(&opts.firmware)
            .args([
                "-chardev",
                &format!("socket,id=c0,host=127.0.0.1,port={port},server=on,wait=off,nodelay=on"),
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
            if let Ok(Some(status)) = guard.child.try_wait() {
                // Port taken between our probe and QEMU's bind, or a bad ELF: retry once more.
                std::thread::sleep(Duration::from_millis(50));
                last_err = Some(anyhow!("QEMU exited ({status}): {}", guard.stderr_text()));
                break;
            }
            match TcpStream::connect(("127.0.0.1", port)) {
                Ok(s) => return Ok((guard, s)),
                Err(_) if t0.elapsed() < Duration::from_secs(10) => {
                    std::thread::sleep(Duration::from_millis(20))
                }
                Err(e) => bail!("cannot connect to QEMU's serial socket on port {port} within 10 s: {e}"),
            }
        }
    }
    Err(last_err.unwrap_or_else(|| anyhow!("QEMU did not start")))
}
