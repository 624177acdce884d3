//! The piloted references (issue 21): Manual-attitude sticks → attitude and thrust setpoint
//! (no safety filter), and the velocity-setpoint reference shared by Position assist (sticks →
//! horizontal velocity in the heading frame + climb rate) and Offboard velocity setpoints.
//!
//! The velocity reference moves a target point with the commanded velocity and keeps it
//! within a leash of the vehicle ([`LEASH_XY_M`], [`LEASH_Z_M`]): centred sticks leave the
//! target where it is (position hold), and a vehicle stopped by the safety filter in front
//! of a wall does not wind the target up into the wall — the PD law's push stays bounded by
//! `kp·leash + kd·|v_sp|`, which the filter removes or turns into a slide.
//!
//! May import: the crate root foundation, [`crate::msg`], [`crate::rc`] (through
//! [`crate::supervisor::modes`]), [`super::tracking`], [`super::thrust`].

use super::thrust::ThrustParams;
use super::tracking::Reference;
use crate::fmath::{maxf, minf, norm3, sincosf, sqrtf};
use crate::frame::GRAVITY;
use crate::msg::AttitudeSetpoint;
use crate::rc::RcInput;
use crate::supervisor::modes::ModeParams;
use crate::Vec3;

/// Largest horizontal distance of the velocity reference's target from the vehicle, m.
pub const LEASH_XY_M: f32 = 0.5;
/// Largest vertical distance of the velocity reference's target from the vehicle, m.
pub const LEASH_Z_M: f32 = 0.3;

/// `x` with a deadband `db` around 0, rescaled so full deflection stays 1.
pub fn deadband(x: f32, db: f32) -> f32 {
    let a = x.abs();
    if a <= db || db >= 1.0 {
        return 0.0;
    }
    let y = minf((a - db) / (1.0 - db), 1.0);
    if x < 0.0 {
        -y
    } else {
        y
    }
}

/// Position assist: the stick velocity setpoint, NED m/s. Pitch forward / roll right in the
/// heading frame of `yaw` (horizontal speed ≤ `assist_speed`, also diagonally), throttle
/// above 0.5 climbs (≤ `assist_climb`).
pub fn stick_velocity(p: &ModeParams, rc: &RcInput, yaw: f32) -> Vec3 {
    let mut f = deadband(rc.pitch, p.deadband);
    let mut r = deadband(rc.roll, p.deadband);
    let n = sqrtf(f * f + r * r);
    if n > 1.0 {
        f /= n;
        r /= n;
    }
    let (s, c) = sincosf(yaw);
    let climb = deadband(2.0 * (rc.throttle - 0.5), p.deadband) * p.assist_climb;
    Vec3::new((c * f - s * r) * p.assist_speed, (s * f + c * r) * p.assist_speed, -climb)
}

/// Yaw rate from the yaw stick, rad/s (> 0 clockwise from above).
pub fn stick_yaw_rate(p: &ModeParams, rc: &RcInput) -> f32 {
    deadband(rc.yaw, p.deadband) * p.yaw_rate_max
}

/// `yaw` wrapped to (−π, π].
pub fn wrap_pi(yaw: f32) -> f32 {
    use core::f32::consts::PI;
    let mut y = yaw;
    // Bounded: the callers add at most a few rad per step.
    for _ in 0..4 {
        if y > PI {
            y -= 2.0 * PI;
        } else if y <= -PI {
            y += 2.0 * PI;
        }
    }
    if y.is_finite() {
        y
    } else {
        0.0
    }
}

/// Manual attitude: roll/pitch proportional to the sticks (up to `manual_tilt_max`), the
/// yaw setpoint `yaw`, thrust from the throttle with hover thrust at mid stick (0 → the
/// thrust map's minimum, 1 → its maximum).
pub fn manual_setpoint(
    p: &ModeParams,
    t: &ThrustParams,
    mass: f32,
    rc: &RcInput,
    yaw: f32,
) -> AttitudeSetpoint {
    let tilt = minf(p.manual_tilt_max, t.tilt_max);
    let hover = mass * GRAVITY;
    let thr = rc.throttle;
    let thrust = if thr <= 0.5 {
        t.thrust_min + (hover - t.thrust_min) * 2.0 * thr
    } else {
        hover + (t.thrust_max - hover) * 2.0 * (thr - 0.5)
    };
    AttitudeSetpoint {
        roll: rc.roll * tilt,
        // Pitch stick forward (> 0) is nose down: negative FRD pitch.
        pitch: -rc.pitch * tilt,
        yaw: wrap_pi(yaw),
        thrust: minf(maxf(thrust, t.thrust_min), t.thrust_max),
        saturated: false,
    }
}

/// The velocity-setpoint reference (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct VelocityRef {
    target: Vec3,
}

impl VelocityRef {
    /// Start at `p` (the vehicle's position: hold it).
    pub fn start(&mut self, p: Vec3) {
        self.target = p;
    }

    /// The target point, NED m.
    pub fn target(&self) -> Vec3 {
        self.target
    }

    /// One step of `dt` s with the velocity setpoint `v_sp` (NED m/s) and the vehicle at `p`:
    /// the target moves with `v_sp` and stays within the leash of `p`.
    pub fn step(&mut self, v_sp: &Vec3, p: &Vec3, dt: f32, yaw: f32) -> Reference {
        let mut t = self.target + v_sp * dt;
        let d = t - p;
        let dxy = sqrtf(d.x * d.x + d.y * d.y);
        if dxy > LEASH_XY_M {
            let k = LEASH_XY_M / dxy;
            t.x = p.x + d.x * k;
            t.y = p.y + d.y * k;
        }
        t.z = p.z + d.z.clamp(-LEASH_Z_M, LEASH_Z_M);
        if !(norm3(&t).is_finite()) {
            t = *p;
        }
        self.target = t;
        Reference { position: t, velocity: *v_sp, acceleration: Vec3::zeros(), yaw }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rc(roll: f32, pitch: f32, yaw: f32, throttle: f32) -> RcInput {
        RcInput { roll, pitch, yaw, throttle, ..RcInput::default() }
    }

    #[test]
    fn sticks_map_to_heading_frame_velocity_with_deadband() {
        let p = ModeParams::default();
        let v = stick_velocity(&p, &rc(0.0, 1.0, 0.0, 0.5), 0.0);
        assert!((v - Vec3::new(1.0, 0.0, 0.0)).norm() < 1e-6, "{v:?}");
        // Heading east: forward is east, right is south.
        let v = stick_velocity(&p, &rc(1.0, 0.0, 0.0, 0.5), core::f32::consts::FRAC_PI_2);
        assert!((v - Vec3::new(-1.0, 0.0, 0.0)).norm() < 1e-5, "{v:?}");
        // Diagonal: limited to the max speed.
        let v = stick_velocity(&p, &rc(1.0, 1.0, 0.0, 0.5), 0.0);
        assert!((norm3(&v) - 1.0).abs() < 1e-5);
        // Inside the deadband: zero; full throttle climbs (NED z < 0).
        assert_eq!(stick_velocity(&p, &rc(0.04, -0.04, 0.0, 0.52), 0.0), Vec3::zeros());
        assert!((stick_velocity(&p, &rc(0.0, 0.0, 0.0, 1.0), 0.0).z + 0.5).abs() < 1e-6);
        assert!((stick_yaw_rate(&p, &rc(0.0, 0.0, -1.0, 0.5)) + 1.0).abs() < 1e-6);
    }

    #[test]
    fn manual_maps_tilt_and_hover_at_mid_throttle() {
        let p = ModeParams::default();
        let t = ThrustParams::default();
        let sp = manual_setpoint(&p, &t, 0.5, &rc(1.0, 1.0, 0.0, 0.5), 0.3);
        assert!((sp.roll - 0.35).abs() < 1e-6 && (sp.pitch + 0.35).abs() < 1e-6);
        assert!((sp.thrust - 0.5 * GRAVITY).abs() < 1e-4);
        assert_eq!(manual_setpoint(&p, &t, 0.5, &rc(0.0, 0.0, 0.0, 1.0), 0.0).thrust, t.thrust_max);
        assert_eq!(manual_setpoint(&p, &t, 0.5, &rc(0.0, 0.0, 0.0, 0.0), 0.0).thrust, t.thrust_min);
    }

    #[test]
    fn velocity_reference_holds_when_centred_and_stays_on_the_leash() {
        let mut r = VelocityRef::default();
        r.start(Vec3::new(1.0, 2.0, -1.0));
        let p = Vec3::new(1.0, 2.0, -1.0);
        for _ in 0..1000 {
            r.step(&Vec3::new(1.0, 0.0, 0.0), &p, 0.004, 0.0);
        }
        assert!((r.target() - Vec3::new(1.5, 2.0, -1.0)).norm() < 1e-5, "{:?}", r.target());
        let before = r.target();
        let out = r.step(&Vec3::zeros(), &p, 0.004, 0.0);
        assert_eq!(out.position, before, "centred sticks hold the target");
        assert!((wrap_pi(3.3) - (3.3 - 2.0 * core::f32::consts::PI)).abs() < 1e-6);
        assert_eq!(wrap_pi(f32::NAN), 0.0);
    }
}
