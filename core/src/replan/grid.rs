//! The replanner's occupancy grid, 2.5-D: [`GRID`] × [`GRID`] square cells of edge `cell` (m),
//! each with a column of [`SLICES`] height slices of the same edge (one bit per slice, a
//! [`Column`] per cell), anchored in the world (NED x = rows, y = columns, z = slices) and moved
//! in whole cells to keep the vehicle near its centre (horizontally and vertically: the
//! window spans `SLICES · cell` of height, 3.2 m at the default 0.2 m, ±1.6 m of the vehicle).
//!
//! * **Marked**: a slice that holds an obstacle point. Bits are kept until the cell or slice
//!   leaves the window (static world assumed; points of moving obstacles are not marked by the
//!   caller). Points above or below the window are not marked (unknown, as unseen space).
//! * **Occupied at a level** ([`Grid::select_level`]): a cell with a marked slice overlapping
//!   the level's height band `[z − band, z + band]` — the 2-D layer a plan at that flight level
//!   searches (slices are whole: a point up to one slice beyond the band may count).
//! * **Blocked** ([`Grid::inflate`]): an occupied cell or a cell whose centre is within the
//!   inflation radius (hull + margin, m) of an occupied cell's centre, or outside the flight
//!   area when one is set ([`Grid::set_area`], a geofence). Unknown space is free.
//! * **Column clear** ([`Grid::column_clear`]): no cell within the inflation radius of a cell
//!   has a marked slice in a height span (a climb or descent there, or a point's own level).
//! * **Line of sight** ([`Grid::line_free`]): every cell a segment crosses is free (a grid
//!   traversal, O(cells crossed) ≤ 2·[`GRID`]).
//!
//! Memory: 2 B per cell for the columns (8 KiB) and two bit layers (1 KiB).
//!
//! May import: `crate::fmath`, `crate::Vec3`.

use crate::fmath::floor_i32;
use crate::Vec3;

/// Cells per side of the grid (64: one `u64` per row).
pub const GRID: usize = 64;
/// Cells in the grid.
pub const CELLS: usize = GRID * GRID;

/// Height slices per cell (one bit each in a [`Column`]).
pub const SLICES: usize = 16;

/// Bit rows of a grid.
pub type Rows = [u64; GRID];

/// A cell's height slices, bit k = slice k (upwards in NED z: bit 0 is the highest slice).
pub type Column = u16;

/// The occupancy grid and its inflated copy (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Cell edge, m.
    cell: f32,
    /// World x, y (NED) of the corner of cell (0, 0), a whole multiple of `cell`.
    origin: [i32; 2],
    /// World NED z of slice 0's top, in slices (slice k spans `[(z0 + k)·cell, (z0 + k + 1)·cell)`).
    z0: i32,
    /// The marked slices of each cell (row-major).
    cols: [Column; CELLS],
    /// The layer of the level last selected ([`Grid::select_level`]).
    occupied: Rows,
    blocked: Rows,
    /// Flight area (NED x, y: min, max), m: cells whose centre lies outside are blocked.
    area: Option<([f32; 2], [f32; 2])>,
}

impl Grid {
    /// An empty grid of cell edge 0 at the origin, as a constant ([`crate::replan::Replanner::ZEROED`]).
    pub const ZEROED: Grid = Grid {
        cell: 0.0,
        origin: [0, 0],
        z0: 0,
        cols: [0; CELLS],
        occupied: [0; GRID],
        blocked: [0; GRID],
        area: None,
    };

    /// An empty grid of cells of edge `cell` m centred on `centre` (NED).
    pub fn new(cell: f32, centre: &Vec3) -> Self {
        let mut g = Grid::ZEROED;
        g.cell = cell;
        g.origin = g.origin_for(centre);
        g.z0 = g.z0_for(centre.z);
        g
    }

    /// Clear in place (no 8 KiB value on the stack): cell edge `cell`, centred on `centre`,
    /// the flight area kept.
    pub fn reset(&mut self, cell: f32, centre: &Vec3) {
        self.cell = cell;
        self.origin = self.origin_for(centre);
        self.z0 = self.z0_for(centre.z);
        self.cols.fill(0);
        self.occupied = [0; GRID];
        self.blocked = [0; GRID];
    }

    fn z0_for(&self, z: f32) -> i32 {
        floor_i32(z / self.cell) - (SLICES / 2) as i32
    }

    /// The slice (index in a [`Column`]) holding NED height `z`, `None` outside the window.
    fn slice_of(&self, z: f32) -> Option<usize> {
        if !z.is_finite() {
            return None;
        }
        let k = floor_i32(z / self.cell) - self.z0;
        (0..SLICES as i32).contains(&k).then_some(k as usize)
    }

    /// The height span `[lo, hi]` (NED z, m) lies inside the window.
    pub fn holds_span(&self, lo: f32, hi: f32) -> bool {
        self.slice_of(lo).is_some() && self.slice_of(hi).is_some() && lo <= hi
    }

    /// The slices overlapping `[lo, hi]` (NED z, m), clipped to the window.
    pub fn span_mask(&self, lo: f32, hi: f32) -> Column {
        if !(lo.is_finite() && hi.is_finite()) || lo > hi {
            return 0;
        }
        let a = (floor_i32(lo / self.cell) - self.z0).max(0);
        let b = (floor_i32(hi / self.cell) - self.z0).min(SLICES as i32 - 1);
        if a > b {
            return 0;
        }
        let upto = |k: i32| if k >= 16 { u32::MAX } else { (1u32 << k) - 1 };
        (upto(b + 1) & !upto(a)) as Column
    }

    /// The marked slices of cell (row, column) (0 outside the grid).
    pub fn column(&self, i: usize, j: usize) -> Column {
        if i < GRID && j < GRID {
            self.cols[i * GRID + j]
        } else {
            0
        }
    }

    /// Make the occupied layer the cells with a marked slice in `[z − band, z + band]` (NED,
    /// m), and clear the blocked layer ([`Grid::inflate`] it next). O([`CELLS`]).
    pub fn select_level(&mut self, z: f32, band: f32) {
        let mask = self.span_mask(z - band, z + band);
        for (i, row) in self.occupied.iter_mut().enumerate() {
            let mut bits = 0u64;
            for (j, c) in self.cols[i * GRID..(i + 1) * GRID].iter().enumerate() {
                if c & mask != 0 {
                    bits |= 1u64 << j;
                }
            }
            *row = bits;
        }
        self.blocked = [0; GRID];
    }

    /// No cell whose centre lies within `radius` m of cell (row, column)'s centre (the
    /// inflation's disc) has a marked slice in `span` ([`Grid::span_mask`]), cells with a
    /// marked slice in `except` aside (but not the cell itself). Cells outside the grid are
    /// unknown: free. O((2k+1)²), k = ⌊radius / cell⌋.
    pub fn column_clear(&self, i: usize, j: usize, span: Column, radius: f32, except: Column) -> bool {
        if self.column(i, j) & span != 0 {
            return false;
        }
        let k = if radius > 0.0 { floor_i32(radius / self.cell).clamp(0, GRID as i32) } else { 0 };
        let r2 = (radius / self.cell) * (radius / self.cell);
        for di in -k..=k {
            let rem = r2 - (di * di) as f32;
            if rem < 0.0 {
                continue;
            }
            let w = floor_i32(crate::fmath::sqrtf(rem)).clamp(0, GRID as i32);
            for dj in -w..=w {
                let (ni, nj) = (i as i32 + di, j as i32 + dj);
                if ni < 0 || nj < 0 {
                    continue;
                }
                let c = self.column(ni as usize, nj as usize);
                if c & span != 0 && c & except == 0 {
                    return false;
                }
            }
        }
        true
    }

    /// Cell edge, m.
    pub fn cell(&self) -> f32 {
        self.cell
    }

    fn origin_for(&self, centre: &Vec3) -> [i32; 2] {
        let half = (GRID / 2) as i32;
        [floor_i32(centre.x / self.cell) - half, floor_i32(centre.y / self.cell) - half]
    }

    /// Limit the search to a flight area (NED x, y, m; a geofence): cells whose centre lies
    /// outside `[lo, hi]` are blocked. `None`: no limit.
    pub fn set_area(&mut self, area: Option<([f32; 2], [f32; 2])>) {
        self.area = area;
    }

    /// The flight area set, if any.
    pub fn area(&self) -> Option<([f32; 2], [f32; 2])> {
        self.area
    }

    /// The centre of cell (row, column) lies in the flight area (always without one).
    pub fn in_area(&self, i: usize, j: usize) -> bool {
        let c = self.centre(i, j, 0.0);
        self.area.is_none_or(|(lo, hi)| c.x >= lo[0] && c.x <= hi[0] && c.y >= lo[1] && c.y <= hi[1])
    }

    /// Move the grid (whole cells and slices) so that `p` is at its centre when `p` is more
    /// than a quarter of the grid (horizontally, or of the window, vertically) from the centre;
    /// cells and slices leaving are forgotten, the layers cleared (select a level again).
    /// In place, O([`CELLS`]).
    pub fn follow(&mut self, p: &Vec3) {
        let want = self.origin_for(p);
        let (dx, dy) = (want[0] - self.origin[0], want[1] - self.origin[1]);
        let quarter = (GRID / 4) as i32;
        let horizontal = dx.abs() > quarter || dy.abs() > quarter;
        let wz = if p.z.is_finite() { self.z0_for(p.z) } else { self.z0 };
        let dz = wz - self.z0;
        let vertical = dz.abs() > (SLICES / 4) as i32;
        if !horizontal && !vertical {
            return;
        }
        let (dx, dy) = if horizontal { (dx, dy) } else { (0, 0) };
        let dz = if vertical { dz } else { 0 };
        // Cell (i, j) takes (i + dx, j + dy), slice k takes k + dz: walking towards the sources,
        // each is read before it is overwritten.
        let n = GRID as i32;
        for a in 0..n {
            let i = if dx >= 0 { a } else { n - 1 - a };
            for b in 0..n {
                let j = if dy >= 0 { b } else { n - 1 - b };
                let (si, sj) = (i + dx, j + dy);
                let src = if (0..n).contains(&si) && (0..n).contains(&sj) {
                    shift_column(self.cols[(si * n + sj) as usize], dz)
                } else {
                    0
                };
                self.cols[(i * n + j) as usize] = src;
            }
        }
        if horizontal {
            self.origin = want;
        }
        if vertical {
            self.z0 = wz;
        }
        self.occupied = [0; GRID];
        self.blocked = [0; GRID];
    }

    /// Cell (row, column) of a world point, `None` outside the grid.
    pub fn cell_of(&self, p: &Vec3) -> Option<(usize, usize)> {
        if !(p.x.is_finite() && p.y.is_finite()) {
            return None;
        }
        let i = floor_i32(p.x / self.cell) - self.origin[0];
        let j = floor_i32(p.y / self.cell) - self.origin[1];
        let inside = (0..GRID as i32).contains(&i) && (0..GRID as i32).contains(&j);
        inside.then_some((i as usize, j as usize))
    }

    /// World centre (NED x, y; z given) of cell (row, column).
    pub fn centre(&self, i: usize, j: usize, z: f32) -> Vec3 {
        Vec3::new(
            (self.origin[0] as f32 + i as f32 + 0.5) * self.cell,
            (self.origin[1] as f32 + j as f32 + 0.5) * self.cell,
            z,
        )
    }

    /// Mark the slice of `p` in its cell; `false` when `p` is outside the grid or the window.
    /// The occupied layer is not updated (select a level).
    pub fn mark(&mut self, p: &Vec3) -> bool {
        match (self.cell_of(p), self.slice_of(p.z)) {
            (Some((i, j)), Some(k)) => {
                self.cols[i * GRID + j] |= 1 << k;
                true
            }
            _ => false,
        }
    }

    /// Cell (row, column) holds an obstacle point at the level selected.
    pub fn is_occupied(&self, i: usize, j: usize) -> bool {
        i < GRID && j < GRID && self.occupied[i] & (1u64 << j) != 0
    }

    /// Cell (row, column) is blocked (after [`Grid::inflate`]); outside the grid or the flight
    /// area: blocked.
    pub fn is_blocked(&self, i: usize, j: usize) -> bool {
        i >= GRID || j >= GRID || self.blocked[i] & (1u64 << j) != 0 || !self.in_area(i, j)
    }

    /// Cells occupied at the level selected.
    pub fn occupied_count(&self) -> u32 {
        self.occupied.iter().map(|r| r.count_ones()).sum()
    }

    /// Cells with any marked slice.
    pub fn marked_count(&self) -> u32 {
        self.cols.iter().filter(|&&c| c != 0).count() as u32
    }

    /// Grow the occupied cells by `radius` m into the blocked set: a cell is blocked when its
    /// centre is within `radius` of an occupied cell's centre. O(GRID · (2k+1)) row operations,
    /// k = ⌊radius / cell⌋ (at most [`GRID`]).
    pub fn inflate(&mut self, radius: f32) {
        let k = if radius > 0.0 { floor_i32(radius / self.cell).clamp(0, GRID as i32) } else { 0 };
        let r2 = (radius / self.cell) * (radius / self.cell);
        self.blocked = self.occupied;
        for di in -k..=k {
            // Half-width of the disc's chord at row offset di, in cells.
            let rem = r2 - (di * di) as f32;
            if rem < 0.0 {
                continue;
            }
            let w = floor_i32(crate::fmath::sqrtf(rem)).clamp(0, GRID as i32);
            for i in 0..GRID {
                let src = i as i32 + di;
                if !(0..GRID as i32).contains(&src) {
                    continue;
                }
                let row = self.occupied[src as usize];
                if row == 0 {
                    continue;
                }
                let mut spread = row;
                for s in 1..=w {
                    spread |= shift_bits(row, s) | shift_bits(row, -s);
                }
                self.blocked[i] |= spread;
            }
        }
    }

    /// Every cell the segment `a → b` (NED x, y) crosses is inside the grid and passes
    /// `free(i, j)`. A grid traversal (Amanatides–Woo): at most 2·[`GRID`] cells.
    pub fn line_free(&self, a: &Vec3, b: &Vec3, free: impl Fn(usize, usize) -> bool) -> bool {
        let (Some((mut i, mut j)), Some((bi, bj))) = (self.cell_of(a), self.cell_of(b)) else {
            return false;
        };
        let (dx, dy) = ((b.x - a.x) / self.cell, (b.y - a.y) / self.cell);
        let (fx, fy) = (
            a.x / self.cell - self.origin[0] as f32 - i as f32,
            a.y / self.cell - self.origin[1] as f32 - j as f32,
        );
        let (si, sj) = (if dx > 0.0 { 1 } else { -1 }, if dy > 0.0 { 1i32 } else { -1 });
        let inv = |d: f32| if d != 0.0 { 1.0 / d.abs() } else { f32::INFINITY };
        let (tdx, tdy) = (inv(dx), inv(dy));
        let mut tx = if dx > 0.0 { (1.0 - fx) * tdx } else { fx * tdx };
        let mut ty = if dy > 0.0 { (1.0 - fy) * tdy } else { fy * tdy };
        for _ in 0..(4 * GRID) {
            if !free(i, j) {
                return false;
            }
            if i == bi && j == bj {
                return true;
            }
            let (ni, nj) = if tx < ty {
                tx += tdx;
                (i as i32 + si, j as i32)
            } else {
                ty += tdy;
                (i as i32, j as i32 + sj)
            };
            if !((0..GRID as i32).contains(&ni) && (0..GRID as i32).contains(&nj)) {
                return false;
            }
            (i, j) = (ni as usize, nj as usize);
        }
        false
    }
}

/// A column's slices moved by `s` (slice k → k − s); slices leaving are dropped.
fn shift_column(c: Column, s: i32) -> Column {
    match s {
        0 => c,
        s if s >= 16 || s <= -16 => 0,
        s if s > 0 => c >> s,
        s => c << (-s),
    }
}

/// `row` with its bits moved by `s` columns (bit j → j − s); bits leaving are dropped.
fn shift_bits(row: u64, s: i32) -> u64 {
    match s {
        0 => row,
        s if s >= 64 || s <= -64 => 0,
        s if s > 0 => row >> s,
        s => row << (-s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_inflates_and_follows() {
        let mut g = Grid::new(0.2, &Vec3::zeros());
        assert!(g.mark(&Vec3::new(1.01, 0.01, -1.0)));
        let (i, j) = g.cell_of(&Vec3::new(1.01, 0.01, -1.0)).unwrap_or((0, 0));
        assert_eq!((i, j), (37, 32));
        assert!(!g.mark(&Vec3::new(100.0, 0.0, 0.0)));
        assert!(!g.mark(&Vec3::new(1.01, 0.01, -5.0)), "above the window");
        g.select_level(-1.0, 0.3);
        g.inflate(0.45);
        // Radius 0.45 m = 2.25 cells: two cells along the axes, one on the diagonal.
        assert!(g.is_blocked(i + 2, j) && g.is_blocked(i, j - 2) && !g.is_blocked(i + 3, j));
        assert!(g.is_blocked(i + 1, j + 1) && g.is_blocked(i + 2, j + 1) && !g.is_blocked(i + 2, j + 2));
        // The vehicle moves 5 m north: the grid follows and the mark keeps its world place.
        g.follow(&Vec3::new(5.0, 0.0, -1.0));
        assert_eq!(g.cell_of(&Vec3::new(1.01, 0.01, -1.0)), Some((12, 32)));
        g.select_level(-1.0, 0.3);
        assert!(g.is_occupied(12, 32) && g.occupied_count() == 1);
        // The mark keeps its height too: not in the layer of a level 1 m up or down.
        g.select_level(-2.0, 0.3);
        assert_eq!((g.occupied_count(), g.marked_count()), (0, 1));
        g.select_level(0.0, 0.3);
        assert_eq!(g.occupied_count(), 0);
        g.follow(&Vec3::new(50.0, 0.0, -1.0));
        assert_eq!(g.occupied_count(), 0, "left the grid");
    }

    #[test]
    fn line_of_sight_crosses_every_cell_it_touches() {
        let mut g = Grid::new(0.2, &Vec3::zeros());
        g.mark(&Vec3::new(1.0, 0.5, 0.0));
        g.select_level(0.0, 0.3);
        g.inflate(0.0);
        let free = |i, j| !g.is_blocked(i, j);
        assert!(!g.line_free(&Vec3::new(0.1, 0.1, 0.0), &Vec3::new(1.9, 0.9, 0.0), free));
        assert!(g.line_free(&Vec3::new(0.1, 0.1, 0.0), &Vec3::new(1.9, 0.1, 0.0), free));
        assert!(!g.line_free(&Vec3::new(0.1, 0.1, 0.0), &Vec3::new(99.0, 0.1, 0.0), free), "leaves the grid");
    }

    #[test]
    fn columns_hold_heights_and_follow_vertically() {
        let mut g = Grid::new(0.2, &Vec3::new(0.0, 0.0, -1.0));
        // A table top at 0.75 m (NED -0.75) and a shelf at 1.9 m in the same cell.
        let (top, shelf) = (Vec3::new(1.0, 1.0, -0.75), Vec3::new(1.0, 1.0, -1.9));
        assert!(g.mark(&top) && g.mark(&shelf));
        let (i, j) = g.cell_of(&top).unwrap_or((0, 0));
        // Flight levels: 1.2 m (band 0.9..1.5) is clear between them, 0.8 m and 1.8 m are not.
        for (z, occupied) in [(-1.2, false), (-0.8, true), (-1.8, true)] {
            g.select_level(z, 0.3);
            assert_eq!(g.is_occupied(i, j), occupied, "level {z}");
        }
        // A climb from 1.2 m to 1.8 m through the cell or beside it (within 0.32 m) is not
        // clear; two cells away it is; beside the shelf's cell the shelf is no exception.
        let climb = g.span_mask(-1.8 - 0.3, -1.2 + 0.3);
        assert!(!g.column_clear(i, j, climb, 0.32, 0));
        assert!(!g.column_clear(i + 1, j, climb, 0.32, 0));
        assert!(g.column_clear(i + 2, j, climb, 0.32, 0));
        // The vehicle moves up 2 m: the window follows; the shelf (0.1 m above its old top) stays.
        g.follow(&Vec3::new(0.0, 0.0, -3.0));
        g.select_level(-1.9, 0.1);
        assert!(g.is_occupied(i, j));
        assert!(!g.mark(&Vec3::new(1.0, 1.0, -0.3)), "below the window now");
    }
}
