//! Return (issue 21): the breadcrumb trail of the flown path and the reference that flies it
//! back to the start, through the PD tracker and the safety filter, ending in Land.
//!
//! ## Breadcrumbs
//! From arming, the home point (arming position) is the first crumb; while airborne with a
//! fresh fix, a crumb is dropped whenever the vehicle is `crumb_spacing` (`RTL_CRUMB_DIST`)
//! from the last one. Capacity [`CRUMB_CAPACITY`] = 32 points (384 B). **When full**, every
//! second crumb after the home point is dropped (the trail keeps its shape at half the
//! resolution) and the spacing doubles, so the trail always reaches back to home and a long
//! flight costs no more memory; the thinning is O(capacity), at most once per new crumb.
//! The crumbs are points the vehicle flew through with the filter on, so the trail back is
//! free of the obstacles that were there; the filter guards against the ones that moved.
//!
//! ## The return reference
//! On entering Return: the crumbs in reverse order, from the vehicle's position
//! ([`ReturnPath::trail_back`]); the last leg ends above home at the height of the last crumb
//! before home (the landing descends from there). With `MIS_GUIDANCE` 1 (the default) the
//! guidance flies it on its jerk-limited trajectory at `RTL_SPEED` with the `TRJ_*` limits and
//! the clock that waits (`Guidance::start_return`, issue 35); with 0 (the paper's guidance) a
//! [`WaypointFollower`] here flies it at `return_speed` (`RTL_SPEED`), `done` when the
//! follower reports the goal reached. The yaw along it follows `MIS_YAW_MODE`
//! ([`super::path_yaw`]): held, or turned towards the direction of travel with the path
//! waiting for the heading.
//!
//! May import: [`super::waypoint`], [`super::tracking`], [`super::path_yaw`], the crate root
//! foundation.

use super::path_yaw::{PathYaw, PathYawParams, Steering};
use super::tracking::Reference;
use super::waypoint::{PathError, Progress, WaypointFollower, WaypointParams};
use crate::fmath::norm3;
use crate::Vec3;

/// Breadcrumbs kept (home included).
pub const CRUMB_CAPACITY: usize = 32;

/// The breadcrumb trail and the return reference (see the module documentation).
#[derive(Clone, Debug)]
pub struct ReturnPath {
    crumbs: heapless::Vec<Vec3, CRUMB_CAPACITY>,
    base_spacing: f32,
    spacing: f32,
    follower: WaypointFollower<CRUMB_CAPACITY>,
    t0_us: Option<u64>,
    path_yaw: PathYaw,
}

impl ReturnPath {
    /// An empty trail with crumbs every `spacing` m, flown back at `speed` m/s.
    pub fn new(spacing: f32, speed: f32) -> Result<Self, PathError> {
        Ok(ReturnPath {
            crumbs: heapless::Vec::new(),
            base_spacing: spacing,
            spacing,
            follower: WaypointFollower::new(WaypointParams { cruise_speed: speed, corner_radius: 0.0 })?,
            t0_us: None,
            path_yaw: PathYaw::default(),
        })
    }

    /// A new trail starting at `home` (on arming).
    pub fn reset(&mut self, home: Vec3) {
        self.crumbs.clear();
        let _ = self.crumbs.push(home);
        self.spacing = self.base_spacing;
        self.t0_us = None;
    }

    /// The crumbs, home first.
    pub fn crumbs(&self) -> &[Vec3] {
        &self.crumbs
    }

    /// Current spacing, m (doubles whenever the trail was thinned).
    pub fn spacing(&self) -> f32 {
        self.spacing
    }

    /// Record the vehicle at `p` (a fresh, finite position while airborne).
    pub fn record(&mut self, p: Vec3) {
        let Some(last) = self.crumbs.last() else {
            let _ = self.crumbs.push(p);
            return;
        };
        if norm3(&(p - last)) < self.spacing {
            return;
        }
        if self.crumbs.is_full() {
            // Keep home and every second crumb after it.
            let n = self.crumbs.len();
            let mut w = 1;
            let mut r = 2;
            while r < n {
                if let Some(&c) = self.crumbs.get(r) {
                    if let Some(slot) = self.crumbs.get_mut(w) {
                        *slot = c;
                    }
                }
                w += 1;
                r += 2;
            }
            self.crumbs.truncate(w);
            self.spacing *= 2.0;
        }
        let _ = self.crumbs.push(p);
    }

    /// The way back from `p`: the crumbs after home in reverse order, then home at the height
    /// of the last of them (at `p`'s height when there is none). Fails when there is no trail.
    pub fn trail_back(&self, p: Vec3) -> Result<heapless::Vec<Vec3, CRUMB_CAPACITY>, PathError> {
        let n = self.crumbs.len();
        let home = *self.crumbs.first().ok_or(PathError::NoPath)?;
        let mut path: heapless::Vec<Vec3, CRUMB_CAPACITY> = heapless::Vec::new();
        for k in (1..n).rev() {
            if let Some(&c) = self.crumbs.get(k) {
                let _ = path.push(c);
            }
        }
        let z = path.last().map_or(p.z, |c| c.z);
        let _ = path.push(Vec3::new(home.x, home.y, z));
        Ok(path)
    }

    /// Start flying back from `p` at `now_us` on the paper's follower (`MIS_GUIDANCE` 0; with
    /// 1 the guidance flies [`Self::trail_back`] on its trajectory,
    /// `Guidance::start_return`). Fails (nothing changes) when there is no trail.
    pub fn start(&mut self, now_us: u64, p: Vec3) -> Result<(), PathError> {
        let path = self.trail_back(p)?;
        self.follower.set_path(&path)?;
        self.follower.start(p)?;
        self.t0_us = Some(now_us);
        self.path_yaw.reset();
        Ok(())
    }

    /// The return reference at `now_us` and whether home is reached; `None` when not started.
    /// The yaw reference `yaw` (rad) is steered per `yaw_params` for the vehicle `v`, and is
    /// the reference's yaw.
    pub fn reference(
        &mut self,
        now_us: u64,
        yaw_params: &PathYawParams,
        yaw: &mut f32,
        v: &Steering,
    ) -> Option<(Reference, Progress)> {
        let t0 = self.t0_us?;
        let mut s = self.follower.sample(self.path_yaw.path_time(yaw_params, t0, now_us));
        self.path_yaw.steer_sample(yaw_params, &mut s, yaw, v);
        let r =
            Reference { position: s.position, velocity: s.velocity, acceleration: s.acceleration, yaw: *yaw };
        Some((r, s.progress))
    }

    /// `true` while flying back and waiting for the heading (`MIS_YAW_MODE` travel).
    pub fn waiting_for_heading(&self) -> bool {
        self.t0_us.is_some() && self.path_yaw.waiting()
    }

    /// Stop flying back (a new mode).
    pub fn stop(&mut self) {
        self.t0_us = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trail_thins_when_full_and_flies_back_to_home() {
        let mut r = ReturnPath::new(0.5, 1.0).unwrap_or_else(|_| unreachable!());
        r.reset(Vec3::zeros());
        for k in 1..=200 {
            r.record(Vec3::new(0.1 * k as f32, 0.0, -1.0));
        }
        let c = r.crumbs();
        assert!(c.len() <= CRUMB_CAPACITY && c.len() > CRUMB_CAPACITY / 2, "{}", c.len());
        assert_eq!(c[0], Vec3::zeros(), "home kept");
        assert!(r.spacing() > 0.5, "thinned: {}", r.spacing());
        assert!(c.windows(2).all(|w| w[1].x > w[0].x), "order kept");
        let p = Vec3::new(20.0, 0.0, -1.0);
        assert!(r.start(0, p).is_ok());
        let hold = PathYawParams::default();
        let mut yaw = 0.0;
        let v = Steering {
            position: None,
            heading: 0.0,
            dt: 0.004,
            held_back: false,
            speed_limit: f32::INFINITY,
        };
        let (r0, _) = r.reference(0, &hold, &mut yaw, &v).unwrap_or_else(|| unreachable!());
        assert!((r0.position - p).norm() < 1e-4);
        let (end, prog) = r.reference(60_000_000, &hold, &mut yaw, &v).unwrap_or_else(|| unreachable!());
        assert!(prog.done);
        assert!((end.position - Vec3::new(0.0, 0.0, -1.0)).norm() < 1e-4, "{:?}", end.position);
    }
}
