//! The greedy loop of the paper's Algorithm 1: a priority queue of operations by appeal with lazy
//! invalidation (an entry is live only while its version is the operation's current one), ties
//! broken by operation id; after an accepted merge the operations of the merged chart are joined
//! per neighbour, rescored, and failed ones come back with their back-off (paper §4.4).

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::time::Instant;

use super::ops::{EngineOp, OpGeometry, OpState};
use super::state::{Engine, MergedLayout, OrdF64};
use super::{DefragError, MergeOptions, MergeReport, StopReason};
use crate::plugin::{LocalSolver, MergeScorer, Score, Veto};
use crate::topology::{ChartId, OpKind, Topology};

type Queue = BinaryHeap<(OrdF64, Reverse<u32>, u32)>;

/// Runs the merge stage on `t` in place: on return its UV vertices, corners, twins, chart ids and
/// chart caches describe the merged layout.
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
    let mut queue = Queue::new();
    let ts = Instant::now();
    for op in 0..e.ops.len() as u32 {
        e.rescore(op, scorer, &mut queue);
    }
    e.report.timings.scoring_ms += ts.elapsed().as_secs_f64() * 1e3;

    let border_stop = opts.uv_border_target * e.border_len_input;
    e.report.stop = loop {
        if opts.time_limit > 0.0 && start.elapsed().as_secs_f64() >= opts.time_limit {
            break StopReason::TimeLimit;
        }
        if opts.uv_border_target > 0.0 && e.border_len < border_stop {
            break StopReason::BorderTarget;
        }
        let Some((_, Reverse(op), version)) = queue.pop() else {
            break StopReason::QueueEmpty;
        };
        let o = &e.ops[op as usize];
        if o.version != version || o.state != OpState::Queued {
            continue;
        }
        e.report.attempted += 1;
        match e.attempt(op, solver) {
            Ok(g) => {
                e.report.accepted += 1;
                if e.ops[op as usize].failures > 0 {
                    e.report.accepted_after_failure += 1;
                }
                e.ops[op as usize].state = OpState::Done;
                let ts = Instant::now();
                e.after_success(&g, scorer, &mut queue);
                e.report.timings.scoring_ms += ts.elapsed().as_secs_f64() * 1e3;
            }
            Err(r) => {
                e.report.rejected.add(r);
                let o = &mut e.ops[op as usize];
                o.failures += 1;
                o.version += 1;
                o.state = OpState::Failed(r);
            }
        }
    };

    let frozen = e.t.charts.iter().filter(|c| c.frozen).count() as u64;
    let live = (0..e.t.charts.len()).filter(|&c| e.chart_live(ChartId(c as u32))).count() as u64;
    e.report.mergeable_charts_after = live;
    e.report.charts_after = live + frozen;
    e.report.energy_after = if e.energy_den > 0.0 { e.energy_num / e.energy_den } else { 0.0 };
    e.report.uv_border_after = e.border_len;
    e.report.timings.total_ms = start.elapsed().as_secs_f64() * 1e3;
    let layout = e.layout();
    Ok((e.report, layout))
}

impl Engine<'_> {
    /// Scores `op` again in the current layout: queued with a new version, or vetoed.
    fn rescore(&mut self, op: u32, scorer: &dyn MergeScorer, queue: &mut Queue) {
        let features = self.features(op);
        let o = &mut self.ops[op as usize];
        o.version += 1;
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
    fn after_success(&mut self, g: &OpGeometry, scorer: &dyn MergeScorer, queue: &mut Queue) {
        let a = g.a;
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
                    self.ops.push(EngineOp {
                        kind: OpKind::Inter,
                        links,
                        state: OpState::Vetoed(Veto::ZeroArea),
                        failures: 0,
                        version: 0,
                    });
                    list.push(id);
                    self.chart_ops[by_other[i].0.idx()].push(id);
                }
                i = j;
            }
            list.retain(|&op| self.ops[op as usize].is_live());
        }
        for &op in &list {
            match self.ops[op as usize].state {
                OpState::Queued | OpState::Vetoed(_) => self.rescore(op, scorer, queue),
                OpState::Failed(_) if !self.opts.no_retry => self.rescore(op, scorer, queue),
                _ => {}
            }
        }
        // Neighbours of a, through its live inter-chart operations.
        let mut neighbours: Vec<ChartId> = Vec::new();
        for &op in &list {
            if self.ops[op as usize].kind == OpKind::Inter {
                let (x, y) = self.op_charts(op);
                neighbours.push(if x == a { y } else { x });
            }
        }
        self.chart_ops[a.idx()] = list;
        neighbours.sort_unstable();
        neighbours.dedup();
        for c in neighbours {
            for i in 0..self.chart_ops[c.idx()].len() {
                let op = self.chart_ops[c.idx()][i];
                if self.ops[op as usize].state == OpState::Vetoed(Veto::Boundary) {
                    self.rescore(op, scorer, queue);
                }
            }
            self.chart_ops[c.idx()].retain(|&op| {
                // Drop dead entries while passing by, so neighbour lists stay short.
                !matches!(self.ops[op as usize].state, OpState::Dead | OpState::Done)
            });
        }
    }
}
