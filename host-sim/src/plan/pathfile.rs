//! Path files: the planner's output as JSON, in the scene file's frame (ENU,
//! x east, y north, z **up**, m), written by `parapet plan` and read by
//! `parapet run --path`.
//!
//! ```json
//! {"scene": "scenes/office.toml", "waypoints": [[0.5, 0.5, 1.0], [4.0, 2.0, 1.0]],
//!  "length_m": 3.8079, "planning_time_ms": 0.21, "iterations": 12, "seed": 0}
//! ```
//! * `scene` (string): the scene the path was planned for (as given to the CLI).
//! * `waypoints` (array of `[x, y, z]`, at least one, all finite, |x| ≤
//!   [`limits::MAX_COORDINATE_M`] = the core's `COORDINATE_LIMIT`): ENU, m.
//! * `length_m`, `planning_time_ms` (numbers), `iterations`, `seed` (unsigned integers).
//!
//! When reading, only `waypoints` is required (a hand-written path needs
//! nothing else); `length_m` is recomputed when absent. Unknown keys are
//! errors. Every reading error names the file and the field.
//! [`PathFile::waypoints_ned`] converts to the internal NED frame with
//! [`parapet_core::frame::enu_to_ned`].

use std::path::{Path, PathBuf};

use parapet_core::frame::{enu_to_ned, ned_to_enu};
use parapet_core::Vec3;
use serde_json::{Map, Value};
use thiserror::Error;

use crate::input::limits;
use crate::plan::{path_length, PlannedPath};

/// Contents of a path file (positions ENU, m).
#[derive(Clone, Debug, PartialEq)]
pub struct PathFile {
    /// The scene the path belongs to (free text, usually the scene file path).
    pub scene: String,
    /// Waypoints, ENU (z up), m; first = start, last = goal.
    pub waypoints: Vec<[f32; 3]>,
    /// Polyline length, m.
    pub length_m: f32,
    /// Planning time, ms (0 for a hand-written file without the field).
    pub planning_time_ms: f64,
    /// Planner iterations (0 when absent).
    pub iterations: u32,
    /// Planner seed (0 when absent).
    pub seed: u64,
}

/// A path file could not be read or written.
#[derive(Debug, Error)]
pub enum PathFileError {
    /// I/O failure.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Not JSON.
    #[error("{file}: not valid JSON: {source}")]
    Json {
        /// The file.
        file: PathBuf,
        /// The parser's error (with line and column).
        source: serde_json::Error,
    },
    /// A field is missing, of the wrong type, non-finite or unknown.
    #[error("{file}: field `{field}`: {message}")]
    Field {
        /// The file.
        file: PathBuf,
        /// The field, e.g. `waypoints[3][2]`.
        field: String,
        /// What is wrong with it.
        message: String,
    },
}

impl PathFile {
    /// Build the file contents from a planned path (waypoints NED → ENU).
    pub fn from_planned(scene: &str, path: &PlannedPath) -> Self {
        PathFile {
            scene: scene.to_string(),
            waypoints: path.waypoints.iter().map(|w| ned_to_enu(*w).into()).collect(),
            length_m: path.length_m,
            planning_time_ms: path.planning_time_ms,
            iterations: path.iterations,
            seed: path.seed,
        }
    }

    /// The waypoints in the internal world frame (NED, m).
    pub fn waypoints_ned(&self) -> Vec<Vec3> {
        self.waypoints.iter().map(|w| enu_to_ned(Vec3::new(w[0], w[1], w[2]))).collect()
    }

    /// The JSON text of the file (pretty-printed, trailing newline).
    pub fn to_json_string(&self) -> String {
        let wps: Vec<Value> = self.waypoints.iter().map(|w| Value::from(w.map(f64::from).to_vec())).collect();
        let mut m = Map::new();
        m.insert("scene".into(), Value::from(self.scene.clone()));
        m.insert("waypoints".into(), Value::Array(wps));
        m.insert("length_m".into(), Value::from(f64::from(self.length_m)));
        m.insert("planning_time_ms".into(), Value::from(self.planning_time_ms));
        m.insert("iterations".into(), Value::from(self.iterations));
        m.insert("seed".into(), Value::from(self.seed));
        let mut s = serde_json::to_string_pretty(&Value::Object(m)).unwrap_or_default();
        s.push('\n');
        s
    }

    /// Write the file (creating or replacing it).
    pub fn write(&self, file: &Path) -> Result<(), PathFileError> {
        std::fs::write(file, self.to_json_string())
            .map_err(|source| PathFileError::Io { file: file.to_path_buf(), source })
    }

    /// Read and validate a path file.
    pub fn read(file: &Path) -> Result<Self, PathFileError> {
        let cap = limits::MAX_INPUT_FILE_BYTES;
        if std::fs::metadata(file).is_ok_and(|m| m.len() > cap) {
            let message = format!("the file is too large (allowed at most {cap} bytes)");
            return Err(PathFileError::Field { file: file.to_path_buf(), field: "(file)".into(), message });
        }
        let text = std::fs::read_to_string(file)
            .map_err(|source| PathFileError::Io { file: file.to_path_buf(), source })?;
        Self::parse(&text, file)
    }

    /// Parse path-file text; `file` is only used in error messages.
    pub fn parse(text: &str, file: &Path) -> Result<Self, PathFileError> {
        let err = |field: &str, message: String| PathFileError::Field {
            file: file.to_path_buf(),
            field: field.to_string(),
            message,
        };
        serde_json::from_str::<NoDuplicateKeys>(text)
            .map_err(|source| PathFileError::Json { file: file.to_path_buf(), source })?;
        let value: Value = serde_json::from_str(text)
            .map_err(|source| PathFileError::Json { file: file.to_path_buf(), source })?;
        let obj = match value {
            Value::Object(o) => o,
            other => return Err(err("(top level)", format!("expected an object, got {}", kind(&other)))),
        };
        const KEYS: [&str; 6] = ["scene", "waypoints", "length_m", "planning_time_ms", "iterations", "seed"];
        if let Some(k) = obj.keys().find(|k| !KEYS.contains(&k.as_str())) {
            return Err(err(k, format!("unknown field (expected one of {})", KEYS.join(", "))));
        }
        let scene = match obj.get("scene") {
            None => String::new(),
            Some(Value::String(s)) => s.clone(),
            Some(v) => return Err(err("scene", format!("expected a string, got {}", kind(v)))),
        };
        let wps = match obj.get("waypoints") {
            None => return Err(err("waypoints", "missing".into())),
            Some(Value::Array(a)) => a,
            Some(v) => {
                return Err(err("waypoints", format!("expected an array of [x, y, z], got {}", kind(v))))
            }
        };
        if wps.is_empty() {
            return Err(err("waypoints", "must contain at least one waypoint".into()));
        }
        let mut waypoints = Vec::with_capacity(wps.len());
        for (i, w) in wps.iter().enumerate() {
            let field = format!("waypoints[{i}]");
            let a = match w {
                Value::Array(a) if a.len() == 3 => a,
                Value::Array(a) => return Err(err(&field, format!("expected 3 numbers, got {}", a.len()))),
                v => return Err(err(&field, format!("expected [x, y, z], got {}", kind(v)))),
            };
            let mut p = [0.0f32; 3];
            for (k, c) in a.iter().enumerate() {
                let f = format!("{field}[{k}]");
                let x = finite_f64(c).map_err(|m| err(&f, m))?;
                if x.abs() > limits::MAX_COORDINATE_M {
                    return Err(err(
                        &f,
                        format!(
                            "coordinate out of range (got {}; allowed |x| ≤ {} m)",
                            crate::input::num(x),
                            limits::MAX_COORDINATE_M
                        ),
                    ));
                }
                p[k] = x as f32;
            }
            waypoints.push(p);
        }
        let length_m = match obj.get("length_m") {
            None => {
                let ned: Vec<Vec3> = waypoints.iter().map(|w| Vec3::new(w[0], w[1], w[2])).collect();
                path_length(&ned)
            }
            Some(v) => {
                let l = finite_f64(v).map_err(|m| err("length_m", m))?;
                // Stored as f32: a larger value would become infinite (found by fuzzing).
                if l < 0.0 || l > f64::from(f32::MAX) {
                    let got = if l.abs() < 1e15 { l.to_string() } else { format!("{l:e}") };
                    return Err(err("length_m", format!("must be in 0..={:e} m, got {got}", f32::MAX)));
                }
                l as f32
            }
        };
        let planning_time_ms = match obj.get("planning_time_ms") {
            None => 0.0,
            Some(v) => finite_f64(v).map_err(|m| err("planning_time_ms", m))?,
        };
        let iterations = match obj.get("iterations") {
            None => 0,
            Some(v) => v
                .as_u64()
                .and_then(|n| u32::try_from(n).ok())
                .ok_or_else(|| err("iterations", format!("expected an unsigned 32-bit integer, got {v}")))?,
        };
        let seed = match obj.get("seed") {
            None => 0,
            Some(v) => {
                v.as_u64().ok_or_else(|| err("seed", format!("expected an unsigned integer, got {v}")))?
            }
        };
        Ok(PathFile { scene, waypoints, length_m, planning_time_ms, iterations, seed })
    }
}

/// Any JSON value, refusing an object that gives a key twice: serde_json's
/// `Value` keeps the last `"waypoints"` silently.
struct NoDuplicateKeys;

impl<'de> serde::Deserialize<'de> for NoDuplicateKeys {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(NoDuplicateKeys)
    }
}

impl<'de> serde::de::Visitor<'de> for NoDuplicateKeys {
    type Value = NoDuplicateKeys;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, _: bool) -> Result<Self, E> {
        Ok(self)
    }
    fn visit_i64<E>(self, _: i64) -> Result<Self, E> {
        Ok(self)
    }
    fn visit_u64<E>(self, _: u64) -> Result<Self, E> {
        Ok(self)
    }
    fn visit_f64<E>(self, _: f64) -> Result<Self, E> {
        Ok(self)
    }
    fn visit_str<E>(self, _: &str) -> Result<Self, E> {
        Ok(self)
    }
    fn visit_unit<E>(self) -> Result<Self, E> {
        Ok(self)
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut a: A) -> Result<Self, A::Error> {
        while a.next_element::<NoDuplicateKeys>()?.is_some() {}
        Ok(self)
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut a: A) -> Result<Self, A::Error> {
        let mut seen = std::collections::HashSet::new();
        while let Some(k) = a.next_key::<String>()? {
            if !seen.insert(k.clone()) {
                return Err(serde::de::Error::custom(format!("field `{k}` is given twice")));
            }
            a.next_value::<NoDuplicateKeys>()?;
        }
        Ok(self)
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

fn finite_f64(v: &Value) -> Result<f64, String> {
    match v.as_f64() {
        Some(x) if x.is_finite() => Ok(x),
        _ => Err(format!("expected a finite number, got {}", kind(v))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> PlannedPath {
        PlannedPath {
            waypoints: vec![Vec3::new(1.0, 2.0, -1.5), Vec3::new(4.0, 6.0, -1.0)],
            length_m: 5.0249,
            planning_time_ms: 0.25,
            iterations: 17,
            seed: 42,
            method: crate::plan::PlanMethod::RrtConnect,
        }
    }

    #[test]
    fn round_trip_converts_frames() {
        let pf = PathFile::from_planned("scenes/office.toml", &sample());
        // NED (1, 2, -1.5) is ENU (2, 1, 1.5): east 2, north 1, 1.5 m up.
        assert_eq!(pf.waypoints[0], [2.0, 1.0, 1.5]);
        let back = PathFile::parse(&pf.to_json_string(), Path::new("x.json")).unwrap();
        assert_eq!(back, pf);
        assert_eq!(back.waypoints_ned(), sample().waypoints);
    }

    #[test]
    fn write_then_read_file() {
        let dir = std::env::temp_dir().join(format!("parapet-pathfile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("p.json");
        let pf = PathFile::from_planned("s", &sample());
        pf.write(&f).unwrap();
        assert_eq!(PathFile::read(&f).unwrap(), pf);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn minimal_file_and_recomputed_length() {
        let pf = PathFile::parse(r#"{"waypoints": [[0,0,1],[3,4,1]]}"#, Path::new("m.json")).unwrap();
        assert!((pf.length_m - 5.0).abs() < 1e-6);
        assert_eq!(pf.scene, "");
    }

    #[test]
    fn errors_name_file_and_field() {
        let f = Path::new("bad.json");
        let msg = |t: &str| PathFile::parse(t, f).unwrap_err().to_string();
        let m = msg(r#"{"waypoints": [[0,0,1],[3,"x",1]]}"#);
        assert!(m.contains("bad.json") && m.contains("waypoints[1][1]"), "{m}");
        let m = msg(r#"{"waypoints": [[0,0]]}"#);
        assert!(m.contains("waypoints[0]") && m.contains("3 numbers"), "{m}");
        let m = msg(r#"{"scene": "a"}"#);
        assert!(m.contains("`waypoints`") && m.contains("missing"), "{m}");
        let m = msg(r#"{"waypoints": [[0,0,1]], "speed": 2}"#);
        assert!(m.contains("`speed`") && m.contains("unknown"), "{m}");
        let m = msg(r#"{"waypoints": [[0,0,1]], "seed": -1}"#);
        assert!(m.contains("`seed`"), "{m}");
        let m = msg(r#"{"waypoints": [[0,0,1]], "length_m": -1}"#);
        assert!(m.contains("`length_m`"), "{m}");
        // Fuzz regression (tests/fuzz/regressions/path_json/length_overflows_f32): 1.4e59 was
        // accepted as an infinite length.
        let m = msg(r#"{"waypoints": [[0,0,1]], "length_m": 14.298372268676e58}"#);
        assert!(m.contains("`length_m`") && m.contains("1.4298372268676e59"), "{m}");
        let m = msg(r#"{"waypoints": [[0,0,1e39]]}"#);
        assert!(m.contains("waypoints[0][2]"), "{m}");
        let m = msg(r#"{"waypoints": [[0,0,1],[2e5,0,1]]}"#);
        assert!(m.contains("waypoints[1][0]") && m.contains("200000") && m.contains("100000"), "{m}");
        let m = msg("[1, 2]");
        assert!(m.contains("bad.json") && m.contains("object"), "{m}");
        let m = msg("{");
        assert!(m.contains("bad.json") && m.contains("JSON"), "{m}");
        let m = msg(r#"{"waypoints": [[0,0,1]], "waypoints": [[5,5,1]]}"#);
        assert!(m.contains("bad.json") && m.contains("`waypoints` is given twice"), "{m}");
        let m = msg(r#"{"waypoints": [[0,0,1]], "scene": "a", "scene": "b"}"#);
        assert!(m.contains("`scene` is given twice"), "{m}");
        let m = PathFile::read(Path::new("/nonexistent/p.json")).unwrap_err().to_string();
        assert!(m.contains("/nonexistent/p.json"), "{m}");
    }
}
