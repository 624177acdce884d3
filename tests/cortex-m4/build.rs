//! Linker set-up: the workspace-root `memory.x` (STM32F405) and cortex-m-rt's `link.x`.
use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let dir = PathBuf::from(env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let memory_x = dir.join("../../memory.x");
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
    if !env::var("TARGET").unwrap_or_default().starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var("OUT_DIR").unwrap_or_default());
    if let Err(e) = fs::copy(&memory_x, out.join("memory.x")) {
        println!("cargo:warning=cannot copy {}: {e}", memory_x.display());
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
}
