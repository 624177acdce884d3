//! The report's plots (SVG and PNG): the top view (planned and flown paths, obstacles, range
//! returns), clearance over time, speed over time with its limit, and filter activity, drawn
//! with plotters in the file frame ENU.
//!
//! Owns the drawing only; the records it draws are [`super::RunRecord`]'s.
//! May import: what [`super`] may (parapet-core, [`crate::world`], plotters).

use std::path::{Path, PathBuf};

use anyhow::Result;
use nalgebra::Vector3;
use parapet_core::obstacle::Shape;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::{e, RunRecord};
use crate::world::scene::{ned_to_enu_arr, to_f64};

/// Fill of unmapped static obstacles in the top view (`mapped = false`).
const UNMAPPED_FILL: RGBColor = RGBColor(230, 210, 60);

pub(super) fn plot_both(dir: &Path, name: &str, rec: &RunRecord) -> Result<Vec<PathBuf>> {
    let (w, h) = plot_size(name, rec);
    let svg = dir.join(format!("{name}.svg"));
    {
        let root = SVGBackend::new(&svg, (w, h)).into_drawing_area();
        draw_any(name, &root, rec)?;
        root.present().map_err(e)?;
    }
    let png = dir.join(format!("{name}.png"));
    {
        let root = BitMapBackend::new(&png, (w, h)).into_drawing_area();
        draw_any(name, &root, rec)?;
        root.present().map_err(e)?;
    }
    Ok(vec![svg, png])
}

fn draw_any<DB: DrawingBackend>(name: &str, root: &DrawingArea<DB, Shift>, rec: &RunRecord) -> Result<()>
where
    DB::ErrorType: 'static,
{
    match name {
        "top_view" => draw_top_view_any(root, rec),
        "clearance" => draw_clearance_any(root, rec),
        "speed" => draw_speed_any(root, rec),
        _ => draw_filter_activity_any(root, rec),
    }
}

fn plot_size(name: &str, rec: &RunRecord) -> (u32, u32) {
    if name == "top_view" {
        let (mn, mx) = rec.scene.bounds_enu;
        let (dx, dy) = ((mx[0] - mn[0]).max(0.1), (mx[1] - mn[1]).max(0.1));
        let w = 1000.0;
        let h = (w * dy / dx).clamp(300.0, 1400.0) + 60.0;
        (w as u32, h as u32)
    } else {
        (1000, 400)
    }
}

/// Height of the top of a shape above the ground, m.
fn top_height(shape: &Shape) -> f64 {
    match shape {
        Shape::Point { center } => -center[2] as f64,
        Shape::Sphere { center, radius } => -(center[2] - radius) as f64,
        Shape::Box { min, .. } => -min[2] as f64,
        Shape::Cylinder { base, height, .. } => -(base[2] - height) as f64,
    }
}

/// Outline of a shape's top view (ENU x, y), closed polygon.
fn outline(shape: &Shape) -> Vec<(f64, f64)> {
    let circle = |c: Vector3<f64>, r: f64| -> Vec<(f64, f64)> {
        let c = ned_to_enu_arr(&c);
        (0..=48)
            .map(|k| {
                let a = k as f64 / 48.0 * std::f64::consts::TAU;
                (c[0] + r * a.cos(), c[1] + r * a.sin())
            })
            .collect()
    };
    match shape {
        Shape::Point { center } => circle(to_f64(&(*center).into()), 0.02),
        Shape::Sphere { center, radius } => circle(to_f64(&(*center).into()), *radius as f64),
        Shape::Cylinder { base, radius, .. } => circle(to_f64(&(*base).into()), *radius as f64),
        Shape::Box { min, max } => {
            let a = ned_to_enu_arr(&to_f64(&(*min).into()));
            let b = ned_to_enu_arr(&to_f64(&(*max).into()));
            let (x0, x1) = (a[0].min(b[0]), a[0].max(b[0]));
            let (y0, y1) = (a[1].min(b[1]), a[1].max(b[1]));
            vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
        }
    }
}

fn draw_top_view_any<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, rec: &RunRecord) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(e)?;
    let (mn, mx) = rec.scene.bounds_enu;
    let title = format!(
        "{} — {} (planned green, flown blue{}{}; light grey: below flight level{})",
        rec.summary.scene,
        rec.summary.filter,
        if rec.ranges.is_empty() { "" } else { ", orange: range returns" },
        if rec.scene.unmapped_count() == 0 { "" } else { ", yellow: unmapped" },
        if rec.summary.collided { ", collision ×" } else { "" }
    );
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(mn[0]..mx[0], mn[1]..mx[1])
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("east x [m]")
        .y_desc("north y [m]")
        .light_line_style(WHITE)
        .draw()
        .map_err(e)?;
    let t_end = rec.samples.last().map(|s| s.t).unwrap_or(0.0);
    for o in &rec.scene.obstacles {
        let moving = !o.is_static();
        // Obstacles whose top is below the start height (desks, low furniture) are
        // drawn lighter: the vehicle may fly over them.
        let low = top_height(&o.shape) < -rec.scene.start.z - rec.scene.vehicle.hull_radius;
        let fill = match (moving, low, o.mapped) {
            (true, _, _) => RGBColor(230, 160, 160),
            // Unmapped (not in the map the path was planned on): yellow, as on the replay page.
            (false, _, false) => UNMAPPED_FILL,
            (false, true, true) => RGBColor(215, 215, 215),
            (false, false, true) => RGBColor(160, 160, 160),
        };
        if moving {
            // Track of its reference point, faint poses every 1/6 of the run, the
            // pose at the end, and (solid) the pose at the closest approach to the
            // vehicle together with the vehicle's hull circle at that instant.
            let track: Vec<(f64, f64)> = (0..=50)
                .map(|k| {
                    let c = crate::world::scene::reference_point(&o.at(t_end * k as f64 / 50.0).0);
                    let a = ned_to_enu_arr(&c);
                    (a[0], a[1])
                })
                .collect();
            chart.draw_series(std::iter::once(PathElement::new(track, fill.stroke_width(1)))).map_err(e)?;
            for k in 0..=6 {
                let pose = outline(&o.at(t_end * k as f64 / 6.0).0);
                chart.draw_series(std::iter::once(Polygon::new(pose, fill.mix(0.3).filled()))).map_err(e)?;
            }
            let pf = |v: &Vector3<f64>| crate::world::scene::to_f32(v);
            let closest = rec.samples.iter().min_by(|a, b| {
                let da = o.at(a.t).0.signed_distance(&pf(&a.pos));
                let db = o.at(b.t).0.signed_distance(&pf(&b.pos));
                da.total_cmp(&db)
            });
            if let Some(k) = closest {
                let pose = outline(&o.at(k.t).0);
                chart.draw_series(std::iter::once(Polygon::new(pose, fill.filled()))).map_err(e)?;
                let hull = outline(&Shape::sphere(pf(&k.pos), rec.scene.vehicle.hull_radius as f32));
                chart
                    .draw_series(std::iter::once(PathElement::new(hull, BLUE.stroke_width(1))))
                    .map_err(e)?;
            }
        } else {
            chart.draw_series(std::iter::once(Polygon::new(outline(&o.shape), fill.filled()))).map_err(e)?;
            if !o.mapped {
                let mut edge = outline(&o.shape);
                edge.extend(edge.first().copied());
                chart
                    .draw_series(std::iter::once(PathElement::new(edge, BLACK.stroke_width(1))))
                    .map_err(e)?;
            }
        }
    }
    let to2 = |v: &Vector3<f64>| {
        let a = ned_to_enu_arr(v);
        (a[0], a[1])
    };
    let green = RGBColor(0, 160, 0);
    chart
        .draw_series(std::iter::once(PathElement::new(
            rec.path.iter().map(to2).collect::<Vec<_>>(),
            green.stroke_width(2),
        )))
        .map_err(e)?;
    chart.draw_series(rec.path.iter().map(|p| Circle::new(to2(p), 3, green.filled()))).map_err(e)?;
    chart
        .draw_series(std::iter::once(PathElement::new(
            rec.samples.iter().map(|s| to2(&s.pos)).collect::<Vec<_>>(),
            BLUE.stroke_width(2),
        )))
        .map_err(e)?;
    // Range returns (`--perception`): at most ~20 000 dots, every k-th return, orange.
    let hits: Vec<[f32; 3]> = rec.ranges.iter().filter_map(|r| r.point).collect();
    if !hits.is_empty() {
        let k = hits.len().div_ceil(20_000);
        let orange = RGBColor(240, 140, 0).mix(0.5);
        chart
            .draw_series(
                hits.iter().step_by(k).map(|p| Circle::new((p[1] as f64, p[0] as f64), 1, orange.filled())),
            )
            .map_err(e)?;
    }
    if let Some(t) = rec.summary.first_collision_time_s {
        if let Some(s) = rec.samples.iter().find(|s| s.t >= t).or(rec.samples.last()) {
            chart.draw_series(std::iter::once(Cross::new(to2(&s.pos), 8, RED.stroke_width(3)))).map_err(e)?;
        }
    }
    let (s, g) = (to2(&rec.scene.start), to2(&rec.scene.goal));
    chart.draw_series(std::iter::once(TriangleMarker::new(s, 8, BLACK.filled()))).map_err(e)?;
    chart.draw_series(std::iter::once(Circle::new(g, 8, BLACK.stroke_width(2)))).map_err(e)?;
    Ok(())
}

fn time_range(rec: &RunRecord) -> std::ops::Range<f64> {
    0.0..rec.samples.last().map(|s| s.t).unwrap_or(1.0).max(1e-3)
}

fn draw_clearance_any<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, rec: &RunRecord) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(e)?;
    let finite = |x: f64| if x.is_finite() { x } else { 5.0 };
    let ymax = rec
        .samples
        .iter()
        .map(|s| finite(s.clearance).max(finite(s.ref_clearance)))
        .fold(0.5f64, f64::max)
        .min(5.0);
    let ymin = rec.samples.iter().map(|s| finite(s.clearance)).fold(-0.05f64, f64::min);
    let mut chart = ChartBuilder::on(root)
        .caption(
            "Clearance (distance to nearest surface − hull radius): flown blue, planned green; bound 0 red",
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(time_range(rec), ymin..ymax * 1.05)
        .map_err(e)?;
    chart.configure_mesh().x_desc("t [s]").y_desc("clearance [m]").draw().map_err(e)?;
    let tr = time_range(rec);
    chart
        .draw_series(LineSeries::new(vec![(tr.start, 0.0), (tr.end, 0.0)], RED.stroke_width(2)))
        .map_err(e)?;
    chart
        .draw_series(LineSeries::new(
            rec.samples.iter().map(|s| (s.t, finite(s.ref_clearance).min(ymax * 1.05))),
            RGBColor(0, 160, 0),
        ))
        .map_err(e)?;
    chart
        .draw_series(LineSeries::new(
            rec.samples.iter().map(|s| (s.t, finite(s.clearance).min(ymax * 1.05))),
            BLUE.stroke_width(2),
        ))
        .map_err(e)?;
    Ok(())
}

fn draw_filter_activity_any<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, rec: &RunRecord) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(root)
        .caption(
            "Filter activity: region (0 none, 1 far D_δ1, 2 nominal safe D_u*, 3 filtering D_⊥, 4 fault); red = intervened",
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(40)
        .build_cartesian_2d(time_range(rec), -0.5f64..4.5f64)
        .map_err(e)?;
    chart.configure_mesh().x_desc("t [s]").y_desc("region").draw().map_err(e)?;
    let pts: Vec<(f64, f64)> = rec.samples.iter().map(|s| (s.t, s.filter.region.code() as f64)).collect();
    chart.draw_series(LineSeries::new(pts, BLUE)).map_err(e)?;
    chart
        .draw_series(
            rec.samples
                .iter()
                .filter(|s| s.filter.intervened)
                .map(|s| Rectangle::new([(s.t, -0.45), (s.t + 0.004, -0.1)], RED.filled())),
        )
        .map_err(e)?;
    Ok(())
}

/// The reference's speed at each sample, m/s: its displacement over the time since the
/// previous sample (0 at the first), horizontal and vertical together.
/// (A repeated time gives 0.)
fn reference_speeds(samples: impl ExactSizeIterator<Item = (f64, Vector3<f64>)>) -> Vec<f64> {
    let mut out = Vec::with_capacity(samples.len());
    let mut prev: Option<(f64, Vector3<f64>)> = None;
    for (t, pos) in samples {
        let v = match prev {
            Some((t0, p0)) if t > t0 => (pos - p0).norm() / (t - t0),
            _ => 0.0,
        };
        out.push(v);
        prev = Some((t, pos));
    }
    out
}

/// Speed against time (issue 35): the flown speed, the reference's, and the mission's cruise
/// speed (`summary.params.speed`, the guidance's limit).
fn draw_speed_any<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, rec: &RunRecord) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(e)?;
    let cruise = rec.summary.params.speed;
    let refs = reference_speeds(rec.samples.iter().map(|s| (s.t, s.ref_pos)));
    let flown_max = rec.samples.iter().map(|s| s.vel.norm()).fold(0.0f64, f64::max);
    let ymax = flown_max.max(cruise).max(0.1) * 1.15;
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!("Speed: flown blue, reference green; cruise (mission speed) {cruise} m/s red"),
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(time_range(rec), 0.0..ymax)
        .map_err(e)?;
    chart.configure_mesh().x_desc("t [s]").y_desc("speed [m/s]").draw().map_err(e)?;
    let tr = time_range(rec);
    chart
        .draw_series(LineSeries::new(vec![(tr.start, cruise), (tr.end, cruise)], RED.stroke_width(2)))
        .map_err(e)?;
    chart
        .draw_series(LineSeries::new(
            rec.samples.iter().zip(&refs).map(|(s, v)| (s.t, v.min(ymax))),
            RGBColor(0, 160, 0),
        ))
        .map_err(e)?;
    chart
        .draw_series(LineSeries::new(rec.samples.iter().map(|s| (s.t, s.vel.norm())), BLUE.stroke_width(2)))
        .map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_speed_is_displacement_over_time() {
        let pts = [(0.0, Vector3::zeros()), (0.5, Vector3::new(3.0, 4.0, 0.0)), (0.5, Vector3::zeros())];
        assert_eq!(reference_speeds(pts.into_iter()), vec![0.0, 10.0, 0.0]);
    }
}
