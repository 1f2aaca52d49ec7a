//! Fuzzes the glTF and GLB reader: the input is the `.gltf` JSON or a GLB (recognised by its
//! magic bytes), then (after the separator) an external buffer `b.bin`, then an image `t.png`.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::gltf(data));
