//! The command line as a library: the clap definitions and the subcommands, shared by the
//! `scanatlas` binary and the Python package, which parses its keyword options with the same
//! definitions (so both accept the same names and values and map them the same way).

// Standard output goes through `commands::print_out`, which takes a closed pipe (`| head`) as the
// end of the reader's interest rather than a panic.
#![cfg_attr(not(test), deny(clippy::print_stdout))]

pub mod cli;
pub mod commands;
pub mod progress;
