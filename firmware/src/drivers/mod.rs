//! Device drivers, hardware-independent over `embedded-hal-async` traits: the MPU-6000 IMU
//! ([`mpu6000`]) and DShot600 motor framing ([`dshot`]).
//!
//! May import: `parapet_core`, [`crate::app::autopilot`] (sample and command types). Not the
//! link, the PIL application or boards.

pub mod dshot;
pub mod mpu6000;
