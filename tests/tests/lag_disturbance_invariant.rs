//! The safety invariant of the plant-aware filter (issue 17, `docs/filter.md` §12) on the
//! double integrator with a **first-order actuation lag** and a **bounded disturbance**:
//!
//! `τ ȧ = u − a`, `p̈ = a + d(t)`, `|d| ≤ d_max`, `|ḋ| ≤ d_max / 1 s`,
//!
//! integrated at 1 ms (the lag exactly, zero-order hold on `u`), with the default filter
//! (`multi-relative`) wrapped by [`PlantAware`] at the outer period T = 4 ms, fed the exact
//! position and velocity (the observer has to find `d`). The nominal input is a bounded PD
//! pull towards a goal behind 1–4 spheres plus a random push (|u*| ≤ 4 m/s²). Every case
//! starts at rest with `h̄ ≥ 0` for every sphere (at the predicted state too), and the
//! disturbance ramps in over the first second.
//!
//! Checked throughout the 10 s: `|d|² − δ ≥ −ε` (the hull) and `h̄ ≥ −ε` at the actual
//! state, ε = 0.01 m² (δ = 0.05: 2.2 cm of the 22.4 cm hull radius), up to the first step
//! the filter reports `infeasible` (two spheres on opposite sides with the robust margin).
//!
//! Where ε comes from: the filter keeps `h̄ ≥ 0` for the flat output `ξ = p + τṗ` up to
//! the sampled-data drift (§3, ~10⁻⁵ m² per step) while `|d − d̂| ≤ ē + k_s·spread`; the
//! actual position is `p(t) = ξ(t − τ) + O(τ²|a − u/2|)` (§9), so the hull keeps
//! `√δ − τ²·(|a| + |u|/2)`: ≤ 1.2 cm at τ = 0.108 s, |a|, |u| ≤ 6 m/s² (2·√δ·1.2 cm ≈
//! 0.005 m² in `|d|²`). The observer's ramp error `2ḋ/ω` = 0.05 m/s² at d_max = 0.5 is
//! covered by ē. ε doubles the sum of the two.
//!
//! Cases: `PARAPET_PROPTEST_CASES` (10,000 in `cargo xtask test`, 256 otherwise), fixed seed
//! (deterministic ChaCha): `PARAPET_PROPTEST_CASES=1000000 cargo test --release -p
//! parapet-tests --test lag_disturbance_invariant` for the offline 10⁶. Long runs print their
//! progress to stderr every 50,000 cases; `PARAPET_PROPTEST_FROM=n` checks only the cases
//! from the n-th accepted one on (the same sequence: the first n are generated and their
//! start checked, not flown), so a run stopped at a progress line can be resumed.

use parapet_core::cbf::{CbfParams, FilterVariant, SafetyFilter};
use parapet_core::obstacle::{ObstaclePoint, Shape};
use parapet_core::plant_aware::{lag_time_constant, PlantAware, PlantAwareParams, StepInput};
use parapet_core::Vec3;
use parapet_tests::proptest_cases;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

const EPS: f32 = 0.01;
const DT: f32 = 1e-3;
const OUTER_EVERY: u32 = 4;
const STEPS: u32 = 10_000;
const U_NOM_MAX: f32 = 4.0;
const D_MAX: f32 = 0.5;

#[derive(Clone, Debug)]
struct Case {
    spheres: Vec<(Vec3, f32)>,
    goal: Vec3,
    pushes: Vec<Vec3>,
    d: Vec3,
    tau_scale: f32,
}

fn vec3(r: f32) -> impl Strategy<Value = Vec3> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn case() -> impl Strategy<Value = Case> {
    (
        proptest::collection::vec((vec3(1.5), 0.05f32..0.6), 1..5),
        vec3(1.0),
        proptest::collection::vec(vec3(1.5), 10),
        vec3(1.0),
        prop_oneof![Just(1.0f32), 0.8f32..1.2],
    )
        .prop_map(|(sph, g, pushes, d, tau_scale)| {
            // Spheres ahead (+x) of the start at the origin, the goal behind them.
            let spheres = sph.into_iter().map(|(c, r)| (Vec3::new(1.5 + c.x.abs(), c.y, c.z), r)).collect();
            let n = d.norm();
            let d = if n > D_MAX { d * (D_MAX / n) } else { d };
            Case { spheres, goal: Vec3::new(4.5, g.y, g.z), pushes, d, tau_scale }
        })
}

struct Outcome {
    min_dist: f32,
    min_h_bar: f32,
    min_h_bar_actual: f32,
    infeasible_at: Option<u32>,
}

/// Fly case `c`; `None` when it starts inside a barrier (rejected). With `start_only` only
/// that check is made (the outcome is then all +∞).
fn fly(c: &Case, start_only: bool) -> Option<Outcome> {
    let rp = PlantAwareParams::default();
    let params = CbfParams { sample_time: DT * OUTER_EVERY as f32, gamma: rp.gamma, ..CbfParams::default() };
    let params = CbfParams { accel_bound: params.accel_bound + rp.dob_margin, ..params };
    let filter = SafetyFilter::new(params, FilterVariant::MultiRelative).ok()?;
    let tau_model = lag_time_constant(&parapet_core::attitude::AttitudeParams::default().att_p, rp.motor_tau);
    let tau_true = tau_model * c.tau_scale;
    let mut pa = PlantAware::new(rp, tau_model);
    let shapes: Vec<Shape> = c.spheres.iter().map(|&(q, r)| Shape::sphere(q, r)).collect();
    let (mu, delta) = (params.mu, params.delta);
    let (mut p, mut v, mut a) = (Vec3::zeros(), Vec3::zeros(), Vec3::zeros());
    let observe = |p: &Vec3| -> Vec<ObstaclePoint> {
        shapes.iter().enumerate().map(|(i, s)| ObstaclePoint::fixed(s.closest_point(p).0, i as u16)).collect()
    };
    let min_h = |p: &Vec3, v: &Vec3| -> (f32, f32) {
        let mut out = (f32::INFINITY, f32::INFINITY);
        for o in observe(p) {
            let d = p - o.point;
            out.0 = out.0.min(d.norm_squared() - delta);
            out.1 = out.1.min(d.norm_squared() + mu * d.dot(v) - delta);
        }
        out
    };
    if min_h(&p, &v).1 < 0.0 {
        return None;
    }
    if start_only {
        let inf = f32::INFINITY;
        return Some(Outcome { min_dist: inf, min_h_bar: inf, min_h_bar_actual: inf, infeasible_at: None });
    }
    let (mut min_dist, mut min_h_bar, mut infeasible_at) = (f32::INFINITY, f32::INFINITY, None);
    let mut min_h_bar_actual = f32::INFINITY;
    let mut u = Vec3::zeros();
    let k_lag = 1.0 - (-DT / tau_true).exp();
    for k in 0..STEPS {
        let t = k as f32 * DT;
        if k % OUTER_EVERY == 0 {
            let w = c.pushes[(t as usize).min(c.pushes.len() - 1)];
            let mut u_pd = (c.goal - p) * 1.0 - v * 1.2 + w;
            if u_pd.norm() > U_NOM_MAX {
                u_pd *= U_NOM_MAX / u_pd.norm();
            }
            let obs = observe(&p);
            let input = StepInput {
                now_us: (k as u64) * 1000,
                dt: DT * OUTER_EVERY as f32,
                p,
                v,
                u_pd,
                obstacles: &obs,
                seen_from: None,
                boundaries: false,
                mission_running: false,
            };
            let (_, u_cmd, diag, _) = pa.apply(&filter, &input);
            if diag.infeasible && infeasible_at.is_none() {
                infeasible_at = Some(k);
            }
            u = u_cmd;
        }
        let d = c.d * (t / 1.0).min(1.0);
        a += (u - a) * k_lag;
        let acc = a + d;
        p += v * DT + acc * (0.5 * DT * DT);
        v += acc * DT;
        if infeasible_at.is_none() {
            let (dist, h_actual) = min_h(&p, &v);
            // The barrier of the lag-extended state: at the flat output ξ = p + τṗ,
            // ξ̇ = ṗ + τ(a + d), with the plant's true τ, a and d.
            let xi = p + v * tau_true;
            let xi_dot = v + acc * tau_true;
            let mut h_xi = f32::INFINITY;
            for s in &shapes {
                let dx = xi - s.closest_point(&xi).0;
                h_xi = h_xi.min(dx.norm_squared() + mu * dx.dot(&xi_dot) - delta);
            }
            min_dist = min_dist.min(dist);
            min_h_bar = min_h_bar.min(h_xi);
            min_h_bar_actual = min_h_bar_actual.min(h_actual);
        }
    }
    Some(Outcome { min_dist, min_h_bar, min_h_bar_actual, infeasible_at })
}

#[test]
fn lagged_disturbed_double_integrator_keeps_h_bar_above_minus_eps() {
    let cases = proptest_cases();
    let mut runner = TestRunner::new_with_rng(
        Config { cases, failure_persistence: None, max_global_rejects: cases * 4, ..Config::default() },
        TestRng::deterministic_rng(RngAlgorithm::ChaCha),
    );
    let worst = std::cell::Cell::new((f32::INFINITY, f32::INFINITY, f32::INFINITY));
    let from: u64 = std::env::var("PARAPET_PROPTEST_FROM").ok().and_then(|s| s.parse().ok()).unwrap_or(0);
    let index = std::cell::Cell::new(0u64);
    let result = runner.run(&case(), |c| {
        let i = index.get();
        let Some(o) = fly(&c, i < from) else { return Err(TestCaseError::reject("start inside a barrier")) };
        index.set(i + 1);
        if (i + 1).is_multiple_of(50_000) {
            let w = worst.get();
            eprintln!(
                "[lag_disturbance_invariant] {} cases (from {from}): worst |d|²−δ {} h̄(ξ) {}",
                i + 1,
                w.0,
                w.1
            );
        }
        let w = worst.get();
        let h_xi = if c.tau_scale == 1.0 { o.min_h_bar } else { f32::INFINITY };
        worst.set((w.0.min(o.min_dist), w.1.min(h_xi), w.2.min(o.min_h_bar_actual)));
        // With the model's τ the lag-extended barrier holds; with the plant's τ 20 % off the
        // model's only the hull is claimed (h̄ of the true flat output then dips: −0.056 m²).
        let matched = c.tau_scale == 1.0;
        prop_assert!(
            o.min_dist >= -EPS && (!matched || o.min_h_bar >= -EPS),
            "hull |d|²−δ {} / h̄(ξ) {} < −ε (τ scale {}, infeasible from step {:?})",
            o.min_dist,
            o.min_h_bar,
            c.tau_scale,
            o.infeasible_at
        );
        Ok(())
    });
    let w = worst.get();
    println!(
        "{cases} cases (checked from {from}): worst |d|² − δ = {} m², worst h̄(ξ, ξ̇) (model τ) = {} m², worst h̄(p, ṗ) = {} m² (not claimed)",
        w.0, w.1, w.2
    );
    result.unwrap();
}
