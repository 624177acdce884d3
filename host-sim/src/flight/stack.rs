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
use parapet_core::cbf::FilterDiagnostics;
use parapet_core::controller::{FlightMode, GuidanceMode, Telemetry};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::perception::Range;

use crate::report::SafetyFlags;
use crate::sim::range::RangeSensor;
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
    /// The safety filter's diagnostics of the step (the core's one type; `h_bar` is the
    /// filter's own min h̄ over the obstacles it was given, from the controller's estimate).
    pub filter: FilterDiagnostics,
    /// The path follower has reached the end of the path.
    pub path_done: bool,
    /// Nominal acceleration u* (PD output), NED, m/s².
    pub u_nominal: Vector3<f64>,
    /// Filtered acceleration u (filter output), NED, m/s².
    pub u_filtered: Vector3<f64>,
    /// Guidance mode of the controller (e.g. Mission, Brake).
    pub mode: GuidanceMode,
    /// Flight mode selected (pilot, ground station, failsafe): with `mode`, the log's PX4
    /// `nav_state` (`parapet_core::wire::modes::px4_nav_state`).
    pub flight_mode: FlightMode,
    /// Deadlock and obstacle-set flags (issue 17).
    pub safety: SafetyFlags,
}

impl OuterOut {
    /// The recorder's view of the controller's telemetry after an outer step.
    pub fn from_telemetry(tel: &Telemetry) -> Self {
        OuterOut {
            reference: to_f64(&tel.reference.position),
            filter: tel.filter,
            path_done: tel.progress.done,
            u_nominal: to_f64(&tel.u_nominal),
            u_filtered: to_f64(&tel.u_filtered),
            mode: tel.mode,
            flight_mode: tel.flight_mode,
            safety: SafetyFlags {
                deadlock: tel.plant_aware.deadlock,
                obstacles_dropped: tel.obstacle_set.dropped,
                obstacles_dropped_near: tel.obstacle_set.dropped_near,
                governor_limit: tel.governor.limit.is_finite().then_some(tel.governor.limit),
                governor_cause: tel.governor.cause,
                governor_active: tel.governor.active,
            },
        }
    }
}

/// What a flight stack is started with ([`FlightStack::start`]): written once, so a stack, a
/// wrapper around one and the runner pass it whole.
#[derive(Debug, Clone, Copy)]
pub struct StackStart<'a> {
    /// Simulated time of the start, s.
    pub t: f64,
    /// Where the vehicle hovers (NED, m): the position held until the mission starts.
    pub start: Vector3<f64>,
    /// The position fixes of the warm-up before `fix`, oldest first (a filtered source's:
    /// `crate::flight::runner::NAV_WARMUP_S`; none with motion capture).
    pub warmup: &'a [PositionReading],
    /// The first position fix (the last of the warm-up).
    pub fix: PositionReading,
    /// The obstacles sensed at the start.
    pub obstacles: &'a [ObstaclePoint],
    /// The first IMU reading.
    pub imu: &'a ImuReading,
}

/// What the runner needs from a flight controller, in simulated time `t` (s).
/// Implemented by `crate::fc::control::Controller` (in-process `FlightController`),
/// `crate::fc::pil::PilLink` (the firmware in QEMU) and `crate::fc::pil::FirmwareTwin`. Call order per 1 ms step:
/// every 4th step `position_fix` (when a fix is due) then `outer`; every step `inner`.
pub trait FlightStack {
    /// Start-up at `s.t` with the vehicle hovering at `s.start` (NED): initialise,
    /// arm, hold `s.start`, start the mission.
    fn start(&mut self, s: &StackStart<'_>) -> Result<()>;
    /// A position/velocity/yaw fix measured at `fix.t_measured`.
    fn position_fix(&mut self, fix: PositionReading);
    /// A barometer reading at `t` (NED down, m; filtered position sources, issue 39).
    /// Default: ignored (a stack without a navigation filter).
    fn height_fix(&mut self, _t: f64, _down: f64) {}
    /// A magnetometer field (body FRD, gauss; `parapet_core::nav::mag::body_field` of the true
    /// roll and pitch and the fix's measured yaw) with each fix of a source that has a compass
    /// (`gps`, `rtk`). Default: ignored (the in-process controller takes the fix's yaw).
    fn mag_fix(&mut self, _t: f64, _field: parapet_core::Vec3) {}
    /// The navigation filter's position estimate at `t` (NED, m) and the bound on its error,
    /// for the obstacle report's frame ([`crate::flight::sensing::to_estimate_frame`]).
    /// Default: `None` (the controller flies the fix: motion capture).
    fn navigation(&self, _t: f64) -> Option<(Vector3<f64>, crate::flight::sensing::ErrorBound)> {
        None
    }
    /// Outer step at `t` with the sensed obstacles; returns what the recorder needs.
    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut;
    /// Inner step at `t`: IMU in, motor throttles (0..1, rotors 1..4) out.
    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4];
    /// Name of the controller's failsafe state (e.g. "Armed").
    fn state_name(&self) -> String;
    /// What the stack's on-board replanner did (issue 38). Default: none (a stack without one).
    fn replan_summary(&self) -> crate::report::ReplanSummary {
        crate::report::ReplanSummary::default()
    }
    /// New paths the on-board replanner set so far (`replan_summary().replans`, without
    /// building the summary: the runner's duration watchdog asks every 0.1 s).
    fn replans(&self) -> u32 {
        self.replan_summary().replans
    }
    /// The mission the stack flies now: its path (NED, m; after an on-board replan the new
    /// path, issue 38) and the index of the waypoint being flown to (MISSION_CURRENT `seq`).
    /// Default: `None` (not known here: the PIL firmware serves its own mission).
    fn mission(&self) -> Option<(Vec<Vector3<f64>>, u16)> {
        None
    }
    /// A battery reading of the simulated pack (`[battery]`; issue 22). Default: ignored
    /// (a stack without a battery path).
    fn battery(&mut self, _t: f64, _reading: &crate::sim::battery::BatteryReading) {}
    /// Switch to taking the scans of the run's range sensors `sensors`
    /// ([`FlightStack::proximity_scan`]) instead of the host's obstacle points, if this stack
    /// can take every one of them; `true` when it did (the PIL firmware, fed by
    /// `OBSTACLE_DISTANCE`, builds its own set in its obstacle memory: planar 360° lidars
    /// only). Called once before [`FlightStack::start`]. Default: `false` (the stack keeps
    /// taking points).
    fn take_proximity_scans(&mut self, _sensors: &[RangeSensor]) -> bool {
        false
    }
    /// A scan of sensor `spec` (one value per beam) taken at `t_scan` and delivered at `t`
    /// (after [`FlightStack::take_proximity_scans`] returned `true`). Default: ignored.
    fn proximity_scan(&mut self, _t: f64, _t_scan: f64, _spec: &RangeSensor, _ranges: &[Range]) {}
    /// A ground station flies the vehicle (`parapet pil --gcs-control`): it starts resting on
    /// the ground below the start, disarmed, motors stopped ([`FlightStack::start`] then arms
    /// nothing); ground contact is no collision and the run does not stop at the goal but when
    /// [`FlightStack::finished`]. Default `false`.
    fn ground_start(&self) -> bool {
        false
    }
    /// The ground station's flight is over (landed and disarmed after having been armed).
    /// Default `false`.
    fn finished(&self) -> bool {
        false
    }
}
