//! What the command-line test files share: running the built binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `scanatlas args` in `cwd` (without the caller's log filter) and returns its output.
#[allow(dead_code)]
pub fn scanatlas(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_scanatlas"))
        .args(args)
        .current_dir(cwd)
        .env_remove("SCANATLAS_LOG")
        .output()
        .expect("the scanatlas binary runs")
}

/// Every file under `dir` with its bytes, by path relative to `dir`, sorted.
#[allow(dead_code)]
pub fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let bytes = std::fs::read(&p).unwrap();
                out.push((p.strip_prefix(dir).unwrap().to_path_buf(), bytes));
            }
        }
    }
    out.sort();
    out
}
