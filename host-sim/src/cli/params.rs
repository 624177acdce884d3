//! `parapet params export|import`: the controller's parameters as a QGroundControl
//! parameter file (`.params`), next to the metadata JSON of `cargo xtask params`.
//!
//! The format is the one QGroundControl writes with "Save to file" (and reads with "Load
//! from file"): `#` comment lines (`# Onboard parameters for Vehicle 1`, `# Stack: …`,
//! `# Vehicle-Id Component-Id Name Value Type`), then one tab-separated line per parameter:
//! `sysid compid NAME value type`, `type` a `MAV_PARAM_TYPE` (9 = REAL32, which is every
//! parameter on Parapet's wire; 6 = INT32 is accepted on import for code parameters).
//!
//! * `export FILE [--scene S]`: the boot defaults of the firmware (`ControllerParams::default`)
//!   or, with a scene, the set `parapet run`/`pil` fly for it (the scene's vehicle and
//!   `[controller]` table; straight path).
//! * `import FILE`: read and check a file (every line: system/component of the vehicle, a
//!   known name, a value in the parameter's range, a type; the whole set consistent) and print
//!   the parameters that differ from the defaults. Exit 2 naming file, line, field, value and
//!   allowed range on the first bad line.
//!
//! May import: `parapet-core` (parameter table, ids), [`crate::world::scene`],
//! [`crate::flight::runner`] (the run's parameters), [`super`] (errors, output), `crate::input`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use parapet_core::controller::ControllerParams;
use parapet_core::params::{self, TABLE};
use parapet_core::wire::ids::{AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};

use super::CliError;
use crate::input::InputError;

/// `MAV_PARAM_TYPE_REAL32`.
pub const TYPE_REAL32: u8 = 9;
/// `MAV_PARAM_TYPE_INT32`.
pub const TYPE_INT32: u8 = 6;

/// `parapet params …`.
#[derive(Debug, clap::Args)]
pub struct ParamsArgs {
    #[command(subcommand)]
    command: ParamsCommand,
}

#[derive(Debug, clap::Subcommand)]
enum ParamsCommand {
    /// Write the parameters as a QGroundControl `.params` file (tab-separated).
    Export {
        /// Output file (e.g. parapet.params).
        file: PathBuf,
        /// The parameters `parapet run` flies for this scene (default: the firmware's boot defaults).
        #[arg(long)]
        scene: Option<PathBuf>,
    },
    /// Read and check a QGroundControl `.params` file; print the values that differ from the defaults.
    Import {
        /// Input file.
        file: PathBuf,
    },
}

/// Shortest decimal that reads back as the same `f32` (QGC reads it as a float).
fn value_text(v: f32) -> String {
    format!("{v}")
}

/// The `.params` text of `p`.
pub fn to_qgc(p: &ControllerParams) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Onboard parameters for Vehicle {VEHICLE_SYSTEM_ID}");
    let _ = writeln!(s, "#");
    let _ = writeln!(s, "# Stack: Parapet");
    let _ = writeln!(s, "# Vehicle: Multi-Rotor");
    let _ = writeln!(s, "# Version: {}", env!("CARGO_PKG_VERSION"));
    let _ = writeln!(s, "#");
    let _ = writeln!(s, "# Vehicle-Id Component-Id Name Value Type");
    for d in &TABLE {
        let _ = writeln!(
            s,
            "{VEHICLE_SYSTEM_ID}\t{AUTOPILOT_COMPONENT_ID}\t{}\t{}\t{TYPE_REAL32}",
            d.name,
            value_text((d.get)(p))
        );
    }
    s
}

/// Parse a `.params` text (`source` names it in errors) onto the defaults; every line
/// checked. Errors name the line, field, value and allowed values.
pub fn from_qgc(text: &str, source: &str) -> Result<ControllerParams, InputError> {
    let mut p = ControllerParams::default();
    for (name, v) in entries_of_qgc(text, source)? {
        params::set(&mut p, name, v)
            .map_err(|_| InputError::file(source, "value refused").field(name).value(v))?;
    }
    p.validate().map_err(|e| {
        InputError::file(source, "the parameter set is inconsistent").value(e.to_string()).allowed(
            "a consistent set (see `parapet run --help` and docs/cascade.md for the cross-parameter rules)",
        )
    })?;
    Ok(p)
}

/// The `(name, value)` lines of a `.params` text (`source` names it in errors), in file order,
/// each checked: the vehicle's system and component, a known name given once, a type, a value
/// in the parameter's range. Errors name the line, field, value and allowed values.
pub fn entries_of_qgc(text: &str, source: &str) -> Result<Vec<(&'static str, f32)>, InputError> {
    let mut out = Vec::new();
    let mut seen = vec![false; TABLE.len()];
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let at = |why: &str| InputError::file(source, format!("line {line_no}: {why}"));
        let f: Vec<&str> = t.split_whitespace().collect();
        if f.len() != 5 {
            return Err(at("expected 5 fields `sysid compid name value type`")
                .value(format!("{} fields", f.len()))
                .allowed("tab-separated as QGroundControl writes"));
        }
        let sys = f[0].parse::<u8>().ok();
        if sys != Some(VEHICLE_SYSTEM_ID) {
            return Err(at("parameter of another vehicle")
                .field("sysid")
                .value(f[0])
                .allowed(VEHICLE_SYSTEM_ID.to_string()));
        }
        if f[1].parse::<u8>().ok() != Some(AUTOPILOT_COMPONENT_ID) {
            return Err(at("parameter of another component (not the autopilot)")
                .field("compid")
                .value(f[1])
                .allowed(AUTOPILOT_COMPONENT_ID.to_string()));
        }
        let name = f[2];
        let Some(idx) = params::index_of(name) else {
            return Err(at("unknown parameter")
                .field("name")
                .value(name)
                .allowed("a name of `cargo xtask params`"));
        };
        let d = &TABLE[idx];
        let ty = f[4].parse::<u8>().ok();
        if !(ty == Some(TYPE_REAL32) || (ty == Some(TYPE_INT32) && d.integer)) {
            return Err(at("unsupported parameter type")
                .field(format!("{name} type"))
                .value(f[4])
                .allowed(if d.integer { "9 (REAL32) or 6 (INT32)" } else { "9 (REAL32)" }));
        }
        let v = f[3].parse::<f32>().ok().filter(|v| d.check(*v).is_ok());
        let Some(v) = v else {
            return Err(at("value out of range").field(name).value(f[3]).allowed(d.range().to_string()));
        };
        if seen[idx] {
            return Err(at("parameter given twice").field(name).value(f[3]).allowed("each name once"));
        }
        seen[idx] = true;
        out.push((d.name, v));
    }
    Ok(out)
}

/// One `--param NAME=VALUE`: the parameter (by its name in `cargo xtask params`) and the value
/// as written, checked against the parameter's range (in `f32`, as the controller holds it).
/// Errors name the option, the name or value and the range.
pub fn parse_assignment(s: &str) -> Result<(&'static params::Param, f64), InputError> {
    let opt = |why: &str| InputError::option("param", why);
    let Some((name, value)) = s.split_once('=') else {
        return Err(opt("expected NAME=VALUE").value(s).allowed("e.g. --param PA_SPEED_MAX=3"));
    };
    let name = name.trim();
    let Some(idx) = params::index_of(name) else {
        return Err(opt("unknown parameter")
            .field(name)
            .allowed("a name of `cargo xtask params` / `parapet params export` (e.g. PA_SPEED_MAX)"));
    };
    let d = &TABLE[idx];
    let v = value.trim().parse::<f64>().ok().filter(|v| v.is_finite() && d.check(*v as f32).is_ok());
    let Some(v) = v else {
        let what = if d.integer { format!("{} (a whole number)", d.range()) } else { d.range().to_string() };
        return Err(opt("value out of range").field(d.name).value(value.trim()).allowed(what));
    };
    Ok((d, v))
}

/// Applies `assigned` to a run: a parameter with a scene key onto `scene` (as its `[controller]`
/// key, [`crate::world::scene::Scene::apply_param`]); the others returned, in order, for
/// `RunConfig::param_overrides`.
pub fn split_assignments(
    scene: &mut crate::world::scene::Scene,
    assigned: &[(&'static params::Param, f64)],
) -> Result<Vec<(&'static str, f32)>, CliError> {
    let mut overrides = Vec::new();
    for &(p, x) in assigned {
        if p.key.is_some() {
            scene.apply_param(p, x).map_err(|e| InputError::option("param", e).field(p.name).value(x))?;
        } else {
            overrides.push((p.name, x as f32));
        }
    }
    Ok(overrides)
}

/// The parameter assignments of a run: the `.params` file's lines (`--params FILE`) first, then
/// each `--param NAME=VALUE` in order (a later one wins).
pub fn assignments(
    file: Option<&Path>,
    given: &[String],
) -> Result<Vec<(&'static params::Param, f64)>, CliError> {
    let mut out = Vec::new();
    if let Some(f) = file {
        if !f.is_file() {
            return Err(InputError::option("params", "not a file").value(f.display()).into());
        }
        for (name, v) in entries_of_qgc(&read(f)?, &f.display().to_string())? {
            let Some(i) = params::index_of(name) else { continue };
            out.push((&TABLE[i], f64::from(v)));
        }
    }
    for s in given {
        out.push(parse_assignment(s)?);
    }
    Ok(out)
}

fn read(path: &Path) -> Result<String, CliError> {
    Ok(crate::input::read_text(path)?)
}

/// `parapet params …`; returns the text for stdout.
pub fn cmd_params(a: ParamsArgs) -> Result<String, CliError> {
    match a.command {
        ParamsCommand::Export { file, scene } => {
            let p = match &scene {
                None => ControllerParams::default(),
                Some(s) => {
                    let scene = super::load_scene(s)?;
                    let cfg =
                        crate::flight::runner::RunConfig::for_scene(&scene, vec![scene.start, scene.goal])
                            .map_err(|e| CliError::BadInput(format!("{}: {e}", scene.source)))?;
                    crate::flight::runner::controller_params(&scene, &cfg, cfg.cbf_params()?, cfg.variant)
                }
            };
            if file.is_dir() {
                return Err(InputError::option("file", "is a directory").value(file.display()).into());
            }
            if let Some(dir) = file.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)
                    .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
            }
            std::fs::write(&file, to_qgc(&p))
                .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", file.display()))?;
            Ok(format!("{} parameters -> {}\n", TABLE.len(), file.display()))
        }
        ParamsCommand::Import { file } => {
            let text = read(&file)?;
            let p = from_qgc(&text, &file.display().to_string())?;
            let d0 = ControllerParams::default();
            let mut s = format!(
                "{}: {} parameters checked; differing from the defaults:\n",
                file.display(),
                TABLE.len()
            );
            let mut n = 0;
            for d in &TABLE {
                let (v, v0) = ((d.get)(&p), (d.get)(&d0));
                if v.to_bits() != v0.to_bits() {
                    n += 1;
                    let _ = writeln!(
                        s,
                        "  {:<16} {} (default {}) {}",
                        d.name,
                        value_text(v),
                        value_text(v0),
                        d.unit
                    );
                }
            }
            if n == 0 {
                s.push_str("  (none)\n");
            }
            Ok(s)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn export_is_qgc_format_and_round_trips() {
        let mut p = ControllerParams::default();
        params::set(&mut p, "CBF_MU", 2.25).expect("in range");
        let text = to_qgc(&p);
        assert!(text.starts_with("# Onboard parameters for Vehicle 1\n"), "{text}");
        let rows: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(rows.len(), TABLE.len());
        assert!(rows.contains(&"1\t1\tCBF_MU\t2.25\t9"), "{rows:?}");
        assert!(rows.iter().all(|r| r.split('\t').count() == 5));
        assert_eq!(from_qgc(&text, "t.params").expect("own output"), p);
        // Exact for every value (shortest decimal of the f32).
        for d in &TABLE {
            let row = rows.iter().find(|r| r.split('\t').nth(2) == Some(d.name)).expect("row");
            let v: f32 = row.split('\t').nth(3).expect("value").parse().expect("float");
            assert_eq!(v.to_bits(), (d.get)(&p).to_bits(), "{}", d.name);
        }
    }

    #[test]
    fn bad_lines_are_named() {
        let ok = "1\t1\tCBF_MU\t2\t9\n";
        assert!(from_qgc(ok, "f").is_ok());
        for (text, want) in [
            ("1\t1\tCBF_MU\t2\n", "5 fields"),
            ("2\t1\tCBF_MU\t2\t9\n", "sysid"),
            ("1\t154\tCBF_MU\t2\t9\n", "compid"),
            ("1\t1\tNOPE\t2\t9\n", "unknown parameter"),
            ("1\t1\tCBF_MU\t1e9\t9\n", "CBF_MU"),
            ("1\t1\tCBF_MU\tabc\t9\n", "out of range"),
            ("1\t1\tCBF_MU\t2\t6\n", "type"),
            ("1\t1\tCBF_MU\t2\t9\n1\t1\tCBF_MU\t3\t9\n", "twice"),
        ] {
            let e = from_qgc(text, "bad.params").expect_err(text).to_string();
            assert!(e.contains("bad.params") && e.contains(want), "{text:?}: {e}");
        }
        // The line number of the bad line is given.
        let e = from_qgc(&format!("# c\n{ok}1\t1\tX\t1\t9\n"), "f").expect_err("unknown").to_string();
        assert!(e.contains("line 3"), "{e}");
    }
}
