//! Board layers (Cortex-M only): one file per board, holding its whole pin map, clocks and
//! peripheral drivers (`f405`: the STM32F405 flight controller; `qemu`: QEMU's netduinoplus2,
//! with the measuring critical-section implementation of the PIL build). Thin: no control or
//! protocol logic.
//!
//! May import: everything of the crate (drivers, app types, link framing, PIL traits) and the
//! HALs. Nothing imports a board except the binaries.
#[cfg(feature = "board-f405")]
pub mod f405;
#[cfg(feature = "board-qemu")]
pub mod qemu;
