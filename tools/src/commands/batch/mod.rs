//! `scanatlas batch INPUT -o OUT_DIR [defrag options]`: every model of a folder or manifest run
//! as a child process of this binary (so a crash, an abort or a time-out of one model never
//! stops the others), up to `--jobs` at once, each logged to `OUT_DIR/batch.jsonl`, skipped
//! on a rerun when its recorded inputs, options and tool still match, locked while running, and
//! sharded over Slurm job arrays or Kubernetes Indexed Jobs.

mod cgroup;
mod child;
mod inputs;
mod log;
mod manifest;
mod plan;
mod resume;
mod shard;
pub mod summary;

use std::collections::{HashMap, VecDeque};
use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime};

use anyhow::{Context, Result};

use crate::cli::{BatchArgs, GlobalArgs};
use crate::commands::UsageError;
use child::{Exit, Finished, Running};
use log::{Entry, Figures, Status};
use manifest::{Job, Options};
use shard::Shard;

const VERSION: &str = env!("CARGO_PKG_VERSION");
const COMMIT: &str = env!("SCANATLAS_COMMIT");

/// A model that needs running, locked, with its process arguments.
struct Ready {
    index: usize,
    lock: std::fs::File,
    args: Vec<String>,
    identity: Identity,
    memory_estimate: u64,
}

/// What the record of a success says about the model's inputs and options.
struct Identity {
    input_hash: String,
    inputs: Vec<inputs::Stamp>,
    options_hash: String,
}

/// What the whole run shares.
struct Batch<'a> {
    out_dir: PathBuf,
    exe: PathBuf,
    jobs: Vec<Job>,
    cli_options: Options,
    threads_per_model: usize,
    timeout: Option<Duration>,
    force: bool,
    shard: Shard,
    host: String,
    quiet: bool,
    /// The peak memory of each model's last attempt, from the log: the best guess of its need.
    past_peaks: HashMap<String, u64>,
    counts: HashMap<Status, usize>,
    /// The lock files of the models whose processes run, by job index: each lock is held for
    /// as long as its model's process runs and released after the model is logged.
    locks: HashMap<usize, std::fs::File>,
    /// What the record of each running model will say about its inputs and options.
    identities: HashMap<usize, Identity>,
    args: &'a BatchArgs,
}

pub fn run(args: &BatchArgs, global: &GlobalArgs) -> Result<()> {
    let usage = |m: String| anyhow::Error::from(UsageError(m));
    let shard = shard::resolve(args.shard.as_deref(), args.shards, &|k| std::env::var(k).ok())
        .map_err(usage)?;
    if args.jobs == 0 {
        return Err(usage("--jobs must be at least 1".into()));
    }
    if !(args.model_timeout >= 0.0 && args.model_timeout.is_finite()) {
        return Err(usage("--model-timeout must be a number of seconds, 0 or more".into()));
    }
    let resources = cgroup::available();
    let memory_budget = match &args.memory_budget {
        Some(text) => cgroup::parse_bytes(text).map_err(usage)?,
        None => resources.memory_bytes,
    };
    let mut cli_options = plan::parse_cli_options(&args.defrag_options)?;
    // `scanatlas --strict batch …` means every model strict (and `--confine` every model
    // confined): the model processes get the switches, and the records count them as options.
    for (name, on) in plan::PASSED_ON.iter().zip([global.strict, global.confine]) {
        if on {
            cli_options.insert((*name).to_string(), None);
        }
    }
    let all_jobs = manifest::discover(&args.input, &args.output)?;
    plan::check_all(&all_jobs, &cli_options, &args.output)?;
    let jobs: Vec<Job> =
        all_jobs.into_iter().enumerate().filter(|(i, _)| shard.takes(*i)).map(|(_, j)| j).collect();
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("creating the output folder {}", args.output.display()))?;
    let threads = global.threads.map(usize::from).unwrap_or(resources.threads).max(1);
    let past_peaks = log::read_all(&args.output)?
        .into_iter()
        .filter_map(|e| Some((e.name, e.peak_rss_bytes?)))
        .collect();
    child::catch_stop_signals();
    let mut batch = Batch {
        out_dir: args.output.clone(),
        exe: std::env::current_exe().context("finding this program's path")?,
        jobs,
        cli_options,
        threads_per_model: (threads / args.jobs).max(1),
        timeout: (args.model_timeout > 0.0).then(|| Duration::from_secs_f64(args.model_timeout)),
        force: args.force,
        shard,
        host: log::host_name(),
        quiet: global.quiet,
        past_peaks,
        counts: HashMap::new(),
        locks: HashMap::new(),
        identities: HashMap::new(),
        args,
    };
    if !batch.quiet {
        eprintln!(
            "batch: {} models in shard {shard}, {} at once with {} threads each, memory budget {:.1} GiB",
            batch.jobs.len(),
            args.jobs,
            batch.threads_per_model,
            memory_budget as f64 / (1u64 << 30) as f64
        );
    }
    batch.run_all(memory_budget)?;
    if args.summary {
        summary::print(&args.output, false)?;
    }
    batch.finish()
}

impl Batch<'_> {
    /// Starts models while there are free slots and memory, reaps them, until all are done or
    /// a stop signal arrives (then the running ones are stopped and logged `interrupted`).
    fn run_all(&mut self, memory_budget: u64) -> Result<()> {
        let mut queue: VecDeque<usize> = (0..self.jobs.len()).collect();
        let mut running: Vec<Running> = Vec::new();
        let mut pending: Option<Ready> = None;
        let mut stopping = false;
        loop {
            if child::stop_signal().is_some() && !stopping {
                stopping = true;
                running.iter_mut().for_each(Running::stop);
            }
            while !stopping && running.len() < self.args.jobs {
                let ready = match pending.take() {
                    Some(p) => p,
                    None => {
                        let Some(next) = queue.pop_front() else { break };
                        match self.prepare(next) {
                            Ok(Some(p)) => p,
                            Ok(None) => continue,
                            Err(e) => {
                                self.failed_to_start(next, &e)?;
                                continue;
                            }
                        }
                    }
                };
                let in_use: u64 = running.iter().map(|r| r.memory_estimate).sum();
                if !running.is_empty()
                    && in_use.saturating_add(ready.memory_estimate) > memory_budget
                {
                    // It waits, still locked, until enough running models have finished.
                    pending = Some(ready);
                    break;
                }
                let index = ready.index;
                match self.spawn(ready) {
                    Ok(r) => running.push(r),
                    Err(e) => self.failed_to_start(index, &e)?,
                }
            }
            if running.is_empty() && ((queue.is_empty() && pending.is_none()) || stopping) {
                return Ok(());
            }
            let mut i = 0;
            while i < running.len() {
                match running[i].poll()? {
                    Some(done) => {
                        let r = running.swap_remove(i);
                        self.finished(&r, &done)?;
                    }
                    None => i += 1,
                }
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Logs a model that could not be started (its folder, its inputs unreadable) as failed.
    fn failed_to_start(&mut self, index: usize, error: &anyhow::Error) -> Result<()> {
        self.locks.remove(&index);
        let now = SystemTime::now();
        let error = Some(format!("{error:#}"));
        self.log(index, Status::Failed, now, Duration::ZERO, error, Figures::default())
    }

    /// Memory a model is expected to need: its last attempt's peak, else four times the size of
    /// its input files (decoded textures are larger than their files).
    fn memory_estimate(&self, job: usize) -> u64 {
        let job = &self.jobs[job];
        if let Some(&peak) = self.past_peaks.get(&job.name) {
            return peak;
        }
        let size: u64 = inputs::files(job)
            .iter()
            .filter_map(|p| std::fs::metadata(p).ok())
            .map(|m| m.len())
            .sum();
        size.saturating_mul(4)
    }

    /// Locks the model and either logs it `busy` or `skipped`, or returns it ready to run.
    fn prepare(&mut self, index: usize) -> Result<Option<Ready>> {
        let job = self.jobs[index].clone();
        let dir = resume::model_dir(&self.out_dir, &job.name);
        let planned = plan::plan(&job, &self.cli_options, &dir, self.threads_per_model)?;
        let started = SystemTime::now();
        let clock = Instant::now();
        let Some(lock) = resume::try_lock(&dir)? else {
            self.log(index, Status::Busy, started, clock.elapsed(), None, Figures::default())?;
            return Ok(None);
        };
        if !self.force
            && let Some(record) = resume::up_to_date(
                &dir,
                || inputs::files(&job),
                &planned.options_hash,
                VERSION,
                COMMIT,
            )
        {
            self.log(index, Status::Skipped, started, clock.elapsed(), None, record.figures)?;
            return Ok(None);
        }
        // The inputs are read before the run, so that the record vouches for what the run read
        // (a file changed meanwhile has a newer stamp, and the next run compares content).
        let files = inputs::files(&job);
        let stamps = inputs::stamps(&files);
        let input_hash = inputs::content_hash(&files)
            .with_context(|| format!("reading the inputs of {}", job.name))?;
        let memory_estimate = self.memory_estimate(index);
        Ok(Some(Ready {
            index,
            lock,
            args: planned.args,
            identity: Identity { input_hash, inputs: stamps, options_hash: planned.options_hash },
            memory_estimate,
        }))
    }

    /// Starts the process of a prepared model, whose lock it keeps until the model is logged.
    fn spawn(&mut self, ready: Ready) -> Result<Running> {
        let job = &self.jobs[ready.index];
        let dir = resume::model_dir(&self.out_dir, &job.name);
        resume::forget(&dir)?;
        resume::clear_leftovers(&dir)?;
        let running = child::spawn(
            &self.exe,
            &ready.args,
            &dir.join(resume::RUN_LOG),
            self.timeout,
            ready.index,
            self.threads_per_model,
            ready.memory_estimate,
        )?;
        if !self.quiet {
            eprintln!("batch: started {} ({})", job.name, job.primary_input().display());
        }
        self.locks.insert(ready.index, ready.lock);
        self.identities.insert(ready.index, ready.identity);
        Ok(running)
    }

    /// Logs a finished process; after a success, records it so that a rerun can skip it.
    fn finished(&mut self, r: &Running, done: &Finished) -> Result<()> {
        let job = self.jobs[r.job].clone();
        let dir = resume::model_dir(&self.out_dir, &job.name);
        let (message, warnings) = child::read_run_log(&dir.join(resume::RUN_LOG));
        let success = done.exit == Exit::Code(0);
        let (status, error) = if success {
            (Status::Ok, None)
        } else if done.timed_out {
            let limit = self.timeout.map_or(0.0, |t| t.as_secs_f64());
            (Status::Failed, Some(format!("stopped at --model-timeout {limit} s")))
        } else if done.stopped
            || child::stop_signal().is_some()
            || matches!(
                done.exit,
                Exit::Code(130 | 143) | Exit::Signal(libc::SIGTERM | libc::SIGINT)
            )
        {
            // Slurm and Kubernetes signal every process of the job, so a model may be stopped
            // before the batch has seen its own signal.
            (Status::Interrupted, Some("stopped by a signal; a rerun redoes it".into()))
        } else {
            let how = match done.exit {
                Exit::Code(c) => format!("exit status {c}"),
                Exit::Signal(s) => format!("killed by signal {s}"),
            };
            (Status::Failed, Some(message.map_or(how.clone(), |m| format!("{how}: {m}"))))
        };
        let mut figures = Figures::default();
        let (status, error) = match (success, self.identities.remove(&r.job)) {
            (true, Some(identity)) => {
                figures = summary::figures_of_report(&dir.join(plan::REPORT_FILE));
                let record = resume::Record {
                    version: VERSION.into(),
                    commit: COMMIT.into(),
                    options_hash: identity.options_hash,
                    input_hash: identity.input_hash,
                    inputs: identity.inputs,
                    outputs: resume::output_files(&dir).unwrap_or_default(),
                    figures: figures.clone(),
                };
                match resume::write_record(&dir, &record) {
                    Ok(()) => (status, error),
                    Err(e) => (Status::Failed, Some(format!("{e:#}"))),
                }
            }
            _ => (status, error),
        };
        let mut entry = self.entry(r.job, status, r.start_time, done.wall, error, figures);
        entry.peak_rss_bytes = Some(done.peak_rss_bytes);
        entry.threads = Some(r.threads);
        entry.warnings = Some(warnings);
        self.write(&entry)?;
        if let Err(e) = resume::clear_leftovers(&dir) {
            tracing::warn!("{}: {e:#}", job.name);
        }
        self.locks.remove(&r.job);
        Ok(())
    }

    fn entry(
        &self,
        index: usize,
        status: Status,
        start: SystemTime,
        wall: Duration,
        error: Option<String>,
        figures: Figures,
    ) -> Entry {
        let job = &self.jobs[index];
        let dir = resume::model_dir(&self.out_dir, &job.name);
        Entry {
            name: job.name.clone(),
            input: job.primary_input().to_path_buf(),
            output: dir.join(&job.model_file),
            command: match job.kind {
                manifest::Kind::Defrag { .. } => "defrag".into(),
                manifest::Kind::Build { .. } => "build".into(),
            },
            status,
            error,
            start: log::rfc3339(start),
            wall_s: wall.as_secs_f64(),
            peak_rss_bytes: None,
            threads: None,
            warnings: None,
            figures,
            version: VERSION.into(),
            commit: COMMIT.into(),
            host: self.host.clone(),
            shard: self.shard.to_string(),
            pid: std::process::id(),
        }
    }

    fn log(
        &mut self,
        index: usize,
        status: Status,
        start: SystemTime,
        wall: Duration,
        error: Option<String>,
        figures: Figures,
    ) -> Result<()> {
        let entry = self.entry(index, status, start, wall, error, figures);
        self.write(&entry)
    }

    fn write(&mut self, entry: &Entry) -> Result<()> {
        // Outcomes of runs are synced; a lost `skipped` or `busy` line costs nothing.
        let sync = !matches!(entry.status, Status::Skipped | Status::Busy);
        log::append(&self.out_dir, entry, sync)?;
        *self.counts.entry(entry.status).or_default() += 1;
        if !self.quiet && !matches!(entry.status, Status::Skipped) {
            let error = entry.error.as_deref().map(|e| format!(": {e}")).unwrap_or_default();
            eprintln!(
                "batch: {} {} in {:.1} s{error}",
                entry.status.label(),
                entry.name,
                entry.wall_s
            );
        }
        Ok(())
    }

    /// The exit: 143/130 after a stop signal, an error (status 1) when any model failed.
    fn finish(&self) -> Result<()> {
        let count = |s: Status| self.counts.get(&s).copied().unwrap_or(0);
        let line = format!(
            "{} ok, {} failed, {} skipped, {} busy, {} interrupted",
            count(Status::Ok),
            count(Status::Failed),
            count(Status::Skipped),
            count(Status::Busy),
            count(Status::Interrupted)
        );
        if !self.quiet {
            eprintln!("batch: {line} (log {})", self.out_dir.join(log::LOG_FILE).display());
        }
        if let Some(signal) = child::stop_signal() {
            eprintln!("batch: stopped by signal {signal}; a rerun carries on");
            std::process::exit(128 + signal);
        }
        if count(Status::Failed) > 0 {
            anyhow::bail!("not every model succeeded: {line}");
        }
        Ok(())
    }
}
