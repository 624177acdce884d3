//! Bad user input, and the documented limits on it.
//!
//! [`InputError`] is the one error type for anything a user gave us — a file
//! (scene, path, CSV, vehicle) or a command-line option — that cannot be used.
//! Its message names *where* (the file or `option --name`), the table and field
//! where that applies, the value that was given and the allowed range, so a user
//! can fix the input without reading the source. The CLI maps it to exit code 2.
//! Library error enums (core's `ParamError`, the planner's errors, …) are turned
//! into an `InputError` at the boundary that knows the file or option; their debug
//! text never reaches the user.
//!
//! [`limits`] holds every cap the tools enforce on user input (durations, steps,
//! sweep sizes, …) so `--help`, `scenes/README.md` and the checks use one number.
//!
//! May import: std only (used by every other host-sim module).

use std::fmt;

/// Input that cannot be used. `Display`:
/// `"<where>: [<table>] field `<field>`: <reason> (got <value>; allowed <allowed>)"`,
/// with the parts that do not apply left out.
///
/// The optional parts are `Box<str>` so the whole error stays under clippy's
/// `result_large_err` threshold (128 bytes) and can be returned by value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputError {
    /// The file (path as given) or the option (`option --duration`).
    pub origin: String,
    /// Table in the file (`sim`, `obstacles[1]`), if any.
    pub table: Option<Box<str>>,
    /// Field or column, if any.
    pub field: Option<Box<str>>,
    /// The offending value as the user wrote it (or as parsed), if any.
    pub value: Option<Box<str>>,
    /// The allowed range or set, if any (`0 < x ≤ 3600`, `paper | multi`).
    pub allowed: Option<Box<str>>,
    /// What is wrong, in words.
    pub reason: String,
}

impl InputError {
    /// An error about a file (or a labelled input such as `the planned path`).
    pub fn file(origin: impl fmt::Display, reason: impl Into<String>) -> Self {
        Self {
            origin: origin.to_string(),
            table: None,
            field: None,
            value: None,
            allowed: None,
            reason: reason.into(),
        }
    }

    /// An error about a command-line option (`name` without the dashes).
    pub fn option(name: &str, reason: impl Into<String>) -> Self {
        Self::file(format!("option --{name}"), reason)
    }

    /// Names the table.
    pub fn table(mut self, table: impl Into<String>) -> Self {
        self.table = Some(table.into().into_boxed_str());
        self
    }

    /// Names the field.
    pub fn field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into().into_boxed_str());
        self
    }

    /// States the value given.
    pub fn value(mut self, value: impl fmt::Display) -> Self {
        self.value = Some(value.to_string().into_boxed_str());
        self
    }

    /// States the allowed range or set.
    pub fn allowed(mut self, allowed: impl Into<String>) -> Self {
        self.allowed = Some(allowed.into().into_boxed_str());
        self
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: ", self.origin)?;
        if let Some(t) = &self.table {
            write!(f, "[{t}] ")?;
        }
        if let Some(k) = &self.field {
            write!(f, "field `{k}`: ")?;
        }
        f.write_str(&self.reason)?;
        match (&self.value, &self.allowed) {
            (Some(v), Some(a)) => write!(f, " (got {v}; allowed {a})"),
            (Some(v), None) => write!(f, " (got {v})"),
            (None, Some(a)) => write!(f, " (allowed {a})"),
            (None, None) => Ok(()),
        }
    }
}

impl std::error::Error for InputError {}

/// Caps on user input. Each is documented in `--help` and `scenes/README.md`;
/// a value beyond a cap is refused with an [`InputError`] naming the cap and,
/// where one exists, the option that raises it.
pub mod limits {
    // --- sweep (owner: the sweep engineer) ---

    /// Most values in one `parapet sweep` range (`--mu`, `--delta1`, `--speed` `A:B:N`: N ≤ this).
    pub const SWEEP_MAX_VALUES: usize = 10_000;

    /// Most sensor-noise seeds of a sweep (`--seeds K`: K ≤ this).
    pub const SWEEP_MAX_SEEDS: u64 = 10_000;

    /// Most runs one `parapet sweep` invocation flies (the grid, or its `--shard I/N`
    /// slice); a larger grid must be split with `--shard I/N`.
    pub const SWEEP_MAX_RUNS: u64 = 1_000_000;

    /// Runs above which `parapet sweep` asks for `--yes` (the message states the count
    /// and the estimated time).
    pub const SWEEP_CONFIRM_RUNS: u64 = 10_000;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_enough_to_return_by_value() {
        assert!(std::mem::size_of::<InputError>() <= 128, "{}", std::mem::size_of::<InputError>());
    }

    #[test]
    fn display_names_every_part() {
        let e = InputError::file("scenes/x.toml", "out of range")
            .table("sim")
            .field("dt")
            .value(0.002)
            .allowed("0 < dt ≤ 0.001");
        assert_eq!(
            e.to_string(),
            "scenes/x.toml: [sim] field `dt`: out of range (got 0.002; allowed 0 < dt ≤ 0.001)"
        );
        let o = InputError::option("duration", "too long").value("1e20");
        assert_eq!(o.to_string(), "option --duration: too long (got 1e20)");
    }
}
