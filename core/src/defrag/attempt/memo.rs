//! The solves of an operation's failed attempt, kept for its next attempt: a retry often builds
//! some of the very problems the failed attempt solved, and the solver is deterministic, so their
//! answers are taken from here instead of solved again.

use std::collections::HashMap;

use crate::plugin::{LocalProblem, LocalSolver, SolveError, SolveReport};

/// A solve kept for later: the problem as the solver got it, the layout it returned and its
/// report.
#[derive(Default)]
pub(crate) struct SolveMemo {
    start: LocalProblem,
    solved: Vec<[f64; 2]>,
    report: SolveReport,
}

impl SolveMemo {
    /// The bytes its buffers hold.
    fn bytes(&self) -> usize {
        use std::mem::size_of;
        let s = &self.start;
        size_of::<[f64; 2]>() * (s.uv.capacity() + self.solved.capacity())
            + s.fixed.capacity()
            + size_of::<[u32; 3]>() * s.triangles.capacity()
            + size_of::<[[f64; 2]; 3]>() * s.targets.capacity()
    }

    /// Whether `p` is bit for bit the problem this solve started from.
    fn start_matches(&self, p: &LocalProblem) -> bool {
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

/// The memo of one engine.
///
/// An operation that fails is attempted again whenever a merge changes one of its charts, but
/// the change often lies outside the optimization area, and the retry then builds the problems of
/// its failed attempt again, bit for bit: its first solve, and often those after freezing the
/// offenders of an overlap or growing the area as well. Every problem of an attempt is compared
/// bit for bit, so a taken answer is the one a solve would give, whichever engine holds the memo
/// and whatever the thread count. The hits are not counted in the report: which engine holds which
/// memo depends on the timing of the judgements ahead, and the report is the same for every thread
/// count (a taken answer reports the iterations of its solve). Only the attempts on both sides are
/// kept: an operation is held one-sided on its first attempt only, so a one-sided problem never
/// comes back.
#[derive(Default)]
pub(crate) struct SolveMemos {
    /// The solves of each operation's last failed attempt, by operation.
    by_op: HashMap<u32, Vec<SolveMemo>>,
    /// The solves of the previous failed attempt of the operation in progress.
    earlier: Vec<SolveMemo>,
    /// The solves of the attempt in progress, until its outcome is known.
    current: Vec<SolveMemo>,
    /// The bytes held by `by_op`.
    kept_bytes: usize,
    /// How many operations `by_op` held after its last sweep (see [`Self::end`]).
    swept: usize,
}

/// `by_op` is swept once it holds this many operations more than twice as many as after its
/// last sweep, so that the sweeps cost little against the attempts between them.
const SWEEP_FLOOR: usize = 256;

/// The most bytes `by_op` holds: the solves of a failed attempt that would take it beyond are
/// not kept, so the memo's memory stays bounded on any input. Sweeping at every such refusal
/// would cost a pass over the whole memo per failed attempt once it is full, so only the
/// sweeps by count (see [`SolveMemos::end`]) make room.
pub(super) const KEPT_BYTES: usize = 32 << 20;

impl SolveMemos {
    /// Starts an attempt of operation `op`: the solves of its previous failed attempt, if any,
    /// become the ones its problems are looked up in.
    pub(super) fn begin(&mut self, op: u32) {
        self.recycle();
        if let Some(earlier) = self.by_op.remove(&op) {
            self.kept_bytes -= earlier.iter().map(SolveMemo::bytes).sum::<usize>();
            self.earlier = earlier;
        }
    }

    /// Solves `problem` with `solver`, or takes the answer of the previous attempt's solve of
    /// the same problem. Either way the solve is kept until the attempt ends.
    pub(super) fn solve(
        &mut self,
        problem: &mut LocalProblem,
        solver: &mut dyn LocalSolver,
    ) -> Result<SolveReport, SolveError> {
        if let Some(i) = self.earlier.iter().position(|m| m.start_matches(problem)) {
            let m = self.earlier.swap_remove(i);
            problem.uv.clone_from(&m.solved);
            let report = m.report;
            self.current.push(m);
            return Ok(report);
        }
        // Fresh buffers of the problem's own size: reused ones would keep the capacity of the
        // largest problem they ever held for as long as the memo keeps them.
        let start = problem.clone();
        let solved = solver.solve(problem);
        if let Ok(report) = &solved {
            self.current.push(SolveMemo { start, solved: problem.uv.clone(), report: *report });
        }
        solved
    }

    /// Ends the attempt of operation `op`: a failed attempt's solves are kept for the
    /// operation's next attempt, a successful one's are dropped with the operation. Now and then
    /// the solves of operations that will never be attempted again (`live` says which may be)
    /// are dropped, so that the memo does not grow with every operation that ever failed.
    pub(super) fn end(&mut self, op: u32, failed: bool, live: impl Fn(u32) -> bool) {
        let bytes: usize = self.current.iter().map(SolveMemo::bytes).sum();
        if failed && !self.current.is_empty() && self.kept_bytes + bytes <= KEPT_BYTES {
            self.kept_bytes += bytes;
            self.by_op.insert(op, std::mem::take(&mut self.current));
        }
        self.recycle();
        if self.by_op.len() > 2 * self.swept.max(SWEEP_FLOOR) {
            self.sweep(&live);
        }
    }

    /// Drops the solves of the operations that `live` says will not be attempted again.
    fn sweep(&mut self, live: &impl Fn(u32) -> bool) {
        self.by_op.retain(|&o, _| live(o));
        self.kept_bytes = self.by_op.values().flatten().map(SolveMemo::bytes).sum();
        self.swept = self.by_op.len();
    }

    /// Drops the memos of the attempt just ended that were not kept.
    fn recycle(&mut self) {
        self.earlier.clear();
        self.current.clear();
    }
}

#[cfg(test)]
mod tests;
