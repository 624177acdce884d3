//! Linker set-up for the Cortex-M builds: makes the workspace-root `memory.x` visible to
//! cortex-m-rt's `link.x` and adds the linker scripts (`defmt.x` only for the real board, whose
//! build links defmt). Host builds (unit tests) get nothing.
use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let target = env::var("TARGET").unwrap_or_default();
    let root_memory_x = PathBuf::from(env::var("CARGO_MANIFEST_DIR").unwrap_or_default()).join("../memory.x");
    println!("cargo:rerun-if-changed={}", root_memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var("OUT_DIR").unwrap_or_default());
    if let Err(e) = fs::copy(&root_memory_x, out.join("memory.x")) {
        println!("cargo:warning=cannot copy {}: {e}", root_memory_x.display());
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if env::var_os("CARGO_FEATURE_BOARD_F405").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
