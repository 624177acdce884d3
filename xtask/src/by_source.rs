//! `cargo xtask size [ELF] --by-source`: the firmware's code bytes attributed to source
//! areas (issue 22's flash budget work).
//!
//! Owns the attribution only; imports nothing of the workspace. With fat LTO most code is
//! inlined into a few task `poll` functions, so symbol sizes (`llvm-nm --size-sort`) say little;
//! the DWARF line table does: every instruction is charged to the file of its innermost
//! (inlined) line entry, read from `llvm-objdump -d -l --no-show-raw-insn` (the system's
//! `llvm-objdump`, or the one of rustup's `llvm-tools`; a missing tool is an error naming it).
//! Areas: `core/<module>`, `firmware/<module>`, `dep:<crate>` for crates.io sources, `rust lib`
//! for the standard library's inlined generics (`Option`/`Result` combinators, `ptr`/`mem`
//! moves, integer ops), `other` for instructions without line information. An instruction's
//! size is the distance to the next one (literal pools and padding included, at most 64 B).
//! `.rodata` (tables, strings) is not code and is not attributed here.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

/// Code bytes per source area, largest first, from `llvm-objdump -d -l` output.
pub fn attribute(objdump: &str) -> Vec<(String, u64)> {
    let mut rows: Vec<(u64, String)> = Vec::new();
    let mut area = String::from("other");
    for line in objdump.lines() {
        if let Some(loc) = line.strip_prefix("; ") {
            // "; /path/to/file.rs:123" (a line-table entry of the instructions that follow).
            if let Some((file, _line)) = loc.trim().rsplit_once(':') {
                area = area_of(file);
            }
            continue;
        }
        if let Some(addr) = insn_address(line) {
            rows.push((addr, area.clone()));
        }
    }
    rows.sort_by_key(|r| r.0);
    let mut by: HashMap<String, u64> = HashMap::new();
    for w in rows.windows(2) {
        let size = w[1].0 - w[0].0;
        *by.entry(w[0].1.clone()).or_default() += if size > 64 { 4 } else { size };
    }
    let mut out: Vec<(String, u64)> = by.into_iter().collect();
    out.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    out
}

/// The address of an instruction line ("  8000520:  push {r4, lr}"), `None` for other lines.
fn insn_address(line: &str) -> Option<u64> {
    let t = line.trim_start();
    if t.len() == line.len() {
        return None; // labels ("08000520 <name>:") start in column 0
    }
    let (hex, rest) = t.split_once(':')?;
    if rest.is_empty() || !rest.starts_with(|c: char| c.is_whitespace()) {
        return None;
    }
    u64::from_str_radix(hex, 16).ok()
}

/// The area of a source file path.
fn area_of(file: &str) -> String {
    let f = file.replace('\\', "/");
    if let Some(i) = f.find("/core/src/") {
        if !f[..i].contains("/library") && !f.contains("/rustc/") {
            return format!("core/{}", module(&f[i + "/core/src/".len()..]));
        }
    }
    if let Some(i) = f.find("/firmware/src/") {
        return format!("firmware/{}", module(&f[i + "/firmware/src/".len()..]));
    }
    if f.contains("compiler-builtins") {
        return "dep:compiler_builtins".into(); // memcpy/memmove, soft f64, 64-bit division
    }
    if f.contains("/rustc/") || f.contains("/library/core/") || f.contains("/library/alloc/") {
        return "rust lib".into();
    }
    if f.ends_with("/out/parapet.rs") {
        return "firmware/generated dialect".into();
    }
    // crates.io sources: ".../registry/src/<index>/<crate>-<version>/..." or "/cargo/<crate>-<version>/..."
    for seg in f.split('/') {
        if let Some((name, ver)) = seg.rsplit_once('-') {
            if ver.starts_with(|c: char| c.is_ascii_digit()) && ver.contains('.') && !name.is_empty() {
                // "index.crates.io-1949cf8c6b5b557f" has no dot in its tail: not a crate.
                return format!("dep:{name}");
            }
        }
    }
    "other".into()
}

/// First path component ("outer/mod.rs" → "outer", "fmath.rs" → "fmath.rs").
fn module(rel: &str) -> &str {
    rel.split('/').next().unwrap_or(rel)
}

/// Run `llvm-objdump` on `elf` and print the `top` largest areas.
pub fn print(elf: &Path, top: usize) -> Result<(), String> {
    let tool = objdump_tool();
    let out =
        Command::new(&tool).args(["-d", "-l", "--no-show-raw-insn"]).arg(elf).output().map_err(|e| {
            format!("{tool}: {e} (install LLVM's llvm-objdump or `rustup component add llvm-tools`)")
        })?;
    if !out.status.success() {
        return Err(format!("{tool} {}: {}", elf.display(), String::from_utf8_lossy(&out.stderr)));
    }
    let areas = attribute(&String::from_utf8_lossy(&out.stdout));
    let total: u64 = areas.iter().map(|a| a.1).sum();
    println!("code bytes by source area ({tool} -d -l; innermost inlined line), total {total} B:");
    for (area, bytes) in areas.iter().take(top) {
        println!("{bytes:>8} B {:>5.1} %  {area}", 100.0 * *bytes as f64 / total.max(1) as f64);
    }
    Ok(())
}

/// rustup's `llvm-objdump` (component `llvm-tools`) when installed, else the one on `PATH`.
fn objdump_tool() -> String {
    let sysroot = Command::new("rustc").args(["--print", "sysroot"]).output().ok();
    if let Some(s) = sysroot.filter(|o| o.status.success()) {
        let root = String::from_utf8_lossy(&s.stdout).trim().to_string();
        if let Ok(dirs) = std::fs::read_dir(Path::new(&root).join("lib/rustlib")) {
            for d in dirs.flatten() {
                let p = d.path().join("bin/llvm-objdump");
                if p.is_file() {
                    return p.display().to_string();
                }
            }
        }
    }
    "llvm-objdump".into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn areas_of_paths() {
        assert_eq!(area_of("/work/main/core/src/outer/mod.rs"), "core/outer");
        assert_eq!(area_of("/work/main/core/src/fmath.rs"), "core/fmath.rs");
        assert_eq!(area_of("/work/main/firmware/src/link/router.rs"), "firmware/link");
        assert_eq!(area_of("/rustc/59807616e/library/core/src/option.rs"), "rust lib");
        assert_eq!(
            area_of(
                "/root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/heapless-0.9.3/src/vec/mod.rs"
            ),
            "dep:heapless"
        );
        assert_eq!(area_of("/cargo/embassy-stm32-0.6.0/src/spi/mod.rs"), "dep:embassy-stm32");
        assert_eq!(
            area_of("/x/target/thumbv7em-none-eabihf/firmware/build/p-1/out/parapet.rs"),
            "firmware/generated dialect"
        );
    }

    #[test]
    fn bytes_go_to_the_innermost_line_entry() {
        let dump = "\
08000100 <f>:
; /work/main/core/src/outer/mod.rs:10
 8000100:      \tpush\t{r4, lr}
 8000102:      \tmovs\tr0, #0
; /rustc/abc/library/core/src/option.rs:5
 8000104:      \tbl\t0x8000200 <g>
; /work/main/firmware/src/main.rs:3
 8000108:      \tpop\t{r4, pc}
 800010a:      \tnop
";
        let a = attribute(dump);
        let get = |k: &str| a.iter().find(|x| x.0 == k).map(|x| x.1);
        assert_eq!(get("core/outer"), Some(4));
        assert_eq!(get("rust lib"), Some(4));
        assert_eq!(get("firmware/main.rs"), Some(2)); // the last instruction has no successor
    }
}
