//! A scan's beam directions with the sines and cosines computed once per scan: the
//! `(sin, cos)` of each column's azimuth and each row's elevation, so that a beam's
//! direction is three products instead of a `sincosf` each time one of the scan's passes
//! (see-through clearing, insertion, segments, frontier, free-cell map) needs it.
//!
//! [`ScanTrig::direction`] equals [`ScanGeometry::direction`] bit for bit (the same
//! `sincosf` of the same angles, the same products); a scan wider than [`TRIG_COLS`]
//! columns or taller than [`TRIG_ROWS`] rows is not tabulated and every direction falls
//! back to [`ScanGeometry::direction`]. Fixed size: 704 bytes of table
//! ([`TRIG_COLS`] = 72, an `OBSTACLE_DISTANCE`'s sectors), no allocation.
//!
//! May import: the parent module ([`ScanGeometry`], [`Range`]), `crate::fmath`, `crate::Vec3`.

use super::{Range, ScanGeometry};
use crate::Vec3;
use nalgebra::Matrix3;

/// Columns a [`ScanTrig`] tabulates (a 72-sector `OBSTACLE_DISTANCE`, a decimated camera).
pub const TRIG_COLS: usize = 72;
/// Rows a [`ScanTrig`] tabulates.
pub const TRIG_ROWS: usize = 16;

/// A scan geometry and, when it fits, its columns' and rows' `(sin, cos)`.
#[derive(Clone, Copy, Debug)]
pub struct ScanTrig {
    geometry: ScanGeometry,
    /// The tables hold `geometry`'s columns and rows.
    tabulated: bool,
    cols: [(f32, f32); TRIG_COLS],
    rows: [(f32, f32); TRIG_ROWS],
}

impl ScanTrig {
    /// Nothing tabulated (every direction computed): a placeholder until [`Self::fill`].
    pub const fn empty(geometry: ScanGeometry) -> Self {
        ScanTrig { geometry, tabulated: false, cols: [(0.0, 1.0); TRIG_COLS], rows: [(0.0, 1.0); TRIG_ROWS] }
    }

    /// The tables of `g`.
    pub fn of(g: &ScanGeometry) -> Self {
        let mut t = Self::empty(*g);
        t.fill(g);
        t
    }

    /// Tabulates `g` (`n_az + n_el` `sincosf`), or only records it when it is wider than
    /// [`TRIG_COLS`] or taller than [`TRIG_ROWS`].
    pub fn fill(&mut self, g: &ScanGeometry) {
        self.geometry = *g;
        let (n_az, n_el) = (usize::from(g.n_az), usize::from(g.n_el));
        self.tabulated = n_az <= TRIG_COLS && n_el <= TRIG_ROWS;
        if !self.tabulated {
            return;
        }
        for (col, c) in self.cols.iter_mut().enumerate().take(n_az) {
            *c = g.column_azimuth(col as u16);
        }
        for (row, r) in self.rows.iter_mut().enumerate().take(n_el) {
            *r = g.row_elevation(row as u16);
        }
    }

    /// The geometry.
    pub fn geometry(&self) -> &ScanGeometry {
        &self.geometry
    }

    /// Sensor-frame unit direction of beam `(row, col)`: [`ScanGeometry::direction`].
    #[inline]
    pub fn direction(&self, row: u16, col: u16) -> Vec3 {
        if self.tabulated {
            if let (Some(&az), Some(&el)) = (self.cols.get(usize::from(col)), self.rows.get(usize::from(row)))
            {
                return ScanGeometry::direction_of(el, az);
            }
        }
        self.geometry.direction(row, col)
    }

    /// Calls `f` with the world direction and free length of every beam that observed free
    /// space — a return within `[min_range, max_range)` (free up to it) or nothing within
    /// `max_range` (free up to that) — and whose world direction `u = r_ws·d` is within
    /// `sin_band` of horizontal (`|u.z| ≤ sin_band`): `f(u, free)`, in the order of `ranges`
    /// (row-major). What the frontier's sectors and the free-cell map take from a scan.
    /// Bounded by `n_el × n_az`.
    pub fn for_each_free_beam(
        &self,
        r_ws: &Matrix3<f32>,
        ranges: &[Range],
        sin_band: f32,
        mut f: impl FnMut(Vec3, f32),
    ) {
        let g = &self.geometry;
        let mut k = 0usize;
        for row in 0..g.n_el {
            for col in 0..g.n_az {
                let r = ranges.get(k).copied().unwrap_or(Range::Unknown);
                k += 1;
                let free = match r {
                    Range::Hit(x) if x >= g.min_range && x < g.max_range => x,
                    Range::Clear => g.max_range,
                    _ => continue,
                };
                let u = r_ws * self.direction(row, col);
                if u.z.abs() > sin_band {
                    continue;
                }
                f(u, free);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every beam of tabulated and untabulated geometries equals `ScanGeometry::direction`
    /// bit for bit (a table built from other angles, or read at the wrong index, fails).
    #[test]
    fn directions_are_the_geometrys_bit_for_bit() {
        let geometries = super::super::sample_geometries();
        let mut reused = ScanTrig::empty(geometries[3]);
        for g in &geometries {
            let t = ScanTrig::of(g);
            reused.fill(g);
            let fits = usize::from(g.n_az) <= TRIG_COLS && usize::from(g.n_el) <= TRIG_ROWS;
            assert_eq!(t.tabulated, fits);
            for row in 0..g.n_el {
                for col in 0..g.n_az {
                    let want = g.direction(row, col);
                    for got in [t.direction(row, col), reused.direction(row, col)] {
                        assert_eq!(
                            [got.x.to_bits(), got.y.to_bits(), got.z.to_bits()],
                            [want.x.to_bits(), want.y.to_bits(), want.z.to_bits()],
                            "{g:?} beam ({row}, {col})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn free_beams_are_the_horizontal_returns_and_clears() {
        let g = ScanGeometry::grid(4, 3, 1.2, 0.9, 0.2, 5.0);
        let t = ScanTrig::of(&g);
        let mut ranges = [Range::Unknown; 12];
        ranges[4] = Range::Hit(2.0); // middle row, col 0
        ranges[5] = Range::Clear; // middle row, col 1
        ranges[6] = Range::Hit(0.1); // below min_range
        ranges[0] = Range::Hit(3.0); // bottom row: 0.3 rad down
        let mut seen = heapless::Vec::<(Vec3, f32), 12>::new();
        t.for_each_free_beam(&Matrix3::identity(), &ranges, 0.1, |u, free| {
            let _ = seen.push((u, free));
        });
        assert_eq!(seen.len(), 2);
        assert_eq!(seen[0], (g.direction(1, 0), 2.0));
        assert_eq!(seen[1], (g.direction(1, 1), 5.0));
    }
}
