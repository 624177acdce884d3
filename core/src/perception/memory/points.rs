//! The memory's obstacle points for the controller: each cell's box point nearest the
//! vehicle (proven moving tracks extrapolated with their velocity; unproven ones with their
//! closing-in estimate, `super::super::track::Track::approach_velocity`, not extrapolated),
//! the frontier's point and walls, handed to a closure
//! or offered to the obstacle-set policy (`crate::obstacle_set`), a cell's point built only
//! when the set keeps it.
//!
//! May import: the parent module (its private fields), the perception module's ids and
//! frontier helpers, `crate::obstacle`, `crate::obstacle_set`, `crate::fmath`, `crate::Vec3`.

use super::super::{CELL_ID_BASE, FOV_WALLS_OFF, FRONTIER_ID, STATIC_ID};
use super::{clamp3, clamp3_no_nan, ObstacleMemory, NO_TRACK};
use crate::fmath::hypotf;
use crate::obstacle::{ObstaclePoint, ObstacleSet};
use crate::obstacle_set::{Ranking, Selector, SetReport};
use crate::perception::frontier::{closes_in, ignore_beyond};
use crate::Vec3;

impl<const N: usize> ObstacleMemory<N> {
    /// Calls `f` with the obstacle points for a vehicle at `p` moving at `v` (NED) at
    /// `t_us`: one per cell remembered (not older than `forget_s`, or a static one within
    /// `keep_near` of `p`; the box point nearest `p`; moving
    /// tracks extrapolated, with their velocity), then the frontier point (when the
    /// direction of motion has not been observed free far enough). O(N).
    pub fn for_each_point(&mut self, t_us: u64, p: &Vec3, v: &Vec3, mu: f32, f: impl FnMut(&ObstaclePoint)) {
        /// Every point built and handed to the closure.
        struct Each<F>(F);
        impl<F: FnMut(&ObstaclePoint)> PointSink for Each<F> {
            fn cell(&mut self, point: &Vec3, velocity: Option<&Vec3>, id: u16) {
                (self.0)(&ObstaclePoint { point: *point, velocity: velocity.copied(), id, normal: None });
            }
            fn point(&mut self, o: &ObstaclePoint) {
                (self.0)(o);
            }
        }
        self.points_into(t_us, p, v, mu, &mut Each(f));
    }

    /// [`Self::for_each_point`] into `sink` (a cell's point as its parts).
    fn points_into<S: PointSink>(&mut self, t_us: u64, p: &Vec3, v: &Vec3, mu: f32, sink: &mut S) {
        // A static cell's box is finite (built from plausible returns): with `p` not NaN the
        // NaN-free clamp gives the same point (a moving cell's shifted box is not checked).
        let p_no_nan = !(p.x.is_nan() || p.y.is_nan() || p.z.is_nan());
        let mut threat = false;
        for c in self.cells.iter() {
            if !self.remembered(c, t_us, p) {
                continue;
            }
            let age_us = t_us.saturating_sub(c.t_us);
            let track = (c.track != NO_TRACK).then(|| self.tracker.get(usize::from(c.track))).flatten();
            let w = track.and_then(|tr| tr.measured_velocity(t_us));
            let shift = w.map_or_else(Vec3::zeros, |w| w * (age_us as f32 * 1e-6));
            let q = if p_no_nan && w.is_none() {
                clamp3_no_nan(p, &(c.lo + shift), &(c.hi + shift))
            } else {
                clamp3(p, &(c.lo + shift), &(c.hi + shift))
            };
            threat |= w.is_some_and(|w| closes_in(&(p - q), &w));
            let id = if c.track == NO_TRACK { STATIC_ID } else { CELL_ID_BASE + u16::from(c.track) };
            // An unproven track's closing-in part only (not extrapolated, no evasion cap).
            let approach =
                if w.is_none() { track.and_then(|tr| tr.approach_velocity(t_us, &(p - q))) } else { None };
            sink.cell(&q, w.or(approach).as_ref(), id);
        }
        if self.now_us.is_some() {
            let far = ignore_beyond(mu, hypotf(v.x, v.y).max(1.0) * 2.0);
            let walls = self.params.fov_walls != FOV_WALLS_OFF;
            // No new wall while a seen mover closes in (the motion is the evasion): the cap.
            if let Some(q) = self.frontier.point(p, v, self.params.fov_margin, far, walls && !threat) {
                sink.point(&ObstaclePoint { point: q, velocity: None, id: FRONTIER_ID, normal: None });
            }
            // Where the observed free range is used up: walls, as half-spaces.
            if walls {
                self.frontier.walls(p, far, |q, n| {
                    sink.point(&ObstaclePoint { point: q, velocity: None, id: FRONTIER_ID, normal: Some(n) });
                });
            }
        }
    }

    /// The points of [`Self::for_each_point`] selected by the controller's set policy
    /// (`crate::obstacle_set`, `M` most critical) and the selection report.
    pub fn select<const M: usize>(
        &mut self,
        t_us: u64,
        p: &Vec3,
        v: &Vec3,
        ranking: Ranking,
        delta1: f32,
    ) -> (ObstacleSet<M>, SetReport) {
        self.select_with(t_us, p, v, ranking, Selector::<M>::new(ranking, delta1, p, v))
    }

    /// [`Self::select`]'s set alone (the same points in the same slots; the dropped points
    /// are not counted: [`Selector::set_only`]).
    pub fn select_set<const M: usize>(
        &mut self,
        t_us: u64,
        p: &Vec3,
        v: &Vec3,
        ranking: Ranking,
        delta1: f32,
    ) -> ObstacleSet<M> {
        self.select_with(t_us, p, v, ranking, Selector::<M>::set_only(ranking, delta1, p, v)).0
    }

    fn select_with<const M: usize>(
        &mut self,
        t_us: u64,
        p: &Vec3,
        v: &Vec3,
        ranking: Ranking,
        selector: Selector<M>,
    ) -> (ObstacleSet<M>, SetReport) {
        /// Cells offered as parts: a point is built only when the set keeps it.
        struct Offers<const M: usize>(Selector<M>);
        impl<const M: usize> PointSink for Offers<M> {
            #[inline(always)]
            fn cell(&mut self, point: &Vec3, velocity: Option<&Vec3>, id: u16) {
                self.0.offer_point(point, velocity, id);
            }
            fn point(&mut self, o: &ObstaclePoint) {
                self.0.offer(o);
            }
        }
        let mu = match ranking {
            Ranking::Critical { mu, .. } => mu,
            Ranking::Nearest => 1.4,
        };
        let mut sel = Offers(selector);
        self.points_into(t_us, p, v, mu, &mut sel);
        sel.0.finish()
    }
}

/// Where [`ObstacleMemory::for_each_point`]'s points go.
trait PointSink {
    /// A cell's point `point` (NED), its track's velocity, its id.
    fn cell(&mut self, point: &Vec3, velocity: Option<&Vec3>, id: u16);
    /// The frontier's points.
    fn point(&mut self, o: &ObstaclePoint);
}
