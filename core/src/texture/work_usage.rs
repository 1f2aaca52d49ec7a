//! The disk the temporary tile files take in the work folder: every [`TileStore`] counts its
//! file's bytes while it lives, so that a run can report the most it held at once.
//!
//! Why a count rather than a look at the folder: the tile files are created unlinked (see
//! [`TileStore`]), so no listing of the work folder sees them, and the free space of the file
//! system moves with whatever else writes to it.
//!
//! The count is process-wide. A [`WorkDirMeter`] records the largest total seen while it lives,
//! so two runs side by side in one process (tests, a library caller) each count the other's files
//! that were alive at the same time; the command line runs one pipeline per process.
//!
//! [`TileStore`]: super::TileStore

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Weak};

/// Bytes of the tile files alive now.
static LIVE: AtomicU64 = AtomicU64::new(0);

/// The peaks of the meters alive now. A store is created per sheet or pyramid level, never per
/// texel, so a lock on each creation costs nothing measurable.
static METERS: Mutex<Vec<Weak<AtomicU64>>> = Mutex::new(Vec::new());

fn meters() -> std::sync::MutexGuard<'static, Vec<Weak<AtomicU64>>> {
    // A panic elsewhere while the lock was held left a list that is still valid.
    METERS.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Counts `bytes` of a new tile file and raises the peak of every live meter.
pub(super) fn add(bytes: u64) {
    let now = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    meters().retain(|m| match m.upgrade() {
        Some(peak) => {
            peak.fetch_max(now, Ordering::Relaxed);
            true
        }
        None => false,
    });
}

/// Counts `bytes` of a tile file as deleted.
pub(super) fn remove(bytes: u64) {
    LIVE.fetch_sub(bytes, Ordering::Relaxed);
}

/// Bytes of the tile files alive now, in this process.
pub fn live_bytes() -> u64 {
    LIVE.load(Ordering::Relaxed)
}

/// The most bytes of tile files alive at once since the meter was started (those alive at its
/// start included).
#[derive(Debug)]
pub struct WorkDirMeter {
    peak: Arc<AtomicU64>,
}

impl WorkDirMeter {
    /// Starts measuring.
    pub fn start() -> Self {
        let peak = Arc::new(AtomicU64::new(live_bytes()));
        meters().push(Arc::downgrade(&peak));
        Self { peak }
    }

    /// The peak so far.
    pub fn peak_bytes(&self) -> u64 {
        self.peak.load(Ordering::Relaxed).max(live_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{PixelFormat, TileStore};

    #[test]
    fn the_meter_keeps_the_peak_after_the_files_are_gone() {
        let dir = tempfile::tempdir().unwrap();
        let meter = WorkDirMeter::start();
        let a = TileStore::create(dir.path(), 300, 10, PixelFormat::RGB8).unwrap();
        let b = TileStore::create(dir.path(), 10, 10, PixelFormat::RGB8).unwrap();
        let both = (a.tile_bytes() * 2 + b.tile_bytes()) as u64;
        drop((a, b));
        // Other tests of this process may have had stores alive beside these: at least ours.
        assert!(meter.peak_bytes() >= both, "{} < {both}", meter.peak_bytes());
    }
}
