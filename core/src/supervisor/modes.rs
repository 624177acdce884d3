//! The flight-mode machine (issue 21): which mode the pilot, a companion computer or a ground
//! station selected, and the per-mode failsafes for RC loss, offboard-setpoint loss and the
//! battery.
//!
//! ```text
//!        mode switch (MODE_SW_LOW/MID/HIGH) · DO_SET_MODE · set_mode()
//!   ┌────────────┬────────────┬──────────┬──────────┬────────┬────────┬───────┐
//!   │ Manual     │ Position   │ Mission  │ Offboard │ Hold   │ Return │ Land  │
//!   │ (no filter)│ (assist)   │ (default)│          │        │        │       │
//!   └─────┬──────┴─────┬──────┴────┬─────┴────┬─────┴───▲────┴───┬────┴───▲───┘
//!         │ RC loss    │ RC loss   │ RC loss  │ RC loss │ RC loss│ done   │
//!         └──────▶─────┴─────▶─────┼──FS_RC_ACT┼─────────┤ FS_RC_LAND_T ───┤
//!                                  │ =1: ─────┴──▶ Return│        └───────▶┘
//!                                  │      offboard loss ─┘ (Offboard → Hold)
//!   battery Low ─▶ Return (from every mode but Return/Land) · battery Critical ─▶ Land
//!   kill switch ─▶ motors off at once (FailsafeState::Disarmed, reason kill-switch), any mode
//! ```
//!
//! The machine decides only; [`crate::outer::OuterLoop`] applies the result (Land is the
//! failsafe machine's Land state, Return ends in it, the kill switch is its disarm). A
//! failsafe of [`super::failsafe`] (Brake for stale data, Land, MotorsOff) takes precedence
//! over every mode while it lasts; the selected mode is kept and flown again after a
//! `data-recovered` resume.
//!
//! Failsafes are **edge-triggered**: each fires once when its condition starts (RC lost, the
//! offboard stream stopped, the battery level dropped), so the pilot may take the vehicle back
//! with the mode switch afterwards (like PX4). After an RC loss the mode switch acts again only
//! when it is moved (a position change), never by the frame that restores the link.
//!
//! Bad input: an [`RcInput`] with a NaN/Inf stick or a stick outside its range (by more than
//! [`STICK_TOLERANCE`]) is rejected whole (switches too) and counted; it does not refresh the
//! RC age, so a stream of bad frames is an RC loss. A receiver `failsafe` frame is an RC loss
//! at once, as is a frame whose producer set `lost` (no signal, timeout, low link quality:
//! [`crate::rc::RcLost`]). Bounded: every call is O(1).
//!
//! May import: the crate root foundation, [`crate::rc`], [`crate::battery`] and
//! [`super::failsafe`] (the shared [`TransitionReason`]).

use super::failsafe::TransitionReason;
use crate::battery::{BatteryLevel, BatteryState};
use crate::param_decl::{access, field, flag, Has, Param};
use crate::rc::{RcInput, SwitchPosition};

/// Sticks may exceed their range by this much (receiver calibration) before a frame is bad.
pub const STICK_TOLERANCE: f32 = 0.05;

/// Flight mode selected by the pilot, a companion computer or a ground station.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlightMode {
    /// Manual attitude: sticks → roll/pitch (up to `MAN_TILT_MAX`), yaw rate and thrust. No
    /// safety filter (the safety pilot's mode).
    Manual = 0,
    /// Position assist: sticks → horizontal velocity in the heading frame, climb rate and yaw
    /// rate; centred sticks hold position. Filtered.
    Position = 1,
    /// The uploaded mission and its commands (takeoff, hold, mission start). Filtered. The
    /// default: without RC or mode commands the controller behaves as before issue 21.
    #[default]
    Mission = 2,
    /// Companion-computer setpoints (position, velocity or acceleration). Filtered.
    Offboard = 3,
    /// Hold the position where the mode was entered. Filtered.
    Hold = 4,
    /// Back to the start along the flown path (breadcrumbs), then Land. Filtered.
    Return = 5,
    /// Land where the vehicle is (the failsafe machine's Land). Filtered.
    Land = 6,
}

impl FlightMode {
    /// Number of modes (the length of per-mode telemetry arrays, indexed by `mode as usize`).
    pub const COUNT: usize = 7;
    /// Every mode, in code order.
    pub const ALL: [FlightMode; Self::COUNT] = [
        FlightMode::Manual,
        FlightMode::Position,
        FlightMode::Mission,
        FlightMode::Offboard,
        FlightMode::Hold,
        FlightMode::Return,
        FlightMode::Land,
    ];

    /// The variant's name.
    pub const fn as_str(self) -> &'static str {
        match self {
            FlightMode::Manual => "Manual",
            FlightMode::Position => "Position",
            FlightMode::Mission => "Mission",
            FlightMode::Offboard => "Offboard",
            FlightMode::Hold => "Hold",
            FlightMode::Return => "Return",
            FlightMode::Land => "Land",
        }
    }

    /// The mode of parameter code `code` (the `MODE_SW_*` values: `mode as i32`).
    pub fn from_code(code: i32) -> Option<FlightMode> {
        Self::ALL.into_iter().find(|m| *m as i32 == code)
    }

    /// `true` when the safety filter guards the mode (all but Manual).
    pub const fn filtered(self) -> bool {
        !matches!(self, FlightMode::Manual)
    }

    /// PX4 main and sub mode (`px4_custom_mode`): Manual 1/0, Position (POSCTL) 3/0, Mission
    /// (AUTO.MISSION) 4/4, Hold (AUTO.LOITER) 4/3, Return (AUTO.RTL) 4/5, Land (AUTO.LAND)
    /// 4/6, Offboard 6/0.
    pub const fn px4_main_sub(self) -> (u8, u8) {
        match self {
            FlightMode::Manual => (1, 0),
            FlightMode::Position => (3, 0),
            FlightMode::Mission => (4, 4),
            FlightMode::Hold => (4, 3),
            FlightMode::Return => (4, 5),
            FlightMode::Land => (4, 6),
            FlightMode::Offboard => (6, 0),
        }
    }

    /// HEARTBEAT `custom_mode` in PX4's encoding: `main << 16 | sub << 24`.
    pub const fn px4_custom_mode(self) -> u32 {
        let (main, sub) = self.px4_main_sub();
        ((main as u32) << 16) | ((sub as u32) << 24)
    }

    /// The mode of a PX4 main/sub pair (DO_SET_MODE param2/param3). Also accepted: AUTO with
    /// sub mode 0 → Mission, STABILIZED (7) → Manual, ALTCTL (2) → Position.
    pub fn from_px4(main: u8, sub: u8) -> Option<FlightMode> {
        match (main, sub) {
            (1, _) | (7, _) => Some(FlightMode::Manual),
            (2, _) | (3, _) => Some(FlightMode::Position),
            (4, 0) | (4, 4) => Some(FlightMode::Mission),
            (4, 3) => Some(FlightMode::Hold),
            (4, 5) => Some(FlightMode::Return),
            (4, 6) => Some(FlightMode::Land),
            (6, _) => Some(FlightMode::Offboard),
            _ => None,
        }
    }

    /// The mode of a HEARTBEAT-style `custom_mode` (`main << 16 | sub << 24`).
    pub fn from_px4_custom_mode(custom_mode: u32) -> Option<FlightMode> {
        Self::from_px4((custom_mode >> 16) as u8, (custom_mode >> 24) as u8)
    }
}

/// What RC loss does in Mission and Offboard (`FS_RC_ACT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RcLossAction {
    /// Carry on (the mission or the companion computer owns the vehicle). Code 0.
    Continue = 0,
    /// Return to the start, then land. Code 1.
    Return = 1,
}

/// Parameters of the mode machine and the piloted modes (the `modes` part of
/// [`crate::controller::ControllerParams`]; the table entries are in [`crate::params`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ModeParams {
    /// Manual: tilt at full roll/pitch stick, rad. Default 0.35 (20°).
    pub manual_tilt_max: f32,
    /// Position assist: horizontal speed at full stick, m/s. Default 1.0.
    pub assist_speed: f32,
    /// Position assist: climb/descent rate at full throttle stick deflection, m/s. Default 0.5.
    pub assist_climb: f32,
    /// Yaw rate at full yaw stick (Manual, Position), rad/s. Default 1.0.
    pub yaw_rate_max: f32,
    /// Stick deadband around centre (Position; the throttle's around 0.5), fraction. Default 0.05.
    pub deadband: f32,
    /// Mode selected by the mode switch's low, middle and high positions. Default
    /// Position, Hold, Mission.
    pub switch_modes: [FlightMode; 3],
    /// No valid RC frame for this long is an RC loss, s. Default 0.5.
    pub rc_timeout_s: f32,
    /// After an RC loss in Manual/Position: Hold, then Land after this long without RC, s.
    /// Default 5.
    pub rc_loss_land_s: f32,
    /// RC loss in Mission/Offboard. Default Continue.
    pub rc_loss_auto: RcLossAction,
    /// No valid offboard setpoint for this long in Offboard → Hold, s. Default 0.5.
    pub offboard_timeout_s: f32,
    /// Breadcrumb spacing of the Return path, m (doubles each time the buffer fills). Default 0.5.
    pub crumb_spacing: f32,
    /// Return speed along the breadcrumbs, m/s. Default 0.5.
    pub return_speed: f32,
    /// Battery failsafes on (Low → Return, Critical → Land). Default true.
    pub battery_failsafe: bool,
}

impl Default for ModeParams {
    fn default() -> Self {
        ModeParams {
            manual_tilt_max: 0.35,
            assist_speed: 1.0,
            assist_climb: 0.5,
            yaw_rate_max: 1.0,
            deadband: 0.05,
            switch_modes: [FlightMode::Position, FlightMode::Hold, FlightMode::Mission],
            rc_timeout_s: 0.5,
            rc_loss_land_s: 5.0,
            rc_loss_auto: RcLossAction::Continue,
            offboard_timeout_s: 0.5,
            crumb_spacing: 0.5,
            return_speed: 0.5,
            battery_failsafe: true,
        }
    }
}

/// The [`crate::param_decl::Access`] of the mode switch's position `i` (a [`FlightMode`] code; an
/// unknown code keeps the mode).
macro_rules! switch_position {
    ($i:literal) => {
        access!(|s| s.switch_modes[$i] as i32 as f32, |s, v| {
            s.switch_modes[$i] = FlightMode::from_code(v as i32).unwrap_or(s.switch_modes[$i])
        })
    };
}

impl ModeParams {
    /// The flight modes' and their failsafes' parameters (issue 21; `crate::params`, MAVLink
    /// `param_index` order).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 15] {
        [
            Param::new("MAN_TILT_MAX", "Modes", "rad", (0.05, 1.0), 2, field!(manual_tilt_max),
                "Manual: tilt at full roll/pitch stick (capped by the thrust map's tilt limit)"),
            Param::new("PA_SPEED_MAX", "Modes", "m/s", (0.1, 10.0), 2, field!(assist_speed),
                "Position assist: horizontal speed at full stick (heading frame)"),
            Param::new("PA_CLIMB_MAX", "Modes", "m/s", (0.1, 5.0), 2, field!(assist_climb),
                "Position assist: climb/descent rate at full throttle deflection from mid"),
            Param::new("PA_YAWRATE_MAX", "Modes", "rad/s", (0.1, 6.0), 2, field!(yaw_rate_max),
                "Yaw rate at full yaw stick (Manual, Position)"),
            Param::new("PA_DEADBAND", "Modes", "", (0.0, 0.5), 3, field!(deadband),
                "Stick deadband around centre (throttle: around 0.5), fraction of full deflection"),
            Param::new("MODE_SW_LOW", "Modes", "", (0.0, 6.0), 0, switch_position!(0),
                "Flight mode of the RC mode switch's low position").code(mode_label),
            Param::new("MODE_SW_MID", "Modes", "", (0.0, 6.0), 0, switch_position!(1),
                "Flight mode of the RC mode switch's middle position").code(mode_label),
            Param::new("MODE_SW_HIGH", "Modes", "", (0.0, 6.0), 0, switch_position!(2),
                "Flight mode of the RC mode switch's high position").code(mode_label),
            Param::new("FS_RC_TIMEOUT", "Failsafe", "s", (0.05, 10.0), 2, field!(rc_timeout_s),
                "No valid RC frame for this long is an RC loss (once RC was seen)"),
            Param::new("FS_RC_LAND_T", "Failsafe", "s", (0.0, 120.0), 1, field!(rc_loss_land_s),
                "RC loss in Manual/Position: Hold, then Land after this long without RC"),
            Param::new("FS_RC_ACT", "Failsafe", "", (0.0, 1.0), 0, access!(|s| s.rc_loss_auto as i32 as f32, |s, v| {
                    s.rc_loss_auto = if v >= 0.5 { RcLossAction::Return } else { RcLossAction::Continue }
                }),
                "RC loss in Mission/Offboard: 0 continue, 1 return").code(|c| match c {
                    0 => Some("continue"),
                    1 => Some("return"),
                    _ => None,
                }),
            Param::new("OFFB_TIMEOUT", "Failsafe", "s", (0.05, 10.0), 2, field!(offboard_timeout_s),
                "Offboard: no valid setpoint for this long -> Hold"),
            Param::new("RTL_CRUMB_DIST", "Modes", "m", (0.1, 10.0), 2, field!(crumb_spacing),
                "Return: breadcrumb spacing of the flown path (doubles when the 32-crumb buffer fills)"),
            Param::new("RTL_SPEED", "Modes", "m/s", (0.05, 5.0), 2, field!(return_speed),
                "Return: speed back along the breadcrumbs"),
            Param::new("FS_BAT_ACT", "Failsafe", "", (0.0, 1.0), 0, flag!(battery_failsafe),
                "Battery failsafes: 0 off, 1 low -> Return, critical -> Land").code(|c| match c {
                    0 => Some("off"),
                    1 => Some("return/land"),
                    _ => None,
                }),
        ]
    }
}

/// The name of a [`FlightMode`] code (the `MODE_SW_*` labels).
fn mode_label(code: i32) -> Option<&'static str> {
    FlightMode::from_code(code).map(FlightMode::as_str)
}

/// `s` seconds in µs (non-negative, saturating).
fn us(s: f32) -> u64 {
    (s.max(0.0) * 1e6) as u64
}

impl ModeParams {
    /// RC timeout, µs.
    pub fn rc_timeout_us(&self) -> u64 {
        us(self.rc_timeout_s)
    }
    /// Hold-then-land time after an RC loss, µs.
    pub fn rc_loss_land_us(&self) -> u64 {
        us(self.rc_loss_land_s)
    }
    /// Offboard setpoint timeout, µs.
    pub fn offboard_timeout_us(&self) -> u64 {
        us(self.offboard_timeout_s)
    }

    /// `true` when every field is finite and in the range of its table entry.
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32, hi: f32| x.is_finite() && x > 0.0 && x <= hi;
        pos(self.manual_tilt_max, 1.0)
            && pos(self.assist_speed, 10.0)
            && pos(self.assist_climb, 5.0)
            && pos(self.yaw_rate_max, 6.0)
            && self.deadband.is_finite()
            && (0.0..=0.5).contains(&self.deadband)
            && pos(self.rc_timeout_s, 10.0)
            && pos(self.offboard_timeout_s, 10.0)
            && self.rc_loss_land_s.is_finite()
            && (0.0..=120.0).contains(&self.rc_loss_land_s)
            && pos(self.crumb_spacing, 10.0)
            && pos(self.return_speed, 5.0)
    }
}

/// One mode change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ModeTransition {
    /// Mode before.
    pub from: FlightMode,
    /// Mode after.
    pub to: FlightMode,
    /// Cause (the failsafe machine's reasons, shared).
    pub reason: TransitionReason,
    /// Time of the change, µs.
    pub t_us: u64,
}

/// What one RC frame asks for (applied by the outer loop).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct RcRequest {
    /// Kill switch on: motors off now.
    pub kill: bool,
    /// Arm switch turned on.
    pub arm: bool,
    /// Arm switch turned off (disarm on the ground).
    pub disarm: bool,
    /// Mode switch moved (or first frame): this mode.
    pub mode: Option<FlightMode>,
    /// The first RC frame ever accepted (the outer loop applies its switch position only
    /// while disarmed: an RC link that comes up in flight changes no mode until the switch moves).
    pub first: bool,
}

/// What the vehicle is doing, for [`Modes::check`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlightContext {
    /// Armed (failsafe state Armed, Brake or Land) and off the ground.
    pub airborne: bool,
}

/// The mode machine (see the module documentation).
#[derive(Clone, Debug)]
pub struct Modes {
    params: ModeParams,
    mode: FlightMode,
    last: Option<ModeTransition>,
    count: u32,
    rc: Option<RcInput>,
    rc_lost: bool,
    rc_lost_since_us: Option<u64>,
    rc_loss_landing: bool,
    switch: Option<SwitchPosition>,
    arm_switch: Option<bool>,
    rc_rejected: u32,
    offboard_t_us: Option<u64>,
    offboard_lost: bool,
    battery: BatteryLevel,
    battery_seen: BatteryLevel,
}

fn stick_ok(x: f32, lo: f32, hi: f32) -> bool {
    x >= lo - STICK_TOLERANCE && x <= hi + STICK_TOLERANCE
}

/// Sticks the machine accepts (finite, within the range by at most the tolerance); any other
/// frame is rejected whole, switches too.
fn sticks_ok(rc: &RcInput) -> bool {
    stick_ok(rc.roll, -1.0, 1.0)
        && stick_ok(rc.pitch, -1.0, 1.0)
        && stick_ok(rc.yaw, -1.0, 1.0)
        && stick_ok(rc.throttle, 0.0, 1.0)
}

/// `true` when [`Modes::on_rc`] would act on `rc`'s kill switch (a frame it accepts, not a
/// receiver failsafe or lost frame, kill on; the time order aside). A firmware checks this where
/// the frame arrives and stops the motors at once, before the outer loop takes the frame.
pub fn kill_requested(rc: &RcInput) -> bool {
    rc.kill && sticks_ok(rc) && !rc.failsafe && rc.lost.is_none()
}

impl Modes {
    /// A machine in the default mode (Mission), no RC seen.
    pub fn new(params: ModeParams) -> Self {
        Modes {
            params,
            mode: FlightMode::default(),
            last: None,
            count: 0,
            rc: None,
            rc_lost: false,
            rc_lost_since_us: None,
            rc_loss_landing: false,
            switch: None,
            arm_switch: None,
            rc_rejected: 0,
            offboard_t_us: None,
            offboard_lost: false,
            battery: BatteryLevel::Ok,
            battery_seen: BatteryLevel::Ok,
        }
    }

    /// Parameters in use.
    pub fn params(&self) -> &ModeParams {
        &self.params
    }

    /// Current mode.
    pub fn mode(&self) -> FlightMode {
        self.mode
    }

    /// Last mode change.
    pub fn last_transition(&self) -> Option<ModeTransition> {
        self.last
    }

    /// Mode changes so far (saturating).
    pub fn transition_count(&self) -> u32 {
        self.count
    }

    /// RC frames rejected (NaN/Inf or out-of-range sticks) since start.
    pub fn rc_rejected(&self) -> u32 {
        self.rc_rejected
    }

    /// The last valid RC frame, if it is not older than the RC timeout at `now_us` and not a
    /// receiver failsafe frame.
    pub fn rc(&self, now_us: u64) -> Option<&RcInput> {
        self.rc.as_ref().filter(|rc| {
            !rc.failsafe && rc.lost.is_none() && now_us.saturating_sub(rc.t_us) <= self.params.rc_timeout_us()
        })
    }

    /// `true` once an RC frame was accepted and the link is lost now (timeout or failsafe).
    pub fn rc_lost(&self) -> bool {
        self.rc_lost
    }

    /// The mode the switch selects now (when RC is valid), else Mission.
    pub fn base_mode(&self, now_us: u64) -> FlightMode {
        match (self.rc(now_us), self.switch) {
            (Some(_), Some(s)) => self.switch_mode(s),
            _ => FlightMode::Mission,
        }
    }

    fn switch_mode(&self, s: SwitchPosition) -> FlightMode {
        let i = match s {
            SwitchPosition::Low => 0,
            SwitchPosition::Mid => 1,
            SwitchPosition::High => 2,
        };
        self.params.switch_modes[i]
    }

    /// Change the mode (the caller checked that the mode can be flown). `None` when already in it.
    pub fn go(&mut self, to: FlightMode, reason: TransitionReason, t_us: u64) -> Option<ModeTransition> {
        if to == self.mode {
            return None;
        }
        let tr = ModeTransition { from: self.mode, to, reason, t_us };
        self.mode = to;
        self.last = Some(tr);
        self.count = self.count.saturating_add(1);
        if to != FlightMode::Hold {
            self.rc_loss_landing = false;
        }
        Some(tr)
    }

    /// Take one RC frame: rejects bad frames (counted, `None`), else stores it and returns
    /// what it asks for. A receiver failsafe frame asks for nothing (and is an RC loss).
    pub fn on_rc(&mut self, rc: &RcInput) -> Option<RcRequest> {
        if !sticks_ok(rc) {
            self.rc_rejected = self.rc_rejected.saturating_add(1);
            return None;
        }
        if self.rc.is_some_and(|old| rc.t_us < old.t_us) {
            return None;
        }
        let mut clamped = *rc;
        clamped.roll = clamped.roll.clamp(-1.0, 1.0);
        clamped.pitch = clamped.pitch.clamp(-1.0, 1.0);
        clamped.yaw = clamped.yaw.clamp(-1.0, 1.0);
        clamped.throttle = clamped.throttle.clamp(0.0, 1.0);
        self.rc = Some(clamped);
        if rc.failsafe || rc.lost.is_some() {
            // Not the pilot's sticks (receiver failsafe, the producer's loss verdict).
            return Some(RcRequest::default());
        }
        let was_lost = self.rc_lost;
        self.rc_lost = false;
        self.rc_lost_since_us = None;
        let mut req = RcRequest { kill: rc.kill, ..RcRequest::default() };
        let prev_arm = self.arm_switch.replace(rc.arm);
        req.arm = rc.arm && prev_arm == Some(false);
        req.disarm = !rc.arm && prev_arm == Some(true);
        let prev_switch = self.switch.replace(rc.mode);
        // First frame or a moved switch selects; the frame that restores a lost link does not.
        req.first = prev_switch.is_none();
        if prev_switch.is_none() || (prev_switch != Some(rc.mode)) {
            req.mode = Some(self.switch_mode(rc.mode));
        }
        if was_lost && prev_switch == Some(rc.mode) {
            req.mode = None;
        }
        Some(req)
    }

    /// A valid offboard setpoint arrived at `t_us`.
    pub fn on_offboard(&mut self, t_us: u64) {
        self.offboard_t_us = Some(self.offboard_t_us.map_or(t_us, |t| t.max(t_us)));
        self.offboard_lost = false;
    }

    /// A fresh offboard setpoint exists at `now_us`.
    pub fn offboard_fresh(&self, now_us: u64) -> bool {
        self.offboard_t_us.is_some_and(|t| now_us.saturating_sub(t) <= self.params.offboard_timeout_us())
    }

    /// Take a battery measurement.
    pub fn on_battery(&mut self, b: &BatteryState) {
        // A level never goes back up in flight (the measurement's contract); enforce it here too.
        self.battery = match (self.battery, b.level) {
            (BatteryLevel::Critical, _) | (_, BatteryLevel::Critical) => BatteryLevel::Critical,
            (BatteryLevel::Low, _) | (_, BatteryLevel::Low) => BatteryLevel::Low,
            _ => BatteryLevel::Ok,
        };
    }

    /// Battery level in use.
    pub fn battery(&self) -> BatteryLevel {
        self.battery
    }

    /// Forget the battery latch and the failsafe edges (on disarm: a new flight).
    pub fn reset_flight(&mut self) {
        self.battery_seen = self.battery;
        self.rc_loss_landing = false;
    }

    /// The failsafe check of one outer step: the mode change it asks for (already applied to
    /// the machine's mode except for Land, which the caller applies through the failsafe
    /// machine and then confirms with [`Self::go`]). At most one per call.
    pub fn check(&mut self, now_us: u64, ctx: FlightContext) -> Option<(FlightMode, TransitionReason)> {
        // RC loss edge (only once RC has been seen).
        if let Some(rc) = self.rc {
            let lost = rc.failsafe || now_us.saturating_sub(rc.t_us) > self.params.rc_timeout_us();
            if lost && !self.rc_lost {
                self.rc_lost = true;
                self.rc_lost_since_us = Some(now_us);
                if ctx.airborne {
                    let to = match self.mode {
                        FlightMode::Manual | FlightMode::Position => Some(FlightMode::Hold),
                        FlightMode::Mission | FlightMode::Offboard => match self.params.rc_loss_auto {
                            RcLossAction::Continue => None,
                            RcLossAction::Return => Some(FlightMode::Return),
                        },
                        _ => None,
                    };
                    if let Some(to) = to {
                        self.rc_loss_landing = to == FlightMode::Hold;
                        return Some((to, TransitionReason::RcLoss));
                    }
                }
            }
        }
        // Hold after an RC loss in a piloted mode: land after the timeout without RC.
        if self.rc_loss_landing && self.rc_lost && self.mode == FlightMode::Hold && ctx.airborne {
            let since = self.rc_lost_since_us.unwrap_or(now_us);
            if now_us.saturating_sub(since) >= self.params.rc_loss_land_us() {
                self.rc_loss_landing = false;
                return Some((FlightMode::Land, TransitionReason::RcLoss));
            }
        }
        // Offboard stream stopped.
        if self.mode == FlightMode::Offboard && !self.offboard_lost && !self.offboard_fresh(now_us) {
            self.offboard_lost = true;
            return Some((FlightMode::Hold, TransitionReason::OffboardLoss));
        }
        // Battery level drops (edges).
        if self.params.battery_failsafe && self.battery != self.battery_seen {
            let level = self.battery;
            self.battery_seen = level;
            if ctx.airborne {
                match level {
                    BatteryLevel::Critical if self.mode != FlightMode::Land => {
                        return Some((FlightMode::Land, TransitionReason::BatteryCritical));
                    }
                    BatteryLevel::Low if !matches!(self.mode, FlightMode::Return | FlightMode::Land) => {
                        return Some((FlightMode::Return, TransitionReason::BatteryLow));
                    }
                    _ => {}
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use TransitionReason as R;

    fn rc(t_us: u64) -> RcInput {
        RcInput { t_us, throttle: 0.5, link_quality: 100, ..RcInput::default() }
    }
    const AIR: FlightContext = FlightContext { airborne: true };

    /// The firmware's early kill check says yes exactly for the frames whose kill the machine
    /// acts on.
    #[test]
    fn kill_requested_matches_what_on_rc_acts_on() {
        use crate::rc::RcLost;
        let kill = RcInput { kill: true, ..rc(10) };
        let cases = [
            (kill, true),
            (RcInput { kill: false, ..kill }, false),
            (RcInput { roll: 1.04, ..kill }, true),
            (RcInput { roll: 1.2, ..kill }, false),
            (RcInput { throttle: f32::NAN, ..kill }, false),
            (RcInput { failsafe: true, ..kill }, false),
            (RcInput { lost: Some(RcLost::LowLinkQuality), ..kill }, false),
        ];
        for (i, (input, expected)) in cases.iter().enumerate() {
            assert_eq!(kill_requested(input), *expected, "case {i}");
            let mut m = Modes::new(ModeParams::default());
            let acted = m.on_rc(input).is_some_and(|r| r.kill);
            assert_eq!(acted, *expected, "case {i}: on_rc");
        }
    }

    #[test]
    fn names_codes_and_px4_modes_round_trip() {
        for m in FlightMode::ALL {
            assert_eq!(FlightMode::from_code(m as i32), Some(m));
            assert_eq!(FlightMode::from_px4_custom_mode(m.px4_custom_mode()), Some(m), "{}", m.as_str());
            let (main, sub) = m.px4_main_sub();
            assert_eq!(FlightMode::from_px4(main, sub), Some(m));
        }
        assert_eq!(FlightMode::Position.px4_custom_mode(), 3 << 16);
        assert_eq!(FlightMode::Return.px4_custom_mode(), (4 << 16) | (5 << 24));
        assert_eq!(FlightMode::from_px4(5, 0), None, "ACRO is not flown");
        assert_eq!(FlightMode::from_code(7), None);
        assert!(!FlightMode::Manual.filtered());
        assert!(FlightMode::ALL[1..].iter().all(|m| m.filtered()));
    }

    #[test]
    fn bad_frames_are_rejected_counted_and_time_out_as_rc_loss() {
        let mut m = Modes::new(ModeParams::default());
        m.go(FlightMode::Position, R::ModeCommand, 0);
        assert!(m.on_rc(&rc(1_000)).is_some());
        for (k, bad) in [
            RcInput { roll: f32::NAN, ..rc(2_000) },
            RcInput { pitch: f32::INFINITY, ..rc(3_000) },
            RcInput { throttle: 1.2, ..rc(4_000) },
            RcInput { yaw: -1.06, ..rc(5_000) },
        ]
        .iter()
        .enumerate()
        {
            assert!(m.on_rc(bad).is_none());
            assert_eq!(m.rc_rejected(), k as u32 + 1);
        }
        // A slight overshoot is clamped, not rejected.
        assert!(m.on_rc(&RcInput { roll: 1.04, ..rc(6_000) }).is_some());
        assert_eq!(m.rc(6_000).map(|r| r.roll), Some(1.0));
        // Only bad frames from now on: RC loss at the timeout → Hold.
        assert_eq!(m.check(6_000 + 500_000, AIR), None);
        assert!(m.on_rc(&RcInput { roll: f32::NAN, ..rc(600_000) }).is_none());
        assert_eq!(m.check(6_000 + 500_001, AIR), Some((FlightMode::Hold, R::RcLoss)));
    }

    #[test]
    fn switch_edges_first_frame_and_rc_regain() {
        let mut m = Modes::new(ModeParams::default());
        let r = m.on_rc(&RcInput { mode: SwitchPosition::Low, ..rc(0) }).unwrap_or_default();
        assert_eq!(r.mode, Some(FlightMode::Position), "the first frame selects");
        let r = m.on_rc(&RcInput { mode: SwitchPosition::Low, ..rc(10) }).unwrap_or_default();
        assert_eq!(r.mode, None, "unchanged switch");
        let r = m.on_rc(&RcInput { mode: SwitchPosition::High, arm: true, ..rc(20) }).unwrap_or_default();
        assert_eq!((r.mode, r.arm), (Some(FlightMode::Mission), true));
        let r = m.on_rc(&RcInput { mode: SwitchPosition::High, arm: false, ..rc(30) }).unwrap_or_default();
        assert!(r.disarm && !r.arm);
        // Lost, then back with the same switch position: no mode change by the regained frame.
        assert!(m.check(1_000_000, FlightContext { airborne: false }).is_none());
        assert!(m.rc_lost());
        let r = m.on_rc(&RcInput { mode: SwitchPosition::High, ..rc(1_100_000) }).unwrap_or_default();
        assert_eq!(r.mode, None);
        assert!(!m.rc_lost());
        let r = m.on_rc(&RcInput { mode: SwitchPosition::Mid, ..rc(1_100_010) }).unwrap_or_default();
        assert_eq!(r.mode, Some(FlightMode::Hold));
    }

    #[test]
    fn rc_loss_per_mode() {
        for (mode, act, expect) in [
            (FlightMode::Manual, RcLossAction::Continue, Some(FlightMode::Hold)),
            (FlightMode::Position, RcLossAction::Continue, Some(FlightMode::Hold)),
            (FlightMode::Mission, RcLossAction::Continue, None),
            (FlightMode::Offboard, RcLossAction::Continue, None),
            (FlightMode::Mission, RcLossAction::Return, Some(FlightMode::Return)),
            (FlightMode::Offboard, RcLossAction::Return, Some(FlightMode::Return)),
            (FlightMode::Hold, RcLossAction::Return, None),
            (FlightMode::Return, RcLossAction::Return, None),
        ] {
            let mut m = Modes::new(ModeParams { rc_loss_auto: act, ..ModeParams::default() });
            m.on_rc(&rc(0));
            m.go(mode, R::ModeCommand, 0);
            m.on_offboard(400_000);
            assert_eq!(m.check(400_000, AIR), None);
            let got = m.check(500_001, AIR);
            assert_eq!(got, expect.map(|to| (to, R::RcLoss)), "{mode:?} {act:?}");
            assert_eq!(m.check(500_002, AIR), None, "edge-triggered");
        }
        // Receiver failsafe frame: lost at once.
        let mut m = Modes::new(ModeParams::default());
        m.on_rc(&rc(0));
        m.go(FlightMode::Position, R::ModeCommand, 0);
        m.on_rc(&RcInput { failsafe: true, ..rc(10) });
        assert!(m.rc(10).is_none());
        assert_eq!(m.check(10, AIR), Some((FlightMode::Hold, R::RcLoss)));
    }

    #[test]
    fn rc_loss_in_position_holds_then_lands_after_the_timeout() {
        let p = ModeParams::default();
        let mut m = Modes::new(p);
        m.on_rc(&rc(0));
        m.go(FlightMode::Position, R::ModeSwitch, 0);
        let t_loss = p.rc_timeout_us() + 1;
        let (to, why) = m.check(t_loss, AIR).unwrap_or((FlightMode::Manual, R::Landed));
        assert_eq!((to, why), (FlightMode::Hold, R::RcLoss));
        m.go(to, why, t_loss);
        assert_eq!(m.check(t_loss + p.rc_loss_land_us() - 1, AIR), None);
        assert_eq!(m.check(t_loss + p.rc_loss_land_us(), AIR), Some((FlightMode::Land, R::RcLoss)));
        // RC back before the land timeout: stays in Hold, no landing.
        let mut m = Modes::new(p);
        m.on_rc(&rc(0));
        m.go(FlightMode::Position, R::ModeSwitch, 0);
        let _ = m.check(t_loss, AIR);
        m.go(FlightMode::Hold, R::RcLoss, t_loss);
        m.on_rc(&rc(t_loss + 1_000));
        assert_eq!(m.check(t_loss + p.rc_loss_land_us() + 1, AIR), None);
        assert_eq!(m.mode(), FlightMode::Hold);
    }

    #[test]
    fn offboard_timeout_holds() {
        let p = ModeParams::default();
        let mut m = Modes::new(p);
        m.on_offboard(1_000);
        m.go(FlightMode::Offboard, R::ModeCommand, 1_000);
        assert_eq!(m.check(1_000 + p.offboard_timeout_us(), AIR), None);
        assert_eq!(m.check(1_001 + p.offboard_timeout_us(), AIR), Some((FlightMode::Hold, R::OffboardLoss)));
    }

    #[test]
    fn battery_low_returns_critical_lands_once_each() {
        let mut m = Modes::new(ModeParams::default());
        m.go(FlightMode::Position, R::ModeCommand, 0);
        let b = |level| BatteryState { level, voltage_v: 11.0, ..BatteryState::default() };
        m.on_battery(&b(BatteryLevel::Low));
        assert_eq!(m.check(1, AIR), Some((FlightMode::Return, R::BatteryLow)));
        assert_eq!(m.check(2, AIR), None, "once");
        m.on_battery(&b(BatteryLevel::Ok));
        assert_eq!(m.battery(), BatteryLevel::Low, "never back up");
        m.on_battery(&b(BatteryLevel::Critical));
        assert_eq!(m.check(3, AIR), Some((FlightMode::Land, R::BatteryCritical)));
        let mut m = Modes::new(ModeParams { battery_failsafe: false, ..ModeParams::default() });
        m.on_battery(&b(BatteryLevel::Critical));
        assert_eq!(m.check(1, AIR), None, "failsafe off");
    }
}
