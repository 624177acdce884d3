//! The boundary between the firmware's tasks and the flight-control cascade.
//!
//! Tasks talk to the cascade only through [`Autopilot`] (and [`ControlSteps`]), so the task logic (link dispatch, loop
//! scheduling, lockstep) is tested on the host against a test double, and the real cascade
//! (the core's outer and inner loops as two stages exchanging messages) plugs in through
//! [`crate::app::cascade`].
//!
//! Frames: world NED, body FRD, SI units (see `parapet_core::frame`).

use parapet_core::battery::{BatteryParams, BatteryState};
use parapet_core::obstacle::ObstaclePoint;
pub use parapet_core::outer::guidance::GuidanceMode;
pub use parapet_core::outer::offboard::OffboardSetpoint;
use parapet_core::rc::map::RcParams;
use parapet_core::rc::{RawChannels, RcInput};
pub use parapet_core::supervisor::modes::FlightMode;

pub use parapet_core::params::ParamRejected;
use parapet_core::Vec3;

/// The IMU sample and the external position fix: the core's messages (`parapet_core::msg`),
/// passed through the firmware as they are (defined once).
pub use parapet_core::msg::{ImuSample, PositionFix};
pub use parapet_core::nav::aid::SourceNoise;
pub use parapet_core::nav::FixKind;

/// Motor command for the four rotors and its sanitiser: the wire contract's
/// (`parapet_core::wire::lockstep`), so the host twin applies exactly the same rule.
pub use parapet_core::wire::lockstep::MotorCommand;

/// Commands from COMMAND_LONG (see [`crate::link::command`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VehicleCommand {
    /// Arm the motors (idle on the ground).
    Arm,
    /// Disarm; `force` disarms even in flight (MAVLink magic 21196).
    Disarm {
        /// Disarm in flight.
        force: bool,
    },
    /// Take off to `height_m` above the current position (m, positive up); `None`: cascade default.
    Takeoff {
        /// Climb height, m, > 0.
        height_m: Option<f32>,
    },
    /// Land at the current horizontal position.
    Land,
    /// Fly the uploaded waypoint path.
    StartMission,
    /// Hold a position: `target_ned` (world NED, m), or the current estimate when `None`.
    Hold {
        /// Point to hold.
        target_ned: Option<Vec3>,
    },
    /// Select a flight mode (MAV_CMD_DO_SET_MODE with the PX4 custom mode,
    /// [`FlightMode::from_px4`]).
    SetMode(FlightMode),
    /// Face a heading (rad, NED; a mission's CONDITION_YAW); armed only.
    SetYaw {
        /// Heading, rad (wrapped to (−π, π]).
        yaw_rad: f32,
    },
    /// The mission's path speed from the next path start (a mission's DO_CHANGE_SPEED): `Some`
    /// m/s, capped at the vehicle's limit (the larger of `WP_SPEED` and `PA_SPEED_MAX`);
    /// `None`: back to `WP_SPEED`.
    SetSpeed {
        /// Speed, m/s (> 0).
        m_s: Option<f32>,
    },
}

/// A command the cascade refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandRejected {
    /// Not possible in the current state (e.g. takeoff while disarmed): MAV_RESULT_TEMPORARILY_REJECTED.
    NotNow,
    /// Parameters out of range: MAV_RESULT_DENIED.
    Invalid,
}

/// A waypoint path the cascade refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathRejected {
    /// More waypoints than the cascade stores.
    TooLong,
    /// A waypoint is not finite or otherwise invalid.
    Invalid,
}

/// The safety filter's diagnostics of the last outer step: the core's one diagnostics type
/// (region, active obstacle, h̄, flags), carried unchanged to the link.
pub use parapet_core::cbf::FilterDiagnostics;
/// Safety-filter region (`DEBUG_VECT "CBF".y`, code [`FilterRegion::code`]): the core's type.
pub use parapet_core::cbf::Region as FilterRegion;

/// Filter diagnostics before the first outer step: no obstacle, h̄ = +∞.
pub const FILTER_IDLE: FilterDiagnostics = FilterDiagnostics::new(FilterRegion::NoObstacle);

/// The outer loop's setpoints of the last outer step (NED).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SetpointReport {
    /// Reference position p_d, m.
    pub position_ned: Vec3,
    /// Reference velocity ṗ_d, m/s.
    pub velocity_ned: Vec3,
    /// Nominal acceleration u* of the PD law (before the filter), m/s² (gravity excluded).
    pub accel_nominal_ned: Vec3,
    /// Acceleration after the safety filter u, m/s² (gravity excluded).
    pub accel_filtered_ned: Vec3,
}

impl SetpointReport {
    /// Before the first outer step: all zero.
    pub const ZERO: Self = Self {
        position_ned: Vec3::new(0.0, 0.0, 0.0),
        velocity_ned: Vec3::new(0.0, 0.0, 0.0),
        accel_nominal_ned: Vec3::new(0.0, 0.0, 0.0),
        accel_filtered_ned: Vec3::new(0.0, 0.0, 0.0),
    };
}

/// Flight phase, reported as HEARTBEAT `custom_mode` (the wire contract's codes).
pub use parapet_core::wire::codes::FlightPhase;

/// A failsafe state (reported in STATUSTEXT on every transition).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Failsafe {
    /// Stable numeric code (`NAMED_VALUE_INT "failsafe"`).
    pub code: u8,
    /// Short human-readable reason (≤ 50 bytes for STATUSTEXT).
    pub reason: &'static str,
}

/// The latest pilot input as RC_CHANNELS (65) reports it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RcReport {
    /// Channels, µs: a receiver's as it sent them; MAVLink pilot input as the channel map gives
    /// them back (`crate::link::manual_control::channels_of`).
    pub channels: RawChannels,
    /// Link quality of the latest frame, percent.
    pub link_quality: u8,
    /// Time of the latest frame, µs.
    pub t_us: u64,
}

/// What the link reports about the cascade.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TelemetrySnapshot {
    /// Motors enabled.
    pub armed: bool,
    /// Current phase.
    pub phase: FlightPhase,
    /// The guidance that produced the reference (with `mode`, the log's PX4 `nav_state`:
    /// `parapet_core::wire::modes::px4_nav_state`).
    pub guidance: GuidanceMode,
    /// Active failsafe, if any.
    pub failsafe: Option<Failsafe>,
    /// Estimated roll, pitch, yaw (ZYX Euler, FRD w.r.t. NED), rad.
    pub attitude_rpy: Vec3,
    /// Estimated body rates, FRD, rad/s.
    pub body_rates_frd: Vec3,
    /// Position estimate, NED, m.
    pub position_ned: Vec3,
    /// Velocity estimate, NED, m/s.
    pub velocity_ned: Vec3,
    /// Safety filter diagnostics.
    pub filter: FilterDiagnostics,
    /// Outer-loop setpoints.
    pub setpoint: SetpointReport,
    /// Selected flight mode (HEARTBEAT `custom_mode`: [`FlightMode::px4_custom_mode`]).
    pub mode: FlightMode,
    /// Flight-mode changes so far: a new value means a mode change (STATUSTEXT
    /// `mode <to>: <reason>`, [`TelemetrySnapshot::mode_reason`]).
    pub mode_changes: u32,
    /// Reason of the last mode change (`TransitionReason::as_str`), if any.
    pub mode_reason: Option<&'static str>,
    /// The safety filter changed the nominal command in the last outer step (never in Manual).
    pub filter_active: bool,
    /// Mission item being flown (MISSION_CURRENT `seq`): the path follower's segment, which ends
    /// at waypoint `mission_seq` (0 before a mission).
    pub mission_seq: u16,
    /// The path follower reached the mission's last waypoint (MISSION_ITEM_REACHED of it).
    pub mission_done: bool,
    /// The last battery measurement the cascade took (BATTERY_STATUS, SYS_STATUS), if any.
    pub battery: Option<BatteryState>,
    /// Attitude and collective thrust setpoint of the last outer step (ATTITUDE_TARGET).
    pub attitude_sp: parapet_core::msg::AttitudeSetpoint,
    /// The latest pilot input (RC_CHANNELS), `None` before the first RC frame.
    pub rc: Option<RcReport>,
    /// The last position fix is fresh (the failsafe's position timeout): SYS_STATUS's GPS
    /// health, GPS_RAW_INT's 3D fix.
    pub position_fresh: bool,
    /// The arm command would be accepted now (the cascade's arm checks and a consistent
    /// parameter set; kept `true` while armed): SYS_STATUS's `MAV_SYS_STATUS_PREARM_CHECK`.
    pub armable: bool,
    /// The on-board replanner's events (issue 38; STATUSTEXT and the log).
    pub replan: crate::app::replanner::ReplanReport,
    /// The navigation filter's status (ESTIMATOR_STATUS), once a filtered source (GPS_INPUT,
    /// VISION_POSITION_ESTIMATE) initialised it.
    pub nav: Option<crate::app::navigation::NavReport>,
    /// The speed governor's limit along the motion at the last outer step, m/s (`+∞`: none;
    /// `parapet_core::governor::GovernorTelemetry::limit`), for the onboard log's `cbf_status`.
    pub governor_limit: f32,
    /// What set [`governor_limit`](Self::governor_limit) (`parapet_core::governor::GovernorCause`
    /// as its code).
    pub governor_cause: u8,
    /// The governor changed the nominal command at the last outer step.
    pub governor_active: bool,
}

impl TelemetrySnapshot {
    /// Before the cascade is running: disarmed, everything zero.
    pub const BOOT: Self = Self {
        armed: false,
        phase: FlightPhase::Disarmed,
        guidance: GuidanceMode::Off,
        failsafe: None,
        attitude_rpy: Vec3::new(0.0, 0.0, 0.0),
        body_rates_frd: Vec3::new(0.0, 0.0, 0.0),
        position_ned: Vec3::new(0.0, 0.0, 0.0),
        velocity_ned: Vec3::new(0.0, 0.0, 0.0),
        filter: FILTER_IDLE,
        setpoint: SetpointReport::ZERO,
        mode: FlightMode::Mission,
        mode_changes: 0,
        mode_reason: None,
        filter_active: false,
        mission_seq: 0,
        mission_done: false,
        battery: None,
        rc: None,
        position_fresh: false,
        armable: false,
        replan: crate::app::replanner::ReplanReport { events: 0, last: None },
        nav: None,
        governor_limit: f32::INFINITY,
        governor_cause: 0,
        governor_active: false,
        attitude_sp: parapet_core::msg::AttitudeSetpoint {
            roll: 0.0,
            pitch: 0.0,
            yaw: 0.0,
            thrust: 0.0,
            saturated: false,
        },
    };
}

/// The flight-control cascade as the link sees it (the host simulator's trait of the same role
/// is `parapet_sim::flight::stack::FlightStack`). Every method is bounded in time and never
/// panics; bad inputs get the cascade's defined safe response.
pub trait Autopilot {
    /// New position/velocity estimate.
    fn update_position(&mut self, fix: &PositionFix);
    /// A fix of a filtered source (GPS_INPUT: `Absolute`, VISION_POSITION_ESTIMATE and a VIO's
    /// ODOMETRY: `Relative`) with the σ it states, for the navigation filter
    /// ([`crate::app::navigation`]). Required, so that no wrapper falls back to the fix path.
    fn navigation_fix(&mut self, fix: &PositionFix, kind: FixKind, noise: SourceNoise);
    /// A barometer height of `t_us` (NED down, m: HIL_SENSOR's `pressure_alt` around home)
    /// for the navigation filter. Required, like [`Autopilot::navigation_fix`].
    fn navigation_height(&mut self, t_us: u64, down: f32);
    /// Replaces the obstacle points (world NED) seen at `now_us`.
    fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]);
    /// Replaces the waypoint path (world NED, m).
    fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), PathRejected>;
    /// One step of streaming a path longer than the cascade holds (issue 38,
    /// `parapet_core::outer::path_stream`): the next of the `waiting` waypoints go onto the path
    /// when a refill is due; returns how many (0: none due, or refused). Default 0 (a stack
    /// without a path store); every wrapper of the cascade forwards it.
    fn stream_path(&mut self, _waiting: &[Vec3]) -> usize {
        0
    }
    /// Drops the waypoint path (MISSION_CLEAR_ALL, MISSION_COUNT 0): a mission being flown
    /// becomes a hold; a later mission start is refused until a new path is set.
    fn clear_path(&mut self);
    /// Executes a vehicle command.
    fn command(&mut self, now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected>;
    /// Current telemetry.
    fn telemetry(&self) -> TelemetrySnapshot;
    /// The bound on the navigation estimate's error of the last outer step: the margin of the
    /// mapped (world-frame) obstacle points the link receives (`crate::link::obstacles`,
    /// `docs/filter.md` § 18). `None` without an initialised filtered source (motion capture:
    /// the points as sent); default `None`, so every wrapper of the cascade forwards it.
    fn mapped_margin(&self) -> Option<parapet_core::nav::bound::ErrorBound> {
        None
    }
    /// The waypoint path the cascade flies now (world NED, m; after an on-board replan the
    /// new one, issue 38). Default: none (a stack without a path store).
    fn flown_path(&self) -> &[Vec3] {
        &[]
    }
    /// Sets parameter `name` (see [`parapet_core::params`]); returns the value now in effect.
    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected>;
    /// Current value of parameter `name`.
    fn get_param(&self, name: &str) -> Option<f32>;
    /// One pilot input (MANUAL_CONTROL / RC_CHANNELS_OVERRIDE through the link, or a receiver
    /// frame mapped with [`Autopilot::rc_params`]); see `FlightController::set_rc`.
    fn set_rc(&mut self, _rc: &RcInput) {}
    /// The live RC channel map (the link's RC_CHANNELS_OVERRIDE needs it).
    fn rc_params(&self) -> RcParams {
        RcParams::default()
    }
    /// One offboard setpoint (SET_POSITION_TARGET_LOCAL_NED, [`crate::link::offboard`]).
    fn set_offboard(&mut self, _sp: &OffboardSetpoint) {}
    /// One battery measurement (low → Return, critical → Land).
    fn set_battery(&mut self, _b: &BatteryState) {}
    /// The battery estimator's parameters as set (the `BAT_*` entries of the parameter table),
    /// for a measurement taken next to the link instead of in a board's ADC task (the PIL's
    /// host-fed pack, `crate::pil::battery`; the boards' task gets them through its mailbox).
    /// Default `None`: the stack takes no such measurement.
    fn battery_params(&self) -> Option<BatteryParams> {
        None
    }
    /// PREFLIGHT_STORAGE / PREFLIGHT_CALIBRATION / DO_MOTOR_TEST ([`crate::setup::Setup::command`]):
    /// the answer when `id` is one of them, `None` otherwise (then the router handles the
    /// command). Default: `None` (no setup services).
    fn setup_command(&mut self, _now_us: u64, _id: u16, _params: [f32; 7]) -> Option<crate::setup::SetupAck> {
        None
    }
    /// Next STATUSTEXT of the setup services ([`crate::setup::Setup::pop_text`]).
    fn setup_text(&mut self) -> Option<crate::setup::Text> {
        None
    }
}

/// Both loops in one context (the lockstep PIL step, host tests): [`Autopilot`] plus the
/// control steps.
pub trait ControlSteps: Autopilot {
    /// Inner loop: estimator + attitude + rate control + mixer. `now_us`: firmware clock, µs.
    fn step_inner(&mut self, now_us: u64, imu: &ImuSample) -> MotorCommand;
    /// Outer loop: waypoint reference → PD tracking → CBF filter → thrust/attitude setpoint.
    fn step_outer(&mut self, now_us: u64);
    /// The on-board replanner's task side, once, between control steps (the PIL application;
    /// a board runs it in a task of its own): serves a waiting request with `planner`
    /// (`crate::app::replanner::serve_pending`). `false`: none was waiting (or no replanner).
    fn serve_replan(&mut self, planner: &mut parapet_core::replan::Replanner) -> bool {
        let _ = planner;
        false
    }
    /// Hands the replanner's mailbox its request buffer (`ReplanMailbox::install`); without
    /// one (or a replanner) nothing.
    fn install_replan(&mut self, request: &'static mut parapet_core::replan::onboard::ReplanRequest) {
        let _ = request;
    }
}

#[cfg(test)]
pub(crate) mod test_double {
    //! A recording [`Autopilot`] for the task-logic tests.
    use super::*;
    use std::vec::Vec;

    /// Records every call; behaves like a trivial vehicle.
    #[derive(Default)]
    pub struct RecordingAutopilot {
        pub inner_steps: Vec<u64>,
        pub outer_steps: Vec<u64>,
        pub fixes: Vec<PositionFix>,
        /// The kind and σ of each fix that went to the navigation filter (the others went to
        /// `update_position`).
        pub nav_fixes: Vec<(FixKind, SourceNoise)>,
        /// Barometer heights (time µs, NED down m).
        pub heights: Vec<(u64, f32)>,
        pub obstacle_batches: Vec<Vec<ObstaclePoint>>,
        pub paths: Vec<Vec<Vec3>>,
        pub commands: Vec<VehicleCommand>,
        pub armed: bool,
        pub failsafe: Option<Failsafe>,
        pub max_path: usize,
        pub params: Vec<(std::string::String, f32)>,
        pub mode: FlightMode,
        pub mode_changes: u32,
        pub mode_reason: Option<&'static str>,
        /// The last battery measurement handed over.
        pub battery: Option<BatteryState>,
        /// What [`Autopilot::battery_params`] answers.
        pub battery_params: Option<BatteryParams>,
        /// What [`Autopilot::mapped_margin`] answers (a filtered source); `None`: motion capture.
        pub mapped_margin: Option<parapet_core::nav::bound::ErrorBound>,
    }

    impl RecordingAutopilot {
        pub fn new() -> Self {
            Self { max_path: 16, ..Default::default() }
        }
    }

    impl ControlSteps for RecordingAutopilot {
        fn step_inner(&mut self, now_us: u64, _imu: &ImuSample) -> MotorCommand {
            self.inner_steps.push(now_us);
            MotorCommand { throttle: [0.5; 4], armed: self.armed }
        }
        fn step_outer(&mut self, now_us: u64) {
            self.outer_steps.push(now_us);
        }
    }

    impl Autopilot for RecordingAutopilot {
        fn update_position(&mut self, fix: &PositionFix) {
            self.fixes.push(*fix);
        }
        fn navigation_fix(&mut self, fix: &PositionFix, kind: FixKind, noise: SourceNoise) {
            self.fixes.push(*fix);
            self.nav_fixes.push((kind, noise));
        }
        fn navigation_height(&mut self, t_us: u64, down: f32) {
            self.heights.push((t_us, down));
        }
        fn update_obstacles(&mut self, _now_us: u64, obstacles: &[ObstaclePoint]) {
            self.obstacle_batches.push(obstacles.to_vec());
        }
        fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), PathRejected> {
            if waypoints_ned.len() > self.max_path {
                return Err(PathRejected::TooLong);
            }
            self.paths.push(waypoints_ned.to_vec());
            Ok(())
        }
        fn clear_path(&mut self) {
            self.paths.push(std::vec::Vec::new());
        }
        fn command(&mut self, _now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected> {
            self.commands.push(cmd);
            match cmd {
                VehicleCommand::Arm => self.armed = true,
                VehicleCommand::Disarm { .. } => self.armed = false,
                VehicleCommand::Takeoff { .. } if !self.armed => return Err(CommandRejected::NotNow),
                VehicleCommand::StartMission if self.paths.is_empty() => return Err(CommandRejected::NotNow),
                _ => {}
            }
            Ok(())
        }
        fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
            if parapet_core::params::index_of(name).is_none() {
                return Err(ParamRejected::Unknown);
            }
            if self.armed {
                return Err(ParamRejected::NotNow);
            }
            self.params.retain(|(n, _)| n != name);
            self.params.push((name.into(), value));
            Ok(value)
        }
        fn get_param(&self, name: &str) -> Option<f32> {
            parapet_core::params::index_of(name)?;
            Some(self.params.iter().find(|(n, _)| n == name).map_or(0.0, |p| p.1))
        }
        fn telemetry(&self) -> TelemetrySnapshot {
            TelemetrySnapshot {
                armed: self.armed,
                phase: if self.armed { FlightPhase::Idle } else { FlightPhase::Disarmed },
                guidance: if self.armed { GuidanceMode::Ground } else { GuidanceMode::Off },
                failsafe: self.failsafe,
                attitude_rpy: Vec3::new(0.1, -0.2, 0.3),
                body_rates_frd: Vec3::zeros(),
                position_ned: Vec3::new(1.0, 2.0, -3.0),
                velocity_ned: Vec3::zeros(),
                filter: FILTER_IDLE,
                setpoint: SetpointReport {
                    position_ned: Vec3::new(1.5, 2.0, -3.0),
                    velocity_ned: Vec3::new(0.25, 0.0, 0.0),
                    accel_nominal_ned: Vec3::new(-1.0, 0.5, 0.0),
                    accel_filtered_ned: Vec3::new(-0.5, 0.5, 0.0),
                },
                mode: self.mode,
                mode_changes: self.mode_changes,
                mode_reason: self.mode_reason,
                battery: self.battery,
                position_fresh: true,
                armable: !self.armed,
                ..TelemetrySnapshot::BOOT
            }
        }
        fn mapped_margin(&self) -> Option<parapet_core::nav::bound::ErrorBound> {
            self.mapped_margin
        }
        fn set_battery(&mut self, b: &BatteryState) {
            self.battery = Some(*b);
        }
        fn battery_params(&self) -> Option<BatteryParams> {
            self.battery_params
        }
    }
}
