//! What the command-line test files share: running the built binary.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `scanatlas args` in `cwd` (without the caller's log filter) and returns its output.
pub fn scanatlas(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_scanatlas"))
        .args(args)
        .current_dir(cwd)
        .env_remove("SCANATLAS_LOG")
        .output()
        .expect("the scanatlas binary runs")
}
