//! [`PilotSink`] for the firmware in QEMU ([`crate::fc::pil::PilLink`]): each RC frame goes
//! over the lockstep link as MANUAL_CONTROL (69) with the core's own mapping
//! (`parapet_core::rc::manual::to_manual_control`: x pitch, y roll, z throttle, r yaw, ×1000;
//! buttons bit 0 arm, bit 1 kill, bits 2–3 mode), sent with the control step it is due at; the
//! firmware's link turns it back into the same `RcInput` (`firmware/src/link/manual_control.rs`).
//!
//! Entering Position-assist: the link has no DO_SET_MODE for Position yet, so the mode switch
//! does it — a frame with the switch at Mid (`MODE_SW_MID`, Hold) at the start, then the
//! script's frames at Low (`MODE_SW_LOW`, Position). The in-process comparison run does the
//! same ([`super::PilotedController::via_switch`]). Offboard is refused (no setpoint path in
//! the PIL host yet).
//!
//! May import: `parapet-core`, mavlink, [`crate::fc::pil`], [`crate::flight`], [`super::stack`].

use anyhow::{bail, Result};
use mavlink::dialects::ardupilotmega::{MavMessage, MANUAL_CONTROL_DATA};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::rc::manual::to_manual_control;
use parapet_core::rc::{RcInput, SwitchPosition};
use parapet_core::wire::ids::VEHICLE_SYSTEM_ID;

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
}

impl PilotedPil {
    /// Wrap `link`.
    pub fn new(link: PilLink) -> Self {
        PilotedPil { link, last_rc: None, frames_sent: 0 }
    }
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
            (PilotMode::Offboard, _) => bail!("PIL: Offboard is not supported over the PIL link yet"),
            // The start-up's MISSION_START selects it.
            (PilotMode::Mission, _) => Ok(()),
        }
    }

    fn rc(&mut self, rc: &RcInput) {
        self.last_rc = Some(*rc);
        self.frames_sent += 1;
        self.link.send(&manual_control(rc));
    }

    fn offboard(&mut self, _sp: &TimedSetpoint) {}

    fn flight_mode(&self) -> String {
        self.link.state_name()
    }

    fn filter_active(&self) -> Option<bool> {
        None
    }
}

impl FlightStack for PilotedPil {
    fn start(
        &mut self,
        t: f64,
        start: nalgebra::Vector3<f64>,
        fix: PositionReading,
        obstacles: &[ObstaclePoint],
        imu: &ImuReading,
    ) -> Result<()> {
        self.link.start(t, start, fix, obstacles, imu)
    }

    fn position_fix(&mut self, fix: PositionReading) {
        self.link.position_fix(fix);
    }

    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        self.link.outer(t, obstacles)
    }

    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        self.link.inner(t, imu)
    }

    fn state_name(&self) -> String {
        self.link.state_name()
    }
}
