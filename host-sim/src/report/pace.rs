//! The pace of a mission flight (issue 35, `summary.json` `pace`): the time to the goal
//! against the **time-optimal time for the same path and limits**, computed here independently
//! of the core's trajectory generator, and the generator's own time on that path, so a slow
//! flight says where its time went.
//!
//! * `time_optimal_s` ([`time_optimal`]): the classic minimum-time solution of a point mass
//!   along a fixed geometric path with speed and acceleration bounds — the forward–backward
//!   integration of the "maximum velocity curve" (Bobrow, Dubowsky, Gibson, IJRR 1985; Shin,
//!   McKay, IEEE TAC 1985; as in Kunz, Stilman, "Time-optimal trajectory generation for path
//!   following with bounded acceleration and velocity", RSS 2012). The path is the waypoint
//!   polyline with a **circular fillet** at each corner: the largest radius whose cut is at most
//!   the corner tolerance (`TRJ_CORNER_TOL`; cut `R·(1/cos(θ/2) − 1)` for a turn `θ`), its
//!   tangent length at most half of either leg; a turn sharper than 179.9° or a zero tolerance
//!   is a stop. Bounds: the horizontal speed `WP_SPEED`, the climb and descent speeds
//!   (`TRJ_V_UP`, `TRJ_V_DN`), the centripetal acceleration per axis (`TRJ_ACC` horizontally,
//!   `TRJ_ACC_VERT` vertically) and the tangential acceleration per axis; rest at both ends.
//!   **Jerk is unbounded** and the fillet is a circle (a curvature step the generator's
//!   curvature-continuous blends avoid; `docs/cascade.md` § The path: about 21 % more corner
//!   speed), and the tangential and centripetal shares are bounded separately, so this time is a
//!   lower bound on any flight of the generator's limits on the same path: a ratio to it is a
//!   strict measure.
//! * `trajectory_s` ([`generator_time`]): the core's `Trajectory` built from the same points and
//!   parameters, stepped at the outer loop's 250 Hz with its clock never held — the time the
//!   reference alone needs. `time_to_goal_s − trajectory_s` is what the flight lost to waiting
//!   (the clock holds while the tracking error is large, i.e. while the safety filter or the
//!   governor holds the vehicle back, or wind pushes it).
//! * `slowed_by`: `"none"` when the flight is within [`PACE_RATIO`] of the optimum, else the
//!   larger share of the lost time: `"trajectory"` (the generator's own time) or the safety
//!   side, `"safety filter"` or `"speed governor"` (the governor's cause is in
//!   `speed_limited_by`).
//!
//! Host-only, `f64`, bounded by the path: the sampled path has at most
//! `length / SAMPLE_STEP_M + 64 · FILLET_SAMPLES` points, the generator at most
//! [`MAX_GENERATOR_STEPS`] steps.

use nalgebra::Vector3;
use parapet_core::outer::trajectory::{Trajectory, TrajectoryParams};
use serde::Serialize;

/// The bar: a flight within this factor of the time-optimal time is on pace.
pub const PACE_RATIO: f64 = 1.3;
/// Spacing of the samples along a straight leg, m.
const SAMPLE_STEP_M: f64 = 0.005;
/// Samples per fillet (the speed and acceleration bounds are evaluated at each).
const FILLET_SAMPLES: usize = 64;
/// The generator's step, s (the outer loop's 250 Hz).
const GENERATOR_DT_S: f32 = 0.004;
/// At most this many generator steps (1 hour at 250 Hz); a longer one is reported as null.
pub const MAX_GENERATOR_STEPS: u64 = 900_000;

/// The limits the pace is measured against (those the mission's trajectory flew with).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaceLimits {
    /// Horizontal speed, m/s (`WP_SPEED`).
    pub cruise: f64,
    /// Climb speed, m/s (`TRJ_V_UP`).
    pub up: f64,
    /// Descent speed, m/s (`TRJ_V_DN`).
    pub down: f64,
    /// Horizontal acceleration, m/s² (`TRJ_ACC`).
    pub accel_xy: f64,
    /// Vertical acceleration, m/s² (`TRJ_ACC_VERT`).
    pub accel_z: f64,
    /// Largest corner cut, m (`TRJ_CORNER_TOL`).
    pub corner_tolerance: f64,
}

impl PaceLimits {
    /// The limits of a trajectory's parameters with its cruise speed.
    pub fn of(p: &TrajectoryParams) -> PaceLimits {
        PaceLimits {
            cruise: f64::from(p.cruise_speed),
            up: f64::from(p.speed_up),
            down: f64::from(p.speed_down),
            accel_xy: f64::from(p.accel_horizontal),
            accel_z: f64::from(p.accel_vertical),
            corner_tolerance: f64::from(p.corner_tolerance),
        }
    }
}

/// `summary.json` `pace` (null for flights without a mission trajectory: the paper's guidance,
/// piloted or offboard flights).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Pace {
    /// Time-optimal time for the path and limits (see the module doc), s.
    pub time_optimal_s: f64,
    /// The trajectory generator's time on the same path with its clock never held, s (null past
    /// [`MAX_GENERATOR_STEPS`] or when it refuses the path).
    pub trajectory_s: Option<f64>,
    /// `time_to_goal_s / time_optimal_s` (null without the goal).
    pub ratio: Option<f64>,
    /// `trajectory_s / time_optimal_s`.
    pub trajectory_ratio: Option<f64>,
    /// `time_to_goal_s − trajectory_s`: time the flight waited for the vehicle, s.
    pub waited_s: Option<f64>,
    /// "none", "trajectory", "safety filter" or "speed governor" (module doc).
    pub slowed_by: String,
}

impl Pace {
    /// The pace of a flight of `waypoints` (NED, m; the vehicle's start first) with `params`
    /// (cruise speed included) that reached the goal at `time_to_goal` (s) or did not;
    /// `governed` when the speed governor limited it (`speed_limited_by` not null).
    pub fn of(
        waypoints: &[Vector3<f64>],
        params: &TrajectoryParams,
        time_to_goal: Option<f64>,
        governed: bool,
    ) -> Option<Pace> {
        let time_optimal_s = time_optimal(waypoints, &PaceLimits::of(params))?;
        let trajectory_s = generator_time(waypoints, params);
        let ratio = time_to_goal.map(|t| t / time_optimal_s);
        let waited_s = time_to_goal.zip(trajectory_s).map(|(t, g)| t - g);
        let slowed_by = match (ratio, trajectory_s) {
            (Some(r), _) if r <= PACE_RATIO => "none",
            (_, Some(g)) if g - time_optimal_s >= waited_s.unwrap_or(0.0) => "trajectory",
            _ if governed => "speed governor",
            _ => "safety filter",
        };
        Some(Pace {
            time_optimal_s,
            trajectory_s,
            ratio,
            trajectory_ratio: trajectory_s.map(|g| g / time_optimal_s),
            waited_s,
            slowed_by: slowed_by.into(),
        })
    }
}

/// One sample of the path: the arc length to the next sample, the unit tangent and the
/// curvature vector (1/m).
struct PathSample {
    ds: f64,
    tangent: Vector3<f64>,
    curvature: Vector3<f64>,
    stop: bool,
}

/// A corner's fillet: tangent length `T` (m) and radius `R` (m); `None` radius: a stop.
fn fillet(d0: &Vector3<f64>, d1: &Vector3<f64>, leg_in: f64, leg_out: f64, tol: f64) -> (f64, Option<f64>) {
    let theta = d0.dot(d1).clamp(-1.0, 1.0).acos();
    if theta < 1e-9 {
        return (0.0, Some(f64::INFINITY));
    }
    if tol <= 0.0 || theta > 179.9f64.to_radians() {
        return (0.0, None);
    }
    let half = theta / 2.0;
    let mut r = tol / (1.0 / half.cos() - 1.0);
    let mut t = r * half.tan();
    let t_max = 0.5 * leg_in.min(leg_out);
    if t > t_max {
        t = t_max;
        r = t / half.tan();
    }
    (t, Some(r))
}

/// The sampled path: straight parts between the fillets, each fillet in [`FILLET_SAMPLES`].
fn sample_path(w: &[Vector3<f64>], tol: f64) -> Vec<PathSample> {
    let legs: Vec<(Vector3<f64>, f64)> = w
        .windows(2)
        .filter_map(|p| {
            let d = p[1] - p[0];
            let l = d.norm();
            (l > 1e-6).then(|| (d / l, l))
        })
        .collect();
    let mut out = Vec::new();
    if legs.is_empty() {
        return out;
    }
    // The fillet at the end of each leg (the last leg ends at the goal: none).
    let fillets: Vec<(f64, Option<f64>)> = (0..legs.len())
        .map(|i| match legs.get(i + 1) {
            Some(next) => fillet(&legs[i].0, &next.0, legs[i].1, next.1, tol),
            None => (0.0, Some(f64::INFINITY)),
        })
        .collect();
    let mut start_cut = 0.0;
    for (i, &(d, l)) in legs.iter().enumerate() {
        let (t, r) = fillets[i];
        let straight = (l - start_cut - t).max(0.0);
        let n = (straight / SAMPLE_STEP_M).ceil().max(1.0) as usize;
        for _ in 0..n {
            out.push(PathSample {
                ds: straight / n as f64,
                tangent: d,
                curvature: Vector3::zeros(),
                stop: false,
            });
        }
        match (r, legs.get(i + 1)) {
            (None, Some(_)) => {
                out.push(PathSample { ds: 0.0, tangent: d, curvature: Vector3::zeros(), stop: true });
            }
            (Some(r), Some(&(d1, _))) if t > 0.0 && r.is_finite() => {
                let theta = d.dot(&d1).clamp(-1.0, 1.0).acos();
                // The unit vector in the turn's plane perpendicular to d, towards d1.
                let e = (d1 - d * d.dot(&d1)).normalize();
                for k in 0..FILLET_SAMPLES {
                    let phi = theta * (k as f64 + 0.5) / FILLET_SAMPLES as f64;
                    let tangent = d * phi.cos() + e * phi.sin();
                    let normal = -d * phi.sin() + e * phi.cos();
                    out.push(PathSample {
                        ds: r * theta / FILLET_SAMPLES as f64,
                        tangent,
                        curvature: normal / r,
                        stop: false,
                    });
                }
            }
            _ => {}
        }
        start_cut = t;
    }
    out
}

/// The time-optimal time along `waypoints` (NED, m) under `limits` (module doc), s; `None` for
/// fewer than two distinct points or a non-positive limit.
pub fn time_optimal(waypoints: &[Vector3<f64>], limits: &PaceLimits) -> Option<f64> {
    let l = limits;
    if [l.cruise, l.up, l.down, l.accel_xy, l.accel_z].iter().any(|x| !(x.is_finite() && *x > 0.0)) {
        return None;
    }
    let samples = sample_path(waypoints, l.corner_tolerance.max(0.0));
    if samples.is_empty() {
        return None;
    }
    let bound = |num: f64, den: f64| if den > 1e-12 { num / den } else { f64::INFINITY };
    // The speed bound at each sample (velocity and centripetal limits) and the tangential
    // acceleration bound over it.
    let caps: Vec<(f64, f64)> = samples
        .iter()
        .map(|s| {
            let t = s.tangent;
            let k = s.curvature;
            let v = if s.stop {
                0.0
            } else {
                bound(l.cruise, t.xy().norm())
                    .min(bound(l.up, (-t.z).max(0.0)))
                    .min(bound(l.down, t.z.max(0.0)))
                    .min(bound(l.accel_xy, k.xy().norm()).sqrt())
                    .min(bound(l.accel_z, k.z.abs()).sqrt())
            };
            (v, bound(l.accel_xy, t.xy().norm()).min(bound(l.accel_z, t.z.abs())))
        })
        .collect();
    // Speeds at the n + 1 sample boundaries; a sample's bound holds on both of its ends.
    let n = samples.len();
    let mut v = vec![f64::INFINITY; n + 1];
    for (i, &(cap, _)) in caps.iter().enumerate() {
        v[i] = v[i].min(cap);
        v[i + 1] = v[i + 1].min(cap);
    }
    v[0] = 0.0;
    v[n] = 0.0;
    for i in 0..n {
        v[i + 1] = v[i + 1].min((v[i] * v[i] + 2.0 * caps[i].1 * samples[i].ds).sqrt());
    }
    for i in (0..n).rev() {
        v[i] = v[i].min((v[i + 1] * v[i + 1] + 2.0 * caps[i].1 * samples[i].ds).sqrt());
    }
    let time = samples
        .iter()
        .enumerate()
        .filter(|(_, s)| s.ds > 0.0)
        .map(|(i, s)| 2.0 * s.ds / (v[i] + v[i + 1]))
        .sum::<f64>();
    time.is_finite().then_some(time)
}

/// The core trajectory generator's time on `waypoints` with `params` and its clock never held,
/// s (module doc); `None` when it refuses the path or needs more than [`MAX_GENERATOR_STEPS`].
pub fn generator_time(waypoints: &[Vector3<f64>], params: &TrajectoryParams) -> Option<f64> {
    let mut points: Vec<parapet_core::Vec3> = Vec::with_capacity(waypoints.len());
    for w in waypoints {
        let p = crate::world::scene::to_f32(w);
        // As the guidance builds it: waypoints within the minimum leg of the previous dropped.
        if points.last().is_none_or(|q| (p - q).norm() >= parapet_core::outer::trajectory::MIN_LEG_LENGTH) {
            points.push(p);
        }
    }
    // A path longer than the trajectory holds streams in as the guidance's does (issue 38:
    // `Trajectory::extend` once `REFILL_PASSED` of its waypoints are passed).
    let first = points.len().min(parapet_core::controller::PATH_CAPACITY);
    let mut traj: Box<Trajectory> = Box::new(Trajectory::new(*params, &points[..first]).ok()?);
    let (mut sent, mut held) = (first, first);
    for step in 1..=MAX_GENERATOR_STEPS {
        let s = traj.step(GENERATOR_DT_S, 1.0).ok()?;
        if traj.is_done() {
            return Some(step as f64 * f64::from(GENERATOR_DT_S));
        }
        if sent < points.len() && s.segment >= parapet_core::outer::path_stream::REFILL_PASSED {
            // At least segment − 2 points go (the trajectory keeps the leg flown and the points
            // just behind it): room for that many more.
            let room = traj.capacity().saturating_sub(held - (s.segment - 2));
            let more = &points[sent..(sent + room).min(points.len())];
            if let Ok((dropped, appended)) = traj.extend(more) {
                (held, sent) = (held - dropped + appended, sent + appended);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(cruise: f64, tol: f64) -> PaceLimits {
        PaceLimits { cruise, up: 3.0, down: 1.5, accel_xy: 3.0, accel_z: 3.0, corner_tolerance: tol }
    }

    #[test]
    fn a_straight_leg_is_the_trapezoid() {
        // 20 m at 3 m/s, 3 m/s²: 1 s up (1.5 m), 17 m at 3 m/s, 1 s down: 2 + 17/3 s.
        let w = [Vector3::zeros(), Vector3::new(20.0, 0.0, 0.0)];
        let t = time_optimal(&w, &limits(3.0, 0.1)).unwrap();
        assert!((t - (2.0 + 17.0 / 3.0)).abs() < 1e-3, "{t}");
        // 1 m never reaches 3 m/s: a triangle, t = 2·√(d/a) = 2·√(1/3).
        let w = [Vector3::zeros(), Vector3::new(1.0, 0.0, 0.0)];
        let t = time_optimal(&w, &limits(3.0, 0.1)).unwrap();
        assert!((t - 2.0 * (1.0f64 / 3.0).sqrt()).abs() < 1e-3, "{t}");
    }

    #[test]
    fn a_right_angle_is_flown_at_the_fillets_speed_and_a_zero_tolerance_stops() {
        // 90°, tolerance 0.1 m: R = 0.1/(√2 − 1) = 0.2414 m, corner speed √(3·R) = 0.851 m/s.
        let w = [Vector3::zeros(), Vector3::new(10.0, 0.0, 0.0), Vector3::new(10.0, 10.0, 0.0)];
        let t_blend = time_optimal(&w, &limits(3.0, 0.1)).unwrap();
        let t_stop = time_optimal(&w, &limits(3.0, 0.0)).unwrap();
        // Stop: two 10 m trapezoids.
        let leg = 2.0 + 7.0 / 3.0;
        assert!((t_stop - 2.0 * leg).abs() < 1e-3, "{t_stop}");
        // Blend: each leg from rest to 3 m/s, cruise, braking to v_c over its straight part
        // 10 − R; then the quarter arc R·π/2 at v_c.
        let r = 0.1 / (2f64.sqrt() - 1.0);
        let vc = (3.0 * r).sqrt();
        let straight = 10.0 - r;
        let brake = (9.0 - vc * vc) / 6.0;
        let leg = 1.0 + (straight - 1.5 - brake) / 3.0 + (3.0 - vc) / 3.0;
        let expected = 2.0 * leg + r * std::f64::consts::FRAC_PI_2 / vc;
        assert!((t_blend - expected).abs() < 5e-3, "{t_blend} vs {expected}");
    }

    #[test]
    fn a_climb_is_limited_by_the_climb_speed() {
        // 10 m straight up (NED −z) at 3 m/s up, 3 m/s²: 2 + 7/3 s; down at 1.5 m/s: 1 + 9.25/1.5 s.
        let w = [Vector3::zeros(), Vector3::new(0.0, 0.0, -10.0)];
        let t = time_optimal(&w, &limits(5.0, 0.1)).unwrap();
        assert!((t - (2.0 + 7.0 / 3.0)).abs() < 1e-3, "{t}");
        let w = [Vector3::zeros(), Vector3::new(0.0, 0.0, 10.0)];
        let t = time_optimal(&w, &limits(5.0, 0.1)).unwrap();
        assert!((t - (1.0 + 9.25 / 1.5)).abs() < 1e-3, "{t}");
    }

    #[test]
    fn the_generator_is_never_faster_than_the_optimum() {
        let w = [
            Vector3::zeros(),
            Vector3::new(4.0, 0.0, 0.0),
            Vector3::new(4.0, 3.0, -0.5),
            Vector3::new(8.0, 5.0, -0.5),
            Vector3::new(8.5, 5.1, 0.0),
        ];
        for cruise in [1.0f32, 3.0, 5.0] {
            let p = TrajectoryParams { cruise_speed: cruise, ..TrajectoryParams::default() };
            let opt = time_optimal(&w, &PaceLimits::of(&p)).unwrap();
            let gen = generator_time(&w, &p).unwrap();
            assert!(gen >= opt, "cruise {cruise}: generator {gen} < optimum {opt}");
        }
        let pace = Pace::of(&w, &TrajectoryParams::default(), None, false).unwrap();
        assert_eq!((pace.ratio, pace.waited_s), (None, None));
    }
}
