//! The wire contract between the firmware and the host: everything both sides of the MAVLink
//! link must agree on, defined once. The firmware (`firmware/src/link/`, `firmware/src/pil/`)
//! encodes with it; the host's processor-in-the-loop code (`host-sim/src/fc/`) decodes with it
//! and its firmware twin replays the same lockstep rule and motor sanitiser.
//!
//! - [`ids`]: system/component ids, the empty-obstacle-batch id [`ids::CLEAR_ID`], magic numbers
//!   and fixed-point scalings.
//! - [`names`]: telemetry and instrumentation names (`DEBUG_VECT` / `NAMED_VALUE_INT` keys).
//! - [`codes`]: small codes carried in message fields: flight phase (HEARTBEAT `custom_mode`),
//!   filter region and flags (`CBF`, `CBF_FLAGS`), active obstacle id, failsafe codes, the
//!   ODOMETRY yaw quaternion, GPS_INPUT's yaw.
//! - [`geo`]: global (lat/lon 1e-7 °, altitude) ↔ local NED around the link's origin.
//! - [`modes`]: PX4's `vehicle_status.nav_state` numbers of the flight and guidance modes (the
//!   ULog of both sides), and the guidance mode a lockstep host infers from the phase.
//! - [`rates`]: the inner and outer loop rates (1 kHz, 250 Hz), defined once.
//! - [`lockstep`]: the lockstep rule (which HIL_SENSOR runs the outer loop) and the motor
//!   command with its sanitiser (what HIL_ACTUATOR_CONTROLS carries).
//! - [`battery`]: the host's raw pack reading on the lockstep link (BATTERY_STATUS from the
//!   host's id: mV, cA).
//! - [`streams`]: the telemetry stream registry (message, default rate, settable), used by the
//!   firmware's scheduler and interval service and the host's ground-station bridge.
//! - [`ulog`]: the one ULog writer (PX4's flight-log format; the firmware's onboard log and the
//!   host's `flight.ulg`), [`log_topics`]: the topics of a flight log and their records.
//!
//! Message types themselves come from the `mavlink` crate on both sides (this module is
//! `no_std` and does not depend on it). May import: [`crate::cbf`] (region codes),
//! [`crate::fmath`] and the mode types ([`crate::supervisor::modes::FlightMode`],
//! [`crate::outer::guidance::GuidanceMode`]); nothing else of the crate (`libm` for rounding).

pub mod battery;
pub mod codes;
pub mod geo;
pub mod ids;
pub mod lockstep;
pub mod log_topics;
pub mod modes;
pub mod names;
pub mod rates;
pub mod streams;
pub mod ulog;
