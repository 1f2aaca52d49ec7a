//! Work beside the pipeline on a thread of its own: the input sheets' decode (`decode_ahead`, at
//! normal priority) and the input's figures for the report, which run on idle CPU time only (the
//! idle scheduling class, with a one-thread pool for the rayon calls inside), so that they never
//! slow the stages they run beside.
//!
//! Why idle time for the figures: the input model's figures for the report are a pure function of the input, needed only
//! at the end, and they cost a noticeable fraction of a second on large scans; the merge leaves a core idle
//! part of the time (its master settles serial work while the shadow waits), so the figures can
//! be had there for nothing. At normal priority the same thread would take its share of the
//! cores from the merge's two threads, whose slowest path sets the run time. `SCHED_IDLE` runs it
//! only when a core has nothing else to do; when the result is asked for, the caller waits, and
//! the cores are then free for it anyway. The result is the same whichever thread computes it.

use std::thread::JoinHandle;
use std::time::Instant;

/// How a [`Background`] job is scheduled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Priority {
    /// The idle scheduling class, with a one-thread pool for the rayon calls inside the job.
    Idle,
    /// Like any other thread of the process.
    Normal,
}

/// A job running on a thread of its own, or kept to run on the caller's thread when no thread
/// could be spawned (a process at its thread limit). Dropping it unfinished (an early error
/// return) waits for the thread and drops the result, so nothing the job made outlives the
/// run; a job kept to run inline is then never run.
pub(super) struct Background<T: Send + 'static> {
    state: Option<State<T>>,
}

enum State<T> {
    Running(JoinHandle<T>),
    Inline(Box<dyn FnOnce() -> T + Send>),
}

/// Puts the calling thread in the idle scheduling class; a failure (another platform, or a
/// sandbox that forbids it) leaves it at normal priority, which changes no result.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    {
        let param = libc::sched_param { sched_priority: 0 };
        // SAFETY: sched_setscheduler reads the parameter block only during the call; pid 0 is
        // the calling thread on Linux. The return value is only a success flag.
        let _ = unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) };
    }
}

/// Runs `job` at `priority` on the calling thread (a spawned one).
fn run<T: Send>(priority: Priority, job: Box<dyn FnOnce() -> T + Send>) -> T {
    if priority == Priority::Normal {
        return job();
    }
    lower_priority();
    // Rayon calls inside the job run on this one idle thread, not on the global pool.
    match rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(|_| "scanatlas-idle".into())
        .start_handler(|_| lower_priority())
        .build()
    {
        Ok(pool) => pool.install(job),
        Err(_) => job(),
    }
}

impl<T: Send + 'static> Background<T> {
    /// Starts `job` on a thread named `name` at `priority`.
    pub fn start(name: &str, priority: Priority, job: impl FnOnce() -> T + Send + 'static) -> Self {
        let job: Box<dyn FnOnce() -> T + Send> = Box::new(job);
        // The job is handed over through a slot so that a failed spawn gives it back.
        let slot = std::sync::Arc::new(std::sync::Mutex::new(Some(job)));
        let theirs = slot.clone();
        let spawned = std::thread::Builder::new().name(name.into()).spawn(move || {
            let job = theirs.lock().ok().and_then(|mut j| j.take());
            run(priority, job.expect("the job is handed over once"))
        });
        let state = match spawned {
            Ok(h) => State::Running(h),
            Err(_) => {
                let job = slot.lock().ok().and_then(|mut j| j.take());
                State::Inline(job.expect("a thread that was not spawned took no job"))
            }
        };
        Self { state: Some(state) }
    }

    /// Waits for the result (or computes it here), with the milliseconds waited.
    pub fn finish(mut self) -> (T, f64) {
        let t = Instant::now();
        let out = match self.state.take() {
            Some(State::Running(h)) => match h.join() {
                Ok(v) => v,
                // A panic is a bug of ours, not bad input: hand it on.
                Err(p) => std::panic::resume_unwind(p),
            },
            Some(State::Inline(job)) => job(),
            None => unreachable!("finish consumes the job"),
        };
        (out, t.elapsed().as_secs_f64() * 1e3)
    }
}

impl<T: Send + 'static> Drop for Background<T> {
    fn drop(&mut self) {
        if let Some(State::Running(h)) = self.state.take() {
            // The result goes with it; a panic has nothing left to clean.
            let _ = h.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    #[test]
    fn the_result_is_the_jobs_whoever_runs_it() {
        let data: Vec<u64> = (0..100_000).collect();
        let expected: u64 = data.iter().map(|x| x * x % 7).sum();
        let bg = Background::start("scanatlas-test", Priority::Idle, move || {
            data.par_iter().map(|x| x * x % 7).sum::<u64>()
        });
        assert_eq!(bg.finish().0, expected);
    }
}
