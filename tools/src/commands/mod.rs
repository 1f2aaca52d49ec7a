//! Dispatch of the subcommands.

mod build;
mod convert;
mod defrag;
mod demo;
mod stats;
mod synth;
mod synth_rig;

use anyhow::Result;

use crate::cli::{Cli, Command};

pub fn run(cli: Cli) -> Result<()> {
    let quiet = cli.global.quiet;
    match cli.command {
        Command::Stats(a) => stats::run(&a),
        Command::Synth(a) => synth::run(&a, quiet),
        Command::Demo(a) => demo::run(&a, quiet),
        Command::Convert(a) => convert::run(&a, quiet),
        Command::Defrag(a) => defrag::run(&a, quiet),
        Command::Build(a) => build::run(&a, quiet),
        Command::SynthRig(a) => synth_rig::run(&a, quiet),
    }
}
