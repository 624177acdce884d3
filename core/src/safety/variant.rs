//! Which filter law runs ([`FilterVariant`]): its names on the command line and in reports,
//! and the properties the rest of the cascade asks of it (relative velocity, several barriers).
//! The laws themselves are in [`super::cbf`] and [`super::braking`].
//!
//! Owns the filter-law parameter `CBF_VARIANT` ([`FilterVariant::params`]).
//!
//! May import: `param_decl`. Re-exported as `crate::cbf::FilterVariant`.

use crate::param_decl::{access, Has, Param};

/// Which filter law to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FilterVariant {
    /// Paper eq. 12 on the closest obstacle (eq. 14), vehicle velocity only.
    Paper,
    /// Closest obstacle, relative velocity `ṗ − v̄` and robust term for |ā| ≤ A.
    Relative,
    /// Every near barrier at once (exact min-norm QP over the K most critical), vehicle velocity.
    Multi,
    /// Every near barrier at once with relative velocity. The default.
    #[default]
    MultiRelative,
    /// The braking-distance barrier `h_b = |d| − r − s²/(2a_b) − τs` (`super::braking`),
    /// every near barrier at once, relative velocity.
    Braking,
}

impl FilterVariant {
    /// All variants, in documentation order.
    pub const ALL: [FilterVariant; 5] = [
        FilterVariant::Paper,
        FilterVariant::Relative,
        FilterVariant::Multi,
        FilterVariant::MultiRelative,
        FilterVariant::Braking,
    ];

    /// The variants on the paper's barrier `h = |d|² + μdᵀḋ` (all but [`FilterVariant::Braking`]).
    pub const SQUARED_DISTANCE: [FilterVariant; 4] =
        [FilterVariant::Paper, FilterVariant::Relative, FilterVariant::Multi, FilterVariant::MultiRelative];

    /// Name used on the command line and in reports.
    pub fn as_str(&self) -> &'static str {
        match self {
            FilterVariant::Paper => "paper",
            FilterVariant::Relative => "relative",
            FilterVariant::Multi => "multi",
            FilterVariant::MultiRelative => "multi-relative",
            FilterVariant::Braking => "braking",
        }
    }
    /// The code of `CBF_VARIANT`: the index in [`FilterVariant::ALL`].
    pub fn code(self) -> i32 {
        match self {
            FilterVariant::Paper => 0,
            FilterVariant::Relative => 1,
            FilterVariant::Multi => 2,
            FilterVariant::MultiRelative => 3,
            FilterVariant::Braking => 4,
        }
    }

    /// The variant of a `CBF_VARIANT` code.
    pub fn from_code(code: i32) -> Option<FilterVariant> {
        usize::try_from(code).ok().and_then(|i| FilterVariant::ALL.get(i).copied())
    }

    /// The filter law's parameter (`crate::params`): `CBF_VARIANT` (an unknown code keeps the law).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 1] {
        [
            Param::new("CBF_VARIANT", "CBF", "", (0.0, 4.0), 0,
                access!(|s| s.code() as f32, |s, v| *s = FilterVariant::from_code(v as i32).unwrap_or(*s)),
                "Filter law: 0 paper, 1 relative, 2 multi, 3 multi-relative, 4 braking (braking-distance barrier)")
                .key("filter").code(|c| FilterVariant::from_code(c).map(|v| v.as_str())),
        ]
    }

    /// `true` for the variants that use the obstacle's velocity.
    pub fn uses_relative_velocity(&self) -> bool {
        matches!(self, FilterVariant::Relative | FilterVariant::MultiRelative | FilterVariant::Braking)
    }
    /// `true` for the variants that enforce several barriers at once.
    pub fn is_multi(&self) -> bool {
        matches!(self, FilterVariant::Multi | FilterVariant::MultiRelative | FilterVariant::Braking)
    }
}

impl core::str::FromStr for FilterVariant {
    type Err = ();
    fn from_str(s: &str) -> Result<Self, ()> {
        FilterVariant::ALL.into_iter().find(|v| v.as_str() == s).ok_or(())
    }
}
