//! `.tlog` telemetry logs as QGroundControl and MAVProxy write them: every MAVLink frame
//! preceded by an 8-byte **big-endian** timestamp in µs (pymavlink's
//! `mavutil.mavlink_connection("x.tlog")`, MAVExplorer). Both directions are recorded: the
//! host's frames to the firmware (lockstep included) and the firmware's frames.
//!
//! The timestamp is the firmware clock of the lockstep step (simulated time + 1 s, µs), not
//! wall time, so a log lines up with `flight.ulg` and is the same for the same run; a replay
//! tool shows it as seconds after 1970-01-01.
//!
//! A batch of bytes is split into frames by their headers (v2 `0xFD`: 12 + len bytes, + 13
//! when signed; v1 `0xFE`: 8 + len); bytes that start no frame (e.g. corrupted by fault
//! injection) are skipped and counted.
//!
//! May import: std.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// Length of the frame at the start of `b`, when `b` starts with a complete one.
pub fn frame_len(b: &[u8]) -> Option<usize> {
    let n = match *b.first()? {
        0xFD => 12 + usize::from(*b.get(1)?) + if b.get(2)? & 0x01 != 0 { 13 } else { 0 },
        0xFE => 8 + usize::from(*b.get(1)?),
        _ => return None,
    };
    (b.len() >= n).then_some(n)
}

/// Split `bytes` into frames; returns them and the number of bytes skipped.
pub fn split_frames(bytes: &[u8]) -> (Vec<&[u8]>, usize) {
    let (mut out, mut skipped, mut i) = (Vec::new(), 0, 0);
    while i < bytes.len() {
        match frame_len(&bytes[i..]) {
            Some(n) => {
                out.push(&bytes[i..i + n]);
                i += n;
            }
            None => {
                skipped += 1;
                i += 1;
            }
        }
    }
    (out, skipped)
}

/// A `.tlog` file being written.
pub struct TlogWriter {
    w: BufWriter<File>,
    /// Frames written.
    pub frames: u64,
    /// Bytes that started no frame.
    pub skipped: u64,
    /// First write error (later records are dropped).
    pub error: Option<io::Error>,
}

impl TlogWriter {
    /// Create `path`.
    pub fn create(path: &Path) -> io::Result<Self> {
        Ok(TlogWriter { w: BufWriter::new(File::create(path)?), frames: 0, skipped: 0, error: None })
    }

    /// Record the frames in `bytes` at `t_us`.
    pub fn record(&mut self, t_us: u64, bytes: &[u8]) {
        if self.error.is_some() {
            return;
        }
        let (frames, skipped) = split_frames(bytes);
        self.skipped += skipped as u64;
        for f in frames {
            let r = self.w.write_all(&t_us.to_be_bytes()).and_then(|()| self.w.write_all(f));
            if let Err(e) = r {
                self.error = Some(e);
                return;
            }
            self.frames += 1;
        }
    }

    /// Flush; the first write error if there was one.
    pub fn flush(&mut self) -> io::Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.w.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{MavMessage, HEARTBEAT_DATA, PARAM_VALUE_DATA};
    use mavlink::{MavHeader, MavlinkVersion};

    fn v2(m: &MavMessage) -> Vec<u8> {
        super::super::frame(MavHeader { system_id: 1, component_id: 1, sequence: 3 }, m)
    }

    #[test]
    fn splits_batches_and_skips_garbage() {
        let a = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        let b = v2(&MavMessage::PARAM_VALUE(PARAM_VALUE_DATA { param_value: 1.5, ..Default::default() }));
        let batch = [a.clone(), vec![0x00, 0x42], b.clone()].concat();
        let (frames, skipped) = split_frames(&batch);
        assert_eq!(frames, [a.as_slice(), b.as_slice()]);
        assert_eq!(skipped, 2);
        // A truncated frame at the end is skipped byte by byte.
        let (frames, skipped) = split_frames(&a[..a.len() - 1]);
        assert!(frames.is_empty());
        assert_eq!(skipped, a.len() - 1);
        assert_eq!(frame_len(&[0xFE, 9]), None);
        assert_eq!(frame_len(&[0xFE, 0, 0, 0, 0, 0, 0, 0]), Some(8));
    }

    /// The file is `[u64 BE time][frame]…` and decodes frame by frame with the mavlink crate.
    #[test]
    fn tlog_layout() {
        let dir = std::env::temp_dir().join(format!("parapet-tlog-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("t.tlog");
        let a = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        let mut w = TlogWriter::create(&path).expect("create");
        w.record(1_000_123, &[a.clone(), a.clone()].concat());
        w.flush().expect("flush");
        assert_eq!(w.frames, 2);
        let bytes = std::fs::read(&path).expect("read");
        assert_eq!(bytes.len(), 2 * (8 + a.len()));
        assert_eq!(u64::from_be_bytes(bytes[..8].try_into().expect("8")), 1_000_123);
        let mut r = mavlink::MavlinkReader::new(&bytes[8..8 + a.len()]);
        let (_, m) = r.read_message::<MavMessage>(MavlinkVersion::V2).expect("frame");
        assert!(matches!(m, MavMessage::HEARTBEAT(_)));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
