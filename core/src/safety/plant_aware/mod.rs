//! Plant-aware wrapping of the safety filter (issue 17): what makes the
//! double-integrator guarantee of [`crate::cbf`] hold on a vehicle whose
//! acceleration lags the command and carries an unmodelled part.
//! Derivations: `docs/filter.md` §9-§12.
//!
//! * **Actuation lag** ([`lag_time_constant`]): the realised acceleration `a`
//!   follows the command `u` through the attitude loop and the motors, modelled
//!   as first order, `τ ȧ = u − a` (τ identified as `0.7/k_att`). Then `ξ = p + τ ṗ` is an exact double
//!   integrator in `u` (`ξ̈ = ṗ̈·τ + p̈ = (u − a) + a = u`, plus the
//!   disturbance): the filter runs on `(ξ, ξ̇ = ṗ + τ(a + d̂))`, and `p(t)` is
//!   `ξ(t − τ)` up to `τ²|a − u/2|`.
//! * **Disturbance observer** ([`DisturbanceObserver`]): `d̂` estimates the
//!   unmodelled acceleration `d = p̈ − a` (accelerometer bias, wind, mass and
//!   thrust error, drag) from the velocity fixes. The filter plans with
//!   `p̈ = u + d̂`: it filters `w = u + d̂` and the command is `w − d̂`; the
//!   estimate's error bound `ē` is added to the robust term `A` (ISSf).
//!   With feed-forward on, the nominal command is `u* − d̂` (removes the PD sag).
//! * **Ground and ceiling** ([`Boundaries`]): horizontal planes given to the
//!   filter as two more (convex, static) obstacle points (multi variants only: the
//!   closest-obstacle law would enforce the plane instead of the obstacle that matters).
//! * **Stall** ([`stall::StallDetector`]): no progress with the filter active.
//!
//! May import: `crate::cbf`, `crate::obstacle` ([`crate::safety`]), `crate::fmath`, `crate::frame`,
//! [`crate::Vec3`] (not the loops: τ comes from the attitude gains as numbers). Imported by the outer loop
//! ([`crate::outer`]) and [`crate::config`].

pub mod limits;
pub mod stall;

use limits::AccelLimits;
use stall::StallDetector;

use crate::fmath::{maxf, minf, norm3};
use crate::obstacle::ObstaclePoint;
use crate::param_decl::{field, Has, Param};
use crate::Vec3;

/// Obstacle id of the ground plane in the filter's obstacle list.
pub const GROUND_ID: u16 = u16::MAX;
/// Obstacle id of the ceiling plane in the filter's obstacle list.
pub const CEILING_ID: u16 = u16::MAX - 1;
const _: () = assert!(CEILING_ID >= crate::obstacle::VIRTUAL_ID); // GROUND_ID is u16::MAX.

/// Invalid plant-aware parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlantAwareError {
    /// The motor time constant must be finite and in [0, 1] s, γ and the relaxation margin finite and ≥ 0.
    LagOutOfRange,
    /// Observer bandwidth finite and in [0, 50] rad/s, margin and limit finite and ≥ 0.
    ObserverOutOfRange,
    /// Ground height finite; ceiling height finite and 0 (off) or above the ground.
    BoundariesInvalid,
    /// Stall time finite and > 0, stall distance finite and ≥ 0.
    StallInvalid,
}

impl core::fmt::Display for PlantAwareError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            PlantAwareError::LagOutOfRange => {
                "lag_tau and motor_tau must be finite and in [0, 1] s, gamma and relax_margin finite and >= 0"
            }
            PlantAwareError::ObserverOutOfRange => {
                "dob_bandwidth must be in [0, 50] rad/s, dob_margin and dob_limit finite and >= 0"
            }
            PlantAwareError::BoundariesInvalid => {
                "ground_height must be finite, ceiling_height 0 (off) or above the ground"
            }
            PlantAwareError::StallInvalid => "stall_time must be > 0 s, stall_distance >= 0 m",
        })
    }
}

/// Parameters of the plant-aware wrapping (used by every filter variant except
/// `paper`, which stays exactly as published).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlantAwareParams {
    /// Evaluate the filter at the lag-predicted state (τ from [`lag_time_constant`]
    /// of the controller's attitude gains and `motor_tau`). Default true.
    pub lag_prediction: bool,
    /// τ, s, in [0, 1]: an identified lag time constant that replaces the one derived
    /// from the gains; 0 (default) = derive it ([`lag_time_constant`]).
    pub lag_tau: f32,
    /// Motor time constant τ_m, s, in [0, 1]. Default 0.02 (the simulator's plant);
    /// with the default gains τ = 0.7/6.5 = 0.108 s.
    pub motor_tau: f32,
    /// γ, 1/s: class-K relaxation of the enforced barriers (`cbf::CbfParams::gamma`;
    /// the controller uses the larger of the two). Default 20: two opposite barriers (a
    /// door, a corridor) at rest stay feasible only while `γ(h_i − δ_r)/(μ|d_i|) ≥ ē + 2ε_v/μ`
    /// for both, so γ bounds the observer error a narrow gap admits: in the middle of the
    /// 0.6 m door (|d| = 0.3 m, μ = 1.4, δ = 0.05) γ = 1 admitted 0.095 m/s² (0.071 with
    /// `relax_margin`), below the measured ē of 0.25–0.65 m/s² in turbulence, so the door was
    /// infeasible and the least-violation answer grazed the jambs; γ = 20 admits 1.43 m/s²
    /// (`docs/filter.md` §11, `docs/robustness.md`).
    pub gamma: f32,
    /// m, m²: the class-K relaxation pulls towards `δ_r = δ + min(m, (δ1 − δ)/2)` instead of δ
    /// (`ḣ ≥ −γ(h − δ_r)`), the barrier itself stays `h ≥ δ`. With a fast γ the vehicle reaches
    /// the relaxation's level quickly, and at δ = hull² the lag residual of `docs/filter.md` §9
    /// (the vehicle is where ξ was τ earlier up to ~1 cm) then touches the hull: at γ = 10 a full
    /// stick into a wall at 2 m/s came within 1.9 mm *inside* the hull (`core/tests/modes.rs`).
    /// Default 0.01 m² (2 cm at the 0.224 m hull).
    pub relax_margin: f32,
    /// ω_o, rad/s: bandwidth of the disturbance observer (both poles at −ω_o);
    /// 0 turns it off (`d̂ = 0`). Default 20 (first 200 flights of the robustness
    /// campaign: 35 collisions at 4, 25 at 12, 22 at 20; §10 of `docs/filter.md`).
    pub dob_bandwidth: f32,
    /// ē, m/s²: bound on `|d − d̂|` used by the filter (added to the robust term A).
    /// Default 0.05 (a constant or slow disturbance after the observer settled,
    /// plus the observer's response to 0.02 m/s velocity noise; §10).
    pub dob_margin: f32,
    /// Gain `k_s` on the observer's spread: the margin is `ē + k_s·spread`, m/s² per
    /// m/s² (see [`DisturbanceObserver::spread`]). Default 2 (4 blocks the 0.6 m door
    /// at δ1 ≥ 0.2 with sensor noise).
    pub dob_spread_gain: f32,
    /// Largest `|d̂|`, m/s² (the estimate is clamped). Default 6 (= the filter's default
    /// `u_max`; 3 clamped the weight error of a 30 % heavy vehicle plus turbulence drag, and
    /// the filter then planned with too little of the disturbance). While `d̂` is at the
    /// clamp with a barrier enforced, the filter's guarantee does not hold and `unavoidable`
    /// is raised.
    pub dob_limit: f32,
    /// Subtract `d̂` from the nominal (PD) command as well (integral-like action
    /// against mass, thrust and drag errors). Default true.
    pub dob_feedforward: bool,
    /// Ground height, m (up, i.e. the plane `z_NED = −ground_height`), always a
    /// barrier in flight. Default 0.
    pub ground_height: f32,
    /// Ceiling height, m (up); 0 = no ceiling. Default 0.
    pub ceiling_height: f32,
    /// Time without progress with the filter intervening after which the mission
    /// is reported as `deadlock` and the vehicle holds, s. Default 20 (10 s stopped the
    /// 0.6 m door at δ1 0.3, seed 3, while it still crept through).
    pub stall_time_s: f32,
    /// Distance the vehicle must move within `stall_time_s` to count as progress, m. Default 0.1.
    pub stall_distance_m: f32,
}

impl Default for PlantAwareParams {
    fn default() -> Self {
        PlantAwareParams {
            lag_prediction: true,
            lag_tau: 0.0,
            motor_tau: DEFAULT_MOTOR_TAU_S,
            gamma: 20.0,
            relax_margin: 0.01,
            dob_bandwidth: 20.0,
            dob_margin: 0.05,
            dob_spread_gain: 2.0,
            dob_limit: 6.0,
            dob_feedforward: true,
            ground_height: 0.0,
            ceiling_height: 0.0,
            stall_time_s: 20.0,
            stall_distance_m: 0.1,
        }
    }
}

impl PlantAwareParams {
    /// The ground and ceiling barriers' parameters (issue 17; `crate::params`).
    #[rustfmt::skip] // one entry per parameter, laid out by hand
    pub const fn params<P: Has<Self>>() -> [Param<P>; 2] {
        [
            Param::new("GND_HEIGHT", "CBF", "m", (-100.0, 100.0), 3, field!(ground_height),
                "Ground height (up); the filter keeps the plane z = -GND_HEIGHT as a barrier in flight"),
            Param::new("CEIL_HEIGHT", "CBF", "m", (0.0, 1000.0), 3, field!(ceiling_height),
                "Ceiling height (up) kept as a barrier in flight; 0 = no ceiling"),
        ]
    }
}

/// Motor time constant assumed by the default lag, s (the simulator's plant default).
pub const DEFAULT_MOTOR_TAU_S: f32 = 0.02;

/// Identified ratio `τ·k_att` of the 6-DOF plant in closed loop (see [`lag_time_constant`]).
pub const LAG_PER_INVERSE_ATT_GAIN: f32 = 0.7;

/// τ of the first-order model of commanded → realised horizontal acceleration
/// (it is `g·tan(tilt)`, so it lags as the tilt does). The tilt follows its
/// setpoint through the attitude P loop (gain `k_att`), the rate loop and the
/// motors. Identified on the simulator's plant (least-squares first-order fit of
/// `dv/dt` to the command along the office path, `docs/filter.md` §9): τ = 0.10,
/// 0.17, 0.35 s at `k_att` = 6.5, 3.9, 1.95 1/s, i.e. `τ ≈ 0.7/k_att` with the
/// default rate loop and a 0.02 s motor; a slower motor adds its excess `τ_m − 0.02`.
/// (The loop's mean delay `1/k_att + 1/k_rate + τ_m` = 0.199 s overestimates it, and
/// over-predicting made a sphere overtaking from behind collide.) Non-positive
/// gains give no attitude contribution.
/// `att_p`: the attitude P gains (roll, pitch, yaw), 1/s (`AttitudeParams::att_p`).
pub fn lag_time_constant(att_p: &[f32; 3], motor_tau_s: f32) -> f32 {
    let k_att = att_p[0].min(att_p[1]);
    let att_part = if k_att > 0.0 { LAG_PER_INVERSE_ATT_GAIN / k_att } else { 0.0 };
    maxf(att_part + motor_tau_s - DEFAULT_MOTOR_TAU_S, 0.0)
}

impl PlantAwareParams {
    /// Check the ranges of [`PlantAwareError`].
    pub fn validate(&self) -> Result<(), PlantAwareError> {
        let nonneg = |x: f32| x.is_finite() && x >= 0.0;
        if !(nonneg(self.motor_tau)
            && self.motor_tau <= 1.0
            && nonneg(self.lag_tau)
            && self.lag_tau <= 1.0
            && nonneg(self.gamma)
            && nonneg(self.relax_margin))
        {
            return Err(PlantAwareError::LagOutOfRange);
        }
        if !(nonneg(self.dob_bandwidth)
            && self.dob_bandwidth <= 50.0
            && nonneg(self.dob_margin)
            && nonneg(self.dob_limit)
            && nonneg(self.dob_spread_gain))
        {
            return Err(PlantAwareError::ObserverOutOfRange);
        }
        let ceiling_ok = self.ceiling_height == 0.0
            || (self.ceiling_height.is_finite() && self.ceiling_height > self.ground_height);
        if !(self.ground_height.is_finite() && ceiling_ok) {
            return Err(PlantAwareError::BoundariesInvalid);
        }
        if !(self.stall_time_s.is_finite() && self.stall_time_s > 0.0 && nonneg(self.stall_distance_m)) {
            return Err(PlantAwareError::StallInvalid);
        }
        Ok(())
    }
}

/// Second-order observer of the unmodelled acceleration `d` in `v̇ = a + d`
/// (`a` the modelled realised acceleration), from velocity measurements:
///
/// `v̂ ← v̂ + (a + d̂)·dt + 2ω·dt·e`, `d̂ ← d̂ + ω²·dt·e`, `e = v_meas − v̂`,
///
/// error dynamics `ë_d + 2ω ė_d + ω² e_d = ḋ̇`-driven with both poles at −ω: a
/// constant `d` is learnt without error with time constant ~1/ω, a ramp `ḋ`
/// leaves `2ḋ/ω`. Bounded per step; non-finite inputs reset it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisturbanceObserver {
    v_hat: Vec3,
    d_hat: Vec3,
    d_slow: Vec3,
    d_smooth: Vec3,
    spread: f32,
    primed: bool,
    saturated: bool,
}

/// Time constant of the smoothing of `d̂` before its spread is taken, s: removes the
/// observer's response to velocity noise, keeps turbulence (≲ 1 Hz at these speeds).
pub const SPREAD_SMOOTH_S: f32 = 0.2;

/// Time constant of the slow mean of `d̂` and of its spread, s.
pub const SPREAD_TAU_S: f32 = 2.0;

impl Default for DisturbanceObserver {
    fn default() -> Self {
        Self::new()
    }
}

impl DisturbanceObserver {
    /// An observer with `d̂ = 0` that primes `v̂` at the first update.
    pub const fn new() -> Self {
        DisturbanceObserver {
            v_hat: Vec3::new(0.0, 0.0, 0.0),
            d_hat: Vec3::new(0.0, 0.0, 0.0),
            d_slow: Vec3::new(0.0, 0.0, 0.0),
            d_smooth: Vec3::new(0.0, 0.0, 0.0),
            spread: 0.0,
            primed: false,
            saturated: false,
        }
    }

    /// Forget everything (`d̂ = 0`).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// The estimate `d̂`, m/s² NED.
    pub fn estimate(&self) -> Vec3 {
        self.d_hat
    }

    /// The last update clamped `|d̂|` to the limit: the disturbance is (likely) larger than
    /// the estimate, beyond the bound the filter's margin assumes.
    pub fn saturated(&self) -> bool {
        self.saturated
    }

    /// How much `d̂` varies: the low-pass (τ [`SPREAD_TAU_S`]) of `|d̃ − d̄|`, `d̃` the
    /// estimate smoothed over [`SPREAD_SMOOTH_S`], `d̄` its slow mean, m/s². A varying disturbance (turbulence) is tracked with a lag of
    /// ~1/ω, so its estimate's error is of this size; the filter widens its margin by it.
    pub fn spread(&self) -> f32 {
        self.spread
    }

    /// One step of length `dt` (s, clamped to [0, 0.05]) with measured velocity
    /// `v_meas` (m/s) and modelled realised acceleration `a` (m/s²); `omega`
    /// rad/s, `limit` clamps `|d̂|`.
    pub fn update(&mut self, v_meas: &Vec3, a: &Vec3, dt: f32, omega: f32, limit: f32) {
        let ok = |x: &Vec3| x.iter().all(|c| c.is_finite() && c.abs() <= 1.0e5);
        if !ok(v_meas) || !ok(a) || !dt.is_finite() {
            self.reset();
            return;
        }
        if !self.primed {
            self.v_hat = *v_meas;
            self.primed = true;
            return;
        }
        if omega <= 0.0 {
            self.d_hat = Vec3::zeros();
            self.v_hat = *v_meas;
            self.saturated = false;
            return;
        }
        let dt = dt.clamp(0.0, 0.05);
        let pred = self.v_hat + (a + self.d_hat) * dt;
        let e = v_meas - pred;
        self.v_hat = pred + e * (2.0 * omega * dt).min(1.0);
        self.d_hat += e * (omega * omega * dt);
        let n = norm3(&self.d_hat);
        self.saturated = n > limit;
        if self.saturated {
            self.d_hat *= limit / n;
        }
        self.d_smooth += (self.d_hat - self.d_smooth) * (dt / (SPREAD_SMOOTH_S + dt));
        let k = dt / (SPREAD_TAU_S + dt);
        self.d_slow += (self.d_smooth - self.d_slow) * k;
        self.spread += (norm3(&(self.d_smooth - self.d_slow)) - self.spread) * k;
    }
}

/// First-order model of the realised acceleration, `τ ȧ = u − a` (backward Euler).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LagModel {
    a: Vec3,
}

impl LagModel {
    /// The modelled realised acceleration, m/s² NED.
    pub fn realised(&self) -> Vec3 {
        self.a
    }
    /// Set the state (e.g. to the command when the loop (re)starts).
    pub fn set(&mut self, a: Vec3) {
        self.a = a;
    }
    /// Advance by `dt` s with command `u`; `tau` 0 gives `a = u`.
    pub fn update(&mut self, u: &Vec3, dt: f32, tau: f32) {
        if !(u.iter().all(|c| c.is_finite())) {
            return;
        }
        if tau <= 0.0 {
            self.a = *u;
            return;
        }
        if dt.is_nan() || dt <= 0.0 {
            return;
        }
        let k = dt / (tau + dt);
        self.a += (u - self.a) * k;
    }
}

/// The state the filter is evaluated at: `ξ = p + τ ṗ`, `ξ̇ = ṗ + τ(a + d̂)`.
pub fn predicted_state(p: &Vec3, v: &Vec3, a: &Vec3, d_hat: &Vec3, tau: f32) -> (Vec3, Vec3) {
    (p + v * tau, v + (a + d_hat) * tau)
}

/// The horizontal boundary planes as obstacle points (closest point to `xi`):
/// the ground `z = −ground_height` and, if set, the ceiling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boundaries {
    /// Ground height, m up.
    pub ground_height: f32,
    /// Ceiling height, m up; 0 = none.
    pub ceiling_height: f32,
}

impl Boundaries {
    /// The planes' closest points to `xi` (NED), ground first.
    pub fn points(&self, xi: &Vec3) -> impl Iterator<Item = ObstaclePoint> {
        let ground = ObstaclePoint {
            point: Vec3::new(xi.x, xi.y, -self.ground_height),
            velocity: None,
            id: GROUND_ID,
            normal: None,
        };
        let ceiling = (self.ceiling_height != 0.0).then(|| ObstaclePoint {
            point: Vec3::new(xi.x, xi.y, -self.ceiling_height),
            velocity: None,
            id: CEILING_ID,
            normal: None,
        });
        core::iter::once(ground).chain(ceiling)
    }
}

/// What the plant-aware filter adds to one outer step (telemetry).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PlantAwareTelemetry {
    /// Disturbance estimate `d̂`, m/s² NED.
    pub disturbance: Vec3,
    /// Modelled realised acceleration `a`, m/s² NED.
    pub realised: Vec3,
    /// Robust term the filter used this step (A + ē + k_s·spread), m/s².
    pub accel_margin: f32,
    /// The filter was evaluated at `ξ = p + τṗ` with this τ, s (0: not plant-aware).
    pub lag_tau: f32,
    /// Smallest `h̄` at the vehicle's actual state (obstacles and boundaries), m².
    pub h_bar_now: f32,
    /// No progress with the filter intervening for the stall time (latched until
    /// the next mission start; the vehicle holds where it stalled).
    pub deadlock: bool,
}

/// Smallest distance of the evaluated state from a point's tangent plane that the filter is
/// given, m: a state on or behind the plane (inside the obstacle) is treated as this far in
/// front of it, so the filter pushes it out along the plane's normal (the point barrier is
/// symmetric and would otherwise push it further in). At 1 cm the class-K term asks for
/// `γδ/(μ·0.01)` ≈ 3.6 m/s² outwards with the defaults, within `u_max`; much closer, the demand
/// exceeds the filter's candidate bound and it would return the least-violation answer instead.
pub const MIN_PLANE_DISTANCE_M: f32 = 0.01;

/// `n/|n|` for a reported surface normal of plausible length (0.5 to 2; the sources give unit
/// normals, f32 round-off aside); `None` for anything else (non-finite, zero), which is then
/// treated as no normal.
#[inline]
fn unit_normal(n: &Vec3) -> Option<Vec3> {
    let r2 = n.norm_squared();
    (0.25..=4.0).contains(&r2).then(|| n * (1.0 / crate::fmath::sqrtf(r2)))
}

/// Obstacle-list capacity of [`PlantAware::apply`]: the controller's set plus the two planes.
pub const MAX_FILTER_POINTS: usize = crate::obstacle::DEFAULT_OBSTACLE_CAPACITY + 2;

/// State of the plant-aware wrapping (lag model, observer, stall detector).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantAware {
    /// Parameters (validated by the owner).
    pub params: PlantAwareParams,
    /// τ used for the prediction, s.
    pub tau: f32,
    lag: LagModel,
    dob: DisturbanceObserver,
    stall: StallDetector,
    /// What the vehicle can realise ([`PlantAware::with_limits`]): the lag model is fed the
    /// command after these limits. `None`: the command as given.
    limits: Option<AccelLimits>,
    /// Bound on the vertical position error, m ([`PlantAware::set_boundary_margin`]).
    boundary_margin: f32,
}

/// One step's inputs to [`PlantAware::apply`].
#[derive(Clone, Copy, Debug)]
pub struct StepInput<'a> {
    /// Time, µs.
    pub now_us: u64,
    /// Outer step, s.
    pub dt: f32,
    /// Position (NED, m) and velocity (m/s) from the fix.
    pub p: Vec3,
    /// Velocity, m/s NED.
    pub v: Vec3,
    /// Nominal (PD) acceleration, m/s² NED.
    pub u_pd: Vec3,
    /// Obstacle points.
    pub obstacles: &'a [ObstaclePoint],
    /// Where the vehicle was when `obstacles` were reported (NED, m; the position estimate at
    /// the report's time stamp): each point's tangent plane is aimed from there, so a closest
    /// surface point held between reports keeps its surface's normal (`docs/filter.md` §9).
    /// `None`: from `p` (points refreshed at this step).
    pub seen_from: Option<Vec3>,
    /// Ground (and ceiling) barriers on (in flight, not taking off or landing).
    pub boundaries: bool,
    /// Flying the mission, away from the reference (stall detection armed).
    pub mission_running: bool,
}

impl PlantAware {
    /// Wrapping with parameters `params`; `derived_tau` (s) is used unless
    /// `params.lag_tau` sets one.
    pub fn new(params: PlantAwareParams, derived_tau: f32) -> Self {
        let tau = if params.lag_tau > 0.0 { params.lag_tau } else { derived_tau };
        PlantAware {
            params,
            tau: if params.lag_prediction { tau } else { 0.0 },
            lag: LagModel::default(),
            dob: DisturbanceObserver::new(),
            stall: StallDetector::default(),
            limits: None,
            boundary_margin: 0.0,
        }
    }

    /// The ground and the ceiling are world planes: with a position estimate whose vertical
    /// error is bounded by `m` (m; a navigation filter, `docs/filter.md` § 18) the ground is
    /// raised and the ceiling lowered by `m`, as the mapped obstacles are moved by their
    /// margin. Default 0 (motion capture); negative or non-finite: 0.
    pub fn set_boundary_margin(&mut self, m: f32) {
        self.boundary_margin = if m.is_finite() { m.max(0.0) } else { 0.0 };
    }

    /// The same, with the vehicle's acceleration limits: the lag model (and so the disturbance
    /// observer) is fed the command the thrust map realises, not the filter's command
    /// ([`limits`]). The outer loop sets them from its thrust parameters and mass.
    pub fn with_limits(mut self, limits: Option<AccelLimits>) -> Self {
        self.limits = limits;
        self
    }

    /// `u` as the vehicle realises it (after [`PlantAware::with_limits`]' limits).
    fn realisable(&self, u: &Vec3) -> Vec3 {
        self.limits.map_or(*u, |l| l.realised(u).0)
    }

    /// Forget the observer, lag and stall states (motors off / on the ground).
    pub fn reset(&mut self) {
        self.lag.set(Vec3::zeros());
        self.dob.reset();
        self.stall.reset();
    }

    /// Forget only the stall anchor (mission (re)start).
    pub fn reset_stall(&mut self) {
        self.stall.reset();
    }

    /// An open-loop command `u` was applied for `dt` s (no fix): advance the lag model with
    /// what the vehicle realises of it.
    pub fn open_loop(&mut self, u: &Vec3, dt: f32) {
        let u = self.realisable(u);
        self.lag.update(&u, dt, self.tau);
    }

    /// One outer step: observer update, filter at the predicted state with
    /// `p̈ = u + d̂` and the boundaries, stall check. Returns the nominal command
    /// (`u_pd − d̂` with feed-forward), the safe command, the filter diagnostics and
    /// the telemetry (`deadlock` as detected this step, not latched).
    pub fn apply(
        &mut self,
        filter: &crate::cbf::SafetyFilter,
        s: &StepInput<'_>,
    ) -> (Vec3, Vec3, crate::cbf::FilterDiagnostics, PlantAwareTelemetry) {
        let rp = self.params;
        let a = self.lag.realised();
        self.dob.update(&s.v, &a, s.dt, rp.dob_bandwidth, rp.dob_limit);
        let d_hat = self.dob.estimate();
        let u_nom = if rp.dob_feedforward { s.u_pd - d_hat } else { s.u_pd };
        let (xi, xi_dot) = predicted_state(&s.p, &s.v, &a, &d_hat, self.tau);
        let m = self.boundary_margin;
        let ceiling_height = if rp.ceiling_height != 0.0 { rp.ceiling_height - m } else { 0.0 };
        let bounds = Boundaries { ground_height: rp.ground_height + m, ceiling_height };
        let mut pts: heapless::Vec<ObstaclePoint, MAX_FILTER_POINTS> = heapless::Vec::new();
        // The planes need the multi variants: the closest-obstacle law (eq. 14) would enforce
        // the ground instead of a nearer-in-h obstacle (a 2 m/s walker was ignored that way).
        let with_bounds = s.boundaries && filter.variant.is_multi();
        let extra = bounds.points(&xi).filter(|_| with_bounds);
        // The relative flat output is (p + τṗ) − (p̄ + τv̄): a moving obstacle is predicted
        // by the same τ (for the variants that use obstacle velocities). Each point is given
        // to the filter as a tangent half-space (§9 of docs/filter.md): the plane through p̄
        // with the surface normal the source reported, else the normal aimed from where the
        // vehicle was when the point was reported, n = (p_r − p̄)/|p_r − p̄| (p_r =
        // `seen_from`, else p). For the closest point of a convex obstacle that plane supports
        // it (the obstacle lies behind), so the barrier on the signed distance
        // s = nᵀ(ξ − p̄) is conservative for every convex shape and exact for a wall however
        // long the point is held. Re-aiming n from the current p instead tilts it towards a
        // vehicle sliding past a held point, and the tangential speed then reads as a retreat
        // (the vehicle crept through a wall that way). The filter sees the point ξ − n·s, with
        // s ≥ MIN_PLANE_DISTANCE_M: behind the plane the point barrier, which is symmetric,
        // would push further in; clamped, it pushes out along n.
        let relative = filter.variant.uses_relative_velocity();
        let tau = self.tau;
        let from = s.seen_from.unwrap_or(s.p);
        let aimed = tau > 0.0 || s.seen_from.is_some();
        // In the same pass: the smallest h̄ at the vehicle's actual state (`min_h_bar`, same
        // arithmetic in the same order; the telemetry's `h_bar_now`).
        let (mu, delta) = (filter.params.mu, filter.params.delta);
        let mut h_bar_now = f32::INFINITY;
        for o in s.obstacles {
            let w = match o.velocity {
                Some(w) if relative => Some(w),
                _ => None,
            };
            let d_dot_now = w.map_or(s.v, |w| s.v - w);
            h_bar_now = h_bar_now.min(crate::cbf::barrier_value(mu, &(s.p - o.point), &d_dot_now) - delta);
            let q = w.map_or(o.point, |w| o.point + w * tau);
            let n = match o.normal.and_then(|n| unit_normal(&n)) {
                Some(n) => Some(n),
                None => {
                    let d = from - o.point;
                    let r2 = d.norm_squared();
                    (aimed && r2 > crate::cbf::MIN_DISTANCE_SQ).then(|| d * (1.0 / crate::fmath::sqrtf(r2)))
                }
            };
            let point = match n {
                Some(n) => {
                    let s_plane = n.dot(&(xi - q));
                    // NaN stays NaN (the filter then faults on it); at or behind the plane: clamped.
                    xi - n * if s_plane < MIN_PLANE_DISTANCE_M { MIN_PLANE_DISTANCE_M } else { s_plane }
                }
                None => q,
            };
            // The filter reads point, velocity and id (not the normal: it gets the plane's point).
            // The caller's set holds at most MAX_FILTER_POINTS − 2: a push cannot fail.
            let _ = pts.push(ObstaclePoint { point, velocity: o.velocity, id: o.id, normal: None });
        }
        for o in extra {
            let _ = pts.push(o);
        }
        if with_bounds {
            for o in bounds.points(&s.p) {
                h_bar_now = h_bar_now.min(crate::cbf::barrier_value(mu, &(s.p - o.point), &s.v) - delta);
            }
        }
        // The filter on w = u + d̂ (p̈ = w for the predicted state).
        let w_nom = u_nom + d_hat;
        // ISSf margin: the static ē is already in the filter's A; add k_s·spread.
        let mut f = *filter;
        // The relaxation's level δ_r (PlantAwareParams::relax_margin): only the class-K term reads
        // δ in the filter's constraints (the diagnostics' h̄ is replaced by h_bar_now below).
        f.params.delta += minf(rp.relax_margin, 0.5 * (f.params.delta1 - delta)).max(0.0);
        let extra = rp.dob_spread_gain * self.dob.spread();
        if rp.dob_bandwidth > 0.0 && extra > 0.0 {
            f.params.accel_bound += minf(extra, rp.dob_limit);
        }
        let (w, mut diag) = f.apply(&xi, &xi_dot, &w_nom, &pts);
        // A barrier is enforced with d̂ at its clamp: |d − d̂| ≤ ē no longer holds, so the
        // filter cannot promise the barrier (ISSf bound exceeded): say so before any contact.
        if self.dob.saturated() && diag.n_constraints > 0 {
            diag.unavoidable = true;
        }
        let u = w - d_hat;
        // The lag model (and through it the observer) gets what the vehicle will realise.
        let u_real = self.realisable(&u);
        self.lag.update(&u_real, s.dt, self.tau);
        diag.h_bar = h_bar_now;
        let stalled = self.stall.update(
            s.now_us,
            &s.p,
            s.mission_running && diag.intervened,
            rp.stall_time_s,
            rp.stall_distance_m,
        );
        let tel = PlantAwareTelemetry {
            disturbance: d_hat,
            realised: a,
            accel_margin: f.params.accel_bound,
            lag_tau: self.tau,
            h_bar_now,
            deadlock: stalled,
        };
        (u_nom, u, diag, tel)
    }
}

/// Smallest `h̄ = |d|² + μdᵀḋ − δ` at the actual state over `obstacles` and the
/// boundary planes (`+∞` with none), with the variant's notion of `ḋ`.
pub fn min_h_bar(
    filter: &crate::cbf::SafetyFilter,
    p: &Vec3,
    v: &Vec3,
    obstacles: &[ObstaclePoint],
    bounds: Option<&Boundaries>,
) -> f32 {
    let (mu, delta) = (filter.params.mu, filter.params.delta);
    let relative = filter.variant.uses_relative_velocity();
    let h_of = |o: &ObstaclePoint| {
        let d = p - o.point;
        let d_dot = match o.velocity {
            Some(w) if relative => v - w,
            _ => *v,
        };
        crate::cbf::barrier_value(mu, &d, &d_dot) - delta
    };
    let mut h = f32::INFINITY;
    for o in obstacles {
        h = h.min(h_of(o));
    }
    if let Some(b) = bounds {
        for o in b.points(p) {
            h = h.min(h_of(&o));
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_lag_follows_the_gains() {
        // The default attitude gains (AttitudeParams::default().att_p).
        let tau = lag_time_constant(&[6.5, 6.5, 2.8], PlantAwareParams::default().motor_tau);
        assert!((tau - 0.7 / 6.5).abs() < 1e-6, "{tau}");
        let slow = [6.5 * 0.3, 6.5 * 0.3, 2.8];
        assert!((lag_time_constant(&slow, 0.05) - (0.7 / 1.95 + 0.03)).abs() < 1e-6);
        assert!(PlantAwareParams::default().validate().is_ok());
        let bad = PlantAwareParams { ceiling_height: -1.0, ..PlantAwareParams::default() };
        assert_eq!(bad.validate(), Err(PlantAwareError::BoundariesInvalid));
    }

    #[test]
    fn xi_is_a_double_integrator_of_the_command_under_first_order_lag() {
        // Exact lag τȧ = u − a integrated finely; ξ = p + τv must follow ξ̈ = u + d.
        let (tau, dt) = (0.2f64, 1e-5f64);
        let (mut p, mut v, mut a) = (0.0f64, 0.3f64, -0.5f64);
        let d = 0.1f64;
        let u = 1.0f64;
        let (xi0, xid0) = (p + tau * v, v + tau * (a + d));
        let t_end = 1.0;
        for _ in 0..(t_end / dt) as usize {
            a += (u - a) / tau * dt;
            v += (a + d) * dt;
            p += v * dt;
        }
        let xi = p + tau * v;
        let expect = xi0 + xid0 * t_end + 0.5 * (u + d) * t_end * t_end;
        assert!((xi - expect).abs() < 1e-4, "{xi} vs {expect}");
    }

    #[test]
    fn observer_learns_a_constant_disturbance_and_resets_on_bad_input() {
        let d = Vec3::new(0.2, -0.1, 0.3);
        let a = Vec3::new(0.5, 0.0, -0.2);
        let (mut v, dt) = (Vec3::zeros(), 0.004);
        let mut obs = DisturbanceObserver::new();
        for _ in 0..2500 {
            v += (a + d) * dt;
            obs.update(&v, &a, dt, 2.0, 3.0);
        }
        assert!((obs.estimate() - d).norm() < 1e-3, "{}", obs.estimate());
        obs.update(&Vec3::new(f32::NAN, 0.0, 0.0), &a, dt, 2.0, 3.0);
        assert_eq!(obs.estimate(), Vec3::zeros());
        // Clamped to the limit.
        let mut obs = DisturbanceObserver::new();
        let mut v = Vec3::zeros();
        for _ in 0..2500 {
            v += Vec3::new(9.0, 0.0, 0.0) * dt;
            obs.update(&v, &Vec3::zeros(), dt, 2.0, 3.0);
        }
        assert!((obs.estimate().norm() - 3.0).abs() < 1e-4);
        assert!(obs.saturated(), "at the clamp");
        // Back within the limit: no longer saturated.
        for _ in 0..2500 {
            v += Vec3::new(1.0, 0.0, 0.0) * dt;
            obs.update(&v, &Vec3::zeros(), dt, 2.0, 3.0);
        }
        assert!(!obs.saturated() && (obs.estimate().x - 1.0).abs() < 1e-3, "{}", obs.estimate());
    }

    #[test]
    fn a_saturated_observer_with_a_barrier_enforced_raises_unavoidable() {
        let filter = crate::cbf::SafetyFilter::new(
            crate::cbf::CbfParams { gamma: 1.0, sample_time: 0.004, ..crate::cbf::CbfParams::default() },
            crate::cbf::FilterVariant::MultiRelative,
        )
        .unwrap();
        let rp = PlantAwareParams::default();
        // A wall 0.25 m ahead (+x); the measured velocity grows towards it at twice the
        // observer's limit (an unmodelled push), the nominal command is zero.
        let mut pa = PlantAware::new(rp, 0.1);
        let mut v = Vec3::zeros();
        let obs = [ObstaclePoint::fixed(Vec3::new(0.25, 0.0, -1.0), 1)];
        let mut exercised = false;
        for k in 0..400u64 {
            v += Vec3::new(2.0 * rp.dob_limit, 0.0, 0.0) * 0.004;
            let s = StepInput {
                now_us: k * 4_000,
                dt: 0.004,
                p: Vec3::new(0.0, 0.0, -1.0),
                v,
                u_pd: Vec3::zeros(),
                obstacles: &obs,
                seen_from: None,
                boundaries: false,
                mission_running: false,
            };
            let (_, _, diag, _) = pa.apply(&filter, &s);
            if pa.dob.saturated() {
                assert!(
                    diag.n_constraints == 0 || diag.unavoidable,
                    "step {k}: saturated, enforced, not flagged"
                );
                exercised |= diag.n_constraints > 0;
            }
        }
        assert!(exercised, "the observer saturates with the wall's barrier enforced");
    }

    /// A command beyond what the vehicle can realise is not read as a disturbance: deep inside
    /// a barrier's margin and closing, the filter asks for tens of m/s²; the plant realises
    /// the thrust map's limit of it (here exactly the model's lag of the limited command, so the
    /// true disturbance is zero). With the limits the observer stays at zero; without them it
    /// reads the shortfall as a disturbance (measured in flight: the vehicle then sank).
    #[test]
    fn an_unrealisable_command_is_not_read_as_a_disturbance() {
        let filter = crate::cbf::SafetyFilter::new(
            crate::cbf::CbfParams { gamma: 20.0, sample_time: 0.004, ..crate::cbf::CbfParams::default() },
            crate::cbf::FilterVariant::MultiRelative,
        )
        .unwrap();
        let limits = AccelLimits { tilt_max: 0.61, a_min: 1.2, a_max: 22.0 };
        let worst_d_hat = |with_limits: bool| {
            let pa = PlantAware::new(PlantAwareParams::default(), 0.1);
            let mut pa = if with_limits { pa.with_limits(Some(limits)) } else { pa };
            let mut truth = LagModel::default();
            let obs = [ObstaclePoint::fixed(Vec3::new(0.0, 0.0, -1.0), 1)];
            let (mut p, mut v) = (Vec3::new(-0.3, 0.0, -1.0), Vec3::new(1.5, 0.0, 0.0));
            let (mut worst, mut saturated) = (0.0f32, false);
            for k in 0..50u64 {
                let s = StepInput {
                    now_us: k * 4_000,
                    dt: 0.004,
                    p,
                    v,
                    u_pd: Vec3::new(1.0, 0.0, 0.0),
                    obstacles: &obs,
                    seen_from: None,
                    boundaries: false,
                    mission_running: false,
                };
                let (_, u, _, tel) = pa.apply(&filter, &s);
                worst = worst.max(tel.disturbance.norm());
                let (u_real, sat) = limits.realised(&u);
                saturated |= sat;
                truth.update(&u_real, 0.004, pa.tau);
                v += truth.realised() * 0.004;
                p += v * 0.004;
            }
            assert!(saturated, "the command must exceed the limits for this test to mean anything");
            worst
        };
        let (with, without) = (worst_d_hat(true), worst_d_hat(false));
        assert!(with < 0.05, "with the limits: |d̂| up to {with}");
        assert!(without > 1.0, "without them the shortfall reads as a disturbance: |d̂| up to {without}");
    }

    /// One wrapper step (lag model and observer at rest, boundaries off) for a vehicle at `p`
    /// moving at `v` with nominal `u_pd`, obstacle `o` reported from `seen_from`.
    fn one_step(p: Vec3, v: Vec3, u_pd: Vec3, o: ObstaclePoint, seen_from: Option<Vec3>) -> Vec3 {
        let filter = crate::cbf::SafetyFilter::new(
            crate::cbf::CbfParams { gamma: 1.0, sample_time: 0.004, accel_bound: 0.05, ..Default::default() },
            crate::cbf::FilterVariant::MultiRelative,
        )
        .unwrap();
        // The relaxation's level at δ itself (relax_margin 0): the tests below check the
        // tangent planes against the class-K term's value at δ.
        let mut pa =
            PlantAware::new(PlantAwareParams { relax_margin: 0.0, ..PlantAwareParams::default() }, 0.108);
        let obs = [o];
        let s = StepInput {
            now_us: 0,
            dt: 0.004,
            p,
            v,
            u_pd,
            obstacles: &obs,
            seen_from,
            boundaries: false,
            mission_running: false,
        };
        let _ = pa.apply(&filter, &s); // primes the observer with v
        let (_, u, diag, _) = pa.apply(&filter, &StepInput { now_us: 4_000, ..s });
        assert!(u.iter().all(|c| c.is_finite()) && diag.fault.is_none(), "{u} {diag:?}");
        u
    }

    #[test]
    fn a_held_wall_point_is_its_tangent_half_space_not_a_point_being_passed() {
        // Wall x = 2, vehicle 0.25 m from it sliding along it at 2 m/s, nominal pushing into it;
        // the wall's closest point was measured 20 ms ago (4 cm behind).
        let (p, v, u_pd) = (Vec3::new(1.75, 0.0, -1.0), Vec3::new(0.0, 2.0, 0.0), Vec3::new(1.0, 0.0, 0.0));
        let held = Vec3::new(2.0, -0.04, -1.0);
        // Re-aimed from the current position (the old wrapper): the tangential speed reads as a
        // retreat of 2·0.04/0.253 = 0.32 m/s, and the filter lets the vehicle accelerate into the wall.
        let re_aimed = one_step(p, v, u_pd, ObstaclePoint::fixed(held, 1), None);
        assert!(re_aimed.x > 0.1, "{re_aimed}");
        // The surface normal from the source, or the normal aimed from where the vehicle was when
        // the point was measured: the plane x = 2; 0.25 m from it at h = 0.0625 < δ1 the class-K
        // term allows at most −γ(h − δ)/(μ s) + ē₀ = −0.0357 + 0.05 into it, i.e. it must push out.
        let with_normal = one_step(p, v, u_pd, ObstaclePoint::surface(held, -Vec3::x(), 1), None);
        let from_report = one_step(p, v, u_pd, ObstaclePoint::fixed(held, 1), Some(p - v * 0.02));
        for u in [with_normal, from_report] {
            assert!(u.x < -0.01 && u.x > -0.03, "{u}");
        }
        assert!((with_normal - from_report).norm() < 1e-4, "{with_normal} vs {from_report}");
    }

    #[test]
    fn behind_a_tangent_plane_the_filter_pushes_back_out_along_its_normal() {
        // 1 cm through the wall x = 2 (normal −x), at rest, no nominal command: the point
        // barrier alone is symmetric and would push on through (+x); the half-space pushes out.
        let p = Vec3::new(2.01, 0.0, -1.0);
        let u = one_step(
            p,
            Vec3::zeros(),
            Vec3::zeros(),
            ObstaclePoint::surface(Vec3::new(2.0, 0.0, -1.0), -Vec3::x(), 1),
            None,
        );
        assert!(u.x < -1.0, "{u}");
        // A corrupt normal is no normal: the point is aimed from the report position instead.
        let bad = ObstaclePoint {
            normal: Some(Vec3::new(f32::NAN, 0.0, 0.0)),
            ..ObstaclePoint::fixed(Vec3::new(2.0, 0.0, -1.0), 1)
        };
        let aimed = one_step(Vec3::new(1.8, 0.0, -1.0), Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), bad, None);
        let plain = one_step(
            Vec3::new(1.8, 0.0, -1.0),
            Vec3::zeros(),
            Vec3::new(1.0, 0.0, 0.0),
            ObstaclePoint::fixed(Vec3::new(2.0, 0.0, -1.0), 1),
            None,
        );
        assert_eq!(aimed, plain);
        // A non-unit normal is normalised.
        let long = ObstaclePoint::surface(Vec3::new(2.0, 0.0, -1.0), Vec3::new(-1.5, 0.0, 0.0), 1);
        let unit = ObstaclePoint::surface(Vec3::new(2.0, 0.0, -1.0), -Vec3::x(), 1);
        let (a, b) = (
            one_step(p, Vec3::zeros(), Vec3::zeros(), long, None),
            one_step(p, Vec3::zeros(), Vec3::zeros(), unit, None),
        );
        assert!((a - b).norm() < 1e-5, "{a} vs {b}");
    }

    #[test]
    fn boundaries_give_the_plane_points_below_and_above() {
        let b = Boundaries { ground_height: 0.5, ceiling_height: 3.0 };
        let pts: heapless::Vec<ObstaclePoint, 2> = b.points(&Vec3::new(1.0, 2.0, -1.0)).collect();
        assert_eq!(pts[0].point, Vec3::new(1.0, 2.0, -0.5));
        assert_eq!(pts[1].point, Vec3::new(1.0, 2.0, -3.0));
        let b = Boundaries { ground_height: 0.0, ceiling_height: 0.0 };
        assert_eq!(b.points(&Vec3::zeros()).count(), 1);
    }
}
