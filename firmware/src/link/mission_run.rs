//! Mission executor: runs the accepted plan's items that are not path waypoints through the
//! cascade's commands and modes, and maps the flight to the ground station's item numbers.
//!
//! ```text
//!  MISSION_START / DO_SET_MODE Mission
//!    plan has NAV_TAKEOFF, armed on the ground or airborne ─▶ TakingOff (cascade Takeoff to its
//!                                                             height: climb, or descend when above)
//!    no NAV_TAKEOFF, a path, armed on the ground           ─▶ TakingOff (the cascade's default height)
//!    no NAV_TAKEOFF, airborne (Hover / Takeoff phase)      ─▶ Flying    (cascade StartMission)
//!  TakingOff ── the ramp seen, then Hover ─▶ Flying, or the end action when the path is empty
//!  Flying ──── follower done ───────▶ Ending: NAV_LAND → cascade Land; NAV_RETURN_TO_LAUNCH →
//!                                     Return mode (the battery failsafe's return); none → Done
//!  Ending ──── disarmed on the ground ─▶ Done
//!  disarmed, a failsafe, Landing or another mode selected while TakingOff/Flying ─▶ Idle (paused)
//! ```
//!
//! Every segment is flown by the cascade's own guidance (takeoff ramp, path follower, Land,
//! Return), so the safety filter is in the loop throughout; this module only issues the
//! commands a pilot would, at the link's poll rate (≥ 10 Hz, so an end action starts within
//! one poll period of the follower's arrival). A plan without TAKEOFF started armed on the
//! ground takes off by itself (issue 41; as PX4): the cascade's default takeoff (its
//! `Takeoff` without a height: 1 m, capped by `MIS_TKO_ALT_MAX`), then the path.
//!
//! [`MissionRun::progress`] gives MISSION_CURRENT / MISSION_ITEM_REACHED in the uploaded seq
//! numbers ([`crate::link::services`] emits them): the item being flown and the last item done
//! (ignored DO_* items count as done with the navigation item before them; NAV_TAKEOFF when the
//! climb ends, a waypoint when the follower passes it, NAV_LAND / RTL when the vehicle has
//! landed and disarmed, trailing DO_* items with the end).
//!
//! May import: [`crate::app::autopilot`] (the `Autopilot` boundary), [`crate::link::mission`],
//! the dialect. O(1) state, every call O([`crate::link::mission::MAX_WAYPOINTS`]).

use crate::app::autopilot::{
    Autopilot, CommandRejected, FlightMode, FlightPhase, TelemetrySnapshot, VehicleCommand,
};
use crate::link::dialect::MissionState;
use crate::link::mission::{EndAction, MissionUpload, Plan};

/// Executor state (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Run {
    /// Not running the plan (never started, or paused by another command or a failsafe).
    Idle,
    /// The cascade's takeoff ramp goes to the plan's takeoff height; `seen` once its phase
    /// showed Takeoff (before, a Hover is the state before the command took effect).
    TakingOff { seen: bool },
    /// The cascade flies the path; `seen` once its phase showed Mission (the snapshot's
    /// follower fields are this mission's from then on).
    Flying { seen: bool },
    /// The end action (LAND / RTL item `seq`) runs until the vehicle disarms.
    Ending { seq: u16 },
    /// The whole plan was flown.
    Done,
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
}

impl MissionProgress {
    /// No plan.
    pub const NONE: Self =
        Self { total: 0, current: 0, reached: None, state: MissionState::MISSION_STATE_NO_MISSION };
}

/// The mission executor (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct MissionRun {
    run: Run,
    /// The plan was started since it was uploaded.
    started: bool,
    /// The takeoff climb is over (or there was none).
    climbed: bool,
}

impl Default for MissionRun {
    fn default() -> Self {
        Self::new()
    }
}

fn airborne(s: &TelemetrySnapshot) -> bool {
    s.armed && matches!(s.phase, FlightPhase::Hover | FlightPhase::Takeoff | FlightPhase::Mission)
}

impl MissionRun {
    /// Nothing started.
    pub const fn new() -> Self {
        Self { run: Run::Idle, started: false, climbed: false }
    }

    /// A new plan was accepted, or the plan was cleared: not started.
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// `true` when a mission start on the ground would take off (the plan has NAV_TAKEOFF, or a
    /// path: then the cascade's default takeoff first).
    pub fn takes_off(m: &MissionUpload) -> bool {
        let plan = m.plan();
        plan.takeoff.is_some() || plan.path_len > 0
    }

    /// MISSION_START (or DO_SET_MODE Mission) at `now_us`: with a TAKEOFF item, armed on the
    /// ground or airborne, the cascade's takeoff ramp to the item's height where the vehicle is
    /// (airborne: up or down to it, as PX4 flies a TAKEOFF item in the air); else the cascade's
    /// StartMission. The cascade's refusal is returned.
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
            self.run = Run::TakingOff { seen: false };
            self.started = true;
            self.climbed = false;
            return Ok(());
        }
        if plan.path_len == 0 && plan.count > 0 && airborne(&s) {
            self.started = true;
            self.climbed = true;
            self.end(&plan, now_us, ap);
            return Ok(());
        }
        ap.command(now_us, VehicleCommand::StartMission)?;
        self.run = Run::Flying { seen: false };
        self.started = true;
        self.climbed = true;
        Ok(())
    }

    /// Starts the end action after the path (or finishes).
    fn end<A: Autopilot>(&mut self, plan: &Plan, now_us: u64, ap: &mut A) {
        self.run = match plan.end {
            Some((seq, action)) => {
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
                } else if !seen {
                    self.run = Run::TakingOff { seen };
                } else if s.phase == FlightPhase::Hover {
                    self.climbed = true;
                    let plan = m.plan();
                    if plan.path_len == 0 {
                        self.end(&plan, now_us, ap);
                    } else {
                        self.run = match ap.command(now_us, VehicleCommand::StartMission) {
                            Ok(()) => Run::Flying { seen: false },
                            Err(_) => Run::Idle,
                        };
                    }
                } else {
                    self.run = Run::TakingOff { seen };
                }
            }
            Run::Flying { seen } => {
                let seen = seen || s.phase == FlightPhase::Mission;
                if !s.armed
                    || s.mode != FlightMode::Mission
                    || !matches!(s.phase, FlightPhase::Hover | FlightPhase::Mission)
                {
                    self.run = Run::Idle;
                } else if seen && s.mission_done {
                    self.end(&m.plan(), now_us, ap);
                } else {
                    self.run = Run::Flying { seen };
                }
            }
            Run::Ending { .. } => {
                if !s.armed {
                    self.run = Run::Done;
                }
            }
        }
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
            };
        }
        let first = plan.takeoff.map_or(0, |(seq, _)| seq);
        // Done: the item and the ignored items after it.
        let done = |seq: Option<u16>| seq.map(|q| m.done_through(q));
        let climbed = if self.climbed { done(plan.takeoff.map(|(seq, _)| seq)) } else { None };
        // Done up to path waypoint k (a landing approach is not the LAND item).
        let upto = |k: u16| -> Option<u16> {
            let seq = m.path_seq(k)?;
            let approach = plan.land_approach && k + 1 == plan.path_len;
            done(if approach { seq.checked_sub(1) } else { Some(seq) })
        };
        let path_end = plan.path_len.checked_sub(1).and_then(upto).max(climbed);
        let active = MissionState::MISSION_STATE_ACTIVE;
        let (current, reached, state) = match self.run {
            Run::Done => (last, Some(last), MissionState::MISSION_STATE_COMPLETE),
            Run::Ending { seq } => (seq, done(seq.checked_sub(1)).max(path_end), active),
            Run::TakingOff { .. } => (first, first.checked_sub(1), active),
            Run::Flying { seen: false } => (m.path_seq(0).unwrap_or(first), climbed, active),
            Run::Flying { seen: true } | Run::Idle => {
                let k = s.mission_seq.min(plan.path_len.saturating_sub(1));
                let (cur, reached) = if s.mission_done {
                    (plan.end.map_or(last, |(seq, _)| seq), path_end)
                } else {
                    (m.path_seq(k).unwrap_or(first), k.checked_sub(1).and_then(upto).max(climbed))
                };
                let state = if self.run == Run::Idle { MissionState::MISSION_STATE_PAUSED } else { active };
                (cur, reached, state)
            }
        };
        MissionProgress { total, current: current.min(last), reached: reached.map(|r| r.min(last)), state }
    }
}
