//! The standard CBF-QP, `min |u − u*|²  s.t.  n_iᵀu ≥ c_i`, solved by the
//! interior-point solver clarabel: the baseline Parapet's closed form is
//! checked against (agreement tests) and timed against (benchmarks).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use parapet_core::qp3::HalfSpace;
use parapet_core::Vec3;

/// Outcome of the reference solver.
#[derive(Debug, Clone, Copy)]
pub struct Reference {
    /// Minimiser, m/s² (f64 solve, rounded to f32).
    pub u: Vec3,
    /// `true` when clarabel reports `Solved`.
    pub solved: bool,
}

/// Solve the CBF-QP with clarabel (tight tolerances).
pub fn solve(u_nom: &Vec3, cons: &[HalfSpace]) -> Reference {
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-10)
        .tol_gap_rel(1e-10)
        .tol_feas(1e-10)
        .build()
        .expect("valid clarabel settings");
    solve_with(u_nom, cons, settings)
}

/// Solve the CBF-QP with clarabel's `settings` (the benchmarks time its defaults).
pub fn solve_with(u_nom: &Vec3, cons: &[HalfSpace], settings: DefaultSettings<f64>) -> Reference {
    // ½uᵀPu + qᵀu with P = 2I, q = −2u*; constraints −nᵀu + s = −c, s ≥ 0.
    let p = CscMatrix::<f64>::from(&[[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]);
    let q: Vec<f64> = u_nom.iter().map(|x| -2.0 * f64::from(*x)).collect();
    let rows: Vec<[f64; 3]> = cons.iter().map(|h| [-h.n.x as f64, -h.n.y as f64, -h.n.z as f64]).collect();
    let a = CscMatrix::<f64>::from(&rows);
    let b: Vec<f64> = cons.iter().map(|h| -f64::from(h.c)).collect();
    let cones = [SupportedConeT::NonnegativeConeT(cons.len())];
    let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings).expect("well-formed QP");
    solver.solve();
    let x = &solver.solution.x;
    Reference {
        u: Vec3::new(x[0] as f32, x[1] as f32, x[2] as f32),
        solved: matches!(solver.solution.status, SolverStatus::Solved | SolverStatus::AlmostSolved),
    }
}
