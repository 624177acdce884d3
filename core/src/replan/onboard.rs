//! The replanner as a service beside the outer loop, the one driver both callers run: the
//! host's in-process controller (`parapet-sim`'s `fc/replan.rs`, all three parts in one outer
//! step) and the firmware (`parapet-firmware`'s `app/replanner.rs`: the planner in an embassy
//! task of its own, off the control loops; the request goes there and back by reference).
//!
//! 1. **Snapshot** (outer side, [`ReplanClock::snapshot`]): while a mission is flown (or the
//!    vehicle holds after the filter reported a stall, `deadlock`), at most every
//!    1 / `RPL_RATE` s, the vehicle's position, the stall flag, the remaining path (the
//!    waypoints from the segment being flown) and the obstacle points the filter was given are
//!    copied into a [`ReplanRequest`].
//! 2. **Plan** (planner side, [`Replanner::serve`]): the request's points are marked in the
//!    grid and [`Replanner::step`] runs on it (its trigger, cooldown and search, as the module
//!    `crate::replan` says); the outcome and the new path are written back into the request.
//! 3. **Apply** (outer side, [`apply`]): a new path is set with the guidance's `set_path`,
//!    whose reference continues from where it is, so it is flown through the same guidance and
//!    safety filter; after a stall the mission is started again. It is dropped when the
//!    mission changed while it was planned (the request's remaining path is no longer the end
//!    of the path flown). `NoPath` / `BudgetExceeded`: the vehicle keeps its path (the filter
//!    holds it in front of the blockage) and the event is reported; retried after the
//!    cooldown.
//!
//! May import: [`crate::outer`] (the loop it serves), the rest of `crate::replan`.

use super::{ReplanOutcome, ReplanParams, Replanner};
use crate::obstacle::ObstaclePoint;
use crate::outer::guidance::{GuidanceMode, PATH_CAPACITY};
use crate::outer::inputs::OBSTACLE_CAPACITY;
use crate::outer::{CommandError, OuterLoop, OuterTelemetry};
use crate::Vec3;

/// What the replanner needs of the loop it serves (the firmware's [`OuterLoop`], the host's
/// `FlightController` facade).
pub trait MissionControl {
    /// The outer loop's telemetry (mode, progress, position, stall flag).
    fn outer_telemetry(&self) -> &OuterTelemetry;
    /// The stored path's waypoints (NED).
    fn mission_path(&self) -> &[Vec3];
    /// Replace the path; a mission being flown continues on it from the reference.
    fn replace_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), CommandError>;
    /// Fly the stored path again (after a stall ended the mission in a hold).
    fn restart_mission(&mut self, now_us: u64) -> Result<(), CommandError>;
}

impl MissionControl for OuterLoop {
    fn outer_telemetry(&self) -> &OuterTelemetry {
        self.telemetry()
    }
    fn mission_path(&self) -> &[Vec3] {
        self.path()
    }
    fn replace_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), CommandError> {
        self.set_path(waypoints_ned)
    }
    fn restart_mission(&mut self, now_us: u64) -> Result<(), CommandError> {
        self.start_mission(now_us)
    }
}

/// One replanning request and, once served, its answer (≈ 3 KiB: keep it in a `static` or a
/// box and hand it over by reference).
#[derive(Clone, Debug)]
pub struct ReplanRequest {
    /// The `RPL_*` parameters the outer side flies (the planner follows their changes).
    pub params: ReplanParams,
    /// The hull radius, m.
    pub hull: f32,
    /// Time of the snapshot, µs (the replanner's clock).
    pub t_us: u64,
    /// The vehicle's position, NED m.
    pub position: Vec3,
    /// The guidance's reference position (on the path being flown), NED m: where the check of
    /// the remaining path starts.
    pub reference: Vec3,
    /// The filter reported a stall (`deadlock`).
    pub stalled: bool,
    /// The waypoints not yet reached.
    pub remaining: heapless::Vec<Vec3, PATH_CAPACITY>,
    /// The static and moving obstacle points the filter was given (the nearest
    /// [`OBSTACLE_CAPACITY`]).
    pub points: heapless::Vec<ObstaclePoint, OBSTACLE_CAPACITY>,
    /// The planner's result (`None`: not served yet, or no check was due).
    pub outcome: Option<ReplanOutcome>,
    /// The new path when `outcome` is `Replanned`.
    pub path: heapless::Vec<Vec3, PATH_CAPACITY>,
}

impl Default for ReplanRequest {
    fn default() -> Self {
        Self::new()
    }
}

impl ReplanRequest {
    /// An empty request with every field zero but `outcome` (`None`) — in memory that was
    /// zeroed instead (the firmware's `static` of it, in a section it zeroes at boot) `outcome`
    /// reads as a zero-waypoint `Replanned`, which nothing reads before a plan wrote it.
    pub const ZEROED: ReplanRequest = ReplanRequest::with_params(ReplanParams::ZEROED);

    /// An empty request.
    pub const fn new() -> Self {
        Self::with_params(ReplanParams::DEFAULT)
    }

    const fn with_params(params: ReplanParams) -> Self {
        ReplanRequest {
            params,
            hull: 0.0,
            t_us: 0,
            position: Vec3::new(0.0, 0.0, 0.0),
            reference: Vec3::new(0.0, 0.0, 0.0),
            stalled: false,
            remaining: heapless::Vec::new(),
            points: heapless::Vec::new(),
            outcome: None,
            path: heapless::Vec::new(),
        }
    }
}

/// When the outer side takes the next snapshot (`RPL_ENABLE`, `RPL_RATE`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplanClock {
    params: ReplanParams,
    hull: f32,
    period_us: u64,
    next_us: u64,
}

impl ReplanClock {
    /// The clock of the parameters `p` (invalid: the defaults, as [`Replanner::new`]) for a
    /// vehicle of hull radius `hull` m.
    pub fn new(p: &ReplanParams, hull: f32) -> Self {
        let params = p.checked();
        // The same period as the planner's own rate check (`Replanner::step`).
        let period_us = ((1.0 / params.rate_hz) * 1e6) as u64;
        ReplanClock { params, hull: super::sane_hull(hull), period_us, next_us: 0 }
    }

    /// Replanning is on.
    pub fn enabled(&self) -> bool {
        self.params.enable
    }

    /// At `now_us`: when a snapshot of `m` is due (module docs), fills `req` with it and the
    /// obstacle `points` given to the filter (the nearest [`OBSTACLE_CAPACITY`]) and returns
    /// `true`.
    pub fn snapshot(
        &mut self,
        now_us: u64,
        m: &impl MissionControl,
        points: &[ObstaclePoint],
        req: &mut ReplanRequest,
    ) -> bool {
        if !self.params.enable || now_us < self.next_us {
            return false;
        }
        let tel = m.outer_telemetry();
        let stalled = tel.plant_aware.deadlock;
        let flying = tel.mode == GuidanceMode::Mission || (stalled && tel.mode == GuidanceMode::Hold);
        if !flying || tel.progress.done {
            return false;
        }
        self.next_us = now_us.saturating_add(self.period_us);
        let path = m.mission_path();
        let remaining = path.get(usize::from(tel.progress.segment)..).unwrap_or(&[]);
        req.params = self.params;
        req.hull = self.hull;
        req.t_us = now_us;
        req.position = tel.position;
        req.reference = tel.reference.position;
        req.stalled = stalled;
        req.remaining.clear();
        let _ = req.remaining.extend_from_slice(&remaining[..remaining.len().min(PATH_CAPACITY)]);
        req.points.clear();
        let _ = req.points.extend_from_slice(&points[..points.len().min(OBSTACLE_CAPACITY)]);
        req.outcome = None;
        req.path.clear();
        true
    }
}

/// A replanning result worth reporting (every outcome but `NotNeeded`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplanEvent {
    /// What the plan did.
    pub outcome: ReplanOutcome,
    /// Waypoints of the new path (0 unless replanned).
    pub waypoints: u8,
    /// Detour waypoints before the rejoined mission (0 unless replanned).
    pub detour: u8,
}

impl Replanner {
    /// The planner side (module docs): take the request's parameters when they changed
    /// ([`Replanner::reconfigure`]), mark its points, run [`Replanner::step`] at its time,
    /// write the outcome and path into it.
    pub fn serve(&mut self, req: &mut ReplanRequest) {
        if req.params != self.params || req.hull != self.hull {
            self.reconfigure(req.params, req.hull);
        }
        self.observe(&req.position, &req.points);
        let ReplanRequest { t_us, position, reference, stalled, remaining, points, outcome, path, .. } = req;
        *outcome = self.step(*t_us, position, reference, *stalled, remaining, points, path);
    }
}

/// The outer side's last part (module docs): a served request's new path onto `m` at
/// `now_us`; the event to report, if any.
pub fn apply(now_us: u64, m: &mut impl MissionControl, req: &ReplanRequest) -> Option<ReplanEvent> {
    let outcome = req.outcome?;
    let event =
        |waypoints: usize, detour: u8| ReplanEvent { outcome, waypoints: waypoints.min(255) as u8, detour };
    match outcome {
        ReplanOutcome::NotNeeded => None,
        ReplanOutcome::Replanned { detour, .. } => {
            // Planned for a mission that has since changed (a new upload): dropped.
            if !m.mission_path().ends_with(&req.remaining) || m.replace_path(&req.path).is_err() {
                return None;
            }
            if req.stalled {
                let _ = m.restart_mission(now_us);
            }
            Some(event(req.path.len(), detour))
        }
        ReplanOutcome::NoPath | ReplanOutcome::BudgetExceeded => Some(event(0, 0)),
    }
}
