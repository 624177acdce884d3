//! The on-board replanner of the in-process controller (issue 38): `parapet_core::replan`'s
//! [`Replanner`] run beside the [`FlightController`] through the driver the firmware's replanner
//! task runs too ([`parapet_core::replan::onboard`]), all in one outer step here: after each
//! outer step, when a snapshot is due (`RPL_RATE`, while a mission is flown or a stall holds
//! it), the controller's position, stall flag and remaining path and the obstacle points it kept
//! of those given (ground truth's closest points, or the obstacle memory's points with range sensing)
//! are served by the planner at once and a new path is set (the reference continues from where
//! it is; after a `deadlock` the mission is started again). Every result other than
//! `NotNeeded` is an event ([`ReplanSummary`], `summary.json`).
//!
//! May import: `parapet-core`, [`crate::report`] (the summary's types).

use parapet_core::controller::FlightController;
use parapet_core::replan::onboard::{apply, ReplanClock, ReplanRequest};
use parapet_core::replan::{ReplanOutcome, Replanner};

use crate::report::{ReplanEvent, ReplanSummary};

/// The replanner, its clock, its request and its record.
#[derive(Clone, Debug)]
pub struct OnboardReplan {
    core: Box<Replanner>,
    clock: ReplanClock,
    request: Box<ReplanRequest>,
    summary: ReplanSummary,
}

impl OnboardReplan {
    /// The replanner of a controller with `fc`'s parameters (`RPL_*`, hull radius), its
    /// detours kept inside the flight area `area` (NED x, y min and max, m: the scene's bounds,
    /// as a geofence).
    pub fn new(fc: &FlightController, area: ([f32; 2], [f32; 2])) -> Self {
        let p = fc.params();
        let mut core = Box::new(Replanner::new(p.replan, p.hull_radius));
        core.set_area(Some(area));
        OnboardReplan {
            core,
            clock: ReplanClock::new(&p.replan, p.hull_radius),
            request: Box::default(),
            summary: ReplanSummary { replan_enabled: p.replan.enable, ..ReplanSummary::default() },
        }
    }

    /// After the outer step at `now_us` (simulated `t` s), with the obstacle points the
    /// controller kept of those it was given (the nearest 32: what the firmware's outer loop
    /// holds too).
    pub fn step(&mut self, t: f64, now_us: u64, fc: &mut FlightController) {
        if !self.clock.snapshot(now_us, fc, fc.obstacles(), &mut self.request) {
            return;
        }
        self.core.serve(&mut self.request);
        let Some(e) = apply(now_us, fc, &self.request) else { return };
        let outcome = match e.outcome {
            ReplanOutcome::Replanned { .. } => "replanned",
            ReplanOutcome::NoPath => "no_path",
            ReplanOutcome::BudgetExceeded | ReplanOutcome::NotNeeded => "budget",
        };
        let s = self.core.stats();
        self.summary.replan_checks = s.checks;
        self.summary.replans = s.replans;
        self.summary.replan_no_path = s.no_path;
        self.summary.replan_budget = s.budget;
        let (waypoints, detour) = (usize::from(e.waypoints), usize::from(e.detour));
        self.summary.replan_events.push(ReplanEvent { t_s: t, outcome, waypoints, detour });
    }

    /// New paths set so far.
    pub fn replans(&self) -> u32 {
        self.summary.replans
    }

    /// The record so far.
    pub fn summary(&self) -> ReplanSummary {
        ReplanSummary { replan_checks: self.core.stats().checks, ..self.summary.clone() }
    }
}
