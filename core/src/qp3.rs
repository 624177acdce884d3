//! Exact minimum-norm projection onto a few half-spaces in R³, in closed form.
//!
//! Solves `min |u − u*|²  s.t.  n_iᵀ u ≥ c_i  (i < k)` for `k ≤ MAX_CONSTRAINTS`
//! half-spaces without an iterative solver. The optimum of a strictly convex
//! QP in R³ is the projection of `u*` onto the affine set of at most three
//! linearly independent active constraints (Carathéodory), so enumerating
//! every active set of size 0, 1, 2, 3, solving each in closed form and keeping
//! the KKT-valid candidate of least cost gives the exact answer. Work is fixed
//! in advance: at most `Σ_{s≤3} C(k, s)` candidates (15 for k = 4, 93 for k = 8),
//! each a ≤ 3×3 solve.
//!
//! Degenerate active sets (collinear or coplanar normals, Gram determinant
//! below [`GRAM_EPS`]) are skipped: the same optimum is then reachable through
//! a smaller, independent subset. If no candidate is feasible (the half-spaces
//! do not intersect), the candidate with the smallest maximum violation is
//! returned and flagged `feasible = false`.

use crate::Vec3;
use nalgebra::{Matrix2, Matrix3, Vector2};

/// Maximum number of half-spaces [`project`] accepts; extra ones are ignored.
pub const MAX_CONSTRAINTS: usize = 8;

/// Active sets whose normals' Gram determinant is below this are skipped as degenerate.
pub const GRAM_EPS: f32 = 1e-6;

/// A half-space `nᵀu ≥ c` with unit normal `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfSpace {
    /// Unit normal (NED, dimensionless).
    pub n: Vec3,
    /// Offset, m/s² (`nᵀu ≥ c`).
    pub c: f32,
}

impl HalfSpace {
    /// Violation `max(0, c − nᵀu)` of `u`, m/s².
    #[inline]
    pub fn violation(&self, u: &Vec3) -> f32 {
        (self.c - self.n.dot(u)).max(0.0)
    }
}

/// Result of [`project`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projection {
    /// The minimiser (or least-violation point when infeasible), m/s².
    pub u: Vec3,
    /// `true` when `u` satisfies every half-space (within tolerance).
    pub feasible: bool,
    /// Bit `i` set when constraint `i` is in the chosen active set.
    pub active_mask: u8,
    /// Largest violation of any constraint at `u`, m/s² (0 when feasible).
    pub max_violation: f32,
}

/// Candidate for an active set: `u = u* + Σ λ_j n_j` with `N_Sᵀ u = c_S`.
/// Returns `None` for degenerate sets, else `(u, min λ)`.
fn candidate(u_nom: &Vec3, cons: &[HalfSpace], idx: &[usize]) -> Option<(Vec3, f32)> {
    match *idx {
        [] => Some((*u_nom, 0.0)),
        [i] => {
            let h = &cons[i];
            let lam = h.c - h.n.dot(u_nom);
            Some((u_nom + h.n * lam, lam))
        }
        [i, j] => {
            let (a, b) = (&cons[i], &cons[j]);
            let g = Matrix2::new(1.0, a.n.dot(&b.n), a.n.dot(&b.n), 1.0);
            if g.determinant() < GRAM_EPS {
                return None;
            }
            let rhs = Vector2::new(a.c - a.n.dot(u_nom), b.c - b.n.dot(u_nom));
            let lam = g.try_inverse()? * rhs;
            Some((u_nom + a.n * lam.x + b.n * lam.y, lam.x.min(lam.y)))
        }
        [i, j, k] => {
            let n = Matrix3::from_columns(&[cons[i].n, cons[j].n, cons[k].n]);
            let g = n.transpose() * n;
            if g.determinant() < GRAM_EPS {
                return None;
            }
            let rhs = Vec3::new(
                cons[i].c - cons[i].n.dot(u_nom),
                cons[j].c - cons[j].n.dot(u_nom),
                cons[k].c - cons[k].n.dot(u_nom),
            );
            let lam = g.try_inverse()? * rhs;
            Some((u_nom + n * lam, lam.min()))
        }
        _ => None,
    }
}

/// Minimum-norm correction of `u_nom` onto `{u : n_iᵀu ≥ c_i}` (see module docs).
/// Uses the first [`MAX_CONSTRAINTS`] entries of `cons`. Bounded time, no allocation.
/// Non-finite data yields a non-finite `u` only if the inputs are non-finite:
/// callers validate inputs first (the CBF filter does).
pub fn project(u_nom: &Vec3, cons: &[HalfSpace]) -> Projection {
    let cons = &cons[..cons.len().min(MAX_CONSTRAINTS)];
    let k = cons.len();
    let scale = 1.0 + u_nom.amax() + cons.iter().fold(0.0f32, |m, h| m.max(h.c.abs()));
    let tol = 1e-5 * scale;
    let max_viol = |u: &Vec3| cons.iter().fold(0.0f32, |m, h| m.max(h.violation(u)));

    let mut best: Option<(Vec3, f32, u8)> = None; // (u, cost, mask) among KKT-valid feasible points
    let mut least_bad: (Vec3, f32, u8) = (*u_nom, max_viol(u_nom), 0); // least violation
    let mut consider = |idx: &[usize]| {
        if let Some((u, lam_min)) = candidate(u_nom, cons, idx) {
            if !(u.x.is_finite() && u.y.is_finite() && u.z.is_finite()) {
                return;
            }
            let mask = idx.iter().fold(0u8, |m, &i| m | (1 << i));
            let viol = max_viol(&u);
            if viol < least_bad.1 {
                least_bad = (u, viol, mask);
            }
            if lam_min >= -tol && viol <= tol {
                let cost = (u - u_nom).norm_squared();
                if best.is_none_or(|b| cost < b.1) {
                    best = Some((u, cost, mask));
                }
            }
        }
    };
    consider(&[]);
    for i in 0..k {
        consider(&[i]);
        for j in (i + 1)..k {
            consider(&[i, j]);
            for l in (j + 1)..k {
                consider(&[i, j, l]);
            }
        }
    }
    match best {
        Some((u, _, mask)) => {
            Projection { u, feasible: true, active_mask: mask, max_violation: max_viol(&u) }
        }
        None => Projection {
            u: least_bad.0,
            feasible: false,
            active_mask: least_bad.2,
            max_violation: least_bad.1,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hs(n: Vec3, c: f32) -> HalfSpace {
        HalfSpace { n: n.normalize(), c }
    }

    #[test]
    fn inactive_constraint_leaves_nominal() {
        let p = project(&Vec3::new(1.0, 2.0, 3.0), &[hs(Vec3::x(), 0.5)]);
        assert!(p.feasible);
        assert_eq!(p.active_mask, 0);
        assert_eq!(p.u, Vec3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn single_constraint_is_orthogonal_projection() {
        let p = project(&Vec3::new(-1.0, 2.0, 0.0), &[hs(Vec3::x(), 0.5)]);
        assert!(p.feasible);
        assert!((p.u - Vec3::new(0.5, 2.0, 0.0)).norm() < 1e-6);
    }

    #[test]
    fn corner_of_two_walls() {
        // u ≥ 1 along x and along y; nominal (−1, −1, 2) → (1, 1, 2).
        let p = project(&Vec3::new(-1.0, -1.0, 2.0), &[hs(Vec3::x(), 1.0), hs(Vec3::y(), 1.0)]);
        assert!(p.feasible);
        assert!((p.u - Vec3::new(1.0, 1.0, 2.0)).norm() < 1e-5);
        assert_eq!(p.active_mask, 0b11);
    }

    #[test]
    fn redundant_duplicate_normals_are_handled() {
        let c = [hs(Vec3::x(), 1.0), hs(Vec3::x(), 2.0), hs(Vec3::x(), 0.0)];
        let p = project(&Vec3::zeros(), &c);
        assert!(p.feasible);
        assert!((p.u - Vec3::new(2.0, 0.0, 0.0)).norm() < 1e-5);
    }

    #[test]
    fn infeasible_opposite_walls_are_flagged() {
        let c = [hs(Vec3::x(), 1.0), hs(-Vec3::x(), 1.0)];
        let p = project(&Vec3::zeros(), &c);
        assert!(!p.feasible);
        assert!(p.max_violation > 0.0);
        assert!(p.u.x.is_finite());
    }

    #[test]
    fn three_planes_vertex() {
        let c = [hs(Vec3::x(), 1.0), hs(Vec3::y(), 1.0), hs(Vec3::z(), 1.0)];
        let p = project(&Vec3::zeros(), &c);
        assert!((p.u - Vec3::new(1.0, 1.0, 1.0)).norm() < 1e-5);
        assert_eq!(p.active_mask, 0b111);
    }
}
