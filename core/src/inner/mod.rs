//! The inner loop (default 1 kHz): attitude estimator → attitude P → rate PID → mixer,
//! producing the motor outputs.
//!
//! Owns [`estimator`] (Mahony attitude estimator with gyro-bias calibration),
//! [`attitude`] (attitude P and rate PID) and [`mixer`] (thrust and torque → rotor
//! thrusts and throttles).
//!
//! May import: the crate root foundation ([`crate::frame`], [`crate::fmath`],
//! [`crate::airframe`], [`crate::Vec3`]). Never [`crate::outer`], [`crate::safety`] or
//! [`crate::supervisor`]: what it needs from the outer loop arrives as a message.

pub mod attitude;
pub mod estimator;
pub mod mixer;
