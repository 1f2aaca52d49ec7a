//! The greedy loop of the paper's Algorithm 1: a priority queue of operations by appeal with lazy
//! invalidation (an entry is live only while its version is the operation's current one), ties
//! broken by operation id; after an accepted merge the operations of the merged chart are joined
//! per neighbour, rescored, and failed ones come back with their back-off (paper §4.4) when the
//! merge wrote near what their refusal read (see `reach`), or in a sweep at the end of the queue.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::time::Instant;

use super::ops::{EngineOp, OpGeometry, OpState};
use super::ord::OrdF64;
use super::reach::WrittenRegion;
use super::span::CriticalPath;
use super::state::{Engine, MergedLayout};
use super::{DefragError, MergeOptions, MergeReport, RejectReason, StopReason};
use crate::plugin::{LocalSolver, MergeScorer, Score, Veto};
use crate::topology::{ChartId, OpKind, Topology};

pub(super) type Queue = BinaryHeap<(OrdF64, Reverse<u32>, u32)>;

/// Stale entries a queue may gather beyond twice its pruned size before it is pruned again.
const PRUNE_SLACK: usize = 4096;

/// Runs the merge stage on `t` in place with a single queue (the serial baseline): on return its
/// UV vertices, corners, twins, chart ids and chart caches describe the merged layout.
pub fn merge_charts(
    t: &mut Topology,
    scorer: &dyn MergeScorer,
    solver: &mut dyn LocalSolver,
    opts: &MergeOptions,
) -> Result<(MergeReport, MergedLayout), DefragError> {
    opts.validate()?;
    let start = Instant::now();
    let mut e = Engine::new(t, opts.clone());
    e.report.timings.init_ms = start.elapsed().as_secs_f64() * 1e3;
    let deadline = opts.deadline(start);
    e.report.stop = e.run_queue(scorer, solver, None, deadline);
    Ok(e.finish(start))
}

impl Engine<'_> {
    /// Whether both charts of `op` are in `scope` (every chart when there is no scope).
    pub(crate) fn in_scope(&self, op: u32, scope: Option<&[bool]>) -> bool {
        scope.is_none_or(|s| {
            let (x, y) = self.op_charts(op);
            s[x.idx()] && s[y.idx()]
        })
    }

    /// The greedy loop over the operations in `scope`: scores the queued and vetoed ones, then
    /// attempts them by appeal until the queue is empty or a stop criterion holds.
    pub(crate) fn run_queue(
        &mut self,
        scorer: &dyn MergeScorer,
        solver: &mut dyn LocalSolver,
        scope: Option<&[bool]>,
        deadline: Option<Instant>,
    ) -> StopReason {
        let mut queue = Queue::new();
        let mut path = CriticalPath::new(self.t.charts.len());
        self.deferring = self.opts.defer;
        let t = Instant::now();
        self.fill_queue(scorer, &mut queue, scope);
        path.book_free(super::ms(t));
        let mut watermark = queue.len();
        let border_stop = self.opts.uv_border_target * self.border_len_input;
        let stop = loop {
            if let Some(stop) = self.stop_now(border_stop, deadline) {
                break stop;
            }
            let Some((_, Reverse(op), version)) = queue.pop() else {
                let t = Instant::now();
                if self.refill(scorer, &mut queue, scope) {
                    path.book_free(super::ms(t));
                    continue;
                }
                break StopReason::QueueEmpty;
            };
            if !self.entry_live(op, version) {
                continue;
            }
            self.report.attempted += 1;
            let charts = self.op_charts(op);
            let t = Instant::now();
            let result = self.attempt(op, solver);
            let judged_ms = super::ms(t);
            let accepted = result.is_ok();
            let t = Instant::now();
            self.settle(op, result, scorer, &mut queue, scope);
            path.book(charts, judged_ms, accepted.then(|| super::ms(t)));
            self.prune_queue(&mut queue, &mut watermark);
        };
        self.book_path(&path);
        stop
    }

    /// Adds a queue's work, span and settling to the report's timings.
    pub(super) fn book_path(&mut self, path: &CriticalPath) {
        let t = &mut self.report.timings;
        t.work_ms += path.work_ms;
        t.span_ms += path.span_ms;
        t.settle_ms += path.settle_ms;
    }

    /// Scores every queued and vetoed operation in `scope` into `queue`.
    pub(super) fn fill_queue(
        &mut self,
        scorer: &dyn MergeScorer,
        queue: &mut Queue,
        scope: Option<&[bool]>,
    ) {
        let ts = Instant::now();
        self.pairing.neighbours.begin(self.t.charts.len());
        for op in 0..self.ops.len() as u32 {
            let live = matches!(self.ops[op as usize].state, OpState::Queued | OpState::Vetoed(_));
            if live && self.in_scope(op, scope) {
                self.rescore(op, scorer, queue, scope);
            }
        }
        self.pairing.neighbours.end();
        self.report.timings.scoring_ms += ts.elapsed().as_secs_f64() * 1e3;
    }

    /// At an empty queue: the deferred operations in `scope` at the end of the first pass (see
    /// [`Self::start_second_pass`]), the parked ones at the end of the last (see
    /// [`Self::sweep_parked`]). `false` when the merge is over. Sweeping at the end of the first
    /// pass as well retried operations that the second pass queues anyway, and the refusals it
    /// added changed their back-off and so the order of the second pass.
    pub(super) fn refill(
        &mut self,
        scorer: &dyn MergeScorer,
        queue: &mut Queue,
        scope: Option<&[bool]>,
    ) -> bool {
        if self.deferring {
            return self.start_second_pass(scorer, queue, scope);
        }
        self.sweep_parked(scorer, queue, scope)
    }

    /// At the end of the queue: scores again every failed operation in `scope` that a commit
    /// into one of its charts has come to since its refusal, none of them near what the refusal
    /// read (see `reach`). Such a commit could still have changed the verdict through what the
    /// read region leaves out, so every merge the queue would once have retried gets one more
    /// attempt before the merge ends. `true` if any went back into the queue.
    fn sweep_parked(
        &mut self,
        scorer: &dyn MergeScorer,
        queue: &mut Queue,
        scope: Option<&[bool]>,
    ) -> bool {
        let before = queue.len();
        let ts = Instant::now();
        self.pairing.neighbours.begin(self.t.charts.len());
        for op in 0..self.ops.len() as u32 {
            let o = &self.ops[op as usize];
            if o.parked && matches!(o.state, OpState::Failed(_)) && self.in_scope(op, scope) {
                self.report.parked_swept += 1;
                self.rescore(op, scorer, queue, scope);
            }
        }
        self.pairing.neighbours.end();
        self.report.timings.scoring_ms += ts.elapsed().as_secs_f64() * 1e3;
        queue.len() > before
    }

    /// At an empty queue: ends the first pass, if the queue was deferring, by queueing the
    /// deferred operations in `scope` again (see `MergeOptions::defer`). `false` when the merge
    /// is over.
    pub(super) fn start_second_pass(
        &mut self,
        scorer: &dyn MergeScorer,
        queue: &mut Queue,
        scope: Option<&[bool]>,
    ) -> bool {
        if !self.deferring {
            return false;
        }
        self.deferring = false;
        let ts = Instant::now();
        self.pairing.neighbours.begin(self.t.charts.len());
        for op in 0..self.ops.len() as u32 {
            if self.ops[op as usize].state == OpState::Failed(RejectReason::Deferred) {
                self.rescore(op, scorer, queue, scope);
            }
        }
        self.pairing.neighbours.end();
        self.report.timings.scoring_ms += ts.elapsed().as_secs_f64() * 1e3;
        true
    }

    /// The stop criterion that holds before the next pop, if any.
    pub(super) fn stop_now(
        &self,
        border_stop: f64,
        deadline: Option<Instant>,
    ) -> Option<StopReason> {
        // A requested stop (a signal) ends the queue like the time limit; the pipeline then
        // gives up the run at its next safe point.
        if deadline.is_some_and(|d| Instant::now() >= d) || crate::cancel::requested() {
            return Some(StopReason::TimeLimit);
        }
        if self.opts.uv_border_target > 0.0 && self.border_len < border_stop {
            return Some(StopReason::BorderTarget);
        }
        None
    }

    /// Drops the stale entries of `queue` once it has grown to more than twice its size after the
    /// last pruning (`watermark`), plus some slack. Every rescoring pushes a new entry and leaves
    /// the old one in the heap; around a chart with hundreds of neighbours that grows with every
    /// merge, and popping a heap of stale entries took a fifth of the serial merge of a 1M-face
    /// synthetic scan. The pop order does not change: entries are distinct (versions only grow),
    /// so a binary heap pops them in the same order whatever its inner arrangement.
    pub(super) fn prune_queue(&self, queue: &mut Queue, watermark: &mut usize) {
        if queue.len() > 2 * *watermark + PRUNE_SLACK {
            queue.retain(|&(_, Reverse(op), version)| self.entry_live(op, version));
            *watermark = queue.len();
        }
    }

    /// Whether a queue entry is the current version of a queued operation (else it is stale, and
    /// stays stale: versions only grow).
    pub(super) fn entry_live(&self, op: u32, version: u32) -> bool {
        let o = &self.ops[op as usize];
        o.version == version && o.state == OpState::Queued
    }

    /// Books the outcome of an attempt of `op`: the operation's state and the counts, and after
    /// a success the rescoring around the merged chart.
    pub(super) fn settle(
        &mut self,
        op: u32,
        result: Result<OpGeometry, super::RejectReason>,
        scorer: &dyn MergeScorer,
        queue: &mut Queue,
        scope: Option<&[bool]>,
    ) {
        if self.ops[op as usize].failures > 0 {
            self.report.retried += 1;
        }
        match result {
            Ok(g) => {
                self.report.accepted += 1;
                if self.ops[op as usize].failures > 0 {
                    self.report.accepted_after_failure += 1;
                }
                self.ops[op as usize].state = OpState::Done;
                let ts = Instant::now();
                self.after_success(&g, scorer, queue, scope);
                self.report.timings.scoring_ms += ts.elapsed().as_secs_f64() * 1e3;
            }
            Err(r) => {
                self.report.rejected.add(r);
                let read = self.trial.read.take();
                let o = &mut self.ops[op as usize];
                o.read = read;
                o.failures += 1;
                o.version += 1;
                o.state = OpState::Failed(r);
            }
        }
    }

    /// The final counts of the report and the layout for packing.
    pub(crate) fn finish(mut self, start: Instant) -> (MergeReport, MergedLayout) {
        self.report.zero_area = self.join_zero_area_charts();
        self.report.unfold = self.unfold_folded_charts();
        let frozen = self.t.charts.iter().filter(|c| c.frozen).count() as u64;
        let live =
            (0..self.t.charts.len()).filter(|&c| self.chart_live(ChartId(c as u32))).count() as u64;
        self.report.mergeable_charts_after = live;
        self.report.charts_after = live + frozen;
        self.report.energy_after =
            if self.energy_den > 0.0 { self.energy_num / self.energy_den } else { 0.0 };
        self.report.uv_border_after = self.border_len;
        self.report.timings.total_ms = start.elapsed().as_secs_f64() * 1e3;
        let layout = self.layout();
        (self.report, layout)
    }
}

impl Engine<'_> {
    /// Whether the commit that wrote `written` can change the verdict of the failed operation
    /// `op`: always, unless its refusal read only a region near its seams (see `reach`) and the
    /// commit wrote away from it. Counted in the report either way.
    fn commit_reaches(&mut self, op: u32, written: Option<&WrittenRegion>) -> bool {
        let reached = match (self.ops[op as usize].read, written) {
            (Some(read), Some(w)) => read.reached_by(w, self.stay_and_move(op)),
            _ => true,
        };
        if reached {
            self.report.retries_queued += 1;
        } else {
            self.report.retries_parked += 1;
        }
        reached
    }

    /// Scores `op` again in the current layout: queued with a new version, or vetoed.
    fn rescore(
        &mut self,
        op: u32,
        scorer: &dyn MergeScorer,
        queue: &mut Queue,
        scope: Option<&[bool]>,
    ) {
        // Operations reaching out of a cluster wait for the round that holds both charts.
        if !self.in_scope(op, scope) {
            return;
        }
        let features = self.features(op);
        let o = &mut self.ops[op as usize];
        o.version += 1;
        o.parked = false;
        o.island = features.island_lookahead;
        match scorer.score(&features) {
            Score::Appeal(x) => {
                o.state = OpState::Queued;
                let x = if x.is_finite() && x >= 0.0 { x } else { 0.0 };
                queue.push((OrdF64(x), Reverse(op), o.version));
            }
            Score::Veto(v) => {
                o.state = OpState::Vetoed(v);
                self.report.vetoes.add(v);
            }
        }
    }

    /// After an accepted merge of b into a (or an intra-chart merge of a): gather a's operations,
    /// join the two operations towards each shared neighbour into one (all seams between two
    /// charts go together), rescore everything on a, bring failed operations back (unless
    /// `no_retry`), and rescore the boundary-vetoed operations of a's neighbours, whose small-island
    /// look-ahead may now pass.
    fn after_success(
        &mut self,
        g: &OpGeometry,
        scorer: &dyn MergeScorer,
        queue: &mut Queue,
        scope: Option<&[bool]>,
    ) {
        let a = g.a;
        let written = self.trial.written.take();
        let mut list = std::mem::take(&mut self.chart_ops[a.idx()]);
        if g.inter {
            list.append(&mut std::mem::take(&mut self.chart_ops[g.b.idx()]));
        }
        list.retain(|&op| self.ops[op as usize].is_live());
        list.sort_unstable();
        list.dedup();

        if g.inter {
            let mut by_other: Vec<(ChartId, u32)> = Vec::new();
            for &op in &list {
                if self.ops[op as usize].kind != OpKind::Inter {
                    continue;
                }
                let (x, y) = self.op_charts(op);
                if x == y {
                    // Cannot happen (the accepted operation took every seam between a and b),
                    // but an inter operation inside one chart must not linger.
                    self.ops[op as usize].state = OpState::Dead;
                    continue;
                }
                by_other.push((if x == a { y } else { x }, op));
            }
            by_other.sort_unstable();
            let mut i = 0;
            while i < by_other.len() {
                let mut j = i + 1;
                while j < by_other.len() && by_other[j].0 == by_other[i].0 {
                    j += 1;
                }
                if j - i > 1 {
                    let mut links = Vec::new();
                    for &(_, op) in &by_other[i..j] {
                        links.extend_from_slice(&self.ops[op as usize].links);
                        self.ops[op as usize].state = OpState::Dead;
                    }
                    let id = self.ops.len() as u32;
                    let vetoed = OpState::Vetoed(Veto::ZeroArea);
                    self.ops.push(EngineOp::new(self.t, OpKind::Inter, links, vetoed));
                    list.push(id);
                    self.chart_ops[by_other[i].0.idx()].push(id);
                }
                i = j;
            }
            list.retain(|&op| self.ops[op as usize].is_live());
        }
        // a's list goes back before any rescoring: the small-island look-ahead of a's operations
        // reads a's neighbours from it. Taken, it left a without neighbours, so the look-ahead
        // passed for every operation of a towards a chart with at most five neighbours, and the
        // boundary filter never vetoed those.
        self.chart_ops[a.idx()] = list;
        // From here on operations only change between live states: the chart graph stands still
        // until the next commit (see `NeighbourMemo`).
        self.pairing.neighbours.begin(self.t.charts.len());
        for i in 0..self.chart_ops[a.idx()].len() {
            let op = self.chart_ops[a.idx()][i];
            match self.ops[op as usize].state {
                OpState::Queued | OpState::Vetoed(_) => self.rescore(op, scorer, queue, scope),
                OpState::Failed(_) if !self.opts.no_retry => {
                    if self.commit_reaches(op, written.as_ref()) {
                        self.rescore(op, scorer, queue, scope);
                    } else {
                        // The retry the commit would have brought would build the same problem
                        // and be refused again: its back-off counts it, as if it had run, so
                        // that the operation keeps the place in the queue it would have had.
                        let o = &mut self.ops[op as usize];
                        if !o.parked {
                            o.failures += 1;
                        }
                        o.parked = true;
                    }
                }
                _ => {}
            }
        }
        // Neighbours of a, through its live inter-chart operations.
        let mut neighbours: Vec<ChartId> = Vec::new();
        for &op in &self.chart_ops[a.idx()] {
            if self.ops[op as usize].kind == OpKind::Inter {
                let (x, y) = self.op_charts(op);
                neighbours.push(if x == a { y } else { x });
            }
        }
        neighbours.sort_unstable();
        neighbours.dedup();
        for c in neighbours {
            for i in 0..self.chart_ops[c.idx()].len() {
                let op = self.chart_ops[c.idx()][i];
                if self.ops[op as usize].state != OpState::Vetoed(Veto::Boundary) {
                    continue;
                }
                // An operation of a was scored just above. One between two other charts has the
                // very features it had when it was vetoed (neither chart changed), except for the
                // look-ahead; scores are functions of the features, so unless the look-ahead
                // changed, rescoring it would only repeat the veto.
                let (x, y) = self.stay_and_move(op);
                if x == a || y == a {
                    continue;
                }
                let island = x != y && self.island_lookahead(x, y);
                if island != self.ops[op as usize].island {
                    self.rescore(op, scorer, queue, scope);
                }
            }
            self.chart_ops[c.idx()].retain(|&op| {
                // Drop dead entries while passing by, so neighbour lists stay short.
                !matches!(self.ops[op as usize].state, OpState::Dead | OpState::Done)
            });
        }
        self.pairing.neighbours.end();
    }
}
