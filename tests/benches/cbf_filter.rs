//! Closed-form CBF filter against the standard CBF-QP solved by clarabel:
//! `cargo bench -p parapet-tests --bench cbf_filter`.
//!
//! For K = 1, 4, 16, 32 obstacles, the same 256 seeded random problems
//! ([`parapet_tests::bench_states`], obstacles in a ±75° forward sector, where
//! the all-K QP is well posed) are cycled through by every method, so a
//! reported time is the mean cost of one filter step over that mix (about half
//! the problems need an intervention). Methods:
//! * `multi` — `SafetyFilter::apply`, `Multi` variant (exact min-norm over the at
//!   most 4 most critical near barriers);
//! * `paper` — `SafetyFilter::apply`, `Paper` variant (eq. 12 on the closest);
//! * `qp_clarabel` — the CBF-QP with **all K** constraints (8), built and solved
//!   by clarabel with its default settings (as one would in a control loop);
//! * `qp_clarabel_tight` — the same with the reference solver's tight
//!   tolerances (`parapet_tests::reference_qp::solve`, used by the agreement table).
//!
//! Before timing, the agreement tables (constraint satisfaction and distance
//! between the answers on 1000 problems per K, obstacles in the forward sector
//! and all around) are printed.

use std::hint::black_box;

use clarabel::solver::DefaultSettings;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use parapet_core::cbf::FilterVariant;
use parapet_core::qp3::HalfSpace;
use parapet_core::Vec3;
use parapet_tests::bench_states::{
    agreement, agreement_table, all_constraints, filter, problems, ALL_AROUND_DEG, FORWARD_HALF_ANGLE_DEG, KS,
};
use parapet_tests::reference_qp;

/// Seed of the benchmark problems.
const SEED: u64 = 2024;
/// Problems cycled through in the timed loops.
const N_TIMED: usize = 256;
/// Problems in the agreement table.
const N_AGREE: usize = 1000;

/// The CBF-QP `min |u − u*|² s.t. nᵢᵀu ≥ cᵢ` with clarabel's default settings.
fn qp_default(u_nom: &Vec3, cons: &[HalfSpace]) -> Vec3 {
    reference_qp::solve_with(u_nom, cons, DefaultSettings { verbose: false, ..DefaultSettings::default() }).u
}

fn bench_filter(c: &mut Criterion) {
    for (spread, what) in [
        (
            FORWARD_HALF_ANGLE_DEG,
            "obstacles within 75° of the direction of flight (the timed set's distribution)",
        ),
        (ALL_AROUND_DEG, "obstacles all around the vehicle"),
    ] {
        let rows: Vec<_> =
            KS.iter().map(|&k| agreement(k, &problems(k, N_AGREE, SEED + 1, spread))).collect();
        println!(
            "\nAgreement on {N_AGREE} random problems per K, {what} (seed {}):\n{}",
            SEED + 1,
            agreement_table(&rows)
        );
    }

    let multi = filter(FilterVariant::Multi);
    let paper = filter(FilterVariant::Paper);
    let mut group = c.benchmark_group("cbf_filter");
    for &k in &KS {
        let probs = problems(k, N_TIMED, SEED, FORWARD_HALF_ANGLE_DEG);
        let cons: Vec<Vec<HalfSpace>> = probs.iter().map(|pr| all_constraints(&multi, pr)).collect();
        for (name, f) in [("multi", &multi), ("paper", &paper)] {
            let mut i = 0;
            group.bench_function(BenchmarkId::new(name, k), |b| {
                b.iter(|| {
                    let pr = &probs[i % N_TIMED];
                    i += 1;
                    f.apply(
                        black_box(&pr.p),
                        black_box(&pr.v),
                        black_box(&pr.u_nom),
                        black_box(&pr.obstacles),
                    )
                })
            });
        }
        // The QP is given the constraints ready-made: building them is the same work
        // for both methods and is excluded from its time (the filter's time includes it).
        let mut i = 0;
        group.bench_function(BenchmarkId::new("qp_clarabel", k), |b| {
            b.iter(|| {
                let j = i % N_TIMED;
                i += 1;
                qp_default(black_box(&probs[j].u_nom), black_box(&cons[j]))
            })
        });
        let mut i = 0;
        group.bench_function(BenchmarkId::new("qp_clarabel_tight", k), |b| {
            b.iter(|| {
                let j = i % N_TIMED;
                i += 1;
                reference_qp::solve(black_box(&probs[j].u_nom), black_box(&cons[j]))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_filter);
criterion_main!(benches);
