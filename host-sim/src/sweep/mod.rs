//! Parameter sweeps: `parapet sweep` and `parapet sweep-merge`.
//!
//! A sweep flies one scene over the grid speed × μ × δ1 × seed (sensor-noise
//! seeds `0..K`) on one fixed path (a path file, the straight line, or the
//! planner's path for planner seed `--plan-seed`, planned once), in parallel on a
//! local rayon pool of `--jobs` threads. Every run is deterministic for its seed,
//! so the grid can be split: `--shard I/N` (I = 1..=N) flies only the runs whose
//! grid index `k` satisfies `k mod N = I − 1`, and `sweep-merge` joins the shards'
//! CSVs into the same `sweep.csv` the unsharded sweep writes.
//!
//! Outputs in `--out` (default `out/sweep`):
//! * `sweep.csv`: one row per run, sorted by grid index, columns [`CSV_HEADER`]:
//!   the grid index, the parameters (μ s, δ1 m², speed m/s, seed) and the run
//!   summary's fields (see `report::Summary`). Numbers are written in Rust's
//!   shortest round-trip form, so a merged CSV equals the unsharded one byte for byte.
//!   The wall-clock time is left out on purpose (it is not deterministic).
//! * `heatmap_collision_rate`, `heatmap_min_clearance`, `heatmap_tracking_rms`
//!   (`.png` and `.svg`): μ on x, δ1 on y; each cell aggregates the runs of all
//!   seeds and speeds at that (μ, δ1): collision rate = share of runs that
//!   collided, min clearance = the smallest over the cell's runs (m), tracking RMS
//!   = mean over the cell's runs (m).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use clap::Args;
use nalgebra::Vector3;
use parapet_core::cbf::FilterVariant;
use plotters::coord::Shift;
use plotters::prelude::*;
use rayon::prelude::*;

use crate::cli::CliError;
use crate::pathfile::PathFile;
use crate::planner::{plan, PlanProblem, PlannerParams};
use crate::report::e;
use crate::runner::{path_length, run, RunConfig};
use crate::scene::{to_f32, to_f64, Scene};

/// Columns of `sweep.csv`.
pub const CSV_HEADER: &str = "index,scene,filter,mu,delta,delta1,kp,kd,speed,seed,noise,collided,\
first_collision_time_s,collision_with,min_clearance_m,min_h_bar,min_filter_h_bar,reached_goal,\
time_to_goal_s,final_distance_to_goal_m,tracking_rms_m,filter_active_fraction,end_reason,sim_time_s";

/// An inclusive range `A:B:N` of `N` evenly spaced values (`N = 1`: just `A`, and `B` must equal `A`).
#[derive(Clone, Debug, PartialEq)]
pub struct GridRange {
    /// First value.
    pub start: f64,
    /// Last value.
    pub end: f64,
    /// Number of values (≥ 1).
    pub n: usize,
}

impl GridRange {
    /// Parse `A:B:N` (A ≤ B finite and > 0, N ≥ 1 integer, at most 10 000 values).
    pub fn parse(s: &str) -> Result<GridRange, String> {
        let parts: Vec<&str> = s.split(':').collect();
        if parts.len() != 3 {
            return Err(format!("{s:?}: expected A:B:N (first:last:count), e.g. 0.5:1.4:4"));
        }
        let num = |t: &str| -> Result<f64, String> {
            t.trim().parse::<f64>().map_err(|_| format!("{s:?}: {t:?} is not a number"))
        };
        let (a, b) = (num(parts[0])?, num(parts[1])?);
        let n: usize = parts[2]
            .trim()
            .parse()
            .map_err(|_| format!("{s:?}: count {:?} is not a whole number", parts[2]))?;
        if !(a.is_finite() && b.is_finite() && a > 0.0 && b > 0.0) {
            return Err(format!("{s:?}: the bounds must be finite and > 0"));
        }
        if n == 0 || n > 10_000 {
            return Err(format!("{s:?}: the count must be in 1..=10000"));
        }
        if a > b {
            return Err(format!("{s:?}: the first value exceeds the last"));
        }
        if n == 1 && a != b {
            return Err(format!("{s:?}: a count of 1 needs first = last"));
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

/// `--shard I/N`: the I-th (1-based) of N interleaved slices of the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Slice number, 1..=count.
    pub index: usize,
    /// Number of slices.
    pub count: usize,
}

impl Shard {
    /// Parse `I/N` with 1 ≤ I ≤ N.
    pub fn parse(s: &str) -> Result<Shard, String> {
        let (i, n) = s.split_once('/').ok_or_else(|| format!("{s:?}: expected I/N, e.g. 2/4"))?;
        let i: usize = i.trim().parse().map_err(|_| format!("{s:?}: {i:?} is not a whole number"))?;
        let n: usize = n.trim().parse().map_err(|_| format!("{s:?}: {n:?} is not a whole number"))?;
        if n == 0 || i == 0 || i > n {
            return Err(format!("{s:?}: need 1 <= I <= N"));
        }
        Ok(Shard { index: i, count: n })
    }

    /// Whether grid index `k` belongs to this shard.
    pub fn contains(&self, k: usize) -> bool {
        k % self.count == self.index - 1
    }
}

/// One run of the grid.
#[derive(Clone, Debug, PartialEq)]
pub struct GridPoint {
    /// Index in the full grid (speed-major, then μ, δ1, seed).
    pub index: usize,
    /// μ, s.
    pub mu: f64,
    /// δ1, m².
    pub delta1: f64,
    /// Reference speed, m/s.
    pub speed: f64,
    /// Sensor-noise seed.
    pub seed: u64,
}

/// The full grid, in index order.
pub fn grid(mu: &GridRange, delta1: &GridRange, speeds: &[f64], seeds: u64) -> Vec<GridPoint> {
    let mut out = Vec::new();
    for &speed in speeds {
        for m in mu.values() {
            for d in delta1.values() {
                for seed in 0..seeds {
                    out.push(GridPoint { index: out.len(), mu: m, delta1: d, speed, seed });
                }
            }
        }
    }
    out
}

/// One row of `sweep.csv`: the columns of [`CSV_HEADER`] as text, plus the
/// parsed fields the heatmaps need.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRow {
    /// Grid index.
    pub index: usize,
    /// μ, s.
    pub mu: f64,
    /// δ1, m².
    pub delta1: f64,
    /// Collided.
    pub collided: bool,
    /// Minimum clearance, m.
    pub min_clearance_m: f64,
    /// Tracking RMS, m.
    pub tracking_rms_m: f64,
    /// All columns as written.
    pub fields: Vec<String>,
}

fn opt_num(x: Option<f64>) -> String {
    x.map(|v| format!("{v}")).unwrap_or_default()
}

fn csv_text(s: &str) -> String {
    // Names never contain quotes in practice; replace the CSV metacharacters to stay one column.
    s.replace([',', '"', '\n'], " ")
}

/// Fly one grid point (a fresh config from `base`) and make its row.
pub fn fly_point(scene: &Scene, base: &RunConfig, p: &GridPoint) -> Result<SweepRow> {
    let mut scene = scene.clone();
    scene.speed = p.speed;
    let mut cfg = base.clone();
    cfg.params.mu = p.mu;
    cfg.params.delta1 = p.delta1;
    cfg.params.speed = p.speed;
    cfg.seed = p.seed;
    if scene.sim.duration.is_none() {
        // Same rule as `parapet run`: 1.5 × path time + 15 s at this speed.
        cfg.duration = base.duration.min(1.5 * path_length(&cfg.path) / p.speed + 15.0);
    }
    let out = run(&scene, &cfg, &mut |_| {}).with_context(|| {
        format!("run {} (mu {}, delta1 {}, speed {}, seed {})", p.index, p.mu, p.delta1, p.speed, p.seed)
    })?;
    let s = out.summary;
    let fields = vec![
        p.index.to_string(),
        csv_text(&s.scene),
        s.filter.clone(),
        format!("{}", p.mu),
        format!("{}", s.params.delta),
        format!("{}", p.delta1),
        format!("{}", s.params.kp),
        format!("{}", s.params.kd),
        format!("{}", p.speed),
        p.seed.to_string(),
        u8::from(s.noise).to_string(),
        u8::from(s.collided).to_string(),
        opt_num(s.first_collision_time_s),
        s.collision_with.as_deref().map(csv_text).unwrap_or_default(),
        format!("{}", s.min_clearance_m),
        format!("{}", s.min_h_bar),
        opt_num(s.min_filter_h_bar),
        u8::from(s.reached_goal).to_string(),
        opt_num(s.time_to_goal_s),
        format!("{}", s.final_distance_to_goal_m),
        format!("{}", s.tracking_rms_m),
        format!("{}", s.filter_active_fraction),
        s.end_reason.clone(),
        format!("{}", s.sim_time_s),
    ];
    Ok(SweepRow {
        index: p.index,
        mu: p.mu,
        delta1: p.delta1,
        collided: s.collided,
        min_clearance_m: s.min_clearance_m,
        tracking_rms_m: s.tracking_rms_m,
        fields,
    })
}

/// Fly `points` on a local pool of `jobs` threads; `tick` is called after each run.
pub fn run_points(
    scene: &Scene,
    base: &RunConfig,
    points: &[GridPoint],
    jobs: usize,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<SweepRow>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.max(1))
        .build()
        .map_err(|err| anyhow!("cannot start the thread pool: {err}"))?;
    let mut rows: Vec<SweepRow> = pool.install(|| {
        points
            .par_iter()
            .map(|p| {
                let r = fly_point(scene, base, p);
                tick();
                r
            })
            .collect::<Result<Vec<_>>>()
    })?;
    rows.sort_by_key(|r| r.index);
    Ok(rows)
}

/// The text of `sweep.csv` for `rows` (sorted by index by the caller).
pub fn csv_string(rows: &[SweepRow]) -> String {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in rows {
        s.push_str(&r.fields.join(","));
        s.push('\n');
    }
    s
}

/// Parse a `sweep.csv` (as written by [`csv_string`]); `file` names it in errors.
pub fn parse_csv(text: &str, file: &str) -> Result<Vec<SweepRow>, String> {
    let mut lines = text.lines();
    match lines.next() {
        Some(h) if h.trim_end() == CSV_HEADER => {}
        _ => return Err(format!("{file}: line 1: not a sweep CSV (expected the header {CSV_HEADER:?})")),
    }
    let ncol = CSV_HEADER.split(',').count();
    let col = |name: &str| CSV_HEADER.split(',').position(|c| c == name).unwrap_or(0);
    let (ci, cm, cd, cc, ccl, cr) = (
        col("index"),
        col("mu"),
        col("delta1"),
        col("collided"),
        col("min_clearance_m"),
        col("tracking_rms_m"),
    );
    let mut rows = Vec::new();
    for (k, line) in lines.enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let ln = k + 2;
        let fields: Vec<String> = line.split(',').map(str::to_string).collect();
        if fields.len() != ncol {
            return Err(format!("{file}: line {ln}: {} columns, expected {ncol}", fields.len()));
        }
        let num = |c: usize| -> Result<f64, String> {
            fields[c].parse::<f64>().map_err(|_| {
                format!(
                    "{file}: line {ln}: column `{}`: {:?} is not a number",
                    CSV_HEADER.split(',').nth(c).unwrap_or("?"),
                    fields[c]
                )
            })
        };
        let index = fields[ci].parse::<usize>().map_err(|_| {
            format!("{file}: line {ln}: column `index`: {:?} is not a whole number", fields[ci])
        })?;
        let collided = match fields[cc].as_str() {
            "0" => false,
            "1" => true,
            other => return Err(format!("{file}: line {ln}: column `collided`: {other:?} is not 0 or 1")),
        };
        rows.push(SweepRow {
            index,
            mu: num(cm)?,
            delta1: num(cd)?,
            collided,
            min_clearance_m: num(ccl)?,
            tracking_rms_m: num(cr)?,
            fields,
        });
    }
    Ok(rows)
}

/// Join shard rows: sort by index; the same index twice must be the same row.
pub fn merge_rows(mut rows: Vec<SweepRow>) -> Result<Vec<SweepRow>, String> {
    rows.sort_by_key(|r| r.index);
    let mut out: Vec<SweepRow> = Vec::with_capacity(rows.len());
    for r in rows {
        match out.last() {
            Some(prev) if prev.index == r.index => {
                if prev.fields != r.fields {
                    return Err(format!("run {} appears twice with different results", r.index));
                }
            }
            _ => out.push(r),
        }
    }
    Ok(out)
}

/// One (μ, δ1) cell of the heatmaps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// Runs in the cell.
    pub runs: usize,
    /// Share of runs that collided.
    pub collision_rate: f64,
    /// Smallest min clearance over the runs, m.
    pub min_clearance_m: f64,
    /// Mean tracking RMS over the runs, m.
    pub tracking_rms_m: f64,
}

/// Sorted μ values, sorted δ1 values, and `cells[i_mu][i_delta1]`.
pub type Aggregate = (Vec<f64>, Vec<f64>, Vec<Vec<Option<Cell>>>);

/// Aggregate rows per (μ, δ1) over seeds and speeds. Returns the sorted μ and δ1
/// values and the cells, `cells[i_mu][i_delta1]` (`None` where no run).
pub fn aggregate(rows: &[SweepRow]) -> Aggregate {
    let key = |x: f64| x.to_bits();
    let mut mus: BTreeMap<u64, f64> = BTreeMap::new();
    let mut d1s: BTreeMap<u64, f64> = BTreeMap::new();
    for r in rows {
        mus.insert(key(r.mu), r.mu);
        d1s.insert(key(r.delta1), r.delta1);
    }
    let mut mu_v: Vec<f64> = mus.into_values().collect();
    let mut d1_v: Vec<f64> = d1s.into_values().collect();
    mu_v.sort_by(f64::total_cmp);
    d1_v.sort_by(f64::total_cmp);
    let mut cells = vec![vec![None; d1_v.len()]; mu_v.len()];
    for (i, &m) in mu_v.iter().enumerate() {
        for (j, &d) in d1_v.iter().enumerate() {
            let sel: Vec<&SweepRow> = rows.iter().filter(|r| r.mu == m && r.delta1 == d).collect();
            if sel.is_empty() {
                continue;
            }
            let n = sel.len() as f64;
            cells[i][j] = Some(Cell {
                runs: sel.len(),
                collision_rate: sel.iter().filter(|r| r.collided).count() as f64 / n,
                min_clearance_m: sel.iter().map(|r| r.min_clearance_m).fold(f64::INFINITY, f64::min),
                tracking_rms_m: sel.iter().map(|r| r.tracking_rms_m).sum::<f64>() / n,
            });
        }
    }
    (mu_v, d1_v, cells)
}

/// Heatmap kinds: file stem, title, value of a cell, colour scale reversed (high = good).
const HEATMAPS: [(&str, &str); 3] = [
    ("heatmap_collision_rate", "collision rate"),
    ("heatmap_min_clearance", "min clearance [m] (worst run)"),
    ("heatmap_tracking_rms", "tracking RMS [m] (mean)"),
];

fn cell_value(stem: &str, c: &Cell) -> f64 {
    match stem {
        "heatmap_collision_rate" => c.collision_rate,
        "heatmap_min_clearance" => c.min_clearance_m,
        _ => c.tracking_rms_m,
    }
}

/// Colour for `t` in [0, 1]: white-yellow (0) → red → dark red (1).
fn ramp(t: f64) -> RGBColor {
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
    let lerp = |a: f64, b: f64, s: f64| (a + (b - a) * s).round() as u8;
    if t < 0.5 {
        let s = t / 0.5;
        RGBColor(255, lerp(255.0, 140.0, s), lerp(204.0, 40.0, s))
    } else {
        let s = (t - 0.5) / 0.5;
        RGBColor(lerp(255.0, 140.0, s), lerp(140.0, 0.0, s), lerp(40.0, 0.0, s))
    }
}

fn draw_heatmap<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    stem: &str,
    title: &str,
    scene: &str,
    agg: &Aggregate,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let (mus, d1s, cells) = agg;
    root.fill(&WHITE).map_err(e)?;
    let vals: Vec<f64> = cells.iter().flatten().flatten().map(|c| cell_value(stem, c)).collect();
    let (lo, hi) = vals.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    let (lo, hi) = if stem == "heatmap_collision_rate" { (0.0, 1.0) } else { (lo, hi) };
    let span = if hi > lo { hi - lo } else { 1.0 };
    // Collision rate and tracking RMS: high = bad = dark; clearance: low = bad = dark.
    let badness = |v: f64| if stem == "heatmap_min_clearance" { (hi - v) / span } else { (v - lo) / span };
    let (nx, ny) = (mus.len().max(1), d1s.len().max(1));
    let mut chart = ChartBuilder::on(root)
        .caption(format!("{scene}: {title} over (μ, δ1)"), ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..nx as f64, 0f64..ny as f64)
        .map_err(e)?;
    let fmt_axis = |vals: &[f64], x: f64| -> String {
        let i = x.floor();
        if (x - i - 0.5).abs() < 1e-6 && i >= 0.0 && (i as usize) < vals.len() {
            format!("{:.3}", vals[i as usize])
        } else {
            String::new()
        }
    };
    let xf = |x: &f64| fmt_axis(mus, *x);
    let yf = |y: &f64| fmt_axis(d1s, *y);
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("μ [s]")
        .y_desc("δ1 [m²]")
        .x_labels(2 * nx + 1)
        .y_labels(2 * ny + 1)
        .x_label_formatter(&xf)
        .y_label_formatter(&yf)
        .draw()
        .map_err(e)?;
    for (i, col) in cells.iter().enumerate() {
        for (j, c) in col.iter().enumerate() {
            let (x0, y0) = (i as f64, j as f64);
            let (fill, label, dark) = match c {
                Some(c) => {
                    let v = cell_value(stem, c);
                    let dark = badness(v) > 0.6;
                    (
                        ramp(badness(v)),
                        if stem == "heatmap_collision_rate" { format!("{v:.2}") } else { format!("{v:.3}") },
                        dark,
                    )
                }
                None => (RGBColor(230, 230, 230), "-".to_string(), false),
            };
            chart
                .draw_series(std::iter::once(Rectangle::new([(x0, y0), (x0 + 1.0, y0 + 1.0)], fill.filled())))
                .map_err(e)?;
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x0, y0), (x0 + 1.0, y0 + 1.0)],
                    WHITE.stroke_width(1),
                )))
                .map_err(e)?;
            let style = TextStyle::from(("sans-serif", 14).into_font())
                .color(if dark { &WHITE } else { &BLACK })
                .pos(plotters::style::text_anchor::Pos::new(
                    plotters::style::text_anchor::HPos::Center,
                    plotters::style::text_anchor::VPos::Center,
                ));
            chart.draw_series(std::iter::once(Text::new(label, (x0 + 0.5, y0 + 0.5), style))).map_err(e)?;
        }
    }
    Ok(())
}

/// Draw the three heatmaps (PNG and SVG) into `dir`. Returns the files written and
/// warnings for plots that could not be drawn (e.g. no usable font).
pub fn write_heatmaps(dir: &Path, scene: &str, rows: &[SweepRow]) -> (Vec<PathBuf>, Vec<String>) {
    let agg = aggregate(rows);
    let (nx, ny) = (agg.0.len().max(1) as u32, agg.1.len().max(1) as u32);
    let size = ((120 + 70 * nx).clamp(420, 1400), (110 + 45 * ny).clamp(300, 1000));
    let mut files = Vec::new();
    let mut warnings = Vec::new();
    for (stem, title) in HEATMAPS {
        let one = || -> Result<Vec<PathBuf>> {
            let svg = dir.join(format!("{stem}.svg"));
            {
                let root = SVGBackend::new(&svg, size).into_drawing_area();
                draw_heatmap(&root, stem, title, scene, &agg)?;
                root.present().map_err(e)?;
            }
            let png = dir.join(format!("{stem}.png"));
            {
                let root = BitMapBackend::new(&png, size).into_drawing_area();
                draw_heatmap(&root, stem, title, scene, &agg)?;
                root.present().map_err(e)?;
            }
            Ok(vec![svg, png])
        };
        match one() {
            Ok(mut v) => files.append(&mut v),
            Err(err) => warnings.push(format!("plot {stem}: {err:#}")),
        }
    }
    (files, warnings)
}

/// Write `sweep.csv` and the heatmaps into `dir` (created). Prints warnings.
pub fn write_outputs(dir: &Path, rows: &[SweepRow]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let csv = dir.join("sweep.csv");
    std::fs::write(&csv, csv_string(rows)).with_context(|| format!("cannot write {}", csv.display()))?;
    let scene = rows.first().and_then(|r| r.fields.get(1).cloned()).unwrap_or_default();
    let (_, warnings) = write_heatmaps(dir, &scene, rows);
    for w in warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

fn parse_range(s: &str) -> Result<GridRange, String> {
    GridRange::parse(s)
}
fn parse_shard(s: &str) -> Result<Shard, String> {
    Shard::parse(s)
}
fn parse_variant(s: &str) -> Result<FilterVariant, String> {
    s.parse().map_err(|_| format!("unknown filter {s:?}: expected paper, relative, multi or multi-relative"))
}

/// Options of `parapet sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Scene file (TOML, ENU z-up).
    #[arg(long)]
    pub scene: PathBuf,
    /// μ values, s: first:last:count (e.g. 0.5:1.4:4).
    #[arg(long, value_parser = parse_range)]
    pub mu: GridRange,
    /// δ1 values, m²: first:last:count (each must exceed δ).
    #[arg(long, value_parser = parse_range)]
    pub delta1: GridRange,
    /// Reference speeds, m/s: first:last:count (default: the scene's speed).
    #[arg(long, value_parser = parse_range)]
    pub speed: Option<GridRange>,
    /// Sensor-noise seeds per grid point: 0..K.
    #[arg(long, default_value_t = 1)]
    pub seeds: u64,
    /// Parallel runs (threads; default: the number of CPUs).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Filter variant: paper | relative | multi | multi-relative (default: the scene's, else multi-relative).
    #[arg(long, value_parser = parse_variant)]
    pub filter: Option<FilterVariant>,
    /// Sensor noise off.
    #[arg(long)]
    pub no_noise: bool,
    /// Fly this path file (JSON from `parapet plan`) instead of planning.
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Fly the straight line start → goal instead of planning.
    #[arg(long, conflicts_with = "path")]
    pub straight: bool,
    /// Planner seed of the one path every run flies (when planning).
    #[arg(long, default_value_t = 0)]
    pub plan_seed: u64,
    /// Duration limit of each run, s (default: the scene's, else 1.5 × path time + 15 s).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Run only slice I of N (1 <= I <= N; grid index k with k mod N = I - 1).
    #[arg(long, value_parser = parse_shard)]
    pub shard: Option<Shard>,
    /// Output directory.
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
}

/// Options of `parapet sweep-merge`.
#[derive(Debug, Args)]
pub struct SweepMergeArgs {
    /// Shard CSVs (sweep.csv files of `parapet sweep --shard`).
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Output directory (sweep.csv and heatmaps).
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
}

fn bad(m: impl Into<String>) -> CliError {
    CliError::BadInput(m.into())
}

/// The path every run of a sweep flies (NED, start first).
fn sweep_path(scene: &Scene, a: &SweepArgs) -> Result<(Vec<Vector3<f64>>, &'static str), CliError> {
    if let Some(p) = &a.path {
        let f = PathFile::read(p).map_err(|err| bad(err.to_string()))?;
        let wps: Vec<Vector3<f64>> = f.waypoints_ned().iter().map(to_f64).collect();
        if wps.is_empty() {
            return Err(bad(format!("{}: field `waypoints`: empty", p.display())));
        }
        return Ok((wps, "file"));
    }
    if a.straight {
        return Ok((vec![scene.start, scene.goal], "straight"));
    }
    let (mn, mx) = scene.bounds_ned();
    let problem = PlanProblem {
        bounds_min: to_f32(&mn),
        bounds_max: to_f32(&mx),
        obstacles: scene.static_shapes(),
        start: to_f32(&scene.start),
        goal: to_f32(&scene.goal),
        hull_radius: scene.vehicle.hull_radius as f32,
    };
    let params = PlannerParams { seed: a.plan_seed, ..PlannerParams::default() };
    let planned = plan(&problem, &params).map_err(|err| {
        let msg = format!("{}: planning failed: {err}", scene.source);
        if err.exit_code() == 3 {
            CliError::NoPath(msg)
        } else {
            bad(msg)
        }
    })?;
    Ok((planned.waypoints.iter().map(to_f64).collect(), "planner"))
}

/// `parapet sweep`.
pub fn cmd_sweep(a: SweepArgs) -> Result<(), CliError> {
    let scene = Scene::load(&a.scene).map_err(|err| bad(err.to_string()))?;
    if a.seeds == 0 {
        return Err(bad("option --seeds: must be at least 1"));
    }
    if a.jobs == Some(0) {
        return Err(bad("option --jobs: must be at least 1"));
    }
    if let Some(d) = a.duration.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(bad(format!("option --duration: must be finite and > 0, got {d}")));
    }
    let (path, source) = sweep_path(&scene, &a)?;
    if path.len() > parapet_core::controller::PATH_CAPACITY {
        return Err(bad(format!(
            "the path has {} waypoints, more than the controller's capacity of {}",
            path.len(),
            parapet_core::controller::PATH_CAPACITY
        )));
    }
    let mut base =
        RunConfig::for_scene(&scene, path).map_err(|err| bad(format!("{}: {err}", scene.source)))?;
    base.path_source = source.into();
    if let Some(v) = a.filter {
        base.variant = v;
    }
    if a.no_noise {
        base.sensors.noise = false;
    }
    base.duration = a.duration.or(scene.sim.duration).unwrap_or(f64::INFINITY);
    let delta = base.params.delta;
    if let Some(d1) = a.delta1.values().into_iter().find(|&d1| d1 <= delta) {
        return Err(bad(format!("option --delta1: every value must exceed delta = {delta} m², got {d1}")));
    }
    let speeds = a.speed.as_ref().map(|s| s.values()).unwrap_or_else(|| vec![scene.speed]);
    let all = grid(&a.mu, &a.delta1, &speeds, a.seeds);
    let points: Vec<GridPoint> =
        all.iter().filter(|p| a.shard.is_none_or(|s| s.contains(p.index))).cloned().collect();
    let jobs = a.jobs.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    let bar = std::io::stderr().is_terminal().then(|| {
        let pb = indicatif::ProgressBar::new(points.len() as u64);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "sweep [{bar:40}] {pos}/{len} runs {elapsed_precise} eta {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb
    });
    let tick = || {
        if let Some(pb) = &bar {
            pb.inc(1);
        }
    };
    let rows = run_points(&scene, &base, &points, jobs, &tick)?;
    if let Some(pb) = bar {
        pb.finish_and_clear();
    }
    write_outputs(&a.out, &rows)?;
    let collided = rows.iter().filter(|r| r.collided).count();
    let mut msg = format!(
        "{}: {} of {} runs{}, {} collided -> {}",
        scene.name,
        rows.len(),
        all.len(),
        a.shard.map(|s| format!(" (shard {}/{})", s.index, s.count)).unwrap_or_default(),
        collided,
        a.out.join("sweep.csv").display()
    );
    let _ = writeln!(msg);
    print!("{msg}");
    Ok(())
}

/// `parapet sweep-merge`.
pub fn cmd_sweep_merge(a: SweepMergeArgs) -> Result<(), CliError> {
    let mut rows = Vec::new();
    for f in &a.inputs {
        let text = std::fs::read_to_string(f)
            .map_err(|err| bad(format!("{}: cannot read the file: {err}", f.display())))?;
        rows.extend(parse_csv(&text, &f.display().to_string()).map_err(bad)?);
    }
    let rows = merge_rows(rows).map_err(bad)?;
    write_outputs(&a.out, &rows)?;
    println!("merged {} files: {} runs -> {}", a.inputs.len(), rows.len(), a.out.join("sweep.csv").display());
    Ok(())
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
        for bad in ["1:2", "a:2:3", "1:2:0", "2:1:3", "-1:2:3", "1:2:x", "1:2:1", "nan:1:2", "1:inf:2"] {
            assert!(GridRange::parse(bad).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn shards_partition_the_grid() {
        let s: Vec<Shard> = (1..=3).map(|i| Shard::parse(&format!("{i}/3")).unwrap()).collect();
        for k in 0..20 {
            assert_eq!(s.iter().filter(|x| x.contains(k)).count(), 1);
        }
        for bad in ["0/3", "4/3", "1/0", "x/2", "1-2"] {
            assert!(Shard::parse(bad).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn grid_order_and_csv_round_trip() {
        let mu = GridRange::parse("0.5:1:2").unwrap();
        let d1 = GridRange::parse("0.1:0.3:3").unwrap();
        let g = grid(&mu, &d1, &[0.25], 2);
        assert_eq!(g.len(), 12);
        assert!(g.iter().enumerate().all(|(i, p)| p.index == i));
        assert_eq!((g[0].mu, g[0].delta1, g[0].seed), (0.5, 0.1, 0));
        assert_eq!((g[1].seed, g[2].delta1), (1, 0.2));
        let ncol = CSV_HEADER.split(',').count();
        let mk = |i: usize, c: bool| {
            let mut f = vec!["0".to_string(); ncol];
            f[0] = i.to_string();
            f[3] = "0.5".into();
            f[5] = "0.1".into();
            f[11] = if c { "1".into() } else { "0".into() };
            f[14] = format!("{}", 0.1 * i as f64);
            f[20] = "0.2".into();
            f
        };
        let rows: Vec<SweepRow> = (0..3)
            .map(|i| SweepRow {
                index: i,
                mu: 0.5,
                delta1: 0.1,
                collided: i == 1,
                min_clearance_m: 0.1 * i as f64,
                tracking_rms_m: 0.2,
                fields: mk(i, i == 1),
            })
            .collect();
        let text = csv_string(&rows);
        assert_eq!(parse_csv(&text, "x").unwrap(), rows);
        let merged =
            merge_rows(vec![rows[2].clone(), rows[0].clone(), rows[1].clone(), rows[0].clone()]).unwrap();
        assert_eq!(merged, rows);
        let mut other = rows[0].clone();
        other.fields[14] = "9".into();
        assert!(merge_rows(vec![rows[0].clone(), other]).is_err());
        let (m, d, cells) = aggregate(&rows);
        assert_eq!((m, d), (vec![0.5], vec![0.1]));
        let c = cells[0][0].unwrap();
        assert_eq!(c.runs, 3);
        assert!((c.collision_rate - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(c.min_clearance_m, 0.0);
        assert!(parse_csv("a,b\n", "f").unwrap_err().contains("f: line 1"));
        assert!(parse_csv(&format!("{CSV_HEADER}\n1,2\n"), "f").unwrap_err().contains("line 2"));
    }
}
