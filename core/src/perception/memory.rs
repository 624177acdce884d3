//! The obstacle memory: a fixed-capacity voxel store of range returns in world NED, with
//! ageing, see-through clearing, cluster tracks and the field-of-view frontier.
//!
//! **Cells (merge).** Space is cut into cubes of edge `voxel` (`MemoryParams::voxel`,
//! default 0.2 m); all returns falling into one cube merge into one cell, which keeps the
//! axis-aligned bounding box of its returns and the time of the last one. The point a cell
//! hands the filter is the point of that box **nearest to the vehicle** (the vehicle
//! position clamped to the box): every return merged into the cell is at least as far, so
//! the merge is conservative, and it is exact for a single return. The box lies inside its
//! cube, so the point is never farther than the cube's diagonal (√3·voxel) from the
//! returns it stands for, and never outside the cube. One wall seen by a 72-beam scan is at
//! most one cell per cube it crosses.
//!
//! **Forgetting.** A cell not hit for `forget_s` (default 5 s) is removed; a wall seen once
//! and then behind the vehicle (out of every sensor's view) is kept that long — unless its
//! box lies within `keep_near` (default 1 m) of the vehicle: a wall beside a vehicle held
//! at a door, out of a forward camera's view, stays until a beam sees through it (the speed
//! campaign's narrow passage: a camera vehicle held 9 s in front of a 0.6 m door forgot the
//! jambs beside it and grazed one, `docs/robustness.md` § At speed). A cell is
//! also removed when a later beam passes through it (*see-through clearing*): the beam's
//! central ray crosses the cell's box (inflated by voxel/4 sideways and downwards, not
//! upwards: a ray grazing a desk top from above, the 3D lidar's lowest row once the desk's
//! edge is below its field, does not see through the top) and its return — or
//! `max_range` for a beam with no return — lies at least `clear_margin` beyond the box's
//! exit. A ray that passes only beside the box (within the inflation, not through the box)
//! clears it only when the four neighbouring beams also see that far: a ray grazing a
//! silhouette — a pillar's edge, whose surface goes on just off its returns — is no evidence
//! that the surface has gone (the office's pillar B2 was grazed by a camera flight whose
//! memory had lost its edge this way, 2026-12-07), while a lone noise return is still
//! cleared by the beams around it. Beams without information ([`Range::Unknown`]) clear nothing. Each cell is tested
//! against the one beam of the scan nearest its direction (O(1) per cell).
//!
//! **Full.** With `N` cells stored a return for a new cube replaces the stored cell
//! farthest from the vehicle when that is farther than the return; otherwise the return is
//! dropped and counted ([`ScanReport::dropped_full`]). So the memory always holds the `N`
//! cells nearest to the vehicle (at the time of insertion) of those it has seen and not
//! forgotten.
//!
//! **Moving clusters** (see [`super::track`]): small segments of the scan row nearest to
//! horizontal that stand in front of their background are tracked (only when that row's middle
//! beam looks within 45° of the world's horizontal: not a down- or up-looking sensor's); their cells carry the
//! track, and cells of a track that the track's cluster did not hit again in a scan that
//! updated the track are removed (the object moved on). A track whose motion is proven
//! hands its cells out with its velocity and extrapolated by it: `q + w·age`.
//!
//! **Ground.** Returns lower than `ground_clip` above the ground plane are not stored (the
//! ground barrier of `crate::plant_aware` handles the ground); they still clear along their beam.
//!
//! **Cost** of [`ObstacleMemory::insert_scan`] for B beams and N cells: clearing O(N) (a
//! nearest-beam lookup and one slab test per cell whose direction is on the beam lattice; a cell
//! outside the lattice's angles is skipped by a tangent test), insertion O(B) lookups of cell
//! keys in a 256-byte hash table (`key_index`; O(N) comparisons when it cannot tell, e.g.
//! N > 128), tracking O(B + MAX_SEGMENTS·MAX_TRACKS + N), the frontier O(B). Measured on the Cortex-M4F (`cd tests/cortex-m4 && cargo run --release`, QEMU
//! `-icount`, `bench_memory`: `ObstacleMemory<64>`, 72-sector scans of a 6 m room with a pole
//! crossed at 1 m/s, 40 scans, memory full from the first scans; 2026-12-02 on `97a0359`):
//! `insert_scan` mean 419 661, max 461 734 instructions (2.7 ms at 168 MHz: inside one 4 ms
//! outer period, ≈ 2.7 % of the CPU at 10 scans/s); `select::<32>` mean 79 216, max 84 529.
//! Most of it was the full memory: each return in a new cube computed every cell's box point
//! to find the farthest one. Since 2026-12-03 each cell's distance is computed once per scan
//! and kept up to date by the insertion (the same values, so the same choice: `parapet run
//! --perception lidar|camera|tof` trajectories and `ranges.csv` identical byte for byte):
//! `insert_scan` 505 604 / 543 810 → **327 856 / 340 301** mean / max (measured on the tree
//! of that day, whose tracking changes had raised it from the figure above). Since 2026-12-04
//! the farthest cell is cached during an insertion and the selection's searches are cached
//! (`crate::obstacle_set`), same results: `insert_scan` mean 322 475 → **302 239**,
//! `select::<32>` mean 79 006 → **46 217** (`docs/perception.md` § Cost). Since 2026-12-05
//! (key table, lattice test, a row's elevation once per row; the selection's blocks of
//! cached worst entries), same results: `insert_scan` mean 292 141 → **207 758**,
//! `select::<32>` mean 47 438 → **40 853**. Later that day (a scan's sines and cosines once
//! per column and row, `ScanTrig`; `floor_i32`; approximate `atan2` checked against its
//! error; a NaN-free clamp, the selection's fixed points), same results: `insert_scan` mean
//! 207 758 → **183 639**, `select::<32>` 40 853 → **35 526**, the firmware's
//! `select_set::<32>` (no bookkeeping of the dropped points) **35 150**.
//!
//! May import: `crate::obstacle`, `crate::obstacle_set`, `crate::cbf` (the input limit),
//! `crate::fmath`, `crate::Vec3`, the parent module.

mod clearing;
mod points;

use super::cell_distances::Distances;
use super::fov_bounds::FovBounds;
use super::frontier::Frontier;
use super::key_index::{KeyIndex, Lookup};
use super::track::{Tracker, MAX_SEGMENTS, MAX_TRACKS, SEGMENT_GAP};
use super::{MemoryParams, Range, Scan, ScanGeometry, ScanTrig, DEFAULT_MEMORY_CAPACITY, FOV_WALLS_OFF};
use crate::cbf::INPUT_LIMIT;
use crate::fmath::{floor_i32, maxf, minf};
use crate::Vec3;

const NO_TRACK: u8 = u8::MAX;
const NO_SEG: u8 = u8::MAX;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Cell {
    key: [i32; 3],
    lo: Vec3,
    hi: Vec3,
    t_us: u64,
    track: u8,
}

/// A stored cell as seen from outside (plots, tests).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellView {
    /// Bounding box of the merged returns, NED, m.
    pub lo: Vec3,
    /// Bounding box of the merged returns, NED, m.
    pub hi: Vec3,
    /// Time of the last return, µs.
    pub t_us: u64,
    /// Track slot, `None` for static cells.
    pub track: Option<u8>,
}

/// What one [`ObstacleMemory::insert_scan`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScanReport {
    /// The scan was rejected whole (invalid geometry, wrong number of ranges, non-finite or
    /// implausible pose or mount): nothing changed.
    pub rejected: bool,
    /// Returns merged into a cell (new or existing).
    pub stored: u16,
    /// Cells created.
    pub new_cells: u16,
    /// Cells removed by see-through clearing.
    pub cleared: u16,
    /// Cells removed because they were older than `forget_s`.
    pub expired: u16,
    /// Cells of a moving track removed because the track's cluster moved on.
    pub moved: u16,
    /// Returns dropped: the memory was full of nearer cells.
    pub dropped_full: u16,
    /// Returns on the ground (not stored).
    pub ground: u16,
    /// Clusters assigned to tracks.
    pub clusters: u8,
}

/// Counters since start (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MemoryStats {
    /// Scans accepted.
    pub scans: u32,
    /// Scans rejected.
    pub rejected: u32,
    /// Returns dropped at capacity.
    pub dropped_full: u32,
}

/// The memory (see the module documentation). `N`: cells.
#[derive(Clone, Debug)]
pub struct ObstacleMemory<const N: usize = DEFAULT_MEMORY_CAPACITY> {
    params: MemoryParams,
    cells: heapless::Vec<Cell, N>,
    tracker: Tracker,
    frontier: Frontier,
    /// The current scan's directions (filled by `insert_scan`, read by its passes).
    trig: ScanTrig,
    stats: MemoryStats,
    now_us: Option<u64>,
}

fn plausible(v: &Vec3) -> bool {
    v.x.abs() <= INPUT_LIMIT && v.y.abs() <= INPUT_LIMIT && v.z.abs() <= INPUT_LIMIT
}

/// `p` clamped to the box `[lo, hi]` (compare and select: `f32::clamp` would link the float
/// formatting of its panic message into the firmware, ≈ 29 KB).
/// Squared distance from `p` to the nearest point of cell `c`'s box (the point the cell hands
/// the filter). `p` not NaN (a scan's validated pose): a cell's box is finite (built from
/// plausible returns), so [`clamp3_no_nan`] applies.
fn box_distance_sq(p: &Vec3, c: &Cell) -> f32 {
    (clamp3_no_nan(p, &c.lo, &c.hi) - p).norm_squared()
}

/// [`ObstacleMemory::remembered`] with the parameters given.
fn remembered(c: &Cell, now: u64, p: &Vec3, forget_us: u64, keep: f32) -> bool {
    now.saturating_sub(c.t_us) <= forget_us
        || (c.track == NO_TRACK && keep > 0.0 && box_distance_sq(p, c) <= keep * keep)
}

fn clamp3(p: &Vec3, lo: &Vec3, hi: &Vec3) -> Vec3 {
    let c = |x: f32, l: f32, h: f32| minf(maxf(x, l), h);
    Vec3::new(c(p.x, lo.x, hi.x), c(p.y, lo.y, hi.y), c(p.z, lo.z, hi.z))
}

/// [`clamp3`] bit for bit when no coordinate of `p`, `lo` or `hi` is NaN (`±∞` allowed):
/// then `maxf`'s and `minf`'s NaN rules never apply and each is one compare and select
/// (`maxss`/`minss` on x86-64) — ties and `±0` as theirs (`maxf(x, l)` keeps `x`, `minf(m, h)`
/// takes `h`). The memory's cells' boxes are finite; callers check `p`.
#[inline(always)]
fn clamp3_no_nan(p: &Vec3, lo: &Vec3, hi: &Vec3) -> Vec3 {
    let c = |x: f32, l: f32, h: f32| {
        let m = if l > x { l } else { x };
        if m < h {
            m
        } else {
            h
        }
    };
    Vec3::new(c(p.x, lo.x, hi.x), c(p.y, lo.y, hi.y), c(p.z, lo.z, hi.z))
}

/// The segment being built in the tracking row.
#[derive(Clone, Copy)]
struct Segment {
    sum: Vec3,
    n: u16,
    lo: Vec3,
    hi: Vec3,
    last: Vec3,
    last_range: f32,
    max_range: f32,
    /// First and last column (unwrapped: may exceed the column count on a full circle).
    first: usize,
    last_col: usize,
    before: Nb,
}

impl Segment {
    fn new(w: &Vec3, r: f32, c: usize, before: Nb) -> Self {
        Segment {
            sum: *w,
            n: 1,
            lo: *w,
            hi: *w,
            last: *w,
            last_range: r,
            max_range: r,
            first: c,
            last_col: c,
            before,
        }
    }

    fn add(&mut self, w: &Vec3, r: f32, c: usize) {
        self.sum += w;
        self.n = self.n.saturating_add(1);
        self.lo = self.lo.inf(w);
        self.hi = self.hi.sup(w);
        self.last = *w;
        self.last_range = r;
        self.max_range = maxf(self.max_range, r);
        self.last_col = c;
    }
}

/// A segment's neighbour beam in the row.
#[derive(Clone, Copy)]
enum Nb {
    /// Nothing within range, or the ground.
    Back,
    /// The end of a fan (no neighbour).
    Edge,
    /// A return at this range.
    Hit(f32),
}

/// The tracking row of a scan: the scan, its world origin and rotation, the row and the
/// per-column class (a cell index, or [`ROW_HIT`], [`ROW_BACK`], [`ROW_UNKNOWN`]).
struct Row<'a, 'b> {
    scan: &'a Scan<'b>,
    origin: &'a Vec3,
    r_ws: &'a nalgebra::Matrix3<f32>,
    row: u16,
    beams: &'a [u16; MAX_ROW],
}

/// Most columns of a tracked row (a wider row is stored but not tracked: all static).
pub const MAX_ROW: usize = 360;
/// Tracking-row beam classes beside a cell index: a return not stored (memory full), a
/// background beam (nothing within range, the ground), no information.
const ROW_HIT: u16 = u16::MAX - 2;
const ROW_BACK: u16 = u16::MAX - 1;
const ROW_UNKNOWN: u16 = u16::MAX;

/// The geometry of a memory's [`ScanTrig`] before its first scan (never read).
const NO_GEOMETRY: ScanGeometry =
    ScanGeometry { az0: 0.0, daz: 1.0, n_az: 1, el0: 0.0, del: 1.0, n_el: 1, min_range: 0.0, max_range: 1.0 };

impl<const N: usize> ObstacleMemory<N> {
    /// Empty. Invalid `params` ([`MemoryParams::valid`]) are replaced by the defaults.
    pub fn new(params: MemoryParams) -> Self {
        ObstacleMemory {
            params: if params.valid() { params } else { MemoryParams::default() },
            cells: heapless::Vec::new(),
            tracker: Tracker::new(),
            frontier: Frontier::new(),
            trig: ScanTrig::empty(NO_GEOMETRY),
            stats: MemoryStats::default(),
            now_us: None,
        }
    }

    /// Empty, with the default parameters (`const`: for statically built owners).
    pub const fn empty() -> Self {
        ObstacleMemory {
            params: MemoryParams::DEFAULT,
            cells: heapless::Vec::new(),
            tracker: Tracker::new(),
            frontier: Frontier::new(),
            trig: ScanTrig::empty(NO_GEOMETRY),
            stats: MemoryStats { scans: 0, rejected: 0, dropped_full: 0 },
            now_us: None,
        }
    }

    /// The parameters in use.
    pub fn params(&self) -> &MemoryParams {
        &self.params
    }

    /// Replaces the parameters (refused, returning `false`, when not [`MemoryParams::valid`]);
    /// a new voxel size applies to cells created from now on.
    pub fn set_params(&mut self, params: MemoryParams) -> bool {
        if params.valid() {
            self.params = params;
        }
        params.valid()
    }

    /// Counters since start.
    pub fn stats(&self) -> MemoryStats {
        self.stats
    }

    /// Cells stored.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// No cell stored.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The stored cells.
    pub fn cells(&self) -> impl Iterator<Item = CellView> + '_ {
        self.cells.iter().map(|c| CellView {
            lo: c.lo,
            hi: c.hi,
            t_us: c.t_us,
            track: (c.track != NO_TRACK).then_some(c.track),
        })
    }

    /// The tracks (slot, track) in use.
    pub fn tracks(&self) -> impl Iterator<Item = (u8, super::track::Track)> + '_ {
        (0..MAX_TRACKS).filter_map(|i| self.tracker.get(i).map(|t| (i as u8, *t)))
    }

    /// The observed free range along the horizontal unit direction `u` from `p`, m.
    pub fn free_along(&self, p: &Vec3, u: &Vec3) -> f32 {
        self.frontier.free_along(p, u)
    }

    fn forget_us(&self) -> u64 {
        (self.params.forget_s * 1e6) as u64
    }

    /// Whether cell `c` is still remembered at `now` by a vehicle at `p`: not older than
    /// `forget_s`, or a static cell whose box lies within `keep_near` of `p` (module docs,
    /// *Forgetting*; a tracked cell is extrapolated with its age, so it is not kept past it).
    fn remembered(&self, c: &Cell, now: u64, p: &Vec3) -> bool {
        remembered(c, now, p, self.forget_us(), self.params.keep_near)
    }

    /// Removes the cells [`Self::remembered`] no more.
    fn expire(&mut self, now: u64, vehicle: &Vec3) -> u16 {
        let (forget_us, keep) = (self.forget_us(), self.params.keep_near);
        let before = self.cells.len();
        self.cells.retain(|c| remembered(c, now, vehicle, forget_us, keep));
        (before - self.cells.len()) as u16
    }

    /// Adds one scan (see the module documentation). Bounded: O(N + B·N) for B beams.
    pub fn insert_scan(&mut self, scan: &Scan) -> ScanReport {
        let g = &scan.geometry;
        let pose_ok = plausible(&scan.pose.position)
            && scan.pose.rotation.iter().all(|x| x.is_finite())
            && plausible(&scan.mount.position)
            && scan.mount.rotation.iter().all(|x| x.is_finite());
        if !g.valid() || scan.ranges.len() != g.beams() || !pose_ok {
            self.stats.rejected = self.stats.rejected.saturating_add(1);
            return ScanReport { rejected: true, ..ScanReport::default() };
        }
        let t = scan.t_us;
        let now = self.now_us.map_or(t, |n| n.max(t));
        self.now_us = Some(now);
        let vehicle = scan.pose.position;
        let mut rep = ScanReport { expired: self.expire(now, &vehicle), ..ScanReport::default() };
        let origin = scan.pose.position + scan.pose.rotation * scan.mount.position;
        let r_ws = scan.pose.rotation * scan.mount.rotation;
        let voxel = self.params.voxel;
        self.trig.fill(g);

        // 1. See-through clearing: each cell against the beam nearest its direction.
        let tol = 0.25 * voxel;
        let fov = FovBounds::of(g);
        let mut i = self.cells.len();
        while i > 0 {
            i -= 1;
            let Some(c) = self.cells.get(i).copied() else { continue };
            if self.beam_clears(&origin, &r_ws, scan, &c, tol, &fov) {
                self.cells.swap_remove(i);
                rep.cleared = rep.cleared.saturating_add(1);
            }
        }

        // 2. Insertion; the tracking row's beams are classified for the segments (3).
        let track_row = {
            let r = libm::roundf(-g.el0 / g.del);
            if r <= 0.0 {
                0
            } else if r >= f32::from(g.n_el - 1) {
                g.n_el - 1
            } else {
                r as u16
            }
        };
        let mut row_beams = [ROW_UNKNOWN; MAX_ROW];
        let mut last_cell: Option<usize> = None;
        // Each cell's squared distance from the vehicle, kept up to date by `store`: the
        // farthest cell a return into a new cube may replace is found without recomputing
        // every cell's box point per return (the same values, so the same choice).
        let mut dist = Distances::new();
        for (d, c) in dist.d.iter_mut().zip(self.cells.iter()) {
            *d = box_distance_sq(&vehicle, c);
        }
        // Which cell holds a cube, kept up to date by `store` (the same cell a scan finds).
        let mut keys = KeyIndex::build(self.cells.len(), self.cells.iter().map(|c| c.key));
        let mut k = 0usize;
        for row in 0..g.n_el {
            for col in 0..g.n_az {
                let range = scan.ranges.get(k).copied().unwrap_or(Range::Unknown);
                k += 1;
                let mut class = match range {
                    Range::Clear => ROW_BACK,
                    Range::Hit(r) if r >= g.max_range => ROW_BACK,
                    _ => ROW_UNKNOWN,
                };
                let w = match range {
                    Range::Hit(r) if r >= g.min_range && r < g.max_range => {
                        Some(origin + r_ws * (self.trig.direction(row, col) * r))
                    }
                    _ => None,
                };
                let w = w.filter(plausible);
                let w = match w {
                    Some(w) if -w.z - self.params.ground_height < self.params.ground_clip => {
                        rep.ground = rep.ground.saturating_add(1);
                        class = ROW_BACK;
                        None
                    }
                    other => other,
                };
                if let Some(w) = w {
                    class = match self.store(&w, &vehicle, t, &mut last_cell, &mut dist, &mut keys, &mut rep)
                    {
                        Some(ci) if ci < usize::from(ROW_HIT) => ci as u16,
                        _ => ROW_HIT,
                    };
                }
                if row == track_row {
                    if let Some(b) = row_beams.get_mut(usize::from(col)) {
                        *b = class;
                    }
                }
            }
        }

        // 3. Segments of the tracking row: clusters (small, in front of their background).
        let mut seg_of_cell = [NO_SEG; N];
        let mut clusters = [Cluster::EMPTY; MAX_SEGMENTS];
        // Only a row that looks along the world's horizontal sees movers against their
        // background: a down- or up-looking sensor's (the `tof` set's, the `lidar3d` set's down
        // ToF) middle beam within 45° of the vertical looks at the floor or ceiling, and its
        // segments are not walkers (with them the walker ahead lost its track and wall cells
        // theirs: docs/robustness.md § At speed, "A down-looking ToF").
        let mid = r_ws * self.trig.direction(track_row, g.n_az / 2);
        let level = mid.z * mid.z < 0.5 * mid.norm_squared();
        let n_clusters = if level && usize::from(g.n_az) <= MAX_ROW {
            let row = Row { scan, origin: &origin, r_ws: &r_ws, row: track_row, beams: &row_beams };
            self.segment_row(&row, &mut clusters, &mut seg_of_cell)
        } else {
            0
        };

        // 4. Tracks: assign clusters, tag their cells, drop what moving tracks left behind.
        let alpha = self.params.track_alpha;
        let gate = self.params.track_gate;
        let mut taken: u16 = 0;
        for c in clusters.iter_mut().take(n_clusters) {
            let slot = self.tracker.update(&c.centroid, (c.lo, c.hi), t, alpha, gate, taken);
            taken |= 1 << slot;
            c.slot = slot as u8;
            rep.clusters = rep.clusters.saturating_add(1);
        }
        let mut i = self.cells.len();
        while i > 0 {
            i -= 1;
            let mark = seg_of_cell.get(i).copied().unwrap_or(NO_SEG);
            let Some(cell) = self.cells.get_mut(i) else { continue };
            if mark == SEG_WALL {
                cell.track = NO_TRACK;
            } else if let Some(c) = clusters.get(usize::from(mark)) {
                cell.track = c.slot;
            } else if cell.track != NO_TRACK && taken & (1 << cell.track) != 0 {
                self.cells.swap_remove(i);
                rep.moved = rep.moved.saturating_add(1);
            }
        }
        self.tracker.expire(now, self.forget_us());

        // 5. The free ranges for the field-of-view frontier.
        let grid = self.params.fov_walls == FOV_WALLS_OFF;
        self.frontier.record(&origin, &r_ws, &self.trig, scan.ranges, self.params.fov_margin, grid);

        self.stats.scans = self.stats.scans.saturating_add(1);
        self.stats.dropped_full = self.stats.dropped_full.saturating_add(u32::from(rep.dropped_full));
        rep
    }

    /// Merges return `w` into its cell (creating or, when full, replacing the farthest);
    /// returns the cell index, `None` when dropped. `dist.d[i]` is cell `i`'s
    /// [`box_distance_sq`] from `vehicle`, read and kept up to date here (with its cached
    /// farthest cell).
    #[allow(clippy::too_many_arguments)]
    fn store(
        &mut self,
        w: &Vec3,
        vehicle: &Vec3,
        t: u64,
        last: &mut Option<usize>,
        dist: &mut Distances<N>,
        keys: &mut KeyIndex,
        rep: &mut ScanReport,
    ) -> Option<usize> {
        let inv = 1.0 / self.params.voxel;
        let key = [floor_i32(w.x * inv), floor_i32(w.y * inv), floor_i32(w.z * inv)];
        let found = match last.filter(|&i| self.cells.get(i).is_some_and(|c| c.key == key)) {
            Some(i) => Some(i),
            None => match keys.find(&key, |i| self.cells.get(i).map(|c| c.key)) {
                Lookup::Found(i) => Some(i),
                Lookup::Absent => None,
                Lookup::Unknown => self.cells.iter().position(|c| c.key == key),
            },
        };
        let idx = match found {
            Some(i) => {
                if let Some(c) = self.cells.get_mut(i) {
                    c.lo = c.lo.inf(w);
                    c.hi = c.hi.sup(w);
                    c.t_us = c.t_us.max(t);
                    dist.set(i, box_distance_sq(vehicle, c));
                }
                i
            }
            None => {
                let cell = Cell { key, lo: *w, hi: *w, t_us: t, track: NO_TRACK };
                let d_new = box_distance_sq(vehicle, &cell);
                if self.cells.push(cell).is_ok() {
                    rep.new_cells = rep.new_cells.saturating_add(1);
                    let i = self.cells.len() - 1;
                    keys.insert(&key, i);
                    dist.set(i, d_new);
                    i
                } else {
                    let dw = (w - vehicle).norm_squared();
                    match dist.farthest(self.cells.len()) {
                        Some((i, d)) if d > dw => {
                            if let Some(c) = self.cells.get_mut(i) {
                                keys.remove(&c.key, i);
                                *c = cell;
                                keys.insert(&key, i);
                            }
                            dist.set(i, d_new);
                            rep.dropped_full = rep.dropped_full.saturating_add(1); // the evicted cell
                            rep.new_cells = rep.new_cells.saturating_add(1);
                            i
                        }
                        _ => {
                            rep.dropped_full = rep.dropped_full.saturating_add(1);
                            return None;
                        }
                    }
                }
            }
        };
        rep.stored = rep.stored.saturating_add(1);
        *last = Some(idx);
        Some(idx)
    }

    /// Cuts the tracking row into segments (module documentation, *Moving clusters*) and
    /// marks the cells of each: the next cluster number for a cluster, [`SEG_WALL`] for the
    /// others. Returns the number of clusters. O(columns + cells marked).
    fn segment_row(
        &self,
        row: &Row,
        clusters: &mut [Cluster; MAX_SEGMENTS],
        seg_of_cell: &mut [u8; N],
    ) -> usize {
        let g = &row.scan.geometry;
        let n = usize::from(g.n_az);
        let gap = SEGMENT_GAP * self.params.voxel;
        let class = |c: usize| row.beams.get(c % n.max(1)).copied().unwrap_or(ROW_UNKNOWN);
        let range = |c: usize| match row.scan.ranges.get(usize::from(row.row) * n + c % n.max(1)) {
            Some(Range::Hit(r)) => *r,
            _ => 0.0,
        };
        let point = |c: usize| {
            let col = (c % n.max(1)) as u16;
            *row.origin + row.r_ws * (self.trig.direction(row.row, col) * range(c))
        };
        let is_hit = |c: usize| class(c) <= ROW_HIT;
        // A full circle starts at a background beam, else at a break between two returns;
        // a fan starts at its first column with its edge as the neighbour.
        let wraps = g.wraps();
        let start = if wraps {
            let back = (0..n).find(|&c| class(c) == ROW_BACK);
            let brk = || {
                (0..n).find(|&c| {
                    let p = c + n - 1;
                    is_hit(c) && is_hit(p) && (point(c) - point(p)).norm() > gap
                })
            };
            match back.or_else(brk) {
                Some(c) => c,
                None => return 0,
            }
        } else {
            0
        };
        let edge_or = |c: usize| match class(c) {
            ROW_BACK | ROW_UNKNOWN => Nb::Back,
            _ => Nb::Hit(range(c)),
        };
        let mut before = if wraps { edge_or(start + n - 1) } else { Nb::Edge };
        let mut n_clusters = 0usize;
        let mut seg: Option<Segment> = None;
        for k in 0..n {
            let c = start + k;
            match class(c) {
                ROW_UNKNOWN => {}
                ROW_BACK => {
                    if let Some(s) = seg.take() {
                        self.close_segment(&s, Nb::Back, row, clusters, &mut n_clusters, seg_of_cell);
                    }
                    before = Nb::Back;
                }
                _ => {
                    let (w, r) = (point(c), range(c));
                    if let Some(s) = seg.as_mut() {
                        if (w - s.last).norm() <= gap {
                            s.add(&w, r, c);
                            continue;
                        }
                    }
                    if let Some(s) = seg.take() {
                        self.close_segment(&s, Nb::Hit(r), row, clusters, &mut n_clusters, seg_of_cell);
                        before = Nb::Hit(s.last_range);
                    }
                    seg = Some(Segment::new(&w, r, c, before));
                }
            }
        }
        if let Some(s) = seg.take() {
            let after = if wraps { edge_or(start) } else { Nb::Edge };
            self.close_segment(&s, after, row, clusters, &mut n_clusters, seg_of_cell);
        }
        n_clusters
    }

    /// Ends a segment: a cluster (extent ≤ `track_size`, both neighbours background, the
    /// edge of a fan, or farther by more than the segment gap, room left) gets the next
    /// cluster number on its cells; any other segment marks them static.
    fn close_segment(
        &self,
        s: &Segment,
        after: Nb,
        row: &Row,
        clusters: &mut [Cluster; MAX_SEGMENTS],
        n: &mut usize,
        seg_of_cell: &mut [u8; N],
    ) {
        let gap = SEGMENT_GAP * self.params.voxel;
        let behind = |nb: Nb| match nb {
            Nb::Back | Nb::Edge => true,
            Nb::Hit(r) => r >= s.max_range + gap,
        };
        let small = s.n > 0 && (s.hi - s.lo).norm() <= self.params.track_size;
        let mark = if small && behind(s.before) && behind(after) && *n < MAX_SEGMENTS {
            if let Some(c) = clusters.get_mut(*n) {
                *c = Cluster { centroid: s.sum / f32::from(s.n), slot: NO_TRACK, lo: s.lo, hi: s.hi };
            }
            *n += 1;
            (*n - 1) as u8
        } else {
            SEG_WALL
        };
        let cols = usize::from(row.scan.geometry.n_az).max(1);
        for c in s.first..=s.last_col {
            if let Some(&ci) = row.beams.get(c % cols) {
                if ci < ROW_HIT {
                    if let Some(m) = seg_of_cell.get_mut(usize::from(ci)) {
                        *m = mark;
                    }
                }
            }
        }
    }
}

/// One cluster of a scan's tracking row (a small segment in front of its background).
#[derive(Clone, Copy)]
struct Cluster {
    /// Centroid of its returns, NED, m.
    centroid: Vec3,
    /// Track slot it was assigned ([`NO_TRACK`] before).
    slot: u8,
    /// Corners of its returns' bounding box (the tracker's proof that both ends moved).
    lo: Vec3,
    hi: Vec3,
}

impl Cluster {
    const EMPTY: Cluster = Cluster {
        centroid: Vec3::new(0.0, 0.0, 0.0),
        slot: NO_TRACK,
        lo: Vec3::new(0.0, 0.0, 0.0),
        hi: Vec3::new(0.0, 0.0, 0.0),
    };
}

/// Mark of `seg_of_cell`: the cell belongs to a segment that is not a cluster.
const SEG_WALL: u8 = 253;

#[cfg(test)]
mod tests {
    extern crate std;
    use super::super::{
        Pose, ScanGeometry, SensorMount, CELL_ID_BASE, FOV_WALLS_HELD, FOV_WALLS_ON, FRONTIER_ID, STATIC_ID,
    };
    use super::*;
    use crate::obstacle::ObstaclePoint;
    use crate::perception::track::{APPROACH_MAX, STATIC_SPEED};
    use proptest::prelude::*;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    use std::vec::Vec;

    /// Vertical cylinders `(centre x, centre y, radius)` and the wall `x = wall_x` (when `Some`).
    struct World {
        cyl: Vec<(f32, f32, f32)>,
        wall_x: Option<f32>,
    }

    impl World {
        /// Exact ray cast from `o` along unit `u` (horizontal geometry, infinite height).
        fn cast(&self, o: &Vec3, u: &Vec3, g: &ScanGeometry) -> Range {
            let mut best = f32::INFINITY;
            if let Some(x) = self.wall_x {
                if u.x > 1e-6 {
                    best = best.min((x - o.x) / u.x);
                }
            }
            for &(cx, cy, r) in &self.cyl {
                let (dx, dy) = (o.x - cx, o.y - cy);
                let a = u.x * u.x + u.y * u.y;
                let b = 2.0 * (dx * u.x + dy * u.y);
                let c = dx * dx + dy * dy - r * r;
                let disc = b * b - 4.0 * a * c;
                if a > 1e-9 && disc >= 0.0 {
                    let s = (-b - disc.sqrt()) / (2.0 * a);
                    if s > 0.0 {
                        best = best.min(s);
                    }
                }
            }
            if best < g.min_range {
                Range::Unknown
            } else if best < g.max_range {
                Range::Hit(best)
            } else {
                Range::Clear
            }
        }

        fn scan<const N: usize>(
            &self,
            m: &mut ObstacleMemory<N>,
            t_us: u64,
            p: Vec3,
            yaw: f32,
            g: ScanGeometry,
        ) -> ScanReport {
            self.scan_mounted(m, t_us, p, yaw, g, SensorMount::centered())
        }

        fn scan_mounted<const N: usize>(
            &self,
            m: &mut ObstacleMemory<N>,
            t_us: u64,
            p: Vec3,
            yaw: f32,
            g: ScanGeometry,
            mount: SensorMount,
        ) -> ScanReport {
            let pose = Pose::from_rpy(p, 0.0, 0.0, yaw);
            let mut ranges = Vec::new();
            for row in 0..g.n_el {
                for col in 0..g.n_az {
                    let u = pose.rotation * (mount.rotation * g.direction(row, col));
                    ranges.push(self.cast(&p, &u, &g));
                }
            }
            m.insert_scan(&Scan { t_us, pose, mount, geometry: g, ranges: &ranges })
        }
    }

    fn lidar() -> ScanGeometry {
        ScanGeometry::planar_360(72, 0.03, 0.1, 8.0)
    }

    fn camera() -> ScanGeometry {
        // A forward fan (e.g. one row of a depth camera), 87°, 16 beams.
        ScanGeometry::grid(16, 1, 1.518, 0.05, 0.2, 6.0)
    }

    fn points<const N: usize>(m: &mut ObstacleMemory<N>, t: u64, p: &Vec3) -> Vec<ObstaclePoint> {
        let mut out = Vec::new();
        m.for_each_point(t, p, &Vec3::zeros(), 1.4, |o| out.push(*o));
        out
    }

    const P: Vec3 = Vec3::new(0.0, 0.0, -1.0);

    /// The NaN-free clamp is `clamp3` bit for bit on non-NaN inputs: random values, ties,
    /// `±0` on either side, infinities (fails with `>=` for `>` or the operands swapped).
    #[test]
    fn the_nan_free_clamp_is_clamp3_bit_for_bit() {
        let vals = [-2.0f32, -1.0, -0.0, 0.0, 0.5, 1.0, 3.0, f32::INFINITY, f32::NEG_INFINITY, 1e-40, -1e-40];
        let bits = |v: Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
        for &x in &vals {
            for &l in &vals {
                for &h in &vals {
                    let (p, lo, hi) = (Vec3::new(x, l, h), Vec3::new(l, h, x), Vec3::new(h, x, l));
                    assert_eq!(
                        bits(clamp3_no_nan(&p, &lo, &hi)),
                        bits(clamp3(&p, &lo, &hi)),
                        "{p:?} {lo:?} {hi:?}"
                    );
                }
            }
        }
        let mut seed = 0xc1a3_0019_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            ((seed >> 40) as f32 / (1u64 << 24) as f32) * 8.0 - 4.0
        };
        for _ in 0..100_000 {
            let p = Vec3::new(next(), next(), next());
            let (a, b) = (Vec3::new(next(), next(), next()), Vec3::new(next(), next(), next()));
            let (lo, hi) = (a.inf(&b), a.sup(&b));
            assert_eq!(bits(clamp3_no_nan(&p, &lo, &hi)), bits(clamp3(&p, &lo, &hi)));
        }
    }

    #[test]
    fn a_wall_seen_once_is_kept_behind_the_vehicle_for_the_forget_time() {
        let params = MemoryParams { forget_s: 3.0, ..MemoryParams::default() };
        let mut m = ObstacleMemory::<128>::new(params);
        let w = World { cyl: Vec::new(), wall_x: Some(2.0) };
        let rep = w.scan(&mut m, 1_000_000, P, 0.0, camera());
        assert!(rep.new_cells > 0 && !rep.rejected);
        // Turned around (the camera now looks away from the wall), 2.9 s later: still there.
        let empty = World { cyl: Vec::new(), wall_x: None };
        for k in 1..=29u64 {
            let r = empty.scan(&mut m, 1_000_000 + k * 100_000, P, core::f32::consts::PI, camera());
            assert_eq!(r.cleared, 0);
        }
        let pts = points(&mut m, 3_900_000, &P);
        let cells: Vec<_> = pts.iter().filter(|o| o.id == STATIC_ID).collect();
        assert!(!cells.is_empty());
        let nearest = cells.iter().map(|o| (o.point - P).norm()).fold(f32::INFINITY, f32::min);
        // The nearest return lies half a beam spacing off the axis: 2/cos(daz/2).
        assert!((nearest - 2.0).abs() < 0.01, "{nearest}");
        // Past the forget time: gone.
        empty.scan(&mut m, 4_100_000, P, core::f32::consts::PI, camera());
        assert!(m.is_empty());
    }

    /// A wall 0.6 m ahead, then the camera turned away for 6 s (past `forget_s` 5 s): within
    /// `keep_near` (1 m) the wall stays; with `keep_near` 0 it is forgotten, as a wall 2 m
    /// away is with the default (the test above). A beam that sees through still clears it.
    #[test]
    fn a_wall_beside_the_vehicle_is_not_forgotten_by_age() {
        let near = World { cyl: Vec::new(), wall_x: Some(0.6) };
        let empty = World { cyl: Vec::new(), wall_x: None };
        let held = |keep_near: f32| {
            let mut m = ObstacleMemory::<128>::new(MemoryParams { keep_near, ..MemoryParams::default() });
            assert!(near.scan(&mut m, 1_000_000, P, 0.0, camera()).new_cells > 0);
            for k in 1..=60u64 {
                empty.scan(&mut m, 1_000_000 + k * 100_000, P, core::f32::consts::PI, camera());
            }
            let pts = points(&mut m, 7_000_000, &P);
            let n = pts.iter().filter(|o| o.id == STATIC_ID).count();
            (n, m)
        };
        let (kept, mut m) = held(1.0);
        assert!(kept > 0, "the wall beside the vehicle was forgotten");
        assert_eq!(held(0.0).0, 0, "keep_near 0 must forget by age");
        // Looking at it again with the wall gone: the beams see through and clear it.
        empty.scan(&mut m, 7_100_000, P, 0.0, camera());
        assert!(m.is_empty());
    }

    /// `fov_walls`: a forward camera saw north free; the vehicle, 4 m east of where it looked
    /// (nothing seen there), moves east. With the cap (0) the memory offers the frontier point
    /// `fov_margin` ahead of the vehicle (no normal), which rides along; with walls (1) no point
    /// but a half-space east of where the vehicle found nothing observed, which stays there as
    /// the vehicle moves on; `2` resolves to walls for a held heading and to the cap for a
    /// heading that turns with the path.
    #[test]
    fn unseen_space_gets_a_speed_cap_or_a_wall_that_stays() {
        let run = |fov_walls: u8| {
            let params = MemoryParams { fov_walls, ..MemoryParams::default() };
            let mut m = ObstacleMemory::<128>::new(params);
            let empty = World { cyl: Vec::new(), wall_x: None };
            empty.scan(&mut m, 1_000, P, 0.0, camera());
            let east = Vec3::new(0.0, 0.3, 0.0);
            let at = |m: &mut ObstacleMemory<128>, p: Vec3| {
                let mut out = Vec::new();
                m.for_each_point(2_000, &p, &east, 1.4, |o| out.push(*o));
                out.into_iter().filter(|o| o.id == FRONTIER_ID).collect::<Vec<_>>()
            };
            let first = at(&mut m, Q);
            let later = at(&mut m, Q + Vec3::new(0.0, 0.1, 0.0));
            (first, later)
        };
        const Q: Vec3 = Vec3::new(0.0, 4.0, -1.0);
        let (first, later) = run(FOV_WALLS_OFF);
        assert_eq!((first.len(), later.len()), (1, 1));
        assert!(first[0].normal.is_none() && ((first[0].point - Q).norm() - 0.25).abs() < 1e-5);
        // Rides along: 0.25 m ahead of the vehicle again.
        let p1 = Q + Vec3::new(0.0, 0.1, 0.0);
        assert!(((later[0].point - p1).norm() - 0.25).abs() < 1e-5);
        let (first, later) = run(FOV_WALLS_ON);
        assert!(!first.is_empty() && first.iter().all(|o| o.normal.is_some()));
        // Fixed in the world: 0.1 m nearer once the vehicle has moved 0.1 m east (the walls'
        // normals are within a sector of west, so their distance shrinks by about that much).
        for (a, b) in first.iter().zip(later.iter()) {
            let n = a.normal.unwrap_or_else(Vec3::zeros);
            let (ga, gb) = (n.dot(&(Q - a.point)), n.dot(&(p1 - b.point)));
            assert!(ga > 0.2 && gb < ga - 0.09, "{ga} → {gb}");
        }
        let held = MemoryParams::DEFAULT;
        assert_eq!(held.fov_walls, FOV_WALLS_HELD);
        assert_eq!(held.with_heading_held(true).fov_walls, FOV_WALLS_ON);
        assert_eq!(held.with_heading_held(false).fov_walls, FOV_WALLS_OFF);
        let off = MemoryParams { fov_walls: FOV_WALLS_OFF, ..held };
        assert_eq!(off.with_heading_held(true).fov_walls, FOV_WALLS_OFF);
        assert!(!MemoryParams { fov_walls: 3, ..held }.valid());
    }

    #[test]
    fn a_beam_through_a_cell_clears_it_and_an_unknown_beam_does_not() {
        let mut m = ObstacleMemory::<128>::new(MemoryParams::default());
        let pole = World { cyl: std::vec![(2.0, 0.0, 0.1)], wall_x: None };
        pole.scan(&mut m, 1_000, P, 0.0, lidar());
        assert!(!m.is_empty());
        let n = m.len();
        // The pole is gone; a dropout scan (all Unknown) keeps it.
        let g = lidar();
        let ranges = [Range::Unknown; 72];
        let pose = Pose::from_rpy(P, 0.0, 0.0, 0.0);
        let scan = Scan { t_us: 2_000, pose, mount: SensorMount::centered(), geometry: g, ranges: &ranges };
        assert_eq!(m.insert_scan(&scan).cleared, 0);
        assert_eq!(m.len(), n);
        // A clear scan sees through it.
        let empty = World { cyl: Vec::new(), wall_x: None };
        let r = empty.scan(&mut m, 3_000, P, 0.0, lidar());
        assert_eq!(r.cleared as usize, n);
        assert!(m.is_empty());
        // A return just behind the cell (closer than clear_margin) does not clear it.
        pole.scan(&mut m, 4_000, P, 0.0, lidar());
        let behind = World { cyl: std::vec![(2.25, 0.0, 0.1)], wall_x: None };
        let r = behind.scan(&mut m, 5_000, P, 0.0, lidar());
        assert_eq!(r.cleared, 0);
    }

    /// A ray passing a few centimetres above a top's returns — a desk seen from above at a
    /// grazing angle, the 3D lidar's lowest row closer than the desk's edge — does not clear
    /// the cell (its box is not inflated upwards); one as close below it, or through it, does.
    #[test]
    fn a_ray_just_above_a_top_keeps_it_one_through_or_below_clears_it() {
        let g = lidar();
        let one = |m: &mut ObstacleMemory<128>, t_us: u64, at: Vec3, r: f32| {
            // Beam 0 (north) returns at `r`, every other beam sees nothing in range.
            let mut ranges = [Range::Clear; 72];
            ranges[0] = Range::Hit(r);
            let pose = Pose::from_rpy(at, 0.0, 0.0, 0.0);
            m.insert_scan(&Scan { t_us, pose, mount: SensorMount::centered(), geometry: g, ranges: &ranges })
        };
        let up = Vec3::new(0.0, 0.0, -0.03); // NED: 3 cm higher
        for (dz, cleared) in [(up, 0), (-up, 1), (Vec3::new(0.0, 0.0, 0.01), 1)] {
            let mut m = ObstacleMemory::<128>::new(MemoryParams::default());
            one(&mut m, 1_000, P, 3.0);
            assert_eq!(m.len(), 1);
            let r = one(&mut m, 2_000, P + dz, 4.5);
            assert_eq!(r.cleared, cleared, "ray {} m below the return", dz.z);
        }
    }

    /// A ray passing just beside a cell's returns (within the inflation, not through them)
    /// clears the cell only when the neighbouring beams also see past it: beside a surface
    /// that goes on (a neighbour returns at the cell) it keeps the cell — a pillar's
    /// silhouette — while a lone return with free beams all round is cleared; a ray through
    /// the returns clears whatever the neighbours see.
    #[test]
    fn a_ray_grazing_a_silhouette_keeps_it_a_lone_return_is_cleared() {
        let g = lidar();
        let scan = |m: &mut ObstacleMemory<128>, t_us: u64, at: Vec3, hits: &[(usize, f32)]| {
            let mut ranges = [Range::Clear; 72];
            for &(k, r) in hits {
                ranges[k] = Range::Hit(r);
            }
            let pose = Pose::from_rpy(at, 0.0, 0.0, 0.0);
            m.insert_scan(&Scan { t_us, pose, mount: SensorMount::centered(), geometry: g, ranges: &ranges })
        };
        let beside = Vec3::new(0.0, 0.03, 0.0); // 3 cm east: beam 0 (north) passes beside the return
                                                // (offset of the second scan, beam 0's and its neighbours' returns, cells cleared)
        type Case<'a> = (Vec3, &'a [(usize, f32)], u32);
        let cases: [Case; 5] = [
            (beside, &[(0, 4.5)], 1),                             // a lone return: cleared
            (beside, &[(0, 4.5), (1, 3.0)], 0),                   // the surface goes on east: kept
            (beside, &[(0, 4.5), (71, 3.0)], 0),                  // … or west: kept
            (beside, &[(0, 4.5), (1, 3.1)], 0),                   // a neighbour short of the margin: kept
            (Vec3::zeros(), &[(0, 4.5), (1, 3.0), (71, 3.0)], 1), // through the return: cleared
        ];
        for (k, (off, hits, cleared)) in cases.into_iter().enumerate() {
            let mut m = ObstacleMemory::<128>::new(MemoryParams::default());
            scan(&mut m, 1_000, P, &[(0, 3.0)]);
            assert_eq!(m.len(), 1);
            let r = scan(&mut m, 2_000, P + off, hits);
            assert_eq!(u32::from(r.cleared), cleared, "case {k}");
        }
    }

    /// Proptest (fixed seed): a wall at a random distance and bearing offset seen by the
    /// lidar from random positions: the cells are at most the cubes the wall crosses, every
    /// point handed out lies in its cube and is no farther from the vehicle than the
    /// returns of that cube (conservative merge).
    #[test]
    fn voxel_merge_is_bounded_and_conservative() {
        let mut runner = TestRunner::new_with_rng(
            Config { cases: 128, failure_persistence: None, ..Config::default() },
            TestRng::from_seed(RngAlgorithm::ChaCha, &[19; 32]),
        );
        let strat = (0.5f32..4.0, -1.0f32..1.0, -1.0f32..1.0, 0.05f32..0.5);
        runner
            .run(&strat, |(wall, px, py, voxel)| {
                let mut m = ObstacleMemory::<512>::new(MemoryParams { voxel, ..MemoryParams::default() });
                let p = Vec3::new(px.min(wall - 0.3), py, -1.0);
                let w = World { cyl: Vec::new(), wall_x: Some(wall) };
                let g = lidar();
                w.scan(&mut m, 1_000, p, 0.3, g);
                // Returns of the scan, recomputed.
                let pose = Pose::from_rpy(p, 0.0, 0.0, 0.3);
                let mut hits = Vec::new();
                for col in 0..g.n_az {
                    let u = pose.rotation * g.direction(0, col);
                    if let Range::Hit(r) = w.cast(&p, &u, &g) {
                        hits.push(p + u * r);
                    }
                }
                // Cubes crossed: distinct keys of the returns.
                let mut keys: Vec<[i32; 3]> = hits
                    .iter()
                    .map(|h| {
                        [
                            (h.x / voxel).floor() as i32,
                            (h.y / voxel).floor() as i32,
                            (h.z / voxel).floor() as i32,
                        ]
                    })
                    .collect();
                keys.sort();
                keys.dedup();
                prop_assert_eq!(m.len(), keys.len());
                prop_assert!(m.len() <= hits.len());
                for c in m.cells() {
                    let q = clamp3(&p, &c.lo, &c.hi);
                    let key = [
                        (q.x / voxel).floor() as i32,
                        (q.y / voxel).floor() as i32,
                        (q.z / voxel).floor() as i32,
                    ];
                    let mine: Vec<_> = hits
                        .iter()
                        .filter(|h| {
                            [
                                (h.x / voxel).floor() as i32,
                                (h.y / voxel).floor() as i32,
                                (h.z / voxel).floor() as i32,
                            ] == key
                        })
                        .collect();
                    prop_assert!(!mine.is_empty(), "a cell's point lies in the cube of its returns");
                    let dq = (q - p).norm();
                    for h in mine {
                        prop_assert!(dq <= (h - p).norm() + 1e-5);
                        prop_assert!((h - q).norm() <= 3f32.sqrt() * voxel + 1e-5);
                    }
                }
                Ok(())
            })
            .unwrap();
    }

    #[test]
    fn a_full_memory_keeps_the_nearest_cells() {
        let mut m = ObstacleMemory::<8>::new(MemoryParams::default());
        // 20 poles at 1..5 m on a ring of bearings: only the 8 nearest stay.
        let cyl: Vec<_> = (0..20)
            .map(|i| {
                let a = i as f32 * core::f32::consts::TAU / 20.0;
                let r = 1.0 + 0.2 * i as f32;
                (r * a.cos(), r * a.sin(), 0.02)
            })
            .collect();
        let w = World { cyl, wall_x: None };
        let g = ScanGeometry::planar_360(360, 0.03, 0.1, 8.0);
        let rep = w.scan(&mut m, 1_000, P, 0.0, g);
        assert_eq!(m.len(), 8);
        assert!(rep.dropped_full > 0);
        let far = m.cells().map(|c| (clamp3(&P, &c.lo, &c.hi) - P).norm()).fold(0.0, f32::max);
        assert!(far < 1.0 + 0.2 * 8.0, "kept a far cell: {far}");
        assert_eq!(m.stats().dropped_full, u32::from(rep.dropped_full));
    }

    /// A person-sized cylinder crossing at 1 m/s 3 m ahead, lidar at 10 Hz: the memory's
    /// point for it carries a velocity within 0.25 m/s of the truth after 2 s, and the
    /// cells it left behind are gone.
    #[test]
    fn a_moving_cluster_gets_a_measured_velocity() {
        let mut m = ObstacleMemory::<128>::new(MemoryParams::default());
        let g = ScanGeometry::planar_360(360, 0.03, 0.1, 8.0);
        let vel = Vec3::new(0.0, 1.0, 0.0);
        let mut last = Vec::new();
        for k in 0..=20u64 {
            let y = -1.5 + k as f32 * 0.1;
            let w = World { cyl: std::vec![(3.0, y, 0.25)], wall_x: None };
            w.scan(&mut m, 1_000_000 + k * 100_000, P, 0.0, g);
            last = points(&mut m, 1_000_000 + k * 100_000, &P);
        }
        let moving: Vec<_> = last.iter().filter(|o| o.id >= CELL_ID_BASE && o.id < FRONTIER_ID).collect();
        assert!(!moving.is_empty(), "{last:?}");
        for o in &moving {
            let v = o.velocity.expect("a confirmed moving track");
            assert!((v - vel).norm() < 0.25, "{v:?}");
            assert!((o.point.y - 0.5).abs() < 0.5, "{:?}", o.point);
        }
        // No cells left along the path (y < 0): the track removed them.
        assert!(m.cells().all(|c| c.hi.y > -0.2), "{:?}", m.cells().collect::<Vec<_>>());
    }

    /// Only a sensor whose tracking row looks along the world's horizontal tracks movers: the
    /// cylinder of `a_moving_cluster_gets_a_measured_velocity` seen by a camera fan pitched 30°
    /// down is clustered and tracked, pitched 60° down (a down-looking sensor's row sees the
    /// floor, not walkers against their background) never.
    #[test]
    fn a_steeply_pitched_sensor_does_not_track() {
        let g = ScanGeometry::grid(64, 1, 1.518, 0.05, 0.1, 8.0);
        let clusters = |pitch_deg: f32| {
            let mut m = ObstacleMemory::<128>::new(MemoryParams::default());
            let mount = SensorMount::new(Vec3::zeros(), 0.0, -pitch_deg.to_radians(), 0.0);
            let mut n = 0u32;
            for k in 0..=20u64 {
                let y = -1.0 + k as f32 * 0.1;
                let w = World { cyl: std::vec![(1.5, y, 0.25)], wall_x: None };
                // 5 m up: the 60° beams meet the cylinder 2.4 m above the ground (not clipped).
                let high = Vec3::new(0.0, 0.0, -5.0);
                n += u32::from(w.scan_mounted(&mut m, 1_000_000 + k * 100_000, high, 0.0, g, mount).clusters);
            }
            n
        };
        assert!(clusters(30.0) > 0);
        assert_eq!(clusters(60.0), 0);
    }

    /// Walls are not placed while a seen mover closes in: a forward 90° fan sees a person
    /// (r 0.25 m) walk at 1 m/s towards the vehicle, which backs away (west, never observed).
    /// With the person standing still the frontier gives walls there; with the person
    /// closing (a measured track) it gives the capped point, so that the evasion is not walled
    /// off (`EVADE_*`).
    #[test]
    fn no_new_wall_while_a_tracked_mover_closes_in() {
        let fan = ScanGeometry::grid(90, 1, 1.571, 0.05, 0.1, 8.0);
        let run = |speed: f32| {
            let params = MemoryParams { fov_walls: FOV_WALLS_ON, ..MemoryParams::default() };
            let mut m = ObstacleMemory::<128>::new(params);
            let mut t = 0;
            for k in 0..=20u64 {
                t = 1_000_000 + k * 100_000;
                let w = World { cyl: std::vec![(3.5 - speed * 0.1 * k as f32, 0.0, 0.25)], wall_x: None };
                w.scan(&mut m, t, P, 0.0, fan);
            }
            let mut out = Vec::new();
            m.for_each_point(t, &P, &Vec3::new(-0.3, 0.0, 0.0), 1.4, |o| out.push(*o));
            let moving = out.iter().any(|o| o.velocity.is_some_and(|w| w.x < -0.7));
            let frontier: Vec<_> = out.into_iter().filter(|o| o.id == FRONTIER_ID).collect();
            (moving, frontier)
        };
        let (moving, still) = run(0.0);
        assert!(!moving && !still.is_empty() && still.iter().all(|o| o.normal.is_some()), "{still:?}");
        let (moving, closing) = run(1.0);
        assert!(moving, "the walker is tracked");
        assert_eq!(closing.len(), 1, "{closing:?}");
        assert!(closing[0].normal.is_none() && ((closing[0].point - P).norm() - 0.25).abs() < 1e-5);
    }

    /// A vehicle flying at 0.5 m/s along a wall 1.5 m away (the returns at grazing
    /// incidence are single points more than the segment gap apart that slide along the
    /// wall with the vehicle), past two static poles, 72-beam lidar with ±1 cm range noise,
    /// 8 s: no track is ever proven moving (no point is extrapolated). (Before the foreground
    /// rule and the motion proof the sliding wall returns were tracked as moving at ≈ 0.5 m/s.)
    /// The unproven tracks' closing-in estimates (issue 36) may only point at the vehicle;
    /// the poles' near faces do not move, so they get none: measured 0 of 326 cluster points
    /// (with the α-β velocity alone, without the near-face test: 5, the fastest 0.126 m/s;
    /// bounds here: 5 %, 0.2 m/s).
    #[test]
    fn static_structure_seen_from_a_moving_vehicle_gets_no_velocity() {
        let mut m = ObstacleMemory::<128>::new(MemoryParams::default());
        let g = lidar();
        let w = World { cyl: std::vec![(0.8, 2.0, 0.1), (-1.2, 3.0, 0.3)], wall_x: Some(1.5) };
        let mut seed = 0x1919_1919_u64;
        let mut noise = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            ((seed >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.02
        };
        let (mut proven, mut estimated, mut cluster_points, mut fastest) = (0, 0, 0, 0.0f32);
        for k in 0..80u64 {
            let t = 1_000_000 + k * 100_000;
            let p = Vec3::new(0.0, -1.0 + 0.05 * k as f32, -1.0);
            let pose = Pose::from_rpy(p, 0.0, 0.0, 0.0);
            let mount = SensorMount::centered();
            let ranges: Vec<Range> = (0..g.n_az)
                .map(|col| match w.cast(&p, &(pose.rotation * g.direction(0, col)), &g) {
                    Range::Hit(r) => Range::Hit(r + noise()),
                    other => other,
                })
                .collect();
            assert!(!m.insert_scan(&Scan { t_us: t, pose, mount, geometry: g, ranges: &ranges }).rejected);
            proven += m.tracks().filter(|(_, tr)| tr.measured_velocity(t).is_some()).count();
            for o in points(&mut m, t, &p) {
                cluster_points += usize::from((CELL_ID_BASE..FRONTIER_ID).contains(&o.id));
                let Some(w) = o.velocity else { continue };
                // Only an unproven track's closing-in estimate: horizontal, along p − q towards
                // the vehicle, at most APPROACH_MAX.
                let d = p - o.point;
                let n = Vec3::new(d.x, d.y, 0.0).normalize();
                assert!(w.dot(&n) > STATIC_SPEED && (w - n * w.dot(&n)).norm() < 1e-4, "{w} at {}", o.point);
                assert!(w.norm() <= APPROACH_MAX + 1e-5);
                estimated += 1;
                fastest = fastest.max(w.norm());
            }
        }
        assert_eq!(proven, 0, "no track of static structure is proven moving");
        assert!(
            estimated * 20 <= cluster_points && fastest < 0.2,
            "{estimated} of {cluster_points}, {fastest} m/s"
        );
    }

    /// A person-sized cylinder walking at 1 m/s, lidar at 10 Hz, one beam in the middle of
    /// it dropped in one scan: the track keeps its slot and its velocity (the dropout
    /// neither splits the cluster nor hands it to a new track without velocity).
    #[test]
    fn a_dropout_inside_a_moving_cluster_keeps_its_track_and_velocity() {
        let mut m = ObstacleMemory::<128>::new(MemoryParams::default());
        let g = ScanGeometry::planar_360(360, 0.03, 0.1, 8.0);
        let mut slot = None;
        for k in 0..=20u64 {
            let t = 1_000_000 + k * 100_000;
            let y = -1.5 + k as f32 * 0.1;
            let w = World { cyl: std::vec![(2.0, y, 0.25)], wall_x: None };
            let pose = Pose::from_rpy(P, 0.0, 0.0, 0.0);
            let mut ranges: Vec<Range> =
                (0..g.n_az).map(|col| w.cast(&P, &(pose.rotation * g.direction(0, col)), &g)).collect();
            if k == 15 {
                // The beam nearest the centre of the cylinder.
                let col = (libm::atan2f(y, 2.0).rem_euclid(core::f32::consts::TAU) / g.daz).round() as usize;
                assert!(matches!(ranges[col % 360], Range::Hit(_)));
                ranges[col % 360] = Range::Unknown;
            }
            let scan = Scan { t_us: t, pose, mount: SensorMount::centered(), geometry: g, ranges: &ranges };
            m.insert_scan(&scan);
            let moving: Vec<_> = m.tracks().filter(|(_, tr)| tr.measured_velocity(t).is_some()).collect();
            if k >= 10 {
                assert_eq!(moving.len(), 1, "k {k}: {moving:?}");
                let (s, tr) = moving[0];
                assert!((tr.velocity - Vec3::new(0.0, 1.0, 0.0)).norm() < 0.25, "k {k}: {tr:?}");
                assert!(slot.is_none_or(|x| x == s), "k {k}: slot {s} after {slot:?}");
                slot = Some(s);
            }
        }
    }

    #[test]
    fn bad_scans_are_rejected_whole() {
        let mut m = ObstacleMemory::<16>::new(MemoryParams::default());
        let g = lidar();
        let ranges = [Range::Hit(1.0); 71];
        let pose = Pose::from_rpy(P, 0.0, 0.0, 0.0);
        let s = Scan { t_us: 0, pose, mount: SensorMount::centered(), geometry: g, ranges: &ranges };
        assert!(m.insert_scan(&s).rejected);
        let ranges = [Range::Hit(1.0); 72];
        let bad = Pose::from_rpy(Vec3::new(f32::NAN, 0.0, 0.0), 0.0, 0.0, 0.0);
        let s = Scan { t_us: 0, pose: bad, mount: SensorMount::centered(), geometry: g, ranges: &ranges };
        assert!(m.insert_scan(&s).rejected);
        let mut g2 = g;
        g2.max_range = 0.05;
        let s = Scan { t_us: 0, pose, mount: SensorMount::centered(), geometry: g2, ranges: &ranges };
        assert!(m.insert_scan(&s).rejected);
        assert!(m.is_empty());
        assert_eq!(m.stats().rejected, 3);
        // Non-finite ranges are ignored beam by beam.
        let ranges = [Range::Hit(f32::NAN); 72];
        let s = Scan { t_us: 0, pose, mount: SensorMount::centered(), geometry: g, ranges: &ranges };
        assert!(!m.insert_scan(&s).rejected);
        assert!(m.is_empty());
    }

    #[test]
    fn ground_returns_are_not_obstacles() {
        let mut m = ObstacleMemory::<64>::new(MemoryParams::default());
        // Looking 30° down from 1 m: every beam hits the floor.
        let g = ScanGeometry::grid(8, 1, 0.8, 0.05, 0.1, 6.0);
        let pose = Pose::from_rpy(P, 0.0, 0.0, 0.0);
        let mount = SensorMount::new(Vec3::zeros(), 0.0, -core::f32::consts::FRAC_PI_6, 0.0);
        let mut ranges = Vec::new();
        for col in 0..g.n_az {
            let u = pose.rotation * (mount.rotation * g.direction(0, col));
            ranges.push(Range::Hit(1.0 / u.z));
        }
        let r = m.insert_scan(&Scan { t_us: 0, pose, mount, geometry: g, ranges: &ranges });
        assert_eq!(r.ground, 8);
        assert!(m.is_empty());
    }
}
