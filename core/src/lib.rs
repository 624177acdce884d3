//! # parapet-core
//!
//! The hardware-independent heart of Parapet: a `#![no_std]`, allocation-free
//! flight-control library in `f32`. The same code runs on the STM32F405 and in
//! the host simulator.
//!
//! ## Frame, units and signs (stated once for the whole project)
//! See [`frame`]: the world frame is **NED** (x north, y east, z down), the
//! body frame is **FRD** (x forward, y right, z down), SI units everywhere
//! (m, s, kg, N, rad). Scene files and plots use ENU (z up); they are converted
//! at the boundary with [`frame::enu_to_ned`] / [`frame::ned_to_enu`].
//!
//! ## Modules
//! - [`obstacle`]: obstacle geometry (closest surface point, signed distance)
//!   and the fixed-capacity [`obstacle::ObstacleSet`] the filter reads.
//! - [`obstacle_set`]: which offered points the set keeps at capacity (most
//!   critical first, one per obstacle) and the report of what was dropped.
//! - [`cbf`]: the closed-form Control Barrier Function safety filter
//!   (paper eq. 7-14, plus the relative-velocity and multi-barrier variants).
//! - [`tracking`]: PD position tracking (eq. 2).
//! - [`thrust`]: acceleration command → collective thrust + attitude reference (eq. 4-5).
//! - [`fmath`]: square root (FPU instruction on the Cortex-M4F), min, max,
//!   single-precision trigonometry.
//! - [`robust`]: the plant-aware wrapping of the filter (actuation lag, disturbance
//!   observer, ground/ceiling barriers, stall detection; issue 17).
//! - [`params`]: named controller parameters (the firmware's MAVLink parameters).
//!
//! ## Unsafe code
//! Denied crate-wide. The one exception is `fmath::sqrtf` on ARM hard-float
//! targets: a five-instruction `asm!` around `VSQRT.F32` (see its SAFETY note),
//! because stable Rust has no `sqrtf` in `core` and libm's is a software routine.
#![no_std]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod airframe;
pub mod attitude;
pub mod cbf;
pub mod controller;
pub mod estimator;
pub mod failsafe;
pub mod fmath;
pub mod frame;
pub mod mixer;
pub mod obstacle;
pub mod obstacle_set;
pub mod params;
pub mod qp3;
pub mod robust;
pub mod thrust;
pub mod tracking;
pub mod waypoint;

pub use nalgebra;

/// 3-vector in `f32` (world NED unless a doc comment says otherwise).
pub type Vec3 = nalgebra::Vector3<f32>;
