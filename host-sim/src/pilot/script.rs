//! Pilot and offboard script files (TOML, `scenes/pilot/*.toml`, documented in
//! `scenes/README.md` § Pilot scripts): a timeline of stick keyframes (or a goal-seeking
//! pilot), a timeline of offboard setpoints, and scripted events (RC loss, kill, mode
//! switch, the offboard stream stopping). [`PilotScript::load`] checks every field and
//! names the file, table, field, value and allowed range of the first bad one.
//!
//! Sampling: [`PilotScript::sticks_at`] interpolates the stick axes between keyframes
//! (`interpolation = "linear"` or `"hold"`); switches (arm, kill, mode) always hold the
//! last keyframe's value. [`PilotScript::setpoint_at`] does the same for the offboard
//! setpoints (a vector interpolates only between two keyframes that both give it). Events
//! override the timeline: `kill` sets the kill switch from its time on, `mode` sets the mode
//! switch, `rc_loss` delivers no RC frame in `[t, until)`, `fix_loss` no position fix measured
//! in `[t, until)`, `offboard_stop` ends the setpoint stream.
//!
//! Frames: files are ENU (x east, y north, z up), like scenes; [`Setpoint`] and the goal are
//! converted to NED here, at the boundary.
//!
//! May import: `parapet-core` (`rc::RcInput`), [`crate::input`] (errors, limits, number
//! format, file reading), [`crate::world::frame`] (ENU → NED).

use std::path::Path;

use nalgebra::Vector3;
use parapet_core::rc::SwitchPosition;
use serde::Deserialize;

use crate::input::{exact, num, read_text, InputError};
use crate::world::frame::enu_arr_to_ned;

/// Most keyframes (sticks + setpoints) and events in one script.
pub const MAX_KEYFRAMES: usize = 100_000;
/// Longest script (last keyframe or event time, and `duration`), s.
pub const MAX_SCRIPT_S: f64 = 3600.0;
/// RC frame rate range, Hz (SBUS ≈ 70, CRSF 50–500).
pub const RC_RATE_HZ: (f64, f64) = (1.0, 1000.0);
/// Largest offboard setpoint component (position m, velocity m/s, acceleration m/s²).
pub const MAX_SETPOINT: f64 = 1000.0;
/// Largest goal-seeking gain, stick per metre.
pub const MAX_GOAL_GAIN: f64 = 100.0;

/// How the stick axes / setpoint vectors move between keyframes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    /// Straight line between two keyframes.
    #[default]
    Linear,
    /// The earlier keyframe's value until the next keyframe.
    Hold,
}

/// The sticks and switches at one time (the fields of `core::rc::RcInput` a pilot moves).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sticks {
    /// Roll, [−1, 1], > 0 right.
    pub roll: f64,
    /// Pitch, [−1, 1], > 0 forward.
    pub pitch: f64,
    /// Yaw, [−1, 1], > 0 clockwise from above.
    pub yaw: f64,
    /// Throttle, [0, 1] (0.5 = hold altitude in Position-assist).
    pub throttle: f64,
    /// Arm switch.
    pub arm: bool,
    /// Kill switch.
    pub kill: bool,
    /// Mode switch.
    pub mode: SwitchPosition,
}

impl Default for Sticks {
    /// Centred sticks, throttle 0.5, armed, kill off, mode switch low.
    fn default() -> Self {
        Sticks {
            roll: 0.0,
            pitch: 0.0,
            yaw: 0.0,
            throttle: 0.5,
            arm: true,
            kill: false,
            mode: SwitchPosition::Low,
        }
    }
}

/// One offboard setpoint (NED, SI); any combination of the three, as in
/// `SET_POSITION_TARGET_LOCAL_NED` with its `type_mask`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Setpoint {
    /// Position, NED, m.
    pub position: Option<Vector3<f64>>,
    /// Velocity, NED, m/s.
    pub velocity: Option<Vector3<f64>>,
    /// Acceleration, NED, m/s².
    pub acceleration: Option<Vector3<f64>>,
}

/// The goal-seeking pilot: pushes the sticks towards `target` regardless of obstacles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GoalPilot {
    /// Target, NED, m.
    pub target: Vector3<f64>,
    /// Stick per metre of horizontal distance (saturates at full stick).
    pub gain: f64,
    /// Throttle offset per metre of height error (0.5 ± this · error, clamped to [0, 1]).
    pub gain_z: f64,
}

impl GoalPilot {
    /// Sticks (roll, pitch, throttle) for the vehicle at `p` (NED) with heading `yaw` (rad):
    /// the horizontal error rotated into the heading frame, times the gain, each axis
    /// clamped to ±1 (a pilot pushing towards the target as hard as the stick goes).
    pub fn sticks(&self, p: &Vector3<f64>, yaw: f64) -> (f64, f64, f64) {
        let e = self.target - p;
        let (s, c) = yaw.sin_cos();
        let fwd = c * e.x + s * e.y;
        let right = -s * e.x + c * e.y;
        let clamp1 = |x: f64| if x.is_finite() { x.clamp(-1.0, 1.0) } else { 0.0 };
        let thr = 0.5 + self.gain_z * (-e.z);
        (
            clamp1(self.gain * right),
            clamp1(self.gain * fwd),
            if thr.is_finite() { thr.clamp(0.0, 1.0) } else { 0.5 },
        )
    }
}

/// A scripted event.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// No RC frame reaches the vehicle in `[from, until)`, s.
    RcLoss { from: f64, until: f64 },
    /// The kill switch goes on at `t` and stays on.
    Kill { t: f64 },
    /// The mode switch moves to `mode` at `t`.
    Mode { t: f64, mode: SwitchPosition },
    /// The offboard setpoint stream stops at `t`.
    OffboardStop { t: f64 },
    /// No position fix measured in `[from, until)` reaches the vehicle.
    FixLoss { from: f64, until: f64 },
}

/// A loaded, checked script (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct PilotScript {
    /// Name (`name`, or the file stem).
    pub name: String,
    /// The file as given.
    pub source: String,
    /// Interpolation of sticks and setpoints.
    pub interpolation: Interpolation,
    /// RC frame rate, Hz.
    pub rc_rate_hz: f64,
    /// Offboard setpoint rate, Hz.
    pub setpoint_rate_hz: f64,
    /// Duration of the flight, s, if the script sets it.
    pub duration: Option<f64>,
    /// Stick keyframes, by time.
    pub sticks: Vec<(f64, Sticks)>,
    /// Offboard keyframes, by time.
    pub setpoints: Vec<(f64, Setpoint)>,
    /// Goal-seeking pilot (replaces the keyframes' roll, pitch and throttle).
    pub goal: Option<GoalPilot>,
    /// Events.
    pub events: Vec<Event>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScript {
    name: Option<String>,
    #[allow(dead_code)]
    description: Option<String>,
    interpolation: Option<Interpolation>,
    rc_rate_hz: Option<f64>,
    setpoint_rate_hz: Option<f64>,
    duration: Option<f64>,
    #[serde(default)]
    stick: Vec<RawStick>,
    #[serde(default)]
    setpoint: Vec<RawSetpoint>,
    goal: Option<RawGoal>,
    #[serde(default)]
    event: Vec<RawEvent>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStick {
    t: f64,
    roll: Option<f64>,
    pitch: Option<f64>,
    yaw: Option<f64>,
    throttle: Option<f64>,
    arm: Option<bool>,
    kill: Option<bool>,
    mode: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSetpoint {
    t: f64,
    #[serde(default, deserialize_with = "exact::option_array")]
    position: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::option_array")]
    velocity: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::option_array")]
    acceleration: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGoal {
    #[serde(deserialize_with = "exact::array")]
    target: [f64; 3],
    gain: Option<f64>,
    gain_z: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEvent {
    kind: String,
    t: f64,
    until: Option<f64>,
    mode: Option<String>,
}

fn switch(s: &str) -> Option<SwitchPosition> {
    match s {
        "low" => Some(SwitchPosition::Low),
        "mid" => Some(SwitchPosition::Mid),
        "high" => Some(SwitchPosition::High),
        _ => None,
    }
}

/// The name of a switch position as scripts write it.
pub fn switch_name(p: SwitchPosition) -> &'static str {
    match p {
        SwitchPosition::Low => "low",
        SwitchPosition::Mid => "mid",
        SwitchPosition::High => "high",
    }
}

fn lerp(a: f64, b: f64, w: f64) -> f64 {
    a + (b - a) * w
}

impl PilotScript {
    /// Load and check `path`.
    pub fn load(path: &Path) -> Result<PilotScript, InputError> {
        let text = read_text(path)?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        Self::parse(&text, &path.display().to_string(), &stem)
    }

    /// Parse and check `text` (from `origin`, named `stem` unless it sets `name`).
    pub fn parse(text: &str, origin: &str, stem: &str) -> Result<PilotScript, InputError> {
        let raw: RawScript = toml::from_str(text)
            .map_err(|e| InputError::file(origin, e.message().to_string()).value(loc(text, &e)))?;
        let err = |table: String, field: &str, reason: &str, value: String, allowed: String| {
            InputError::file(origin, reason).table(table).field(field).value(value).allowed(allowed)
        };
        let time = |table: String, field: &str, t: f64| -> Result<f64, InputError> {
            if t.is_finite() && (0.0..=MAX_SCRIPT_S).contains(&t) {
                Ok(t)
            } else {
                Err(err(table, field, "time out of range", num(t), format!("0 ≤ t ≤ {MAX_SCRIPT_S} s")))
            }
        };
        // A keyframe's time `t` of `table`: in range and after the previous one (`last_t`, moved on).
        let keyframe_time = |table: &str, t: f64, last_t: &mut f64| -> Result<f64, InputError> {
            let t = time(table.to_string(), "t", t)?;
            if t <= *last_t {
                let allowed = format!("> {}", num(*last_t));
                return Err(err(table.to_string(), "t", "keyframe times must increase", num(t), allowed));
            }
            *last_t = t;
            Ok(t)
        };
        // The mode switch position `m` of `table`'s `mode` field.
        let switch_at = |table: &str, m: &str| {
            let why = "unknown switch position";
            switch(m).ok_or_else(|| {
                err(table.to_string(), "mode", why, format!("{m:?}"), "low | mid | high".into())
            })
        };
        let rate = |field: &str, r: Option<f64>, d: f64| -> Result<f64, InputError> {
            let r = r.unwrap_or(d);
            if r.is_finite() && (RC_RATE_HZ.0..=RC_RATE_HZ.1).contains(&r) {
                Ok(r)
            } else {
                Err(InputError::file(origin, "rate out of range")
                    .field(field)
                    .value(num(r))
                    .allowed(format!("{} ≤ rate ≤ {} Hz", RC_RATE_HZ.0, RC_RATE_HZ.1)))
            }
        };
        let n = raw.stick.len() + raw.setpoint.len() + raw.event.len();
        if n > MAX_KEYFRAMES {
            return Err(InputError::file(origin, "too many keyframes and events")
                .value(n)
                .allowed(format!("at most {MAX_KEYFRAMES}")));
        }
        let duration = match raw.duration {
            Some(d) if d.is_finite() && d > 0.0 && d <= MAX_SCRIPT_S => Some(d),
            Some(d) => {
                return Err(InputError::file(origin, "duration out of range")
                    .field("duration")
                    .value(num(d))
                    .allowed(format!("0 < duration ≤ {MAX_SCRIPT_S} s")))
            }
            None => None,
        };
        // Sticks: each missing field keeps the previous keyframe's value.
        let mut sticks = Vec::with_capacity(raw.stick.len());
        let mut prev = Sticks::default();
        let mut last_t = f64::NEG_INFINITY;
        for (i, s) in raw.stick.iter().enumerate() {
            let table = format!("stick[{i}]");
            let t = keyframe_time(&table, s.t, &mut last_t)?;
            let axis = |field: &str, v: Option<f64>, old: f64, lo: f64| -> Result<f64, InputError> {
                match v {
                    None => Ok(old),
                    Some(x) if x.is_finite() && (lo..=1.0).contains(&x) => Ok(x),
                    Some(x) => {
                        Err(err(table.clone(), field, "stick out of range", num(x), format!("{lo} ≤ x ≤ 1")))
                    }
                }
            };
            let mode = match &s.mode {
                None => prev.mode,
                Some(m) => switch_at(&table, m)?,
            };
            prev = Sticks {
                roll: axis("roll", s.roll, prev.roll, -1.0)?,
                pitch: axis("pitch", s.pitch, prev.pitch, -1.0)?,
                yaw: axis("yaw", s.yaw, prev.yaw, -1.0)?,
                throttle: axis("throttle", s.throttle, prev.throttle, 0.0)?,
                arm: s.arm.unwrap_or(prev.arm),
                kill: s.kill.unwrap_or(prev.kill),
                mode,
            };
            sticks.push((t, prev));
        }
        let mut setpoints = Vec::with_capacity(raw.setpoint.len());
        let mut last_t = f64::NEG_INFINITY;
        for (i, s) in raw.setpoint.iter().enumerate() {
            let table = format!("setpoint[{i}]");
            let t = keyframe_time(&table, s.t, &mut last_t)?;
            let vec = |field: &str, v: Option<[f64; 3]>| -> Result<Option<Vector3<f64>>, InputError> {
                match v {
                    None => Ok(None),
                    Some(a) if a.iter().all(|x| x.is_finite() && x.abs() <= MAX_SETPOINT) => {
                        Ok(Some(enu_arr_to_ned(a)))
                    }
                    Some(a) => Err(err(
                        table.clone(),
                        field,
                        "component out of range",
                        format!("{a:?}"),
                        format!("finite, |x| ≤ {MAX_SETPOINT}"),
                    )),
                }
            };
            let sp = Setpoint {
                position: vec("position", s.position)?,
                velocity: vec("velocity", s.velocity)?,
                acceleration: vec("acceleration", s.acceleration)?,
            };
            if sp == Setpoint::default() {
                return Err(err(
                    table,
                    "position",
                    "a setpoint needs at least one of position, velocity, acceleration",
                    "none".into(),
                    "position | velocity | acceleration".into(),
                ));
            }
            setpoints.push((t, sp));
        }
        let goal = match &raw.goal {
            None => None,
            Some(g) => {
                let gain = g.gain.unwrap_or(1.0);
                let gain_z = g.gain_z.unwrap_or(0.5);
                for (field, v) in [("gain", gain), ("gain_z", gain_z)] {
                    if !(v.is_finite() && v > 0.0 && v <= MAX_GOAL_GAIN) {
                        return Err(err(
                            "goal".into(),
                            field,
                            "gain out of range",
                            num(v),
                            format!("0 < gain ≤ {MAX_GOAL_GAIN}"),
                        ));
                    }
                }
                if !g.target.iter().all(|x| x.is_finite() && x.abs() <= MAX_SETPOINT) {
                    return Err(err(
                        "goal".into(),
                        "target",
                        "component out of range",
                        format!("{:?}", g.target),
                        format!("finite, |x| ≤ {MAX_SETPOINT} m"),
                    ));
                }
                Some(GoalPilot { target: enu_arr_to_ned(g.target), gain, gain_z })
            }
        };
        let mut events = Vec::with_capacity(raw.event.len());
        for (i, e) in raw.event.iter().enumerate() {
            let table = format!("event[{i}]");
            let t = time(table.clone(), "t", e.t)?;
            let unused = |field: &str, present: bool| {
                if present {
                    Err(err(
                        table.clone(),
                        field,
                        "not a field of this event kind",
                        "given".into(),
                        "left out".into(),
                    ))
                } else {
                    Ok(())
                }
            };
            let ev = match e.kind.as_str() {
                "rc_loss" | "fix_loss" => {
                    unused("mode", e.mode.is_some())?;
                    let until = e.until.ok_or_else(|| {
                        err(
                            table.clone(),
                            "until",
                            "a loss needs its end time",
                            "missing".into(),
                            format!("{} < until", num(t)),
                        )
                    })?;
                    let until = time(table.clone(), "until", until)?;
                    if until <= t {
                        return Err(err(
                            table,
                            "until",
                            "the loss must end after it starts",
                            num(until),
                            format!("> {}", num(t)),
                        ));
                    }
                    if e.kind == "rc_loss" {
                        Event::RcLoss { from: t, until }
                    } else {
                        Event::FixLoss { from: t, until }
                    }
                }
                "kill" => {
                    unused("until", e.until.is_some())?;
                    unused("mode", e.mode.is_some())?;
                    Event::Kill { t }
                }
                "offboard_stop" => {
                    unused("until", e.until.is_some())?;
                    unused("mode", e.mode.is_some())?;
                    Event::OffboardStop { t }
                }
                "mode" => {
                    unused("until", e.until.is_some())?;
                    let m = e.mode.as_deref().unwrap_or("");
                    let mode = switch_at(&table, m)?;
                    Event::Mode { t, mode }
                }
                k => {
                    return Err(err(
                        table,
                        "kind",
                        "unknown event",
                        format!("{k:?}"),
                        "rc_loss | fix_loss | kill | mode | offboard_stop".into(),
                    ))
                }
            };
            events.push(ev);
        }
        if sticks.is_empty() && setpoints.is_empty() && goal.is_none() {
            return Err(InputError::file(origin, "the script gives neither sticks, a goal nor setpoints")
                .allowed("[[stick]] keyframes, a [goal] table or [[setpoint]] keyframes"));
        }
        Ok(PilotScript {
            name: raw.name.unwrap_or_else(|| stem.to_string()),
            source: origin.to_string(),
            interpolation: raw.interpolation.unwrap_or_default(),
            rc_rate_hz: rate("rc_rate_hz", raw.rc_rate_hz, 50.0)?,
            setpoint_rate_hz: rate("setpoint_rate_hz", raw.setpoint_rate_hz, 50.0)?,
            duration,
            sticks,
            setpoints,
            goal,
            events,
        })
    }

    /// `true` when the script moves sticks (keyframes or a goal pilot).
    pub fn has_sticks(&self) -> bool {
        !self.sticks.is_empty() || self.goal.is_some()
    }

    /// Last time the script mentions (keyframes, event times), s.
    pub fn end_time(&self) -> f64 {
        let k = self.sticks.iter().map(|s| s.0).chain(self.setpoints.iter().map(|s| s.0));
        let e = self.events.iter().map(|e| match *e {
            Event::RcLoss { until, .. } | Event::FixLoss { until, .. } => until,
            Event::Kill { t } | Event::Mode { t, .. } | Event::OffboardStop { t } => t,
        });
        k.chain(e).fold(0.0, f64::max)
    }

    /// `true` when a scripted `fix_loss` covers a fix measured at `t` (s).
    pub fn fix_lost(&self, t: f64) -> bool {
        self.events.iter().any(|e| matches!(*e, Event::FixLoss { from, until } if t >= from && t < until))
    }

    /// The sticks at `t` (s) for the vehicle at `p` (NED) with heading `yaw` (for the goal
    /// pilot), events applied; `None` while an RC loss is scripted.
    pub fn sticks_at(&self, t: f64, p: &Vector3<f64>, yaw: f64) -> Option<Sticks> {
        if self.events.iter().any(|e| matches!(*e, Event::RcLoss { from, until } if t >= from && t < until)) {
            return None;
        }
        let mut s = self.keyframe_sticks(t);
        if let Some(g) = &self.goal {
            (s.roll, s.pitch, s.throttle) = g.sticks(p, yaw);
        }
        // Events in time order (a later mode event wins over an earlier one).
        let mut mode_t = f64::NEG_INFINITY;
        for e in &self.events {
            match *e {
                Event::Kill { t: tk } if t >= tk => s.kill = true,
                Event::Mode { t: tm, mode } if t >= tm && tm >= mode_t => {
                    s.mode = mode;
                    mode_t = tm;
                }
                _ => {}
            }
        }
        Some(s)
    }

    fn keyframe_sticks(&self, t: f64) -> Sticks {
        let k = &self.sticks;
        let i = k.partition_point(|(tk, _)| *tk <= t);
        let Some(&(t0, a)) = i.checked_sub(1).and_then(|j| k.get(j)) else {
            return k.first().map_or_else(Sticks::default, |f| f.1);
        };
        match (self.interpolation, k.get(i)) {
            (Interpolation::Linear, Some(&(t1, b))) => {
                let w = (t - t0) / (t1 - t0);
                Sticks {
                    roll: lerp(a.roll, b.roll, w),
                    pitch: lerp(a.pitch, b.pitch, w),
                    yaw: lerp(a.yaw, b.yaw, w),
                    throttle: lerp(a.throttle, b.throttle, w),
                    ..a
                }
            }
            _ => a,
        }
    }

    /// The offboard setpoint at `t` (s); `None` before the first keyframe, after an
    /// `offboard_stop` and when the script has none.
    pub fn setpoint_at(&self, t: f64) -> Option<Setpoint> {
        if self.events.iter().any(|e| matches!(*e, Event::OffboardStop { t: ts } if t >= ts)) {
            return None;
        }
        let k = &self.setpoints;
        let i = k.partition_point(|(tk, _)| *tk <= t);
        let &(t0, a) = k.get(i.checked_sub(1)?)?;
        match (self.interpolation, k.get(i)) {
            (Interpolation::Linear, Some(&(t1, b))) => {
                let w = (t - t0) / (t1 - t0);
                let mix = |x: Option<Vector3<f64>>, y: Option<Vector3<f64>>| match (x, y) {
                    (Some(x), Some(y)) => Some(x + (y - x) * w),
                    (x, _) => x,
                };
                Some(Setpoint {
                    position: mix(a.position, b.position),
                    velocity: mix(a.velocity, b.velocity),
                    acceleration: mix(a.acceleration, b.acceleration),
                })
            }
            _ => Some(a),
        }
    }
}

/// "line L, column C" of a TOML error.
fn loc(text: &str, e: &toml::de::Error) -> String {
    match e.span() {
        Some(s) => {
            let before = &text[..s.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            format!("line {line}, column {col}")
        }
        None => "unknown position".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<PilotScript, InputError> {
        PilotScript::parse(text, "p.toml", "p")
    }

    #[test]
    fn keyframes_interpolate_and_switches_hold() {
        let s = parse(
            "[[stick]]\nt = 0\npitch = 0\n[[stick]]\nt = 2\npitch = 1\nroll = -0.5\nmode = \"mid\"\n\
             [[stick]]\nt = 4\npitch = 0\n",
        )
        .unwrap();
        let p = Vector3::zeros();
        let at = |t| s.sticks_at(t, &p, 0.0).unwrap();
        assert_eq!(at(1.0).pitch, 0.5);
        assert_eq!(at(1.0).roll, -0.25);
        assert_eq!(at(1.0).mode, SwitchPosition::Low, "switches hold until the keyframe");
        assert_eq!(at(2.0).mode, SwitchPosition::Mid);
        assert_eq!(at(3.0).pitch, 0.5);
        assert_eq!(at(3.0).roll, -0.5, "missing fields keep the previous keyframe's value");
        assert_eq!(at(10.0).pitch, 0.0);
        let mut h = s.clone();
        h.interpolation = Interpolation::Hold;
        assert_eq!(h.sticks_at(1.9, &p, 0.0).unwrap().pitch, 0.0);
        assert_eq!(h.sticks_at(3.9, &p, 0.0).unwrap().pitch, 1.0);
    }

    #[test]
    fn events_override_the_timeline() {
        let s = parse(
            "[[stick]]\nt = 0\npitch = 1\n[[event]]\nkind = \"rc_loss\"\nt = 1\nuntil = 2\n\
             [[event]]\nkind = \"kill\"\nt = 3\n[[event]]\nkind = \"mode\"\nt = 0.5\nmode = \"high\"\n\
             [[setpoint]]\nt = 0\nvelocity = [1, 0, 0]\n[[setpoint]]\nt = 2\nvelocity = [3, 0, 0]\n\
             [[event]]\nkind = \"offboard_stop\"\nt = 4\n",
        )
        .unwrap();
        let p = Vector3::zeros();
        assert!(s.sticks_at(0.99, &p, 0.0).is_some());
        assert!(s.sticks_at(1.0, &p, 0.0).is_none());
        assert!(s.sticks_at(2.0, &p, 0.0).is_some());
        assert!(!s.sticks_at(2.9, &p, 0.0).unwrap().kill);
        assert!(s.sticks_at(3.0, &p, 0.0).unwrap().kill);
        assert_eq!(s.sticks_at(0.6, &p, 0.0).unwrap().mode, SwitchPosition::High);
        // ENU east 2 m/s = NED y 2.
        assert_eq!(s.setpoint_at(1.0).unwrap().velocity, Some(Vector3::new(0.0, 2.0, 0.0)));
        assert!(s.setpoint_at(3.99).is_some());
        assert!(s.setpoint_at(4.0).is_none());
        assert_eq!(s.end_time(), 4.0);
    }

    #[test]
    fn goal_pilot_pushes_in_the_heading_frame_and_saturates() {
        let g = GoalPilot { target: Vector3::new(10.0, 0.0, -1.0), gain: 1.0, gain_z: 0.5 };
        let (r, p, thr) = g.sticks(&Vector3::new(0.0, 0.0, -1.0), 0.0);
        assert_eq!((r, p, thr), (0.0, 1.0, 0.5));
        // Heading east: the target north is to the left.
        let (r, p, _) = g.sticks(&Vector3::new(9.5, 0.0, -1.0), std::f64::consts::FRAC_PI_2);
        assert!((r + 0.5).abs() < 1e-9 && p.abs() < 1e-9, "{r} {p}");
        let (_, _, thr) = g.sticks(&Vector3::new(0.0, 0.0, 0.0), 0.0);
        assert!(thr > 0.5, "below the target: climb");
    }

    #[test]
    fn bad_fields_are_named_with_value_and_range() {
        let cases = [
            ("[[stick]]\nt = 0\npitch = 1.5\n", "[stick[0]] field `pitch`", "1.5", "-1 ≤ x ≤ 1"),
            ("[[stick]]\nt = 0\nthrottle = -0.1\n", "field `throttle`", "-0.1", "0 ≤ x ≤ 1"),
            ("[[stick]]\nt = 1\n[[stick]]\nt = 1\n", "[stick[1]] field `t`", "1", "> 1"),
            ("[[stick]]\nt = -1\n", "field `t`", "-1", "0 ≤ t"),
            ("[[stick]]\nt = 0\nmode = \"up\"\n", "field `mode`", "\"up\"", "low | mid | high"),
            (
                "[[event]]\nkind = \"rc_loss\"\nt = 2\nuntil = 1\n[[stick]]\nt = 0\n",
                "field `until`",
                "1",
                "> 2",
            ),
            (
                "[[event]]\nkind = \"boom\"\nt = 2\n[[stick]]\nt = 0\n",
                "field `kind`",
                "\"boom\"",
                "rc_loss |",
            ),
            ("[[setpoint]]\nt = 0\nvelocity = [1, 2]\n", "p.toml", "line 3", "array of 3"),
            ("[[setpoint]]\nt = 0\n", "[setpoint[0]]", "none", "position |"),
            ("[goal]\ntarget = [1, 2, 3]\ngain = 0\n", "[goal] field `gain`", "0", "0 < gain"),
            ("rc_rate_hz = 0.5\n[[stick]]\nt = 0\n", "field `rc_rate_hz`", "0.5", "1 ≤ rate"),
            ("duration = 0\n[[stick]]\nt = 0\n", "field `duration`", "0", "0 < duration"),
            ("name = \"x\"\n", "p.toml", "neither", "[[stick]]"),
            ("[[stick]]\nt = 0\nwhat = 1\n", "p.toml", "line 3", "unknown field"),
        ];
        for (text, place, value, allowed) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.starts_with("p.toml"), "{e}");
            for part in [place, value, allowed] {
                assert!(e.contains(part), "{text:?}: {e:?} lacks {part:?}");
            }
        }
        // Setpoint times must increase too (the same check as the sticks').
        let e = parse("[[setpoint]]\nt = 2\nvelocity = [1, 0, 0]\n[[setpoint]]\nt = 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("[setpoint[1]] field `t`") && e.contains("> 2"), "{e}");
        // An event's mode is checked like a stick keyframe's.
        let e = parse("[[event]]\nkind = \"mode\"\nt = 1\nmode = \"up\"\n[[stick]]\nt = 0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("[event[0]] field `mode`") && e.contains("low | mid | high"), "{e}");
    }

    #[test]
    fn shipped_scripts_load() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/pilot");
        let mut n = 0;
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            let name = p.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
            if name.ends_with(".pilot.toml") || name.ends_with(".offboard.toml") {
                PilotScript::load(&p).unwrap_or_else(|e| panic!("{e}"));
                n += 1;
            }
        }
        assert!(n >= 8, "{n} scripts in {}", dir.display());
    }
}
