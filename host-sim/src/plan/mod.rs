//! Offline path planner: A* on an occupancy grid of the flight plane
//! ([`grid`], issue 38) and bidirectional RRT-Connect on the vehicle's bounding
//! sphere, followed by path shortcutting (paper §Planner; issue 5).
//!
//! # API
//! ```ignore
//! use parapet_sim::plan::{plan, PlanProblem, PlannerParams, PlanError};
//! let problem = PlanProblem { bounds_min, bounds_max, obstacles, start, goal, hull_radius }; // NED, m
//! let params = PlannerParams { seed: 7, ..PlannerParams::default() };
//! match plan(&problem, &params) {
//!     Ok(path) => { /* path.waypoints: NED, m, start first, goal last */ }
//!     Err(e) => std::process::exit(e.exit_code()), // 2: bad start/goal/input, 3: no path
//! }
//! ```
//! * [`PlanProblem`]: the scene in the **world NED frame** (m): bounds of the
//!   centre of mass, the **static** obstacles, start, goal and the hull radius.
//!   Moving obstacles are deliberately *not* part of the problem: the planner
//!   plans against what is known at planning time, and the CBF safety filter
//!   handles obstacles that move (the caller drops them, or passes only the
//!   static ones).
//! * [`PlannerParams`]: margin, seed, budgets, goal bias, waypoint capacity.
//! * [`plan`] returns a [`PlannedPath`] (waypoints NED, start first, goal
//!   last, at most `max_waypoints` of them) or a [`PlanError`] whose
//!   [`PlanError::exit_code`] is the CLI's exit code.
//! * [`PlanProblem::from_scene`] builds the problem from a loaded
//!   [`crate::world::scene::Scene`].
//! * [`path_is_valid`] checks any waypoint list (e.g. one read from a path file
//!   with [`crate::plan::pathfile`]) against a problem with the same segment test.
//!
//! # Configuration space and validity
//! The configuration is the centre of mass. A position `p` is **valid** when it
//! lies inside `[bounds_min, bounds_max]` (component-wise) and its clearance —
//! the signed distance to the nearest obstacle surface, from
//! [`Shape::closest_point`] — is at least `required = hull_radius + margin`.
//! Start or goal closer than `required` to an obstacle counts as "in
//! collision" (the margin is part of the planner's notion of free space).
//!
//! A **segment** is valid when every point on it is. The bounds box is convex,
//! so a segment between two in-bounds points stays in bounds. Obstacles are
//! checked by *clearance-based stepping along the segment*, never by a fixed
//! sampling step (which can jump over a thin obstacle):
//!
//! * At arc length `s`, obstacle `i` has clearance `c = |p − q|` to its closest
//!   point `q`, outward normal `n = (p − q)/c`. Every shape here (point,
//!   sphere, box, vertical cylinder) is **convex**, so the whole obstacle lies
//!   behind the supporting plane through `q` with normal `n`. Along the ray
//!   `p + t·d` (`|d| = 1`) the distance to the obstacle is therefore at least
//!   the distance to that plane, `c + t·(d·n)`. This stays `≥ required` for
//!   `t ≤ (c − required)/(−d·n)` when `d·n < 0`, and for every `t` when
//!   `d·n ≥ 0` (moving away from or parallel to the plane). Since
//!   `c + t·(d·n) ≥ c − t`, this step is never shorter than the plain
//!   Lipschitz step `c − required` and is exact for a planar face hit head-on.
//! * Broad phase: each obstacle's bounding box is grown by `required` once
//!   per problem; an obstacle whose grown box misses the segment's bounding
//!   box is at least `required` away from every point of the segment and is
//!   certified for the whole segment without a distance evaluation. Problems
//!   with at least [`INDEX_MIN_OBSTACLES`] obstacles find the candidates in a
//!   BVH ([`crate::world::index::StaticIndex`], built per call or passed in
//!   with [`plan_with_index`]) and keep only those whose grown box meets the
//!   **segment itself** (a long diagonal segment's bounding box holds
//!   thousands of trunks in a forest); the point checks of samples query the
//!   same tree. Smaller problems (every shipped scene) scan the grown boxes as
//!   before, so their paths are unchanged bit for bit.
//! * Each remaining obstacle keeps the arc length up to which it is
//!   certified; only obstacles whose certificate has run out are
//!   re-evaluated, so a segment check usually costs at most one distance
//!   evaluation per nearby obstacle.
//! * **Why conservative:** every accepted piece of the segment is covered by a
//!   certificate that is a true lower bound on the distance to each obstacle,
//!   evaluated with a small extra tolerance ([`CERT_EPS_M`]) against f32
//!   rounding. The check can only err towards rejecting a valid segment.
//! * **Near the limit:** where `c − required` is tiny and the segment heads
//!   into the obstacle, certified steps shrink (a segment grazing a curved
//!   surface at exactly the required clearance would need infinitely many).
//!   A certified step shorter than `PlannerParams::min_step_m` (default 1 mm)
//!   declares the segment blocked at that point, and the loop is also capped at
//!   [`MAX_SEGMENT_STEPS`] evaluations. Both only reject, never accept; the
//!   effect is that segments may not approach an obstacle more closely than
//!   about `required` plus a fraction of a millimetre while heading into it.
//!
//! # Algorithm
//! 1. Validate the input; check start and goal (named errors).
//! 2. Try the straight segment start → goal; if valid, done (0 iterations,
//!    [`PlanMethod::Straight`]).
//! 3. Search, by the problem's size:
//!    * **Indexed problems** (≥ [`INDEX_MIN_OBSTACLES`] obstacles: generated
//!      forests, cities, warehouses): RRT-Connect below with at most
//!      [`RRT_FIRST_ITERATIONS`] iterations, then the **grid search** ([`grid`]:
//!      A* on a conservative occupancy grid of the horizontal plane through the
//!      start, cells of `grid_cell_m`, in a region around start and goal that
//!      grows while it holds no path; every grid move is collision-free by
//!      construction, then string pulling with the segment check). Both paths
//!      are shortcut (step 4) and the shorter is kept, so a path is never longer
//!      than the one RRT-Connect alone returned when it succeeded within those
//!      iterations. The grid search is deterministic and complete at its
//!      resolution: it does not miss the gaps of a dense forest the way
//!      sampling does. If neither finds a path (a world that needs a climb, or
//!      no path at the grid's resolution), RRT-Connect runs again with the whole
//!      budget.
//!    * **Small problems** (every shipped scene): RRT-Connect first, with half
//!      the wall-clock budget; if it finds nothing, the grid search gets the
//!      rest. (Their paths are unchanged whenever RRT-Connect finds one.)
//!
//!    RRT-Connect (Kuffner & LaValle 2000): two trees rooted at start and
//!    goal, nearest neighbours from a `kiddo` k-d tree per tree. Samples are
//!    uniform in the bounds, redrawn (up to [`FREE_SAMPLE_TRIES`] times) until
//!    clear of obstacles, with goal bias (with probability `goal_bias` the
//!    sample is the other tree's root). Each iteration extends one tree by at
//!    most `range_m` towards the sample — from its nearest node, or if that
//!    step is blocked from the next nearest, up to `neighbours` nodes — then
//!    greedily connects the other tree towards the new node in steps of at
//!    most `range_m`; the trees swap roles every iteration. A step is added
//!    only when the whole step is valid (a node left against an obstacle by a
//!    partial step becomes the nearest node for many samples it cannot serve;
//!    measured, that multiplied the iterations on the office scene by ~5).
//!    Stops at the first connection, after `max_iterations` iterations or
//!    after `time_budget_ms` (`parapet plan --max-iterations`, `--time-limit`).
//!    Indexed problems (large scenes) sample in the box around start and goal
//!    grown by [`REGION_MIN_MARGIN_M`] or half their distance, whichever is
//!    larger, clipped to the bounds; the margin doubles every
//!    [`REGION_GROW_ITERATIONS`] iterations (the region becomes the bounds), and
//!    the default `range_m` is 20 % of the region's largest extent. A mission of
//!    60 m in a 1.4 km forest then samples where the path can be, not the
//!    whole forest.
//! 4. Shortcutting (of either search's path): random vertex-to-vertex shortcuts, `shortcut_attempts`
//!    random shortcuts between points anywhere on the path, `corner_passes`
//!    corner-cutting passes (each interior waypoint is replaced by two points
//!    on its neighbouring segments, as far out as bisection finds valid), then
//!    a final greedy pass (from each kept waypoint jump to the farthest
//!    waypoint reachable by a valid segment) and removal of collinear
//!    waypoints. Every segment of the returned path has itself passed the
//!    segment check (pieces kept from cut segments are re-checked rather than
//!    assumed valid), so [`path_is_valid`] holds for every returned path.
//! 5. If the result has more than `max_waypoints` waypoints (start and goal
//!    included), that is an error ([`PlanError::TooManyWaypoints`]); the path
//!    is never truncated.
//!
//! # Determinism
//! All randomness comes from a `ChaCha8Rng` seeded with `PlannerParams::seed`;
//! shortcutting uses counts, not time. The same problem, parameters and seed
//! give the same path, bit for bit, whenever the search ends by finding a
//! path or by the iteration budget. Only a search cut short by the wall-clock
//! `time_budget_ms` depends on the machine's speed. RRT-Connect and its
//! shortcutting draw from stream 0 of the seed, the grid path's shortcutting
//! from stream 1; the grid search itself draws no random numbers.
//!
//! Owns the planner and [`pathfile`]; [`generate`] checks generated scenes with it.
//! May import: `parapet-core` (shapes), [`crate::world`] (scene, index), [`crate::input`].

use std::borrow::Cow;
use std::time::Instant;

use crate::world::index::StaticIndex;
use parapet_core::obstacle::Shape;
use parapet_core::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

pub mod generate;
pub mod grid;
pub mod pathfile;
mod rrt;
mod shortcut;
mod space;

use rrt::search;

use shortcut::simplify;
use space::Space;

/// Default planning margin added to the hull radius, m.
pub const DEFAULT_MARGIN_M: f32 = 0.05;

/// Default waypoint capacity (start and goal included): what a mission holds,
/// [`crate::input::limits::MAX_WAYPOINTS`]. The flight controller holds
/// [`parapet_core::controller::PATH_CAPACITY`] (64) at a time and is given a longer path in
/// windows as it flies it (`parapet_core::outer::path_stream`, issue 38).
pub const DEFAULT_MAX_WAYPOINTS: usize = crate::input::limits::MAX_WAYPOINTS;

/// Hard cap on clearance evaluations per segment check (the check rejects
/// the rest of the segment when it is reached; only relevant for a segment
/// that grazes curved surfaces at the limit over a long stretch).
pub const MAX_SEGMENT_STEPS: usize = 4096;

/// Uniform draws per sample looking for a position clear of obstacles
/// before the last draw is used as it is.
pub const FREE_SAMPLE_TRIES: usize = 32;

/// Bisection steps per corner in the corner-cutting pass (finds the cut to
/// within 1/64 of the neighbouring segments).
pub const CORNER_BISECTIONS: usize = 6;

/// Tolerance (m) subtracted from every certified clearance against f32
/// rounding, so that certificates stay true lower bounds.
pub const CERT_EPS_M: f32 = 1e-5;

/// A planning problem in the world **NED** frame (m). Static obstacles only:
/// the planner ignores moving obstacles (the safety filter handles them).
#[derive(Clone, Debug, PartialEq)]
pub struct PlanProblem {
    /// Lower corner of the box the centre of mass must stay in, NED, m.
    pub bounds_min: Vec3,
    /// Upper corner of that box, NED, m (≥ `bounds_min` component-wise).
    pub bounds_max: Vec3,
    /// Static obstacles, NED, m.
    pub obstacles: Vec<Shape>,
    /// Start position of the centre of mass, NED, m.
    pub start: Vec3,
    /// Goal position of the centre of mass, NED, m.
    pub goal: Vec3,
    /// Radius of the vehicle's bounding sphere, m (≥ 0).
    pub hull_radius: f32,
}

impl PlanProblem {
    /// The planning problem of a loaded scene: its NED bounds, **the map** — its
    /// static, mapped obstacles ([`Scene::map_shapes`]; moving ones are left to the
    /// safety filter, unmapped ones to the sensors and the filter in flight) —,
    /// mission start and goal, and the vehicle's hull radius.
    ///
    /// [`Scene::map_shapes`]: crate::world::scene::Scene::map_shapes
    pub fn from_scene(scene: &crate::world::scene::Scene) -> Self {
        Self::with_obstacles(scene, scene.map_shapes())
    }

    /// [`Self::from_scene`] with every static obstacle, mapped or not: the world
    /// as it stands (the scene generator's check that the world has a path).
    pub fn of_world(scene: &crate::world::scene::Scene) -> Self {
        Self::with_obstacles(scene, scene.static_shapes())
    }

    fn with_obstacles(scene: &crate::world::scene::Scene, obstacles: Vec<Shape>) -> Self {
        let (lo, hi) = scene.bounds_ned();
        PlanProblem {
            bounds_min: crate::world::scene::to_f32(&lo),
            bounds_max: crate::world::scene::to_f32(&hi),
            obstacles,
            start: crate::world::scene::to_f32(&scene.start),
            goal: crate::world::scene::to_f32(&scene.goal),
            hull_radius: scene.vehicle.hull_radius as f32,
        }
    }
}

/// Planner tuning. `Default` gives the documented defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannerParams {
    /// Extra clearance beyond the hull radius, m (≥ 0; default 0.05).
    pub margin: f32,
    /// RNG seed; same seed, same path (see the module docs).
    pub seed: u64,
    /// RRT-Connect iteration budget (≥ 1; default 100 000).
    pub max_iterations: u32,
    /// Wall-clock budget of the search (grid and RRT-Connect), ms (> 0; default 1000).
    pub time_budget_ms: f64,
    /// Probability in [0, 1] that a sample is the other tree's root (default 0.05).
    pub goal_bias: f32,
    /// Maximum number of waypoints, start and goal included (≥ 2; default
    /// [`DEFAULT_MAX_WAYPOINTS`], what a mission holds).
    pub max_waypoints: usize,
    /// Maximum extension length per tree step, m; `None` = 20 % of the
    /// largest bounds extent (OMPL's default range), at least 0.1 m.
    pub range_m: Option<f32>,
    /// Shortest certified step of the segment check, m (> 0; default 0.001).
    pub min_step_m: f32,
    /// Number of random shortcut attempts between arbitrary path points
    /// (default 200; 0 disables them, the greedy pass still runs).
    pub shortcut_attempts: u32,
    /// Number of nearest tree nodes tried, nearest first, when extending a
    /// tree towards a sample (≥ 1; 1 is plain RRT-Connect; default 3).
    pub neighbours: usize,
    /// Corner-cutting passes after the random shortcuts (default 1; 0 disables).
    pub corner_passes: u32,
    /// Cell edge of the grid search, m (0.01 ≤ x ≤ 10; default
    /// [`grid::DEFAULT_GRID_CELL_M`] = 0.1). Gaps narrower than about the hull
    /// diameter + margin + 1.4 cells are closed for the grid (RRT-Connect may
    /// still find them).
    pub grid_cell_m: f32,
}

impl Default for PlannerParams {
    fn default() -> Self {
        PlannerParams {
            margin: DEFAULT_MARGIN_M,
            seed: 0,
            max_iterations: 100_000,
            time_budget_ms: 1000.0,
            goal_bias: 0.05,
            max_waypoints: DEFAULT_MAX_WAYPOINTS,
            range_m: None,
            min_step_m: 0.001,
            shortcut_attempts: 200,
            neighbours: 3,
            corner_passes: 1,
            grid_cell_m: grid::DEFAULT_GRID_CELL_M,
        }
    }
}

/// A collision-free piecewise-linear path.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedPath {
    /// Waypoints, NED, m; the first is the start and the last the goal.
    pub waypoints: Vec<Vec3>,
    /// Total length of the polyline, m.
    pub length_m: f32,
    /// Wall-clock time of the whole `plan` call (search + shortcutting), ms.
    pub planning_time_ms: f64,
    /// RRT-Connect iterations, or A* expansions of the grid search (0 when the
    /// straight line was free); see `method`.
    pub iterations: u32,
    /// The seed that produced this path.
    pub seed: u64,
    /// Which search found the path.
    pub method: PlanMethod,
}

/// Which search found a path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanMethod {
    /// The straight line start → goal was free.
    Straight,
    /// A* on the occupancy grid ([`grid`]).
    Grid,
    /// RRT-Connect.
    RrtConnect,
}

impl PlanMethod {
    /// The name in path files and messages: `straight`, `grid`, `rrt-connect`.
    pub fn as_str(self) -> &'static str {
        match self {
            PlanMethod::Straight => "straight",
            PlanMethod::Grid => "grid",
            PlanMethod::RrtConnect => "rrt-connect",
        }
    }
}

/// Why planning failed.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum PlanError {
    /// The start is closer than hull radius + margin to an obstacle (or inside one).
    #[error("start position is in collision (closer than hull radius + margin to an obstacle)")]
    StartInCollision,
    /// The goal is closer than hull radius + margin to an obstacle (or inside one).
    #[error("goal position is in collision (closer than hull radius + margin to an obstacle)")]
    GoalInCollision,
    /// The start is outside the scene bounds.
    #[error("start position is outside the scene bounds")]
    StartOutOfBounds,
    /// The goal is outside the scene bounds.
    #[error("goal position is outside the scene bounds")]
    GoalOutOfBounds,
    /// The search budget ran out without connecting start and goal.
    #[error("no path found after {iterations} iterations in {elapsed_ms:.1} ms")]
    NoPathFound {
        /// Iterations performed.
        iterations: u32,
        /// Time spent, ms.
        elapsed_ms: f64,
    },
    /// The simplified path needs more waypoints than the firmware can hold.
    #[error("the path needs {n} waypoints but at most {max} fit the firmware's path capacity")]
    TooManyWaypoints {
        /// Waypoints of the simplified path.
        n: usize,
        /// Capacity (`PlannerParams::max_waypoints`).
        max: usize,
    },
    /// A number in the problem or the parameters is not finite or out of range.
    #[error("invalid planner input: {0}")]
    InvalidInput(String),
}

impl PlanError {
    /// Process exit code for the CLI: 2 for bad input, start or goal
    /// (in collision, out of bounds); 3 when no usable path was found
    /// (search budget exhausted, or too many waypoints).
    pub fn exit_code(&self) -> i32 {
        match self {
            PlanError::NoPathFound { .. } | PlanError::TooManyWaypoints { .. } => 3,
            _ => 2,
        }
    }
}

/// Problems with at least this many obstacles use the spatial index
/// ([`crate::world::index`]) for every validity check, and sample in a region
/// around start and goal that grows while no path is found.
pub const INDEX_MIN_OBSTACLES: usize = crate::world::tracker::INDEX_MIN_OBSTACLES;

/// Indexed problems: the first sampling region is the box around start and
/// goal grown by this much or by half their distance, whichever is larger, m.
pub const REGION_MIN_MARGIN_M: f32 = 20.0;

/// Indexed problems: RRT-Connect's iterations before the grid search (the
/// shorter of the two paths is kept; a sparse world is usually connected in
/// tens of iterations, a dense one is left to the grid).
pub const RRT_FIRST_ITERATIONS: u32 = 100;

/// Indexed problems: the sampling region's margin doubles after this many
/// iterations without a connection (until the region is the whole bounds).
pub const REGION_GROW_ITERATIONS: u32 = 500;

fn check_vec(name: &str, v: &Vec3) -> Result<(), PlanError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(PlanError::InvalidInput(format!("{name} is not finite: {v:?}")))
    }
}

fn validate(problem: &PlanProblem, params: &PlannerParams) -> Result<(), PlanError> {
    let bad = |m: String| Err(PlanError::InvalidInput(m));
    check_vec("bounds_min", &problem.bounds_min)?;
    check_vec("bounds_max", &problem.bounds_max)?;
    check_vec("start", &problem.start)?;
    check_vec("goal", &problem.goal)?;
    if (0..3).any(|i| problem.bounds_min[i] > problem.bounds_max[i]) {
        return bad(format!(
            "bounds_min {:?} exceeds bounds_max {:?}",
            problem.bounds_min, problem.bounds_max
        ));
    }
    if !(problem.hull_radius.is_finite() && problem.hull_radius >= 0.0) {
        return bad(format!("hull_radius must be finite and >= 0 m, got {}", problem.hull_radius));
    }
    for (i, o) in problem.obstacles.iter().enumerate() {
        if !o.is_valid() {
            return bad(format!("obstacle {i} has a non-finite or negative size: {o:?}"));
        }
    }
    if !(params.margin.is_finite() && params.margin >= 0.0) {
        return bad(format!("margin must be finite and >= 0 m, got {}", params.margin));
    }
    if problem.hull_radius + params.margin <= 0.0 {
        return bad("hull_radius + margin must be > 0 m".into());
    }
    if params.max_iterations == 0 {
        return bad("max_iterations must be >= 1".into());
    }
    if !(params.time_budget_ms.is_finite() && params.time_budget_ms > 0.0) {
        return bad(format!("time_budget_ms must be finite and > 0, got {}", params.time_budget_ms));
    }
    if !(0.0..=1.0).contains(&params.goal_bias) {
        return bad(format!("goal_bias must be in [0, 1], got {}", params.goal_bias));
    }
    if params.neighbours == 0 {
        return bad("neighbours must be >= 1".into());
    }
    if params.max_waypoints < 2 {
        return bad(format!("max_waypoints must be >= 2, got {}", params.max_waypoints));
    }
    if let Some(r) = params.range_m {
        if !(r.is_finite() && r > 0.0) {
            return bad(format!("range_m must be finite and > 0 m, got {r}"));
        }
    }
    if !(params.min_step_m.is_finite() && params.min_step_m > 0.0) {
        return bad(format!("min_step_m must be finite and > 0 m, got {}", params.min_step_m));
    }
    if !(0.01..=10.0).contains(&params.grid_cell_m) {
        return bad(format!("grid_cell_m must be in [0.01, 10] m, got {}", params.grid_cell_m));
    }
    Ok(())
}

/// Total length of a polyline, m.
pub fn path_length(waypoints: &[Vec3]) -> f32 {
    waypoints.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// `true` when every waypoint is valid and every segment between consecutive
/// waypoints passes the planner's (conservative) segment check for the
/// problem's bounds, static obstacles and `hull_radius + margin`.
pub fn path_is_valid(problem: &PlanProblem, margin: f32, waypoints: &[Vec3]) -> bool {
    let mut space = Space::new(problem, problem.hull_radius + margin, PlannerParams::default().min_step_m);
    if waypoints.is_empty() || !waypoints.iter().all(|p| space.point_valid(p)) {
        return false;
    }
    waypoints.windows(2).all(|w| space.segment_valid(&w[0], &w[1]))
}

/// Plan a collision-free path from `problem.start` to `problem.goal`.
///
/// Errors: invalid numbers → [`PlanError::InvalidInput`]; start/goal outside
/// the bounds or closer than `hull_radius + margin` to an obstacle → the named
/// variant; budget exhausted → [`PlanError::NoPathFound`]; simplified path
/// longer than `max_waypoints` → [`PlanError::TooManyWaypoints`].
pub fn plan(problem: &PlanProblem, params: &PlannerParams) -> Result<PlannedPath, PlanError> {
    plan_with_index(problem, None, params)
}

/// The index [`plan_with_index`] takes: the problem's obstacles in a BVH,
/// `None` for problems below [`INDEX_MIN_OBSTACLES`] (they scan every box).
/// Build it once to plan the same obstacles many times (seeds, missions).
pub fn index_for(problem: &PlanProblem) -> Option<StaticIndex> {
    (problem.obstacles.len() >= INDEX_MIN_OBSTACLES).then(|| StaticIndex::from_shapes(&problem.obstacles))
}

/// [`plan`] with a prebuilt index of `problem.obstacles` ([`index_for`]; it
/// must have been built from the same obstacle list). Same result as [`plan`].
pub fn plan_with_index(
    problem: &PlanProblem,
    index: Option<&StaticIndex>,
    params: &PlannerParams,
) -> Result<PlannedPath, PlanError> {
    let t0 = Instant::now();
    validate(problem, params)?;
    if let Some(i) = index {
        if i.len() != problem.obstacles.len() {
            return Err(PlanError::InvalidInput(format!(
                "the index holds {} obstacles, the problem {}",
                i.len(),
                problem.obstacles.len()
            )));
        }
    }
    let required = problem.hull_radius + params.margin;
    let mut space = Space::new_unindexed(problem, required, params.min_step_m).indexed(index);
    let (start, goal) = (problem.start, problem.goal);
    if !space.in_bounds(&start) {
        return Err(PlanError::StartOutOfBounds);
    }
    if !space.point_valid(&start) {
        return Err(PlanError::StartInCollision);
    }
    if !space.in_bounds(&goal) {
        return Err(PlanError::GoalOutOfBounds);
    }
    if !space.point_valid(&goal) {
        return Err(PlanError::GoalInCollision);
    }

    let (waypoints, iterations, method) = if space.segment_valid(&start, &goal) {
        (vec![start, goal], 0, PlanMethod::Straight)
    } else {
        find_path(&mut space, problem, params, &t0)?
    };
    if waypoints.len() > params.max_waypoints {
        return Err(PlanError::TooManyWaypoints { n: waypoints.len(), max: params.max_waypoints });
    }
    Ok(PlannedPath {
        length_m: path_length(&waypoints),
        waypoints,
        planning_time_ms: t0.elapsed().as_secs_f64() * 1e3,
        iterations,
        seed: params.seed,
        method,
    })
}

/// Steps 3 and 4 (module docs): the shortcut path, the iterations or
/// expansions of the search that found it, and which search that was.
fn find_path(
    space: &mut Space,
    problem: &PlanProblem,
    params: &PlannerParams,
    t0: &Instant,
) -> Result<(Vec<Vec3>, u32, PlanMethod), PlanError> {
    let budget = params.time_budget_ms;
    // RRT-Connect and its shortcutting draw from the seed's stream 0, as they
    // always did: the same seed gives the same path as before the grid search.
    let rrt = |space: &mut Space, max_iterations: u32, budget_ms: f64| {
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
        let capped = PlannerParams { max_iterations, ..params.clone() };
        let (raw, it) = search(space, problem, &capped, &mut rng, t0, budget_ms)?;
        let path = simplify(space, raw, params.shortcut_attempts, params.corner_passes, &mut rng);
        Ok::<_, PlanError>((path, it, PlanMethod::RrtConnect))
    };
    let grid = |space: &mut Space, budget_ms: f64| {
        let mut expansions = 0;
        match grid::search(space, problem, params.grid_cell_m, budget_ms, t0, &mut expansions) {
            grid::GridResult::Path(raw) => {
                // The grid's shortcutting draws from stream 1.
                let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
                rng.set_stream(1);
                let path = simplify(space, raw, params.shortcut_attempts, params.corner_passes, &mut rng);
                Some((path, expansions, PlanMethod::Grid))
            }
            grid::GridResult::NoPath | grid::GridResult::OutOfTime => None,
        }
    };
    if space.index.is_none() {
        return match rrt(space, params.max_iterations, 0.5 * budget) {
            Err(PlanError::NoPathFound { iterations, .. }) => grid(space, budget).ok_or_else(|| {
                PlanError::NoPathFound { iterations, elapsed_ms: t0.elapsed().as_secs_f64() * 1e3 }
            }),
            r => r,
        };
    }
    let quick = rrt(space, params.max_iterations.min(RRT_FIRST_ITERATIONS), budget).ok();
    match (quick, grid(space, budget)) {
        (Some(q), Some(g)) => Ok(if path_length(&g.0) < path_length(&q.0) { g } else { q }),
        (Some(p), None) | (None, Some(p)) => Ok(p),
        (None, None) => rrt(space, params.max_iterations, budget),
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::shortcut::{cumulative, point_at};
    use super::*;

    /// A 12 × 6 × 3 m box, start and goal 10 m apart at 1.5 m (also the grid's tests).
    pub(in crate::plan) fn problem(obstacles: Vec<Shape>) -> PlanProblem {
        PlanProblem {
            bounds_min: Vec3::new(-1.0, -1.0, -3.0),
            bounds_max: Vec3::new(11.0, 5.0, 0.0),
            obstacles,
            start: Vec3::new(0.0, 2.0, -1.5),
            goal: Vec3::new(10.0, 2.0, -1.5),
            hull_radius: 0.2236,
        }
    }

    #[test]
    fn straight_line_when_free() {
        let p = problem(vec![Shape::sphere(Vec3::new(5.0, -0.5, -1.5), 0.5)]);
        let path = plan(&p, &PlannerParams::default()).unwrap();
        assert_eq!(path.waypoints, vec![p.start, p.goal]);
        assert_eq!(path.iterations, 0);
        assert!((path.length_m - 10.0).abs() < 1e-4);
    }

    #[test]
    fn thin_wall_is_not_jumped() {
        // A 1 mm thick wall across the straight line, with a gap at one side.
        let wall = Shape::aabb(Vec3::new(5.0, -1.0, -3.0), Vec3::new(5.001, 4.0, 0.0));
        let p = problem(vec![wall]);
        let mut space = Space::new(&p, p.hull_radius + 0.05, 0.001);
        assert!(!space.segment_valid(&p.start, &p.goal));
        let path = plan(&p, &PlannerParams::default()).unwrap();
        assert!(path.waypoints.len() >= 3);
        // The path passes through the gap y in (4.0 + r, 5].
        assert!(path.waypoints.iter().any(|w| w.y > 4.0 + p.hull_radius));
    }

    #[test]
    fn free_prefix_stops_before_obstacle() {
        let p = problem(vec![Shape::aabb(Vec3::new(5.0, -1.0, -3.0), Vec3::new(6.0, 5.0, 0.0))]);
        let req = p.hull_radius + 0.05;
        let mut space = Space::new(&p, req, 0.001);
        let free = space.free_prefix(&p.start, &p.goal);
        // Head-on against a face: exact up to the tolerance.
        assert!((free - (5.0 - req)).abs() < 1e-3, "free = {free}");
    }

    #[test]
    fn grazing_sphere_at_limit_is_bounded() {
        // Segment tangent to the inflated sphere: terminates (bounded loop) and
        // never accepts a point inside the required clearance.
        let req = 0.2736;
        let s = Shape::sphere(Vec3::new(5.0, 2.0 + 0.5 + req, -1.5), 0.5);
        let p = problem(vec![s]);
        let mut space = Space::new(&p, req, 0.001);
        let free = space.free_prefix(&p.start, &p.goal);
        let q = p.start + Vec3::x() * free;
        assert!(s.signed_distance(&q) >= req - 1e-4);
        assert!(free < 10.0);
    }

    #[test]
    fn invalid_inputs_are_named() {
        let mut p = problem(vec![]);
        p.start.x = f32::NAN;
        let e = plan(&p, &PlannerParams::default()).unwrap_err();
        assert!(matches!(e, PlanError::InvalidInput(ref m) if m.contains("start")), "{e}");
        let p = problem(vec![]);
        let e = plan(&p, &PlannerParams { goal_bias: 2.0, ..Default::default() }).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let mut p = problem(vec![]);
        p.goal.z = 1.0;
        assert_eq!(plan(&p, &PlannerParams::default()), Err(PlanError::GoalOutOfBounds));
        let mut p = problem(vec![]);
        p.start.y = -2.0;
        assert_eq!(plan(&p, &PlannerParams::default()), Err(PlanError::StartOutOfBounds));
        let p = problem(vec![Shape::sphere(Vec3::new(10.0, 2.3, -1.5), 0.1)]);
        assert_eq!(plan(&p, &PlannerParams::default()), Err(PlanError::GoalInCollision));
    }

    #[test]
    fn too_many_waypoints_is_an_error() {
        // A slalom of walls needs more than 2 waypoints.
        let mut obs = Vec::new();
        for k in 0..4 {
            let x = 2.0 + 2.0 * k as f32;
            let (y0, y1) = if k % 2 == 0 { (-1.0, 3.5) } else { (0.5, 5.0) };
            obs.push(Shape::aabb(Vec3::new(x, y0, -3.0), Vec3::new(x + 0.2, y1, 0.0)));
        }
        let p = problem(obs);
        let ok = plan(&p, &PlannerParams::default()).unwrap();
        assert!(ok.waypoints.len() > 3);
        let e = plan(&p, &PlannerParams { max_waypoints: 3, ..Default::default() }).unwrap_err();
        assert_eq!(e, PlanError::TooManyWaypoints { n: ok.waypoints.len(), max: 3 });
        assert_eq!(e.exit_code(), 3);
    }

    #[test]
    fn point_at_walks_the_polyline() {
        let path = vec![Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 0.0)];
        let cum = cumulative(&path);
        assert_eq!(cum, vec![0.0, 1.0, 3.0]);
        let (s, p) = point_at(&path, &cum, 2.0);
        assert_eq!(s, 1);
        assert!((p - Vec3::new(1.0, 1.0, 0.0)).norm() < 1e-6);
        let (s, p) = point_at(&path, &cum, 3.0);
        assert_eq!(s, 1);
        assert!((p - path[2]).norm() < 1e-6);
    }
}
