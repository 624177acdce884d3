//! Disturbances of a flight: wind ([`wind`]: steady, Dryden turbulence, 1-cosine
//! gusts), a plant vehicle that differs from the controller's (`[plant]`, vehicle
//! mismatch), and sensor / report / rotor faults ([`faults`]).
//!
//! A scene may carry the tables `[wind]`, `[plant]` and `[faults]`; `parapet run
//! --disturbances FILE` takes the same tables from another file (each table given
//! there replaces the scene's) and `--wind`, `--turbulence`, `--gust` set the wind
//! on the command line. [`Disturbances`] is the parsed, validated set;
//! [`Live`] applies it to the plant during a flight (wind each step, the rotor
//! fault from its time on). With every table absent nothing changes: the plant
//! flies in still air with the controller's vehicle, no fault is drawn.
//!
//! `[plant]` takes any `[vehicle]` key (`crate::sim::plant::VehicleParams`) and
//! overrides the scene's `[vehicle]` for the **plant only**: the controller keeps
//! the scene's `[vehicle]` (its model of the vehicle), the simulated vehicle flies
//! with the merged values. [`Mismatch`] expresses the same as factors on the
//! controller's vehicle (what `parapet campaign` draws).
//!
//! May import: `crate::sim::plant`, `crate::input` and the external crates.

pub mod args;
pub mod faults;
pub mod wind;

use std::path::Path;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::input::InputError;
use crate::sim::plant::{Plant, VehicleParams};
use faults::FaultParams;
use wind::{WindField, WindParams};

/// The disturbances of a flight.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Disturbances {
    /// The `[wind]` table.
    pub wind: WindParams,
    /// The plant's vehicle when it differs from the controller's (`[plant]` merged onto `[vehicle]`).
    pub plant: Option<VehicleParams>,
    /// The `[faults]` table.
    pub faults: FaultParams,
}

/// Vehicle mismatch as factors on the controller's vehicle (1 = no mismatch).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Mismatch {
    /// Mass factor.
    pub mass: f64,
    /// Inertia factor (all three axes).
    pub inertia: f64,
    /// Thrust coefficient factor.
    pub k_f: f64,
    /// Torque coefficient factor.
    pub k_m: f64,
    /// Motor time-constant factor.
    pub motor_tau: f64,
    /// Drag factor (linear, rotor and parasitic drag).
    pub drag: f64,
}

impl Default for Mismatch {
    fn default() -> Self {
        Mismatch { mass: 1.0, inertia: 1.0, k_f: 1.0, k_m: 1.0, motor_tau: 1.0, drag: 1.0 }
    }
}

impl Mismatch {
    /// The plant vehicle: `v` with the factors applied.
    pub fn apply(&self, v: &VehicleParams) -> VehicleParams {
        VehicleParams {
            mass: v.mass * self.mass,
            inertia: v.inertia.map(|i| i * self.inertia),
            k_f: v.k_f * self.k_f,
            k_m: v.k_m * self.k_m,
            motor_tau: v.motor_tau * self.motor_tau,
            drag: v.drag.map(|d| d * self.drag),
            rotor_drag_kd: v.rotor_drag_kd * self.drag,
            rotor_drag_kz: v.rotor_drag_kz * self.drag,
            parasitic_drag: v.parasitic_drag.map(|d| d * self.drag),
            ..v.clone()
        }
    }
}

/// The raw disturbance tables of a TOML file (scene or disturbance file).
#[derive(Clone, Debug, Default, Deserialize)]
pub struct RawTables {
    /// `[wind]`.
    pub wind: Option<WindParams>,
    /// `[plant]` (vehicle keys).
    pub plant: Option<toml::Table>,
    /// `[faults]`.
    pub faults: Option<FaultParams>,
}

/// `[plant]` keys merged onto `vehicle`, validated; `file` labels errors.
pub fn merge_plant(
    vehicle: &VehicleParams,
    plant: &toml::Table,
    file: &str,
) -> Result<VehicleParams, InputError> {
    let mut base = toml::Table::try_from(vehicle)
        .map_err(|e| InputError::file(file, format!("cannot merge the vehicle: {e}")).table("plant"))?;
    for (k, v) in plant {
        base.insert(k.clone(), v.clone());
    }
    let merged: VehicleParams = toml::Value::Table(base)
        .try_into()
        .map_err(|e: toml::de::Error| InputError::file(file, e.message().to_string()).table("plant"))?;
    merged.validate().map_err(|e| InputError::file(file, e.reason).table("plant").field(e.field))?;
    check_integrable(&merged).map_err(|(field, value, allowed)| {
        InputError::file(file, "too stiff for the plant's 1 ms RK4 step")
            .table("plant")
            .field(field)
            .value(value)
            .allowed(allowed)
    })?;
    Ok(merged)
}

/// Plant values the fixed-step RK4 (step ≤ 1 ms) cannot integrate: linear drag or
/// rotor drag at full speed faster than the step (`drag ≤ m / 1 ms`,
/// `4 k_d ω_max ≤ m / 1 ms`, the same for `k_z`) and a yaw torque coefficient beyond
/// the roll arm's moment per unit thrust (`k_m ≤ k_f · arm_length`), as
/// `crate::flight::validate` refuses them for `[vehicle]`. `Err((field, value, allowed))`.
pub fn check_integrable(v: &VehicleParams) -> Result<(), (String, String, String)> {
    let max_drag = v.mass / super::INNER_DT;
    let num = crate::input::num;
    if let Some(d) = v.drag.iter().find(|d| **d > max_drag) {
        return Err(("drag".into(), num(*d), format!("0 ≤ drag ≤ mass / 1 ms = {}", num(max_drag))));
    }
    let max_rotor = max_drag / (4.0 * v.omega_max);
    for (field, k) in [("rotor_drag_kd", v.rotor_drag_kd), ("rotor_drag_kz", v.rotor_drag_kz)] {
        if k > max_rotor {
            return Err((
                field.into(),
                num(k),
                format!("0 ≤ {field} ≤ mass / (4 omega_max 1 ms) = {}", num(max_rotor)),
            ));
        }
    }
    let max_km = v.k_f * v.arm_length;
    if v.k_m > max_km {
        return Err(("k_m".into(), num(v.k_m), format!("0 ≤ k_m ≤ k_f · arm_length = {}", num(max_km))));
    }
    Ok(())
}

impl Disturbances {
    /// Whether the flight is undisturbed (still air, the controller's vehicle, no fault).
    pub fn is_none(&self) -> bool {
        self.wind.is_calm() && self.plant.is_none() && self.faults == FaultParams::default()
    }

    /// The plant's vehicle given the controller's `vehicle`.
    pub fn plant_vehicle(&self, vehicle: &VehicleParams) -> VehicleParams {
        self.plant.clone().unwrap_or_else(|| vehicle.clone())
    }

    /// Validate and take the tables present in `raw` (over `self`); `vehicle` is the
    /// controller's (what `[plant]` overrides), `file` labels errors.
    pub fn overlay(&mut self, raw: RawTables, vehicle: &VehicleParams, file: &str) -> Result<(), InputError> {
        if let Some(w) = raw.wind {
            w.validate().map_err(|(field, reason, value, allowed)| {
                InputError::file(file, reason).table("wind").field(field).value(value).allowed(allowed)
            })?;
            self.wind = w;
        }
        if let Some(p) = raw.plant {
            self.plant = Some(merge_plant(vehicle, &p, file)?);
        }
        if let Some(f) = raw.faults {
            f.validate().map_err(|(field, value, allowed)| {
                InputError::file(file, "out of range")
                    .table("faults")
                    .field(field)
                    .value(value)
                    .allowed(allowed)
            })?;
            self.faults = f;
        }
        Ok(())
    }

    /// Read a disturbance file (TOML with `[wind]`, `[plant]`, `[faults]`; other
    /// tables are refused) and overlay it on `self`.
    pub fn overlay_file(&mut self, path: &Path, vehicle: &VehicleParams) -> Result<(), InputError> {
        let file = path.display().to_string();
        let src = crate::input::read_text(path)?;
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct File {
            wind: Option<WindParams>,
            plant: Option<toml::Table>,
            faults: Option<FaultParams>,
        }
        let f: File = toml::from_str(&src).map_err(|e| InputError::file(&file, e.message().to_string()))?;
        self.overlay(RawTables { wind: f.wind, plant: f.plant, faults: f.faults }, vehicle, &file)
    }

    /// The TOML text of a disturbance file that reproduces `self` (for `--disturbances`).
    pub fn to_toml(&self) -> String {
        #[derive(Serialize)]
        struct File<'a> {
            wind: &'a WindParams,
            #[serde(skip_serializing_if = "Option::is_none")]
            plant: Option<&'a VehicleParams>,
            faults: &'a FaultParams,
        }
        toml::to_string(&File { wind: &self.wind, plant: self.plant.as_ref(), faults: &self.faults })
            .unwrap_or_default()
    }
}

/// The disturbances acting during one flight: the wind field and the rotor fault.
#[derive(Clone, Debug)]
pub struct Live {
    wind: Option<WindField>,
    rotor_fault: Option<faults::RotorFault>,
    fault_on: bool,
}

impl Live {
    /// The live disturbances of `d` for a flight with seed `seed`.
    pub fn new(d: &Disturbances, seed: u64) -> Self {
        Live {
            wind: (!d.wind.is_calm()).then(|| WindField::new(&d.wind, seed)),
            rotor_fault: d.faults.rotor_fault.clone(),
            fault_on: false,
        }
    }

    /// Before the plant steps of `[t, t + dt)`: set the wind and the rotor fault.
    pub fn apply(&mut self, t: f64, dt: f64, plant: &mut Plant) {
        if let Some(w) = &mut self.wind {
            let (pos, vel) = (plant.state.pos, plant.state.vel);
            plant.set_wind(w.step(t, dt, &pos, &vel));
        }
        if let Some(f) = &self.rotor_fault {
            if !self.fault_on && t >= f.time {
                let mut s = [1.0; 4];
                s[(f.rotor as usize).clamp(1, 4) - 1] = f.factor;
                plant.set_rotor_scale(s);
                self.fault_on = true;
            }
        }
    }

    /// The wind of the current step, NED, m/s (zero in still air).
    pub fn wind(&self) -> Vector3<f64> {
        self.wind.as_ref().map_or(Vector3::zeros(), WindField::current)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_parse_validate_and_name_the_field() {
        let v = VehicleParams::default();
        let src = r#"
            [wind]
            speed = 2.0
            direction_deg = 270
            turbulence = "light"
            [[wind.gusts]]
            amplitude = 1.5
            length = 4.0
            time = 3.0
            [plant]
            mass = 0.6
            [faults]
            gyro_bias_walk = 0.001
            rotor_fault = { rotor = 2, factor = 0.7, time = 5.0 }
        "#;
        let raw: RawTables = toml::from_str(src).unwrap();
        let mut d = Disturbances::default();
        assert!(d.is_none());
        d.overlay(raw, &v, "f.toml").unwrap();
        assert!(!d.is_none());
        let p = d.plant_vehicle(&v);
        assert_eq!(p.mass, 0.6);
        assert_eq!(p.k_f, v.k_f);
        assert!((d.wind.steady() - Vector3::new(0.0, 2.0, 0.0)).norm() < 1e-12);
        // The file text reproduces the set.
        let again: RawTables = toml::from_str(&d.to_toml()).unwrap();
        let mut e = Disturbances::default();
        e.overlay(again, &v, "g.toml").unwrap();
        assert_eq!(d, e);
        // Errors name file, table, field, value and range.
        let bad: RawTables = toml::from_str("[faults]\nfix_outlier_prob = 2.0\n").unwrap();
        let msg = Disturbances::default().overlay(bad, &v, "f.toml").unwrap_err().to_string();
        assert!(
            msg.contains("f.toml") && msg.contains("[faults]") && msg.contains("fix_outlier_prob"),
            "{msg}"
        );
        assert!(msg.contains("got 2") && msg.contains("0 ≤ x ≤ 1"), "{msg}");
        let bad: RawTables = toml::from_str("[plant]\nmass = -1.0\n").unwrap();
        let msg = Disturbances::default().overlay(bad, &v, "f.toml").unwrap_err().to_string();
        assert!(msg.contains("[plant]") && msg.contains("mass"), "{msg}");
        for (t, field) in [
            ("k_m = 1e10", "k_m"),
            ("drag = [0.1, 0.1, 1e30]", "drag"),
            ("rotor_drag_kd = 1.0", "rotor_drag_kd"),
        ] {
            let bad: RawTables = toml::from_str(&format!("[plant]\n{t}\n")).unwrap();
            let msg = Disturbances::default().overlay(bad, &v, "f.toml").unwrap_err().to_string();
            assert!(msg.contains("[plant]") && msg.contains(field) && msg.contains("allowed"), "{msg}");
        }
        let bad: RawTables = toml::from_str("[wind]\nspeed = 99.0\n").unwrap();
        let msg = Disturbances::default().overlay(bad, &v, "f.toml").unwrap_err().to_string();
        assert!(msg.contains("[wind]") && msg.contains("speed") && msg.contains("99"), "{msg}");
    }

    #[test]
    fn mismatch_factors_apply_to_the_plant_only() {
        let v = VehicleParams { rotor_drag_kd: 1e-5, ..Default::default() };
        let m = Mismatch { mass: 1.2, k_f: 0.9, motor_tau: 2.0, drag: 1.5, ..Default::default() };
        let p = m.apply(&v);
        assert!((p.mass - 0.6).abs() < 1e-12 && (p.k_f - 0.9 * v.k_f).abs() < 1e-18);
        assert!((p.motor_tau - 0.04).abs() < 1e-12 && (p.drag[0] - 0.15).abs() < 1e-12);
        assert!((p.rotor_drag_kd - 1.5e-5).abs() < 1e-18);
        assert_eq!(Mismatch::default().apply(&v), v);
    }

    #[test]
    fn live_rotor_fault_starts_at_its_time() {
        let d = Disturbances {
            faults: FaultParams {
                rotor_fault: Some(faults::RotorFault { rotor: 1, factor: 0.5, time: 0.01 }),
                ..Default::default()
            },
            ..Default::default()
        };
        let mut plant = Plant::new(VehicleParams::default()).unwrap();
        plant.ground = false;
        plant.set_hover(Vector3::new(0.0, 0.0, -5.0), 0.0);
        let mut live = Live::new(&d, 0);
        for k in 0..10 {
            live.apply(k as f64 * 0.001, 0.001, &mut plant);
            plant.step(0.001);
        }
        assert!(plant.state.rates.norm() < 1e-12, "healthy before the fault");
        for k in 10..20 {
            live.apply(k as f64 * 0.001, 0.001, &mut plant);
            plant.step(0.001);
        }
        assert!(plant.state.rates.x > 0.0, "rotor 1 weak: rolls right");
    }
}
