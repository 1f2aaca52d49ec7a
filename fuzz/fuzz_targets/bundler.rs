//! Fuzzes the Bundler reader: the input is `bundle.out`, then (after the separator) `list.txt`.
//! The folder of photos holds one valid 1×1 PNG, `p.png`.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::bundler(data));
