//! The QEMU process: start `qemu-system-arm -machine netduinoplus2 -icount shift=0`
//! with the firmware, the lockstep link on its stdin/stdout (the firmware's semihosting
//! console, see [`qemu_args`]), keep its stderr, kill it on drop; the thread that decodes
//! the firmware's MAVLink stream.
//!
//! May import: std, anyhow, mavlink, [`super`] (options).

use std::io::Read;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};

use anyhow::{bail, Result};
use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MavHeader, MavlinkReader, MavlinkVersion, Message};

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
    /// A frame: its header, message and MAVLink version (the firmware answers a v1 ground
    /// station in v1: `firmware/src/link/v1.rs`).
    Msg(MavHeader, Box<MavMessage>, MavlinkVersion),
    DecodeError,
    Closed(String),
}

/// Decode the firmware's MAVLink stream (v2, and the v1 frames of its v1 refusal) into `tx`
/// until the pipe closes.
pub(super) fn reader_thread(from_fw: ChildStdout, tx: mpsc::Sender<Inbound>) {
    // Buffered: one `read(2)` takes a whole batch of frames (the firmware writes each batch
    // with one `SYS_WRITE`), instead of the parser's small reads.
    let mut reader = MavlinkReader::new(std::io::BufReader::with_capacity(4096, from_fw));
    loop {
        let ev = match reader.read_any_raw_message::<MavMessage>() {
            Ok(raw) => {
                let h = MavHeader {
                    system_id: raw.system_id(),
                    component_id: raw.component_id(),
                    sequence: raw.sequence(),
                };
                match MavMessage::parse(raw.version(), raw.message_id(), raw.payload()) {
                    Ok(m) => Inbound::Msg(h, Box::new(m), raw.version()),
                    Err(_) => Inbound::DecodeError,
                }
            }
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

/// The host's ends of the lockstep link: QEMU's stdin (host → firmware) and stdout
/// (firmware → host).
pub(super) struct LinkPipes {
    pub(super) to_fw: ChildStdin,
    pub(super) from_fw: ChildStdout,
}

/// The emulator's command line (without the program): the firmware's semihosting console
/// (`SYS_OPEN(":tt")`) is QEMU's own stdin/stdout, which the host holds as pipes.
///
/// `-serial null`, `-monitor none` and `-display none` keep every QEMU chardev off stdio, so
/// QEMU leaves the pipes blocking and untouched: the guest's `SYS_READ` blocks in `read(2)`
/// (the emulated core stands still, no virtual time passes) until the host wrote the step.
/// There is no port: nothing can connect to another run's emulator.
pub fn qemu_args(firmware: &std::path::Path) -> Vec<std::ffi::OsString> {
    let mut a: Vec<std::ffi::OsString> = [
        "-machine",
        "netduinoplus2",
        "-display",
        "none",
        "-monitor",
        "none",
        "-serial",
        "null",
        "-icount",
        "shift=0",
        "-semihosting-config",
        "enable=on,target=native",
        "-kernel",
    ]
    .iter()
    .map(Into::into)
    .collect();
    a.push(firmware.into());
    a
}

/// Start QEMU with the firmware; the lockstep link is QEMU's stdin/stdout (see [`qemu_args`]).
pub(super) fn start_qemu(opts: &PilOptions) -> Result<(QemuGuard, LinkPipes)> {
    let mut cmd = Command::new(&opts.qemu);
    cmd.args(qemu_args(&opts.firmware)).stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::piped());
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
    let (to_fw, from_fw) = (child.stdin.take(), child.stdout.take());
    let guard = QemuGuard { child, stderr };
    match (to_fw, from_fw) {
        (Some(to_fw), Some(from_fw)) => Ok((guard, LinkPipes { to_fw, from_fw })),
        _ => bail!("QEMU started without its stdin/stdout pipes"),
    }
}
