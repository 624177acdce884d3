//! The MAVLink log download (the protocol QGroundControl's "Log Download" and pymavlink /
//! MAVProxy's `log` module speak): LOG_REQUEST_LIST → LOG_ENTRY, LOG_REQUEST_DATA → LOG_DATA,
//! LOG_ERASE, LOG_REQUEST_END, served from a [`LogStore`].
//!
//! - **Ids** on the wire are list positions, `0 ..= num_logs − 1`, oldest first (as PX4 does and
//!   as QGroundControl expects from a non-ArduPilot vehicle); `last_log_num` = `num_logs − 1`.
//!   An empty store answers one LOG_ENTRY with `num_logs` 0. `time_utc` is 0 (no UTC clock).
//! - **LOG_REQUEST_DATA** (`id`, `ofs`, `count`, `count` 0xFFFF_FFFF = to the end) streams
//!   LOG_DATA of [`CHUNK`] = 90 bytes from `ofs`, the last one shorter; when the requested range
//!   reaches the end of the log and the last chunk was full, or `ofs` is at or past the end, one
//!   LOG_DATA with `count` 0 marks the end. A new request replaces the running one;
//!   LOG_REQUEST_END stops it. An unknown id answers nothing (counted).
//! - **LOG_ERASE** erases every log; refused (counted, nothing is sent: the protocol has no
//!   answer) while a log is being written, i.e. while armed.
//! - **Bounded work**: [`LogTransfer::poll`] sends at most [`REPLIES_PER_POLL`] messages (each a
//!   store read of ≤ 90 bytes); requests themselves only set state.
//! - Addressing as the rest of the link: `target_system` 0 or ours, `target_component` 0 or
//!   the autopilot's; others are ignored and counted.
//!
//! This runs in the lowest-priority task that owns the store (the link task on a board, the
//! PIL application in QEMU), never in a control task: the board task passes LOG_* frames here
//! ([`LogTransfer::on_frame`]) before the rest go to the dispatcher.
//!
//! May import: `mavlink_core`, [`crate::link::dialect`], [`crate::link::frame_parser`], [`crate::link::framing`],
//! [`crate::link::command`] (addressing), [`crate::log::store`].

use mavlink_core::{MAVLinkV2MessageRaw, MavlinkVersion, MessageData};

use crate::link::command::addressed_to;
use crate::link::dialect::{
    LOG_DATA_DATA, LOG_ENTRY_DATA, LOG_ERASE_DATA, LOG_REQUEST_DATA_DATA, LOG_REQUEST_END_DATA,
    LOG_REQUEST_LIST_DATA,
};
use crate::link::frame_parser::RawFrame;
use crate::link::framing::{FrameWriter, AUTOPILOT_COMPONENT_ID};
use crate::log::store::LogStore;

/// Bytes of one LOG_DATA.
pub const CHUNK: usize = 90;
/// Most messages one [`LogTransfer::poll`] sends.
pub const REPLIES_PER_POLL: usize = 4;

/// A message of the log protocol to send.
#[derive(Clone, Debug, PartialEq)]
pub enum LogReply {
    /// LOG_ENTRY.
    Entry(LOG_ENTRY_DATA),
    /// LOG_DATA.
    Data(LOG_DATA_DATA),
}

impl LogReply {
    /// Encodes the message as the next frame of `writer`.
    pub fn encode(&self, writer: &mut FrameWriter) -> MAVLinkV2MessageRaw {
        match self {
            LogReply::Entry(m) => writer.encode(m),
            LogReply::Data(m) => writer.encode(m),
        }
    }
}

/// Counters of the log protocol (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TransferStats {
    /// LOG_* requests handled.
    pub requests: u32,
    /// LOG_DATA bytes sent.
    pub bytes_sent: u32,
    /// Requests for an unknown log id.
    pub unknown_log: u32,
    /// LOG_ERASE refused (a log is being written).
    pub erase_refused: u32,
    /// Requests addressed to another system or component.
    pub not_for_us: u32,
    /// Requests that did not decode.
    pub decode_errors: u32,
    /// Store reads that failed.
    pub read_errors: u32,
}

#[derive(Clone, Copy, Debug)]
struct Listing {
    next: u16,
    end: u16,
}

#[derive(Clone, Copy, Debug)]
struct Streaming {
    index: u16,
    ofs: u32,
    end: u32,
    /// A count-0 LOG_DATA follows the data (the range reached the end of the log).
    terminate: bool,
    last_full: bool,
}

/// The log protocol's state (see the module doc).
pub struct LogTransfer {
    own_system: u8,
    listing: Option<Listing>,
    streaming: Option<Streaming>,
    stats: TransferStats,
}

fn de<D: MessageData>(payload: &[u8]) -> Option<D> {
    D::deser(MavlinkVersion::V2, payload).ok()
}

impl LogTransfer {
    /// Idle, for vehicle `own_system`.
    pub const fn new(own_system: u8) -> Self {
        Self {
            own_system,
            listing: None,
            streaming: None,
            stats: TransferStats {
                requests: 0,
                bytes_sent: 0,
                unknown_log: 0,
                erase_refused: 0,
                not_for_us: 0,
                decode_errors: 0,
                read_errors: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> TransferStats {
        self.stats
    }

    /// `true` while a listing or a download is in progress.
    pub fn busy(&self) -> bool {
        self.listing.is_some() || self.streaming.is_some()
    }

    /// `true` for the message ids this module handles (LOG_REQUEST_LIST, LOG_REQUEST_DATA,
    /// LOG_ERASE, LOG_REQUEST_END).
    pub fn handles(msg_id: u32) -> bool {
        matches!(
            msg_id,
            LOG_REQUEST_LIST_DATA::ID
                | LOG_REQUEST_DATA_DATA::ID
                | LOG_ERASE_DATA::ID
                | LOG_REQUEST_END_DATA::ID
        )
    }

    fn for_me(&mut self, ts: u8, tc: u8) -> bool {
        let ok = addressed_to(ts, tc, (self.own_system, AUTOPILOT_COMPONENT_ID));
        if !ok {
            self.stats.not_for_us = self.stats.not_for_us.saturating_add(1);
        }
        ok
    }

    fn decode_failed(&mut self) -> bool {
        self.stats.decode_errors = self.stats.decode_errors.saturating_add(1);
        true
    }

    /// Takes a CRC-checked frame: `true` if it is a log request (handled here: the caller
    /// must not pass it on), `false` for every other message.
    pub fn on_frame<S: LogStore>(&mut self, f: &RawFrame<'_>, store: &mut S) -> bool {
        if !Self::handles(f.msg_id) {
            return false;
        }
        match f.msg_id {
            LOG_REQUEST_LIST_DATA::ID => {
                let Some(m) = de::<LOG_REQUEST_LIST_DATA>(f.payload) else { return self.decode_failed() };
                if self.for_me(m.target_system, m.target_component) {
                    self.stats.requests = self.stats.requests.saturating_add(1);
                    self.listing = Some(Listing { next: m.start, end: m.end.max(m.start) });
                }
            }
            LOG_REQUEST_DATA_DATA::ID => {
                let Some(m) = de::<LOG_REQUEST_DATA_DATA>(f.payload) else { return self.decode_failed() };
                if self.for_me(m.target_system, m.target_component) {
                    self.stats.requests = self.stats.requests.saturating_add(1);
                    self.start_stream(&m, store);
                }
            }
            LOG_ERASE_DATA::ID => {
                let Some(m) = de::<LOG_ERASE_DATA>(f.payload) else { return self.decode_failed() };
                if self.for_me(m.target_system, m.target_component) {
                    self.stats.requests = self.stats.requests.saturating_add(1);
                    if store.erase_all().is_err() {
                        self.stats.erase_refused = self.stats.erase_refused.saturating_add(1);
                    } else {
                        self.streaming = None;
                        self.listing = None;
                    }
                }
            }
            _ => {
                let Some(m) = de::<LOG_REQUEST_END_DATA>(f.payload) else { return self.decode_failed() };
                if self.for_me(m.target_system, m.target_component) {
                    self.stats.requests = self.stats.requests.saturating_add(1);
                    self.streaming = None;
                }
            }
        }
        true
    }

    fn start_stream<S: LogStore>(&mut self, m: &LOG_REQUEST_DATA_DATA, store: &mut S) {
        let Some(info) = store.info(m.id) else {
            self.stats.unknown_log = self.stats.unknown_log.saturating_add(1);
            self.streaming = None;
            return;
        };
        let wanted_end = m.ofs.saturating_add(m.count);
        let end = wanted_end.min(info.size);
        self.streaming = Some(Streaming {
            index: m.id,
            ofs: m.ofs.min(info.size),
            end,
            terminate: wanted_end >= info.size,
            last_full: true,
        });
    }

    /// Sends up to [`REPLIES_PER_POLL`] pending messages through `emit`.
    pub fn poll<S: LogStore>(&mut self, store: &mut S, emit: &mut impl FnMut(LogReply)) {
        for _ in 0..REPLIES_PER_POLL {
            if let Some(l) = self.listing {
                emit(LogReply::Entry(self.entry(l.next, store)));
                let n = store.count();
                self.listing = if l.next >= l.end || l.next.saturating_add(1) >= n {
                    None
                } else {
                    Some(Listing { next: l.next + 1, end: l.end })
                };
                continue;
            }
            let Some(s) = self.streaming else { return };
            if let Some(reply) = self.next_chunk(s, store) {
                emit(reply);
            }
        }
    }

    fn entry<S: LogStore>(&self, index: u16, store: &S) -> LOG_ENTRY_DATA {
        let n = store.count();
        match store.info(index) {
            Some(info) => LOG_ENTRY_DATA {
                time_utc: info.time_utc,
                size: info.size,
                id: index,
                num_logs: n,
                last_log_num: n.saturating_sub(1),
            },
            // Empty store (or a start beyond the last log): "no logs" / the count only.
            None => {
                LOG_ENTRY_DATA { time_utc: 0, size: 0, id: 0, num_logs: n, last_log_num: n.saturating_sub(1) }
            }
        }
    }

    fn next_chunk<S: LogStore>(&mut self, s: Streaming, store: &mut S) -> Option<LogReply> {
        let id = store.info(s.index).map(|i| i.id);
        let mut data = [0u8; CHUNK];
        if s.ofs >= s.end {
            self.streaming = None;
            // The terminator: only when the range reached the end of the log and the last
            // chunk was a full one (a short chunk already ends the download).
            return (s.terminate && s.last_full).then_some(LogReply::Data(LOG_DATA_DATA {
                ofs: s.ofs,
                id: s.index,
                count: 0,
                data,
            }));
        }
        let Some(id) = id else {
            self.stats.unknown_log = self.stats.unknown_log.saturating_add(1);
            self.streaming = None;
            return None;
        };
        let want = ((s.end - s.ofs) as usize).min(CHUNK);
        let n = match store.read(id, s.ofs, data.get_mut(..want).unwrap_or(&mut [])) {
            Ok(n) => n,
            Err(_) => {
                self.stats.read_errors = self.stats.read_errors.saturating_add(1);
                self.streaming = None;
                return None;
            }
        };
        if n == 0 {
            self.streaming = None;
            return None;
        }
        self.stats.bytes_sent = self.stats.bytes_sent.saturating_add(n as u32);
        let next = Streaming { ofs: s.ofs + n as u32, last_full: n == CHUNK, ..s };
        // A short chunk at the end of the log ends the download by itself.
        self.streaming =
            if next.ofs >= next.end && !(next.terminate && next.last_full) { None } else { Some(next) };
        Some(LogReply::Data(LOG_DATA_DATA { ofs: s.ofs, id: s.index, count: n as u8, data }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::store::RamRing;
    use std::vec::Vec;

    fn frame<D: MessageData>(m: &D) -> (u32, Vec<u8>) {
        let mut w = FrameWriter::new(255, 190);
        let raw = w.encode(m);
        (D::ID, raw.payload().to_vec())
    }

    fn send<S: LogStore>(t: &mut LogTransfer, s: &mut S, f: (u32, Vec<u8>)) -> bool {
        t.on_frame(&RawFrame { msg_id: f.0, sys_id: 255, comp_id: 190, seq: 0, payload: &f.1 }, s)
    }

    fn drain<S: LogStore>(t: &mut LogTransfer, s: &mut S) -> Vec<LogReply> {
        let mut out = Vec::new();
        for _ in 0..10_000 {
            let before = out.len();
            t.poll(s, &mut |r| out.push(r));
            assert!(out.len() - before <= REPLIES_PER_POLL);
            if !t.busy() {
                break;
            }
        }
        out
    }

    fn store_with(sizes: &[usize]) -> RamRing<4096, 8> {
        let mut s = RamRing::new();
        for (k, &n) in sizes.iter().enumerate() {
            s.begin(0).unwrap();
            s.append(&(0..n).map(|i| (i as u8).wrapping_add(k as u8)).collect::<Vec<u8>>()).unwrap();
            s.end();
        }
        s
    }

    fn download<S: LogStore>(
        t: &mut LogTransfer,
        s: &mut S,
        id: u16,
        ofs: u32,
        count: u32,
    ) -> (Vec<u8>, Vec<u8>) {
        let req = LOG_REQUEST_DATA_DATA { ofs, count, id, target_system: 1, target_component: 1 };
        assert!(send(t, s, frame(&req)));
        let mut bytes = Vec::new();
        let mut counts = Vec::new();
        for r in drain(t, s) {
            let LogReply::Data(d) = r else { panic!("not LOG_DATA") };
            assert_eq!(d.id, id);
            assert_eq!(d.ofs as usize, ofs as usize + bytes.len());
            bytes.extend_from_slice(&d.data[..usize::from(d.count)]);
            counts.push(d.count);
        }
        (bytes, counts)
    }

    #[test]
    fn list_then_fetch_every_log() {
        let mut s = store_with(&[200, 180, 7]);
        let mut t = LogTransfer::new(1);
        let req = LOG_REQUEST_LIST_DATA { start: 0, end: 0xFFFF, target_system: 1, target_component: 0 };
        assert!(send(&mut t, &mut s, frame(&req)));
        let entries: Vec<LOG_ENTRY_DATA> = drain(&mut t, &mut s)
            .into_iter()
            .map(|r| match r {
                LogReply::Entry(e) => e,
                LogReply::Data(_) => panic!("data in a listing"),
            })
            .collect();
        assert_eq!(entries.iter().map(|e| (e.id, e.size)).collect::<Vec<_>>(), [(0, 200), (1, 180), (2, 7)]);
        assert!(entries.iter().all(|e| e.num_logs == 3 && e.last_log_num == 2));
        // 200 = 2 × 90 + 20: the short chunk ends it; 180 = 2 × 90: a count-0 terminator.
        let (b, c) = download(&mut t, &mut s, 0, 0, u32::MAX);
        assert_eq!(b, (0..200).map(|i| i as u8).collect::<Vec<u8>>());
        assert_eq!(c, [90, 90, 20]);
        let (b, c) = download(&mut t, &mut s, 1, 0, u32::MAX);
        assert_eq!(b.len(), 180);
        assert_eq!(c, [90, 90, 0]);
        // A part from the middle; past the end: one terminator.
        let (b, c) = download(&mut t, &mut s, 0, 100, 50);
        assert_eq!((b[0], b.len(), c), (100, 50, std::vec![50]));
        let (b, c) = download(&mut t, &mut s, 2, 7, 90);
        assert_eq!((b.len(), c), (0, std::vec![0]));
        assert!(t.stats().bytes_sent >= 430);
    }

    #[test]
    fn empty_store_unknown_ids_end_and_erase() {
        let mut s = store_with(&[]);
        let mut t = LogTransfer::new(1);
        let list = LOG_REQUEST_LIST_DATA { start: 0, end: 0xFFFF, target_system: 0, target_component: 0 };
        send(&mut t, &mut s, frame(&list));
        let r = drain(&mut t, &mut s);
        assert_eq!(r.len(), 1);
        assert!(matches!(&r[0], LogReply::Entry(e) if e.num_logs == 0));
        let (b, _) = download(&mut t, &mut s, 3, 0, 10);
        assert!(b.is_empty());
        assert_eq!(t.stats().unknown_log, 1);

        let mut s = store_with(&[1000]);
        let req =
            LOG_REQUEST_DATA_DATA { ofs: 0, count: u32::MAX, id: 0, target_system: 1, target_component: 1 };
        send(&mut t, &mut s, frame(&req));
        let mut n = 0;
        t.poll(&mut s, &mut |_| n += 1);
        assert_eq!(n, REPLIES_PER_POLL);
        send(&mut t, &mut s, frame(&LOG_REQUEST_END_DATA { target_system: 1, target_component: 1 }));
        assert!(!t.busy());
        // Erase refused while a log is open, done otherwise; other vehicles' requests ignored.
        s.begin(0).unwrap();
        send(&mut t, &mut s, frame(&LOG_ERASE_DATA { target_system: 1, target_component: 1 }));
        assert_eq!((t.stats().erase_refused, s.count()), (1, 2));
        s.end();
        send(&mut t, &mut s, frame(&LOG_ERASE_DATA { target_system: 9, target_component: 1 }));
        assert_eq!((t.stats().not_for_us, s.count()), (1, 2));
        send(&mut t, &mut s, frame(&LOG_ERASE_DATA { target_system: 1, target_component: 1 }));
        assert_eq!(s.count(), 0);
        // Other messages are not taken; a garbled request is counted.
        assert!(!t.on_frame(&RawFrame { msg_id: 0, sys_id: 1, comp_id: 1, seq: 0, payload: &[] }, &mut s));
    }
}
