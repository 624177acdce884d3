//! The application: the boundary between the link and the flight-control cascade
//! ([`autopilot`]), the cascade as an outer and an inner stage ([`cascade`]), the mailboxes
//! through which the stages and tasks exchange messages ([`mailbox`]), the on-board replanner
//! beside the outer stage ([`replanner`]), the navigation filter the outer stage runs
//! ([`navigation`]) and loop timing ([`loop_timing`]).
//!
//! May import: `parapet_core` only (the tests also drive it through [`crate::link`]). Not the link, the
//! PIL application, drivers or boards.

pub mod autopilot;
pub mod cascade;
pub mod loop_timing;
pub mod mailbox;
pub mod navigation;
pub mod replanner;
