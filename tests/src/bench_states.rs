//! Seeded random filter problems shared by the `cbf_filter` benchmark and the
//! `filter_vs_qp` test, and the agreement table the benchmark prints.
//!
//! A problem is a vehicle state (position, velocity, NED), a nominal
//! acceleration `u*` and `K` static obstacle points around the vehicle. The
//! distribution is chosen so that the filter has work to do: obstacle 0 is
//! always near (0.24–0.40 m from the centre of mass, the hull radius being
//! 0.224 m), the others lie 0.24–3 m away (biased towards near, `r = 0.24 +
//! 2.76·U²`), and in half the problems `u*` points roughly at obstacle 0.
//!
//! Obstacle directions are uniform within a cone of half-angle
//! [`FORWARD_HALF_ANGLE_DEG`] around the direction of flight (a forward sector,
//! as a forward-looking sensor or a wall/clutter on one side gives), or over
//! the whole sphere ([`ALL_AROUND_DEG`]). The distinction matters for the
//! baseline: every constraint (8) passes through the braking input
//! `−(2/μ)ṗ`, so when the obstacles surround the vehicle the all-K CBF-QP's
//! feasible set shrinks to that single point, an interior-point solver has no
//! interior to work in, and clarabel fails on most such problems (the benchmark
//! prints the table for both spreads; the timings use the forward sector, where
//! the QP is well posed).
//!
//! Both methods get constraint (8) of the paper for each obstacle, own
//! velocity: `nᵀu ≥ c`, `n = d/|d|`, `c = −(2/μ) nᵀṗ` (see `parapet_core::cbf`).
//! The CBF-QP baseline enforces all `K`; Parapet's `Multi` variant enforces the
//! (at most [`MAX_ACTIVE_BARRIERS`]) most critical of those with `h ≤ δ1` (event
//! rule with the controller's sample time), the `Paper` variant only the closest.

use parapet_core::cbf::{FilterVariant, SafetyFilter, MAX_ACTIVE_BARRIERS};
use parapet_core::controller::ControllerParams;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::qp3::HalfSpace;
use parapet_core::Vec3;

use crate::reference_qp;

/// Obstacle counts of the benchmark.
pub const KS: [usize; 4] = [1, 4, 16, 32];

/// Half-angle of the forward sector the obstacles lie in (timed problems), degrees.
pub const FORWARD_HALF_ANGLE_DEG: f32 = 75.0;

/// Half-angle meaning "all around the vehicle", degrees.
pub const ALL_AROUND_DEG: f32 = 180.0;

/// SplitMix64: a tiny seeded generator, so the problems are the same on every machine.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// Generator with the given seed.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
    /// Uniformly distributed unit vector.
    pub fn direction(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.uniform(-1.0, 1.0), self.uniform(-1.0, 1.0), self.uniform(-1.0, 1.0));
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }
}

/// One filter problem.
#[derive(Clone, Debug)]
pub struct FilterProblem {
    /// Vehicle position, NED, m.
    pub p: Vec3,
    /// Vehicle velocity, NED, m/s.
    pub v: Vec3,
    /// Nominal acceleration `u*`, NED, m/s².
    pub u_nom: Vec3,
    /// Obstacle points (static), NED, m; ids 0..K.
    pub obstacles: Vec<ObstaclePoint>,
}

impl SplitMix64 {
    /// Unit vector uniform within `half_angle_deg` of the unit vector `axis` (rejection).
    pub fn direction_within(&mut self, axis: &Vec3, half_angle_deg: f32) -> Vec3 {
        let cos_max = half_angle_deg.to_radians().cos();
        loop {
            let d = self.direction();
            if half_angle_deg >= 180.0 || d.dot(axis) >= cos_max {
                return d;
            }
        }
    }
}

/// `n` problems with `k` obstacles each within `half_angle_deg` of the direction of
/// flight, from `seed` (see the module docs).
pub fn problems(k: usize, n: usize, seed: u64, half_angle_deg: f32) -> Vec<FilterProblem> {
    let mut rng = SplitMix64::new(seed ^ (k as u64).wrapping_mul(0x1000_0000_01B3));
    (0..n)
        .map(|_| {
            let p = Vec3::new(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0), rng.uniform(-3.0, -0.5));
            let heading = rng.direction();
            let v = heading * rng.uniform(0.0, 1.5);
            let obstacles: Vec<ObstaclePoint> = (0..k)
                .map(|i| {
                    let r = if i == 0 {
                        rng.uniform(0.24, 0.40)
                    } else {
                        let x = rng.unit();
                        0.24 + 2.76 * x * x
                    };
                    ObstaclePoint::fixed(p + rng.direction_within(&heading, half_angle_deg) * r, i as u16)
                })
                .collect();
            let mut u_nom = rng.direction() * rng.uniform(0.0, 4.0);
            if rng.unit() < 0.5 {
                // Push roughly at obstacle 0.
                let towards = (obstacles[0].point - p).normalize();
                u_nom = (towards * 2.0 + rng.direction() * 0.5) * rng.uniform(0.5, 2.0);
            }
            FilterProblem { p, v, u_nom, obstacles }
        })
        .collect()
}

/// The filter as the controller runs it: default (paper office) parameters, with the
/// controller's rule for the sample time (for every variant but `Paper` the period of the
/// 250 Hz outer loop, `ControllerParams::outer_params`).
pub fn filter(variant: FilterVariant) -> SafetyFilter {
    let params = ControllerParams { filter_variant: variant, ..ControllerParams::default() }.outer_params();
    SafetyFilter::new(params.cbf, variant).expect("the default filter parameters are valid")
}

/// Constraint (8) of every obstacle of `pr` (own velocity), in obstacle order, in the form
/// the filter `f` enforces it (with its class-K relaxation, `SafetyFilter::enforced_constraint`),
/// so the all-K QP and the filter's own set are the same kind of constraint.
pub fn all_constraints(f: &SafetyFilter, pr: &FilterProblem) -> Vec<HalfSpace> {
    pr.obstacles
        .iter()
        .filter_map(|o| f.barrier(&pr.p, &pr.v, o).map(|b| f.enforced_constraint(&b)))
        .collect()
}

/// The constraints a `Multi`/`MultiRelative` filter enforces on `pr`: the (at most
/// [`MAX_ACTIVE_BARRIERS`]) smallest-`h` barriers among those whose trigger value is ≤ δ1,
/// each with the filter's class-K relaxation (`SafetyFilter::enforced_constraint`; γ > 0
/// in the controller's default parameters since issue 17).
pub fn enforced_constraints(f: &SafetyFilter, pr: &FilterProblem) -> Vec<HalfSpace> {
    let mut near: Vec<(f32, HalfSpace)> = pr
        .obstacles
        .iter()
        .filter_map(|o| f.barrier(&pr.p, &pr.v, o))
        .filter(|b| f.trigger_value(b, &pr.u_nom) <= f.params.delta1)
        .map(|b| (b.h, f.enforced_constraint(&b)))
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    near.into_iter().take(MAX_ACTIVE_BARRIERS).map(|(_, c)| c).collect()
}

/// Largest violation `max(0, c − nᵀu)` of `u` over `cons`, m/s².
pub fn max_violation(u: &Vec3, cons: &[HalfSpace]) -> f32 {
    cons.iter().map(|h| h.violation(u)).fold(0.0, f32::max)
}

/// Agreement statistics for one obstacle count.
#[derive(Clone, Debug)]
pub struct Agreement {
    /// Obstacles per problem.
    pub k: usize,
    /// Problems.
    pub n: usize,
    /// Fraction of problems where `Multi` changed `u*`.
    pub multi_intervened: f64,
    /// Mean number of constraints `Multi` enforced.
    pub multi_mean_enforced: f64,
    /// Largest violation by `Multi` of a constraint it enforced, m/s².
    pub multi_max_violation_enforced: f32,
    /// Fraction of problems where `Multi`'s output violates (by > 1e-4) some constraint (8) it did
    /// not enforce (a far barrier, `h > δ1`, or beyond the K most critical).
    pub multi_violates_unenforced: f64,
    /// Largest `|u_multi − u_QP(same enforced set)|` where clarabel solved that QP, m/s²
    /// (exactness of the closed form).
    pub multi_vs_qp_same_max: f32,
    /// Median and largest `|u_multi − u_QP(all K)|` over the problems the QP solved, m/s².
    pub multi_vs_qp_all: (f32, f32),
    /// Fraction of problems where `Paper` changed `u*`.
    pub paper_intervened: f64,
    /// Largest violation by `Paper` of the closest obstacle's constraint when that one is near.
    pub paper_max_violation_closest: f32,
    /// Median and largest `|u_paper − u_QP(all K)|` over the problems the QP solved, m/s².
    pub paper_vs_qp_all: (f32, f32),
    /// Fraction of problems clarabel reports solved (all K constraints).
    pub qp_solved: f64,
    /// Largest violation by the QP answer of any of the K constraints (solved problems), m/s².
    pub qp_max_violation: f32,
}

fn median_max(mut x: Vec<f32>) -> (f32, f32) {
    if x.is_empty() {
        return (0.0, 0.0);
    }
    x.sort_by(f32::total_cmp);
    (x[x.len() / 2], x[x.len() - 1])
}

/// Run both filters and the QP (clarabel, tight tolerances) on `problems`.
pub fn agreement(k: usize, problems: &[FilterProblem]) -> Agreement {
    let multi = filter(FilterVariant::Multi);
    let paper = filter(FilterVariant::Paper);
    let n = problems.len();
    let (mut m_int, mut m_enf, mut m_viol, mut m_unenf, mut m_same) = (0usize, 0usize, 0f32, 0usize, 0f32);
    let (mut p_int, mut p_viol, mut q_solved, mut q_viol) = (0usize, 0f32, 0usize, 0f32);
    let (mut d_multi, mut d_paper) = (Vec::new(), Vec::new());
    for pr in problems {
        let all = all_constraints(&multi, pr);
        let enforced = enforced_constraints(&multi, pr);
        let (um, dm) = multi.apply(&pr.p, &pr.v, &pr.u_nom, &pr.obstacles);
        m_int += dm.intervened as usize;
        m_enf += dm.n_constraints as usize;
        m_viol = m_viol.max(max_violation(&um, &enforced));
        m_unenf += (max_violation(&um, &all) > 1e-4) as usize;
        let same = if enforced.is_empty() {
            Some(pr.u_nom)
        } else {
            let r = reference_qp::solve(&pr.u_nom, &enforced);
            r.solved.then_some(r.u)
        };
        if let Some(same) = same {
            m_same = m_same.max((um - same).norm());
        }

        let (up, dp) = paper.apply(&pr.p, &pr.v, &pr.u_nom, &pr.obstacles);
        p_int += dp.intervened as usize;
        let closest = pr
            .obstacles
            .iter()
            .filter_map(|o| paper.barrier(&pr.p, &pr.v, o))
            .min_by(|a, b| a.dist_sq.total_cmp(&b.dist_sq));
        if let Some(b) = closest.filter(|b| b.h <= paper.params.delta1) {
            p_viol = p_viol.max(b.constraint.violation(&up));
        }

        let qp = reference_qp::solve(&pr.u_nom, &all);
        if qp.solved {
            // Distances and violations only where clarabel reports an answer.
            q_solved += 1;
            q_viol = q_viol.max(max_violation(&qp.u, &all));
            d_multi.push((um - qp.u).norm());
            d_paper.push((up - qp.u).norm());
        }
    }
    let frac = |c: usize| c as f64 / n.max(1) as f64;
    Agreement {
        k,
        n,
        multi_intervened: frac(m_int),
        multi_mean_enforced: frac(m_enf),
        multi_max_violation_enforced: m_viol,
        multi_violates_unenforced: frac(m_unenf),
        multi_vs_qp_same_max: m_same,
        multi_vs_qp_all: median_max(d_multi),
        paper_intervened: frac(p_int),
        paper_max_violation_closest: p_viol,
        paper_vs_qp_all: median_max(d_paper),
        qp_solved: frac(q_solved),
        qp_max_violation: q_viol,
    }
}

/// The agreement table (Markdown) for the given rows.
pub fn agreement_table(rows: &[Agreement]) -> String {
    let mut s = String::from(
        "| K | problems | multi: intervened | multi: mean enforced | multi: max viol. enforced (m/s²) \
         | multi: violates an unenforced (8) | max ‖u_multi − u_QP(same set)‖ | median / max ‖u_multi − u_QP(all K)‖ \
         | paper: intervened | paper: max viol. closest | median / max ‖u_paper − u_QP(all K)‖ \
         | QP solved | QP: max viol. (m/s²) |\n|",
    );
    s.push_str(&"---|".repeat(13));
    s.push('\n');
    for a in rows {
        // Distances to the all-K QP exist only where clarabel solved it.
        let vs_all = |d: (f32, f32)| {
            if a.qp_solved > 0.0 {
                format!("{:.3} / {:.3}", d.0, d.1)
            } else {
                "n/a".to_string()
            }
        };
        let qp_viol = if a.qp_solved > 0.0 { format!("{:.1e}", a.qp_max_violation) } else { "n/a".into() };
        s.push_str(&format!(
            "| {} | {} | {:.0} % | {:.2} | {:.1e} | {:.0} % | {:.1e} | {} | {:.0} % | {:.1e} | {} | {:.0} % | {} |\n",
            a.k,
            a.n,
            100.0 * a.multi_intervened,
            a.multi_mean_enforced,
            a.multi_max_violation_enforced,
            100.0 * a.multi_violates_unenforced,
            a.multi_vs_qp_same_max,
            vs_all(a.multi_vs_qp_all),
            100.0 * a.paper_intervened,
            a.paper_max_violation_closest,
            vs_all(a.paper_vs_qp_all),
            100.0 * a.qp_solved,
            qp_viol,
        ));
    }
    s
}
