//! Which cell holds a voxel key, during one scan's insertion into
//! [`super::memory::ObstacleMemory`]: an open-addressing hash table of the cells' keys, so a
//! return finds its cell in a few probes instead of comparing every cell's key.
//!
//! Keys are unique among the cells (a return into an existing cube merges into it; a new
//! cube gets a new cell), so the cell a lookup finds is the one a scan over the cells finds:
//! the memory's contents do not depend on the table. The table is built from the cells when
//! the insertion starts and follows its two changes (a new cell appended, a cell replaced by
//! a new cube). It answers [`Lookup::Unknown`] (the caller scans the cells, as without it)
//! when it cannot be sure: more than [`MAX_INDEXED`] cells, or no free slot left within
//! [`SLOTS`] probes (replaced cells leave tombstones; a scan has a bounded number of returns).
//!
//! Bounded: every probe sequence is at most [`SLOTS`] long; 256 bytes.
//!
//! Written here, not taken from a crate: `heapless::FnvIndexMap` would work, but its
//! removal moves entries and its capacity must be a power of two fixed at the type, while
//! this table must stay at 256 bytes for any memory capacity and fall back when unsure.
//!
//! May import: nothing but `core`.

/// Slots of the table.
pub(super) const SLOTS: usize = 256;
/// Most cells the table indexes (half the slots: probe sequences stay short); a memory with
/// more cells is scanned linearly.
pub(super) const MAX_INDEXED: usize = 128;

const EMPTY: u8 = 0;
const GONE: u8 = 255;

/// Answer of [`KeyIndex::find`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Lookup {
    /// Cell `i` holds the key.
    Found(usize),
    /// No cell holds the key.
    Absent,
    /// The table cannot tell: scan the cells.
    Unknown,
}

/// The table: slot value `i + 1` for cell `i`, [`EMPTY`], or [`GONE`] (a removed entry).
pub(super) struct KeyIndex {
    slots: [u8; SLOTS],
    usable: bool,
}

fn home(key: &[i32; 3]) -> usize {
    let h = (key[0] as u32).wrapping_mul(0x9E37_79B1)
        ^ (key[1] as u32).wrapping_mul(0x85EB_CA77)
        ^ (key[2] as u32).wrapping_mul(0xC2B2_AE3D);
    (h >> 24) as usize
}

impl KeyIndex {
    /// The table of `keys` (cell `i` has `keys(i)`), `n` cells.
    pub(super) fn build(n: usize, keys: impl Iterator<Item = [i32; 3]>) -> Self {
        let mut t = KeyIndex { slots: [EMPTY; SLOTS], usable: n <= MAX_INDEXED };
        if t.usable {
            for (i, k) in keys.enumerate().take(n) {
                t.insert(&k, i);
            }
        }
        t
    }

    /// The cell holding `key`; `key_of(i)` is cell `i`'s key.
    pub(super) fn find(&self, key: &[i32; 3], key_of: impl Fn(usize) -> Option<[i32; 3]>) -> Lookup {
        if !self.usable {
            return Lookup::Unknown;
        }
        let h = home(key);
        for j in 0..SLOTS {
            match self.slots.get((h + j) % SLOTS).copied().unwrap_or(EMPTY) {
                EMPTY => return Lookup::Absent,
                GONE => {}
                s => {
                    let i = usize::from(s) - 1;
                    if key_of(i).is_some_and(|k| k == *key) {
                        return Lookup::Found(i);
                    }
                }
            }
        }
        Lookup::Unknown
    }

    /// Cell `i` now holds `key`, a key no cell held (a new cell, or one replaced after
    /// [`Self::remove`]).
    pub(super) fn insert(&mut self, key: &[i32; 3], i: usize) {
        if !self.usable || i >= MAX_INDEXED {
            self.usable = false;
            return;
        }
        let h = home(key);
        for j in 0..SLOTS {
            if let Some(s) = self.slots.get_mut((h + j) % SLOTS) {
                // A removed entry's slot is reused: the key is absent (a new cube), so no
                // later slot of its sequence holds it.
                if *s == EMPTY || *s == GONE {
                    *s = (i + 1) as u8;
                    return;
                }
            }
        }
        // No free slot: lookups could no longer prove absence.
        self.usable = false;
    }

    /// Cell `i`, holding `key`, is about to be replaced.
    pub(super) fn remove(&mut self, key: &[i32; 3], i: usize) {
        if !self.usable {
            return;
        }
        let h = home(key);
        for j in 0..SLOTS {
            if let Some(s) = self.slots.get_mut((h + j) % SLOTS) {
                if *s == EMPTY {
                    break;
                }
                if usize::from(*s) == i + 1 {
                    *s = GONE;
                    return;
                }
            }
        }
        // Not found (cannot happen while usable): stop trusting the table.
        self.usable = false;
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// Against a linear scan of a list of unique keys under appends and replacements, until
    /// tombstones fill the table: found cells are the scan's, absence is true absence, and
    /// the table says `Unknown` rather than guess.
    #[test]
    fn lookups_agree_with_a_scan_of_the_cells() {
        let mut seed = 0x1919_u64;
        let mut next = move |m: i32| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 33) as i32 % m
        };
        let (mut found, mut absent, mut unknown) = (0, 0, 0);
        for round in 0..40 {
            let cap = [16, 64, 128, 200][round % 4];
            let mut cells: Vec<[i32; 3]> = Vec::new();
            while cells.len() < cap / 2 {
                let k = [next(12), next(12), next(3)];
                if !cells.contains(&k) {
                    cells.push(k);
                }
            }
            let mut t = KeyIndex::build(cells.len(), cells.iter().copied());
            for _ in 0..2000 {
                let k = [next(12), next(12), next(3)];
                let want = cells.iter().position(|c| *c == k);
                let got = t.find(&k, |i| cells.get(i).copied());
                match (got, want) {
                    (Lookup::Found(i), Some(j)) => {
                        assert_eq!(i, j);
                        found += 1;
                    }
                    (Lookup::Absent, None) => {
                        absent += 1;
                        if cells.len() < cap {
                            cells.push(k);
                            t.insert(&k, cells.len() - 1);
                        } else {
                            let i = next(cells.len() as i32) as usize;
                            let old = cells[i];
                            t.remove(&old, i);
                            cells[i] = k;
                            t.insert(&k, i);
                        }
                    }
                    (Lookup::Unknown, _) => unknown += 1,
                    other => panic!("round {round}: {other:?} for {k:?}"),
                }
            }
        }
        // Unknown: the rounds of 200 cells (more than indexed).
        assert!(found > 5_000 && absent > 20_000 && unknown > 10_000, "{found} {absent} {unknown}");
    }
}
