//! The processor-in-the-loop application: the handshake and lockstep over one byte link
//! ([`app`], re-exported here), the lockstep step itself ([`lockstep`]) and the battery
//! measurement of the host's simulated pack ([`battery`]).
//!
//! Hardware-independent and host-tested (the QEMU board supplies the byte port and tick
//! counter). May import: [`crate::app`], [`crate::link`], `parapet_core`. Not drivers or boards.

pub mod app;
pub mod battery;
pub mod lockstep;

pub use app::*;
