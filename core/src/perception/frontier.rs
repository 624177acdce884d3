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
//! **Walls** (where nothing observed is left; only when the caller asks for them, the memory's
//! `fov_walls`). When the free range along the direction of
//! motion is used up or was never observed (`D = 0` in a bracketing sector `i`), the sector
//! gets a wall: the vertical plane `c_iᵀx = w_i` across its centre direction `c_i`, placed
//! `m` ahead of the vehicle (`w_i = c_iᵀp + m`) and only ever moved closer while the sector
//! stays unobserved (`w_i ← min(w_i, c_iᵀp + m)`); a scan that records the sector removes
//! it. Each wall is handed to the filter as a half-space (its point nearest the vehicle with
//! the normal `−c_i`, which the plant-aware filter treats as a tangent plane,
//! `docs/filter.md` § 15). A point that is re-placed `m` ahead of the vehicle every update
//! never comes closer and only caps the speed (a creep into unseen space); a wall fixed in the
//! world stops the vehicle within `m − √δ` of where it first found nothing observed, in
//! every direction it tries (`docs/filter.md` § 14). A half-space blocks every direction with
//! a positive part along `c_i`, observed ones beside the sector included: walls trade the
//! goals of flights that need those directions for the guarantee (measured in
//! `docs/perception.md` § Failure modes, "Walls for a held heading"). While a tracked
//! obstacle closes in ([`closes_in`]) the memory asks for no new wall: the direction of motion
//! is then an evasion, which gets the capped point (walls already placed stay).
//!
//! **Seen from earlier positions** (with the speed cap, not with walls). The sector record only
//! knows the last scan per sector, from where it was taken: space beside or behind a forward
//! sensor that it saw on the way has no record. [`FreeGrid`] keeps what was seen free in a
//! world-fixed map; along `u` the corridor of the hull's width (radius `m`) through its free
//! cells gives `D_g(u)`, which stands in for a bracketing sector **that has no record** (a
//! direction the sensors have not looked in since the start: beside and behind a forward
//! camera, the gaps between ToF sensors). A sector with a record keeps its own, the last
//! scan's, free range. With walls (a held heading) the grid is not consulted: the fixed gaps
//! of a held sensor set would be crossed diagonally towards what the sensors barely see
//! (measured, `docs/perception.md`).
//!
//! Vertical motion is not limited here (the ground and ceiling barriers of `crate::plant_aware`).
//!
//! May import: `crate::fmath`, `crate::Vec3`, the parent module's types.

use super::free_grid::FreeGrid;
use super::{Range, ScanTrig, HORIZONTAL_BAND};
use crate::fmath::{hypotf, sqrtf};
use crate::Vec3;
use nalgebra::Matrix3;

/// Horizontal sectors (22.5° each).
pub const SECTORS: usize = 16;
/// Below this horizontal speed the frontier keeps the last direction of motion, m/s.
pub const MIN_SPEED: f32 = 0.05;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Record {
    origin: Vec3,
    free: f32,
}

/// The per-sector free ranges and walls.
#[derive(Clone, Debug)]
pub struct Frontier {
    sectors: [Option<Record>; SECTORS],
    /// Per sector `i`, the offset `w_i` (m) of its wall `c_iᵀx = w_i` (see the module docs);
    /// `+∞`: no wall.
    walls: [f32; SECTORS],
    last_dir: Option<Vec3>,
    /// The space seen free from earlier positions ([`FreeGrid`]): stands in for unrecorded sectors.
    grid: FreeGrid,
}

impl Default for Frontier {
    fn default() -> Self {
        Self::new()
    }
}

/// The sector of the horizontal direction `(dx, dy)`: `⌊(atan2(dy, dx) + π) / 2π · SECTORS⌋`
/// (modulo `SECTORS`) with libm's `atan2f`, which is called only when the approximate bearing
/// lies too close to a sector boundary to tell (`fmath::certain`).
fn sector_of(dx: f32, dy: f32) -> usize {
    use crate::fmath::{atan2_approx, certain, floor_i32, ATAN2_APPROX_ERROR};
    let s_of = |b: f32| (b + core::f32::consts::PI) / core::f32::consts::TAU * SECTORS as f32;
    // |s − s*| ≤ the bearing's error × SECTORS / 2π (+1 %) plus the round-off of the two
    // evaluations (a few ulp of at most SECTORS): 1e-3 covers 8e-6 several times over.
    const E: f32 = ATAN2_APPROX_ERROR * SECTORS as f32 / core::f32::consts::TAU * 1.01 + 1e-3;
    let i = certain(s_of(atan2_approx(dy, dx)), E, floor_i32)
        .unwrap_or_else(|| floor_i32(s_of(libm::atan2f(dy, dx)))); // −π..π
    i.rem_euclid(SECTORS as i32) as usize
}

/// Bearing of sector `i`'s centre, rad.
fn centre(i: usize) -> f32 {
    (i as f32 + 0.5) / SECTORS as f32 * core::f32::consts::TAU - core::f32::consts::PI
}

impl Frontier {
    /// Nothing observed.
    pub const fn new() -> Self {
        Frontier {
            sectors: [None; SECTORS],
            walls: [f32::INFINITY; SECTORS],
            last_dir: None,
            grid: FreeGrid::new(),
        }
    }

    /// Record one scan: `origin` = the sensor's world position, `r_ws` = sensor → world,
    /// `trig` = the scan's geometry (its directions),
    /// `band` = the hull's vertical half-extent for the free grid (the frontier margin), m.
    /// The grid is marked only with `grid` (the speed cap: with walls it is not consulted) and
    /// while some sector has no record (records are never dropped, and the grid answers only
    /// for a sector without one: a 360° sensor marks it once).
    /// Bounded by the scan's beams (≤ `MAX_BEAMS`) plus [`SECTORS`], and the grid's walks.
    pub fn record(
        &mut self,
        origin: &Vec3,
        r_ws: &Matrix3<f32>,
        trig: &ScanTrig,
        ranges: &[Range],
        band: f32,
        grid: bool,
    ) {
        if grid && self.sectors.iter().any(Option::is_none) {
            self.grid.record(origin, r_ws, trig, ranges, band);
        }
        let mut votes = [f32::INFINITY; SECTORS];
        trig.for_each_free_beam(r_ws, ranges, libm::sinf(HORIZONTAL_BAND), |u, free| {
            if let Some(v) = votes.get_mut(sector_of(u.x, u.y)) {
                if free < *v {
                    *v = free;
                }
            }
        });
        for ((s, w), v) in self.sectors.iter_mut().zip(self.walls.iter_mut()).zip(votes.iter()) {
            if v.is_finite() {
                *s = Some(Record { origin: *origin, free: *v });
                *w = f32::INFINITY;
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
        self.free_along_or(p, u, 0.0)
    }

    /// As [`Self::free_along`], a bracketing sector without a record counting as `unrecorded`.
    fn free_along_or(&self, p: &Vec3, u: &Vec3, unrecorded: f32) -> f32 {
        let (j, k) = bracket(u);
        let of = |i: usize| match self.sectors.get(i).copied().flatten() {
            Some(_) => self.free_from(i, p),
            None => unrecorded,
        };
        let (a, c) = (of(j), of(k));
        if a < c {
            a
        } else {
            c
        }
    }

    /// The walls (see the module docs) within `ignore_beyond` (m) of a vehicle at `p`: each
    /// as `(point, normal)`, its point nearest to `p` (NED) and its unit normal `−c_i`.
    /// At most [`SECTORS`].
    pub fn walls(&self, p: &Vec3, ignore_beyond: f32, mut f: impl FnMut(Vec3, Vec3)) {
        for (i, &w) in self.walls.iter().enumerate() {
            if !w.is_finite() {
                continue;
            }
            let (sn, cs) = crate::fmath::sincosf(centre(i));
            let c = Vec3::new(cs, sn, 0.0);
            let gap = w - c.dot(p);
            if gap <= ignore_beyond {
                f(p + c * gap, -c);
            }
        }
    }
}

/// The sector of the horizontal direction `u` and its neighbour on the side of `u`'s bearing
/// from that sector's centre: the two sectors whose centres bracket `u`.
fn bracket(u: &Vec3) -> (usize, usize) {
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
    (j, k)
}

impl Frontier {
    /// The virtual frontier point for a vehicle at `p` moving at `v` (NED): `None` before the
    /// first horizontal motion, when `margin` ≤ 0 (off), when the free range exceeds
    /// `ignore_beyond` (m; the filter cannot act on so far a point), or, with `walls`, when it
    /// is used up: then the bracketing sectors without free range get (or keep, moved closer)
    /// their walls ([`Self::walls`]) instead. Without `walls` the point then sits `margin`
    /// ahead of the vehicle (a speed cap).
    pub fn point(
        &mut self,
        p: &Vec3,
        v: &Vec3,
        margin: f32,
        ignore_beyond: f32,
        walls: bool,
    ) -> Option<Vec3> {
        let s = hypotf(v.x, v.y);
        if s >= MIN_SPEED && s.is_finite() {
            self.last_dir = Some(Vec3::new(v.x / s, v.y / s, 0.0));
        }
        let u = self.last_dir?;
        if margin <= 0.0 || !(margin.is_finite()) {
            return None;
        }
        let d = if walls {
            self.free_along(p, &u)
        } else {
            let grid = self.grid.corridor(p, &u, margin, ignore_beyond);
            self.free_along_or(p, &u, grid)
        };
        if d > ignore_beyond {
            return None;
        }
        if d > 0.0 || !walls {
            return Some(p + u * (d + margin));
        }
        let (j, k) = bracket(&u);
        for i in [j, k] {
            if self.free_from(i, p) > 0.0 {
                continue;
            }
            let (sn, cs) = crate::fmath::sincosf(centre(i));
            let w = cs * p.x + sn * p.y + margin;
            if let Some(slot) = self.walls.get_mut(i) {
                if w < *slot {
                    *slot = w;
                }
            }
        }
        None
    }
}

/// While a tracked obstacle closes on the vehicle by its own motion faster than this (m/s) …
pub const EVADE_MIN_CLOSING: f32 = 0.1;
/// … and would reach it within this (s, distance / closing speed), the frontier places no new
/// wall (the caller passes `walls = false` to [`Frontier::point`]): the direction of motion is
/// then the filter's evasion of a seen mover, not the path's, and a wall there would forbid it.
pub const EVADE_HORIZON_S: f32 = 4.0;

/// Whether an obstacle point at `−d` from the vehicle (`d` = vehicle − point) moving at `w`
/// closes in by its own motion (`EVADE_*`): `dᵀw > s_min |d|` and `|d|² < T dᵀw`.
pub fn closes_in(d: &Vec3, w: &Vec3) -> bool {
    let n = d.norm();
    let closing = d.dot(w);
    closing > EVADE_MIN_CLOSING * n && n * n < EVADE_HORIZON_S * closing
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
    extern crate std;
    use super::*;
    use crate::perception::ScanGeometry;

    /// `sector_of` with the approximate bearing is the libm bearing's sector: random
    /// directions and directions a hair either side of every sector boundary (where the
    /// fallback decides), the branch cut (±0) and degenerate vectors.
    #[test]
    fn sector_of_is_the_libm_bearings_sector() {
        let reference = |dx: f32, dy: f32| {
            let s = (libm::atan2f(dy, dx) + core::f32::consts::PI) / core::f32::consts::TAU * SECTORS as f32;
            crate::fmath::floor_i32(s).rem_euclid(SECTORS as i32) as usize
        };
        let mut seed = 0x5ec7_0019_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        let check = |dx: f32, dy: f32| assert_eq!(sector_of(dx, dy), reference(dx, dy), "({dx}, {dy})");
        for _ in 0..100_000 {
            check(next() * 2.0 - 1.0, next() * 2.0 - 1.0);
        }
        for k in 0..=SECTORS {
            let b = k as f32 / SECTORS as f32 * core::f32::consts::TAU - core::f32::consts::PI;
            for eps in [0.0f32, 1e-7, -1e-7, 1e-6, -1e-6, 3e-5, -3e-5, 2e-4, -2e-4] {
                for r in [1e-3f32, 1.0, 50.0] {
                    check(libm::cosf(b + eps) * r, libm::sinf(b + eps) * r);
                }
            }
        }
        for (dx, dy) in
            [(-1.0f32, 0.0f32), (-1.0, -0.0), (1.0, 0.0), (0.0, 0.0), (f32::NAN, 1.0), (f32::INFINITY, 0.0)]
        {
            check(dx, dy);
        }
    }

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
        f.record(&Vec3::zeros(), &Matrix3::identity(), &ScanTrig::of(&g), &ranges, 0.25, true);
        let p = Vec3::new(1.0, 0.0, 0.0);
        let fwd = f.free_along(&p, &Vec3::new(1.0, 0.0, 0.0));
        assert!((fwd - 3.0).abs() < 1e-5, "{fwd}");
        assert_eq!(f.free_along(&p, &Vec3::new(0.0, 1.0, 0.0)), 0.0);
        assert_eq!(f.free_along(&p, &Vec3::new(-1.0, 0.0, 0.0)), 0.0);
        // Moving right without walls: no sector record, but the fan saw part of that side from
        // the origin (within 30°): the hull's strip, x in [0.75, 1.25], is seen up to
        // y = 0.75·tan 30° = 0.433 m at its near edge, so the centre may advance less than that.
        let q = f.point(&p, &Vec3::new(0.0, 1.0, 0.0), 0.25, 100.0, false).unwrap();
        assert!(q.x == 1.0 && q.y > 0.25 && q.y < 0.25 + 0.433, "{q:?}");
        // Far to the side, never seen: the frontier point sits at the margin.
        let far = Vec3::new(1.0, 3.0, 0.0);
        let q = f.point(&far, &Vec3::new(0.0, 1.0, 0.0), 0.25, 100.0, false).unwrap();
        assert!((q - Vec3::new(1.0, 3.25, 0.0)).norm() < 1e-5, "{q:?}");
        assert!(f.point(&p, &Vec3::new(0.5, 0.0, 0.0), 0.25, 100.0, false).is_some());
        let mut none = 0;
        f.walls(&p, 100.0, |_, _| none += 1);
        assert_eq!(none, 0);
        // With walls: no point, a wall at the margin (half-space, normal −y).
        assert!(f.point(&p, &Vec3::new(0.0, 1.0, 0.0), 0.25, 100.0, true).is_none());
        let mut walls = std::vec::Vec::new();
        f.walls(&p, 100.0, |q, n| walls.push((q, n)));
        assert!(!walls.is_empty());
        for (q, n) in &walls {
            assert!(n.z == 0.0 && (n.norm() - 1.0).abs() < 1e-5);
            // The plane is 0.25 m from p along the sector's centre, and faces the vehicle.
            assert!(((p - q).norm() - 0.25).abs() < 1e-5 && n.dot(&(p - q)) > 0.0, "{q} {n}");
        }
        // Moving forward: at the observed range plus the margin.
        let q = f.point(&p, &Vec3::new(0.5, 0.0, 0.0), 0.25, 100.0, true).unwrap();
        assert!((q - Vec3::new(4.25, 0.0, 0.0)).norm() < 1e-5);
        // Slow: keeps the last direction; off with margin 0; far ranges left out.
        assert!(f.point(&p, &Vec3::zeros(), 0.25, 100.0, true).is_some());
        assert!(f.point(&p, &Vec3::new(0.5, 0.0, 0.0), 0.0, 100.0, true).is_none());
        assert!(f.point(&p, &Vec3::new(0.5, 0.0, 0.0), 0.25, 2.0, true).is_none());
    }

    /// A wall is fixed in the world: while the vehicle creeps towards it, it does not ride
    /// along (it comes closer, so the filter stops the vehicle); trying again from further on
    /// never moves it further out; a scan that records the sector removes it.
    #[test]
    fn a_wall_stays_where_nothing_was_observed_until_a_scan_sees_there() {
        let mut f = Frontier::new();
        let g = ScanGeometry::grid(12, 1, 1.047, 0.05, 0.1, 4.0); // forward fan (north = +x)
        f.record(&Vec3::zeros(), &Matrix3::identity(), &ScanTrig::of(&g), &[Range::Clear; 12], 0.25, true);
        let east = Vec3::new(0.0, 0.2, 0.0);
        let gaps = |f: &Frontier, p: &Vec3| {
            let mut v = std::vec::Vec::new();
            f.walls(p, 100.0, |q, n| v.push(n.dot(&(p - q))));
            v
        };
        assert!(f.point(&Vec3::zeros(), &east, 0.25, 100.0, true).is_none());
        let g0 = gaps(&f, &Vec3::zeros());
        assert!(!g0.is_empty() && g0.iter().all(|g| *g > 0.2 && *g <= 0.25 + 1e-6), "{g0:?}");
        for k in 1..=10 {
            let p = Vec3::new(0.0, 0.01 * k as f32, 0.0);
            assert!(f.point(&p, &east, 0.25, 100.0, true).is_none());
            let gk = gaps(&f, &p);
            // Each wall is nearer by the way made towards it (its normal's share of 1 cm/step).
            for (a, b) in g0.iter().zip(gk.iter()) {
                assert!(*b < *a - 0.009 * k as f32 + 1e-5, "step {k}: {a} → {b}");
            }
        }
        // Trying again from further ahead (pushed on, say) never moves a wall further out.
        let ahead = Vec3::new(0.0, 0.3, 0.0);
        let before = gaps(&f, &ahead);
        assert!(f.point(&ahead, &east, 0.25, 100.0, true).is_none());
        assert_eq!(gaps(&f, &ahead), before);
        // Back west 1 m and east again: moved closer, 0.25 m ahead again (only ever closer).
        let back = Vec3::new(0.0, -1.0, 0.0);
        assert!(f.point(&back, &east, 0.25, 100.0, true).is_none());
        assert!(gaps(&f, &back).iter().all(|g| (*g - 0.25).abs() < 1e-5), "{:?}", gaps(&f, &back));
        // Walls beyond `ignore_beyond` are left out; a scan seeing east removes them.
        let mut n = 0;
        f.walls(&back, 0.2, |_, _| n += 1);
        assert_eq!(n, 0);
        let r_east = nalgebra::Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        f.record(&back, &r_east, &ScanTrig::of(&g), &[Range::Clear; 12], 0.25, true);
        assert!(gaps(&f, &back).is_empty());
        assert!(f.point(&back, &east, 0.25, 100.0, true).is_some());
    }

    #[test]
    fn a_return_limits_its_sector_to_the_smallest_vote() {
        let mut f = Frontier::new();
        let (g, mut r) = ring(72, Range::Clear);
        r[0] = Range::Hit(2.0); // straight ahead
        f.record(&Vec3::zeros(), &Matrix3::identity(), &ScanTrig::of(&g), &r, 0.25, true);
        let d = f.free_along(&Vec3::zeros(), &Vec3::new(1.0, 0.0, 0.0));
        assert!((d - 2.0).abs() < 1e-5, "{d}");
        let d = f.free_along(&Vec3::zeros(), &Vec3::new(-1.0, 0.0, 0.0));
        assert!((d - 10.0).abs() < 1e-5, "{d}");
    }
}
