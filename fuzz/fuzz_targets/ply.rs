//! Fuzzes the PLY reader (ASCII and binary), with a texture `t.png` after the separator.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let parts = common::split(data, 2);
    common::put("t.png", parts[1]);
    let ply = common::put("m.ply", parts[0]);
    common::load(&ply);
});
