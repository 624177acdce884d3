//! The real flight-control cascade behind [`Autopilot`]: `parapet_core::controller::FlightController`
//! plus the last gyro sample (for the body rates in telemetry).

use parapet_core::controller::{CommandError, ControllerParams, FlightController, GuidanceMode, ParamError};
use parapet_core::estimator;
use parapet_core::failsafe::{FailsafeState, TransitionReason};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::waypoint::PathError;
use parapet_core::wire::codes;
use parapet_core::Vec3;

use crate::app::autopilot::{
    Autopilot, CommandRejected, Failsafe, FilterReport, FlightPhase, ImuSample, MotorCommand, ParamRejected,
    PathRejected, PositionFix, SetpointReport, TelemetrySnapshot, VehicleCommand,
};
use parapet_core::params;

/// Takeoff height used when NAV_TAKEOFF gives none, m (capped by the cascade's limit).
pub const DEFAULT_TAKEOFF_HEIGHT_M: f32 = 1.0;

/// [`FlightController`] as an [`Autopilot`].
#[derive(Clone, Debug)]
pub struct Cascade {
    fc: FlightController,
    last_gyro: Vec3,
}

impl Cascade {
    /// Cascade with `params` (validated by the controller).
    pub fn new(params: ControllerParams) -> Result<Self, ParamError> {
        Ok(Self { fc: FlightController::new(params)?, last_gyro: Vec3::zeros() })
    }

    /// The wrapped controller.
    pub fn controller(&self) -> &FlightController {
        &self.fc
    }
}

fn rejected(e: CommandError) -> CommandRejected {
    match e {
        CommandError::BadHeight | CommandError::BadTarget | CommandError::Path(_) => CommandRejected::Invalid,
        CommandError::Arm(_)
        | CommandError::NotArmed
        | CommandError::AlreadyDisarmed
        | CommandError::NotFlying
        | CommandError::NoPosition => CommandRejected::NotNow,
    }
}

impl Autopilot for Cascade {
    fn step_inner(&mut self, now_us: u64, imu: &ImuSample) -> MotorCommand {
        self.last_gyro = imu.gyro_frd;
        let out =
            self.fc.step_inner(now_us, &estimator::ImuSample { gyro: imu.gyro_frd, accel: imu.accel_frd });
        MotorCommand { throttle: out.throttle, armed: out.armed }
    }

    fn step_outer(&mut self, now_us: u64) {
        self.fc.step_outer(now_us);
    }

    fn update_position(&mut self, fix: &PositionFix) {
        self.fc.update_position(parapet_core::controller::PositionFix {
            t_us: fix.t_us,
            position: fix.position_ned,
            velocity: fix.velocity_ned,
            yaw: fix.yaw,
        });
    }

    fn update_obstacles(&mut self, now_us: u64, obstacles: &[ObstaclePoint]) {
        self.fc.update_obstacles(now_us, obstacles);
    }

    fn set_path(&mut self, waypoints_ned: &[Vec3]) -> Result<(), PathRejected> {
        self.fc.set_path(waypoints_ned).map_err(|e| match e {
            CommandError::Path(PathError::TooMany { .. }) => PathRejected::TooLong,
            _ => PathRejected::Invalid,
        })
    }

    fn command(&mut self, now_us: u64, cmd: VehicleCommand) -> Result<(), CommandRejected> {
        let r = match cmd {
            VehicleCommand::Arm => self.fc.arm(now_us),
            VehicleCommand::Disarm { force } => {
                let t = self.fc.telemetry();
                let airborne = !matches!(t.mode, GuidanceMode::Off | GuidanceMode::Ground);
                if airborne && !force {
                    return Err(CommandRejected::NotNow);
                }
                self.fc.disarm(now_us)
            }
            VehicleCommand::Takeoff { height_m } => {
                let h = height_m.unwrap_or(DEFAULT_TAKEOFF_HEIGHT_M.min(self.fc.params().takeoff_height_max));
                self.fc.takeoff(now_us, h)
            }
            VehicleCommand::Land => self.fc.land(now_us),
            VehicleCommand::StartMission => self.fc.start_mission(now_us),
            VehicleCommand::Hold { target_ned } => {
                let target = target_ned.unwrap_or(self.fc.telemetry().position);
                self.fc.hold_position(now_us, target)
            }
        };
        r.map_err(rejected)
    }

    fn set_param(&mut self, name: &str, value: f32) -> Result<f32, ParamRejected> {
        let mut p = *self.fc.params();
        params::set(&mut p, name, value)?;
        if self.fc.state() != FailsafeState::Disarmed {
            return Err(ParamRejected::NotNow);
        }
        self.fc = FlightController::new(p).map_err(|_| ParamRejected::Invalid)?;
        params::get(self.fc.params(), name).ok_or(ParamRejected::Unknown)
    }

    fn get_param(&self, name: &str) -> Option<f32> {
        params::get(self.fc.params(), name)
    }

    fn telemetry(&self) -> TelemetrySnapshot {
        let t = self.fc.telemetry();
        let commanded_land = t.last_transition.is_some_and(|tr| tr.reason == TransitionReason::LandCommand);
        let failsafe = match t.state {
            FailsafeState::Brake => Some(codes::failsafe::BRAKE),
            FailsafeState::Land if !commanded_land => Some(codes::failsafe::LAND),
            FailsafeState::MotorsOff => Some(codes::failsafe::MOTORS_OFF),
            _ => None,
        }
        .map(|code| Failsafe { code, reason: t.last_transition.map_or("unknown", |tr| tr.reason.as_str()) });
        let phase = match (t.state, t.mode) {
            (FailsafeState::Disarmed | FailsafeState::MotorsOff, _) => FlightPhase::Disarmed,
            (FailsafeState::Brake, _) => FlightPhase::Failsafe,
            (FailsafeState::Land, _) => FlightPhase::Landing,
            (FailsafeState::Armed, GuidanceMode::Takeoff) => FlightPhase::Takeoff,
            (FailsafeState::Armed, GuidanceMode::Mission) => FlightPhase::Mission,
            (FailsafeState::Armed, GuidanceMode::Hold) => FlightPhase::Hover,
            (FailsafeState::Armed, GuidanceMode::Land) => FlightPhase::Landing,
            (FailsafeState::Armed, _) => FlightPhase::Idle,
        };
        let f = &t.filter;
        TelemetrySnapshot {
            armed: t.state.motors_enabled(),
            phase,
            failsafe,
            attitude_rpy: Vec3::new(t.attitude.roll, t.attitude.pitch, t.attitude.yaw),
            body_rates_frd: self.last_gyro - t.gyro_bias,
            position_ned: t.position,
            velocity_ned: t.velocity,
            filter: FilterReport {
                region: f.region,
                active_id: f.active_id,
                h_bar: f.h_bar,
                intervened: f.intervened,
                unavoidable: f.unavoidable,
                infeasible: f.infeasible,
                n_constraints: f.n_constraints,
            },
            setpoint: SetpointReport {
                position_ned: t.reference.position,
                velocity_ned: t.reference.velocity,
                accel_nominal_ned: t.u_nominal,
                accel_filtered_ned: t.u_filtered,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::framing::FrameWriter;
    use crate::link::obstacles::CLEAR_ID;
    use crate::link::outbound::Outbound;
    use crate::link::{FixClock, Link};
    use crate::pil::lockstep::LockstepScheduler;
    use mavlink::dialects::ardupilotmega::{
        MavCmd, MavFrame, MavResult, COMMAND_LONG_DATA, HIL_SENSOR_DATA, OBSTACLE_DISTANCE_3D_DATA,
        ODOMETRY_DATA,
    };

    /// The ODOMETRY yaw reaches the estimator (as in `parapet run`): the first external yaw
    /// sets the heading; without one the heading stays where the accelerometer start left it.
    #[test]
    fn position_fix_yaw_sets_the_estimated_heading() {
        let heading = |yaw: Option<f32>| {
            let Ok(mut ap) = Cascade::new(ControllerParams::default()) else { panic!("default params") };
            let imu = ImuSample { gyro_frd: Vec3::zeros(), accel_frd: Vec3::new(0.0, 0.0, -9.81) };
            for k in 0..50u64 {
                let t = 1_000_000 + k * 1000;
                if k % 4 == 0 {
                    let fix = PositionFix {
                        t_us: t,
                        position_ned: Vec3::zeros(),
                        velocity_ned: Vec3::zeros(),
                        yaw,
                    };
                    ap.update_position(&fix);
                }
                let _ = ap.step_inner(t, &imu);
            }
            ap.telemetry().attitude_rpy.z
        };
        assert!((heading(Some(1.0)) - 1.0).abs() < 1e-3, "{}", heading(Some(1.0)));
        assert!(heading(None).abs() < 1e-3, "{}", heading(None));
    }

    /// The lockstep path with the real cascade on a vehicle at rest: arm is accepted once the
    /// position and obstacle data are fresh, the motors then idle, and a takeoff command spins
    /// them up (the cascade is the one the firmware flies).
    #[test]
    fn arm_and_takeoff_through_the_link_with_the_real_cascade() {
        let mut ap = match Cascade::new(ControllerParams::default()) {
            Ok(c) => c,
            Err(e) => panic!("default params rejected: {e:?}"),
        };
        // Parameters apply while disarmed (the cascade is rebuilt with them).
        assert_eq!(ap.set_param("CBF_MU", 1.2), Ok(1.2));
        assert_eq!(ap.get_param("CBF_MU"), Some(1.2));
        assert_eq!(ap.set_param("CBF_DELTA1", 0.01), Err(ParamRejected::Invalid)); // δ1 < δ
        assert_eq!(ap.get_param("CBF_DELTA1"), Some(0.1));
        let mut link = Link::new(1, FixClock::Message);
        let mut sched = LockstepScheduler::default();
        let mut host = FrameWriter::new(255, 190);
        let mut acks = std::vec::Vec::new();
        let mut last_motors = MotorCommand::OFF;
        for k in 0..1500u64 {
            let t = 1_000_000 + k * 1000;
            if k % 4 == 0 {
                let odo = ODOMETRY_DATA {
                    time_usec: t,
                    q: [1.0, 0.0, 0.0, 0.0],
                    frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                    child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                    ..Default::default()
                };
                link.push_bytes(host.encode(&odo).raw_bytes(), t, &mut ap);
                let clear = OBSTACLE_DISTANCE_3D_DATA {
                    time_boot_ms: (t / 1000) as u32,
                    obstacle_id: CLEAR_ID,
                    frame: MavFrame::MAV_FRAME_LOCAL_NED,
                    ..Default::default()
                };
                link.push_bytes(host.encode(&clear).raw_bytes(), t, &mut ap);
            }
            let cmd = |c: MavCmd, p1: f32, p7: f32| COMMAND_LONG_DATA {
                param1: p1,
                param7: p7,
                command: c,
                target_system: 1,
                ..Default::default()
            };
            if k == 500 {
                link.push_bytes(
                    host.encode(&cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0)).raw_bytes(),
                    t,
                    &mut ap,
                );
            }
            if k == 1000 {
                link.push_bytes(
                    host.encode(&cmd(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 1.0)).raw_bytes(),
                    t,
                    &mut ap,
                );
            }
            let hil = HIL_SENSOR_DATA { time_usec: t, zacc: -9.81, ..Default::default() };
            link.push_bytes(host.encode(&hil).raw_bytes(), t, &mut ap);
            let Some(sample) = link.take_hil_sample() else { panic!("HIL_SENSOR not decoded at step {k}") };
            let out = sched.step(&sample, &mut link, &mut ap);
            while let Some(r) = link.pop_reply() {
                if let Outbound::CommandAck(a) = r {
                    acks.push(a.result);
                }
            }
            if k == 999 {
                assert!(out.motors.armed, "armed at idle before takeoff");
                assert!(out.motors.throttle.iter().all(|&x| x > 0.0 && x < 0.3), "{:?}", out.motors);
            }
            last_motors = out.motors;
        }
        assert_eq!(acks, vec![MavResult::MAV_RESULT_ACCEPTED, MavResult::MAV_RESULT_ACCEPTED]);
        // Parameters are refused while armed, and a hold command switches to hover.
        assert_eq!(ap.set_param("CBF_MU", 0.9), Err(ParamRejected::NotNow));
        assert_eq!(ap.command(2_500_000, VehicleCommand::Hold { target_ned: None }), Ok(()));
        ap.step_outer(2_500_000);
        assert_eq!(ap.telemetry().phase, FlightPhase::Hover);
        assert_eq!(
            ap.command(2_500_000, VehicleCommand::Disarm { force: false }),
            Err(CommandRejected::NotNow)
        );
        assert!(last_motors.armed);
        let s = ap.telemetry();
        assert!(s.failsafe.is_none(), "{s:?}");
    }
}
