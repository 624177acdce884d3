//! On-board replanning (issue 38): when the map the mission was planned on is wrong, the
//! vehicle plans a detour by itself, from what it has sensed, and flies it through the same
//! guidance and safety filter.
//!
//! **What it knows** ([`grid`]): a persistent 2.5-D occupancy grid, [`grid::GRID`]² cells
//! (default 0.2 m: a 12.8 m square that follows the vehicle in whole cells), each with a
//! column of [`grid::SLICES`] world-anchored height slices of the cell's edge (3.2 m, ±1.6 m
//! of the vehicle, following it vertically too), marked with the static obstacle points the
//! filter is given (ground truth's closest points, or the obstacle memory's points with range
//! sensing; not the virtual frontier, ceiling and ground points, [`VIRTUAL_ID`]). A plan at
//! flight level z collapses the slices within `band_m` of z into a 2-D layer of occupied
//! cells, grown by the hull radius + `margin_m`, and searches that. **Unknown space
//! is assumed free**: a detour through space nobody has seen is flown under the same safety
//! filter, which stops the vehicle before anything it then senses, and the next check replans.
//!
//! **Trigger** ([`Replanner::step`]): checked at `rate_hz` (≥ 1 Hz; default 2): the remaining
//! mission path (from the guidance's reference on it, `horizon_m` of it, sampled every half
//! cell) comes within the hull radius less [`POINT_SLACK_M`], in 3D, of a static obstacle point
//! the filter is given now — a blockage the offline planner's own clearance (hull + 0.05 m from
//! surfaces) would have rejected, allowing for an obstacle memory's point standing up to half a
//! voxel nearer than the surface. The path is walked from the reference, not from the vehicle:
//! the straight line from a vehicle the filter pushed off the path to the next waypoint is not
//! the path, and it cut door corners of the mapped office (stalled, below, from the vehicle:
//! the reference may have run past the wall the vehicle is held in front of). The test
//! is 3D and against the points, not the grid: the grid rounds to cells and slices, so a planned
//! path that passes over a table, a plant or under a lamp within the height band, or a door
//! edge a cell's half diagonal closer than it is, would look blocked (it did, on the mapped
//! office: 10 replans and no goal). Samples within the hull radius of the vehicle are left to
//! the filter, and leaving the flight area is no trigger (the vehicle may stand a few cm outside
//! it, the mission's path was planned inside it). Or the filter reports a
//! stall (`deadlock`, `crate::plant_aware`), or the vehicle has stayed within [`STUCK_M`] of
//! one place for [`STUCK_S`], and the remaining path passes within [`STALL_REACH_CELLS`]
//! (half a cell) of the centre of a cell occupied at the path's own height anywhere in the
//! grid — it runs through the cell (a crate across it). Not the inflation radius (hull +
//! `margin_m`): that is more than the offline planner's clearance (hull + 0.05 m), so a vehicle
//! held by wind in a passage the planner threaded read as blocked and replanned out of it
//! (`narrow_passage` in the speed campaign: 64 goals fewer and 3 grazes not flagged with
//! replanning on; docs/perception.md § Confirmation). After a replan, a no-path or a budget
//! result the next plan waits `cooldown_s` (no thrashing).
//!
//! **Confirmation** (`dwell_s`, `RPL_DWELL`, default 4 s): a blockage by a *sensed* point (the
//! obstacle memory's cells and clusters, ids from [`STATIC_ID`]) is planned around only once
//! a static point has stood within [`STILL_M`] of where the blocking point was first seen at
//! every check for `dwell_s`; until then the check is `NotNeeded` and the filter alone keeps
//! the vehicle off it. Why: the memory hands a walker's cells out as static until its track
//! is proven moving, so without it a person crossing the path triggered detours that the
//! person then walked into (`outdoor_person_crossing` with `lidar3d`: 5 replans, goal 20 s
//! later than without replanning; docs/perception.md § Confirmation). A walker of length `L`
//! along its motion leaves the first point's neighbourhood after (`L` + [`STILL_M`]) / `v`:
//! the paper's 0.5 m person at 0.2 m/s after 3.75 s, within 4 s; anything slower or longer
//! is indistinguishable from a static obstacle over the wait and is planned around. Points
//! whose source knows their motion (ground truth, a map: ids below [`STATIC_ID`]) and a stall
//! are planned at once; a vehicle held in front of a blockage for [`STUCK_S`] counts as stalled,
//! so the wait is at most that when the filter stops the vehicle.
//!
//! **Flight levels** (issue 38: in `office_blocked` the way from room B to room C passes over
//! printer B, as the offline planner's 3-D path does; at the vehicle's height the printer
//! closes the door, and the 2-D replanner found no path there, or its detours rejoined the
//! mission beyond the climb and lost it). The check walks the whole remaining path at its
//! own heights. A plan tries up to [`MAX_LEVELS`] flight levels, in order: the vehicle's
//! height, then the highest and the lowest waypoint height of the remaining path from the
//! blockage to where it leaves the grid (where the mission climbs over or ducks under what it
//! passes), each skipped within a cell of a level tried before or when its band leaves the
//! grid's window; the first level with a path wins. A detour at a level rejoins the mission
//! only on the path's first run of waypoints at that level beyond the blockage (at the
//! vehicle's height: the run from the blockage on) — never beyond where the mission leaves
//! that level, which would drop the heights it flies there. At a level other than the
//! vehicle's the vehicle first climbs (descends) where it stands, and a target more than
//! [`VERTICAL_M`] off the level is reached straight down (up) from above it: each such
//! vertical leg needs its column clear of marked slices from one height to the other (band
//! included) within the inflation radius — at the vehicle, cells it already stands beside at
//! its own height aside (a wall it climbs along) — else that level (target) is not used: the
//! vehicle never climbs through what it has seen. The detour's waypoints carry the level's
//! height. Why levels from the path and no 3-D search: the mission's heights lie inside the
//! flight envelope the offline planner kept (the envelope's ceiling and floor are virtual
//! points the grid does not hold), and a 2-D search per level costs the 2-D planner's memory
//! and time times the levels tried.
//!
//! **Plan** ([`Replanner::plan`]): per level, A* with octile costs on the grid ([`search`];
//! Hart, Nilsson & Raphael 1968) from the vehicle's cell to the **target**: the farthest
//! waypoint of the remaining path's run at that level beyond the blockage that is free (at its
//! own height) and inside the grid (the mission's
//! waypoints are route points of a planned path: rejoining it as far on as the grid reaches
//! keeps successive detours from piling up); if that is not reachable, the nearer ones in turn,
//! last the first free point of the path after the blockage ([`MAX_TARGETS`] tries per level). The cell path is simplified by
//! line of sight on the grid (a waypoint only where the straight line would cross a blocked
//! cell), and the new path is: detour waypoints → the target → the rest of the mission.
//! Cells within the inflation radius of the vehicle that are not themselves occupied are
//! passable, so a vehicle already near an obstacle can leave it.
//!
//! **Results** ([`ReplanOutcome`]): `Replanned` (the caller sets the new path with
//! `FlightController::set_path`, whose reference continues from where it is); `NotNeeded`
//! (path clear in the grid); `NoPath` (no target reachable: the vehicle keeps its path, the
//! filter holds it in front of the blockage and the stall detector reports `deadlock`; the
//! caller reports the event; retried after the cooldown, as the grid may change);
//! `BudgetExceeded` (the search's expansion cap or open list, or the new path would exceed
//! the detour or path capacity: handled like `NoPath`).
//!
//! **Bounds.** Memory: the grid 9 KiB (8 KiB of columns, 2 B per cell; two 512 B bit
//! layers), the search ≈ 20 KiB (`Replanner` 30,344 B in all, the F405 image's `PLANNER`;
//! 8,196 B more than with the 2-D grid). Time: the trigger tests at most `horizon_m` / (cell / 2) path samples
//! against the points given (one distance each; when stalled, also a column test of ≤ 9
//! cells each); per level a column test, a layer collapse (O(CELLS)) and inflation; at most
//! [`MAX_SEARCHES`] = [`MAX_LEVELS`] · [`MAX_TARGETS`] = 12 searches (4 with the 2-D grid; a
//! target whose cell is blocked at the level, or whose column is not clear, is skipped
//! without one) of at most
//! `max_expansions` (≤ 4096) expansions of 8 neighbours, plus O(path cells · 2·GRID)
//! line-of-sight tests.
//!
//! **Where it runs** ([`onboard`]): beside the outer loop, off the control loops — the outer
//! side takes a snapshot at `rate_hz`, the planner serves it, the outer side applies the new
//! path; the host's in-process controller and the firmware's replanner task run that one driver.
//!
//! May import: `crate::obstacle`, `crate::fmath`, `crate::Vec3`, the virtual points' and the
//! memory's ids of `crate::perception` and `crate::safety::plant_aware`; [`onboard`] also
//! `crate::outer`; `params` (the `RPL_*` parameters, re-exported here) `crate::param_decl`.

pub mod grid;
pub mod onboard;
mod params;
pub mod search;

pub use params::{sane_hull, ReplanParams};

use crate::obstacle::ObstaclePoint;
use crate::perception::STATIC_ID;
use crate::Vec3;
use grid::{Grid, CELLS, GRID};
use search::{Search, SearchResult};

/// Targets tried per level (waypoints of the run at the level, then the first free point beyond the blockage).
pub const MAX_TARGETS: usize = 4;
/// Flight levels tried per plan (the vehicle's height, the remaining path's highest and lowest).
pub const MAX_LEVELS: usize = 3;
/// Searches per plan at most (levels · targets; a target skipped without a search does not
/// count): reaching it is `BudgetExceeded`.
pub const MAX_SEARCHES: usize = 12;
/// Detour waypoints at most (before the target; the vertical legs included).
pub const MAX_DETOUR: usize = 16;
/// A level more than this (m) off the vehicle's (or the target's) height is reached by a
/// vertical leg where the vehicle (the target) stands; within it the detour's first (last)
/// leg slopes.
pub const VERTICAL_M: f32 = 0.1;
/// The vehicle within this of one place (m) ...
pub const STUCK_M: f32 = 0.15;
/// ... for this long (s) counts as stalled.
pub const STUCK_S: f32 = 3.0;
/// The blockage trigger's slack, m: a path sample counts as blocked when it lies within the
/// hull radius minus this of a static point. The offline planner keeps the hull radius + 0.05 m
/// from the surfaces it knows, and an obstacle memory's point stands up to about half a
/// voxel (0.1 m at the default 0.2 m) nearer the vehicle than the surface it was seen on (a
/// cell hands out its returns' box point nearest the vehicle; on the mapped office 0.083 m off
/// pillar B2 and 0.084 m off lamp C, lidar3d and lidar): hull + 0.05 − 0.1 = hull − 0.05 is
/// the nearest a mapped path can come to such a point; an unmapped obstacle across the path
/// puts a point within a few cm of a sample.
pub const POINT_SLACK_M: f32 = 0.05;
/// A stalled vehicle's remaining path counts as blocked in the grid where a marked cell's
/// centre lies within this many cells of a path sample (module docs: *Trigger*).
pub const STALL_REACH_CELLS: f32 = 0.5;
/// Obstacle points moving faster than this (m/s) are not marked (the grid is for the static world).
pub const STATIC_SPEED: f32 = 0.1;
/// A pending blockage stays the same while a static point lies within this (m) of where its
/// point was first seen ([`ReplanParams::dwell_s`]): an obstacle memory hands out a cell's
/// return nearest the vehicle, so the point of a static surface moves by up to a voxel's half
/// diagonal (0.17 m at the default 0.2 m) as the vehicle closes in; a walker that the memory
/// has not proven moving leaves it in 0.25 / v s (1.25 s at the paper's 0.2 m/s).
pub const STILL_M: f32 = 0.25;

/// What one plan did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplanOutcome {
    /// A new path was written: `detour` waypoints before the target, `waypoints` in all.
    Replanned {
        /// Detour waypoints (before the target point).
        detour: u8,
        /// Waypoints of the new path.
        waypoints: u8,
    },
    /// The remaining path is clear in the grid.
    NotNeeded,
    /// No target beyond the blockage is reachable through the grid.
    NoPath,
    /// The search's cap or a capacity was reached first.
    BudgetExceeded,
}

/// Counters since start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReplanStats {
    /// Plans run (checks that were due and not in cooldown).
    pub checks: u32,
    /// New paths.
    pub replans: u32,
    /// `NoPath` results.
    pub no_path: u32,
    /// `BudgetExceeded` results.
    pub budget: u32,
}

/// The on-board replanner (see the module documentation). Keeps its grid between calls.
#[derive(Clone, Debug)]
pub struct Replanner {
    params: ReplanParams,
    hull: f32,
    grid: Grid,
    search: Search,
    next_check_us: u64,
    stats: ReplanStats,
    /// Where the vehicle was, and since when (µs), for [`Replanner::no_progress`].
    anchor: (Vec3, u64),
    /// The blockage being confirmed: the static point that blocked the path, and since when
    /// (µs); x infinite: none ([`Replanner::confirmed`]).
    pending: (Vec3, u64),
}

/// Where the remaining path is blocked: `kb`, the index of the blocked segment's end waypoint,
/// and the first free point after the blockage (if the path has one in the grid).
struct Blockage {
    kb: usize,
    first_free: Option<Target>,
    /// The sensed static point that blocks the path, to be confirmed ([`Replanner::confirmed`];
    /// `None`: a point whose source knows it static — a map's, ground truth's — or blocked in
    /// the grid, when stalled).
    point: Option<Vec3>,
}

/// A point on the remaining path: where, and the index of the waypoint its segment ends at.
#[derive(Clone, Copy, Debug)]
struct Target {
    p: Vec3,
    /// Index into the remaining path of the segment's end waypoint.
    next: usize,
    /// The point is that waypoint itself.
    at_waypoint: bool,
}

impl Replanner {
    /// A replanner with every field zero (all-zero parameters, which no request carries: the
    /// first [`Replanner::serve`] takes the request's parameters with
    /// [`Replanner::reconfigure`]), as a constant: the firmware's `static` of it is built at
    /// compile time, never on a stack (≈ 29 KiB), and is all zero bytes (it lives in a section
    /// the firmware zeroes at boot).
    pub const ZEROED: Replanner = Replanner {
        params: ReplanParams::ZEROED,
        hull: 0.0,
        grid: Grid::ZEROED,
        search: Search::ZEROED,
        next_check_us: 0,
        stats: ReplanStats { checks: 0, replans: 0, no_path: 0, budget: 0 },
        anchor: (Vec3::new(0.0, 0.0, 0.0), 0),
        pending: (Vec3::new(0.0, 0.0, 0.0), 0),
    };

    /// A replanner for a vehicle of hull radius `hull` m (invalid parameters: the defaults).
    pub fn new(params: ReplanParams, hull: f32) -> Self {
        let params = params.checked();
        Replanner {
            params,
            hull: sane_hull(hull),
            grid: Grid::new(params.cell_m, &Vec3::zeros()),
            search: Search::default(),
            next_check_us: 0,
            stats: ReplanStats::default(),
            anchor: (Vec3::new(f32::INFINITY, 0.0, 0.0), 0),
            pending: (Vec3::new(f32::INFINITY, 0.0, 0.0), 0),
        }
    }

    /// New parameters and hull radius, in place (the search's buffers are kept: no 20 KiB
    /// value on the stack): the grid starts empty, the counters and flight area are kept.
    pub fn reconfigure(&mut self, params: ReplanParams, hull: f32) {
        // A flight area set on a configured replanner is kept ([`Replanner::ZEROED`] has none).
        let area = if self.params.valid() { self.grid.area() } else { None };
        self.params = params.checked();
        self.hull = sane_hull(hull);
        self.grid.reset(self.params.cell_m, &Vec3::zeros());
        self.grid.set_area(area);
        self.next_check_us = 0;
        self.anchor = (Vec3::new(f32::INFINITY, 0.0, 0.0), 0);
        self.pending = (Vec3::new(f32::INFINITY, 0.0, 0.0), 0);
    }

    /// The hull radius in use, m.
    pub fn hull(&self) -> f32 {
        self.hull
    }

    /// The parameters in use.
    pub fn params(&self) -> &ReplanParams {
        &self.params
    }

    /// Counters since start.
    pub fn stats(&self) -> ReplanStats {
        self.stats
    }

    /// Limit detours to a flight area (NED x, y min and max, m; a geofence); `None`: no limit.
    pub fn set_area(&mut self, area: Option<([f32; 2], [f32; 2])>) {
        self.grid.set_area(area);
    }

    /// The grid (plots, tests).
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Mark the static `points` in the grid's columns (those within its height window), which
    /// first follows the vehicle at `pos` (NED); the occupied layer is then the vehicle's level.
    /// O(points + CELLS).
    pub fn observe(&mut self, pos: &Vec3, points: &[ObstaclePoint]) {
        if !pos.iter().all(|c| c.is_finite()) {
            return;
        }
        self.grid.follow(pos);
        for o in points {
            if !ignored(o) {
                self.grid.mark(&o.point);
            }
        }
        self.grid.select_level(pos.z, self.params.band_m);
    }

    /// The trigger at `now_us`: when a check is due (rate, cooldown) and replanning is on,
    /// [`Replanner::plan`] from `pos` along `remaining` (the waypoints not yet reached, checked
    /// from `along`: the guidance's reference on the path) against the obstacle `points` given
    /// now, with the whole remaining path in the grid checked when `stalled`. `None`: no check
    /// was due.
    #[allow(clippy::too_many_arguments)]
    pub fn step<const N: usize>(
        &mut self,
        now_us: u64,
        pos: &Vec3,
        along: &Vec3,
        stalled: bool,
        remaining: &[Vec3],
        points: &[ObstaclePoint],
        out: &mut heapless::Vec<Vec3, N>,
    ) -> Option<ReplanOutcome> {
        if !self.params.enable {
            return None;
        }
        let stuck = self.no_progress(now_us, pos);
        if now_us < self.next_check_us || remaining.is_empty() {
            return None;
        }
        let r = self.plan_at(Some(now_us), pos, along, remaining, points, stalled || stuck, out);
        let wait = match r {
            ReplanOutcome::NotNeeded => 1.0 / self.params.rate_hz,
            _ => self.params.cooldown_s.max(1.0 / self.params.rate_hz),
        };
        self.next_check_us = now_us.saturating_add((wait * 1e6) as u64);
        Some(r)
    }

    /// The vehicle has stayed within [`STUCK_M`] of one place for [`STUCK_S`] (a stall the
    /// filter need not report: the trajectory guidance's clock waits for the vehicle).
    fn no_progress(&mut self, now_us: u64, pos: &Vec3) -> bool {
        let moved = (pos - self.anchor.0).norm_squared() > STUCK_M * STUCK_M;
        if moved || !pos.iter().all(|c| c.is_finite()) || now_us < self.anchor.1 {
            self.anchor = (*pos, now_us);
            return false;
        }
        now_us - self.anchor.1 >= (STUCK_S * 1e6) as u64
    }

    /// The blockage by the static `point` at `now_us` has stood still for `dwell_s`: a static
    /// point given now lies within [`STILL_M`] of where the pending blockage's point was first
    /// seen, continuously since then. A blockage elsewhere (a walker that moved on, a new one)
    /// starts the wait again from `point`.
    fn confirmed(&mut self, now_us: u64, point: Vec3, points: &[ObstaclePoint]) -> bool {
        let (at, since) = self.pending;
        let still = at.x.is_finite() && touching(points, &at, STILL_M).is_some() && now_us >= since;
        if !still {
            self.pending = (point, now_us);
        }
        let since = self.pending.1;
        now_us.saturating_sub(since) as f32 * 1e-6 >= self.params.dwell_s
    }

    /// Plan from `pos` along `remaining`, checking `horizon_m` of it, from the point `along`
    /// (the guidance's reference: the path as planned, not the line from wherever the vehicle
    /// stands to the next waypoint; from `pos` when `stalled` or `along` is not finite), for a
    /// blockage by the
    /// static `points` (all of it, and for grid cells within [`STALL_REACH_CELLS`] too, when
    /// `stalled`); the new path (when [`ReplanOutcome::Replanned`]) is written to `out`,
    /// otherwise `out` is left empty. See the module documentation.
    pub fn plan<const N: usize>(
        &mut self,
        pos: &Vec3,
        along: &Vec3,
        remaining: &[Vec3],
        points: &[ObstaclePoint],
        stalled: bool,
        out: &mut heapless::Vec<Vec3, N>,
    ) -> ReplanOutcome {
        self.plan_at(None, pos, along, remaining, points, stalled, out)
    }

    /// [`Replanner::plan`] with a blockage confirmed over time when `now_us` is given
    /// ([`Replanner::confirmed`]; `None`: planned at once, as a stall is).
    #[allow(clippy::too_many_arguments)]
    fn plan_at<const N: usize>(
        &mut self,
        now_us: Option<u64>,
        pos: &Vec3,
        along: &Vec3,
        remaining: &[Vec3],
        points: &[ObstaclePoint],
        stalled: bool,
        out: &mut heapless::Vec<Vec3, N>,
    ) -> ReplanOutcome {
        let horizon = if stalled { f32::INFINITY } else { self.params.horizon_m };
        out.clear();
        self.stats.checks = self.stats.checks.saturating_add(1);
        if !pos.iter().all(|c| c.is_finite()) || remaining.is_empty() {
            return ReplanOutcome::NotNeeded;
        }
        let radius = self.hull + self.params.margin_m;
        self.grid.follow(pos);
        // Stalled, the way on from where the vehicle stands is what is blocked (the reference
        // may have run past a thin wall the filter holds the vehicle in front of).
        let from = if stalled || !along.iter().all(|c| c.is_finite()) { pos } else { along };
        let Some(blockage) = self.find_blockage(pos, from, remaining, points, horizon, stalled, radius)
        else {
            self.pending.0.x = f32::INFINITY;
            return ReplanOutcome::NotNeeded;
        };
        if let (Some(now), Some(point), false) = (now_us, blockage.point, stalled) {
            if !self.confirmed(now, point, points) {
                return ReplanOutcome::NotNeeded;
            }
        }
        self.pending.0.x = f32::INFINITY;
        let levels = self.levels(pos, remaining, blockage.kb);
        let r = self.search_levels(pos, remaining, radius, &blockage, &levels, out);
        match r {
            ReplanOutcome::Replanned { .. } => self.stats.replans = self.stats.replans.saturating_add(1),
            ReplanOutcome::NoPath => self.stats.no_path = self.stats.no_path.saturating_add(1),
            ReplanOutcome::BudgetExceeded => self.stats.budget = self.stats.budget.saturating_add(1),
            ReplanOutcome::NotNeeded => {}
        }
        if !matches!(r, ReplanOutcome::Replanned { .. }) {
            out.clear();
        }
        r
    }

    /// Walk the remaining path from `from` every half cell: `None` when the first `horizon` m
    /// pass no static point of `points` within the hull radius (or it leaves the grid first).
    /// Otherwise the blockage: the blocked segment and the first free point after it.
    #[allow(clippy::too_many_arguments)]
    fn find_blockage(
        &self,
        pos: &Vec3,
        from: &Vec3,
        remaining: &[Vec3],
        points: &[ObstaclePoint],
        horizon: f32,
        stalled: bool,
        radius: f32,
    ) -> Option<Blockage> {
        let step = 0.5 * self.grid.cell();
        let free = |p: &Vec3| self.free_at(p, pos, radius);
        // Stalled, a sample is blocked only where a marked cell's centre lies within half a
        // cell of it (the path runs through the cell: a crate across it), not where a wall
        // stands at the offline planner's clearance (hull + 0.05 m, less than the inflation
        // radius): a vehicle held by wind in a passage the planner threaded is no blockage.
        let open = |p: &Vec3| self.free_at(p, pos, STALL_REACH_CELLS * self.grid.cell());
        let (mut s, mut blocked_at, mut first_free) = (0.0f32, None::<usize>, None::<Target>);
        let mut point = None;
        let reach = (self.hull - POINT_SLACK_M).max(0.0);
        let mut a = *from;
        'walk: for (k, b) in remaining.iter().enumerate() {
            let len = crate::fmath::norm3(&(b - a));
            let n = ((len / step) as u32).min(16 * GRID as u32) + 1;
            for m in 1..=n {
                let p = a + (b - a) * (m as f32 / n as f32);
                match (blocked_at, self.grid.cell_of(&p)) {
                    (None, None) => return None,
                    // Samples within the hull radius of the vehicle are the filter's (the
                    // vehicle there is as near the points as the filter let it come).
                    (None, Some(_))
                        if (touching(points, &p, reach).is_some()
                            && (p - pos).norm_squared() > self.hull * self.hull)
                            || (stalled && !open(&p)) =>
                    {
                        if s + len * m as f32 / n as f32 > horizon {
                            return None;
                        }
                        blocked_at = Some(k);
                        point = touching(points, &p, reach).filter(|o| o.id >= STATIC_ID).map(|o| o.point);
                    }
                    (Some(_), Some(_)) if free(&p) => {
                        first_free = Some(Target { p, next: k, at_waypoint: m == n });
                        break 'walk;
                    }
                    _ => {}
                }
            }
            s += len;
            if blocked_at.is_none() && s > horizon {
                return None;
            }
            a = *b;
        }
        Some(Blockage { kb: blocked_at?, first_free, point })
    }

    /// The targets of a plan at flight level `z` (`own`: the vehicle's height), in the order
    /// tried: the waypoints of the remaining path's first run at that level beyond the
    /// blockage (consecutive waypoints within `band_m` of `z`; at the vehicle's height the run
    /// must start at the blocked segment's end) that are free at their own height and in the
    /// grid, farthest first (the detour rejoins the mission as far on as the grid reaches, so
    /// that successive detours do not pile up — but not beyond where the mission leaves the
    /// level: rejoining there would drop the heights it climbs or descends to, the way over or
    /// under what it passes), then the first free point after the blockage when it lies on
    /// that run.
    fn level_targets(
        &self,
        pos: &Vec3,
        remaining: &[Vec3],
        blockage: &Blockage,
        (z, own): (f32, bool),
        radius: f32,
    ) -> heapless::Vec<Target, MAX_TARGETS> {
        let band = self.params.band_m;
        let on = |w: &Vec3| (w.z - z).abs() <= band;
        let on_at = |k: usize| remaining.get(k).is_some_and(on);
        let kb = blockage.kb;
        let start = if own { kb } else { (kb..remaining.len()).find(|&k| on_at(k)).unwrap_or(kb) };
        let end = (start..remaining.len()).find(|&k| !on_at(k)).unwrap_or(remaining.len());
        let fallback = blockage.first_free.filter(|f| on(&f.p) && f.next <= end && (!own || f.next >= start));
        let mut targets: heapless::Vec<Target, MAX_TARGETS> = heapless::Vec::new();
        for k in (start..end).rev() {
            if targets.len() + usize::from(fallback.is_some()) >= MAX_TARGETS
                || fallback.is_some_and(|f| k < f.next)
            {
                break;
            }
            if let Some(w) = remaining.get(k).filter(|w| self.free_at(w, pos, radius)) {
                let _ = targets.push(Target { p: *w, next: k, at_waypoint: true });
            }
        }
        if let Some(f) = fallback {
            let _ = targets.push(f);
        }
        targets
    }

    /// `p` is in the grid and the flight area, and free at its own height: no cell within the
    /// inflation `radius` of its cell has a marked slice within `band_m` of `p.z` — or, within
    /// `radius` of the vehicle at `pos`, its own cell has none (as [`passable`]).
    fn free_at(&self, p: &Vec3, pos: &Vec3, radius: f32) -> bool {
        let Some((i, j)) = self.grid.cell_of(p) else { return false };
        let band = self.grid.span_mask(p.z - self.params.band_m, p.z + self.params.band_m);
        self.grid.in_area(i, j)
            && (self.grid.column_clear(i, j, band, radius, 0)
                || (self.grid.column(i, j) & band == 0
                    && (self.grid.centre(i, j, pos.z) - pos).xy().norm_squared() <= radius * radius))
    }

    /// The flight levels a plan tries, in order ([`MAX_LEVELS`]): the vehicle's height, then the
    /// highest and the lowest waypoint of the remaining path from the blockage (the blocked
    /// segment's end waypoint, index `kb`) to where it leaves the grid (where the mission
    /// climbs over or ducks under what it passes), each only when it is more than a cell from
    /// the levels before it and its band lies in the grid's window.
    fn levels(&self, pos: &Vec3, remaining: &[Vec3], kb: usize) -> heapless::Vec<f32, MAX_LEVELS> {
        let mut levels: heapless::Vec<f32, MAX_LEVELS> = heapless::Vec::new();
        let _ = levels.push(pos.z);
        let span = remaining.get(kb..).unwrap_or(&[]);
        let zs =
            span.iter().take_while(|w| self.grid.cell_of(w).is_some()).map(|w| w.z).filter(|z| z.is_finite());
        // NED: the highest point is the smallest z.
        let (high, low) = zs.fold((f32::INFINITY, f32::NEG_INFINITY), |(h, l), z| (h.min(z), l.max(z)));
        let band = self.params.band_m;
        for z in [high, low] {
            let far = levels.iter().all(|l| (l - z).abs() > self.grid.cell());
            if z.is_finite() && far && self.grid.holds_span(z - band, z + band) {
                let _ = levels.push(z);
            }
        }
        levels
    }

    /// Search each level's targets ([`Replanner::level_targets`]) in turn (levels outer,
    /// targets inner: a detour at the vehicle's height first); at most [`MAX_SEARCHES`]
    /// searches (then `BudgetExceeded`).
    fn search_levels<const N: usize>(
        &mut self,
        pos: &Vec3,
        remaining: &[Vec3],
        radius: f32,
        blockage: &Blockage,
        levels: &[f32],
        out: &mut heapless::Vec<Vec3, N>,
    ) -> ReplanOutcome {
        let mut searches = 0usize;
        let Some(start) = self.grid.cell_of(pos) else { return ReplanOutcome::NoPath };
        let band = self.params.band_m;
        let own = self.grid.span_mask(pos.z - band, pos.z + band);
        for (n, &z) in levels.iter().enumerate() {
            // The climb (or descent) to the level at the vehicle: its column clear from its
            // height to the level's, what it already stands beside at its own height aside.
            let climb = self.grid.span_mask(pos.z.min(z) - band, pos.z.max(z) + band);
            if (z - pos.z).abs() > VERTICAL_M && !self.grid.column_clear(start.0, start.1, climb, radius, own)
            {
                continue;
            }
            self.grid.select_level(z, band);
            self.grid.inflate(radius);
            let targets = self.level_targets(pos, remaining, blockage, (z, n == 0), radius);
            for t in &targets {
                let Some(goal) = self.grid.cell_of(&t.p) else { continue };
                // The target's column clear from the level to its height, its cell passable at the level.
                let down = self.grid.span_mask(t.p.z.min(z) - band, t.p.z.max(z) + band);
                if !passable(&self.grid, goal.0, goal.1, pos, radius)
                    || ((t.p.z - z).abs() > VERTICAL_M
                        && !self.grid.column_clear(goal.0, goal.1, down, radius, 0))
                {
                    continue;
                }
                if searches >= MAX_SEARCHES {
                    return ReplanOutcome::BudgetExceeded;
                }
                searches += 1;
                let grid = &self.grid;
                let passable = |i: usize, j: usize| passable(grid, i, j, pos, radius);
                match self.search.run(start, goal, passable, u32::from(self.params.max_expansions)) {
                    SearchResult::Budget => return ReplanOutcome::BudgetExceeded,
                    SearchResult::NoPath(_) => continue,
                    SearchResult::Found(_) => {
                        return self.assemble(pos, remaining, radius, (start, goal), z, t, out)
                    }
                }
            }
        }
        ReplanOutcome::NoPath
    }

    /// The new path of a found search: line-of-sight waypoints from the target back to the
    /// vehicle, reversed, then the target and the rest of the mission.
    #[allow(clippy::too_many_arguments)]
    fn assemble<const N: usize>(
        &self,
        pos: &Vec3,
        remaining: &[Vec3],
        radius: f32,
        (start, goal): ((usize, usize), (usize, usize)),
        z: f32,
        t: &Target,
        out: &mut heapless::Vec<Vec3, N>,
    ) -> ReplanOutcome {
        let free = |i: usize, j: usize| passable(&self.grid, i, j, pos, radius);
        let mut back: heapless::Vec<Vec3, MAX_DETOUR> = heapless::Vec::new();
        // Off the level, the target is reached straight down (or up) from above it.
        let over = Vec3::new(t.p.x, t.p.y, z);
        if (t.p.z - z).abs() > VERTICAL_M && back.push(over).is_err() {
            return ReplanOutcome::BudgetExceeded;
        }
        let mut anchor = over;
        let (mut cell, mut last) = (goal, over);
        for _ in 0..CELLS {
            let Some(prev) = self.search.parent(cell.0, cell.1) else { break };
            let q =
                if prev == start { Vec3::new(pos.x, pos.y, z) } else { self.grid.centre(prev.0, prev.1, z) };
            if !self.grid.line_free(&anchor, &q, free) {
                // `last` is the farthest cell seen from the anchor: a corner of the detour.
                if back.push(Vec3::new(last.x, last.y, z)).is_err() {
                    return ReplanOutcome::BudgetExceeded;
                }
                anchor = last;
            }
            last = q;
            cell = prev;
        }
        // Off the level, the vehicle first climbs (or descends) to it where it stands.
        if (pos.z - z).abs() > VERTICAL_M && back.push(Vec3::new(pos.x, pos.y, z)).is_err() {
            return ReplanOutcome::BudgetExceeded;
        }
        let rest = if t.at_waypoint {
            &remaining[(t.next + 1).min(remaining.len())..]
        } else {
            &remaining[t.next..]
        };
        if back.len() + 1 + rest.len() > N {
            return ReplanOutcome::BudgetExceeded;
        }
        for w in back.iter().rev().chain(core::iter::once(&t.p)).chain(rest.iter()) {
            let _ = out.push(*w);
        }
        ReplanOutcome::Replanned { detour: back.len() as u8, waypoints: out.len().min(255) as u8 }
    }
}

/// A static point of `points` lies within `r` m (3D) of `p`.
/// The first static point of `points` within `r` of `p`.
fn touching<'a>(points: &'a [ObstaclePoint], p: &Vec3, r: f32) -> Option<&'a ObstaclePoint> {
    points.iter().find(|o| !ignored(o) && (o.point - p).norm_squared() <= r * r)
}

/// The virtual points' first id ([`crate::obstacle::VIRTUAL_ID`]): they stand for unseen space
/// or the flight envelope, not for something in the way: the replanner neither marks nor tests
/// them.
pub use crate::obstacle::VIRTUAL_ID;

/// The point is not a static obstacle: a moving one's (faster than [`STATIC_SPEED`]) or a
/// virtual one ([`VIRTUAL_ID`]).
fn ignored(o: &ObstaclePoint) -> bool {
    o.id >= VIRTUAL_ID || o.velocity.is_some_and(|v| v.norm_squared() > STATIC_SPEED * STATIC_SPEED)
}

/// A cell the search may enter: not blocked, or blocked only by inflation within `radius` of
/// the vehicle at `start` (so that a vehicle already near an obstacle can leave it).
fn passable(grid: &Grid, i: usize, j: usize, start: &Vec3, radius: f32) -> bool {
    if !grid.is_blocked(i, j) {
        return true;
    }
    let c = grid.centre(i, j, start.z);
    !grid.is_occupied(i, j) && grid.in_area(i, j) && (c - start).xy().norm_squared() <= radius * radius
}

#[cfg(test)]
mod tests;
