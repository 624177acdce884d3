//! No import cycles in any crate (`parapet_tests::layering`: the `use` edges between the
//! children of every folder form a DAG), plus core's cascade-folder rules
//! (`docs/cascade.md` § Module rules): the inner loop never reaches the outer loop, the
//! safety filter or the supervisor; the outer loop never reaches the inner loop; nothing
//! but `lib.rs` imports the facade (`controller.rs`). Source files stay under 800 non-test lines.

use parapet_tests::layering::{cycles, find_cycle, paths_in, resolve, sibling_edges, Crate, ModPath, Use};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn src(krate: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(krate).join("src")
}

/// core's root-level re-exports (`core/src/lib.rs`): `crate::cbf` is `safety/cbf.rs`.
const CORE_ALIASES: &[(&str, &str)] = &[
    ("attitude", "inner::attitude"),
    ("estimator", "inner::estimator"),
    ("mixer", "inner::mixer"),
    ("thrust", "outer::thrust"),
    ("tracking", "outer::tracking"),
    ("waypoint", "outer::waypoint"),
    ("cbf", "safety::cbf"),
    ("obstacle", "safety::obstacle"),
    ("qp3", "safety::qp3"),
    ("braking", "safety::braking"),
    ("obstacle_set", "safety::obstacle_set"),
    ("plant_aware", "safety::plant_aware"),
    ("failsafe", "supervisor::failsafe"),
];

/// What each core folder may import besides itself (root-level children of `core/src`).
const CORE_RULES: &[(&str, &[&str])] = &[
    ("inner", &["airframe", "frame", "fmath", "msg"]),
    // Issue 21: the piloted and offboard references read the pilot input and the battery.
    (
        "outer",
        &[
            "airframe",
            "frame",
            "fmath",
            "msg",
            "safety",
            "supervisor",
            "obstacle_set",
            "robust",
            "rc",
            "battery",
            "param_decl",
        ],
    ),
    // Issue 21/22: the mode machine reads the pilot input and the battery level.
    ("supervisor", &["airframe", "frame", "fmath", "msg", "rc", "battery", "param_decl"]),
    ("safety", &["airframe", "frame", "fmath", "param_decl"]),
    // Issue 19: the obstacle memory turns range scans into points for the filter's set.
    ("perception", &["frame", "fmath", "safety", "param_decl"]),
    // Issue 21: pilot input (decoders, channel map) and issue 22: the battery message.
    ("rc", &["fmath", "param_decl"]),
    ("battery", &["fmath", "param_decl"]),
    // Issue 22: the motor-test state machine stands alone; calibration maths on the frame helpers.
    ("motor_test", &[]),
    ("calibration", &["frame", "fmath", "msg", "param_decl"]),
    ("msg", &[]),
    // Issue 37: how a parameter is declared beside its struct; every stage imports it, so it
    // imports nothing (`params` gathers the declarations into the table, never the reverse).
    ("param_decl", &[]),
    // Issue 37: the wire contract names the filter's regions and the mode types (`wire::modes`,
    // PX4's nav_state); `config` and `schedule` read its rates, never the other way round.
    ("wire", &["safety", "fmath", "outer", "supervisor"]),
];

fn scan(krate: &str, aliases: &[(&str, &str)]) -> Crate {
    let dir = src(krate);
    Crate::scan(&dir, aliases).unwrap_or_else(|e| panic!("reading {}: {e}", dir.display()))
}

fn root_edges(c: &Crate) -> BTreeMap<String, BTreeMap<String, String>> {
    c.edges().remove(&ModPath::new()).unwrap_or_default()
}

fn assert_no_cycle(krate: &str, aliases: &[(&str, &str)]) -> Crate {
    let c = scan(krate, aliases);
    if std::env::var_os("LAYERING_DUMP").is_some() {
        for (parent, g) in c.edges() {
            for (a, t) in g {
                for (b, at) in t {
                    eprintln!("{krate} {}: {a} -> {b} ({at})", parent.join("::"));
                }
            }
        }
    }
    let found = c.cycles();
    assert!(found.is_empty(), "import cycles in {krate}/src:\n{}", found.join("\n"));
    c
}

#[test]
fn core_has_no_import_cycle_and_keeps_its_folder_rules() {
    let c = assert_no_cycle("core", CORE_ALIASES);
    let root = root_edges(&c);
    let mut violations = Vec::new();
    for (unit, targets) in &root {
        for (to, at) in targets {
            if to == "controller" {
                violations.push(format!("{unit} imports the facade crate::controller ({at})"));
            }
            if let Some((_, ok)) = CORE_RULES.iter().find(|(u, _)| u == unit) {
                if !ok.contains(&to.as_str()) {
                    violations.push(format!("{unit} imports {to} ({at})"));
                }
            }
        }
    }
    assert!(violations.is_empty(), "core folder rules broken:\n{}", violations.join("\n"));
    // The folders must have been seen, or the rules check nothing.
    for u in ["inner", "outer", "safety", "supervisor", "controller"] {
        assert!(root.contains_key(u), "no imports found for core's {u}: {root:?}");
    }
    assert!(root["outer"].contains_key("safety"), "the alias-free path outer → safety is missing");
    assert!(root["controller"].contains_key("inner"), "controller → inner is missing");
}

#[test]
fn firmware_has_no_import_cycle() {
    let c = assert_no_cycle("firmware", &[]);
    let root = root_edges(&c);
    for (a, b) in [("pil", "app"), ("link", "app")] {
        assert!(root.get(a).is_some_and(|t| t.contains_key(b)), "missing firmware edge {a} → {b}: {root:?}");
    }
}

#[test]
fn host_sim_has_no_import_cycle() {
    let c = assert_no_cycle("host-sim", &[]);
    assert!(c.modules.contains(&vec!["world".to_string(), "scene".to_string()]));
    // The parser sees the edges it must see (a broken parser would pass the cycle check).
    let root = root_edges(&c);
    for (a, b) in [("flight", "world"), ("fc", "flight"), ("cli", "plan"), ("world", "sim")] {
        assert!(root.get(a).is_some_and(|t| t.contains_key(b)), "missing edge {a} → {b}");
    }
    let n: usize = root.values().map(BTreeMap::len).sum();
    assert!(n >= 20, "only {n} edges between top-level modules");
}

#[test]
fn xtask_has_no_import_cycle() {
    assert_no_cycle("xtask", &[]);
}

fn planted(code: &[(&str, &str)], aliases: &[(&str, &str)]) -> Vec<Use> {
    let mods: BTreeSet<ModPath> =
        [vec![], vec!["a".into()], vec!["b".into()], vec!["b".into(), "y".into()], vec!["c".into()]]
            .into_iter()
            .collect();
    let mut uses = Vec::new();
    for (from, text) in code {
        let from = vec![from.to_string()];
        for (_, raw) in paths_in(text) {
            let to = resolve(&from, &raw, &mods, aliases).expect("resolvable");
            uses.push(Use { from: from.clone(), to, at: String::new() });
        }
    }
    uses
}

/// The check can fail: a planted two-module cycle (group import one way, `super::` the other).
#[test]
fn finds_a_planted_cycle() {
    let uses = planted(&[("a", "use crate::b::{X, y::Z};"), ("b", "fn f() { super::a::g() }")], &[]);
    let edges = sibling_edges(&uses);
    assert_eq!(find_cycle(&edges[&ModPath::new()]), Some(vec!["a".into(), "b".into(), "a".into()]));
    assert_eq!(cycles(&edges).len(), 1);
}

/// Multi-line nested groups and root re-exports are edges too (rustfmt writes long `use`
/// lists over several lines; core re-exports `safety::cbf` as `crate::cbf`).
#[test]
fn finds_a_cycle_through_a_multiline_group_and_an_alias() {
    let uses = planted(
        &[
            ("a", "use crate::{\n    c::Q,\n    b::{\n        y::Z,\n    },\n};"),
            ("b", "let v = crate::yy::W;"),
        ],
        &[("yy", "a")],
    );
    let edges = sibling_edges(&uses);
    let root = &edges[&ModPath::new()];
    assert!(root["a"].contains_key("c") && root["a"].contains_key("b"), "{root:?}");
    assert!(find_cycle(root).is_some(), "{root:?}");
    // Without the back edge there is none.
    let uses = planted(&[("a", "use crate::{c::Q, b::y::Z};")], &[]);
    assert!(cycles(&sibling_edges(&uses)).is_empty());
}

/// Files are split by concern before they grow past [`MAX_NON_TEST_LINES`] (issue 37): the lines
/// of every `src/` file of the crates up to its first `#[cfg(test)]` (test code is not counted).
const MAX_NON_TEST_LINES: usize = 800;

#[test]
fn source_files_stay_under_the_non_test_line_limit() {
    let mut long = Vec::new();
    let mut seen = 0;
    for krate in ["core", "firmware", "host-sim", "xtask", "tests"] {
        let mut dirs = vec![src(krate)];
        while let Some(dir) = dirs.pop() {
            for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
                let path = entry.expect("directory entry").path();
                if path.is_dir() {
                    dirs.push(path);
                } else if path.extension().is_some_and(|e| e == "rs") {
                    let text = std::fs::read_to_string(&path).expect("source file");
                    let n = text.lines().take_while(|l| !l.starts_with("#[cfg(test)]")).count();
                    seen += 1;
                    if n > MAX_NON_TEST_LINES {
                        long.push(format!("{} ({n} lines)", path.display()));
                    }
                }
            }
        }
    }
    assert!(seen > 100, "only {seen} source files found");
    assert!(
        long.is_empty(),
        "over {MAX_NON_TEST_LINES} non-test lines, split by concern:\n{}",
        long.join("\n")
    );
}
