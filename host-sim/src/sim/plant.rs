//! Full rigid-body 6-DOF quadrotor plant, integrated with fixed-step RK4.
//!
//! ## Frames and units
//! World frame **NED** (x north, y east, z down), body frame **FRD**, SI units,
//! exactly as [`parapet_core::frame`]. The attitude quaternion `q` rotates body
//! vectors into the world frame (`v_world = q * v_body`). Body rates `ω_b`
//! (p, q, r) are in FRD, rad/s. The plant integrates in `f64`; the controller
//! works in `f32`.
//!
//! ## Model
//! * Rotor `i` (layout and spin directions from [`parapet_core::airframe`],
//!   rotors 1..4 = index 0..4: front-right CCW, rear-left CCW, front-left CW,
//!   rear-right CW) produces thrust `f_i = k_f ω_i²` along body −z and a
//!   reaction (drag) torque `ROTOR_YAW_SIGN[i] · k_m ω_i²` about body z.
//! * Rotor speed follows its command with first-order lag:
//!   `ω̇_i = (ω_cmd,i − ω_i) / τ_motor`, the command clamped to
//!   `[omega_min, omega_max]`.
//! * Translation: `m v̇ = R (F_thrust + F_drag) + m g e_z`, with linear body
//!   drag `F_drag = −diag(drag) · v_a`, `v_a = Rᵀ (v − w)` the **air-relative**
//!   velocity in the body frame (`w` the wind, NED, set with [`Plant::set_wind`]
//!   and held over a step; zero by default: air at rest).
//! * Aerodynamics (RotorPy's `Multirotor` model, off when its coefficients are 0):
//!   rotor drag ("H-force") at each hub, `H_i = −ω_i diag(k_d, k_d, k_z) v_i` with
//!   `v_i = v_a + ω_b × r_i` the air velocity at rotor i (`r_i` its hub, body z = 0),
//!   its moment `r_i × H_i` about the centre of mass, and quadratic parasitic
//!   drag `D = −|v_a| diag(c_D) v_a` at the centre of mass.
//! * Rotor fault: each rotor's thrust can be scaled ([`Plant::set_rotor_scale`]).
//! * Rotation: Euler's equations with the gyroscopic term,
//!   `I ω̇ = τ − ω × (I ω)`; `q̇ = ½ q ⊗ (0, ω)`. Rotor inertia (the rotors' own
//!   gyroscopic and spin-up reaction torques) is neglected.
//! * **Ground contact**: the ground is the plane z = 0 (NED; z > 0 is below
//!   ground). After each step a vehicle at or below the ground is put back on
//!   it (z = 0) and loses any downward velocity (perfectly inelastic impact);
//!   if moreover the net vertical force does not lift it (world z-acceleration
//!   ≥ 0, i.e. not upwards), it rests: v = 0, ω = 0, attitude unchanged (no
//!   slip, no tipping). A vehicle producing lift leaves the ground normally.
//!   (The runner counts touching the ground with the hull as a collision.)
//! * Integration: classic fixed-step RK4 of the 17-dimensional state
//!   (p, v, q, ω_b, rotor speeds), the quaternion renormalised after each step.
//!   The step (default 1 ms, 1 kHz) is a parameter of [`Plant::step`].
//!
//! May import: `parapet-core` (airframe, frame), nalgebra, serde, [`crate::input`].

use nalgebra::{SVector, UnitQuaternion, Vector3};
use parapet_core::airframe::{Airframe, ROTOR_XY_UNIT, ROTOR_YAW_SIGN};
use serde::{Deserialize, Serialize};

/// Standard gravity, m/s² (world +z, NED).
pub const GRAVITY: f64 = parapet_core::frame::GRAVITY as f64;

/// Vehicle parameters of the plant. Loadable from a scene's `[vehicle]` table
/// or a vehicle TOML file (same keys); missing keys take the defaults below,
/// unknown keys are errors.
///
/// Defaults: the paper's vehicle (m = 0.5 kg, I = diag(0.0019, 0.0019, 0.0033))
/// with plausible values for its size (0.35 × 0.30 m frame): arm 0.13 m,
/// ω_max = 1200 rad/s, `k_f` such that one rotor gives 3.07 N at ω_max
/// (thrust-to-weight ≈ 2.5, [`Airframe::default`]), `k_m = 0.016 k_f`,
/// motor time constant 0.02 s, linear drag 0.1 N·s/m per body axis, hull
/// (bounding-sphere) radius √0.05 = 0.2236 m.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VehicleParams {
    /// Mass, kg.
    pub mass: f64,
    /// Principal moments of inertia (Ix, Iy, Iz) about the FRD body axes, kg·m².
    #[serde(deserialize_with = "crate::input::exact::array")]
    pub inertia: [f64; 3],
    /// Distance from the centre of mass to each rotor axis, m.
    pub arm_length: f64,
    /// Maximum rotor speed, rad/s (throttle 1).
    pub omega_max: f64,
    /// Minimum rotor speed the ESC holds when armed, rad/s (commands below are raised to it).
    pub omega_min: f64,
    /// Rotor thrust coefficient, N/(rad/s)²: `f = k_f ω²`.
    pub k_f: f64,
    /// Rotor drag-torque coefficient, N·m/(rad/s)²: `τ = k_m ω²`.
    pub k_m: f64,
    /// First-order motor time constant, s.
    pub motor_tau: f64,
    /// Linear body drag coefficients along the FRD body axes, N/(m/s).
    #[serde(deserialize_with = "crate::input::exact::array")]
    pub drag: [f64; 3],
    /// Radius of the sphere bounding the vehicle (collision hull), m.
    pub hull_radius: f64,
    /// Rotor drag ("H-force") coefficient in the rotor plane, N/(rad/s · m/s) (RotorPy's
    /// `k_d`); default 0 (off).
    pub rotor_drag_kd: f64,
    /// Rotor drag coefficient along the rotor axis (induced inflow), N/(rad/s · m/s)
    /// (RotorPy's `k_z`); default 0 (off).
    pub rotor_drag_kz: f64,
    /// Quadratic parasitic drag along the FRD body axes, N/(m/s)² (RotorPy's `c_Dx`,
    /// `c_Dy`, `c_Dz`); default 0 (off).
    #[serde(deserialize_with = "crate::input::exact::array")]
    pub parasitic_drag: [f64; 3],
}

impl Default for VehicleParams {
    fn default() -> Self {
        let af = Airframe::default();
        let omega_max = 1200.0;
        let k_f = af.rotor_thrust_max as f64 / (omega_max * omega_max);
        VehicleParams {
            mass: 0.5,
            inertia: [0.0019, 0.0019, 0.0033],
            arm_length: 0.13,
            omega_max,
            omega_min: 0.0,
            k_f,
            k_m: 0.016 * k_f,
            motor_tau: 0.02,
            drag: [0.1, 0.1, 0.1],
            hull_radius: 0.05f64.sqrt(),
            rotor_drag_kd: 0.0,
            rotor_drag_kz: 0.0,
            parasitic_drag: [0.0; 3],
        }
    }
}

/// An invalid vehicle parameter: the field name and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("vehicle field `{field}`: {reason}")]
pub struct ParamError {
    /// Name of the offending field (as in the TOML table).
    pub field: &'static str,
    /// What is wrong with it.
    pub reason: String,
}

impl VehicleParams {
    /// Check every value is finite and in range; names the first bad field.
    pub fn validate(&self) -> Result<(), ParamError> {
        let pos = |field: &'static str, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(ParamError { field, reason: format!("must be finite and > 0, got {x}") })
            }
        };
        let nonneg = |field: &'static str, x: f64| {
            if x.is_finite() && x >= 0.0 {
                Ok(())
            } else {
                Err(ParamError { field, reason: format!("must be finite and >= 0, got {x}") })
            }
        };
        pos("mass", self.mass)?;
        for &i in &self.inertia {
            pos("inertia", i)?;
        }
        pos("arm_length", self.arm_length)?;
        pos("omega_max", self.omega_max)?;
        nonneg("omega_min", self.omega_min)?;
        if self.omega_min >= self.omega_max {
            return Err(ParamError { field: "omega_min", reason: "must be < omega_max".into() });
        }
        pos("k_f", self.k_f)?;
        nonneg("k_m", self.k_m)?;
        pos("motor_tau", self.motor_tau)?;
        for &d in &self.drag {
            nonneg("drag", d)?;
        }
        pos("hull_radius", self.hull_radius)?;
        nonneg("rotor_drag_kd", self.rotor_drag_kd)?;
        nonneg("rotor_drag_kz", self.rotor_drag_kz)?;
        for &c in &self.parasitic_drag {
            nonneg("parasitic_drag", c)?;
        }
        let t_max = 4.0 * self.k_f * self.omega_max * self.omega_max;
        if t_max <= self.mass * GRAVITY {
            return Err(ParamError {
                field: "k_f",
                reason: format!(
                    "the four rotors give at most {t_max:.3} N, not more than the weight {:.3} N",
                    self.mass * GRAVITY
                ),
            });
        }
        Ok(())
    }

    /// Thrust of one rotor at `omega_max`, N.
    pub fn rotor_thrust_max(&self) -> f64 {
        self.k_f * self.omega_max * self.omega_max
    }

    /// Rotor speed at which the four rotors together carry the weight, rad/s.
    pub fn hover_omega(&self) -> f64 {
        (self.mass * GRAVITY / (4.0 * self.k_f)).sqrt()
    }

    /// Rotor positions in the body FRD x-y plane, m (index 0..4 = rotors 1..4).
    pub fn rotor_positions(&self) -> [[f64; 2]; 4] {
        let a = self.arm_length / 2f64.sqrt();
        ROTOR_XY_UNIT.map(|[x, y]| [x as f64 * a, y as f64 * a])
    }

    /// Whether any aerodynamic term beyond the linear body drag is on.
    pub fn has_aero(&self) -> bool {
        self.rotor_drag_kd != 0.0
            || self.rotor_drag_kz != 0.0
            || self.parasitic_drag.iter().any(|&c| c != 0.0)
    }

    /// The airframe description the controller needs (f32).
    pub fn airframe(&self) -> Airframe {
        Airframe {
            mass: self.mass as f32,
            inertia: self.inertia.map(|x| x as f32),
            arm_length: self.arm_length as f32,
            rotor_thrust_max: self.rotor_thrust_max() as f32,
            torque_to_thrust: (self.k_m / self.k_f) as f32,
        }
    }
}

/// Plant state. Position/velocity world NED (m, m/s); `att` body FRD → world NED;
/// `rates` body FRD (rad/s); `rotor` rotor speeds (rad/s, index 0..4 = rotors 1..4).
#[derive(Clone, Debug, PartialEq)]
pub struct PlantState {
    /// Position of the centre of mass, NED, m.
    pub pos: Vector3<f64>,
    /// Velocity, NED, m/s.
    pub vel: Vector3<f64>,
    /// Attitude, rotation body FRD → world NED.
    pub att: UnitQuaternion<f64>,
    /// Body rates (p, q, r), FRD, rad/s.
    pub rates: Vector3<f64>,
    /// Rotor speeds, rad/s.
    pub rotor: [f64; 4],
}

impl Default for PlantState {
    fn default() -> Self {
        PlantState {
            pos: Vector3::zeros(),
            vel: Vector3::zeros(),
            att: UnitQuaternion::identity(),
            rates: Vector3::zeros(),
            rotor: [0.0; 4],
        }
    }
}

type X = SVector<f64, 17>;

/// What the state derivative needs besides the state, fixed during one step:
/// the vehicle parameters in the form the equations use and the clamped
/// rotor-speed commands.
#[derive(Clone, Copy, Debug)]
struct Consts {
    /// Thrust coefficient of each rotor (`k_f` times its fault scale), N/(rad/s)².
    k_f: [f64; 4],
    /// `ROTOR_YAW_SIGN[i] · k_m`, N·m/(rad/s)².
    yaw_k_m: [f64; 4],
    /// Roll moment arm of rotor i, `−y_i`, m.
    roll_arm: [f64; 4],
    /// Pitch moment arm of rotor i, `x_i`, m.
    pitch_arm: [f64; 4],
    /// Rotor-speed commands clamped to `[omega_min, omega_max]`, rad/s.
    cmd: [f64; 4],
    /// `1 / τ_motor`, 1/s.
    inv_motor_tau: f64,
    /// Linear body drag, N/(m/s).
    drag: [f64; 3],
    /// The drag coefficient when it is the same on the three axes.
    iso_drag: Option<f64>,
    /// `1 / m`, 1/kg.
    inv_mass: f64,
    /// Principal moments of inertia, kg·m².
    inertia: [f64; 3],
    /// Their reciprocals, 1/(kg·m²).
    inv_inertia: [f64; 3],
    /// Wind velocity, NED, m/s (held over a step).
    wind: [f64; 3],
    /// The aerodynamic terms, when any is on.
    aero: Option<Aero>,
}

/// The aerodynamic coefficients of [`Consts`] (see the module docs).
#[derive(Clone, Copy, Debug)]
struct Aero {
    /// Rotor drag in the rotor plane, N/(rad/s · m/s).
    kd: f64,
    /// Rotor drag along the rotor axis, N/(rad/s · m/s).
    kz: f64,
    /// Quadratic parasitic drag per body axis, N/(m/s)².
    cd: [f64; 3],
    /// Rotor hub positions, body FRD, m (z = 0).
    hub: [[f64; 2]; 4],
}

/// Rotation matrix (body → world) of the quaternion `(w, x, y, z)` after
/// normalisation, as `[row0, row1, row2]`. Equal (to round-off) to
/// `UnitQuaternion::from_quaternion(q).to_rotation_matrix()`, without forming
/// the unit quaternion: `R(q) = R̃(q) / |q|²` with `R̃` the homogeneous form.
#[inline(always)]
fn rotation(w: f64, x: f64, y: f64, z: f64) -> [[f64; 3]; 3] {
    let s = 1.0 / (w * w + x * x + y * y + z * z);
    let (ww, xx, yy, zz) = (w * w, x * x, y * y, z * z);
    let (xy, wz, wy, xz, yz, wx) = (x * y, w * z, w * y, x * z, y * z, w * x);
    [
        [(ww + xx - yy - zz) * s, 2.0 * (xy - wz) * s, 2.0 * (wy + xz) * s],
        [2.0 * (wz + xy) * s, (ww - xx + yy - zz) * s, 2.0 * (yz - wx) * s],
        [2.0 * (xz - wy) * s, 2.0 * (wx + yz) * s, (ww - xx - yy + zz) * s],
    ]
}

impl Consts {
    /// The constants for vehicle `p` and rotor-speed commands `omega_cmd` (rad/s).
    fn new(p: &VehicleParams, omega_cmd: &[f64; 4]) -> Self {
        let pos = p.rotor_positions();
        Consts {
            k_f: [p.k_f; 4],
            yaw_k_m: ROTOR_YAW_SIGN.map(|s| s as f64 * p.k_m),
            roll_arm: pos.map(|r| -r[1]),
            pitch_arm: pos.map(|r| r[0]),
            cmd: omega_cmd.map(|c| c.clamp(p.omega_min, p.omega_max)),
            inv_motor_tau: 1.0 / p.motor_tau,
            drag: p.drag,
            iso_drag: (p.drag[0] == p.drag[1] && p.drag[1] == p.drag[2]).then_some(p.drag[0]),
            inv_mass: 1.0 / p.mass,
            inertia: p.inertia,
            inv_inertia: p.inertia.map(|i| 1.0 / i),
            wind: [0.0; 3],
            aero: p.has_aero().then_some(Aero {
                kd: p.rotor_drag_kd,
                kz: p.rotor_drag_kz,
                cd: p.parasitic_drag,
                hub: pos,
            }),
        }
    }

    /// Collective thrust (N, along body −z) of the rotor speeds `w`.
    #[inline(always)]
    fn thrust(&self, w: &[f64; 4]) -> f64 {
        let mut thrust = 0.0;
        for (k_f, wi) in self.k_f.iter().zip(w) {
            thrust += k_f * wi * wi;
        }
        thrust
    }

    /// Acceleration of the centre of mass (NED, m/s²) at velocity `v`, attitude
    /// quaternion `q` = (w, i, j, k) (normalised here) and collective thrust
    /// `thrust`: `R (F_thrust + F_drag) / m + g e_z` with `F_drag = −D Rᵀ (v − wind)`.
    /// With the same drag on every axis `R D Rᵀ = d I`, and only the body z axis
    /// `R e_z` is needed. (Without the aerodynamic terms; see [`Self::aero_accel`].)
    #[inline(always)]
    fn accel_of(&self, v: [f64; 3], q: [f64; 4], thrust: f64) -> Vector3<f64> {
        let m = self.inv_mass;
        let wind = self.wind;
        let v = [v[0] - wind[0], v[1] - wind[1], v[2] - wind[2]];
        if let Some(d) = self.iso_drag {
            let [w, x, y, z] = q;
            let s = 1.0 / (w * w + x * x + y * y + z * z);
            let ez =
                [2.0 * (w * y + x * z) * s, 2.0 * (y * z - w * x) * s, (w * w - x * x - y * y + z * z) * s];
            return Vector3::new(
                (-d * v[0] - thrust * ez[0]) * m,
                (-d * v[1] - thrust * ez[1]) * m,
                (-d * v[2] - thrust * ez[2]) * m + GRAVITY,
            );
        }
        let r = rotation(q[0], q[1], q[2], q[3]);
        // v_body = Rᵀ v.
        let vb = [
            r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
            r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
            r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
        ];
        let f = [-self.drag[0] * vb[0], -self.drag[1] * vb[1], -self.drag[2] * vb[2] - thrust];
        Vector3::new(
            (r[0][0] * f[0] + r[0][1] * f[1] + r[0][2] * f[2]) * m,
            (r[1][0] * f[0] + r[1][1] * f[1] + r[1][2] * f[2]) * m,
            (r[2][0] * f[0] + r[2][1] * f[1] + r[2][2] * f[2]) * m + GRAVITY,
        )
    }

    /// Acceleration of the centre of mass at plant state `s` (NED, m/s²).
    fn acceleration(&self, s: &PlantState) -> Vector3<f64> {
        let q = s.att.quaternion();
        let q = [q.w, q.i, q.j, q.k];
        match &self.aero {
            None => self.accel_of(s.vel.into(), q, self.thrust(&s.rotor)),
            Some(a) => self.aero_accel(a, s.vel.into(), q, s.rates.into(), &s.rotor).0,
        }
    }

    /// With the aerodynamic terms on: the acceleration of the centre of mass (NED,
    /// m/s²) and the aerodynamic moment (rotor drag, body FRD, N·m) at velocity
    /// `v`, attitude `q` (normalised here), body rates `rates` and rotor speeds `w`.
    fn aero_accel(
        &self,
        a: &Aero,
        v: [f64; 3],
        q: [f64; 4],
        rates: [f64; 3],
        w: &[f64; 4],
    ) -> (Vector3<f64>, [f64; 3]) {
        let r = rotation(q[0], q[1], q[2], q[3]);
        let va = [v[0] - self.wind[0], v[1] - self.wind[1], v[2] - self.wind[2]];
        // Air-relative velocity, body frame: v_a = Rᵀ (v − wind).
        let vb = [
            r[0][0] * va[0] + r[1][0] * va[1] + r[2][0] * va[2],
            r[0][1] * va[0] + r[1][1] * va[1] + r[2][1] * va[2],
            r[0][2] * va[0] + r[1][2] * va[1] + r[2][2] * va[2],
        ];
        let speed = (vb[0] * vb[0] + vb[1] * vb[1] + vb[2] * vb[2]).sqrt();
        let mut f = [
            -self.drag[0] * vb[0] - a.cd[0] * speed * vb[0],
            -self.drag[1] * vb[1] - a.cd[1] * speed * vb[1],
            -self.drag[2] * vb[2] - a.cd[2] * speed * vb[2] - self.thrust(w),
        ];
        let mut m = [0.0; 3];
        let [p, qq, rr] = rates;
        for (i, wi) in w.iter().enumerate() {
            let [x, y] = a.hub[i];
            // Air velocity at the hub: v_a + ω × r_i, r_i = (x, y, 0).
            let vi = [vb[0] - rr * y, vb[1] + rr * x, vb[2] + p * y - qq * x];
            let h = [-wi * a.kd * vi[0], -wi * a.kd * vi[1], -wi * a.kz * vi[2]];
            f[0] += h[0];
            f[1] += h[1];
            f[2] += h[2];
            // r_i × H_i.
            m[0] += y * h[2];
            m[1] -= x * h[2];
            m[2] += x * h[1] - y * h[0];
        }
        let im = self.inv_mass;
        let acc = Vector3::new(
            (r[0][0] * f[0] + r[0][1] * f[1] + r[0][2] * f[2]) * im,
            (r[1][0] * f[0] + r[1][1] * f[1] + r[1][2] * f[2]) * im,
            (r[2][0] * f[0] + r[2][1] * f[1] + r[2][2] * f[2]) * im + GRAVITY,
        );
        (acc, m)
    }

    /// The state derivative ẋ of the 17-dimensional state
    /// `x = (p, v, q (w, i, j, k), ω_b, rotor speeds)`: the equations of the module docs.
    #[inline(always)]
    fn derivative(&self, x: &X) -> X {
        let w = [x[13], x[14], x[15], x[16]];
        let mut xd = X::zeros();
        let mut tau = [0.0; 3];
        let mut thrust = 0.0;
        for i in 0..4 {
            let f = self.k_f[i] * w[i] * w[i];
            thrust += f;
            tau[0] += self.roll_arm[i] * f;
            tau[1] += self.pitch_arm[i] * f;
            tau[2] += self.yaw_k_m[i] * w[i] * w[i];
            xd[13 + i] = (self.cmd[i] - w[i]) * self.inv_motor_tau;
        }
        let (qw, qi, qj, qk) = (x[6], x[7], x[8], x[9]);
        let acc = match &self.aero {
            None => self.accel_of([x[3], x[4], x[5]], [qw, qi, qj, qk], thrust),
            Some(a) => {
                let (acc, m) =
                    self.aero_accel(a, [x[3], x[4], x[5]], [qw, qi, qj, qk], [x[10], x[11], x[12]], &w);
                tau[0] += m[0];
                tau[1] += m[1];
                tau[2] += m[2];
                acc
            }
        };
        // Euler's equations: I ω̇ = τ − ω × (I ω).
        let (p, q, rr) = (x[10], x[11], x[12]);
        let ii = self.inertia;
        let iw = [ii[0] * p, ii[1] * q, ii[2] * rr];
        let gyro = [q * iw[2] - rr * iw[1], rr * iw[0] - p * iw[2], p * iw[1] - q * iw[0]];
        // q̇ = ½ q ⊗ (0, ω), on the raw (not re-normalised) quaternion of x.
        xd[0] = x[3];
        xd[1] = x[4];
        xd[2] = x[5];
        xd[3] = acc.x;
        xd[4] = acc.y;
        xd[5] = acc.z;
        xd[6] = 0.5 * (-qi * p - qj * q - qk * rr);
        xd[7] = 0.5 * (qw * p + qj * rr - qk * q);
        xd[8] = 0.5 * (qw * q - qi * rr + qk * p);
        xd[9] = 0.5 * (qw * rr + qi * q - qj * p);
        let inv = self.inv_inertia;
        xd[10] = (tau[0] - gyro[0]) * inv[0];
        xd[11] = (tau[1] - gyro[1]) * inv[1];
        xd[12] = (tau[2] - gyro[2]) * inv[2];
        xd
    }
}

impl PlantState {
    fn to_x(&self) -> X {
        let q = self.att.quaternion();
        let mut x = X::zeros();
        x.fixed_rows_mut::<3>(0).copy_from(&self.pos);
        x.fixed_rows_mut::<3>(3).copy_from(&self.vel);
        x[6] = q.w;
        x[7] = q.i;
        x[8] = q.j;
        x[9] = q.k;
        x.fixed_rows_mut::<3>(10).copy_from(&self.rates);
        for i in 0..4 {
            x[13 + i] = self.rotor[i];
        }
        x
    }
    fn from_x(x: &X) -> Self {
        let (w, i, j, k) = (x[6], x[7], x[8], x[9]);
        let inv = 1.0 / (w * w + i * i + j * j + k * k).sqrt();
        let q = nalgebra::Quaternion::new(w * inv, i * inv, j * inv, k * inv);
        PlantState {
            pos: x.fixed_rows::<3>(0).into_owned(),
            vel: x.fixed_rows::<3>(3).into_owned(),
            att: UnitQuaternion::new_unchecked(q),
            rates: x.fixed_rows::<3>(10).into_owned(),
            rotor: [x[13], x[14], x[15], x[16]],
        }
    }

    /// Roll, pitch, yaw (rad; FRD, Euler ZYX body → world).
    pub fn euler(&self) -> (f64, f64, f64) {
        self.att.euler_angles()
    }
}

/// The quadrotor plant: parameters, state, motor commands.
#[derive(Clone, Debug)]
pub struct Plant {
    params: VehicleParams,
    /// Current state.
    pub state: PlantState,
    omega_cmd: [f64; 4],
    /// The derivative's constants for `params` and `omega_cmd` (kept up to date by the setters).
    consts: Consts,
    /// Whether the ground plane z = 0 is simulated (default true).
    pub ground: bool,
    accel: Vector3<f64>,
}

impl Plant {
    /// A plant at rest at the origin, level, rotors stopped. Fails on invalid parameters.
    pub fn new(params: VehicleParams) -> Result<Self, ParamError> {
        params.validate()?;
        let consts = Consts::new(&params, &[0.0; 4]);
        let mut p = Plant {
            params,
            state: PlantState::default(),
            omega_cmd: [0.0; 4],
            consts,
            ground: true,
            accel: Vector3::zeros(),
        };
        p.accel = p.consts.acceleration(&p.state);
        Ok(p)
    }

    /// The vehicle parameters.
    pub fn params(&self) -> &VehicleParams {
        &self.params
    }

    /// Put the vehicle at `pos` (NED, m) with yaw `yaw` (rad), level, at rest,
    /// rotors spinning at (and commanded to) the hover speed.
    pub fn set_hover(&mut self, pos: Vector3<f64>, yaw: f64) {
        let w = self.params.hover_omega();
        self.state = PlantState {
            pos,
            vel: Vector3::zeros(),
            att: UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            rates: Vector3::zeros(),
            rotor: [w; 4],
        };
        self.command([w; 4]);
        self.accel = Vector3::zeros();
    }

    /// Motor commands ("throttles", `c ∈ [0, 1]`, see airframe.rs "Motor
    /// command"): `ω_cmd = c · ω_max`. Non-finite commands count as 0.
    pub fn set_throttles(&mut self, throttle: [f32; 4]) {
        let omega_max = self.params.omega_max;
        self.command(
            throttle.map(|c| if c.is_finite() { (c as f64).clamp(0.0, 1.0) * omega_max } else { 0.0 }),
        );
    }

    /// Rotor-speed commands, rad/s (clamped to `[omega_min, omega_max]` when integrated).
    pub fn set_rotor_speed_commands(&mut self, omega: [f64; 4]) {
        self.command(omega.map(|w| if w.is_finite() { w } else { 0.0 }));
    }

    /// Impose the rotor speeds directly (state and command), bypassing the motor lag
    /// for the following steps (used by open-loop replay).
    pub fn set_rotor_speeds(&mut self, omega: [f64; 4]) {
        let w = omega.map(|w| if w.is_finite() { w.clamp(0.0, self.params.omega_max) } else { 0.0 });
        self.state.rotor = w;
        self.command(w);
    }

    /// Wind velocity, NED, m/s, held over the following steps (zero: air at rest).
    /// Non-finite components count as 0.
    pub fn set_wind(&mut self, wind: Vector3<f64>) {
        self.consts.wind = [wind.x, wind.y, wind.z].map(|w| if w.is_finite() { w } else { 0.0 });
    }

    /// The wind the plant flies in, NED, m/s.
    pub fn wind(&self) -> Vector3<f64> {
        Vector3::from(self.consts.wind)
    }

    /// Scale each rotor's thrust (a rotor fault: 1 = healthy, 0 = no thrust; clamped
    /// to [0, 1], non-finite counts as 1). The drag torque is not scaled.
    pub fn set_rotor_scale(&mut self, scale: [f64; 4]) {
        let k_f = self.params.k_f;
        self.consts.k_f = scale.map(|s| if s.is_finite() { k_f * s.clamp(0.0, 1.0) } else { k_f });
    }

    /// Set the rotor-speed commands (rad/s, finite) and the derivative's clamped copy.
    fn command(&mut self, omega: [f64; 4]) {
        self.omega_cmd = omega;
        self.consts.cmd = omega.map(|c| c.clamp(self.params.omega_min, self.params.omega_max));
    }

    /// Advance by `dt` seconds with one RK4 step, then apply ground contact.
    pub fn step(&mut self, dt: f64) {
        let c = &self.consts;
        let x = self.state.to_x();
        let k1 = c.derivative(&x);
        let k2 = c.derivative(&(x + k1 * (dt / 2.0)));
        let k3 = c.derivative(&(x + k2 * (dt / 2.0)));
        let k4 = c.derivative(&(x + k3 * dt));
        let xn = x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt / 6.0);
        let mut s = PlantState::from_x(&xn);
        for w in &mut s.rotor {
            *w = w.clamp(0.0, self.params.omega_max);
        }
        self.state = s;
        let acc = c.acceleration(&self.state);
        self.accel = acc;
        if self.ground && self.state.pos.z >= 0.0 {
            // Never below the ground; an impact stops the vertical motion.
            self.state.pos.z = 0.0;
            self.state.vel.z = self.state.vel.z.min(0.0);
            if acc.z >= 0.0 {
                // Not lifting: resting on the ground.
                self.state.vel = Vector3::zeros();
                self.state.rates = Vector3::zeros();
                self.accel = Vector3::zeros();
            }
        }
    }

    /// Acceleration of the centre of mass at the current state, NED, m/s²
    /// (zero while resting on the ground).
    pub fn acceleration(&self) -> Vector3<f64> {
        self.accel
    }

    /// Specific force (what an ideal accelerometer measures), body FRD, m/s²:
    /// `Rᵀ (a − g e_z)`. Level hover reads (0, 0, −g).
    pub fn specific_force_body(&self) -> Vector3<f64> {
        self.state.att.inverse_transform_vector(&(self.accel - Vector3::new(0.0, 0.0, GRAVITY)))
    }

    /// Total mechanical energy of the rigid body, J: translational + rotational
    /// kinetic energy + potential energy (height −z above the ground).
    pub fn energy(&self) -> f64 {
        let s = &self.state;
        let i = Vector3::from(self.params.inertia);
        0.5 * self.params.mass * s.vel.norm_squared() + 0.5 * s.rates.component_mul(&s.rates).dot(&i)
            - self.params.mass * GRAVITY * s.pos.z
    }

    /// Angular momentum of the rigid body in the world frame, kg·m²/s.
    pub fn angular_momentum_world(&self) -> Vector3<f64> {
        let i = Vector3::from(self.params.inertia);
        self.state.att * i.component_mul(&self.state.rates)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plant_no_ground() -> Plant {
        plant_with(|_| {})
    }

    /// A plant without ground with the default vehicle changed by `change`.
    fn plant_with(change: impl FnOnce(&mut VehicleParams)) -> Plant {
        let mut v = VehicleParams::default();
        change(&mut v);
        let mut p = Plant::new(v).unwrap();
        p.ground = false;
        p
    }

    #[test]
    fn defaults_match_airframe() {
        let v = VehicleParams::default();
        let af = v.airframe();
        let def = Airframe::default();
        assert!((af.rotor_thrust_max - def.rotor_thrust_max).abs() < 1e-4);
        assert!((af.torque_to_thrust - def.torque_to_thrust).abs() < 1e-6);
        assert_eq!(af.arm_length, def.arm_length);
        v.validate().unwrap();
    }

    #[test]
    fn free_fall_matches_closed_form() {
        let mut p = plant_with(|v| v.drag = [0.0; 3]);
        p.state.pos = Vector3::new(0.0, 0.0, -100.0);
        for _ in 0..1000 {
            p.step(0.001);
        }
        // z(t) = z0 + g t²/2 after 1 s, rotors stopped, no drag.
        assert!((p.state.pos.z - (-100.0 + 0.5 * GRAVITY)).abs() < 1e-9);
        assert!((p.state.vel.z - GRAVITY).abs() < 1e-9);
        // An accelerometer in free fall reads zero.
        assert!(p.specific_force_body().norm() < 1e-9);
    }

    #[test]
    fn hover_at_hover_speed_stays_put() {
        let mut p = plant_no_ground();
        p.set_hover(Vector3::new(1.0, 2.0, -3.0), 0.7);
        for _ in 0..5000 {
            p.step(0.001);
        }
        assert!((p.state.pos - Vector3::new(1.0, 2.0, -3.0)).norm() < 1e-9);
        assert!(p.state.rates.norm() < 1e-12);
        let f = p.specific_force_body();
        assert!((f - Vector3::new(0.0, 0.0, -GRAVITY)).norm() < 1e-9);
        // Hover rotor speed is below max and gives thrust = weight.
        let w = p.params().hover_omega();
        assert!((4.0 * p.params().k_f * w * w - 0.5 * GRAVITY).abs() < 1e-9);
    }

    #[test]
    fn ground_holds_a_vehicle_without_lift_and_releases_with_lift() {
        let mut p = Plant::new(VehicleParams::default()).unwrap();
        for _ in 0..500 {
            p.step(0.001);
        }
        assert_eq!(p.state.pos.z, 0.0);
        assert_eq!(p.state.vel, Vector3::zeros());
        p.set_throttles([0.8; 4]);
        for _ in 0..500 {
            p.step(0.001);
        }
        assert!(p.state.pos.z < -0.05, "took off: z = {}", p.state.pos.z);
        // Falling fast onto the ground while producing some lift: stops at z = 0.
        p.set_hover(Vector3::new(0.0, 0.0, -0.01), 0.0);
        p.state.vel.z = 3.0;
        p.set_rotor_speeds([p.params().hover_omega() * 1.05; 4]);
        for _ in 0..100 {
            p.step(0.001);
            assert!(p.state.pos.z <= 0.0);
        }
    }

    #[test]
    fn pure_yaw_torque_spins_about_z_only() {
        let mut p = plant_no_ground();
        let par = p.params().clone();
        let w0 = par.hover_omega();
        // Speed up the CCW rotors (1, 2), slow the CW ones (3, 4), same total thrust.
        let dw = 50.0;
        let (wa, wb) = (w0 + dw, (2.0 * w0 * w0 - (w0 + dw).powi(2)).sqrt());
        p.set_hover(Vector3::new(0.0, 0.0, -5.0), 0.0);
        p.set_rotor_speeds([wa, wa, wb, wb]);
        let tau_z = 2.0 * par.k_m * (wa * wa - wb * wb);
        for _ in 0..500 {
            p.step(0.001);
        }
        let r_expected = tau_z / par.inertia[2] * 0.5;
        assert!(tau_z > 0.0);
        assert!((p.state.rates.z - r_expected).abs() < 1e-9, "{} vs {}", p.state.rates.z, r_expected);
        assert!(p.state.rates.xy().norm() < 1e-12);
        assert!((p.state.pos - Vector3::new(0.0, 0.0, -5.0)).norm() < 1e-9);
        // Positive yaw (FRD) = clockwise from above: north turns east.
        let yaw = p.state.euler().2;
        assert!((yaw - 0.5 * r_expected * 0.5).abs() < 1e-6);
    }

    #[test]
    fn roll_and_pitch_torque_signs() {
        // More thrust on the left rotors (3: front-left, 2: rear-left) → positive roll (right side down).
        let mut p = plant_no_ground();
        let w0 = p.params().hover_omega();
        p.set_hover(Vector3::new(0.0, 0.0, -5.0), 0.0);
        p.set_rotor_speeds([w0, w0 + 10.0, w0 + 10.0, w0]);
        p.step(0.001);
        assert!(p.state.rates.x > 0.0);
        assert!(p.state.rates.y.abs() < 1e-9);
        // More thrust on the front rotors (1, 3) → positive pitch (nose up).
        p.set_hover(Vector3::new(0.0, 0.0, -5.0), 0.0);
        p.set_rotor_speeds([w0 + 10.0, w0, w0 + 10.0, w0]);
        p.step(0.001);
        assert!(p.state.rates.y > 0.0);
        assert!(p.state.rates.x.abs() < 1e-9);
    }

    #[test]
    fn torque_free_rotation_conserves_energy_and_angular_momentum() {
        let mut p = plant_with(|v| {
            v.drag = [0.0; 3];
            v.inertia = [0.0019, 0.0025, 0.0033];
        });
        p.state.pos = Vector3::new(0.0, 0.0, -1000.0);
        p.state.vel = Vector3::new(1.0, -2.0, 0.5);
        p.state.rates = Vector3::new(3.0, 0.2, -1.0); // tumbling, gyroscopic term active
        let i = Vector3::from(p.params.inertia);
        let e_rot = |p: &Plant| 0.5 * p.state.rates.component_mul(&p.state.rates).dot(&i);
        let (e0, l0, r0) = (p.energy(), p.angular_momentum_world(), e_rot(&p));
        for _ in 0..3000 {
            p.step(0.001);
        }
        let (e1, l1, r1) = (p.energy(), p.angular_momentum_world(), e_rot(&p));
        assert!((e1 - e0).abs() / e0.abs() < 1e-8, "energy drift {}", e1 - e0);
        assert!((r1 - r0).abs() / r0 < 1e-7, "rotational energy drift {}", r1 - r0);
        assert!((l1 - l0).norm() / l0.norm() < 1e-8, "momentum drift {}", (l1 - l0).norm());
        // The tumble did exchange rate between axes (the gyroscopic term is there).
        assert!((p.state.rates - Vector3::new(3.0, 0.2, -1.0)).norm() > 0.1);
    }

    #[test]
    fn rk4_converges_when_halving_dt() {
        // A manoeuvring flight: unequal rotor speeds through the motor lag.
        let run = |dt: f64| {
            let mut p = plant_no_ground();
            p.set_hover(Vector3::new(0.0, 0.0, -10.0), 0.0);
            p.set_rotor_speed_commands([700.0, 690.0, 720.0, 705.0]);
            let n = (1.0 / dt).round() as usize;
            for _ in 0..n {
                p.step(dt);
            }
            p.state
        };
        let a = run(0.002);
        let b = run(0.001);
        let c = run(0.0005);
        let e1 = (a.pos - b.pos).norm();
        let e2 = (b.pos - c.pos).norm();
        // Stated bound: halving the 1 ms step moves the position after 1 s by < 1 µm,
        // and the error shrinks at least 8× per halving (4th order ⇒ ~16×).
        assert!(e2 < 1e-6, "e2 = {e2}");
        assert!(e1 / e2 > 8.0, "ratio {}", e1 / e2);
        assert!((b.rates - c.rates).norm() < 1e-6);
    }

    /// The derivative as the model equations read, with nalgebra's quaternion
    /// and rotation types (the plain form of [`Consts::derivative`]).
    fn reference_derivative(p: &VehicleParams, cmd: &[f64; 4], x: &X) -> X {
        let s = PlantState::from_x(x);
        let r = s.att.to_rotation_matrix();
        let mut thrust = 0.0;
        let mut tau = Vector3::zeros();
        let pos = p.rotor_positions();
        let mut xd = X::zeros();
        for i in 0..4 {
            let w = s.rotor[i];
            let f = p.k_f * w * w;
            thrust += f;
            tau.x += -pos[i][1] * f;
            tau.y += pos[i][0] * f;
            tau.z += ROTOR_YAW_SIGN[i] as f64 * p.k_m * w * w;
            xd[13 + i] = (cmd[i].clamp(p.omega_min, p.omega_max) - w) / p.motor_tau;
        }
        let v_body = r.transpose() * s.vel;
        let f_body =
            Vector3::new(-p.drag[0] * v_body.x, -p.drag[1] * v_body.y, -p.drag[2] * v_body.z - thrust);
        let acc = r * f_body / p.mass + Vector3::new(0.0, 0.0, GRAVITY);
        let inertia = Vector3::from(p.inertia);
        let wdot = (tau - s.rates.cross(&inertia.component_mul(&s.rates))).component_div(&inertia);
        let q = nalgebra::Quaternion::new(x[6], x[7], x[8], x[9]);
        let qd = q * nalgebra::Quaternion::new(0.0, s.rates.x, s.rates.y, s.rates.z) * 0.5;
        xd.fixed_rows_mut::<3>(0).copy_from(&s.vel);
        xd.fixed_rows_mut::<3>(3).copy_from(&acc);
        xd[6] = qd.w;
        xd[7] = qd.i;
        xd[8] = qd.j;
        xd[9] = qd.k;
        xd.fixed_rows_mut::<3>(10).copy_from(&wdot);
        xd
    }

    #[test]
    fn derivative_matches_the_plain_equations() {
        // Tumbling, moving, unequal rotors, a quaternion off the unit sphere
        // (as the RK4 stages see it), drag and a non-symmetric inertia.
        // Drag different on each axis (full rotation) and the same (shortcut).
        for drag in [[0.1, 0.2, 0.3], [0.15; 3]] {
            let mut p = plant_with(|v| {
                v.inertia = [0.0019, 0.0025, 0.0033];
                v.drag = drag;
            });
            p.set_rotor_speed_commands([700.0, 1500.0, -3.0, 650.0]);
            let mut x = X::zeros();
            let vals = [
                1.0, -2.0, -3.0, 0.7, -0.4, 0.2, 0.9, 0.3, -0.2, 0.25, 3.0, -1.5, 0.8, 610.0, 720.0, 680.0,
                655.0,
            ];
            for (xi, v) in x.iter_mut().zip(vals) {
                *xi = v;
            }
            let c = p.consts;
            let fast = c.derivative(&x);
            let plain = reference_derivative(&p.params, &p.omega_cmd, &x);
            for i in 0..17 {
                let tol = 1e-12 * (1.0 + plain[i].abs());
                assert!((fast[i] - plain[i]).abs() <= tol, "component {i}: {} vs {}", fast[i], plain[i]);
            }
            // The cheap acceleration of a state is the derivative's.
            let s = PlantState::from_x(&x);
            let a = c.acceleration(&s);
            let plain = reference_derivative(&p.params, &p.omega_cmd, &s.to_x());
            assert!((a - plain.fixed_rows::<3>(3)).norm() < 1e-12);
        }
    }

    /// The aerodynamic derivative as RotorPy writes it (nalgebra vectors, per rotor).
    fn reference_aero(p: &VehicleParams, wind: Vector3<f64>, x: &X) -> (Vector3<f64>, Vector3<f64>) {
        let s = PlantState::from_x(x);
        let r = s.att.to_rotation_matrix();
        let vb = r.transpose() * (s.vel - wind);
        let cd = Vector3::from(p.parasitic_drag);
        let mut f = -vb.component_mul(&Vector3::from(p.drag)) - vb.norm() * cd.component_mul(&vb);
        let mut m = Vector3::zeros();
        let kdm = Vector3::new(p.rotor_drag_kd, p.rotor_drag_kd, p.rotor_drag_kz);
        for (i, xy) in p.rotor_positions().iter().enumerate() {
            let ri = Vector3::new(xy[0], xy[1], 0.0);
            let w = s.rotor[i];
            let vi = vb + s.rates.cross(&ri);
            let h = -w * kdm.component_mul(&vi);
            let t = Vector3::new(0.0, 0.0, -p.k_f * w * w);
            f += h + t;
            m += ri.cross(&(h + t));
            m.z += ROTOR_YAW_SIGN[i] as f64 * p.k_m * w * w;
        }
        (r * f / p.mass + Vector3::new(0.0, 0.0, GRAVITY), m)
    }

    #[test]
    fn aerodynamic_derivative_matches_rotorpy_form() {
        let mut p = plant_with(|v| {
            v.inertia = [0.0019, 0.0025, 0.0033];
            v.drag = [0.05, 0.07, 0.02];
            v.rotor_drag_kd = 3e-5;
            v.rotor_drag_kz = 2e-5;
            v.parasitic_drag = [0.01, 0.02, 0.03];
        });
        let wind = Vector3::new(2.0, -1.0, 0.3);
        p.set_wind(wind);
        let vals = [
            1.0, -2.0, -3.0, 0.7, -0.4, 0.2, 0.9, 0.3, -0.2, 0.25, 3.0, -1.5, 0.8, 610.0, 720.0, 680.0, 655.0,
        ];
        let mut x = X::zeros();
        for (xi, v) in x.iter_mut().zip(vals) {
            *xi = v;
        }
        let fast = p.consts.derivative(&x);
        let (acc, m) = reference_aero(&p.params, wind, &x);
        let s = PlantState::from_x(&x);
        let i = Vector3::from(p.params.inertia);
        let wdot = (m - s.rates.cross(&i.component_mul(&s.rates))).component_div(&i);
        for k in 0..3 {
            assert!((fast[3 + k] - acc[k]).abs() < 1e-11 * (1.0 + acc[k].abs()), "acc {k}");
            assert!((fast[10 + k] - wdot[k]).abs() < 1e-10 * (1.0 + wdot[k].abs()), "wdot {k}");
        }
        // The accelerometer's acceleration is the derivative's.
        assert!((p.consts.acceleration(&s) - acc).norm() < 1e-11);
        // The rotor drag damps body rates: rolling right gives a negative roll moment.
        p.set_wind(Vector3::zeros());
        let c = p.consts;
        let roll = |rate: f64| {
            let mut y = X::zeros();
            y[6] = 1.0;
            y[10] = rate;
            for k in 0..4 {
                y[13 + k] = 700.0;
            }
            c.derivative(&y)[10]
        };
        let (right, left) = (roll(1.0), roll(-1.0));
        assert!(right < 0.0 && left > 0.0, "{right} {left}");
    }

    #[test]
    fn wind_acts_through_the_air_relative_velocity() {
        // At rest in a steady wind, the linear drag pushes downwind with d W / m.
        let mut p = plant_no_ground();
        p.set_hover(Vector3::new(0.0, 0.0, -5.0), 0.0);
        let w = Vector3::new(0.0, 3.0, 0.0);
        p.set_wind(w);
        p.step(1e-4);
        let a = p.acceleration();
        assert!((a.y - 0.1 * 3.0 / 0.5).abs() < 1e-3, "a = {a:?}");
        assert!(a.x.abs() < 1e-9);
        // Moving with the wind: no drag, the hover stays unaccelerated.
        let mut q = plant_no_ground();
        q.set_hover(Vector3::new(0.0, 0.0, -5.0), 0.0);
        q.state.vel = w;
        q.set_wind(w);
        q.step(1e-3);
        assert!(q.acceleration().norm() < 1e-9);
    }

    #[test]
    fn a_rotor_fault_scales_its_thrust() {
        let mut p = plant_no_ground();
        p.set_hover(Vector3::new(0.0, 0.0, -5.0), 0.0);
        p.set_rotor_scale([0.5, 1.0, 1.0, 1.0]);
        p.step(0.001);
        // Rotor 1 (front-right) weaker: less lift and a roll to the right... the
        // left side is stronger, so positive roll, and nose down (negative pitch).
        assert!(p.state.vel.z > 0.0);
        assert!(p.state.rates.x > 0.0 && p.state.rates.y < 0.0, "{:?}", p.state.rates);
        p.set_rotor_scale([1.0; 4]);
        assert_eq!(p.consts.k_f, [p.params.k_f; 4]);
    }

    #[test]
    fn invalid_params_name_the_field() {
        let v = VehicleParams { mass: -1.0, ..Default::default() };
        assert_eq!(v.validate().unwrap_err().field, "mass");
        let v = VehicleParams { k_f: 1e-9, ..Default::default() };
        assert_eq!(v.validate().unwrap_err().field, "k_f");
        assert!(Plant::new(VehicleParams { motor_tau: f64::NAN, ..Default::default() }).is_err());
    }
}
