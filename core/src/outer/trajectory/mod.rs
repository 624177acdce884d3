//! Trajectory generation (issue 35, stage in progress): from a polyline of waypoints and the
//! vehicle's limits, a jerk-limited, time-parameterised reference `p_d, ṗ_d, p̈_d` (and jerk)
//! that slows for corners, stays within the corner tolerance of the polyline, starts and ends
//! at rest, and whose clock waits for the vehicle. [`super::guidance`] flies missions on it
//! when `MIS_GUIDANCE` = 1 (the default, 0, still flies [`super::waypoint`]).
//!
//! ## Method
//! * **Geometry** (`geometry.rs`): the polyline's legs are kept straight and each corner is
//!   replaced by a symmetric quintic Bézier blend that leaves and joins the legs with zero
//!   curvature (curvature-continuous path), cuts the corner by at most
//!   [`TrajectoryParams::corner_tolerance`] and takes at most half of either leg. A turn
//!   sharper than 160°, a zero tolerance, or a blend slower than stopping makes a stop
//!   corner (speed 0 at the waypoint).
//! * **Speed limits**: on a leg, the largest speed whose horizontal component is at most the
//!   cruise speed and whose vertical component is at most the up/down limit; on a blend, also
//!   over every direction of the blend and `√(A/κ_max)` (lateral acceleration ≤ `A`).
//! * **Timing** (`profile.rs`): a 1-D jerk-limited motion `(s, ṡ, s̈)` along the arc length,
//!   advanced **online**, one bounded step at a time. Each step picks the largest speed target
//!   `u ≤ clock_scale · (limit here)` such that, after following the time-optimal
//!   jerk-limited velocity plan towards `u` for `dt` (integrated exactly, phase switches
//!   inside the step included), the motion can still brake (jerk- and acceleration-limited)
//!   to every upcoming speed limit before reaching it: the corners, the stop corners and the
//!   goal at rest. The largest safe `u` is found by bisection ([`BISECTION_ITERATIONS`]
//!   halvings); only limits within the current braking distance are looked at (at most all
//!   `2N − 3` pieces). This is the approach of PX4's `PositionSmoothing`/`VelocitySmoothing`
//!   (velocity set-point from the jerk-limited braking distance to the next waypoint) and of
//!   ArduPilot's `SCurve` (jerk-limited S-curve segments that brake for the corner speed),
//!   made into a safe-set rule evaluated every step as in on-line trajectory generation
//!   (Haschke, Kröger, Wahl, "On-line trajectory generation: basic concepts for instantaneous
//!   reactions to unforeseen events", IROS 2008; Berscheid, Kröger, "Jerk-limited real-time
//!   trajectory generation with arbitrary target states" (Ruckig), RSS 2021).
//!
//! Why online and 1-D along a blended path: the path is fixed by the planner (its clearance
//! is the corner tolerance), so only the timing remains and it is a scalar problem; each step
//! costs a bounded `O(N)` regardless of the path's length; the clock that waits is natural
//! (`clock_scale` scales the speed target, and the generator brakes jerk-limited when it
//! drops); and re-generation when the mission changes is "build a new trajectory and carry
//! on from the current state" rather than recomputing a global time-optimal schedule.
//!
//! ## A reference that never runs away
//! [`Trajectory::step`] takes `clock_scale ∈ [0, 1]`, which scales the allowed speed. The
//! guidance (`MIS_GUIDANCE` 1) passes [`clock_scale`]`(tracking error, bound)` — 1 while the
//! vehicle follows within half the bound, 0 at the bound — and 0 while the safety filter
//! holds the vehicle back. With 0 the reference brakes jerk-limited and stops; it never jumps.
//!
//! ## Guarantees (checked by `core/tests/trajectory_properties.rs`)
//! Starts at the first waypoint at rest; ends exactly at the last at rest ([`TrajectorySample::done`],
//! after snapping the last ≤ [`SNAP_DISTANCE`] when the motion is at rest); position and
//! velocity continuous; `ṡ ≤` the speed limit, `|s̈| ≤ A`, `|s⃛| ≤ J` along the path; lateral
//! acceleration `≤ A` on the blends; every point within the corner tolerance of the polyline.
//! `A` is the horizontal acceleration limit for a horizontal path, the smaller of the
//! horizontal and vertical limits otherwise; on a blend the tangential and lateral
//! accelerations are each bounded by `A` (their sum by `√2·A`).
//!
//! ## Capacity and cost
//! At most `N` waypoints (const generic, default [`DEFAULT_PATH_CAPACITY`]); a longer path is
//! rejected, never truncated. A step is `O(BISECTION_ITERATIONS · K)` with `K ≤ 2N` the limits
//! within the braking distance; construction is `O(N)`. Memory: one leg (32 bytes) and one
//! corner brief (20 bytes) per waypoint, plus the full corner being flown (its arc-length
//! table, rebuilt on entering the blend): `Trajectory<64>` is 3,328 bytes on the host
//! (`the_trajectory_fits_the_flight_controllers_ram`). The flight controller keeps one in its
//! guidance, re-built in place ([`Trajectory::rebuild`]) so that no copy passes the stack.
//!
//! ## Numerics
//! A braking at the acceleration limit is exactly tight, so the step's displacement and speed
//! change are added to `s` and `ṡ` with compensated (Kahan) sums, and the safety check
//! shortens each distance by a few `f32` roundings (at most ¼ of [`SNAP_DISTANCE`]).
//!
//! Owns [`TrajectoryParams`] and [`ParamError`] (child `params.rs`), [`Trajectory`],
//! [`TrajectorySample`], [`TrajectoryError`], [`clock_scale`], and the private children
//! `geometry.rs` (blends, speed limits) and `profile.rs` (the 1-D motion).
//! May import [`crate::fmath`], [`crate::frame`], [`crate::Vec3`] and [`super::waypoint`]
//! (capacity and path-error conventions); nothing else of the outer loop.

mod extend;
mod geometry;
mod params;
mod profile;

pub use params::{ParamError, TrajectoryParams};

use super::waypoint::{PathError, COORDINATE_LIMIT, DEFAULT_PATH_CAPACITY};
use crate::fmath::{maxf, minf, norm3};
use crate::frame::is_finite3;
use crate::Vec3;
use geometry::{AxisLimits, Corner, CornerBrief, Leg};
use profile::{brake_distance, follow_delta, velocity_plan, Limits, Motion};

/// Consecutive waypoints closer than this (m) are a repeated waypoint (a zero-length leg).
pub const MIN_LEG_LENGTH: f32 = 1.0e-3;

/// Largest accepted step, s.
pub const MAX_STEP_DT: f32 = 0.1;

/// Halvings of the bisection for the speed target in each step.
pub const BISECTION_ITERATIONS: usize = 12;

/// Distance (m) to a stop corner or the goal below which a motion at rest snaps onto it.
pub const SNAP_DISTANCE: f32 = 1.0e-3;

/// Speed (m/s) below which the motion counts as at rest for the snap.
pub const SNAP_SPEED: f32 = 1.0e-3;

/// Why a trajectory or a step was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrajectoryError {
    /// A parameter is out of its range or not finite (the field is named).
    Param(ParamError),
    /// The waypoints are empty, too many, non-finite or out of range (as for the waypoint follower).
    Path(PathError),
    /// Waypoint `index` repeats waypoint `index − 1` (closer than [`MIN_LEG_LENGTH`]): a
    /// zero-length leg has no direction.
    RepeatedWaypoint {
        /// Index of the repeating waypoint in the given slice.
        index: usize,
    },
    /// The step's `dt` is not in (0, [`MAX_STEP_DT`]] s.
    BadDt,
    /// The clock scale is NaN or infinite, or the speed cap is NaN.
    BadClockScale,
    /// [`Trajectory::new_moving`]: the start speed or acceleration is not finite or out of
    /// range, or the motion could not brake for the limits ahead.
    BadStartState,
}

impl From<ParamError> for TrajectoryError {
    fn from(e: ParamError) -> Self {
        TrajectoryError::Param(e)
    }
}

impl From<PathError> for TrajectoryError {
    fn from(e: PathError) -> Self {
        TrajectoryError::Path(e)
    }
}

/// The reference at one step, world NED, SI.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrajectorySample {
    /// Desired position `p_d`, m.
    pub position: Vec3,
    /// Desired velocity `ṗ_d`, m/s.
    pub velocity: Vec3,
    /// Desired acceleration `p̈_d`, m/s² (tangential `s̈·T` plus lateral `ṡ²·κN`).
    pub acceleration: Vec3,
    /// Jerk over the last step, `(p̈_d − p̈_d,prev)/dt`, m/s³.
    pub jerk: Vec3,
    /// Arc length flown from the first waypoint, m.
    pub s: f32,
    /// Speed along the path `ṡ`, m/s.
    pub speed: f32,
    /// Acceleration along the path `s̈`, m/s².
    pub path_acceleration: f32,
    /// Speed limit of the piece being flown (before the clock scale), m/s.
    pub speed_limit: f32,
    /// `true` once the goal is reached at rest (the reference then stays there).
    pub done: bool,
    /// Leg being flown (leg `k` goes from waypoint `k` to `k + 1`; a blend counts to the
    /// incoming leg up to its middle).
    pub segment: usize,
}

/// `clock_scale` for [`Trajectory::step`] from the tracking error (m) and its bound (m):
/// 1 up to half the bound, then linearly down to 0 at the bound and beyond. A non-finite
/// error or a bound that is not positive and finite gives 0 (wait).
pub fn clock_scale(tracking_error_m: f32, bound_m: f32) -> f32 {
    if !tracking_error_m.is_finite() || !bound_m.is_finite() || bound_m <= 0.0 {
        return 0.0;
    }
    let half = 0.5 * bound_m;
    let e = tracking_error_m.abs();
    if e <= half {
        1.0
    } else if e >= bound_m {
        0.0
    } else {
        (bound_m - e) / half
    }
}

/// Distance (m) by which [`Trajectory`]'s safety check shortens each distance it compares
/// with a braking distance: eight `f32` roundings (relative `ε`) of the arc lengths `a`, `b`
/// whose difference the distance is and of the braking distance `brake`, at most a quarter of
/// [`SNAP_DISTANCE`] (so a motion at rest that margin short of a stop still snaps onto it).
fn rounding_margin(a: f32, b: f32, brake: f32) -> f32 {
    minf(8.0 * f32::EPSILON * (a.abs() + b.abs() + brake), 0.25 * SNAP_DISTANCE)
}

/// Kahan compensations of the arc length and the speed (`true value ≈ stored − comp`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct Comp {
    s: f32,
    v: f32,
}

impl Comp {
    /// `m` advanced by `d` with compensated sums; the new motion and compensations.
    fn add(&self, m: &Motion, d: &profile::Delta, end_speed: f32) -> (Motion, Comp) {
        let ys = d.ds - self.s;
        let s = m.s + ys;
        let (v, cv) = if d.complete {
            (end_speed, 0.0)
        } else {
            let yv = d.dv - self.v;
            let v = m.v + yv;
            (v, (v - m.v) - yv)
        };
        (Motion { s, v, a: d.a }, Comp { s: (s - m.s) - ys, v: cv })
    }
}

/// An online jerk-limited trajectory along a polyline of at most `N` waypoints.
#[derive(Clone, Debug)]
pub struct Trajectory<const N: usize = DEFAULT_PATH_CAPACITY> {
    params: TrajectoryParams,
    lim: Limits,
    legs: heapless::Vec<Leg, N>,
    /// `corners[k]` joins leg `k` and leg `k + 1` (at waypoint `k + 1`).
    corners: heapless::Vec<CornerBrief, N>,
    /// The corner being flown, `(k, corners[k] in full)`, rebuilt on entering its blend.
    flown: Option<(usize, Corner)>,
    goal: Vec3,
    /// Piece being flown: `2k` = straight part of leg `k`, `2k + 1` = corner `k`.
    piece: usize,
    /// Arc length of the start of `piece`, m.
    piece_start: f32,
    /// The motion, `s` local to `piece`.
    motion: Motion,
    /// Kahan compensation of `motion.s` and `motion.v`: the low-order parts of the step
    /// changes lost to rounding, so that neither drifts from the integrated plans (a drift of
    /// the speed over a long braking at the acceleration limit would leave no room to brake).
    comp: Comp,
    total: f32,
    done: bool,
    last_acceleration: Vec3,
}

/// The axis speed limits of `params`.
fn axis_limits(params: &TrajectoryParams) -> AxisLimits {
    AxisLimits { horizontal: params.cruise_speed, up: params.speed_up, down: params.speed_down }
}

impl<const N: usize> Trajectory<N> {
    /// A trajectory from `waypoints[0]` (normally the current position) through the others to
    /// the last, starting at rest. Errors on invalid parameters, an empty slice, more than `N`
    /// waypoints, a NaN/Inf coordinate, a coordinate beyond ±[`COORDINATE_LIMIT`] or a
    /// repeated consecutive waypoint. One waypoint is a trajectory that is done at once.
    pub fn new(params: TrajectoryParams, waypoints: &[Vec3]) -> Result<Self, TrajectoryError> {
        let mut t = Self::idle();
        t.rebuild(params, waypoints)?;
        Ok(t)
    }

    /// An empty trajectory (no legs, done at the origin) with the default parameters: the
    /// storage [`rebuild`](Self::rebuild) fills.
    pub fn idle() -> Self {
        Trajectory {
            params: TrajectoryParams::default(),
            lim: Limits { accel: 1.0, jerk: 1.0 },
            legs: heapless::Vec::new(),
            corners: heapless::Vec::new(),
            flown: None,
            goal: Vec3::zeros(),
            piece: 0,
            piece_start: 0.0,
            motion: Motion::default(),
            comp: Comp::default(),
            total: 0.0,
            done: true,
            last_acceleration: Vec3::zeros(),
        }
    }

    /// [`new`](Self::new) in place: this trajectory becomes the one through `waypoints`
    /// (nothing of the old one is kept). On an error it is left [`idle`](Self::idle).
    pub fn rebuild(&mut self, params: TrajectoryParams, waypoints: &[Vec3]) -> Result<(), TrajectoryError> {
        self.clear();
        params.validate()?;
        if waypoints.is_empty() {
            return Err(PathError::Empty.into());
        }
        if waypoints.len() > N {
            return Err(PathError::TooMany { capacity: N }.into());
        }
        if let Some(index) = waypoints.iter().position(|w| !is_finite3(w)) {
            return Err(PathError::NonFinite { index }.into());
        }
        if let Some(index) = waypoints.iter().position(|w| w.amax() > COORDINATE_LIMIT) {
            return Err(PathError::OutOfRange { index }.into());
        }
        let axes = axis_limits(&params);
        let mut horizontal = true;
        for (i, pair) in waypoints.windows(2).enumerate() {
            let [a, b] = pair else {
                continue;
            };
            let d = b - a;
            let length = norm3(&d);
            if length < MIN_LEG_LENGTH {
                self.clear();
                return Err(TrajectoryError::RepeatedWaypoint { index: i + 1 });
            }
            let dir = d / length;
            horizontal &= dir.z.abs() <= 1e-6;
            // Cannot fail: at most N − 1 legs.
            let _ = self.legs.push(Leg { from: *a, dir, length, limit: axes.along(&dir) });
        }
        let accel = if horizontal {
            params.accel_horizontal
        } else {
            minf(params.accel_horizontal, params.accel_vertical)
        };
        self.params = params;
        self.lim = Limits { accel, jerk: params.jerk };
        for k in 0..self.legs.len().saturating_sub(1) {
            let brief = self.corner(k).map_or(CornerBrief::default(), |c| c.brief());
            // Cannot fail: at most N − 2 corners.
            let _ = self.corners.push(brief);
        }
        self.goal = waypoints.last().copied().unwrap_or_else(Vec3::zeros);
        self.done = waypoints.len() == 1;
        self.total = (0..self.piece_count()).map(|p| self.piece_len(p)).sum();
        Ok(())
    }

    /// Back to [`idle`](Self::idle), keeping the storage.
    fn clear(&mut self) {
        self.params = TrajectoryParams::default();
        self.lim = Limits { accel: 1.0, jerk: 1.0 };
        self.legs.clear();
        self.corners.clear();
        self.flown = None;
        self.goal = Vec3::zeros();
        self.piece = 0;
        self.piece_start = 0.0;
        self.motion = Motion::default();
        self.comp = Comp::default();
        self.total = 0.0;
        self.done = true;
        self.last_acceleration = Vec3::zeros();
    }

    /// Corner `k` in full (between legs `k` and `k + 1`), built from the legs and the
    /// parameters: the same inputs at every call, so the same corner.
    fn corner(&self, k: usize) -> Option<Corner> {
        let (l0, l1) = (self.legs.get(k)?, self.legs.get(k + 1)?);
        let axes = axis_limits(&self.params);
        Some(Corner::new(
            l1.from,
            (l0, l1),
            self.params.corner_tolerance,
            (self.lim.accel, self.lim.jerk),
            &axes,
        ))
    }

    /// The corner of the current piece in full when it is a blend (cached in `flown`).
    fn sync_flown(&mut self) {
        let k = self.piece / 2;
        let wanted = self.piece % 2 == 1;
        if wanted && self.flown.as_ref().is_none_or(|(j, _)| *j != k) {
            self.flown = self.corner(k).map(|c| (k, c));
        } else if !wanted {
            self.flown = None;
        }
    }

    /// The full corner `k` from the cache when it is the one flown, else rebuilt.
    fn flown_corner(&self, k: usize) -> Option<Corner> {
        match &self.flown {
            Some((j, c)) if *j == k => Some(*c),
            _ => self.corner(k),
        }
    }

    /// A trajectory that starts **moving** along its first leg at `speed` (m/s) with the
    /// tangential acceleration `accel` (m/s²): re-generation when the mission changes in
    /// flight. `waypoints[0]` is the current reference position and the first leg must point
    /// along the current reference velocity (the caller's to ensure: the velocity is taken as
    /// `speed` along that leg). Errors as [`new`](Self::new), and
    /// [`TrajectoryError::BadStartState`] when `speed` or `accel` is not finite, `speed` is
    /// negative or above the first leg's speed limit, `|accel|` exceeds the acceleration limit,
    /// the acceleration cannot be ramped out before the speed reaches 0 or the leg's limit
    /// (`speed ∓ accel²/2J`), the path is a single waypoint while moving, or the motion cannot brake for the limits
    /// ahead (then brake the old reference with `clock_scale` 0 first, and start from rest).
    pub fn new_moving(
        params: TrajectoryParams,
        waypoints: &[Vec3],
        speed: f32,
        accel: f32,
    ) -> Result<Self, TrajectoryError> {
        let mut t = Self::idle();
        t.rebuild_moving(params, waypoints, speed, accel)?;
        Ok(t)
    }

    /// [`new_moving`](Self::new_moving) in place. On an error it is left
    /// [`idle`](Self::idle).
    pub fn rebuild_moving(
        &mut self,
        params: TrajectoryParams,
        waypoints: &[Vec3],
        speed: f32,
        accel: f32,
    ) -> Result<(), TrajectoryError> {
        self.rebuild(params, waypoints)?;
        let t = self;
        let bad = !speed.is_finite()
            || !accel.is_finite()
            || speed < 0.0
            || speed > t.piece_limit(0)
            || accel.abs() > t.lim.accel
            // An acceleration the jerk limit cannot ramp out before the speed reaches 0 or
            // the first leg's limit.
            || (accel < 0.0 && speed < accel * accel / (2.0 * t.lim.jerk))
            || (accel > 0.0 && speed + accel * accel / (2.0 * t.lim.jerk) > t.piece_limit(0))
            || (t.legs.is_empty() && (speed > 0.0 || accel != 0.0));
        let m = Motion { s: 0.0, v: speed, a: accel };
        if bad || (!t.legs.is_empty() && !t.safe(&m)) {
            t.clear();
            return Err(TrajectoryError::BadStartState);
        }
        t.motion = m;
        t.last_acceleration = t.legs.first().map_or(Vec3::zeros(), |l| l.dir * accel);
        Ok(())
    }

    /// Capacity in waypoints (`N`).
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Parameters in use.
    pub fn params(&self) -> &TrajectoryParams {
        &self.params
    }

    /// The goal (last waypoint), NED m.
    pub fn goal(&self) -> Vec3 {
        self.goal
    }

    /// Length of the flown curve (legs shortened by the blends, plus the blends), m.
    pub fn total_length(&self) -> f32 {
        self.total
    }

    /// Tangential acceleration bound `A` used along this path, m/s².
    pub fn accel_limit(&self) -> f32 {
        self.lim.accel
    }

    /// `true` once the goal has been reached at rest.
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// The unit direction of travel at the current point: the tangent of the piece being
    /// flown, the outgoing leg's on a stop corner (at rest, about to turn onto it); zero once
    /// done. Defined at rest too (the yaw along the path turns towards it before moving).
    pub fn travel_direction(&self) -> Vec3 {
        if self.done {
            return Vec3::zeros();
        }
        let k = self.piece / 2;
        let leg_dir = |i: usize| self.legs.get(i).map_or(Vec3::zeros(), |l| l.dir);
        if self.piece.is_multiple_of(2) {
            return leg_dir(k);
        }
        match self.corners.get(k) {
            Some(c) if !c.stop => self.flown_corner(k).map_or(leg_dir(k + 1), |c| c.eval(self.motion.s).1),
            _ => leg_dir(k + 1),
        }
    }

    fn piece_count(&self) -> usize {
        (2 * self.legs.len()).saturating_sub(1)
    }

    /// Half-length of corner `k`'s blend (0 for none, also for `k` out of range).
    fn corner_half(&self, k: Option<usize>) -> f32 {
        k.and_then(|k| self.corners.get(k)).map_or(0.0, |c| c.half)
    }

    fn piece_len(&self, p: usize) -> f32 {
        let k = p / 2;
        if p % 2 == 1 {
            return self.corners.get(k).map_or(0.0, |c| c.arc);
        }
        let Some(leg) = self.legs.get(k) else {
            return 0.0;
        };
        let before = self.corner_half(k.checked_sub(1));
        let after = self.corner_half(Some(k));
        maxf(leg.length - before - after, 0.0)
    }

    fn piece_limit(&self, p: usize) -> f32 {
        let k = p / 2;
        if p % 2 == 1 {
            self.corners.get(k).map_or(0.0, |c| c.limit)
        } else {
            self.legs.get(k).map_or(0.0, |l| l.limit)
        }
    }

    fn piece_is_stop(&self, p: usize) -> bool {
        p % 2 == 1 && self.corners.get(p / 2).is_some_and(|c| c.stop)
    }

    /// `true` when the end of `piece` is a point where the motion must be at rest (a stop
    /// corner follows, or it is the last piece).
    fn ends_at_rest(&self, p: usize) -> bool {
        p + 1 >= self.piece_count() || self.piece_is_stop(p + 1)
    }

    /// Can the motion `m` (`s` local to the current piece) still brake to every upcoming
    /// speed limit and to rest at the goal? Looks only as far as its braking distance to rest.
    /// Each distance is shortened by [`rounding_margin`] for the rounding of `f32` arc lengths.
    fn safe(&self, m: &Motion) -> bool {
        let horizon = brake_distance(m.v, m.a, 0.0, self.lim);
        let count = self.piece_count();
        let mut start = 0.0f32; // start of piece p, local to the current piece
        for p in self.piece..count {
            if p > self.piece {
                let d = start - m.s;
                if d > horizon {
                    return true;
                }
                let brake = brake_distance(m.v, m.a, self.piece_limit(p), self.lim);
                if brake > maxf(d - rounding_margin(start, m.s, brake), 0.0) {
                    return false;
                }
                if self.piece_is_stop(p) {
                    return true;
                }
            }
            start += self.piece_len(p);
        }
        horizon <= maxf(start - m.s - rounding_margin(start, m.s, horizon), 0.0)
    }

    /// Advance the reference by `dt` seconds (in (0, [`MAX_STEP_DT`]]) with the allowed speed
    /// scaled by `clock_scale` (clamped into [0, 1]; 0 = brake and wait). Returns the new
    /// reference. Bounded time: `O(BISECTION_ITERATIONS · N)`.
    pub fn step(&mut self, dt: f32, clock_scale: f32) -> Result<TrajectorySample, TrajectoryError> {
        self.step_capped(dt, clock_scale, f32::INFINITY)
    }

    /// [`Trajectory::step`] with the speed target also at most `speed_cap` m/s (≥ 0; `+∞`: no
    /// cap), an absolute bound rather than a scale of the path's limit: the speed governor's
    /// limit along the motion (`crate::governor`), which must not be multiplied by a corner's
    /// lower limit (that made a 5 m/s mission slower than a 3 m/s one through the same
    /// corners). A NaN cap is refused like a NaN scale; a negative one brakes like 0.
    pub fn step_capped(
        &mut self,
        dt: f32,
        clock_scale: f32,
        speed_cap: f32,
    ) -> Result<TrajectorySample, TrajectoryError> {
        if !(dt > 0.0 && dt <= MAX_STEP_DT) {
            return Err(TrajectoryError::BadDt);
        }
        if !clock_scale.is_finite() || speed_cap.is_nan() {
            return Err(TrajectoryError::BadClockScale);
        }
        if self.done {
            return Ok(self.finish(dt));
        }
        if self.arrive(dt) {
            if self.done {
                return Ok(self.finish(dt));
            }
            // At rest on a stop corner: this step reports the corner at rest, the next one
            // leaves it (so the acceleration never jumps by more than J·dt).
            return Ok(self.sample(dt));
        }
        let scale = clock_scale.clamp(0.0, 1.0);
        let mut m = self.motion;
        let mut comp = self.comp;
        // Rounding can leave a braking state slightly inconsistent: a deceleration that,
        // ramped to zero at the jerk limit, would take the speed below 0 (by ~1e-6 m/s). Lift
        // the speed onto the consistent value so that no plan reverses.
        let floor = m.a * m.a / (2.0 * self.lim.jerk);
        if m.a < 0.0 && m.v < floor {
            m.v = floor;
            comp.v = 0.0;
        }
        let target = minf(scale * self.piece_limit(self.piece), maxf(speed_cap, 0.0));
        let next = |u: f32| {
            let plan = velocity_plan(m.v, m.a, u, self.lim);
            comp.add(&m, &follow_delta(m.v, m.a, &plan, dt), plan.end_speed)
        };
        let (mut n, mut c) = next(target);
        if !self.safe(&n) {
            (n, c) = next(0.0);
            if self.safe(&n) {
                let (mut lo, mut hi) = (0.0f32, target);
                for _ in 0..BISECTION_ITERATIONS {
                    let mid = 0.5 * (lo + hi);
                    let cand = next(mid);
                    if self.safe(&cand.0) {
                        lo = mid;
                        (n, c) = cand;
                    } else {
                        hi = mid;
                    }
                }
            }
        }
        if n.v < 0.0 {
            // Rounding at the end of a stop (the plans never reverse): rest, not backwards.
            n.v = 0.0;
            n.a = maxf(n.a, 0.0);
            c.v = 0.0;
        }
        self.comp = c;
        self.advance(n);
        Ok(self.sample(dt))
    }

    /// At rest within [`SNAP_DISTANCE`] of a stop corner or the goal (speed ≤ [`SNAP_SPEED`],
    /// acceleration ≤ `J·dt/2`): snap onto it — done at the goal, onto the next leg at rest
    /// after a stop corner. Returns `true` when it snapped.
    fn arrive(&mut self, dt: f32) -> bool {
        let count = self.piece_count();
        let n = self.motion;
        if !self.ends_at_rest(self.piece) {
            return false;
        }
        let len = self.piece_len(self.piece);
        let at_rest = n.v.abs() <= SNAP_SPEED && n.a.abs() <= 0.5 * self.lim.jerk * dt;
        if !(len - n.s <= SNAP_DISTANCE && at_rest) {
            return false;
        }
        if self.piece + 1 >= count {
            self.done = true;
            self.motion = Motion { s: len, v: 0.0, a: 0.0 };
            self.comp = Comp::default();
        } else {
            // Past the stop corner (zero length), onto the next leg, at rest.
            self.piece_start += len;
            self.piece += 2;
            self.motion = Motion::default();
            self.comp = Comp::default();
        }
        true
    }

    /// Move the motion `n` (local to the current piece) onto the piece it lies in, never past
    /// a stop corner or the goal (where [`arrive`](Self::arrive) takes over).
    fn advance(&mut self, mut n: Motion) {
        for _ in 0..self.piece_count() {
            let len = self.piece_len(self.piece);
            if self.ends_at_rest(self.piece) {
                n.s = minf(n.s, len);
                break;
            }
            if n.s < len {
                break;
            }
            n.s -= len;
            self.piece_start += len;
            self.piece += 1;
        }
        self.motion = n;
        self.sync_flown();
    }

    /// The reference for the current motion.
    fn sample(&mut self, dt: f32) -> TrajectorySample {
        let m = self.motion;
        let k = self.piece / 2;
        self.sync_flown();
        let (position, tangent, curvature, segment) = if self.piece % 2 == 1 {
            match self.flown_corner(k) {
                Some(c) => {
                    let (p, t, kn) = c.eval(m.s);
                    (p, t, kn, if m.s < 0.5 * c.arc { k } else { k + 1 })
                }
                None => (self.goal, Vec3::zeros(), Vec3::zeros(), k),
            }
        } else {
            match self.legs.get(k) {
                Some(l) => {
                    let start = l.from + l.dir * self.corner_half(k.checked_sub(1));
                    (start + l.dir * m.s, l.dir, Vec3::zeros(), k)
                }
                None => (self.goal, Vec3::zeros(), Vec3::zeros(), k),
            }
        };
        let acceleration = tangent * m.a + curvature * (m.v * m.v);
        let jerk = (acceleration - self.last_acceleration) / dt;
        self.last_acceleration = acceleration;
        TrajectorySample {
            position,
            velocity: tangent * m.v,
            acceleration,
            jerk,
            s: self.piece_start + m.s,
            speed: m.v,
            path_acceleration: m.a,
            speed_limit: self.piece_limit(self.piece),
            done: false,
            segment,
        }
    }

    /// The reference once done: the goal at rest.
    fn finish(&mut self, dt: f32) -> TrajectorySample {
        let jerk = -self.last_acceleration / dt;
        self.last_acceleration = Vec3::zeros();
        TrajectorySample {
            position: self.goal,
            velocity: Vec3::zeros(),
            acceleration: Vec3::zeros(),
            jerk,
            s: self.total,
            speed: 0.0,
            path_acceleration: 0.0,
            speed_limit: 0.0,
            done: true,
            segment: self.legs.len().saturating_sub(1),
        }
    }
}

#[cfg(test)]
mod tests;
