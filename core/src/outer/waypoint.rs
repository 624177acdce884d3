//! Waypoint follower: a fixed-capacity piecewise-linear path flown at constant
//! cruise speed, producing the desired position, velocity and acceleration
//! `p_d(t)`, `ṗ_d(t)`, `p̈_d(t)` (world NED) of the paper's eq. 2.
//!
//! ## The reference
//! The path is the polyline `o → w₀ → w₁ → … → w_{n−1}`, where `o` is the
//! *origin* given to [`WaypointFollower::start`] (normally the current hold
//! point; when it coincides with `w₀` the first leg has zero length and takes
//! no time). Segment `k` is the leg that **ends** at waypoint `k`.
//!
//! * **Default (`corner_radius = 0`)**: exactly the paper's constant-speed,
//!   piecewise-linear reference. Arc length `s = V·(t − t₀)`; `p_d` is the
//!   point at arc length `s`, `ṗ_d = V·(unit direction of the segment)`,
//!   `p̈_d = 0`. The velocity steps at each corner (no smoothing): the
//!   resulting tracking transient is what the safety filter must make safe.
//! * **Optional smoothing (`corner_radius = w > 0`, m)**: the reference is the
//!   piecewise-linear one averaged over a moving arc-length window of width
//!   `2w` (a box filter). Position, velocity and acceleration are exact and
//!   mutually consistent: `ṗ_d = V·(p(s+w) − p(s−w))/(2w)`,
//!   `p̈_d = V²·(d(s+w) − d(s−w))/(2w)` with `d` the unit direction (zero
//!   before the origin and after the goal). Velocity is continuous, the
//!   acceleration is bounded by `V²/w`, the start and stop ramp over `2w/V`
//!   seconds and corners are cut by a fraction of `w`.
//! * **Arrival**: once the goal is reached the reference is the goal with zero
//!   velocity and acceleration (hover at the goal) and [`Progress::done`] is set.
//!
//! ## Capacity
//! At most `N` waypoints (const generic, default [`DEFAULT_PATH_CAPACITY`] = 64).
//! A longer path is **rejected** with [`PathError::TooMany`] — never truncated;
//! NaN/Inf coordinates and coordinates beyond ±[`COORDINATE_LIMIT`] are rejected too.
//! Every query is O(N).

use crate::fmath::{maxf, minf, norm3};
use crate::frame::is_finite3;
use crate::param_decl::{field, Has, Param};
use crate::Vec3;

/// Default maximum number of waypoints in a path.
pub const DEFAULT_PATH_CAPACITY: usize = 64;

/// Largest accepted waypoint/origin coordinate magnitude, m. Larger values are
/// rejected ([`PathError::OutOfRange`]) so that lengths and times stay finite.
pub const COORDINATE_LIMIT: f32 = 1.0e5;

/// Largest accepted cruise speed (m/s) and corner radius (m).
pub const PARAM_LIMIT: f32 = 100.0;

/// Why a path or a parameter set was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PathError {
    /// The path has no waypoint.
    Empty,
    /// The path has more waypoints than the capacity (given).
    TooMany {
        /// Capacity of the follower (waypoints).
        capacity: usize,
    },
    /// Waypoint `index` has a NaN or infinite coordinate.
    NonFinite {
        /// Index of the offending waypoint in the given slice.
        index: usize,
    },
    /// Waypoint `index` has a coordinate beyond ±[`COORDINATE_LIMIT`].
    OutOfRange {
        /// Index of the offending waypoint in the given slice.
        index: usize,
    },
    /// Cruise speed not in (0, [`PARAM_LIMIT`]] m/s, or corner radius not in [0, [`PARAM_LIMIT`]] m.
    BadParams,
    /// The origin given to [`WaypointFollower::start`] is not finite or beyond ±[`COORDINATE_LIMIT`].
    BadOrigin,
    /// [`WaypointFollower::start`] was called with no path set.
    NoPath,
}

/// Parameters of the waypoint follower.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WaypointParams {
    /// Constant cruise speed along the path, m/s. Default 0.25 (paper, office experiment).
    pub cruise_speed: f32,
    /// Half-width of the corner-smoothing window, m (arc length). Default 0 = no
    /// smoothing: the paper's exact piecewise-linear reference.
    pub corner_radius: f32,
}

impl Default for WaypointParams {
    fn default() -> Self {
        WaypointParams { cruise_speed: 0.25, corner_radius: 0.0 }
    }
}

impl WaypointParams {
    /// The path speed (`crate::params`).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 1] {
        [
            Param::new("WP_SPEED", "Mission", "m/s", (0.001, PARAM_LIMIT), 2, field!(cruise_speed),
                "Reference speed along the path").key("speed"),
        ]
    }
}

impl WaypointParams {
    /// Check the parameters (speed in (0, 100] m/s, radius in [0, 100] m).
    pub fn validate(&self) -> Result<(), PathError> {
        let ok = self.cruise_speed > 0.0
            && self.cruise_speed <= PARAM_LIMIT
            && self.corner_radius >= 0.0
            && self.corner_radius <= PARAM_LIMIT;
        if ok {
            Ok(())
        } else {
            Err(PathError::BadParams)
        }
    }
}

/// Desired state at one instant, world NED.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathSample {
    /// Desired position `p_d`, m.
    pub position: Vec3,
    /// Desired velocity `ṗ_d`, m/s.
    pub velocity: Vec3,
    /// Desired acceleration `p̈_d`, m/s² (zero unless corner smoothing is on).
    pub acceleration: Vec3,
    /// Progress along the path.
    pub progress: Progress,
}

/// Progress along the path.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Progress {
    /// Segment being flown = index of the waypoint it ends at (segment 0 is origin → w₀).
    /// With smoothing, the segment containing the window centre.
    pub segment: u16,
    /// Fraction of that segment already flown, 0..1.
    pub fraction: f32,
    /// `true` once the goal has been reached (the reference hovers at the goal).
    pub done: bool,
}

fn in_range(w: &Vec3) -> bool {
    w.amax() <= COORDINATE_LIMIT
}

/// Constant-speed follower of a path of at most `N` waypoints (default 64).
#[derive(Clone, Debug)]
pub struct WaypointFollower<const N: usize = DEFAULT_PATH_CAPACITY> {
    params: WaypointParams,
    points: heapless::Vec<Vec3, N>,
    /// Arc length from the origin to waypoint k, m (valid after `start`).
    cum: heapless::Vec<f32, N>,
    origin: Vec3,
    started: bool,
}

impl<const N: usize> WaypointFollower<N> {
    /// A follower with no path. Errors when the parameters are invalid.
    pub fn new(params: WaypointParams) -> Result<Self, PathError> {
        params.validate()?;
        Ok(WaypointFollower {
            params,
            points: heapless::Vec::new(),
            cum: heapless::Vec::new(),
            origin: Vec3::zeros(),
            started: false,
        })
    }

    /// Capacity in waypoints (`N`).
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Parameters in use.
    pub fn params(&self) -> &WaypointParams {
        &self.params
    }

    /// Change the cruise speed (m/s, in (0, [`PARAM_LIMIT`]]; else [`PathError::BadParams`] and
    /// the speed unchanged). A path being flown keeps its timing: the new speed applies from
    /// the next [`start`](Self::start) (a mission item's DO_CHANGE_SPEED at a segment boundary).
    pub fn set_cruise_speed(&mut self, speed: f32) -> Result<(), PathError> {
        let params = WaypointParams { cruise_speed: speed, ..self.params };
        params.validate()?;
        self.params = params;
        Ok(())
    }

    /// Replace the path (waypoints NED, m). Errors — leaving the previous path
    /// untouched — on an empty slice, more than `N` points, or a non-finite
    /// coordinate. Stops any path being flown ([`start`](Self::start) again).
    /// Repeated consecutive points are allowed (zero-length segments take no time).
    pub fn set_path(&mut self, waypoints: &[Vec3]) -> Result<(), PathError> {
        if waypoints.is_empty() {
            return Err(PathError::Empty);
        }
        if waypoints.len() > N {
            return Err(PathError::TooMany { capacity: N });
        }
        if let Some(index) = waypoints.iter().position(|w| !is_finite3(w)) {
            return Err(PathError::NonFinite { index });
        }
        if let Some(index) = waypoints.iter().position(|w| !in_range(w)) {
            return Err(PathError::OutOfRange { index });
        }
        self.points.clear();
        self.cum.clear();
        for w in waypoints {
            // Cannot fail: the length was checked above.
            let _ = self.points.push(*w);
        }
        self.started = false;
        Ok(())
    }

    /// The stored waypoints (NED, m), in order.
    pub fn waypoints(&self) -> &[Vec3] {
        &self.points
    }

    /// Drop the stored path (MAVLink MISSION_CLEAR_ALL): no waypoint is left, so a later
    /// [`start`](Self::start) fails with [`PathError::NoPath`] until a new path is set.
    pub fn clear(&mut self) {
        self.points.clear();
        self.cum.clear();
        self.started = false;
    }

    /// Number of waypoints stored.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// `true` when no path is stored.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The goal (last waypoint), if a path is stored.
    pub fn goal(&self) -> Option<Vec3> {
        self.points.last().copied()
    }

    /// `true` once [`start`](Self::start) succeeded for the stored path.
    pub fn is_started(&self) -> bool {
        self.started
    }

    /// Begin flying the stored path from `origin` (NED, m; normally the current
    /// hold point). Time in [`sample`](Self::sample) is measured from this call.
    pub fn start(&mut self, origin: Vec3) -> Result<(), PathError> {
        if self.points.is_empty() {
            return Err(PathError::NoPath);
        }
        if !is_finite3(&origin) || !in_range(&origin) {
            return Err(PathError::BadOrigin);
        }
        self.origin = origin;
        self.cum.clear();
        let mut acc = 0.0f32;
        let mut prev = origin;
        for w in self.points.iter() {
            acc += norm3(&(w - prev));
            prev = *w;
            let _ = self.cum.push(acc);
        }
        self.started = true;
        Ok(())
    }

    /// Total path length from the origin to the goal, m (0 before `start`).
    pub fn total_length(&self) -> f32 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// Time needed to fly the whole path, s (includes the smoothing ramps).
    pub fn duration(&self) -> f32 {
        (self.total_length() + 2.0 * self.params.corner_radius) / self.params.cruise_speed
    }

    /// Vertex `k` of the polyline: 0 = origin, k ≥ 1 = waypoint k−1.
    fn vertex(&self, k: usize) -> Vec3 {
        if k == 0 {
            self.origin
        } else {
            self.points.get(k - 1).copied().unwrap_or(self.origin)
        }
    }

    /// Arc length of vertex `k` (0 for the origin).
    fn vertex_s(&self, k: usize) -> f32 {
        if k == 0 {
            0.0
        } else {
            self.cum.get(k - 1).copied().unwrap_or(0.0)
        }
    }

    /// Point, unit direction and (segment, fraction) at arc length `s`. Before the
    /// origin and after the goal the direction is zero.
    fn at(&self, s: f32) -> (Vec3, Vec3, u16, f32) {
        let n = self.cum.len();
        if s < 0.0 || n == 0 {
            return (self.origin, Vec3::zeros(), 0, 0.0);
        }
        for k in 0..n {
            let s1 = self.cum[k];
            if s < s1 {
                let s0 = self.vertex_s(k);
                let a = self.vertex(k);
                let b = self.vertex(k + 1);
                let len = s1 - s0;
                // len > 0 here because s0 ≤ s < s1.
                let f = ((s - s0) / len).clamp(0.0, 1.0);
                let dir = (b - a) / len;
                return (a + (b - a) * f, dir, k as u16, f);
            }
        }
        (self.vertex(n), Vec3::zeros(), (n - 1) as u16, 1.0)
    }

    /// ∫ p(σ) dσ over [s_a, s_b] (s_a ≤ s_b) of the polyline extended by the origin
    /// before 0 and by the goal after the end. Exact (piecewise linear). O(N).
    fn integral(&self, s_a: f32, s_b: f32) -> Vec3 {
        let n = self.cum.len();
        let total = self.total_length();
        let mut acc = Vec3::zeros();
        if s_a < 0.0 {
            acc += self.origin * (minf(s_b, 0.0) - s_a);
        }
        if s_b > total {
            acc += self.vertex(n) * (s_b - maxf(s_a, total));
        }
        for k in 0..n {
            let s0 = self.vertex_s(k);
            let s1 = self.cum[k];
            let lo = maxf(s_a, s0);
            let hi = minf(s_b, s1);
            if hi > lo {
                let (pa, _, _, _) = self.at(lo);
                let (pb, _, _, _) = self.at(hi);
                // at(hi) with hi == s1 returns the next segment's start, which is the same point.
                acc += (pa + pb) * (0.5 * (hi - lo));
            }
        }
        acc
    }

    /// Desired state at `t_s` seconds after [`start`](Self::start). Negative or
    /// non-finite times give the start of the path; before `start` (or with no
    /// path) the sample is the origin at rest and `done`.
    pub fn sample(&self, t_s: f32) -> PathSample {
        if !self.started {
            return PathSample {
                position: self.origin,
                velocity: Vec3::zeros(),
                acceleration: Vec3::zeros(),
                progress: Progress { segment: 0, fraction: 0.0, done: true },
            };
        }
        let t = if t_s.is_finite() { maxf(t_s, 0.0) } else { 0.0 };
        let v = self.params.cruise_speed;
        let w = self.params.corner_radius;
        let total = self.total_length();
        let n = self.cum.len();
        let goal = self.vertex(n);
        // Arc length of the window centre (the start is delayed by w so the
        // smoothed reference starts at the origin at rest).
        let s = v * t - w;
        if s - w >= total {
            return PathSample {
                position: goal,
                velocity: Vec3::zeros(),
                acceleration: Vec3::zeros(),
                progress: Progress { segment: (n - 1) as u16, fraction: 1.0, done: true },
            };
        }
        let (p, dir, segment, fraction) = self.at(s);
        let progress = Progress { segment, fraction, done: false };
        if w <= 0.0 {
            return PathSample { position: p, velocity: dir * v, acceleration: Vec3::zeros(), progress };
        }
        let (p_hi, d_hi, _, _) = self.at(s + w);
        let (p_lo, d_lo, _, _) = self.at(s - w);
        let inv = 1.0 / (2.0 * w);
        PathSample {
            position: self.integral(s - w, s + w) * inv,
            velocity: (p_hi - p_lo) * (v * inv),
            acceleration: (d_hi - d_lo) * (v * v * inv),
            progress,
        }
    }
}

/// The property tests' `f32` strategy (shared with `core/tests`, `tests/tests`).
#[cfg(test)]
#[path = "../../tests/support/wild.rs"]
mod wild;

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).norm() <= tol
    }

    fn follower(speed: f32, radius: f32) -> WaypointFollower<8> {
        WaypointFollower::new(WaypointParams { cruise_speed: speed, corner_radius: radius }).unwrap()
    }

    /// A mission's DO_CHANGE_SPEED: the new speed times the next start; out of range refused,
    /// the speed unchanged.
    #[test]
    fn cruise_speed_changes_apply_from_the_next_start() {
        let mut f = follower(1.0, 0.0);
        f.set_path(&[Vec3::new(2.0, 0.0, 0.0)]).unwrap();
        f.start(Vec3::zeros()).unwrap();
        assert!((f.duration() - 2.0).abs() < 1e-6);
        f.set_cruise_speed(0.5).unwrap();
        f.start(Vec3::zeros()).unwrap();
        assert!((f.duration() - 4.0).abs() < 1e-6);
        for bad in [0.0, -1.0, f32::NAN, PARAM_LIMIT * 2.0] {
            assert_eq!(f.set_cruise_speed(bad), Err(PathError::BadParams));
        }
        assert_eq!(f.params().cruise_speed, 0.5);
    }

    /// Three segments of lengths 1, 2 and 0.5 m (the second one diagonal in 3-D
    /// so that its length is not axis-aligned).
    fn three_segment_path() -> [Vec3; 4] {
        [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(1.0 + 1.2, 1.6, -1.0), // |(1.2, 1.6, 0)| = 2
            Vec3::new(2.2, 1.6, -1.5),
        ]
    }

    #[test]
    fn exact_constant_speed_timing_three_segments() {
        let wps = three_segment_path();
        let mut f = follower(0.5, 0.0);
        f.set_path(&wps).unwrap();
        f.start(wps[0]).unwrap();
        assert!((f.total_length() - 3.5).abs() < 1e-6);
        assert!((f.duration() - 7.0).abs() < 1e-5);
        // Corners are reached at t = 2 s (s = 1) and t = 6 s (s = 3), the goal at 7 s.
        let corner1 = f.sample(2.0 - 1e-3);
        assert!(close(corner1.position, wps[1], 1e-3), "{:?}", corner1.position);
        assert!(close(corner1.velocity, Vec3::new(0.5, 0.0, 0.0), 1e-6));
        assert_eq!(corner1.progress.segment, 1);
        let after = f.sample(2.0 + 1e-3);
        assert!(close(after.velocity, Vec3::new(0.3, 0.4, 0.0), 1e-5), "velocity steps at the corner");
        assert_eq!(after.progress.segment, 2);
        // Middle of segment 2 at t = 4 s.
        let mid = f.sample(4.0);
        assert!(close(mid.position, Vec3::new(1.6, 0.8, -1.0), 1e-5));
        assert!((mid.progress.fraction - 0.5).abs() < 1e-5);
        assert!(!mid.progress.done);
        // Last segment goes up (−z) at 0.5 m/s.
        let last = f.sample(6.5);
        assert!(close(last.position, Vec3::new(2.2, 1.6, -1.25), 1e-5));
        assert!(close(last.velocity, Vec3::new(0.0, 0.0, -0.5), 1e-6));
        assert_eq!(last.progress.segment, 3);
        // Speed is exactly the cruise speed and acceleration zero everywhere before arrival.
        for i in 0..700 {
            let smp = f.sample(i as f32 * 0.01);
            assert!((smp.velocity.norm() - 0.5).abs() < 1e-5, "t = {}", i as f32 * 0.01);
            assert_eq!(smp.acceleration, Vec3::zeros());
        }
        // Arrival: hover at the goal.
        let end = f.sample(7.0 + 1e-3);
        assert!(end.progress.done);
        assert_eq!(end.position, wps[3]);
        assert_eq!(end.velocity, Vec3::zeros());
        assert!(f.sample(1e6).progress.done);
    }

    #[test]
    fn origin_leg_before_first_waypoint() {
        let mut f = follower(1.0, 0.0);
        f.set_path(&[Vec3::new(3.0, 4.0, 0.0)]).unwrap();
        f.start(Vec3::zeros()).unwrap();
        assert!((f.duration() - 5.0).abs() < 1e-6);
        let s = f.sample(2.5);
        assert!(close(s.position, Vec3::new(1.5, 2.0, 0.0), 1e-6));
        assert_eq!(s.progress.segment, 0);
    }

    #[test]
    fn rejects_bad_paths_without_truncating() {
        let mut f = follower(1.0, 0.0);
        assert_eq!(f.set_path(&[]), Err(PathError::Empty));
        let many = [Vec3::zeros(); 9];
        assert_eq!(f.set_path(&many), Err(PathError::TooMany { capacity: 8 }));
        assert!(f.is_empty(), "a rejected path is not partially stored");
        let bad = [Vec3::zeros(), Vec3::new(f32::NAN, 0.0, 0.0)];
        assert_eq!(f.set_path(&bad), Err(PathError::NonFinite { index: 1 }));
        let bad = [Vec3::new(0.0, f32::INFINITY, 0.0)];
        assert_eq!(f.set_path(&bad), Err(PathError::NonFinite { index: 0 }));
        let bad = [Vec3::zeros(), Vec3::zeros(), Vec3::new(0.0, 0.0, -2.0e5)];
        assert_eq!(f.set_path(&bad), Err(PathError::OutOfRange { index: 2 }));
        // Exactly at capacity is accepted.
        assert!(f.set_path(&[Vec3::zeros(); 8]).is_ok());
        assert_eq!(f.start(Vec3::new(f32::NAN, 0.0, 0.0)), Err(PathError::BadOrigin));
        let mut g = follower(1.0, 0.0);
        assert_eq!(g.start(Vec3::zeros()), Err(PathError::NoPath));
        assert!(g.sample(1.0).progress.done);
        assert!(WaypointFollower::<4>::new(WaypointParams { cruise_speed: 0.0, corner_radius: 0.0 }).is_err());
        assert!(
            WaypointFollower::<4>::new(WaypointParams { cruise_speed: 1.0, corner_radius: -1.0 }).is_err()
        );
        assert!(WaypointFollower::<4>::new(WaypointParams { cruise_speed: f32::NAN, corner_radius: 0.0 })
            .is_err());
        assert!(WaypointFollower::<4>::new(WaypointParams { cruise_speed: 1e3, corner_radius: 0.0 }).is_err());
        assert!(WaypointFollower::<4>::new(WaypointParams {
            cruise_speed: 1.0,
            corner_radius: f32::INFINITY
        })
        .is_err());
    }

    #[test]
    fn default_capacity_is_64() {
        let f: WaypointFollower = WaypointFollower::new(WaypointParams::default()).unwrap();
        assert_eq!(f.capacity(), DEFAULT_PATH_CAPACITY);
        assert_eq!(DEFAULT_PATH_CAPACITY, 64);
    }

    #[test]
    fn smoothing_is_consistent_and_bounded() {
        let wps = three_segment_path();
        let (v, w) = (0.5f32, 0.2f32);
        let mut f = follower(v, w);
        f.set_path(&wps).unwrap();
        f.start(wps[0]).unwrap();
        // Starts at rest at the origin and ends at rest at the goal.
        let s0 = f.sample(0.0);
        assert!(close(s0.position, wps[0], 1e-6) && s0.velocity.norm() < 1e-6);
        assert!((f.duration() - (3.5 + 0.4) / 0.5).abs() < 1e-5);
        let end = f.sample(f.duration() + 1e-3);
        assert!(end.progress.done && close(end.position, wps[3], 1e-6));
        // Velocity is the derivative of position and acceleration that of velocity
        // (central differences), the speed never exceeds V and |a| ≤ V²/w.
        let h = 1e-3f32;
        let mut t = 0.01f32;
        while t < f.duration() - 0.01 {
            let (a, b, c) = (f.sample(t - h), f.sample(t), f.sample(t + h));
            let dv = (c.position - a.position) / (2.0 * h);
            assert!(close(dv, b.velocity, 2e-2), "t {t}: {dv:?} vs {:?}", b.velocity);
            assert!(b.velocity.norm() <= v + 1e-4);
            assert!(b.acceleration.norm() <= v * v / w + 1e-3);
            t += 0.037;
        }
        // The velocity is continuous across the first corner (t = 2.4 s with the delay).
        let (a, b) = (f.sample(2.4 - 1e-3), f.sample(2.4 + 1e-3));
        assert!((a.velocity - b.velocity).norm() < 1e-2);
        // Away from corners it equals the unsmoothed path.
        let mid = f.sample(4.4);
        assert!(close(mid.position, Vec3::new(1.6, 0.8, -1.0), 1e-4));
    }

    #[test]
    fn single_waypoint_at_origin_is_immediately_done() {
        let mut f = follower(1.0, 0.0);
        let p = Vec3::new(1.0, 2.0, -3.0);
        f.set_path(&[p]).unwrap();
        f.start(p).unwrap();
        let s = f.sample(0.0);
        assert!(s.progress.done);
        assert_eq!(s.position, p);
        assert_eq!(f.sample(f32::NAN).position, p);
    }

    mod props {
        use super::*;
        use proptest::prelude::*;

        fn wild() -> impl Strategy<Value = f32> {
            super::super::wild::wild(6, -50.0..50.0)
        }

        fn wild3() -> impl Strategy<Value = Vec3> {
            (wild(), wild(), wild()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(1000))]
            /// No path, parameter, origin or time makes the follower panic; an accepted
            /// path always gives a finite reference at the cruise speed at most.
            #[test]
            fn never_panics_and_accepted_paths_give_finite_references(
                speed in prop_oneof![0.01f32..5.0, wild()],
                radius in prop_oneof![0.0f32..1.0, wild()],
                path in proptest::collection::vec(wild3(), 0..12),
                origin in wild3(),
                times in proptest::collection::vec(wild(), 1..8),
            ) {
                let params = WaypointParams { cruise_speed: speed, corner_radius: radius };
                let Ok(mut f) = WaypointFollower::<8>::new(params) else {
                    return Ok(());
                };
                let accepted = f.set_path(&path).is_ok();
                let valid = !path.is_empty() && path.len() <= 8 && path.iter().all(|w| is_finite3(w) && in_range(w));
                prop_assert_eq!(accepted, valid);
                let started = f.start(origin).is_ok();
                for t in times {
                    let s = f.sample(t);
                    if started {
                        prop_assert!(is_finite3(&s.position) && is_finite3(&s.velocity));
                        prop_assert!(is_finite3(&s.acceleration));
                        prop_assert!(s.velocity.norm() <= speed * 1.001 + 1e-5);
                        prop_assert!(s.progress.fraction >= 0.0 && s.progress.fraction <= 1.0);
                    }
                }
            }
        }
    }
}
