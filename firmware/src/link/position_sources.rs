//! External position sources other than ODOMETRY (issue 39): GPS_INPUT (232) and
//! VISION_POSITION_ESTIMATE (102) converted **once, here**, into the core's position fix
//! (world frame = local NED around [`parapet_core::wire::geo::ORIGIN`], `docs/navigation.md`
//! § Firmware inputs), and the source monitor that tells the ground station which source
//! feeds the vehicle ([`SourceMonitor`]: STATUSTEXT on a switch and on a loss, not for the
//! first source).
//!
//! * **GPS_INPUT**: latitude/longitude (1e-7 °) and altitude (m AMSL) → NED with
//!   [`parapet_core::wire::geo::global_to_ned`] (flat earth around the origin; positions beyond its
//!   10 km range refused); velocity `vn, ve, vd` is already NED; yaw (cdeg, 0 = none, 36000 =
//!   north) → rad. Refused: `fix_type` below 3D, altitude or horizontal velocity flagged as
//!   ignored (the fix path needs both), a vertical velocity flagged as ignored is taken as 0.
//! * **VISION_POSITION_ESTIMATE**: `x, y, z` already local NED, `yaw` rad. The message has no
//!   velocity: the fix's velocity is the difference of two consecutive estimates
//!   ([`VisionVelocity`]), so the first one, the first after a `reset_counter` change and
//!   the first after a gap longer than [`VISION_MAX_GAP_US`] are held back (not refused, not
//!   forwarded).
//!
//! Every fix is checked before it goes on: non-finite values, a position farther than
//! [`parapet_core::wire::geo::MAX_RANGE_M`] from the origin, a speed above [`MAX_FIX_SPEED`] and,
//! on the lockstep link (message time = firmware time), a fix older than [`MAX_FIX_AGE_US`]
//! are refused and counted ([`FixRefusal`], `LinkStats::position_rejected`).
//!
//! * **ODOMETRY of a VIO** (`estimator_type` VIO or VISION, [`odometry_is_vision`]): converted
//!   as every ODOMETRY (`crate::link::inputs::odometry_fix`), σ from its covariances
//!   ([`odometry_noise`]), to the filter as a relative source; other ODOMETRY (motion capture)
//!   is not a source of this module.
//!
//! The fixes go to the navigation filter (`Autopilot::navigation_fix`,
//! [`crate::app::navigation`]) with the σ they state ([`gps_input_noise`], [`vision_noise`]):
//! GPS_INPUT as an absolute source, VISION_POSITION_ESTIMATE and a VIO's ODOMETRY as relative
//! ones (their frame may jump). Other ODOMETRY stays on the latest-fix path (motion capture).
//!
//! Owns: the conversions, the checks and [`SourceMonitor`]; the dispatcher's handling of these
//! fixes (`impl Router`) is [`crate::link::source_dispatch`], apart so that the router may
//! import this module without a cycle. May import: `parapet_core`, the dialect, [`crate::app`]
//! (the boundary types), [`parapet_core::wire::geo`]. No allocation, no panics.

use crate::app::autopilot::{PositionFix, SourceNoise};
use crate::link::dialect::{
    GpsFixType, GpsInputIgnoreFlags, MavEstimatorType, GPS_INPUT_DATA, ODOMETRY_DATA,
    VISION_POSITION_ESTIMATE_DATA,
};
use parapet_core::wire::geo::{global_to_ned, AltRef, MAX_RANGE_M};
use parapet_core::Vec3;

/// Fastest speed a fix may report, m/s (a multirotor's fix beyond it is a bad value).
pub const MAX_FIX_SPEED: f32 = 50.0;
/// Oldest fix accepted on the lockstep link (message time = firmware time), µs.
pub const MAX_FIX_AGE_US: u64 = 1_000_000;
/// Longest gap between two vision estimates whose difference is taken as the velocity, µs.
pub const VISION_MAX_GAP_US: u64 = 500_000;
/// Time without any accepted fix after which the source is reported lost, µs.
pub const SOURCE_LOSS_US: u64 = 1_000_000;

/// Why a fix was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FixRefusal {
    /// NaN or infinite position, velocity or yaw.
    NonFinite,
    /// Position beyond the local frame's range, or speed above [`MAX_FIX_SPEED`].
    OutOfRange,
    /// Older than [`MAX_FIX_AGE_US`].
    Stale,
    /// GPS_INPUT without a 3D fix, or with the altitude or horizontal velocity ignored.
    NoFix,
}

/// σ of a GPS_INPUT that states no accuracy (PX4 EKF2's `EKF2_GPS_P_NOISE`, `EKF2_GPS_V_NOISE`).
pub const GPS_DEFAULT_NOISE: SourceNoise = SourceNoise { position: 0.5, velocity: 0.3 };
/// σ of a VISION_POSITION_ESTIMATE without a covariance (position: PX4's `EKF2_EVP_NOISE`;
/// velocity: the difference of two estimates is noisier than a measured one).
pub const VISION_DEFAULT_NOISE: SourceNoise = SourceNoise { position: 0.1, velocity: 0.3 };
use parapet_core::wire::codes::sigma_of_variance;
pub use parapet_core::wire::codes::MIN_SIGMA;

fn stated(x: f32, ignored: bool, default: f32) -> f32 {
    if ignored || !x.is_finite() || x <= 0.0 {
        default
    } else {
        x.max(MIN_SIGMA)
    }
}

/// The σ of a GPS_INPUT's fix: `horiz_accuracy` and `speed_accuracy` when given (not flagged
/// as ignored, finite, > 0; floored at [`MIN_SIGMA`]), else [`GPS_DEFAULT_NOISE`].
pub fn gps_input_noise(m: &GPS_INPUT_DATA) -> SourceNoise {
    let f = m.ignore_flags;
    SourceNoise {
        position: stated(
            m.horiz_accuracy,
            f.contains(GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_HORIZONTAL_ACCURACY),
            GPS_DEFAULT_NOISE.position,
        ),
        velocity: stated(
            m.speed_accuracy,
            f.contains(GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_SPEED_ACCURACY),
            GPS_DEFAULT_NOISE.velocity,
        ),
    }
}

/// The σ of a VISION_POSITION_ESTIMATE's fix: √ of the x variance (`covariance[0]`) when
/// given, else [`VISION_DEFAULT_NOISE`]; the velocity σ is always the default.
pub fn vision_noise(m: &VISION_POSITION_ESTIMATE_DATA) -> SourceNoise {
    let position = sigma_of_variance(m.covariance[0], VISION_DEFAULT_NOISE.position);
    SourceNoise { position, velocity: VISION_DEFAULT_NOISE.velocity }
}

/// `true` for an ODOMETRY of a visual(-inertial) odometry (`estimator_type` VIO or VISION): it
/// goes to the navigation filter as a relative source, like VISION_POSITION_ESTIMATE. Any other
/// estimator (motion capture, unknown: what the PIL host and a motion-capture lab send) keeps
/// the latest-fix path.
pub fn odometry_is_vision(m: &ODOMETRY_DATA) -> bool {
    matches!(
        m.estimator_type,
        MavEstimatorType::MAV_ESTIMATOR_TYPE_VIO | MavEstimatorType::MAV_ESTIMATOR_TYPE_VISION
    )
}

/// The σ of a VIO's ODOMETRY: √ of the x variances (`pose_covariance[0]`,
/// `velocity_covariance[0]`) when given (finite, > 0; floored at [`MIN_SIGMA`]), else
/// [`VISION_DEFAULT_NOISE`]'s.
pub fn odometry_noise(m: &ODOMETRY_DATA) -> SourceNoise {
    SourceNoise {
        position: sigma_of_variance(m.pose_covariance[0], VISION_DEFAULT_NOISE.position),
        velocity: sigma_of_variance(m.velocity_covariance[0], VISION_DEFAULT_NOISE.velocity),
    }
}

/// Which message fed the last accepted fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// ODOMETRY (331).
    Odometry,
    /// GPS_INPUT (232).
    Gps,
    /// VISION_POSITION_ESTIMATE (102).
    Vision,
}

impl Source {
    /// The name in the STATUSTEXT.
    pub const fn name(self) -> &'static str {
        match self {
            Source::Odometry => "ODOMETRY",
            Source::Gps => "GPS_INPUT",
            Source::Vision => "VISION_POSITION_ESTIMATE",
        }
    }
}

/// The checks every fix passes (see the module docs); `age_us` the fix's age on the lockstep
/// link (`None` when the arrival time stamps it).
pub fn check_fix(fix: &PositionFix, age_us: Option<u64>) -> Result<(), FixRefusal> {
    let finite = fix.position.iter().chain(fix.velocity.iter()).all(|x| x.is_finite());
    if !finite || fix.yaw.is_some_and(|y| !y.is_finite()) {
        return Err(FixRefusal::NonFinite);
    }
    let far = fix.position.iter().any(|x| x.abs() > MAX_RANGE_M);
    if far || fix.velocity.norm() > MAX_FIX_SPEED {
        return Err(FixRefusal::OutOfRange);
    }
    if age_us.is_some_and(|a| a > MAX_FIX_AGE_US) {
        return Err(FixRefusal::Stale);
    }
    Ok(())
}

/// GPS_INPUT → a fix of `t_us` (not yet [`check_fix`]ed).
pub fn gps_input_fix(m: &GPS_INPUT_DATA, t_us: u64) -> Result<PositionFix, FixRefusal> {
    let needed =
        GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_ALT | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VEL_HORIZ;
    if (m.fix_type as u8) < (GpsFixType::GPS_FIX_TYPE_3D_FIX as u8) || m.ignore_flags.intersects(needed) {
        return Err(FixRefusal::NoFix);
    }
    if !m.alt.is_finite() {
        return Err(FixRefusal::NonFinite);
    }
    let position = global_to_ned(m.lat, m.lon, m.alt, AltRef::Amsl).map_err(|_| FixRefusal::OutOfRange)?;
    let vd =
        if m.ignore_flags.contains(GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VEL_VERT) { 0.0 } else { m.vd };
    let yaw = parapet_core::wire::codes::gps_input_yaw(m.yaw);
    Ok(PositionFix { t_us, position, velocity: Vec3::new(m.vn, m.ve, vd), yaw })
}

/// The velocity of VISION_POSITION_ESTIMATE: the previous estimate (time, position, reset
/// counter) to difference against.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VisionVelocity {
    last: Option<(u64, Vec3, u8)>,
}

impl VisionVelocity {
    /// No estimate yet.
    pub const fn new() -> Self {
        Self { last: None }
    }

    /// VISION_POSITION_ESTIMATE of `t_us` → a fix (not yet [`check_fix`]ed); `Ok(None)` while
    /// it is held back (see the module docs). Non-finite positions are refused and not kept.
    pub fn fix(
        &mut self,
        m: &VISION_POSITION_ESTIMATE_DATA,
        t_us: u64,
    ) -> Result<Option<PositionFix>, FixRefusal> {
        let p = Vec3::new(m.x, m.y, m.z);
        if !p.iter().all(|x| x.is_finite()) {
            return Err(FixRefusal::NonFinite);
        }
        let prev = self.last.replace((t_us, p, m.reset_counter));
        let Some((t0, p0, reset0)) = prev else { return Ok(None) };
        let dt = t_us.saturating_sub(t0);
        if reset0 != m.reset_counter || dt == 0 || dt > VISION_MAX_GAP_US {
            return Ok(None);
        }
        let velocity = (p - p0) / (dt as f32 * 1e-6);
        let yaw = m.yaw.is_finite().then_some(m.yaw);
        Ok(Some(PositionFix { t_us, position: p, velocity, yaw }))
    }
}

/// STATUSTEXT prefix when the position source changes (followed by its message name).
pub const POSITION_SOURCE_TEXT: &str = "Position source: ";
/// STATUSTEXT when the position source has fed no fix for [`SOURCE_LOSS_US`].
pub const POSITION_LOST_TEXT: &str = "Position source lost";

/// Which source feeds the vehicle, for the ground station.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SourceMonitor {
    current: Option<Source>,
    last_us: u64,
    lost: bool,
}

impl SourceMonitor {
    /// No source yet.
    pub const fn new() -> Self {
        Self { current: None, last_us: 0, lost: false }
    }

    /// A fix of `source` accepted at firmware time `now_us`: `Some(text)` when the source
    /// changed (another one than before, or one back after a loss); the first source is the
    /// vehicle's set-up, not announced (GPS_RAW_INT shows the fix).
    pub fn accepted(&mut self, source: Source, now_us: u64) -> Option<&'static str> {
        let changed = self.current.is_some_and(|c| c != source) || self.lost;
        self.current = Some(source);
        self.last_us = now_us;
        self.lost = false;
        changed.then_some(source.name())
    }

    /// At firmware time `now_us`: `true` once when the source has fed no fix for
    /// [`SOURCE_LOSS_US`].
    pub fn poll(&mut self, now_us: u64) -> bool {
        let due =
            self.current.is_some() && !self.lost && now_us.saturating_sub(self.last_us) > SOURCE_LOSS_US;
        self.lost |= due;
        due
    }

    /// The source of the last accepted fix.
    pub fn current(&self) -> Option<Source> {
        self.current
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::wire::geo::{LAT_E7_PER_M, LON_E7_PER_M, ORIGIN};

    fn gps(north_m: f32, east_m: f32, up_m: f32) -> GPS_INPUT_DATA {
        GPS_INPUT_DATA {
            fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
            lat: ORIGIN.0 + (north_m * LAT_E7_PER_M) as i32,
            lon: ORIGIN.1 + (east_m * LON_E7_PER_M) as i32,
            alt: ORIGIN.2 as f32 / 1000.0 + up_m,
            vn: 1.0,
            ve: -2.0,
            vd: 0.5,
            yaw: 9_000,
            ignore_flags: GpsInputIgnoreFlags::empty(), // the generated default is ALT
            ..Default::default()
        }
    }

    #[test]
    fn gps_input_becomes_a_local_ned_fix() {
        let f = gps_input_fix(&gps(10.0, -20.0, 5.0), 7).unwrap();
        assert!((f.position - Vec3::new(10.0, -20.0, -5.0)).norm() < 0.02, "{:?}", f.position);
        assert_eq!((f.t_us, f.velocity), (7, Vec3::new(1.0, -2.0, 0.5)));
        assert!(f.yaw.is_some_and(|y| (y - core::f32::consts::FRAC_PI_2).abs() < 1e-6));
        assert_eq!(check_fix(&f, Some(0)), Ok(()));
        let mut m = gps(0.0, 0.0, 0.0);
        m.yaw = 0;
        assert_eq!(gps_input_fix(&m, 0).map(|f| f.yaw), Ok(None), "0 = no yaw");
        m.ignore_flags = GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VEL_VERT;
        assert_eq!(gps_input_fix(&m, 0).map(|f| f.velocity.z), Ok(0.0));
    }

    #[test]
    fn bad_gps_input_is_refused() {
        let mut m = gps(0.0, 0.0, 0.0);
        m.fix_type = GpsFixType::GPS_FIX_TYPE_2D_FIX;
        assert_eq!(gps_input_fix(&m, 0), Err(FixRefusal::NoFix));
        let mut m = gps(0.0, 0.0, 0.0);
        m.ignore_flags = GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_ALT;
        assert_eq!(gps_input_fix(&m, 0), Err(FixRefusal::NoFix));
        let mut m = gps(0.0, 0.0, 0.0);
        m.alt = f32::NAN;
        assert_eq!(gps_input_fix(&m, 0), Err(FixRefusal::NonFinite));
        assert_eq!(gps_input_fix(&gps(20_000.0, 0.0, 0.0), 0), Err(FixRefusal::OutOfRange));
        let mut m = gps(0.0, 0.0, 0.0);
        m.vn = f32::INFINITY;
        let f = gps_input_fix(&m, 0).unwrap();
        assert_eq!(check_fix(&f, None), Err(FixRefusal::NonFinite));
        m.vn = 60.0;
        let f = gps_input_fix(&m, 0).unwrap();
        assert_eq!(check_fix(&f, None), Err(FixRefusal::OutOfRange));
        let f = gps_input_fix(&gps(0.0, 0.0, 0.0), 0).unwrap();
        assert_eq!(check_fix(&f, Some(MAX_FIX_AGE_US + 1)), Err(FixRefusal::Stale));
        assert_eq!(check_fix(&f, Some(MAX_FIX_AGE_US)), Ok(()));
    }

    fn vision(x: f32, reset: u8) -> VISION_POSITION_ESTIMATE_DATA {
        VISION_POSITION_ESTIMATE_DATA {
            x,
            y: 1.0,
            z: -2.0,
            yaw: 0.3,
            reset_counter: reset,
            ..Default::default()
        }
    }

    #[test]
    fn vision_velocity_is_the_difference_and_restarts_on_a_reset_or_gap() {
        let mut v = VisionVelocity::new();
        assert_eq!(v.fix(&vision(0.0, 0), 0), Ok(None), "first estimate held back");
        let f = v.fix(&vision(0.1, 0), 50_000).unwrap().unwrap();
        assert!((f.velocity - Vec3::new(2.0, 0.0, 0.0)).norm() < 1e-4, "{:?}", f.velocity);
        assert_eq!((f.position, f.yaw, f.t_us), (Vec3::new(0.1, 1.0, -2.0), Some(0.3), 50_000));
        assert_eq!(v.fix(&vision(5.0, 1), 100_000), Ok(None), "a reset: no velocity across it");
        assert!(v.fix(&vision(5.1, 1), 150_000).unwrap().is_some());
        assert_eq!(v.fix(&vision(5.2, 1), 150_000 + VISION_MAX_GAP_US + 1), Ok(None), "gap");
        assert_eq!(v.fix(&vision(f32::NAN, 1), 1_000_000), Err(FixRefusal::NonFinite));
    }

    #[test]
    fn the_monitor_reports_a_switch_and_a_loss_once() {
        let mut m = SourceMonitor::new();
        assert!(!m.poll(5_000_000), "no source yet: nothing lost");
        assert_eq!(m.accepted(Source::Gps, 0), None, "the first source is not announced");
        assert_eq!(m.accepted(Source::Gps, 100_000), None);
        assert!(!m.poll(100_000 + SOURCE_LOSS_US));
        assert!(m.poll(100_001 + SOURCE_LOSS_US));
        assert!(!m.poll(200_000 + SOURCE_LOSS_US), "once");
        assert_eq!(m.accepted(Source::Gps, 3_000_000), Some("GPS_INPUT"), "back after the loss");
        assert_eq!(m.accepted(Source::Vision, 3_100_000), Some("VISION_POSITION_ESTIMATE"));
        assert_eq!(m.current(), Some(Source::Vision));
    }
}
