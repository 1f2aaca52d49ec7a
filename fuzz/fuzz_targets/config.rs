//! Fuzzes the `defrag --config FILE.toml` reader through the command line's own library:
//! parsing, merging under the flags, and the check of every plugin name and parameter.

#![no_main]

#[path = "common.rs"]
mod common;

use scanatlas_cli::{cli, commands};
use clap::Parser;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = common::put("c.toml", data);
    let argv = ["scanatlas", "defrag", "in.obj", "-o", "out.obj", "--config"];
    let Ok(parsed) = cli::Cli::try_parse_from(argv.iter().copied().chain([path.to_str().unwrap()]))
    else {
        return;
    };
    let cli::Command::Defrag(args) = parsed.command else { return };
    let mut registry = scanatlas_core::plugin::Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
    let _ = commands::config::defrag_config(&args, &registry);
});
