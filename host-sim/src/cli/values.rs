//! Value parsers and computed help lines of the `run` family's options (`--filter`,
//! `--guidance`, `--yaw-mode`, `--wind`; the controller options' defaults from the parameter
//! table). The lists of names come from the core's enums, never written here.
//!
//! May import: `parapet_core` (the enums and the parameter table), [`crate::flight::runner`].

use parapet_core::cbf::FilterVariant;
use parapet_core::outer::guidance::MissionGuidance;
use parapet_core::outer::path_yaw::YawMode;

/// The help line of `--speed` with the parameter table's range.
pub(super) fn speed_help() -> String {
    let range = parapet_core::params::by_key("speed").map(|p| p.range().to_string()).unwrap_or_default();
    format!("Reference speed along the path, m/s, {range} [default: the scene's]")
}

/// The help line of a controller option with its built-in default (the parameter
/// table's, shortest decimals).
pub(super) fn default_help(what: &str, name: &str) -> String {
    let d = crate::flight::runner::table_default(name);
    format!("{what} [default: the scene's [controller] {name}, else {d}]")
}

/// `x,y,z` (three finite numbers, commas, optional spaces).
pub(super) fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected x,y,z (three numbers), got {s:?}"));
    }
    let mut v = [0.0; 3];
    for (k, p) in parts.iter().enumerate() {
        v[k] = p
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{p:?} is not a finite number"))?;
    }
    Ok(v)
}

pub(super) fn parse_variant(s: &str) -> Result<FilterVariant, String> {
    s.parse().map_err(|_| {
        let names: Vec<&str> = FilterVariant::ALL.iter().map(|v| v.as_str()).collect();
        format!("unknown filter {s:?}: expected one of {}", names.join(", "))
    })
}

pub(crate) fn parse_guidance(s: &str) -> Result<MissionGuidance, String> {
    s.parse().map_err(|_| {
        let names: Vec<&str> = MissionGuidance::ALL.iter().map(|g| g.as_str()).collect();
        format!("unknown guidance {s:?}: expected one of {}", names.join(", "))
    })
}

/// A `--position-source` name (the `[sensors] position_source` presets, `crate::sim::source`).
pub(crate) fn parse_position_source(s: &str) -> Result<crate::sim::source::PositionSource, String> {
    use crate::sim::source::PositionSource;
    s.parse().map_err(|()| {
        let names: Vec<&str> = PositionSource::ALL.iter().map(|p| p.as_str()).collect();
        format!("unknown position source {s:?}: expected one of {}", names.join(", "))
    })
}

pub(super) fn parse_assumption(s: &str) -> Result<crate::sim::coverage::Assumption, String> {
    s.parse()
}

pub(super) fn parse_yaw_mode(s: &str) -> Result<YawMode, String> {
    s.parse().map_err(|_| format!("unknown yaw mode {s:?}: expected hold or travel"))
}
