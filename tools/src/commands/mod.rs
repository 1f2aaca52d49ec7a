//! Dispatch of the subcommands.

mod batch;
pub mod build;
mod completions;
pub mod config;
mod convert;
pub mod defrag;
mod demo;
mod man;
mod plugins;
mod report;
mod rig_score;
mod stats;
mod synth;
mod synth_rig;

use anyhow::Result;
use scanatlas_core::warnings::{Warning, check_strict};

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

/// Writes `text` to standard output. A reader that stopped reading (`scanatlas stats --json |
/// head`) is not an error: the rest is simply not wanted, as with every Unix filter.
pub fn print_out(text: impl AsRef<[u8]>) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_ref()).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => Ok(other.map_err(|e| anyhow::anyhow!("writing to standard output: {e}"))?),
    }
}

/// Prints each warning as a `scanatlas: warning:` line on stderr (with `--quiet` too: warnings
/// are what an unattended run must not hide) and, with `--strict`, fails when there is any.
pub fn report_warnings(warnings: &[Warning], strict: bool) -> Result<()> {
    for w in warnings {
        eprintln!("scanatlas: warning: {w}");
    }
    check_strict(strict, warnings)?;
    Ok(())
}

pub fn run(cli: Cli) -> Result<()> {
    let quiet = cli.global.quiet;
    let strict = cli.global.strict;
    if cli.global.confine {
        scanatlas_core::io::set_confinement(true);
    }
    match cli.command {
        Command::Stats(a) => stats::run(&a, strict),
        Command::Synth(a) => synth::run(&a, quiet),
        Command::Demo(a) => demo::run(&a, quiet),
        Command::Convert(a) => convert::run(&a, quiet, strict),
        Command::Defrag(a) => defrag::run(&a, quiet, strict),
        Command::Plugins(a) => plugins::run(&a),
        Command::Build(a) => build::run(&a, quiet, strict),
        Command::SynthRig(a) => synth_rig::run(&a, quiet),
        Command::RigScore(a) => rig_score::run(&a),
        Command::Batch(a) => batch::run(&a, &cli.global),
        Command::BatchSummary(a) => batch::summary::run(&a),
        Command::Completions(a) => completions::run(&a),
        Command::Man(a) => man::run(&a),
        Command::Report(a) => report::run(&a, quiet),
    }
}
