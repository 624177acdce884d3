//! Guidance: the nominal reference of the outer loop while Armed — on the ground, a
//! takeoff ramp, holding a point, or flying the stored path ([`crate::waypoint`]).
//!
//! Rate: the outer loop's (default 250 Hz), plus the commands (takeoff, hold, mission,
//! new path). The yaw reference is the estimated yaw at arming, held constant — or, along the
//! path with `MIS_YAW_MODE` = travel, turned towards the direction of travel while the path
//! waits for the heading ([`super::path_yaw`]).
//!
//! May import: [`crate::waypoint`], [`crate::tracking::Reference`], [`super::path_yaw`], the
//! command errors of [`crate::outer`], the crate root foundation.

use super::path_yaw::{PathYaw, PathYawParams, Steering};
use super::CommandError;
use crate::fmath::norm3;
use crate::frame::is_finite3;
use crate::tracking::Reference;
use crate::waypoint::{PathError, Progress, WaypointFollower, WaypointParams, DEFAULT_PATH_CAPACITY};
use crate::Vec3;

/// Capacity of the controller's path, waypoints.
pub const PATH_CAPACITY: usize = DEFAULT_PATH_CAPACITY;

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
        }
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
        })
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
            Mode::Mission { t0_us } => {
                let p = &self.params.path_yaw;
                let mut s = self.follower.sample(self.path_yaw.path_time(p, t0_us, now_us));
                self.path_yaw.steer_sample(p, &mut s, &mut self.yaw_ref, v);
                *progress = s.progress;
                let r = Reference {
                    position: s.position,
                    velocity: s.velocity,
                    acceleration: s.acceleration,
                    yaw: self.yaw_ref,
                };
                (GuidanceMode::Mission, Some(r))
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
        self.follower.set_path(waypoints_ned).map_err(CommandError::Path)?;
        if let Mode::Mission { .. } = self.mode {
            if self.follower.start(origin).is_ok() {
                self.mode = Mode::Mission { t0_us: now_us };
                self.path_yaw.reset();
            } else {
                self.mode = Mode::Hold(origin);
            }
        }
        Ok(())
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

    /// Hold `target` from now on.
    pub fn hold(&mut self, target: Vec3) {
        self.mode = Mode::Hold(target);
    }

    /// Fly the stored path from `origin` (the current reference position), from `now_us`.
    pub fn start_mission(&mut self, now_us: u64, origin: Vec3) -> Result<(), CommandError> {
        if self.mode == Mode::Ground {
            return Err(CommandError::NotFlying);
        }
        self.follower.start(origin).map_err(CommandError::Path)?;
        self.mode = Mode::Mission { t0_us: now_us };
        self.path_yaw.reset();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn guidance_mode_names_are_the_variant_names() {
        use GuidanceMode::*;
        for m in [Off, Ground, Hold, Takeoff, Mission, Brake, Land, NoFix, Manual, Assist, Offboard, Return] {
            assert_eq!(m.as_str(), std::format!("{m:?}"));
        }
    }
}
