//! The `scanatlas` command line: argument parsing, logging, and exit codes (0 success, 1 failure,
//! 2 bad usage). Every subcommand lives in its own module under `commands/`.

mod cli;
mod commands;
mod progress;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    init_logging(args.global.verbose, args.global.quiet);
    progress::init(args.global.quiet, args.global.progress == cli::ProgressArg::Json);
    if let Some(n) = args.global.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n.max(1)).build_global()
    {
        eprintln!("scanatlas: error: cannot start {n} threads: {e}");
        return ExitCode::from(1);
    }
    match commands::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if err.downcast_ref::<commands::UsageError>().is_some() => {
            eprintln!("scanatlas: error: {err}");
            ExitCode::from(2)
        }
        Err(err) => {
            // One line per cause, outermost first, so cron logs stay readable.
            eprintln!("scanatlas: error: {err}");
            for cause in err.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::from(1)
        }
    }
}

fn init_logging(verbose: u8, quiet: bool) {
    let level = match (quiet, verbose) {
        (true, _) => "error",
        (false, 0) => "warn",
        (false, 1) => "info",
        (false, 2) => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_env("SCANATLAS_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(level));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
}
