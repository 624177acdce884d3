//! `sweep.json`: the identity of a sweep, written next to its `sweep.csv`, so
//! `sweep-merge` can refuse shards that do not belong together.
//!
//! [`Identity`] is everything that decides the rows: parapet version and CSV
//! format, scene name and a hash of the scene file's bytes, the path flown (its
//! source and a hash of its waypoints), filter, noise, duration rule and cap, the
//! grid (μ, δ1, speed ranges, the `--grid` parameter axes, seed count), the
//! parameters set by name. Two shards merge only when their identities
//! are equal and they split the grid the same way (same N); [`plan_merge`] finds
//! the shards that are missing or given twice. The manifest is written after the
//! last row, so a sweep that was interrupted has none and cannot be merged.
//!
//! May import: `super::grid`, `crate::input` (errors), serde, serde_json.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::grid::{Grid, GridRange, ParamAxis};
use crate::input::limits::MAX_INPUT_FILE_BYTES;
use crate::input::InputError;

/// Version of the `sweep.csv` + `sweep.json` format (changes with the columns).
pub const FORMAT: u32 = 4;

/// FNV-1a, 64 bit: a stable fingerprint (not a security hash) of a scene file or path.
pub fn fnv1a64(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// What decides a sweep's rows; equal for every shard of one sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Identity {
    /// [`FORMAT`].
    pub format: u32,
    /// `parapet` version that flew it.
    pub parapet_version: String,
    /// Scene name.
    pub scene: String,
    /// [`fnv1a64`] of the scene file's bytes.
    pub scene_fnv1a64: String,
    /// Where the path came from: `planner`, `file` or `straight`.
    pub path_source: String,
    /// Planner seed (planned paths only).
    pub plan_seed: Option<u64>,
    /// [`fnv1a64`] of the flown waypoints (NED f64, little-endian bits).
    pub path_fnv1a64: String,
    /// `--foreign-path` given.
    pub foreign_path: bool,
    /// Filter variant.
    pub filter: String,
    /// Sensor noise on.
    pub noise: bool,
    /// Duration limit of each run, s (`None`: the default duration at its speed).
    pub duration_s: Option<f64>,
    /// `--max-duration`, s (decides which runs fail).
    pub max_duration_s: f64,
    /// μ range, s.
    pub mu: GridRange,
    /// δ1 range, m².
    pub delta1: GridRange,
    /// Speed range, m/s.
    pub speed: GridRange,
    /// Seed count K (seeds 0..K).
    pub seeds: u64,
    /// Parameters set by name for every run (`--param`, `--params`): name → value as given
    /// (absent when none; a keyed one that the grid sets, μ, δ1 or the speed, is the grid's).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub params: std::collections::BTreeMap<String, f64>,
    /// The `--grid NAME=A:B:N` axes, in their order (absent when none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub grid_params: Vec<ParamAxis>,
}

impl Identity {
    /// The grid.
    pub fn grid(&self) -> Grid {
        Grid::new(&self.mu, &self.delta1, &self.speed, self.seeds).with_axes(&self.grid_params)
    }

    /// The first field where `self` and `other` differ, with both values as JSON.
    pub fn first_difference(&self, other: &Identity) -> Option<(String, String, String)> {
        let (a, b) = (serde_json::to_value(self).ok()?, serde_json::to_value(other).ok()?);
        let (a, b) = (a.as_object()?, b.as_object()?);
        // Every key of either side: a field one side leaves out (`params`) is null there.
        a.keys().chain(b.keys().filter(|k| !a.contains_key(*k))).find_map(|k| {
            let (va, vb) = (a.get(k).cloned().unwrap_or_default(), b.get(k).cloned().unwrap_or_default());
            (va != vb).then(|| (k.clone(), va.to_string(), vb.to_string()))
        })
    }
}

/// `sweep.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// What the rows depend on.
    pub identity: Identity,
    /// Scene file as given (informative; not compared).
    pub scene_file: String,
    /// Path file as given, if any (informative; not compared).
    pub path_file: Option<String>,
    /// Number of runs in the whole grid.
    pub grid_runs: u64,
    /// N of `--shard I/N` (1 unsharded, or a complete merge).
    pub shard_count: u64,
    /// The shards I (1-based) whose rows `sweep.csv` holds, ascending.
    pub shards: Vec<u64>,
    /// Rows in `sweep.csv`.
    pub rows: u64,
    /// Rows with status `failed`.
    pub failed: u64,
}

impl Manifest {
    /// Read and check a `sweep.json`.
    pub fn read(path: &Path) -> Result<Manifest, InputError> {
        let file = path.display().to_string();
        let len = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
        if len > MAX_INPUT_FILE_BYTES {
            return Err(InputError::file(
                &file,
                "too large for a sweep manifest (input::limits::MAX_INPUT_FILE_BYTES)",
            )
            .value(format!("{len} bytes"))
            .allowed(format!("≤ {MAX_INPUT_FILE_BYTES} bytes")));
        }
        let text = std::fs::read_to_string(path).map_err(|e| {
            InputError::file(
                &file,
                format!(
                    "cannot read the sweep manifest: {e} (every `parapet sweep` writes sweep.json next to \
                     sweep.csv once its last run is done; a sweep that was interrupted has none)"
                ),
            )
        })?;
        let m: Manifest = serde_json::from_str(&text).map_err(|e| {
            InputError::file(
                &file,
                format!("line {}: not a sweep manifest of this parapet version: {e}", e.line()),
            )
        })?;
        if m.identity.format != FORMAT {
            return Err(InputError::file(&file, "written by a different parapet version")
                .field("identity.format")
                .value(m.identity.format)
                .allowed(FORMAT.to_string()));
        }
        let runs = m.identity.grid().size();
        if runs != Some(m.grid_runs) {
            return Err(InputError::file(&file, "does not match the grid")
                .field("grid_runs")
                .value(m.grid_runs));
        }
        let sorted = m.shards.windows(2).all(|w| w[0] < w[1]);
        if m.shard_count == 0 || !sorted || m.shards.iter().any(|&i| i == 0 || i > m.shard_count) {
            return Err(InputError::file(&file, "bad shard list")
                .field("shards")
                .value(format!("{:?} of {}", m.shards, m.shard_count))
                .allowed(format!("ascending, each in 1..={}", m.shard_count)));
        }
        Ok(m)
    }

    /// Write as pretty JSON.
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        std::fs::write(path, text + "\n")
    }
}

/// The shards of a merge: which input holds each present shard, which are missing.
#[derive(Clone, Debug, PartialEq)]
pub struct MergePlan {
    /// N.
    pub shard_count: u64,
    /// `(I, input number)` for every present shard, ascending in I.
    pub present: Vec<(u64, usize)>,
    /// Absent shards I, ascending.
    pub missing: Vec<u64>,
}

/// Check that `inputs` (name, manifest) belong to one sweep split the same way,
/// each shard at most once; returns where each shard is and which are missing.
pub fn plan_merge(inputs: &[(String, Manifest)]) -> Result<MergePlan, InputError> {
    let Some((first_name, first)) = inputs.first() else {
        return Err(InputError::file("sweep-merge", "no input"));
    };
    let mut owner: std::collections::BTreeMap<u64, usize> = Default::default();
    for (k, (name, m)) in inputs.iter().enumerate() {
        if let Some((field, a, b)) = first.identity.first_difference(&m.identity) {
            return Err(InputError::file(
                name,
                format!("is from a different sweep than {first_name}: {field} is {b} here, {a} there"),
            )
            .field(format!("identity.{field}")));
        }
        if m.shard_count != first.shard_count {
            return Err(InputError::file(
                name,
                format!(
                    "splits the grid into {} shards, {first_name} into {} (merge shards of one --shard I/N split)",
                    m.shard_count, first.shard_count
                ),
            )
            .field("shard_count"));
        }
        for &i in &m.shards {
            if let Some(&prev) = owner.get(&i) {
                let other = &inputs[prev].0;
                return Err(InputError::file(
                    name,
                    format!("shard {i}/{} is given twice (also in {other})", m.shard_count),
                )
                .field("shards"));
            }
            owner.insert(i, k);
        }
    }
    let n = first.shard_count;
    let missing = if owner.len() as u64 == n {
        Vec::new()
    } else {
        // Fewer present than N: list the gaps (bounded by the inputs, not by N, up to a cap).
        (1..=n).filter(|i| !owner.contains_key(i)).take(1000).collect()
    };
    Ok(MergePlan { shard_count: n, present: owner.into_iter().collect(), missing })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity() -> Identity {
        Identity {
            format: FORMAT,
            parapet_version: "0.1.0".into(),
            scene: "one_sphere".into(),
            scene_fnv1a64: fnv1a64(b"scene"),
            path_source: "straight".into(),
            plan_seed: None,
            path_fnv1a64: fnv1a64(b"path"),
            foreign_path: false,
            filter: "paper".into(),
            noise: true,
            duration_s: Some(12.0),
            max_duration_s: 3600.0,
            mu: GridRange::parse("0.5:1.4:2").unwrap(),
            delta1: GridRange::parse("0.06:0.3:2").unwrap(),
            speed: GridRange::parse("0.25").unwrap(),
            seeds: 1,
            params: Default::default(),
            grid_params: Vec::new(),
        }
    }

    fn shard(i: u64, n: u64) -> Manifest {
        Manifest {
            identity: identity(),
            scene_file: "scenes/one_sphere.toml".into(),
            path_file: None,
            grid_runs: 4,
            shard_count: n,
            shards: vec![i],
            rows: 1,
            failed: 0,
        }
    }

    #[test]
    fn fnv_is_the_reference_function() {
        // Published FNV-1a 64 test vectors.
        assert_eq!(fnv1a64(b""), "cbf29ce484222325");
        assert_eq!(fnv1a64(b"a"), "af63dc4c8601ec8c");
        assert_eq!(fnv1a64(b"foobar"), "85944171f73967e8");
    }

    #[test]
    fn json_round_trip() {
        let d = std::env::temp_dir().join(format!("parapet-manifest-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("sweep.json");
        let m = shard(2, 3);
        m.write(&p).unwrap();
        assert_eq!(Manifest::read(&p).unwrap(), m);
        let mut bad = m.clone();
        bad.shards = vec![4];
        bad.write(&p).unwrap();
        assert!(Manifest::read(&p).unwrap_err().to_string().contains("shards"));
        std::fs::write(&p, "{}").unwrap();
        assert!(Manifest::read(&p).unwrap_err().to_string().contains("sweep.json"));
    }

    #[test]
    fn merge_plans() {
        let named = |v: Vec<Manifest>| -> Vec<(String, Manifest)> {
            v.into_iter().enumerate().map(|(k, m)| (format!("in{k}"), m)).collect()
        };
        let p = plan_merge(&named(vec![shard(3, 3), shard(1, 3), shard(2, 3)])).unwrap();
        assert_eq!(p.present, vec![(1, 1), (2, 2), (3, 0)]);
        assert!(p.missing.is_empty());
        let p = plan_merge(&named(vec![shard(3, 4), shard(1, 4)])).unwrap();
        assert_eq!(p.missing, vec![2, 4]);
        let e = plan_merge(&named(vec![shard(1, 3), shard(1, 3)])).unwrap_err().to_string();
        assert!(e.contains("in1") && e.contains("twice") && e.contains("in0"), "{e}");
        let e = plan_merge(&named(vec![shard(1, 3), shard(2, 4)])).unwrap_err().to_string();
        assert!(e.contains("4 shards"), "{e}");
        let mut other = shard(2, 3);
        other.identity.scene = "narrow_passage".into();
        let e = plan_merge(&named(vec![shard(1, 3), other])).unwrap_err().to_string();
        assert!(e.contains("in1") && e.contains("scene") && e.contains("narrow_passage"), "{e}");
        let mut other = shard(2, 3);
        other.identity.mu = GridRange::parse("0.5:1.4:3").unwrap();
        let e = plan_merge(&named(vec![shard(1, 3), other])).unwrap_err().to_string();
        assert!(e.contains("identity.mu"), "{e}");
    }
}
