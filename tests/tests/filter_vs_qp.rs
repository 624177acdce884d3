//! Issue 9: on the `cbf_filter` benchmark's problems, both outputs satisfy the
//! constraints they enforce, the closed form equals the CBF-QP on the set it
//! enforces, and the distance to the all-K CBF-QP is reported.
//!
//! Checks, for K = 1, 4, 16, 32 and 300 problems each (obstacles in the forward
//! sector, where the all-K QP has an interior; see `bench_states`):
//! * `Multi` violates none of its enforced constraints (8) (f32 round-off: 1e-4·(1+|u|));
//! * its cost |u − u*|² is no larger than the QP's on the same constraint set (it is
//!   the exact minimiser), and the minimisers agree to 1e-3 m/s²;
//! * `Paper` satisfies the closest obstacle's constraint whenever that barrier is near;
//! * clarabel solves every all-K QP and its answer violates no constraint (1e-6);
//! * more enforced constraints never cost less: cost(QP all K) ≥ cost(QP same set) − tol.
//!
//! `cargo test -p parapet-tests --test filter_vs_qp -- --nocapture` prints the agreement table.

use parapet_core::cbf::FilterVariant;
use parapet_tests::bench_states::{
    agreement, agreement_table, all_constraints, enforced_constraints, filter, max_violation, problems,
    FORWARD_HALF_ANGLE_DEG, KS,
};
use parapet_tests::reference_qp;

const N: usize = 300;
const SEED: u64 = 99;

fn cost(u: &parapet_core::Vec3, u_nom: &parapet_core::Vec3) -> f64 {
    (u - u_nom).cast::<f64>().norm_squared()
}

#[test]
fn multi_is_the_exact_qp_on_what_it_enforces() {
    let f = filter(FilterVariant::Multi);
    let mut intervened = 0;
    for &k in &KS {
        for (i, pr) in problems(k, N, SEED, FORWARD_HALF_ANGLE_DEG).iter().enumerate() {
            let enforced = enforced_constraints(&f, pr);
            let (u, d) = f.apply(&pr.p, &pr.v, &pr.u_nom, &pr.obstacles);
            assert_eq!(d.n_constraints as usize, enforced.len(), "K {k} problem {i}");
            intervened += d.intervened as usize;
            let tol = 1e-4 * (1.0 + u.norm());
            assert!(max_violation(&u, &enforced) <= tol, "K {k} problem {i}: violates an enforced (8)");
            if enforced.is_empty() {
                assert_eq!(u, pr.u_nom);
                continue;
            }
            let qp = reference_qp::solve(&pr.u_nom, &enforced);
            assert!(qp.solved, "K {k} problem {i}: clarabel failed");
            let (c, cq) = (cost(&u, &pr.u_nom), cost(&qp.u, &pr.u_nom));
            assert!(c <= cq * (1.0 + 1e-4) + 1e-4, "K {k} problem {i}: cost {c} > QP {cq}");
            assert!((u - qp.u).norm() <= 1e-3 * (1.0 + qp.u.norm()), "K {k} problem {i}: {u} vs {}", qp.u);
        }
    }
    // The problems are meant to exercise the filter: a fair share must need a correction.
    assert!(intervened > KS.len() * N / 5, "only {intervened} interventions");
}

#[test]
fn paper_and_the_all_k_qp_satisfy_their_constraints() {
    let paper = filter(FilterVariant::Paper);
    let multi = filter(FilterVariant::Multi);
    for &k in &KS {
        for (i, pr) in problems(k, N, SEED + 1, FORWARD_HALF_ANGLE_DEG).iter().enumerate() {
            let (u, _) = paper.apply(&pr.p, &pr.v, &pr.u_nom, &pr.obstacles);
            let closest = pr
                .obstacles
                .iter()
                .filter_map(|o| paper.barrier(&pr.p, &pr.v, o))
                .min_by(|a, b| a.dist_sq.total_cmp(&b.dist_sq))
                .expect("k ≥ 1 obstacles, none at zero distance");
            if closest.h <= paper.params.delta1 {
                assert!(closest.constraint.violation(&u) <= 1e-4 * (1.0 + u.norm()), "K {k} problem {i}");
            }
            let all = all_constraints(&multi, pr);
            let qp = reference_qp::solve(&pr.u_nom, &all);
            assert!(qp.solved, "K {k} problem {i}: clarabel failed");
            assert!(max_violation(&qp.u, &all) <= 1e-6 * (1.0 + qp.u.norm()), "K {k} problem {i}");
            let enforced = enforced_constraints(&multi, pr);
            let same =
                if enforced.is_empty() { pr.u_nom } else { reference_qp::solve(&pr.u_nom, &enforced).u };
            assert!(
                cost(&qp.u, &pr.u_nom) >= cost(&same, &pr.u_nom) * (1.0 - 1e-4) - 1e-4,
                "K {k} problem {i}"
            );
        }
    }
}

#[test]
fn agreement_table_is_consistent() {
    let rows: Vec<_> =
        KS.iter().map(|&k| agreement(k, &problems(k, N, SEED + 2, FORWARD_HALF_ANGLE_DEG))).collect();
    println!("{}", agreement_table(&rows));
    for a in &rows {
        assert!(a.multi_max_violation_enforced <= 1e-3, "K {}: {}", a.k, a.multi_max_violation_enforced);
        assert!(a.multi_vs_qp_same_max <= 1e-2, "K {}: {}", a.k, a.multi_vs_qp_same_max);
        assert_eq!(a.qp_solved, 1.0, "K {}", a.k);
        // With one obstacle there is nothing the multi filter leaves out but a far barrier.
        assert!(a.multi_intervened > 0.2 && a.paper_intervened > 0.2, "K {}: too few interventions", a.k);
    }
    assert_eq!(rows.iter().map(|a| a.n).sum::<usize>(), KS.len() * N);
}
