//! Parameter storage: the [`parapet_core::params::TABLE`] values kept across power cycles in
//! the board's NOR flash (`embedded-storage-async` traits): the STM32F405's internal flash
//! (sectors 10-11, see `memory-f405.x`), the H743's bank-2 sectors 6-7, a [`ram::RamFlash`] on the
//! QEMU board and in the host tests.
//!
//! Owns [`ParamStore`], [`Loaded`], [`StoreError`], [`LAYOUT_VERSION`], [`SaveSchedule`]; the
//! record layout is [`record`]. May import `parapet_core` (the parameter table) only (the
//! Cortex-M4F benchmark `tests/cortex-m4` includes this folder by path).
//!
//! ## Why not sequential-storage
//! Until 2026-12-03 this was a key-value map of `sequential-storage` 8.0.2 (one item per
//! parameter). Its power-cut test failed: cutting the power at every flash write of a save,
//! after 0..=24 earlier saves, prefills 1, 2, 5, 8, 15 and 19 each had a cut point (writes
//! 140, 104, 44, 167, 170, 65) after which the map reloaded as corrupt — reported by the
//! crate even after its own repair — and adding one parameter moved those points.
//! Upstream: tweedegolf/sequential-storage #136 ("store_item can acknowledge an item that
//! disappears after reboot": an append after a torn item header completes a phantom header
//! that hides the new item; fix #137 not merged) and #132; 8.0.2 is the newest release on
//! crates.io. Hence this small store, whose power-cut safety follows from its layout.
//!
//! ## Layout
//! The range is two **slots** of equal size (F405: one 128 KiB sector each), each a row of
//! fixed positions of [`record::RECORD_LEN`] = 512 bytes (256 per F405 sector). A save
//! writes the **whole table** as one record — magic, sequence number, [`LAYOUT_VERSION`],
//! the values, CRC-32 last — at the next erased position of the slot that holds the newest
//! record; when that slot is full it erases the other slot and writes at its first position.
//! At boot every position is read: the valid record (magic and CRC) with the highest
//! sequence number is the stored set.
//!
//! ## Power cut: the previous set always survives
//! 1. A record is written only into erased positions: after the last non-erased position of
//!    its slot, or into the other slot right after erasing it. Positions are fixed, so a torn
//!    record never changes where a later record is looked for (the failure of #136 cannot
//!    happen).
//! 2. A slot is erased only when the save switches to it, i.e. when the newest valid record
//!    is in the *other* slot; a save switches at most once. So the newest valid record is
//!    never erased or overwritten before a newer valid one has been written and read back.
//! 3. A cut while writing leaves a record whose CRC (its last word, written last) does not
//!    match: invalid, the previous record is the newest. A cut while erasing hits a slot
//!    without the newest record; a half-erased slot is erased again before it is written.
//! 4. Every written record is read back; one that does not read as written (a weak cell)
//!    leaves its position used and the save goes on at the next position.
//!
//! So after a cut at any flash operation the store loads the old set or the new one, never a
//! mix and never nothing (host test `power_cut_at_every_write_keeps_old_or_new_values`: every
//! write and erase of a save cut, after 0..=24 earlier saves, so at every position and at the
//! slot switch). What remains: a torn record that happens to carry a matching CRC-32 (2⁻³²),
//! and cells whose charge decays later (the record becomes invalid: the previous one loads).
//!
//! ## Wear
//! A save programs one 512-byte record (F405: 76 of its 128 words, 16 µs each) and erases a
//! sector only when its slot is full: **1 erase per 256 saves** on the F405 and the H743 (128
//! KiB sectors), each sector erased every 512 saves; at the STM32F4's 10,000 cycles that is
//! ≈ 5·10⁶ saves. (The QEMU board's 2 × 2 KiB RAM flash: 1 erase per 4 saves.)
//!
//! ## Loading
//! [`ParamStore::load`] applies the stored set only when the newest valid record is of this
//! firmware's version and every value is accepted by [`parapet_core::params::set`];
//! otherwise the parameters keep their defaults and [`Loaded::statustext`] is the warning
//! the ground station gets: erased flash (first boot, after a reset) → defaults, no
//! warning; newest record of another firmware's table → "Params: other firmware version,
//! defaults"; written flash without a valid record (a cut first save, the old
//! sequential-storage format, damage) or a refused value → "Params: storage corrupt,
//! defaults". The next save writes after whatever is there.
//!
//! ## When it runs
//! Never in a control task: the board runs the store in the lowest-priority task. A save
//! is debounced ([`SaveSchedule`], [`SAVE_DEBOUNCE_US`] after the last PARAM_SET) and
//! deferred while armed: on the F405 (one flash bank) a sector erase stalls every
//! instruction fetch from flash — the whole CPU, interrupts included — for the erase time
//! (128 KiB sector: 1-2 s typical, 4 s max at x32 parallelism, RM0090 / DS8626), and a word
//! write for ~16 µs. A save erases once in 256, but the rule makes no exception.

pub mod ram;
pub mod record;

use embedded_storage_async::nor_flash::NorFlash;
use parapet_core::config::ControllerParams;
use parapet_core::params::{self, COUNT, TABLE};
use record::{CHUNK, CRC_OFFSET, MAGIC, RECORD_LEN};

/// The store's range on the STM32F405, as offsets from the flash base 0x0800_0000 (what
/// embassy-stm32's flash driver takes): sectors 10 and 11, 2 × 128 KiB, kept out of the
/// linker's `FLASH` region by `memory-f405.x`.
pub const F405_RANGE: core::ops::Range<u32> = 0x000C_0000..0x0010_0000;

/// Storage format number, part of [`LAYOUT_VERSION`] (bump when the record layout changes;
/// 2: [`record`]'s whole-table records, 1: the sequential-storage map).
pub const FORMAT: u32 = 2;

/// FNV-1a over the table's names and ranges and [`FORMAT`]. Not the defaults: a stored value
/// is still a value of the same parameter when a new firmware changes its default (the
/// defaults are the stages' own, `Param::default_value`; PX4 likewise keeps set parameters
/// across a default change).
const fn layout_version() -> u32 {
    const PRIME: u32 = 0x0100_0193;
    let mut h: u32 = 0x811c_9dc5 ^ FORMAT;
    let mut i = 0;
    while i < COUNT {
        let p = &TABLE[i];
        let name = p.name.as_bytes();
        let mut k = 0;
        while k < name.len() {
            h = (h ^ name[k] as u32).wrapping_mul(PRIME);
            k += 1;
        }
        let nums = [p.min.to_bits(), p.max.to_bits()];
        let mut n = 0;
        while n < 2 {
            h = (h ^ nums[n]).wrapping_mul(PRIME);
            n += 1;
        }
        i += 1;
    }
    h
}

/// This firmware's parameter-table version (the records' version word).
pub const LAYOUT_VERSION: u32 = layout_version();

/// How the stored parameters were found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loaded {
    /// A complete set of this firmware's version: applied.
    Stored,
    /// Nothing stored (erased flash: first boot, after a reset): defaults.
    Empty,
    /// Written by a firmware with another parameter table (the version found): defaults.
    Foreign(u32),
    /// No valid record on written flash, unreadable flash, or out-of-range values: defaults.
    Corrupt,
}

impl Loaded {
    /// The STATUSTEXT for the ground station (`None`: nothing to warn about).
    pub fn statustext(self) -> Option<&'static str> {
        match self {
            Loaded::Stored | Loaded::Empty => None,
            Loaded::Foreign(_) => Some("Params: other firmware version, defaults"),
            Loaded::Corrupt => Some("Params: storage corrupt, defaults"),
        }
    }
}

/// A flash operation failed (the parameters in RAM are unchanged and still in effect; the
/// flash holds the previous set, see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// The flash driver reported an error.
    Flash,
    /// No position of either slot read back as written.
    Storage,
}

/// What a position of a slot holds.
enum Position {
    /// Every byte erased (0xFF).
    Erased,
    /// A record with the magic and a matching CRC.
    Valid { seq: u32, version: u32 },
    /// Anything else (a torn write, another format, damage).
    Garbage,
}

/// A valid record: where, its sequence number and version.
#[derive(Clone, Copy, Debug)]
struct Found {
    slot: u32,
    pos: u32,
    seq: u32,
    version: u32,
}

/// What a scan of both slots found, kept up to date by the saves.
#[derive(Clone, Copy, Debug)]
struct State {
    /// The valid record with the highest sequence number (any version).
    newest: Option<Found>,
    /// Per slot: the first position after the last one that is not erased.
    next: [u32; 2],
}

/// The parameter store over flash `F` (see the module docs).
pub struct ParamStore<F: NorFlash> {
    flash: F,
    /// Start of slot 0 (slot 1 follows), bytes from the flash's start.
    base: u32,
    /// Bytes per slot (a multiple of the erase size).
    slot_len: u32,
    /// The last scan, updated by the saves; `None`: scan before the next save.
    state: Option<State>,
}

impl<F: NorFlash> ParamStore<F> {
    /// A store over `range` of `flash`: two slots of whole erase pages (the range's start
    /// and half its length multiples of the erase size, a slot ≥ one record), or `None`.
    pub fn new(flash: F, range: core::ops::Range<u32>) -> Option<Self> {
        let len = range.end.checked_sub(range.start)?;
        let slot_len = len / 2;
        let erase = u32::try_from(F::ERASE_SIZE).ok()?;
        let ok = erase > 0
            && len % 2 == 0
            && range.start.is_multiple_of(erase)
            && slot_len.is_multiple_of(erase)
            && slot_len as usize >= RECORD_LEN
            && range.end as usize <= flash.capacity()
            && CHUNK.is_multiple_of(F::WRITE_SIZE)
            && 4 % F::READ_SIZE == 0;
        ok.then_some(Self { flash, base: range.start, slot_len, state: None })
    }

    /// Read the stored set into `into` when the newest record is complete and valid (see
    /// [`Loaded`]); otherwise `into` is left as it was (the defaults at boot). Flash errors
    /// are reported as [`Loaded::Corrupt`] too: the defaults are the safe answer.
    pub async fn load(&mut self, into: &mut ControllerParams) -> Loaded {
        self.state = None;
        let Ok(state) = self.scan().await else { return Loaded::Corrupt };
        self.state = Some(state);
        let Some(newest) = state.newest else {
            return if state.next == [0, 0] { Loaded::Empty } else { Loaded::Corrupt };
        };
        if newest.version != LAYOUT_VERSION {
            return Loaded::Foreign(newest.version);
        }
        let mut p = *into;
        for (k, d) in TABLE.iter().enumerate() {
            let Ok(bits) = self.value(&newest, k).await else { return Loaded::Corrupt };
            if params::set(&mut p, d.name, f32::from_bits(bits)).is_err() {
                return Loaded::Corrupt;
            }
        }
        *into = p;
        Loaded::Stored
    }

    /// Write `p` as a new record unless the newest record holds exactly these values of this
    /// version. Returns how many parameters changed (`COUNT + 1` when no record of this
    /// version was there; 0: nothing written). On an error the flash keeps the previous set.
    pub async fn save(&mut self, p: &ControllerParams) -> Result<usize, StoreError> {
        let state = match self.state.take() {
            Some(s) => s,
            None => self.scan().await?,
        };
        let value = |k: usize| TABLE.get(k).map_or(u32::MAX, |d| (d.get)(p).to_bits());
        let changed = match state.newest {
            Some(n) if n.version == LAYOUT_VERSION => {
                let mut changed = 0;
                for k in 0..COUNT {
                    if self.value(&n, k).await? != value(k) {
                        changed += 1;
                    }
                }
                changed
            }
            _ => COUNT + 1,
        };
        if changed == 0 {
            self.state = Some(state);
            return Ok(0);
        }
        let state = self.append(state, &value).await?;
        self.state = Some(state);
        Ok(changed)
    }

    /// Writes the record of `value` after the newest (module docs, rules 1-4) and returns the
    /// state with it as the newest. At most one slot switch; every position at most once.
    async fn append(&mut self, mut state: State, value: &impl Fn(usize) -> u32) -> Result<State, StoreError> {
        let seq = state.newest.map_or(0, |n| n.seq).saturating_add(1);
        let crc = record::crc(seq, LAYOUT_VERSION, value);
        let positions = self.positions();
        let mut slot = state.newest.map_or(0, |n| n.slot);
        let mut switched = false;
        for _ in 0..=2 * positions {
            let next = state.next.get(slot as usize).copied().unwrap_or(positions);
            if next >= positions {
                if switched {
                    break; // never erase the slot that holds the newest record
                }
                switched = true;
                slot = 1 - slot;
                let from = self.offset(slot, 0);
                self.flash.erase(from, from + self.slot_len).await.map_err(|_| StoreError::Flash)?;
                state.next = if slot == 0 { [0, state.next[1]] } else { [state.next[0], 0] };
                continue;
            }
            let pos = next;
            state.next = if slot == 0 { [pos + 1, state.next[1]] } else { [state.next[0], pos + 1] };
            let at = self.offset(slot, pos);
            for c in 0..RECORD_LEN / CHUNK {
                let bytes = record::chunk(c, seq, LAYOUT_VERSION, value, crc);
                // Erased flash already reads 0xFF: the padding chunks are not programmed.
                if bytes.iter().any(|&b| b != 0xFF) {
                    let to = at + (c * CHUNK) as u32;
                    self.flash.write(to, &bytes).await.map_err(|_| StoreError::Flash)?;
                }
            }
            if let Position::Valid { seq: s, version } = self.examine(at).await? {
                if s == seq && version == LAYOUT_VERSION {
                    state.newest = Some(Found { slot, pos, seq, version });
                    return Ok(state);
                }
            }
        }
        Err(StoreError::Storage)
    }

    /// MAV_CMD_PREFLIGHT_STORAGE "reset to defaults": erase the range (the caller then
    /// applies the defaults in RAM; the next save writes them).
    pub async fn reset(&mut self) -> Result<(), StoreError> {
        self.state = None;
        let end = self.base + 2 * self.slot_len;
        self.flash.erase(self.base, end).await.map_err(|_| StoreError::Flash)?;
        self.state = Some(State { newest: None, next: [0, 0] });
        Ok(())
    }

    /// The flash back (tests: inspect or corrupt the image).
    pub fn into_flash(self) -> F {
        self.flash
    }

    /// Record positions per slot.
    fn positions(&self) -> u32 {
        self.slot_len / RECORD_LEN as u32
    }

    /// Flash offset of position `pos` of slot `slot`.
    fn offset(&self, slot: u32, pos: u32) -> u32 {
        self.base + slot * self.slot_len + pos * RECORD_LEN as u32
    }

    /// Every position of both slots: the newest valid record and where the free space starts.
    async fn scan(&mut self) -> Result<State, StoreError> {
        let mut state = State { newest: None, next: [0, 0] };
        for slot in 0..2u32 {
            for pos in 0..self.positions() {
                match self.examine(self.offset(slot, pos)).await? {
                    Position::Erased => continue,
                    Position::Garbage => {}
                    Position::Valid { seq, version } => {
                        if state.newest.is_none_or(|n| seq > n.seq) {
                            state.newest = Some(Found { slot, pos, seq, version });
                        }
                    }
                }
                state.next = if slot == 0 { [pos + 1, state.next[1]] } else { [state.next[0], pos + 1] };
            }
        }
        Ok(state)
    }

    /// What the position at flash offset `at` holds. The CRC is computed only behind the
    /// magic (an erased position costs its reads and compares).
    async fn examine(&mut self, at: u32) -> Result<Position, StoreError> {
        let mut chunk = [0u8; CHUNK];
        let mut crc = !0u32;
        let mut erased = true;
        let (mut magic, mut seq, mut version, mut stored) = (0, 0, 0, 0);
        for c in 0..RECORD_LEN / CHUNK {
            let from = at + (c * CHUNK) as u32;
            self.flash.read(from, &mut chunk).await.map_err(|_| StoreError::Flash)?;
            erased &= chunk.iter().all(|&b| b == 0xFF);
            for (j, w) in chunk.chunks_exact(4).enumerate() {
                let i = c * CHUNK / 4 + j;
                let v = u32::from_le_bytes(w.try_into().unwrap_or([0; 4]));
                match i {
                    0 => magic = v,
                    1 => seq = v,
                    2 => version = v,
                    _ => {}
                }
                if 4 * i == CRC_OFFSET {
                    stored = v;
                } else if magic == MAGIC {
                    crc = record::crc32_update(crc, w);
                }
            }
        }
        Ok(if erased {
            Position::Erased
        } else if magic == MAGIC && !crc == stored {
            Position::Valid { seq, version }
        } else {
            Position::Garbage
        })
    }

    /// Value `k` (`f32` bits) of the record `r`.
    async fn value(&mut self, r: &Found, k: usize) -> Result<u32, StoreError> {
        let mut w = [0u8; 4];
        let at = self.offset(r.slot, r.pos) + record::value_offset(k) as u32;
        self.flash.read(at, &mut w).await.map_err(|_| StoreError::Flash)?;
        Ok(u32::from_le_bytes(w))
    }
}

/// Time after the last PARAM_SET before the parameters are saved, µs.
pub const SAVE_DEBOUNCE_US: u64 = 1_000_000;

/// When to save: [`SAVE_DEBOUNCE_US`] after the last change, and only while disarmed (a save
/// due while armed waits for the disarm).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SaveSchedule {
    last_change_us: Option<u64>,
}

impl SaveSchedule {
    /// Nothing to save.
    pub const fn new() -> Self {
        Self { last_change_us: None }
    }

    /// A parameter changed (PARAM_SET accepted, calibration result, PREFLIGHT_STORAGE write).
    pub fn changed(&mut self, now_us: u64) {
        self.last_change_us = Some(now_us);
    }

    /// A save is waiting.
    pub fn pending(&self) -> bool {
        self.last_change_us.is_some()
    }

    /// `true` when the save should run now (then it is no longer pending).
    pub fn due(&mut self, now_us: u64, armed: bool) -> bool {
        match self.last_change_us {
            Some(t) if !armed && now_us.saturating_sub(t) >= SAVE_DEBOUNCE_US => {
                self.last_change_us = None;
                true
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests;
