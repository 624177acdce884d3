//! The replanner's horizontal occupancy grid: [`GRID`] × [`GRID`] square cells of edge
//! `cell` (m) at the flight level, one bit per cell (a `u64` per row), anchored in the world
//! (NED x = rows, y = bits) and moved in whole cells to keep the vehicle near its centre.
//!
//! * **Occupied**: a cell that holds an obstacle point seen within the height band around
//!   the flight level. Bits are kept until the cell leaves the grid (static world assumed;
//!   points of moving obstacles are not marked by the caller).
//! * **Blocked** ([`Grid::inflate`]): an occupied cell or a cell whose centre is within the
//!   inflation radius (hull + margin, m) of an occupied cell's centre, or outside the flight
//!   area when one is set ([`Grid::set_area`], a geofence). Unknown space is free.
//! * **Line of sight** ([`Grid::line_free`]): every cell a segment crosses is free (a grid
//!   traversal, O(cells crossed) ≤ 2·[`GRID`]).
//!
//! May import: `crate::fmath`, `crate::Vec3`.

use crate::fmath::floor_i32;
use crate::Vec3;

/// Cells per side of the grid (64: one `u64` per row).
pub const GRID: usize = 64;
/// Cells in the grid.
pub const CELLS: usize = GRID * GRID;

/// Bit rows of a grid.
pub type Rows = [u64; GRID];

/// The occupancy grid and its inflated copy (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Cell edge, m.
    cell: f32,
    /// World x, y (NED) of the corner of cell (0, 0), a whole multiple of `cell`.
    origin: [i32; 2],
    occupied: Rows,
    blocked: Rows,
    /// Flight area (NED x, y: min, max), m: cells whose centre lies outside are blocked.
    area: Option<([f32; 2], [f32; 2])>,
}

impl Grid {
    /// An empty grid of cell edge 0 at the origin, as a constant ([`crate::replan::Replanner::ZEROED`]).
    pub const ZEROED: Grid =
        Grid { cell: 0.0, origin: [0, 0], occupied: [0; GRID], blocked: [0; GRID], area: None };

    /// An empty grid of cells of edge `cell` m centred on `centre` (NED).
    pub fn new(cell: f32, centre: &Vec3) -> Self {
        let mut g = Grid { cell, origin: [0, 0], occupied: [0; GRID], blocked: [0; GRID], area: None };
        g.origin = g.origin_for(centre);
        g
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

    /// Move the grid (whole cells) so that `p` is at its centre when `p` is more than a
    /// quarter of the grid from the centre; cells leaving the grid are forgotten. O(GRID).
    pub fn follow(&mut self, p: &Vec3) {
        let want = self.origin_for(p);
        let (dx, dy) = (want[0] - self.origin[0], want[1] - self.origin[1]);
        let quarter = (GRID / 4) as i32;
        if dx.abs() <= quarter && dy.abs() <= quarter {
            return;
        }
        let old = self.occupied;
        self.occupied = [0; GRID];
        for (i, row) in self.occupied.iter_mut().enumerate() {
            let src = i as i32 + dx;
            if (0..GRID as i32).contains(&src) {
                *row = shift_bits(old[src as usize], dy);
            }
        }
        self.origin = want;
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

    /// Mark the cell of `p` occupied; `false` when `p` is outside the grid.
    pub fn mark(&mut self, p: &Vec3) -> bool {
        match self.cell_of(p) {
            Some((i, j)) => {
                self.occupied[i] |= 1u64 << j;
                true
            }
            None => false,
        }
    }

    /// Cell (row, column) holds an obstacle point.
    pub fn is_occupied(&self, i: usize, j: usize) -> bool {
        i < GRID && j < GRID && self.occupied[i] & (1u64 << j) != 0
    }

    /// Cell (row, column) is blocked (after [`Grid::inflate`]); outside the grid or the flight
    /// area: blocked.
    pub fn is_blocked(&self, i: usize, j: usize) -> bool {
        i >= GRID || j >= GRID || self.blocked[i] & (1u64 << j) != 0 || !self.in_area(i, j)
    }

    /// `p` (NED x, y) lies within `r` m of the centre of an occupied cell of its own or the
    /// eight neighbouring cells.
    pub fn near_occupied(&self, p: &Vec3, r: f32) -> bool {
        let Some((i, j)) = self.cell_of(p) else { return false };
        for di in -1i32..=1 {
            for dj in -1i32..=1 {
                let (ni, nj) = (i as i32 + di, j as i32 + dj);
                if ni < 0 || nj < 0 || !self.is_occupied(ni as usize, nj as usize) {
                    continue;
                }
                let c = self.centre(ni as usize, nj as usize, p.z);
                if (c - p).xy().norm_squared() <= r * r {
                    return true;
                }
            }
        }
        false
    }

    /// Occupied cells.
    pub fn occupied_count(&self) -> u32 {
        self.occupied.iter().map(|r| r.count_ones()).sum()
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
        g.inflate(0.45);
        // Radius 0.45 m = 2.25 cells: two cells along the axes, one on the diagonal.
        assert!(g.is_blocked(i + 2, j) && g.is_blocked(i, j - 2) && !g.is_blocked(i + 3, j));
        assert!(g.is_blocked(i + 1, j + 1) && g.is_blocked(i + 2, j + 1) && !g.is_blocked(i + 2, j + 2));
        // The vehicle moves 5 m north: the grid follows and the mark keeps its world place.
        g.follow(&Vec3::new(5.0, 0.0, -1.0));
        assert_eq!(g.cell_of(&Vec3::new(1.01, 0.01, -1.0)), Some((12, 32)));
        assert!(g.is_occupied(12, 32) && g.occupied_count() == 1);
        g.follow(&Vec3::new(50.0, 0.0, -1.0));
        assert_eq!(g.occupied_count(), 0, "left the grid");
    }

    #[test]
    fn line_of_sight_crosses_every_cell_it_touches() {
        let mut g = Grid::new(0.2, &Vec3::zeros());
        g.mark(&Vec3::new(1.0, 0.5, 0.0));
        g.inflate(0.0);
        let free = |i, j| !g.is_blocked(i, j);
        assert!(!g.line_free(&Vec3::new(0.1, 0.1, 0.0), &Vec3::new(1.9, 0.9, 0.0), free));
        assert!(g.line_free(&Vec3::new(0.1, 0.1, 0.0), &Vec3::new(1.9, 0.1, 0.0), free));
        assert!(!g.line_free(&Vec3::new(0.1, 0.1, 0.0), &Vec3::new(99.0, 0.1, 0.0), free), "leaves the grid");
    }
}
