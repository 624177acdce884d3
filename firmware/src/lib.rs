//! # parapet-firmware
//!
//! Embassy flight-control firmware for STM32F405 flight controllers, plus a `board-qemu` build
//! that runs the same application on QEMU's `netduinoplus2` for processor-in-the-loop tests.
//!
//! The library part is hardware-independent and host-tested: the MAVLink link
//! ([`link`], [`frame_parser`], [`messages`], [`outbound`], [`wire`]), the mission protocol
//! ([`mission`]), commands ([`command`]), obstacle decoding ([`obstacle_link`]), telemetry
//! ([`telemetry`]), loop timing ([`loop_timing`]), the lockstep PIL step ([`lockstep`]), DShot
//! framing ([`dshot`]) and the IMU driver ([`mpu6000`]). Tasks reach the flight-control cascade
//! only through [`autopilot::Autopilot`].
//!
//! Board layers ([`board`], `src/board/*.rs`) build only for `target_os = "none"`; the executors
//! and tasks live in the binaries (`src/main.rs` for the STM32F405 board,
//! `src/bin/parapet-firmware-qemu.rs` for QEMU).
//!
//! Frames: world NED, body FRD, SI units; see `firmware/README.md` for the wire protocol.
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod app;
#[cfg(target_os = "none")]
pub mod board;
pub mod drivers;
pub mod link;
pub mod pil;

// Paths of the modules before the move into folders (removed in the next commit).
pub use app::{autopilot, cascade, loop_timing, shared};
pub use drivers::{dshot, mpu6000};
pub use link::obstacles as obstacle_link;
pub use link::{command, frame_parser, framing as wire, messages, mission, outbound, params, telemetry};
pub use pil::lockstep;

#[cfg(test)]
extern crate std;
