//! Mission executor: runs the accepted plan item by item through the cascade's commands and
//! modes, and maps the flight to the ground station's item numbers.
//!
//! ```text
//!  MISSION_START / DO_SET_MODE Mission
//!    plan has NAV_TAKEOFF, armed on the ground or airborne ─▶ TakingOff (cascade Takeoff to its
//!                                                             height: climb, or descend when above)
//!    no NAV_TAKEOFF, a path, armed on the ground           ─▶ TakingOff (the cascade's default height)
//!    no NAV_TAKEOFF, airborne (Hover / Takeoff phase)      ─▶ the first item
//!  TakingOff ── the ramp seen, then Hover ─▶ the item after the climb
//!  an item (MissionUpload::next_from): points ─▶ Flying (the cascade's path follower through the
//!    points up to the first item with an action); an action where the vehicle is ─▶ Acting;
//!    NAV_LAND / NAV_RETURN_TO_LAUNCH ─▶ Ending (cascade Land / Return mode); none left ─▶ Done
//!  Flying ──── follower done ───────▶ the last point's action (Acting), the end, or the next item
//!  Acting ──── hold time over / heading reached / speed set ─▶ the next item (LOITER_UNLIM: never)
//!  Ending ──── disarmed on the ground ─▶ Done
//!  disarmed, a failsafe, Landing or another mode selected while TakingOff/Flying/Acting ─▶ Idle (paused)
//! ```
//!
//! Every segment is flown by the cascade's own guidance (takeoff ramp, path follower, Land,
//! Return), so the safety filter is in the loop throughout; this module only issues the
//! commands a pilot would, at the link's poll rate (≥ 10 Hz, so an action starts within one
//! poll period of the follower's arrival). The path is handed to the cascade one segment at a
//! time (`set_path` with the points up to the next item with an action; a plan without such
//! items is one segment, the whole path, as before). A segment longer than the cascade holds
//! (`PATH_CAPACITY`, 64) is given to it in windows: the first 64 points, then at each poll
//! `Autopilot::stream_path` with the points not yet given (issue 38,
//! `parapet_core::outer::path_stream`: the cascade tops its path up once 16 are passed and its
//! trajectory runs on without stopping). Actions ([`crate::link::mission_items`]):
//! a hold (NAV_WAYPOINT p1 after reaching p2, NAV_LOITER_TIME, NAV_DELAY) keeps the vehicle at
//! the reference where the segment ended, NAV_LOITER_UNLIM until another mode or plan;
//! CONDITION_YAW sets the cascade's yaw reference and waits for the heading; DO_CHANGE_SPEED
//! sets the path speed of the following segments (reset to `WP_SPEED` at every start). A plan
//! without TAKEOFF started armed on the ground takes off by itself (issue 41; as PX4): the
//! cascade's default takeoff (1 m, capped by `MIS_TKO_ALT_MAX`), then the items.
//!
//! [`MissionRun::progress`] gives MISSION_CURRENT / MISSION_ITEM_REACHED in the uploaded seq
//! numbers ([`crate::link::services`] emits them): the item being flown and the last item done
//! (ignored DO_* items count as done with the navigation item before them; NAV_TAKEOFF when the
//! climb ends, a waypoint when the follower passes it (a held one on arrival), a hold, delay or
//! yaw when it is over, NAV_LAND / RTL when the vehicle has landed and disarmed).
//!
//! May import: [`crate::app::autopilot`] (the `Autopilot` boundary), [`crate::link::mission`],
//! [`crate::link::mission_items`], the dialect. O(1) state, every call
//! O([`crate::link::mission::MAX_WAYPOINTS`]²) at most (a transition's item scan).

use crate::app::autopilot::{
    Autopilot, CommandRejected, FlightMode, FlightPhase, TelemetrySnapshot, VehicleCommand,
};
use crate::link::dialect::MissionState;
use crate::link::mission::{EndAction, MissionUpload, Next};
use crate::link::mission_items::{self, Action};
use parapet_core::replan::ReplanOutcome;
use parapet_core::Vec3;

/// A new segment's follower fields are its own after this, µs (a few outer steps: the
/// snapshot of the step before still shows the previous segment done).
const SEGMENT_SETTLE_US: u64 = 40_000;

/// The cascade's path capacity, in the executor's point numbers.
const CAP: u16 = parapet_core::controller::PATH_CAPACITY as u16;

/// Executor state (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Run {
    /// Not running the plan (never started, or paused by another command or a failsafe).
    Idle,
    /// The cascade's takeoff ramp goes to the plan's takeoff height; `seen` once its phase
    /// showed Takeoff (before, a Hover is the state before the command took effect).
    TakingOff { seen: bool },
    /// The cascade flies path points `from..=to` (item `last` is point `to`'s); `seen` once
    /// the snapshot's follower fields are this segment's (from `since_us` +
    /// [`SEGMENT_SETTLE_US`] in phase Mission). Streamed (a segment longer than the cascade
    /// holds): its path is points `win..sent` (`sent` > `to` once all are given).
    Flying { seen: bool, since_us: u64, from: u16, to: u16, last: u16, win: u16, sent: u16 },
    /// Item `seq`'s action.
    Acting { seq: u16, step: Acting },
    /// The end action (LAND / RTL item `seq`) runs until the vehicle disarms.
    Ending { seq: u16 },
    /// The whole plan was flown.
    Done,
}

/// Where an action is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Acting {
    /// A hold waits until the vehicle is within `radius_m` of `at`.
    Arriving { at: Vec3, radius_m: f32, secs: Option<f32> },
    /// Holding until `until_us` (`None`: unlimited).
    Holding { until_us: Option<u64> },
    /// Turning to `yaw` (rad) since `since_us`.
    Turning { yaw: f32, since_us: u64 },
}

/// MISSION_CURRENT / MISSION_ITEM_REACHED state in the uploaded seq numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MissionProgress {
    /// Items of the accepted plan.
    pub total: u16,
    /// The item being flown (MISSION_CURRENT `seq`).
    pub current: u16,
    /// The last item done, if any (MISSION_ITEM_REACHED up to it).
    pub reached: Option<u16>,
    /// MISSION_CURRENT `mission_state`.
    pub state: MissionState,
    /// MISSION_CURRENT `mission_id`: the accepted plan's id ([`MissionUpload::plan_id`]).
    pub mission_id: u32,
}

impl MissionProgress {
    /// No plan.
    pub const NONE: Self = Self {
        total: 0,
        current: 0,
        reached: None,
        state: MissionState::MISSION_STATE_NO_MISSION,
        mission_id: 0,
    };
}

/// The mission executor (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct MissionRun {
    run: Run,
    /// The plan was started since it was uploaded.
    started: bool,
    /// The item being flown when paused (MISSION_CURRENT while Idle).
    current: u16,
    /// The last item done.
    reached: Option<u16>,
    /// The replanner's event count last seen ([`MissionRun::follow_replan`]; kept by
    /// [`MissionRun::reset`]).
    replan_events: u16,
}

impl Default for MissionRun {
    fn default() -> Self {
        Self::new()
    }
}

fn airborne(s: &TelemetrySnapshot) -> bool {
    s.armed && matches!(s.phase, FlightPhase::Hover | FlightPhase::Takeoff | FlightPhase::Mission)
}

fn dist(a: Vec3, b: Vec3) -> f32 {
    let d = a - b;
    libm::sqrtf(d.x * d.x + d.y * d.y + d.z * d.z)
}

impl MissionRun {
    /// Nothing started.
    pub const fn new() -> Self {
        Self { run: Run::Idle, started: false, current: 0, reached: None, replan_events: 0 }
    }

    /// A new plan was accepted, or the plan was cleared: not started.
    pub fn reset(&mut self) {
        *self = Self { replan_events: self.replan_events, ..Self::new() };
    }

    /// The on-board replanner set a new path (issue 38: a new event in the snapshot, a
    /// `Replanned` one): the items of the flight being flown (before one is flown: the plan's
    /// first) become the path the cascade flies ([`MissionUpload::replanned`]), and the flight
    /// counts in the new items, so MISSION_CURRENT does. `true` when the plan changed.
    pub fn follow_replan<A: Autopilot>(&mut self, m: &mut MissionUpload, ap: &A) -> bool {
        let r = ap.telemetry().replan;
        if r.events == self.replan_events {
            return false;
        }
        self.replan_events = r.events;
        let replanned = r.last.is_some_and(|e| matches!(e.outcome, ReplanOutcome::Replanned { .. }));
        // The points the cascade's path held before the replan: `win..sent` of the flight.
        let (from, to, last, win, sent) = match (self.run, m.next_from(0)) {
            (Run::Flying { from, to, last, win, sent, .. }, _) => (from, to, last, win, sent),
            // Not flying: the cascade holds the first flight's first points (the upload's set_path).
            (_, Next::Fly { from, to, last }) => {
                (from, to, last, from, (to + 1).min(from.saturating_add(CAP)))
            }
            _ => return false,
        };
        let flown = ap.flown_path();
        let end = if sent > to { Some(last) } else { sent.checked_sub(1).and_then(|k| m.path_seq(k)) };
        if !replanned || end.and_then(|end| m.replanned(flown, win, end)).is_none() {
            return false;
        }
        // Those points are the flown path's now: what follows them moved by the difference.
        let sent_now = win.saturating_add(flown.len() as u16);
        let shift = |k: u16| {
            (i32::from(k) + i32::from(sent_now) - i32::from(sent)).clamp(0, i32::from(u16::MAX)) as u16
        };
        let (to, last) = (shift(to), shift(last));
        if let Run::Flying { seen, since_us, .. } = self.run {
            self.run = Run::Flying { seen, since_us, from, to, last, win, sent: sent_now };
        }
        let first = m.path_seq(from).unwrap_or(0);
        (self.current, self.reached) = (first, self.reached.filter(|&q| q < first));
        true
    }

    /// `true` when a mission start on the ground would take off (the plan has NAV_TAKEOFF, or a
    /// path: then the cascade's default takeoff first).
    pub fn takes_off(m: &MissionUpload) -> bool {
        let plan = m.plan();
        plan.takeoff.is_some() || plan.path_len > 0
    }

    /// MISSION_START (or DO_SET_MODE Mission) at `now_us`: with a TAKEOFF item, armed on the
    /// ground or airborne, the cascade's takeoff ramp to the item's height where the vehicle is
    /// (airborne: up or down to it, as PX4 flies a TAKEOFF item in the air); else the first
    /// item. The path speed is reset to `WP_SPEED`. The cascade's refusal is returned.
    pub fn start<A: Autopilot>(
        &mut self,
        m: &MissionUpload,
        now_us: u64,
        ap: &mut A,
    ) -> Result<(), CommandRejected> {
        let plan = m.plan();
        let s = ap.telemetry();
        let on_ground = s.armed && s.phase == FlightPhase::Idle;
        let height = match plan.takeoff {
            Some((_, h)) if on_ground || airborne(&s) => Some(Some(h)),
            // No TAKEOFF item, armed on the ground: the cascade's default takeoff first, as PX4
            // takes off to MIS_TAKEOFF_ALT before a plan without one.
            None if on_ground && plan.path_len > 0 => Some(None),
            _ => None,
        };
        if let Some(height_m) = height {
            ap.command(now_us, VehicleCommand::Takeoff { height_m })?;
            let _ = ap.command(now_us, VehicleCommand::SetSpeed { m_s: None });
            *self = Self {
                run: Run::TakingOff { seen: false },
                started: true,
                current: 0,
                reached: None,
                ..*self
            };
            self.current = plan.takeoff.map_or(0, |t| t.0);
            return Ok(());
        }
        if !airborne(&s) || plan.count == 0 {
            // The cascade's own refusal (not armed, not flying, no path).
            ap.command(now_us, VehicleCommand::StartMission)?;
        }
        let _ = ap.command(now_us, VehicleCommand::SetSpeed { m_s: None });
        *self = Self { run: Run::Idle, started: true, current: 0, reached: None, ..*self };
        match self.next(m, 0, now_us, ap) {
            Err(e) => {
                self.run = Run::Idle;
                Err(e)
            }
            Ok(()) => Ok(()),
        }
    }

    /// Runs the plan from item `seq` on ([`MissionUpload::next_from`]).
    fn next<A: Autopilot>(
        &mut self,
        m: &MissionUpload,
        seq: u16,
        now_us: u64,
        ap: &mut A,
    ) -> Result<(), CommandRejected> {
        // Speed changes take effect at once and go on: at most one per item.
        let mut seq = seq;
        for _ in 0..crate::link::mission::MAX_WAYPOINTS {
            match m.next_from(seq) {
                Next::Fly { from, to, last } => {
                    self.current = m.path_seq(from).unwrap_or(last);
                    return self.fly(m, from, to, last, now_us, ap);
                }
                Next::Act(q) => {
                    if let Some(Action::Speed(v)) = m.action_at(q) {
                        let _ = ap.command(now_us, VehicleCommand::SetSpeed { m_s: v });
                        self.reached = Some(m.done_through(q));
                        seq = q + 1;
                        continue;
                    }
                    self.act(m, q, None, now_us, ap);
                    return Ok(());
                }
                Next::End(q) => {
                    self.end(q, m.plan().end.map(|e| e.1), now_us, ap);
                    return Ok(());
                }
                Next::Done => {
                    self.run = Run::Done;
                    return Ok(());
                }
            }
        }
        self.run = Run::Done;
        Ok(())
    }

    /// Flies path points `from..=to` (see [`Run::Flying`]).
    fn fly<A: Autopilot>(
        &mut self,
        m: &MissionUpload,
        from: u16,
        to: u16,
        last: u16,
        now_us: u64,
        ap: &mut A,
    ) -> Result<(), CommandRejected> {
        let path = m.accepted_path();
        let seg = path.get(usize::from(from)..=usize::from(to)).unwrap_or(&[]);
        // A segment longer than the cascade holds: the first window, the rest streamed.
        let seg = seg.get(..seg.len().min(usize::from(CAP))).unwrap_or(&[]);
        let sent = from.saturating_add(seg.len() as u16);
        if ap.set_path(seg).is_err() {
            self.run = Run::Idle;
            return Err(CommandRejected::Invalid);
        }
        // In phase Mission the new path restarts the follower from the reference itself.
        if ap.telemetry().phase != FlightPhase::Mission {
            if let Err(e) = ap.command(now_us, VehicleCommand::StartMission) {
                self.run = Run::Idle;
                return Err(e);
            }
        }
        self.run = Run::Flying { seen: false, since_us: now_us, from, to, last, win: from, sent };
        Ok(())
    }

    /// Starts item `seq`'s action where the vehicle is (`at`: the point just flown to).
    fn act<A: Autopilot>(&mut self, m: &MissionUpload, seq: u16, at: Option<Vec3>, now_us: u64, ap: &mut A) {
        self.current = seq;
        let s = ap.telemetry();
        let step = match m.action_at(seq) {
            Some(Action::Hold { secs, radius_m }) => {
                Acting::Arriving { at: at.unwrap_or(s.setpoint.position_ned), radius_m, secs }
            }
            Some(Action::Yaw { deg, dir, relative }) => {
                let yaw = mission_items::yaw_target(deg, dir, relative, s.attitude_rpy.z);
                if ap.command(now_us, VehicleCommand::SetYaw { yaw_rad: yaw }).is_err() {
                    self.run = Run::Idle;
                    return;
                }
                Acting::Turning { yaw, since_us: now_us }
            }
            // Speed is set in `next`; nothing else acts.
            Some(Action::Speed(_)) | None => Acting::Holding { until_us: Some(now_us) },
        };
        self.run = Run::Acting { seq, step };
    }

    /// Starts the end action of item `seq` (or finishes).
    fn end<A: Autopilot>(&mut self, seq: u16, action: Option<EndAction>, now_us: u64, ap: &mut A) {
        self.current = seq;
        self.run = match action {
            Some(action) => {
                let cmd = match action {
                    EndAction::Land => VehicleCommand::Land,
                    EndAction::Return => VehicleCommand::SetMode(FlightMode::Return),
                };
                match ap.command(now_us, cmd) {
                    Ok(()) => Run::Ending { seq },
                    Err(_) => Run::Idle,
                }
            }
            None => Run::Done,
        };
    }

    /// Periodic step (the link's poll): the transitions of the module docs.
    pub fn poll<A: Autopilot>(&mut self, m: &MissionUpload, now_us: u64, ap: &mut A) {
        let s = ap.telemetry();
        let in_mission = s.armed
            && s.mode == FlightMode::Mission
            && matches!(s.phase, FlightPhase::Hover | FlightPhase::Mission);
        match self.run {
            Run::Idle | Run::Done => {}
            Run::TakingOff { seen } => {
                let seen = seen || s.phase == FlightPhase::Takeoff;
                // Until the ramp shows, the phase is the one the command was given in.
                let before =
                    !seen && matches!(s.phase, FlightPhase::Idle | FlightPhase::Hover | FlightPhase::Mission);
                if !s.armed
                    || s.mode != FlightMode::Mission
                    || !(before || matches!(s.phase, FlightPhase::Takeoff | FlightPhase::Hover))
                {
                    self.run = Run::Idle;
                } else if seen && s.phase == FlightPhase::Hover {
                    let plan = m.plan();
                    let first = plan.takeoff.map_or(0, |t| t.0);
                    if plan.takeoff.is_some() {
                        self.reached = Some(m.done_through(first));
                    }
                    if self.next(m, first, now_us, ap).is_err() {
                        self.run = Run::Idle;
                    }
                } else {
                    self.run = Run::TakingOff { seen };
                }
            }
            Run::Flying { seen, since_us, from, to, last, win, sent } => {
                let seen =
                    seen || (s.phase == FlightPhase::Mission && now_us >= since_us + SEGMENT_SETTLE_US);
                if !in_mission {
                    self.pause(m, &s);
                } else if seen && s.mission_done && sent > to {
                    self.arrived(m, to, last, now_us, ap);
                } else if seen && s.mission_done {
                    // A window flown to its end before the rest could follow: fly on from there.
                    if self.fly(m, sent, to, last, now_us, ap).is_err() {
                        self.run = Run::Idle;
                    }
                } else if sent <= to && in_mission {
                    // The segment's points not given yet, as the cascade takes them.
                    let path = m.accepted_path();
                    let waiting = path.get(usize::from(sent)..=usize::from(to)).unwrap_or(&[]);
                    let sent = sent.saturating_add(ap.stream_path(waiting) as u16);
                    let win = sent.saturating_sub(ap.flown_path().len() as u16);
                    self.run = Run::Flying { seen, since_us, from, to, last, win, sent };
                } else {
                    self.run = Run::Flying { seen, since_us, from, to, last, win, sent };
                }
            }
            Run::Acting { seq, step } => {
                if !in_mission {
                    self.run = Run::Idle;
                    return;
                }
                let done = match step {
                    Acting::Arriving { at, radius_m, secs } => {
                        if radius_m <= 0.0 || dist(s.position_ned, at) <= radius_m {
                            let until_us = secs.map(|t| now_us + (t * 1e6) as u64);
                            self.run = Run::Acting { seq, step: Acting::Holding { until_us } };
                        }
                        false
                    }
                    Acting::Holding { until_us } => until_us.is_some_and(|t| now_us >= t),
                    Acting::Turning { yaw, since_us } => {
                        mission_items::yaw_reached(s.attitude_rpy.z, yaw)
                            || now_us.saturating_sub(since_us) >= mission_items::YAW_TIMEOUT_US
                    }
                };
                if done {
                    self.reached = Some(m.done_through(seq));
                    if self.next(m, seq + 1, now_us, ap).is_err() {
                        self.run = Run::Idle;
                    }
                }
            }
            Run::Ending { .. } => {
                if !s.armed {
                    self.run = Run::Done;
                }
            }
        }
    }

    /// The follower reached point `to` (item `last`): its action, the end, or the next items.
    fn arrived<A: Autopilot>(&mut self, m: &MissionUpload, to: u16, last: u16, now_us: u64, ap: &mut A) {
        if m.ends_at(last) {
            // A LAND item's approach point: reaching it is not reaching the LAND item.
            self.reached = last.checked_sub(1).map(|q| m.done_through(q)).max(self.reached);
            self.end(last, m.plan().end.map(|e| e.1), now_us, ap);
            return;
        }
        // Reached on arrival, a held waypoint or loiter too (as PX4), before its hold.
        self.reached = Some(m.done_through(last)).max(self.reached);
        if m.action_at(last).is_some_and(|a| !matches!(a, Action::Speed(_))) {
            let at = m.accepted_path().get(usize::from(to)).copied();
            self.act(m, last, at, now_us, ap);
        } else if self.next(m, last + 1, now_us, ap).is_err() {
            self.run = Run::Idle;
        }
    }

    /// Another command took the vehicle (a reposition): paused where it was.
    pub fn stop(&mut self) {
        if !matches!(self.run, Run::Done) {
            self.started = true;
            self.run = Run::Idle;
        }
    }

    /// Paused while flying a segment: remember the item being flown.
    fn pause(&mut self, m: &MissionUpload, s: &TelemetrySnapshot) {
        if let Run::Flying { seen: true, to, win, .. } = self.run {
            let k = win.saturating_add(s.mission_seq).min(to);
            self.current = m.path_seq(k).unwrap_or(self.current);
        }
        self.run = Run::Idle;
    }

    /// MISSION_CURRENT / MISSION_ITEM_REACHED state for plan `m` and snapshot `s`.
    pub fn progress(&self, m: &MissionUpload, s: &TelemetrySnapshot) -> MissionProgress {
        let plan = m.plan();
        let total = plan.count;
        if total == 0 {
            return MissionProgress::NONE;
        }
        let last = total - 1;
        // A mission flown without this executor (e.g. the cascade's own mode switch) counts too.
        let flying = s.mode == FlightMode::Mission && s.phase == FlightPhase::Mission;
        if !self.started && !flying {
            return MissionProgress {
                total,
                current: 0,
                reached: None,
                state: MissionState::MISSION_STATE_NOT_STARTED,
                mission_id: m.plan_id(),
            };
        }
        let run = match self.run {
            Run::Idle if !self.started => {
                let to = plan.path_len.saturating_sub(1);
                let last = m.path_seq(to).unwrap_or(last);
                Run::Flying { seen: true, since_us: 0, from: 0, to, last, win: 0, sent: to.saturating_add(1) }
            }
            r => r,
        };
        let active = MissionState::MISSION_STATE_ACTIVE;
        let done = |seq: Option<u16>| seq.map(|q| m.done_through(q));
        let (current, reached, state) = match run {
            Run::Done => (last, Some(last), MissionState::MISSION_STATE_COMPLETE),
            Run::Ending { seq } => (seq, done(seq.checked_sub(1)).max(self.reached), active),
            Run::TakingOff { .. } => (self.current, self.current.checked_sub(1), active),
            Run::Acting { seq, .. } => (seq, self.reached, active),
            Run::Flying { seen: false, .. } => (self.current, self.reached, active),
            Run::Flying { seen: true, from, to, last: end, win, sent, .. } => {
                let k = win.saturating_add(s.mission_seq).min(to);
                if s.mission_done && sent > to {
                    (end, self.reached, active)
                } else {
                    let before = k.checked_sub(1).filter(|&j| j >= from).and_then(|j| m.path_seq(j));
                    (m.path_seq(k).unwrap_or(end), done(before).max(self.reached), active)
                }
            }
            Run::Idle => (self.current, self.reached, MissionState::MISSION_STATE_PAUSED),
        };
        let (current, reached, mission_id) = (current.min(last), reached.map(|r| r.min(last)), m.plan_id());
        MissionProgress { total, current, reached, state, mission_id }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::{FixKind, ParamRejected, PathRejected, PositionFix, SourceNoise};
    use crate::link::dialect::{MavCmd, MavFrame, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA};
    use parapet_core::obstacle::ObstaclePoint;
    use parapet_core::replan::onboard::ReplanEvent;

    /// A cascade that only reports its replanner's events and flies `path`.
    struct Replanning {
        snapshot: TelemetrySnapshot,
        path: std::vec::Vec<Vec3>,
    }

    impl Autopilot for Replanning {
        fn update_position(&mut self, _: &PositionFix) {}
        fn navigation_fix(&mut self, _: &PositionFix, _: FixKind, _: SourceNoise) {}
        fn navigation_height(&mut self, _: u64, _: f32) {}
        fn update_obstacles(&mut self, _: u64, _: &[ObstaclePoint]) {}
        fn set_path(&mut self, w: &[Vec3]) -> Result<(), PathRejected> {
            if w.len() > parapet_core::controller::PATH_CAPACITY {
                return Err(PathRejected::TooLong);
            }
            self.path = w.to_vec();
            Ok(())
        }
        /// As the cascade streams (`path_stream`) when it has passed `mission_seq` points.
        fn stream_path(&mut self, waiting: &[Vec3]) -> usize {
            let next = usize::from(self.snapshot.mission_seq);
            let n = parapet_core::outer::path_stream::refill_count(self.path.len(), next, waiting.len());
            if n == 0 {
                return 0;
            }
            self.path.drain(..next.min(self.path.len()));
            self.path.extend_from_slice(&waiting[..n]);
            self.snapshot.mission_seq = 0;
            n
        }
        fn clear_path(&mut self) {}
        fn command(&mut self, _: u64, _: VehicleCommand) -> Result<(), CommandRejected> {
            Ok(())
        }
        fn telemetry(&self) -> TelemetrySnapshot {
            self.snapshot
        }
        fn flown_path(&self) -> &[Vec3] {
            &self.path
        }
        fn set_param(&mut self, _: &str, v: f32) -> Result<f32, ParamRejected> {
            Ok(v)
        }
        fn get_param(&self, _: &str) -> Option<f32> {
            None
        }
    }

    fn plan(points: &[Vec3]) -> MissionUpload {
        let items: std::vec::Vec<_> =
            points.iter().map(|p| (MavCmd::MAV_CMD_NAV_WAYPOINT, *p, 0.0)).collect();
        plan_of(&items)
    }

    /// A local-frame plan of (command, position, param1) items.
    fn plan_of(items: &[(MavCmd, Vec3, f32)]) -> MissionUpload {
        let mut m = MissionUpload::new();
        let count = MISSION_COUNT_DATA {
            count: items.len() as u16,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        };
        m.on_count(&count, 255, 190, 0);
        for (k, (command, p, param1)) in items.iter().enumerate() {
            let it = MISSION_ITEM_INT_DATA {
                x: parapet_core::wire::ids::local_xy_to_wire(f64::from(p.x)),
                y: parapet_core::wire::ids::local_xy_to_wire(f64::from(p.y)),
                z: p.z,
                seq: k as u16,
                command: *command as u16,
                param1: *param1,
                frame: MavFrame::MAV_FRAME_LOCAL_NED,
                ..Default::default()
            };
            m.on_item(&it, 255, 190, 0, 10.0);
        }
        m.accept();
        m
    }

    /// Issue 38: in a plan with a takeoff and a return the replanned waypoints sit between
    /// them, and MISSION_CURRENT's seq is the first of them (not the takeoff's 0).
    #[test]
    fn a_replan_of_a_plan_with_a_takeoff_and_a_return_counts_from_its_first_waypoint() {
        let (a, b, c) = (Vec3::new(1.0, 0.0, -1.0), Vec3::new(1.5, 0.8, -1.0), Vec3::new(3.0, 0.0, -1.0));
        let wire = |seq: u16, command: MavCmd, p: Vec3| MISSION_ITEM_INT_DATA {
            x: parapet_core::wire::ids::local_xy_to_wire(f64::from(p.x)),
            y: parapet_core::wire::ids::local_xy_to_wire(f64::from(p.y)),
            z: p.z,
            seq,
            command: command as u16,
            frame: MavFrame::MAV_FRAME_LOCAL_NED,
            ..Default::default()
        };
        let items = [
            wire(0, MavCmd::MAV_CMD_NAV_TAKEOFF, Vec3::new(0.0, 0.0, -1.0)),
            wire(1, MavCmd::MAV_CMD_NAV_WAYPOINT, a),
            wire(2, MavCmd::MAV_CMD_NAV_WAYPOINT, c),
            wire(3, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, Vec3::zeros()),
        ];
        let mut m = MissionUpload::new();
        let count =
            MISSION_COUNT_DATA { count: 4, target_system: 1, target_component: 1, ..Default::default() };
        m.on_count(&count, 255, 190, 0);
        for it in &items {
            m.on_item(it, 255, 190, 0, 10.0);
        }
        m.accept();
        let mut ap = Replanning { snapshot: TelemetrySnapshot::BOOT, path: vec![a, c] };
        let mut run = MissionRun::new();
        let replanned = ReplanOutcome::Replanned { detour: 1, waypoints: 3 };
        ap.snapshot.replan = crate::app::replanner::ReplanReport {
            events: 1,
            last: Some(ReplanEvent { outcome: replanned, waypoints: 3, detour: 1 }),
        };
        ap.path = vec![b, c, a];
        assert!(run.follow_replan(&mut m, &ap));
        assert_eq!(m.accepted_path().as_slice(), &[b, c, a][..]);
        assert_eq!((m.stored_len(), m.plan().takeoff.map(|t| t.0)), (5, Some(0)));
        assert_eq!(m.plan().end.map(|e| e.0), Some(4));
        assert_eq!(run.current, 1);
    }

    /// Issue 38: each new `Replanned` event makes the accepted plan the flown path, once; a
    /// no-path event or a repeated count changes nothing; a new upload keeps the count seen.
    #[test]
    fn a_replan_event_makes_the_flown_path_the_plan_once() {
        let (a, b, c) = (Vec3::new(1.0, 0.0, -1.0), Vec3::new(1.5, 0.8, -1.0), Vec3::new(3.0, 0.0, -1.0));
        let mut m = plan(&[a, c]);
        let id0 = m.plan_id();
        let mut ap = Replanning { snapshot: TelemetrySnapshot::BOOT, path: vec![a, c] };
        let mut run = MissionRun::new();
        assert!(!run.follow_replan(&mut m, &ap));
        let event = |outcome, n| ReplanEvent { outcome, waypoints: n, detour: 1 };
        // A no-path event: the plan stays.
        ap.snapshot.replan =
            crate::app::replanner::ReplanReport { events: 1, last: Some(event(ReplanOutcome::NoPath, 0)) };
        assert!(!run.follow_replan(&mut m, &ap));
        assert_eq!(m.plan_id(), id0);
        // A new path: the plan is the flown path, once.
        ap.path = vec![b, c, a];
        let replanned = ReplanOutcome::Replanned { detour: 1, waypoints: 3 };
        ap.snapshot.replan =
            crate::app::replanner::ReplanReport { events: 2, last: Some(event(replanned, 3)) };
        assert!(run.follow_replan(&mut m, &ap));
        assert_eq!(m.accepted_path().as_slice(), &[b, c, a][..]);
        assert_ne!(m.plan_id(), id0);
        assert!(!run.follow_replan(&mut m, &ap));
        // A new upload after it: the event already seen does not overwrite it.
        let mut m2 = plan(&[a, c]);
        run.reset();
        assert!(!run.follow_replan(&mut m2, &ap));
        assert_eq!(m2.plan_id(), id0);
    }

    /// Issue 38: a replan during the flight after a hold replaces that flight's items only;
    /// the executor flies on to the new last item, MISSION_CURRENT counts from the flight's
    /// first item and the items reached before it stay reached.
    #[test]
    fn a_replan_after_a_hold_rewrites_the_flight_being_flown_and_keeps_what_was_reached() {
        use MavCmd::{MAV_CMD_NAV_LOITER_TIME as HOLD, MAV_CMD_NAV_WAYPOINT as WP};
        let (a, h, b, c) = (
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(2.0, 0.0, -1.0),
            Vec3::new(3.0, 0.0, -1.0),
            Vec3::new(5.0, 0.0, -1.0),
        );
        let mut m = plan_of(&[(WP, a, 0.0), (HOLD, h, 2.0), (WP, b, 0.0), (WP, c, 0.0)]);
        let mut run = MissionRun::new();
        run.run = Run::Flying { seen: true, since_us: 7, from: 2, to: 3, last: 3, win: 2, sent: 4 };
        (run.current, run.reached) = (2, Some(1));
        let (e1, e2) = (Vec3::new(3.0, 1.0, -1.0), Vec3::new(4.0, 1.0, -1.0));
        let mut ap = Replanning { snapshot: TelemetrySnapshot::BOOT, path: vec![e1, e2, c] };
        let replanned = ReplanOutcome::Replanned { detour: 2, waypoints: 3 };
        ap.snapshot.replan = crate::app::replanner::ReplanReport {
            events: 1,
            last: Some(ReplanEvent { outcome: replanned, waypoints: 3, detour: 2 }),
        };
        assert!(run.follow_replan(&mut m, &ap));
        assert_eq!(m.accepted_path().as_slice(), &[a, h, e1, e2, c][..]);
        assert!(m.action_at(1).is_some(), "the hold stays");
        assert_eq!(
            run.run,
            Run::Flying { seen: true, since_us: 7, from: 2, to: 4, last: 4, win: 2, sent: 5 }
        );
        assert_eq!((run.current, run.reached), (2, Some(1)));
    }

    /// Issue 38: a segment of 100 points (the cascade holds 64) is given as the first 64, then
    /// streamed as the cascade passes them; MISSION_CURRENT counts from the window's start and
    /// the segment ends only when its last point was given and flown.
    #[test]
    fn a_segment_longer_than_the_cascade_holds_is_streamed_to_it() {
        let points: std::vec::Vec<Vec3> = (0..100).map(|k| Vec3::new(k as f32, 0.0, -1.0)).collect();
        let m = plan(&points);
        let mut ap = Replanning { snapshot: TelemetrySnapshot::BOOT, path: vec![] };
        (ap.snapshot.armed, ap.snapshot.mode, ap.snapshot.phase) =
            (true, FlightMode::Mission, FlightPhase::Mission);
        let mut run = MissionRun::new();
        run.fly(&m, 0, 99, 99, 0, &mut ap).expect("fly");
        assert_eq!(ap.path.as_slice(), &points[..64]);
        let mut now = SEGMENT_SETTLE_US;
        // Not due before 16 are passed.
        ap.snapshot.mission_seq = 15;
        run.poll(&m, now, &mut ap);
        assert_eq!(ap.path.len(), 64);
        assert_eq!(run.progress(&m, &ap.snapshot).current, 15);
        for _ in 0..10 {
            now += 100_000;
            ap.snapshot.mission_seq = 20;
            run.poll(&m, now, &mut ap);
        }
        let Run::Flying { win, sent, .. } = run.run else { panic!("{:?}", run.run) };
        assert_eq!(sent, 100, "all given");
        assert_eq!(ap.path.last(), points.last());
        assert_eq!(&points[usize::from(win)..usize::from(sent)], ap.path.as_slice());
        ap.snapshot.mission_seq = 3;
        assert_eq!(run.progress(&m, &ap.snapshot).current, win + 3);
        // Done only with every point given: then the plan's end.
        ap.snapshot.mission_done = true;
        run.poll(&m, now + 100_000, &mut ap);
        assert_eq!(run.run, Run::Done);
    }

    /// A replan reported before the executor flies (the cascade holds the upload's first 64
    /// points of a 100-point plan): only those are replaced, the 36 not yet given stay.
    #[test]
    fn a_replan_before_the_flight_keeps_the_points_not_yet_given() {
        let points: std::vec::Vec<Vec3> = (0..100).map(|k| Vec3::new(k as f32, 0.0, -1.0)).collect();
        let mut m = plan(&points);
        let detour = Vec3::new(0.5, 1.0, -1.0);
        let mut flown = vec![detour];
        flown.extend_from_slice(&points[1..64]);
        let mut ap = Replanning { snapshot: TelemetrySnapshot::BOOT, path: flown };
        let replanned = ReplanOutcome::Replanned { detour: 1, waypoints: 64 };
        ap.snapshot.replan = crate::app::replanner::ReplanReport {
            events: 1,
            last: Some(ReplanEvent { outcome: replanned, waypoints: 64, detour: 1 }),
        };
        let mut run = MissionRun::new();
        assert!(run.follow_replan(&mut m, &ap));
        let path = m.accepted_path();
        assert_eq!((m.stored_len(), path[0]), (100, detour));
        assert_eq!(&path[1..], &points[1..]);
    }
}
