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
//! ## Modules (folders follow the cascade, `docs/cascade.md`)
//! - [`outer`]: the outer loop — [`waypoint`] follower, [`tracking`] (PD, eq. 2),
//!   [`thrust`] (acceleration → collective thrust + attitude, eq. 4-5).
//! - [`safety`]: the safety filter in one folder — [`obstacle`] geometry and set, the
//!   closed-form CBF filter [`cbf`] (paper eq. 7-14, plus the relative-velocity,
//!   multi-barrier and braking variants), [`braking`], [`qp3`], the obstacle-set policy
//!   [`obstacle_set`] (which offered points the set keeps at capacity, most critical first,
//!   one per obstacle, and the report of what was dropped) and the plant-aware wrapping
//!   [`plant_aware`] (actuation lag, disturbance observer, ground/ceiling barriers, stall
//!   detection; issue 17).
//! - [`inner`]: the inner loop — [`estimator`], [`attitude`] (attitude P, rate PID), [`mixer`].
//! - [`supervisor`]: [`failsafe`] state machine, arming, modes, landing.
//! - [`msg`]: the `Copy` messages the stages exchange (attitude command, state estimate, …).
//! - [`controller`]: [`controller::FlightController`], the whole cascade behind one API;
//!   [`config`]: its parameters ([`controller::ControllerParams`]) and their validation.
//! - [`schedule`]: which inner step runs the outer step ([`schedule::OuterSchedule`]).
//! - [`airframe`], [`frame`], [`fmath`]: vehicle description, frames and units, square
//!   root (FPU instruction on the Cortex-M4F), min, max, single-precision trigonometry.
//! - [`params`]: named controller parameters (the firmware's MAVLink parameters), the one
//!   table gathered from the declarations beside each stage's struct ([`param_decl`]).
//! - [`perception`]: range scans → a bounded world-frame obstacle memory (voxel merge,
//!   ageing, see-through clearing, cluster velocity tracks, the field-of-view frontier) →
//!   the filter's obstacle points (issue 19).
//! - [`replan`]: on-board replanning around what the map lacked (grid A* on the sensed
//!   obstacles, trigger, cooldown; issue 38).
//! - [`rc`]: pilot input (CRSF/SBUS/MAVLink manual control → [`rc::RcInput`]; issue 21).
//! - [`battery`]: the battery measurement message ([`battery::BatteryState`]) and its estimator
//!   (filter, cell count, low/critical levels, remaining charge; issue 22).
//! - [`calibration`]: IMU correction (accelerometer offset/scale, board orientation, level trim)
//!   and the accelerometer six-position calibration (issue 22).
//! - [`motor_test`]: the MAV_CMD_DO_MOTOR_TEST state machine (issue 22).
//! - [`wire`]: the firmware ↔ host link contract (ids, names, codes, lockstep rule, motor sanitiser).
//!
//! The modules of the folders are re-exported at the root (`parapet_core::cbf`,
//! `parapet_core::estimator`, …), so each has one short path.
//!
//! ## Unsafe code
//! Denied crate-wide. The one exception is `fmath::sqrtf` on ARM hard-float
//! targets: a five-instruction `asm!` around `VSQRT.F32` (see its SAFETY note),
//! because stable Rust has no `sqrtf` in `core` and libm's is a software routine.
#![no_std]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod airframe;
pub mod battery;
pub mod calibration;
pub mod config;
pub mod controller;
pub mod fmath;
pub mod frame;
pub mod inner;
pub mod motor_test;
pub mod msg;
pub mod nav;
pub mod outer;
pub mod param_decl;
pub mod params;
pub mod perception;
pub mod rc;
pub mod replan;
pub mod safety;
pub mod schedule;
pub mod supervisor;
pub mod wire;

pub use inner::{attitude, estimator, mixer};
pub use outer::{thrust, tracking, waypoint};
pub use safety::{braking, cbf, governor, obstacle, obstacle_set, plant_aware, qp3};
pub use supervisor::failsafe;

pub use nalgebra;

/// 3-vector in `f32` (world NED unless a doc comment says otherwise).
pub type Vec3 = nalgebra::Vector3<f32>;
