//! What every fuzz target shares: a private scratch folder per process, and the split of one
//! fuzz input into the several files a format spreads over.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The separator between the files packed into one fuzz input (the seeds hold it, so mutations
/// mostly keep it).
pub const SEPARATOR: &[u8] = b"@@FILE@@";

/// A scratch folder that lives as long as the process (on tmpfs when there is one).
pub fn scratch() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let base = Path::new("/dev/shm");
        let b = tempfile::Builder::new().prefix("scanatlas-fuzz-").tempdir_in(base);
        b.or_else(|_| tempfile::tempdir()).expect("a scratch folder")
    })
    .path()
}

/// Splits `data` at every [`SEPARATOR`] into at most `n` parts (the last keeps the rest);
/// missing parts are empty.
pub fn split(data: &[u8], n: usize) -> Vec<&[u8]> {
    let mut parts = Vec::with_capacity(n);
    let mut rest = data;
    while parts.len() + 1 < n {
        match rest.windows(SEPARATOR.len()).position(|w| w == SEPARATOR) {
            Some(i) => {
                parts.push(&rest[..i]);
                rest = &rest[i + SEPARATOR.len()..];
            }
            None => break,
        }
    }
    parts.push(rest);
    parts.resize(n, &[][..]);
    parts
}

/// Writes `bytes` to `name` in the scratch folder (or a sub-folder of it).
pub fn put(name: &str, bytes: &[u8]) -> PathBuf {
    let path = scratch().join(name);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).expect("scratch sub-folder");
    }
    std::fs::write(&path, bytes).expect("scratch file");
    path
}

/// Reads a model and, when it is valid, its sheet sizes from the image headers (the probes are
/// part of loading a model). Every outcome but a panic, a hang or a huge allocation is fine.
pub fn load(path: &Path) {
    if let Ok(mut model) = scanatlas_core::io::read_model(path) {
        let _ = scanatlas_core::pipeline::probe_sheet_sizes(&mut model);
        let _ = scanatlas_core::metrics::atlas_stats(
            &model,
            &scanatlas_core::pipeline::sheet_sizes(&model),
            &scanatlas_core::metrics::StatsOptions { overlaps: false },
        );
    }
}
