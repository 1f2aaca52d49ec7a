//! One model's run as a child process of this binary: started with its stderr in the model's
//! `run.log`, polled with `wait4` (which also gives its peak memory), stopped with SIGTERM at its
//! time limit or when the batch itself is told to stop, and SIGKILL after a grace period.

use std::fs::File;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicI32, Ordering};
use std::time::{Duration, Instant, SystemTime};

use anyhow::{Context, Result};

/// How long a process told to stop may take before it is killed.
const GRACE: Duration = Duration::from_secs(20);

/// The signal (SIGTERM or SIGINT) that asked the batch to stop, 0 while none did.
static STOP_SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_stop_signal(signal: libc::c_int) {
    STOP_SIGNAL.store(signal, Ordering::SeqCst);
}

/// Routes SIGTERM (Slurm's time limit, `kill`, Kubernetes) and SIGINT to a flag the batch loop
/// reads, instead of ending the batch mid-way through its bookkeeping.
pub fn catch_stop_signals() {
    for signal in [libc::SIGTERM, libc::SIGINT] {
        // SAFETY: the handler only stores into an atomic, which is async-signal-safe.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_stop_signal as *const () as usize;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
}

/// The stop signal received so far, if any.
pub fn stop_signal() -> Option<i32> {
    match STOP_SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// How the process ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exit {
    Code(i32),
    Signal(i32),
}

/// A finished process.
#[derive(Debug)]
pub struct Finished {
    pub exit: Exit,
    pub wall: Duration,
    pub peak_rss_bytes: u64,
    /// It was stopped at `--model-timeout`.
    pub timed_out: bool,
    /// It was stopped because the batch was told to stop.
    pub stopped: bool,
}

/// A running model process.
#[derive(Debug)]
pub struct Running {
    pub job: usize,
    pub threads: usize,
    pub memory_estimate: u64,
    pub start_time: SystemTime,
    child: Child,
    started: Instant,
    deadline: Option<Instant>,
    term_sent: Option<Instant>,
    timed_out: bool,
    stopped: bool,
}

/// Starts `exe args...` with stdout discarded and stderr into `log`.
pub fn spawn(
    exe: &Path,
    args: &[String],
    log: &Path,
    timeout: Option<Duration>,
    job: usize,
    threads: usize,
    memory_estimate: u64,
) -> Result<Running> {
    let stderr = File::create(log).with_context(|| format!("creating {}", log.display()))?;
    let child = Command::new(exe)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(stderr)
        .spawn()
        .with_context(|| format!("starting {}", exe.display()))?;
    let started = Instant::now();
    Ok(Running {
        job,
        threads,
        memory_estimate,
        start_time: SystemTime::now(),
        child,
        started,
        deadline: timeout.map(|t| started + t),
        term_sent: None,
        timed_out: false,
        stopped: false,
    })
}

impl Running {
    fn signal(&mut self, signal: libc::c_int) {
        // SAFETY: kill on the pid of a child this process has not reaped yet (so the pid
        // cannot have been reused).
        unsafe { libc::kill(self.child.id() as libc::pid_t, signal) };
    }

    /// Asks the process to stop (SIGTERM), once.
    pub fn stop(&mut self) {
        if self.term_sent.is_none() {
            self.stopped = true;
            self.signal(libc::SIGTERM);
            self.term_sent = Some(Instant::now());
        }
    }

    /// Reaps the process if it ended; enforces the time limit and the grace period.
    pub fn poll(&mut self) -> Result<Option<Finished>> {
        let now = Instant::now();
        if self.term_sent.is_none() && self.deadline.is_some_and(|d| now >= d) {
            self.timed_out = true;
            self.signal(libc::SIGTERM);
            self.term_sent = Some(now);
        }
        if self.term_sent.is_some_and(|t| now.duration_since(t) >= GRACE) {
            self.signal(libc::SIGKILL);
        }
        let mut status: libc::c_int = 0;
        // SAFETY: `usage` is a plain struct that wait4 fills in.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        let pid = self.child.id() as libc::pid_t;
        // SAFETY: wait4 on our own child with valid out-pointers.
        let rc = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        if rc == 0 {
            return Ok(None);
        }
        if rc < 0 {
            let err = std::io::Error::last_os_error();
            if err.kind() == std::io::ErrorKind::Interrupted {
                return Ok(None);
            }
            return Err(err).context("waiting for a model process");
        }
        let exit = if libc::WIFSIGNALED(status) {
            Exit::Signal(libc::WTERMSIG(status))
        } else {
            Exit::Code(libc::WEXITSTATUS(status))
        };
        Ok(Some(Finished {
            exit,
            wall: now.duration_since(self.started),
            // Linux reports ru_maxrss in KiB.
            peak_rss_bytes: (usage.ru_maxrss.max(0) as u64) * 1024,
            timed_out: self.timed_out,
            stopped: self.stopped,
        }))
    }
}

/// The error lines a failed run printed (`scanatlas: error:` and its causes, or a panic), else
/// its last line; and the number of warnings it logged.
pub fn read_run_log(log: &Path) -> (Option<String>, u64) {
    let Ok(bytes) = std::fs::read(log) else { return (None, 0) };
    let text = String::from_utf8_lossy(&bytes);
    let warnings = text.lines().filter(|l| l.contains(" WARN ")).count() as u64;
    let errors: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| {
            l.starts_with("scanatlas: error:")
                || l.starts_with("caused by:")
                || l.contains("panicked at")
        })
        .collect();
    let message = if errors.is_empty() {
        text.lines().rev().map(str::trim).find(|l| !l.is_empty()).map(str::to_string)
    } else {
        Some(errors.join("; "))
    };
    (message, warnings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_process_over_its_time_limit_is_stopped_and_measured() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("run.log");
        let args = vec!["-c".to_string(), "exec sleep 30".to_string()];
        let mut r =
            spawn(Path::new("/bin/sh"), &args, &log, Some(Duration::from_millis(100)), 0, 1, 0)
                .unwrap();
        let finished = loop {
            if let Some(f) = r.poll().unwrap() {
                break f;
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        assert!(finished.timed_out);
        assert_eq!(finished.exit, Exit::Signal(libc::SIGTERM));
        assert!(finished.wall < Duration::from_secs(10));
        assert!(finished.peak_rss_bytes > 0);
    }

    #[test]
    fn error_lines_are_picked_from_the_run_log() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("run.log");
        std::fs::write(
            &log,
            "2026 WARN something odd\nscanatlas: error: reading x.obj\n  caused by: line 3: bad\n",
        )
        .unwrap();
        let (message, warnings) = read_run_log(&log);
        assert_eq!(
            message.as_deref(),
            Some("scanatlas: error: reading x.obj; caused by: line 3: bad")
        );
        assert_eq!(warnings, 1);
    }
}
