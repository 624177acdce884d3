//! The outer loop's inputs: the external position fix (with the fix-derived acceleration
//! the estimator may use) and the obstacle set the safety filter reads.
//!
//! Rate: on every fix / obstacle update (any rate; the defaults feed them at 100 Hz), read
//! by the outer loop at the outer rate. Between fixes the position is the fix extrapolated
//! with its velocity, `p = p_fix + ṗ_fix·age`, while the fix is fresh (age ≤ the position
//! timeout). Inputs that are NaN/Inf, beyond ±[`INPUT_LIMIT`] or time-stamped in the future
//! are reported as bad inputs (the supervisor brakes).
//!
//! May import: [`crate::safety::obstacle`], [`crate::obstacle_set`], [`crate::msg`], the crate
//! root foundation.

use crate::cbf::INPUT_LIMIT;
use crate::frame::{clampf, GRAVITY};
use crate::msg::{EstimatorAid, PositionFix};
use crate::obstacle::{ObstaclePoint, ObstacleSet};
use crate::obstacle_set::{self, Ranking, SetReport};
use crate::Vec3;

/// Capacity of the controller's obstacle set.
pub const OBSTACLE_CAPACITY: usize = 32;

/// Input parameters (a part of [`crate::controller::ControllerParams`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputParams {
    /// A position fix older than this is stale, µs.
    pub position_timeout_us: u64,
    /// Obstacle data older than this is stale, µs.
    pub obstacle_timeout_us: u64,
    /// Time constant of the low-pass on the fix-derived acceleration, s.
    pub accel_comp_tau_s: f32,
    /// Hull size δ of the filter, m² (an obstacle point closer than √δ is inside the hull).
    pub hull_delta: f32,
}

/// What an obstacle update did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObstacleIntake {
    /// Bad inputs in the update (non-finite or out-of-range points, a future time stamp).
    pub bad_inputs: bool,
    /// Points dropped (set full) or rejected; `None` when the whole update was ignored.
    pub dropped: Option<u8>,
    /// What the set policy kept and dropped ([`crate::obstacle_set`]); `None` when ignored.
    pub report: Option<SetReport>,
}

/// The inputs (see the module documentation).
#[derive(Clone, Debug)]
pub struct Inputs {
    params: InputParams,
    fix: Option<PositionFix>,
    accel_est: Vec3,
    obstacles: ObstacleSet<OBSTACLE_CAPACITY>,
    obstacle_t_us: Option<u64>,
    /// Where the vehicle was when the obstacle set was reported (`docs/filter.md` §9).
    obstacle_from: Option<Vec3>,
}

/// Finite and within ±[`INPUT_LIMIT`] (m, m/s): anything else is a corrupt input.
/// (`|x| ≤ L` is false for NaN and ±∞: one comparison per component.)
fn plausible(v: &Vec3) -> bool {
    v.x.abs() <= INPUT_LIMIT && v.y.abs() <= INPUT_LIMIT && v.z.abs() <= INPUT_LIMIT
}

fn age(now: u64, t: u64) -> u64 {
    now.saturating_sub(t)
}

/// `true` when `t_us` lies more than `limit_us` after the controller clock `clock_us`
/// (a timestamp from the future would otherwise never become stale).
fn is_future(clock_us: Option<u64>, t_us: u64, limit_us: u64) -> bool {
    clock_us.is_some_and(|now| t_us > now.saturating_add(limit_us))
}

impl Inputs {
    /// No fix, no obstacle data yet.
    pub fn new(params: InputParams) -> Self {
        Inputs {
            params,
            fix: None,
            accel_est: Vec3::zeros(),
            obstacles: ObstacleSet::new(),
            obstacle_t_us: None,
            obstacle_from: None,
        }
    }

    /// Fresh position and velocity at `now_us` (fix extrapolated), or `None` when stale/missing.
    pub fn position_estimate(&self, now_us: u64) -> Option<(Vec3, Vec3)> {
        let f = self.fix?;
        let a = age(now_us, f.t_us);
        if a > self.params.position_timeout_us {
            return None;
        }
        let p = f.position + f.velocity * (a as f32 * 1e-6);
        Some((p, f.velocity))
    }

    /// The vehicle's position at `t_us` from the last fix, extrapolated forwards or back
    /// along its velocity (`t_us` may precede the fix: a report stamped before the newest
    /// fix); `None` without a fix or more than the position timeout away from it.
    pub fn position_at(&self, t_us: u64) -> Option<Vec3> {
        let f = self.fix?;
        let gap_us = t_us.abs_diff(f.t_us);
        if gap_us > self.params.position_timeout_us {
            return None;
        }
        let dt = gap_us as f32 * if t_us >= f.t_us { 1e-6 } else { -1e-6 };
        Some(f.position + f.velocity * dt)
    }

    /// Where the vehicle was when the current obstacle set was reported ([`Self::position_at`]
    /// the update's time stamp): the filter aims each point's tangent plane from there
    /// (`crate::plant_aware::StepInput::seen_from`). `None` before the first update or without a fix.
    pub fn obstacles_seen_from(&self) -> Option<Vec3> {
        self.obstacle_from
    }

    /// Position of the last accepted fix (stale or not).
    pub fn last_fix_position(&self) -> Option<Vec3> {
        self.fix.map(|f| f.position)
    }

    /// Ages of the last fix and the last obstacle update at `now_us`, µs.
    pub fn ages(&self, now_us: u64) -> (Option<u64>, Option<u64>) {
        (self.fix.map(|f| age(now_us, f.t_us)), self.obstacle_t_us.map(|t| age(now_us, t)))
    }

    /// What the estimator may use from the fixes.
    pub fn aid(&self) -> EstimatorAid {
        EstimatorAid {
            fix_t_us: self.fix.map(|f| f.t_us),
            accel_ned: self.accel_est,
            yaw: self.fix.and_then(|f| f.yaw),
        }
    }

    /// Obstacle points in the set.
    pub fn obstacles(&self) -> &[ObstaclePoint] {
        self.obstacles.as_slice()
    }

    /// Id of the first stored obstacle point closer than the hull radius √δ
    /// to `p` (NED, m): `|p − q|² < δ`.
    pub fn obstacle_in_hull(&self, p: &Vec3) -> Option<u16> {
        let delta = self.params.hull_delta;
        self.obstacles.as_slice().iter().find(|o| (o.point - *p).norm_squared() < delta).map(|o| o.id)
    }

    /// Store an external position fix (`clock_us`: the controller clock). Returns `false`
    /// for a bad input (rejected: NaN/Inf or beyond ±[`INPUT_LIMIT`] position or velocity, a
    /// non-finite yaw, a time stamp more than the position timeout after the clock). Fixes
    /// older than the stored one are ignored.
    pub fn update_position(&mut self, fix: PositionFix, clock_us: Option<u64>) -> bool {
        let yaw_ok = fix.yaw.is_none_or(|y| y.is_finite());
        let future = is_future(clock_us, fix.t_us, self.params.position_timeout_us);
        if !plausible(&fix.position) || !plausible(&fix.velocity) || !yaw_ok || future {
            return false;
        }
        if let Some(prev) = self.fix {
            if fix.t_us < prev.t_us {
                return true;
            }
            let dt = (fix.t_us - prev.t_us) as f32 * 1e-6;
            if dt > 0.0 && dt <= 0.1 {
                let lim = 2.0 * GRAVITY;
                let raw = ((fix.velocity - prev.velocity) / dt).map(|x| clampf(x, -lim, lim));
                let k = dt / (self.params.accel_comp_tau_s + dt);
                self.accel_est += (raw - self.accel_est) * k;
            } else if dt > 0.1 {
                self.accel_est = Vec3::zeros();
            }
        }
        self.fix = Some(fix);
        true
    }

    /// Replace the obstacle set with `obstacles` valid at `now_us`, keeping the
    /// [`OBSTACLE_CAPACITY`] nearest to the vehicle (`clock_us`: the controller clock).
    pub fn update_obstacles(
        &mut self,
        now_us: u64,
        obstacles: &[ObstaclePoint],
        clock_us: Option<u64>,
        ranking: Ranking,
        delta1: f32,
    ) -> ObstacleIntake {
        if is_future(clock_us, now_us, self.params.obstacle_timeout_us) {
            return ObstacleIntake { bad_inputs: true, dropped: None, report: None };
        }
        let estimate = self.position_estimate(now_us);
        let vehicle = estimate.map(|(p, _)| p).or(self.fix.map(|f| f.position)).unwrap_or_else(Vec3::zeros);
        let v_est = estimate.map_or_else(Vec3::zeros, |(_, v)| v);
        // Obstacle-set policy at capacity (crate::obstacle_set): the published nearest-first
        // for the closest-obstacle variants, most critical first for the multi ones.
        let rep = obstacle_set::select(&mut self.obstacles, ranking, delta1, &vehicle, &v_est, obstacles);
        self.obstacle_t_us = Some(now_us);
        self.obstacle_from = self.position_at(now_us);
        let dropped = u8::try_from(rep.dropped.saturating_add(rep.rejected)).unwrap_or(u8::MAX);
        ObstacleIntake { bad_inputs: rep.rejected > 0, dropped: Some(dropped), report: Some(rep) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_obstacle_report_is_seen_from_the_position_at_its_time_stamp() {
        let params = InputParams {
            position_timeout_us: 100_000,
            obstacle_timeout_us: 100_000,
            accel_comp_tau_s: 0.05,
            hull_delta: 0.05,
        };
        let mut inp = Inputs::new(params);
        assert_eq!(inp.position_at(0), None);
        let fix = PositionFix {
            t_us: 1_000_000,
            position: Vec3::new(1.0, 2.0, -1.0),
            velocity: Vec3::new(0.0, 2.0, 0.0),
            yaw: None,
        };
        assert!(inp.update_position(fix, Some(1_000_000)));
        // A report stamped 10 ms before the fix is seen from 2 cm back; 10 ms after, 2 cm ahead.
        let near = |a: Option<Vec3>, b: Vec3| a.is_some_and(|a| (a - b).norm() < 1e-5);
        assert!(near(inp.position_at(990_000), Vec3::new(1.0, 1.98, -1.0)));
        assert!(near(inp.position_at(1_010_000), Vec3::new(1.0, 2.02, -1.0)));
        assert_eq!(inp.position_at(1_200_000), None, "beyond the position timeout");
        let ranking = Ranking::Nearest;
        let _ = inp.update_obstacles(
            990_000,
            &[ObstaclePoint::fixed(Vec3::x(), 1)],
            Some(1_000_000),
            ranking,
            0.1,
        );
        assert!(near(inp.obstacles_seen_from(), Vec3::new(1.0, 1.98, -1.0)));
    }
}
