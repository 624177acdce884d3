//! The import rules of the cascade folders (`docs/cascade.md` § Module rules), checked over
//! the `crate::…` paths in the source (comments left out): the inner loop never reaches the
//! outer loop, the safety filter or the supervisor; the outer loop never reaches the inner
//! loop; nothing but the facade imports the facade; no two folders import each other.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::Path;

/// The folder (or root file) a `crate::<name>` path lands in; the folder modules are also
/// re-exported at the root (`crate::cbf` is `safety/cbf.rs`).
fn unit_of(name: &str) -> &str {
    match name {
        "attitude" | "estimator" | "mixer" | "inner" => "inner",
        "thrust" | "tracking" | "waypoint" | "guidance" | "inputs" | "outer" => "outer",
        "cbf" | "obstacle" | "qp3" | "safety" => "safety",
        "failsafe" | "supervisor" => "supervisor",
        other => other,
    }
}

/// What each unit may import besides itself.
fn allowed(unit: &str) -> Option<&'static [&'static str]> {
    let list: &'static [&'static str] = match unit {
        "inner" => &["airframe", "frame", "fmath", "Vec3", "msg"],
        "outer" => &["airframe", "frame", "fmath", "Vec3", "msg", "safety", "supervisor"],
        "supervisor" => &["airframe", "frame", "fmath", "Vec3", "msg"],
        "safety" => &["airframe", "frame", "fmath", "Vec3"],
        "msg" => &["Vec3"],
        _ => return None,
    };
    Some(list)
}

/// `crate::<name>` paths used in `src` outside comments.
fn crate_paths(src: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for line in src.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            let tail = &rest[i + "crate::".len()..];
            let name: String = tail.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            if !name.is_empty() {
                out.insert(name);
            }
            rest = tail;
        }
    }
    out
}

fn files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn cascade_folders_import_only_what_their_module_docs_allow_and_form_no_cycle() {
    // The path scanner itself: code paths count, comments do not.
    let seen = crate_paths("use crate::outer::OuterLoop; let x = crate::cbf::INPUT_LIMIT; // crate::inner");
    assert_eq!(seen.into_iter().collect::<Vec<_>>(), ["cbf", "outer"]);
    assert_eq!(allowed("inner").map(|a| a.contains(&unit_of("cbf"))), Some(false));
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut violations = Vec::new();
    for f in &all {
        let rel = f.strip_prefix(&src).unwrap();
        let first = rel.components().next().unwrap().as_os_str().to_string_lossy().into_owned();
        let unit = unit_of(first.trim_end_matches(".rs")).to_string();
        let text = fs::read_to_string(f).unwrap();
        for name in crate_paths(&text) {
            let to = unit_of(&name).to_string();
            if to == unit {
                continue;
            }
            if to == "controller" && unit != "lib" {
                violations.push(format!("{} imports the facade (crate::controller)", rel.display()));
            }
            if let Some(ok) = allowed(&unit) {
                if !ok.contains(&to.as_str()) {
                    violations.push(format!("{} ({unit}) imports crate::{name} ({to})", rel.display()));
                }
            }
            edges.entry(unit.clone()).or_default().insert(to);
        }
    }
    assert!(violations.is_empty(), "{violations:#?}");
    // The folders must have been seen, or the test checks nothing.
    for u in ["inner", "outer", "safety", "supervisor", "msg", "controller"] {
        assert!(edges.contains_key(u), "no imports found for {u}: {edges:?}");
    }
    // No cycle between units (lib.rs declares everything and is left out).
    let units: Vec<&String> = edges.keys().filter(|u| u.as_str() != "lib").collect();
    for a in &units {
        // Depth-first search from a: reaching a again is a cycle.
        let mut stack: Vec<&str> = edges[*a].iter().map(String::as_str).collect();
        let mut seen = BTreeSet::new();
        while let Some(u) = stack.pop() {
            assert!(u != a.as_str(), "import cycle through {a}: {edges:#?}");
            if u != "lib" && seen.insert(u) {
                if let Some(next) = edges.get(u) {
                    stack.extend(next.iter().map(String::as_str));
                }
            }
        }
    }
}
