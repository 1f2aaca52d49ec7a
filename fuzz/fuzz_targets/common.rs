//! What every fuzz target shares: a private scratch folder per process, the split of one fuzz
//! input into the several files a format spreads over, and the body of each reader's target (so
//! that `tools/tests/suite/fuzz_regressions.rs` replays kept inputs through the very same code).

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

/// The `obj` target: `scan.obj`, then its MTL `scan.mtl`, then a texture `t.png`.
pub fn obj(data: &[u8]) {
    let parts = split(data, 3);
    put("t.png", parts[2]);
    put("scan.mtl", parts[1]);
    load(&put("scan.obj", parts[0]));
}

/// The `ply` target: an ASCII or binary PLY, then a texture `t.png`.
pub fn ply(data: &[u8]) {
    let parts = split(data, 2);
    put("t.png", parts[1]);
    load(&put("m.ply", parts[0]));
}

/// The `gltf` target: a `.gltf` JSON or a GLB, then an external buffer `b.bin`, then an image.
pub fn gltf(data: &[u8]) {
    let parts = split(data, 3);
    put("b.bin", parts[1]);
    put("t.png", parts[2]);
    load(&put("m.gltf", parts[0]));
}

/// Runs `body` on `data`; with `SCANATLAS_FUZZ_PEAK_MB=N` set, aborts (so that libFuzzer keeps
/// the input as a crash) when the process's peak resident size rose more than N MB above its
/// resident size before the input. libFuzzer samples the resident size once a second, so its own
/// out-of-memory report names whichever input ran at that moment; this names the input that
/// raised the peak, read from the kernel's high-water mark (`VmHWM`, reset before each input).
pub fn watch_peak(data: &[u8], body: impl FnOnce(&[u8])) {
    static LIMIT_MB: OnceLock<Option<u64>> = OnceLock::new();
    let limit = LIMIT_MB.get_or_init(|| std::env::var("SCANATLAS_FUZZ_PEAK_MB").ok()?.parse().ok());
    let Some(limit_mb) = *limit else { return body(data) };
    // Writing 5 to clear_refs resets the high-water mark to the current resident size.
    let _ = std::fs::write("/proc/self/clear_refs", "5");
    let before = status_kb("VmRSS:");
    body(data);
    let peak = status_kb("VmHWM:");
    if peak.saturating_sub(before) > limit_mb * 1024 {
        eprintln!(
            "the peak resident size rose {} MB (from {} MB) during this {}-byte input",
            (peak - before) / 1024,
            before / 1024,
            data.len()
        );
        std::process::abort();
    }
}

/// A `kB` field of `/proc/self/status`, 0 if it cannot be read.
fn status_kb(field: &str) -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let line = status.lines().find(|l| l.starts_with(field)).unwrap_or_default();
    line.split_whitespace().nth(1).and_then(|kb| kb.parse().ok()).unwrap_or(0)
}

/// The `image` target: a PNG, JPEG, TIFF, OpenEXR or WebP file, probed then decoded.
pub fn image(data: &[u8]) {
    use scanatlas_core::model::ImageSource;
    use scanatlas_core::texture::decode::{decode_to_store, probe_size};
    let src = ImageSource::Embedded {
        name: "fuzz".into(),
        mime: String::new(),
        bytes: std::sync::Arc::new(data.to_vec()),
    };
    if probe_size(&src).is_ok() {
        let _ = decode_to_store(&src, scratch());
    }
}

/// The `colmap` target: first byte even, COLMAP text; odd, binary; then the cameras, images and
/// points files.
pub fn colmap(data: &[u8]) {
    use scanatlas_core::photo_atlas::colmap::{read_binary, read_text};
    let Some((&kind, rest)) = data.split_first() else { return };
    let parts = split(rest, 3);
    let binary = kind % 2 == 1;
    let dir = if binary { "bin" } else { "txt" };
    for (name, bytes) in ["cameras", "images", "points3D"].iter().zip(&parts) {
        put(&format!("{dir}/{name}.{dir}"), bytes);
    }
    let dir = scratch().join(dir);
    let _ = if binary { read_binary(&dir) } else { read_text(&dir) };
}

/// The `bundler` target: `bundle.out`, then `list.txt` (the photo folder holds one 1×1 PNG).
pub fn bundler(data: &[u8]) {
    let parts = split(data, 2);
    put("photos/p.png", include_bytes!("../assets/1x1.png"));
    put("bundler/list.txt", parts[1]);
    let bundle = put("bundler/bundle.out", parts[0]);
    let _ = scanatlas_core::photo_atlas::bundler::read(&bundle, &scratch().join("photos"));
}
