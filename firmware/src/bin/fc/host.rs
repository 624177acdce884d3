//! On the host, `cargo run -p parapet-firmware --release` (or `--bin parapet-firmware-h743`)
//! lands here: re-run cargo for the Cortex-M target, whose runner (`.cargo/config.toml`) flashes
//! the board through probe-rs.

/// Re-runs cargo for binary `bin` on the Cortex-M target, with `features` (the board's cargo
/// feature arguments) and the caller's arguments.
pub fn main(bin: &str, features: &[&str]) {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!("{bin}: building for thumbv7em-none-eabihf and flashing through probe-rs");
    let status = std::process::Command::new(cargo)
        .args(["run", "-p", "parapet-firmware", "--release", "--target", "thumbv7em-none-eabihf"])
        .args(features)
        .args(["--bin", bin])
        .args(std::env::args().skip(1))
        .status();
    match status {
        Ok(s) => std::process::exit(s.code().unwrap_or(1)),
        Err(e) => {
            eprintln!("{bin}: cannot run cargo: {e}");
            std::process::exit(1);
        }
    }
}
