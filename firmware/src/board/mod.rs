//! Board layers (Cortex-M only): one file per board, holding its whole pin map, clocks and
//! peripheral drivers (`f405`: the MATEKF405 flight controller; `h743`: the MATEKH743; `qemu`:
//! QEMU's netduinoplus2, with the measuring critical-section implementation of the PIL build).
//! Thin: no control or protocol logic. The flight-controller boards implement
//! [`stm32::FlightBoard`] (what the flight binary needs of a board, checked by the compiler) on
//! a marker type ([`f405::MatekF405`], [`h743::MatekH743`]); each binary under `src/bin/` names
//! its board once and runs the same tasks (`src/bin/fc/`) on it.
//!
//! May import: everything of the crate (drivers, app types, link framing, PIL traits) and the
//! HALs. Nothing imports a board except the binaries.
#[cfg(all(target_os = "none", any(feature = "board-f405", feature = "board-h743", feature = "board-qemu")))]
pub mod ccm;
#[cfg(feature = "board-f405")]
pub mod f405;
#[cfg(feature = "board-h743")]
pub mod h743;
#[cfg(feature = "board-qemu")]
pub mod qemu;
#[cfg(any(feature = "board-f405", feature = "board-h743"))]
pub mod stm32;
