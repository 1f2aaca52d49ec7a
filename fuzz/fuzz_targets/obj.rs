//! Fuzzes the OBJ reader with its MTL library: the input is `scan.obj`, then (after the
//! separator) `scan.mtl`, then a texture `t.png`.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let parts = common::split(data, 3);
    common::put("t.png", parts[2]);
    common::put("scan.mtl", parts[1]);
    let obj = common::put("scan.obj", parts[0]);
    common::load(&obj);
});
