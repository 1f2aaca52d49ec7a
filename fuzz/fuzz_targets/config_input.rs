//! The body of the `config` fuzz target: a `defrag --config FILE.toml` file through the command
//! line's own library (parsing, merging under the flags, and the check of every plugin name and
//! parameter). Kept apart from `common.rs` because only this target needs the CLI crate.

use clap::Parser;
use scanatlas_cli::{cli, commands};

/// Reads `data` as the config file of a `defrag` command line.
pub fn config(data: &[u8]) {
    let path = super::common::put("c.toml", data);
    let argv = ["scanatlas", "defrag", "in.obj", "-o", "out.obj", "--config"];
    let Some(path) = path.to_str() else { return };
    let Ok(parsed) = cli::Cli::try_parse_from(argv.iter().copied().chain([path])) else {
        return;
    };
    let cli::Command::Defrag(args) = parsed.command else { return };
    let mut registry = scanatlas_core::plugin::Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
    let _ = commands::config::defrag_config(&args, &registry);
}
