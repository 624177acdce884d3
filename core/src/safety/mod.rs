//! The safety filter: obstacle geometry and the closed-form CBF filter.
//!
//! Owns [`obstacle`] (obstacle points, shapes, the fixed-capacity nearest set the filter
//! reads), [`cbf`] (the filter laws, paper eq. 7-14 and the relative-velocity and
//! multi-barrier variants), [`variant`] (which law runs), [`diagnostics`] (the one
//! filter-diagnostics type, [`diagnostics::FilterDiagnostics`], and the regions),
//! [`braking`] (the braking-distance barrier), [`governor`] (the in-flight speed governor: the speed towards each direction limited to what can stop inside observed space), [`qp3`] (the exact 3-D projection the
//! multi-barrier variants use), [`obstacle_set`] (which offered points the fixed-capacity set keeps, and
//! the report of what was dropped) and [`plant_aware`] (the filter wrapped for the real plant:
//! actuation lag, disturbance observer, ground and ceiling barriers, stall detection). The
//! filter is this one folder. Runs inside the outer loop, at the outer rate.
//!
//! May import: the crate root foundation ([`crate::frame`], [`crate::fmath`],
//! [`crate::Vec3`]) and its own modules. Never the loops, the supervisor or the
//! controller facade.

pub mod braking;
pub mod cbf;
pub mod diagnostics;
pub mod governor;
pub mod obstacle;
pub mod obstacle_set;
pub mod plant_aware;
pub mod qp3;
pub mod variant;
