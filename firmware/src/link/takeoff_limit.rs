//! Takeoffs refused for their height, with the reason: the cascade refuses a takeoff above its
//! limit (`GuidanceParams::takeoff_height_max`, 120 m above home; QGroundControl's default plan
//! takes off to 50 m) — a NAV_TAKEOFF command (COMMAND_ACK DENIED) or a mission start whose
//! TAKEOFF item is higher (MISSION_START DENIED; DO_SET_MODE AUTO.MISSION does not fly it) — and
//! the link sends a STATUSTEXT WARNING [`TOO_HIGH_TEXT`] so the ground station shows why.
//!
//! A takeoff to a finite height above 0 is refused `Invalid` (DENIED) only for its height: the
//! cascade's other refusals of a takeoff (disarmed, no position fix) are `NotNow`.
//!
//! May import: the dialect, [`crate::link::telemetry`] (the STATUSTEXT). No allocation, no panics.

use crate::link::dialect::{MavSeverity, STATUSTEXT_DATA};

/// The STATUSTEXT of a takeoff refused for its height.
pub const TOO_HIGH_TEXT: &str = "Takeoff refused: above the height limit";

/// `true` when a takeoff to `height_m` that the cascade refused Invalid (DENIED) was refused for
/// its height (`None`: no takeoff asked).
pub fn refused_for_height(height_m: Option<f32>) -> bool {
    height_m.is_some_and(|h| h.is_finite() && h > 0.0)
}

/// The STATUSTEXT WARNING [`TOO_HIGH_TEXT`].
pub fn text() -> STATUSTEXT_DATA {
    crate::link::telemetry::status_text(MavSeverity::MAV_SEVERITY_WARNING, TOO_HIGH_TEXT, "")
}
