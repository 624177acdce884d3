//! The sweep grid: value ranges (`--mu`, `--delta1`, `--speed`), the parameter axes
//! (`--grid NAME=A:B:N`, [`parse_axes`]), the seed count (`--seeds`), shards
//! (`--shard I/N`), grid indices and the size checks.
//!
//! The grid is never materialised: its size is computed with checked arithmetic
//! and a run's parameters are decoded from its index ([`Grid::point`]), so a
//! refused or sharded grid costs nothing proportional to its size. Index order is
//! speed-major, then μ, δ1, the `--grid` axes in the order given, seed (seed fastest).
//!
//! May import: `crate::input` (errors and caps), `parapet_core::params` (the table), serde.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::input::limits::{SWEEP_MAX_GRID_PARAMS, SWEEP_MAX_SEEDS, SWEEP_MAX_VALUES};
use crate::input::InputError;
use parapet_core::params::{self, Param, TABLE};

/// An inclusive range `A:B:N` of `N` evenly spaced values, or one value `A`
/// (same as `A:A:1`).
#[derive(Clone, Debug, PartialEq)]
pub struct GridRange {
    /// First value.
    pub start: f64,
    /// Last value.
    pub end: f64,
    /// Number of values (1..=[`SWEEP_MAX_VALUES`]).
    pub n: usize,
}

impl GridRange {
    /// Parse `A:B:N` (A ≤ B finite and > 0, N a whole number in
    /// 1..=[`SWEEP_MAX_VALUES`]; N = 1 needs A = B) or a single value `A`.
    pub fn parse(s: &str) -> Result<GridRange, String> {
        Self::parse_values(s, true)
    }

    /// [`GridRange::parse`] without the sign rule (a `--grid` axis: its parameter's range decides).
    pub fn parse_any(s: &str) -> Result<GridRange, String> {
        Self::parse_values(s, false)
    }

    fn parse_values(s: &str, positive: bool) -> Result<GridRange, String> {
        let num = |t: &str| -> Result<f64, String> {
            t.trim().parse::<f64>().map_err(|_| format!("{s:?}: {t:?} is not a number"))
        };
        let parts: Vec<&str> = s.split(':').collect();
        let (a, b, n) = match parts.as_slice() {
            [one] => {
                let a = num(one)?;
                (a, a, 1)
            }
            [a, b, n] => {
                let n: usize = n.trim().parse().map_err(|_| {
                    format!("{s:?}: count {n:?} is not a whole number (allowed 1..={SWEEP_MAX_VALUES})")
                })?;
                (num(a)?, num(b)?, n)
            }
            _ => {
                return Err(format!(
                    "{s:?}: expected A:B:N (first:last:count, e.g. 0.5:1.4:4) or one value (e.g. 0.9)"
                ))
            }
        };
        if !(a.is_finite() && b.is_finite()) {
            return Err(format!("{s:?}: the values must be finite"));
        }
        if positive && !(a > 0.0 && b > 0.0) {
            return Err(format!("{s:?}: the values must be finite and > 0"));
        }
        if n == 0 || n > SWEEP_MAX_VALUES {
            return Err(format!(
                "{s:?}: the count must be in 1..={SWEEP_MAX_VALUES} (input::limits::SWEEP_MAX_VALUES), got {n}"
            ));
        }
        if a > b {
            return Err(format!("{s:?}: the first value exceeds the last"));
        }
        if n == 1 && a != b {
            return Err(format!("{s:?}: a count of 1 needs first = last (or write the one value, e.g. {a})"));
        }
        Ok(GridRange { start: a, end: b, n })
    }

    /// The values, first to last (the last is exactly `end`).
    pub fn values(&self) -> Vec<f64> {
        if self.n == 1 {
            return vec![self.start];
        }
        (0..self.n)
            .map(|i| {
                if i + 1 == self.n {
                    self.end
                } else {
                    self.start + (self.end - self.start) * i as f64 / (self.n - 1) as f64
                }
            })
            .collect()
    }
}

impl std::fmt::Display for GridRange {
    /// `A:B:N` with the shortest round-trip form of each number (parses back exactly).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.start, self.end, self.n)
    }
}

impl Serialize for GridRange {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for GridRange {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        GridRange::parse(&s).map_err(serde::de::Error::custom)
    }
}

/// One `--grid NAME=A:B:N` axis: a parameter of the table by its name and its values
/// (`NAME=A:B:N` in `sweep.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub struct ParamAxis {
    /// The parameter's name (`cargo xtask params`).
    pub name: String,
    /// Its values.
    pub range: GridRange,
}

impl From<ParamAxis> for String {
    /// `NAME=A:B:N` (parses back exactly).
    fn from(a: ParamAxis) -> String {
        format!("{}={}", a.name, a.range)
    }
}

impl TryFrom<String> for ParamAxis {
    type Error = String;
    fn try_from(s: String) -> Result<ParamAxis, String> {
        let (name, r) = s.split_once('=').ok_or_else(|| format!("{s:?}: expected NAME=A:B:N"))?;
        Ok(ParamAxis { name: name.to_string(), range: GridRange::parse_any(r)? })
    }
}

/// The options of a sweep that set parameters another way: an axis may not name them.
pub struct Taken<'a> {
    /// `--param NAME=VALUE` options as given.
    pub params: &'a [String],
    /// `--filter` given (CBF_VARIANT).
    pub filter: bool,
    /// `--guidance` given (MIS_GUIDANCE).
    pub guidance: bool,
}

/// Parse and check the `--grid NAME=A:B:N` options: at most [`SWEEP_MAX_GRID_PARAMS`], each a
/// known continuous parameter (a code parameter is refused: one sweep per code with `--param`),
/// not one the sweep sets otherwise (`CBF_MU` `--mu`, `CBF_DELTA1` `--delta1`, `WP_SPEED`
/// `--speed`, a `--param`, another `--grid`), every value in the parameter's range. Errors
/// name the option, the parameter, the value and what is allowed.
pub fn parse_axes(given: &[String], taken: &Taken) -> Result<Vec<(&'static Param, ParamAxis)>, InputError> {
    let opt = |why: &str| InputError::option("grid", why);
    if given.len() > SWEEP_MAX_GRID_PARAMS {
        return Err(opt("too many parameter axes (input::limits::SWEEP_MAX_GRID_PARAMS)")
            .value(given.len())
            .allowed(format!("at most {SWEEP_MAX_GRID_PARAMS} --grid options")));
    }
    let mut out: Vec<(&'static Param, ParamAxis)> = Vec::new();
    for g in given {
        let Some((name, r)) = g.split_once('=') else {
            return Err(opt("expected NAME=A:B:N").value(g).allowed("e.g. --grid TRJ_ACC=0.5:2:4"));
        };
        let name = name.trim();
        let Some(d) = params::index_of(name).map(|i| &TABLE[i]) else {
            return Err(opt("unknown parameter")
                .field(name)
                .allowed("a name of `cargo xtask params` / `parapet params export` (e.g. TRJ_ACC)"));
        };
        let other = match d.name {
            "CBF_MU" => Some("--mu"),
            "CBF_DELTA1" => Some("--delta1"),
            "WP_SPEED" => Some("--speed"),
            "CBF_VARIANT" if taken.filter => Some("--filter"),
            "MIS_GUIDANCE" if taken.guidance => Some("--guidance"),
            n if taken.params.iter().any(|p| p.split_once('=').is_some_and(|(q, _)| q.trim() == n)) => {
                Some("--param")
            }
            n if out.iter().any(|(p, _)| p.name == n) => Some("--grid"),
            _ => None,
        };
        if let Some(o) = other {
            return Err(opt(&format!("the parameter is already set by {o}")).field(d.name).value(g).allowed(
                match o {
                    "--mu" | "--delta1" | "--speed" => format!("grid {} with {o} A:B:N", d.name),
                    _ => format!("{} set once: by {o} or by --grid, not both", d.name),
                },
            ));
        }
        if d.integer {
            return Err(opt("a code parameter cannot be gridded").field(d.name).value(r).allowed(format!(
                "a continuous parameter; fly one sweep per code with --param {}=CODE",
                d.name
            )));
        }
        let range = GridRange::parse_any(r).map_err(|e| opt("not a range").field(d.name).value(e))?;
        if let Some(v) = range.values().into_iter().find(|v| d.check(*v as f32).is_err()) {
            return Err(opt("value out of range").field(d.name).value(v).allowed(d.range().to_string()));
        }
        out.push((d, ParamAxis { name: d.name.to_string(), range }));
    }
    Ok(out)
}

/// `x` as the controller holds it (`f32`), written back as its shortest decimal: what a sweep
/// row's `--grid` column holds.
pub fn as_flown(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(f64::from(x))
}

/// Parse `--seeds K`: a count (1..=[`SWEEP_MAX_SEEDS`]) of sensor-noise seeds
/// 0..K-1. A range `a..b` is refused with a hint (it is a count, not a range).
pub fn parse_seed_count(s: &str) -> Result<u64, String> {
    if s.contains("..") {
        return Err(format!(
            "{s:?}: --seeds is a count K (the runs use seeds 0..K-1), not a range: \
             e.g. --seeds 4 flies seeds 0, 1, 2, 3"
        ));
    }
    let k: u64 = s.trim().parse().map_err(|_| {
        format!("{s:?}: not a whole number (a count K of seeds, allowed 1..={SWEEP_MAX_SEEDS})")
    })?;
    if k == 0 || k > SWEEP_MAX_SEEDS {
        return Err(format!(
            "{s:?}: the seed count must be in 1..={SWEEP_MAX_SEEDS} (input::limits::SWEEP_MAX_SEEDS)"
        ));
    }
    Ok(k)
}

/// `--shard I/N`: the I-th (1-based) of N interleaved slices of the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// Slice number, 1..=count.
    pub index: u64,
    /// Number of slices.
    pub count: u64,
}

impl Shard {
    /// The whole grid as one shard.
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// Parse `I/N` with 1 ≤ I ≤ N.
    pub fn parse(s: &str) -> Result<Shard, String> {
        let (i, n) = s.split_once('/').ok_or_else(|| format!("{s:?}: expected I/N, e.g. 2/4"))?;
        let i: u64 = i.trim().parse().map_err(|_| format!("{s:?}: {i:?} is not a whole number"))?;
        let n: u64 = n.trim().parse().map_err(|_| format!("{s:?}: {n:?} is not a whole number"))?;
        if n == 0 || i == 0 || i > n {
            return Err(format!("{s:?}: need 1 <= I <= N"));
        }
        Ok(Shard { index: i, count: n })
    }

    /// Whether grid index `k` belongs to this shard.
    pub fn contains(&self, k: u64) -> bool {
        k % self.count == self.index - 1
    }

    /// Number of indices of a grid of `total` runs in this shard.
    pub fn len(&self, total: u64) -> u64 {
        let first = self.index - 1;
        if total <= first {
            0
        } else {
            (total - first - 1) / self.count + 1
        }
    }

    /// Whether the shard has no index of a grid of `total` runs.
    pub fn is_empty(&self, total: u64) -> bool {
        self.len(total) == 0
    }

    /// The `j`-th grid index of this shard (j = 0, 1, …).
    pub fn nth(&self, j: u64) -> u64 {
        j * self.count + (self.index - 1)
    }
}

/// One run of the grid.
#[derive(Clone, Debug, PartialEq)]
pub struct GridPoint {
    /// Index in the full grid (speed-major, then μ, δ1, seed).
    pub index: u64,
    /// μ, s.
    pub mu: f64,
    /// δ1, m².
    pub delta1: f64,
    /// Reference speed, m/s.
    pub speed: f64,
    /// Sensor-noise seed.
    pub seed: u64,
    /// The values of the `--grid` axes, in their order.
    pub params: Vec<f64>,
}

/// The grid speed × μ × δ1 × `--grid` axes × seeds, with its values (at most
/// [`SWEEP_MAX_VALUES`] per axis) but not its points.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Speeds, m/s.
    pub speeds: Vec<f64>,
    /// μ values, s.
    pub mu: Vec<f64>,
    /// δ1 values, m².
    pub delta1: Vec<f64>,
    /// Seed count K (seeds 0..K).
    pub seeds: u64,
    /// The `--grid` axes: parameter name and values.
    pub params: Vec<(String, Vec<f64>)>,
}

impl Grid {
    /// The grid of these ranges.
    pub fn new(mu: &GridRange, delta1: &GridRange, speed: &GridRange, seeds: u64) -> Grid {
        Grid { speeds: speed.values(), mu: mu.values(), delta1: delta1.values(), seeds, params: Vec::new() }
    }

    /// This grid with the parameter axes `axes`.
    pub fn with_axes(mut self, axes: &[ParamAxis]) -> Grid {
        self.params = axes.iter().map(|a| (a.name.clone(), a.range.values())).collect();
        self
    }

    /// Number of runs, `None` when it does not fit in a u64.
    pub fn size(&self) -> Option<u64> {
        [self.speeds.len(), self.mu.len(), self.delta1.len()]
            .into_iter()
            .chain(self.params.iter().map(|(_, v)| v.len()))
            .try_fold(self.seeds, |acc, n| acc.checked_mul(u64::try_from(n).ok()?))
    }

    /// The run with grid index `k` (`k` < [`Grid::size`]).
    pub fn point(&self, k: u64) -> GridPoint {
        let nd = self.delta1.len().max(1) as u64;
        let nm = self.mu.len().max(1) as u64;
        let seed = k % self.seeds.max(1);
        let mut rest = k / self.seeds.max(1);
        let pick = |v: &[f64], i: usize| v.get(i).or(v.last()).copied().unwrap_or(f64::NAN);
        // The last axis varies fastest (after the seed).
        let mut params = vec![f64::NAN; self.params.len()];
        for (slot, (_, v)) in params.iter_mut().zip(&self.params).rev() {
            let n = v.len().max(1) as u64;
            *slot = pick(v, (rest % n) as usize);
            rest /= n;
        }
        let (d, rest) = ((rest % nd) as usize, rest / nd);
        let (m, s) = ((rest % nm) as usize, (rest / nm) as usize);
        GridPoint {
            index: k,
            mu: pick(&self.mu, m),
            delta1: pick(&self.delta1, d),
            speed: pick(&self.speeds, s),
            seed,
            params,
        }
    }

    /// "3 speeds × 4 μ × 2 δ1 × 2 TRJ_ACC × 5 seeds", for messages.
    pub fn describe(&self) -> String {
        let axes: String = self.params.iter().map(|(n, v)| format!(" × {} {n}", v.len())).collect();
        format!(
            "{} speeds × {} μ × {} δ1{axes} × {} seeds",
            self.speeds.len(),
            self.mu.len(),
            self.delta1.len(),
            self.seeds
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_and_reject() {
        assert_eq!(GridRange::parse("0.5:1.4:4").unwrap().values().len(), 4);
        let v = GridRange::parse("0.051:0.3:3").unwrap().values();
        assert_eq!(v[0], 0.051);
        assert_eq!(v[2], 0.3);
        assert!((v[1] - 0.1755).abs() < 1e-12);
        assert_eq!(GridRange::parse("1:1:1").unwrap().values(), vec![1.0]);
        // One value is the range A:A:1.
        assert_eq!(GridRange::parse("0.9").unwrap(), GridRange::parse("0.9:0.9:1").unwrap());
        for bad in [
            "1:2", "a:2:3", "1:2:0", "2:1:3", "-1:2:3", "1:2:x", "1:2:1", "nan:1:2", "1:inf:2", "0", "-0.9",
            "x",
        ] {
            assert!(GridRange::parse(bad).is_err(), "{bad} accepted");
        }
        let too_many = format!("1:2:{}", SWEEP_MAX_VALUES + 1);
        assert!(GridRange::parse(&too_many).unwrap_err().contains("SWEEP_MAX_VALUES"));
        assert!(GridRange::parse(&format!("1:2:{SWEEP_MAX_VALUES}")).is_ok());
        // Display parses back to the same range (the manifest stores it so).
        let r = GridRange::parse("0.051:0.3:4").unwrap();
        assert_eq!(GridRange::parse(&r.to_string()).unwrap(), r);
    }

    #[test]
    fn seed_counts() {
        assert_eq!(parse_seed_count("4"), Ok(4));
        assert_eq!(parse_seed_count(&SWEEP_MAX_SEEDS.to_string()), Ok(SWEEP_MAX_SEEDS));
        assert!(parse_seed_count("0..4").unwrap_err().contains("count"));
        assert!(parse_seed_count("0").is_err());
        assert!(parse_seed_count("18446744073709551615").unwrap_err().contains("SWEEP_MAX_SEEDS"));
        assert!(parse_seed_count("18446744073709551616").is_err());
    }

    #[test]
    fn shards_partition_the_grid() {
        let s: Vec<Shard> = (1..=3).map(|i| Shard::parse(&format!("{i}/3")).unwrap()).collect();
        for k in 0..20 {
            assert_eq!(s.iter().filter(|x| x.contains(k)).count(), 1);
        }
        for total in 0..12 {
            for x in &s {
                let listed: Vec<u64> = (0..x.len(total)).map(|j| x.nth(j)).collect();
                let want: Vec<u64> = (0..total).filter(|&k| x.contains(k)).collect();
                assert_eq!(listed, want, "shard {x:?} of {total}");
            }
        }
        for bad in ["0/3", "4/3", "1/0", "x/2", "1-2"] {
            assert!(Shard::parse(bad).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn grid_order_size_and_decoding() {
        let mu = GridRange::parse("0.5:1:2").unwrap();
        let d1 = GridRange::parse("0.1:0.3:3").unwrap();
        let sp = GridRange::parse("0.25:0.5:2").unwrap();
        let g = Grid::new(&mu, &d1, &sp, 2);
        assert_eq!(g.size(), Some(24));
        // The decoded points are the nested loops speed, μ, δ1, seed in index order.
        let mut k = 0;
        for &speed in &g.speeds {
            for &m in &g.mu {
                for &d in &g.delta1 {
                    for seed in 0..2 {
                        let params = Vec::new();
                        assert_eq!(g.point(k), GridPoint { index: k, mu: m, delta1: d, speed, seed, params });
                        k += 1;
                    }
                }
            }
        }
        // Sizes beyond u64 are None, not a wrapped number.
        let big = GridRange::parse("1:2:10000").unwrap();
        let huge = Grid::new(&big, &big, &big, u64::MAX / 2);
        assert_eq!(huge.size(), None);
        let ok = Grid::new(&big, &big, &big, SWEEP_MAX_SEEDS);
        assert_eq!(ok.size(), Some(10_000u64.pow(3) * SWEEP_MAX_SEEDS));
    }

    #[test]
    fn parameter_axes_decode_in_order_and_are_checked() {
        let one = GridRange::parse("1").unwrap();
        let acc = ParamAxis { name: "TRJ_ACC".into(), range: GridRange::parse_any("0.5:2:4").unwrap() };
        let jerk = ParamAxis { name: "TRJ_JERK".into(), range: GridRange::parse_any("1:2:2").unwrap() };
        let g = Grid::new(&GridRange::parse("0.5:1:2").unwrap(), &one, &one, 3).with_axes(&[acc, jerk]);
        assert_eq!(g.size(), Some(2 * 4 * 2 * 3));
        assert!(g.describe().contains("× 1 δ1 × 4 TRJ_ACC × 2 TRJ_JERK × 3 seeds"), "{}", g.describe());
        let mut k = 0;
        for &m in &g.mu {
            for &a in &g.params[0].1 {
                for &j in &g.params[1].1 {
                    for seed in 0..3 {
                        let p = g.point(k);
                        assert_eq!((p.mu, p.params, p.seed), (m, vec![a, j], seed), "k {k}");
                        k += 1;
                    }
                }
            }
        }
        let strings = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
        let none = Taken { params: &[], filter: false, guidance: false };
        let ok = parse_axes(&strings(&["TRJ_ACC=0.5:2:4", "PCP_TRK_SIZE=0:1:2"]), &none).unwrap();
        assert_eq!(
            String::from(ok[1].1.clone()),
            "PCP_TRK_SIZE=0:1:2",
            "0 allowed where the range allows it"
        );
        let four = strings(&["TRJ_ACC=1", "TRJ_JERK=1", "TRJ_V_UP=1", "TRJ_V_DN=1"]);
        for (given, want) in [
            (four, "at most 3"),
            (strings(&["NO_SUCH=1:2:2"]), "NO_SUCH"),
            (strings(&["TRJ_ACC"]), "NAME=A:B:N"),
            (strings(&["TRJ_ACC=0.05:1:3"]), "0.1 ≤ TRJ_ACC ≤ 15"),
            (strings(&["TRJ_ACC=2:1:3"]), "first value exceeds"),
            (strings(&["CBF_MU=0.5:1:2"]), "--mu"),
            (strings(&["CBF_DELTA1=0.1:0.2:2"]), "--delta1"),
            (strings(&["WP_SPEED=0.5:1:2"]), "--speed"),
            (strings(&["TRJ_ACC=1:2:2", "TRJ_ACC=3"]), "already set by --grid"),
            (strings(&["CBF_VARIANT=0:3:4"]), "code parameter"),
        ] {
            let e = parse_axes(&given, &none).unwrap_err().to_string();
            assert!(e.contains("--grid") && e.contains(want), "{given:?}: {e}");
        }
        let p = strings(&["TRJ_ACC=1"]);
        let taken = Taken { params: &p, filter: true, guidance: true };
        for (axis, want) in [("TRJ_ACC=1:2:2", "--param"), ("MIS_GUIDANCE=1", "--guidance")] {
            let e = parse_axes(&strings(&[axis]), &taken).unwrap_err().to_string();
            assert!(e.contains(want), "{axis}: {e}");
        }
        // The manifest's form parses back.
        let a = &ok[0].1;
        let text = serde_json::to_string(a).unwrap();
        assert_eq!(serde_json::from_str::<ParamAxis>(&text).unwrap(), *a);
        assert_eq!(as_flown(0.3), 0.3);
    }
}
