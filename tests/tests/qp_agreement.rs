//! Issue 11: the closed-form active-set projection agrees with an interior-point
//! QP solver (clarabel, f64) on random CBF-QPs with 1..=K constraints.
//!
//! Problems are built the way the filter builds them: `K` barriers around the
//! vehicle with unit normals `n_i` and offsets `c_i = −(2/μ) n_iᵀṗ`, so the
//! braking input `−(2/μ)ṗ` is feasible and the problem always has an answer.
//!
//! On **every** problem the closed form must be feasible (no constraint violated
//! by more than `1e-4·(1 + |u|)`, f32 round-off) and as cheap as the solver's
//! answer up to the same relative tolerance plus what the f32 data itself leaves
//! open: the offsets `c_i` are f32 numbers known to about `ε·scale`, and the
//! closed form snaps planes that pass through the braking point up to round-off
//! onto it exactly. A change `η` of the data moves the optimum by up to
//! `η / σ_min`, `σ_min` the smallest singular value of any 1–3 of the normals,
//! and its cost by `2|u − u*|·η/σ_min + (η/σ_min)²` (see [`data_cost_slack`]).
//! For three normals at `|det| ≈ 2e-4` that is ~1e-2: a seed once found a case
//! where clarabel's point, 5e-4 from the shared vertex, was cheaper by 3e-4
//! relative — an equally valid answer to a problem differing by f32 round-off.
//! On **well-conditioned** problems
//! (every pair of normals at least ~6° apart, `|n_i × n_j|² ≥ 0.01`, and every
//! triple with `|det| ≥ 0.05`) the minimiser itself must agree:
//! `|u_cf − u_qp| ≤ 1e-4·(1 + |u_qp|)`. For nearly coplanar normals the
//! optimum is ill-conditioned — perturbing the data by f32 round-off moves it
//! by ~ε/det — so no f32 method can meet 1e-4 there; the cost check still holds.

use parapet_core::cbf::MAX_ACTIVE_BARRIERS;
use parapet_core::qp3::{project, HalfSpace};
use parapet_core::Vec3;
use parapet_tests::{proptest_cases, reference_qp};
use proptest::prelude::*;

fn vec3(r: f32) -> impl Strategy<Value = Vec3> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn well_conditioned(cons: &[HalfSpace]) -> bool {
    let k = cons.len();
    for i in 0..k {
        for j in (i + 1)..k {
            if cons[i].n.cross(&cons[j].n).norm_squared() < 0.01 {
                return false;
            }
            for l in (j + 1)..k {
                if cons[i].n.dot(&cons[j].n.cross(&cons[l].n)).abs() < 0.05 {
                    return false;
                }
            }
        }
    }
    true
}

/// Smallest singular value over every subset of 1–3 of the normals (f64).
fn sigma_min(cons: &[HalfSpace]) -> f64 {
    let n: Vec<nalgebra::Vector3<f64>> = cons.iter().map(|h| h.n.cast::<f64>()).collect();
    let mut s = 1.0f64;
    let k = n.len();
    for i in 0..k {
        for j in (i + 1)..k {
            // Rows n_i, n_j: singular values sqrt(1 ± n_iᵀn_j) for unit normals.
            s = s.min(
                nalgebra::Matrix2x3::from_rows(&[n[i].transpose(), n[j].transpose()]).singular_values().min(),
            );
            for l in (j + 1)..k {
                let m = nalgebra::Matrix3::from_rows(&[n[i].transpose(), n[j].transpose(), n[l].transpose()]);
                s = s.min(m.singular_values().min());
            }
        }
    }
    s
}

/// Cost change an f32-sized perturbation of the data can cause at the optimum:
/// data uncertainty `η = 16ε·(max|c_i| + |u_ref| + |u*|)` (offsets rounded to f32,
/// normals rounded and normalised in f32, the closed form's snapping within 4ε),
/// moved through `1/σ_min`.
fn data_cost_slack(cons: &[HalfSpace], u_ref: &Vec3, u_nom: &Vec3, u_qp: &Vec3) -> f64 {
    let scale = cons.iter().fold(0.0f64, |m, h| m.max(f64::from(h.c.abs())))
        + f64::from(u_ref.norm())
        + f64::from(u_nom.norm());
    let du = 16.0 * f64::from(f32::EPSILON) * scale / sigma_min(cons);
    2.0 * f64::from((u_qp - u_nom).norm()) * du + du * du
}

fn cost(u: &Vec3, u_nom: &Vec3) -> f64 {
    (u - u_nom).cast::<f64>().norm_squared()
}

enum Check {
    Agrees,
    SolverFailed,
    Fails(String),
}

/// One CBF-QP built the filter's way (unit normals, planes through the braking
/// point `−(2/μ)v`), solved both ways and compared as the module docs say.
fn check_cbf_problem(normals: &[Vec3], v: &Vec3, u_nom: &Vec3, mu: f32) -> Check {
    let cons: Vec<HalfSpace> = normals
        .iter()
        .map(|n| {
            let n = n.normalize();
            HalfSpace { n, c: -(2.0 / mu) * n.dot(v) }
        })
        .collect();
    let braking = v * (-2.0 / mu);
    let cf = project(u_nom, &cons, &braking);
    let qp = reference_qp::solve(u_nom, &cons);
    if !qp.solved {
        return Check::SolverFailed;
    }
    let tol = 1e-4 * (1.0 + qp.u.norm());
    if !cf.feasible {
        return Check::Fails("closed form says infeasible on a feasible problem".into());
    }
    if let Some(h) = cons.iter().find(|h| h.n.dot(&cf.u) < h.c - tol) {
        return Check::Fails(format!("closed form {} violates {h:?}", cf.u));
    }
    let (c_cf, c_qp) = (cost(&cf.u, u_nom), cost(&qp.u, u_nom));
    let slack = data_cost_slack(&cons, &braking, u_nom, &qp.u);
    if c_cf > c_qp * (1.0 + 1e-4) + 1e-4 + slack {
        return Check::Fails(format!("cost {c_cf} vs solver {c_qp} (data slack {slack})"));
    }
    if well_conditioned(&cons) && (cf.u - qp.u).norm() > tol {
        return Check::Fails(format!(
            "closed form {} vs clarabel {} (diff {})",
            cf.u,
            qp.u,
            (cf.u - qp.u).norm()
        ));
    }
    Check::Agrees
}

/// The case a random seed found (CI, 2026-11): three normals at |det| = 2e-4 sharing
/// the braking point. The closed form returns the shared vertex (the exact optimum
/// of the snapped problem); clarabel, on the unsnapped f32 data, a point 5e-4 away
/// and 3.4e-4 cheaper (relative). Both are answers to the problem up to f32 data.
#[test]
fn near_coplanar_shared_vertex() {
    let normals = [
        Vec3::new(-0.592_641_95, -0.234_577_61, -0.437_690_97),
        Vec3::new(0.978_782_5, 0.874_704_7, 0.051_298_298),
        Vec3::new(0.256_075_98, -0.421_896_67, 0.909_530_2),
    ];
    let (v, u_nom, mu) =
        (Vec3::new(1.854_141_4, 1.638_601_5, 0.0), Vec3::new(-4.158_694_3, 0.0, 0.0), 1.671_140_2);
    match check_cbf_problem(&normals, &v, &u_nom, mu) {
        Check::Agrees => {}
        Check::SolverFailed => panic!("clarabel did not solve"),
        Check::Fails(why) => panic!("{why}"),
    }
    // The closed form's answer is the shared vertex itself.
    let cons: Vec<HalfSpace> = normals
        .iter()
        .map(|n| HalfSpace { n: n.normalize(), c: -(2.0 / mu) * n.normalize().dot(&v) })
        .collect();
    let braking = v * (-2.0 / mu);
    let cf = project(&u_nom, &cons, &braking);
    assert!((cf.u - braking).norm() < 1e-5, "{} vs vertex {}", cf.u, braking);
}

proptest! {
    #![proptest_config(ProptestConfig {
        max_global_rejects: proptest_cases().max(10_000),
        ..ProptestConfig::with_cases(proptest_cases().max(10_000))
    })]

    #[test]
    fn closed_form_matches_interior_point_solver(
        normals in prop::collection::vec(vec3(1.0), 1..=MAX_ACTIVE_BARRIERS),
        v in vec3(2.0), u_nom in vec3(6.0), mu in 0.3f32..2.0,
    ) {
        prop_assume!(normals.iter().all(|n| n.norm() > 0.05));
        match check_cbf_problem(&normals, &v, &u_nom, mu) {
            Check::Agrees => {}
            // An interior-point method needs an interior: when every constraint passes through
            // the braking point with normals in one plane, the feasible set can be a line and
            // clarabel may stop short; such problems are skipped (counted as rejects).
            Check::SolverFailed => prop_assume!(false, "clarabel did not solve"),
            Check::Fails(why) => prop_assert!(false, "{}", why),
        }
    }

    /// Arbitrary (possibly infeasible) well-conditioned half-spaces: when clarabel finds
    /// a feasible point, the closed form is feasible with the same minimiser; when the
    /// closed form says infeasible, so does the solver.
    #[test]
    fn arbitrary_half_spaces(
        normals in prop::collection::vec((vec3(1.0), -3.0f32..3.0), 1..=MAX_ACTIVE_BARRIERS),
        u_nom in vec3(6.0),
    ) {
        prop_assume!(normals.iter().all(|(n, _)| n.norm() > 0.05));
        let cons: Vec<HalfSpace> = normals.iter().map(|(n, c)| HalfSpace { n: n.normalize(), c: *c }).collect();
        prop_assume!(well_conditioned(&cons));
        let cf = project(&u_nom, &cons, &Vec3::zeros());
        let qp = reference_qp::solve(&u_nom, &cons);
        let qp_feasible = qp.solved && cons.iter().all(|h| h.n.dot(&qp.u) >= h.c - 1e-4);
        if qp_feasible {
            prop_assert!(cf.feasible);
            prop_assert!((cf.u - qp.u).norm() <= 1e-4 * (1.0 + qp.u.norm()), "{} vs {}", cf.u, qp.u);
        }
        if !cf.feasible {
            prop_assert!(!qp_feasible);
        }
    }
}
