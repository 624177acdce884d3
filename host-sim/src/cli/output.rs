//! Where the `parapet` commands' output goes: standard output that a closed
//! pipe cannot turn into a panic ([`out`]), and output paths that never replace
//! an input file ([`refuse_overwrite`]).
//!
//! May import: `cli` (its error type), `input`.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::anyhow;

use crate::cli::CliError;
use crate::input::InputError;

/// Write `text` to standard output. A reader that closed the pipe (`| head`,
/// `| true`) gives [`CliError::StdoutClosed`] (quiet exit 0); other write
/// errors are failures (exit 1). Never panics, unlike `print!`.
pub fn out(text: &str) -> Result<(), CliError> {
    let mut so = std::io::stdout().lock();
    match so.write_all(text.as_bytes()).and_then(|()| so.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(CliError::StdoutClosed),
        Err(e) => Err(CliError::Failed(anyhow!("cannot write to standard output: {e}"))),
    }
}

/// `true` when `a` and `b` name the same existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y)
}

/// Refuse (exit 2) when one of `outputs` would replace one of `inputs`
/// (`(what, path)`), naming the option, both files and what the input is.
pub fn refuse_overwrite(option: &str, outputs: &[PathBuf], inputs: &[(&str, &Path)]) -> Result<(), CliError> {
    for o in outputs {
        for (what, i) in inputs {
            if same_file(o, i) {
                return Err(InputError::option(
                    option,
                    format!("would overwrite the {what} {}", i.display()),
                )
                .value(o.display())
                .allowed("a path that is not an input file")
                .into());
            }
        }
    }
    Ok(())
}
