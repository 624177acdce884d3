//! IMU calibration: what is applied to every raw IMU sample before the estimator
//! ([`ImuCorrection`]: accelerometer offset and scale, board orientation, level-horizon trim),
//! the parameters that hold it ([`SensorCal`], the `CAL_*` / `SENS_BOARD_ROT` parameters of
//! [`crate::params`]), the accelerometer six-position calibration ([`accel`]) and the
//! level-horizon trim ([`level_trim`]).
//!
//! **Gyro bias** is not calibrated here: the attitude estimator already learns it at rest
//! (`inner::estimator`, `rest_bias_tau_s`: while disarmed and not rotating the bias is pulled
//! to the gyro reading with a 1 s time constant) and in flight (the Mahony integral), so
//! MAV_CMD_PREFLIGHT_CALIBRATION's gyro request only has to check the vehicle is still.
//!
//! ## The correction (PX4's order)
//! `accel_body = R_trim · R_board · ((raw − offset) ⊙ scale)`, `gyro_body = R_trim · R_board · raw`:
//! offset and scale are per sensor axis (the six-position result), `R_board` is the
//! sensor-to-body rotation [`BoardRotation`] (PX4 `SENS_BOARD_ROT` codes 0..=15: yaw in 45°
//! steps, optionally after a roll of 180°), `R_trim = R_y(pitch) R_x(roll)` the level trim.
//! The rotation matrix is built once ([`ImuCorrection::new`]); [`ImuCorrection::apply`] is two
//! 3×3 products (bounded). A sample that is not finite is passed on unchanged (the estimator
//! refuses it with its own error).
//!
//! May import: `frame`, `fmath`, `msg` (the IMU sample).

pub mod accel;

use crate::fmath;
use crate::frame::GRAVITY;
use crate::msg::ImuSample;
use crate::param_decl::{access, field, Access, Has, Param};
use crate::Vec3;
use nalgebra::Matrix3;

/// The sensor-to-body orientation of the IMU (PX4 `SENS_BOARD_ROT` codes 0..=15).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct BoardRotation(u8);

impl BoardRotation {
    /// Highest supported code: 0..=7 yaw k·45°, 8..=15 roll 180° then yaw (k−8)·45°
    /// (12 = pitch 180°).
    pub const MAX_CODE: u8 = 15;
    /// No rotation.
    pub const NONE: Self = Self(0);

    /// From the parameter code (`None` above [`Self::MAX_CODE`]).
    pub fn from_code(code: u8) -> Option<Self> {
        (code <= Self::MAX_CODE).then_some(Self(code))
    }

    /// The parameter code.
    pub fn code(self) -> u8 {
        self.0
    }

    /// Name of a code (ground-station labels).
    pub fn name(code: i32) -> Option<&'static str> {
        const NAMES: [&str; 16] = [
            "none",
            "yaw 45",
            "yaw 90",
            "yaw 135",
            "yaw 180",
            "yaw 225",
            "yaw 270",
            "yaw 315",
            "roll 180",
            "roll 180, yaw 45",
            "roll 180, yaw 90",
            "roll 180, yaw 135",
            "pitch 180",
            "roll 180, yaw 225",
            "roll 180, yaw 270",
            "roll 180, yaw 315",
        ];
        usize::try_from(code).ok().and_then(|c| NAMES.get(c).copied())
    }

    /// Sensor → body rotation matrix (exact for the 90° multiples).
    pub fn matrix(self) -> Matrix3<f32> {
        const H: f32 = core::f32::consts::FRAC_1_SQRT_2;
        const CS: [(f32, f32); 8] =
            [(1.0, 0.0), (H, H), (0.0, 1.0), (-H, H), (-1.0, 0.0), (-H, -H), (0.0, -1.0), (H, -H)];
        let (c, s) = CS[usize::from(self.0 % 8)];
        let yaw = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        if self.0 >= 8 {
            yaw * Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0)
        } else {
            yaw
        }
    }
}

/// The stored calibration (parameters `CAL_ACC0_*`, `CAL_TRIM_*`, `SENS_BOARD_ROT`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorCal {
    /// Accelerometer offset per sensor axis, m/s². Default 0.
    pub accel_offset: Vec3,
    /// Accelerometer scale per sensor axis. Default 1.
    pub accel_scale: Vec3,
    /// IMU orientation on the board. Default none.
    pub board_rotation: BoardRotation,
    /// Level-horizon trim, roll, rad. Default 0.
    pub trim_roll: f32,
    /// Level-horizon trim, pitch, rad. Default 0.
    pub trim_pitch: f32,
}

impl Default for SensorCal {
    fn default() -> Self {
        Self {
            accel_offset: Vec3::zeros(),
            accel_scale: Vec3::new(1.0, 1.0, 1.0),
            board_rotation: BoardRotation::NONE,
            trim_roll: 0.0,
            trim_pitch: 0.0,
        }
    }
}

impl SensorCal {
    /// The accelerometer calibration, level trim and board rotation (issue 22;
    /// `crate::params`, MAVLink `param_index` order).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 9] {
        [
            acc("CAL_ACC0_XOFF", false, field!(accel_offset.x),
                "Accelerometer offset, sensor x"),
            acc("CAL_ACC0_YOFF", false, field!(accel_offset.y),
                "Accelerometer offset, sensor y"),
            acc("CAL_ACC0_ZOFF", false, field!(accel_offset.z),
                "Accelerometer offset, sensor z"),
            acc("CAL_ACC0_XSCALE", true, field!(accel_scale.x),
                "Accelerometer scale, sensor x"),
            acc("CAL_ACC0_YSCALE", true, field!(accel_scale.y),
                "Accelerometer scale, sensor y"),
            acc("CAL_ACC0_ZSCALE", true, field!(accel_scale.z),
                "Accelerometer scale, sensor z"),
            Param::new("CAL_TRIM_ROLL", "Sensors", "rad", (-TRIM_MAX, TRIM_MAX), 4, field!(trim_roll),
                "Level-horizon trim, roll"),
            Param::new("CAL_TRIM_PITCH", "Sensors", "rad", (-TRIM_MAX, TRIM_MAX), 4, field!(trim_pitch),
                "Level-horizon trim, pitch"),
            Param::new("SENS_BOARD_ROT", "Sensors", "", (0.0, BoardRotation::MAX_CODE as f32), 0,
                access!(|s| f32::from(s.board_rotation.code()), |s, v| {
                    if let Some(r) = BoardRotation::from_code(v as u8) {
                        s.board_rotation = r;
                    }
                }),
                "IMU orientation on the board (PX4 SENS_BOARD_ROT codes 0-15)").code(BoardRotation::name),
        ]
    }
}

/// An accelerometer calibration parameter (`CAL_ACC0_*`), per sensor axis: a scale or an
/// offset, m/s².
const fn acc<P>(name: &'static str, scale: bool, access: Access<P>, description: &'static str) -> Param<P> {
    let (unit, range) =
        if scale { ("", ACCEL_SCALE_RANGE) } else { ("m/s^2", (-ACCEL_OFFSET_MAX, ACCEL_OFFSET_MAX)) };
    Param::new(name, "Sensors", unit, range, 4, access, description)
}

/// Largest accelerometer offset the parameters allow, m/s².
pub const ACCEL_OFFSET_MAX: f32 = 5.0;
/// Accelerometer scale range the parameters allow.
pub const ACCEL_SCALE_RANGE: (f32, f32) = (0.5, 1.5);
/// Largest level trim, rad (about 20°).
pub const TRIM_MAX: f32 = 0.35;

/// [`SensorCal`] prepared for the per-sample work.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuCorrection {
    rotation: Matrix3<f32>,
    offset: Vec3,
    scale: Vec3,
}

impl Default for ImuCorrection {
    fn default() -> Self {
        Self::new(&SensorCal::default())
    }
}

impl ImuCorrection {
    /// Build the rotation once.
    pub fn new(cal: &SensorCal) -> Self {
        Self {
            rotation: trim_matrix(cal.trim_roll, cal.trim_pitch) * cal.board_rotation.matrix(),
            offset: cal.accel_offset,
            scale: cal.accel_scale,
        }
    }

    /// Raw sensor-frame sample → body-frame sample (non-finite samples pass unchanged).
    pub fn apply(&self, raw: &ImuSample) -> ImuSample {
        if !(crate::frame::is_finite3(&raw.gyro) && crate::frame::is_finite3(&raw.accel)) {
            return *raw;
        }
        ImuSample {
            gyro: self.rotation * raw.gyro,
            accel: self.rotation * (raw.accel - self.offset).component_mul(&self.scale),
        }
    }

    /// Only the accelerometer offset and scale (sensor frame), as the six-position
    /// calibration sees it.
    pub fn accel_sensor(&self, raw: &Vec3) -> Vec3 {
        (raw - self.offset).component_mul(&self.scale)
    }
}

/// `R_y(pitch) R_x(roll)`.
fn trim_matrix(roll: f32, pitch: f32) -> Matrix3<f32> {
    let (sr, cr) = fmath::sincosf(roll);
    let (sp, cp) = fmath::sincosf(pitch);
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr);
    let ry = Matrix3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp);
    ry * rx
}

/// Why a level-horizon trim was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrimError {
    /// The mean specific force is not finite or not within 10 % of g (moving, or not calibrated).
    NotAtRest,
    /// The board is tilted more than [`TRIM_MAX`] (not a trim: set the board rotation).
    TooLarge,
}

/// Level-horizon trim from the mean body-frame specific force measured with the vehicle
/// standing level (board rotation and accelerometer calibration applied, **no** trim): the
/// roll and pitch that map it onto `(0, 0, −|a|)`. Add them to the stored trim when the
/// mean was taken with a trim in effect.
pub fn level_trim(mean_accel: &Vec3) -> Result<(f32, f32), TrimError> {
    let n = fmath::norm3(mean_accel);
    if !n.is_finite() || (n - GRAVITY).abs() > 0.1 * GRAVITY {
        return Err(TrimError::NotAtRest);
    }
    let (ax, ay, az) = (mean_accel.x, mean_accel.y, mean_accel.z);
    let roll = libm::atan2f(-ay, -az);
    let pitch = libm::atan2f(ax, fmath::hypotf(ay, az));
    if roll.abs() > TRIM_MAX || pitch.abs() > TRIM_MAX {
        return Err(TrimError::TooLarge);
    }
    Ok((roll, pitch))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Vec3, b: &Vec3, tol: f32) -> bool {
        (a - b).norm() < tol
    }

    #[test]
    fn board_rotations_are_proper_and_match_px4() {
        for code in 0..=BoardRotation::MAX_CODE {
            let m = BoardRotation::from_code(code).unwrap().matrix();
            assert!((m.determinant() - 1.0).abs() < 1e-5, "{code}");
            assert!((m * m.transpose() - Matrix3::identity()).norm() < 1e-5);
            assert!(BoardRotation::name(i32::from(code)).is_some());
        }
        assert!(BoardRotation::from_code(16).is_none());
        // Yaw 90: the sensor's x axis points to the body's right (y).
        let m = BoardRotation::from_code(2).unwrap().matrix();
        assert!(close(&(m * Vec3::x()), &Vec3::y(), 1e-6));
        // Roll 180: sensor z up, y left.
        let m = BoardRotation::from_code(8).unwrap().matrix();
        assert!(close(&(m * Vec3::z()), &-Vec3::z(), 1e-6) && close(&(m * Vec3::y()), &-Vec3::y(), 1e-6));
        // Pitch 180 (12): x and z flip.
        let m = BoardRotation::from_code(12).unwrap().matrix();
        assert!(close(&(m * Vec3::x()), &-Vec3::x(), 1e-6) && close(&(m * Vec3::z()), &-Vec3::z(), 1e-6));
    }

    #[test]
    fn correction_applies_offset_scale_then_rotation() {
        let cal = SensorCal {
            accel_offset: Vec3::new(0.2, -0.1, 0.3),
            accel_scale: Vec3::new(1.02, 0.98, 1.01),
            board_rotation: BoardRotation::from_code(4).unwrap(), // yaw 180
            ..Default::default()
        };
        let c = ImuCorrection::new(&cal);
        let raw = ImuSample { gyro: Vec3::new(0.1, 0.2, 0.3), accel: Vec3::new(1.2, 0.9, -9.5) };
        let out = c.apply(&raw);
        let fixed = Vec3::new(1.0 * 1.02, 1.0 * 0.98, -9.8 * 1.01);
        assert!(close(&out.accel, &Vec3::new(-fixed.x, -fixed.y, fixed.z), 1e-4));
        assert!(close(&out.gyro, &Vec3::new(-0.1, -0.2, 0.3), 1e-6));
        let bad = ImuSample { gyro: Vec3::new(f32::NAN, 0.0, 0.0), accel: Vec3::zeros() };
        assert_eq!(c.apply(&bad).gyro.x.to_bits(), f32::NAN.to_bits());
    }

    #[test]
    fn level_trim_levels_a_tilted_board() {
        for (roll, pitch) in [(0.05f32, -0.03f32), (-0.2, 0.1), (0.0, 0.0), (0.3, 0.3)] {
            // A board mounted with this tilt measures gravity as R_trimᵀ·(0, 0, −g).
            let m = trim_matrix(roll, pitch);
            let meas = m.transpose() * Vec3::new(0.0, 0.0, -GRAVITY);
            let (r, p) = level_trim(&meas).unwrap();
            assert!((r - roll).abs() < 1e-4 && (p - pitch).abs() < 1e-4, "{roll} {pitch}: {r} {p}");
            let c = ImuCorrection::new(&SensorCal { trim_roll: r, trim_pitch: p, ..Default::default() });
            let out = c.apply(&ImuSample { gyro: Vec3::zeros(), accel: meas });
            assert!(close(&out.accel, &Vec3::new(0.0, 0.0, -GRAVITY), 1e-3));
        }
        assert_eq!(level_trim(&Vec3::new(0.0, 0.0, -5.0)), Err(TrimError::NotAtRest));
        assert_eq!(level_trim(&Vec3::new(f32::NAN, 0.0, -9.8)), Err(TrimError::NotAtRest));
        let tilted = trim_matrix(0.5, 0.0).transpose() * Vec3::new(0.0, 0.0, -GRAVITY);
        assert_eq!(level_trim(&tilted), Err(TrimError::TooLarge));
    }
}
