//! Grid search of the planner (issue 38): A* on an occupancy grid of the
//! horizontal plane through the start, for worlds where sampling struggles
//! (dense forests: RRT-Connect needed 44–938 ms, or missed the 1 s budget, at
//! 0.35 trunks/m²).
//!
//! # Method
//! 1. **Plane.** The grid lies in the horizontal plane `z = start.z` (NED). The
//!    goal is reached through `g' = (goal.x, goal.y, start.z)`; when the goal is
//!    at another height, the vertical leg `g' → goal` must pass the segment
//!    check. (Forests, cities and warehouses are 2.5D: their obstacles stand on
//!    the ground above the flight level. A world that needs a climb falls back
//!    to RRT-Connect.)
//! 2. **Region** (sized by the work): the box around start and goal grown by
//!    [`GRID_MIN_MARGIN_M`] or a tenth of their distance, whichever is larger,
//!    clipped to the bounds; when no path exists in it, the margin doubles until
//!    the region is the whole bounds. Cells of `cell_m` (default
//!    [`DEFAULT_GRID_CELL_M`]); a region of more than [`MAX_GRID_CELLS`] cells
//!    gets coarser cells, so memory is bounded (≈ 10 bytes a cell).
//! 3. **Occupancy, conservative.** A cell is free when its centre has a
//!    clearance of at least `required + ρ` to every obstacle, `ρ = cell·√2/2`
//!    (plus 0.1 mm against rounding). The obstacles near the region (from the
//!    spatial index, or a scan of the bounding boxes of a small problem) are
//!    rasterised row by row: the plane's cut through an obstacle grown by
//!    `R = required + ρ` is a disc (sphere, cylinder) or a rounded rectangle
//!    (box), exactly, so no distance is evaluated per cell.
//! 4. **Why grid moves are valid.** A* moves between the centres of 8-adjacent
//!    free cells (diagonals through two blocked cells included). Every point of
//!    such a move lies within `ρ` of one of its ends, and the distance to an
//!    obstacle is 1-Lipschitz, so every point of the move keeps clearance
//!    `≥ required`: a grid path is collision-free by construction. The start and
//!    `g'` connect to free cells within two cells of them through segments that
//!    pass the planner's segment check.
//! 5. **A\*** (Hart, Nilsson & Raphael 1968) with the octile distance, ties
//!    broken towards the larger cost-to-come, in integer costs (axis move 1000,
//!    diagonal 1414) so that ties are exact; flat arrays indexed by cell (no
//!    hashing), a binary heap. Complete at the grid's resolution: when a path of
//!    free cells exists in the region, A* finds the shortest one.
//! 6. **String pulling.** From each kept point, the farthest later grid point
//!    reachable by a segment that passes the planner's segment check (found by
//!    doubling and bisection over the grid path, each accepted segment checked)
//!    becomes the next waypoint. The result goes to the planner's shortcutting
//!    like an RRT path.
//!
//! The cost of a call is the rasterisation (obstacles near the region), the
//! grid's memory (cells of the region) and A*'s expansions (a band around the
//! path in clutter); the wall-clock budget is checked during A*.
//!
//! Owns the grid search. May import: the planner's parent items and `space`.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::space::{shape_aabb, Space};
use super::*;

/// Default cell edge of the grid, m.
pub const DEFAULT_GRID_CELL_M: f32 = 0.1;

/// Largest number of cells of one grid (the cells get coarser beyond it).
pub const MAX_GRID_CELLS: usize = 4_000_000;

/// The first region is the box around start and goal grown by this much or by
/// a tenth of their horizontal distance, whichever is larger, m.
pub const GRID_MIN_MARGIN_M: f32 = 5.0;

/// Extra clearance of free cells against rounding, m.
const ROUND_OFF_M: f64 = 1e-4;

/// A*'s cost of an axis move and of a diagonal move (cell edge = 1000).
const AXIS: u32 = 1000;
const DIAGONAL: u32 = 1414;

/// The heuristic is the octile distance times `1 + 1/HEURISTIC_EXCESS` (weighted
/// A*: the grid path is at most that factor longer than the grid's shortest,
/// before string pulling and shortcutting; u32::MAX: plain A*).
const HEURISTIC_EXCESS: u32 = 20;

/// Neighbour offsets (di, dj) of the 8-connected grid; the first four are the
/// axis moves.
const MOVES: [(i32, i32); 8] = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)];

/// What the grid search found.
pub(super) enum GridResult {
    /// A raw path (start first, goal last) whose segments all passed the segment check.
    Path(Vec<Vec3>),
    /// No grid path (the world needs a climb, the start or goal has no free cell
    /// near it, or the whole bounds hold no path at the grid's resolution).
    NoPath,
    /// The wall-clock budget ran out.
    OutOfTime,
}

/// Grid search from `problem.start` to `problem.goal` (see the module docs).
/// `expansions` counts A*'s expanded cells over all regions tried.
pub(super) fn search(
    space: &mut Space,
    problem: &PlanProblem,
    cell_m: f32,
    budget_ms: f64,
    t0: &Instant,
    expansions: &mut u32,
) -> GridResult {
    let (start, goal) = (problem.start, problem.goal);
    let goal_in_plane = Vec3::new(goal.x, goal.y, start.z);
    if goal_in_plane != goal
        && !(space.point_valid(&goal_in_plane) && space.segment_valid(&goal_in_plane, &goal))
    {
        return GridResult::NoPath;
    }
    let (lo_b, hi_b) = (problem.bounds_min, problem.bounds_max);
    let dist = ((goal.x - start.x).powi(2) + (goal.y - start.y).powi(2)).sqrt();
    let mut margin = GRID_MIN_MARGIN_M.max(0.1 * dist);
    loop {
        let lo = [(start.x.min(goal.x) - margin).max(lo_b.x), (start.y.min(goal.y) - margin).max(lo_b.y)];
        let hi = [(start.x.max(goal.x) + margin).min(hi_b.x), (start.y.max(goal.y) + margin).min(hi_b.y)];
        let whole = lo[0] <= lo_b.x && lo[1] <= lo_b.y && hi[0] >= hi_b.x && hi[1] >= hi_b.y;
        let mut grid = Grid::new(lo, hi, start.z, cell_m, space.required);
        grid.rasterise(space);
        match grid.astar(space, &start, &goal_in_plane, budget_ms, t0, expansions) {
            Astar::Found(cells) => {
                let mut pts = Vec::with_capacity(cells.len() + 3);
                pts.push(start);
                pts.extend(cells.iter().map(|&c| grid.centre(c)));
                pts.push(goal_in_plane);
                let Some(mut path) = pull_string(space, &pts) else { return GridResult::NoPath };
                if goal_in_plane != goal {
                    path.push(goal);
                }
                return GridResult::Path(path);
            }
            Astar::OutOfTime => return GridResult::OutOfTime,
            Astar::NoPath if whole => return GridResult::NoPath,
            Astar::NoPath => margin *= 2.0,
        }
    }
}

enum Astar {
    /// Cells from a start cell to a goal cell.
    Found(Vec<u32>),
    NoPath,
    OutOfTime,
}

/// An occupancy grid of a horizontal rectangle at height `z` (NED).
struct Grid {
    /// Centre of cell (0, 0), m.
    x0: f64,
    y0: f64,
    z: f64,
    /// Cell edge, m.
    h: f64,
    nx: usize,
    ny: usize,
    /// Obstacle reach of a blocked centre: required + ρ + round-off, m.
    reach: f64,
    blocked: Vec<bool>,
}

impl Grid {
    fn new(lo: [f32; 2], hi: [f32; 2], z: f32, cell_m: f32, required: f32) -> Self {
        let (w, d) = ((hi[0] - lo[0]).max(0.0) as f64, (hi[1] - lo[1]).max(0.0) as f64);
        let mut h = cell_m as f64;
        if (w / h + 1.0) * (d / h + 1.0) > MAX_GRID_CELLS as f64 {
            // Coarser cells keep the memory bounded (more conservative, still valid).
            h = ((w + h) * (d + h) / MAX_GRID_CELLS as f64).sqrt() * 1.01;
        }
        let (nx, ny) = (((w / h).floor() as usize).max(1), ((d / h).floor() as usize).max(1));
        // Centred in the region, so every centre is inside it (and the bounds).
        let x0 = lo[0] as f64 + 0.5 * (w - (nx - 1) as f64 * h);
        let y0 = lo[1] as f64 + 0.5 * (d - (ny - 1) as f64 * h);
        let reach = required as f64 + h * std::f64::consts::FRAC_1_SQRT_2 + ROUND_OFF_M;
        Grid { x0, y0, z: z as f64, h, nx, ny, reach, blocked: vec![false; nx * ny] }
    }

    fn centre(&self, c: u32) -> Vec3 {
        let (i, j) = (c as usize % self.nx, c as usize / self.nx);
        Vec3::new((self.x0 + i as f64 * self.h) as f32, (self.y0 + j as f64 * self.h) as f32, self.z as f32)
    }

    /// Mark every cell whose centre is within `reach` of an obstacle.
    fn rasterise(&mut self, space: &Space) {
        let r = self.reach;
        let lo = [self.x0 - r, self.y0 - r, self.z - r];
        let hi = [
            self.x0 + (self.nx - 1) as f64 * self.h + r,
            self.y0 + (self.ny - 1) as f64 * self.h + r,
            self.z + r,
        ];
        match &space.index {
            Some(index) => index.for_each_overlapping(&lo, &hi, |leaf| {
                self.mark(index.leaf(leaf).1);
                true
            }),
            None => {
                for o in space.obstacles {
                    let (a, b) = shape_aabb(o);
                    let (a, b) = (a.cast::<f64>(), b.cast::<f64>());
                    if (0..3).all(|k| a[k] <= hi[k] && b[k] >= lo[k]) {
                        self.mark(o);
                    }
                }
            }
        }
    }

    /// Mark the cells of one obstacle: its cut by the plane, grown by `reach`,
    /// is the set of points within `rho` of the rectangle `[ax, bx] × [ay, by]`.
    fn mark(&mut self, shape: &Shape) {
        let r = self.reach;
        let f = |v: f32| v as f64;
        // (rectangle x, rectangle y, rho); None when the plane misses the grown obstacle.
        let cut = match *shape {
            Shape::Point { center: c } | Shape::Sphere { center: c, .. } => {
                let rad = if let Shape::Sphere { radius, .. } = *shape { f(radius) } else { 0.0 };
                let dz = (self.z - f(c[2])).abs();
                let reach = rad + r;
                (dz < reach).then(|| ([f(c[0]); 2], [f(c[1]); 2], (reach * reach - dz * dz).sqrt()))
            }
            Shape::Box { min, max } => {
                let dz = (f(min[2]) - self.z).max(self.z - f(max[2])).max(0.0);
                (dz < r).then(|| ([f(min[0]), f(max[0])], [f(min[1]), f(max[1])], (r * r - dz * dz).sqrt()))
            }
            Shape::Cylinder { base, radius, height } => {
                // NED: from base z (bottom) up to base z − height.
                let dz = ((f(base[2]) - f(height)) - self.z).max(self.z - f(base[2])).max(0.0);
                (dz < r).then(|| ([f(base[0]); 2], [f(base[1]); 2], f(radius) + (r * r - dz * dz).sqrt()))
            }
        };
        let Some((ax, ay, rho)) = cut else { return };
        let j_lo = ((ay[0] - rho - self.y0) / self.h).ceil().max(0.0);
        let j_hi = ((ay[1] + rho - self.y0) / self.h).floor().min((self.ny - 1) as f64);
        // Empty (or NaN) row range: nothing to mark.
        if j_lo.partial_cmp(&j_hi).is_none_or(|o| o == std::cmp::Ordering::Greater) {
            return;
        }
        for j in j_lo as usize..=j_hi as usize {
            let y = self.y0 + j as f64 * self.h;
            let dy = (ay[0] - y).max(y - ay[1]).max(0.0);
            if dy > rho {
                continue;
            }
            let half = (rho * rho - dy * dy).sqrt();
            let i_lo = ((ax[0] - half - self.x0) / self.h).ceil().max(0.0);
            let i_hi = ((ax[1] + half - self.x0) / self.h).floor().min((self.nx - 1) as f64);
            if i_lo <= i_hi {
                let row = j * self.nx;
                self.blocked[row + i_lo as usize..=row + i_hi as usize].fill(true);
            }
        }
    }

    /// Free cells within two cells of `p` that `p` reaches by a valid segment,
    /// with the segment's length.
    fn attach(&self, space: &mut Space, p: &Vec3) -> Vec<(u32, f32)> {
        let ci = ((p.x as f64 - self.x0) / self.h).round() as i64;
        let cj = ((p.y as f64 - self.y0) / self.h).round() as i64;
        let mut out = Vec::new();
        for dj in -2..=2i64 {
            for di in -2..=2i64 {
                let (i, j) = (ci + di, cj + dj);
                if i < 0 || j < 0 || i >= self.nx as i64 || j >= self.ny as i64 {
                    continue;
                }
                let c = (j as usize * self.nx + i as usize) as u32;
                if self.blocked[c as usize] {
                    continue;
                }
                let q = self.centre(c);
                if space.segment_valid(p, &q) {
                    out.push((c, (q - p).norm()));
                }
            }
        }
        out
    }

    fn astar(
        &self,
        space: &mut Space,
        start: &Vec3,
        goal: &Vec3,
        budget_ms: f64,
        t0: &Instant,
        expansions: &mut u32,
    ) -> Astar {
        let sources = self.attach(space, start);
        let targets = self.attach(space, goal);
        if sources.is_empty() || targets.is_empty() {
            return Astar::NoPath;
        }
        let n = self.nx * self.ny;
        // Per cell: the move that reached it (index into MOVES; SOURCE for a start
        // cell, NONE before it is reached), and its cost-to-come.
        const NONE: u8 = u8::MAX;
        const SOURCE: u8 = 8;
        let mut via = vec![NONE; n];
        let mut g = vec![u32::MAX; n];
        let mut is_target = vec![false; n];
        for &(c, _) in &targets {
            is_target[c as usize] = true;
        }
        let (gi, gj) = (
            ((goal.x as f64 - self.x0) / self.h).round() as i64,
            ((goal.y as f64 - self.y0) / self.h).round() as i64,
        );
        // Integer costs (an axis move 1000, a diagonal 1414, in cells/1000): equal
        // sums are equal exactly, so the tie-break towards the larger cost-to-come
        // follows one of the many equally short octile paths instead of widening
        // over all of them (float sums differ in their last bits).
        let octile = |c: usize| {
            let dx = ((c % self.nx) as i64 - gi).unsigned_abs() as u32;
            let dy = ((c / self.nx) as i64 - gj).unsigned_abs() as u32;
            // Minus the reach of the goal's attachment (two cells).
            let h = (AXIS * dx.max(dy) + (DIAGONAL - AXIS) * dx.min(dy)).saturating_sub(2 * DIAGONAL);
            h + h / HEURISTIC_EXCESS
        };
        let mut heap: BinaryHeap<Reverse<(u64, u32)>> = BinaryHeap::new();
        // Min f first, then max g.
        let key = |f: u32, g: u32| ((f as u64) << 32) | (!g) as u64;
        let cost_of = |d: f32| ((d as f64 / self.h) * AXIS as f64).round() as u32;
        for &(c, d) in &sources {
            let d = cost_of(d);
            if d < g[c as usize] {
                g[c as usize] = d;
                via[c as usize] = SOURCE;
                heap.push(Reverse((key(d.saturating_add(octile(c as usize)), d), c)));
            }
        }
        let costs = [AXIS, AXIS, AXIS, AXIS, DIAGONAL, DIAGONAL, DIAGONAL, DIAGONAL];
        let (nx, ny) = (self.nx as i32, self.ny as i32);
        while let Some(Reverse((k, c))) = heap.pop() {
            let cu = c as usize;
            // A stale entry (the cell was reached more cheaply since) is skipped.
            if !(k as u32) != g[cu] {
                continue;
            }
            *expansions = expansions.saturating_add(1);
            if (*expansions).is_multiple_of(4096) && t0.elapsed().as_secs_f64() * 1e3 > budget_ms {
                return Astar::OutOfTime;
            }
            if is_target[cu] {
                let mut cells = vec![c];
                let mut k = cu;
                while via[k] < SOURCE {
                    let (di, dj) = MOVES[via[k] as usize];
                    k = (k as i64 - di as i64 - dj as i64 * self.nx as i64) as usize;
                    cells.push(k as u32);
                }
                cells.reverse();
                return Astar::Found(cells);
            }
            let (i, j) = ((cu % self.nx) as i32, (cu / self.nx) as i32);
            for (m, &(di, dj)) in MOVES.iter().enumerate() {
                let (ni, nj) = (i + di, j + dj);
                if ni < 0 || nj < 0 || ni >= nx || nj >= ny {
                    continue;
                }
                let nc = nj as usize * self.nx + ni as usize;
                let ng = g[cu].saturating_add(costs[m]);
                if ng < g[nc] && !self.blocked[nc] {
                    g[nc] = ng;
                    via[nc] = m as u8;
                    heap.push(Reverse((key(ng.saturating_add(octile(nc)), ng), nc as u32)));
                }
            }
        }
        Astar::NoPath
    }
}

/// String pulling over the grid path `pts` (start, cell centres, goal): from
/// each kept point the farthest later point reachable by a valid segment
/// (doubling, then bisection; only checked segments are kept). `None` when a
/// step between neighbours fails the check (not expected: grid moves are
/// valid by construction, the check is conservative by a fraction of a mm).
fn pull_string(space: &mut Space, pts: &[Vec3]) -> Option<Vec<Vec3>> {
    let n = pts.len();
    let mut out = vec![pts[0]];
    let mut a = 0;
    while a + 1 < n {
        if !space.segment_valid(&pts[a], &pts[a + 1]) {
            return None;
        }
        // Largest step known good, and a step known bad (or past the end).
        let (mut good, mut step) = (1, 2);
        while a + step < n && space.segment_valid(&pts[a], &pts[a + step]) {
            good = step;
            step *= 2;
        }
        // `a + step` failed the check, or lies past the end.
        let mut bad = step.min(n - a);
        while bad - good > 1 {
            let mid = (good + bad) / 2;
            if space.segment_valid(&pts[a], &pts[a + mid]) {
                good = mid;
            } else {
                bad = mid;
            }
        }
        a += good;
        out.push(pts[a]);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::super::tests::problem;
    use super::*;

    /// Every blocked cell's centre is within `reach` of an obstacle and every
    /// free one farther, for each kind of shape cut by the plane in several ways.
    #[test]
    fn rasterisation_matches_the_signed_distance() {
        let shapes = vec![
            Shape::sphere(Vec3::new(2.0, 1.0, -1.7), 0.6),
            Shape::sphere(Vec3::new(4.0, 3.0, -0.7), 0.5),
            Shape::aabb(Vec3::new(5.0, 0.2, -1.3), Vec3::new(5.7, 1.5, -0.2)),
            Shape::aabb(Vec3::new(6.5, 2.5, -3.0), Vec3::new(7.0, 4.0, -1.9)),
            Shape::cylinder(Vec3::new(8.0, 1.0, 0.0), 0.3, 1.2),
            Shape::cylinder(Vec3::new(9.0, 3.0, 0.0), 0.25, 5.0),
            Shape::cylinder(Vec3::new(1.0, 3.5, -1.8), 0.4, 0.5),
        ];
        let p = problem(shapes.clone());
        let space = Space::new(&p, 0.2736, 0.001);
        let mut grid = Grid::new([-1.0, -1.0], [11.0, 5.0], -1.5, 0.05, 0.2736);
        grid.rasterise(&space);
        let mut blocked = 0;
        for c in 0..grid.blocked.len() {
            let q = grid.centre(c as u32);
            let d = shapes.iter().map(|s| s.signed_distance(&q) as f64).fold(f64::INFINITY, f64::min);
            // Rounding of the f32 distance: a hair on either side of the reach is not judged.
            if (d - grid.reach).abs() < 1e-4 {
                continue;
            }
            assert_eq!(
                grid.blocked[c],
                d < grid.reach,
                "cell {c} at {q:?}: distance {d}, reach {}",
                grid.reach
            );
            blocked += usize::from(grid.blocked[c]);
        }
        assert!(blocked > 1000, "{blocked}");
    }

    #[test]
    fn grid_path_goes_through_the_gap_and_passes_the_check() {
        // A wall across the line with a 0.8 m gap at its north end.
        let wall = Shape::aabb(Vec3::new(5.0, -1.0, -3.0), Vec3::new(5.1, 4.2, 0.0));
        let p = problem(vec![wall]);
        let mut space = Space::new(&p, p.hull_radius + 0.05, 0.001);
        let mut exp = 0;
        let GridResult::Path(path) = search(&mut space, &p, 0.1, 1e9, &Instant::now(), &mut exp) else {
            panic!("no grid path");
        };
        assert_eq!((path[0], path[path.len() - 1]), (p.start, p.goal));
        assert!(path.windows(2).all(|w| space.segment_valid(&w[0], &w[1])));
        assert!(path.iter().any(|w| w.y > 4.2 + p.hull_radius));
        assert!(exp > 0);
    }

    #[test]
    fn a_closed_wall_has_no_grid_path() {
        let wall = Shape::aabb(Vec3::new(5.0, -1.0, -3.0), Vec3::new(5.1, 5.0, 0.0));
        let p = problem(vec![wall]);
        let mut space = Space::new(&p, p.hull_radius + 0.05, 0.001);
        let mut exp = 0;
        assert!(matches!(search(&mut space, &p, 0.1, 1e9, &Instant::now(), &mut exp), GridResult::NoPath));
    }

    #[test]
    fn a_goal_at_another_height_is_reached_by_a_vertical_leg() {
        let wall = Shape::aabb(Vec3::new(5.0, -1.0, -3.0), Vec3::new(5.1, 4.2, 0.0));
        let mut p = problem(vec![wall]);
        p.goal.z = -2.5;
        let mut space = Space::new(&p, p.hull_radius + 0.05, 0.001);
        let mut exp = 0;
        let GridResult::Path(path) = search(&mut space, &p, 0.1, 1e9, &Instant::now(), &mut exp) else {
            panic!("no grid path");
        };
        assert_eq!(path[path.len() - 1], p.goal);
        assert_eq!(path[path.len() - 2], Vec3::new(p.goal.x, p.goal.y, p.start.z));
        assert!(path.windows(2).all(|w| space.segment_valid(&w[0], &w[1])));
    }
}
