//! Fuzzes the Bundler reader: the input is `bundle.out`, then (after the separator) `list.txt`.
//! The folder of photos holds one valid 1×1 PNG, `p.png`.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let parts = common::split(data, 2);
    common::put("photos/p.png", include_bytes!("../assets/1x1.png"));
    common::put("bundler/list.txt", parts[1]);
    let bundle = common::put("bundler/bundle.out", parts[0]);
    let _ = scanatlas_core::photo_atlas::bundler::read(&bundle, &common::scratch().join("photos"));
});
