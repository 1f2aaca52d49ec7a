//! `scanatlas completions SHELL`: the shell completion script of the whole command line, from the
//! same clap definition that parses it, so it never falls behind a new flag.

use anyhow::Result;
use clap::CommandFactory;

use crate::cli::{Cli, CompletionsArgs};

pub fn run(args: &CompletionsArgs) -> Result<()> {
    let mut cmd = Cli::command();
    let mut script = Vec::new();
    clap_complete::generate(args.shell, &mut cmd, "scanatlas", &mut script);
    super::print_out(&script)
}
