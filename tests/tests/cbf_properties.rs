//! Properties of the safety filter's single step (issue 2, 10, 11):
//! in D_⊥ the output satisfies constraint (8); no input whatsoever yields a
//! non-finite output or a panic; the relative-velocity law reduces exactly to
//! eq. 12 for static obstacles; the multi-barrier law equals eq. 12 with one obstacle.

use parapet_core::cbf::{CbfParams, FilterVariant, Region, SafetyFilter};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::Vec3;
use parapet_tests::proptest_cases;
use proptest::prelude::*;

fn vec3(r: f32) -> impl Strategy<Value = Vec3> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn params() -> impl Strategy<Value = CbfParams> {
    (0.3f32..2.0, 0.01f32..0.1, 0.001f32..0.3, 0.0f32..1.0).prop_map(|(mu, delta, extra, a)| CbfParams {
        mu,
        delta,
        delta1: delta + extra,
        accel_bound: a,
        ..CbfParams::default()
    })
}

/// The variants on the paper's barrier (constraint 8 is theirs; the braking-distance
/// barrier has its own properties in `core/tests/braking_properties.rs`).
fn variant() -> impl Strategy<Value = FilterVariant> {
    prop::sample::select(FilterVariant::SQUARED_DISTANCE.to_vec())
}

/// Every variant.
fn any_variant() -> impl Strategy<Value = FilterVariant> {
    prop::sample::select(FilterVariant::ALL.to_vec())
}

#[path = "../../core/tests/support/wild.rs"]
mod wild;

fn nasty() -> impl Strategy<Value = f32> {
    wild::wild(3, -5.0..5.0)
}

fn nasty3() -> impl Strategy<Value = Vec3> {
    (nasty(), nasty(), nasty()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(proptest_cases()))]

    /// Property 1: whenever the filter intervenes (D_⊥), every enforced constraint
    /// `2dᵀḋ + μdᵀ(u − ā) ≥ μ|d|A` holds for the output (equality for eq. 12).
    #[test]
    fn perpendicular_region_satisfies_constraint_8(
        prm in params(), var in variant(),
        dir in vec3(1.0), dist in 0.05f32..0.6, v in vec3(2.0), u in vec3(6.0),
        others in prop::collection::vec((vec3(1.0), vec3(0.5)), 0..4usize.min(parapet_core::cbf::MAX_ACTIVE_BARRIERS)), ov in vec3(0.8),
    ) {
        prop_assume!(dir.norm() > 1e-3);
        let f = SafetyFilter::new(prm, var).unwrap();
        let p = Vec3::new(1.0, -2.0, -1.5);
        let mut obs = vec![ObstaclePoint { point: p - dir.normalize() * dist, velocity: Some(ov), id: 0, normal: None }];
        for (i, (q, w)) in others.iter().enumerate() {
            obs.push(ObstaclePoint { point: p + q, velocity: Some(*w), id: i as u16 + 1, normal: None });
        }
        let (out, diag) = f.apply(&p, &v, &u, &obs);
        prop_assert!(out.iter().all(|x| x.is_finite()));
        if diag.region == Region::Perpendicular && !diag.infeasible {
            // Every barrier the variant enforces: single-barrier variants the closest one,
            // multi variants every one with h ≤ δ1 (at most 4 here, so all are enforced).
            let closest = obs.iter().min_by(|a, b| (p - a.point).norm().total_cmp(&(p - b.point).norm())).unwrap();
            for o in &obs {
                let b = f.barrier(&p, &v, o).unwrap();
                let enforced = if var.is_multi() { b.h <= prm.delta1 } else { o.id == closest.id };
                if enforced {
                    let slack = b.constraint.n.dot(&out) - b.constraint.c;
                    prop_assert!(slack >= -1e-4 * (1.0 + b.constraint.c.abs() + u.norm()), "slack {slack} for {o:?}");
                }
            }
            if !var.is_multi() {
                // Eq. 12 makes (8) an equality: 2dᵀḋ + μdᵀu − μ|d|A = 0.
                let b = f.barrier(&p, &v, closest).unwrap();
                let slack = b.constraint.n.dot(&out) - b.constraint.c;
                prop_assert!(slack.abs() <= 1e-4 * (1.0 + b.constraint.c.abs() + u.norm()));
            }
        }
    }

    /// Property 2: no input whatsoever produces a non-finite output or a panic.
    #[test]
    fn no_input_produces_non_finite_output(
        var in any_variant(), p in nasty3(), v in nasty3(), u in nasty3(),
        obs in prop::collection::vec((nasty3(), prop::option::of(nasty3())), 0..6),
        same_point in any::<bool>(),
    ) {
        let f = SafetyFilter::new(CbfParams::default(), var).unwrap();
        let mut pts: Vec<ObstaclePoint> =
            obs.iter().enumerate().map(|(i, (q, w))| ObstaclePoint { point: *q, velocity: *w, id: i as u16, normal: None }).collect();
        if same_point {
            pts.push(ObstaclePoint::fixed(p, 99)); // zero distance
        }
        let (out, diag) = f.apply(&p, &v, &u, &pts);
        prop_assert!(out.iter().all(|x| x.is_finite()), "{out:?} {diag:?}");
        prop_assert!(out.norm() <= f.params.u_max + 1e-3 || diag.fault.is_none());
    }

    /// For static obstacles the relative-velocity law is exactly eq. 12, and with one
    /// obstacle the multi-barrier law agrees with eq. 12.
    #[test]
    fn extensions_reduce_to_eq_12(
        prm in params(), p in vec3(1.0), v in vec3(2.0), u in vec3(6.0),
        obs in prop::collection::vec(vec3(1.5), 1..6), zero_velocity in any::<bool>(),
    ) {
        let prm = CbfParams { accel_bound: 0.0, ..prm };
        let pts: Vec<ObstaclePoint> = obs.iter().enumerate().map(|(i, q)| ObstaclePoint {
            point: *q, velocity: if zero_velocity { Some(Vec3::zeros()) } else { None }, id: i as u16, normal: None,
        }).collect();
        let paper = SafetyFilter::new(prm, FilterVariant::Paper).unwrap();
        let rel = SafetyFilter::new(prm, FilterVariant::Relative).unwrap();
        prop_assert_eq!(paper.apply(&p, &v, &u, &pts), rel.apply(&p, &v, &u, &pts));
        let multi = SafetyFilter::new(prm, FilterVariant::Multi).unwrap();
        let (a, da) = paper.apply(&p, &v, &u, &pts[..1]);
        let (b, db) = multi.apply(&p, &v, &u, &pts[..1]);
        prop_assert!((a - b).norm() <= 1e-4 * (1.0 + a.norm()), "{a} vs {b}");
        prop_assert_eq!(da.intervened, db.intervened);
    }
}
