//! Small codes carried in message fields, with their encoders and decoders.

use crate::cbf::Region;
use crate::safety::governor::GovernorCause;

/// Flight phase, carried as NAMED_VALUE_INT `PHASE` (the HEARTBEAT `custom_mode` carries the PX4
/// flight mode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u32)]
pub enum FlightPhase {
    /// Motors off.
    Disarmed = 0,
    /// Armed on the ground, motors idle.
    Idle = 1,
    /// Climbing to the takeoff height.
    Takeoff = 2,
    /// Holding position.
    Hover = 3,
    /// Flying the waypoint path.
    Mission = 4,
    /// Descending to land.
    Landing = 5,
    /// A failsafe owns the vehicle.
    Failsafe = 6,
}

impl FlightPhase {
    /// Every phase, in code order.
    pub const ALL: [FlightPhase; 7] = [
        FlightPhase::Disarmed,
        FlightPhase::Idle,
        FlightPhase::Takeoff,
        FlightPhase::Hover,
        FlightPhase::Mission,
        FlightPhase::Landing,
        FlightPhase::Failsafe,
    ];

    /// HEARTBEAT `custom_mode`.
    pub const fn code(self) -> u32 {
        self as u32
    }

    /// The phase of a HEARTBEAT `custom_mode`; `None` for unknown codes.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.code() == code)
    }
}

/// Failsafe codes (`NAMED_VALUE_INT FAILSAFE`).
pub mod failsafe {
    /// Braking to a stop (position data lost, filter fault).
    pub const BRAKE: u8 = 1;
    /// Landing in place (not commanded).
    pub const LAND: u8 = 2;
    /// Motors stopped.
    pub const MOTORS_OFF: u8 = 3;
}

/// `DEBUG_VECT CBF.y`: the filter region's code (see [`Region::code`]).
pub fn region_to_wire(r: Region) -> f32 {
    f32::from(r.code())
}

/// The region of a `DEBUG_VECT CBF.y`; non-finite or out-of-range values decode as
/// [`Region::Fault`] (a receiver must not invent a benign region).
pub fn region_from_wire(y: f32) -> Region {
    let code = if y.is_finite() { y.clamp(0.0, 4.0) as u8 } else { Region::Fault.code() };
    region_from_code(code).unwrap_or(Region::Fault)
}

/// The region with code `code`, if any.
pub fn region_from_code(code: u8) -> Option<Region> {
    Region::ALL.into_iter().find(|r| r.code() == code)
}

/// `DEBUG_VECT GOV` of the speed governor's limit (m/s, `+∞`/NaN: none), cause and whether it
/// acted: (limit or −1, the cause's code, 1 or 0).
pub fn governor_to_wire(limit: f32, cause: GovernorCause, active: bool) -> (f32, f32, f32) {
    let x = if limit.is_finite() && limit >= 0.0 { limit } else { -1.0 };
    (x, f32::from(cause as u8), if active { 1.0 } else { 0.0 })
}

/// The governor's (limit, cause, acted) of a `DEBUG_VECT GOV`: a negative or non-finite limit is
/// none; an unknown cause code decodes as [`GovernorCause::None`].
pub fn governor_from_wire(x: f32, y: f32, z: f32) -> (Option<f32>, GovernorCause, bool) {
    let limit = (x.is_finite() && x >= 0.0).then_some(x);
    let code = if y.is_finite() { y.clamp(0.0, 255.0) as u8 } else { 0 };
    (limit, GovernorCause::from_code(code).unwrap_or_default(), z == 1.0)
}

/// `DEBUG_VECT CBF.z`: the active obstacle id, −1 for none.
pub fn active_id_to_wire(id: Option<u16>) -> f32 {
    id.map_or(-1.0, f32::from)
}

/// The active obstacle id of a `DEBUG_VECT CBF.z` (negative or non-finite: none).
pub fn active_id_from_wire(z: f32) -> Option<u16> {
    (z >= 0.0 && z.is_finite()).then_some(z.min(f32::from(u16::MAX)) as u16)
}

/// `NAMED_VALUE_INT CBF_FLAGS`: bit 0 intervened, bit 1 unavoidable, bit 2 infeasible,
/// bits 8..15 the number of active barrier constraints.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CbfFlags {
    /// The filter changed the nominal command.
    pub intervened: bool,
    /// The obstacle cannot be avoided with the available acceleration.
    pub unavoidable: bool,
    /// The multi-barrier problem had no feasible solution.
    pub infeasible: bool,
    /// Barrier constraints active in the last step.
    pub n_constraints: u8,
}

impl CbfFlags {
    /// The wire value.
    pub fn encode(self) -> i32 {
        i32::from(self.intervened)
            | (i32::from(self.unavoidable) << 1)
            | (i32::from(self.infeasible) << 2)
            | (i32::from(self.n_constraints) << 8)
    }

    /// Decodes a wire value (other bits ignored).
    pub fn decode(v: i32) -> Self {
        Self {
            intervened: v & 1 != 0,
            unavoidable: v & 2 != 0,
            infeasible: v & 4 != 0,
            n_constraints: ((v >> 8) & 0xFF) as u8,
        }
    }
}

/// Smallest σ a position source's stated variance gives the navigation filter, m or m/s (a
/// noise-free source keeps the update well posed; the host's `fc/nav.rs` floors the scene's
/// noise the same way).
pub const MIN_SIGMA: f32 = 0.01;

/// The σ of a stated variance `var` (ODOMETRY's `pose_covariance[0]`, VISION_POSITION_ESTIMATE's
/// `covariance[0]`): `√var` floored at [`MIN_SIGMA`] when finite and > 0, else `default`. One
/// definition for the firmware's decoding and the PIL twin's.
pub fn sigma_of_variance(var: f32, default: f32) -> f32 {
    if var.is_finite() && var > 0.0 {
        libm::sqrtf(var).max(MIN_SIGMA)
    } else {
        default
    }
}

/// ODOMETRY `q` ([w, x, y, z], body → NED) of a level vehicle with heading `yaw` (rad).
pub fn odometry_quaternion(yaw: f32) -> [f32; 4] {
    let (s, c) = crate::fmath::sincosf(yaw / 2.0);
    [c, 0.0, 0.0, s]
}

/// Heading (ZYX yaw, rad, in (−π, π]) of an ODOMETRY `q` ([w, x, y, z], body → NED); `None`
/// when `q` is not finite or not close to unit norm (MAVLink: NaN or zeros = unknown).
pub fn odometry_yaw(q: [f32; 4]) -> Option<f32> {
    let [w, x, y, z] = q;
    let n2 = w * w + x * x + y * y + z * z;
    if !n2.is_finite() || !(0.25..=4.0).contains(&n2) {
        return None;
    }
    // atan2 is invariant to the common scale n², so no normalisation is needed.
    let yaw = libm::atan2f(2.0 * (w * z + x * y), n2 - 2.0 * (y * y + z * z));
    yaw.is_finite().then_some(yaw)
}

/// Heading of GPS_INPUT's `yaw` (cdeg, 0 = none, 36000 = north), rad in [0, 2π); `None` for 0.
pub fn gps_input_yaw(cdeg: u16) -> Option<f32> {
    (cdeg != 0).then(|| f32::from(cdeg % 36_000) * (core::f32::consts::PI / 18_000.0))
}

/// GPS_INPUT's `yaw` (cdeg, 1..=36000, 36000 = north) of the heading `yaw` (rad); 0 (none) when
/// not finite.
pub fn gps_input_yaw_cdeg(yaw: f32) -> u16 {
    if !yaw.is_finite() {
        return 0;
    }
    let c = (libm::roundf(yaw.to_degrees() * 100.0) as i32).rem_euclid(36_000) as u16;
    if c == 0 {
        36_000
    } else {
        c
    }
}

#[cfg(test)]
mod tests {
    /// Every cause and a limit, none and NaN round-trip through `DEBUG_VECT GOV`; bad codes
    /// decode as no cause.
    #[test]
    fn the_governor_round_trips_through_its_debug_vect() {
        for c in GovernorCause::ALL {
            for (limit, active) in [(2.5f32, true), (0.0, false)] {
                let (x, y, z) = governor_to_wire(limit, c, active);
                assert_eq!(governor_from_wire(x, y, z), (Some(limit), c, active));
            }
        }
        for none in [f32::INFINITY, f32::NAN, -3.0] {
            let (x, y, z) = governor_to_wire(none, GovernorCause::Range, false);
            assert_eq!(governor_from_wire(x, y, z), (None, GovernorCause::Range, false));
        }
        assert_eq!(governor_from_wire(1.0, 9.0, 0.0).1, GovernorCause::None);
        assert_eq!(governor_from_wire(1.0, f32::NAN, 0.0).1, GovernorCause::None);
    }
    use super::*;

    #[test]
    fn phase_codes_round_trip() {
        for p in FlightPhase::ALL {
            assert_eq!(FlightPhase::from_code(p.code()), Some(p));
        }
        assert_eq!(FlightPhase::from_code(7), None);
        assert_eq!(FlightPhase::Mission.code(), 4);
    }

    #[test]
    fn region_and_active_id_round_trip_and_bad_values_decode_as_fault_or_none() {
        for code in 0..=4u8 {
            let r = region_from_code(code).unwrap_or(Region::Fault);
            assert_eq!(region_from_wire(region_to_wire(r)), r);
        }
        assert_eq!(region_from_code(5), None);
        for (i, r) in Region::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(r.code()), i);
            assert_eq!(Region::NAMES[i], r.name());
        }
        assert_eq!(region_from_wire(f32::NAN), Region::Fault);
        assert_eq!(region_from_wire(9.0), Region::Fault);
        assert_eq!(active_id_from_wire(active_id_to_wire(Some(17))), Some(17));
        assert_eq!(active_id_from_wire(active_id_to_wire(None)), None);
        assert_eq!(active_id_from_wire(f32::NAN), None);
    }

    #[test]
    fn cbf_flags_round_trip() {
        let f = CbfFlags { intervened: true, unavoidable: false, infeasible: true, n_constraints: 3 };
        assert_eq!(f.encode(), 1 | 4 | (3 << 8));
        assert_eq!(CbfFlags::decode(f.encode()), f);
        assert_eq!(CbfFlags::decode(0), CbfFlags::default());
    }

    #[test]
    fn odometry_yaw_round_trip_and_unknown_quaternions() {
        for yaw in [0.0f32, 0.3, -1.2, 3.0, -3.1] {
            let got = odometry_yaw(odometry_quaternion(yaw));
            assert!(got.is_some_and(|g| (g - yaw).abs() < 1e-5), "{yaw} → {got:?}");
        }
        assert_eq!(odometry_yaw([1.0, 0.0, 0.0, 0.0]), Some(0.0));
        assert_eq!(odometry_yaw([0.0; 4]), None);
        assert_eq!(odometry_yaw([f32::NAN, 0.0, 0.0, 0.0]), None);
        // A rolled vehicle: yaw is still the ZYX heading (90° about down, then 30° roll).
        let (s, c) = (core::f32::consts::FRAC_PI_4.sin(), core::f32::consts::FRAC_PI_4.cos());
        let (sr, cr) = (0.15f32.sin(), 0.15f32.cos());
        let qz = [c, 0.0, 0.0, s];
        let qx = [cr, sr, 0.0, 0.0];
        let q = [
            qz[0] * qx[0] - qz[3] * qx[3],
            qz[0] * qx[1] + qz[1] * qx[0] + qz[2] * qx[3] - qz[3] * qx[2],
            qz[0] * qx[2] - qz[1] * qx[3] + qz[2] * qx[0] + qz[3] * qx[1],
            qz[0] * qx[3] + qz[1] * qx[2] - qz[2] * qx[1] + qz[3] * qx[0],
        ];
        let got = odometry_yaw(q);
        assert!(got.is_some_and(|g| (g - core::f32::consts::FRAC_PI_2).abs() < 1e-5), "{got:?}");
    }

    #[test]
    fn gps_input_yaw_round_trips_to_the_centidegree() {
        assert_eq!(gps_input_yaw(0), None);
        assert_eq!(gps_input_yaw(36_000), Some(0.0));
        assert_eq!(gps_input_yaw_cdeg(0.0), 36_000);
        assert_eq!(gps_input_yaw_cdeg(f32::NAN), 0);
        assert_eq!(gps_input_yaw_cdeg(-core::f32::consts::FRAC_PI_2), 27_000);
        for yaw in [0.3f32, 1.0, 3.1, -0.2, -3.1] {
            let back = gps_input_yaw(gps_input_yaw_cdeg(yaw)).unwrap();
            let d = (back - yaw).rem_euclid(2.0 * core::f32::consts::PI);
            assert!(d.min(2.0 * core::f32::consts::PI - d) < 1e-4, "{yaw} -> {back}");
        }
    }
}
