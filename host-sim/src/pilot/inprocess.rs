//! [`PilotSink`] for the in-process controller ([`crate::fc::control::Controller`]).
//!
//! STAND-IN (until the core's mode machine, issue 21 MODES21, lands): Position-assist and
//! Offboard are emulated on the host through the existing `hold_position` command, which the
//! PD tracker and the safety filter then act on exactly as in flight:
//! * a velocity setpoint `v` (sticks × `max_speed`, or offboard) becomes the hold target
//!   `p_ref + v·k_d/k_p`, so the PD output is `k_p (p_ref − p) + k_d (v − ṗ)`, where `p_ref`
//!   integrates `v` and stays within `leash` of the vehicle;
//! * an offboard position is held; an acceleration `a` becomes the target `p + (a + k_d ṗ)/k_p`;
//! * kill switch → `disarm` (motors off at once); RC loss (no frame for `rc_timeout`) or
//!   setpoint loss (`sp_timeout`) → hold `p_ref`; RC loss longer than `rc_land_after` → land.
//!
//! May import: `parapet-core`, [`crate::fc::control`], [`super::stack`].

use anyhow::Result;
use parapet_core::controller::GuidanceMode;
use parapet_core::rc::RcInput;
use parapet_core::Vec3;

use super::stack::{PilotMode, PilotSink, TimedSetpoint};
use crate::fc::control::Controller;
use crate::flight::stack::{FlightStack, OuterOut};

/// Settings of the Position-assist emulation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AssistParams {
    /// Horizontal speed at full stick, m/s.
    pub max_speed: f32,
    /// Climb rate at full throttle deflection, m/s.
    pub max_climb: f32,
    /// Largest distance of the integrated reference from the vehicle, m.
    pub leash: f32,
    /// RC loss after this long without a frame, µs.
    pub rc_timeout_us: u64,
    /// Land after an RC loss this long, µs.
    pub rc_land_after_us: u64,
    /// Offboard setpoint loss after this long without one, µs.
    pub sp_timeout_us: u64,
}

impl Default for AssistParams {
    fn default() -> Self {
        AssistParams {
            max_speed: 2.0,
            max_climb: 1.0,
            leash: 1.0,
            rc_timeout_us: 500_000,
            rc_land_after_us: 3_000_000,
            sp_timeout_us: 500_000,
        }
    }
}

/// The in-process controller with pilot input (see the module documentation).
pub struct PilotedController {
    /// The controller.
    pub ctrl: Controller,
    params: AssistParams,
    mode: PilotMode,
    flight_mode: &'static str,
    rc: Option<RcInput>,
    sp: Option<TimedSetpoint>,
    p_ref: Option<Vec3>,
    last_outer_us: Option<u64>,
    killed: bool,
    landing: bool,
}

impl PilotedController {
    /// Wrap `ctrl`.
    pub fn new(ctrl: Controller, params: AssistParams) -> Self {
        PilotedController {
            ctrl,
            params,
            mode: PilotMode::Position,
            flight_mode: "Mission",
            rc: None,
            sp: None,
            p_ref: None,
            last_outer_us: None,
            killed: false,
            landing: false,
        }
    }

    fn target(&mut self, now: u64) -> Option<Vec3> {
        let tel = self.ctrl.telemetry();
        let (p, v) = (tel.position, tel.velocity);
        let tr = self.ctrl.fc().params().tracking;
        let (kp, kd) = (tr.kp[0].max(1e-3), tr.kd[0]);
        let dt = self.last_outer_us.map_or(0.0, |t| now.saturating_sub(t) as f32 * 1e-6);
        let p_ref = *self.p_ref.get_or_insert(p);
        let fresh = |t_us: u64, limit: u64| now.saturating_sub(t_us) <= limit;
        let vel = match self.mode {
            PilotMode::Position => match self.rc {
                Some(rc) if fresh(rc.t_us, self.params.rc_timeout_us) => {
                    self.flight_mode = "Position";
                    let (s, c) = libm_sin_cos(tel.reference.yaw);
                    let (f, r) = (rc.pitch * self.params.max_speed, rc.roll * self.params.max_speed);
                    let up = (rc.throttle - 0.5) * 2.0 * self.params.max_climb;
                    Some(Vec3::new(c * f - s * r, s * f + c * r, -up))
                }
                last => {
                    self.flight_mode = "Hold";
                    let since = last.map_or(0, |rc| now.saturating_sub(rc.t_us));
                    if since > self.params.rc_land_after_us && !self.landing {
                        self.landing = self.ctrl.fc_mut().land(now).is_ok();
                    }
                    None
                }
            },
            PilotMode::Offboard => match self.sp {
                Some(sp) if fresh(sp.t_us, self.params.sp_timeout_us) => {
                    self.flight_mode = "Offboard";
                    let s = sp.setpoint;
                    let f = |x: nalgebra::Vector3<f64>| Vec3::new(x.x as f32, x.y as f32, x.z as f32);
                    if let Some(q) = s.position {
                        self.p_ref = Some(f(q));
                        return Some(f(q) + s.velocity.map_or(Vec3::zeros(), |w| f(w) * (kd / kp)));
                    }
                    if let Some(a) = s.acceleration.filter(|_| s.velocity.is_none()) {
                        self.p_ref = Some(p);
                        return Some(p + (f(a) + v * kd) / kp);
                    }
                    s.velocity.map(f)
                }
                _ => {
                    self.flight_mode = "Hold";
                    None
                }
            },
        };
        let leash = self.params.leash;
        let next = match vel {
            Some(w) => {
                let mut q = p_ref + w * dt;
                let d = q - p;
                let n = d.norm();
                if n > leash {
                    q = p + d * (leash / n);
                }
                self.p_ref = Some(q);
                q + w * (kd / kp)
            }
            None => p_ref,
        };
        Some(next)
    }
}

fn libm_sin_cos(x: f32) -> (f32, f32) {
    (x.sin(), x.cos())
}

impl PilotSink for PilotedController {
    fn enter(&mut self, _now_us: u64, mode: PilotMode) -> Result<()> {
        self.mode = mode;
        self.flight_mode = match mode {
            PilotMode::Position => "Position",
            PilotMode::Offboard => "Offboard",
        };
        Ok(())
    }

    fn rc(&mut self, rc: &RcInput) {
        if rc.kill && !self.killed {
            self.killed = self.ctrl.fc_mut().disarm(rc.t_us).is_ok();
            self.flight_mode = "Killed";
        }
        self.rc = Some(*rc);
    }

    fn offboard(&mut self, sp: &TimedSetpoint) {
        self.sp = Some(*sp);
    }

    fn flight_mode(&self) -> String {
        self.flight_mode.to_string()
    }

    fn filter_active(&self) -> bool {
        self.ctrl.telemetry().filter.intervened
    }
}

impl FlightStack for PilotedController {
    fn start(
        &mut self,
        t: f64,
        start: nalgebra::Vector3<f64>,
        fix: crate::sim::sensors::PositionReading,
        obstacles: &[parapet_core::obstacle::ObstaclePoint],
        imu: &crate::sim::sensors::ImuReading,
    ) -> Result<()> {
        self.ctrl.start(t, start, fix, obstacles, imu)
    }

    fn position_fix(&mut self, fix: crate::sim::sensors::PositionReading) {
        self.ctrl.position_fix(fix);
    }

    fn outer(&mut self, t: f64, obstacles: &[parapet_core::obstacle::ObstaclePoint]) -> OuterOut {
        let now = crate::flight::stack::clock_us(t);
        let flying = !self.killed && !self.landing && self.ctrl.telemetry().mode != GuidanceMode::Off;
        if flying {
            if let Some(target) = self.target(now) {
                let _ = self.ctrl.fc_mut().hold_position(now, target);
            }
        }
        self.last_outer_us = Some(now);
        let out = self.ctrl.outer(t, obstacles);
        if self.landing && !self.killed {
            self.flight_mode = "Land";
        }
        out
    }

    fn inner(&mut self, t: f64, imu: &crate::sim::sensors::ImuReading) -> [f32; 4] {
        self.ctrl.inner(t, imu)
    }

    fn state_name(&self) -> String {
        self.ctrl.state_name()
    }
}
