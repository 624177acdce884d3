//! The campaign file (TOML) and the per-flight draws.
//!
//! ```toml
//! name = "ci"                 # label
//! seed = 1                    # campaign seed: flight i's draws depend only on (seed, i)
//! flights = 200
//! [run]                       # `parapet run` options every flight gets (optional)
//! filter = "multi-relative"   #   filter, yaw_mode, noise (bool), no_cbf (bool), duration, sensing_range,
//! assume = ["forward-flight"] #   world assumptions (`--assume`: docs/perception.md § Coverage check),
//! PA_SPEED_MAX = 3.0          #   or any parameter by its name (`--param NAME=VALUE`)
//! [[scenes]]                  # flight i flies scenes[i mod n]
//! file = "../office.toml"     # relative to the campaign file
//! path = "../office_path.json"  # optional; or straight = true; else the planner (flight seed)
//! [draw]                      # quantity = number (fixed) or one distribution:
//! wind_speed = { uniform = [0.0, 3.0] }
//! mass = { normal = [1.0, 0.1], min = 0.8, max = 1.2 }
//! motor_tau = { log_uniform = [0.5, 2.0] }
//! fix_dropout_length = { fixed = 0.2 }
//! CBF_ACC_BOUND = { uniform = [0.5, 2.0] }   # any parameter by name: `--param NAME=x`
//! position_source = { choice = ["mocap", "gps", "rtk", "vio"] }  # or one name; optional
//!                             #   weights = [1, 1, 1, 1] (relative, ≥ 0, not all 0)
//! perception = { choice = ["truth", "lidar3d", "tof"] }  # likewise: truth or a `--perception` preset
//! ```
//!
//! Quantities ([`QUANTITIES`]): wind (`wind_speed` m/s, `wind_direction_deg` from,
//! `turbulence_sigma` horizontal σ m/s or `turbulence_w20` the MIL-HDBK-1797 wind at
//! 20 ft that sets it (light 7.7, moderate 15.4 m/s), one gust `gust_amplitude` / `gust_length` /
//! `gust_time` / `gust_direction_deg`), mismatch factors on the controller's vehicle
//! (`mass`, `inertia`, `k_f`, `k_m`, `motor_tau`, `drag`), plant aerodynamics
//! (`rotor_drag_kd`, `rotor_drag_kz`, `parasitic_drag`: absolute), a rotor fault
//! (`rotor_fault_factor`, `rotor_fault_time`, `rotor_fault_rotor` rounded to 1..4),
//! every `[faults]` field, and the controller's `mu`, `delta`, `delta1`, `kp`, `kd`,
//! `speed` (passed as `parapet run` options); and any parameter of the table by its name
//! (`parapet params export`), passed as `--param NAME=x`: a drawn parameter must be continuous
//! (not a code) and its distribution's support (uniform, log-uniform bounds; normal's min and
//! max, which must then be given) inside the parameter's range, checked when the file is read.
//! `position_source` (issue 39) is drawn among named sources (`crate::sim::source`: the
//! `[sensors] position_source` presets), passed as `--position-source NAME` and recorded in
//! `campaign.csv`'s `position_source` column (the source every flight flew, drawn or not).
//! `perception` (issue 36) is drawn likewise among `truth` and the `--perception` presets,
//! passed as `--perception NAME` and recorded in the `perception` column. A flight whose sensor
//! set the pre-flight coverage check refuses (as `parapet run` does, with the `[run] assume`
//! list) is not flown: `end_reason` `error`, its `error` naming the gap.
//!
//! Determinism: each quantity of flight i is drawn from its own ChaCha8 stream
//! seeded with a mix of (campaign seed, i, the quantity's name); the flight's noise
//! seed is a mix of (campaign seed, i). Adding a quantity does not change the others.
//!
//! Parameters set on the command line (`parapet campaign --params FILE --param NAME=VALUE`,
//! [`Campaign::with_params`]) apply to every flight: over the file's `[run]` keys, under the
//! `[draw]`s (a `--param` of a parameter the file draws is refused); they enter the identity.
//!
//! May import: `crate::sim::disturbance`, `crate::sim::source`, `crate::input`, `crate::cli::params`
//! (the `--param` checks), the external crates.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::input::InputError;
use crate::sim::disturbance::faults::RotorFault;
use crate::sim::disturbance::wind::Gust;
use crate::sim::disturbance::{Disturbances, Mismatch};
use crate::sim::plant::VehicleParams;
use crate::sim::source::PositionSource;
use parapet_core::outer::guidance::MissionGuidance;

/// Largest number of flights of a campaign.
pub const MAX_FLIGHTS: u64 = crate::input::limits::CAMPAIGN_MAX_FLIGHTS;

/// Every quantity a campaign can draw.
pub const QUANTITIES: &[&str] = &[
    "wind_speed",
    "wind_direction_deg",
    "turbulence_sigma",
    "turbulence_w20",
    "gust_amplitude",
    "gust_length",
    "gust_time",
    "gust_direction_deg",
    "mass",
    "inertia",
    "k_f",
    "k_m",
    "motor_tau",
    "drag",
    "rotor_drag_kd",
    "rotor_drag_kz",
    "parasitic_drag",
    "rotor_fault_rotor",
    "rotor_fault_factor",
    "rotor_fault_time",
    "gyro_bias_walk",
    "accel_bias_walk",
    "fix_dropout_rate",
    "fix_dropout_length",
    "fix_outlier_prob",
    "fix_outlier_size",
    "fix_latency_jitter",
    "obstacle_position_noise",
    "obstacle_latency",
    "obstacle_miss_prob",
    "mu",
    "delta",
    "delta1",
    "kp",
    "kd",
    "speed",
];

/// A distribution of one quantity.
#[derive(Clone, Debug, PartialEq)]
pub enum Dist {
    /// Always this value.
    Fixed(f64),
    /// Uniform in [a, b].
    Uniform(f64, f64),
    /// Normal (mean, std), clamped to [min, max].
    Normal(f64, f64, f64, f64),
    /// Log-uniform in [a, b] (0 < a ≤ b).
    LogUniform(f64, f64),
}

impl Dist {
    /// One draw.
    pub fn sample(&self, rng: &mut ChaCha8Rng) -> f64 {
        match *self {
            Dist::Fixed(x) => x,
            Dist::Uniform(a, b) => a + (b - a) * rng.random::<f64>(),
            Dist::Normal(m, s, lo, hi) => {
                let n: f64 = StandardNormal.sample(rng);
                (m + s * n).clamp(lo, hi)
            }
            Dist::LogUniform(a, b) => (a.ln() + (b.ln() - a.ln()) * rng.random::<f64>()).exp(),
        }
    }
}

/// One scene of the campaign.
#[derive(Clone, Debug, PartialEq)]
pub struct CampaignScene {
    /// Scene file (resolved against the campaign file's directory).
    pub file: PathBuf,
    /// Path file, if any.
    pub path: Option<PathBuf>,
    /// Fly the straight line.
    pub straight: bool,
}

/// A parsed campaign file.
#[derive(Clone, Debug, PartialEq)]
pub struct Campaign {
    /// Label.
    pub name: String,
    /// The file it came from.
    pub source: PathBuf,
    /// Campaign seed.
    pub seed: u64,
    /// Number of flights.
    pub flights: u64,
    /// `parapet run` options every flight gets.
    pub run_args: Vec<String>,
    /// Scenes, flown in turn.
    pub scenes: Vec<CampaignScene>,
    /// Distributions by quantity (sorted by name).
    pub draw: BTreeMap<String, Dist>,
    /// The position sources drawn, with their relative weights (`[draw] position_source`);
    /// `None`: each scene's own.
    pub position_source: Option<Vec<(PositionSource, f64)>>,
    /// The perceptions drawn (`[draw] perception`: `truth` or a `--perception` preset), with
    /// their relative weights; `None`: the `[run]` options' (default `truth`).
    pub perception: Option<Vec<(&'static str, f64)>>,
    /// Identity (FNV-1a of the campaign text and every scene and path file, then of the
    /// parameters set on the command line), hex.
    pub identity: String,
    /// Parameters set on the command line for every flight (`--params FILE`, then each
    /// `--param NAME=VALUE`; the last given wins): name → value ([`Campaign::with_params`]).
    pub params_set: BTreeMap<String, f64>,
}

/// What flight i flies.
#[derive(Clone, Debug)]
pub struct FlightDraw {
    /// Flight index.
    pub index: u64,
    /// Scene index in [`Campaign::scenes`].
    pub scene: usize,
    /// Noise (and planner) seed.
    pub seed: u64,
    /// Drawn values, by quantity.
    pub values: BTreeMap<String, f64>,
    /// The drawn position source, if the campaign draws it.
    pub position_source: Option<PositionSource>,
    /// The drawn perception, if the campaign draws it.
    pub perception: Option<&'static str>,
    /// The `parapet run` options (without `--disturbances` and `--out`).
    pub args: Vec<String>,
}

/// SplitMix64 finaliser.
pub fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// FNV-1a, 64 bit.
pub fn fnv(bytes: &[u8], mut h: u64) -> u64 {
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

const FNV0: u64 = 0xcbf2_9ce4_8422_2325;

fn bad(file: &Path, table: &str, field: &str, reason: &str) -> InputError {
    InputError::file(file.display(), reason).table(table).field(field)
}

fn parse_dist(file: &Path, name: &str, v: &toml::Value) -> Result<Dist, InputError> {
    let num =
        |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).filter(|x| x.is_finite());
    let pair = |v: &toml::Value| -> Option<(f64, f64)> {
        let a = v.as_array()?;
        (a.len() == 2).then_some(())?;
        Some((num(&a[0])?, num(&a[1])?))
    };
    let allowed = "a number, or { fixed = x } | { uniform = [a, b] } | { normal = [mean, std], min, max } | \
                   { log_uniform = [a, b] }";
    let err = |reason: &str| bad(file, "draw", name, reason).value(v.to_string()).allowed(allowed);
    if let Some(x) = num(v) {
        return Ok(Dist::Fixed(x));
    }
    let t = v.as_table().ok_or_else(|| err("not a distribution"))?;
    let kinds: Vec<&String> = t.keys().filter(|k| !matches!(k.as_str(), "min" | "max")).collect();
    if kinds.len() != 1 {
        return Err(err("exactly one of fixed, uniform, normal, log_uniform"));
    }
    let (kind, arg) = (kinds[0].as_str(), &t[kinds[0]]);
    if kind != "normal" && (t.contains_key("min") || t.contains_key("max")) {
        return Err(err("min / max only with normal"));
    }
    match kind {
        "fixed" => num(arg).map(Dist::Fixed).ok_or_else(|| err("fixed needs a number")),
        "uniform" => match pair(arg) {
            Some((a, b)) if a <= b => Ok(Dist::Uniform(a, b)),
            _ => Err(err("uniform needs [a, b] with a ≤ b")),
        },
        "log_uniform" => match pair(arg) {
            Some((a, b)) if 0.0 < a && a <= b => Ok(Dist::LogUniform(a, b)),
            _ => Err(err("log_uniform needs [a, b] with 0 < a ≤ b")),
        },
        "normal" => {
            let lo = t.get("min").map(num).unwrap_or(Some(f64::NEG_INFINITY));
            let hi = t.get("max").map(num).unwrap_or(Some(f64::INFINITY));
            match (pair(arg), lo, hi) {
                (Some((m, s)), Some(lo), Some(hi)) if s >= 0.0 && lo <= hi => Ok(Dist::Normal(m, s, lo, hi)),
                _ => Err(err("normal needs [mean, std ≥ 0] and min ≤ max")),
            }
        }
        _ => Err(err("unknown distribution")),
    }
}

/// The quantity name of the position-source draw.
pub const POSITION_SOURCE: &str = "position_source";
/// The quantity name of the perception draw (issue 36's speed campaign).
pub const PERCEPTION: &str = "perception";
/// The perceptions a campaign may draw: `truth` (the default) and the `--perception` presets.
pub fn perception_names() -> Vec<&'static str> {
    std::iter::once("truth").chain(crate::sim::range::PRESETS).collect()
}

/// A `[draw]` choice among named values (`all`: name and value): one name, or
/// `{ choice = [names], weights = [w] }` (relative weights ≥ 0, not all 0; each name once).
/// `what` names a value in messages ("position source").
fn parse_choice<T: Copy + PartialEq>(
    file: &Path,
    key: &str,
    what: &str,
    v: &toml::Value,
    all: &[(&str, T)],
) -> Result<Vec<(T, f64)>, InputError> {
    let names: Vec<&str> = all.iter().map(|a| a.0).collect();
    let allowed = format!(
        "a {what} name or {{ choice = [names], weights = [w ≥ 0, …] }} with names among {}",
        names.join(", ")
    );
    let err =
        |reason: &str, value: String| bad(file, "draw", key, reason).value(value).allowed(allowed.clone());
    let one = |x: &toml::Value| -> Result<T, InputError> {
        x.as_str()
            .and_then(|s| all.iter().find(|a| a.0 == s))
            .map(|a| a.1)
            .ok_or_else(|| err(&format!("unknown {what}"), x.to_string()))
    };
    let Some(t) = v.as_table() else { return Ok(vec![(one(v)?, 1.0)]) };
    for k in t.keys() {
        if !matches!(k.as_str(), "choice" | "weights") {
            return Err(err("unknown key (choice, weights)", k.clone()));
        }
    }
    let choice = t
        .get("choice")
        .and_then(|c| c.as_array())
        .filter(|c| !c.is_empty())
        .ok_or_else(|| err("choice needs a non-empty list of names", v.to_string()))?;
    let values = choice.iter().map(one).collect::<Result<Vec<_>, _>>()?;
    let weights = match t.get("weights") {
        None => vec![1.0; values.len()],
        Some(w) => {
            let w: Option<Vec<f64>> = w.as_array().map(|a| {
                a.iter().filter_map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64))).collect()
            });
            match w {
                Some(w)
                    if w.len() == values.len()
                        && w.iter().all(|x| x.is_finite() && *x >= 0.0)
                        && w.iter().sum::<f64>() > 0.0 =>
                {
                    w
                }
                _ => return Err(err("weights: one number ≥ 0 per choice, not all 0", v.to_string())),
            }
        }
    };
    for (k, x) in choice.iter().enumerate() {
        if choice[..k].contains(x) {
            return Err(err(&format!("a {what} named twice"), x.to_string()));
        }
    }
    Ok(values.into_iter().zip(weights).collect())
}

/// One draw among weighted values (`u` uniform in [0, 1)); `None` only for an empty list.
fn pick<T: Copy>(choices: &[(T, f64)], u: f64) -> Option<T> {
    let total: f64 = choices.iter().map(|s| s.1).sum();
    let mut x = u * total;
    for &(s, w) in choices {
        if x < w {
            return Some(s);
        }
        x -= w;
    }
    // Rounding at the top end: the last value with a weight.
    choices.iter().rev().find(|s| s.1 > 0.0).or(choices.last()).map(|s| s.0)
}

/// A parameter drawn by name: continuous, every value the distribution can give in its range.
fn check_param_dist(
    file: &Path,
    name: &str,
    v: &toml::Value,
    p: &parapet_core::params::Param,
    d: &Dist,
) -> Result<(), InputError> {
    let err = |reason: &str| bad(file, "draw", name, reason).value(v.to_string());
    let (lo, hi) = match *d {
        Dist::Fixed(x) => (x, x),
        Dist::Uniform(a, b) | Dist::LogUniform(a, b) => (a, b),
        Dist::Normal(_, _, lo, hi) => (lo, hi),
    };
    if p.integer && !matches!(d, Dist::Fixed(_)) {
        return Err(err("a code parameter can only be fixed").allowed("{ fixed = x } or a number"));
    }
    let inside = |x: f64| x.is_finite() && p.check(x as f32).is_ok();
    if !(inside(lo) && inside(hi)) {
        return Err(err("draws outside the parameter's range (normal: give min and max)")
            .allowed(p.range().to_string()));
    }
    Ok(())
}

impl Campaign {
    /// Read and check a campaign file.
    pub fn load(path: &Path) -> Result<Campaign, InputError> {
        let src = crate::input::read_text(path)?;
        let table: toml::Table = toml::from_str(&src).map_err(|e| {
            InputError::file(path.display(), crate::world::scene::describe_toml_error(&src, &e))
        })?;
        let dir = path.parent().unwrap_or(Path::new(""));
        let top = |field: &str, reason: &str| InputError::file(path.display(), reason).field(field);
        for k in table.keys() {
            if !matches!(k.as_str(), "name" | "seed" | "flights" | "run" | "scenes" | "draw") {
                return Err(top(k, "unknown key").allowed("name, seed, flights, run, scenes, draw"));
            }
        }
        let name = table.get("name").and_then(|v| v.as_str()).unwrap_or("campaign").to_string();
        let seed = match table.get("seed") {
            None => 0,
            Some(v) => v.as_integer().filter(|s| *s >= 0).ok_or_else(|| {
                top("seed", "not an integer ≥ 0").value(v.to_string()).allowed("0 ≤ seed < 2^63")
            })? as u64,
        };
        let flights_allowed = format!("an integer, 1 ≤ flights ≤ {MAX_FLIGHTS}");
        let flights = match table.get("flights") {
            None => return Err(top("flights", "missing").allowed(flights_allowed)),
            // The value as written (`1e9`, `"10"`), not a conversion of it.
            Some(v) => match v.as_integer() {
                Some(n) if (1..=MAX_FLIGHTS as i64).contains(&n) => n,
                Some(_) => {
                    return Err(top("flights", "out of range").value(v.to_string()).allowed(flights_allowed))
                }
                None => {
                    return Err(top("flights", "not an integer")
                        .value(v.to_string())
                        .allowed(flights_allowed))
                }
            },
        };
        let mut run_args = Vec::new();
        if let Some(r) = table.get("run") {
            let r = r.as_table().ok_or_else(|| top("run", "not a table"))?;
            for (k, v) in r {
                let f = |reason: &str| bad(path, "run", k, reason).value(v.to_string());
                match (k.as_str(), v) {
                    ("filter", toml::Value::String(s)) => run_args.extend(["--filter".into(), s.clone()]),
                    ("yaw_mode", toml::Value::String(s)) => run_args.extend(["--yaw-mode".into(), s.clone()]),
                    ("guidance", toml::Value::String(s)) => {
                        crate::cli::values::parse_guidance(s).map_err(|e| f("not a guidance").allowed(e))?;
                        run_args.extend(["--guidance".into(), s.clone()])
                    }
                    ("assume", toml::Value::Array(list)) => {
                        let names = crate::sim::coverage::Assumption::names();
                        for x in list {
                            let ok = x.as_str().is_some_and(|n| n.parse::<crate::sim::coverage::Assumption>().is_ok());
                            if !ok {
                                return Err(bad(path, "run", k, "not a world assumption")
                                    .value(x.to_string())
                                    .allowed(format!("a list of names among {names}")));
                            }
                            run_args.extend(["--assume".into(), x.as_str().unwrap_or_default().to_string()]);
                        }
                    }
                    ("noise", toml::Value::Boolean(b)) => {
                        run_args.push(if *b { "--noise" } else { "--no-noise" }.into())
                    }
                    ("no_cbf", toml::Value::Boolean(b)) => {
                        if *b {
                            run_args.push("--no-cbf".into())
                        }
                    }
                    ("duration" | "sensing_range", v) => {
                        let x = v
                            .as_float()
                            .or_else(|| v.as_integer().map(|i| i as f64))
                            .ok_or_else(|| f("not a number"))?;
                        run_args.extend([format!("--{}", k.replace('_', "-")), format!("{x}")]);
                    }
                    (name, v) if parapet_core::params::index_of(name).is_some() => {
                        let x = v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
                        let a = crate::cli::params::parse_assignment(&format!(
                            "{name}={}",
                            x.unwrap_or(f64::NAN)
                        ))
                        .map_err(|e| f("not a value of the parameter").allowed(e.to_string()))?;
                        run_args.extend(["--param".into(), format!("{}={}", a.0.name, a.1)]);
                    }
                    _ => return Err(f("unknown key or wrong type").allowed(
                        "filter, yaw_mode, guidance (string), noise, no_cbf (bool), duration, sensing_range (number), \
                         assume (list of world assumptions), a parameter name (number)",
                    )),
                }
            }
        }
        let scenes_v = table
            .get("scenes")
            .and_then(|v| v.as_array())
            .ok_or_else(|| top("scenes", "missing: at least one [[scenes]] table"))?;
        let mut scenes = Vec::new();
        let mut id = fnv(src.as_bytes(), FNV0);
        for (i, s) in scenes_v.iter().enumerate() {
            let t = s.as_table().ok_or_else(|| top(&format!("scenes[{i}]"), "not a table"))?;
            let tab = format!("scenes[{i}]");
            for k in t.keys() {
                if !matches!(k.as_str(), "file" | "path" | "straight") {
                    return Err(bad(path, &tab, k, "unknown key").allowed("file, path, straight"));
                }
            }
            let file =
                t.get("file").and_then(|v| v.as_str()).ok_or_else(|| bad(path, &tab, "file", "missing"))?;
            let file = dir.join(file);
            let sp = t.get("path").and_then(|v| v.as_str()).map(|p| dir.join(p));
            let straight = t.get("straight").and_then(|v| v.as_bool()).unwrap_or(false);
            if straight && sp.is_some() {
                return Err(bad(path, &tab, "straight", "not with a path"));
            }
            for f in std::iter::once(&file).chain(sp.iter()) {
                let text = crate::input::read_text(f)?;
                id = fnv(text.as_bytes(), id);
            }
            scenes.push(CampaignScene { file, path: sp, straight });
        }
        if scenes.is_empty() {
            return Err(top("scenes", "at least one [[scenes]] table"));
        }
        let mut draw = BTreeMap::new();
        let mut position_source = None;
        let mut perception = None;
        if let Some(d) = table.get("draw") {
            let d = d.as_table().ok_or_else(|| top("draw", "not a table"))?;
            for (k, v) in d {
                if k == POSITION_SOURCE {
                    let all: Vec<_> = PositionSource::ALL.iter().map(|p| (p.as_str(), *p)).collect();
                    position_source = Some(parse_choice(path, k, "position source", v, &all)?);
                    continue;
                }
                if k == PERCEPTION {
                    let all: Vec<_> = perception_names().into_iter().map(|p| (p, p)).collect();
                    perception = Some(parse_choice(path, k, "perception", v, &all)?);
                    continue;
                }
                let param = parapet_core::params::index_of(k).map(|i| &parapet_core::params::TABLE[i]);
                if !QUANTITIES.contains(&k.as_str()) && param.is_none() {
                    return Err(bad(path, "draw", k, "unknown quantity").allowed(format!(
                        "{}, {POSITION_SOURCE}, {PERCEPTION}, or a parameter name of `parapet params export`",
                        QUANTITIES.join(", ")
                    )));
                }
                let dist = parse_dist(path, k, v)?;
                if let Some(p) = param {
                    check_param_dist(path, k, v, p, &dist)?;
                }
                draw.insert(k.clone(), dist);
            }
        }
        Ok(Campaign {
            name,
            source: path.to_path_buf(),
            seed,
            flights: flights as u64,
            run_args,
            scenes,
            draw,
            position_source,
            perception,
            identity: format!("{id:016x}"),
            params_set: BTreeMap::new(),
        })
    }

    /// The parameter a `[draw]` quantity sets, if any: a parameter drawn by its name, or one of
    /// the controller's `mu`, `delta`, `delta1`, `kp`, `kd`, `speed` (by its scene key).
    fn drawn_param(q: &str) -> Option<&'static parapet_core::params::Param> {
        let by_name = parapet_core::params::index_of(q).map(|i| &parapet_core::params::TABLE[i]);
        let keyed = ["mu", "delta", "delta1", "kp", "kd", "speed"].contains(&q);
        by_name.or_else(|| keyed.then(|| parapet_core::params::by_key(q)).flatten())
    }

    /// Every flight with the parameters set on the command line: `--params FILE` (a
    /// QGroundControl `.params` file, passed to each flight as `--params FILE`) then each
    /// `--param NAME=VALUE`, each checked as `parapet run` checks it (exit 2 naming the file or
    /// option, the parameter, the value and its range). Precedence: the file's `[run]` keys <
    /// `--params` < `--param` < the `[draw]`s (a drawn value differs per flight); a `--param`
    /// naming a parameter the file draws is refused. A `[run]` key of a parameter set here
    /// (`PA_SPEED_MAX = …`, `filter`, `yaw_mode`, `guidance`) is dropped from the flights'
    /// options. The set enters the identity and [`Campaign::params_set`].
    pub fn with_params(
        mut self,
        file: Option<&Path>,
        given: &[String],
    ) -> Result<Campaign, crate::cli::CliError> {
        for g in given {
            let (p, x) = crate::cli::params::parse_assignment(g)?;
            if let Some(q) = self.draw.keys().find(|q| Self::drawn_param(q).is_some_and(|d| d.name == p.name))
            {
                return Err(InputError::option("param", "the campaign file draws this parameter")
                    .field(p.name)
                    .value(format!("{x} ([draw] {q} in {})", self.source.display()))
                    .allowed("a parameter the campaign does not draw (remove it from --param or from [draw])")
                    .into());
            }
        }
        let assigned = crate::cli::params::assignments(file, given)?;
        if assigned.is_empty() && file.is_none() {
            return Ok(self);
        }
        for (p, x) in &assigned {
            self.params_set.insert(p.name.to_string(), *x);
        }
        // The [run] options of what is set here give way to it.
        let set = |n: &str| self.params_set.contains_key(n);
        let replaced = |opt: &str, value: &str| match opt {
            "--param" => value.split_once('=').is_some_and(|(n, _)| set(n)),
            "--filter" => set("CBF_VARIANT"),
            "--yaw-mode" => set("MIS_YAW_MODE"),
            "--guidance" => set("MIS_GUIDANCE"),
            _ => false,
        };
        let mut args = Vec::new();
        let mut i = 0;
        while i < self.run_args.len() {
            let value = self.run_args.get(i + 1).map_or("", String::as_str);
            if replaced(&self.run_args[i], value) {
                i += 2;
            } else {
                args.push(self.run_args[i].clone());
                i += 1;
            }
        }
        if let Some(f) = file {
            args.extend(["--params".into(), f.display().to_string()]);
        }
        for g in given {
            let (p, x) = crate::cli::params::parse_assignment(g)?;
            args.extend(["--param".into(), format!("{}={x}", p.name)]);
        }
        self.run_args = args;
        let text: String = self.params_set.iter().map(|(n, x)| format!("{n}={x}\n")).collect();
        self.identity = format!("{}-p{:016x}", self.identity, fnv(text.as_bytes(), FNV0));
        Ok(self)
    }

    /// The parameters set on the command line that the campaign does not draw by name: each
    /// has a `campaign.csv` column (after the drawn quantities) with the value its flight's
    /// controller flew.
    pub fn set_columns(&self) -> Vec<String> {
        self.params_set.keys().filter(|n| !self.draw.contains_key(*n)).cloned().collect()
    }

    /// The value columns of `campaign.csv`: the drawn quantities, then [`Campaign::set_columns`].
    pub fn columns(&self) -> Vec<String> {
        self.draw.keys().cloned().chain(self.set_columns()).collect()
    }

    /// Every flight with the mission guidance `g` (`parapet campaign --guidance`, after the
    /// file's `[run]` options, so it wins), which also enters the identity; `None`: unchanged.
    pub fn with_guidance(mut self, g: Option<MissionGuidance>) -> Campaign {
        if let Some(g) = g {
            if let Some(i) = self.run_args.iter().position(|a| a == "--guidance") {
                self.run_args.drain(i..(i + 2).min(self.run_args.len()));
            }
            self.run_args.extend(["--guidance".into(), g.as_str().into()]);
            self.identity = format!("{}-{}", self.identity, g.as_str());
        }
        self
    }

    /// The draws of flight `i`.
    pub fn flight(&self, i: u64) -> FlightDraw {
        let base = mix(self.seed ^ mix(i));
        let scene = (i % self.scenes.len() as u64) as usize;
        let seed = mix(base ^ 0x5345_4544);
        let mut values = BTreeMap::new();
        for (name, dist) in &self.draw {
            let mut rng = ChaCha8Rng::seed_from_u64(mix(base ^ fnv(name.as_bytes(), FNV0)));
            values.insert(name.clone(), dist.sample(&mut rng));
        }
        let choose =
            |key: &str| ChaCha8Rng::seed_from_u64(mix(base ^ fnv(key.as_bytes(), FNV0))).random::<f64>();
        let position_source = self.position_source.as_deref().and_then(|c| pick(c, choose(POSITION_SOURCE)));
        let perception = self.perception.as_deref().and_then(|c| pick(c, choose(PERCEPTION)));
        let sc = &self.scenes[scene];
        let mut args = vec!["--scene".to_string(), sc.file.display().to_string()];
        if let Some(p) = &sc.path {
            args.extend(["--path".into(), p.display().to_string()]);
        } else if sc.straight {
            args.push("--straight".into());
        }
        args.extend(["--seed".into(), seed.to_string()]);
        args.extend(self.run_args.iter().cloned());
        if let Some(src) = position_source {
            args.extend(["--position-source".into(), src.as_str().into()]);
        }
        if let Some(p) = perception {
            args.extend(["--perception".into(), p.into()]);
        }
        for q in ["mu", "delta", "delta1", "kp", "kd", "speed"] {
            if let Some(x) = values.get(q) {
                args.extend([format!("--{q}"), format!("{x}")]);
            }
        }
        for (name, x) in &values {
            if parapet_core::params::index_of(name).is_some() {
                args.extend(["--param".into(), format!("{name}={x}")]);
            }
        }
        FlightDraw { index: i, scene, seed, values, position_source, perception, args }
    }
}

impl FlightDraw {
    /// The flight's disturbances: `base` (the scene's, after the run options) with
    /// the drawn quantities; `vehicle` is the controller's.
    pub fn disturbances(&self, base: &Disturbances, vehicle: &VehicleParams) -> Disturbances {
        let v = |k: &str| self.values.get(k).copied();
        let mut d = base.clone();
        let w = &mut d.wind;
        if let Some(x) = v("wind_speed") {
            w.speed = x;
        }
        if let Some(x) = v("wind_direction_deg") {
            w.direction_deg = x;
        }
        if let Some(x) = v("turbulence_sigma") {
            w.sigma = Some(x);
        }
        if let Some(x) = v("turbulence_w20") {
            w.w20 = Some(x);
        }
        if let Some(a) = v("gust_amplitude") {
            w.gusts.push(Gust {
                amplitude: a,
                length: v("gust_length").unwrap_or(10.0),
                time: v("gust_time").unwrap_or(5.0),
                direction_deg: v("gust_direction_deg"),
            });
        }
        let m = Mismatch {
            mass: v("mass").unwrap_or(1.0),
            inertia: v("inertia").unwrap_or(1.0),
            k_f: v("k_f").unwrap_or(1.0),
            k_m: v("k_m").unwrap_or(1.0),
            motor_tau: v("motor_tau").unwrap_or(1.0),
            drag: v("drag").unwrap_or(1.0),
        };
        let mut plant = m.apply(&d.plant_vehicle(vehicle));
        if let Some(x) = v("rotor_drag_kd") {
            plant.rotor_drag_kd = x;
        }
        if let Some(x) = v("rotor_drag_kz") {
            plant.rotor_drag_kz = x;
        }
        if let Some(x) = v("parasitic_drag") {
            plant.parasitic_drag = [x; 3];
        }
        d.plant = Some(plant);
        let f = &mut d.faults;
        let set = |slot: &mut f64, k: &str| {
            if let Some(x) = v(k) {
                *slot = x;
            }
        };
        set(&mut f.gyro_bias_walk, "gyro_bias_walk");
        set(&mut f.accel_bias_walk, "accel_bias_walk");
        set(&mut f.fix_dropout_rate, "fix_dropout_rate");
        set(&mut f.fix_dropout_length, "fix_dropout_length");
        set(&mut f.fix_outlier_prob, "fix_outlier_prob");
        set(&mut f.fix_outlier_size, "fix_outlier_size");
        set(&mut f.fix_latency_jitter, "fix_latency_jitter");
        set(&mut f.obstacle_position_noise, "obstacle_position_noise");
        set(&mut f.obstacle_latency, "obstacle_latency");
        set(&mut f.obstacle_miss_prob, "obstacle_miss_prob");
        if let Some(factor) = v("rotor_fault_factor") {
            f.rotor_fault = Some(RotorFault {
                rotor: v("rotor_fault_rotor").map_or(1, |r| r.round().clamp(1.0, 4.0) as u8),
                factor,
                time: v("rotor_fault_time").unwrap_or(0.0),
            });
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    /// A fresh temporary directory `parapet-spec-<name>-<pid>`.
    fn tmp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("parapet-spec-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn scene_dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes")
    }

    #[test]
    fn any_parameter_by_name_is_set_or_drawn_and_checked_against_its_range() {
        let dir = std::env::temp_dir().join(format!("parapet-spec-param-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let sc = scene_dir().join("one_sphere.toml");
        let head =
            format!("flights = 10\n[[scenes]]\nfile = {:?}\nstraight = true\n", sc.display().to_string());
        let text =
            format!("{head}[run]\nPA_SPEED_MAX = 3\n[draw]\nCBF_ACC_BOUND = {{ uniform = [0.5, 2.0] }}\n");
        let c = Campaign::load(&write(&dir, "p.toml", &text)).unwrap_or_else(|e| panic!("{e}"));
        for i in 0..10 {
            let f = c.flight(i);
            let x = f.values["CBF_ACC_BOUND"];
            assert!((0.5..=2.0).contains(&x));
            assert!(f.args.windows(2).any(|w| w == ["--param", "PA_SPEED_MAX=3"]), "{:?}", f.args);
            let drawn = format!("CBF_ACC_BOUND={x}");
            assert!(f.args.windows(2).any(|w| w[0] == "--param" && w[1] == drawn), "{:?}", f.args);
            // The flight's options are `parapet run`'s: they parse and set the parameter.
            let (_, cfg) = crate::cli::run_config_from_args(&f.args).unwrap_or_else(|e| panic!("{e}"));
            assert!((cfg.accel_bound - x).abs() < 1e-6, "{} vs {x}", cfg.accel_bound);
            assert_eq!(cfg.param_overrides, vec![("PA_SPEED_MAX", 3.0f32)]);
        }
        for (bad, field) in [
            ("[run]\nPA_SPEED_MAX = 30\n", "PA_SPEED_MAX"),
            ("[run]\nPA_SPEED_MAX = \"fast\"\n", "PA_SPEED_MAX"),
            ("[draw]\nCBF_ACC_BOUND = { uniform = [0.5, 200.0] }\n", "CBF_ACC_BOUND"),
            ("[draw]\nCBF_ACC_BOUND = { normal = [1.0, 0.2] }\n", "CBF_ACC_BOUND"),
            ("[draw]\nCBF_VARIANT = { uniform = [0.0, 3.0] }\n", "CBF_VARIANT"),
            ("[draw]\nNO_SUCH = 1.0\n", "NO_SUCH"),
        ] {
            let e =
                Campaign::load(&write(&dir, "bad.toml", &format!("{head}{bad}"))).unwrap_err().to_string();
            assert!(e.contains(field), "{bad}: {e}");
        }
    }

    #[test]
    fn the_guidance_is_a_run_key_and_an_option_that_enters_the_identity() {
        let dir = std::env::temp_dir().join(format!("parapet-spec-guidance-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let sc = scene_dir().join("one_sphere.toml");
        let head =
            format!("flights = 2\n[[scenes]]\nfile = {:?}\nstraight = true\n", sc.display().to_string());
        let c =
            Campaign::load(&write(&dir, "g.toml", &format!("{head}[run]\nguidance = \"paper\"\n"))).unwrap();
        let guidance = |args: &[String]| {
            let (_, cfg) = crate::cli::run_config_from_args(args).unwrap_or_else(|e| panic!("{e}"));
            cfg.param_overrides.iter().find(|(n, _)| *n == "MIS_GUIDANCE").map(|(_, v)| *v)
        };
        assert_eq!(guidance(&c.flight(0).args), Some(MissionGuidance::Paper.code() as f32));
        // The option wins over the file and changes the identity (shards of one campaign agree).
        let id = c.identity.clone();
        let t = c.with_guidance(Some(MissionGuidance::Trajectory));
        assert_ne!(t.identity, id);
        assert_eq!(guidance(&t.flight(1).args), Some(MissionGuidance::Trajectory.code() as f32));
        let e = Campaign::load(&write(&dir, "bad.toml", &format!("{head}[run]\nguidance = \"fast\"\n")))
            .unwrap_err()
            .to_string();
        assert!(e.contains("guidance") && e.contains("fast") && e.contains("trajectory"), "{e}");
    }

    /// `parapet campaign --params FILE --param NAME=VALUE`: over the `[run]` keys (dropped from
    /// the flights' options), under the draws; a `--param` of a drawn parameter refused; the
    /// set enters the identity.
    #[test]
    fn command_line_parameters_replace_run_keys_and_enter_the_identity() {
        let (dir, sc) = (tmp_dir("cli-params"), scene_dir().join("one_sphere.toml"));
        let text = format!(
            "flights = 3\n[run]\nPA_SPEED_MAX = 3\nfilter = \"paper\"\nTRJ_ACC = 3\n[[scenes]]\nfile = {:?}\n\
             straight = true\n[draw]\nCBF_ACC_BOUND = {{ uniform = [0.5, 2.0] }}\nkp = 0.6\n",
            sc.display().to_string()
        );
        let file = write(&dir, "c.toml", &text);
        let params = write(&dir, "p.params", "1\t1\tPA_SPEED_MAX\t2\t9\n1\t1\tCBF_ACC_BOUND\t1.5\t9\n");
        let plain = Campaign::load(&file).unwrap();
        let c = Campaign::load(&file)
            .unwrap()
            .with_params(Some(&params), &["CBF_VARIANT=1".into()])
            .unwrap_or_else(|e| panic!("{e}"));
        assert_ne!(c.identity, plain.identity);
        assert_eq!(c.params_set.get("PA_SPEED_MAX"), Some(&2.0));
        assert_eq!(c.set_columns(), ["CBF_VARIANT", "PA_SPEED_MAX"], "CBF_ACC_BOUND is drawn: its column");
        let f = c.flight(1);
        let (_, cfg) = crate::cli::run_config_from_args(&f.args).unwrap_or_else(|e| panic!("{e}"));
        assert!(!f.args.iter().any(|a| a == "PA_SPEED_MAX=3" || a == "--filter"), "{:?}", f.args);
        assert!(f.args.iter().any(|a| a == "TRJ_ACC=3"), "a [run] key not set here stays: {:?}", f.args);
        assert_eq!(cfg.variant.as_str(), "relative", "--param CBF_VARIANT=1 over [run] filter = paper");
        assert!(cfg.param_overrides.contains(&("PA_SPEED_MAX", 2.0)), "{:?}", cfg.param_overrides);
        assert!((cfg.accel_bound - f.values["CBF_ACC_BOUND"]).abs() < 1e-6, "the draw over the file");
        for given in ["CBF_ACC_BOUND=1", "TRK_KP=1"] {
            let e =
                Campaign::load(&file).unwrap().with_params(None, &[given.into()]).unwrap_err().to_string();
            assert!(e.contains("--param") && e.contains("draws this parameter"), "{given}: {e}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn the_position_source_is_drawn_by_weight_passed_as_an_option_and_checked() {
        let dir = std::env::temp_dir().join(format!("parapet-spec-source-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let sc = scene_dir().join("one_sphere.toml");
        let head =
            format!("flights = 400\n[[scenes]]\nfile = {:?}\nstraight = true\n", sc.display().to_string());
        let text = format!(
            "{head}[draw]\nwind_speed = {{ uniform = [0, 3] }}\n\
             position_source = {{ choice = [\"gps\", \"vio\", \"rtk\"], weights = [3, 1, 0] }}\n"
        );
        let c = Campaign::load(&write(&dir, "s.toml", &text)).unwrap_or_else(|e| panic!("{e}"));
        let mut counts = BTreeMap::new();
        for i in 0..400 {
            let f = c.flight(i);
            let src = f.position_source.expect("drawn");
            *counts.entry(src.as_str()).or_insert(0) += 1;
            assert!(f.args.windows(2).any(|w| w == ["--position-source", src.as_str()]), "{:?}", f.args);
            let (_, cfg) = crate::cli::run_config_from_args(&f.args).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(cfg.sensors.position_source, src);
            assert_eq!(cfg.sensors.rate, src.preset().rate_hz, "the preset comes with the source");
        }
        // Weights 3 : 1 : 0 (binomial σ ≈ 9 of 400).
        assert_eq!(counts.get("rtk"), None, "{counts:?}");
        assert!((270..=330).contains(&counts["gps"]), "{counts:?}");
        // The other quantities' draws do not depend on whether the source is drawn.
        let plain = Campaign::load(&write(
            &dir,
            "p.toml",
            &format!("{head}[draw]\nwind_speed = {{ uniform = [0, 3] }}\n"),
        ))
        .unwrap();
        assert_eq!(plain.flight(5).values, c.flight(5).values);
        assert!(plain.flight(5).position_source.is_none());
        let one =
            Campaign::load(&write(&dir, "o.toml", &format!("{head}[draw]\nposition_source = \"vio\"\n")))
                .unwrap();
        assert_eq!(one.flight(3).position_source, Some(PositionSource::Vio));
        for (body, value) in [
            ("position_source = \"galileo\"", "galileo"),
            ("position_source = { choice = [\"gps\", \"lidar\"] }", "lidar"),
            ("position_source = { choice = [] }", "choice"),
            ("position_source = { choice = [\"gps\"], weights = [-1] }", "-1"),
            ("position_source = { choice = [\"gps\", \"rtk\"], weights = [0, 0] }", "weights"),
            ("position_source = { choice = [\"gps\", \"gps\"] }", "gps"),
            ("position_source = { pick = [\"gps\"] }", "pick"),
            ("position_source = 3", "3"),
        ] {
            let e = Campaign::load(&write(&dir, "bad.toml", &format!("{head}[draw]\n{body}\n")))
                .unwrap_err()
                .to_string();
            for want in ["bad.toml", "[draw]", "position_source", value, "mocap, gps, rtk, vio"] {
                assert!(e.contains(want), "{body}: `{want}` not in {e}");
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    /// `[draw] perception` (issue 36) draws among `truth` and the presets and is passed as
    /// `--perception`; `[run] assume` as `--assume`; bad names are refused naming the field.
    #[test]
    fn the_perception_is_drawn_and_passed_and_bad_names_are_refused() {
        let dir = std::env::temp_dir().join(format!("parapet-spec-perc-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let sc = scene_dir().join("one_sphere.toml");
        let head =
            format!("flights = 40\n[[scenes]]\nfile = {:?}\nstraight = true\n", sc.display().to_string());
        let text = format!("{head}[run]\nassume = [\"forward-flight\"]\n[draw]\nperception = {{ choice = [\"truth\", \"tof\"], weights = [1, 3] }}\n");
        let c = Campaign::load(&write(&dir, "p.toml", &text)).unwrap();
        let mut tof = 0;
        for i in 0..40 {
            let f = c.flight(i);
            let p = f.perception.expect("drawn");
            let k = f.args.iter().position(|a| a == "--perception").expect("passed");
            assert_eq!(f.args[k + 1], p);
            assert!(
                f.args.windows(2).any(|w| w[0] == "--assume" && w[1] == "forward-flight"),
                "{:?}",
                f.args
            );
            tof += usize::from(p == "tof");
        }
        assert!((20..40).contains(&tof), "weights 1:3 give mostly tof: {tof} of 40");
        for (body, field, value) in [
            ("[draw]\nperception = \"sonar\"", "perception", "sonar"),
            ("[draw]\nperception = { choice = [\"tof\", \"tof\"] }", "perception", "tof"),
            ("[run]\nassume = [\"no-walls\"]", "assume", "no-walls"),
        ] {
            let e =
                Campaign::load(&write(&dir, "bad.toml", &format!("{head}{body}\n"))).unwrap_err().to_string();
            for want in ["bad.toml", field, value] {
                assert!(e.contains(want), "{body}: `{want}` not in {e}");
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn draws_depend_only_on_seed_and_index_and_follow_their_distributions() {
        let dir = std::env::temp_dir().join(format!("parapet-spec-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let sc = scene_dir().join("one_sphere.toml");
        let text = format!(
            "seed = 5\nflights = 10\n[[scenes]]\nfile = {:?}\nstraight = true\n[draw]\n\
             wind_speed = {{ uniform = [0, 3] }}\nmass = {{ normal = [1.0, 0.1], min = 0.8, max = 1.2 }}\n\
             motor_tau = {{ log_uniform = [0.5, 2.0] }}\nkp = 0.6\n",
            sc.display().to_string()
        );
        let c = Campaign::load(&write(&dir, "a.toml", &text)).unwrap_or_else(|e| panic!("{e}"));
        // Adding a quantity does not change the others' draws.
        let more = text.replace("kp = 0.6", "kp = 0.6\nfix_dropout_rate = 0.5");
        let d = Campaign::load(&write(&dir, "b.toml", &more)).unwrap();
        assert_ne!(c.identity, d.identity);
        let (mut sum, mut lo, mut hi) = (0.0, f64::INFINITY, 0.0f64);
        let n = 4000;
        for i in 0..n {
            let a = c.flight(i);
            let b = d.flight(i);
            assert_eq!(a.values["wind_speed"], b.values["wind_speed"]);
            assert_eq!(a.seed, b.seed);
            assert!((0.8..=1.2).contains(&a.values["mass"]));
            let t = a.values["motor_tau"];
            lo = lo.min(t);
            hi = hi.max(t);
            sum += t.ln();
            assert_eq!(a.values["kp"], 0.6);
        }
        // Log-uniform: ln τ uniform on [ln 0.5, ln 2], mean 0.
        assert!((sum / n as f64).abs() < 0.03 && lo >= 0.5 && hi <= 2.0 && lo < 0.52 && hi > 1.95);
        let f = c.flight(7);
        assert!(f.args.contains(&"--kp".to_string()) && f.args.contains(&"--straight".to_string()));
        // [run] options reach every flight's command line (the yaw mode as `--yaw-mode`).
        let run = text.replace("[draw]", "[run]\nyaw_mode = \"travel\"\nfilter = \"multi\"\n[draw]");
        let r = Campaign::load(&write(&dir, "r.toml", &run)).unwrap_or_else(|e| panic!("{e}"));
        let args = r.flight(3).args;
        assert!(args.windows(2).any(|w| w == ["--yaw-mode", "travel"]), "{args:?}");
        assert!(args.windows(2).any(|w| w == ["--filter", "multi"]), "{args:?}");
        assert_eq!(c.flight(7).values, f.values);
        assert_ne!(c.flight(8).values, f.values);
        // Errors name the file, table, field and what is allowed.
        for (body, want) in [
            ("[draw]\nwindspeed = 1\n", "unknown quantity"),
            ("[draw]\nmass = { uniform = [2, 1] }\n", "a ≤ b"),
            ("[draw]\nmass = { gamma = [2, 1] }\n", "unknown distribution"),
            ("[draw]\nmotor_tau = { log_uniform = [0, 1] }\n", "0 < a"),
        ] {
            let t = format!("flights = 1\n[[scenes]]\nfile = {:?}\n{body}", sc.display().to_string());
            let e = Campaign::load(&write(&dir, "bad.toml", &t)).unwrap_err().to_string();
            assert!(e.contains("bad.toml") && e.contains("[draw]") && e.contains(want), "{e}");
        }
        let e = Campaign::load(&write(&dir, "bad.toml", "flights = 0\n")).unwrap_err().to_string();
        assert!(e.contains("flights") && e.contains("1 ≤ flights"), "{e}");
        for (text, reason, got) in [
            ("seed = 1\n", "missing", None),
            ("flights = 1e9\n", "not an integer", Some("got 1000000000.0")),
            ("flights = 1000000000\n", "out of range", Some("got 1000000000;")),
            ("flights = \"10\"\n", "not an integer", Some("got \"10\"")),
            ("flights = 18446744073709551615\n", "line 1", None),
        ] {
            let e = Campaign::load(&write(&dir, "bad.toml", text)).unwrap_err().to_string();
            assert!(e.contains("field `flights`") && e.contains(reason), "{e}");
            // A value the TOML reader itself cannot hold is named by its line and key.
            assert!(reason == "line 1" || e.contains("1 ≤ flights"), "{e}");
            if let Some(g) = got {
                assert!(e.contains(g), "{e}");
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
