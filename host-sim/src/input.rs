//! Bad user input, and the documented limits on it.
//!
//! [`InputError`] is the one error type for anything a user gave us — a file
//! (scene, path, CSV, vehicle) or a command-line option — that cannot be used.
//! Its message names *where* (the file or `option --name`), the table and field
//! where that applies, the value that was given and the allowed range, so a user
//! can fix the input without reading the source. The CLI maps it to exit code 2.
//! Library error enums (core's `ParamError`, the planner's errors, …) are turned
//! into an `InputError` at the boundary that knows the file or option; their debug
//! text never reaches the user.
//!
//! [`limits`] holds every cap the tools enforce on user input (durations, steps,
//! sweep sizes, …) so `--help`, `scenes/README.md` and the checks use one number.
//!
//! [`exact`] reads fixed-length arrays from files with their length checked.
//!
//! May import: std, serde and `parapet-core`'s public constants (used by every
//! other host-sim module, so nothing else of host-sim).

use std::fmt;

/// Input that cannot be used. `Display`:
/// ``"<where>: [<table>] field `<field>`: <reason> (got <value>; allowed <allowed>)"``,
/// with the parts that do not apply left out.
///
/// The optional parts are `Box<str>` so the whole error stays under clippy's
/// `result_large_err` threshold (128 bytes) and can be returned by value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputError {
    /// The file (path as given) or the option (`option --duration`).
    pub origin: String,
    /// Table in the file (`sim`, `obstacles[1]`), if any.
    pub table: Option<Box<str>>,
    /// Field or column, if any.
    pub field: Option<Box<str>>,
    /// The offending value as the user wrote it (or as parsed), if any.
    pub value: Option<Box<str>>,
    /// The allowed range or set, if any (`0 < x ≤ 3600`, `paper | multi`).
    pub allowed: Option<Box<str>>,
    /// What is wrong, in words.
    pub reason: String,
}

impl InputError {
    /// An error about a file (or a labelled input such as `the planned path`).
    pub fn file(origin: impl fmt::Display, reason: impl Into<String>) -> Self {
        Self {
            origin: origin.to_string(),
            table: None,
            field: None,
            value: None,
            allowed: None,
            reason: reason.into(),
        }
    }

    /// An error about a command-line option (`name` without the dashes).
    pub fn option(name: &str, reason: impl Into<String>) -> Self {
        Self::file(format!("option --{name}"), reason)
    }

    /// Names the table.
    pub fn table(mut self, table: impl Into<String>) -> Self {
        self.table = Some(table.into().into_boxed_str());
        self
    }

    /// Names the field.
    pub fn field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into().into_boxed_str());
        self
    }

    /// States the value given.
    pub fn value(mut self, value: impl fmt::Display) -> Self {
        self.value = Some(value.to_string().into_boxed_str());
        self
    }

    /// States the allowed range or set.
    pub fn allowed(mut self, allowed: impl Into<String>) -> Self {
        self.allowed = Some(allowed.into().into_boxed_str());
        self
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: ", self.origin)?;
        if let Some(t) = &self.table {
            write!(f, "[{t}] ")?;
        }
        if let Some(k) = &self.field {
            write!(f, "field `{k}`: ")?;
        }
        f.write_str(&self.reason)?;
        match (&self.value, &self.allowed) {
            (Some(v), Some(a)) => write!(f, " (got {v}; allowed {a})"),
            (Some(v), None) => write!(f, " (got {v})"),
            (None, Some(a)) => write!(f, " (allowed {a})"),
            (None, None) => Ok(()),
        }
    }
}

impl std::error::Error for InputError {}

/// Caps on user input. Each is documented in `--help` and `scenes/README.md`;
/// a value beyond a cap is refused with an [`InputError`] naming the cap and,
/// where one exists, the option that raises it.
pub mod limits {
    use parapet_core::{cbf, controller, waypoint};

    /// Longest simulated duration of one run (`--duration`, `[sim] duration` or the
    /// default duration), s, unless `--max-duration` raises it. A run stops earlier
    /// at the goal or a collision; memory grows with the time actually flown.
    pub const MAX_DURATION_S: f64 = 3600.0;
    /// Largest value of `--max-duration`, s (one simulated day).
    pub const MAX_DURATION_CEILING_S: f64 = 86_400.0;
    /// Smallest plant integration step (`[sim] dt`, `replay --dt`), s.
    pub const MIN_DT_S: f64 = 1e-5;
    /// Largest plant integration step, s: the inner-loop period (the plant takes
    /// round(1 ms / dt) steps per inner step). Equals `sim::INNER_DT`.
    pub const MAX_DT_S: f64 = 1.0 / parapet_core::wire::rates::INNER_RATE_HZ as f64;
    /// Most plant integration steps of one run or replay (duration / dt).
    pub const MAX_PLANT_STEPS: f64 = 4e8;
    /// Largest `[sensors] position_latency`, s: half the flight controller's
    /// position timeout (`FailsafeParams::position_timeout_us`, 0.2 s), so a fix
    /// delayed by the latency and one outer period is still fresh when arming.
    pub const MAX_POSITION_LATENCY_S: f64 = 0.1;
    /// Largest `[sensors] position_latency` with a filtered source (`position_source` other
    /// than `mocap`), s: the navigation filter's history (`parapet_core::nav`, 0.512 s).
    pub const MAX_FILTERED_LATENCY_S: f64 = 0.5;
    /// Largest `[sensors] rate`, Hz: one fix per outer step.
    pub const MAX_FIX_RATE_HZ: f64 = parapet_core::wire::rates::INNER_RATE_HZ as f64 / 4.0;
    /// The latency cap of a source: [`MAX_POSITION_LATENCY_S`] for motion capture (the
    /// controller extrapolates the latest fix), [`MAX_FILTERED_LATENCY_S`] otherwise.
    pub fn max_position_latency_s(mocap: bool) -> f64 {
        if mocap {
            MAX_POSITION_LATENCY_S
        } else {
            MAX_FILTERED_LATENCY_S
        }
    }
    /// Largest noise standard deviation in `[sensors]` (rad/s, m/s², m, m/s).
    pub const MAX_SENSOR_NOISE: f64 = 100.0;
    /// Largest reference speed (`--speed`, `[mission] speed`, `[controller] speed`),
    /// m/s: the waypoint follower's limit `waypoint::PARAM_LIMIT`.
    pub const MAX_SPEED_MPS: f64 = waypoint::PARAM_LIMIT as f64;
    /// Largest coordinate magnitude of bounds, mission, obstacles (and their sizes)
    /// and path waypoints, m: the core's `waypoint::COORDINATE_LIMIT` (the
    /// controller drops obstacle points beyond `cbf::INPUT_LIMIT`, the same value).
    pub const MAX_COORDINATE_M: f64 = waypoint::COORDINATE_LIMIT as f64;
    /// Most waypoints in a path (planned or `--path`): a MAVLink mission's item count (`u16`).
    /// The controller holds `PATH_CAPACITY` (64) at a time; a longer path is given to it in
    /// windows as it is flown (`parapet_core::outer::path_stream`, issue 38).
    pub const MAX_WAYPOINTS: usize = u16::MAX as usize;
    /// Most obstacle points the controller keeps at once (the most critical of those
    /// reported, `parapet_core::obstacle_set`): `controller::OBSTACLE_CAPACITY`.
    pub const MAX_OBSTACLES_SENSED: usize = controller::OBSTACLE_CAPACITY;
    /// Most obstacles the simulated proximity sensor reports in one outer step (every
    /// obstacle within the sensing range up to this; beyond it the nearest). A scene may
    /// hold more.
    pub const MAX_OBSTACLES_REPORTED: usize = 4096;
    /// Most barriers the `multi` filters enforce at once: `cbf::MAX_ACTIVE_BARRIERS`.
    pub const MAX_BARRIERS: usize = cbf::MAX_ACTIVE_BARRIERS;
    /// Wall-clock budget of the planner's tree search, s (`PlannerParams::time_budget_ms`).
    pub const PLANNER_BUDGET_S: f64 = 1.0;
    /// Largest input file read (scene, path, vehicle, replay CSV), bytes (64 MiB).
    pub const MAX_INPUT_FILE_BYTES: u64 = 64 << 20;
    /// Most data rows of a replay CSV.
    pub const MAX_REPLAY_ROWS: usize = 1_000_000;
    /// Longest time span of a replay CSV (last t − first t), s.
    pub const MAX_REPLAY_SPAN_S: f64 = 3600.0;
    /// Longest `pil --timeout` (wall-clock wait for the firmware), s.
    pub const MAX_PIL_TIMEOUT_S: f64 = 3600.0;

    /// The flight controller's position timeout, s (`FailsafeParams::position_timeout_us`),
    /// which [`MAX_POSITION_LATENCY_S`] stays below.
    pub fn position_timeout_s() -> f64 {
        parapet_core::failsafe::FailsafeParams::default().position_timeout_us as f64 * 1e-6
    }

    // Within the default caps, the step cap never binds at the smallest dt.
    const _: () = assert!(MAX_DURATION_S / MIN_DT_S <= MAX_PLANT_STEPS);
    const _: () = assert!(MAX_REPLAY_SPAN_S / MIN_DT_S <= MAX_PLANT_STEPS);

    // --- sweep (owner: the sweep engineer) ---

    /// Most values in one `parapet sweep` range (`--mu`, `--delta1`, `--speed` `A:B:N`: N ≤ this).
    pub const SWEEP_MAX_VALUES: usize = 10_000;

    /// Most parameter axes of one `parapet sweep` (`--grid NAME=A:B:N`, repeatable), beside
    /// `--mu`, `--delta1`, `--speed` and the seeds: each axis multiplies the grid.
    pub const SWEEP_MAX_GRID_PARAMS: usize = 3;

    /// Most sensor-noise seeds of a sweep (`--seeds K`: K ≤ this).
    pub const SWEEP_MAX_SEEDS: u64 = 10_000;
    /// Largest number of flights of a campaign (`campaign::spec::MAX_FLIGHTS`).
    pub const CAMPAIGN_MAX_FLIGHTS: u64 = 1_000_000;

    /// Most runs one `parapet sweep` invocation flies (the grid, or its `--shard I/N`
    /// slice); a larger grid must be split with `--shard I/N`.
    pub const SWEEP_MAX_RUNS: u64 = 1_000_000;

    /// Runs above which `parapet sweep` asks for `--yes` (the message states the count
    /// and the estimated time).
    pub const SWEEP_CONFIRM_RUNS: u64 = 10_000;

    /// Most threads of `parapet sweep --jobs`.
    pub const SWEEP_MAX_JOBS: usize = 256;
}

/// A number as a user reads it: shortest decimal, exponent form for very large
/// or small magnitudes (`1e300`, `1e-7`, `0.002`, `150`).
pub fn num(x: f64) -> String {
    let shortest = |x: f64| {
        if x != 0.0 && x.is_finite() && !(1e-4..1e6).contains(&x.abs()) {
            format!("{x:e}")
        } else {
            format!("{x}")
        }
    };
    let s = shortest(x);
    // A computed value (900014.9999999999): 7 significant digits are enough.
    match format!("{x:.6e}").parse::<f64>() {
        Ok(r) if s.len() > 12 => shortest(r),
        _ => s,
    }
}

/// Read a user-given text file, refusing one larger than
/// [`limits::MAX_INPUT_FILE_BYTES`]; errors name the file.
pub fn read_text(path: &std::path::Path) -> Result<String, InputError> {
    use std::io::Read as _;
    let shown = path.display();
    let cannot = |e: std::io::Error| InputError::file(&shown, format!("cannot read the file: {e}"));
    let f = std::fs::File::open(path).map_err(cannot)?;
    let mut text = String::new();
    let cap = limits::MAX_INPUT_FILE_BYTES;
    let n = f.take(cap + 1).read_to_string(&mut text).map_err(cannot)?;
    if n as u64 > cap {
        return Err(InputError::file(&shown, "the file is too large")
            .value(format!("more than {cap} bytes"))
            .allowed(format!("at most {cap} bytes")));
    }
    Ok(text)
}

/// The `f64` value of an `f32` constant with its shortest decimal form
/// (`1.4f32` → `1.4`, not `1.399999976158142`); the `f32` round trip is exact.
pub fn f32_as_f64(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(x as f64)
}

/// A number written with `D` decimals in a file (`trajectory.csv`, replay output):
/// serialises as that text.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fixed<const D: usize>(pub f64);

impl<const D: usize> serde::Serialize for Fixed<D> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // The text of `{:.D}` (crate::decimal), without a heap string per number.
        crate::decimal::with_fixed(self.0, D, |text| s.serialize_str(text))
    }
}

/// Fixed-length number arrays (`start = [x, y, z]`) read with their length
/// checked: serde's `[f64; N]` takes the first N elements from a TOML document
/// and silently drops the rest; these refuse any other length with serde's
/// "invalid length L, expected an array of N numbers", which the file's error
/// text locates (line, table, field). Use with `#[serde(deserialize_with = …)]`
/// (plus `default` for the `Option` forms).
pub mod exact {
    use std::fmt;

    use serde::de::{Deserializer, Error, SeqAccess, Visitor};
    use serde::Deserialize;

    /// `[f64; N]` that refuses arrays of another length.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Exact<const N: usize>(pub [f64; N]);

    struct ArrayVisitor<const N: usize>;

    impl<'de, const N: usize> Visitor<'de> for ArrayVisitor<N> {
        type Value = [f64; N];

        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            write!(f, "an array of {N} numbers")
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[f64; N], A::Error> {
            let mut out = [0.0; N];
            let mut n = 0usize;
            while let Some(x) = seq.next_element::<f64>()? {
                if let Some(slot) = out.get_mut(n) {
                    *slot = x;
                }
                n += 1;
            }
            if n == N {
                Ok(out)
            } else {
                Err(A::Error::invalid_length(n, &self))
            }
        }
    }

    impl<'de, const N: usize> Deserialize<'de> for Exact<N> {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            d.deserialize_seq(ArrayVisitor::<N>).map(Exact)
        }
    }

    /// A required `[f64; N]` field.
    pub fn array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
        Exact::<N>::deserialize(d).map(|a| a.0)
    }

    /// An optional `[f64; N]` field (with `#[serde(default)]`).
    pub fn option_array<'de, D: Deserializer<'de>, const N: usize>(
        d: D,
    ) -> Result<Option<[f64; N]>, D::Error> {
        Option::<Exact<N>>::deserialize(d).map(|o| o.map(|a| a.0))
    }

    /// An optional list of `[f64; N]` (with `#[serde(default)]`).
    pub fn option_arrays<'de, D: Deserializer<'de>, const N: usize>(
        d: D,
    ) -> Result<Option<Vec<[f64; N]>>, D::Error> {
        Option::<Vec<Exact<N>>>::deserialize(d).map(|o| o.map(|v| v.into_iter().map(|a| a.0).collect()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_agree_with_the_code_they_describe() {
        assert_eq!(limits::MAX_DT_S, crate::sim::INNER_DT);
        assert_eq!(limits::PLANNER_BUDGET_S * 1000.0, crate::plan::PlannerParams::default().time_budget_ms);
        let timeout_us = parapet_core::failsafe::FailsafeParams::default().position_timeout_us;
        assert!((limits::MAX_POSITION_LATENCY_S * 1e6).round() as u64 <= timeout_us / 2);
    }

    #[test]
    fn read_text_refuses_a_file_over_the_cap() {
        let dir = std::env::temp_dir().join(format!("parapet-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("big.csv");
        let file = std::fs::File::create(&f).unwrap();
        file.set_len(limits::MAX_INPUT_FILE_BYTES + 1).unwrap();
        let e = read_text(&f).unwrap_err().to_string();
        assert!(e.contains("big.csv") && e.contains("too large"), "{e}");
        std::fs::write(&f, "ok").unwrap();
        assert_eq!(read_text(&f).unwrap(), "ok");
        assert!(read_text(&dir.join("none")).unwrap_err().to_string().contains("none"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn numbers_read_like_the_input() {
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(1e-7), "1e-7");
        assert_eq!(num(0.002), "0.002");
        assert_eq!(num(150.0), "150");
        assert_eq!(num(1e7), "1e7");
        assert_eq!(num(f64::NAN), "NaN");
        assert_eq!(num(900014.9999999999), "900015");
        assert_eq!(num(0.123456789), "0.123456789");
        assert_eq!(num(0.12345678912345), "0.1234568");
        assert_eq!(num(1.399999976158142), "1.4");
    }

    #[test]
    fn small_enough_to_return_by_value() {
        assert!(std::mem::size_of::<InputError>() <= 128, "{}", std::mem::size_of::<InputError>());
    }

    #[test]
    fn display_names_every_part() {
        let e = InputError::file("scenes/x.toml", "out of range")
            .table("sim")
            .field("dt")
            .value(0.002)
            .allowed("0 < dt ≤ 0.001");
        assert_eq!(
            e.to_string(),
            "scenes/x.toml: [sim] field `dt`: out of range (got 0.002; allowed 0 < dt ≤ 0.001)"
        );
        let o = InputError::option("duration", "too long").value("1e20");
        assert_eq!(o.to_string(), "option --duration: too long (got 1e20)");
    }
}
