//! `scanatlas man [COMMAND]`: the roff manual page of scanatlas or of one subcommand on stdout, or
//! every page written to a folder with `--out-dir` (for packagers: `scanatlas.1`,
//! `scanatlas-defrag.1`, ...).

use anyhow::{Context, Result};
use clap::CommandFactory;

use super::UsageError;
use crate::cli::{Cli, ManArgs};

pub fn run(args: &ManArgs) -> Result<()> {
    let cmd = Cli::command();
    if let Some(dir) = &args.out_dir {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating the folder {}", dir.display()))?;
        return write_all_pages(cmd, dir);
    }
    let page = match &args.command {
        None => cmd,
        Some(name) => subcommand(&cmd, name)?,
    };
    let mut buf = Vec::new();
    clap_mangen::Man::new(page).render(&mut buf).context("rendering the manual page")?;
    super::print_out(&buf)?;
    Ok(())
}

/// The subcommand `name`, named `scanatlas-NAME` as its page is, or a usage error listing the
/// valid names.
fn subcommand(cmd: &clap::Command, name: &str) -> Result<clap::Command> {
    let Some(sub) = cmd.find_subcommand(name) else {
        let names: Vec<&str> = cmd.get_subcommands().map(clap::Command::get_name).collect();
        return Err(
            UsageError(format!("unknown command `{name}`; valid: {}", names.join(", "))).into()
        );
    };
    Ok(named(sub))
}

/// A subcommand renamed `scanatlas-NAME` (its page's title and file name) with the version of the
/// whole program.
fn named(sub: &clap::Command) -> clap::Command {
    let name = format!("scanatlas-{}", sub.get_name());
    sub.clone().name(name).version(env!("CARGO_PKG_VERSION"))
}

/// Writes `scanatlas.1` and one `scanatlas-NAME.1` per subcommand into `dir`, each atomically.
fn write_all_pages(cmd: clap::Command, dir: &std::path::Path) -> Result<()> {
    let mut pages = vec![cmd.clone()];
    pages.extend(cmd.get_subcommands().filter(|s| s.get_name() != "help").map(named));
    for page in pages {
        let man = clap_mangen::Man::new(page);
        let path = dir.join(man.get_filename());
        let mut buf = Vec::new();
        man.render(&mut buf).context("rendering a manual page")?;
        scanatlas_core::atomic::write_atomic::<std::io::Error, _>(&path, &[], |w| {
            w.write_all(&buf)
        })
        .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
