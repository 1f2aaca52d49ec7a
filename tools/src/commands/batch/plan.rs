//! The command line of each model's process: the batch's `defrag` options read with the real
//! `defrag` argument definitions, a manifest's per-model options over them, every resulting
//! command checked by the real parser (and the plugin registry) before anything runs, and the
//! hash of the options that the resume record compares.

use std::collections::HashMap;
use std::path::Path;

use anyhow::Result;
use clap::{CommandFactory, Parser};

use super::manifest::{Job, Kind, Options};
use super::resume;
use crate::cli::{Cli, Command};
use crate::commands::UsageError;

/// Options the batch sets itself for every model.
const RESERVED: [&str; 9] =
    ["output", "report", "threads", "quiet", "verbose", "mesh", "cameras", "images", "help"];

/// Global switches of the batch that each model's process gets too, `build` ones included.
pub const PASSED_ON: [&str; 2] = ["strict", "confine"];

/// The report file in each model's folder.
pub const REPORT_FILE: &str = "report.json";

fn usage(msg: impl Into<String>) -> anyhow::Error {
    UsageError(msg.into()).into()
}

/// Whether the long option `name` of `subcommand` takes a value, or `None` if it has no such
/// option.
fn takes_value(subcommand: &str, name: &str) -> Option<bool> {
    let cli = Cli::command();
    let sub = cli.find_subcommand(subcommand)?;
    let arg = sub.get_arguments().chain(cli.get_arguments()).find(|a| {
        a.get_long() == Some(name) || a.get_all_aliases().is_some_and(|v| v.contains(&name))
    })?;
    Some(arg.get_action().takes_values())
}

/// The batch's trailing `defrag` options (`--solver slim --no-retry --padding=2`) as options.
pub fn parse_cli_options(tokens: &[String]) -> Result<Options> {
    let mut out = Options::new();
    let mut it = tokens.iter();
    while let Some(token) = it.next() {
        let Some(flag) = token.strip_prefix("--") else {
            return Err(usage(format!(
                "unexpected {token:?} after the batch's input: defrag options are `--name value`"
            )));
        };
        let (name, inline) = match flag.split_once('=') {
            Some((n, v)) => (n, Some(v.to_string())),
            None => (flag, None),
        };
        check_name(name)?;
        match takes_value("defrag", name) {
            None => return Err(usage(format!("`defrag` has no option --{name}"))),
            Some(true) => {
                let value = match inline {
                    Some(v) => v,
                    None => it
                        .next()
                        .cloned()
                        .ok_or_else(|| usage(format!("--{name} needs a value")))?,
                };
                out.insert(name.to_string(), Some(value));
            }
            Some(false) => {
                if inline.is_some() {
                    return Err(usage(format!("--{name} takes no value")));
                }
                out.insert(name.to_string(), None);
            }
        }
    }
    Ok(out)
}

fn check_name(name: &str) -> Result<()> {
    if RESERVED.contains(&name) {
        return Err(usage(format!(
            "--{name} is set by the batch for each model (give --threads before the input)"
        )));
    }
    Ok(())
}

/// A job's process arguments (after the executable) and the hash of what decides its outputs.
#[derive(Clone, Debug)]
pub struct Planned {
    pub args: Vec<String>,
    pub options_hash: String,
}

/// The model process's arguments for `job` writing into `dir` with `threads` threads.
pub fn plan(job: &Job, cli_options: &Options, dir: &Path, threads: usize) -> Result<Planned> {
    let model = dir.join(&job.model_file).to_string_lossy().into_owned();
    let report = dir.join(REPORT_FILE).to_string_lossy().into_owned();
    let mut args = vec!["--threads".to_string(), threads.to_string()];
    let options = match &job.kind {
        Kind::Defrag { input } => {
            args.extend(["defrag".into(), input.to_string_lossy().into_owned()]);
            let mut merged = cli_options.clone();
            merged.extend(job.options.clone());
            merged
        }
        Kind::Build { mesh, cameras, images } => {
            args.push("build".into());
            for (flag, path) in [("--mesh", mesh), ("--cameras", cameras), ("--images", images)] {
                args.extend([flag.to_string(), path.to_string_lossy().into_owned()]);
            }
            let mut merged: Options = cli_options
                .iter()
                .filter(|(name, _)| PASSED_ON.contains(&name.as_str()))
                .map(|(name, value)| (name.clone(), value.clone()))
                .collect();
            merged.extend(job.options.clone());
            merged
        }
    };
    args.extend(["-o".into(), model, "--report".into(), report]);
    let mut hasher = blake3::Hasher::new();
    hasher.update(args[2].as_bytes());
    for (name, value) in &options {
        check_name(name)?;
        match value {
            Some(v) => args.push(format!("--{name}={v}")),
            None => args.push(format!("--{name}")),
        }
        hasher.update(format!("\0{name}={value:?}").as_bytes());
        // A config file's content decides the outputs as much as a flag does.
        if name == "config"
            && let Some(path) = value
            && let Ok(bytes) = std::fs::read(path)
        {
            hasher.update(&bytes);
        }
    }
    // Temporary tiles go to a folder of their own that the batch removes after each attempt, so
    // a killed run leaves nothing behind (unless the options name a work folder).
    if matches!(job.kind, Kind::Defrag { .. }) && !options.contains_key("work-dir") {
        let work = dir.join(resume::WORK_DIR).to_string_lossy().into_owned();
        args.extend(["--work-dir".into(), work]);
    }
    Ok(Planned { args, options_hash: hasher.finalize().to_hex().to_string() })
}

/// Checks every job's command with the real parser and, for `defrag`, the plugin registry, so
/// that a bad option is a usage error (exit status 2) before any model runs. Commands that
/// differ only in their paths are checked once.
pub fn check_all(jobs: &[Job], cli_options: &Options, out_dir: &Path) -> Result<()> {
    let registry = super::super::defrag::builtin_registry();
    let mut checked: HashMap<String, ()> = HashMap::new();
    for job in jobs {
        let dir = resume::model_dir(out_dir, &job.name);
        let planned = plan(job, cli_options, &dir, 1)?;
        if checked.insert(planned.options_hash.clone(), ()).is_some() {
            continue;
        }
        let argv = std::iter::once("scanatlas".to_string()).chain(planned.args.iter().cloned());
        let cli = Cli::try_parse_from(argv).map_err(|e| {
            let text = e.to_string();
            let first = text.lines().next().unwrap_or("").trim_start_matches("error: ");
            usage(format!("model {:?}: {first}", job.name))
        })?;
        if let Command::Defrag(args) = &cli.command {
            super::super::config::defrag_config(args, &registry)
                .map_err(|e| usage(format!("model {:?}: {e}", job.name)))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens(s: &str) -> Vec<String> {
        s.split_whitespace().map(str::to_string).collect()
    }

    #[test]
    fn cli_options_are_read_with_defrag_definitions() {
        let o = parse_cli_options(&tokens("--solver slim --no-retry --padding=2")).unwrap();
        assert_eq!(o.get("solver"), Some(&Some("slim".into())));
        assert_eq!(o.get("no-retry"), Some(&None));
        assert_eq!(o.get("padding"), Some(&Some("2".into())));
        assert!(parse_cli_options(&tokens("--no-such-option 3")).is_err());
        assert!(parse_cli_options(&tokens("--threads 3")).is_err());
        assert!(parse_cli_options(&tokens("--solver")).is_err());
        assert!(parse_cli_options(&tokens("stray")).is_err());
    }

    #[test]
    fn manifest_options_override_and_change_the_hash() {
        let job = |options: Options| Job {
            name: "a".into(),
            kind: Kind::Defrag { input: "in/a.obj".into() },
            model_file: "a.obj".into(),
            options,
        };
        let cli = parse_cli_options(&tokens("--solver slim --padding 2")).unwrap();
        let base = plan(&job(Options::new()), &cli, Path::new("out/a"), 1).unwrap();
        let mut over = Options::new();
        over.insert("solver".into(), Some("arap".into()));
        let other = plan(&job(over), &cli, Path::new("out/a"), 4).unwrap();
        assert!(other.args.contains(&"--solver=arap".to_string()));
        assert!(!other.args.contains(&"--solver=slim".to_string()));
        assert_ne!(base.options_hash, other.options_hash);
        // Threads never change the outputs, so never the hash.
        let again = plan(&job(Options::new()), &cli, Path::new("out/a"), 8).unwrap();
        assert_eq!(base.options_hash, again.options_hash);
    }

    #[test]
    fn global_switches_reach_build_jobs_but_defrag_options_do_not() {
        let mut cli = parse_cli_options(&tokens("--padding 2")).unwrap();
        cli.insert("strict".into(), None);
        let job = Job {
            name: "b".into(),
            kind: Kind::Build { mesh: "m.ply".into(), cameras: "c".into(), images: "i".into() },
            model_file: "model.obj".into(),
            options: Options::new(),
        };
        let planned = plan(&job, &cli, Path::new("out/b"), 1).unwrap();
        assert!(planned.args.contains(&"--strict".to_string()));
        assert!(!planned.args.iter().any(|a| a.starts_with("--padding")));
    }
}
