//! [`PilotSink`] for the in-process controller ([`crate::fc::control::Controller`]): RC frames
//! go to `FlightController::set_rc`, setpoints to `set_offboard`, the run's mode is entered
//! with `set_mode` (Position-assist or Offboard, the core's mode machine,
//! `parapet_core::supervisor::modes`), the flight mode and the filter's intervention are the
//! controller's telemetry. Nothing of the modes is emulated here.
//!
//! May import: `parapet-core`, [`crate::fc::control`], [`crate::flight`], [`super::stack`].

use anyhow::{anyhow, Result};
use parapet_core::controller::{FlightMode, OffboardSetpoint};
use parapet_core::rc::{RcInput, SwitchPosition};
use parapet_core::supervisor::modes::RcLossAction;

use super::stack::{PilotMode, PilotSink, TimedSetpoint};
use crate::fc::control::Controller;
use crate::flight::runner::{controller_params, RunConfig};
use crate::flight::stack::{FlightStack, OuterOut};
use crate::world::scene::{to_f32, Scene};

/// Overrides of the controller's mode parameters for a piloted run (`None` = the parameter
/// table's default).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AssistParams {
    /// Position-assist horizontal speed at full stick, m/s (`PA_SPEED_MAX`).
    pub max_speed: Option<f32>,
    /// Position-assist climb rate at full throttle deflection, m/s (`PA_CLIMB_MAX`).
    pub max_climb: Option<f32>,
    /// RC loss in Mission / Offboard: continue or return (`FS_RC_ACT`).
    pub rc_loss_auto: Option<RcLossAction>,
}

/// The in-process controller with pilot input (see the module documentation).
pub struct PilotedController {
    /// The controller.
    pub ctrl: Controller,
    /// Enter Position-assist with the mode switch (Mid, then the script's Low) instead of
    /// `set_mode`, exactly as [`super::pil`] must (for the PIL comparison).
    pub via_switch: bool,
    last_rc: Option<RcInput>,
}

impl PilotedController {
    /// The run's controller ([`controller_params`]) with `assist` applied.
    pub fn new(scene: &Scene, cfg: &RunConfig, assist: AssistParams) -> Result<Self> {
        let mut p = controller_params(scene, cfg, cfg.cbf_params()?, cfg.variant);
        if let Some(v) = assist.max_speed {
            p.modes.assist_speed = v;
        }
        if let Some(v) = assist.max_climb {
            p.modes.assist_climb = v;
        }
        if let Some(v) = assist.rc_loss_auto {
            p.modes.rc_loss_auto = v;
        }
        Ok(PilotedController {
            ctrl: Controller::with_params(scene, cfg, p)?,
            via_switch: false,
            last_rc: None,
        })
    }
}

/// The core's offboard setpoint of a timed host setpoint (NED, f32; no yaw).
pub fn core_setpoint(sp: &TimedSetpoint) -> OffboardSetpoint {
    let s = &sp.setpoint;
    OffboardSetpoint {
        t_us: sp.t_us,
        position: s.position.as_ref().map(to_f32),
        velocity: s.velocity.as_ref().map(to_f32),
        acceleration: s.acceleration.as_ref().map(to_f32),
        yaw: None,
        yaw_rate: None,
    }
}

impl PilotSink for PilotedController {
    fn enter(&mut self, now_us: u64, mode: PilotMode) -> Result<()> {
        if let (true, PilotMode::Position, Some(rc)) = (self.via_switch, mode, self.last_rc) {
            // As the PIL link does: the mode switch to Mid (Hold) now, the script's Low
            // (Position) with its next frame.
            self.rc(&RcInput { mode: SwitchPosition::Mid, ..rc });
            return Ok(());
        }
        let m = match mode {
            PilotMode::Position => FlightMode::Position,
            PilotMode::Offboard => FlightMode::Offboard,
            // The start-up's mission start selected it.
            PilotMode::Mission => return Ok(()),
        };
        self.ctrl.fc_mut().set_mode(now_us, m).map_err(|e| {
            anyhow!(
                "the flight controller refused {}: {}",
                m.as_str(),
                crate::flight::validate::describe_command_error(e)
            )
        })
    }

    fn rc(&mut self, rc: &RcInput) {
        self.last_rc = Some(*rc);
        self.ctrl.fc_mut().set_rc(rc);
    }

    fn offboard(&mut self, sp: &TimedSetpoint) {
        self.ctrl.fc_mut().set_offboard(&core_setpoint(sp));
    }

    fn flight_mode(&self) -> String {
        self.ctrl.fc().mode().as_str().to_string()
    }

    fn filter_active(&self) -> Option<bool> {
        Some(self.ctrl.telemetry().filter_active)
    }

    fn mode_reason(&self) -> Option<&'static str> {
        self.ctrl.telemetry().last_mode_change.map(|m| m.reason.as_str())
    }
}

impl FlightStack for PilotedController {
    fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> Result<()> {
        self.ctrl.start(s)
    }

    fn position_fix(&mut self, fix: crate::sim::sensors::PositionReading) {
        self.ctrl.position_fix(fix);
    }

    fn outer(&mut self, t: f64, obstacles: &[parapet_core::obstacle::ObstaclePoint]) -> OuterOut {
        self.ctrl.outer(t, obstacles)
    }

    fn inner(&mut self, t: f64, imu: &crate::sim::sensors::ImuReading) -> [f32; 4] {
        self.ctrl.inner(t, imu)
    }

    fn state_name(&self) -> String {
        self.ctrl.state_name()
    }

    fn battery(&mut self, t: f64, reading: &crate::sim::battery::BatteryReading) {
        self.ctrl.battery(t, reading);
    }
}
