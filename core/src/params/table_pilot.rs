//! Part of [`super::TABLE`]: the pilot-facing parameters: flight modes, per-mode failsafes, return, RC channel map and pulse ranges (issue 21), the yaw along a path (issue 19).
//!
//! Entries in MAVLink `param_index` order; [`super`] concatenates the parts. May import
//! what [`super`] may.

use super::*;
use crate::outer::guidance::MissionGuidance;
use crate::outer::path_yaw::YawMode;

/// Entries of this part.
pub(super) const N: usize = 42;

/// The [`Access`] of the mode switch's position `i` (a [`FlightMode`] code; an unknown code
/// keeps the mode).
macro_rules! switch_position {
    ($i:literal) => {
        (
            |p: &ControllerParams| p.modes.switch_modes[$i] as i32 as f32,
            |p: &mut ControllerParams, v: f32| {
                p.modes.switch_modes[$i] = FlightMode::from_code(v as i32).unwrap_or(p.modes.switch_modes[$i])
            },
        )
    };
}

/// This part's entries, in `param_index` order.
#[rustfmt::skip] // one entry per parameter, laid out by hand
pub(super) const TABLE: [Param; N] = [
    Param::new("MAN_TILT_MAX", "Modes", "rad", (0.05, 1.0), 2, field!(modes.manual_tilt_max),
        "Manual: tilt at full roll/pitch stick (capped by the thrust map's tilt limit)"),
    Param::new("PA_SPEED_MAX", "Modes", "m/s", (0.1, 10.0), 2, field!(modes.assist_speed),
        "Position assist: horizontal speed at full stick (heading frame)"),
    Param::new("PA_CLIMB_MAX", "Modes", "m/s", (0.1, 5.0), 2, field!(modes.assist_climb),
        "Position assist: climb/descent rate at full throttle deflection from mid"),
    Param::new("PA_YAWRATE_MAX", "Modes", "rad/s", (0.1, 6.0), 2, field!(modes.yaw_rate_max),
        "Yaw rate at full yaw stick (Manual, Position)"),
    Param::new("PA_DEADBAND", "Modes", "", (0.0, 0.5), 3, field!(modes.deadband),
        "Stick deadband around centre (throttle: around 0.5), fraction of full deflection"),
    Param::new("MODE_SW_LOW", "Modes", "", (0.0, 6.0), 0, switch_position!(0),
        "Flight mode of the RC mode switch's low position").code(mode_label),
    Param::new("MODE_SW_MID", "Modes", "", (0.0, 6.0), 0, switch_position!(1),
        "Flight mode of the RC mode switch's middle position").code(mode_label),
    Param::new("MODE_SW_HIGH", "Modes", "", (0.0, 6.0), 0, switch_position!(2),
        "Flight mode of the RC mode switch's high position").code(mode_label),
    Param::new("FS_RC_TIMEOUT", "Failsafe", "s", (0.05, 10.0), 2, field!(modes.rc_timeout_s),
        "No valid RC frame for this long is an RC loss (once RC was seen)"),
    Param::new("FS_RC_LAND_T", "Failsafe", "s", (0.0, 120.0), 1, field!(modes.rc_loss_land_s),
        "RC loss in Manual/Position: Hold, then Land after this long without RC"),
    Param::new("FS_RC_ACT", "Failsafe", "", (0.0, 1.0), 0, (|p| p.modes.rc_loss_auto as i32 as f32, |p, v| {
            p.modes.rc_loss_auto = if v >= 0.5 { RcLossAction::Return } else { RcLossAction::Continue }
        }),
        "RC loss in Mission/Offboard: 0 continue, 1 return").code(rc_act_label),
    Param::new("OFFB_TIMEOUT", "Failsafe", "s", (0.05, 10.0), 2, field!(modes.offboard_timeout_s),
        "Offboard: no valid setpoint for this long -> Hold"),
    Param::new("RTL_CRUMB_DIST", "Modes", "m", (0.1, 10.0), 2, field!(modes.crumb_spacing),
        "Return: breadcrumb spacing of the flown path (doubles when the 32-crumb buffer fills)"),
    Param::new("RTL_SPEED", "Modes", "m/s", (0.05, 5.0), 2, field!(modes.return_speed),
        "Return: speed back along the breadcrumbs"),
    Param::new("FS_BAT_ACT", "Failsafe", "", (0.0, 1.0), 0, (|p| if p.modes.battery_failsafe { 1.0 } else { 0.0 }, |p, v| p.modes.battery_failsafe = v >= 0.5),
        "Battery failsafes: 0 off, 1 low -> Return, critical -> Land").code(bat_act_label),
    // Issue 19: the yaw along a path (`outer::path_yaw`), so forward sensors look where the
    // vehicle flies (PX4 MPC_YAW_MODE / MPC_YAWRAUTO_MAX; the heading threshold, PX4's MIS_YAW_ERR, is
    // the constant `path_yaw::MAX_HEADING_ERROR`).
    Param::new("MIS_YAW_MODE", "Mission", "", (0.0, 1.0), 0, (|p| p.guidance.path_yaw.mode.code() as f32, |p, v| {
            p.guidance.path_yaw.mode = YawMode::from_code(v as i32).unwrap_or(p.guidance.path_yaw.mode)
        }),
        "Yaw along the path (Mission, Return): 0 hold the heading at arming, 1 face the direction of travel").key("yaw_mode").code(|c| YawMode::from_code(c).map(YawMode::as_str)),
    Param::new("MIS_YAW_RATE", "Mission", "rad/s", (0.05, 6.0), 3, field!(guidance.path_yaw.rate),
        "MIS_YAW_MODE 1: largest turn rate of the yaw reference towards the travel direction"),
    Param::new("MIS_TKO_ALT_MAX", "Mission", "m", (1.0, 500.0), 1, field!(guidance.takeoff_height_max),
        "Largest takeoff height above home: a higher TAKEOFF mission item is refused at upload \
         (MISSION_ACK INVALID_PARAM7), a higher NAV_TAKEOFF command or mission start is DENIED"),
    // Issue 35: the mission's guidance (`outer::guidance`): the paper's constant-speed point
    // (the paper reproduction) or the jerk-limited trajectory (default; `outer::trajectory`,
    // cruise speed WP_SPEED) with these limits (PX4 MPC_ACC_HOR, MPC_JERK_AUTO, MPC_Z_V_AUTO_*,
    // MPC_XY_ERR_MAX).
    Param::new("MIS_GUIDANCE", "Mission", "", (0.0, 1.0), 0, (|p| p.guidance.mission.code() as f32, |p, v| p.guidance.mission = MissionGuidance::from_code(v as i32).unwrap_or(p.guidance.mission)),
        "Mission guidance: 0 paper (constant-speed point, s = V t), 1 trajectory (jerk-limited, waits for the vehicle)").key("guidance").code(|c| MissionGuidance::from_code(c).map(MissionGuidance::as_str)),
    Param::new("TRJ_ACC", "Mission", "m/s^2", (0.1, 15.0), 2, field!(guidance.trajectory.accel_horizontal),
        "MIS_GUIDANCE 1: horizontal acceleration limit of the trajectory (tangential and lateral)"),
    Param::new("TRJ_ACC_VERT", "Mission", "m/s^2", (0.1, 15.0), 2, field!(guidance.trajectory.accel_vertical),
        "MIS_GUIDANCE 1: vertical acceleration limit of the trajectory"),
    Param::new("TRJ_JERK", "Mission", "m/s^3", (0.1, 80.0), 2, field!(guidance.trajectory.jerk),
        "MIS_GUIDANCE 1: jerk limit along the trajectory"),
    Param::new("TRJ_V_UP", "Mission", "m/s", (0.1, 10.0), 2, field!(guidance.trajectory.speed_up),
        "MIS_GUIDANCE 1: upward speed limit of the trajectory"),
    Param::new("TRJ_V_DN", "Mission", "m/s", (0.1, 10.0), 2, field!(guidance.trajectory.speed_down),
        "MIS_GUIDANCE 1: downward speed limit of the trajectory"),
    Param::new("TRJ_CORNER_TOL", "Mission", "m", (0.0, 5.0), 3, field!(guidance.trajectory.corner_tolerance),
        "MIS_GUIDANCE 1: largest corner cut of the trajectory (the planner's margin); 0 stops at every corner"),
    Param::new("TRJ_ERR_MAX", "Mission", "m", (0.05, 10.0), 2, field!(guidance.trajectory.tracking_error_bound),
        "MIS_GUIDANCE 1: tracking error at which the trajectory's clock stops (full speed up to half of it)"),
    Param::new("TRJ_XY_P", "Mission", "1/s", (0.1, 5.0), 2, field!(tracking.trajectory_pos_p),
        "MIS_GUIDANCE 1: horizontal position gain of the position P -> velocity P tracking cascade"),
    Param::new("TRJ_XY_VEL_P", "Mission", "1/s", (0.1, 10.0), 2, field!(tracking.trajectory_vel_p),
        "MIS_GUIDANCE 1: horizontal velocity gain of the tracking cascade (acceleration per m/s of velocity error)"),
    // Issue 21: the RC receiver's channel map and ranges (`rc::map`; the loss timeout is FS_RC_TIMEOUT).
    rc_map("RC_MAP_ROLL", 1.0, u8_field!(rc.map_roll),
        "RC channel of the roll stick"),
    rc_map("RC_MAP_PITCH", 1.0, u8_field!(rc.map_pitch),
        "RC channel of the pitch stick"),
    rc_map("RC_MAP_THR", 1.0, u8_field!(rc.map_throttle),
        "RC channel of the throttle stick"),
    rc_map("RC_MAP_YAW", 1.0, u8_field!(rc.map_yaw),
        "RC channel of the yaw stick"),
    rc_map("RC_MAP_ARM", 0.0, u8_field!(rc.map_arm),
        "RC channel of the arm switch (on above RC_SW_HIGH_US); 0 none"),
    rc_map("RC_MAP_MODE", 0.0, u8_field!(rc.map_mode),
        "RC channel of the mode switch (MODE_SW_LOW/MID/HIGH); 0 none"),
    rc_map("RC_MAP_KILL", 0.0, u8_field!(rc.map_kill),
        "RC channel of the kill switch (on unless below RC_SW_LOW_US); 0 none"),
    rc_us("RC_MIN_US", (700.0, 1400.0), field!(rc.min_us),
        "RC stick low end (throttle 0, stick -1)"),
    rc_us("RC_TRIM_US", (1410.0, 1590.0), field!(rc.trim_us),
        "RC stick centre (Futaba SBUS: 1520)"),
    rc_us("RC_MAX_US", (1600.0, 2300.0), field!(rc.max_us),
        "RC stick high end (throttle 1, stick +1)"),
    rc_us("RC_DEADBAND_US", (0.0, 100.0), field!(rc.deadband_us),
        "RC roll/pitch/yaw deadband around RC_TRIM_US"),
    rc_us("RC_SW_LOW_US", (800.0, 1500.0), field!(rc.switch_low_us),
        "RC switch: below this = low position"),
    rc_us("RC_SW_HIGH_US", (1500.0, 2200.0), field!(rc.switch_high_us),
        "RC switch: above this = high position"),
    Param::new("RC_LQ_MIN", "RC", "%", (0.0, 100.0), 0, field!(rc.lq_min),
        "RC link quality below this = RC lost (CRSF link statistics)"),
];
