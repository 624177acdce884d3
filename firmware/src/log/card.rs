//! Flight logs on a block device (a microSD card, 512-byte blocks) without a file system:
//! [`CardStore`], a [`LogStore`] over the [`BlockDevice`] trait (the board's SD driver behind
//! it; [`RamBlocks`] in RAM for host tests).
//!
//! **On-card layout** (format version [`FORMAT_VERSION`]; little-endian):
//!
//! | blocks | what |
//! |---|---|
//! | 0, 1 | two copies of the directory: magic `PRPTLOG\0`, version u16, log count u16, generation u32, ring head (absolute data block) u32, ring size (blocks) u32, next log id u16, open flag u8, then up to [`MAX_LOGS`] entries of 20 B (id u16, 0 u16, first absolute data block u32, blocks u32, bytes u32, UTC start u32), CRC-16/MCRF4XX of bytes 0..510 in 510..512 |
//! | 2 .. 2 + ring | the data ring: absolute data block `a` is card block `2 + a % ring`; every data block holds [`PAYLOAD`] = 504 log bytes, then the log id u16, the bytes used u16 and a CRC-16 over the payload, id, bytes used and `a` (so a stale block of an earlier lap fails it) |
//!
//! A log is a run of consecutive absolute blocks, each full but the last. Directory updates
//! alternate between the copies (generation parity) and the newer valid copy wins at mount, so
//! a power cut during any single block write keeps the previous directory. The directory is
//! written at `begin` (the new entry, open), every [`FLUSH_BLOCKS`] data blocks, at `end`, and
//! *before* a data block overwrites the oldest log (the entry is dropped first: a closed log in
//! the directory is never overwritten). At mount an open log is recovered by reading up to
//! [`FLUSH_BLOCKS`] + 1 blocks past its recorded length and keeping each block whose id and
//! CRC match (the open log keeps every block written before the cut; the bytes still in the
//! RAM buffer are lost). No valid copy, or another version, formats the card (both copies
//! rewritten, every log gone; [`Mounted`] says why, for a STATUSTEXT). The card is the log's
//! alone: a FAT file system on it is overwritten at the first mount.
//!
//! **Bounded work**: an append writes at most one data block per 504 bytes given (≤ 1 for a
//! ULog record set of ≈ 300 B, plus one directory write every 16 blocks or at an eviction); a
//! read reads at most `buf.len() / 504 + 2` blocks (one block is cached); mount reads at most
//! 2 + [`FLUSH_BLOCKS`] + 1 blocks. **Failure**: a device error (card absent, not answering,
//! a write refused) turns the store off: every later call returns [`LogError::Device`], nothing
//! is listed, and [`CardStore::take_fault`] gives one message for a STATUSTEXT. The flight is
//! unaffected (the store runs in the log task only).
//!
//! Written by hand: the FAT of `embedded-sdmmc` (≈ 20 KB of flash; the F405 image must fit
//! 128 KiB) has no power-cut guarantee for an open file and unbounded cluster-chain walks; this
//! layout is `no_std`, bounded per call and ≈ 2 KB of code. The CRC is the MAVLink one
//! (`crc-any`, already linked).
//!
//! May import: [`crate::log::store`], [`crate::log::ulog`] (the error type).

use crc_any::CRCu16;
use heapless::Deque;

use crate::log::store::{LogInfo, LogStore};
use crate::log::ulog::LogError;

/// Bytes of a block.
pub const BLOCK: usize = 512;
/// Log bytes in one data block.
pub const PAYLOAD: usize = BLOCK - 8;
/// Logs listed at most (the oldest is dropped beyond).
pub const MAX_LOGS: usize = 16;
/// Data blocks between directory writes of an open log (8 KB, ≈ 1 s of log at 25 Hz).
pub const FLUSH_BLOCKS: u32 = 16;
/// On-card format version.
pub const FORMAT_VERSION: u16 = 1;
/// Most data blocks used (1 GiB): larger cards use their first GiB.
pub const MAX_RING: u32 = 1 << 21;
const MAGIC: [u8; 8] = *b"PRPTLOG\0";
const DATA_START: u32 = 2;
const ENTRY_AT: usize = 32;
const ENTRY_LEN: usize = 20;

/// A device of 512-byte blocks.
pub trait BlockDevice {
    /// Reads block `lba`.
    fn read(&mut self, lba: u32, buf: &mut [u8; BLOCK]) -> Result<(), LogError>;
    /// Writes block `lba`.
    fn write(&mut self, lba: u32, buf: &[u8; BLOCK]) -> Result<(), LogError>;
    /// Number of blocks.
    fn blocks(&mut self) -> Result<u32, LogError>;
}

/// What mounting found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mounted {
    /// A valid directory.
    Clean,
    /// A valid directory with a log open at a power cut: recovered up to its last written block.
    Recovered,
    /// No valid directory (new or corrupt card): formatted.
    FormattedCorrupt,
    /// A directory of another format version: formatted.
    FormattedVersion,
}

impl Mounted {
    /// The STATUSTEXT for a formatted card, `None` otherwise.
    pub fn text(self) -> Option<&'static str> {
        match self {
            Mounted::Clean | Mounted::Recovered => None,
            Mounted::FormattedCorrupt => Some("log card: no valid directory, formatted"),
            Mounted::FormattedVersion => Some("log card: other format version, formatted"),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Entry {
    id: u16,
    start: u32,
    blocks: u32,
    bytes: u32,
    time_utc: u32,
}

fn crc(parts: &[&[u8]]) -> u16 {
    let mut c = CRCu16::crc16mcrf4cc();
    for p in parts {
        c.digest(p);
    }
    c.get_crc()
}

fn get_u16(b: &[u8], at: usize) -> u16 {
    b.get(at..at + 2).map_or(0, |s| u16::from_le_bytes([s[0], s[1]]))
}

fn get_u32(b: &[u8], at: usize) -> u32 {
    b.get(at..at + 4).map_or(0, |s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

fn put(b: &mut [u8], at: usize, v: &[u8]) {
    if let Some(d) = b.get_mut(at..at + v.len()) {
        d.copy_from_slice(v);
    }
}

/// A log store on a block device (see the module doc).
pub struct CardStore<D: BlockDevice> {
    dev: D,
    /// `false` once the device failed (or never answered).
    on: bool,
    fault: Option<&'static str>,
    ring: u32,
    head: u32,
    generation: u32,
    next_id: u16,
    logs: Deque<Entry, MAX_LOGS>,
    open: bool,
    /// Data blocks of the open log since its last directory write.
    unflushed: u32,
    /// The open log's block being filled (payload bytes `..fill`).
    buf: [u8; BLOCK],
    fill: usize,
    /// A read cache: absolute block in `cache`.
    cache: [u8; BLOCK],
    cached: Option<u32>,
}

impl<D: BlockDevice> CardStore<D> {
    /// A store that is off (every call fails with [`LogError::Device`]) until [`Self::mount`].
    pub const fn new(dev: D) -> Self {
        Self {
            dev,
            on: false,
            fault: None,
            ring: 0,
            head: 0,
            generation: 0,
            next_id: 1,
            logs: Deque::new(),
            open: false,
            unflushed: 0,
            buf: [0; BLOCK],
            fill: 0,
            cache: [0; BLOCK],
            cached: None,
        }
    }

    /// Reads the directory (formatting the card when it has none, recovering an open log).
    /// A device error leaves the store off (see [`Self::take_fault`]).
    pub fn mount(&mut self) -> Result<Mounted, LogError> {
        self.on = false;
        self.cached = None;
        let r = self.try_mount();
        match r {
            Ok(_) => self.on = true,
            Err(_) => self.fault = Some("log card: absent or not answering, logging off"),
        }
        r
    }

    fn try_mount(&mut self) -> Result<Mounted, LogError> {
        let blocks = self.dev.blocks()?;
        let ring = blocks.saturating_sub(DATA_START).min(MAX_RING);
        if ring < 2 * FLUSH_BLOCKS {
            return Err(LogError::Device);
        }
        let mut best: Option<(u32, u32)> = None;
        let mut other_version = false;
        for copy in 0..2u32 {
            self.dev.read(copy, &mut self.cache)?;
            let b = &self.cache;
            if b[..8] != MAGIC || crc(&[&b[..510]]) != get_u16(b, 510) {
                continue;
            }
            if get_u16(b, 8) != FORMAT_VERSION || get_u32(b, 20) != ring {
                other_version = true;
                continue;
            }
            let g = get_u32(b, 12);
            if best.is_none_or(|(bg, _)| g.wrapping_sub(bg) < u32::MAX / 2) {
                best = Some((g, copy));
            }
        }
        let Some((_, copy)) = best else {
            self.ring = ring;
            self.head = 0;
            self.next_id = 1;
            self.logs.clear();
            self.open = false;
            // Both copies, so that neither holds an older directory.
            self.write_dir()?;
            self.write_dir()?;
            return Ok(if other_version { Mounted::FormattedVersion } else { Mounted::FormattedCorrupt });
        };
        self.dev.read(copy, &mut self.cache)?;
        let b = &self.cache;
        self.generation = get_u32(b, 12);
        self.head = get_u32(b, 16);
        self.ring = ring;
        self.next_id = get_u16(b, 24).max(1);
        let was_open = b[26] != 0;
        self.logs.clear();
        for i in 0..usize::from(get_u16(b, 10)).min(MAX_LOGS) {
            let at = ENTRY_AT + i * ENTRY_LEN;
            let e = Entry {
                id: get_u16(b, at),
                start: get_u32(b, at + 4),
                blocks: get_u32(b, at + 8),
                bytes: get_u32(b, at + 12),
                time_utc: get_u32(b, at + 16),
            };
            let _ = self.logs.push_back(e);
        }
        self.open = false;
        if !was_open {
            return Ok(Mounted::Clean);
        }
        self.recover()?;
        self.write_dir()?;
        Ok(Mounted::Recovered)
    }

    /// Extends the last (open at the cut) log by the blocks written after its last directory.
    fn recover(&mut self) -> Result<(), LogError> {
        let Some(mut e) = self.logs.back().copied() else { return Ok(()) };
        for _ in 0..=FLUSH_BLOCKS {
            let a = e.start.wrapping_add(e.blocks);
            if e.blocks >= self.ring {
                break;
            }
            let Some(used) = self.read_data(a, e.id)? else { break };
            e.blocks += 1;
            e.bytes = e.bytes.saturating_add(used as u32);
            if used < PAYLOAD {
                break;
            }
        }
        self.head = e.start.wrapping_add(e.blocks);
        if let Some(last) = self.logs.back_mut() {
            *last = e;
        }
        Ok(())
    }

    /// Reads absolute data block `a` into the cache: `Some(bytes used)` if it belongs to log `id`.
    fn read_data(&mut self, a: u32, id: u16) -> Result<Option<usize>, LogError> {
        if self.cached != Some(a) {
            self.cached = None;
            self.dev.read(DATA_START + a % self.ring, &mut self.cache)?;
            self.cached = Some(a);
        }
        let b = &self.cache;
        let used = usize::from(get_u16(b, PAYLOAD + 2));
        let ok = get_u16(b, PAYLOAD) == id
            && used <= PAYLOAD
            && crc(&[&b[..PAYLOAD + 4], &a.to_le_bytes()]) == get_u16(b, PAYLOAD + 4 + 2);
        Ok(ok.then_some(used))
    }

    fn write_dir(&mut self) -> Result<(), LogError> {
        self.generation = self.generation.wrapping_add(1);
        let mut b = [0u8; BLOCK];
        put(&mut b, 0, &MAGIC);
        put(&mut b, 8, &FORMAT_VERSION.to_le_bytes());
        put(&mut b, 10, &(self.logs.len() as u16).to_le_bytes());
        put(&mut b, 12, &self.generation.to_le_bytes());
        put(&mut b, 16, &self.head.to_le_bytes());
        put(&mut b, 20, &self.ring.to_le_bytes());
        put(&mut b, 24, &self.next_id.to_le_bytes());
        b[26] = u8::from(self.open);
        for (i, e) in self.logs.iter().enumerate() {
            let at = ENTRY_AT + i * ENTRY_LEN;
            put(&mut b, at, &e.id.to_le_bytes());
            put(&mut b, at + 4, &e.start.to_le_bytes());
            put(&mut b, at + 8, &e.blocks.to_le_bytes());
            put(&mut b, at + 12, &e.bytes.to_le_bytes());
            put(&mut b, at + 16, &e.time_utc.to_le_bytes());
        }
        let c = crc(&[&b[..510]]);
        put(&mut b, 510, &c.to_le_bytes());
        let r = self.dev.write(self.generation % 2, &b);
        self.unflushed = 0;
        self.fail_on(r)
    }

    fn fail_on<T>(&mut self, r: Result<T, LogError>) -> Result<T, LogError> {
        if r.is_err() {
            self.on = false;
            self.open = false;
            self.fault = Some("log card: write failed, logging off");
        }
        r
    }

    /// Writes the filled block of the open log (bytes used `fill`) at the ring head.
    fn write_block(&mut self) -> Result<(), LogError> {
        let Some(e) = self.logs.back().copied() else { return Err(LogError::NotOpen) };
        if e.blocks >= self.ring {
            return Err(LogError::Full);
        }
        let a = self.head;
        // The oldest logs whose blocks `a` overwrites leave the directory first.
        let mut evicted = false;
        while self.logs.len() > 1 && self.logs.front().is_some_and(|f| a.wrapping_sub(f.start) >= self.ring) {
            self.logs.pop_front();
            evicted = true;
        }
        if evicted {
            self.write_dir()?;
        }
        self.buf[PAYLOAD..PAYLOAD + 2].copy_from_slice(&e.id.to_le_bytes());
        self.buf[PAYLOAD + 2..PAYLOAD + 4].copy_from_slice(&(self.fill as u16).to_le_bytes());
        let c = crc(&[&self.buf[..PAYLOAD + 4], &a.to_le_bytes()]);
        self.buf[PAYLOAD + 6..].copy_from_slice(&c.to_le_bytes());
        if self.cached == Some(a) {
            self.cached = None;
        }
        let r = self.dev.write(DATA_START + a % self.ring, &self.buf);
        self.fail_on(r)?;
        self.head = a.wrapping_add(1);
        if let Some(last) = self.logs.back_mut() {
            last.blocks += 1;
            last.bytes = last.bytes.saturating_add(self.fill as u32);
        }
        self.fill = 0;
        self.buf = [0; BLOCK];
        self.unflushed += 1;
        if self.unflushed >= FLUSH_BLOCKS {
            self.write_dir()?;
        }
        Ok(())
    }

    /// The message of a fault that turned the store off (once), for a STATUSTEXT.
    pub fn take_fault(&mut self) -> Option<&'static str> {
        self.fault.take()
    }

    /// `true` while the store works.
    pub fn is_on(&self) -> bool {
        self.on
    }

    /// The device (e.g. to change a bus clock).
    pub fn device(&mut self) -> &mut D {
        &mut self.dev
    }

    fn check_on(&self) -> Result<(), LogError> {
        if self.on {
            Ok(())
        } else {
            Err(LogError::Device)
        }
    }
}

impl<D: BlockDevice> LogStore for CardStore<D> {
    fn begin(&mut self, time_utc: u32) -> Result<u16, LogError> {
        self.end();
        self.check_on()?;
        if self.logs.is_full() {
            self.logs.pop_front();
        }
        let id = self.next_id.max(1);
        self.next_id = if id == u16::MAX { 1 } else { id + 1 };
        let e = Entry { id, start: self.head, blocks: 0, bytes: 0, time_utc };
        self.logs.push_back(e).map_err(|_| LogError::Full)?;
        self.open = true;
        self.fill = 0;
        self.buf = [0; BLOCK];
        self.write_dir()?;
        Ok(id)
    }

    fn append(&mut self, mut bytes: &[u8]) -> Result<(), LogError> {
        self.check_on()?;
        if !self.open {
            return Err(LogError::NotOpen);
        }
        while !bytes.is_empty() {
            let n = bytes.len().min(PAYLOAD - self.fill);
            let (a, rest) = bytes.split_at(n);
            self.buf[self.fill..self.fill + n].copy_from_slice(a);
            self.fill += n;
            bytes = rest;
            if self.fill == PAYLOAD {
                if let Err(e) = self.write_block() {
                    // Full: the block stays unwritten, the log keeps what it has.
                    self.fill = PAYLOAD - n;
                    return Err(e);
                }
            }
        }
        Ok(())
    }

    fn end(&mut self) {
        if !self.open || !self.on {
            self.open = false;
            return;
        }
        let r = if self.fill > 0 { self.write_block() } else { Ok(()) };
        self.fill = 0;
        self.open = false;
        if r.is_ok() || r == Err(LogError::Full) {
            let _ = self.write_dir();
        }
    }

    fn is_open(&self) -> bool {
        self.open
    }

    fn count(&self) -> u16 {
        if self.on {
            self.logs.len() as u16
        } else {
            0
        }
    }

    fn info(&self, index: u16) -> Option<LogInfo> {
        if !self.on {
            return None;
        }
        let e = self.logs.iter().nth(usize::from(index))?;
        // The open log's buffered bytes are not readable yet.
        Some(LogInfo { id: e.id, size: e.bytes, time_utc: e.time_utc })
    }

    fn read(&mut self, id: u16, ofs: u32, buf: &mut [u8]) -> Result<usize, LogError> {
        self.check_on()?;
        let e = *self.logs.iter().find(|e| e.id == id).ok_or(LogError::NotFound)?;
        let want = (e.bytes.saturating_sub(ofs) as usize).min(buf.len());
        let mut done = 0;
        while done < want {
            let pos = ofs as usize + done;
            let (k, within) = ((pos / PAYLOAD) as u32, pos % PAYLOAD);
            let used = match self.read_data(e.start.wrapping_add(k), e.id) {
                Ok(Some(u)) => u,
                Ok(None) => return Err(LogError::Device),
                Err(err) => return self.fail_on(Err(err)),
            };
            let n = (want - done).min(used.saturating_sub(within));
            if n == 0 {
                break;
            }
            buf[done..done + n].copy_from_slice(&self.cache[within..within + n]);
            done += n;
        }
        Ok(done)
    }

    fn erase_all(&mut self) -> Result<(), LogError> {
        self.check_on()?;
        if self.open {
            return Err(LogError::Busy);
        }
        self.logs.clear();
        self.write_dir()
    }
}

/// A block device in RAM (host tests): `blocks` blocks; writes fail after `writes_left`
/// (a power cut or a card pulled), reads fail with `absent`.
#[cfg(test)]
pub struct RamBlocks {
    /// The blocks.
    pub data: std::vec::Vec<[u8; BLOCK]>,
    /// Writes that still succeed (`None`: unlimited).
    pub writes_left: Option<u32>,
    /// Writes done.
    pub writes: u32,
    /// Every call fails (no card).
    pub absent: bool,
}

#[cfg(test)]
impl RamBlocks {
    /// `blocks` zeroed blocks.
    pub fn new(blocks: usize) -> Self {
        Self { data: std::vec![[0; BLOCK]; blocks], writes_left: None, writes: 0, absent: false }
    }
}

#[cfg(test)]
impl BlockDevice for RamBlocks {
    fn read(&mut self, lba: u32, buf: &mut [u8; BLOCK]) -> Result<(), LogError> {
        if self.absent {
            return Err(LogError::Device);
        }
        *buf = *self.data.get(lba as usize).ok_or(LogError::Device)?;
        Ok(())
    }
    fn write(&mut self, lba: u32, buf: &[u8; BLOCK]) -> Result<(), LogError> {
        if self.absent || self.writes_left == Some(0) {
            return Err(LogError::Device);
        }
        self.writes_left = self.writes_left.map(|n| n - 1);
        self.writes += 1;
        *self.data.get_mut(lba as usize).ok_or(LogError::Device)? = *buf;
        Ok(())
    }
    fn blocks(&mut self) -> Result<u32, LogError> {
        if self.absent {
            return Err(LogError::Device);
        }
        Ok(self.data.len() as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::logger::tests::{check_with_pyulog, sample};
    use crate::log::logger::{FlightLogger, DEFAULT_PERIOD_US};
    use crate::log::store::tests::read_all;
    use crate::log::store::RamRing;
    use parapet_core::controller::ControllerParams;
    use std::vec::Vec;

    fn mounted(blocks: usize) -> CardStore<RamBlocks> {
        let mut s = CardStore::new(RamBlocks::new(blocks));
        assert_eq!(s.mount(), Ok(Mounted::FormattedCorrupt), "a blank card is formatted");
        s
    }

    /// The same card after a power cycle.
    fn remount(s: CardStore<RamBlocks>) -> (CardStore<RamBlocks>, Result<Mounted, LogError>) {
        let mut dev = s.dev;
        dev.writes_left = None;
        dev.absent = false;
        let mut s = CardStore::new(dev);
        let r = s.mount();
        (s, r)
    }

    fn pattern(seed: u32, n: usize) -> Vec<u8> {
        (0..n).map(|i| (i as u32).wrapping_mul(31).wrapping_add(seed * 7) as u8).collect()
    }

    #[test]
    fn logs_from_the_flight_logger_round_trip_through_the_card_and_pyulog() {
        let params = ControllerParams::default();
        let mut lg_ram = FlightLogger::new(DEFAULT_PERIOD_US, &params, "host-test");
        let mut lg_card = FlightLogger::new(DEFAULT_PERIOD_US, &params, "host-test");
        let mut ram: RamRing<262144, 8> = RamRing::new();
        let mut card = mounted(2 + 1024);
        let get = |n: &str| parapet_core::params::get(&params, n);
        // Three flights: 2 s, 0.5 s, 3 s armed at the 250 Hz outer rate, each with its disarm sample.
        let mut t = 3_000_000u64;
        for steps in [500u64, 125, 750] {
            for k in 0..steps {
                lg_ram.on_sample(&sample(t + k * 4000, true), &mut ram, get);
                lg_card.on_sample(&sample(t + k * 4000, true), &mut card, get);
            }
            t += steps * 4000;
            lg_ram.on_sample(&sample(t, false), &mut ram, get);
            lg_card.on_sample(&sample(t, false), &mut card, get);
            t += 1_000_000;
        }
        assert_eq!(lg_card.stats().store_errors, 0);
        assert_eq!(card.count(), 3);
        let mut logs = Vec::new();
        for i in 0..3 {
            let (a, b) = (ram.info(i).unwrap(), card.info(i).unwrap());
            assert_eq!(a.size, b.size);
            let bytes = read_all(&mut card, b.id);
            assert_eq!(bytes, read_all(&mut ram, a.id), "log {i} byte for byte");
            logs.push(bytes);
        }
        // After a power cycle the card lists and reads the same.
        let (mut card, r) = remount(card);
        assert_eq!(r, Ok(Mounted::Clean));
        for (i, bytes) in logs.iter().enumerate() {
            let id = card.info(i as u16).unwrap().id;
            assert_eq!(&read_all(&mut card, id), bytes);
        }
        check_with_pyulog(&logs[0], "card", &["25", "51", "1", "2"], "ok: 51 records");
    }

    #[test]
    fn the_oldest_log_is_overwritten_and_a_log_larger_than_the_card_is_cut() {
        // 40 data blocks; logs of 15 blocks.
        let mut s = mounted(2 + 40);
        let mut ids = Vec::new();
        for k in 0..3 {
            ids.push(s.begin(k).unwrap());
            s.append(&pattern(k, 15 * PAYLOAD - 10)).unwrap();
            s.end();
        }
        assert_eq!(s.count(), 2, "the first log was overwritten by the third");
        assert_eq!(s.find(ids[0]), None);
        assert_eq!(s.read(ids[0], 0, &mut [0; 4]), Err(LogError::NotFound));
        for k in 1..3 {
            assert_eq!(read_all(&mut s, ids[k as usize]), pattern(k, 15 * PAYLOAD - 10));
        }
        let (mut s, r) = remount(s);
        assert_eq!(r, Ok(Mounted::Clean));
        assert_eq!(s.count(), 2);
        assert_eq!(read_all(&mut s, ids[2]), pattern(2, 15 * PAYLOAD - 10));
        // One log larger than the ring: cut at 40 blocks, its start kept.
        let id = s.begin(9).unwrap();
        let big = pattern(9, 50 * PAYLOAD);
        let mut r = Ok(());
        for c in big.chunks(300) {
            r = s.append(c);
            if r.is_err() {
                break;
            }
        }
        assert_eq!(r, Err(LogError::Full));
        s.end();
        assert_eq!(s.count(), 1);
        let back = read_all(&mut s, id);
        assert_eq!(back.len(), 40 * PAYLOAD);
        assert_eq!(back, big[..40 * PAYLOAD]);
        s.erase_all().unwrap();
        assert_eq!(s.count(), 0);
        let (s, _) = remount(s);
        assert_eq!(s.count(), 0);
    }

    /// The workload of the power-cut test: 5 logs of different lengths (some evict older ones).
    fn workload(s: &mut CardStore<RamBlocks>, closed: &mut Vec<(u16, Vec<u8>, u32)>) -> Result<(), LogError> {
        for k in 0..5u32 {
            let id = s.begin(k)?;
            let start = s.head;
            let data = pattern(k, [700, 9000, 2 * PAYLOAD, 13_000, 333][k as usize]);
            for c in data.chunks(280) {
                s.append(c)?;
            }
            s.end();
            if !s.is_on() {
                return Err(LogError::Device);
            }
            closed.push((id, data, start));
        }
        Ok(())
    }

    #[test]
    fn a_power_cut_at_any_write_keeps_every_closed_log_and_the_open_one_to_its_last_block() {
        // 40 data blocks: the logs take 2, 18, 2, 26, 1 blocks (the 4th evicts the 1st and 2nd).
        let mut full = mounted(2 + 40);
        let w0 = full.dev.writes;
        workload(&mut full, &mut Vec::new()).unwrap();
        let total = full.dev.writes - w0;
        assert!(total > 40, "{total} writes");
        for cut in 0..total {
            let mut s = mounted(2 + 40);
            s.dev.writes_left = Some(cut);
            let mut closed = Vec::new();
            assert!(workload(&mut s, &mut closed).is_err(), "cut {cut}");
            assert!(s.take_fault().is_some() && s.take_fault().is_none(), "one fault message");
            // What the store had on the card when the power went: the open log's written bytes.
            let open = s.logs.back().copied().filter(|e| !closed.iter().any(|(id, _, _)| *id == e.id));
            let (mut s, r) = remount(s);
            assert!(matches!(r, Ok(Mounted::Clean | Mounted::Recovered)), "cut {cut}: {r:?}");
            let listed: Vec<LogInfo> = (0..s.count()).filter_map(|i| s.info(i)).collect();
            for (id, data, start) in &closed {
                // A closed log is listed, unless the ring head passed it (evicted before its
                // blocks were overwritten).
                match listed.iter().find(|l| l.id == *id) {
                    Some(_) => assert_eq!(&read_all(&mut s, *id), data, "cut {cut}: closed log {id}"),
                    None => assert!(s.head - start >= s.ring, "cut {cut}: closed log {id} lost"),
                }
            }
            if let Some(e) = open {
                let k = u32::from(e.id - 1);
                let data = pattern(k, [700, 9000, 2 * PAYLOAD, 13_000, 333][k as usize]);
                if let Some(l) = listed.iter().find(|l| l.id == e.id) {
                    let back = read_all(&mut s, e.id);
                    assert!(l.size >= e.bytes, "cut {cut}: open log kept {} of {} written", l.size, e.bytes);
                    assert_eq!(back, data[..back.len()], "cut {cut}: open log is a prefix");
                } else {
                    assert_eq!(e.bytes, 0, "cut {cut}: an open log with written blocks was lost");
                }
            }
            // The card keeps working after the cut.
            let id = s.begin(77).unwrap();
            s.append(&pattern(77, 1000)).unwrap();
            s.end();
            assert_eq!(read_all(&mut s, id), pattern(77, 1000), "cut {cut}");
        }
    }

    #[test]
    fn a_corrupt_or_foreign_directory_formats_the_card_with_a_message() {
        let mut s = mounted(2 + 64);
        let id = s.begin(0).unwrap();
        s.append(&pattern(1, 2000)).unwrap();
        s.end();
        // The newest copy corrupt: the other one (written at `begin`, the log open) wins and the
        // log is recovered from its blocks.
        let newest = (s.generation % 2) as usize;
        s.dev.data[newest][40] ^= 0x55;
        let (mut s, r) = remount(s);
        assert_eq!(r, Ok(Mounted::Recovered));
        assert_eq!(read_all(&mut s, id), pattern(1, 2000));
        // Both corrupt: formatted, said for a STATUSTEXT.
        s.dev.data[0][40] ^= 0x55;
        s.dev.data[1][40] ^= 0x55;
        let (mut s, r) = remount(s);
        assert_eq!(r, Ok(Mounted::FormattedCorrupt));
        assert!(Mounted::FormattedCorrupt.text().is_some() && Mounted::Clean.text().is_none());
        assert_eq!(s.count(), 0);
        assert!(s.take_fault().is_none(), "a formatted card works");
        s.begin(0).unwrap();
        s.end();
        // Another format version (valid CRC): formatted too.
        for b in 0..2 {
            let d = &mut s.dev.data[b];
            d[8] = 99;
            let c = crc(&[&d[..510]]);
            d[510..].copy_from_slice(&c.to_le_bytes());
        }
        let (s, r) = remount(s);
        assert_eq!(r, Ok(Mounted::FormattedVersion));
        assert_eq!(s.count(), 0);
    }

    #[test]
    fn no_card_or_a_pulled_card_turns_logging_off_with_one_message() {
        let mut dev = RamBlocks::new(2 + 64);
        dev.absent = true;
        let mut s = CardStore::new(dev);
        assert_eq!(s.mount(), Err(LogError::Device));
        assert!(s.take_fault().is_some());
        assert_eq!(s.take_fault(), None);
        assert_eq!(s.begin(0), Err(LogError::Device));
        assert_eq!((s.count(), s.is_open()), (0, false));
        // The logger runs on (counting) and never opens a log.
        let params = ControllerParams::default();
        let mut lg = FlightLogger::new(DEFAULT_PERIOD_US, &params, "host-test");
        for k in 0..100 {
            lg.on_sample(&sample(k * 4000, true), &mut s, |_| None);
        }
        assert!(lg.stats().store_errors > 0 && lg.stats().records == 0);
        // A card pulled in flight: the log stops, one message, the card is off.
        let mut s = mounted(2 + 64);
        s.begin(0).unwrap();
        s.append(&pattern(0, 3000)).unwrap();
        s.dev.absent = true;
        assert_eq!(s.append(&pattern(0, 3000)), Err(LogError::Device));
        assert!(s.take_fault().is_some() && s.take_fault().is_none());
        assert!(!s.is_open() && !s.is_on());
        assert_eq!(s.append(b"x"), Err(LogError::Device));
        s.end();
        // Put back and power-cycled: the log is there up to its last written block.
        let (mut s, r) = remount(s);
        assert_eq!(r, Ok(Mounted::Recovered));
        assert_eq!(read_all(&mut s, 1), pattern(0, 3000)[..5 * PAYLOAD]);
    }
}
