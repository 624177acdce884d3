//! Board layers (Cortex-M only): one file per board, holding its whole pin map, clocks and
//! peripheral drivers.
#[cfg(feature = "board-f405")]
pub mod f405;
#[cfg(feature = "board-qemu")]
pub mod qemu;
