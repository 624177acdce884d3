//! The campaign's outputs: `campaign.csv` (one row per flight), `summary.json`
//! (rates with Clopper–Pearson bounds, quantiles, per-scene rows, where the
//! collisions are, the worst flights), plots, and the worst flights' reproduction
//! files. Everything written here depends only on the rows (never on wall time or
//! the order flights finished), so a merged campaign's files are byte-identical to
//! a single-process run's.
//!
//! May import: `super::spec`, plotters, serde, csv, anyhow.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use plotters::prelude::*;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The outcome of one flight.
/// Its `campaign.csv` columns are the fields in order ([`OUTCOME_COLUMNS`]); numbers are
/// written in Rust's shortest round-trip form.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// The hull touched an obstacle or the ground.
    pub collided: bool,
    /// What it touched (`obstacles[i] (name)` or `ground`), empty without collision.
    pub collision_with: String,
    /// The scene's goal was reached.
    pub reached_goal: bool,
    /// `goal`, `path_end`, `duration`, `collision`, or `error`.
    pub end_reason: String,
    /// Minimum clearance, m.
    #[serde(with = "shortest")]
    pub min_clearance_m: f64,
    /// Minimum true h̄, m².
    #[serde(with = "shortest")]
    pub min_h_bar: f64,
    /// Tracking RMS, m.
    #[serde(with = "shortest")]
    pub tracking_rms_m: f64,
    /// Outer steps in which the filter changed u*.
    pub filter_active_steps: u64,
    /// Outer steps with the unavoidable flag.
    pub unavoidable_steps: u64,
    /// Outer steps with the infeasible flag.
    pub infeasible_steps: u64,
    /// Outer steps with the deadlock flag (issue 17).
    pub deadlock_steps: u64,
    /// Outer steps in which the controller's obstacle set dropped points at capacity.
    pub obstacles_dropped_steps: u64,
    /// Outer steps flown.
    pub outer_steps: u64,
    /// Simulated time, s.
    #[serde(with = "shortest")]
    pub sim_time_s: f64,
    /// Time to the goal, s.
    #[serde(with = "shortest_opt")]
    pub time_to_goal_s: Option<f64>,
    /// Why the flight could not be flown (`end_reason` = `error`), else empty.
    pub error: String,
}

/// One row of `campaign.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Flight index.
    pub flight: u64,
    /// Scene name.
    pub scene: String,
    /// Noise / planner seed.
    pub seed: u64,
    /// The position source flown (`[draw] position_source`, else the scene's; empty when the
    /// flight's options could not be read).
    pub position_source: String,
    /// The perception flown (`truth` or a `--perception` value; empty when the flight's options
    /// could not be read).
    pub perception: String,
    /// Drawn values in the campaign's quantity order, then the values flown of the parameters
    /// set on the command line (`Campaign::set_columns`).
    pub values: Vec<f64>,
    /// Outcome.
    pub outcome: Outcome,
}

/// The outcome columns of `campaign.csv` (the fields of [`Outcome`], in order).
pub const OUTCOME_COLUMNS: [&str; 16] = [
    "collided",
    "collision_with",
    "reached_goal",
    "end_reason",
    "min_clearance_m",
    "min_h_bar",
    "tracking_rms_m",
    "filter_active_steps",
    "unavoidable_steps",
    "infeasible_steps",
    "deadlock_steps",
    "obstacles_dropped_steps",
    "outer_steps",
    "sim_time_s",
    "time_to_goal_s",
    "error",
];

/// The header of `campaign.csv` for the drawn quantities `names`.
pub fn header(names: &[String]) -> Vec<String> {
    let mut h = vec![
        "flight".to_string(),
        "scene".into(),
        "seed".into(),
        "position_source".into(),
        "perception".into(),
    ];
    h.extend(names.iter().cloned());
    h.extend(OUTCOME_COLUMNS.iter().map(|s| s.to_string()));
    h
}

/// An `f64` in Rust's shortest round-trip form (`Display`), as `campaign.csv` writes numbers.
struct Shortest(f64);

impl Serialize for Shortest {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(&self.0)
    }
}

mod shortest {
    use super::{Deserialize, Deserializer, Serialize, Serializer, Shortest};

    pub fn serialize<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
        Shortest(*x).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        f64::deserialize(d)
    }
}

mod shortest_opt {
    use super::{Deserialize, Deserializer, Serialize, Serializer, Shortest};

    pub fn serialize<S: Serializer>(x: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        x.map(Shortest).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        Option::<f64>::deserialize(d)
    }
}

impl Row {
    /// The CSV record: flight, scene, seed, position source, perception, the drawn values,
    /// then the [`Outcome`] fields.
    fn record(&self) -> (u64, &str, u64, &str, &str, Vec<Shortest>, &Outcome) {
        (
            self.flight,
            &self.scene,
            self.seed,
            &self.position_source,
            &self.perception,
            self.values.iter().map(|v| Shortest(*v)).collect(),
            &self.outcome,
        )
    }

    /// Parse a record written by [`write_csv`] with `n` drawn values.
    pub fn parse(rec: &csv::StringRecord, n: usize) -> Result<Row> {
        const FIXED: usize = 5;
        if rec.len() != FIXED + n + OUTCOME_COLUMNS.len() {
            return Err(anyhow!("expected {} columns, got {}", FIXED + n + OUTCOME_COLUMNS.len(), rec.len()));
        }
        let f = |i: usize| rec.get(i).unwrap_or("");
        let num = |i: usize| f(i).parse::<f64>().map_err(|e| anyhow!("column {}: `{}`: {e}", i + 1, f(i)));
        let int = |i: usize| f(i).parse::<u64>().map_err(|e| anyhow!("column {}: `{}`: {e}", i + 1, f(i)));
        let values = (0..n).map(|k| num(FIXED + k)).collect::<Result<Vec<_>>>()?;
        let tail: csv::StringRecord = rec.iter().skip(FIXED + n).collect();
        let header: csv::StringRecord = OUTCOME_COLUMNS.iter().collect();
        let outcome: Outcome =
            tail.deserialize(Some(&header)).map_err(|e| anyhow!("outcome columns: {e}"))?;
        Ok(Row {
            flight: int(0)?,
            scene: f(1).to_string(),
            seed: int(2)?,
            position_source: f(3).to_string(),
            perception: f(4).to_string(),
            values,
            outcome,
        })
    }

    fn flown(&self) -> bool {
        self.outcome.end_reason != "error"
    }
}

/// Write `rows` (sorted by flight) as `campaign.csv` at `path`.
pub fn write_csv(path: &Path, names: &[String], rows: &[Row]) -> Result<()> {
    // The header names the drawn quantities, so it is written as a record; the rows are
    // serde records (tuple of the fixed columns, the values and the Outcome struct).
    let mut w = csv::WriterBuilder::new()
        .has_headers(false)
        .from_path(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    w.write_record(header(names))?;
    for r in rows {
        w.serialize(r.record())?;
    }
    w.flush().with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// Read a `campaign.csv` written for the quantities `names`.
pub fn read_csv(path: &Path, names: &[String]) -> Result<Vec<Row>> {
    let mut r = csv::Reader::from_path(path).with_context(|| format!("cannot read {}", path.display()))?;
    let h: Vec<String> = r.headers()?.iter().map(str::to_string).collect();
    if h != header(names) {
        return Err(anyhow!("{}: the columns are not this campaign's", path.display()));
    }
    let mut rows = Vec::new();
    for (i, rec) in r.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: row {}", path.display(), i + 2))?;
        rows.push(
            Row::parse(&rec, names.len()).with_context(|| format!("{}: row {}", path.display(), i + 2))?,
        );
    }
    Ok(rows)
}

/// Upper end of the two-sided 95 % Clopper–Pearson interval of `k` events in `n`
/// trials: the p with P(X ≤ k | n, p) = 0.025 (1 when k = n, 0 when n = 0).
pub fn clopper_pearson_upper(k: u64, n: u64) -> f64 {
    if n == 0 || k >= n {
        return if n == 0 { 0.0 } else { 1.0 };
    }
    let cdf = |p: f64| -> f64 {
        // log of each binomial term, then log-sum-exp.
        let (lp, lq) = (p.ln(), (1.0 - p).ln());
        let mut lt = n as f64 * lq;
        let mut terms = Vec::with_capacity(k as usize + 1);
        terms.push(lt);
        for j in 0..k {
            lt += ((n - j) as f64 / (j + 1) as f64).ln() + lp - lq;
            terms.push(lt);
        }
        let m = terms.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        m.exp() * terms.iter().map(|t| (t - m).exp()).sum::<f64>()
    };
    let (mut lo, mut hi) = (k as f64 / n as f64, 1.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) > 0.025 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// Nearest-rank quantile `q` ∈ [0, 1] of sorted `v`.
fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let k = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[k - 1]
}

/// Rates of a group of flights.
#[derive(Clone, Debug, Serialize)]
pub struct Rates {
    /// Flights in the group.
    pub flights: u64,
    /// Flights that could not be flown.
    pub failed: u64,
    /// Flights that collided.
    pub collisions: u64,
    /// Collided flights whose filter never raised `unavoidable` before the contact
    /// (the flight ends at the contact): the collisions the filter did not foresee.
    pub collisions_unflagged: u64,
    /// Share of flown flights in which the controller reported a deadlock.
    pub deadlock_rate: f64,
    /// collisions / flown.
    pub collision_rate: f64,
    /// 95 % Clopper–Pearson upper bound of the collision rate.
    pub collision_rate_upper_95: f64,
    /// Share of flown flights that reached the scene's goal.
    pub goal_rate: f64,
    /// Share of flown flights that ended at the duration limit.
    pub timeout_rate: f64,
    /// Min-clearance quantiles of the flown flights, m: p0 (min), p1, p5, p50.
    pub min_clearance_m: BTreeMap<String, f64>,
    /// Mean tracking RMS, m.
    pub mean_tracking_rms_m: f64,
}

fn rates(rows: &[&Row]) -> Rates {
    let flown: Vec<&&Row> = rows.iter().filter(|r| r.flown()).collect();
    let n = flown.len() as u64;
    let k = flown.iter().filter(|r| r.outcome.collided).count() as u64;
    let share = |f: &dyn Fn(&Row) -> bool| {
        if n == 0 {
            0.0
        } else {
            flown.iter().filter(|r| f(r)).count() as f64 / n as f64
        }
    };
    let mut clear: Vec<f64> = flown.iter().map(|r| r.outcome.min_clearance_m).collect();
    clear.sort_by(f64::total_cmp);
    let q = [("p0", 0.0), ("p1", 0.01), ("p5", 0.05), ("p50", 0.5)];
    Rates {
        flights: rows.len() as u64,
        failed: rows.len() as u64 - n,
        collisions: k,
        collisions_unflagged: flown
            .iter()
            .filter(|r| r.outcome.collided && r.outcome.unavoidable_steps == 0)
            .count() as u64,
        deadlock_rate: share(&|r| r.outcome.deadlock_steps > 0),
        collision_rate: if n == 0 { 0.0 } else { k as f64 / n as f64 },
        collision_rate_upper_95: clopper_pearson_upper(k, n),
        goal_rate: share(&|r| r.outcome.reached_goal),
        timeout_rate: share(&|r| r.outcome.end_reason == "duration"),
        min_clearance_m: q.iter().map(|(s, p)| (s.to_string(), quantile(&clear, *p))).collect(),
        mean_tracking_rms_m: if n == 0 {
            0.0
        } else {
            flown.iter().map(|r| r.outcome.tracking_rms_m).sum::<f64>() / n as f64
        },
    }
}

/// One of the worst flights.
#[derive(Clone, Debug, Serialize)]
pub struct Worst {
    /// Flight index.
    pub flight: u64,
    /// Scene.
    pub scene: String,
    /// Outcome summary.
    pub end_reason: String,
    /// Min clearance, m.
    pub min_clearance_m: f64,
    /// What it hit.
    pub collision_with: String,
    /// Its disturbance file, relative to the campaign's output directory.
    pub disturbances_file: String,
    /// The `parapet run` options that fly it (plus `--disturbances <out>/<file>`).
    pub run_args: Vec<String>,
    /// Its full `parapet run` report (`replay.html`, `summary.json`, `trajectory.csv`, …),
    /// relative to the campaign's output directory: the first [`WORST_REPORTS`] worst flights
    /// only (null for the others).
    pub report: Option<String>,
}

/// How many of the worst flights (the first of [`Summary::worst`]: smallest min clearance,
/// collisions first) are flown again after the campaign to write their full report with its
/// replay page, `worst/flight_NNNNNN/` ([`worst_report_dir`]).
pub const WORST_REPORTS: usize = 3;

/// The report directory of a worst flight, relative to the output directory: the `--out` of
/// its command in `worst.txt`.
pub fn worst_report_dir(flight: u64) -> String {
    format!("worst/flight_{flight:06}")
}

/// `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Campaign name.
    pub campaign: String,
    /// Campaign identity.
    pub identity: String,
    /// Campaign seed.
    pub seed: u64,
    /// The drawn quantities and their distributions.
    pub distributions: BTreeMap<String, String>,
    /// The parameters set for every flight on the command line (`--param`, `--params`; their
    /// `campaign.csv` columns hold the value each flight's controller flew).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub params_set: BTreeMap<String, f64>,
    /// Every flight.
    pub all: Rates,
    /// Per scene.
    pub per_scene: BTreeMap<String, Rates>,
    /// Per position source (`campaign.csv`'s `position_source`).
    pub per_source: BTreeMap<String, Rates>,
    /// Per perception (`campaign.csv`'s `perception`).
    pub per_perception: BTreeMap<String, Rates>,
    /// Collisions by scene and obstacle: `scene: { what: count }`.
    pub collisions_by_obstacle: BTreeMap<String, BTreeMap<String, u64>>,
    /// The 10 flights with the smallest min clearance (collisions first); the first
    /// [`WORST_REPORTS`] with their full report.
    pub worst: Vec<Worst>,
}

/// The summary of `rows`; `worst_args(flight)` gives a flight's run options.
pub fn summarise(
    c: &super::spec::Campaign,
    rows: &[Row],
    worst_args: &dyn Fn(u64) -> Vec<String>,
) -> Summary {
    let all: Vec<&Row> = rows.iter().collect();
    let mut scenes: BTreeMap<String, Vec<&Row>> = BTreeMap::new();
    let mut sources: BTreeMap<String, Vec<&Row>> = BTreeMap::new();
    let mut perceptions: BTreeMap<String, Vec<&Row>> = BTreeMap::new();
    let mut by_obstacle: BTreeMap<String, BTreeMap<String, u64>> = BTreeMap::new();
    for r in rows {
        scenes.entry(r.scene.clone()).or_default().push(r);
        sources.entry(r.position_source.clone()).or_default().push(r);
        perceptions.entry(r.perception.clone()).or_default().push(r);
        if r.outcome.collided {
            *by_obstacle
                .entry(r.scene.clone())
                .or_default()
                .entry(r.outcome.collision_with.clone())
                .or_default() += 1;
        }
    }
    let mut flown: Vec<&Row> = rows.iter().filter(|r| r.flown()).collect();
    flown.sort_by(|a, b| {
        a.outcome.min_clearance_m.total_cmp(&b.outcome.min_clearance_m).then(a.flight.cmp(&b.flight))
    });
    let worst = flown
        .iter()
        .take(10)
        .enumerate()
        .map(|(k, r)| Worst {
            flight: r.flight,
            scene: r.scene.clone(),
            end_reason: r.outcome.end_reason.clone(),
            min_clearance_m: r.outcome.min_clearance_m,
            collision_with: r.outcome.collision_with.clone(),
            disturbances_file: worst_file(r.flight),
            run_args: worst_args(r.flight),
            report: (k < WORST_REPORTS).then(|| worst_report_dir(r.flight)),
        })
        .collect();
    Summary {
        campaign: c.name.clone(),
        identity: c.identity.clone(),
        seed: c.seed,
        distributions: c.draw.iter().map(|(k, d)| (k.clone(), format!("{d:?}"))).collect(),
        params_set: c.params_set.clone(),
        all: rates(&all),
        per_scene: scenes.iter().map(|(k, v)| (k.clone(), rates(v))).collect(),
        per_source: sources.iter().map(|(k, v)| (k.clone(), rates(v))).collect(),
        per_perception: perceptions.iter().map(|(k, v)| (k.clone(), rates(v))).collect(),
        collisions_by_obstacle: by_obstacle,
        worst,
    }
}

/// The disturbance file of a worst flight, relative to the output directory.
pub fn worst_file(flight: u64) -> String {
    format!("worst/flight_{flight:06}.toml")
}

/// A shell word: quoted when it holds anything but safe characters.
pub fn shell_word(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_./,=:+".contains(c)) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// Draw the plots into `dir`; returns warnings for the ones that could not be drawn.
pub fn plots(dir: &Path, names: &[String], rows: &[Row]) -> Vec<String> {
    let mut warnings = Vec::new();
    let flown: Vec<&Row> = rows.iter().filter(|r| r.flown()).collect();
    if let Err(e) = histogram(&dir.join("min_clearance_hist.svg"), &flown) {
        warnings.push(format!("min_clearance_hist.svg not drawn: {e}"));
    }
    for q in ["wind_speed", "mass", "speed", "turbulence_sigma", "k_f", "motor_tau"] {
        if let Some(k) = names.iter().position(|n| n == q) {
            let path = dir.join(format!("outcome_vs_{q}.svg"));
            if let Err(e) = scatter(&path, q, k, &flown) {
                warnings.push(format!("{} not drawn: {e}", path.display()));
            }
        }
    }
    warnings
}

fn histogram(path: &PathBuf, rows: &[&Row]) -> Result<()> {
    let v: Vec<f64> = rows.iter().map(|r| r.outcome.min_clearance_m.max(-0.05)).collect();
    if v.is_empty() {
        return Ok(());
    }
    let (lo, hi) =
        (v.iter().cloned().fold(f64::INFINITY, f64::min), v.iter().cloned().fold(0.0f64, f64::max));
    let nb = 40usize;
    let w = ((hi - lo) / nb as f64).max(1e-6);
    let mut counts = vec![0u32; nb];
    for x in &v {
        counts[(((x - lo) / w) as usize).min(nb - 1)] += 1;
    }
    let root = SVGBackend::new(path, (800, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let top = *counts.iter().max().unwrap_or(&1) as f64 * 1.1;
    let mut ch = ChartBuilder::on(&root)
        .caption("min clearance per flight (collisions at ≤ 0)", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(lo..lo + w * nb as f64, 0.0..top)
        .map_err(|e| anyhow!("{e}"))?;
    ch.configure_mesh().x_desc("min clearance, m").y_desc("flights").draw().map_err(|e| anyhow!("{e}"))?;
    ch.draw_series(counts.iter().enumerate().map(|(i, c)| {
        let x0 = lo + i as f64 * w;
        let color = if x0 + w <= 0.0 { RED } else { BLUE };
        Rectangle::new([(x0, 0.0), (x0 + w, *c as f64)], color.mix(0.6).filled())
    }))
    .map_err(|e| anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

fn scatter(path: &PathBuf, q: &str, k: usize, rows: &[&Row]) -> Result<()> {
    let pts: Vec<(f64, f64, bool, bool)> = rows
        .iter()
        .map(|r| {
            (r.values[k], r.outcome.min_clearance_m.max(-0.05), r.outcome.collided, r.outcome.reached_goal)
        })
        .collect();
    if pts.is_empty() {
        return Ok(());
    }
    let (x0, x1) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let y1 = pts.iter().fold(0.05f64, |a, p| a.max(p.1));
    let pad = ((x1 - x0) * 0.05).max(1e-3);
    let root = SVGBackend::new(path, (800, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let mut ch = ChartBuilder::on(&root)
        .caption(format!("outcome vs {q} (red collision, green goal, grey other)"), ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0 - pad..x1 + pad, -0.06..y1 * 1.05)
        .map_err(|e| anyhow!("{e}"))?;
    ch.configure_mesh().x_desc(q).y_desc("min clearance, m").draw().map_err(|e| anyhow!("{e}"))?;
    ch.draw_series(pts.iter().map(|&(x, y, c, g)| {
        let color = if c {
            RED
        } else if g {
            GREEN
        } else {
            RGBColor(128, 128, 128)
        };
        Circle::new((x, y), 2, color.mix(0.7).filled())
    }))
    .map_err(|e| anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clopper_pearson_matches_known_values() {
        // Rule of three: 0 in n gives ≈ 3.689 / n (two-sided 95 %: 1 − 0.025^(1/n)).
        let u = clopper_pearson_upper(0, 1000);
        assert!((u - (1.0 - 0.025f64.powf(1.0 / 1000.0))).abs() < 1e-9, "{u}");
        // R: binom.test(5, 100)$conf.int[2] = 0.1128 (0.11283491).
        assert!((clopper_pearson_upper(5, 100) - 0.112_834_9).abs() < 1e-5);
        // binom.test(50, 10000)$conf.int[2] = 0.006587...
        assert!((clopper_pearson_upper(50, 10_000) - 0.006_587).abs() < 5e-5);
        assert_eq!(clopper_pearson_upper(3, 3), 1.0);
    }

    #[test]
    fn rows_round_trip_through_csv() {
        let names = vec!["mass".to_string(), "wind_speed".to_string()];
        let rows = vec![
            Row {
                flight: 0,
                scene: "office, big".into(),
                seed: u64::MAX,
                position_source: "gps".into(),
                perception: "lidar3d".into(),
                values: vec![1.0 / 3.0, 2.5e-7],
                outcome: Outcome {
                    collided: true,
                    collision_with: "obstacles[3] (pillar \"B\")".into(),
                    end_reason: "collision".into(),
                    min_clearance_m: -1e-4,
                    min_h_bar: f64::INFINITY,
                    time_to_goal_s: None,
                    ..Default::default()
                },
            },
            Row {
                flight: 1,
                scene: "x".into(),
                seed: 3,
                position_source: String::new(),
                perception: "truth".into(),
                values: vec![0.1, 0.2],
                outcome: Outcome { reached_goal: true, time_to_goal_s: Some(60.828), ..Default::default() },
            },
        ];
        let p = std::env::temp_dir().join(format!("parapet-rows-{}.csv", std::process::id()));
        write_csv(&p, &names, &rows).unwrap();
        assert_eq!(read_csv(&p, &names).unwrap(), rows);
        assert!(read_csv(&p, &names[..1]).is_err());
        std::fs::remove_file(&p).ok();
    }
}
