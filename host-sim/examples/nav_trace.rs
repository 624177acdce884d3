//! One campaign flight with a filtered position source traced against the truth (issue 39,
//! `docs/robustness.md` § Position sources): the estimation error (3-D), the σ of the mapped
//! obstacles' margin (`NavAid::world_sigma`), the filter's σ per axis and its resets, and the
//! safety filter's `unavoidable` flag, around the contact or the smallest clearance.
//!
//! ```sh
//! cargo run --release -p parapet-sim --example nav_trace -- CAMPAIGN.toml FLIGHT [LAST_S]
//! ```
//! Prints the flight's outcome, the largest error over the flight in margin σ (horizontal,
//! vertical, along the nearest mapped point's direction), then one line per 0.1 s of the last
//! `LAST_S` seconds (default 1) before the end.

#[macro_use]
mod common;

use anyhow::{anyhow, Result};
use nalgebra::Vector3;
use parapet_core::obstacle::ObstaclePoint;
use parapet_sim::campaign::flight_config;
use parapet_sim::campaign::spec::Campaign;
use parapet_sim::fc::control::Controller;
use parapet_sim::flight::runner::run_with;
use parapet_sim::flight::sensing::ErrorBound;
use parapet_sim::flight::stack::{clock_us, FlightStack, OuterOut};
use parapet_sim::sim::sensors::PositionReading;
use parapet_sim::world::scene::to_f64;

/// What the controller had at one outer step.
struct Step {
    est: Option<Vector3<f64>>,
    bound: ErrorBound,
    sigma_p: Vector3<f64>,
    resets: u32,
    /// Unit direction from the estimate to the nearest (margin-shifted) obstacle point.
    towards: Option<Vector3<f64>>,
    /// Its distance from the estimate, m.
    dist: f64,
}

struct Recorder {
    c: Controller,
    steps: Vec<Step>,
    /// Every fix: time measured, position.
    fixes: Vec<(f64, Vector3<f64>)>,
}

impl FlightStack for Recorder {
    fn start(&mut self, s: &parapet_sim::flight::stack::StackStart<'_>) -> Result<()> {
        self.c.start(s)
    }
    fn position_fix(&mut self, fix: PositionReading) {
        self.fixes.push((fix.t_measured, fix.position));
        self.c.position_fix(fix);
    }
    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        let nav = self.c.nav();
        let est = nav.and_then(|n| n.estimate(clock_us(t))).map(|(p, _)| to_f64(&p));
        let near = est.and_then(|e| {
            obstacles.iter().map(|o| to_f64(&o.point) - e).min_by(|a, b| a.norm().total_cmp(&b.norm()))
        });
        self.steps.push(Step {
            est,
            bound: nav.map_or(ErrorBound { horizontal: 0.0, vertical: 0.0 }, |n| n.error_bound(clock_us(t))),
            sigma_p: nav.map_or(Vector3::zeros(), |n| to_f64(&n.status().sigma_p)),
            resets: nav.map_or(0, |n| n.status().resets),
            towards: near.map(|d| d / d.norm().max(1e-9)),
            dist: near.map_or(f64::INFINITY, |d| d.norm()),
        });
        self.c.outer(t, obstacles)
    }
    forward_to_controller!();
}

fn main() -> Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let (Some(file), Some(i)) = (a.first(), a.get(1)) else {
        return Err(anyhow!("usage: CAMPAIGN.toml FLIGHT [LAST_S]"));
    };
    let last_s: f64 = a.get(2).map_or(Ok(1.0), |s| s.parse())?;
    let c = Campaign::load(std::path::Path::new(file)).map_err(|e| anyhow!("{e}"))?;
    let i: u64 = i.parse()?;
    let (scene, cfg) = flight_config(&c, i).map_err(|(_, e)| anyhow!("{e}"))?;
    let cbf = cfg.cbf_params()?;
    let mut rec = Recorder { c: Controller::new(&scene, &cfg, cbf)?, steps: Vec::new(), fixes: Vec::new() };
    let out = run_with(&scene, &cfg, &mut rec, &mut |_| {})?;
    let s = &out.summary;
    println!(
        "flight {i} {} {:?}: collided={} with={:?} end={}@{:.2}s min_clearance={:.4} unavoidable_steps={}",
        scene.name,
        cfg.sensors.position_source,
        s.collided,
        s.collision_obstacle,
        s.end_reason,
        s.sim_time_s,
        s.min_clearance_m,
        out.samples.iter().filter(|x| x.filter.unavoidable).count()
    );
    // Largest error over the flight, in margin σ.
    let (mut h, mut v, mut along, mut beyond) = ((0.0f64, 0.0), (0.0f64, 0.0), (0.0f64, 0.0), 0usize);
    for (x, st) in out.samples.iter().zip(&rec.steps) {
        let Some(e) = st.est.map(|p| p - x.pos) else { continue };
        let eh = e.xy().norm() / st.bound.horizontal.max(1e-9);
        if eh > h.0 {
            h = (eh, x.t);
        }
        let ev = e.z.abs() / st.bound.vertical.max(1e-9);
        if ev > v.0 {
            v = (ev, x.t);
        }
        if let Some(u) = st.towards.filter(|_| st.dist < 2.0) {
            let k = -e.dot(&u) / f64::from(st.bound.along(&u.cast::<f32>())).max(1e-9);
            if k > along.0 {
                along = (k, x.t);
            }
            if k > 1.0 {
                beyond += 1;
            }
        }
    }
    println!(
        "max error / its bound: horizontal {:.2} at {:.2}s, vertical {:.2} at {:.2}s, towards the nearest point (within 2 m) {:.2} at {:.2}s; steps beyond the bound there: {beyond}",
        h.0, h.1, v.0, v.1, along.0, along.1
    );
    // The source's error (fix − truth at the time it describes), last 5 fixes.
    let truth_at =
        |t: f64| out.samples.iter().min_by(|a, b| (a.t - t).abs().total_cmp(&(b.t - t).abs())).map(|x| x.pos);
    for (tm, p) in rec.fixes.iter().rev().take(5).rev() {
        if let Some(q) = truth_at(*tm) {
            let d = p - q;
            println!("fix of {tm:.3}s: fix-true ({:.3},{:.3},{:.3})", d.x, d.y, d.z);
        }
    }
    println!("t\ttrue_clear\test-true(x,y,z)\t|e|\tbound(h,v)\tsigma_p(x,y,z)\te_towards/bound\tdist_to_shifted\tresets\tunavoidable\tregion");
    let t_end = out.samples.last().map_or(0.0, |x| x.t);
    let mut next = t_end - last_s;
    for (x, st) in out.samples.iter().zip(&rec.steps) {
        if x.t + 1e-9 < next && x.t < t_end {
            continue;
        }
        next = x.t + 0.1;
        let e = st.est.map_or(Vector3::zeros(), |p| p - x.pos);
        let away =
            st.towards.map_or(0.0, |u| -e.dot(&u) / f64::from(st.bound.along(&u.cast::<f32>())).max(1e-9));
        println!(
            "{:.3}\t{:.4}\t({:.3},{:.3},{:.3})\t{:.3}\t({:.3},{:.3})\t({:.3},{:.3},{:.3})\t{:.2}\t{:.3}\t{}\t{}\t{:?}",
            x.t,
            x.clearance,
            e.x,
            e.y,
            e.z,
            e.norm(),
            st.bound.horizontal,
            st.bound.vertical,
            st.sigma_p.x,
            st.sigma_p.y,
            st.sigma_p.z,
            away,
            st.dist,
            st.resets,
            x.filter.unavoidable,
            x.filter.region
        );
    }
    Ok(())
}
