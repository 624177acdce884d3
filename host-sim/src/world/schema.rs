//! The scene file's schema: the TOML tables as serde reads them
//! (`RawScene` and its parts, [`ControllerOverrides`], [`SimSettings`]), the
//! per-table checks and the conversion of an obstacle table to a
//! [`SceneObstacle`], and the error texts (`line N, <table>, field k: …`).
//!
//! Owns the file format (documented in `scenes/README.md`). May import:
//! `parapet-core` (shapes), [`crate::input`] (limits, number format),
//! [`crate::sim`] (the `[vehicle]`, `[sensors]`, `[[sensor]]`, `[wind]`, `[faults]` tables),
//! [`super::obstacle`], [`super::frame`].

use serde::{Deserialize, Serialize};

use super::frame::{enu_arr_to_ned, to_f32};
use super::obstacle::{Motion, SceneObstacle};
use crate::input::{exact, limits, num};
use crate::sim::plant::VehicleParams;
use crate::sim::sensors::SensorParams;
use parapet_core::obstacle::Shape;
use parapet_core::outer::guidance::MissionGuidance;
use parapet_core::outer::path_yaw::YawMode;

/// Optional controller overrides (`[controller]` table). Missing values keep
/// the controller defaults (or the command-line values, which win over the scene).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerOverrides {
    /// Barrier velocity weight μ, s.
    pub mu: Option<f64>,
    /// Safety level δ, m² (the hull radius squared).
    pub delta: Option<f64>,
    /// Engagement level δ1 > δ, m².
    pub delta1: Option<f64>,
    /// PD position gain k_p, 1/s² (all axes).
    pub kp: Option<f64>,
    /// PD velocity gain k_d, 1/s (all axes).
    pub kd: Option<f64>,
    /// Filter variant: a `parapet_core::cbf::FilterVariant` name (`paper`, `relative`, `multi`,
    /// `multi-relative`; the parameter table's `CBF_VARIANT`).
    pub filter: Option<String>,
    /// Bound A on the unknown obstacle acceleration, m/s² (relative variants).
    pub accel_bound: Option<f64>,
    /// Velocity-uncertainty margin ε_v of the filter's constraint, m/s (default 0).
    pub velocity_margin: Option<f64>,
    /// Reference speed along the path, m/s; overrides `[mission] speed` when given.
    pub speed: Option<f64>,
    /// Yaw along the path: a `parapet_core::outer::path_yaw::YawMode` name (`hold`, `travel`;
    /// the parameter table's `MIS_YAW_MODE`).
    pub yaw_mode: Option<String>,
    /// Mission guidance: a `parapet_core::outer::guidance::MissionGuidance` name (`paper`,
    /// `trajectory`; the parameter table's `MIS_GUIDANCE`).
    pub guidance: Option<String>,
    /// Obstacle memory voxel edge, m (`PCP_VOXEL`; range-sensor perception only).
    pub mem_voxel: Option<f64>,
    /// Obstacle memory forget time, s (`PCP_FORGET`).
    pub mem_forget: Option<f64>,
    /// Cells this near the vehicle are not forgotten by age, m (`PCP_KEEP_NEAR`; 0: off).
    pub mem_keep_near: Option<f64>,
    /// See-through clearing margin, m (`PCP_CLR_MARGIN`).
    pub mem_clear_margin: Option<f64>,
    /// Largest cluster tracked for its velocity, m (`PCP_TRK_SIZE`; 0: no tracking).
    pub mem_track_size: Option<f64>,
    /// Field-of-view frontier margin, m (`PCP_FOV_MARGIN`; 0: no frontier).
    pub fov_margin: Option<f64>,
    /// Where nothing observed is left (`PCP_FOV_WALLS`): 0 speed cap, 1 walls, 2 walls
    /// while the heading is held.
    pub fov_walls: Option<f64>,
}

/// Optional simulation settings (`[sim]` table).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimSettings {
    /// Range of the proximity sensor, m: obstacles farther than this (surface
    /// distance from the centre of mass) are not reported to the controller. Default 3.
    pub sensing_range: Option<f64>,
    /// Duration limit of a run, s. Default: 1.5 × path length / min(speed, 1 m/s) + 15 s.
    pub duration: Option<f64>,
    /// Plant integration step, s. Default 0.001 (1 kHz).
    pub dt: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawScene {
    pub(crate) name: String,
    #[serde(default)]
    pub(crate) description: Option<String>,
    pub(crate) bounds: RawBounds,
    pub(crate) mission: RawMission,
    #[serde(default)]
    pub(crate) vehicle: Option<VehicleParams>,
    #[serde(default)]
    pub(crate) controller: Option<ControllerOverrides>,
    #[serde(default)]
    pub(crate) sensors: Option<SensorParams>,
    #[serde(default)]
    pub(crate) sim: Option<SimSettings>,
    #[serde(default)]
    pub(crate) wind: Option<crate::sim::disturbance::wind::WindParams>,
    #[serde(default)]
    pub(crate) plant: Option<toml::Table>,
    #[serde(default)]
    pub(crate) faults: Option<crate::sim::disturbance::faults::FaultParams>,
    #[serde(default)]
    pub(crate) obstacles: Vec<RawObstacle>,
    /// The battery model (`[battery]`, `crate::sim::battery`; issue 22).
    #[serde(default)]
    pub(crate) battery: Option<crate::sim::battery::BatteryModelParams>,
    /// Range sensors (`[[sensor]]`, `crate::sim::range`), for `--perception scene`.
    #[serde(default)]
    pub(crate) sensor: Vec<crate::sim::range::RangeSensorSpec>,
}

/// The `[[sensor]]` tables resolved and checked; errors name the table
/// (`sensor[i]`), the field, the value and the allowed range.
pub(crate) fn convert_sensors(
    raw: &[crate::sim::range::RangeSensorSpec],
) -> Result<Vec<crate::sim::range::RangeSensor>, String> {
    use crate::sim::range::MAX_SENSORS;
    if raw.len() > MAX_SENSORS {
        return Err(format!(
            "[[sensor]]: {} tables, at most {MAX_SENSORS} range sensors per vehicle",
            raw.len()
        ));
    }
    let mut out: Vec<crate::sim::range::RangeSensor> = Vec::with_capacity(raw.len());
    for (i, r) in raw.iter().enumerate() {
        let s = r.resolve(i).map_err(|m| format!("sensor[{i}]: {m}"))?;
        if out.iter().any(|o| o.name == s.name) {
            return Err(format!(
                "sensor[{i}]: field `name`: {:?} is used by an earlier sensor (names must differ)",
                s.name
            ));
        }
        out.push(s);
    }
    Ok(out)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawBounds {
    #[serde(deserialize_with = "exact::array")]
    pub(crate) min: [f64; 3],
    #[serde(deserialize_with = "exact::array")]
    pub(crate) max: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawMission {
    #[serde(deserialize_with = "exact::array")]
    pub(crate) start: [f64; 3],
    #[serde(deserialize_with = "exact::array")]
    pub(crate) goal: [f64; 3],
    pub(crate) speed: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawObstacle {
    kind: String,
    #[serde(default)]
    name: Option<String>,
    #[serde(default, deserialize_with = "exact::option_array")]
    center: Option<[f64; 3]>,
    radius: Option<f64>,
    #[serde(default, deserialize_with = "exact::option_array")]
    min: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::option_array")]
    max: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::option_array")]
    base: Option<[f64; 3]>,
    height: Option<f64>,
    #[serde(default, deserialize_with = "exact::option_array")]
    velocity: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::option_arrays")]
    waypoints: Option<Vec<[f64; 4]>>,
    /// `false`: in the world, not in the map (`SceneObstacle::mapped`); default `true`.
    #[serde(default)]
    mapped: Option<bool>,
}

/// `|x| ≤ MAX_COORDINATE_M` for every component.
pub(crate) fn within_limit(a: &[f64]) -> bool {
    a.iter().all(|x| x.abs() <= limits::MAX_COORDINATE_M)
}

/// "field `f`: <what> (got <value>; allowed <allowed>)", numbers as a user
/// writes them ([`num`]: `1e9`, not `1000000000.0`).
pub(crate) fn bad(field: &str, what: &str, value: impl Shown, allowed: &str) -> String {
    format!("field `{field}`: {what} (got {}; allowed {allowed})", value.shown())
}

/// A value in an error message.
pub(crate) trait Shown {
    fn shown(&self) -> String;
}

impl Shown for f64 {
    fn shown(&self) -> String {
        num(*self)
    }
}

impl<const N: usize> Shown for [f64; N] {
    fn shown(&self) -> String {
        let parts: Vec<String> = self.iter().map(|x| num(*x)).collect();
        format!("[{}]", parts.join(", "))
    }
}

impl<T: Shown> Shown for &T {
    fn shown(&self) -> String {
        (*self).shown()
    }
}

impl ControllerOverrides {
    /// Sets the field of parameter `p`'s key (`[controller] key = x`, as `--param NAME=x` asks):
    /// the number, or, for a key that takes a name (`filter`, `yaw_mode`, `guidance`), the name of code `x`
    /// from the table. Through the table's key and serde, so no field is named here. `Err` when
    /// `p` has no key or the field takes neither.
    pub fn set_param(&mut self, p: &parapet_core::params::Param, x: f64) -> Result<(), String> {
        let key = p.key.ok_or_else(|| format!("{} has no [controller] key", p.name))?;
        let mut table = match toml::Value::try_from(&*self) {
            Ok(toml::Value::Table(t)) => t,
            _ => return Err("internal: [controller] is not a table".into()),
        };
        table.insert(key.into(), toml::Value::Float(x));
        if let Ok(c) = toml::Value::Table(table.clone()).try_into::<ControllerOverrides>() {
            *self = c;
            return Ok(());
        }
        let name = p.label.and_then(|l| l(x as i32)).ok_or_else(|| format!("{key} = {x}: no such code"))?;
        table.insert(key.into(), toml::Value::String(name.into()));
        *self =
            toml::Value::Table(table).try_into::<ControllerOverrides>().map_err(|e| format!("{key}: {e}"))?;
        Ok(())
    }

    /// The numeric fields by key: each key is a [`parapet_core::params::Param::key`] of the
    /// controller's parameter table, which gives its unit and range (`filter` and `yaw_mode`,
    /// names, are `CBF_VARIANT`'s and `MIS_YAW_MODE`'s keys; `guidance` `MIS_GUIDANCE`'s).
    pub fn numbers(&self) -> [(&'static str, Option<f64>); 15] {
        [
            ("mu", self.mu),
            ("delta", self.delta),
            ("delta1", self.delta1),
            ("kp", self.kp),
            ("kd", self.kd),
            ("accel_bound", self.accel_bound),
            ("velocity_margin", self.velocity_margin),
            ("speed", self.speed),
            ("mem_voxel", self.mem_voxel),
            ("mem_forget", self.mem_forget),
            ("mem_keep_near", self.mem_keep_near),
            ("mem_clear_margin", self.mem_clear_margin),
            ("mem_track_size", self.mem_track_size),
            ("fov_margin", self.fov_margin),
            ("fov_walls", self.fov_walls),
        ]
    }
}

/// `x` is in `p`'s range as the controller sees it (in `f32`: 1e300 is not finite there).
pub(crate) fn param_accepts(p: &parapet_core::params::Param, x: f64) -> bool {
    x.is_finite() && p.check(x as f32).is_ok()
}

/// `[controller]` values against the parameter table's ranges
/// ([`parapet_core::params::TABLE`]), then δ1 > δ when both are given.
pub(crate) fn validate_controller(c: &ControllerOverrides) -> Result<(), String> {
    for (key, x) in c.numbers() {
        let (Some(x), Some(p)) = (x, parapet_core::params::by_key(key)) else { continue };
        if !param_accepts(p, x) {
            let what = format!("out of range ({})", p.description);
            return Err(bad(key, &what, x, &p.range().to_string()));
        }
    }
    if let (Some(d), Some(d1)) = (c.delta, c.delta1) {
        if d1 as f32 <= d as f32 {
            return Err(bad("delta1", &format!("must exceed delta = {d}"), d1, &format!("delta1 > {d}")));
        }
    }
    if let Some(f) = &c.filter {
        if f.parse::<parapet_core::cbf::FilterVariant>().is_err() {
            let names = parapet_core::cbf::FilterVariant::ALL.map(|v| v.as_str());
            return Err(format!("field `filter`: unknown variant {f:?}, expected one of {names:?}"));
        }
    }
    if let Some(m) = &c.yaw_mode {
        if m.parse::<YawMode>().is_err() {
            let names = YawMode::ALL.map(|v| v.as_str());
            return Err(format!("field `yaw_mode`: unknown yaw mode {m:?}, expected one of {names:?}"));
        }
    }
    if let Some(g) = &c.guidance {
        if g.parse::<MissionGuidance>().is_err() {
            let names = MissionGuidance::ALL.map(|v| v.as_str());
            return Err(format!("field `guidance`: unknown guidance {g:?}, expected one of {names:?}"));
        }
    }
    Ok(())
}

pub(crate) fn validate_sensors(s: &SensorParams) -> Result<(), String> {
    let lat_cap = limits::max_position_latency_s(s.position_source.is_mocap());
    for (field, x) in [
        ("gyro_noise", s.gyro_noise),
        ("gyro_bias", s.gyro_bias),
        ("accel_noise", s.accel_noise),
        ("accel_bias", s.accel_bias),
        ("position_noise", s.position_noise),
        ("velocity_noise", s.velocity_noise),
        ("position_latency", s.position_latency),
        ("obstacle_velocity_noise", s.obstacle_velocity_noise),
        ("rate", s.rate),
        ("dropout_start", s.dropout_start),
        ("dropout_length", s.dropout_length),
    ] {
        let (cap, unit) = match field {
            "position_latency" => (lat_cap, " s"),
            "rate" => (limits::MAX_FIX_RATE_HZ, " Hz"),
            "dropout_start" | "dropout_length" => (limits::MAX_DURATION_CEILING_S, " s"),
            _ => (limits::MAX_SENSOR_NOISE, ""),
        };
        if !(x.is_finite() && (0.0..=cap).contains(&x)) {
            let why = if field == "position_latency" && s.position_source.is_mocap() {
                format!(
                    "beyond the cap (the flight controller's position timeout is {} s; a filtered \
                     `position_source` allows {} s)",
                    num(limits::position_timeout_s()),
                    num(limits::MAX_FILTERED_LATENCY_S)
                )
            } else if field == "position_latency" {
                "beyond the navigation filter's history".to_string()
            } else {
                "out of range".to_string()
            };
            return Err(bad(field, &why, x, &format!("0 ≤ {field} ≤ {}{unit}", num(cap))));
        }
    }
    Ok(())
}

/// The keys a `[sensors]` table of the scene text `src` sets (for
/// [`SensorParams::apply_source_preset`]); empty when there is no such table.
pub(crate) fn sensors_keys(src: &str) -> Vec<String> {
    let table: toml::Table = toml::from_str(src).unwrap_or_default();
    match table.get("sensors") {
        Some(toml::Value::Table(t)) => t.keys().cloned().collect(),
        _ => Vec::new(),
    }
}

pub(crate) fn convert_obstacle(o: RawObstacle) -> Result<SceneObstacle, String> {
    let max = limits::MAX_COORDINATE_M;
    let finite3 = |field: &str, a: [f64; 3]| {
        if a.iter().all(|x| x.is_finite()) && within_limit(&a) {
            Ok(enu_arr_to_ned(a))
        } else {
            Err(bad(field, "out of range", a, &format!("finite, |x| ≤ {max}")))
        }
    };
    let positive = |field: &str, x: f64| {
        if x.is_finite() && x > 0.0 && x <= max {
            Ok(x as f32)
        } else {
            Err(bad(field, "must be finite and > 0", x, &format!("0 < {field} ≤ {max} m")))
        }
    };
    let need = |field: &str, present: bool| {
        if present {
            Ok(())
        } else {
            Err(format!("field `{field}` is missing (required for kind = {:?})", o.kind))
        }
    };
    let forbid = |field: &str, present: bool| {
        if present {
            Err(format!("field `{field}` is not allowed for kind = {:?}", o.kind))
        } else {
            Ok(())
        }
    };
    let shape = match o.kind.as_str() {
        "sphere" => {
            forbid("min", o.min.is_some())?;
            forbid("max", o.max.is_some())?;
            forbid("base", o.base.is_some())?;
            forbid("height", o.height.is_some())?;
            need("center", o.center.is_some())?;
            need("radius", o.radius.is_some())?;
            let c = finite3("center", o.center.unwrap_or_default())?;
            Shape::sphere(to_f32(&c), positive("radius", o.radius.unwrap_or_default())?)
        }
        "box" => {
            forbid("center", o.center.is_some())?;
            forbid("radius", o.radius.is_some())?;
            forbid("base", o.base.is_some())?;
            forbid("height", o.height.is_some())?;
            need("min", o.min.is_some())?;
            need("max", o.max.is_some())?;
            let (mn, mx) = (o.min.unwrap_or_default(), o.max.unwrap_or_default());
            let (a, b) = (finite3("min", mn)?, finite3("max", mx)?);
            if (0..3).any(|i| mn[i] >= mx[i]) {
                return Err(format!(
                    "field `max`: must exceed `min` in every coordinate (min {mn:?}, max {mx:?})"
                ));
            }
            Shape::aabb(to_f32(&a), to_f32(&b))
        }
        "cylinder" => {
            forbid("center", o.center.is_some())?;
            forbid("min", o.min.is_some())?;
            forbid("max", o.max.is_some())?;
            need("base", o.base.is_some())?;
            need("radius", o.radius.is_some())?;
            need("height", o.height.is_some())?;
            let b = finite3("base", o.base.unwrap_or_default())?;
            let r = positive("radius", o.radius.unwrap_or_default())?;
            let h = positive("height", o.height.unwrap_or_default())?;
            Shape::cylinder(to_f32(&b), r, h)
        }
        other => {
            return Err(format!(
                "field `kind`: unknown kind {other:?}, expected \"sphere\", \"box\" or \"cylinder\""
            ))
        }
    };
    let motion = match (o.velocity, o.waypoints) {
        (Some(_), Some(_)) => {
            return Err("field `waypoints`: give either `velocity` or `waypoints`, not both".into())
        }
        (Some(v), None) => Motion::Velocity(finite3("velocity", v)?),
        (None, Some(w)) => {
            if w.is_empty() {
                return Err("field `waypoints`: needs at least one [t, x, y, z] entry".into());
            }
            let mut out = Vec::with_capacity(w.len());
            for (k, e) in w.iter().enumerate() {
                if !(e.iter().all(|x| x.is_finite()) && within_limit(&e[1..])) {
                    let allowed = format!("finite, |x| ≤ {max} m");
                    return Err(bad("waypoints", &format!("entry {k} out of range"), e, &allowed));
                }
                if let Some((t_prev, _)) = out.last() {
                    if e[0] <= *t_prev {
                        return Err(format!("field `waypoints`: times must increase strictly (entry {k})"));
                    }
                }
                out.push((e[0], enu_arr_to_ned([e[1], e[2], e[3]])));
            }
            Motion::Waypoints(out)
        }
        (None, None) => Motion::Static,
    };
    Ok(SceneObstacle { name: o.name, shape, motion, mapped: o.mapped.unwrap_or(true) })
}

/// Turn a TOML/serde error into "line N, <table>, field `k`: message".
pub(crate) fn describe_toml_error(src: &str, e: &toml::de::Error) -> String {
    let msg = e.message().trim().to_string();
    let Some(span) = e.span() else {
        return msg;
    };
    let start = span.start.min(src.len());
    // Up to the end of the line where the span starts: a missing key's span is
    // its table's `[[obstacles]]` header, which must count.
    let line_end = src[start..].find('\n').map_or(src.len(), |k| start + k);
    let before = &src[..start];
    let through = &src[..line_end];
    let line_no = before.matches('\n').count() + 1;
    let line = src.lines().nth(line_no - 1).unwrap_or("");
    // The table the offending line belongs to.
    let mut table = String::from("top level");
    let mut n_obstacles = 0usize;
    for l in through.lines() {
        let t = l.trim();
        if t.starts_with("[[obstacles]]") {
            n_obstacles += 1;
            table = format!("obstacles[{}]", n_obstacles - 1);
        } else if t.starts_with('[') {
            table = t.split(']').next().map(|s| format!("{s}]")).unwrap_or_default();
        }
    }
    let mut out = format!("line {line_no}, {table}");
    if let Some((key, _)) = line.split_once('=') {
        let key = key.trim();
        if !key.is_empty() && !key.starts_with('[') && !msg.contains(&format!("`{key}`")) {
            out.push_str(&format!(", field `{key}`"));
        }
    }
    out.push_str(": ");
    out.push_str(&msg);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every `[controller]` key is a key of the parameter table (so its range and unit come
    /// from there), and `numbers()` names the serde fields as the file spells them.
    #[test]
    fn controller_keys_are_parameter_table_keys() {
        let all = ControllerOverrides {
            mu: Some(1.0),
            delta: Some(2.0),
            delta1: Some(3.0),
            kp: Some(4.0),
            kd: Some(5.0),
            filter: Some("paper".into()),
            accel_bound: Some(6.0),
            velocity_margin: Some(7.0),
            speed: Some(8.0),
            yaw_mode: Some("travel".into()),
            guidance: Some("trajectory".into()),
            mem_voxel: Some(0.25),
            mem_forget: Some(9.0),
            mem_keep_near: Some(0.5),
            mem_clear_margin: Some(0.5),
            mem_track_size: Some(0.0),
            fov_margin: Some(0.5),
            fov_walls: Some(1.0),
        };
        let table = toml::Table::try_from(&all).unwrap();
        let numbers = all.numbers();
        assert_eq!(table.len(), numbers.len() + 3);
        for (key, x) in numbers {
            assert_eq!(table[key].as_float(), x, "{key}");
            assert!(parapet_core::params::by_key(key).is_some(), "{key} is not in the parameter table");
        }
        assert_eq!(parapet_core::params::by_key("filter").map(|p| p.name), Some("CBF_VARIANT"));
        let with_filter = |f: &str| {
            validate_controller(&ControllerOverrides { filter: Some(f.into()), ..Default::default() })
        };
        let e = with_filter("fast").unwrap_err();
        assert!(e.contains("\"fast\"") && e.contains("multi-relative"), "{e}");
        assert_eq!(with_filter("relative"), Ok(()));
        assert_eq!(parapet_core::params::by_key("yaw_mode").map(|p| p.name), Some("MIS_YAW_MODE"));
        let with_yaw = |m: &str| {
            validate_controller(&ControllerOverrides { yaw_mode: Some(m.into()), ..Default::default() })
        };
        let e = with_yaw("north").unwrap_err();
        assert!(e.contains("field `yaw_mode`") && e.contains("\"north\"") && e.contains("travel"), "{e}");
        assert_eq!(with_yaw("travel"), Ok(()));
        assert_eq!(with_yaw("hold"), Ok(()));
        assert_eq!(parapet_core::params::by_key("guidance").map(|p| p.name), Some("MIS_GUIDANCE"));
        let with_guidance = |g: &str| {
            validate_controller(&ControllerOverrides { guidance: Some(g.into()), ..Default::default() })
        };
        let e = with_guidance("fast").unwrap_err();
        assert!(e.contains("field `guidance`") && e.contains("\"fast\"") && e.contains("trajectory"), "{e}");
        assert_eq!(with_guidance("paper"), Ok(()));
        assert_eq!(with_guidance("trajectory"), Ok(()));
    }

    #[test]
    fn controller_values_are_checked_against_the_table() {
        let with = |f: fn(&mut ControllerOverrides)| {
            let mut c = ControllerOverrides::default();
            f(&mut c);
            validate_controller(&c)
        };
        assert_eq!(with(|_| {}), Ok(()));
        assert_eq!(with(|c| c.mu = Some(100.0)), Ok(()));
        let e = with(|c| c.mu = Some(100.5)).unwrap_err();
        assert!(e.contains("field `mu`") && e.contains("100.5") && e.contains("0.01 ≤ mu ≤ 100 s"), "{e}");
        let e = with(|c| c.kp = Some(1e300)).unwrap_err();
        assert!(e.contains("field `kp`") && e.contains("1e300"), "{e}");
        let e = with(|c| c.velocity_margin = Some(-0.1)).unwrap_err();
        assert!(e.contains("velocity_margin") && e.contains("0 ≤ velocity_margin ≤ 10 m/s"), "{e}");
        let e = with(|c| c.speed = Some(0.0)).unwrap_err();
        assert!(e.contains("speed") && e.contains("m/s"), "{e}");
        assert_eq!(with(|c| c.mem_track_size = Some(0.0)), Ok(()));
        let e = with(|c| c.mem_voxel = Some(0.01)).unwrap_err();
        assert!(e.contains("field `mem_voxel`") && e.contains("0.02 ≤ mem_voxel ≤ 5 m"), "{e}");
        let e = with(|c| c.fov_margin = Some(-1.0)).unwrap_err();
        assert!(e.contains("field `fov_margin`") && e.contains("0 ≤ fov_margin ≤ 5 m"), "{e}");
        let e = with(|c| {
            c.delta = Some(0.2);
            c.delta1 = Some(0.1)
        })
        .unwrap_err();
        assert!(e.contains("delta1") && e.contains("0.2"), "{e}");
    }
}
