//! `sweep.csv`: one [`SweepRecord`] per run, written and read with the `csv`
//! crate through serde (one type for both directions, strings quoted as CSV
//! requires, numbers in their shortest round-trip form so a merged CSV equals
//! the unsharded one byte for byte).
//!
//! Columns ([`COLUMNS`], in this order): the grid index; the run's parameters
//! (scene, filter, μ s, δ m², δ1 m², k_p, k_d, speed m/s, seed, noise); `status`
//! (`ok` or `failed`); the run summary's fields (see `report::Summary`; empty on
//! a failed row); `error` (why a failed row failed; empty on `ok`). The
//! wall-clock time is left out on purpose (it is not deterministic). Then one column per
//! `--grid` axis, named by its parameter, holding the value the run's controller flew (read
//! back from its parameter set, as the shortest decimal of the `f32`).
//!
//! Reading ([`CsvRows`]) checks the header and every row and names the file, the
//! line, the column and the value of anything it cannot use.
//!
//! May import: `crate::input` (errors), `csv`, `serde`.

use std::fs::File;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::input::InputError;

/// Outcome of one run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Flown; the summary columns are filled.
    Ok,
    /// Not flown or aborted; `error` says why, the summary columns are empty.
    Failed,
}

/// One row of `sweep.csv`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepRecord {
    /// Grid index.
    pub index: u64,
    /// Scene name.
    pub scene: String,
    /// Filter variant.
    pub filter: String,
    /// μ, s.
    pub mu: f64,
    /// δ, m².
    pub delta: f64,
    /// δ1, m².
    pub delta1: f64,
    /// k_p, 1/s².
    pub kp: f64,
    /// k_d, 1/s.
    pub kd: f64,
    /// Reference speed, m/s.
    pub speed: f64,
    /// Sensor-noise seed.
    pub seed: u64,
    /// Sensor noise on.
    pub noise: bool,
    /// `ok` or `failed`.
    pub status: Status,
    /// Collided (empty when failed).
    pub collided: Option<bool>,
    /// Time of the first collision, s.
    pub first_collision_time_s: Option<f64>,
    /// What was hit first.
    pub collision_with: Option<String>,
    /// Minimum clearance, m.
    pub min_clearance_m: Option<f64>,
    /// Minimum h̄ on the true state, m².
    pub min_h_bar: Option<f64>,
    /// Minimum of the controller's own h̄, m².
    pub min_filter_h_bar: Option<f64>,
    /// Goal reached.
    pub reached_goal: Option<bool>,
    /// Time to the goal, s.
    pub time_to_goal_s: Option<f64>,
    /// Final distance to the goal, m.
    pub final_distance_to_goal_m: Option<f64>,
    /// The path's last waypoint reached (differs from `reached_goal` only for a foreign path).
    pub reached_path_end: Option<bool>,
    /// Final distance to the path's last waypoint, m.
    pub final_distance_to_path_end_m: Option<f64>,
    /// Tracking RMS, m.
    pub tracking_rms_m: Option<f64>,
    /// Share of outer steps with the filter active.
    pub filter_active_fraction: Option<f64>,
    /// Why the run ended.
    pub end_reason: Option<String>,
    /// Simulated time, s.
    pub sim_time_s: Option<f64>,
    /// Why the run failed (failed rows only).
    pub error: Option<String>,
    /// The values of the `--grid` axes as flown (the columns after [`COLUMNS`]).
    #[serde(skip)]
    pub params: Vec<f64>,
}

/// Column names of `sweep.csv`, in order (the field names of [`SweepRecord`]).
pub const COLUMNS: [&str; 28] = [
    "index",
    "scene",
    "filter",
    "mu",
    "delta",
    "delta1",
    "kp",
    "kd",
    "speed",
    "seed",
    "noise",
    "status",
    "collided",
    "first_collision_time_s",
    "collision_with",
    "min_clearance_m",
    "min_h_bar",
    "min_filter_h_bar",
    "reached_goal",
    "time_to_goal_s",
    "final_distance_to_goal_m",
    "reached_path_end",
    "final_distance_to_path_end_m",
    "tracking_rms_m",
    "filter_active_fraction",
    "end_reason",
    "sim_time_s",
    "error",
];

/// What the heatmaps need of a flown row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// Collided.
    pub collided: bool,
    /// Minimum clearance, m.
    pub min_clearance_m: f64,
    /// Tracking RMS, m.
    pub tracking_rms_m: f64,
}

impl SweepRecord {
    /// The outcome of a flown row; `None` for a failed one.
    pub fn outcome(&self) -> Option<Outcome> {
        if self.status != Status::Ok {
            return None;
        }
        Some(Outcome {
            collided: self.collided?,
            min_clearance_m: self.min_clearance_m?,
            tracking_rms_m: self.tracking_rms_m?,
        })
    }

    /// Whether the row is consistent: an `ok` row has its summary (and no error),
    /// a `failed` row an error (and no summary). `Err` names the column.
    pub fn check(&self) -> Result<(), (&'static str, &'static str)> {
        match self.status {
            Status::Ok => {
                let missing = [
                    ("collided", self.collided.is_none()),
                    ("min_clearance_m", self.min_clearance_m.is_none()),
                    ("min_h_bar", self.min_h_bar.is_none()),
                    ("reached_goal", self.reached_goal.is_none()),
                    ("final_distance_to_goal_m", self.final_distance_to_goal_m.is_none()),
                    ("reached_path_end", self.reached_path_end.is_none()),
                    ("final_distance_to_path_end_m", self.final_distance_to_path_end_m.is_none()),
                    ("tracking_rms_m", self.tracking_rms_m.is_none()),
                    ("filter_active_fraction", self.filter_active_fraction.is_none()),
                    ("end_reason", self.end_reason.is_none()),
                    ("sim_time_s", self.sim_time_s.is_none()),
                ];
                if let Some((c, _)) = missing.iter().find(|(_, m)| *m) {
                    return Err((c, "empty on a row with status ok"));
                }
                if self.error.is_some() {
                    return Err(("error", "must be empty on a row with status ok"));
                }
            }
            Status::Failed => {
                if self.error.as_deref().is_none_or(str::is_empty) {
                    return Err(("error", "empty on a row with status failed"));
                }
                if self.collided.is_some() || self.min_clearance_m.is_some() || self.tracking_rms_m.is_some()
                {
                    return Err(("collided", "a failed row has no results"));
                }
            }
        }
        Ok(())
    }
}

/// Streams records into a `sweep.csv`.
pub struct CsvSink {
    w: csv::Writer<File>,
}

/// The header of a `sweep.csv` with the `--grid` axes `names`.
pub fn header(names: &[String]) -> Vec<String> {
    COLUMNS.iter().map(|c| c.to_string()).chain(names.iter().cloned()).collect()
}

impl CsvSink {
    /// Create (truncate) `path` and write the header (`names`: the `--grid` axes).
    pub fn create(path: &Path, names: &[String]) -> std::io::Result<CsvSink> {
        let file = File::create(path)?;
        let mut w = csv::WriterBuilder::new().has_headers(false).from_writer(file);
        w.write_record(header(names)).map_err(std::io::Error::other)?;
        Ok(CsvSink { w })
    }

    /// Append one record.
    pub fn push(&mut self, r: &SweepRecord) -> std::io::Result<()> {
        self.w.serialize((r, &r.params)).map_err(std::io::Error::other)
    }

    /// Flush and close.
    pub fn finish(mut self) -> std::io::Result<()> {
        self.w.flush()?;
        let file = self.w.into_inner().map_err(|e| std::io::Error::other(e.to_string()))?;
        file.sync_all()
    }
}

/// Reads the records of one `sweep.csv`, checking the header first.
pub struct CsvRows {
    file: String,
    r: csv::Reader<File>,
    headers: csv::StringRecord,
    raw: csv::StringRecord,
}

impl CsvRows {
    /// Open `path` and check its header (`file` names it in errors; `names`: the `--grid` axes).
    pub fn open(path: &Path, names: &[String]) -> Result<CsvRows, InputError> {
        let file = path.display().to_string();
        let f =
            File::open(path).map_err(|e| InputError::file(&file, format!("cannot read the file: {e}")))?;
        let mut r = csv::ReaderBuilder::new().has_headers(true).from_reader(f);
        let headers = r
            .headers()
            .map_err(|e| InputError::file(format!("{file}: line 1"), format!("not a sweep CSV: {e}")))?
            .clone();
        let want = header(names);
        if headers.iter().ne(want.iter().map(String::as_str)) {
            return Err(InputError::file(
                format!("{file}: line 1"),
                "not a sweep CSV of this parapet version and grid: the header differs",
            )
            .value(format!("{:?}", headers.iter().collect::<Vec<_>>().join(",")))
            .allowed(format!("{:?}", want.join(","))));
        }
        Ok(CsvRows { file, r, headers, raw: csv::StringRecord::new() })
    }

    /// The file as named in errors.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The next record, `Ok(None)` at the end of the file.
    pub fn next_record(&mut self) -> Result<Option<(u64, SweepRecord)>, InputError> {
        let more = self.r.read_record(&mut self.raw).map_err(|e| {
            let line = e.position().map(|p| p.line()).unwrap_or(0);
            InputError::file(format!("{}: line {line}", self.file), format!("malformed CSV: {e}"))
        })?;
        if !more {
            return Ok(None);
        }
        let line = self.raw.position().map(|p| p.line()).unwrap_or(0);
        let at = format!("{}: line {line}", self.file);
        let mut rec: SweepRecord = self.raw.deserialize(Some(&self.headers)).map_err(|e| {
            let (col, reason) = match e.kind() {
                csv::ErrorKind::Deserialize { err, .. } => {
                    (err.field().map(|i| i as usize), err.kind().to_string())
                }
                other => (None, format!("{other:?}")),
            };
            match col {
                Some(c) => InputError::file(&at, format!("column {}: {reason}", c + 1))
                    .field(COLUMNS.get(c).copied().unwrap_or("?"))
                    .value(format!("{:?}", self.raw.get(c).unwrap_or(""))),
                None => InputError::file(&at, format!("cannot read the row: {reason}")),
            }
        })?;
        for c in COLUMNS.len()..self.headers.len() {
            let text = self.raw.get(c).unwrap_or("");
            let x = text.parse::<f64>().map_err(|e| {
                InputError::file(&at, format!("column {}: {e}", c + 1))
                    .field(self.headers.get(c).unwrap_or("?"))
                    .value(format!("{text:?}"))
            })?;
            rec.params.push(x);
        }
        rec.check().map_err(|(col, reason)| {
            let c = COLUMNS.iter().position(|x| *x == col).unwrap_or(0);
            InputError::file(&at, format!("column {}: {reason}", c + 1))
                .field(col)
                .value(format!("{:?}", self.raw.get(c).unwrap_or("")))
        })?;
        Ok(Some((line, rec)))
    }
}

/// Write `records` as a complete `sweep.csv` text (tests and small tools).
pub fn to_string(records: &[SweepRecord]) -> String {
    let mut w = csv::WriterBuilder::new().has_headers(false).from_writer(Vec::new());
    let mut ok = w.write_record(COLUMNS).is_ok();
    for r in records {
        ok &= w.serialize(r).is_ok();
    }
    let bytes = w.into_inner().unwrap_or_default();
    debug_assert!(ok);
    String::from_utf8(bytes).unwrap_or_default()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A flown row (for the tests of this and the other sweep modules).
    pub(crate) fn ok_row(index: u64, collided: bool, clearance: f64) -> SweepRecord {
        SweepRecord {
            index,
            scene: "a \"quoted\", scene\nname".into(),
            filter: "paper".into(),
            mu: 0.5,
            delta: 0.05,
            delta1: 0.1,
            kp: 0.5,
            kd: 0.8,
            speed: 0.25,
            seed: index,
            noise: true,
            status: Status::Ok,
            collided: Some(collided),
            first_collision_time_s: collided.then_some(1.25),
            collision_with: collided.then(|| "obstacles[0] (pillar, left)".into()),
            min_clearance_m: Some(clearance),
            min_h_bar: Some(-0.001),
            min_filter_h_bar: None,
            reached_goal: Some(!collided),
            time_to_goal_s: (!collided).then_some(12.5),
            final_distance_to_goal_m: Some(0.1),
            reached_path_end: Some(!collided),
            final_distance_to_path_end_m: Some(0.1),
            tracking_rms_m: Some(0.2),
            filter_active_fraction: Some(0.01),
            end_reason: Some(if collided { "collision" } else { "goal" }.into()),
            sim_time_s: Some(12.5),
            error: None,
            params: Vec::new(),
        }
    }

    fn dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("parapet-record-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn write_all(path: &Path, text: &str) -> std::io::Result<()> {
        std::fs::write(path, text)
    }

    fn read_all(path: &Path) -> Result<Vec<SweepRecord>, InputError> {
        let mut r = CsvRows::open(path, &[])?;
        let mut v = Vec::new();
        while let Some((_, rec)) = r.next_record()? {
            v.push(rec);
        }
        Ok(v)
    }

    #[test]
    fn columns_are_the_record_fields() {
        // The serde header of a record equals COLUMNS (one source of truth for both).
        let mut w = csv::Writer::from_writer(Vec::new());
        w.serialize(ok_row(0, false, 0.1)).unwrap();
        let text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        assert_eq!(text.lines().next().unwrap(), COLUMNS.join(","));
    }

    #[test]
    fn round_trip_with_quoting_and_failed_rows() {
        let d = dir("round");
        let mut failed = ok_row(2, false, 0.0);
        failed.status = Status::Failed;
        for x in [&mut failed.min_clearance_m, &mut failed.min_h_bar, &mut failed.tracking_rms_m] {
            *x = None;
        }
        (failed.collided, failed.reached_goal, failed.end_reason) = (None, None, None);
        (failed.reached_path_end, failed.final_distance_to_path_end_m) = (None, None);
        (failed.final_distance_to_goal_m, failed.filter_active_fraction, failed.sim_time_s) =
            (None, None, None);
        failed.error = Some("run 2: waypoint follower: speed 200 m/s, allowed ≤ 100, \"quoted\"".into());
        let rows = vec![ok_row(0, false, 0.125), ok_row(1, true, -0.01), failed.clone()];
        let p = d.join("sweep.csv");
        let mut sink = CsvSink::create(&p, &[]).unwrap();
        for r in &rows {
            sink.push(r).unwrap();
        }
        sink.finish().unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(text, to_string(&rows));
        // The comma, quote and newline in the scene name are quoted, not replaced.
        assert!(text.contains("\"a \"\"quoted\"\", scene\nname\""), "{text}");
        assert_eq!(read_all(&p).unwrap(), rows);
        assert_eq!(rows[2].outcome(), None);
        assert_eq!(
            rows[1].outcome(),
            Some(Outcome { collided: true, min_clearance_m: -0.01, tracking_rms_m: 0.2 })
        );
    }

    #[test]
    fn bad_csvs_name_file_line_column_and_value() {
        let d = dir("bad");
        let p = d.join("s.csv");
        let file = p.display().to_string();
        write_all(&p, "not,a,sweep\n").unwrap();
        let e = read_all(&p).unwrap_err().to_string();
        assert!(e.contains(&format!("{file}: line 1")) && e.contains("header"), "{e}");
        // The first row's scene name spans two lines: the second row starts on line 4.
        let good = to_string(&[ok_row(0, false, 0.1), ok_row(1, false, 0.375)]);
        let bad = good.replacen(",0.375,", ",zero.two,", 1);
        assert_ne!(bad, good);
        write_all(&p, &bad).unwrap();
        let e = read_all(&p).unwrap_err().to_string();
        assert!(e.contains(&format!("{file}: line 4")), "{e}");
        assert!(e.contains("min_clearance_m") && e.contains("zero.two") && e.contains("column 16"), "{e}");
        // An ok row without its results (one line per row here).
        let plain: Vec<SweepRecord> =
            (0..2).map(|i| SweepRecord { scene: "plain".into(), ..ok_row(i, false, 0.1) }).collect();
        let good = to_string(&plain);
        let lines: Vec<&str> = good.lines().collect();
        let cut = lines[2].replacen(",goal,", ",,", 1);
        write_all(&p, &format!("{}\n{}\n{cut}\n", lines[0], lines[1])).unwrap();
        let e = read_all(&p).unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("end_reason"), "{e}");
        // Too few columns.
        write_all(&p, &format!("{}\n1,2\n", lines[0])).unwrap();
        let e = read_all(&p).unwrap_err().to_string();
        assert!(e.contains("line 2"), "{e}");
        let e = read_all(&d.join("missing.csv")).unwrap_err().to_string();
        assert!(e.contains("missing.csv") && e.contains("cannot read"), "{e}");
    }

    #[test]
    fn grid_columns_follow_the_record_and_are_read_back() {
        let d = dir("grid");
        let p = d.join("sweep.csv");
        let names = vec!["TRJ_ACC".to_string()];
        let rows = vec![
            SweepRecord { params: vec![0.5], ..ok_row(0, false, 0.1) },
            SweepRecord { params: vec![2.0], ..ok_row(1, false, 0.2) },
        ];
        let mut sink = CsvSink::create(&p, &names).unwrap();
        for r in &rows {
            sink.push(r).unwrap();
        }
        sink.finish().unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.lines().next().unwrap().ends_with(",error,TRJ_ACC"), "{text}");
        let mut r = CsvRows::open(&p, &names).unwrap();
        let mut back = Vec::new();
        while let Some((_, rec)) = r.next_record().unwrap() {
            back.push(rec);
        }
        assert_eq!(back, rows);
        let e = CsvRows::open(&p, &[]).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("header"), "{e}");
        write_all(&p, &text.replacen(",0.5\n", ",x\n", 1)).unwrap();
        let mut r = CsvRows::open(&p, &names).unwrap();
        let e = r.next_record().unwrap_err().to_string();
        assert!(e.contains("TRJ_ACC") && e.contains("\"x\""), "{e}");
    }
}
