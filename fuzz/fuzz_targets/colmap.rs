//! Fuzzes the COLMAP readers. The first byte chooses text (even) or binary (odd); the rest is
//! the cameras file, then (after the separator) the images file, then the points file.

#![no_main]

#[path = "common.rs"]
mod common;

use scanatlas_core::photo_atlas::colmap::{read_binary, read_text};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((&kind, rest)) = data.split_first() else { return };
    let parts = common::split(rest, 3);
    let binary = kind % 2 == 1;
    let dir = if binary { "bin" } else { "txt" };
    let ext = if binary { "bin" } else { "txt" };
    for (name, bytes) in ["cameras", "images", "points3D"].iter().zip(&parts) {
        common::put(&format!("{dir}/{name}.{ext}"), bytes);
    }
    let dir = common::scratch().join(dir);
    let _ = if binary { read_binary(&dir) } else { read_text(&dir) };
});
