//! The one import-cycle checker of the workspace (std only), run on every crate's `src/`
//! by `tests/tests/layering.rs`: for every folder, the `use` edges between its direct
//! children (files and sub-folders) must form a DAG.
//!
//! Edges come from the `crate::…` and `super::…` paths in the non-test code of every file
//! (comments dropped; a file's code after its first `#[cfg(test)]` is test code and may
//! import upwards, like the integration tests). A path `crate::a::b::Item` written in
//! `src/c/d.rs` is an edge `c → a` between the children of the crate root; one written in
//! `src/a/x.rs` to `crate::a::y::Item` is an edge `x → y` inside `a`. A module using its
//! own ancestors' or descendants' items is not a sibling edge. `use` groups
//! (`crate::a::{b, c::{D, E}}`, also over several lines) are expanded.
//!
//! A crate with a `lib.rs` is the library: its `main.rs` and `bin/` use it as an external
//! crate and are left out. Root-level re-exports (`pub use safety::cbf;` in core) are given
//! as aliases so that `crate::cbf::X` is the edge to `safety`.
//!
//! Imports: std only (the checker reads source text; it does not link the crates).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path below the crate root, e.g. `["world", "scene"]`.
pub type ModPath = Vec<String>;

/// One import: source module, target module (deepest existing module of the path),
/// and where it was written (`file:line`).
#[derive(Clone, Debug)]
pub struct Use {
    pub from: ModPath,
    pub to: ModPath,
    pub at: String,
}

/// One folder's graph: child → (child it imports → example location).
pub type Graph = BTreeMap<String, BTreeMap<String, String>>;

/// Sibling edges per parent folder.
pub type Edges = BTreeMap<ModPath, Graph>;

/// The scanned source tree of one crate.
pub struct Crate {
    pub src: PathBuf,
    pub modules: BTreeSet<ModPath>,
    pub uses: Vec<Use>,
}

fn rs_files(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    let mut entries = Vec::new();
    for e in std::fs::read_dir(dir)? {
        entries.push(e?.path());
    }
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rs_files(&p, out)?;
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
    Ok(())
}

/// Module path of a file relative to `src` (`lib.rs` / `main.rs` are the root, `x/mod.rs` is `x`).
pub fn module_of(rel: &Path) -> ModPath {
    let mut segs: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
    let last = segs.pop().unwrap_or_default();
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        segs.push(stem.to_string());
    }
    segs
}

/// Non-test code of a file with `//` comments blanked out (line structure kept).
pub fn code_of(text: &str) -> String {
    let mut out = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        out.push_str(line.find("//").map_or(line, |k| &line[..k]));
        out.push('\n');
    }
    out
}

fn ident_len(t: &str) -> usize {
    t.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(t.len())
}

/// Expand the path tail `t` (after `prefix`), pushing every full path; `t` may hold a
/// `{…}` group with nested groups.
fn expand(prefix: &[String], t: &str, out: &mut Vec<Vec<String>>) {
    let mut segs = prefix.to_vec();
    let mut t = t.trim_start();
    loop {
        if let Some(group) = t.strip_prefix('{') {
            // Split at the top-level commas up to the matching brace.
            let (mut depth, mut start) = (0usize, 0usize);
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => {
                        expand(&segs, &group[start..i], out);
                        return;
                    }
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        expand(&segs, &group[start..i], out);
                        start = i + 1;
                    }
                    _ => {}
                }
            }
            expand(&segs, &group[start..], out);
            return;
        }
        let n = ident_len(t);
        if n == 0 {
            if !segs.is_empty() {
                out.push(segs);
            }
            return;
        }
        segs.push(t[..n].to_string());
        t = t[n..].trim_start();
        match t.strip_prefix("::") {
            Some(r) => t = r.trim_start(),
            None => {
                out.push(segs);
                return;
            }
        }
    }
}

/// Every `crate::…` / `super::…` path in `code` with its byte offset, groups expanded,
/// as raw segment lists starting with `crate` or `super`.
pub fn paths_in(code: &str) -> Vec<(usize, Vec<String>)> {
    let mut out = Vec::new();
    for root in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(k) = code[from..].find(root).map(|k| k + from) {
            from = k + root.len();
            let before = code[..k].chars().last();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue; // `self::super::`, `a::super::` or part of a longer name
            }
            let mut found = Vec::new();
            expand(&[], &code[k..], &mut found);
            out.extend(found.into_iter().filter(|p| !p.is_empty()).map(|p| (k, p)));
        }
    }
    out
}

/// Resolve a raw path written in module `from` to the deepest existing module;
/// `aliases` maps a root-level re-exported name to its module.
pub fn resolve(
    from: &ModPath,
    raw: &[String],
    mods: &BTreeSet<ModPath>,
    aliases: &[(&str, &str)],
) -> Option<ModPath> {
    let mut base: ModPath = Vec::new();
    let mut rest = raw;
    if raw.first().map(String::as_str) == Some("crate") {
        rest = &raw[1..];
        if let Some(first) = rest.first() {
            if let Some((_, target)) = aliases.iter().find(|(a, _)| a == first) {
                base = target.split("::").map(str::to_string).collect();
                rest = &rest[1..];
            }
        }
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

impl Crate {
    /// Read every `.rs` file under `src` (a crate's `src` directory).
    pub fn scan(src: &Path, aliases: &[(&str, &str)]) -> std::io::Result<Crate> {
        let mut files = Vec::new();
        rs_files(src, &mut files)?;
        let rel = |f: &Path| f.strip_prefix(src).map(Path::to_path_buf).unwrap_or_default();
        let is_lib = src.join("lib.rs").exists();
        files.retain(|f| {
            let r = rel(f);
            !(is_lib && (r == Path::new("main.rs") || r.starts_with("bin")))
        });
        let mut modules = BTreeSet::new();
        for f in &files {
            let m = module_of(&rel(f));
            for k in 0..=m.len() {
                modules.insert(m[..k].to_vec());
            }
        }
        let mut uses = Vec::new();
        for f in &files {
            let r = rel(f);
            let from = module_of(&r);
            let code = code_of(&std::fs::read_to_string(f)?);
            for (offset, raw) in paths_in(&code) {
                if let Some(to) = resolve(&from, &raw, &modules, aliases) {
                    let line = code[..offset].matches('\n').count() + 1;
                    uses.push(Use { from: from.clone(), to, at: format!("{}:{line}", r.display()) });
                }
            }
        }
        Ok(Crate { src: src.to_path_buf(), modules, uses })
    }

    /// The sibling edges of this crate.
    pub fn edges(&self) -> Edges {
        sibling_edges(&self.uses)
    }

    /// Every folder with an import cycle, described with the location of each edge.
    pub fn cycles(&self) -> Vec<String> {
        cycles(&self.edges())
    }
}

/// Sibling edges per parent folder of `uses`.
pub fn sibling_edges(uses: &[Use]) -> Edges {
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

/// A cycle in one folder's graph, as the list of children `a, b, …, a`.
pub fn find_cycle(g: &Graph) -> Option<Vec<String>> {
    fn dfs(
        n: &str,
        g: &Graph,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(n.to_string(), 1);
        stack.push(n.to_string());
        for m in g.get(n).into_iter().flat_map(BTreeMap::keys) {
            match state.get(m.as_str()).copied().unwrap_or(0) {
                1 => {
                    let i = stack.iter().position(|s| s == m).unwrap_or(0);
                    let mut c: Vec<String> = stack[i..].to_vec();
                    c.push(m.clone());
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

/// One line per folder with a cycle: `in app: a → b (a.rs:3), b → a (b.rs:7)`.
pub fn cycles(edges: &Edges) -> Vec<String> {
    let mut out = Vec::new();
    for (parent, g) in edges {
        if let Some(c) = find_cycle(g) {
            let name = if parent.is_empty() { "crate".to_string() } else { parent.join("::") };
            let detail: Vec<String> =
                c.windows(2).map(|w| format!("{} → {} ({})", w[0], w[1], g[&w[0]][&w[1]])).collect();
            out.push(format!("in {name}: {}", detail.join(", ")));
        }
    }
    out
}
