//! Dispatch of the subcommands.

mod build;
mod config;
mod convert;
mod defrag;
mod demo;
mod plugins;
mod report;
mod rig_score;
mod stats;
mod synth;
mod synth_rig;

use anyhow::Result;

use crate::cli::{Cli, Command};

/// A usage mistake found after argument parsing (an unknown plugin or parameter, a bad config
/// file): `main` exits with status 2 for it, as for clap's own usage errors.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

pub fn run(cli: Cli) -> Result<()> {
    let quiet = cli.global.quiet;
    match cli.command {
        Command::Stats(a) => stats::run(&a),
        Command::Synth(a) => synth::run(&a, quiet),
        Command::Demo(a) => demo::run(&a, quiet),
        Command::Convert(a) => convert::run(&a, quiet),
        Command::Defrag(a) => defrag::run(&a, quiet),
        Command::Plugins(a) => plugins::run(&a),
        Command::Build(a) => build::run(&a, quiet),
        Command::SynthRig(a) => synth_rig::run(&a, quiet),
        Command::RigScore(a) => rig_score::run(&a),
        Command::Report(a) => report::run(&a, quiet),
    }
}
