//! Identifiers, magic numbers and fixed-point scalings of the link.

/// MAVLink system id of the vehicle.
pub const VEHICLE_SYSTEM_ID: u8 = 1;
/// MAVLink component id of the autopilot (MAV_COMP_ID_AUTOPILOT1).
pub const AUTOPILOT_COMPONENT_ID: u8 = 1;
/// MAVLink system id the host (the simulator driving the PIL link) sends as: its own, no ground
/// station's (QGroundControl 255/190, MAVProxy 255/230, MAVSDK 245/190), so the firmware's
/// answers to the host's start-up commands (COMMAND_ACK, MISSION_REQUEST_INT, …), which the
/// bridge forwards with every other firmware frame, are addressed to nobody a ground station
/// is (issue 41: they reached QGroundControl addressed to 255/190, its own ids).
pub const HOST_SYSTEM_ID: u8 = 254;
/// MAVLink component id the host sends as (MAV_COMP_ID_USER1).
pub const HOST_COMPONENT_ID: u8 = 25;

/// `obstacle_id` 65 535 of OBSTACLE_DISTANCE_3D: "unknown id" per the message definition, a
/// **valid point** (issue 19; it used to mean "no obstacle"). Hosts never give a tracked
/// obstacle this id (`parapet-sim`'s track ids), so a point with it is an untracked one.
pub const CLEAR_ID: u16 = u16::MAX;

/// OBSTACLE_DISTANCE_3D `min_distance` / `max_distance` of the message that carries **no
/// point** and closes the previous batch, opening an empty one (no obstacle in view): an empty
/// range (`min_distance > max_distance`: nothing can lie within it). Receivers test
/// [`is_empty_batch`]; ArduPilot likewise ignores a point outside `[min, max]`.
pub const EMPTY_BATCH_RANGE: (f32, f32) = (1.0, 0.0);

/// Whether an OBSTACLE_DISTANCE_3D with these `min_distance`, `max_distance` is the empty-batch
/// marker ([`EMPTY_BATCH_RANGE`]).
pub fn is_empty_batch(min_distance: f32, max_distance: f32) -> bool {
    min_distance > max_distance
}

/// COMMAND_LONG COMPONENT_ARM_DISARM `param2` that forces a disarm in flight.
pub const FORCE_DISARM_MAGIC: f32 = 21196.0;

/// MISSION_ITEM_INT `x`, `y` scale in `MAV_FRAME_LOCAL_NED`: metres × 10⁴ (`z` is metres, `f32`).
pub const LOCAL_XY_SCALE: f32 = 1.0e4;

/// Waypoint coordinate (m) → MISSION_ITEM_INT `x`/`y`: rounded to the nearest 10⁻⁴ m
/// (saturating at the `i32` range; NaN → 0).
pub fn local_xy_to_wire(metres: f64) -> i32 {
    libm::round(metres * f64::from(LOCAL_XY_SCALE)) as i32
}

/// MISSION_ITEM_INT `x`/`y` → waypoint coordinate, m (the quantised value the vehicle flies).
pub fn local_xy_from_wire(v: i32) -> f32 {
    v as f32 / LOCAL_XY_SCALE
}

/// Opaque id of an on-vehicle mission plan (MAVLink `MISSION_CURRENT.mission_id`,
/// `MISSION_COUNT.opaque_id`, `MISSION_ACK.opaque_id`): the common message set asks only that
/// it change whenever the plan changes, so a ground station that sees a new id downloads the
/// plan again (issue 38: a replanned path). FNV-1a's step (32 bit) over 32-bit words — each
/// item's command and its wire x, y, z, in order; never 0 (0 means "ids not supported / no
/// plan"). Fold the items
/// with [`plan_id_item`] from [`PLAN_ID_START`] and finish with [`plan_id_finish`].
pub const PLAN_ID_START: u32 = 0x811c_9dc5;

/// Most items a mission upload to the firmware may carry (its `MAX_WAYPOINTS`; MISSION_COUNT
/// above it → MAV_MISSION_NO_SPACE): twice the cascade's path (`PATH_CAPACITY`, 64), whose
/// longer segments the firmware's executor streams in (issue 38). The host's PIL link checks
/// a path against it before the upload.
pub const MISSION_ITEM_CAPACITY: usize = 128;

/// One item (`command`, wire `x`, `y`, `z`) folded into a plan id (see [`PLAN_ID_START`]).
pub fn plan_id_item(acc: u32, command: u16, x: i32, y: i32, z: f32) -> u32 {
    [u32::from(command), x as u32, y as u32, z.to_bits()]
        .iter()
        .fold(acc, |h, w| (h ^ w).wrapping_mul(0x0100_0193))
}

/// The folded id as sent: never 0 (see [`PLAN_ID_START`]).
pub fn plan_id_finish(acc: u32) -> u32 {
    acc.max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_xy_round_trip_is_the_quantisation() {
        assert_eq!(local_xy_to_wire(1.23456), 12346);
        assert_eq!(local_xy_to_wire(-1.23454), -12345);
        assert_eq!(local_xy_from_wire(local_xy_to_wire(-2.5)), -2.5);
        assert_eq!(local_xy_to_wire(f64::NAN), 0);
        assert_eq!(local_xy_to_wire(1e9), i32::MAX);
    }

    /// The plan id changes with any item's command or coordinate and with the order, and is
    /// never the "not supported" 0.
    #[test]
    fn plan_id_changes_with_the_plan() {
        let id = |items: &[(u16, i32, i32, f32)]| {
            plan_id_finish(items.iter().fold(PLAN_ID_START, |a, &(c, x, y, z)| plan_id_item(a, c, x, y, z)))
        };
        let a = (16, 10_000, 0, -1.5);
        let b = (16, 10_000, 1, -1.5);
        let base = id(&[a, b]);
        assert_ne!(base, 0);
        assert_ne!(id(&[a]), base);
        assert_ne!(id(&[b, a]), base);
        assert_ne!(id(&[a, (16, 10_000, 2, -1.5)]), base);
        assert_ne!(id(&[a, (21, 10_000, 1, -1.5)]), base);
        assert_ne!(id(&[a, (16, 10_000, 1, -1.25)]), base);
        assert_eq!(id(&[a, b]), base);
        assert_eq!(plan_id_finish(0), 1);
    }
}
