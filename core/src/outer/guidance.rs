//! Guidance: the nominal reference of the outer loop while Armed — on the ground, a
//! takeoff ramp, holding a point, or flying the stored path ([`crate::waypoint`]).
//!
//! Rate: the outer loop's (default 250 Hz), plus the commands (takeoff, hold, mission,
//! new path). The yaw reference is the estimated yaw at arming, held constant — or, along the
//! path with `MIS_YAW_MODE` = travel, turned towards the direction of travel while the path
//! waits for the heading ([`super::path_yaw`]).
//!
//! A position reset of the navigation filter ([`Guidance::shift_reference`]) moves a hold
//! point and a takeoff ramp with the estimate and shifts a mission's reference by the reset's
//! delta, decaying back to the path ([`super::reset_shift`]).
//!
//! May import: [`crate::waypoint`], [`crate::tracking::Reference`], [`super::path_yaw`], [`super::reset_shift`], the
//! command errors of [`crate::outer`], the crate root foundation.

use super::path_yaw::{PathYaw, PathYawParams, Steering, YawMode};
use super::reset_shift::ResetShift;
use super::trajectory::{
    clock_scale, Trajectory, TrajectoryError, TrajectoryParams, MAX_STEP_DT, MIN_LEG_LENGTH,
};
use super::CommandError;
use crate::fmath::{hypotf, norm3};
use crate::frame::is_finite3;
use crate::param_decl::{access, field, Has, Param};
use crate::tracking::{limit_lead, Reference, MOVING_REFERENCE_SPEED};
use crate::waypoint::{
    PathError, PathSample, Progress, WaypointFollower, WaypointParams, DEFAULT_PATH_CAPACITY,
};
use crate::Vec3;

mod lent;
mod stream;

/// Capacity of the controller's path, waypoints.
pub const PATH_CAPACITY: usize = DEFAULT_PATH_CAPACITY;

/// Capacity of the mission trajectory: the start point and the path's waypoints.
pub const TRAJECTORY_CAPACITY: usize = PATH_CAPACITY + 1;

/// A new path during a trajectory mission carries the reference's motion over when the
/// reference velocity is within this cosine (about 2.6°) of the new first leg.
pub const CARRY_MAX_ANGLE_COS: f32 = 0.999;

/// Which guidance flies a mission (`MIS_GUIDANCE`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MissionGuidance {
    /// 0: the paper's constant-speed point along the polyline (`s = V·t`,
    /// [`crate::waypoint`]), as the paper flies it (0.25 m/s); the paper reproduction names it.
    Paper,
    /// 1 (default): the jerk-limited trajectory ([`super::trajectory`]) whose clock waits for
    /// the vehicle, tracked by the position → velocity cascade
    /// ([`super::tracking::PdTracker::update_trajectory`]).
    #[default]
    Trajectory,
}

impl MissionGuidance {
    /// Every guidance, in code order.
    pub const ALL: [MissionGuidance; 2] = [MissionGuidance::Paper, MissionGuidance::Trajectory];

    /// The name in scene files and on the command line: `paper`, `trajectory`.
    pub const fn as_str(self) -> &'static str {
        match self {
            MissionGuidance::Paper => "paper",
            MissionGuidance::Trajectory => "trajectory",
        }
    }

    /// The parameter code (0 paper, 1 trajectory).
    pub const fn code(self) -> i32 {
        match self {
            MissionGuidance::Paper => 0,
            MissionGuidance::Trajectory => 1,
        }
    }

    /// The guidance with parameter code `c`.
    pub const fn from_code(c: i32) -> Option<MissionGuidance> {
        match c {
            0 => Some(MissionGuidance::Paper),
            1 => Some(MissionGuidance::Trajectory),
            _ => None,
        }
    }
}

impl core::str::FromStr for MissionGuidance {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        MissionGuidance::ALL.into_iter().find(|m| m.as_str() == s).ok_or(())
    }
}

/// Which guidance produced the reference (telemetry).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GuidanceMode {
    /// Motors off (Disarmed or MotorsOff).
    #[default]
    Off,
    /// Armed on the ground, motors at idle.
    Ground,
    /// Holding a point.
    Hold,
    /// Takeoff ramp.
    Takeoff,
    /// Flying the path.
    Mission,
    /// Failsafe braking (holding the last good position).
    Brake,
    /// Landing.
    Land,
    /// No fresh position fix: level attitude, open-loop thrust.
    NoFix,
    /// Manual attitude (sticks straight to the inner loop, no filter).
    Manual,
    /// Position assist (stick velocity setpoint).
    Assist,
    /// Offboard setpoints.
    Offboard,
    /// Flying back along the breadcrumbs.
    Return,
}

impl GuidanceMode {
    /// Number of guidance modes.
    pub const COUNT: usize = 12;
    /// Every guidance mode, in code order ([`GuidanceMode::code`] is the index: the log's
    /// `vehicle_status.parapet_mode`).
    pub const ALL: [GuidanceMode; Self::COUNT] = [
        GuidanceMode::Off,
        GuidanceMode::Ground,
        GuidanceMode::Hold,
        GuidanceMode::Takeoff,
        GuidanceMode::Mission,
        GuidanceMode::Brake,
        GuidanceMode::Land,
        GuidanceMode::NoFix,
        GuidanceMode::Manual,
        GuidanceMode::Assist,
        GuidanceMode::Offboard,
        GuidanceMode::Return,
    ];

    /// The mode's code: its index in [`GuidanceMode::ALL`] (the declaration order).
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The mode of code `code`, if any.
    pub fn from_code(code: u8) -> Option<GuidanceMode> {
        Self::ALL.get(usize::from(code)).copied()
    }

    /// The mode named `name` ([`GuidanceMode::as_str`]), if any.
    pub fn from_name(name: &str) -> Option<GuidanceMode> {
        Self::ALL.into_iter().find(|m| m.as_str() == name)
    }

    /// `false` only for [`GuidanceMode::Off`] (motors off): the log's `arming_state`.
    pub const fn motors_on(self) -> bool {
        !matches!(self, GuidanceMode::Off)
    }

    /// The variant's name ("Off", "Ground", "Hold", "Takeoff", "Mission", "Brake", "Land",
    /// "NoFix", "Manual", "Assist", "Offboard", "Return").
    pub const fn as_str(self) -> &'static str {
        match self {
            GuidanceMode::Off => "Off",
            GuidanceMode::Ground => "Ground",
            GuidanceMode::Hold => "Hold",
            GuidanceMode::Takeoff => "Takeoff",
            GuidanceMode::Mission => "Mission",
            GuidanceMode::Brake => "Brake",
            GuidanceMode::Land => "Land",
            GuidanceMode::NoFix => "NoFix",
            GuidanceMode::Manual => "Manual",
            GuidanceMode::Assist => "Assist",
            GuidanceMode::Offboard => "Offboard",
            GuidanceMode::Return => "Return",
        }
    }
}

/// Guidance parameters (the `guidance` part of [`crate::controller::ControllerParams`];
/// the path follower's are `waypoint`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuidanceParams {
    /// Vertical speed of the takeoff ramp, m/s. Default 0.5.
    pub takeoff_speed: f32,
    /// Largest takeoff height above home, m. Default [`TAKEOFF_HEIGHT_MAX_DEFAULT`].
    pub takeoff_height_max: f32,
    /// The yaw along a path, Mission and Return (`MIS_YAW_*`). Default: hold the heading.
    pub path_yaw: PathYawParams,
    /// Which guidance flies a mission (`MIS_GUIDANCE`). Default: the paper's.
    pub mission: MissionGuidance,
    /// The trajectory's limits (`TRJ_*`) for [`MissionGuidance::Trajectory`]; its cruise
    /// speed is replaced by the path follower's (`WP_SPEED`) when a mission is built.
    pub trajectory: TrajectoryParams,
}

/// Default takeoff height limit, m: 120 m, the height ceiling of the common drone rules (EU
/// open category, US Part 107's 400 ft), which takes QGroundControl's default plan (50 m) and
/// keeps a mission from commanding a takeoff beyond it. Was 10 m, which refused QGroundControl's
/// default plan. Parameter `MIS_TKO_ALT_MAX` (1–500 m).
pub const TAKEOFF_HEIGHT_MAX_DEFAULT: f32 = 120.0;

impl Default for GuidanceParams {
    fn default() -> Self {
        GuidanceParams {
            takeoff_speed: 0.5,
            takeoff_height_max: TAKEOFF_HEIGHT_MAX_DEFAULT,
            path_yaw: PathYawParams::default(),
            mission: MissionGuidance::default(),
            trajectory: TrajectoryParams::default(),
        }
    }
}

impl GuidanceParams {
    /// The takeoff limit and the mission's guidance (issue 35; `crate::params`): the paper's
    /// constant-speed point (the paper reproduction) or the jerk-limited trajectory
    /// (`outer::trajectory`, cruise speed `WP_SPEED`).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 2] {
        [
            Param::new("MIS_TKO_ALT_MAX", "Mission", "m", (1.0, 500.0), 1, field!(takeoff_height_max),
                "Largest takeoff height above home: a higher TAKEOFF mission item is refused at upload \
                 (MISSION_ACK INVALID_PARAM7), a higher NAV_TAKEOFF command or mission start is DENIED"),
            Param::new("MIS_GUIDANCE", "Mission", "", (0.0, 1.0), 0,
                access!(|s| s.mission.code() as f32, |s, v| s.mission = MissionGuidance::from_code(v as i32).unwrap_or(s.mission)),
                "Mission guidance: 0 paper (constant-speed point, s = V t), 1 trajectory (jerk-limited, waits for the vehicle)")
                .key("guidance").code(|c| MissionGuidance::from_code(c).map(MissionGuidance::as_str)),
        ]
    }
}

/// Nominal guidance while Armed.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    /// On the ground, motors idle.
    Ground,
    /// Hold a fixed point (position step).
    Hold(Vec3),
    /// Straight ramp `from → to` at `speed`, started at `t0_us`.
    Ramp { from: Vec3, to: Vec3, t0_us: u64, speed: f32 },
    /// Fly the stored path, started at `t0_us`.
    Mission { t0_us: u64 },
    /// The trajectory is lent to another flight mode (Return, Offboard: [`lent`]); the
    /// reference comes from [`Guidance::lent_reference`].
    Lent,
}

/// The guidance stage (see the module documentation).
#[derive(Clone, Debug)]
pub struct Guidance {
    params: GuidanceParams,
    follower: WaypointFollower<PATH_CAPACITY>,
    mode: Mode,
    yaw_ref: f32,
    home: Vec3,
    path_yaw: PathYaw,
    /// The mission's trajectory ([`MissionGuidance::Trajectory`], built at the mission start
    /// in place: [`Trajectory::rebuild`]); flown while `flying_trajectory`.
    trajectory: Trajectory<TRAJECTORY_CAPACITY>,
    flying_trajectory: bool,
    /// The trajectory's last reference (the clock's tracking error is measured against it).
    last_traj: Option<Reference>,
    /// For each point of the trajectory, the index of the stored path's waypoint it is (the
    /// origin counts as 0; waypoints within `MIN_LEG_LENGTH` of the previous point are not
    /// points): [`Progress::segment`] of leg `k` is the waypoint it ends at, `point_waypoint[k + 1]`,
    /// as the paper's follower numbers its segments (segment 0 is origin → w₀).
    point_waypoint: heapless::Vec<u16, TRAJECTORY_CAPACITY>,
    /// The mission reference's shift after a position reset, decaying.
    reset_shift: Option<ResetShift>,
    /// The cruise speed the trajectory was built with, m/s (a mission's `WP_SPEED`, Return's
    /// `RTL_SPEED`, Offboard's mission speed).
    traj_cruise: f32,
    /// The offboard position set-point the lent trajectory flies to ([`lent`]).
    offboard_target: Option<Vec3>,
}

fn age(now: u64, t: u64) -> u64 {
    now.saturating_sub(t)
}

impl Guidance {
    /// Guidance on the ground with an empty path for a follower with `waypoint`.
    pub fn new(params: GuidanceParams, waypoint: WaypointParams) -> Result<Self, PathError> {
        Ok(Guidance {
            follower: WaypointFollower::new(waypoint)?,
            params,
            mode: Mode::Ground,
            yaw_ref: 0.0,
            home: Vec3::zeros(),
            path_yaw: PathYaw::default(),
            trajectory: Trajectory::idle(),
            flying_trajectory: false,
            last_traj: None,
            point_waypoint: heapless::Vec::new(),
            reset_shift: None,
            traj_cruise: waypoint.cruise_speed,
            offboard_target: None,
        })
    }

    /// The mission's cruise speed, m/s (`MIS_SPEED`, or a DO_CHANGE_SPEED): the limit of the
    /// trajectory tracking's horizontal velocity set-point.
    pub fn mission_speed(&self) -> f32 {
        self.follower.params().cruise_speed
    }

    /// `true` while a mission trajectory ([`MissionGuidance::Trajectory`]) is flown: the
    /// outer loop tracks it with the cascade gains ([`super::tracking::PdTracker::update_trajectory`]).
    pub fn flying_trajectory(&self) -> bool {
        self.flying_trajectory && matches!(self.mode, Mode::Mission { .. })
    }

    /// `true` on the ground (armed and idle, or not armed).
    pub fn on_ground(&self) -> bool {
        self.mode == Mode::Ground
    }

    /// Back on the ground (disarmed, motors off).
    pub fn ground(&mut self) {
        self.mode = Mode::Ground;
    }

    /// Armed at `home` (NED) facing `yaw_ref` (rad): on the ground.
    pub fn arm(&mut self, home: Vec3, yaw_ref: f32) {
        self.mode = Mode::Ground;
        self.yaw_ref = yaw_ref;
        self.home = home;
    }

    /// The yaw reference (the estimated yaw at arming; the pilot's or the companion's in
    /// the piloted and offboard modes), rad.
    pub fn yaw_ref(&self) -> f32 {
        self.yaw_ref
    }

    /// Set the yaw reference (rad, wrapped by the caller).
    pub fn set_yaw_ref(&mut self, yaw: f32) {
        if yaw.is_finite() {
            self.yaw_ref = yaw;
        }
    }

    /// Hold `target` with zero velocity at the reference yaw.
    pub fn hold_ref(&self, target: Vec3) -> Reference {
        Reference {
            position: target,
            velocity: Vec3::zeros(),
            acceleration: Vec3::zeros(),
            yaw: self.yaw_ref,
        }
    }

    fn ramp_ref(&self, from: Vec3, to: Vec3, elapsed_us: u64, speed: f32) -> (Reference, bool) {
        let d = to - from;
        let len = norm3(&d);
        let s = speed * (elapsed_us as f32 * 1e-6);
        if len.is_nan() || len <= 0.0 || s >= len {
            return (self.hold_ref(to), true);
        }
        let dir = d / len;
        let r = Reference {
            position: from + dir * s,
            velocity: dir * speed,
            acceleration: Vec3::zeros(),
            yaw: self.yaw_ref,
        };
        (r, false)
    }

    /// `true` while the path waits for the heading (`MIS_YAW_MODE` travel).
    pub fn waiting_for_heading(&self) -> bool {
        matches!(self.mode, Mode::Mission { .. }) && self.path_yaw.waiting()
    }

    /// The nominal reference at `now_us` (`None` on the ground); a finished takeoff ramp
    /// turns into a hold. `progress` is updated while flying the path. The vehicle `v`
    /// steers the yaw along the path in `MIS_YAW_MODE` travel.
    pub fn reference(
        &mut self,
        now_us: u64,
        v: &Steering,
        progress: &mut Progress,
    ) -> (GuidanceMode, Option<Reference>) {
        let shift = self.reset_shift.and_then(|s| s.at(now_us));
        if shift.is_none() {
            self.reset_shift = None;
        }
        let (sp, sv, sa) = shift.unwrap_or((Vec3::zeros(), Vec3::zeros(), Vec3::zeros()));
        let shifted = |r: Reference| Reference {
            position: r.position + sp,
            velocity: r.velocity + sv,
            acceleration: r.acceleration + sa,
            ..r
        };
        match self.mode {
            Mode::Ground => (GuidanceMode::Ground, None),
            Mode::Hold(target) => (GuidanceMode::Hold, Some(self.hold_ref(target))),
            Mode::Ramp { from, to, t0_us, speed } => {
                let (r, done) = self.ramp_ref(from, to, age(now_us, t0_us), speed);
                if done {
                    self.mode = Mode::Hold(to);
                }
                (GuidanceMode::Takeoff, Some(r))
            }
            Mode::Lent => {
                // Only in the Mission flight mode; the lending mode left without a release.
                let at = self.last_traj.map_or(self.home, |r| r.position);
                (GuidanceMode::Hold, Some(self.hold_ref(at)))
            }
            Mode::Mission { .. } if self.flying_trajectory => {
                let r = self.trajectory_ref(v, progress, &sp, true);
                (GuidanceMode::Mission, Some(shifted(r)))
            }
            Mode::Mission { t0_us } => {
                let p = &self.params.path_yaw;
                let mut s = self.follower.sample(self.path_yaw.governed_time(
                    p,
                    t0_us,
                    now_us,
                    v.speed_limit / self.mission_speed(),
                ));
                self.path_yaw.steer_sample(p, &mut s, &mut self.yaw_ref, v);
                *progress = s.progress;
                let r = Reference {
                    position: s.position,
                    velocity: s.velocity,
                    acceleration: s.acceleration,
                    yaw: self.yaw_ref,
                };
                (GuidanceMode::Mission, Some(shifted(r)))
            }
        }
    }

    /// The navigation filter reset its position by `delta` (NED, m; the estimate jumped by it)
    /// at `now_us`: a hold point and a takeoff ramp move with the estimate (the vehicle stays
    /// where it is), a mission's reference is shifted by `delta`, the shift decaying back to the
    /// path ([`super::reset_shift`]), so the tracking error does not jump. Non-finite: ignored.
    pub fn shift_reference(&mut self, now_us: u64, delta: Vec3) {
        if !is_finite3(&delta) {
            return;
        }
        match &mut self.mode {
            Mode::Ground | Mode::Lent => {}
            Mode::Hold(target) => *target += delta,
            Mode::Ramp { from, to, .. } => {
                *from += delta;
                *to += delta;
            }
            Mode::Mission { .. } => {
                // A shift still decaying carries on from where it is.
                let now = self.reset_shift.and_then(|s| s.at(now_us)).map_or(Vec3::zeros(), |s| s.0);
                self.reset_shift = ResetShift::new(now + delta, now_us);
            }
        }
    }

    /// Replace the path; while flying the mission, restart it at `now_us` from `origin`
    /// (the current reference position), or hold `origin` if it cannot start.
    pub fn set_path(
        &mut self,
        waypoints_ned: &[Vec3],
        now_us: u64,
        origin: Vec3,
    ) -> Result<(), CommandError> {
        self.set_path_from(waypoints_ned, now_us, origin, true)
    }

    /// [`Self::set_path`] from `origin`: the current reference (`carry`: a trajectory being
    /// flown carries its motion over when it can), or a point away from it such as the
    /// vehicle's position (`carry` false: the new path starts there at rest).
    pub fn set_path_from(
        &mut self,
        waypoints_ned: &[Vec3],
        now_us: u64,
        origin: Vec3,
        carry: bool,
    ) -> Result<(), CommandError> {
        self.follower.set_path(waypoints_ned).map_err(CommandError::Path)?;
        if let Mode::Mission { .. } = self.mode {
            // `origin` (the current reference, or the vehicle) has the shift in it.
            self.reset_shift = None;
            // A trajectory being flown carries its motion over when it can.
            let carry = self.last_traj.filter(|_| carry && self.flying_trajectory);
            if self.follower.start(origin).is_ok() && self.build_trajectory(origin, carry).is_ok() {
                self.mode = Mode::Mission { t0_us: now_us };
                self.path_yaw.reset();
            } else {
                self.mode = Mode::Hold(origin);
                self.flying_trajectory = false;
            }
        }
        Ok(())
    }

    /// The mission's cruise speed from the next path start on (m/s, the follower's range; a
    /// mission item's DO_CHANGE_SPEED). Refused out of range, the speed unchanged.
    pub fn set_cruise_speed(&mut self, speed: f32) -> Result<(), CommandError> {
        self.follower.set_cruise_speed(speed).map_err(CommandError::Path)
    }

    /// Drop the stored path; while flying the mission, hold `origin` (the current reference
    /// position) instead. A later mission start fails until a new path is set.
    pub fn clear_path(&mut self, origin: Vec3) {
        self.follower.clear();
        if let Mode::Mission { .. } = self.mode {
            self.mode = Mode::Hold(origin);
        }
    }

    /// Take off to `height_m` (m, in (0, takeoff_height_max]) above home: a ramp at
    /// `takeoff_speed` from `position` (the fresh position estimate, needed) when on the
    /// ground, else from `reference`.
    pub fn takeoff(
        &mut self,
        now_us: u64,
        height_m: f32,
        position: Option<Vec3>,
        reference: Vec3,
    ) -> Result<(), CommandError> {
        if !(height_m.is_finite() && height_m > 0.0 && height_m <= self.params.takeoff_height_max) {
            return Err(CommandError::BadHeight);
        }
        let p = position.ok_or(CommandError::NoPosition)?;
        let from = match self.mode {
            Mode::Ground => p,
            _ => reference,
        };
        let to = Vec3::new(from.x, from.y, self.home.z - height_m);
        self.mode = Mode::Ramp { from, to, t0_us: now_us, speed: self.params.takeoff_speed };
        Ok(())
    }

    /// `hold_position`'s target check.
    pub fn check_target(target: &Vec3) -> Result<(), CommandError> {
        if is_finite3(target) {
            Ok(())
        } else {
            Err(CommandError::BadTarget)
        }
    }

    /// The guidance's parameters.
    pub fn params(&self) -> &GuidanceParams {
        &self.params
    }

    /// The stored path's waypoints (NED), as flown from the origin of the last start.
    pub fn waypoints(&self) -> &[Vec3] {
        self.follower.waypoints()
    }

    /// Hold `target` from now on.
    pub fn hold(&mut self, target: Vec3) {
        self.mode = Mode::Hold(target);
        self.reset_shift = None;
    }

    /// Fly the stored path from `origin` (the current reference position), from `now_us`.
    pub fn start_mission(&mut self, now_us: u64, origin: Vec3) -> Result<(), CommandError> {
        if self.mode == Mode::Ground {
            return Err(CommandError::NotFlying);
        }
        self.follower.start(origin).map_err(CommandError::Path)?;
        self.build_trajectory(origin, None)?;
        self.mode = Mode::Mission { t0_us: now_us };
        self.reset_shift = None;
        self.path_yaw.reset();
        Ok(())
    }

    /// With [`MissionGuidance::Trajectory`], build the mission's trajectory from `origin`
    /// through the stored path (waypoints within [`MIN_LEG_LENGTH`] of the previous one
    /// dropped, so a path that starts where the vehicle is, or repeats a waypoint, is flown);
    /// otherwise drop any. An error (parameters out of range, e.g. `WP_SPEED` above the
    /// trajectory's 20 m/s) refuses the start, as [`CommandError::Path`]: the vehicle keeps
    /// its current guidance, nothing is flown blindly.
    ///
    /// `carry` (a new path during a trajectory mission: the last reference) starts the new
    /// trajectory moving ([`Trajectory::new_moving`]) when the reference moves along the new
    /// first leg (within [`CARRY_MAX_ANGLE_COS`]) and the motion is one the new trajectory can
    /// take over; otherwise it starts at rest.
    fn build_trajectory(&mut self, origin: Vec3, carry: Option<Reference>) -> Result<(), CommandError> {
        self.flying_trajectory = false;
        self.last_traj = None;
        if self.params.mission != MissionGuidance::Trajectory {
            return Ok(());
        }
        let points = trajectory_points(origin, self.follower.waypoints(), &mut self.point_waypoint)?;
        self.fly_points(&points, carry, self.follower.params().cruise_speed)
    }

    /// Build the trajectory through `points` (from the current reference, `points[0]`) at
    /// `cruise` m/s with the `TRJ_*` limits, in place, and fly it from the next step: moving
    /// when `carry` (the last reference) moves along the first leg (within
    /// [`CARRY_MAX_ANGLE_COS`]) and the new trajectory can take the motion over
    /// ([`Trajectory::rebuild_moving`]); otherwise, or when that fails, at rest. An error
    /// leaves nothing flown (`flying_trajectory` false).
    fn fly_points(
        &mut self,
        points: &[Vec3],
        carry: Option<Reference>,
        cruise: f32,
    ) -> Result<(), CommandError> {
        self.flying_trajectory = false;
        self.last_traj = None;
        let origin = points.first().copied().unwrap_or(self.home);
        let params = TrajectoryParams { cruise_speed: cruise, ..self.params.trajectory };
        let mut start = Reference {
            position: origin,
            velocity: Vec3::zeros(),
            acceleration: Vec3::zeros(),
            yaw: self.yaw_ref,
        };
        let moving = carry.zip(points.get(1)).and_then(|(r, next)| {
            let leg = next - origin;
            let (speed, len) = (norm3(&r.velocity), norm3(&leg));
            let dir = leg / len;
            let along = r.velocity.dot(&dir);
            (speed > 1e-3 && len > 0.0 && along >= CARRY_MAX_ANGLE_COS * speed).then_some((dir, speed, r))
        });
        let carried = moving.is_some_and(|(dir, speed, r)| {
            let accel = r.acceleration.dot(&dir);
            let ok = self.trajectory.rebuild_moving(params, points, speed, accel).is_ok();
            if ok {
                start.velocity = dir * speed;
                start.acceleration = dir * accel;
            }
            ok
        });
        if !carried {
            self.trajectory.rebuild(params, points).map_err(|e| CommandError::Path(path_error(e)))?;
        }
        self.flying_trajectory = true;
        self.last_traj = Some(start);
        self.traj_cruise = cruise;
        Ok(())
    }

    /// One step of the mission trajectory (see [`super::trajectory`]): the clock runs at
    /// `clock_scale(|p_d − p|, TRJ_ERR_MAX)` (the error without the vehicle's lead along the
    /// travel, [`limit_lead`]: a vehicle pushed ahead does not stop the reference), and stops (0) without a position fix, while the
    /// safety filter held the vehicle back in the previous step ([`Steering::held_back`]) and
    /// while the path waits for the heading (`MIS_YAW_MODE` travel). A step that fails (a
    /// time step out of range) keeps the last reference.
    /// `shift`: the reset shift the reference gets (the clock measures the error against it);
    /// `steer`: the yaw follows `MIS_YAW_MODE` (Mission, Return; not Offboard, whose set-point
    /// gives the yaw).
    fn trajectory_ref(
        &mut self,
        v: &Steering,
        progress: &mut Progress,
        shift: &Vec3,
        steer: bool,
    ) -> Reference {
        let traj = &mut self.trajectory;
        if !self.flying_trajectory {
            return Reference {
                position: self.home,
                velocity: Vec3::zeros(),
                acceleration: Vec3::zeros(),
                yaw: self.yaw_ref,
            };
        };
        // Set with the trajectory (its start at rest); the goal at rest never happens.
        let last = self.last_traj.unwrap_or(Reference {
            position: traj.goal(),
            velocity: Vec3::zeros(),
            acceleration: Vec3::zeros(),
            yaw: self.yaw_ref,
        });
        // The yaw: steer towards the direction of travel (the velocity, or at rest the
        // tangent where the motion goes next); the clock waits while the heading is off.
        let p = &self.params.path_yaw;
        if steer && p.mode == YawMode::Travel {
            let moving = last.velocity.x * last.velocity.x + last.velocity.y * last.velocity.y > 1e-4;
            let dir = if moving { last.velocity } else { traj.travel_direction() };
            let mut probe = PathSample {
                position: last.position,
                velocity: dir,
                acceleration: Vec3::zeros(),
                progress: Progress::default(),
            };
            self.path_yaw.steer_sample(p, &mut probe, &mut self.yaw_ref, v);
        }
        let scale = match v.position {
            Some(q) if !v.held_back && !self.path_yaw.waiting() => {
                // A lead (the vehicle ahead along the travel, or at rest along where the
                // motion goes next) does not stop the clock.
                let moving = hypotf(last.velocity.x, last.velocity.y) > MOVING_REFERENCE_SPEED;
                let dir = if moving { last.velocity } else { traj.travel_direction() };
                let behind = limit_lead(last.position + shift - q, &dir, 0.0);
                clock_scale(norm3(&behind), self.params.trajectory.tracking_error_bound)
            }
            _ => 0.0,
        };
        // The speed governor's limit along the motion caps the speed target (an absolute cap,
        // not a scale of the path's limit: [`Trajectory::step_capped`]).
        let dt = v.dt.min(MAX_STEP_DT);
        let r = match traj.step_capped(dt, scale, v.speed_limit) {
            Ok(s) => {
                let end = s.segment.saturating_add(1);
                let last = self.point_waypoint.last().copied().unwrap_or(0);
                *progress = Progress {
                    segment: self.point_waypoint.get(end).copied().unwrap_or(last),
                    fraction: 0.0,
                    done: s.done,
                };
                Reference {
                    position: s.position,
                    velocity: s.velocity,
                    acceleration: s.acceleration,
                    yaw: 0.0,
                }
            }
            Err(_) => last,
        };
        let r = Reference { yaw: self.yaw_ref, ..r };
        self.last_traj = Some(r);
        r
    }
}

/// The trajectory's points: `origin`, then `waypoints` without those within
/// [`MIN_LEG_LENGTH`] of the previous point (a path that starts where the vehicle is, or
/// repeats a waypoint, is flown); `index[k]` is the index in `waypoints` of point `k` (the
/// origin counts as 0). More than [`TRAJECTORY_CAPACITY`] points: refused.
fn trajectory_points(
    origin: Vec3,
    waypoints: &[Vec3],
    index: &mut heapless::Vec<u16, TRAJECTORY_CAPACITY>,
) -> Result<heapless::Vec<Vec3, TRAJECTORY_CAPACITY>, CommandError> {
    let mut points: heapless::Vec<Vec3, TRAJECTORY_CAPACITY> = heapless::Vec::new();
    let _ = points.push(origin);
    index.clear();
    let _ = index.push(0);
    for (i, w) in waypoints.iter().enumerate() {
        let far = points.last().is_none_or(|q| norm3(&(w - q)) >= MIN_LEG_LENGTH);
        if far {
            let k = u16::try_from(i).unwrap_or(u16::MAX);
            if points.push(*w).is_err() || index.push(k).is_err() {
                return Err(CommandError::Path(PathError::TooMany { capacity: PATH_CAPACITY }));
            }
        }
    }
    Ok(points)
}

/// A trajectory error as the path error a refused command reports.
fn path_error(e: TrajectoryError) -> PathError {
    match e {
        TrajectoryError::Path(p) => p,
        TrajectoryError::RepeatedWaypoint { .. }
        | TrajectoryError::Param(_)
        | TrajectoryError::BadDt
        | TrajectoryError::BadClockScale
        | TrajectoryError::BadStartState => PathError::BadParams,
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    fn steering(p: Vec3) -> Steering {
        Steering { position: Some(p), heading: 0.0, dt: 0.004, held_back: false, speed_limit: f32::INFINITY }
    }

    fn trajectory_guidance() -> Guidance {
        let params = GuidanceParams { mission: MissionGuidance::Trajectory, ..GuidanceParams::default() };
        let mut g = Guidance::new(params, WaypointParams { cruise_speed: 2.0, corner_radius: 0.0 }).unwrap();
        g.arm(Vec3::zeros(), 0.0);
        g.hold(Vec3::new(0.0, 0.0, -1.0));
        g
    }

    #[test]
    fn names_and_codes_round_trip() {
        for m in MissionGuidance::ALL {
            assert_eq!(m.as_str().parse::<MissionGuidance>(), Ok(m));
            assert_eq!(MissionGuidance::from_code(m.code()), Some(m));
        }
        assert_eq!(MissionGuidance::from_code(2), None);
        assert_eq!(MissionGuidance::default(), MissionGuidance::Trajectory);
    }

    /// Fly a trajectory mission with the vehicle (its estimate) on the reference; at 1.5 s the
    /// estimate jumps by `delta` (an absolute source's reset), the guidance told (`shift`) or
    /// not. Returns the largest step of the commanded acceleration (the cascade's
    /// `update_trajectory`) between consecutive steps, and its largest step before the jump.
    fn command_steps_across_a_reset(delta: Vec3, shift: bool) -> (f32, f32) {
        use crate::tracking::{PdTracker, TrackingParams};
        let mut g = trajectory_guidance();
        let origin = Vec3::new(0.0, 0.0, -1.0);
        g.set_path(&[Vec3::new(6.0, 0.0, -1.0), Vec3::new(6.0, 4.0, -1.0)], 0, origin).unwrap();
        g.start_mission(0, origin).unwrap();
        let mut tracker = PdTracker::new(TrackingParams::default());
        let (mut progress, mut p, mut v) = (Progress::default(), origin, Vec3::zeros());
        let (mut prev, mut before, mut after) = (None::<Vec3>, 0.0f32, 0.0f32);
        let dt = 0.004;
        for k in 1..1500u64 {
            let now = 4_000 * k;
            if k == 375 {
                // The true vehicle does not move; its estimate (what the loop flies) jumps.
                p += delta;
                if shift {
                    g.shift_reference(now, delta);
                }
            }
            let (_, r) = g.reference(now, &steering(p), &mut progress);
            let r = r.unwrap();
            let a = tracker.update_trajectory(&r, &p, &v, dt, g.mission_speed(), false);
            if let Some(q) = prev {
                let step = norm3(&(a - q));
                if k < 375 {
                    before = before.max(step);
                } else {
                    after = after.max(step);
                }
            }
            prev = Some(a);
            // The vehicle flies the commanded acceleration (a double integrator).
            v += a * dt;
            p += v * dt;
        }
        (after, before)
    }

    /// Issue 39: a GPS jump of 1.5 m across the travel in flight (the filter resets its
    /// position, the estimate jumps) does not jump the commanded acceleration when the
    /// guidance shifts its reference with the reset; without the shift it jumps by the
    /// position gain times the jump.
    #[test]
    fn a_position_reset_shifts_the_reference_so_the_command_does_not_jump() {
        let delta = Vec3::new(0.3, 1.5, 0.0);
        let (after, before) = command_steps_across_a_reset(delta, true);
        assert!(after <= before.max(0.05) * 2.0, "step after the reset {after} m/s², before {before}");
        let (unshifted, _) = command_steps_across_a_reset(delta, false);
        assert!(unshifted > 10.0 * after.max(0.05), "without the shift: {unshifted} m/s² (with: {after})");
        // A hold moves with the estimate: the reference jumps with it.
        let mut g = trajectory_guidance();
        let mut progress = Progress::default();
        g.shift_reference(0, delta);
        let (_, r) = g.reference(4_000, &steering(Vec3::zeros()), &mut progress);
        assert!(norm3(&(r.unwrap().position - (Vec3::new(0.0, 0.0, -1.0) + delta))) < 1e-6);
    }

    #[test]
    fn the_trajectory_mission_starts_at_rest_at_the_origin_and_ends_done_at_the_goal() {
        let mut g = trajectory_guidance();
        let origin = Vec3::new(0.0, 0.0, -1.0);
        // The first waypoint repeats the origin (a mission item at the takeoff point): dropped.
        let path = [origin, Vec3::new(3.0, 0.0, -1.0), Vec3::new(3.0, 2.0, -1.0)];
        g.set_path(&path, 0, origin).unwrap();
        g.start_mission(0, origin).unwrap();
        let mut progress = Progress::default();
        let (mode, r) = g.reference(4_000, &steering(origin), &mut progress);
        let r = r.unwrap();
        assert_eq!(mode, GuidanceMode::Mission);
        assert!(norm3(&(r.position - origin)) < 1e-4, "{:?}", r.position);
        assert!(norm3(&r.velocity) < 1e-3, "{:?}", r.velocity);
        // The vehicle follows the reference exactly: the clock runs at full speed.
        let mut p = r.position;
        let mut top = 0.0f32;
        let mut steps = 1;
        while !progress.done {
            let (_, r) = g.reference(4_000 * (steps + 1), &steering(p), &mut progress);
            let r = r.unwrap();
            top = top.max(norm3(&r.velocity));
            p = r.position;
            steps += 1;
            assert!(steps < 10_000, "not done after {steps} steps");
        }
        assert!(norm3(&(p - path[2])) < 1e-5, "{p:?}");
        assert!(top > 1.5 && top <= 2.0 + 1e-3, "top speed {top}");
        // Done: the goal held at rest.
        let (_, r) = g.reference(4_000 * (steps + 1), &steering(p), &mut progress);
        assert_eq!(r.unwrap().velocity, Vec3::zeros());
    }

    /// `Progress::segment` numbers the legs by the stored path's waypoint they end at, as the
    /// paper's follower does (segment 0 is origin → w₀): for a path that starts elsewhere the
    /// first leg is 0 (MISSION_CURRENT 0 for the first mission item), for one whose first
    /// waypoint repeats the origin (dropped) the first leg flown is 1.
    #[test]
    fn trajectory_segments_are_the_waypoints_the_legs_end_at() {
        let origin = Vec3::new(0.0, 0.0, -1.0);
        let (a, b) = (Vec3::new(2.0, 0.0, -1.0), Vec3::new(2.0, 2.0, -1.0));
        for (path, want) in [(&[a, b][..], [0u16, 1]), (&[origin, a, b][..], [1, 2])] {
            let mut g = trajectory_guidance();
            g.set_path(path, 0, origin).unwrap();
            g.start_mission(0, origin).unwrap();
            let mut progress = Progress::default();
            let mut p = origin;
            let mut seen: heapless::Vec<u16, 8> = heapless::Vec::new();
            for k in 1..5_000u64 {
                let (_, r) = g.reference(4_000 * k, &steering(p), &mut progress);
                p = r.unwrap().position;
                if seen.last() != Some(&progress.segment) {
                    seen.push(progress.segment).unwrap();
                }
                if progress.done {
                    break;
                }
            }
            assert!(progress.done);
            assert_eq!(seen[..], want[..], "{path:?}");
        }
    }

    #[test]
    fn the_trajectory_clock_waits_for_the_vehicle() {
        let mut g = trajectory_guidance();
        let origin = Vec3::new(0.0, 0.0, -1.0);
        g.set_path(&[Vec3::new(10.0, 0.0, -1.0)], 0, origin).unwrap();
        g.start_mission(0, origin).unwrap();
        let mut progress = Progress::default();
        // The vehicle stays at the origin: the reference gets at most TRJ_ERR_MAX ahead plus
        // the jerk-limited braking distance from the speed it had when the clock began to
        // slow (here 2.83 m from 0.25 m at 1 m/s, 2.9 m/s²), then stops and waits.
        let mut far = 0.0f32;
        let mut last = None;
        for k in 1..5_000u64 {
            let (_, r) = g.reference(4_000 * k, &steering(origin), &mut progress);
            far = far.max(norm3(&(r.unwrap().position - origin)));
            last = r;
        }
        assert!(far < 3.0, "ran away: {far}");
        assert_eq!(last.unwrap().velocity, Vec3::zeros());
        assert!(!progress.done);
        // A vehicle ahead along the travel (pushed there) does not stop the clock: the
        // reference keeps moving towards it (stopped, it would stay within 3 m, as above).
        let mut g = trajectory_guidance();
        g.set_path(&[Vec3::new(10.0, 0.0, -1.0)], 0, origin).unwrap();
        g.start_mission(0, origin).unwrap();
        let ahead = Vec3::new(8.0, 0.0, -1.0);
        let mut r = None;
        for k in 1..1_500u64 {
            r = g.reference(4_000 * k, &steering(ahead), &mut progress).1;
        }
        let x = r.unwrap().position.x;
        assert!(x > 5.0, "reference at {x} after 6 s");
        // Held back by the filter: the clock stops at once.
        let mut g = trajectory_guidance();
        g.set_path(&[Vec3::new(10.0, 0.0, -1.0)], 0, origin).unwrap();
        g.start_mission(0, origin).unwrap();
        let held = Steering { held_back: true, ..steering(origin) };
        for k in 1..1_000u64 {
            let (_, r) = g.reference(4_000 * k, &held, &mut progress);
            assert_eq!(r.unwrap().position, origin);
        }
    }

    #[test]
    fn a_new_path_along_the_motion_carries_it_over_else_restarts_at_rest() {
        let mut g = trajectory_guidance();
        let origin = Vec3::new(0.0, 0.0, -1.0);
        g.set_path(&[Vec3::new(10.0, 0.0, -1.0)], 0, origin).unwrap();
        g.start_mission(0, origin).unwrap();
        let mut progress = Progress::default();
        let mut p = origin;
        let mut r = g.hold_ref(origin);
        for k in 1..500u64 {
            r = g.reference(4_000 * k, &steering(p), &mut progress).1.unwrap();
            p = r.position;
        }
        assert!(r.velocity.x > 1.5, "{:?}", r.velocity);
        // Straight on: the motion goes on without a jump.
        g.set_path(&[Vec3::new(8.0, 0.0, -1.0)], 2_000_000, r.position).unwrap();
        let r2 = g.reference(2_004_000, &steering(p), &mut progress).1.unwrap();
        assert!((r2.velocity - r.velocity).norm() < 0.05, "{:?} -> {:?}", r.velocity, r2.velocity);
        assert!((r2.position - r.position).norm() < 0.02, "{:?} -> {:?}", r.position, r2.position);
        // Sideways: from rest at the current reference.
        g.set_path(&[Vec3::new(r2.position.x, 5.0, -1.0)], 2_008_000, r2.position).unwrap();
        let r3 = g.reference(2_012_000, &steering(p), &mut progress).1.unwrap();
        assert!(r3.velocity.norm() < 0.01, "{:?}", r3.velocity);
        assert!((r3.position - r2.position).norm() < 1e-3);
    }

    #[test]
    fn a_trajectory_that_cannot_be_built_refuses_the_mission() {
        let mut g = trajectory_guidance();
        let origin = Vec3::new(0.0, 0.0, -1.0);
        // WP_SPEED above the trajectory's 20 m/s.
        let params = GuidanceParams { mission: MissionGuidance::Trajectory, ..GuidanceParams::default() };
        let mut fast =
            Guidance::new(params, WaypointParams { cruise_speed: 50.0, corner_radius: 0.0 }).unwrap();
        fast.arm(Vec3::zeros(), 0.0);
        fast.hold(origin);
        fast.set_path(&[Vec3::new(5.0, 0.0, -1.0)], 0, origin).unwrap();
        assert_eq!(fast.start_mission(0, origin), Err(CommandError::Path(PathError::BadParams)));
        let mut progress = Progress::default();
        let (mode, r) = fast.reference(4_000, &steering(origin), &mut progress);
        assert_eq!((mode, r.unwrap().position), (GuidanceMode::Hold, origin));
        // A path that is only the origin: done at once, at the origin.
        g.set_path(&[origin, origin], 0, origin).unwrap();
        g.start_mission(0, origin).unwrap();
        let (_, r) = g.reference(4_000, &steering(origin), &mut progress);
        assert_eq!(r.unwrap().position, origin);
        assert!(progress.done);
    }

    #[test]
    fn guidance_mode_names_are_the_variant_names() {
        use GuidanceMode::*;
        for m in [Off, Ground, Hold, Takeoff, Mission, Brake, Land, NoFix, Manual, Assist, Offboard, Return] {
            assert_eq!(m.as_str(), std::format!("{m:?}"));
        }
    }
}
