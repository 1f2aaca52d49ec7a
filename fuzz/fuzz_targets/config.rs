//! Fuzzes the `defrag --config FILE.toml` reader through the command line's own library:
//! parsing, merging under the flags, and the check of every plugin name and parameter.

#![no_main]

#[path = "common.rs"]
mod common;
#[path = "config_input.rs"]
mod config_input;

libfuzzer_sys::fuzz_target!(|data: &[u8]| config_input::config(data));
