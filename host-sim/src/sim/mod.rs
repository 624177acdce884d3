//! The simulated vehicle and its environment (no controller, no scene).
//!
//! * [`plant`]: rigid-body 6-DOF quadrotor (NED/FRD), RK4 at 1 kHz, RotorPy-style aerodynamics.
//! * [`battery`]: LiPo pack (charge, voltage sag with the motor current) and its voltage/current sensor.
//! * [`sensors`]: IMU and position/velocity measurement with noise and latency.
//! * [`source`]: the position-source presets (mocap, GPS, RTK, VIO), magnetometer yaw, barometer.
//! * [`disturbance`]: wind (steady, Dryden, gusts), vehicle mismatch, sensor/report/rotor faults.
//! * [`range`]: range sensors (lidar, depth camera, ToF): description, beam pattern, noise, dropouts.
//! * [`replay`]: open-loop replay of rotor speeds from a CSV.
//! * [`track_ids`]: the `u16` track ids of the obstacles in view (scenes beyond 65,535 obstacles).
//!
//! Owns the physics and sensor models. May import: `parapet-core`, and of
//! host-sim only [`crate::input`] (errors, limits).
/// Plant step and inner-loop period, s (1 kHz: `parapet_core::wire::rates`).
pub const INNER_DT: f64 = 1.0 / parapet_core::wire::rates::INNER_RATE_HZ as f64;

pub mod battery;
pub mod coverage;
pub mod disturbance;
pub mod plant;
pub mod range;
pub mod replay;
pub mod sensors;
pub mod source;
pub mod track_ids;
