//! The outer loop (default 250 Hz): guidance → PD tracking → safety filter →
//! thrust/attitude map, producing the attitude command the inner loop flies.
//!
//! Owns [`waypoint`] (the path follower), [`tracking`] (PD tracking, eq. 2) and
//! [`thrust`] (acceleration → collective thrust and attitude, eq. 4-5).
//!
//! May import: the crate root foundation ([`crate::frame`], [`crate::fmath`],
//! [`crate::airframe`], [`crate::Vec3`]), [`crate::safety`] and [`crate::supervisor`].
//! Never [`crate::inner`]: what it needs from the inner loop arrives as a message.

pub mod thrust;
pub mod tracking;
pub mod waypoint;
