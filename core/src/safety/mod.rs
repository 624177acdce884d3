//! The safety filter: obstacle geometry and the closed-form CBF filter.
//!
//! Owns [`obstacle`] (obstacle points, shapes, the fixed-capacity nearest set the filter
//! reads), [`cbf`] (the filter laws, paper eq. 7-14 and the relative-velocity and
//! multi-barrier variants, and the one filter-diagnostics type,
//! [`cbf::FilterDiagnostics`]), [`braking`] (the braking-distance barrier) and [`qp3`] (the exact 3-D projection the multi-barrier
//! variants use). Runs inside the outer loop, at the outer rate.
//!
//! May import: the crate root foundation ([`crate::frame`], [`crate::fmath`],
//! [`crate::Vec3`]) and its own modules. Never the loops, the supervisor or the
//! controller facade.

pub mod braking;
pub mod cbf;
pub mod obstacle;
pub mod qp3;
