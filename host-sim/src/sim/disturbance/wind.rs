//! Wind: a steady wind, Dryden turbulence (MIL-HDBK-1797 low-altitude model) and
//! discrete 1-cosine gusts, as one wind velocity (NED, m/s) per plant step.
//!
//! ## Conventions
//! * `direction_deg`: where the wind blows **from**, degrees clockwise from north
//!   (meteorological; 270 = from the west, blowing east = +y NED).
//! * Turbulence axes: `u` along the steady wind (towards where it blows; north when
//!   there is no steady wind), `v` horizontal to its right, `w` vertical (NED down).
//! * Dryden spectra (one-sided, ω in rad/s, `V` the speed at which the frozen
//!   turbulence field passes the vehicle, `L` the scale lengths):
//!   `Φ_u(ω) = σ_u² (2 L_u/(π V)) / (1 + (L_u ω/V)²)`,
//!   `Φ_v(ω) = σ_v² (L_v/(π V)) (1 + 3 (L_v ω/V)²) / (1 + (L_v ω/V)²)²`, `Φ_w` as `Φ_v`
//!   with `L_w`, `σ_w`. Low altitude (h in ft, clamped to [10, 1000] ft): `L_w = h`,
//!   `L_u = L_v = h / (0.177 + 0.000823 h)^1.2`, `σ_w = 0.1 W20`,
//!   `σ_u = σ_v = σ_w / (0.177 + 0.000823 h)^0.4`; `W20` (wind speed at 20 ft) 15 / 30 / 45
//!   knots for light / moderate / severe, or `w20` (m/s) given; `sigma` (m/s) sets `σ_u`
//!   directly instead (it wins over both).
//! * `V` = the air-relative speed `|v − w_steady|`, at least [`MIN_CONVECTION_MPS`]
//!   (a hovering vehicle in still air still sees the field change).
//! * Realisation per step (dt): `u`: exact first-order Gauss–Markov,
//!   `x ← a x + √(1−a²) n`, `a = e^{−V dt / L_u}`, `u = σ_u x`; `v`, `w`: two such
//!   first-order lags in cascade (`y1` exact, `y2 ← a y2 + (1−a) y1`) and
//!   `(√3 y1 + (1−√3) y2)/√2`, whose spectrum is the Dryden one
//!   `∝ (1 + √3 T s)/(1 + T s)²` with unit variance (error O(dt V/L)).
//! * Gust: from `time` on, `A/2 (1 − cos(2π s/length))` for `0 ≤ s ≤ length`, `s` the
//!   air distance travelled since `time` (∫ V dt); horizontal, from `direction_deg`
//!   (default the steady wind's).
//!
//! May import: `crate::input` (errors) and the external crates.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Lower bound of the convection speed of the turbulence field, m/s.
pub const MIN_CONVECTION_MPS: f64 = 0.5;
/// Feet per metre.
const FT: f64 = 0.3048;
/// Knots in m/s.
const KNOT: f64 = 0.514_444;
/// Caps of the wind table (m/s, m, s).
pub const MAX_WIND_MPS: f64 = 50.0;
/// Cap of a gust's length, m.
pub const MAX_GUST_LENGTH_M: f64 = 1e4;

/// Turbulence intensity (MIL-HDBK-1797 low altitude: W20 = 15 / 30 / 45 kt).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Intensity {
    /// No turbulence.
    #[default]
    None,
    /// W20 = 15 kt.
    Light,
    /// W20 = 30 kt.
    Moderate,
    /// W20 = 45 kt.
    Severe,
}

impl Intensity {
    /// Wind speed at 20 ft, m/s.
    pub fn w20(self) -> f64 {
        match self {
            Intensity::None => 0.0,
            Intensity::Light => 15.0 * KNOT,
            Intensity::Moderate => 30.0 * KNOT,
            Intensity::Severe => 45.0 * KNOT,
        }
    }
}

/// One discrete 1-cosine gust.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gust {
    /// Peak speed, m/s.
    pub amplitude: f64,
    /// Length of the gust (air distance), m.
    pub length: f64,
    /// Start time, s.
    pub time: f64,
    /// Where it blows from, degrees clockwise from north (default: the steady wind's).
    #[serde(default)]
    pub direction_deg: Option<f64>,
}

/// The `[wind]` table.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WindParams {
    /// Steady wind speed, m/s.
    pub speed: f64,
    /// Where the steady wind blows from, degrees clockwise from north.
    pub direction_deg: f64,
    /// Turbulence intensity.
    pub turbulence: Intensity,
    /// Wind speed at 20 ft that sets the turbulence, m/s (overrides `turbulence`).
    pub w20: Option<f64>,
    /// Horizontal turbulence σ_u = σ_v, m/s (overrides `turbulence`).
    pub sigma: Option<f64>,
    /// Discrete gusts.
    pub gusts: Vec<Gust>,
}

/// Horizontal unit vector (NED) towards which a wind from `deg` blows.
pub fn blowing_to(deg: f64) -> Vector3<f64> {
    let r = deg.to_radians();
    Vector3::new(-r.cos(), -r.sin(), 0.0)
}

impl WindParams {
    /// Whether the wind is still air.
    pub fn is_calm(&self) -> bool {
        self.speed == 0.0
            && self.sigma.unwrap_or(0.0) == 0.0
            && (self.sigma.is_some() || self.w20() == 0.0)
            && self.gusts.iter().all(|g| g.amplitude == 0.0)
    }

    /// The wind speed at 20 ft that sets the turbulence, m/s.
    pub fn w20(&self) -> f64 {
        self.w20.unwrap_or(self.turbulence.w20())
    }

    /// The steady wind, NED, m/s.
    pub fn steady(&self) -> Vector3<f64> {
        blowing_to(self.direction_deg) * self.speed
    }

    /// Check every value; `Err((field, reason, value, allowed))`.
    pub fn validate(&self) -> Result<(), (String, String, String, String)> {
        let check = |field: String, x: f64, lo: f64, hi: f64| {
            if x.is_finite() && x >= lo && x <= hi {
                Ok(())
            } else {
                Err((field, "out of range".to_string(), format!("{x}"), format!("{lo} ≤ x ≤ {hi}")))
            }
        };
        check("speed".into(), self.speed, 0.0, MAX_WIND_MPS)?;
        check("direction_deg".into(), self.direction_deg, -360.0, 360.0)?;
        if let Some(s) = self.sigma {
            check("sigma".into(), s, 0.0, MAX_WIND_MPS)?;
        }
        if let Some(s) = self.w20 {
            check("w20".into(), s, 0.0, 10.0 * MAX_WIND_MPS)?;
        }
        for (i, g) in self.gusts.iter().enumerate() {
            check(format!("gusts[{i}].amplitude"), g.amplitude, -MAX_WIND_MPS, MAX_WIND_MPS)?;
            check(format!("gusts[{i}].length"), g.length, 0.01, MAX_GUST_LENGTH_M)?;
            check(format!("gusts[{i}].time"), g.time, 0.0, 86_400.0)?;
            if let Some(d) = g.direction_deg {
                check(format!("gusts[{i}].direction_deg"), d, -360.0, 360.0)?;
            }
        }
        Ok(())
    }
}

/// Dryden scale lengths (m) `(L_u = L_v, L_w)` and standard deviations (m/s)
/// `(σ_u = σ_v, σ_w)` at height `h` (m) for `w20` (m/s) or a given `sigma_u`.
pub fn dryden_scales(h: f64, w20: f64, sigma_u: Option<f64>) -> ((f64, f64), (f64, f64)) {
    let hf = (h / FT).clamp(10.0, 1000.0);
    let c = 0.177 + 0.000823 * hf;
    let (l_u, l_w) = (hf / c.powf(1.2) * FT, hf * FT);
    let ratio = c.powf(0.4); // σ_w / σ_u
    let (s_u, s_w) = match sigma_u {
        Some(s) => (s, s * ratio),
        None => (0.1 * w20 / ratio, 0.1 * w20),
    };
    ((l_u, l_w), (s_u, s_w))
}

/// One Dryden component's filter state.
#[derive(Clone, Debug, Default)]
struct Lag2 {
    y1: f64,
    y2: f64,
}

impl Lag2 {
    fn start(rng: &mut ChaCha8Rng) -> Self {
        let y1 = normal(rng);
        Lag2 { y1, y2: 0.5 * y1 + 0.5 * normal(rng) }
    }
    /// Advance by a decay `a` = e^{−dt/T}; the unit-variance Dryden-v output.
    fn step(&mut self, a: f64, rng: &mut ChaCha8Rng) -> f64 {
        let y1 = self.y1;
        self.y1 = a * y1 + (1.0 - a * a).sqrt() * normal(rng);
        self.y2 = a * self.y2 + (1.0 - a) * y1;
        (3f64.sqrt() * self.y1 + (1.0 - 3f64.sqrt()) * self.y2) / 2f64.sqrt()
    }
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// The wind of one flight (its state advances with the flight).
#[derive(Clone, Debug)]
pub struct WindField {
    params: WindParams,
    steady: Vector3<f64>,
    /// Turbulence axes: u (along the steady wind), v (right of it), NED.
    axes: [Vector3<f64>; 2],
    w20: f64,
    turbulent: bool,
    rng: ChaCha8Rng,
    u: f64,
    v: Lag2,
    w: Lag2,
    /// Air distance travelled since each gust's start, m.
    gust_s: Vec<f64>,
    /// The last wind returned, NED, m/s.
    current: Vector3<f64>,
    /// [`dryden_scales`] of the last clamped height (ft): `(h, (L_u, L_w), (σ_u, σ_w))`.
    scales: (f64, (f64, f64), (f64, f64)),
}

impl WindField {
    /// The wind of `params`, turbulence seeded with `seed`.
    pub fn new(params: &WindParams, seed: u64) -> Self {
        let steady = params.steady();
        let u_axis = if params.speed > 0.0 { steady / params.speed } else { Vector3::x() };
        let v_axis = Vector3::new(-u_axis.y, u_axis.x, 0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5749_4e44_5f44_5259);
        let turbulent = params.sigma.map_or(params.w20() > 0.0, |s| s > 0.0);
        let (u, v, w) = if turbulent {
            (normal(&mut rng), Lag2::start(&mut rng), Lag2::start(&mut rng))
        } else {
            (0.0, Lag2::default(), Lag2::default())
        };
        WindField {
            steady,
            axes: [u_axis, v_axis],
            w20: params.w20(),
            turbulent,
            rng,
            u,
            v,
            w,
            gust_s: vec![0.0; params.gusts.len()],
            current: steady,
            scales: (f64::NAN, (0.0, 0.0), (0.0, 0.0)),
            params: params.clone(),
        }
    }

    /// The steady part, NED, m/s.
    pub fn steady(&self) -> Vector3<f64> {
        self.steady
    }

    /// The last wind returned by [`step`](Self::step) (the steady wind before the first).
    pub fn current(&self) -> Vector3<f64> {
        self.current
    }

    /// The wind (NED, m/s) over the step from `t` to `t + dt` (s) of a vehicle at
    /// `pos` (NED, m) moving at `vel` (NED, m/s).
    pub fn step(&mut self, t: f64, dt: f64, pos: &Vector3<f64>, vel: &Vector3<f64>) -> Vector3<f64> {
        let conv = (vel - self.steady).norm().max(MIN_CONVECTION_MPS);
        let mut wind = self.steady;
        if self.turbulent {
            // The scales change with the height only (and not at all below 10 ft).
            let hf = (-pos.z / FT).clamp(10.0, 1000.0);
            if hf != self.scales.0 {
                let (l, s) = dryden_scales(hf * FT, self.w20, self.params.sigma);
                self.scales = (hf, l, s);
            }
            let (_, (l_u, l_w), (s_u, s_w)) = self.scales;
            let a_u = (-conv * dt / l_u).exp();
            let a_w = (-conv * dt / l_w).exp();
            self.u = a_u * self.u + (1.0 - a_u * a_u).sqrt() * normal(&mut self.rng);
            let v = self.v.step(a_u, &mut self.rng);
            let w = self.w.step(a_w, &mut self.rng);
            wind += self.axes[0] * (s_u * self.u) + self.axes[1] * (s_u * v) + Vector3::z() * (s_w * w);
        }
        for (g, s) in self.params.gusts.iter().zip(self.gust_s.iter_mut()) {
            if t < g.time || *s > g.length {
                continue;
            }
            let dir = blowing_to(g.direction_deg.unwrap_or(self.params.direction_deg));
            wind += dir * (0.5 * g.amplitude * (1.0 - (2.0 * std::f64::consts::PI * *s / g.length).cos()));
            *s += conv * dt;
        }
        self.current = wind;
        wind
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conventions_and_spec_values() {
        // From the west blows east (+y NED); from the north blows south.
        assert!((blowing_to(270.0) - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
        assert!((blowing_to(0.0) - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-12);
        // MIL-HDBK-1797 at 1000 ft: L_u = L_w = 1000 ft... (0.177 + 0.823)^1.2 = 1; σ_u = σ_w.
        let ((l_u, l_w), (s_u, s_w)) = dryden_scales(1000.0 * FT, Intensity::Light.w20(), None);
        assert!((l_u - 1000.0 * FT).abs() < 1e-9 && (l_w - 1000.0 * FT).abs() < 1e-9);
        assert!((s_u - s_w).abs() < 1e-12 && (s_w - 0.1 * 15.0 * KNOT).abs() < 1e-12);
        // Below 10 ft the 10 ft values.
        assert_eq!(dryden_scales(0.5, 1.0, None), dryden_scales(10.0 * FT, 1.0, None));
    }

    #[test]
    fn gust_has_the_one_minus_cosine_shape() {
        let p = WindParams {
            direction_deg: 270.0,
            gusts: vec![Gust { amplitude: 2.0, length: 1.0, time: 1.0, direction_deg: None }],
            ..Default::default()
        };
        let mut f = WindField::new(&p, 0);
        let (pos, vel) = (Vector3::new(0.0, 0.0, -1.0), Vector3::zeros());
        let dt = 0.001;
        let mut peak = (0.0, 0.0);
        for k in 0..4000 {
            let t = k as f64 * dt;
            let w = f.step(t, dt, &pos, &vel);
            assert!(w.x.abs() < 1e-12 && w.z == 0.0);
            if t < 1.0 || t > 1.0 + 1.0 / MIN_CONVECTION_MPS + dt {
                assert!(w.y.abs() < 1e-9, "t = {t}: {w:?}");
            }
            if w.y > peak.1 {
                peak = (t, w.y);
            }
        }
        // Convected at 0.5 m/s through 1 m: peak 2 m/s at the middle (1 s after the start).
        assert!((peak.1 - 2.0).abs() < 1e-5, "{peak:?}");
        assert!((peak.0 - 2.0).abs() < 2e-3, "{peak:?}");
    }

    /// Averaged periodogram (Hann window, 50 % overlap) of `x` sampled at `dt`,
    /// one-sided in rad/s, at the bins `ks` of segments of `n` samples.
    fn psd(x: &[f64], dt: f64, n: usize, ks: &[usize]) -> Vec<f64> {
        let win: Vec<f64> =
            (0..n).map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos()).collect();
        let u: f64 = win.iter().map(|w| w * w).sum();
        let mut out = vec![0.0; ks.len()];
        let mut segs = 0;
        let mut start = 0;
        while start + n <= x.len() {
            for (o, &k) in out.iter_mut().zip(ks) {
                let (mut re, mut im) = (0.0, 0.0);
                for i in 0..n {
                    let ph = 2.0 * std::f64::consts::PI * (k * i) as f64 / n as f64;
                    re += x[start + i] * win[i] * ph.cos();
                    im -= x[start + i] * win[i] * ph.sin();
                }
                // One-sided PSD per rad/s: 2 |X|² dt / (U · 2π).
                *o += 2.0 * (re * re + im * im) * dt / u / (2.0 * std::f64::consts::PI);
            }
            segs += 1;
            start += n / 2;
        }
        out.iter().map(|o| o / segs as f64).collect()
    }

    #[test]
    fn dryden_sigma_and_spectrum_match_the_specification() {
        // Light turbulence at 10 ft, no steady wind, a vehicle moving at 2 m/s (V = 2).
        let p = WindParams { turbulence: Intensity::Light, ..Default::default() };
        let mut f = WindField::new(&p, 42);
        let (pos, vel) = (Vector3::new(0.0, 0.0, -10.0 * FT), Vector3::new(0.0, 2.0, 0.0));
        let dt = 0.02; // 50 Hz is ample for scales of seconds
        let n = 1_000_000; // 20 000 s
        let mut series = [Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n)];
        for k in 0..n {
            let w = f.step(k as f64 * dt, dt, &pos, &vel);
            series[0].push(w.x); // u axis = north without steady wind
            series[1].push(w.y); // v axis = east
            series[2].push(w.z);
        }
        let ((l_u, l_w), (s_u, s_w)) = dryden_scales(10.0 * FT, Intensity::Light.w20(), None);
        let v_conv = 2.0;
        for (axis, (l, s)) in [(l_u, s_u), (l_u, s_u), (l_w, s_w)].into_iter().enumerate() {
            let x = &series[axis];
            let mean = x.iter().sum::<f64>() / n as f64;
            let sd = (x.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
            // Correlation times up to L_u / V = 11.5 s: 20 000 s give a σ within ~3.5 %.
            assert!((sd - s).abs() < 0.1 * s, "axis {axis}: σ {sd} vs {s}");
            let seg = 2048;
            let ks = [2usize, 4, 8, 16, 32, 64];
            let got = psd(x, dt, seg, &ks);
            for (&k, g) in ks.iter().zip(&got) {
                let om = 2.0 * std::f64::consts::PI * k as f64 / (seg as f64 * dt);
                let xl = l * om / v_conv;
                let spec = if axis == 0 {
                    s * s * 2.0 * l / (std::f64::consts::PI * v_conv) / (1.0 + xl * xl)
                } else {
                    s * s * l / (std::f64::consts::PI * v_conv) * (1.0 + 3.0 * xl * xl)
                        / (1.0 + xl * xl).powi(2)
                };
                let ratio = g / spec;
                assert!((0.75..1.33).contains(&ratio), "axis {axis} ω {om:.3}: {g:.4e} vs {spec:.4e}");
            }
        }
        // The seed decides the realisation; the same seed repeats it.
        let (mut a, mut b, mut c) = (WindField::new(&p, 1), WindField::new(&p, 1), WindField::new(&p, 2));
        let (wa, wb, wc) =
            (a.step(0.0, dt, &pos, &vel), b.step(0.0, dt, &pos, &vel), c.step(0.0, dt, &pos, &vel));
        assert_eq!(wa, wb);
        assert_ne!(wa, wc);
    }

    #[test]
    fn calm_air_is_zero_and_draws_nothing() {
        let p = WindParams::default();
        assert!(p.is_calm());
        let mut f = WindField::new(&p, 3);
        assert_eq!(f.step(0.0, 0.001, &Vector3::zeros(), &Vector3::new(1.0, 0.0, 0.0)), Vector3::zeros());
        let bad = WindParams { speed: -1.0, ..Default::default() };
        assert_eq!(bad.validate().unwrap_err().0, "speed");
    }
}
