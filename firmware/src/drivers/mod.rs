//! Device drivers, hardware-independent over `embedded-hal-async` traits: the MPU-6000 IMU
//! ([`mpu6000`]), DShot600 motor framing ([`dshot`]) and the RC receiver UART protocols
//! ([`rc_uart`]: CRSF / SBUS line settings, byte chunks → receiver frames).
//!
//! May import: `parapet_core` (`rc` for the receiver), [`crate::app::autopilot`] (sample and command types). Not the
//! link, the PIL application or boards.

pub mod dshot;
pub mod mpu6000;
pub mod rc_uart;
