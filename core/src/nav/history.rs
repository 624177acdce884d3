//! The filter's past: a fixed ring buffer of the nominal position and velocity at past IMU
//! steps, so a delayed fix is compared with the state the filter had at the time the fix
//! describes (`docs/cascade.md` § Navigation filter).
//!
//! Owns: [`History`], [`HISTORY_LEN`]. May import: the crate root foundation.

use crate::Vec3;

/// Entries kept. With one entry every [`super::NavParams::history_period_us`] (4 ms by
/// default) the buffer spans 0.512 s: fixes up to 0.5 s old are fused at their time.
pub const HISTORY_LEN: usize = 128;

/// One past nominal state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Past {
    /// Time, µs.
    pub t_us: u64,
    /// Position, NED, m.
    pub p: Vec3,
    /// Velocity, NED, m/s.
    pub v: Vec3,
}

/// Ring buffer of [`Past`] states, oldest overwritten.
#[derive(Clone, Debug)]
pub struct History {
    buf: [Past; HISTORY_LEN],
    /// Index of the next write.
    head: usize,
    len: usize,
}

impl Default for History {
    fn default() -> Self {
        Self::new()
    }
}

impl History {
    /// Empty.
    pub const fn new() -> Self {
        let z = Past { t_us: 0, p: Vec3::new(0.0, 0.0, 0.0), v: Vec3::new(0.0, 0.0, 0.0) };
        History { buf: [z; HISTORY_LEN], head: 0, len: 0 }
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        self.head = 0;
        self.len = 0;
    }

    /// Time of the newest entry, µs.
    pub fn newest_t_us(&self) -> Option<u64> {
        (self.len > 0).then(|| self.buf[(self.head + HISTORY_LEN - 1) % HISTORY_LEN].t_us)
    }

    /// Append (the oldest entry is dropped when full).
    pub fn push(&mut self, e: Past) {
        self.buf[self.head] = e;
        self.head = (self.head + 1) % HISTORY_LEN;
        self.len = (self.len + 1).min(HISTORY_LEN);
    }

    /// The newest entry at or before `t_us`; `None` when `t_us` precedes the oldest entry.
    /// At most [`HISTORY_LEN`] entries are looked at.
    pub fn at_or_before(&self, t_us: u64) -> Option<Past> {
        for k in 1..=self.len {
            let e = self.buf[(self.head + HISTORY_LEN - k) % HISTORY_LEN];
            if e.t_us <= t_us {
                return Some(e);
            }
        }
        None
    }

    /// Apply `f` to every entry (a correction carried back into the past).
    pub fn for_each_mut(&mut self, mut f: impl FnMut(&mut Past)) {
        for k in 1..=self.len {
            let i = (self.head + HISTORY_LEN - k) % HISTORY_LEN;
            f(&mut self.buf[i]);
        }
    }
}
