//! No import cycles inside `host-sim/src`: for every folder, the `use` edges
//! between its direct children (files and sub-folders) form a DAG.
//!
//! Edges come from the `crate::…` and `super::…` paths in the non-test code of
//! every file (comments dropped; a file's code after its first `#[cfg(test)]`
//! is test code and may import upwards, like the integration tests). A path
//! `crate::a::b::Item` written in `src/c/d.rs` is an edge `c → a` between the
//! children of the crate root; one written in `src/a/x.rs` to `crate::a::y::Item`
//! is an edge `x → y` inside `a`. A module using its own ancestors' or
//! descendants' items is not a sibling edge.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path below the crate root, e.g. `["world", "scene"]`.
type ModPath = Vec<String>;

/// One import: source module, target path (as written, resolved to absolute
/// segments), file and line.
struct Use {
    from: ModPath,
    to: Vec<String>,
    at: String,
}

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rs_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rs_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// Module path of a source file (`lib.rs` and `main.rs` are the root, `x/mod.rs` is `x`).
fn module_of(file: &Path) -> ModPath {
    let rel = file.strip_prefix(src_dir()).unwrap();
    let mut segs: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
    let last = segs.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        segs.push(stem.to_string());
    }
    segs
}

/// The module tree: every module path that exists as a file or folder.
fn modules(files: &[PathBuf]) -> BTreeSet<ModPath> {
    let mut set = BTreeSet::new();
    for f in files {
        let m = module_of(f);
        for k in 0..=m.len() {
            set.insert(m[..k].to_vec());
        }
    }
    set
}

/// Non-test code of a file with comments removed, as (line number, text).
fn code_lines(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let code = match line.find("//") {
            Some(k) => &line[..k],
            None => line,
        };
        out.push((i + 1, code.to_string()));
    }
    out
}

/// Every `crate::…` / `super::…` path in `code`, with `{a, b::c}` groups expanded
/// one level (enough for this crate's `use` lines), as raw segment lists.
fn paths_in(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for root in ["crate::", "super::"] {
        let mut rest = code;
        while let Some(k) = rest.find(root) {
            let before = rest[..k].chars().last();
            let tail = &rest[k..];
            rest = &rest[k + root.len()..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let mut segs: Vec<String> = vec![root.trim_end_matches(':').to_string()];
            let mut t = &tail[root.len()..];
            loop {
                while t.starts_with("super::") {
                    segs.push("super".into());
                    t = &t["super::".len()..];
                }
                if let Some(group) = t.strip_prefix('{') {
                    let end = group.find('}').unwrap_or(group.len());
                    for item in group[..end].split(',') {
                        let item: Vec<String> = item
                            .trim()
                            .split("::")
                            .map(|s| s.trim().to_string())
                            .take_while(|s| {
                                !s.is_empty() && s.chars().all(|c| c.is_alphanumeric() || c == '_')
                            })
                            .collect();
                        if !item.is_empty() {
                            out.push(segs.iter().cloned().chain(item).collect());
                        }
                    }
                    break;
                }
                let n = t.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(t.len());
                if n == 0 {
                    out.push(segs.clone());
                    break;
                }
                segs.push(t[..n].to_string());
                t = &t[n..];
                match t.strip_prefix("::") {
                    Some(r) => t = r,
                    None => {
                        out.push(segs.clone());
                        break;
                    }
                }
            }
        }
    }
    out
}

/// Resolve a raw path written in module `from` to the deepest existing module.
fn resolve(from: &ModPath, raw: &[String], mods: &BTreeSet<ModPath>) -> Option<ModPath> {
    let mut base: ModPath = Vec::new();
    let mut rest = raw;
    if raw.first().map(String::as_str) == Some("crate") {
        rest = &raw[1..];
    } else {
        base = from.clone();
        while rest.first().map(String::as_str) == Some("super") {
            base.pop()?;
            rest = &rest[1..];
        }
    }
    for s in rest {
        let mut next = base.clone();
        next.push(s.clone());
        if !mods.contains(&next) {
            break;
        }
        base = next;
    }
    Some(base)
}

fn uses() -> (Vec<Use>, BTreeSet<ModPath>) {
    let mut files = Vec::new();
    rs_files(&src_dir(), &mut files);
    let mods = modules(&files);
    let mut out = Vec::new();
    for f in &files {
        if f.file_name().is_some_and(|n| n == "main.rs") {
            continue; // the binary uses the library as an external crate
        }
        let from = module_of(f);
        let text = std::fs::read_to_string(f).unwrap();
        for (line, code) in code_lines(&text) {
            for raw in paths_in(&code) {
                if let Some(to) = resolve(&from, &raw, &mods) {
                    let at = format!("{}:{line}", f.strip_prefix(src_dir()).unwrap().display());
                    out.push(Use { from: from.clone(), to, at });
                }
            }
        }
    }
    (out, mods)
}

/// Sibling edges per parent folder: parent → (child → (child → example location)).
type Edges = BTreeMap<ModPath, BTreeMap<String, BTreeMap<String, String>>>;

fn sibling_edges(uses: &[Use]) -> Edges {
    let mut edges = Edges::new();
    for u in uses {
        let k = u.from.iter().zip(&u.to).take_while(|(a, b)| a == b).count();
        if k == u.from.len() || k == u.to.len() {
            continue; // own descendant or ancestor
        }
        edges
            .entry(u.from[..k].to_vec())
            .or_default()
            .entry(u.from[k].clone())
            .or_default()
            .entry(u.to[k].clone())
            .or_insert_with(|| u.at.clone());
    }
    edges
}

/// A cycle in one folder's graph, as the list of children and the example use of each edge.
fn find_cycle(g: &BTreeMap<String, BTreeMap<String, String>>) -> Option<Vec<String>> {
    fn dfs(
        n: &str,
        g: &BTreeMap<String, BTreeMap<String, String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(n.to_string(), 1);
        stack.push(n.to_string());
        for (m, at) in g.get(n).into_iter().flatten() {
            match state.get(m.as_str()).copied().unwrap_or(0) {
                1 => {
                    let i = stack.iter().position(|s| s == m).unwrap();
                    let mut c: Vec<String> = stack[i..].to_vec();
                    c.push(format!("{m} (last edge at {at})"));
                    return Some(c);
                }
                0 => {
                    if let Some(c) = dfs(m, g, state, stack) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for n in g.keys() {
        if state.get(n.as_str()).copied().unwrap_or(0) == 0 {
            if let Some(c) = dfs(n, g, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn no_import_cycle_between_sibling_modules() {
    let (uses, _) = uses();
    let edges = sibling_edges(&uses);
    let mut cycles = Vec::new();
    for (parent, g) in &edges {
        if let Some(c) = find_cycle(g) {
            let name = if parent.is_empty() { "crate".to_string() } else { parent.join("::") };
            let detail: Vec<String> = c
                .windows(2)
                .map(|w| {
                    let to = w[1].split(' ').next().unwrap();
                    format!("{} → {to} ({})", w[0], g[&w[0]][to])
                })
                .collect();
            cycles.push(format!("in {name}: {}", detail.join(", ")));
        }
    }
    if std::env::var_os("LAYERING_DUMP").is_some() {
        for (parent, g) in &edges {
            for (a, t) in g {
                for (b, at) in t {
                    eprintln!("{}: {a} -> {b} ({at})", parent.join("::"));
                }
            }
        }
    }
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}

/// The parser sees the edges it must see (a broken parser would pass the test above).
#[test]
fn parser_finds_known_edges() {
    let (uses, mods) = uses();
    assert!(mods.contains(&vec!["world".to_string(), "scene".to_string()]));
    let edges = sibling_edges(&uses);
    let root = &edges[&Vec::<String>::new()];
    for (a, b) in [("flight", "world"), ("fc", "flight"), ("cli", "plan"), ("world", "sim")] {
        assert!(root.get(a).is_some_and(|t| t.contains_key(b)), "missing edge {a} → {b}");
    }
    let n: usize = root.values().map(BTreeMap::len).sum();
    assert!(n >= 20, "only {n} edges between top-level modules");
}

#[test]
fn finds_a_planted_cycle() {
    let mods: BTreeSet<ModPath> =
        [vec![], vec!["a".into()], vec!["b".into()]].into_iter().collect::<BTreeSet<ModPath>>();
    let mut uses = Vec::new();
    for (from, code) in [("a", "use crate::b::{X, y::Z};"), ("b", "fn f() { super::a::g() }")] {
        let from = vec![from.to_string()];
        for raw in paths_in(code) {
            let to = resolve(&from, &raw, &mods).unwrap();
            uses.push(Use { from: from.clone(), to, at: String::new() });
        }
    }
    let edges = sibling_edges(&uses);
    assert!(find_cycle(&edges[&Vec::<String>::new()]).is_some());
}
