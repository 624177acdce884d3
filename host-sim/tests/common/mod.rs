//! Helpers shared by the command-line tests (`cli.rs`, `sweep.rs`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run the built `parapet` binary from the workspace root.
pub fn parapet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_parapet"))
        .args(args)
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("run parapet")
}

/// A fresh, empty temporary directory `parapet-<suite>-<pid>-<name>`.
pub fn tmp(suite: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("parapet-{suite}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
