//! Closed loop of the safety filter on the double integrator `p̈ = u` — the
//! model the CBF guarantee is derived for — with exact zero-order-hold
//! integration, so any violation comes from the filter and the sampling, not
//! from the integrator.

use parapet_core::cbf::{FilterDiagnostics, SafetyFilter};
use parapet_core::obstacle::{ObstaclePoint, Shape};
use parapet_core::Vec3;

/// An obstacle of the closed-loop scenario: a shape moving with constant
/// velocity plus an optional bounded acceleration profile.
#[derive(Clone, Copy, Debug)]
pub struct MovingShape {
    /// Shape at t = 0 (NED, m).
    pub shape: Shape,
    /// Velocity at t = 0, m/s.
    pub velocity: Vec3,
}

/// Result of one closed-loop run.
#[derive(Clone, Copy, Debug)]
pub struct RunResult {
    /// Smallest `h̄_i` of any obstacle over the run (true geometry, variant's velocity), m².
    pub min_h_bar: f32,
    /// Smallest `h̄` of the closest obstacle (the one eq. 14 makes active), m².
    pub min_h_bar_closest: f32,
    /// Smallest squared distance centre → obstacle surface minus δ over the run, m².
    pub min_dist_sq_margin: f32,
    /// Steps on which the filter intervened.
    pub interventions: u32,
    /// Steps on which the filter said `infeasible`.
    pub infeasible_steps: u32,
    /// First step on which the filter said `infeasible` (its problem had no solution).
    pub first_infeasible_step: Option<u32>,
    /// Smallest `h̄_i` of any obstacle up to that step (the whole run when never), m².
    pub min_h_bar_while_feasible: f32,
    /// Largest |u| applied, m/s².
    pub max_u: f32,
}

/// Closest surface points of `obs`, displaced by `state[i].0` and moving at
/// `state[i].1`, seen from `p`.
pub fn observe(obs: &[MovingShape], state: &[(Vec3, Vec3)], p: &Vec3, out: &mut Vec<ObstaclePoint>) {
    out.clear();
    for (i, (o, (pos, vel))) in obs.iter().zip(state).enumerate() {
        let (point, _) = o.shape.translated(*pos).closest_point(p);
        out.push(ObstaclePoint { point, velocity: Some(*vel), id: i as u16, normal: None });
    }
}

/// Fly `steps` steps of `dt` from `(p0, v0)`; the nominal input at each step is
/// `nominal(t, p, v)`. Obstacle `i` starts with its velocity and accelerates with
/// `accel(i, t)`, held constant over each step.
#[allow(clippy::too_many_arguments)]
pub fn fly(
    filter: &SafetyFilter,
    obs: &[MovingShape],
    accel: &dyn Fn(usize, f32) -> Vec3,
    nominal: &dyn Fn(f32, &Vec3, &Vec3) -> Vec3,
    p0: Vec3,
    v0: Vec3,
    dt: f32,
    steps: u32,
) -> RunResult {
    let mut p = p0;
    let mut v = v0;
    let mut pts = Vec::with_capacity(obs.len());
    // Obstacle displacement and velocity; `accel` is constant within a step.
    let mut state: Vec<(Vec3, Vec3)> = obs.iter().map(|o| (Vec3::zeros(), o.velocity)).collect();
    let delta = filter.params.delta;
    let mut r = RunResult {
        min_h_bar: f32::INFINITY,
        min_h_bar_closest: f32::INFINITY,
        min_dist_sq_margin: f32::INFINITY,
        interventions: 0,
        infeasible_steps: 0,
        first_infeasible_step: None,
        min_h_bar_while_feasible: f32::INFINITY,
        max_u: 0.0,
    };
    for k in 0..=steps {
        let t = k as f32 * dt;
        observe(obs, &state, &p, &mut pts);
        let mut closest = (f32::INFINITY, f32::INFINITY); // (|d|², h̄)
        for o in &pts {
            if let Some(b) = filter.barrier(&p, &v, o) {
                r.min_h_bar = r.min_h_bar.min(b.h - delta);
                r.min_dist_sq_margin = r.min_dist_sq_margin.min(b.dist_sq - delta);
                if b.dist_sq < closest.0 {
                    closest = (b.dist_sq, b.h - delta);
                }
            } else {
                r.min_dist_sq_margin = r.min_dist_sq_margin.min(-delta);
                closest = (0.0, -delta);
            }
        }
        r.min_h_bar_closest = r.min_h_bar_closest.min(closest.1);
        if r.first_infeasible_step.is_none() {
            r.min_h_bar_while_feasible = r.min_h_bar;
        }
        if k == steps {
            break;
        }
        let (u, diag): (Vec3, FilterDiagnostics) = filter.apply(&p, &v, &nominal(t, &p, &v), &pts);
        r.interventions += u32::from(diag.intervened);
        r.infeasible_steps += u32::from(diag.infeasible);
        if diag.infeasible && r.first_infeasible_step.is_none() {
            r.first_infeasible_step = Some(k);
        }
        r.max_u = r.max_u.max(u.norm());
        p += v * dt + u * (0.5 * dt * dt);
        v += u * dt;
        for (i, (pos, vel)) in state.iter_mut().enumerate() {
            let a = accel(i, t);
            *pos += *vel * dt + a * (0.5 * dt * dt);
            *vel += a * dt;
        }
    }
    r
}

/// Smallest `h̄_i` over `obs` at t = 0 for the state `(p, v)`.
pub fn initial_min_h_bar(filter: &SafetyFilter, obs: &[MovingShape], p: &Vec3, v: &Vec3) -> f32 {
    let mut pts = Vec::new();
    let state: Vec<(Vec3, Vec3)> = obs.iter().map(|o| (Vec3::zeros(), o.velocity)).collect();
    observe(obs, &state, p, &mut pts);
    pts.iter()
        .map(|o| filter.barrier(p, v, o).map_or(f32::NEG_INFINITY, |b| b.h - filter.params.delta))
        .fold(f32::INFINITY, f32::min)
}
