//! Board layers (Cortex-M only): one file per board, holding its whole pin map, clocks and
//! peripheral drivers (`f405`: the MATEKF405 flight controller; `h743`: the MATEKH743; `qemu`:
//! QEMU's netduinoplus2, with the measuring critical-section implementation of the PIL build).
//! Thin: no control or protocol logic. The two flight-controller boards expose the same items
//! (`init`, `Board`, `DshotMotors`, `ImuParts`, …), and [`active`] is the one the build selected:
//! the binary `src/main.rs` runs the same tasks on either.
//!
//! May import: everything of the crate (drivers, app types, link framing, PIL traits) and the
//! HALs. Nothing imports a board except the binaries.
#[cfg(feature = "board-f405")]
pub mod f405;
#[cfg(feature = "board-h743")]
pub mod h743;
#[cfg(feature = "board-qemu")]
pub mod qemu;

/// The flight-controller board of this build (`board-f405` or `board-h743`; they exclude each
/// other).
#[cfg(all(feature = "board-f405", not(feature = "board-h743")))]
pub use f405 as active;
/// The flight-controller board of this build.
#[cfg(feature = "board-h743")]
pub use h743 as active;
