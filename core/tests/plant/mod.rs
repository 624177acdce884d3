//! The closed-loop test plant of the controller tests (not the host-sim plant): a rigid-body
//! quadrotor ([`Quad`]) and a 1 kHz loop ([`Sim`]) feeding it to a [`FlightController`].

use nalgebra::UnitQuaternion;
use parapet_core::airframe::Airframe;
use parapet_core::controller::{ControllerParams, FlightController, PositionFix};
use parapet_core::estimator::ImuSample;
use parapet_core::frame::GRAVITY;
use parapet_core::mixer::MixerOutput;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::schedule::OuterSchedule;
use parapet_core::Vec3;

/// The loop's inner period, µs (1 kHz).
pub const INNER_PERIOD_US: u64 = 1000;

const G: Vec3 = Vec3::new(0.0, 0.0, GRAVITY);

/// Rigid-body quadrotor written for these tests (not the host-sim plant):
/// quaternion attitude, Euler's equations with the gyroscopic term, rotor
/// thrusts from the motor commands with a first-order lag, a flat ground.
pub struct Quad {
    pub af: Airframe,
    pub p: Vec3,
    pub v: Vec3,
    pub q: UnitQuaternion<f32>,
    pub w: Vec3,
    pub f: [f32; 4],
    pub tau_motor: f32,
    pub ground_z: f32,
    pub a: Vec3,
}

impl Quad {
    pub fn new(p: Vec3) -> Self {
        let af = Airframe::default();
        let hover = af.mass * GRAVITY / 4.0;
        let on_ground = p.z >= 0.0;
        Quad {
            af,
            p,
            v: Vec3::zeros(),
            q: UnitQuaternion::identity(),
            w: Vec3::zeros(),
            f: if on_ground { [0.0; 4] } else { [hover; 4] },
            tau_motor: 0.02,
            ground_z: 0.0,
            a: Vec3::zeros(),
        }
    }

    pub fn on_ground(&self) -> bool {
        self.p.z >= self.ground_z - 1e-6
    }

    pub fn step(&mut self, throttle: &[f32; 4], dt: f32) {
        let k = dt / (self.tau_motor + dt);
        for (f, c) in self.f.iter_mut().zip(throttle) {
            *f += (c * c * self.af.rotor_thrust_max - *f) * k;
        }
        let m = MixerOutput { thrust_n: self.f, ..MixerOutput::default() };
        let (t, tau) = m.wrench(&self.af);
        let j = Vec3::from(self.af.inertia);
        let jw = j.component_mul(&self.w);
        let w_dot = (tau - self.w.cross(&jw)).component_div(&j);
        let mut a = self.q * Vec3::new(0.0, 0.0, -t / self.af.mass) + G;
        self.w += w_dot * dt;
        self.q *= UnitQuaternion::from_scaled_axis(self.w * dt);
        self.v += a * dt;
        self.p += self.v * dt;
        if self.p.z >= self.ground_z {
            // Ground contact: stop, level out (keep yaw).
            self.p.z = self.ground_z;
            if self.v.z > 0.0 || a.z > 0.0 {
                self.v = Vec3::zeros();
                a = Vec3::zeros();
                self.w = Vec3::zeros();
                let (_, _, yaw) = self.q.euler_angles();
                self.q = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw);
            }
        }
        self.a = a;
    }

    pub fn imu(&self) -> ImuSample {
        ImuSample { gyro: self.w, accel: self.q.inverse() * (self.a - G) }
    }

    pub fn fix(&self, t_us: u64) -> PositionFix {
        let (_, _, yaw) = self.q.euler_angles();
        PositionFix { t_us, position: self.p, velocity: self.v, yaw: Some(yaw) }
    }
}

/// Closed loop at 1 kHz: fixes and (empty or given) obstacle updates at 100 Hz,
/// outer loop at 250 Hz, inner loop at 1 kHz. `feed_fix`/`feed_obs` can cut the data.
pub struct Sim {
    pub ctl: FlightController,
    /// Which inner step runs the outer step (250 Hz under 1 kHz with the defaults).
    pub schedule: OuterSchedule,
    pub quad: Quad,
    pub t_us: u64,
    pub feed_fix: bool,
    pub feed_obs: bool,
    pub obstacles: heapless::Vec<ObstaclePoint, 16>,
    pub min_dist: f32,
    pub noise: Option<Noise>,
}

/// Sensor imperfections for the noisy closed-loop test (deterministic xorshift).
pub struct Noise {
    pub state: u64,
    pub gyro_bias: Vec3,
    pub gyro_sigma: f32,
    pub accel_sigma: f32,
    pub pos_sigma: f32,
    pub vel_sigma: f32,
}

impl Noise {
    /// Approximately normal (sum of 4 uniforms), zero mean, unit variance.
    pub fn normal(&mut self) -> f32 {
        let mut acc = 0.0f32;
        for _ in 0..4 {
            self.state ^= self.state << 13;
            self.state ^= self.state >> 7;
            self.state ^= self.state << 17;
            acc += (self.state >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
        }
        acc * 1.732
    }
    pub fn vec(&mut self, sigma: f32) -> Vec3 {
        Vec3::new(self.normal(), self.normal(), self.normal()) * sigma
    }
}

impl Sim {
    pub fn new(params: ControllerParams, p0: Vec3) -> Self {
        let mut s = Sim {
            schedule: OuterSchedule::new(&params),
            ctl: FlightController::new(params).unwrap(),
            quad: Quad::new(p0),
            t_us: 1_000_000,
            feed_fix: true,
            feed_obs: true,
            obstacles: heapless::Vec::new(),
            min_dist: f32::INFINITY,
            noise: None,
        };
        // Prime the estimator and the data with the vehicle frozen in place.
        s.run_frozen(0.02);
        s
    }

    /// Feed data and run both loops for `seconds` with the vehicle held still (priming).
    pub fn run_frozen(&mut self, seconds: f32) {
        for _ in 0..(seconds * 1000.0) as u32 {
            self.t_us += 1000;
            self.ctl.update_position(self.quad.fix(self.t_us));
            self.ctl.update_obstacles(self.t_us, &[]);
            self.ctl.step_outer(self.t_us);
            self.ctl.step_inner(self.t_us, &self.quad.imu());
        }
    }

    pub fn run(&mut self, seconds: f32, mut each: impl FnMut(&Quad, &FlightController)) {
        let n = (seconds * 1000.0) as u32;
        for _ in 0..n {
            self.t_us += 1000;
            let t = self.t_us;
            if t.is_multiple_of(10_000) {
                if self.feed_fix {
                    let mut fix = self.quad.fix(t);
                    if let Some(n) = self.noise.as_mut() {
                        fix.position += n.vec(n.pos_sigma);
                        fix.velocity += n.vec(n.vel_sigma);
                    }
                    self.ctl.update_position(fix);
                }
                if self.feed_obs {
                    let p = self.quad.p;
                    let pts: heapless::Vec<ObstaclePoint, 16> = self.obstacles.clone();
                    self.ctl.update_obstacles(t, &pts);
                    for o in pts.iter() {
                        self.min_dist = self.min_dist.min((o.point - p).norm());
                    }
                }
            }
            if self.schedule.is_outer_step(t / INNER_PERIOD_US) {
                self.ctl.step_outer(t);
            }
            let mut imu = self.quad.imu();
            if let Some(n) = self.noise.as_mut() {
                imu.gyro += n.gyro_bias + n.vec(n.gyro_sigma);
                imu.accel += n.vec(n.accel_sigma);
            }
            let out = self.ctl.step_inner(t, &imu);
            assert!(out.throttle.iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c)));
            self.quad.step(&out.throttle, 1e-3);
            each(&self.quad, &self.ctl);
        }
    }
}
