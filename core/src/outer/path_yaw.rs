//! The yaw reference while flying a path (Mission, Return): `MIS_YAW_MODE`, like PX4's
//! `MPC_YAW_MODE` / ArduPilot's `WP_YAW_BEHAVIOR`.
//!
//! * [`YawMode::Hold`] (0, the default): the yaw reference is not touched — the heading at
//!   arming (or the last one a piloted mode left), held constant. The path is sampled exactly
//!   as before this mode existed (bit-identical flights).
//! * [`YawMode::Travel`] (1): the yaw reference turns towards the horizontal direction of the
//!   path reference's velocity `atan2(ṗ_d,y, ṗ_d,x)` (NED: 0 = north, positive clockwise from
//!   above), at most `MIS_YAW_RATE` (rad/s) per second, the shorter way round (a turn of
//!   exactly π goes clockwise). While that velocity is slower than [`STATIONARY_SPEED`] (the
//!   goal, vertical legs) the yaw reference turns towards the reference point as seen from
//!   the vehicle when the vehicle is more than [`FACE_POINT_RADIUS`] from it horizontally
//!   (an overshoot past the goal, a push by the filter: the way back is then in view), and
//!   keeps its value otherwise or when the inputs are not finite. **The path waits for the
//!   heading** (along the path's velocity only): while the larger of the reference's and the
//!   estimated heading's error to the direction of travel exceeds [`MAX_HEADING_ERROR`] (12°,
//!   PX4's `MIS_YAW_ERR` default), the path's clock stops and the reference holds its point
//!   with zero velocity and acceleration, so the vehicle turns on the spot before it flies a
//!   leg — a forward sensor looks where the vehicle goes, and the vehicle never flies sideways into space
//!   its sensors have not seen. At a corner of the piecewise-linear path the reference
//!   stops within one outer step past the corner, turns, then goes on.
//!
//! Time along the path = time since the start − time waited (integer µs, saturating):
//! [`PathYaw::path_time`], then [`PathYaw::steer_sample`] on the follower's sample at it.
//! A heading that never aligns (e.g. a yaw-saturated vehicle) keeps the vehicle holding
//! its point: there is no timeout (PX4's `MIS_YAW_TMT` default, none).
//!
//! Bounded (no loop), NaN-safe: a non-finite direction, rate or time step leaves the yaw
//! reference unchanged; a non-finite estimated heading is replaced by the reference's.
//!
//! May import: [`super::waypoint`], the crate root foundation.

use super::waypoint::PathSample;
use crate::frame::{clampf, wrap_pi};
use crate::param_decl::{access, field, Has, Param};
use crate::Vec3;

/// How the yaw reference is chosen while flying a path (`MIS_YAW_MODE`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum YawMode {
    /// 0: hold the heading (the one at arming).
    #[default]
    Hold,
    /// 1: face the direction of travel along the path (rate-limited; the path waits for it).
    Travel,
}

impl YawMode {
    /// Every mode, in code order.
    pub const ALL: [YawMode; 2] = [YawMode::Hold, YawMode::Travel];

    /// The name in scene files and on the command line: `hold`, `travel`.
    pub const fn as_str(self) -> &'static str {
        match self {
            YawMode::Hold => "hold",
            YawMode::Travel => "travel",
        }
    }

    /// The parameter code (0 hold, 1 travel).
    pub const fn code(self) -> i32 {
        match self {
            YawMode::Hold => 0,
            YawMode::Travel => 1,
        }
    }

    /// The mode with parameter code `c`.
    pub const fn from_code(c: i32) -> Option<YawMode> {
        match c {
            0 => Some(YawMode::Hold),
            1 => Some(YawMode::Travel),
            _ => None,
        }
    }
}

impl core::str::FromStr for YawMode {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        YawMode::ALL.into_iter().find(|m| m.as_str() == s).ok_or(())
    }
}

/// The yaw settings of path flight (part of [`super::guidance::GuidanceParams`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathYawParams {
    /// Mode (`MIS_YAW_MODE`). Default [`YawMode::Hold`].
    pub mode: YawMode,
    /// Largest turn rate of the yaw reference, rad/s (`MIS_YAW_RATE`). Default π/4 (45°/s,
    /// PX4's `MPC_YAWRAUTO_MAX`).
    pub rate: f32,
}

impl Default for PathYawParams {
    fn default() -> Self {
        PathYawParams { mode: YawMode::Hold, rate: DEFAULT_RATE }
    }
}

impl PathYawParams {
    /// The yaw along a path's parameters (issue 19; `crate::params`): PX4's `MPC_YAW_MODE` /
    /// `MPC_YAWRAUTO_MAX` (the heading threshold, PX4's `MIS_YAW_ERR`, is the constant
    /// [`MAX_HEADING_ERROR`]).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 2] {
        [
            Param::new("MIS_YAW_MODE", "Mission", "", (0.0, 1.0), 0,
                access!(|s| s.mode.code() as f32, |s, v| s.mode = YawMode::from_code(v as i32).unwrap_or(s.mode)),
                "Yaw along the path (Mission, Return): 0 hold the heading at arming, 1 face the direction of travel")
                .key("yaw_mode").code(|c| YawMode::from_code(c).map(YawMode::as_str)),
            Param::new("MIS_YAW_RATE", "Mission", "rad/s", (0.05, 6.0), 3, field!(rate),
                "MIS_YAW_MODE 1: largest turn rate of the yaw reference towards the travel direction"),
        ]
    }
}

impl PathYawParams {
    /// `rate` finite and > 0.
    pub fn is_valid(&self) -> bool {
        self.rate.is_finite() && self.rate > 0.0
    }
}

/// Default `MIS_YAW_RATE`, rad/s (45°/s).
pub const DEFAULT_RATE: f32 = core::f32::consts::FRAC_PI_4;
/// The path waits while the heading is farther than this from the direction of travel, rad
/// (12°, PX4's `MIS_YAW_ERR` default; a constant here: a parameter costs flash the F405 image
/// does not have to spare, and 12° is well inside a forward sensor's field of view — the
/// camera's ±43.5°, a ToF's ±22.5°).
pub const MAX_HEADING_ERROR: f32 = 0.209_439_5;
/// Below this horizontal reference speed the path gives no direction of travel, m/s.
pub const STATIONARY_SPEED: f32 = 0.01;
/// With a stationary reference, the yaw reference faces the reference point while the
/// vehicle is farther than this from it horizontally, m (the host's goal tolerance, 0.1 m).
pub const FACE_POINT_RADIUS: f32 = 0.1;

/// What the yaw steering takes of the vehicle at one outer step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Steering {
    /// Fresh position estimate, NED m (`None` without a fix).
    pub position: Option<Vec3>,
    /// Estimated heading, rad.
    pub heading: f32,
    /// Outer step, s.
    pub dt: f32,
    /// The safety filter held the vehicle back along the reference's velocity in the last
    /// outer step (the mission trajectory's clock stops, [`super::guidance`]).
    pub held_back: bool,
    /// The speed governor's limit along the motion at the last outer step, m/s (`+∞`: none;
    /// `crate::governor`): the mission's reference advances no faster (the paper guidance's
    /// clock through [`PathYaw::governed_time`], the trajectory's clock scale), so it does not
    /// run ahead of a vehicle the governor slows (towards the goal, through walls).
    pub speed_limit: f32,
}

/// The path clock and the waiting state of one path being flown (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PathYaw {
    /// Time waited since the path's start, µs.
    waited_us: u64,
    /// Time of the last sample, µs (valid whenever `waiting`: only a sample sets it).
    last_us: u64,
    /// The last sample waited for the heading.
    waiting: bool,
    /// Path time lost to the speed governor since the path's start, µs.
    governed_us: u64,
    /// Time of the last [`Self::governed_time`], µs.
    governed_last_us: Option<u64>,
}

impl PathYaw {
    /// A path (re)started: nothing waited.
    pub fn reset(&mut self) {
        *self = PathYaw::default();
    }

    /// `true` while the path waits for the heading (the last sample's decision).
    pub fn waiting(&self) -> bool {
        self.waiting
    }

    /// Time waited for the heading since the path's start, µs.
    pub fn waited_us(&self) -> u64 {
        self.waited_us
    }

    /// Time along a path started at `t0_us`, at `now_us`, s: the time since the start, minus
    /// (in [`YawMode::Travel`]) the time waited for the heading. In [`YawMode::Hold`] exactly
    /// the time since the start (the follower is sampled as before this mode existed).
    pub fn path_time(&mut self, p: &PathYawParams, t0_us: u64, now_us: u64) -> f32 {
        let elapsed = now_us.saturating_sub(t0_us);
        if p.mode == YawMode::Hold {
            return elapsed as f32 * 1e-6;
        }
        if self.waiting {
            self.waited_us = self.waited_us.saturating_add(now_us.saturating_sub(self.last_us));
        }
        self.last_us = now_us;
        elapsed.saturating_sub(self.waited_us) as f32 * 1e-6
    }

    /// [`Self::path_time`] minus the time lost to the speed governor: between two calls the
    /// path advances at the rate `min(1, speed_limit / speed)` (`speed` the path's speed at
    /// the previous sample, `speed_limit` the governor's, [`Steering::speed_limit`]), so the
    /// reference moves no faster than the governor lets the vehicle.
    pub fn governed_time(&mut self, p: &PathYawParams, t0_us: u64, now_us: u64, rate: f32) -> f32 {
        let rate = if rate.is_nan() { 1.0 } else { rate.clamp(0.0, 1.0) };
        let dt = self.governed_last_us.map_or(0, |t| now_us.saturating_sub(t));
        self.governed_us = self.governed_us.saturating_add((dt as f32 * (1.0 - rate)) as u64);
        self.governed_last_us = Some(now_us);
        (self.path_time(p, t0_us, now_us) - self.governed_us as f32 * 1e-6).max(0.0)
    }

    /// Steer the yaw reference `yaw` (rad) per `p` for the vehicle `v` and the path's sample
    /// `s` at [`Self::path_time`]; while the path waits for the heading, `s` holds its point
    /// (zero velocity and acceleration). Nothing happens in [`YawMode::Hold`].
    pub fn steer_sample(&mut self, p: &PathYawParams, s: &mut PathSample, yaw: &mut f32, v: &Steering) {
        if p.mode == YawMode::Hold {
            return;
        }
        let moving = horizontal_sq(&s.velocity) >= STATIONARY_SPEED * STATIONARY_SPEED;
        self.waiting = if moving {
            steer(p, yaw, &s.velocity, v.heading, v.dt)
        } else {
            if let Some(to) = v.position.map(|q| s.position - q) {
                if horizontal_sq(&to) > FACE_POINT_RADIUS * FACE_POINT_RADIUS {
                    steer(p, yaw, &to, v.heading, v.dt);
                }
            }
            false
        };
        if self.waiting {
            s.velocity = Vec3::zeros();
            s.acceleration = Vec3::zeros();
        }
    }
}

/// `x² + y²` of `v`.
fn horizontal_sq(v: &Vec3) -> f32 {
    v.x * v.x + v.y * v.y
}

/// Turn `yaw` (rad) towards the horizontal direction of `velocity` at most `p.rate · dt`;
/// returns `true` when the heading error (the larger of `yaw`'s and `est_yaw`'s) still
/// exceeds [`MAX_HEADING_ERROR`]. A (nearly) stationary or non-finite `velocity` keeps `yaw` and
/// never waits; a non-finite `yaw` is left as it is.
pub fn steer(p: &PathYawParams, yaw: &mut f32, velocity: &Vec3, est_yaw: f32, dt: f32) -> bool {
    let speed_sq = horizontal_sq(velocity);
    if !(speed_sq.is_finite() && speed_sq >= STATIONARY_SPEED * STATIONARY_SPEED && yaw.is_finite()) {
        return false;
    }
    let target = libm::atan2f(velocity.y, velocity.x);
    let step = p.rate * dt;
    let step = if step.is_finite() && step > 0.0 { step } else { 0.0 };
    *yaw = wrap_pi(*yaw + clampf(wrap_pi(target - *yaw), -step, step));
    let heading = if est_yaw.is_finite() { est_yaw } else { *yaw };
    let error = wrap_pi(target - *yaw).abs().max(wrap_pi(target - heading).abs());
    // `error` is finite here (finite target, yaw and heading).
    error > MAX_HEADING_ERROR
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::waypoint::{WaypointFollower, WaypointParams};
    use core::f32::consts::{FRAC_PI_2, PI};

    const TRAVEL: PathYawParams = PathYawParams { mode: YawMode::Travel, rate: DEFAULT_RATE };

    /// [`steer`] with the vehicle's heading on the reference.
    fn turn(yaw: &mut f32, v: &Vec3, dt: f32) -> bool {
        let est = *yaw;
        steer(&TRAVEL, yaw, v, est, dt)
    }

    fn east() -> Vec3 {
        Vec3::new(0.0, 0.25, 0.0)
    }

    #[test]
    fn names_and_codes_round_trip() {
        for m in YawMode::ALL {
            assert_eq!(m.as_str().parse::<YawMode>(), Ok(m));
            assert_eq!(YawMode::from_code(m.code()), Some(m));
        }
        assert_eq!(YawMode::from_code(2), None);
        assert!("north".parse::<YawMode>().is_err());
        assert_eq!(YawMode::default(), YawMode::Hold);
        assert!(PathYawParams::default().is_valid());
        assert!(!PathYawParams { rate: f32::NAN, ..TRAVEL }.is_valid());
        assert!(!PathYawParams { rate: 0.0, ..TRAVEL }.is_valid());
    }

    #[test]
    fn the_turn_is_rate_limited() {
        let mut yaw = 0.0;
        let dt = 0.004;
        let mut steps = 0;
        while turn(&mut yaw, &east(), dt) {
            steps += 1;
            assert!(steps < 10_000);
        }
        // From north to east at 45°/s: (90° − 12°) / 45°/s = 1.733 s of waiting.
        let t = steps as f32 * dt;
        assert!((t - (FRAC_PI_2 - MAX_HEADING_ERROR) / DEFAULT_RATE).abs() < 2.0 * dt, "{t}");
        let mut prev = 0.0f32;
        let mut yaw = 0.0;
        for _ in 0..1000 {
            turn(&mut yaw, &east(), dt);
            assert!((yaw - prev).abs() <= DEFAULT_RATE * dt * 1.0001, "{prev} -> {yaw}");
            assert!(yaw <= FRAC_PI_2 + 1e-6, "no overshoot: {yaw}");
            prev = yaw;
        }
        assert!((yaw - FRAC_PI_2).abs() < 1e-6, "{yaw}");
    }

    #[test]
    fn the_turn_wraps_around_pi_the_short_way() {
        // Heading 170°, travel towards −170° (south-south-west): 20° through ±π.
        let mut yaw = 170f32.to_radians();
        let a = (-170f32).to_radians();
        let v = Vec3::new(libm::cosf(a), libm::sinf(a), 0.0);
        for _ in 0..200 {
            turn(&mut yaw, &v, 0.004);
            assert!(yaw.abs() >= 170f32.to_radians() - 1e-4, "went the long way: {yaw}");
            assert!(yaw > -PI && yaw <= PI, "wrapped: {yaw}");
        }
        assert!((yaw - a).abs() < 1e-5, "{yaw}");
        // Exactly opposite: a deterministic direction (clockwise), and it gets there.
        let mut yaw = 0.0;
        turn(&mut yaw, &Vec3::new(-1.0, 0.0, 0.0), 0.004);
        assert!(yaw > 0.0, "{yaw}");
        for _ in 0..2000 {
            turn(&mut yaw, &Vec3::new(-1.0, 0.0, 0.0), 0.004);
        }
        assert!((yaw.abs() - PI).abs() < 1e-5, "{yaw}");
    }

    #[test]
    fn a_stationary_or_bad_reference_keeps_the_yaw_and_never_waits() {
        for v in [
            Vec3::zeros(),
            Vec3::new(0.005, 0.005, 0.0),
            Vec3::new(0.0, 0.0, -0.5), // a vertical leg
            Vec3::new(f32::NAN, 1.0, 0.0),
            Vec3::new(f32::INFINITY, 1.0, 0.0),
        ] {
            let mut yaw = 0.3;
            assert!(!steer(&TRAVEL, &mut yaw, &v, 0.3, 0.004), "{v:?}");
            assert_eq!(yaw, 0.3, "{v:?}");
        }
        // A non-finite time step or rate: no turn (still waits while misaligned).
        for (dt, rate) in [(f32::NAN, DEFAULT_RATE), (0.004, f32::INFINITY), (-1.0, DEFAULT_RATE)] {
            let mut yaw = 0.0;
            let p = PathYawParams { rate, ..TRAVEL };
            assert!(steer(&p, &mut yaw, &east(), 0.0, dt));
            assert_eq!(yaw, 0.0);
        }
        // A non-finite estimate: the reference's heading decides.
        let mut yaw = FRAC_PI_2;
        assert!(!steer(&TRAVEL, &mut yaw, &east(), f32::NAN, 0.004));
        // A non-finite yaw reference is left alone.
        let mut yaw = f32::NAN;
        assert!(!steer(&TRAVEL, &mut yaw, &east(), 0.0, 0.004));
        assert!(yaw.is_nan());
    }

    #[test]
    fn the_estimated_heading_must_align_too() {
        let mut yaw = FRAC_PI_2;
        // The reference is aligned, the vehicle still 30° behind: wait.
        assert!(steer(&TRAVEL, &mut yaw, &east(), FRAC_PI_2 - 0.52, 0.004));
        assert!(!steer(&TRAVEL, &mut yaw, &east(), FRAC_PI_2 - 0.1, 0.004));
    }

    /// The follower's sample at the path's time, steered (what Guidance and ReturnPath do).
    fn sample(
        py: &mut PathYaw,
        p: &PathYawParams,
        f: &WaypointFollower<8>,
        (t0, now): (u64, u64),
        yaw: &mut f32,
        v: &Steering,
    ) -> PathSample {
        let mut s = f.sample(py.path_time(p, t0, now));
        py.steer_sample(p, &mut s, yaw, v);
        s
    }

    fn follower() -> WaypointFollower<8> {
        let mut f = WaypointFollower::new(WaypointParams { cruise_speed: 0.5, corner_radius: 0.0 }).unwrap();
        // 1 m north, then 1 m east.
        f.set_path(&[Vec3::new(1.0, 0.0, -1.0), Vec3::new(1.0, 1.0, -1.0)]).unwrap();
        f.start(Vec3::new(0.0, 0.0, -1.0)).unwrap();
        f
    }

    #[test]
    fn the_path_waits_for_the_heading_at_a_corner() {
        let f = follower();
        let mut py = PathYaw::default();
        let mut yaw = 0.0; // facing north, along the first leg
        let dt = 0.004;
        let mut first_wait = None;
        let mut corner_hold = 0u32;
        for k in 0..3000u64 {
            let now = k * 4000;
            let v =
                Steering { position: None, heading: yaw, dt, held_back: false, speed_limit: f32::INFINITY };
            let s = sample(&mut py, &TRAVEL, &f, (0, now), &mut yaw, &v);
            if py.waiting() {
                first_wait.get_or_insert(now);
                corner_hold += 1;
                assert_eq!(s.velocity, Vec3::zeros());
                // Held at the corner (within one step past it).
                assert!(
                    (s.position - Vec3::new(1.0, 0.0, -1.0)).norm() < 0.5 * 0.004 + 1e-5,
                    "{:?}",
                    s.position
                );
            }
            if s.progress.done {
                break;
            }
        }
        // Waits from the corner (2 s at 0.5 m/s) until within 12° of east.
        let t0 = first_wait.unwrap() as f32 * 1e-6;
        assert!((t0 - 2.0).abs() < 0.01, "{t0}");
        let waited = corner_hold as f32 * dt;
        assert!((waited - (FRAC_PI_2 - MAX_HEADING_ERROR) / DEFAULT_RATE).abs() < 3.0 * dt, "{waited}");
        assert_eq!(py.waited_us(), u64::from(corner_hold) * 4000);
        assert!((yaw - FRAC_PI_2).abs() < 1e-5, "{yaw}");
    }

    #[test]
    fn hold_is_the_plain_follower_and_leaves_the_yaw() {
        let f = follower();
        let mut py = PathYaw::default();
        let hold = PathYawParams::default();
        let mut yaw = 0.7;
        for k in 0..1500u64 {
            let now = 1_000 + k * 4000;
            let v = Steering {
                position: Some(Vec3::new(-3.0, 0.0, 0.0)),
                heading: 0.0,
                dt: 0.004,
                held_back: false,
                speed_limit: f32::INFINITY,
            };
            let s = sample(&mut py, &hold, &f, (1_000, now), &mut yaw, &v);
            assert_eq!(s, f.sample((now - 1_000) as f32 * 1e-6));
            assert_eq!(yaw, 0.7);
            assert!(!py.waiting());
        }
    }

    #[test]
    fn a_stationary_reference_is_faced_from_a_vehicle_away_from_it() {
        let f = follower();
        let goal = Vec3::new(1.0, 1.0, -1.0);
        let mut py = PathYaw::default();
        // Facing east along the last leg, long after the goal; overshot 0.5 m east of the goal:
        // turn to face it (west), never wait.
        let mut yaw = FRAC_PI_2;
        let done = 10_000_000;
        let past = Some(goal + Vec3::new(0.0, 0.5, 0.0));
        for k in 0..2000u64 {
            let v = Steering {
                position: past,
                heading: yaw,
                dt: 0.004,
                held_back: false,
                speed_limit: f32::INFINITY,
            };
            let s = sample(&mut py, &TRAVEL, &f, (0, done + k * 4000), &mut yaw, &v);
            assert!(s.progress.done && !py.waiting());
            assert_eq!(s.position, goal);
        }
        assert!((yaw.abs() - FRAC_PI_2).abs() < 1e-5 && yaw < 0.0, "faces west: {yaw}");
        // Within FACE_POINT_RADIUS (or without a fix): the yaw is kept.
        for position in [Some(goal + Vec3::new(0.06, -0.06, 0.3)), None] {
            let before = yaw;
            let v =
                Steering { position, heading: yaw, dt: 0.004, held_back: false, speed_limit: f32::INFINITY };
            sample(&mut py, &TRAVEL, &f, (0, done), &mut yaw, &v);
            assert_eq!(yaw, before);
        }
    }
}
