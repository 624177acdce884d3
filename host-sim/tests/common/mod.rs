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

/// A fresh, empty temporary directory `parapet-<suite>-<pid>-<name>`, removed when the test
/// passes and kept (for a look at what the flight wrote) when it fails.
pub fn tmp(suite: &str, name: &str) -> TmpDir {
    let d = std::env::temp_dir().join(format!("parapet-{suite}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TmpDir(d)
}

/// An output directory of one test: a run writes 5-50 MB of logs and pages, and a suite that
/// left them behind filled the disk of the machine that runs it. Deleted on drop unless the
/// thread is panicking, so a failing test keeps its evidence.
pub struct TmpDir(PathBuf);

impl std::ops::Deref for TmpDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TmpDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for TmpDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TmpDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("test output kept in {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}
