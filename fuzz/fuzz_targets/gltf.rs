//! Fuzzes the glTF and GLB reader: the input is the `.gltf` JSON or a GLB (recognised by its
//! magic bytes), then (after the separator) an external buffer `b.bin`, then an image `t.png`.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let parts = common::split(data, 3);
    common::put("b.bin", parts[1]);
    common::put("t.png", parts[2]);
    let gltf = common::put("m.gltf", parts[0]);
    common::load(&gltf);
});
