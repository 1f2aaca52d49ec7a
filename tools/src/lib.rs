//! The command line as a library: the clap definitions and the subcommands, shared by the
//! `scanatlas` binary and the Python package, which parses its keyword options with the same
//! definitions (so both accept the same names and values and map them the same way).

pub mod cli;
pub mod commands;
pub mod progress;
