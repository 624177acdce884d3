//! See-through clearing (the parent module's docs, **Cells**): whether a scan's beam shows
//! that a stored cell's box is no longer there — the slab test of the beam nearest the
//! cell's direction against its box (inflated sideways and downwards, not upwards), and for a
//! ray that passes only beside the box, the neighbouring beams' confirmation.
//!
//! May import: the parent module (its private fields), the perception module's scan types,
//! [`super::super::fov_bounds`], `crate::Vec3`.

use super::super::fov_bounds::FovBounds;
use super::super::{Range, Scan};
use super::{Cell, ObstacleMemory};
use crate::Vec3;

impl<const N: usize> ObstacleMemory<N> {
    /// Whether the scan's beam nearest to cell `c`'s direction passes through it.
    pub(super) fn beam_clears(
        &self,
        origin: &Vec3,
        r_ws: &nalgebra::Matrix3<f32>,
        scan: &Scan,
        c: &Cell,
        tol: f32,
        fov: &FovBounds,
    ) -> bool {
        let g = &scan.geometry;
        let centre = (c.lo + c.hi) * 0.5;
        let q = r_ws.transpose() * (centre - origin);
        if q.norm_squared() < 1e-6 || fov.surely_outside(&q) {
            return false;
        }
        let Some((row, col)) = g.nearest_beam(&q) else {
            return false;
        };
        let k = usize::from(row) * usize::from(g.n_az) + usize::from(col);
        let free = match scan.ranges.get(k) {
            Some(Range::Hit(r)) if *r >= g.min_range && *r < g.max_range => *r,
            Some(Range::Clear) => g.max_range,
            _ => return false,
        };
        let u = r_ws * self.trig.direction(row, col);
        // Not inflated upwards (NED −z): a ray passing just above a top's returns (a desk top
        // seen from above at a grazing angle) does not see through it.
        let t = Vec3::new(tol, tol, tol);
        let up = Vec3::new(tol, tol, 0.0);
        let Some((_, exit)) = slab(origin, &u, &(c.lo - up), &(c.hi + t)) else {
            return false;
        };
        let past = exit + self.params.clear_margin;
        if past > free {
            return false;
        }
        // Through the box itself: seen through. Only beside it (within `tol`): a ray grazing
        // a silhouette (a pillar's edge, the surface going on just off the returns) is no
        // evidence, so it clears only when the neighbouring beams see past the cell too.
        slab(origin, &u, &c.lo, &c.hi).is_some() || neighbours_see_past(scan, row, col, past)
    }
}

/// Parameters of the segment through the inflated box `[lo, hi]` on the ray `o + s·u`:
/// `Some((enter, exit))` when the ray meets it (slab test).
fn slab(o: &Vec3, u: &Vec3, lo: &Vec3, hi: &Vec3) -> Option<(f32, f32)> {
    let mut t0 = f32::NEG_INFINITY;
    let mut t1 = f32::INFINITY;
    for k in 0..3 {
        let (ok, uk, lk, hk) = (o[k], u[k], lo[k], hi[k]);
        if uk.abs() < 1e-9 {
            if ok < lk || ok > hk {
                return None;
            }
            continue;
        }
        let (a, b) = ((lk - ok) / uk, (hk - ok) / uk);
        let (a, b) = if a < b { (a, b) } else { (b, a) };
        if a > t0 {
            t0 = a;
        }
        if b < t1 {
            t1 = b;
        }
    }
    (t0 <= t1 && t1 >= 0.0).then_some((t0, t1))
}

/// Whether the beams next to `(row, col)` (one column and one row either side; those that
/// exist, a full circle wrapping in azimuth) all see at least `past` m: a return at or
/// beyond it, or nothing within `max_range`. A beam without information, or a return
/// short of `past`, objects.
fn neighbours_see_past(scan: &Scan, row: u16, col: u16, past: f32) -> bool {
    let g = &scan.geometry;
    let (n_az, n_el) = (i32::from(g.n_az), i32::from(g.n_el));
    let wraps = g.wraps();
    [(0, -1), (0, 1), (-1, 0), (1, 0)].into_iter().all(|(dr, dc)| {
        let r = i32::from(row) + dr;
        let mut c = i32::from(col) + dc;
        if wraps {
            c = c.rem_euclid(n_az);
        }
        if r < 0 || r >= n_el || c < 0 || c >= n_az || (wraps && n_az < 3 && dc != 0) {
            return true;
        }
        let k = (r * n_az + c) as usize;
        match scan.ranges.get(k) {
            Some(Range::Hit(d)) => *d >= past,
            Some(Range::Clear) => true,
            _ => false,
        }
    })
}
