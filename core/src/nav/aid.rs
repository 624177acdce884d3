//! The navigation filter as a flight controller runs it — the one implementation the host's
//! in-process controller (`host-sim/src/fc/nav.rs`) and the firmware's outer stage
//! (`firmware/src/app/navigation.rs`) share: predicted with every IMU sample and the attitude
//! estimator's attitude, updated with every delayed fix (position, velocity) and barometer
//! reading, and read at every outer step as the controller's fix (time now, the filter's
//! position and velocity; the yaw of the source — magnetometer or vision — for the attitude
//! estimator).
//!
//! **Failsafe**: while no position fix has been fused for [`NAV_TIMEOUT_US`] (a dropout), or
//! the horizontal σ exceeds [`NAV_MAX_SIGMA_M`], the controller gets no fix: its own position
//! timeout (0.2 s) then brakes (`PositionStale`) and lands, as with a lost motion capture.
//! Shorter dropouts are bridged by the filter on the IMU.
//!
//! **Resets**: an absolute source's position reset is handed on once ([`NavAid::take_reset`])
//! for the controller's reference shift, on the host and on the vehicle alike.
//!
//! **Error bound**: [`NavAid::error_bound`], the margin of mapped obstacles and of the ground
//! and ceiling ([`super::bound`]), from the filter's σ and the time since the first fix.
//!
//! Owns: [`NavAid`], [`SourceNoise`], the timeout and σ limit. May import: [`super`],
//! [`crate::msg`] (the fix and attitude messages), [`crate::frame`].

use super::bound::{error_bound, ErrorBound, UnobservedDrift};
use super::{FixKind, Fusion, NavFilter, NavParams, NavStatus};
use crate::frame::rotation_from_euler;
use crate::msg::{Euler, PositionFix};
use crate::Vec3;

/// Longest time without a fused position fix the filter's estimate is flown on, µs.
pub const NAV_TIMEOUT_US: u64 = 2_000_000;

/// The σ the firmware gives a barometer height (HIL_SENSOR's `pressure_alt`), m: the
/// host's for its barometer (`host-sim/src/fc/nav.rs`: the presets' 0.3 m noise × 1.5, a
/// test checks they agree).
pub const BARO_SIGMA_M: f32 = 0.45;
/// Largest horizontal position σ the estimate is flown with, m (defined beside the filter:
/// the error bound caps at it too, [`super::bound::ERROR_BOUND_MAX_M`]).
pub use super::NAV_MAX_SIGMA_M;

/// The σ a source states for its fixes (per axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SourceNoise {
    /// Position σ, m.
    pub position: f32,
    /// Velocity σ, m/s.
    pub velocity: f32,
}

/// The filter, the yaw and kind of the last fix, and the resets handed on (see the module docs).
#[derive(Clone, Debug)]
pub struct NavAid {
    filter: NavFilter,
    yaw: Option<f32>,
    kind: Option<FixKind>,
    /// Resets already handed to the controller ([`NavAid::take_reset`]).
    seen_resets: u32,
    /// Time of the first fix, µs (the unobserved drifts run from it).
    first_fix_us: Option<u64>,
}

impl NavAid {
    /// Not initialised: waits for an IMU sample and a position fix.
    pub fn new(params: NavParams) -> Self {
        NavAid { filter: NavFilter::new(params), yaw: None, kind: None, seen_resets: 0, first_fix_us: None }
    }

    /// One IMU sample (specific force, body FRD) at `t_us` with the estimator's attitude;
    /// `false` when the filter skipped it.
    pub fn imu(&mut self, t_us: u64, accel: &Vec3, attitude: &Euler) -> bool {
        let rot = rotation_from_euler(attitude.roll, attitude.pitch, attitude.yaw);
        self.filter.predict(t_us, accel, &rot)
    }

    /// A delayed fix (`fix.t_us`: the time it describes) of a source of kind `kind` with σ
    /// `noise`: position, then velocity. Returns what the filter did with the position.
    pub fn fix(&mut self, fix: &PositionFix, noise: SourceNoise, kind: FixKind) -> Fusion {
        let f = self.filter.fuse_position(fix.t_us, &fix.position, noise.position, kind);
        let _ = self.filter.fuse_velocity(fix.t_us, &fix.velocity, noise.velocity);
        self.yaw = fix.yaw;
        self.kind = Some(kind);
        self.first_fix_us.get_or_insert(fix.t_us);
        f
    }

    /// The bound on the estimate's error against the world at `now_us`
    /// ([`super::bound::error_bound`]): [`super::bound::MAPPED_MARGIN_SIGMA`]·σ per axis plus
    /// the drifts `drift` since the first fix (`t = 0` before it).
    pub fn error_bound(&self, now_us: u64, drift: &UnobservedDrift) -> ErrorBound {
        let t = self.first_fix_us.map_or(0.0, |t0| now_us.saturating_sub(t0) as f64 * 1e-6);
        error_bound(&self.filter.status().sigma_p, t, drift)
    }

    /// The kind of the last fix's source; `None` before the first fix.
    pub fn kind(&self) -> Option<FixKind> {
        self.kind
    }

    /// The delta of an absolute source's reset not yet handed on (the estimate jumped by it),
    /// once per reset: the controller shifts its reference by it
    /// (`FlightController::position_reset`, `docs/navigation.md` § A position reset), before
    /// the first fix after the reset. A relative source's reset moves only the frame offset:
    /// the estimate does not jump, nothing to hand on.
    pub fn take_reset(&mut self) -> Option<Vec3> {
        let st = self.filter.status();
        let new = st.resets != self.seen_resets;
        self.seen_resets = st.resets;
        (new && self.kind == Some(FixKind::Absolute)).then_some(st.last_reset_delta)
    }

    /// A barometer reading (NED down, m, σ `sigma` m) of `t_us`.
    pub fn height(&mut self, t_us: u64, down: f32, sigma: f32) -> Fusion {
        self.filter.fuse_height(t_us, down, sigma)
    }

    /// `true` while the controller is given the filter's estimate: initialised, a position
    /// fused within [`NAV_TIMEOUT_US`], the horizontal σ within [`NAV_MAX_SIGMA_M`] and every σ
    /// a number (a NaN σ: the covariance is broken, the margins are not known).
    pub fn usable(&self, now_us: u64) -> bool {
        let Some(age) = self.filter.position_age_us(now_us) else { return false };
        let s = self.filter.status().sigma_p;
        let finite = s.x.is_finite() && s.y.is_finite() && s.z.is_finite();
        self.filter.is_initialised() && age <= NAV_TIMEOUT_US && finite && s.x.max(s.y) <= NAV_MAX_SIGMA_M
    }

    /// The controller's fix at `now_us`; `None` before the first fix and in the failsafe
    /// (see the module docs).
    pub fn controller_fix(&self, now_us: u64) -> Option<PositionFix> {
        if !self.usable(now_us) {
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

    /// The filter (read-only).
    pub fn filter(&self) -> &NavFilter {
        &self.filter
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOISE: SourceNoise = SourceNoise { position: 0.5, velocity: 0.1 };

    fn hover(aid: &mut NavAid, from_us: u64, to_us: u64) {
        let level = Euler { roll: 0.0, pitch: 0.0, yaw: 0.0 };
        let mut t = from_us;
        while t <= to_us {
            aid.imu(t, &Vec3::new(0.0, 0.0, -crate::frame::GRAVITY), &level);
            t += 1_000;
        }
    }

    fn fix(t_us: u64) -> PositionFix {
        PositionFix { t_us, position: Vec3::new(1.0, 2.0, -3.0), velocity: Vec3::zeros(), yaw: Some(0.3) }
    }

    #[test]
    fn the_controller_gets_the_estimate_until_the_timeout_then_none() {
        let mut aid = NavAid::new(NavParams::default());
        assert_eq!(aid.controller_fix(0), None);
        hover(&mut aid, 0, 10_000);
        // Three agreeing fixes initialise (NavParams::init_fixes).
        assert_eq!(aid.fix(&fix(3_000), NOISE, FixKind::Absolute), Fusion::Pending);
        assert_eq!(aid.controller_fix(4_000), None);
        assert_eq!(aid.fix(&fix(4_000), NOISE, FixKind::Absolute), Fusion::Pending);
        assert_eq!(aid.fix(&fix(5_000), NOISE, FixKind::Absolute), Fusion::Initialised);
        hover(&mut aid, 11_000, 100_000);
        let f = aid.controller_fix(100_000).map(|f| (f.t_us, f.yaw));
        assert_eq!(f, Some((100_000, Some(0.3))));
        assert!(aid.controller_fix(5_000 + NAV_TIMEOUT_US).is_some());
        assert_eq!(aid.controller_fix(5_001 + NAV_TIMEOUT_US), None);
    }

    /// A source that jumps 4 m east: an absolute one's reset is handed on once, with its
    /// delta; a relative one's (its frame offset moves, the estimate does not) never.
    #[test]
    fn an_absolute_reset_is_handed_on_once_a_relative_one_never() {
        for kind in [FixKind::Absolute, FixKind::Relative] {
            let mut aid = NavAid::new(NavParams::default());
            hover(&mut aid, 0, 10_000);
            for t in [3_000, 4_000, 5_000] {
                aid.fix(&fix(t), NOISE, kind);
            }
            let mut t = 10_000;
            let mut handed = [None; 12];
            for h in handed.iter_mut() {
                hover(&mut aid, t + 1_000, t + 100_000);
                t += 100_000;
                let mut f = fix(t - 50_000);
                f.position.y += 4.0;
                aid.fix(&f, NOISE, kind);
                *h = aid.take_reset();
            }
            assert_eq!(aid.status().resets, 1, "{kind:?}");
            let n = handed.iter().filter(|d| d.is_some()).count();
            if kind == FixKind::Absolute {
                assert_eq!(n, 1, "{handed:?}");
                let d = handed.iter().flatten().next().copied().unwrap_or_default();
                assert!((d.y - 4.0).abs() < 0.5 && d.x.abs() < 0.1, "{d:?}");
            } else {
                assert_eq!(n, 0, "{handed:?}");
            }
        }
    }
}
