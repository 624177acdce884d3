//! Open-loop replay: drive the plant with rotor speeds from a CSV and write the
//! resulting states, for validation against other simulators.
//!
//! ## Input CSV
//! Header `t,w1,w2,w3,w4` then one row per sample: time (s, strictly
//! increasing) and the four rotor speeds (rad/s, ≥ 0). Rotor order is PX4's,
//! body FRD (see [`parapet_core::airframe`]), `a = arm_length/√2`:
//!
//! | column | rotor | position (x fwd, y right) | spin seen from above |
//! |--------|-------|---------------------------|----------------------|
//! | w1     | 1     | front-right (+a, +a)      | CCW                  |
//! | w2     | 2     | rear-left   (−a, −a)      | CCW                  |
//! | w3     | 3     | front-left  (+a, −a)      | CW                   |
//! | w4     | 4     | rear-right  (−a, +a)      | CW                   |
//!
//! Speeds are held constant from their row's time to the next row's time
//! (zero-order hold). By default they are imposed on the rotors directly
//! (no motor lag) so that only the rigid-body and rotor-force model is
//! compared; with `motor_lag` they are commands passed through the
//! first-order motor model instead, the rotors starting at the first row's
//! speeds (or at [`ReplayOptions::initial_speed`]), so the vehicle does not drop
//! while they spin up from rest.
//!
//! ## Output CSV
//! `t,x,y,z,vx,vy,vz,qw,qx,qy,qz,p,q,r`, one row per input row, the state at
//! that row's time (before its speeds act). Frames: position/velocity in world
//! **NED** (x north, y east, z down; m, m/s), quaternion `(qw, qx, qy, qz)`
//! rotating body **FRD** vectors into NED, body rates `(p, q, r)` about FRD
//! axes (rad/s). The vehicle starts at rest, level, at the given start
//! position (NED), heading north. The ground plane is off unless requested.
//!
//! ## Vehicle file
//! [`load_vehicle`]: a `[vehicle]` table (a scene file works: its other tables
//! are ignored, a scene without `[vehicle]` gives the default vehicle, as the
//! scene loader does) or VehicleParams keys at the top level.
//!
//! ## Limits ([`crate::input::limits`])
//! At most `MAX_REPLAY_ROWS` data rows spanning at most `MAX_REPLAY_SPAN_S`
//! (last t − first t), times within ±10¹⁰ s (Unix time fits); dt in
//! [`MIN_DT_S`, `MAX_DT_S`] and at most `MAX_PLANT_STEPS` integration steps,
//! so a replay's time and memory are bounded by its input.
//!
//! May import: [`crate::sim::plant`], [`crate::input`], csv, serde.

use std::path::Path;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::input::{limits, Fixed, InputError};
use crate::sim::plant::{Plant, VehicleParams};

/// One input sample: time (s) and rotor speeds (rad/s, rotors 1..4).
pub type RotorSample = (f64, [f64; 4]);

/// Columns of the input CSV.
const ROTOR_COLUMNS: [&str; 5] = ["t", "w1", "w2", "w3", "w4"];

/// One input row (serde record of the input CSV).
#[derive(Deserialize)]
struct RotorRow {
    t: f64,
    w1: f64,
    w2: f64,
    w3: f64,
    w4: f64,
}

/// One output row: the state at a row's time (serde record of the output CSV).
#[derive(Serialize)]
struct StateRow {
    t: Fixed<6>,
    x: Fixed<9>,
    y: Fixed<9>,
    z: Fixed<9>,
    vx: Fixed<9>,
    vy: Fixed<9>,
    vz: Fixed<9>,
    qw: Fixed<9>,
    qx: Fixed<9>,
    qy: Fixed<9>,
    qz: Fixed<9>,
    p: Fixed<9>,
    q: Fixed<9>,
    r: Fixed<9>,
}

/// Largest |t| accepted, s: room for a Unix-time clock (1.7e9 s), small enough
/// that the gaps between rows keep µs resolution in `f64`.
const MAX_ABS_TIME_S: f64 = 1e10;

/// Parse the `t,w1,w2,w3,w4` CSV. Errors name the line and column, the value
/// and the allowed range; the row count and time span are capped (module docs).
pub fn parse_rotor_csv(src: &str) -> Result<Vec<RotorSample>, String> {
    let mut out: Vec<RotorSample> = Vec::new();
    let mut reader =
        csv::ReaderBuilder::new().trim(csv::Trim::All).flexible(true).from_reader(src.as_bytes());
    let header = reader.headers().map_err(|e| format!("line 1: {e}"))?.clone();
    if header.is_empty() || header.iter().all(str::is_empty) {
        return Err("empty file (expected header `t,w1,w2,w3,w4`)".into());
    }
    if header.iter().ne(ROTOR_COLUMNS) {
        return Err(format!(
            "line 1: header must be `t,w1,w2,w3,w4`, got `{}`",
            header.iter().collect::<Vec<_>>().join(",")
        ));
    }
    for rec in reader.records() {
        let rec = rec.map_err(|e| e.to_string())?;
        let line = rec.position().map_or(0, |p| p.line());
        if rec.len() == 1 && rec.get(0) == Some("") {
            continue; // a line of blanks
        }
        if rec.len() != 5 {
            return Err(format!("line {line}: expected 5 columns, got {}", rec.len()));
        }
        let row: RotorRow = rec.deserialize(Some(&header)).map_err(|_| {
            // Name the first field that is not a number.
            let k = rec.iter().position(|f| f.parse::<f64>().is_err()).unwrap_or(0);
            format!(
                "line {line}: column `{}`: not a finite number: `{}`",
                ROTOR_COLUMNS[k],
                rec.get(k).unwrap_or("")
            )
        })?;
        let v = [row.t, row.w1, row.w2, row.w3, row.w4];
        if let Some(k) = v.iter().position(|x| !x.is_finite()) {
            return Err(format!(
                "line {line}: column `{}`: not a finite number: `{}`",
                ROTOR_COLUMNS[k],
                rec.get(k).unwrap_or("")
            ));
        }
        let i = line as usize - 1;
        if v[1..].iter().any(|w| *w < 0.0) {
            return Err(format!("line {}: rotor speeds must be >= 0", i + 1));
        }
        if v[0].abs() > MAX_ABS_TIME_S {
            return Err(format!(
                "line {}: column `t`: time out of range (got {}; allowed |t| ≤ {MAX_ABS_TIME_S:e} s)",
                i + 1,
                crate::input::num(v[0])
            ));
        }
        if let Some((t_prev, _)) = out.last() {
            if v[0] <= *t_prev {
                return Err(format!("line {}: column `t`: times must increase strictly", i + 1));
            }
        }
        if let Some((t0, _)) = out.first() {
            if v[0] - t0 > limits::MAX_REPLAY_SPAN_S {
                return Err(format!(
                    "line {}: column `t`: the replay would span {} s from the first row's t = {} (allowed ≤ {} s)",
                    i + 1,
                    crate::input::num(v[0] - t0),
                    crate::input::num(*t0),
                    limits::MAX_REPLAY_SPAN_S
                ));
            }
        }
        if out.len() == limits::MAX_REPLAY_ROWS {
            return Err(format!(
                "line {}: more than {} data rows (allowed ≤ {} rows)",
                i + 1,
                limits::MAX_REPLAY_ROWS,
                limits::MAX_REPLAY_ROWS
            ));
        }
        out.push((v[0], [v[1], v[2], v[3], v[4]]));
    }
    if out.is_empty() {
        return Err("no data rows".into());
    }
    Ok(out)
}

/// Load vehicle parameters from a TOML file: a `[vehicle]` table (a scene file:
/// other tables are ignored, a scene without `[vehicle]` flies the default
/// vehicle, as the scene loader does), or VehicleParams keys at the top level.
pub fn load_vehicle(path: &Path) -> Result<VehicleParams, InputError> {
    let file = path.display();
    let src = crate::input::read_text(path)?;
    let value: toml::Table = toml::from_str(&src).map_err(|e| InputError::file(&file, e.message().trim()))?;
    let is_scene = ["mission", "bounds", "obstacles"].iter().any(|k| value.contains_key(*k));
    let table = match value.get("vehicle") {
        Some(toml::Value::Table(t)) => t.clone(),
        Some(_) => return Err(InputError::file(&file, "must be a table").field("vehicle")),
        None if is_scene => toml::Table::new(),
        None => value,
    };
    let v: VehicleParams = toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| InputError::file(&file, e.message().trim()).table("vehicle"))?;
    v.validate().map_err(|e| InputError::file(&file, e.reason).table("vehicle").field(e.field))?;
    Ok(v)
}

/// Replay options.
#[derive(Clone, Debug)]
pub struct ReplayOptions {
    /// Integration step, s (default 0.001).
    pub dt: f64,
    /// Start position, NED, m.
    pub start_ned: Vector3<f64>,
    /// Pass the speeds through the motor lag model instead of imposing them.
    pub motor_lag: bool,
    /// Simulate the ground plane z = 0.
    pub ground: bool,
    /// With `motor_lag`: the rotor speeds at the first row's time, rad/s (default:
    /// the first row's speeds).
    pub initial_speed: Option<[f64; 4]>,
    /// Steady wind, NED, m/s (default still air).
    pub wind_ned: Vector3<f64>,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            dt: 0.001,
            start_ned: Vector3::zeros(),
            motor_lag: false,
            ground: false,
            initial_speed: None,
            wind_ned: Vector3::zeros(),
        }
    }
}

/// Run the replay; returns the output CSV text.
pub fn replay(
    vehicle: VehicleParams,
    inputs: &[RotorSample],
    opts: &ReplayOptions,
) -> Result<String, String> {
    if !(limits::MIN_DT_S..=limits::MAX_DT_S).contains(&opts.dt) {
        return Err(format!(
            "option --dt: integration step out of range (got {}; allowed {:e} ≤ dt ≤ {:e} s)",
            crate::input::num(opts.dt),
            limits::MIN_DT_S,
            limits::MAX_DT_S
        ));
    }
    if let (Some(first), Some(last)) = (inputs.first(), inputs.last()) {
        let steps = (last.0 - first.0) / opts.dt;
        if steps.is_nan() || steps > limits::MAX_PLANT_STEPS {
            return Err(format!(
                "option --dt: the replay needs {steps:.3e} steps, more than the cap of {:e} (raise --dt)",
                limits::MAX_PLANT_STEPS
            ));
        }
    }
    let mut plant = Plant::new(vehicle).map_err(|e| e.to_string())?;
    plant.ground = opts.ground;
    plant.state.pos = opts.start_ned;
    if !opts.wind_ned.iter().all(|w| w.is_finite()) {
        return Err(format!("wind must be finite, got {:?}", opts.wind_ned));
    }
    plant.set_wind(opts.wind_ned);
    if opts.motor_lag {
        if let Some(w0) = opts.initial_speed.or(inputs.first().map(|s| s.1)) {
            if !w0.iter().all(|w| w.is_finite() && *w >= 0.0) {
                return Err(format!("initial rotor speed must be finite and >= 0, got {w0:?}"));
            }
            plant.set_rotor_speeds(w0);
        }
    }
    let mut out = csv::Writer::from_writer(Vec::new());
    let mut t = inputs.first().map(|s| s.0).unwrap_or(0.0);
    for (k, (tk, w)) in inputs.iter().enumerate() {
        // Integrate up to this row's time with the previous row's speeds.
        // A counted number of equal steps (≤ dt each): no accumulation of `t`
        // that could stall, and at most span / dt + rows steps in all.
        if k > 0 {
            let gap = *tk - t;
            let n = (gap / opts.dt - 1e-9).ceil().max(1.0) as u64;
            let h = gap / n as f64;
            for _ in 0..n {
                plant.step(h);
            }
            t = *tk;
        }
        out.serialize(state_row(*tk, &plant)).map_err(|e| e.to_string())?;
        if opts.motor_lag {
            plant.set_rotor_speed_commands(*w);
        } else {
            plant.set_rotor_speeds(*w);
        }
    }
    let bytes = out.into_inner().map_err(|e| e.to_string())?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

fn state_row(t: f64, plant: &Plant) -> StateRow {
    let s = &plant.state;
    let q = s.att.quaternion();
    StateRow {
        t: Fixed(t),
        x: Fixed(s.pos.x),
        y: Fixed(s.pos.y),
        z: Fixed(s.pos.z),
        vx: Fixed(s.vel.x),
        vy: Fixed(s.vel.y),
        vz: Fixed(s.vel.z),
        qw: Fixed(q.w),
        qx: Fixed(q.i),
        qy: Fixed(q.j),
        qz: Fixed(q.k),
        p: Fixed(s.rates.x),
        q: Fixed(s.rates.y),
        r: Fixed(s.rates.z),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hover_replay_stays_put_and_csv_errors_are_located() {
        let v = VehicleParams::default();
        let w = v.hover_omega();
        let csv = format!("t,w1,w2,w3,w4\n0,{w},{w},{w},{w}\n0.5,{w},{w},{w},{w}\n1.0,0,0,0,0\n");
        let rows = parse_rotor_csv(&csv).unwrap();
        let out = replay(v, &rows, &ReplayOptions::default()).unwrap();
        let last: Vec<f64> = out.lines().last().unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(out.lines().count(), 4);
        assert!((last[0] - 1.0).abs() < 1e-9);
        assert!(last[3].abs() < 1e-6, "z = {}", last[3]);
        assert!((last[7] - 1.0).abs() < 1e-9);
        assert!(parse_rotor_csv("t,w1,w2,w3,w4\n0,1,2,3,x\n").unwrap_err().contains("w4"));
        assert!(parse_rotor_csv("t,a,b\n").is_err());
        assert!(parse_rotor_csv("t,w1,w2,w3,w4\n1,1,1,1,1\n0.5,1,1,1,1\n").unwrap_err().contains("line 3"));
    }

    #[test]
    fn motor_lag_replay_starts_at_the_first_speed() {
        let v = VehicleParams::default();
        let w = v.hover_omega();
        let csv = format!("t,w1,w2,w3,w4\n0,{w},{w},{w},{w}\n0.5,{w},{w},{w},{w}\n");
        let rows = parse_rotor_csv(&csv).unwrap();
        let opts = ReplayOptions { motor_lag: true, ..Default::default() };
        let out = replay(v.clone(), &rows, &opts).unwrap();
        let vz: f64 = out.lines().last().unwrap().split(',').nth(6).unwrap().parse().unwrap();
        assert!(vz.abs() < 1e-9, "hovers from the start: vz = {vz}");
        // A stated initial speed of 0: the rotors spin up and the vehicle sinks first.
        let opts = ReplayOptions { motor_lag: true, initial_speed: Some([0.0; 4]), ..Default::default() };
        let out = replay(v, &rows, &opts).unwrap();
        let vz: f64 = out.lines().last().unwrap().split(',').nth(6).unwrap().parse().unwrap();
        assert!(vz > 0.1, "sinks while spinning up: vz = {vz}");
    }

    #[test]
    fn spans_rows_and_steps_are_capped() {
        let e = parse_rotor_csv("t,w1,w2,w3,w4\n0,1,1,1,1\n1e9,1,1,1,1\n").unwrap_err();
        assert!(e.contains("line 3") && e.contains("`t`") && e.contains("1e9") && e.contains("3600"), "{e}");
        let e = parse_rotor_csv("t,w1,w2,w3,w4\n1e300,1,1,1,1\n").unwrap_err();
        assert!(e.contains("line 2") && e.contains("1e300"), "{e}");
        let mut big = String::from("t,w1,w2,w3,w4\n");
        for k in 0..=limits::MAX_REPLAY_ROWS {
            big.push_str(&format!("{},0,0,0,0\n", k as f64 * 1e-3));
        }
        let e = parse_rotor_csv(&big).unwrap_err();
        assert!(e.contains(&format!("line {}", limits::MAX_REPLAY_ROWS + 2)) && e.contains("rows"), "{e}");
        let rows = [(0.0, [0.0; 4]), (10.0, [0.0; 4])];
        let opts = ReplayOptions { dt: 1e-7, ..ReplayOptions::default() };
        assert!(replay(VehicleParams::default(), &rows, &opts).unwrap_err().contains("--dt"));
        // Steps are counted: an uneven gap ends exactly on the row's time.
        let rows = [(0.0, [0.0; 4]), (0.0105, [0.0; 4])];
        let out = replay(VehicleParams::default(), &rows, &ReplayOptions::default()).unwrap();
        assert!(out.lines().last().unwrap().starts_with("0.010500,"), "{out}");
    }
}
