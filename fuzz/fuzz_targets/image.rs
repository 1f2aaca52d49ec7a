//! Fuzzes the image decoders (PNG, JPEG, TIFF, OpenEXR, recognised by their magic bytes): the
//! header probe, then the decode into a tile store, from embedded bytes.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::watch_peak(data, common::image));
