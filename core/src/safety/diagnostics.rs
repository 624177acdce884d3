//! What the filter decided in one step: the [`Region`] of the state space, the
//! [`FilterFault`] behind a braking fallback, and the [`FilterDiagnostics`] record that logs,
//! telemetry and tests read. Re-exported from [`super::cbf`].
//!
//! May import: nothing beyond `core` (the bounds it names are [`super::cbf`]'s constants).

/// The region of the state space the filter found the vehicle in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Region {
    /// No obstacle given: `u = u*`.
    NoObstacle,
    /// `D_δ1`: every considered barrier has `h > δ1`: `u = u*`.
    Far,
    /// `D_u*`: the nominal input already satisfies every near constraint: `u = u*`.
    NominalSafe,
    /// `D_⊥`: the filter corrected `u*`.
    Perpendicular,
    /// Bad input: a bounded braking command was returned (see [`FilterFault`]).
    Fault,
}

impl Region {
    /// Every region, in code order ([`Region::code`] is the index).
    pub const ALL: [Region; 5] =
        [Region::NoObstacle, Region::Far, Region::NominalSafe, Region::Perpendicular, Region::Fault];

    /// Every region's [`Region::name`], in code order.
    pub const NAMES: [&'static str; 5] = [
        Region::NoObstacle.name(),
        Region::Far.name(),
        Region::NominalSafe.name(),
        Region::Perpendicular.name(),
        Region::Fault.name(),
    ];

    /// Small integer code for logs and telemetry (0..=4 in declaration order).
    pub fn code(&self) -> u8 {
        *self as u8
    }

    /// The region's name in reports (`trajectory.csv`'s `region`, the replay page): `none`,
    /// `far`, `nominal_safe`, `filtering` (`D_⊥`, the filter corrected the command), `fault`.
    pub const fn name(self) -> &'static str {
        match self {
            Region::NoObstacle => "none",
            Region::Far => "far",
            Region::NominalSafe => "nominal_safe",
            Region::Perpendicular => "filtering",
            Region::Fault => "fault",
        }
    }
}

/// Why the filter returned its braking command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FilterFault {
    /// Vehicle position or velocity non-finite or beyond [`INPUT_LIMIT`](super::cbf::INPUT_LIMIT).
    BadState,
    /// Nominal acceleration non-finite or beyond [`INPUT_LIMIT`](super::cbf::INPUT_LIMIT).
    BadNominal,
    /// An obstacle point or velocity non-finite or beyond [`INPUT_LIMIT`](super::cbf::INPUT_LIMIT).
    BadObstacle,
    /// The vehicle's centre is at an obstacle point: the direction `Π` is undefined.
    ZeroDistance,
}

/// What the filter did in one step (for logs, telemetry and tests).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FilterDiagnostics {
    /// Region of the decision.
    pub region: Region,
    /// Id of the deciding obstacle: the closest (single-barrier variants) or the
    /// most critical enforced one (multi variants); `None` when none.
    pub active_id: Option<u16>,
    /// Smallest `h̄ = h − δ` over all given obstacles, m²; `+∞` with none.
    pub h_bar: f32,
    /// `true` when the output differs from the nominal input.
    pub intervened: bool,
    /// Number of barriers enforced this step (0 ..= [`MAX_ACTIVE_BARRIERS`](super::cbf::MAX_ACTIVE_BARRIERS)).
    pub n_constraints: u8,
    /// Number of barriers with `h ≤ δ1` (may exceed `n_constraints`).
    pub n_near: u8,
    /// An enforced constraint needs more than `u_max` along its normal: the
    /// vehicle cannot keep `ḣ ≥ 0` with the acceleration it has.
    pub unavoidable: bool,
    /// The enforced constraints have no common solution (possible only with
    /// relative velocity); the least-violation answer was returned.
    pub infeasible: bool,
    /// Set when the output is the braking fallback.
    pub fault: Option<FilterFault>,
}

impl FilterDiagnostics {
    /// Nothing decided yet in `region`: no active obstacle, `h̄ = +∞`, no flags (with
    /// [`Region::NoObstacle`]: the diagnostics before the first filter step).
    pub const fn new(region: Region) -> Self {
        FilterDiagnostics {
            region,
            active_id: None,
            h_bar: f32::INFINITY,
            intervened: false,
            n_constraints: 0,
            n_near: 0,
            unavoidable: false,
            infeasible: false,
            fault: None,
        }
    }
}
