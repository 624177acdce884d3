//! The navigation filter between a filtered position source (`gps`, `rtk`, `vio`:
//! `crate::sim::source`) and the in-process controller: [`parapet_core::nav::aid::NavAid`] (the
//! code the firmware runs too: IMU-rate predict, delayed fixes, the controller's fix and the
//! dropout failsafe of [`parapet_core::nav::aid::NAV_TIMEOUT_US`]) fed with the simulator's
//! readings and the σ the scene states for its source.
//!
//! **Relative sources** (`vio`): the filter fuses the odometry in its own frame, whose drift
//! against the world it cannot observe, so its σ says nothing of it. For the margin of mapped
//! obstacles (`docs/filter.md` § 18) [`NavAid::world_sigma`] adds the source's declared drift
//! (random walk, m/√s) since the first fix: `σ_w² = σ² + drift² · t`.
//!
//! Owns: [`NavAid`]. May import: `parapet-core`, [`crate::sim`].

use parapet_core::controller::PositionFix;
use parapet_core::msg::Euler;
use parapet_core::nav::aid::{NavAid as CoreAid, SourceNoise};
use parapet_core::nav::{FixKind, NavParams, NavStatus};
use parapet_core::Vec3;

use crate::sim::sensors::{PositionReading, SensorParams};
use crate::sim::source::PositionSource;

/// The filter and what it knows of its source.
#[derive(Clone, Debug)]
pub struct NavAid {
    aid: CoreAid,
    kind: FixKind,
    noise: SourceNoise,
    sigma_baro: f32,
    /// A relative source's drift, m/√s (0 for an absolute one).
    drift: f32,
    /// Time of the first fix, µs.
    first_fix_us: Option<u64>,
    /// Resets already handed to the controller ([`NavAid::take_reset`]).
    seen_resets: u32,
}

impl NavAid {
    /// For the source of `sensors`; `None` for motion capture (the latest fix, as before).
    pub fn for_sensors(sensors: &SensorParams) -> Option<Self> {
        let src = sensors.position_source;
        if src.is_mocap() {
            return None;
        }
        let baro = src.preset().baro.map_or(1.0, |(n, _)| n);
        Some(NavAid {
            aid: CoreAid::new(NavParams::default()),
            kind: Self::kind_of(src),
            noise: Self::noise_of(sensors),
            sigma_baro: floor(baro) * 1.5,
            drift: if Self::kind_of(src) == FixKind::Relative { src.preset().drift as f32 } else { 0.0 },
            first_fix_us: None,
            seen_resets: 0,
        })
    }

    /// How the filter takes the fixes of `src` (vision: relative).
    pub fn kind_of(src: PositionSource) -> FixKind {
        if src == PositionSource::Vio {
            FixKind::Relative
        } else {
            FixKind::Absolute
        }
    }

    /// The σ the filter is told: the noise the scene gives the source (a floor keeps a
    /// noise-free flight well posed).
    pub fn noise_of(sensors: &SensorParams) -> SourceNoise {
        SourceNoise { position: floor(sensors.position_noise), velocity: floor(sensors.velocity_noise) }
    }

    /// One IMU sample (specific force, body FRD) at `t_us` with the estimator's attitude.
    pub fn imu(&mut self, t_us: u64, accel: &Vec3, attitude: &Euler) {
        let _ = self.aid.imu(t_us, accel, attitude);
    }

    /// A delayed fix (`t_us`: the time it describes).
    pub fn fix(&mut self, t_us: u64, r: &PositionReading) {
        let _ = self.aid.fix(&reading_fix(t_us, r), self.noise, self.kind);
        self.first_fix_us.get_or_insert(t_us);
    }

    /// A barometer reading (NED down, m) of `t_us`.
    pub fn height(&mut self, t_us: u64, down: f64) {
        let _ = self.aid.height(t_us, down as f32, self.sigma_baro);
    }

    /// The controller's fix at `now_us`; `None` before the first fix and in the failsafe.
    pub fn controller_fix(&self, now_us: u64) -> Option<PositionFix> {
        self.aid.controller_fix(now_us)
    }

    /// The estimate at `now_us` (NED position, velocity).
    pub fn estimate(&self, now_us: u64) -> Option<(Vec3, Vec3)> {
        self.aid.estimate(now_us)
    }

    /// The horizontal position σ against the world at `now_us`, m: the filter's, plus a relative
    /// source's drift since the first fix (module docs).
    pub fn world_sigma(&self, now_us: u64) -> f32 {
        let s = self.aid.status().sigma_p;
        let h = s.x.max(s.y);
        let t = self.first_fix_us.map_or(0.0, |t0| now_us.saturating_sub(t0) as f32 * 1e-6);
        (h * h + self.drift * self.drift * t).sqrt()
    }

    /// The delta of an absolute source's reset not yet handed on (the estimate jumped by it;
    /// `FlightController::position_reset`), once per reset. A relative source's reset moves
    /// only the frame offset: the estimate does not jump, nothing to hand on.
    pub fn take_reset(&mut self) -> Option<Vec3> {
        let st = self.aid.status();
        let new = st.resets != self.seen_resets;
        self.seen_resets = st.resets;
        (new && self.kind == FixKind::Absolute).then_some(st.last_reset_delta)
    }

    /// Counters and σ.
    pub fn status(&self) -> NavStatus {
        self.aid.status()
    }
}

fn floor(x: f64) -> f32 {
    (x as f32).max(0.01)
}

/// A simulator reading as the core's fix of `t_us` (f64 → f32, the yaw attached).
pub fn reading_fix(t_us: u64, r: &PositionReading) -> PositionFix {
    let p = Vec3::new(r.position.x as f32, r.position.y as f32, r.position.z as f32);
    let v = Vec3::new(r.velocity.x as f32, r.velocity.y as f32, r.velocity.z as f32);
    PositionFix { t_us, position: p, velocity: v, yaw: Some(r.yaw as f32) }
}
