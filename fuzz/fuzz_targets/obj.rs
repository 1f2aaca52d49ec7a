//! Fuzzes the OBJ reader with its MTL library: the input is `scan.obj`, then (after the
//! separator) `scan.mtl`, then a texture `t.png`.

#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::obj(data));
