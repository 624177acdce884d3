//! `cargo xtask params [--out FILE]`: the controller's parameter table
//! (`parapet_core::params::TABLE`) as a ground-station parameter metadata file in the
//! PX4 / QGroundControl `parameters.json` format (the MAVLink `COMP_METADATA_TYPE_PARAMETER`
//! schema): `{"version": 1, "parameters": [{"name", "type", "default", "min", "max",
//! "units", "shortDesc", "longDesc", "group", "decimalPlaces"[, "values"]}, …]}`, so a
//! ground station shows units, ranges and code names. Default output:
//! `out/params/parameters.json`. `--firmware` writes the same document without indentation to
//! [`FIRMWARE_FILE`], the copy the firmware serves by MAVLink FTP (COMPONENT_METADATA,
//! `firmware/src/link/metadata.rs`); a test fails when that committed copy is stale.
//!
//! Every value on the wire is MAV_PARAM_TYPE_REAL32, so every entry is `"Float"`;
//! named codes and flags carry `"values"` (`{"value", "description"}` per allowed code).
//! Numbers are the table's `f32` values at their shortest decimal (1.4, not
//! 1.399999976158142). Owns the JSON layout only; may import `parapet-core`.

use std::path::PathBuf;

use parapet_core::params::{Param, TABLE};
use serde_json::{json, Value};

/// The `f32` as the `f64` with its shortest decimal form.
fn num(x: f32) -> Value {
    let v: f64 = x.to_string().parse().unwrap_or(f64::from(x));
    json!(v)
}

fn entry(p: &Param) -> Value {
    let long = format!(
        "{}. Range {}{}.",
        p.description,
        p.range(),
        p.key.map(|k| format!("; scene [controller] key and parapet option `{k}`")).unwrap_or_default()
    );
    let mut e = json!({
        "name": p.name,
        "type": "Float",
        "default": num(p.default_value()),
        "min": num(p.min),
        "max": num(p.max),
        "units": p.unit,
        "shortDesc": p.description,
        "longDesc": long,
        "group": p.group,
        "decimalPlaces": p.decimals,
    });
    if let (Some(label), Value::Object(m)) = (p.label, &mut e) {
        let values: Vec<Value> = (p.min as i32..=p.max as i32)
            .filter_map(|c| label(c).map(|d| json!({"value": c, "description": d})))
            .collect();
        m.insert("values".into(), Value::Array(values));
    }
    e
}

/// The metadata document for the whole table.
pub fn metadata() -> Value {
    json!({
        "version": 1,
        "parameters": TABLE.iter().map(entry).collect::<Vec<_>>(),
    })
}

/// The firmware's copy of the metadata (served by MAVLink FTP), relative to the repository root.
pub const FIRMWARE_FILE: &str = "firmware/metadata/parameters.json";

/// The firmware's copy: the document on one line (no indentation: ~30 % less flash) + newline.
pub fn firmware_text() -> Result<String, String> {
    serde_json::to_string(&metadata()).map(|t| t + "\n").map_err(|e| format!("params: {e}"))
}

/// `cargo xtask params [--out FILE | --firmware]`.
pub fn params(args: &[String]) -> Result<(), String> {
    let (out, text) = match args {
        [] => (crate::root().join("out/params/parameters.json"), None),
        [flag, file] if flag == "--out" => (PathBuf::from(file), None),
        [flag] if flag == "--firmware" => (crate::root().join(FIRMWARE_FILE), Some(firmware_text()?)),
        _ => return Err("usage: cargo xtask params [--out FILE | --firmware]".into()),
    };
    let text = match text {
        Some(t) => t,
        None => serde_json::to_string_pretty(&metadata()).map_err(|e| format!("params: {e}"))? + "\n",
    };
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("params: cannot create {}: {e}", dir.display()))?;
    }
    std::fs::write(&out, text).map_err(|e| format!("params: cannot write {}: {e}", out.display()))?;
    eprintln!("xtask: {} parameters written to {}", TABLE.len(), out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The written file parses, and has every table entry once with min ≤ default ≤ max.
    #[test]
    fn metadata_file_parses_and_lists_every_parameter() {
        let dir = std::env::temp_dir().join(format!("parapet-xtask-params-{}", std::process::id()));
        let file = dir.join("parameters.json");
        params(&["--out".into(), file.display().to_string()]).unwrap();
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(doc["version"], 1);
        let list = doc["parameters"].as_array().unwrap();
        assert_eq!(list.len(), TABLE.len());
        for p in &TABLE {
            let e: Vec<_> = list.iter().filter(|e| e["name"] == p.name).collect();
            assert_eq!(e.len(), 1, "{} listed {} times", p.name, e.len());
            let e = e[0];
            let f = |k: &str| e[k].as_f64().unwrap_or_else(|| panic!("{}: {k} missing", p.name));
            assert!(f("min") <= f("default") && f("default") <= f("max"), "{}: {e}", p.name);
            assert_eq!(f("default") as f32, p.default_value(), "{}", p.name);
            assert_eq!(e["type"], "Float");
            assert_eq!(e["units"], p.unit);
            assert_eq!(e["group"], p.group);
            assert!(e["shortDesc"].as_str().is_some_and(|s| !s.is_empty()));
            // Named codes list their values; whole-number counts (RC channels, cells) do not.
            assert_eq!(e["values"].is_array(), p.label.is_some(), "{}", p.name);
            assert!(p.label.is_none() || p.integer, "{}: a labelled code must be integral", p.name);
        }
        // Shortest decimals, and the codes named.
        let mu = list.iter().find(|e| e["name"] == "CBF_MU").unwrap();
        assert_eq!(mu["default"].to_string(), "1.4");
        let v = list.iter().find(|e| e["name"] == "CBF_VARIANT").unwrap();
        assert_eq!(v["values"][3]["description"], "multi-relative");
        assert!(params(&["--bogus".into()]).is_err());
    }

    /// The metadata the firmware serves by MAVLink FTP is the table's: regenerate it with
    /// `cargo xtask params --firmware` when this fails (a parameter added, renamed, re-ranged).
    #[test]
    fn the_firmwares_parameter_metadata_is_not_stale() {
        let file = crate::root().join(FIRMWARE_FILE);
        let committed = std::fs::read_to_string(&file).unwrap_or_default();
        assert!(
            committed == firmware_text().unwrap(),
            "{} is stale: run `cargo xtask params --firmware`",
            file.display()
        );
    }
}
