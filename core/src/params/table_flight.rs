//! Part of [`super::TABLE`]: the flight parameters: CBF filter and its plant-aware wrapping, tracking, mission speed, obstacle failsafe, vehicle, ground/ceiling barriers, perception memory (issues 1-19).
//!
//! Entries in MAVLink `param_index` order; [`super`] concatenates the parts. May import
//! what [`super`] may.

use super::*;

/// Entries of this part.
pub(super) const N: usize = 31;

/// This part's entries, in `param_index` order.
#[rustfmt::skip] // one entry per parameter, laid out by hand
pub(super) const TABLE: [Param; N] = [
    Param::new("CBF_MU", "CBF", "s", (0.01, 100.0), 2, field!(cbf.mu),
        "Barrier velocity weight mu: the filter keeps h + mu*dh/dt above delta").key("mu"),
    Param::new("CBF_DELTA", "CBF", "m^2", (1e-4, 100.0), 4, field!(cbf.delta),
        "Safety level delta (hull radius squared); must stay below CBF_DELTA1").key("delta"),
    Param::new("CBF_DELTA1", "CBF", "m^2", (1e-4, 100.0), 4, field!(cbf.delta1),
        "Engagement level delta1 > CBF_DELTA: the filter acts below it").key("delta1"),
    Param::new("CBF_ACC_BOUND", "CBF", "m/s^2", (0.0, 50.0), 2, field!(cbf.accel_bound),
        "Bound A on the unknown obstacle acceleration (relative variants)").key("accel_bound"),
    Param::new("CBF_VARIANT", "CBF", "", (0.0, 4.0), 0, (|p| variant_code(p.filter_variant), |p, v| {
            if let Some(f) = variant_of(v as i32) {
                p.filter_variant = f;
            }
        }),
        "Filter law: 0 paper, 1 relative, 2 multi, 3 multi-relative, 4 braking (braking-distance barrier)").key("filter").code(|c| variant_of(c).map(|v| v.as_str())),
    Param::new("TRK_KP", "Tracking", "1/s^2", (0.01, 100.0), 3, (|p| p.tracking.kp[0], |p, v| p.tracking.kp = [v; 3]),
        "PD position gain k_p (all axes)").key("kp"),
    Param::new("TRK_KD", "Tracking", "1/s", (0.01, 100.0), 3, (|p| p.tracking.kd[0], |p, v| p.tracking.kd = [v; 3]),
        "PD velocity gain k_d (all axes)").key("kd"),
    Param::new("WP_SPEED", "Mission", "m/s", (0.001, crate::outer::waypoint::PARAM_LIMIT), 2, field!(waypoint.cruise_speed),
        "Reference speed along the path").key("speed"),
    Param::new("FS_OBST_REQ", "Failsafe", "", (0.0, 1.0), 0, flag!(failsafe.obstacles_required),
        "Obstacle data must be fresh to arm and to stay armed (0 no, 1 yes)").code(|c| match c {
            0 => Some("not required"),
            1 => Some("required"),
            _ => None,
        }),
    Param::new("CBF_VEL_MARGIN", "CBF", "m/s", (0.0, 10.0), 3, field!(cbf.velocity_margin),
        "Velocity-uncertainty margin eps_v of the filter's constraint").key("velocity_margin"),
    Param::new("CBF_BRAKE_ACC", "CBF", "m/s^2", (0.1, 15.0), 2, field!(cbf.brake_accel),
        "CBF_VARIANT 4: deceleration the braking-distance barrier counts on (at most the filter's u_max)"),
    Param::new("CBF_BRAKE_DLY", "CBF", "s", (0.01, 1.0), 3, field!(cbf.brake_delay),
        "CBF_VARIANT 4: actuation lag plus sensing latency before braking takes effect"),
    Param::new("CBF_BRAKE_GAMMA", "CBF", "1/s", (0.0, 20.0), 2, field!(cbf.brake_gamma),
        "CBF_VARIANT 4: class-K rate of the braking-distance barrier (how fast it may be approached)"),
    Param::new("CBF_BRAKE_UNK_V", "CBF", "m/s", (0.0, 10.0), 2, field!(cbf.brake_unknown_speed),
        "CBF_VARIANT 4: speed at which a sensed small cluster not proven moving may approach (0: static)"),
    Param::new("VEH_MASS", "Vehicle", "kg", (0.07, 50.0), 3, (|p| p.airframe.mass, |p, v| {
            p.airframe.mass = v;
        }),
        "Vehicle mass; hover thrust mass*g must stay below THR_MAX"),
    Param::new("VEH_IXX", "Vehicle", "kg m^2", (1e-5, 10.0), 5, (|p| p.airframe.inertia[0], |p, v| {
            p.airframe.inertia[0] = v;
        }),
        "Moment of inertia about body x (roll)"),
    Param::new("VEH_IYY", "Vehicle", "kg m^2", (1e-5, 10.0), 5, (|p| p.airframe.inertia[1], |p, v| {
            p.airframe.inertia[1] = v;
        }),
        "Moment of inertia about body y (pitch)"),
    Param::new("VEH_IZZ", "Vehicle", "kg m^2", (1e-5, 10.0), 5, (|p| p.airframe.inertia[2], |p, v| {
            p.airframe.inertia[2] = v;
        }),
        "Moment of inertia about body z (yaw)"),
    Param::new("VEH_ARM", "Vehicle", "m", (0.02, 2.0), 3, field!(airframe.arm_length),
        "Distance from the centre of mass to each rotor axis"),
    Param::new("VEH_ROTOR_TMAX", "Vehicle", "N", (0.1, 500.0), 2, field!(airframe.rotor_thrust_max),
        "Largest thrust of one rotor; 4x it must be at least THR_MAX"),
    Param::new("VEH_KAPPA", "Vehicle", "m", (1e-4, 0.5), 4, field!(airframe.torque_to_thrust),
        "Rotor drag-torque to thrust ratio k_m/k_f"),
    Param::new("THR_MAX", "Vehicle", "N", (0.5, 2000.0), 2, field!(thrust.thrust_max),
        "Largest collective thrust commanded; above VEH_MASS*g, at most 4*VEH_ROTOR_TMAX"),
    // Issue 17: the hull that bounds δ, and the ground / ceiling planes the filter keeps.
    Param::new("VEH_HULL_R", "Vehicle", "m", (0.01, 5.0), 4, field!(hull_radius),
        "Radius of the sphere bounding the vehicle; CBF_DELTA must be at least its square"),
    Param::new("GND_HEIGHT", "CBF", "m", (-100.0, 100.0), 3, field!(plant_aware.ground_height),
        "Ground height (up); the filter keeps the plane z = -GND_HEIGHT as a barrier in flight"),
    Param::new("CEIL_HEIGHT", "CBF", "m", (0.0, 1000.0), 3, field!(plant_aware.ceiling_height),
        "Ceiling height (up) kept as a barrier in flight; 0 = no ceiling"),
    // Issue 19: the obstacle memory of the range-sensor perception (`crate::perception`).
    Param::new("PCP_VOXEL", "Perception", "m", (0.02, 5.0), 3, field!(perception.voxel),
        "Obstacle memory voxel edge: range returns in one cube merge into one point").key("mem_voxel"),
    Param::new("PCP_FORGET", "Perception", "s", (0.05, 600.0), 2, field!(perception.forget_s),
        "An obstacle cell not seen again for this long is forgotten").key("mem_forget"),
    Param::new("PCP_CLR_MARGIN", "Perception", "m", (0.0, 5.0), 3, field!(perception.clear_margin),
        "A beam clears a cell it passes when its return lies this far beyond the cell").key("mem_clear_margin"),
    Param::new("PCP_TRK_SIZE", "Perception", "m", (0.0, 10.0), 2, field!(perception.track_size),
        "Clusters up to this size are tracked for their velocity; larger ones are static").key("mem_track_size"),
    Param::new("PCP_FOV_MARGIN", "Perception", "m", (0.0, 5.0), 3, field!(perception.fov_margin),
        "Frontier point beyond the observed free range (>= hull radius); 0 = off").key("fov_margin"),
    Param::new("PCP_FOV_WALLS", "Perception", "", (0.0, 2.0), 0, u8_field!(perception.fov_walls),
        "Where the observed free range is used up: 0 cap the speed (creep), 1 walls stop the vehicle, \
             2 walls while the heading is held (MIS_YAW_MODE 0)").key("fov_walls").code(|c| match c {
            0 => Some("cap"),
            1 => Some("walls"),
            2 => Some("walls when held"),
            _ => None,
        }),
];
