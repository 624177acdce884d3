//! Parameter storage: the [`parapet_core::params::TABLE`] values kept across power cycles in
//! a wear-levelled key-value map ([`sequential-storage`](https://docs.rs/sequential-storage)
//! 8.0.2) over any `embedded-storage-async` NOR flash: the STM32F405's internal flash on the
//! board (sectors 10-11, see `memory.x`), a [`ram::RamFlash`] on the QEMU board and in the host tests.
//!
//! Owns [`ParamStore`], [`Loaded`], [`StoreError`], [`LAYOUT_VERSION`], [`SaveSchedule`].
//! May import `parapet_core` (the parameter table) only.
//!
//! ## Layout and integrity
//! * Key `k` = 1..=COUNT holds parameter `k − 1` (table order) as the `f32` bits; key 0 holds
//!   the **version record** [`LAYOUT_VERSION`], an FNV-1a hash of every parameter's name,
//!   default, minimum and maximum plus [`FORMAT`]: any firmware whose table differs has
//!   another version. Every item carries sequential-storage's own CRC (header and data).
//! * A save writes the changed parameters first and the version record **last**, so a
//!   version record on flash means a complete save happened once; each later item
//!   supersedes the older one with its key only after it is completely written.
//! * **Power cut during a save**: on the next boot every parameter has either its previous
//!   or its new value (sequential-storage repairs a half-written item on the next operation;
//!   host test `power_cut_at_every_write_keeps_old_or_new_values`).
//! * [`ParamStore::load`] applies the stored set only when it is complete and every value is
//!   accepted by [`parapet_core::params::set`]; otherwise the parameters keep their defaults
//!   and [`Loaded::statustext`] is the warning the ground station gets:
//!   empty flash (first boot) → defaults, no warning; another firmware's version →
//!   "Params: other firmware version, defaults"; a missing, unreadable or refused value, or
//!   a corrupted map → "Params: storage corrupt, defaults". The next save then erases the
//!   range first.
//!
//! ## When it runs
//! Never in a control task: the board runs the store in the lowest-priority task. A save
//! is debounced ([`SaveSchedule`], [`SAVE_DEBOUNCE_US`] after the last PARAM_SET) and
//! deferred while armed: on the F405 (one flash bank) a sector erase stalls every
//! instruction fetch from flash — the whole CPU, interrupts included — for the erase time
//! (128 KiB sector: 1-2 s typical, 4 s max at x32 parallelism, RM0090 / DS8626), and a word
//! write for ~16 µs. sequential-storage erases a sector only when the open one is full
//! (after ~5,000 item writes here), but the rule makes no exception.

pub mod ram;

use embedded_storage_async::nor_flash::NorFlash;
use parapet_core::config::ControllerParams;
use parapet_core::params::{self, COUNT, TABLE};
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};

/// The store's range on the STM32F405, as offsets from the flash base 0x0800_0000 (what
/// embassy-stm32's flash driver takes): sectors 10 and 11, 2 × 128 KiB, kept out of the
/// linker's `FLASH` region by `memory.x`.
pub const F405_RANGE: core::ops::Range<u32> = 0x000C_0000..0x0010_0000;

/// Storage format number, part of [`LAYOUT_VERSION`] (bump when the item layout changes).
pub const FORMAT: u32 = 1;

/// FNV-1a over the table's names, defaults and ranges and [`FORMAT`].
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
        let nums = [p.default.to_bits(), p.min.to_bits(), p.max.to_bits()];
        let mut n = 0;
        while n < 3 {
            h = (h ^ nums[n]).wrapping_mul(PRIME);
            n += 1;
        }
        i += 1;
    }
    h
}

/// This firmware's parameter-table version (the version record's value).
pub const LAYOUT_VERSION: u32 = layout_version();

/// Key of the version record.
const VERSION_KEY: u16 = 0;
/// Work buffer: key (2 B) + value (4 B), rounded up to the flash word.
const BUF_LEN: usize = 32;

/// How the stored parameters were found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loaded {
    /// A complete set of this firmware's version: applied.
    Stored,
    /// Nothing stored (first boot, after a reset, or a first save that never finished): defaults.
    Empty,
    /// Written by a firmware with another parameter table (the version found): defaults.
    Foreign(u32),
    /// Incomplete, unreadable or out-of-range values: defaults.
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

/// A flash operation failed (the parameters in RAM are unchanged and still in effect).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// The flash driver reported an error.
    Flash,
    /// The map is full of live items or corrupt beyond sequential-storage's repair.
    Storage,
}

impl<E> From<sequential_storage::Error<E>> for StoreError {
    fn from(e: sequential_storage::Error<E>) -> Self {
        match e {
            sequential_storage::Error::Storage { .. } => StoreError::Flash,
            _ => StoreError::Storage,
        }
    }
}

/// The parameter store over flash `F` (see the module docs).
pub struct ParamStore<F: NorFlash> {
    map: MapStorage<u16, F, Cache<Uncached, Uncached, Uncached, u16>>,
    /// The bits on flash per parameter (`None`: not known to be stored).
    stored: [Option<u32>; COUNT],
    version_stored: bool,
    erase_first: bool,
    buf: [u8; BUF_LEN],
}

impl<F: NorFlash> ParamStore<F> {
    /// A store over `range` of `flash` (at least two erase pages, page-aligned), or `None`
    /// when the range does not fit sequential-storage's rules.
    pub fn new(flash: F, range: core::ops::Range<u32>) -> Option<Self> {
        let config = MapConfig::try_new(range).ok()?;
        Some(Self {
            map: MapStorage::new(flash, config, Cache::new_uncached()),
            stored: [None; COUNT],
            version_stored: false,
            erase_first: false,
            buf: [0; BUF_LEN],
        })
    }

    /// Read the stored set into `into` when it is complete and valid (see [`Loaded`]);
    /// otherwise `into` is left as it was (the defaults at boot). Flash errors are
    /// reported as [`Loaded::Corrupt`] too: the defaults are the safe answer.
    pub async fn load(&mut self, into: &mut ControllerParams) -> Loaded {
        let found = self.read_all().await;
        let (version, values) = match found {
            Ok(v) => v,
            Err(()) => return self.defaults(Loaded::Corrupt),
        };
        match version {
            None if values.iter().all(Option::is_none) => {
                self.stored = [None; COUNT];
                self.version_stored = false;
                return Loaded::Empty;
            }
            // Items without a version record: a first save that was cut; nothing complete.
            None => {
                self.stored = values;
                self.version_stored = false;
                return Loaded::Empty;
            }
            Some(v) if v != LAYOUT_VERSION => return self.defaults(Loaded::Foreign(v)),
            Some(_) => {}
        }
        let mut p = *into;
        for (d, v) in TABLE.iter().zip(values.iter()) {
            let Some(bits) = *v else { return self.defaults(Loaded::Corrupt) };
            if params::set(&mut p, d.name, f32::from_bits(bits)).is_err() {
                return self.defaults(Loaded::Corrupt);
            }
        }
        *into = p;
        self.stored = values;
        self.version_stored = true;
        Loaded::Stored
    }

    fn defaults(&mut self, why: Loaded) -> Loaded {
        self.stored = [None; COUNT];
        self.version_stored = false;
        self.erase_first = true;
        why
    }

    /// Version record and last value per key; `Err` on any error of the map.
    async fn read_all(&mut self) -> Result<(Option<u32>, [Option<u32>; COUNT]), ()> {
        let mut values = [None; COUNT];
        let mut version = None;
        let mut it = self.map.fetch_all_items(&mut self.buf).await.map_err(|_| ())?;
        loop {
            match it.next::<u32>(&mut self.buf).await {
                Ok(Some((VERSION_KEY, v))) => version = Some(v),
                Ok(Some((k, v))) => match values.get_mut(usize::from(k) - 1) {
                    Some(slot) => *slot = Some(v),
                    None => return Err(()), // a key this table does not have
                },
                Ok(None) => break,
                Err(_) => return Err(()),
            }
        }
        Ok((version, values))
    }

    /// Write every parameter whose stored value differs, then the version record; returns
    /// how many items were written (0: nothing changed). On an error the flash keeps, per
    /// parameter, the old or the new value.
    pub async fn save(&mut self, p: &ControllerParams) -> Result<usize, StoreError> {
        if self.erase_first {
            self.map.erase_all().await?;
            self.erase_first = false;
        }
        let mut written = 0;
        for (k, d) in TABLE.iter().enumerate() {
            let bits = (d.get)(p).to_bits();
            let Some(slot) = self.stored.get_mut(k) else { continue };
            if *slot != Some(bits) {
                self.map.store_item(&mut self.buf, &(k as u16 + 1), &bits).await?;
                *slot = Some(bits);
                written += 1;
            }
        }
        if !self.version_stored {
            self.map.store_item(&mut self.buf, &VERSION_KEY, &LAYOUT_VERSION).await?;
            self.version_stored = true;
            written += 1;
        }
        Ok(written)
    }

    /// MAV_CMD_PREFLIGHT_STORAGE "reset to defaults": erase the range (the caller then
    /// applies the defaults in RAM; the next save writes them).
    pub async fn reset(&mut self) -> Result<(), StoreError> {
        self.map.erase_all().await?;
        self.stored = [None; COUNT];
        self.version_stored = false;
        self.erase_first = false;
        Ok(())
    }

    /// The flash back (tests: inspect or corrupt the image).
    pub fn into_flash(self) -> F {
        self.map.destroy().0
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
