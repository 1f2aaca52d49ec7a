//! What an attempt keeps while it runs, and the solves it keeps for a deferred operation's next
//! attempt.

use std::collections::HashMap;

use crate::plugin::{LocalProblem, SolveReport};
use crate::topology::ChartId;

/// The buffers and flags of the attempt in progress, and the memo of deferred solves.
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
    /// The first solve of each deferred operation's attempt, by operation (see `SolveMemo`), and
    /// the one of the attempt in progress (valid while `memo_filled`) until its outcome is known.
    pub(super) solve_memo: HashMap<u32, SolveMemo>,
    pub(super) memo_scratch: SolveMemo,
    pub(super) memo_filled: bool,
}

/// A solve kept for later (see `Engine::first_solve`): the problem as the solver got it, the
/// layout it returned and its report.
#[derive(Default)]
pub(crate) struct SolveMemo {
    pub(super) start: LocalProblem,
    pub(super) solved: Vec<[f64; 2]>,
    pub(super) report: SolveReport,
}

impl SolveMemo {
    /// Whether `p` is bit for bit the problem this solve started from.
    pub(super) fn start_matches(&self, p: &LocalProblem) -> bool {
        let bits = |a: &[[f64; 2]], b: &[[f64; 2]]| {
            a.len() == b.len()
                && a.iter().zip(b).all(|(x, y)| x.map(f64::to_bits) == y.map(f64::to_bits))
        };
        let s = &self.start;
        s.fixed == p.fixed
            && s.triangles == p.triangles
            && bits(&s.uv, &p.uv)
            && s.targets.len() == p.targets.len()
            && s.targets.iter().zip(&p.targets).all(|(x, y)| bits(x, y))
    }
}
