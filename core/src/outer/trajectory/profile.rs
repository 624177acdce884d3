//! The 1-D jerk-limited motion along the arc length: the time-optimal velocity plan from a
//! state `(v, a)` to a speed `u` (three constant-jerk phases), its exact integration over a
//! step, and the braking distance from `(v, a)` down to a speed `v_f`.
//!
//! Owns only scalar maths; imports [`crate::fmath`] and nothing else.

use crate::fmath::{maxf, minf, sqrtf};

/// Acceleration and jerk limits of the motion along the path (both > 0), m/s², m/s³.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Limits {
    /// Tangential acceleration bound, m/s².
    pub accel: f32,
    /// Jerk bound, m/s³.
    pub jerk: f32,
}

/// State of the 1-D motion: arc length (local to a piece), speed and acceleration along it.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Motion {
    /// Arc length, m.
    pub s: f32,
    /// Speed `ṡ`, m/s.
    pub v: f32,
    /// Acceleration `s̈`, m/s².
    pub a: f32,
}

/// A plan of three constant-jerk phases, then zero jerk (the acceleration is 0 at its end).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Plan {
    /// Jerk of each phase, m/s³.
    pub jerk: [f32; 3],
    /// Duration of each phase, s (≥ 0).
    pub dur: [f32; 3],
    /// Speed at the end of the plan, m/s (set exactly when the plan completes).
    pub end_speed: f32,
}

/// Time-optimal plan from `(v, a)` to the speed `u` with `a = 0` at the end, under the limits
/// (the velocity mode of PX4's `VelocitySmoothing`): jerk `±J` until the acceleration reaches
/// the peak `±a_p`, hold, jerk `∓J` back to 0. `a` is clamped into `[−A, A]` first.
pub(crate) fn velocity_plan(v: f32, a: f32, u: f32, lim: Limits) -> Plan {
    let (amax, j) = (lim.accel, lim.jerk);
    let a = a.clamp(-amax, amax);
    // The speed reached if the acceleration were ramped to 0 now.
    let v_rest = v + a * a.abs() / (2.0 * j);
    let d = if u > v_rest {
        1.0
    } else if u < v_rest {
        -1.0
    } else {
        // Only ramp the acceleration to zero.
        let jr = if a > 0.0 { -j } else { j };
        return Plan { jerk: [jr, 0.0, 0.0], dur: [a.abs() / j, 0.0, 0.0], end_speed: u };
    };
    // Mirror so that the plan accelerates: a0 is the current acceleration in that direction.
    let a0 = d * a;
    let dv = d * (u - v);
    let mut ap = sqrtf(maxf(j * dv + 0.5 * a0 * a0, 0.0));
    let mut hold = 0.0;
    if ap > amax {
        ap = amax;
        hold = maxf((dv - (2.0 * amax * amax - a0 * a0) / (2.0 * j)) / amax, 0.0);
    }
    Plan { jerk: [d * j, 0.0, -d * j], dur: [maxf((ap - a0) / j, 0.0), hold, ap / j], end_speed: u }
}

/// Change of a motion over a step: displacement, speed change and the final acceleration,
/// kept apart from the (large) arc length and speed they are added to, so that the caller can
/// add them without losing their low-order bits (compensated summation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Delta {
    /// Displacement `Δs`, m.
    pub ds: f32,
    /// Speed change `Δṡ`, m/s (unused when `complete`).
    pub dv: f32,
    /// Acceleration at the end of the step, m/s².
    pub a: f32,
    /// The plan completed within the step: the speed is exactly the plan's end speed.
    pub complete: bool,
}

/// Follow `plan` from speed `v` and acceleration `a` for `dt` seconds, integrating each
/// constant-jerk phase exactly (a phase may end inside the step). When the plan completes
/// within the step the acceleration is exactly 0 and the speed the plan's end speed.
pub(crate) fn follow_delta(v: f32, a: f32, plan: &Plan, dt: f32) -> Delta {
    let (mut ds, mut dv, mut a) = (0.0f32, 0.0f32, a);
    let mut left = dt;
    for (jerk, dur) in plan.jerk.iter().zip(plan.dur.iter()) {
        let t = minf(*dur, left);
        let vt = v + dv;
        ds += t * (vt + t * (0.5 * a + t * jerk / 6.0));
        dv += t * (a + 0.5 * t * jerk);
        a += t * jerk;
        if *dur > left {
            return Delta { ds, dv, a, complete: false };
        }
        left -= *dur;
    }
    // The plan is complete: a = 0, v = u.
    if left > 0.0 {
        ds += plan.end_speed * left;
    }
    Delta { ds, dv: plan.end_speed - v, a: 0.0, complete: true }
}

/// [`follow_delta`] applied to `m` (plain sums; for tests).
#[cfg(test)]
pub(crate) fn follow(m: Motion, plan: &Plan, dt: f32) -> Motion {
    let d = follow_delta(m.v, m.a, plan, dt);
    Motion { s: m.s + d.ds, v: if d.complete { plan.end_speed } else { m.v + d.dv }, a: d.a }
}

/// Distance of a symmetric jerk-limited speed change from `v0` down to `vf` (`v0 ≥ vf`),
/// starting and ending at zero acceleration: `(v0 + vf)/2 · T`, with
/// `T = Δv/A + A/J` when `Δv ≥ A²/J` (trapezoidal acceleration) and `T = 2√(Δv/J)` otherwise.
pub(crate) fn rest_to_rest_distance(v0: f32, vf: f32, lim: Limits) -> f32 {
    let (amax, j) = (lim.accel, lim.jerk);
    let dv = maxf(v0 - vf, 0.0);
    let t = if dv >= amax * amax / j { dv / amax + amax / j } else { 2.0 * sqrtf(dv / j) };
    0.5 * (v0 + vf) * t
}

/// Shortest distance in which the motion at `(v, a)` can bring its speed to `vf` or below
/// (jerk and acceleration limited; the braking plan is [`velocity_plan`] towards `vf`). 0 when
/// the speed never exceeds `vf` under that plan (already slow enough and not speeding up).
pub(crate) fn brake_distance(v: f32, a: f32, vf: f32, lim: Limits) -> f32 {
    let (amax, j) = (lim.accel, lim.jerk);
    let a = a.clamp(-amax, amax);
    if a > 0.0 {
        // Ramp the acceleration down through 0 (jerk −J), then brake from zero acceleration.
        let t0 = a / j;
        let v0 = v + a * a / (2.0 * j);
        if v0 <= vf {
            return 0.0;
        }
        let d0 = t0 * (v + t0 * (0.5 * a - t0 * j / 6.0));
        return d0 + rest_to_rest_distance(v0, vf, lim);
    }
    if v <= vf {
        return 0.0;
    }
    let a_abs = -a;
    let t = a_abs / j;
    // The state lies on a braking ramp that started from zero acceleration at speed vv.
    let vv = v + a * a / (2.0 * j);
    let ap = minf(amax, sqrtf(j * (vv - vf)));
    if ap >= a_abs {
        let virtual_ramp = t * (vv - j * t * t / 6.0);
        maxf(rest_to_rest_distance(vv, vf, lim) - virtual_ramp, 0.0)
    } else {
        // Braking harder than needed: ramping the acceleration up to 0 takes the speed below
        // vf; the distance until it crosses vf (v − |a|τ + Jτ²/2 = vf).
        let disc = maxf(a_abs * a_abs - 2.0 * j * (v - vf), 0.0);
        let tau = minf((a_abs - sqrtf(disc)) / j, t);
        tau * (v + tau * (-0.5 * a_abs + tau * j / 6.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIM: Limits = Limits { accel: 3.0, jerk: 4.0 };

    /// Follow a plan in small steps and return the final state.
    fn run(mut m: Motion, u: f32, steps: usize, dt: f32) -> Motion {
        for _ in 0..steps {
            let p = velocity_plan(m.v, m.a, u, LIM);
            m = follow(m, &p, dt);
        }
        m
    }

    #[test]
    fn velocity_plan_reaches_the_target_with_zero_acceleration() {
        for &(v, a, u) in
            &[(0.0, 0.0, 3.0), (3.0, 0.0, 0.0), (1.0, 2.0, 0.5), (1.0, -2.0, 2.5), (2.0, 3.0, 2.1)]
        {
            let m = run(Motion { s: 0.0, v, a }, u, 2000, 0.004);
            assert!((m.v - u).abs() < 1e-5 && m.a == 0.0, "{v} {a} {u}: {m:?}");
        }
    }

    #[test]
    fn braking_distance_matches_the_braking_plan() {
        // From several states, fly the plan towards vf and measure the distance until v ≤ vf.
        for &(v, a, vf) in &[
            (3.0f32, 0.0f32, 0.0f32),
            (3.0, 2.0, 0.0),
            (3.0, -1.0, 0.0),
            (3.0, -3.0, 2.5),
            (1.0, 0.5, 0.3),
            (0.2, -0.1, 0.0),
            (5.0, -2.9, 4.9),
        ] {
            let d = brake_distance(v, a, vf, LIM);
            let mut m = Motion { s: 0.0, v, a };
            let dt = 1e-4;
            let mut crossed = if v <= vf && a <= 0.0 { Some(0.0) } else { None };
            for _ in 0..200_000 {
                if crossed.is_some() {
                    break;
                }
                let p = velocity_plan(m.v, m.a, vf, LIM);
                let n = follow(m, &p, dt);
                if n.v <= vf + 1e-6 && n.a <= 1e-6 {
                    crossed = Some(n.s);
                }
                m = n;
            }
            let measured = crossed.unwrap();
            assert!((measured - d).abs() < 1e-3 + 1e-3 * d, "{v} {a} {vf}: {measured} vs {d}");
        }
    }
}
