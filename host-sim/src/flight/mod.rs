//! The closed loop: plant → sensors → flight stack → motor commands → plant,
//! with the run's settings, the metrics, and the checks made before a flight.
//!
//! * [`runner`]: [`runner::RunConfig`], the loop ([`runner::run_with`]) and its metrics.
//! * [`sensing`]: the ground-truth proximity report and the true barrier h̄ at the outer rate.
//! * [`stack`]: [`stack::FlightStack`], what the loop needs from a flight stack (implemented in
//!   [`crate::fc`]), and the controller clock.
//! * [`validate`]: up-front checks of a run's settings against the core's limits.
//! * [`preflight`]: pre-flight checks (start, waypoints, path vs scene) before any flight.
//! * [`paths`]: path lengths and the default duration limit.
//!
//! May import: `parapet-core`, [`crate::input`], [`crate::sim`], [`crate::world`],
//! [`crate::plan`] (path files), [`crate::report`] (samples, summary).
pub mod paths;
pub mod preflight;
pub mod runner;
pub mod sensing;
pub mod stack;
pub mod validate;
