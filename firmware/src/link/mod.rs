//! The MAVLink link: the message types ([`dialect`], generated at build time), framing
//! ([`frame_parser`], [`framing`]), the inbound and outbound message sets ([`messages`],
//! [`outbound`]), the dispatcher ([`router`]) behind [`Link`] ([`endpoint`], re-exported here), the vehicle-state inputs ([`inputs`]: HIL_SENSOR, ODOMETRY), commands
//! ([`command`]), the mission protocol ([`mission`], the deprecated float items [`mission_float`]) and its executor ([`mission_run`]), obstacle batches ([`obstacles`]),
//! parameters ([`params`]), telemetry streams ([`telemetry`]) and the pilot input over MAVLink
//! ([`manual_control`]: MANUAL_CONTROL, RC_CHANNELS_OVERRIDE, RC_CHANNELS) and the link-level
//! services ([`services`]: PING, SYSTEM_TIME, GLOBAL_POSITION_INT, MISSION_CURRENT, HOME_POSITION,
//! message intervals, ATTITUDE_TARGET, BATTERY_STATUS, MISSION_ITEM_REACHED) and the MAVLink v1
//! refusal ([`v1`]), the standard modes protocol ([`standard_modes`]: AVAILABLE_MODES,
//! CURRENT_MODE), the read-only MAVLink FTP server ([`ftp`]) over the component metadata files
//! ([`metadata`]: COMPONENT_METADATA), the takeoff height limit's
//! refusals ([`takeoff_limit`]). The global ↔ local NED conversion around home is the wire
//! contract's `parapet_core::wire::geo` (shared with the host's PIL link).
//!
//! Hardware-independent and host-tested. May import: `parapet_core` (including the wire contract
//! `parapet_core::wire`), `mavlink_core`, [`crate::app`] (the `Autopilot` boundary). Not the PIL
//! application, drivers or boards.

pub mod command;
pub mod dialect;
pub mod endpoint;
pub mod frame_parser;
pub mod framing;
pub mod ftp;
pub mod inputs;
pub mod manual_control;
pub mod messages;
pub mod metadata;
pub mod mission;
pub mod mission_float;
pub mod mission_items;
pub mod mission_run;
pub mod obstacles;
pub mod offboard;
pub mod outbound;
pub mod params;
pub mod position_sources;
pub mod received;
pub mod reposition;
pub mod router;
pub mod services;
pub mod source_dispatch;
pub mod standard_modes;
pub mod takeoff_limit;
pub mod telemetry;
pub mod v1;

pub use endpoint::*;
pub use inputs::*;
pub use outbound::{autopilot_version, CAPABILITIES};
pub use router::{PARAMS_PER_POLL, REPLY_QUEUE_LEN, REPLY_RESERVE};
