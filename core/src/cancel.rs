//! Cancellation of a run: a process-wide flag that a signal handler (or a library user) sets, and
//! that the pipelines read at their safe points (between stages, and cheaply inside the long
//! loops: the merge queue, the texture tiles), so an interrupted run stops soon, removes its
//! temporary files and leaves the destination as it was.
//!
//! Why a process-wide flag: a signal handler may only do async-signal-safe work, and storing an
//! integer into a static atomic is; the long loops then read it without taking any lock.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal that asked to stop (0 while nobody asked; -1 when asked by code, not a signal).
static REQUESTED: AtomicI32 = AtomicI32::new(0);

/// The code used by [`request`] when the stop does not come from a signal.
pub const BY_CALLER: i32 = -1;

/// Asks every running pipeline to stop at its next safe point. `signal` is the signal number
/// (or [`BY_CALLER`]); the first request wins. Async-signal-safe.
pub fn request(signal: i32) {
    let _ = REQUESTED.compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst);
}

/// Whether a stop was asked for.
#[inline]
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed) != 0
}

/// The signal that asked to stop, if any.
pub fn signal() -> Option<i32> {
    match REQUESTED.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// Clears the request (for a library user that runs again after a stop, and for tests).
pub fn reset() {
    REQUESTED.store(0, Ordering::SeqCst);
}

/// The error of a stopped run, for the pipelines' `?`.
#[derive(Debug, thiserror::Error)]
#[error("interrupted{}", signal_name(*.0))]
pub struct Interrupted(pub i32);

fn signal_name(signal: i32) -> String {
    match signal {
        libc::SIGINT => " by SIGINT".into(),
        libc::SIGTERM => " by SIGTERM".into(),
        libc::SIGHUP => " by SIGHUP".into(),
        BY_CALLER => String::new(),
        s => format!(" by signal {s}"),
    }
}

/// `Err(Interrupted)` when a stop was asked for: the check at a safe point.
pub fn check() -> Result<(), Interrupted> {
    match signal() {
        None => Ok(()),
        Some(s) => Err(Interrupted(s)),
    }
}
