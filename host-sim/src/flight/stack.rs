//! What the closed loop needs from a flight stack ([`FlightStack`]), what one
//! outer step reports to the recorder ([`OuterOut`]), and the controller clock.
//!
//! * **Clock**: controller time (µs) = (simulated time + [`CLOCK_OFFSET_S`]) · 10⁶,
//!   so that position fixes measured before t = 0 (latency priming) keep
//!   non-negative timestamps.
//!
//! Owns the interface between [`super::runner`] and the flight stacks of
//! [`crate::fc`] (which implement it). May import: `parapet-core`,
//! [`crate::sim::sensors`] (readings).

use anyhow::Result;
use nalgebra::Vector3;
use parapet_core::cbf::Region;
use parapet_core::controller::Telemetry;
use parapet_core::obstacle::ObstaclePoint;

use crate::sim::sensors::{ImuReading, PositionReading};
use crate::world::scene::to_f64;

/// Offset of the controller clock from simulated time, s.
pub const CLOCK_OFFSET_S: f64 = 1.0;

/// Controller clock (µs) at simulated time `t` (s).
pub fn clock_us(t: f64) -> u64 {
    ((t + CLOCK_OFFSET_S).max(0.0) * 1e6).round() as u64
}

/// What one outer step produced, for the recorder.
#[derive(Clone, Debug, PartialEq)]
pub struct OuterOut {
    /// Reference position, NED, m.
    pub reference: Vector3<f64>,
    /// Filter region name.
    pub region: &'static str,
    /// Filter region code ([`Region::code`]).
    pub region_code: u8,
    /// Obstacle the filter acted on.
    pub active_obstacle: Option<u16>,
    /// The filter changed u*.
    pub filter_active: bool,
    /// The path follower has reached the end of the path.
    pub path_done: bool,
    /// Nominal acceleration u* (PD output), NED, m/s².
    pub u_nominal: Vector3<f64>,
    /// Filtered acceleration u (filter output), NED, m/s².
    pub u_filtered: Vector3<f64>,
    /// The filter's own min h̄ over the obstacles it was given (controller's estimate), m².
    pub filter_h_bar: f64,
    /// Barriers enforced this step.
    pub n_constraints: u8,
    /// The filter flagged a constraint it cannot meet with the available acceleration.
    pub unavoidable: bool,
    /// The enforced constraints had no common solution.
    pub infeasible: bool,
    /// Guidance mode of the controller (e.g. "Mission", "Brake").
    pub mode: &'static str,
}

impl OuterOut {
    /// The recorder's view of the controller's telemetry after an outer step.
    pub fn from_telemetry(tel: &Telemetry) -> Self {
        OuterOut {
            reference: to_f64(&tel.reference.position),
            region: region_name(tel.filter.region),
            region_code: tel.filter.region.code(),
            active_obstacle: tel.filter.active_id,
            filter_active: tel.filter.intervened,
            path_done: tel.progress.done,
            u_nominal: to_f64(&tel.u_nominal),
            u_filtered: to_f64(&tel.u_filtered),
            filter_h_bar: tel.filter.h_bar as f64,
            n_constraints: tel.filter.n_constraints,
            unavoidable: tel.filter.unavoidable,
            infeasible: tel.filter.infeasible,
            mode: tel.mode.as_str(),
        }
    }
}

/// Region name for reports.
pub fn region_name(r: Region) -> &'static str {
    match r {
        Region::NoObstacle => "none",
        Region::Far => "far",
        Region::NominalSafe => "nominal_safe",
        Region::Perpendicular => "filtering",
        Region::Fault => "fault",
    }
}

/// What the runner needs from a flight controller, in simulated time `t` (s).
/// Implemented by `crate::fc::control::Controller` (in-process `FlightController`),
/// `crate::fc::pil::PilLink` (the firmware in QEMU) and `crate::fc::pil::FirmwareTwin`. Call order per 1 ms step:
/// every 4th step `position_fix` (when a fix is due) then `outer`; every step `inner`.
pub trait FlightStack {
    /// Start-up at `t` with the vehicle hovering at `start` (NED): initialise,
    /// arm, hold `start`, start the mission.
    fn start(
        &mut self,
        t: f64,
        start: Vector3<f64>,
        fix: PositionReading,
        obstacles: &[ObstaclePoint],
        imu: &ImuReading,
    ) -> Result<()>;
    /// A position/velocity/yaw fix measured at `fix.t_measured`.
    fn position_fix(&mut self, fix: PositionReading);
    /// Outer step at `t` with the sensed obstacles; returns what the recorder needs.
    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut;
    /// Inner step at `t`: IMU in, motor throttles (0..1, rotors 1..4) out.
    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4];
    /// Name of the controller's failsafe state (e.g. "Armed").
    fn state_name(&self) -> String;
}
