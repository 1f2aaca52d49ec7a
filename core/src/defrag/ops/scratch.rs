//! The buffers of the operation geometry, held by the engine and reused for every operation.

use crate::topology::{ChartId, UvVertId};

/// How many neighbours of a chart the memo keeps: enough to answer every question of the
/// small-island look-ahead (at most its step budget plus one, and whether there are more).
pub(super) const MEMO_CAP: usize = 7;

/// What `Engine::op_geometry` leaves behind.
#[derive(Default)]
pub(crate) struct OpScratch {
    /// The distinct vertex pairs `(stays, moves)` of the operation last measured, sorted.
    pub(in crate::defrag) pairs: Vec<[UvVertId; 2]>,
    /// The positions of those pairs, the input of the rigid fit.
    pub(super) pts: Vec<([f64; 2], [f64; 2])>,
    pub(in crate::defrag) neighbours: NeighbourMemo,
}

/// The first neighbours of each chart, remembered while the chart graph cannot change: during
/// a rescoring (after a commit, or of the whole queue), operations change state only between
/// live states, so every chart keeps its neighbours. The small-island look-ahead of each
/// operation around a big chart asks for the same small charts' neighbours again and again.
#[derive(Default)]
pub(in crate::defrag) struct NeighbourMemo {
    /// Per chart: the epoch its entry was filled in, how many distinct neighbours it has (up to
    /// `MEMO_CAP + 1`, meaning more than `MEMO_CAP`), and the first of them in discovery order.
    pub(super) epoch: Vec<u32>,
    pub(super) count: Vec<u8>,
    pub(super) first: Vec<[ChartId; MEMO_CAP]>,
    /// The epoch of the rescoring under way; 0 when none is (entries are never read then).
    pub(super) current: u32,
    /// The buffer an entry is found in, kept so that filling one allocates nothing.
    pub(super) found: Vec<ChartId>,
}

impl NeighbourMemo {
    /// Opens a rescoring over `charts` charts: entries of earlier ones are stale from now on.
    pub(in crate::defrag) fn begin(&mut self, charts: usize) {
        if self.epoch.len() < charts {
            self.epoch.resize(charts, 0);
            self.count.resize(charts, 0);
            self.first.resize(charts, [ChartId(0); MEMO_CAP]);
        }
        self.current = self.current.wrapping_add(1).max(1);
        if self.current == 1 {
            // After a wrap every entry might carry a live-looking epoch.
            self.epoch.fill(0);
        }
    }

    /// Closes the rescoring: the chart graph may change again.
    pub(in crate::defrag) fn end(&mut self) {
        self.current = 0;
    }
}
