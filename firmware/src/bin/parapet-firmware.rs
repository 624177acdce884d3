//! Parapet flight-control firmware for the MATEKF405 (STM32F405) flight controller: the tasks of
//! `src/bin/fc/` (`flight_binary!`) on [`MatekF405`] (`board::f405`).
//!
//! `cargo run -p parapet-firmware --release` flashes it through probe-rs; logs are defmt over RTT.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

parapet_firmware::flight_binary!(parapet_firmware::board::f405::MatekF405, []);
