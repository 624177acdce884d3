//! Command-line options of the disturbances, shared by `parapet run` and `pil`
//! (flattened into their options): `--disturbances FILE`, `--wind`,
//! `--turbulence`, `--gust`. Applied after the scene's tables, in that order.
//!
//! May import: `super`, `crate::input`, `crate::sim::plant`, clap.

use std::path::PathBuf;

use clap::Args;

use super::wind::{Gust, Intensity, MAX_GUST_LENGTH_M, MAX_WIND_MPS};
use super::Disturbances;
use crate::input::InputError;
use crate::sim::plant::VehicleParams;

/// Disturbance options.
#[derive(Debug, Clone, Default, Args)]
pub struct DisturbanceArgs {
    /// [disturbances] A TOML file with [wind], [plant] and/or [faults] tables (the scene
    /// file's syntax, see docs/robustness.md); each table given replaces the scene's.
    #[arg(long, value_name = "FILE")]
    pub disturbances: Option<PathBuf>,
    /// [disturbances] Steady wind as SPEED,DIRECTION: m/s and the direction it blows from,
    /// degrees clockwise from north (270 = from the west). Replaces the steady part only.
    #[arg(long, value_name = "SPEED,DIR", allow_hyphen_values = true)]
    pub wind: Option<String>,
    /// [disturbances] Dryden turbulence: none, light, moderate, severe (MIL-HDBK-1797 low
    /// altitude) or the horizontal σ in m/s.
    #[arg(long, value_name = "LEVEL|SIGMA")]
    pub turbulence: Option<String>,
    /// [disturbances] A 1-cosine gust as AMPLITUDE,LENGTH,TIME[,DIR] (m/s, m, s, degrees
    /// from); repeatable.
    #[arg(long, value_name = "A,L,T[,DIR]", allow_hyphen_values = true)]
    pub gust: Vec<String>,
}

fn numbers(opt: &str, s: &str, n: &[usize]) -> Result<Vec<f64>, InputError> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|x| x.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if n.contains(&v.len()) && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => Err(InputError::option(opt, format!("expected {} finite comma-separated numbers", n[0]))
            .value(s)
            .allowed(match opt {
                "wind" => "SPEED,DIR".to_string(),
                _ => "AMPLITUDE,LENGTH,TIME[,DIR]".to_string(),
            })),
    }
}

impl DisturbanceArgs {
    /// Apply the options to `d` (the scene's disturbances); `vehicle` is the controller's.
    pub fn apply(&self, d: &mut Disturbances, vehicle: &VehicleParams) -> Result<(), InputError> {
        if let Some(p) = &self.disturbances {
            d.overlay_file(p, vehicle)?;
        }
        let range = |opt: &str, field: &str, x: f64, lo: f64, hi: f64| {
            if (lo..=hi).contains(&x) {
                Ok(())
            } else {
                Err(InputError::option(opt, format!("{field} out of range"))
                    .value(crate::input::num(x))
                    .allowed(format!("{lo} ≤ {field} ≤ {hi}")))
            }
        };
        if let Some(w) = &self.wind {
            let v = numbers("wind", w, &[2])?;
            range("wind", "speed", v[0], 0.0, MAX_WIND_MPS)?;
            range("wind", "direction", v[1], -360.0, 360.0)?;
            d.wind.speed = v[0];
            d.wind.direction_deg = v[1];
        }
        if let Some(t) = &self.turbulence {
            match t.as_str() {
                "none" => (d.wind.turbulence, d.wind.sigma, d.wind.w20) = (Intensity::None, None, None),
                "light" => (d.wind.turbulence, d.wind.sigma, d.wind.w20) = (Intensity::Light, None, None),
                "moderate" => {
                    (d.wind.turbulence, d.wind.sigma, d.wind.w20) = (Intensity::Moderate, None, None)
                }
                "severe" => (d.wind.turbulence, d.wind.sigma, d.wind.w20) = (Intensity::Severe, None, None),
                s => {
                    let x: f64 = s.parse().ok().filter(|x: &f64| x.is_finite()).ok_or_else(|| {
                        InputError::option("turbulence", "not a level or a number")
                            .value(s)
                            .allowed("none | light | moderate | severe | σ in m/s")
                    })?;
                    range("turbulence", "sigma", x, 0.0, MAX_WIND_MPS)?;
                    d.wind.sigma = Some(x);
                }
            }
        }
        for g in &self.gust {
            let v = numbers("gust", g, &[3, 4])?;
            range("gust", "amplitude", v[0], -MAX_WIND_MPS, MAX_WIND_MPS)?;
            range("gust", "length", v[1], 0.01, MAX_GUST_LENGTH_M)?;
            range("gust", "time", v[2], 0.0, 86_400.0)?;
            if let Some(&dir) = v.get(3) {
                range("gust", "direction", dir, -360.0, 360.0)?;
            }
            d.wind.gusts.push(Gust {
                amplitude: v[0],
                length: v[1],
                time: v[2],
                direction_deg: v.get(3).copied(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_set_the_wind_and_refuse_bad_values() {
        let v = VehicleParams::default();
        let a = DisturbanceArgs {
            wind: Some("2.5,90".into()),
            turbulence: Some("0.4".into()),
            gust: vec!["1,3,2".into(), "-1,3,4,180".into()],
            ..Default::default()
        };
        let mut d = Disturbances::default();
        a.apply(&mut d, &v).unwrap();
        assert_eq!((d.wind.speed, d.wind.direction_deg, d.wind.sigma), (2.5, 90.0, Some(0.4)));
        assert_eq!(d.wind.gusts.len(), 2);
        assert_eq!(d.wind.gusts[1].direction_deg, Some(180.0));
        for (a, want) in [
            (DisturbanceArgs { wind: Some("60,0".into()), ..Default::default() }, "option --wind"),
            (DisturbanceArgs { wind: Some("1".into()), ..Default::default() }, "SPEED,DIR"),
            (DisturbanceArgs { turbulence: Some("stormy".into()), ..Default::default() }, "severe"),
            (DisturbanceArgs { gust: vec!["1,0,1".into()], ..Default::default() }, "length"),
        ] {
            let msg = a.apply(&mut Disturbances::default(), &v).unwrap_err().to_string();
            assert!(msg.contains(want), "{msg}");
        }
    }
}
