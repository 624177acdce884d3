//! The application: the boundary between the tasks and the flight-control cascade
//! ([`autopilot`]), the real cascade behind it ([`cascade`]), how tasks share state
//! ([`shared`]) and loop timing ([`loop_timing`]).
//!
//! May import: `parapet_core` only (the tests also drive it through [`crate::link`]). Not the link, the
//! PIL application, drivers or boards.

pub mod autopilot;
pub mod cascade;
pub mod loop_timing;
pub mod shared;
