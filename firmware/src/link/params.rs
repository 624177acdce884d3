//! Tunable parameters over MAVLink (PARAM_SET / PARAM_REQUEST_READ → PARAM_VALUE). The
//! parameters — names, `param_index` order, `param_count`, units, ranges — are
//! [`parapet_core::params::TABLE`], shared with the host (which sends a scene's settings to a
//! processor-in-the-loop firmware) and the ground-station metadata (`cargo xtask params`).
//!
//! A PARAM_SET is checked against that parameter's own range only
//! ([`parapet_core::params::set`]), so any set of changes may be sent in any order; a
//! refused value keeps the old one and the answer carries the value in effect. Disarmed, the
//! cascade is rebuilt from the stored set whenever that set satisfies the cross-parameter
//! constraints (δ1 > δ, m·g < THR_MAX ≤ 4·VEH_ROTOR_TMAX), which clears its path, fix and
//! obstacles (set parameters before the mission upload); while it does not, the cascade keeps
//! the last consistent set and arming is refused. **Armed** (issue 41, in-flight tuning as
//! PX4): only [`IN_FLIGHT`] (PD gains, the filter's μ/δ/δ1/A/velocity margin, the path speed)
//! are taken, applied in place between two outer steps when the whole set stays consistent
//! (`OuterLoop::retune`); every other parameter is refused ([`ParamRejected::NotNow`]) and
//! the link sends the STATUSTEXT [`PARAM_ARMED_TEXT`] + the name.
//!
//! Owns nothing of its own; may import `parapet-core` only.

pub use parapet_core::params::{
    get, in_flight, index_of, set, ParamRejected, COUNT, IN_FLIGHT, NAMES, TABLE,
};

/// STATUSTEXT prefix of a PARAM_SET refused while armed (the parameter's name follows).
pub const PARAM_ARMED_TEXT: &str = "Set-up, disarm to change: ";
