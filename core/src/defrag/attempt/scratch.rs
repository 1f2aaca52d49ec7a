//! What an attempt keeps while it runs, and the solves it keeps for a failed operation's next
//! attempt.

use super::memo::SolveMemos;
use crate::defrag::reach::{ReadRegion, WrittenRegion};
use crate::topology::ChartId;

/// The buffers and flags of the attempt in progress, and the memo of failed attempts' solves.
#[derive(Default)]
pub(crate) struct AttemptScratch {
    /// The vertices of the moved chart b.
    pub(in crate::defrag) moved: Vec<u32>,
    /// The fused vertex groups as (group, vertex), sorted.
    pub(super) groups: Vec<(u32, u32)>,
    /// The problem's fused starting layout, for reruns and the rescue.
    pub(in crate::defrag) start_uv: Vec<[f64; 2]>,
    /// The chart held still by the attempt in progress (see `MergeOptions::one_sided`).
    pub(in crate::defrag) hold: Option<ChartId>,
    /// The solves of failed attempts, for the same operations' next attempts.
    pub(super) memo: SolveMemos,
    /// What the attempt just ended read, if it was refused for a reason that depends only on
    /// that (see `reach`): the settling keeps it in the operation's table entry.
    pub(in crate::defrag) read: Option<ReadRegion>,
    /// What the last commit wrote, for deciding which failed operations it brings back.
    pub(in crate::defrag) written: Option<WrittenRegion>,
}
