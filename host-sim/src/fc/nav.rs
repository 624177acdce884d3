//! The navigation filter ([`parapet_core::nav`]) between a filtered position source (`gps`,
//! `rtk`, `vio`: `crate::sim::source`) and the in-process controller, as a firmware's inner
//! task would run it: predicted with every IMU sample and the attitude estimator's attitude,
//! updated with every delayed fix (position, velocity) and barometer reading, and read at
//! every outer step as the controller's fix (time now, the filter's position, velocity and σ;
//! the yaw of the source — magnetometer or vision — for the attitude estimator).
//!
//! **Failsafe**: while no position fix has been fused for [`NAV_TIMEOUT_S`] (a dropout), or
//! the horizontal σ exceeds [`NAV_MAX_SIGMA_M`], the controller gets no fix: its own
//! position timeout (0.2 s) then brakes (`PositionStale`) and lands, as with a lost motion
//! capture. Shorter dropouts are bridged by the filter on the IMU.
//!
//! Owns: [`NavAid`]. May import: `parapet-core`, [`crate::sim`].

use parapet_core::controller::PositionFix;
use parapet_core::frame::rotation_from_euler;
use parapet_core::msg::Euler;
use parapet_core::nav::{FixKind, NavFilter, NavParams, NavStatus};
use parapet_core::Vec3;

use crate::sim::sensors::{PositionReading, SensorParams};
use crate::sim::source::PositionSource;

/// Longest time without a fused position fix the filter's estimate is flown on, s.
pub const NAV_TIMEOUT_S: f64 = 2.0;
/// Largest horizontal position σ the estimate is flown with, m.
pub const NAV_MAX_SIGMA_M: f32 = 3.0;

/// The filter and what it knows of its source.
#[derive(Clone, Debug)]
pub struct NavAid {
    filter: NavFilter,
    kind: FixKind,
    sigma_p: f32,
    sigma_v: f32,
    sigma_baro: f32,
    yaw: Option<f32>,
}

impl NavAid {
    /// For the source of `sensors`; `None` for motion capture (the latest fix, as before).
    pub fn for_sensors(sensors: &SensorParams) -> Option<Self> {
        let src = sensors.position_source;
        if src.is_mocap() {
            return None;
        }
        let kind = if src == PositionSource::Vio { FixKind::Relative } else { FixKind::Absolute };
        // The filter is told the σ it is given (a floor keeps a noise-free flight well posed).
        let floor = |x: f64| (x as f32).max(0.01);
        let baro = src.preset().baro.map_or(1.0, |(n, _)| n);
        Some(NavAid {
            filter: NavFilter::new(NavParams::default()),
            kind,
            sigma_p: floor(sensors.position_noise),
            sigma_v: floor(sensors.velocity_noise),
            sigma_baro: floor(baro) * 1.5,
            yaw: None,
        })
    }

    /// One IMU sample (specific force, body FRD) at `t_us` with the estimator's attitude.
    pub fn imu(&mut self, t_us: u64, accel: &Vec3, attitude: &Euler) {
        let rot = rotation_from_euler(attitude.roll, attitude.pitch, attitude.yaw);
        let _ = self.filter.predict(t_us, accel, &rot);
    }

    /// A delayed fix (`t_us`: the time it describes).
    pub fn fix(&mut self, t_us: u64, r: &PositionReading) {
        let p = Vec3::new(r.position.x as f32, r.position.y as f32, r.position.z as f32);
        let v = Vec3::new(r.velocity.x as f32, r.velocity.y as f32, r.velocity.z as f32);
        let _ = self.filter.fuse_position(t_us, &p, self.sigma_p, self.kind);
        let _ = self.filter.fuse_velocity(t_us, &v, self.sigma_v);
        self.yaw = Some(r.yaw as f32);
    }

    /// A barometer reading (NED down, m) of `t_us`.
    pub fn height(&mut self, t_us: u64, down: f64) {
        let _ = self.filter.fuse_height(t_us, down as f32, self.sigma_baro);
    }

    /// The controller's fix at `now_us`; `None` before the first fix and in the failsafe
    /// (see the module docs).
    pub fn controller_fix(&self, now_us: u64) -> Option<PositionFix> {
        let age = self.filter.position_age_us(now_us)?;
        let st = self.filter.status();
        if age as f64 * 1e-6 > NAV_TIMEOUT_S || st.sigma_p.x.max(st.sigma_p.y) > NAV_MAX_SIGMA_M {
            return None;
        }
        let (position, velocity) = self.filter.estimate(now_us)?;
        Some(PositionFix { t_us: now_us, position, velocity, yaw: self.yaw })
    }

    /// The estimate at `now_us` (NED position, velocity).
    pub fn estimate(&self, now_us: u64) -> Option<(Vec3, Vec3)> {
        self.filter.estimate(now_us)
    }

    /// Counters and σ.
    pub fn status(&self) -> NavStatus {
        self.filter.status()
    }
}
