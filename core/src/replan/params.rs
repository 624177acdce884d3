//! The replanner's parameters (`RPL_*`, [`ReplanParams`]): units, ranges, defaults and
//! validation, one definition for the host and the firmware (`crate::params`).
//!
//! May import: `crate::param_decl`, the grid's capacity ([`super::grid::CELLS`]).

use super::grid::CELLS;
use crate::param_decl::{field, flag, on_off, Has, Param};

/// Parameters of the replanner (the `RPL_*` parameters).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplanParams {
    /// Replanning on. Default on (`RPL_ENABLE` 1, as ArduPilot's path planners in Auto;
    /// docs/perception.md § "On by default"); 0 leaves a blocked vehicle to the filter's stall.
    pub enable: bool,
    /// Checks per second, Hz. Default 2.
    pub rate_hz: f32,
    /// Wait after a replan (or no-path / budget result) before the next plan, s. Default 2.
    pub cooldown_s: f32,
    /// Length of the remaining path checked for a blockage, m. Default 3.
    pub horizon_m: f32,
    /// Clearance beyond the hull radius the detour keeps from obstacle cells, m. Default 0.1.
    pub margin_m: f32,
    /// Grid cell edge, m. Default 0.2 (the grid is 64 cells = 12.8 m across).
    pub cell_m: f32,
    /// A plan at flight level z searches the cells with a point within this height of z, m
    /// (whole slices: up to a slice more). Default 0.3 (above the hull radius: a desk top
    /// 0.45 m below the flight level is flown over, not around).
    pub band_m: f32,
    /// Expansions per search at most (≤ 4096). Default 4096.
    pub max_expansions: u16,
    /// A blockage must stand still this long before it is planned around, s (the
    /// confirmation of the module docs; 0: at once). Default 4.
    pub dwell_s: f32,
}

impl Default for ReplanParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl ReplanParams {
    /// On-board replanning's parameters (issue 38; `crate::params`, MAVLink `param_index` order).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 6] {
        [
            Param::new("RPL_ENABLE", "Replan", "", (0.0, 1.0), 0, flag!(enable),
                "Replan on board when the remaining path is blocked by what the sensors saw (docs/perception.md)").code(on_off),
            Param::new("RPL_RATE", "Replan", "Hz", (1.0, 50.0), 1, field!(rate_hz),
                "Checks per second of the remaining path against the replanner's grid"),
            Param::new("RPL_COOLDOWN", "Replan", "s", (0.0, 60.0), 2, field!(cooldown_s),
                "Wait after a replan (or a no-path result) before the next plan"),
            Param::new("RPL_HORIZON", "Replan", "m", (0.1, 50.0), 2, field!(horizon_m),
                "Length of the remaining path checked for a blockage"),
            Param::new("RPL_MARGIN", "Replan", "m", (0.0, 2.0), 3, field!(margin_m),
                "Clearance beyond the hull radius a detour keeps from sensed obstacles"),
            Param::new("RPL_DWELL", "Replan", "s", (0.0, 10.0), 1, field!(dwell_s),
                "A blockage must stay in place this long before a detour is planned (walkers pass)"),
        ]
    }
}

/// A hull radius the replanner uses: finite and ≥ 0, else 0.
pub fn sane_hull(hull: f32) -> f32 {
    if hull.is_finite() && hull >= 0.0 {
        hull
    } else {
        0.0
    }
}

impl ReplanParams {
    /// The defaults (see each field).
    pub const DEFAULT: ReplanParams = ReplanParams {
        enable: true,
        rate_hz: 2.0,
        cooldown_s: 2.0,
        horizon_m: 3.0,
        margin_m: 0.1,
        cell_m: 0.2,
        band_m: 0.3,
        max_expansions: CELLS as u16,
        dwell_s: 4.0,
    };

    /// Every field zero (invalid: a placeholder no request carries; [`super::Replanner::ZEROED`]).
    pub const ZEROED: ReplanParams = ReplanParams {
        enable: false,
        rate_hz: 0.0,
        cooldown_s: 0.0,
        horizon_m: 0.0,
        margin_m: 0.0,
        cell_m: 0.0,
        band_m: 0.0,
        max_expansions: 0,
        dwell_s: 0.0,
    };

    /// These parameters when [`ReplanParams::valid`], else the defaults.
    pub fn checked(self) -> Self {
        if self.valid() {
            self
        } else {
            ReplanParams::default()
        }
    }

    /// Every field finite and in its range (rate [1, 50] Hz, cooldown [0, 60] s, horizon
    /// (0, 50] m, margin [0, 2] m, cell [0.05, 1] m, band (0, 5] m, expansions ≥ 1, dwell
    /// [0, 10] s).
    pub fn valid(&self) -> bool {
        (1.0..=50.0).contains(&self.rate_hz)
            && (0.0..=60.0).contains(&self.cooldown_s)
            && self.horizon_m > 0.0
            && self.horizon_m <= 50.0
            && (0.0..=2.0).contains(&self.margin_m)
            && (0.05..=1.0).contains(&self.cell_m)
            && self.band_m > 0.0
            && self.band_m <= 5.0
            && self.max_expansions >= 1
            && (0.0..=10.0).contains(&self.dwell_s)
    }
}
