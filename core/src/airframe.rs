//! Airframe description shared by the controller (mixer) and the simulator's
//! plant, so the rotor layout is defined exactly once.
//!
//! ## Rotor layout (X quadrotor, PX4 numbering), body frame FRD
//! | rotor | index | position (x fwd, y right) | spin (seen from above) | yaw torque sign |
//! |-------|-------|---------------------------|------------------------|-----------------|
//! | 1     | 0     | front-right (+a, +a)      | CCW                    | +1              |
//! | 2     | 1     | rear-left   (−a, −a)      | CCW                    | +1              |
//! | 3     | 2     | front-left  (+a, −a)      | CW                     | −1              |
//! | 4     | 3     | rear-right  (−a, +a)      | CW                     | −1              |
//!
//! with `a = arm_length / √2`. A rotor spinning CCW seen from above is driven
//! by a CCW motor torque; its reaction on the body is CW seen from above, which
//! is **positive** yaw in FRD (z down). Each rotor's thrust `f_i` (N) acts along
//! body −z; its drag torque about body z is `sign_i · κ · f_i` with
//! `κ = k_m / k_f` (m).
//!
//! ## Motor command
//! A motor command ("throttle") `c ∈ [0, 1]` is proportional to the commanded
//! rotor speed: `ω_cmd = c · ω_max`, so `f = k_f ω² = c² · f_max`. This is the
//! model of an RPM-controlled ESC (DShot with bidirectional RPM) and what
//! `HIL_ACTUATOR_CONTROLS.controls[0..4]` carries in processor-in-the-loop.

use crate::param_decl::{field, Has, Param};

/// Yaw-torque sign of each rotor (index 0..4 = rotors 1..4): +1 for CCW rotors.
pub const ROTOR_YAW_SIGN: [f32; 4] = [1.0, 1.0, -1.0, -1.0];

/// Unit position of each rotor in the body FRD x-y plane, to be multiplied by
/// `arm_length / √2` (index 0..4 = rotors 1..4).
pub const ROTOR_XY_UNIT: [[f32; 2]; 4] = [[1.0, 1.0], [-1.0, -1.0], [1.0, -1.0], [-1.0, 1.0]];

/// Physical parameters the controller needs to know about the vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Airframe {
    /// Mass, kg. Paper: 0.5.
    pub mass: f32,
    /// Principal moments of inertia (Ix, Iy, Iz) about body FRD axes, kg·m². Paper: (0.0019, 0.0019, 0.0033).
    pub inertia: [f32; 3],
    /// Distance from the centre of mass to each rotor axis, m. Default 0.13.
    pub arm_length: f32,
    /// Maximum thrust of one rotor (at `ω_max`), N. Default 3.07 (thrust-to-weight ≈ 2.5).
    pub rotor_thrust_max: f32,
    /// Rotor drag-torque to thrust ratio `κ = k_m / k_f`, m. Default 0.016.
    pub torque_to_thrust: f32,
}

impl Default for Airframe {
    fn default() -> Self {
        Airframe {
            mass: 0.5,
            inertia: [0.0019, 0.0019, 0.0033],
            arm_length: 0.13,
            rotor_thrust_max: 3.07,
            torque_to_thrust: 0.016,
        }
    }
}

impl Airframe {
    /// The vehicle's parameters (`crate::params`, MAVLink `param_index` order).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 7] {
        [
            Param::new("VEH_MASS", "Vehicle", "kg", (0.07, 50.0), 3, field!(mass),
                "Vehicle mass; hover thrust mass*g must stay below THR_MAX"),
            Param::new("VEH_IXX", "Vehicle", "kg m^2", (1e-5, 10.0), 5, field!(inertia[0]),
                "Moment of inertia about body x (roll)"),
            Param::new("VEH_IYY", "Vehicle", "kg m^2", (1e-5, 10.0), 5, field!(inertia[1]),
                "Moment of inertia about body y (pitch)"),
            Param::new("VEH_IZZ", "Vehicle", "kg m^2", (1e-5, 10.0), 5, field!(inertia[2]),
                "Moment of inertia about body z (yaw)"),
            Param::new("VEH_ARM", "Vehicle", "m", (0.02, 2.0), 3, field!(arm_length),
                "Distance from the centre of mass to each rotor axis"),
            Param::new("VEH_ROTOR_TMAX", "Vehicle", "N", (0.1, 500.0), 2, field!(rotor_thrust_max),
                "Largest thrust of one rotor; 4x it must be at least THR_MAX"),
            Param::new("VEH_KAPPA", "Vehicle", "m", (1e-4, 0.5), 4, field!(torque_to_thrust),
                "Rotor drag-torque to thrust ratio k_m/k_f"),
        ]
    }
}

impl Airframe {
    /// Rotor positions in the body FRD x-y plane, m (index 0..4 = rotors 1..4).
    pub fn rotor_positions(&self) -> [[f32; 2]; 4] {
        let a = self.arm_length * core::f32::consts::FRAC_1_SQRT_2;
        ROTOR_XY_UNIT.map(|[x, y]| [x * a, y * a])
    }
}
