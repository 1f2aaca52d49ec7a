//! Embeds the git commit the binary is built from (`SCANATLAS_COMMIT`, "unknown" outside a git
//! checkout), so that `--version` and every batch log line say which code produced an output.

use std::path::PathBuf;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8(out.stdout).ok()?.trim().to_string();
    (!text.is_empty()).then_some(text)
}

fn main() {
    let commit = git(&["rev-parse", "--short=12", "HEAD"]).unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=SCANATLAS_COMMIT={commit}");
    // Rebuild when HEAD moves (a commit, a checkout) so the embedded commit stays true.
    if let Some(dir) = git(&["rev-parse", "--absolute-git-dir"]) {
        let dir = PathBuf::from(dir);
        for file in ["HEAD", "logs/HEAD"] {
            println!("cargo:rerun-if-changed={}", dir.join(file).display());
        }
    }
    println!("cargo:rerun-if-changed=build.rs");
}
