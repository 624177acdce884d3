//! [`PilotSink`] for the firmware in QEMU ([`crate::fc::pil::PilLink`]): each RC frame goes
//! over the lockstep link as MANUAL_CONTROL (69) with the core's own mapping
//! (`parapet_core::rc::manual::to_manual_control`: x pitch, y roll, z throttle, r yaw, ×1000;
//! buttons bit 0 arm, bit 1 kill, bits 2–3 mode), sent with the control step it is due at; the
//! firmware's link turns it back into the same `RcInput` (`firmware/src/link/manual_control.rs`).
//!
//! Entering Position-assist: the mode switch does it — a frame with the switch at Mid
//! (`MODE_SW_MID`, Hold) at the start, then the script's frames at Low (`MODE_SW_LOW`,
//! Position). The in-process comparison run does the same
//! ([`super::PilotedController::via_switch`]).
//!
//! **Offboard**: each setpoint goes as SET_POSITION_TARGET_LOCAL_NED (84) with the step it is
//! due at ([`position_target`]: `MAV_FRAME_LOCAL_NED`, the script's groups, the others and yaw /
//! yaw rate ignored in `type_mask`), at the script's `setpoint_rate_hz` — the stream a companion
//! computer sends, as PX4 wants it before Offboard may be entered. The mode is entered with
//! MAV_CMD_DO_SET_MODE (p1 = CUSTOM_MODE_ENABLED, p2 = 6, PX4's OFFBOARD main mode) in the first
//! flight step, after the link's MISSION_START (which selects Mission), so the firmware enters
//! it before its first flight outer step, as the in-process run's `set_mode` does. The
//! firmware's answer is its mode report (HEARTBEAT `custom_mode`, the "MODE Offboard:
//! mode-command" STATUSTEXT): [`PilotSink::flight_mode`] is the mode it last reported.
//!
//! May import: `parapet-core`, mavlink, [`crate::fc::pil`], [`crate::flight`], [`super::stack`].

use anyhow::{bail, Result};
use mavlink::dialects::ardupilotmega::{
    MavCmd, MavFrame, MavMessage, PositionTargetTypemask as M, COMMAND_LONG_DATA, MANUAL_CONTROL_DATA,
    SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::rc::manual::to_manual_control;
use parapet_core::rc::{RcInput, SwitchPosition};
use parapet_core::wire::ids::{AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};

use super::stack::{PilotMode, PilotSink, TimedSetpoint};
use crate::fc::pil::PilLink;
use crate::flight::stack::{FlightStack, OuterOut};
use crate::sim::sensors::{ImuReading, PositionReading};

/// The firmware in QEMU with pilot input (see the module documentation).
pub struct PilotedPil {
    /// The link.
    pub link: PilLink,
    last_rc: Option<RcInput>,
    /// MANUAL_CONTROL frames sent.
    pub frames_sent: u64,
    /// SET_POSITION_TARGET_LOCAL_NED setpoints sent.
    pub setpoints_sent: u64,
    /// DO_SET_MODE Offboard to send after the link's MISSION_START (first flight step).
    offboard_pending: bool,
}

impl PilotedPil {
    /// Wrap `link`.
    pub fn new(link: PilLink) -> Self {
        PilotedPil { link, last_rc: None, frames_sent: 0, setpoints_sent: 0, offboard_pending: false }
    }
}

/// PX4's OFFBOARD main mode (DO_SET_MODE param2).
pub const PX4_MAIN_OFFBOARD: f32 = 6.0;

/// The SET_POSITION_TARGET_LOCAL_NED of one timed setpoint (NED; `time_boot_ms` = its time).
pub fn position_target(sp: &TimedSetpoint) -> MavMessage {
    let s = &sp.setpoint;
    let mut mask = M::POSITION_TARGET_TYPEMASK_YAW_IGNORE | M::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE;
    let mut group = |v: Option<nalgebra::Vector3<f64>>, bits: M| {
        if v.is_none() {
            mask |= bits;
        }
        v.map_or([0.0; 3], |v| [v.x as f32, v.y as f32, v.z as f32])
    };
    let p = group(
        s.position,
        M::POSITION_TARGET_TYPEMASK_X_IGNORE
            | M::POSITION_TARGET_TYPEMASK_Y_IGNORE
            | M::POSITION_TARGET_TYPEMASK_Z_IGNORE,
    );
    let v = group(
        s.velocity,
        M::POSITION_TARGET_TYPEMASK_VX_IGNORE
            | M::POSITION_TARGET_TYPEMASK_VY_IGNORE
            | M::POSITION_TARGET_TYPEMASK_VZ_IGNORE,
    );
    let a = group(
        s.acceleration,
        M::POSITION_TARGET_TYPEMASK_AX_IGNORE
            | M::POSITION_TARGET_TYPEMASK_AY_IGNORE
            | M::POSITION_TARGET_TYPEMASK_AZ_IGNORE,
    );
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms: (sp.t_us / 1000) as u32,
        target_system: VEHICLE_SYSTEM_ID,
        target_component: AUTOPILOT_COMPONENT_ID,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        type_mask: mask,
        x: p[0],
        y: p[1],
        z: p[2],
        vx: v[0],
        vy: v[1],
        vz: v[2],
        afx: a[0],
        afy: a[1],
        afz: a[2],
        yaw: 0.0,
        yaw_rate: 0.0,
    })
}

/// MAV_CMD_DO_SET_MODE to PX4's OFFBOARD (custom-mode flag set, main mode 6, sub mode 0).
pub fn set_mode_offboard() -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: VEHICLE_SYSTEM_ID,
        target_component: AUTOPILOT_COMPONENT_ID,
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        param1: 1.0,
        param2: PX4_MAIN_OFFBOARD,
        ..Default::default()
    })
}

/// The MANUAL_CONTROL message of one RC frame (`..Default::default()`: the extension fields
/// exist when the fuzz workspace turns MAVLink 2 extensions on).
#[allow(clippy::needless_update)]
pub fn manual_control(rc: &RcInput) -> MavMessage {
    let (x, y, z, r, buttons) = to_manual_control(rc);
    MavMessage::MANUAL_CONTROL(MANUAL_CONTROL_DATA {
        target: VEHICLE_SYSTEM_ID,
        x,
        y,
        z,
        r,
        buttons,
        ..Default::default()
    })
}

impl PilotSink for PilotedPil {
    fn enter(&mut self, _now_us: u64, mode: PilotMode) -> Result<()> {
        match (mode, self.last_rc) {
            (PilotMode::Position, Some(rc)) => {
                self.rc(&RcInput { mode: SwitchPosition::Mid, ..rc });
                Ok(())
            }
            (PilotMode::Position, None) => bail!("PIL: no RC frame to enter Position-assist with"),
            (PilotMode::Offboard, _) if self.setpoints_sent == 0 => {
                bail!("PIL: no offboard setpoint streamed to enter Offboard with")
            }
            (PilotMode::Offboard, _) => {
                self.offboard_pending = true;
                Ok(())
            }
            // The start-up's MISSION_START selects it.
            (PilotMode::Mission, _) => Ok(()),
        }
    }

    fn rc(&mut self, rc: &RcInput) {
        self.last_rc = Some(*rc);
        self.frames_sent += 1;
        self.link.send(&manual_control(rc));
    }

    fn offboard(&mut self, sp: &TimedSetpoint) {
        self.setpoints_sent += 1;
        self.link.send(&position_target(sp));
    }

    fn flight_mode(&self) -> String {
        self.link.flight_mode().map_or_else(|| "Unknown".into(), |m| m.as_str().to_string())
    }

    fn filter_active(&self) -> Option<bool> {
        None
    }
}

impl FlightStack for PilotedPil {
    fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> Result<()> {
        self.link.start(s)
    }

    fn position_fix(&mut self, fix: PositionReading) {
        self.link.position_fix(fix);
    }

    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        let out = self.link.outer(t, obstacles);
        if std::mem::take(&mut self.offboard_pending) {
            self.link.send(&set_mode_offboard());
        }
        out
    }

    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        self.link.inner(t, imu)
    }

    fn state_name(&self) -> String {
        self.link.state_name()
    }
}
