//! Fuzzes the COLMAP readers. The first byte chooses text (even) or binary (odd); the rest is
//! the cameras file, then (after the separator) the images file, then the points file.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::colmap(data));
