//! The supervisor: failsafe state machine, arming, modes and landing.
//!
//! Owns [`failsafe`] (Disarmed / Armed / Brake / Land / MotorsOff and the arm checks).
//! Runs with the outer loop, at the outer rate, and on every command.
//!
//! May import: the crate root foundation ([`crate::frame`], [`crate::fmath`],
//! [`crate::Vec3`]). Never the loops.

pub mod failsafe;
