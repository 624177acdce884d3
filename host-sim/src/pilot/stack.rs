//! The simulated pilot in the loop: [`Piloted`] wraps any flight stack that also takes pilot
//! input ([`PilotSink`]) and, between the runner's steps, delivers what a receiver and a
//! companion computer would: RC frames at the script's `rc_rate_hz` (none during a scripted
//! RC loss), offboard setpoints at `setpoint_rate_hz` (none after `offboard_stop`). Frames are
//! delivered before the inner step whose time they are due at (a receiver interrupt), so a
//! kill switch acts on that very inner step. The goal-seeking pilot sees the vehicle through
//! the latest position fix (extrapolated with its velocity), as a pilot watching it would.
//!
//! A scripted `fix_loss` withholds the position fixes measured in its window (the controller's
//! position-loss failsafe).
//!
//! A piloted flight has no path end: the wrapper reports `path_done = false`, so the runner
//! flies until a collision or the duration limit.
//!
//! Every outer step is logged ([`PilotRecord`]: sticks, setpoint, flight mode, filter
//! intervention) for `pilot.csv` and the summary's `pilot` object.
//!
//! May import: `parapet-core`, [`crate::flight`] (the `FlightStack` interface, clock),
//! [`crate::sim::sensors`] (readings), [`super::script`].

use anyhow::Result;
use nalgebra::Vector3;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::rc::RcInput;

use super::script::{PilotScript, Setpoint, Sticks};
use crate::flight::stack::{clock_us, FlightStack, OuterOut};
use crate::sim::sensors::{ImuReading, PositionReading};

/// Which flight mode a piloted run flies (entered right after the start-up).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PilotMode {
    /// Position-assist (`--pilot`).
    Position,
    /// Offboard (`--offboard`).
    Offboard,
    /// Mission: the run's path as uploaded, the mode the start-up selects (nothing is entered);
    /// RC frames still arrive (a safety pilot's), for the RC-loss failsafe of Mission.
    Mission,
}

/// One offboard setpoint with its time stamp (controller clock, µs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimedSetpoint {
    /// Time the companion sent it, µs, controller clock.
    pub t_us: u64,
    /// The setpoint, NED.
    pub setpoint: Setpoint,
}

/// A flight stack that takes pilot input.
pub trait PilotSink {
    /// Enter `mode` at `now_us` (after the start-up hover).
    fn enter(&mut self, now_us: u64, mode: PilotMode) -> Result<()>;
    /// One RC frame.
    fn rc(&mut self, rc: &RcInput);
    /// One offboard setpoint.
    fn offboard(&mut self, sp: &TimedSetpoint);
    /// Name of the flight mode now (e.g. "Position", "Hold").
    fn flight_mode(&self) -> String;
    /// `true` when the filter changed the nominal command at the last outer step; `None`
    /// when the stack cannot tell (the recorder's `filter.intervened` is used).
    fn filter_active(&self) -> Option<bool>;
    /// Reason of the last flight-mode change (`TransitionReason::as_str`, e.g. "rc-loss"), if
    /// the stack reports it.
    fn mode_reason(&self) -> Option<&'static str> {
        None
    }
}

/// What one outer step of a piloted flight recorded.
#[derive(Clone, Debug, PartialEq)]
pub struct PilotRecord {
    /// Simulated time, s.
    pub t: f64,
    /// The last RC frame's sticks (`None` while no frame arrives).
    pub sticks: Option<Sticks>,
    /// The last setpoint sent (`None` when none is being sent).
    pub setpoint: Option<Setpoint>,
    /// Flight mode after the step.
    pub flight_mode: String,
    /// Reason of the last flight-mode change after the step, if reported.
    pub mode_reason: Option<&'static str>,
    /// Guidance mode after the step.
    pub guidance: &'static str,
    /// The filter changed u* at this step.
    pub filter_active: bool,
}

/// The wrapper (see the module documentation).
pub struct Piloted<'a, S: FlightStack + PilotSink> {
    /// The wrapped stack.
    pub stack: &'a mut S,
    script: &'a PilotScript,
    mode: PilotMode,
    next_rc: u64,
    next_sp: u64,
    fix: Option<PositionReading>,
    sticks: Option<Sticks>,
    setpoint: Option<Setpoint>,
    /// The log, one record per outer step.
    pub log: Vec<PilotRecord>,
    /// Time of the first RC frame with the kill switch on, s.
    pub kill_sent_at: Option<f64>,
    /// Time of the first inner step with all motors at zero at or after the kill, s.
    pub motors_off_at: Option<f64>,
}

impl<'a, S: FlightStack + PilotSink> Piloted<'a, S> {
    /// Wrap `stack` to fly `script` in `mode`.
    pub fn new(stack: &'a mut S, script: &'a PilotScript, mode: PilotMode) -> Self {
        Piloted {
            stack,
            script,
            mode,
            next_rc: 0,
            next_sp: 0,
            fix: None,
            sticks: None,
            setpoint: None,
            log: Vec::new(),
            kill_sent_at: None,
            motors_off_at: None,
        }
    }

    /// The vehicle as the pilot sees it at `t`: the fix extrapolated, and its yaw.
    fn seen(&self, t: f64) -> (Vector3<f64>, f64) {
        match &self.fix {
            Some(f) => (f.position + f.velocity * (t - f.t_measured).max(0.0), f.yaw),
            None => (Vector3::zeros(), 0.0),
        }
    }

    /// Deliver the RC frames and setpoints due at `t` (at most one of each: the latest).
    fn deliver(&mut self, t: f64) {
        let rc_period = 1.0 / self.script.rc_rate_hz;
        if self.script.has_sticks() && t + 1e-9 >= self.next_rc as f64 * rc_period {
            // Frame k is due at k / rate; skip frames the inner rate cannot carry.
            self.next_rc = ((t + 1e-9) / rc_period).floor() as u64 + 1;
            let (p, yaw) = self.seen(t);
            self.sticks = self.script.sticks_at(t, &p, yaw);
            if let Some(s) = self.sticks {
                let rc = RcInput {
                    t_us: clock_us(t),
                    roll: s.roll as f32,
                    pitch: s.pitch as f32,
                    yaw: s.yaw as f32,
                    throttle: s.throttle as f32,
                    arm: s.arm,
                    kill: s.kill,
                    mode: s.mode,
                    link_quality: 100,
                    ..Default::default()
                };
                if s.kill && self.kill_sent_at.is_none() {
                    self.kill_sent_at = Some(t);
                }
                self.stack.rc(&rc);
            }
        }
        let sp_period = 1.0 / self.script.setpoint_rate_hz;
        if !self.script.setpoints.is_empty() && t + 1e-9 >= self.next_sp as f64 * sp_period {
            self.next_sp = ((t + 1e-9) / sp_period).floor() as u64 + 1;
            self.setpoint = self.script.setpoint_at(t);
            if let Some(sp) = self.setpoint {
                self.stack.offboard(&TimedSetpoint { t_us: clock_us(t), setpoint: sp });
            }
        }
    }
}

impl<S: FlightStack + PilotSink> FlightStack for Piloted<'_, S> {
    fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> Result<()> {
        self.fix = Some(s.fix);
        self.stack.start(s)?;
        // The first frame / setpoint before the mode change (a mode needs its input fresh).
        self.deliver(s.t);
        self.stack.enter(clock_us(s.t), self.mode)
    }

    fn position_fix(&mut self, fix: PositionReading) {
        // A scripted position loss: the fix reaches neither the pilot nor the controller.
        if self.script.fix_lost(fix.t_measured) {
            return;
        }
        self.fix = Some(fix);
        self.stack.position_fix(fix);
    }

    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        self.deliver(t);
        let mut out = self.stack.outer(t, obstacles);
        out.path_done = false;
        self.log.push(PilotRecord {
            t,
            sticks: self.sticks,
            setpoint: self.setpoint,
            flight_mode: self.stack.flight_mode(),
            mode_reason: self.stack.mode_reason(),
            guidance: out.mode.as_str(),
            filter_active: self.stack.filter_active().unwrap_or(out.filter.intervened),
        });
        out
    }

    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        self.deliver(t);
        let thr = self.stack.inner(t, imu);
        if self.kill_sent_at.is_some() && self.motors_off_at.is_none() && thr.iter().all(|&x| x == 0.0) {
            self.motors_off_at = Some(t);
        }
        thr
    }

    fn state_name(&self) -> String {
        self.stack.state_name()
    }

    fn battery(&mut self, t: f64, reading: &crate::sim::battery::BatteryReading) {
        self.stack.battery(t, reading);
    }
}
