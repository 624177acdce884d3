//! # parapet-firmware
//!
//! Embassy flight-control firmware for STM32F405 flight controllers, plus a `board-qemu` build
//! that runs the same application on QEMU's `netduinoplus2` for processor-in-the-loop tests.
//!
//! The library part is hardware-independent and host-tested; one folder per concern:
//!
//! | folder | owns | may import |
//! |---|---|---|
//! | [`app`] | the boundary to the cascade ([`app::autopilot`]), the real cascade ([`app::cascade`]), how tasks exchange messages ([`app::shared`]), loop timing | `parapet_core` |
//! | [`link`] | MAVLink framing, inbound/outbound message sets, dispatcher ([`link::Link`]), commands, mission, obstacle batches, parameters, telemetry | `parapet_core` (wire contract `parapet_core::wire`), `mavlink`, [`app`] |
//! | [`log`] | the onboard flight log: ULog writer, log stores (RAM ring), the arming-to-disarming logger, the MAVLink log download | [`app`], [`link`] (dialect, framing), `parapet_core` |
//! | [`pil`] | the processor-in-the-loop application and its lockstep step | [`app`], [`link`], `parapet_core` |
//! | [`setup`] | PREFLIGHT_STORAGE / PREFLIGHT_CALIBRATION / DO_MOTOR_TEST: the calibration runs, the motor test, the storage requests and their STATUSTEXTs | [`storage`], `parapet_core` |
//! | [`storage`] | parameter storage in flash (whole-table records in two alternating slots, version and CRC, debounced saves), the RAM NOR flash | `parapet_core` |
//! | [`vehicle`] | a cascade with the setup services around it (IMU correction, calibration, motor test, storage steps) | [`app`], [`setup`], [`storage`], `parapet_core` |
//! | [`drivers`] | MPU-6000 IMU, DShot600 framing | [`app::autopilot`] types |
//! | [`board`] | pin maps, clocks, peripherals of one board (Cortex-M only) | everything above |
//!
//! No import cycle between sibling modules (checked by the workspace's `tests/tests/layering.rs`).
//! Tasks reach the flight-control cascade only through [`app::autopilot`]. The board layers
//! (`src/board/*.rs`) build only for `target_os = "none"`; the executors and tasks live in the
//! binaries (`src/bin/parapet-firmware.rs` and `parapet-firmware-h743.rs`, one per STM32 board,
//! with the tasks of `src/bin/fc/`; `src/bin/parapet-firmware-qemu.rs` for QEMU).
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
pub mod log;
pub mod pil;
pub mod setup;
pub mod storage;
pub mod vehicle;

#[cfg(test)]
extern crate std;

/// A flight binary (`src/bin/parapet-firmware*.rs`), written once for every STM32 board: on the
/// Cortex-M target `type Board = $board` and the tasks of `src/bin/fc/` on it; on the host a stub
/// that builds the binary for the target with the board's cargo feature arguments and flashes it
/// through probe-rs (`src/bin/fc/host.rs`). Invoked from a file in `src/bin/` (the module paths
/// are relative to it).
#[macro_export]
macro_rules! flight_binary {
    ($board:ty, [$($feature:literal),* $(,)?]) => {
        /// The board of this binary.
        #[cfg(target_os = "none")]
        type Board = $board;

        #[cfg(target_os = "none")]
        #[path = "fc/mod.rs"]
        mod fc;

        #[cfg(not(target_os = "none"))]
        #[path = "fc/host.rs"]
        mod host;

        #[cfg(not(target_os = "none"))]
        fn main() {
            host::main(env!("CARGO_BIN_NAME"), &[$($feature),*])
        }
    };
}
