//! Heatmaps of a sweep: the per-(μ, δ1) aggregation of the flown rows and the
//! three plots `heatmap_collision_rate`, `heatmap_min_clearance`,
//! `heatmap_tracking_rms` (`.png` and `.svg`).
//!
//! μ is on x, δ1 on y; each cell aggregates the runs of all seeds and speeds at
//! that (μ, δ1): collision rate = share of runs that collided, min clearance =
//! the smallest over the cell's runs (m), tracking RMS = mean over the cell's runs
//! (m). Failed rows (`status = failed`) are left out; a cell with no flown run is
//! drawn grey with `-`. [`Aggregator`] is fed row by row while the CSV streams, so
//! its memory is one small record per distinct (μ, δ1), not per run.
//!
//! May import: `super::record`, `crate::report` (the plot error helper), plotters.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::record::SweepRecord;
use crate::report::e;

/// One (μ, δ1) cell of the heatmaps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// Flown (not failed) runs in the cell.
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

#[derive(Clone, Copy, Debug)]
struct Acc {
    runs: usize,
    collided: usize,
    min_clearance_m: f64,
    sum_rms: f64,
}

/// Running per-(μ, δ1) totals of flown rows (failed rows are counted apart).
#[derive(Clone, Debug, Default)]
pub struct Aggregator {
    // Keys: the bits of μ and δ1; both are > 0, where the bit order is the numeric order.
    cells: BTreeMap<(u64, u64), Acc>,
    failed: u64,
    rows: u64,
    collided: u64,
}

impl Aggregator {
    /// Count one row.
    pub fn add(&mut self, r: &SweepRecord) {
        self.rows += 1;
        let Some(o) = r.outcome() else {
            self.failed += 1;
            return;
        };
        if o.collided {
            self.collided += 1;
        }
        let acc = self.cells.entry((r.mu.to_bits(), r.delta1.to_bits())).or_insert(Acc {
            runs: 0,
            collided: 0,
            min_clearance_m: f64::INFINITY,
            sum_rms: 0.0,
        });
        acc.runs += 1;
        acc.collided += usize::from(o.collided);
        acc.min_clearance_m = acc.min_clearance_m.min(o.min_clearance_m);
        acc.sum_rms += o.tracking_rms_m;
    }

    /// Rows counted.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Failed rows counted.
    pub fn failed(&self) -> u64 {
        self.failed
    }

    /// Flown rows that collided.
    pub fn collided(&self) -> u64 {
        self.collided
    }

    /// The sorted μ and δ1 values of the flown rows and the cells,
    /// `cells[i_mu][i_delta1]` (`None` where no run was flown).
    pub fn aggregate(&self) -> Aggregate {
        let mut mu_v: Vec<u64> = self.cells.keys().map(|k| k.0).collect();
        let mut d1_v: Vec<u64> = self.cells.keys().map(|k| k.1).collect();
        mu_v.sort_unstable();
        mu_v.dedup();
        d1_v.sort_unstable();
        d1_v.dedup();
        let mut cells = vec![vec![None; d1_v.len()]; mu_v.len()];
        for (&(m, d), a) in &self.cells {
            let (Ok(i), Ok(j)) = (mu_v.binary_search(&m), d1_v.binary_search(&d)) else { continue };
            let n = a.runs as f64;
            cells[i][j] = Some(Cell {
                runs: a.runs,
                collision_rate: a.collided as f64 / n,
                min_clearance_m: a.min_clearance_m,
                tracking_rms_m: a.sum_rms / n,
            });
        }
        (
            mu_v.into_iter().map(f64::from_bits).collect(),
            d1_v.into_iter().map(f64::from_bits).collect(),
            cells,
        )
    }
}

/// Heatmap kinds: file stem, title.
const HEATMAPS: [(&str, &str); 3] = [
    ("heatmap_collision_rate", "collision rate"),
    ("heatmap_min_clearance", "min clearance [m] (worst run)"),
    ("heatmap_tracking_rms", "tracking RMS [m] (mean)"),
];

/// The file names the heatmaps are written to (for the overwrite checks).
pub fn file_names() -> Vec<String> {
    HEATMAPS.iter().flat_map(|(stem, _)| [format!("{stem}.png"), format!("{stem}.svg")]).collect()
}

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

/// Most distinct μ (or δ1) values a heatmap is drawn for; a larger grid gets
/// its `sweep.csv` but no heatmaps (a warning says so).
pub const MAX_AXIS_CELLS: usize = 100;

/// Draw the three heatmaps (PNG and SVG) into `dir`. Returns the files written and
/// warnings for plots that could not be drawn (no usable font, too many cells).
pub fn write_heatmaps(dir: &Path, scene: &str, agg: &Aggregate) -> (Vec<PathBuf>, Vec<String>) {
    if agg.0.len() > MAX_AXIS_CELLS || agg.1.len() > MAX_AXIS_CELLS {
        let msg = format!(
            "heatmaps not drawn: {} μ × {} δ1 values, more than {MAX_AXIS_CELLS} on an axis",
            agg.0.len(),
            agg.1.len()
        );
        return (Vec::new(), vec![msg]);
    }
    let (nx, ny) = (agg.0.len().max(1) as u32, agg.1.len().max(1) as u32);
    let size = ((120 + 70 * nx).clamp(420, 1400), (110 + 45 * ny).clamp(300, 1000));
    let mut files = Vec::new();
    let mut warnings = Vec::new();
    for (stem, title) in HEATMAPS {
        let one = || -> Result<Vec<PathBuf>> {
            let svg = dir.join(format!("{stem}.svg"));
            {
                let root = SVGBackend::new(&svg, size).into_drawing_area();
                draw_heatmap(&root, stem, title, scene, agg)?;
                root.present().map_err(e)?;
            }
            let png = dir.join(format!("{stem}.png"));
            {
                let root = BitMapBackend::new(&png, size).into_drawing_area();
                draw_heatmap(&root, stem, title, scene, agg)?;
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

#[cfg(test)]
mod tests {
    use super::super::record::tests::ok_row;
    use super::super::record::Status;
    use super::*;

    fn row(index: u64, mu: f64, delta1: f64, collided: bool, clearance: f64, rms: f64) -> SweepRecord {
        SweepRecord { mu, delta1, tracking_rms_m: Some(rms), ..ok_row(index, collided, clearance) }
    }

    fn failed(index: u64, mu: f64, delta1: f64) -> SweepRecord {
        let mut r = row(index, mu, delta1, false, -5.0, 9.0);
        r.status = Status::Failed;
        (r.collided, r.min_clearance_m, r.tracking_rms_m) = (None, None, None);
        r.error = Some("refused".into());
        r
    }

    #[test]
    fn cells_aggregate_flown_rows_and_skip_failed_ones() {
        let rows = [
            row(0, 0.5, 0.1, false, 0.3, 0.1),
            row(1, 0.5, 0.1, true, -0.02, 0.3),
            row(2, 0.5, 0.1, false, 0.1, 0.2),
            row(3, 1.4, 0.3, false, 0.25, 0.4),
            failed(4, 0.5, 0.1),
            // Only a failed run at (1.4, 0.1): no cell there.
            failed(5, 1.4, 0.1),
        ];
        let mut agg = Aggregator::default();
        for r in &rows {
            agg.add(r);
        }
        assert_eq!((agg.rows(), agg.failed(), agg.collided()), (6, 2, 1));
        let (mu, d1, cells) = agg.aggregate();
        assert_eq!((mu, d1), (vec![0.5, 1.4], vec![0.1, 0.3]));
        let c = cells[0][0].unwrap();
        assert_eq!(c.runs, 3);
        assert!((c.collision_rate - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(c.min_clearance_m, -0.02);
        assert!((c.tracking_rms_m - 0.2).abs() < 1e-12);
        assert_eq!(cells[1][1].map(|c| (c.runs, c.min_clearance_m)), Some((1, 0.25)));
        assert_eq!((cells[0][1], cells[1][0]), (None, None));
    }

    #[test]
    fn too_many_cells_are_not_drawn() {
        let mut agg = Aggregator::default();
        for i in 0..=MAX_AXIS_CELLS as u64 {
            agg.add(&row(i, 0.5 + i as f64, 0.1, false, 0.1, 0.1));
        }
        let dir = std::env::temp_dir().join(format!("parapet-heatmap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (files, warnings) = write_heatmaps(&dir, "s", &agg.aggregate());
        assert!(files.is_empty());
        assert!(warnings[0].contains("101 μ"), "{warnings:?}");
        assert!(!dir.join("heatmap_collision_rate.png").exists());
    }
}
