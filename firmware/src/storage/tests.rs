//! Host tests of the parameter store on a RAM NOR flash: round trip, power cut at every
//! write of a save, corrupt and foreign images, the save schedule.

use super::ram::{RamFlash, RamFlashError, WORD};
use super::*;
use embassy_futures::block_on;
use embedded_storage_async::nor_flash::{ErrorType, ReadNorFlash};
use std::vec::Vec;

const PAGE: usize = 1024;
type Flash = RamFlash<{ 4 * PAGE }, PAGE>;
const RANGE: core::ops::Range<u32> = 0..(4 * PAGE) as u32;

fn store(f: Flash) -> ParamStore<Flash> {
    ParamStore::new(f, RANGE).unwrap()
}

/// A parameter set with every value different from the defaults where the range allows.
fn changed(seed: u32) -> ControllerParams {
    let mut p = ControllerParams::default();
    for (k, d) in TABLE.iter().enumerate() {
        let span = d.max - d.min;
        let frac = ((k as u32 * 7 + seed * 13) % 10) as f32 / 10.0 + 0.05;
        let v = if d.integer {
            (d.min + ((k as u32 + seed) % (span as u32 + 1)) as f32).min(d.max)
        } else {
            d.min + span.min(1e3) * frac
        };
        let _ = params::set(&mut p, d.name, v);
    }
    p
}

fn values(p: &ControllerParams) -> Vec<u32> {
    TABLE.iter().map(|d| (d.get)(p).to_bits()).collect()
}

#[test]
fn version_covers_the_table() {
    assert_ne!(LAYOUT_VERSION, 0);
    // Deterministic: the const and a second evaluation agree.
    assert_eq!(LAYOUT_VERSION, layout_version());
}

#[test]
fn empty_flash_gives_defaults_without_warning_and_round_trips() {
    let mut s = store(Flash::new());
    let mut p = ControllerParams::default();
    assert_eq!(block_on(s.load(&mut p)), Loaded::Empty);
    assert_eq!(Loaded::Empty.statustext(), None);
    assert_eq!(p, ControllerParams::default());
    let want = changed(1);
    assert_ne!(values(&want), values(&ControllerParams::default()));
    assert_eq!(block_on(s.save(&want)), Ok(COUNT + 1));
    // Unchanged: nothing written.
    assert_eq!(block_on(s.save(&want)), Ok(0));
    let mut one = want;
    params::set(&mut one, "CBF_MU", 2.5).unwrap();
    assert_eq!(block_on(s.save(&one)), Ok(1));
    // Reboot.
    let mut s = store(s.into_flash());
    let mut p = ControllerParams::default();
    assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
    assert_eq!(values(&p), values(&one));
    assert_eq!(block_on(s.save(&one)), Ok(0));
}

#[test]
fn many_saves_wrap_the_pages_and_keep_the_last_set() {
    let mut s = store(Flash::new());
    let mut p = ControllerParams::default();
    block_on(s.load(&mut p));
    for k in 0..40 {
        block_on(s.save(&changed(k))).unwrap();
    }
    let mut s = store(s.into_flash());
    let mut p = ControllerParams::default();
    assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
    assert_eq!(values(&p), values(&changed(39)));
}

/// A flash that loses power after `budget` writes/erases: the cut write clears only the
/// first half of its words' bits as asked (a half-programmed word), a cut erase erases half
/// the page; afterwards every operation fails.
struct CutFlash {
    inner: Flash,
    budget: usize,
    dead: bool,
}

impl ErrorType for CutFlash {
    type Error = RamFlashError;
}

impl ReadNorFlash for CutFlash {
    const READ_SIZE: usize = 1;
    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        if self.dead {
            return Err(RamFlashError::OutOfBounds);
        }
        self.inner.read(offset, bytes).await
    }
    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl NorFlash for CutFlash {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE;
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if self.dead {
            return Err(RamFlashError::OutOfBounds);
        }
        if self.budget == 0 {
            self.dead = true;
            let half = (from as usize)..(from as usize + (to - from) as usize / 2);
            self.inner.bytes_mut()[half].fill(0xFF);
            return Err(RamFlashError::OutOfBounds);
        }
        self.budget -= 1;
        self.inner.erase(from, to).await
    }
    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if self.dead {
            return Err(RamFlashError::OutOfBounds);
        }
        if self.budget == 0 {
            self.dead = true;
            // Half of the bytes programmed, and of those only some bits.
            let n = (bytes.len() / 2).max(1);
            let mem = self.inner.bytes_mut();
            for (i, b) in bytes.iter().take(n).enumerate() {
                mem[offset as usize + i] &= b | 0x5A;
            }
            return Err(RamFlashError::OutOfBounds);
        }
        self.budget -= 1;
        self.inner.write(offset, bytes).await
    }
}

#[test]
fn power_cut_at_every_write_keeps_old_or_new_values() {
    // Start states: a fresh set, and flash filled by 1..=24 earlier saves, every count (so the
    // cut save lands at every offset of the pages and has to open and erase pages).
    let mut cases = 0;
    for prefill in 0u32..=24 {
        let mut s = store(Flash::new());
        let mut p = ControllerParams::default();
        block_on(s.load(&mut p));
        for k in 0..prefill {
            block_on(s.save(&changed(100 + k))).unwrap();
        }
        let old = changed(1);
        block_on(s.save(&old)).unwrap();
        let base = s.into_flash();
        let new = changed(2);
        let (old_v, new_v) = (values(&old), values(&new));
        let mut budget = 0;
        loop {
            let mut s =
                ParamStore::new(CutFlash { inner: base.clone(), budget, dead: false }, RANGE).unwrap();
            let mut p = ControllerParams::default();
            assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
            let finished = block_on(s.save(&new)).is_ok();
            // Power back: a new store over what the flash holds.
            let mut s = store(s.into_flash().inner);
            let mut p = ControllerParams::default();
            assert_eq!(block_on(s.load(&mut p)), Loaded::Stored, "prefill {prefill}, cut at write {budget}");
            let got = values(&p);
            for (k, g) in got.iter().enumerate() {
                assert!(
                    *g == old_v[k] || *g == new_v[k],
                    "prefill {prefill}, cut at write {budget}: {} is neither old nor new",
                    TABLE[k].name
                );
            }
            if finished {
                assert_eq!(got, new_v);
                break;
            }
            // The interrupted save can be redone.
            block_on(s.save(&new)).unwrap();
            let mut s = store(s.into_flash());
            let mut p = ControllerParams::default();
            assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
            assert_eq!(values(&p), new_v);
            budget += 1;
            cases += 1;
        }
    }
    std::println!("power cut: {cases} interrupted saves, each reloaded with old-or-new values");
    // Each save programs 6 chunks (72 values: 5 chunks of header and values, 1 with the CRC);
    // the saves that switch slots (prefills 3, 7, …, 23: 4 records per 2 KiB slot) erase first.
    assert!(cases >= 25 * 6 + 6, "{cases} cut points");
}

#[test]
fn a_corrupt_image_never_loads_a_wrong_value() {
    let want = changed(3);
    let mut s = store(Flash::new());
    block_on(s.load(&mut ControllerParams::default()));
    block_on(s.save(&want)).unwrap();
    let base = s.into_flash();
    let used: Vec<usize> = (0..base.bytes().len()).filter(|&i| base.bytes()[i] != 0xFF).collect();
    let mut corrupt = 0;
    for &i in &used {
        let mut f = base.clone();
        f.bytes_mut()[i] ^= 0x10;
        let mut s = store(f);
        let mut p = ControllerParams::default();
        match block_on(s.load(&mut p)) {
            Loaded::Stored => assert_eq!(values(&p), values(&want), "flip at {i} loaded wrong values"),
            other => {
                assert_eq!(p, ControllerParams::default(), "flip at {i}: {other:?} but not defaults");
                assert!(other.statustext().is_some() || other == Loaded::Empty);
                corrupt += 1;
            }
        }
    }
    std::println!(
        "corruption: {corrupt} of {} single-byte flips detected (defaults), the rest loaded the right values",
        used.len()
    );
    // Most flips are detected (the rest hit bytes no value depends on).
    assert!(corrupt * 2 > used.len(), "{corrupt} of {} flips detected", used.len());
    // A corrupt store is erased by the next save and then works again.
    let mut f = base.clone();
    f.bytes_mut()[used[used.len() / 2]] ^= 0xFF;
    let mut s = store(f);
    let mut p = ControllerParams::default();
    if block_on(s.load(&mut p)) != Loaded::Stored {
        block_on(s.save(&want)).unwrap();
        let mut s = store(s.into_flash());
        assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
        assert_eq!(values(&p), values(&want));
    }
}

/// A flash whose writes report success but program nothing (a worn or protected part).
struct DeafFlash(Flash);

impl ErrorType for DeafFlash {
    type Error = RamFlashError;
}

impl ReadNorFlash for DeafFlash {
    const READ_SIZE: usize = 1;
    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes).await
    }
    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

impl NorFlash for DeafFlash {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE;
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.0.erase(from, to).await
    }
    async fn write(&mut self, _offset: u32, _bytes: &[u8]) -> Result<(), Self::Error> {
        Ok(())
    }
}

#[test]
fn records_that_do_not_read_back_fail_the_save_and_keep_the_stored_set() {
    // Every record read back after writing: none is there, so the save tries each free
    // position, switches slots once (erasing the other slot, not the one with the stored
    // record) and fails; the stored set still loads.
    let old = changed(6);
    let mut s = store(Flash::new());
    block_on(s.load(&mut ControllerParams::default()));
    block_on(s.save(&old)).unwrap();
    let mut s = ParamStore::new(DeafFlash(s.into_flash()), RANGE).unwrap();
    let mut p = ControllerParams::default();
    assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
    assert_eq!(block_on(s.save(&changed(7))), Err(StoreError::Storage));
    assert_eq!(block_on(s.save(&changed(7))), Err(StoreError::Storage), "and again");
    let mut s = store(s.into_flash().0);
    assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
    assert_eq!(values(&p), values(&old));
}

/// A flash holding one record (sequence 1) of layout `version` with the values `value(k)`.
fn image(version: u32, value: impl Fn(usize) -> u32) -> Flash {
    let mut f = Flash::new();
    let crc = record::crc(1, version, &value);
    for c in 0..record::RECORD_LEN / record::CHUNK {
        let at = c * record::CHUNK;
        f.bytes_mut()[at..at + record::CHUNK].copy_from_slice(&record::chunk(c, 1, version, &value, crc));
    }
    f
}

#[test]
fn a_foreign_version_or_a_refused_value_gives_defaults() {
    // Another firmware's record: another layout version.
    let other = changed(4);
    let mut s = store(image(LAYOUT_VERSION ^ 1, |k| (TABLE[k].get)(&other).to_bits()));
    let mut p = ControllerParams::default();
    assert_eq!(block_on(s.load(&mut p)), Loaded::Foreign(LAYOUT_VERSION ^ 1));
    assert_eq!(p, ControllerParams::default());
    assert_eq!(Loaded::Foreign(0).statustext(), Some("Params: other firmware version, defaults"));
    // The next save's record is the newest: it loads.
    block_on(s.save(&p)).unwrap();
    let mut s = store(s.into_flash());
    assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
    assert_eq!(p, ControllerParams::default());

    // This firmware's version but a value outside its parameter's range.
    let mut s = store(image(LAYOUT_VERSION, |k| {
        if k == 0 {
            f32::NAN.to_bits()
        } else {
            (TABLE[k].get)(&other).to_bits()
        }
    }));
    let mut p = ControllerParams::default();
    assert_eq!(block_on(s.load(&mut p)), Loaded::Corrupt);
    assert_eq!(p, ControllerParams::default());
    // The image alone (without the NaN) loads: the refusal was the value's.
    let mut s = store(image(LAYOUT_VERSION, |k| (TABLE[k].get)(&other).to_bits()));
    assert_eq!(block_on(s.load(&mut p)), Loaded::Stored);
    assert_eq!(values(&p), values(&other));
}

#[test]
fn reset_erases_the_store() {
    let mut s = store(Flash::new());
    block_on(s.load(&mut ControllerParams::default()));
    block_on(s.save(&changed(5))).unwrap();
    block_on(s.reset()).unwrap();
    let mut s = store(s.into_flash());
    let mut p = ControllerParams::default();
    assert_eq!(block_on(s.load(&mut p)), Loaded::Empty);
    assert_eq!(p, ControllerParams::default());
}

#[test]
fn saves_are_debounced_and_never_while_armed() {
    let mut sch = SaveSchedule::new();
    assert!(!sch.due(10_000_000, false));
    sch.changed(0);
    sch.changed(500_000);
    assert!(!sch.due(1_400_000, false)); // 0.9 s after the last change
    assert!(!sch.due(2_000_000, true)); // armed: deferred
    assert!(sch.pending());
    assert!(!sch.due(60_000_000, true));
    assert!(sch.due(60_000_001, false)); // disarmed
    assert!(!sch.pending());
    assert!(!sch.due(70_000_000, false));
}
