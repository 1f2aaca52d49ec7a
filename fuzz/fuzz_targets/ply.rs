//! Fuzzes the PLY reader (ASCII and binary), with a texture `t.png` after the separator.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::ply(data));
