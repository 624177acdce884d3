//! The QEMU firmware binary: where `cargo build` puts it, how to build it, and
//! the environment variable that points at a prebuilt one.
//!
//! May import: std, anyhow.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};

/// Firmware binary of the `board-qemu` build.
pub const FIRMWARE_BIN: &str = "parapet-firmware-qemu";
/// Rust target of the firmware.
pub const FIRMWARE_TARGET: &str = "thumbv7em-none-eabihf";
/// Environment variable with the path of a prebuilt QEMU firmware ELF (set by `cargo xtask test`).
pub const ELF_ENV: &str = "PARAPET_FIRMWARE_QEMU_ELF";

/// Where `cargo build` puts the QEMU firmware ELF (`CARGO_TARGET_DIR` or `<workspace>/target`).
pub fn default_firmware_path() -> PathBuf {
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("target"));
    target_dir.join(FIRMWARE_TARGET).join("release").join(FIRMWARE_BIN)
}

/// The workspace this crate was built from.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_else(|| ".".into())
}

/// The `cargo build` command of the QEMU firmware (run in the workspace root).
pub fn firmware_build_command() -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.args(["build", "--release", "-p", "parapet-firmware", "--target", FIRMWARE_TARGET])
        .args(["--no-default-features", "--features", "board-qemu", "--bin", FIRMWARE_BIN])
        .current_dir(workspace_root());
    c
}

/// `true` when `path` starts with the ELF magic (0x7f 'E' 'L' 'F').
pub fn is_elf(path: &Path) -> bool {
    let mut magic = [0u8; 4];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)).is_ok() && magic == *b"\x7fELF"
}

/// Build the QEMU firmware (cargo: a no-op when up to date) and return the ELF path.
pub fn build_firmware() -> Result<PathBuf> {
    let mut cmd = firmware_build_command();
    eprintln!("parapet pil: building the firmware: {cmd:?}");
    let status = cmd.status().context("cannot start cargo to build the firmware")?;
    if !status.success() {
        bail!("building the QEMU firmware failed ({status}); command: {cmd:?}");
    }
    let elf = default_firmware_path();
    if !elf.exists() {
        bail!("the firmware build succeeded but {} does not exist", elf.display());
    }
    Ok(elf)
}

/// The firmware ELF: `$PARAPET_FIRMWARE_QEMU_ELF` when set, else built with [`build_firmware`].
pub fn firmware_from_env_or_build() -> Result<PathBuf> {
    match std::env::var_os(ELF_ENV) {
        Some(p) => Ok(PathBuf::from(p)),
        None => build_firmware(),
    }
}
