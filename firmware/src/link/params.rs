//! Tunable parameters over MAVLink (PARAM_SET / PARAM_REQUEST_READ → PARAM_VALUE): the
//! table of names and how each maps onto `ControllerParams` lives in
//! [`parapet_core::params`] (shared with the host, which uses it to give a processor-in-the-loop
//! firmware the scene's settings). The cascade takes a new value only while disarmed and only
//! if the whole parameter set still validates; it is rebuilt, which clears its path, fix and
//! obstacles (set parameters before the mission upload).

pub use parapet_core::params::{get, index_of, set, ParamRejected, NAMES};
