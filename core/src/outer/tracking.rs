//! Nominal PD position tracking (paper eq. 2) with feed-forward acceleration,
//! an optional vertical integral term and output limits.
//!
//! `u* = p̈_d + K_d (ṗ_d − ṗ) + K_p (p_d − p) + e_z ∫ k_i (z_d − z) dt`, world NED, m/s².

use crate::fmath::hypotf;
use crate::frame::{clampf, is_finite3};
use crate::param_decl::{access, field, Has, Param};
use crate::Vec3;

/// Tracking gains and limits.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackingParams {
    /// Position gain per NED axis, 1/s². Default 0.5 (paper, office experiment).
    pub kp: [f32; 3],
    /// Velocity gain per NED axis, 1/s. Default 0.8 (paper, office experiment).
    pub kd: [f32; 3],
    /// Integral gain on the vertical axis, 1/s³ (0 disables). Default 0.3.
    pub ki_z: f32,
    /// Bound on the vertical integral's contribution, m/s². Default 1.0.
    pub integral_limit_z: f32,
    /// Bound on the horizontal acceleration norm, m/s². Default 4.0.
    pub accel_max_xy: f32,
    /// Bound on upward acceleration (−z), m/s². Default 4.0.
    pub accel_max_up: f32,
    /// Bound on downward acceleration (+z), m/s². Default 3.0.
    pub accel_max_down: f32,
    /// While a mission trajectory is flown: horizontal position gain `K_p` of the position P →
    /// velocity P cascade, 1/s (`TRJ_XY_P`; PX4's `MPC_XY_P` is 0.95). Default 1.0.
    pub trajectory_pos_p: f32,
    /// While a mission trajectory is flown: horizontal velocity gain `K_v`, 1/s
    /// (`TRJ_XY_VEL_P`; PX4's `MPC_XY_VEL_P_ACC` is 1.8). Default 2.0.
    pub trajectory_vel_p: f32,
}

impl Default for TrackingParams {
    fn default() -> Self {
        TrackingParams {
            kp: [0.5; 3],
            kd: [0.8; 3],
            ki_z: 0.3,
            integral_limit_z: 1.0,
            accel_max_xy: 4.0,
            accel_max_up: 4.0,
            accel_max_down: 3.0,
            trajectory_pos_p: 1.0,
            trajectory_vel_p: 2.0,
        }
    }
}

impl TrackingParams {
    /// The PD tracker's parameters (`crate::params`, MAVLink `param_index` order).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 2] {
        [
            Param::new("TRK_KP", "Tracking", "1/s^2", (0.01, 100.0), 3, access!(|s| s.kp[0], |s, v| s.kp = [v; 3]),
                "PD position gain k_p (all axes)").key("kp"),
            Param::new("TRK_KD", "Tracking", "1/s", (0.01, 100.0), 3, access!(|s| s.kd[0], |s, v| s.kd = [v; 3]),
                "PD velocity gain k_d (all axes)").key("kd"),
        ]
    }

    /// The trajectory tracking cascade's gains (`crate::params`; in the table with the
    /// trajectory's own parameters, `outer::trajectory`).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn trajectory_params<P: Has<Self>>() -> [Param<P>; 2] {
        [
            Param::new("TRJ_XY_P", "Mission", "1/s", (0.1, 5.0), 2, field!(trajectory_pos_p),
                "MIS_GUIDANCE 1: horizontal position gain of the position P -> velocity P tracking cascade"),
            Param::new("TRJ_XY_VEL_P", "Mission", "1/s", (0.1, 10.0), 2, field!(trajectory_vel_p),
                "MIS_GUIDANCE 1: horizontal velocity gain of the tracking cascade (acceleration per m/s of velocity error)"),
        ]
    }
}

impl TrackingParams {
    /// The paper's setting: the same `kp`, `kd` on every axis, defaults otherwise.
    pub fn uniform(kp: f32, kd: f32) -> Self {
        TrackingParams { kp: [kp; 3], kd: [kd; 3], ..Self::default() }
    }
}

/// Desired trajectory sample, world NED.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Reference {
    /// p_d, m.
    pub position: Vec3,
    /// ṗ_d, m/s.
    pub velocity: Vec3,
    /// p̈_d, m/s².
    pub acceleration: Vec3,
    /// Yaw reference, rad (FRD ZYX, 0 = north, positive towards east).
    pub yaw: f32,
}

/// PD tracker with vertical integral. Owns only the integrator state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PdTracker {
    /// Gains and limits.
    pub params: TrackingParams,
    integral_z: f32,
    input_fault: bool,
}

impl PdTracker {
    /// A tracker with zero integrator.
    pub fn new(params: TrackingParams) -> Self {
        PdTracker { params, integral_z: 0.0, input_fault: false }
    }

    /// Zero the integrator.
    pub fn reset(&mut self) {
        self.integral_z = 0.0;
    }

    /// Current vertical integral contribution, m/s² (NED: negative pushes up).
    pub fn integral_z(&self) -> f32 {
        self.integral_z
    }

    /// `true` when the last [`update`](Self::update) got non-finite input and returned zero.
    pub fn input_fault(&self) -> bool {
        self.input_fault
    }

    /// Nominal acceleration `u*` (NED, m/s²) for position `pos` (m) and velocity
    /// `vel` (m/s), after `dt_s` seconds since the last call (the integrator only
    /// advances for `0 < dt_s ≤ 0.1`). Non-finite input returns zero acceleration
    /// (hover) and sets [`input_fault`](Self::input_fault).
    pub fn update(&mut self, r: &Reference, pos: &Vec3, vel: &Vec3, dt_s: f32) -> Vec3 {
        let (kp, kd) = (Vec3::from(self.params.kp), Vec3::from(self.params.kd));
        self.update_with(r, pos, vel, dt_s, (kp, kd))
    }

    /// [`update`](Self::update) for a mission trajectory (`MIS_GUIDANCE` 1): horizontally the
    /// cascade of PX4's and ArduPilot's position controllers, a position P `K_p` giving a
    /// velocity set-point on top of the velocity feed-forward and a velocity P `K_v` giving
    /// the acceleration on top of the acceleration feed-forward,
    /// `u = p̈_d + K_v·(ṗ_d + K_p·(p_d − p) − ṗ)`,
    /// which is the PD law with `k_p = K_v·K_p` and `k_d = K_v` (defaults 2.0 1/s² and
    /// 2.0 1/s: damping ratio 0.71, where the paper's 0.5 and 0.8 leave a lag of
    /// `k_d·V/k_p` = 1.6 m per m/s of a constant-speed reference without feed-forward);
    /// vertically the paper's gains with the integral, as [`update`](Self::update).
    ///
    /// A vehicle ahead of the moving reference along its direction of travel (pushed there by
    /// the safety filter, e.g. away from an obstacle closing from behind) is pulled back by
    /// at most the reference's own speed: the position error's along-track part is limited
    /// to `−|ṗ_d,xy|/K_p` ([`limit_lead`]), so the velocity set-point never points backwards
    /// along the path. Without the limit the reference, its clock stopped by the large error,
    /// pulled the vehicle back into the obstacle with the full acceleration limit
    /// (`scenes/sphere_overtaking.toml`, `docs/cascade.md`).
    ///
    /// The horizontal correction `K_p·(p_d − p)` of the velocity set-point is limited to
    /// `speed_max` (the mission's cruise speed): a vehicle pushed off its reference by the
    /// filter (a person walking at it head-on) is driven back at no more than the mission's
    /// speed, not with the gain times the whole error, and a vehicle lagging a reference that
    /// moves at cruise still closes the lag (a limit on the whole set-point at cruise left a
    /// steady lag of up to `TRJ_ERR_MAX`/2: the office with `lidar`, seed 1, met printer B).
    ///
    /// `ended`: the trajectory has ended at its goal (at rest there); a vehicle pushed off the
    /// goal then steps aside ([`step_aside_at_rest`]) instead of being pulled back into what
    /// pushes it. Not while the trajectory's clock merely waits: stepping aside there made
    /// `outdoor_person` at 3 m/s 1.8 s slower.
    pub fn update_trajectory(
        &mut self,
        r: &Reference,
        pos: &Vec3,
        vel: &Vec3,
        dt_s: f32,
        speed_max: f32,
        ended: bool,
    ) -> Vec3 {
        let p = &self.params;
        let (kv, kpos) = (p.trajectory_vel_p, p.trajectory_pos_p);
        let kp = Vec3::new(kv * kpos, kv * kpos, p.kp[2]);
        let kd = Vec3::new(kv, kv, p.kd[2]);
        let ref_speed = hypotf(r.velocity.x, r.velocity.y);
        let lead_max = if kpos > 0.0 { ref_speed / kpos } else { f32::INFINITY };
        let raw = r.position - pos;
        let mut e = limit_lead(raw, &r.velocity, lead_max);
        // `e != raw` only where the reference moves (faster than MOVING_REFERENCE_SPEED).
        let moving = e != raw && ref_speed > MOVING_REFERENCE_SPEED;
        let t = if moving {
            Vec3::new(r.velocity.x / ref_speed, r.velocity.y / ref_speed, 0.0)
        } else {
            Vec3::zeros()
        };
        let excess = vel.dot(&t) - ref_speed;
        if moving && excess > 0.0 && kpos > 0.0 {
            // Pushed ahead of the moving reference and faster than it (by the filter:
            // something closing from behind, e.g. `scenes/sphere_overtaking.toml`): step aside
            // instead of being herded along the path — the cross-track pull is replaced by a
            // set-point away from the path, on the side the vehicle already is (left of the
            // travel when exactly on it), as fast as the vehicle is pushed beyond the
            // reference's speed. Once it is no longer pushed the pull returns.
            let along = e.dot(&t);
            let left = Vec3::new(-t.y, t.x, 0.0);
            let side = if (-raw).dot(&left) >= 0.0 { left } else { -left };
            let aside = side * (excess / kpos);
            e = Vec3::new(t.x * along + aside.x, t.y * along + aside.y, e.z);
        } else if ended && !moving && kpos > 0.0 {
            e = step_aside_at_rest(e, &raw, vel, kpos);
        }
        // Correction limit (horizontal): the position term K_p·e of the velocity set-point
        // v_sp = ṗ_d + K_p·e is scaled onto `speed_max`, so a vehicle behind a reference moving
        // at cruise still closes the gap (the set-point may exceed the cruise speed by at most
        // the cruise speed, as PX4's is bounded by MPC_XY_VEL_MAX above MPC_XY_CRUISE).
        if kpos > 0.0 && speed_max.is_finite() && speed_max >= 0.0 {
            let c = kpos * hypotf(e.x, e.y);
            if c > speed_max {
                let k = speed_max / c;
                e.x *= k;
                e.y *= k;
            }
        }
        let r = Reference { position: pos + e, ..*r };
        self.update_with(&r, pos, vel, dt_s, (kp, kd))
    }

    fn update_with(
        &mut self,
        r: &Reference,
        pos: &Vec3,
        vel: &Vec3,
        dt_s: f32,
        (kp, kd): (Vec3, Vec3),
    ) -> Vec3 {
        let ok = [r.position, r.velocity, r.acceleration, *pos, *vel].iter().all(is_finite3);
        self.input_fault = !ok;
        if !ok {
            return Vec3::zeros();
        }
        let p = &self.params;
        let e = r.position - pos;
        let mut u = r.acceleration + kd.component_mul(&(r.velocity - vel)) + kp.component_mul(&e);
        u.z += self.integral_z;

        // Output limits: horizontal norm, then vertical interval.
        let (z_lo, z_hi) = (-p.accel_max_up.abs(), p.accel_max_down.abs());
        let z_sat = u.z < z_lo || u.z > z_hi;
        u.z = clampf(u.z, z_lo, z_hi);
        let xy = hypotf(u.x, u.y);
        let xy_max = p.accel_max_xy.abs();
        if xy > xy_max && xy > 0.0 {
            u.x *= xy_max / xy;
            u.y *= xy_max / xy;
        }

        // Conditional integration (anti-windup): hold while saturated in the error's direction.
        if p.ki_z > 0.0 && dt_s.is_finite() && dt_s > 0.0 && dt_s <= 0.1 {
            let pushing_further = z_sat && (e.z > 0.0) == (u.z >= z_hi);
            if !pushing_further {
                let lim = p.integral_limit_z.abs();
                self.integral_z = clampf(self.integral_z + p.ki_z * e.z * dt_s, -lim, lim);
            }
        }
        if !u.iter().all(|x| x.is_finite()) {
            self.input_fault = true;
            return Vec3::zeros();
        }
        u
    }
}

/// Horizontal speed below which a reference has no direction of travel, m/s ([`limit_lead`]).
pub const MOVING_REFERENCE_SPEED: f32 = 0.05;

/// A vehicle farther than this from a reference at rest (m, horizontally) ...
pub const PUSHED_AT_REST_DISTANCE: f32 = 0.1;
/// ... and moving away from it faster than this (m/s) is being pushed off it (the safety
/// filter giving way to something closing in: the trajectory's own stop overshoots by
/// millimetres at centimetres per second).
pub const PUSHED_AT_REST_SPEED: f32 = 0.3;

/// The position error of [`PdTracker::update_trajectory`] with `ended` (the trajectory at rest at its goal): a vehicle pushed off it ([`PUSHED_AT_REST_DISTANCE`],
/// [`PUSHED_AT_REST_SPEED`]) is not pulled straight back into what pushes it — something
/// closing from behind at the goal, `scenes/sphere_overtaking.toml` with `tof8` at 1 m/s, where
/// the pull of up to the cruise speed between the filter's interventions let the sphere catch
/// the vehicle — but steps aside: the set-point is perpendicular to the push, on the side of
/// the push line the reference leaves the vehicle (left of the push when on it), at the push
/// speed. `e` is the error so far, `raw = p_d − p`; vertical untouched. Once the push stops
/// the pull returns.
fn step_aside_at_rest(e: Vec3, raw: &Vec3, vel: &Vec3, kpos: f32) -> Vec3 {
    let away = Vec3::new(-raw.x, -raw.y, 0.0);
    let d = hypotf(away.x, away.y);
    let speed = hypotf(vel.x, vel.y);
    if !(d > PUSHED_AT_REST_DISTANCE && speed > PUSHED_AT_REST_SPEED) {
        return e;
    }
    let push = Vec3::new(vel.x / speed, vel.y / speed, 0.0);
    if push.dot(&away) / d * speed <= PUSHED_AT_REST_SPEED {
        return e;
    }
    let left = Vec3::new(-push.y, push.x, 0.0);
    let side = if away.dot(&left) >= 0.0 { left } else { -left };
    let aside = side * (speed / kpos);
    Vec3::new(aside.x, aside.y, e.z)
}

/// The position error `e = p_d − p` (m) with the vehicle's lead limited: where the reference
/// moves horizontally (faster than [`MOVING_REFERENCE_SPEED`]) in direction `t`, the part of
/// `e` along `t` is raised to `−lead_max` when the vehicle is further ahead than `lead_max`
/// (m). The cross-track and vertical parts, a vehicle behind and a reference at rest are
/// unchanged. Non-finite input returns `e` unchanged (the caller screens it).
pub fn limit_lead(e: Vec3, v_d: &Vec3, lead_max: f32) -> Vec3 {
    let speed = hypotf(v_d.x, v_d.y);
    if !(speed > MOVING_REFERENCE_SPEED && speed.is_finite()) || lead_max.is_nan() {
        return e;
    }
    let t = Vec3::new(v_d.x / speed, v_d.y / speed, 0.0);
    let along = e.dot(&t);
    let floor = -lead_max.abs();
    if along < floor {
        e - t * (along - floor)
    } else {
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trajectory_cascade_hand_computed() {
        // K_p 1.5, K_v 2: u_x = a + K_v·(v_d + K_p·e − v) = 0.1 + 2·(0.3 + 1.5·1 − 0.2) = 3.3;
        // vertical: the PD gains (0.32, 0.5) on e_z = −1 − (−0.8) = −0.2, v_z 0.1: −0.114.
        let params = TrackingParams {
            ki_z: 0.0,
            trajectory_pos_p: 1.5,
            trajectory_vel_p: 2.0,
            ..TrackingParams::uniform(0.32, 0.5)
        };
        let mut t = PdTracker::new(params);
        let r = Reference {
            position: Vec3::new(1.0, 0.0, -1.0),
            velocity: Vec3::new(0.3, 0.0, 0.0),
            acceleration: Vec3::new(0.1, 0.0, 0.0),
            yaw: 0.0,
        };
        let u =
            t.update_trajectory(&r, &Vec3::new(0.0, 0.0, -0.8), &Vec3::new(0.2, 0.0, 0.1), 0.004, 5.0, false);
        assert!((u.x - 3.3).abs() < 1e-5, "{u:?}");
        assert!(u.y.abs() < 1e-6);
        assert!((u.z - (0.32 * -0.2 + 0.5 * -0.1)).abs() < 1e-6, "{u:?}");
        // The same state through the paper's PD law: 0.1 + 0.5·0.1 + 0.32·1 = 0.47.
        assert!(
            (t.update(&r, &Vec3::new(0.0, 0.0, -0.8), &Vec3::new(0.2, 0.0, 0.1), 0.004).x - 0.47).abs()
                < 1e-5
        );
    }

    /// The trajectory cascade with K_p 1, K_v 2, no integral and a wide acceleration limit.
    fn cascade() -> PdTracker {
        PdTracker::new(TrackingParams {
            ki_z: 0.0,
            accel_max_xy: 20.0,
            trajectory_pos_p: 1.0,
            trajectory_vel_p: 2.0,
            ..TrackingParams::uniform(0.32, 0.5)
        })
    }

    #[test]
    fn a_vehicle_pushed_ahead_is_pulled_back_by_at_most_the_reference_speed() {
        // Reference at x = 1 moving +x at 0.3 m/s; vehicle 4 m ahead at 1 m/s. K_p 1, K_v 2:
        // unlimited, u_x = 2·(0.3 + 1·(1 − 5) − 1) = −9.4 (saturated); limited, the along-track
        // error is −0.3 m, so u_x = 2·(0.3 − 0.3 − 1) = −2.
        let mut t = cascade();
        let r = Reference {
            position: Vec3::new(1.0, 0.0, -1.0),
            velocity: Vec3::new(0.3, 0.0, 0.0),
            acceleration: Vec3::zeros(),
            yaw: 0.0,
        };
        let (pos, vel) = (Vec3::new(5.0, 0.5, -1.0), Vec3::new(1.0, 0.0, 0.0));
        let u = t.update_trajectory(&r, &pos, &vel, 0.004, 50.0, false);
        assert!((u.x + 2.0).abs() < 1e-5, "{u:?}");
        // Pushed faster than the reference, it steps aside on its side (+y) at the excess
        // speed: 2·(1 − 0.3)/1 = 1.4 (`pushed_ahead_steps_aside_and_a_lag_at_cruise_closes`).
        assert!((u.y - 1.4).abs() < 1e-5, "{u:?}");
        // Behind the reference, or a reference at rest: the full error.
        let behind = Vec3::new(-3.0, 0.0, -1.0);
        let u = t.update_trajectory(&r, &behind, &Vec3::zeros(), 0.004, 50.0, false);
        assert!((u.x - 2.0 * (0.3 + 4.0)).abs() < 1e-5, "{u:?}");
        let rest = Reference { velocity: Vec3::zeros(), ..r };
        let u = t.update_trajectory(&rest, &pos, &Vec3::zeros(), 0.004, 50.0, false);
        assert!((u.x - 2.0 * -4.0).abs() < 1e-5, "{u:?}");
    }

    #[test]
    fn the_correction_is_limited_to_the_mission_speed() {
        // Reference at rest at x = 1, vehicle 3 m behind, at rest; K_p 1, K_v 2, speed 0.5:
        // v_sp = 3 m/s unlimited (u_x = 6), 0.5 m/s limited (u_x = 1).
        let mut t = cascade();
        let r = Reference { position: Vec3::new(1.0, 0.0, -1.0), ..Reference::default() };
        let pos = Vec3::new(-2.0, 0.0, -1.0);
        let u = t.update_trajectory(&r, &pos, &Vec3::zeros(), 0.004, 0.5, false);
        assert!((u.x - 1.0).abs() < 1e-5, "{u:?}");
        let u = t.update_trajectory(&r, &pos, &Vec3::zeros(), 0.004, 50.0, false);
        assert!((u.x - 6.0).abs() < 1e-5, "{u:?}");
        // The limit bounds the correction, not the reference's own speed: behind a reference
        // at 2 m/s, v_sp = 2 + 0.5, u_x = 2·2.5 = 5.
        let fast = Reference { velocity: Vec3::new(2.0, 0.0, 0.0), ..r };
        let u = t.update_trajectory(&fast, &pos, &Vec3::zeros(), 0.004, 0.5, false);
        assert!((u.x - 5.0).abs() < 1e-5, "{u:?}");
    }

    #[test]
    fn limit_lead_changes_only_a_lead_beyond_the_limit() {
        let v = Vec3::new(0.0, 2.0, 0.0);
        assert_eq!(limit_lead(Vec3::new(1.0, -3.0, 0.5), &v, 1.0), Vec3::new(1.0, -1.0, 0.5));
        assert_eq!(limit_lead(Vec3::new(1.0, -0.5, 0.5), &v, 1.0), Vec3::new(1.0, -0.5, 0.5));
        assert_eq!(limit_lead(Vec3::new(1.0, 3.0, 0.5), &v, 1.0), Vec3::new(1.0, 3.0, 0.5));
        assert_eq!(limit_lead(Vec3::new(1.0, -3.0, 0.5), &Vec3::new(0.0, 0.01, 5.0), 0.0).y, -3.0);
        let nan = Vec3::new(f32::NAN, 0.0, 0.0);
        assert_eq!(limit_lead(Vec3::new(1.0, -3.0, 0.5), &nan, 1.0), Vec3::new(1.0, -3.0, 0.5));
    }

    #[test]
    fn pd_law_hand_computed() {
        let mut t = PdTracker::new(TrackingParams { ki_z: 0.0, ..TrackingParams::uniform(0.32, 0.5) });
        let r = Reference {
            position: Vec3::new(1.0, 0.0, -1.0),
            velocity: Vec3::new(0.3, 0.0, 0.0),
            acceleration: Vec3::new(0.1, 0.0, 0.0),
            yaw: 0.0,
        };
        let u = t.update(&r, &Vec3::new(0.5, 0.2, -1.0), &Vec3::new(0.1, 0.0, 0.0), 0.01);
        // x: 0.1 + 0.5·0.2 + 0.32·0.5 = 0.36; y: 0.32·(−0.2) = −0.064.
        assert!((u - Vec3::new(0.36, -0.064, 0.0)).norm() < 1e-6);
    }

    #[test]
    fn limits_and_nan() {
        let mut t = PdTracker::new(TrackingParams::uniform(10.0, 0.0));
        let r = Reference { position: Vec3::new(10.0, 10.0, -10.0), ..Reference::default() };
        let u = t.update(&r, &Vec3::zeros(), &Vec3::zeros(), 0.01);
        assert!((libm::hypotf(u.x, u.y) - 4.0).abs() < 1e-5);
        assert!((u.z + 4.0).abs() < 1e-6);
        let u = t.update(&r, &Vec3::new(f32::NAN, 0.0, 0.0), &Vec3::zeros(), 0.01);
        assert_eq!(u, Vec3::zeros());
        assert!(t.input_fault());
    }

    #[test]
    fn integrator_removes_vertical_bias_and_does_not_wind_up() {
        let mut t = PdTracker::new(TrackingParams::default());
        let r = Reference { position: Vec3::new(0.0, 0.0, -1.0), ..Reference::default() };
        // Vehicle 0.1 m low (z = −0.9): integral pushes up (negative), bounded.
        for _ in 0..10_000 {
            t.update(&r, &Vec3::new(0.0, 0.0, -0.9), &Vec3::zeros(), 0.01);
        }
        assert!(t.integral_z() < 0.0);
        assert!(t.integral_z() >= -1.0 - 1e-6);
    }

    /// Pushed ahead of a moving reference faster than it, the vehicle steps aside (on its
    /// side of the path, as fast as it is pushed beyond the reference's speed); at the
    /// reference's speed the cross-track error pulls it back; behind, a lag at cruise closes
    /// (the correction, not the whole set-point, is limited to the cruise speed).
    #[test]
    fn pushed_ahead_steps_aside_and_a_lag_at_cruise_closes() {
        let params = TrackingParams { ki_z: 0.0, ..TrackingParams::default() };
        let r = Reference {
            position: Vec3::new(0.0, 0.0, -1.0),
            velocity: Vec3::new(0.3, 0.0, 0.0),
            acceleration: Vec3::zeros(),
            yaw: 0.0,
        };
        let pos = Vec3::new(1.0, 0.05, -1.0);
        let mut t = PdTracker::new(params);
        // K_v 2, K_p 1: aside set-point (1.0 − 0.3)/1 = 0.7 m/s → u_y = 2·0.7 = 1.4.
        // (Cruise 5 m/s here, so the correction limit does not act.) Along the path: the lead
        // limited to 0.3 m, u_x = 2·(0.3 − 0.3 − 1) = −2.
        let pushed = t.update_trajectory(&r, &pos, &Vec3::new(1.0, 0.0, 0.0), 0.004, 5.0, false);
        assert!((pushed.y - 1.4).abs() < 1e-4 && (pushed.x + 2.0).abs() < 1e-4, "{pushed:?}");
        let mirrored = t.update_trajectory(
            &r,
            &Vec3::new(1.0, -0.05, -1.0),
            &Vec3::new(1.0, 0.0, 0.0),
            0.004,
            5.0,
            false,
        );
        assert!((mirrored.y + 1.4).abs() < 1e-4, "{mirrored:?}");
        // Not pushed (at the reference's speed): pulled back towards the path, −2·1·0.05.
        let held = t.update_trajectory(&r, &pos, &Vec3::new(0.3, 0.0, 0.0), 0.004, 5.0, false);
        assert!((held.y + 0.1).abs() < 1e-4, "{held:?}");
        // With cruise 0.3 m/s the whole correction (lead and aside) is scaled onto 0.3 m/s.
        let slow = t.update_trajectory(&r, &pos, &Vec3::new(1.0, 0.0, 0.0), 0.004, 0.3, false);
        let k = 0.3 / libm::hypotf(0.3, 0.7);
        assert!((slow.y - 2.0 * 0.7 * k).abs() < 1e-4, "{slow:?}");
        // 0.2 m behind a reference at cruise (0.3 m/s), at its speed: u_x = 2·(1·0.2) = 0.4.
        let lag = t.update_trajectory(
            &r,
            &Vec3::new(-0.2, 0.0, -1.0),
            &Vec3::new(0.3, 0.0, 0.0),
            0.004,
            0.3,
            false,
        );
        assert!((lag.x - 0.4).abs() < 1e-4, "{lag:?}");
    }

    /// At a reference at rest (the goal), a vehicle pushed away from it faster than 0.3 m/s
    /// steps aside instead of being pulled back through what pushes it; slower, or closer
    /// than 0.1 m, it is pulled back as before.
    #[test]
    fn pushed_off_a_reference_at_rest_steps_aside() {
        let params = TrackingParams { ki_z: 0.0, ..TrackingParams::default() };
        let r = Reference { position: Vec3::new(0.0, 0.0, -1.0), ..Reference::default() };
        let mut t = PdTracker::new(params);
        // 1 m past the goal along +x, 0.05 m to its right (+y), pushed at 0.8 m/s along +x:
        // K_v 2, K_p 1, set-point 0.8 m/s perpendicular to the push on the vehicle's side
        // (+y): u = 2·(0.8·ŷ − 0.8·x̂) = (−1.6, 1.6).
        let pos = Vec3::new(1.0, 0.05, -1.0);
        let pushed = t.update_trajectory(&r, &pos, &Vec3::new(0.8, 0.0, 0.0), 0.004, 5.0, true);
        assert!((pushed.x + 1.6).abs() < 1e-4 && (pushed.y - 1.6).abs() < 1e-4, "{pushed:?}");
        // While the trajectory runs (its clock waiting, say), the same state is pulled back:
        // u = 2·((−1, −0.05) − (0.8, 0)) = (−3.6, −0.1).
        let waiting = t.update_trajectory(&r, &pos, &Vec3::new(0.8, 0.0, 0.0), 0.004, 5.0, false);
        assert!((waiting.x + 3.6).abs() < 1e-4 && (waiting.y + 0.1).abs() < 1e-4, "{waiting:?}");
        let mirrored = t.update_trajectory(
            &r,
            &Vec3::new(1.0, -0.05, -1.0),
            &Vec3::new(0.8, 0.0, 0.0),
            0.004,
            5.0,
            true,
        );
        assert!((mirrored.y + 1.6).abs() < 1e-4, "{mirrored:?}");
        // Drifting away at 0.2 m/s: pulled back, u_x = 2·(1·(−1) − 0.2) = −2.4.
        let slow = t.update_trajectory(&r, &pos, &Vec3::new(0.2, 0.0, 0.0), 0.004, 5.0, true);
        assert!((slow.x + 2.4).abs() < 1e-4, "{slow:?}");
        // Coming back at 0.8 m/s: not pushed, u_x = 2·(−1 + 0.8) = −0.4.
        let back = t.update_trajectory(&r, &pos, &Vec3::new(-0.8, 0.0, 0.0), 0.004, 5.0, true);
        assert!((back.x + 0.4).abs() < 1e-4, "{back:?}");
        // 5 cm off (the trajectory's own stop): pulled back, u_x = 2·(−0.05 − 0.8) = −1.7.
        let near =
            t.update_trajectory(&r, &Vec3::new(0.05, 0.0, -1.0), &Vec3::new(0.8, 0.0, 0.0), 0.004, 5.0, true);
        assert!((near.x + 1.7).abs() < 1e-4, "{near:?}");
    }
}
