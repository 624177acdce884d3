//! A world-fixed 2D map of the space observed free at the flight level, and the free length
//! of the corridor a hull would sweep through it. Used by [`super::frontier`] to *extend* the
//! per-sector free range where space was seen from earlier positions (beside and behind a
//! forward sensor); it never shortens it.
//!
//! **Map.** [`SIDE`] × [`SIDE`] cells of [`CELL`] m (12.8 m square, one bit per cell, 512 B),
//! fixed in the world, re-centred on the vehicle in whole cells (what leaves the square is
//! forgotten) when the vehicle is more than [`RECENTRE`] cells from its centre, and started
//! again (empty) when the altitude has left the band it was started in.
//!
//! **Marking (conservative).** A beam with information (a return at r, or nothing within
//! `max_range`) marks a cell free only when its horizontal projection passes within
//! [`CENTRE_PASS`] of the cell's centre and the beam goes on at least [`SEE_BEYOND`] past the
//! cell, within the hull's vertical band (`band` of the flight level) all the way: an
//! obstacle covering the middle of a cell can never be marked free, and the cell just in
//! front of a return never is. Then every return within the band clears its cell (a surface
//! there), and a scan's returns win over its own beams.
//!
//! **Corridor.** From `p` along the horizontal unit direction `u`, a hull of radius `m` sweeps a
//! strip of half-width `m`; along lines parallel to `u` across it (at most [`CELL`] apart, so
//! that no cell meeting the strip is missed) the first cell that is not free is met at
//! `L(o)` (exact grid traversal, Amanatides & Woo), and the hull's centre can advance
//! `min_o (L(o) − √(m² − o²))` with the whole disc on free cells.
//!
//! Where it ends: the cells are 0.2 m; an obstacle thinner than about a third of a cell that
//! lies off every marking beam's centre pass (a thin pole near a cell's corner) can sit in a
//! cell marked free — the beam-spacing limit of `docs/filter.md` § 14 at the map's resolution.
//! Static world: movers are the tracks' business ([`super::track`]).
//!
//! Bounded: a scan walks at most `beams × MAX_WALK` cells, a corridor at most
//! [`MAX_LINES`] × `MAX_WALK`. Written by hand: a fixed bit grid with a grid traversal has no
//! no_std, allocation-free crate here.
//!
//! May import: `crate::fmath`, `crate::Vec3`, the parent module's types.

// The comparisons are written so that a NaN fails them (`!(t <= len)` is true for a NaN):
// bad inputs end a walk or answer 0 instead of running on.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::{Range, ScanTrig, HORIZONTAL_BAND};
use crate::fmath::{hypotf, sqrtf};
use crate::Vec3;
use nalgebra::Matrix3;

/// Cell side, m.
pub const CELL: f32 = 0.2;
/// Cells per side of the map (one `u64` row per y index).
pub const SIDE: usize = 64;
/// Re-centre when the vehicle is this many cells (x or y) from the centre: at least
/// `(SIDE/2 − RECENTRE)·CELL` = 4.8 m of map around the vehicle.
pub const RECENTRE: i32 = 8;
/// Lines across a corridor at most (offsets ≤ [`CELL`] apart up to a half-width of 2.4 m).
pub const MAX_LINES: usize = 25;
/// A beam marks a cell only when its line passes this close to the cell's centre, m.
pub const CENTRE_PASS: f32 = 0.05;
/// … and goes on at least this far past the cell, m.
pub const SEE_BEYOND: f32 = 0.3;
/// Longest grid walk, cells.
const MAX_WALK: usize = 2 * SIDE + 2;
const HALF: i32 = (SIDE / 2) as i32;

/// The observed free cells at the flight level.
#[derive(Clone, Debug)]
pub struct FreeGrid {
    rows: [u64; SIDE],
    x0: i32,
    y0: i32,
    /// Flight level (NED z) of the map; NaN before the first scan.
    z_ref: f32,
}

impl Default for FreeGrid {
    fn default() -> Self {
        Self::new()
    }
}

fn cell_of(x: f32) -> i32 {
    crate::fmath::floor_i32(x / CELL)
}

/// Within ±10⁶ m horizontally and finite (cell indices far from overflow).
fn usable(p: &Vec3) -> bool {
    p.x.abs() <= 1e6 && p.y.abs() <= 1e6 && p.z.is_finite()
}

/// Number of lines across a corridor of half-width `m`.
fn lines(m: f32) -> usize {
    (libm::ceilf(2.0 * m / CELL) as usize + 1).clamp(2, MAX_LINES)
}

/// The cells crossed by the segment from `(ax, ay)` along the unit `(dx, dy)` for `len` m,
/// in order: `visit(ix, iy, t_in, t_out)`; stops when it returns false. ≤ [`MAX_WALK`] cells.
fn walk(ax: f32, ay: f32, dx: f32, dy: f32, len: f32, mut visit: impl FnMut(i32, i32, f32, f32) -> bool) {
    let (mut ix, mut iy) = (cell_of(ax), cell_of(ay));
    let axis = |a: f32, d: f32, i: i32| -> (i32, f32, f32) {
        if d > 0.0 {
            (1, ((i + 1) as f32 * CELL - a) / d, CELL / d)
        } else if d < 0.0 {
            (-1, (i as f32 * CELL - a) / d, -CELL / d)
        } else {
            (0, f32::INFINITY, f32::INFINITY)
        }
    };
    let (sx, mut tx, ddx) = axis(ax, dx, ix);
    let (sy, mut ty, ddy) = axis(ay, dy, iy);
    let mut t = 0.0f32;
    for _ in 0..MAX_WALK {
        let next = if tx < ty { tx } else { ty };
        if !visit(ix, iy, t, next) {
            return;
        }
        if tx < ty {
            ix = ix.saturating_add(sx);
            tx += ddx;
        } else {
            iy = iy.saturating_add(sy);
            ty += ddy;
        }
        t = next;
        if !(t <= len) {
            return;
        }
    }
}

/// Moves the bits by `(dx, dy)` cells (the map's origin moves by that much).
fn shift(rows: &mut [u64; SIDE], dx: i32, dy: i32) {
    let old = *rows;
    for (j, r) in rows.iter_mut().enumerate() {
        let src = (j as i32).wrapping_add(dy);
        let o = if (0..SIDE as i32).contains(&src) { old.get(src as usize).copied().unwrap_or(0) } else { 0 };
        *r = if !(-63..=63).contains(&dx) {
            0
        } else if dx >= 0 {
            o >> dx
        } else {
            o << -dx
        };
    }
}

impl FreeGrid {
    /// Nothing observed.
    pub const fn new() -> Self {
        FreeGrid { rows: [0; SIDE], x0: 0, y0: 0, z_ref: f32::NAN }
    }

    fn bit(&self, ix: i32, iy: i32) -> Option<(usize, u64)> {
        let (i, j) = (ix.wrapping_sub(self.x0), iy.wrapping_sub(self.y0));
        if !(0..SIDE as i32).contains(&i) || !(0..SIDE as i32).contains(&j) {
            return None;
        }
        Some((j as usize, 1u64 << i))
    }

    /// Whether world cell `(ix, iy)` is marked free (false outside the map).
    pub fn is_free(&self, ix: i32, iy: i32) -> bool {
        self.bit(ix, iy).and_then(|(j, b)| self.rows.get(j).map(|r| r & b != 0)).unwrap_or(false)
    }

    /// Marks world cell `(ix, iy)`; false outside the map.
    fn set(&mut self, ix: i32, iy: i32, free: bool) -> bool {
        let Some((j, b)) = self.bit(ix, iy) else { return false };
        if let Some(r) = self.rows.get_mut(j) {
            if free {
                *r |= b;
            } else {
                *r &= !b;
            }
        }
        true
    }

    /// Cells marked free.
    pub fn free_cells(&self) -> u32 {
        self.rows.iter().map(|r| r.count_ones()).sum()
    }

    /// Whether the map holds the flight level of altitude `z` (NED) for a band `band`.
    pub fn holds_level(&self, z: f32, band: f32) -> bool {
        (z - self.z_ref).abs() <= band
    }

    /// Starts a new map at `p`'s level when `p` left the band, re-centres it when `p` is
    /// [`RECENTRE`] cells from its centre.
    fn hold(&mut self, p: &Vec3, band: f32) {
        let (cx, cy) = (cell_of(p.x), cell_of(p.y));
        if !self.holds_level(p.z, band) {
            self.rows = [0; SIDE];
            self.x0 = cx.saturating_sub(HALF);
            self.y0 = cy.saturating_sub(HALF);
            self.z_ref = p.z;
            return;
        }
        let (dx, dy) =
            (cx.saturating_sub(HALF).wrapping_sub(self.x0), cy.saturating_sub(HALF).wrapping_sub(self.y0));
        if dx.abs() <= RECENTRE && dy.abs() <= RECENTRE {
            return;
        }
        shift(&mut self.rows, dx, dy);
        self.x0 = self.x0.wrapping_add(dx);
        self.y0 = self.y0.wrapping_add(dy);
    }

    /// Record one scan: `origin` = the sensor's world position, `r_ws` = sensor → world,
    /// `trig` = the scan's geometry (its directions), `band` = the hull's vertical half-extent, m.
    pub fn record(
        &mut self,
        origin: &Vec3,
        r_ws: &Matrix3<f32>,
        trig: &ScanTrig,
        ranges: &[Range],
        band: f32,
    ) {
        let g = trig.geometry();
        if !(usable(origin) && band > 0.0 && band.is_finite()) {
            return;
        }
        self.hold(origin, band);
        let sin_band = libm::sinf(HORIZONTAL_BAND);
        let (lo, hi) = (self.z_ref - band, self.z_ref + band);
        // 1. Free cells along the beams.
        trig.for_each_free_beam(r_ws, ranges, sin_band, |u, free| {
            // Within [lo, hi] in z (NED) along origin.z + t·u.z.
            let t_band = if u.z > 0.0 {
                (hi - origin.z) / u.z
            } else if u.z < 0.0 {
                (lo - origin.z) / u.z
            } else {
                f32::INFINITY
            };
            let len = if t_band < free { t_band } else { free };
            let h = hypotf(u.x, u.y);
            if !(len > SEE_BEYOND && h > 0.0) {
                return;
            }
            let (dx, dy) = (u.x / h, u.y / h);
            let lh = len * h;
            let reach = lh - SEE_BEYOND * h;
            walk(origin.x, origin.y, dx, dy, lh, |ix, iy, _, t_out| {
                if t_out > reach {
                    return false;
                }
                let (cx, cy) = ((ix as f32 + 0.5) * CELL - origin.x, (iy as f32 + 0.5) * CELL - origin.y);
                let along = cx * dx + cy * dy;
                if along >= 0.0 && (cx * dy - cy * dx).abs() <= CENTRE_PASS {
                    return self.set(ix, iy, true);
                }
                self.bit(ix, iy).is_some()
            });
        });
        // 2. A return within the band: a surface in its cell.
        let mut k = 0usize;
        for row in 0..g.n_el {
            for col in 0..g.n_az {
                let r = ranges.get(k).copied().unwrap_or(Range::Unknown);
                k += 1;
                if let Range::Hit(x) = r {
                    if x >= g.min_range && x < g.max_range {
                        let w = origin + r_ws * (trig.direction(row, col) * x);
                        if w.z >= lo && w.z <= hi && usable(&w) {
                            self.set(cell_of(w.x), cell_of(w.y), false);
                        }
                    }
                }
            }
        }
    }

    /// How far the centre of a hull of radius `m` at `p` can advance along the horizontal unit
    /// direction `u` with the whole disc on free cells, looking `reach` m ahead (more than
    /// `reach` when all of it is free), m; 0 when `p` is not at the map's level or not usable.
    /// The cells under the hull now are not required (the vehicle is there).
    pub fn corridor(&self, p: &Vec3, u: &Vec3, m: f32, reach: f32) -> f32 {
        if !(usable(p) && m > 0.0 && m.is_finite() && reach >= 0.0 && self.holds_level(p.z, m)) {
            return 0.0;
        }
        let n = lines(m);
        let mut best = f32::INFINITY;
        for k in 0..n {
            let o = -m + 2.0 * m * k as f32 / (n - 1) as f32;
            let s0 = sqrtf((m * m - o * o).max(0.0));
            // From the disc's front on this line.
            let (ax, ay) = (p.x - o * u.y + s0 * u.x, p.y + o * u.x + s0 * u.y);
            let len = reach + CELL;
            let mut l = len;
            walk(ax, ay, u.x, u.y, len, |ix, iy, t_in, _| {
                if self.is_free(ix, iy) {
                    true
                } else {
                    l = t_in;
                    false
                }
            });
            if l < best {
                best = l;
            }
        }
        if best > 0.0 {
            best
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::perception::ScanGeometry;

    fn ring(n: u16) -> ScanGeometry {
        ScanGeometry::planar_360(n, 0.05, 0.1, 10.0)
    }

    /// The grid walk visits exactly the cells a dense sampling of the segment meets.
    #[test]
    fn the_walk_visits_the_cells_of_the_segment() {
        let mut seed = 0x9e37_79b9u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed as f32 / u32::MAX as f32) * 2.0 - 1.0
        };
        for _ in 0..500 {
            let (ax, ay) = (next() * 3.0, next() * 3.0);
            let a = next() * 3.2;
            let (dx, dy) = (libm::cosf(a), libm::sinf(a));
            let len = (next() + 1.0) * 2.0;
            let mut got = std::vec::Vec::new();
            walk(ax, ay, dx, dy, len, |ix, iy, _, _| {
                got.push((ix, iy));
                true
            });
            let mut want = std::vec::Vec::new();
            for i in 0..=20_000 {
                let t = len * i as f32 / 20_000.0;
                let c = (cell_of(ax + t * dx), cell_of(ay + t * dy));
                if want.last() != Some(&c) {
                    want.push(c);
                }
            }
            // Sampling can miss a corner the exact walk touches, never the reverse.
            for c in &want {
                assert!(got.contains(c), "{c:?} missing: {got:?}");
            }
            assert!(got.len() <= want.len() + 2, "{} > {}", got.len(), want.len());
        }
    }

    /// A 360° ring of clear beams marks the space around; a return clears its cell and the
    /// corridor stops before it; nothing is free before the first scan.
    #[test]
    fn a_scan_marks_free_space_and_a_return_stops_the_corridor() {
        let mut g = FreeGrid::new();
        let p = Vec3::new(0.1, 0.1, -1.0);
        let east = Vec3::new(1.0, 0.0, 0.0);
        assert_eq!(g.corridor(&p, &east, 0.25, 3.0), 0.0);
        let geo = ring(360);
        let mut r = [Range::Clear; 360];
        g.record(&p, &Matrix3::identity(), &ScanTrig::of(&geo), &r, 0.25);
        assert!(g.free_cells() > 100, "{}", g.free_cells());
        assert!(g.corridor(&p, &east, 0.25, 3.0) > 3.0);
        // A wall 2 m east (beams within ±10° of east return there).
        for (i, x) in r.iter_mut().enumerate() {
            if !(11..350).contains(&i) {
                *x = Range::Hit(2.0 / libm::cosf((i as f32).to_radians()));
            }
        }
        let mut g = FreeGrid::new();
        g.record(&p, &Matrix3::identity(), &ScanTrig::of(&geo), &r, 0.25);
        let c = g.corridor(&p, &east, 0.25, 3.0);
        assert!(c > 1.0 && c < 1.9 - 0.25 + 1e-3, "{c}");
        // West is free.
        assert!(g.corridor(&p, &-east, 0.25, 3.0) > 3.0);
    }

    /// The free length is world-fixed: moving towards the boundary shortens it by the move.
    #[test]
    fn the_corridor_shrinks_by_the_distance_flown() {
        let mut g = FreeGrid::new();
        // A narrow forward fan (±17°, 6 m) seen from 2.1 m behind the vehicle.
        let geo = ScanGeometry::grid(61, 1, 0.6, 0.05, 0.1, 6.0);
        g.record(
            &Vec3::new(-2.0, 0.1, -1.0),
            &Matrix3::identity(),
            &ScanTrig::of(&geo),
            &[Range::Clear; 61],
            0.25,
        );
        let p = Vec3::new(0.1, 0.1, -1.0);
        let east = Vec3::new(1.0, 0.0, 0.0);
        let c0 = g.corridor(&p, &east, 0.2, 5.0);
        assert!(c0 > 1.0 && c0 < 4.0, "{c0}");
        let q = p + east * 0.5;
        let c1 = g.corridor(&q, &east, 0.2, 5.0);
        assert!((c0 - c1 - 0.5).abs() < 1e-4, "{c0} {c1}");
        // Sideways close to the fan's origin little was seen (±17°: 0.21 m at 0.7 m, the next
        // cell's centre): the hull may advance less than a cell there.
        let side = g.corridor(&Vec3::new(-1.4, 0.1, -1.0), &Vec3::new(0.0, 1.0, 0.0), 0.2, 5.0);
        assert!(side < CELL, "{side}");
        // Further back, beside the fan's origin, nothing was seen: no advance at all.
        assert_eq!(g.corridor(&Vec3::new(-2.0, 0.1, -1.0), &Vec3::new(0.0, 1.0, 0.0), 0.2, 5.0), 0.0);
    }

    /// A cell whose centre is covered (a return there) is never marked free by a later beam
    /// passing its edge; re-centring keeps cells; a new flight level starts empty.
    #[test]
    fn returns_recentring_and_levels() {
        let mut g = FreeGrid::new();
        let p = Vec3::new(0.1, 0.1, -1.0);
        g.record(&p, &Matrix3::identity(), &ScanTrig::of(&ring(360)), &[Range::Clear; 360], 0.25);
        let n = g.free_cells();
        let (ix, iy) = (cell_of(2.0), cell_of(0.1));
        assert!(g.is_free(ix, iy));
        // Move 2 m east (10 cells, past RECENTRE): the cell is still free.
        let q = Vec3::new(2.1, 0.1, -1.0);
        g.record(&q, &Matrix3::identity(), &ScanTrig::of(&ring(1)), &[Range::Unknown], 0.25);
        assert!(g.is_free(ix, iy));
        assert!(g.free_cells() <= n);
        // 0.5 m higher: a new level.
        let hi = Vec3::new(2.1, 0.1, -1.5);
        g.record(&hi, &Matrix3::identity(), &ScanTrig::of(&ring(1)), &[Range::Unknown], 0.25);
        assert_eq!(g.free_cells(), 0);
        // Non-finite inputs change nothing and answer 0.
        let nan = Vec3::new(f32::NAN, 0.0, -1.0);
        g.record(&nan, &Matrix3::identity(), &ScanTrig::of(&ring(1)), &[Range::Clear], 0.25);
        assert_eq!(g.corridor(&nan, &Vec3::new(1.0, 0.0, 0.0), 0.25, 3.0), 0.0);
    }
}
