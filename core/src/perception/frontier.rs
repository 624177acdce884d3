//! The free range observed around the vehicle, per horizontal world sector, and the virtual
//! frontier point that keeps the vehicle inside observed space ("unseen space is not free
//! space", `docs/filter.md` § 14).
//!
//! **Record.** The horizontal plane is cut into [`SECTORS`] sectors of world bearing. Every
//! beam with information ([`Range::Hit`] r or [`Range::Clear`], free up to r or
//! `max_range`) whose world direction is within [`HORIZONTAL_BAND`] of horizontal votes for
//! the sector of its bearing; a scan replaces, in each sector it voted for, the record
//! `(origin o, free range r)` with its own, `r` the **smallest** vote of the scan's beams
//! in that sector (conservative within the sector). Sectors a scan did not see keep their
//! older record; a sector never seen has none.
//!
//! **Free range now.** From the vehicle position `p`, sector `i`'s record is worth
//! `D_i = r_i − |p − o_i|` (the vehicle has moved `|p − o_i|` since; in a static world the
//! observed ray shortened by at most that), 0 without a record. For a direction of motion `u`
//! the free range is `D(u) = max(0, min(D_j, D_k))` over the two sectors whose centres
//! bracket `u`'s bearing.
//!
//! **Frontier point.** With the horizontal velocity `v_h` (or the last direction when slower
//! than [`MIN_SPEED`]): a static point at `p + (D(u) + m)·u`, `m` = `fov_margin` ≥ the hull
//! radius. The filter's barrier on it keeps the hull out of the unobserved space beyond
//! `D(u)` and caps the speed towards it (derivation in `docs/filter.md` § 14).
//!
//! Vertical motion is not limited here (the ground and ceiling barriers of `crate::robust`).
//!
//! May import: `crate::fmath`, `crate::Vec3`, the parent module's types.

use super::{Range, ScanGeometry};
use crate::fmath::{hypotf, sqrtf};
use crate::Vec3;
use nalgebra::Matrix3;

/// Horizontal sectors (22.5° each).
pub const SECTORS: usize = 16;
/// A beam votes when its world elevation is within this of horizontal, rad (15°).
pub const HORIZONTAL_BAND: f32 = 0.2618;
/// Below this horizontal speed the frontier keeps the last direction of motion, m/s.
pub const MIN_SPEED: f32 = 0.05;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Record {
    origin: Vec3,
    free: f32,
}

/// The per-sector free ranges.
#[derive(Clone, Debug)]
pub struct Frontier {
    sectors: [Option<Record>; SECTORS],
    last_dir: Option<Vec3>,
}

impl Default for Frontier {
    fn default() -> Self {
        Self::new()
    }
}

fn sector_of(dx: f32, dy: f32) -> usize {
    let b = libm::atan2f(dy, dx); // −π..π
    let s = (b + core::f32::consts::PI) / core::f32::consts::TAU * SECTORS as f32;
    let i = libm::floorf(s) as i32;
    i.rem_euclid(SECTORS as i32) as usize
}

/// Bearing of sector `i`'s centre, rad.
fn centre(i: usize) -> f32 {
    (i as f32 + 0.5) / SECTORS as f32 * core::f32::consts::TAU - core::f32::consts::PI
}

impl Frontier {
    /// Nothing observed.
    pub const fn new() -> Self {
        Frontier { sectors: [None; SECTORS], last_dir: None }
    }

    /// Record one scan: `origin` = the sensor's world position, `r_ws` = sensor → world.
    /// Bounded by the scan's beams (≤ `MAX_BEAMS`) plus [`SECTORS`].
    pub fn record(&mut self, origin: &Vec3, r_ws: &Matrix3<f32>, g: &ScanGeometry, ranges: &[Range]) {
        let mut votes = [f32::INFINITY; SECTORS];
        let sin_band = libm::sinf(HORIZONTAL_BAND);
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
                let u = r_ws * g.direction(row, col);
                if u.z.abs() > sin_band {
                    continue;
                }
                let i = sector_of(u.x, u.y);
                if let Some(v) = votes.get_mut(i) {
                    if free < *v {
                        *v = free;
                    }
                }
            }
        }
        for (s, v) in self.sectors.iter_mut().zip(votes.iter()) {
            if v.is_finite() {
                *s = Some(Record { origin: *origin, free: *v });
            }
        }
    }

    /// Free range of sector `i` from `p`, m (0 without a record).
    fn free_from(&self, i: usize, p: &Vec3) -> f32 {
        match self.sectors.get(i % SECTORS).copied().flatten() {
            Some(r) => {
                let d = r.free - (p - r.origin).norm();
                if d > 0.0 {
                    d
                } else {
                    0.0
                }
            }
            None => 0.0,
        }
    }

    /// The observed free range along the horizontal unit direction `u` from `p`, m.
    pub fn free_along(&self, p: &Vec3, u: &Vec3) -> f32 {
        let j = sector_of(u.x, u.y);
        let b = libm::atan2f(u.y, u.x);
        // The neighbour on the side of u's bearing from sector j's centre.
        let mut off = b - centre(j);
        if off > core::f32::consts::PI {
            off -= core::f32::consts::TAU;
        } else if off < -core::f32::consts::PI {
            off += core::f32::consts::TAU;
        }
        let k = if off >= 0.0 { (j + 1) % SECTORS } else { (j + SECTORS - 1) % SECTORS };
        let (a, c) = (self.free_from(j, p), self.free_from(k, p));
        if a < c {
            a
        } else {
            c
        }
    }

    /// The virtual frontier point for a vehicle at `p` moving at `v` (NED): `None` before the
    /// first horizontal motion, when `margin` ≤ 0 (off), or when the free range exceeds
    /// `ignore_beyond` (m; the filter cannot act on so far a point).
    pub fn point(&mut self, p: &Vec3, v: &Vec3, margin: f32, ignore_beyond: f32) -> Option<Vec3> {
        let s = hypotf(v.x, v.y);
        if s >= MIN_SPEED && s.is_finite() {
            self.last_dir = Some(Vec3::new(v.x / s, v.y / s, 0.0));
        }
        let u = self.last_dir?;
        if margin <= 0.0 || !(margin.is_finite()) {
            return None;
        }
        let d = self.free_along(p, &u);
        if d > ignore_beyond {
            return None;
        }
        Some(p + u * (d + margin))
    }
}

/// The free range beyond which the frontier point is left out, m: the filter's barrier on a
/// static point at distance `L` caps the approach speed below `L/μ`; at `L ≥ μ·s_max + 1` it
/// cannot engage for speeds up to `s_max`. (Kept as a helper so the caller can state it.)
pub fn ignore_beyond(mu: f32, max_speed: f32) -> f32 {
    let l = mu * max_speed + 1.0;
    if l.is_finite() && l > 0.0 {
        l
    } else {
        sqrtf(f32::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(n: u16, r: Range) -> (ScanGeometry, [Range; 72]) {
        (ScanGeometry::planar_360(n, 0.05, 0.1, 10.0), [r; 72])
    }

    #[test]
    fn sectors_cover_the_circle() {
        for k in 0..360 {
            let a = (k as f32).to_radians();
            let i = sector_of(libm::cosf(a), libm::sinf(a));
            assert!(i < SECTORS);
            let c = centre(i);
            let mut d = a - c;
            while d > core::f32::consts::PI {
                d -= core::f32::consts::TAU;
            }
            while d < -core::f32::consts::PI {
                d += core::f32::consts::TAU;
            }
            assert!(d.abs() <= core::f32::consts::PI / SECTORS as f32 + 1e-4, "{k}° → sector {i}");
        }
    }

    #[test]
    fn unseen_direction_has_no_free_range_and_a_seen_one_shrinks_with_motion() {
        let mut f = Frontier::new();
        // A forward 60° fan, free to 4 m.
        let g = ScanGeometry::grid(12, 1, 1.047, 0.05, 0.1, 4.0);
        let ranges = [Range::Clear; 12];
        f.record(&Vec3::zeros(), &Matrix3::identity(), &g, &ranges);
        let p = Vec3::new(1.0, 0.0, 0.0);
        let fwd = f.free_along(&p, &Vec3::new(1.0, 0.0, 0.0));
        assert!((fwd - 3.0).abs() < 1e-5, "{fwd}");
        assert_eq!(f.free_along(&p, &Vec3::new(0.0, 1.0, 0.0)), 0.0);
        assert_eq!(f.free_along(&p, &Vec3::new(-1.0, 0.0, 0.0)), 0.0);
        // Moving right (unseen): the frontier point sits at the margin.
        let q = f.point(&p, &Vec3::new(0.0, 1.0, 0.0), 0.25, 100.0).unwrap();
        assert!((q - Vec3::new(1.0, 0.25, 0.0)).norm() < 1e-5);
        // Moving forward: at the observed range plus the margin.
        let q = f.point(&p, &Vec3::new(0.5, 0.0, 0.0), 0.25, 100.0).unwrap();
        assert!((q - Vec3::new(4.25, 0.0, 0.0)).norm() < 1e-5);
        // Slow: keeps the last direction; off with margin 0; far ranges left out.
        assert!(f.point(&p, &Vec3::zeros(), 0.25, 100.0).is_some());
        assert!(f.point(&p, &Vec3::new(0.5, 0.0, 0.0), 0.0, 100.0).is_none());
        assert!(f.point(&p, &Vec3::new(0.5, 0.0, 0.0), 0.25, 2.0).is_none());
    }

    #[test]
    fn a_return_limits_its_sector_to_the_smallest_vote() {
        let mut f = Frontier::new();
        let (g, mut r) = ring(72, Range::Clear);
        r[0] = Range::Hit(2.0); // straight ahead
        f.record(&Vec3::zeros(), &Matrix3::identity(), &g, &r);
        let d = f.free_along(&Vec3::zeros(), &Vec3::new(1.0, 0.0, 0.0));
        assert!((d - 2.0).abs() < 1e-5, "{d}");
        let d = f.free_along(&Vec3::zeros(), &Vec3::new(-1.0, 0.0, 0.0));
        assert!((d - 10.0).abs() < 1e-5, "{d}");
    }
}
