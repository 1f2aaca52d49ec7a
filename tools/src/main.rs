//! The `scanatlas` command line: argument parsing, logging, signals, and exit codes (0 success,
//! 1 failure, 2 bad usage, 130 and 143 when stopped by SIGINT and SIGTERM). Every subcommand
//! lives in its own module under `commands/`.

use std::process::ExitCode;

use clap::Parser;
use scanatlas_cli::{cli, commands, progress};
use tracing_subscriber::filter::Targets;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    init_logging(args.global.verbose, args.global.quiet);
    progress::init(args.global.quiet, args.global.progress == cli::ProgressArg::Json);
    if let Some(n) = args.global.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(usize::from(n)).build_global()
    {
        eprintln!("scanatlas: error: cannot start {n} threads: {e}");
        return ExitCode::from(1);
    }
    if let Err(e) = catch_signals() {
        eprintln!("scanatlas: error: cannot install the signal handlers: {e}");
        return ExitCode::from(1);
    }
    let result = commands::run(args);
    // A signal that arrives after the last safe point finds the work done: the run completed (its
    // report says so), and its exit status says the same.
    if let Some(signal) = scanatlas_core::cancel::signal().filter(|&s| s > 0 && result.is_err()) {
        // The run stopped at a safe point and removed its temporary files; the shell's
        // convention for a death by signal N is 128 + N.
        eprintln!("scanatlas: interrupted by signal {signal}");
        return ExitCode::from(128 + signal as u8);
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if err.downcast_ref::<commands::UsageError>().is_some() => {
            eprintln!("scanatlas: error: {err}");
            ExitCode::from(2)
        }
        Err(err) => {
            // Under --strict the warnings are the reason for the failure: all of them are shown.
            for w in strict_warnings(&err) {
                eprintln!("scanatlas: warning: {w}");
            }
            // One line per cause, outermost first, so cron logs stay readable. Error types that
            // quote their source in their own message would print it twice: such a cause is
            // left out.
            let mut shown = err.to_string();
            eprintln!("scanatlas: error: {shown}");
            for cause in err.chain().skip(1) {
                let cause = cause.to_string();
                if !shown.contains(&cause) {
                    eprintln!("  caused by: {cause}");
                }
                shown = cause;
            }
            ExitCode::from(1)
        }
    }
}

/// SIGINT, SIGTERM and SIGHUP ask the running pipeline to stop at its next safe point (see
/// `scanatlas_core::cancel`); a second one of the same kind ends the process at once.
fn catch_signals() -> std::io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let asked = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for sig in [SIGINT, SIGTERM, SIGHUP] {
        // Registered first, so it sees the flag as the earlier signal left it: a second signal
        // exits at once (what is left then is what a kill leaves, see docs/OUTPUT-SAFETY.md).
        signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, asked.clone())?;
        signal_hook::flag::register(sig, asked.clone())?;
        // SAFETY: the handler only stores into a static atomic, which is async-signal-safe.
        unsafe {
            signal_hook::low_level::register(sig, move || scanatlas_core::cancel::request(sig))
        }?;
    }
    Ok(())
}

/// The warnings that made a `--strict` run fail before any work (warnings met after the run
/// are printed by the command itself).
fn strict_warnings(err: &anyhow::Error) -> &[scanatlas_core::warnings::Warning] {
    use scanatlas_core::pipeline::PipelineError;
    match err.downcast_ref::<PipelineError>() {
        Some(PipelineError::Strict(s)) => &s.0,
        _ => &[],
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
    // `Targets` reads `SCANATLAS_LOG` directives such as `info` or `scanatlas_core=debug,warn`
    // without the regular-expression engine that `EnvFilter` would add to the build.
    let from_env = std::env::var("SCANATLAS_LOG").ok().map(|d| (d.parse::<Targets>(), d));
    let filter = match &from_env {
        Some((Ok(targets), _)) => targets.clone(),
        _ => level.parse::<Targets>().unwrap_or_default(),
    };
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_target(false)
        .finish()
        .with(filter)
        .init();
    if let Some((Err(e), directives)) = from_env {
        tracing::warn!(
            "SCANATLAS_LOG={directives:?} is not a list of log directives ({e}); using {level}"
        );
    }
}
