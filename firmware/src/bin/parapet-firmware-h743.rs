//! Parapet flight-control firmware for the MATEKH743 (STM32H743) flight controller: the tasks of
//! `src/bin/fc/` (`flight_binary!`) on [`MatekH743`] (`board::h743`). Not flown yet (`docs/bring-up.md`).
//!
//! Build: `cargo build --release -p parapet-firmware --target thumbv7em-none-eabihf
//! --no-default-features --features board-h743 --bin parapet-firmware-h743`.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

parapet_firmware::flight_binary!(
    parapet_firmware::board::h743::MatekH743,
    ["--no-default-features", "--features", "board-h743"]
);
