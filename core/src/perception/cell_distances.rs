//! The cells' squared distances from the vehicle during one scan's insertion into
//! [`super::memory::ObstacleMemory`], with the first farthest cell cached (the cell a return into
//! a new cube of a full memory may replace). Bounded: one pass over `N` when the cache is empty.
//!
//! May import: nothing but `core`.

/// Each cell's squared distance from the vehicle during one scan's insertion (kept up to
/// date by `store`), and the first farthest cell, cached: a return into a new cube of a
/// full memory needs it, and most such returns are dropped (farther than every cell),
/// which changes nothing, so it is not rescanned for each of them.
pub(super) struct Distances<const N: usize> {
    /// Cell `i`'s squared distance, m².
    pub(super) d: [f32; N],
    /// `(index, distance)` of the first largest of `d[..len]` when `Some`.
    far: Option<(usize, f32)>,
}

impl<const N: usize> Distances<N> {
    /// All 0, nothing cached.
    pub(super) fn new() -> Self {
        Distances { d: [0.0; N], far: None }
    }

    /// Sets cell `i`'s distance, keeping the cached farthest cell exact: a change of the
    /// farthest cell itself drops the cache; any other cell becomes the first farthest
    /// when it is now farther, or as far and earlier (the others are unchanged).
    pub(super) fn set(&mut self, i: usize, v: f32) {
        if let Some(d) = self.d.get_mut(i) {
            *d = v;
        }
        self.far = match self.far {
            Some((f, _)) if f == i => None,
            Some((f, fv)) if not_ge(fv, v) || (fv == v && i < f) => Some((i, v)),
            other => other,
        };
    }

    /// The first farthest of the first `len` cells (`d[i] >= best` keeps the earlier).
    pub(super) fn farthest(&mut self, len: usize) -> Option<(usize, f32)> {
        if self.far.is_none() {
            let mut it = self.d.iter().take(len).copied().enumerate();
            let mut best = it.next();
            if let Some(b) = best.as_mut() {
                for (i, x) in it {
                    if not_ge(b.1, x) {
                        *b = (i, x);
                    }
                }
            }
            self.far = best;
        }
        self.far
    }
}

/// `!(a >= b)`, the fold's test as first written (also true when either is NaN).
fn not_ge(a: f32, b: f32) -> bool {
    a.partial_cmp(&b).is_none_or(|o| o.is_lt())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cached farthest cell equals the first farthest recomputed from scratch after
    /// any sequence of distance changes (ties, the farthest cell itself changed, growth).
    #[test]
    fn the_cached_farthest_cell_is_the_first_farthest() {
        let mut seed = 0x0019_f00d_u64;
        let mut next = |n: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % n
        };
        for _ in 0..200 {
            let mut dist = Distances::<16>::new();
            for _ in 0..200 {
                let i = next(16) as usize;
                // Few distinct values: many ties.
                dist.set(i, next(6) as f32 * 0.5);
                if next(3) == 0 {
                    let got = dist.farthest(16);
                    let mut want = (0, dist.d[0]);
                    for (j, &x) in dist.d.iter().enumerate() {
                        if x > want.1 {
                            want = (j, x);
                        }
                    }
                    assert_eq!(got, Some(want), "{:?}", dist.d);
                }
            }
        }
    }
}
