//! Part of [`super::TABLE`]: the set-up parameters: battery measurement and thresholds, accelerometer calibration, level trim, board rotation (issue 22); the speed governor (`GOV_*`, issue 36); on-board replanning (`RPL_*`, issue 38).
//!
//! Entries in MAVLink `param_index` order; [`super`] concatenates the parts. May import
//! what [`super`] may.

use super::*;

/// Entries of this part.
pub(super) const N: usize = 25;

/// This part's entries, in `param_index` order.
#[rustfmt::skip] // one entry per parameter, laid out by hand
pub(super) const TABLE: [Param; N] = [
    Param::new("BAT_LOW_V", "Battery", "V", (3.0, 4.2), 2, field!(battery.low_cell_v),
        "Low battery: resting voltage per cell below this (return)"),
    Param::new("BAT_CRIT_V", "Battery", "V", (2.8, 4.0), 2, field!(battery.critical_cell_v),
        "Critical battery: resting voltage per cell below this (land)"),
    Param::new("BAT_R_INT", "Battery", "Ohm", (0.0, 1.0), 3, field!(battery.r_internal_ohm),
        "Pack internal resistance for the sag compensation (with a current sensor)"),
    Param::new("BAT_V_DIV", "Battery", "", (1.0, 100.0), 2, field!(battery.v_divider),
        "VBAT divider: pack volts per ADC volt (MATEKF405 11)"),
    Param::new("BAT_A_PER_V", "Battery", "A/V", (0.0, 500.0), 1, field!(battery.amps_per_volt),
        "Current sensor scale, A per ADC volt (0 = no current sensor)"),
    Param::new("BAT_CELLS", "Battery", "", (0.0, crate::battery::MAX_CELLS as f32), 0, u8_field!(battery.cells),
        "Cells in series (0 = detect at power-up, disarmed)").whole(),
    Param::new("BAT_ENABLE", "Battery", "", (0.0, 1.0), 0, flag!(battery.enabled),
        "Battery measured (0: no battery failsafe)").code(|c| match c {
            0 => Some("off"),
            1 => Some("on"),
            _ => None,
        }),
    acc("CAL_ACC0_XOFF", false, field!(sensors.accel_offset.x),
        "Accelerometer offset, sensor x"),
    acc("CAL_ACC0_YOFF", false, field!(sensors.accel_offset.y),
        "Accelerometer offset, sensor y"),
    acc("CAL_ACC0_ZOFF", false, field!(sensors.accel_offset.z),
        "Accelerometer offset, sensor z"),
    acc("CAL_ACC0_XSCALE", true, field!(sensors.accel_scale.x),
        "Accelerometer scale, sensor x"),
    acc("CAL_ACC0_YSCALE", true, field!(sensors.accel_scale.y),
        "Accelerometer scale, sensor y"),
    acc("CAL_ACC0_ZSCALE", true, field!(sensors.accel_scale.z),
        "Accelerometer scale, sensor z"),
    Param::new("CAL_TRIM_ROLL", "Sensors", "rad", (-crate::calibration::TRIM_MAX, crate::calibration::TRIM_MAX), 4, field!(sensors.trim_roll),
        "Level-horizon trim, roll"),
    Param::new("CAL_TRIM_PITCH", "Sensors", "rad", (-crate::calibration::TRIM_MAX, crate::calibration::TRIM_MAX), 4, field!(sensors.trim_pitch),
        "Level-horizon trim, pitch"),
    Param::new("SENS_BOARD_ROT", "Sensors", "", (0.0, crate::calibration::BoardRotation::MAX_CODE as f32), 0, (|p| f32::from(p.sensors.board_rotation.code()), |p, v| {
            if let Some(r) = crate::calibration::BoardRotation::from_code(v as u8) {
                p.sensors.board_rotation = r;
            }
        }),
        "IMU orientation on the board (PX4 SENS_BOARD_ROT codes 0-15)").code(crate::calibration::BoardRotation::name),
    Param::new("GOV_ENABLE", "Governor", "", (0.0, 1.0), 0, flag!(governor.enable),
        "Speed governor: 1 limits the speed towards each direction to what can stop inside observed free space (docs/filter.md)").code(|c| match c {
            0 => Some("off"),
            1 => Some("on"),
            _ => None,
        }),
    Param::new("GOV_MARGIN", "Governor", "m", (0.0, 2.0), 2, field!(governor.margin),
        "Speed governor: distance kept beyond the hull radius when stopped"),
    Param::new("GOV_DELAY", "Governor", "s", (0.0, 1.0), 3, field!(governor.delay),
        "Speed governor: latency added to CBF_BRAKE_DLY (plus the obstacle data age) before braking"),
    Param::new("GOV_RANGE", "Governor", "m", (0.5, 100.0), 1, field!(governor.range),
        "Speed governor: sensing range; space beyond it counts as blocked (set from the sensors by the simulator)"),
    // Issue 38: on-board replanning (`crate::replan`).
    Param::new("RPL_ENABLE", "Replan", "", (0.0, 1.0), 0, flag!(replan.enable),
        "Replan on board when the remaining path is blocked by what the sensors saw (docs/perception.md)").code(|c| match c {
            0 => Some("off"),
            1 => Some("on"),
            _ => None,
        }),
    Param::new("RPL_RATE", "Replan", "Hz", (1.0, 50.0), 1, field!(replan.rate_hz),
        "Checks per second of the remaining path against the replanner's grid"),
    Param::new("RPL_COOLDOWN", "Replan", "s", (0.0, 60.0), 2, field!(replan.cooldown_s),
        "Wait after a replan (or a no-path result) before the next plan"),
    Param::new("RPL_HORIZON", "Replan", "m", (0.1, 50.0), 2, field!(replan.horizon_m),
        "Length of the remaining path checked for a blockage"),
    Param::new("RPL_MARGIN", "Replan", "m", (0.0, 2.0), 3, field!(replan.margin_m),
        "Clearance beyond the hull radius a detour keeps from sensed obstacles"),
];
