//! The on-board replanner of the in-process controller (issue 38): `parapet_core::replan`'s
//! [`Replanner`] run beside the [`FlightController`] as the firmware would run it, off the
//! control loops: every outer step it marks the obstacle points the filter was given (the
//! controller's own input: ground truth's closest points, or the obstacle memory's points
//! with range sensing) in its grid; at `RPL_RATE` it checks the controller's remaining path
//! (`FlightController::path` from the segment being flown) and, on a new path, sets it with
//! `FlightController::set_path` (the reference continues from where it is; after a `deadlock`
//! the mission is started again). Every result other than `NotNeeded` is an event
//! ([`ReplanSummary`], `summary.json`).
//!
//! May import: `parapet-core`, [`crate::report`] (the summary's types).

use parapet_core::controller::{FlightController, GuidanceMode};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::outer::guidance::PATH_CAPACITY;
use parapet_core::replan::{ReplanOutcome, Replanner};
use parapet_core::Vec3;

use crate::report::{ReplanEvent, ReplanSummary};

/// The replanner, its output buffer and its record.
#[derive(Clone, Debug)]
pub struct OnboardReplan {
    core: Box<Replanner>,
    buf: heapless::Vec<Vec3, PATH_CAPACITY>,
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
            buf: heapless::Vec::new(),
            summary: ReplanSummary { replan_enabled: p.replan.enable, ..ReplanSummary::default() },
        }
    }

    /// After the outer step at `now_us` (simulated `t` s) that was given `obstacles`.
    pub fn step(&mut self, t: f64, now_us: u64, fc: &mut FlightController, obstacles: &[ObstaclePoint]) {
        if !self.summary.replan_enabled {
            return;
        }
        let tel = fc.telemetry();
        self.core.observe(&tel.position, obstacles);
        let stalled = tel.plant_aware.deadlock;
        let flying = tel.mode == GuidanceMode::Mission || (stalled && tel.mode == GuidanceMode::Hold);
        if !flying || tel.progress.done {
            return;
        }
        let path = fc.path();
        let remaining = &path[usize::from(tel.progress.segment).min(path.len())..];
        let Some(r) = self.core.step(now_us, &tel.position, stalled, remaining, obstacles, &mut self.buf)
        else {
            return;
        };
        let (outcome, waypoints, detour) = match r {
            ReplanOutcome::NotNeeded => return,
            ReplanOutcome::Replanned { detour, .. } => {
                if fc.set_path(&self.buf).is_err() {
                    return;
                }
                if stalled {
                    let _ = fc.start_mission(now_us);
                }
                ("replanned", self.buf.len(), usize::from(detour))
            }
            ReplanOutcome::NoPath => ("no_path", 0, 0),
            ReplanOutcome::BudgetExceeded => ("budget", 0, 0),
        };
        let s = self.core.stats();
        self.summary.replan_checks = s.checks;
        self.summary.replans = s.replans;
        self.summary.replan_no_path = s.no_path;
        self.summary.replan_budget = s.budget;
        self.summary.replan_events.push(ReplanEvent { t_s: t, outcome, waypoints, detour });
    }

    /// The record so far.
    pub fn summary(&self) -> ReplanSummary {
        ReplanSummary { replan_checks: self.core.stats().checks, ..self.summary.clone() }
    }
}
