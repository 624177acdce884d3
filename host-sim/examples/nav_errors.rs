//! The navigation filter against the truth (issue 39, `docs/navigation.md`): fly a scene with
//! a position source and print, per flight, the RMS and max position/velocity error of the
//! filter's estimate and of the "latest fix extrapolated" (`p_fix + ṗ_fix·age`, what the
//! controller flew before the filter), the failsafe states seen, collision and goal.
//!
//! ```sh
//! cargo run --release -p parapet-sim --example nav_errors -- SCENE PATH SOURCE SPEED SEED [PERCEPTION] [DROPOUT_START DROPOUT_LENGTH] [guidance=NAME]
//! ```
//! PERCEPTION: `truth` or a `--perception` preset (`lidar`); `guidance=paper|trajectory`
//! (anywhere after SEED) sets `MIS_GUIDANCE`. Output: one tab-separated line.

#[macro_use]
mod common;

use std::collections::BTreeSet;
use std::path::Path;

use anyhow::{anyhow, Result};
use nalgebra::Vector3;
use parapet_core::obstacle::ObstaclePoint;
use parapet_sim::fc::control::Controller;
use parapet_sim::flight::runner::{default_duration, default_yaw_mode, run_with, RunConfig};
use parapet_sim::flight::stack::{clock_us, FlightStack, OuterOut};
use parapet_sim::plan::pathfile::PathFile;
use parapet_sim::sim::sensors::PositionReading;
use parapet_sim::world::scene::{to_f64, Scene};

type Est = Option<(Vector3<f64>, Vector3<f64>)>;

struct Recorder {
    c: Controller,
    last_fix: Option<PositionReading>,
    est: Vec<(Est, Est)>,
    states: BTreeSet<String>,
}

impl FlightStack for Recorder {
    fn start(&mut self, s: &parapet_sim::flight::stack::StackStart<'_>) -> Result<()> {
        self.last_fix = Some(s.fix);
        self.c.start(s)
    }
    fn position_fix(&mut self, fix: PositionReading) {
        self.last_fix = Some(fix);
        self.c.position_fix(fix);
    }
    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        let out = self.c.outer(t, obstacles);
        let nav = self.c.nav().and_then(|n| n.estimate(clock_us(t))).map(|(p, v)| (to_f64(&p), to_f64(&v)));
        let base = self.last_fix.filter(|f| t - f.t_measured <= 0.2).map(|f| {
            let age = t - f.t_measured;
            (f.position + f.velocity * age, f.velocity)
        });
        self.est.push((nav, base));
        self.states.insert(self.c.state_name());
        out
    }
    forward_to_controller!();
}

/// RMS and max of the position and velocity errors (m, m/s) over the steps with an estimate,
/// and the fraction of steps with one.
fn stats(errs: &[(f64, f64)], n: usize) -> String {
    if errs.is_empty() {
        return "-\t-\t-\t-\t0.00".into();
    }
    let k = errs.len() as f64;
    let rms = |f: fn(&(f64, f64)) -> f64| (errs.iter().map(|e| f(e) * f(e)).sum::<f64>() / k).sqrt();
    let max = |f: fn(&(f64, f64)) -> f64| errs.iter().map(f).fold(0.0, f64::max);
    format!(
        "{:.3}\t{:.3}\t{:.3}\t{:.3}\t{:.2}",
        rms(|e| e.0),
        max(|e| e.0),
        rms(|e| e.1),
        max(|e| e.1),
        k / n.max(1) as f64
    )
}

fn main() -> Result<()> {
    let all: Vec<String> = std::env::args().skip(1).collect();
    let guidance = all.iter().find_map(|x| x.strip_prefix("guidance="));
    let a: Vec<&String> = all.iter().filter(|x| !x.starts_with("guidance=")).collect();
    if a.len() < 5 {
        return Err(anyhow!(
            "usage: SCENE PATH SOURCE SPEED SEED [PERCEPTION] [DROPOUT_START DROPOUT_LENGTH]"
        ));
    }
    let scene = Scene::load(Path::new(a[0])).map_err(|e| anyhow!("{e}"))?;
    let path = PathFile::read(Path::new(a[1])).map_err(|e| anyhow!("{e}"))?;
    let wps: Vec<Vector3<f64>> =
        path.waypoints.iter().map(|w| Vector3::new(w[1] as f64, w[0] as f64, -(w[2] as f64))).collect();
    let mut cfg = RunConfig::for_scene(&scene, wps)?;
    cfg.sensors.position_source = a[2].parse().map_err(|()| anyhow!("unknown source {}", a[2]))?;
    cfg.sensors.apply_source_preset(&[]);
    cfg.params.speed = a[3].parse()?;
    cfg.seed = a[4].parse()?;
    if let Some(g) = guidance {
        cfg.guidance = g.parse().map_err(|()| anyhow!("unknown guidance {g}"))?;
    }
    if let Some(p) = a.get(5).filter(|p| p.as_str() != "truth") {
        cfg.perception = parapet_sim::sim::range::preset(p);
        cfg.yaw_mode = default_yaw_mode(cfg.perception.as_deref());
    }
    if let (Some(s), Some(l)) = (a.get(6), a.get(7)) {
        cfg.sensors.dropout_start = s.parse()?;
        cfg.sensors.dropout_length = l.parse()?;
    }
    cfg.duration = default_duration(&scene, &cfg.path, cfg.params.speed);
    let cbf = cfg.cbf_params()?;
    let c = Controller::new(&scene, &cfg, cbf)?;
    let mut rec = Recorder { c, last_fix: None, est: Vec::new(), states: BTreeSet::new() };
    let out = run_with(&scene, &cfg, &mut rec, &mut |_| {})?;
    let (mut nav, mut base) = (Vec::new(), Vec::new());
    for (s, (n, b)) in out.samples.iter().zip(&rec.est) {
        if let Some((p, v)) = n {
            nav.push(((p - s.pos).norm(), (v - s.vel).norm()));
        }
        if let Some((p, v)) = b {
            base.push(((p - s.pos).norm(), (v - s.vel).norm()));
        }
    }
    let n = out.samples.len();
    let st = rec.c.nav().map(|n| n.status());
    let states: Vec<&str> = rec.states.iter().map(String::as_str).collect();
    println!(
        "{}\t{}\t{}\t{}\tnav\t{}\tlatest-fix\t{}\tcollided={}\tmin_clearance={:.3}\tgoal={}\tend={}@{:.1}s\tto_goal={:.2}m\tvmax={:.2}\tstates={}\tgated={}\tresets={}",
        scene.name,
        a[2],
        a[3],
        a[4],
        stats(&nav, n),
        stats(&base, n),
        out.summary.collided,
        out.summary.min_clearance_m,
        out.summary.reached_goal,
        out.summary.end_reason,
        out.summary.sim_time_s,
        out.summary.final_distance_to_goal_m,
        out.samples.iter().map(|s| s.vel.norm()).fold(0.0, f64::max),
        states.join(","),
        st.map_or(0, |s| s.gated),
        st.map_or(0, |s| s.resets),
    );
    Ok(())
}
