//! Where flight logs are kept: the [`LogStore`] trait (open one log, append, close; list, read,
//! erase) and [`RamRing`], its implementation in RAM (the QEMU board, host tests).
//!
//! Capacity rule of every store: a new log evicts the oldest logs as its bytes overwrite them
//! (ring), and at most `L` logs are listed (a new log beyond that evicts the oldest). A single
//! log larger than the whole store is cut at the capacity: further appends fail with
//! [`LogError::Full`] (counted by the logger) and the bytes written so far stay readable, so the
//! ULog header and definitions at its start are never overwritten.
//!
//! May import: [`crate::log::ulog`] (the error type), `parapet_core::wire::ulog` (the sink trait).

use heapless::Deque;

use parapet_core::wire::ulog::ULogSink;

use crate::log::ulog::LogError;

/// One stored log as the MAVLink log protocol lists it (LOG_ENTRY).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LogInfo {
    /// Log id (1, 2, …; unique until it wraps at 65535).
    pub id: u16,
    /// Bytes.
    pub size: u32,
    /// UTC time of the log's start, s since 1970 (0 = unknown: no GPS time on this vehicle).
    pub time_utc: u32,
}

/// A log store. Bounded: every call does work proportional to its byte count (or the number of
/// listed logs, at most a few dozen).
pub trait LogStore {
    /// Starts a new log (closing an open one); returns its id.
    fn begin(&mut self, time_utc: u32) -> Result<u16, LogError>;
    /// Appends to the open log.
    fn append(&mut self, bytes: &[u8]) -> Result<(), LogError>;
    /// Closes the open log (no effect without one).
    fn end(&mut self);
    /// `true` while a log is open.
    fn is_open(&self) -> bool;
    /// Number of stored logs (the open one included).
    fn count(&self) -> u16;
    /// The `index`-th stored log, oldest first.
    fn info(&self, index: u16) -> Option<LogInfo>;
    /// Reads bytes of log `id` from offset `ofs` into `buf`; returns how many (0 at the end).
    fn read(&mut self, id: u16, ofs: u32, buf: &mut [u8]) -> Result<usize, LogError>;
    /// Erases every log; refused ([`LogError::Busy`]) while one is open.
    fn erase_all(&mut self) -> Result<(), LogError>;

    /// The stored log with `id`.
    fn find(&self, id: u16) -> Option<LogInfo> {
        (0..self.count()).filter_map(|i| self.info(i)).find(|l| l.id == id)
    }
}

/// A store's open log as the ULog writer's sink (each message appended in one piece).
pub struct Appender<'a, S>(pub &'a mut S);

impl<S: LogStore> ULogSink for Appender<'_, S> {
    type Error = LogError;
    fn write(&mut self, bytes: &[u8]) -> Result<(), LogError> {
        self.0.append(bytes)
    }
}

#[derive(Clone, Copy, Debug)]
struct Entry {
    id: u16,
    /// Absolute position of the first byte (bytes ever written before it).
    start: u64,
    len: u32,
    time_utc: u32,
}

/// A ring of `N` bytes holding at most `L` logs (see the module doc for the capacity rule).
pub struct RamRing<const N: usize, const L: usize> {
    data: [u8; N],
    /// Bytes ever written (absolute position of the next byte).
    head: u64,
    logs: Deque<Entry, L>,
    open: bool,
    /// Id of the next log; 0 stands for 1, so that a new store is all zero (placed in .bss,
    /// not copied from flash).
    next_id: u16,
}

impl<const N: usize, const L: usize> Default for RamRing<N, L> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const L: usize> RamRing<N, L> {
    /// An empty store.
    pub const fn new() -> Self {
        Self { data: [0; N], head: 0, logs: Deque::new(), open: false, next_id: 0 }
    }

    /// Capacity, bytes.
    pub const fn capacity(&self) -> usize {
        N
    }

    fn evict_overwritten(&mut self) {
        let oldest_kept = self.head.saturating_sub(N as u64);
        while let Some(first) = self.logs.front() {
            let last_open = self.open && self.logs.len() == 1;
            if first.start >= oldest_kept || last_open {
                break;
            }
            self.logs.pop_front();
        }
    }
}

impl<const N: usize, const L: usize> LogStore for RamRing<N, L> {
    fn begin(&mut self, time_utc: u32) -> Result<u16, LogError> {
        self.end();
        if L == 0 || N == 0 {
            return Err(LogError::Full);
        }
        if self.logs.is_full() {
            self.logs.pop_front();
        }
        let id = self.next_id.max(1);
        self.next_id = if id == u16::MAX { 1 } else { id + 1 };
        self.logs.push_back(Entry { id, start: self.head, len: 0, time_utc }).map_err(|_| LogError::Full)?;
        self.open = true;
        Ok(id)
    }

    fn append(&mut self, bytes: &[u8]) -> Result<(), LogError> {
        if !self.open {
            return Err(LogError::NotOpen);
        }
        let Some(e) = self.logs.back_mut() else { return Err(LogError::NotOpen) };
        let new_len = (e.len as usize).saturating_add(bytes.len());
        if new_len > N {
            return Err(LogError::Full);
        }
        e.len = new_len as u32;
        // Two slice copies: up to the end of the ring, then the rest from its start.
        let pos = (self.head % N as u64) as usize;
        let first = bytes.len().min(N - pos);
        let (a, b) = bytes.split_at(first);
        if let Some(d) = self.data.get_mut(pos..pos + first) {
            d.copy_from_slice(a);
        }
        if let Some(d) = self.data.get_mut(..b.len()) {
            d.copy_from_slice(b);
        }
        self.head += bytes.len() as u64;
        self.evict_overwritten();
        Ok(())
    }

    fn end(&mut self) {
        self.open = false;
    }

    fn is_open(&self) -> bool {
        self.open
    }

    fn count(&self) -> u16 {
        self.logs.len() as u16
    }

    fn info(&self, index: u16) -> Option<LogInfo> {
        let e = self.logs.iter().nth(usize::from(index))?;
        Some(LogInfo { id: e.id, size: e.len, time_utc: e.time_utc })
    }

    fn read(&mut self, id: u16, ofs: u32, buf: &mut [u8]) -> Result<usize, LogError> {
        let e = *self.logs.iter().find(|e| e.id == id).ok_or(LogError::NotFound)?;
        let n = (e.len.saturating_sub(ofs) as usize).min(buf.len());
        let pos = ((e.start + u64::from(ofs)) % N as u64) as usize;
        let first = n.min(N - pos);
        let (a, b) = buf.split_at_mut(first);
        if let Some(s) = self.data.get(pos..pos + first) {
            a.copy_from_slice(s);
        }
        if let (Some(b), Some(s)) = (b.get_mut(..n - first), self.data.get(..n - first)) {
            b.copy_from_slice(s);
        }
        Ok(n)
    }

    fn erase_all(&mut self) -> Result<(), LogError> {
        if self.open {
            return Err(LogError::Busy);
        }
        self.logs.clear();
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::vec::Vec;

    /// All bytes of log `id`, read in short pieces.
    pub(crate) fn read_all<S: LogStore>(s: &mut S, id: u16) -> Vec<u8> {
        let mut out = Vec::new();
        let mut buf = [0u8; 7];
        loop {
            let n = s.read(id, out.len() as u32, &mut buf).unwrap();
            if n == 0 {
                return out;
            }
            out.extend_from_slice(&buf[..n]);
        }
    }

    #[test]
    fn logs_round_trip_and_the_oldest_is_overwritten() {
        let mut s: RamRing<100, 4> = RamRing::new();
        assert_eq!(s.append(b"x"), Err(LogError::NotOpen));
        let a = s.begin(11).unwrap();
        s.append(&[1; 40]).unwrap();
        s.end();
        let b = s.begin(22).unwrap();
        s.append(&[2; 30]).unwrap();
        s.append(&[3; 10]).unwrap();
        s.end();
        assert_eq!((a, b), (1, 2));
        assert_eq!(s.count(), 2);
        assert_eq!(s.info(0), Some(LogInfo { id: 1, size: 40, time_utc: 11 }));
        assert_eq!(read_all(&mut s, b), [[2u8; 30].as_slice(), &[3; 10]].concat());
        // A third log of 30 bytes wraps the ring over the start of log 1: log 1 is gone.
        let c = s.begin(33).unwrap();
        s.append(&(0..30).collect::<Vec<u8>>()).unwrap();
        s.end();
        assert_eq!(s.count(), 2);
        assert_eq!(s.find(a), None);
        assert_eq!(s.read(a, 0, &mut [0; 4]), Err(LogError::NotFound));
        assert_eq!(read_all(&mut s, c), (0..30).collect::<Vec<u8>>());
        assert_eq!(read_all(&mut s, b).len(), 40);
        // Reads past the end return nothing.
        assert_eq!(s.read(c, 30, &mut [0; 4]), Ok(0));
        assert_eq!(s.read(c, 1000, &mut [0; 4]), Ok(0));
    }

    #[test]
    fn a_log_larger_than_the_store_is_cut_and_keeps_its_start() {
        let mut s: RamRing<64, 4> = RamRing::new();
        s.begin(0).unwrap();
        s.append(&[0; 10]).unwrap();
        s.end();
        let id = s.begin(0).unwrap();
        s.append(&[7; 60]).unwrap();
        assert_eq!(s.append(&[8; 5]), Err(LogError::Full));
        s.append(&[9; 4]).unwrap();
        assert_eq!(s.count(), 1, "the older log was overwritten");
        assert_eq!(s.erase_all(), Err(LogError::Busy));
        s.end();
        assert_eq!(read_all(&mut s, id), [[7u8; 60].as_slice(), &[9; 4]].concat());
        s.erase_all().unwrap();
        assert_eq!(s.count(), 0);
    }

    #[test]
    fn at_most_l_logs_are_listed_and_ids_wrap_past_zero() {
        let mut s: RamRing<64, 2> = RamRing::new();
        s.next_id = u16::MAX;
        for _ in 0..3 {
            s.begin(0).unwrap();
            s.append(b"ab").unwrap();
        }
        s.end();
        let ids: Vec<u16> = (0..s.count()).filter_map(|i| s.info(i)).map(|l| l.id).collect();
        assert_eq!(ids, [1, 2]);
    }
}
