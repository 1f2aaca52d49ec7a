//! Speculative attempts on a queue that holds the whole atlas (the default merge, and the last
//! round of the clusters): shadow engines (replicas of the master, each on its own copy of the
//! topology, one per worker thread beyond the first) judge operations that are further down the
//! queue while the master attempts the one at the top, and the master takes a judgement over
//! when it reaches that operation, if nothing the judgement read has changed since. The master
//! still settles every operation in queue order, so the result is the serial one whatever the
//! timing and however many shadows there are.
//!
//! What an attempt reads: the faces, UV vertices, half-edges and caches of its two charts (the
//! grid only for faces of those charts, and only as a set: every candidate is tested against its
//! current triangle), its operation's links, and the atlas-wide energy sum for the budget check.
//! A commit writes only the faces, vertices and half-edges of the two charts it merges. So a
//! judgement made after the master's first `at` commits still holds after more of them if none of
//! the later commits touched either of its charts, and every budget check along its way comes out
//! the same with the master's energy sum as with the one it was judged against.
//!
//! Each shadow keeps up by replaying each of the master's commits from a record of the slots it
//! wrote (`Engine::apply_record`), in the master's order, so its state after `at` replays is the
//! master's after `at` commits, bit for bit.
//!
//! A shadow judges its requests most urgent first (by queue key, so the one the master reaches
//! soonest goes first, whatever order they were asked in), after replaying every commit sent
//! before it, and drops unjudged a request that a commit since has touched (its judgement could
//! never be taken). First come, first served left the master waiting for the top operation behind
//! requests further down, and spent the shadow on judgements already overturned; by key the merge
//! is a little faster. Requests go to the shadow with the fewest pending.
//!
//! How far this can go on many cores: `span` measures the queue's work and its span from the
//! charts each judgement reads and each commit writes; their ratio bounds the speed-up.

use std::cmp::Reverse;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

use super::commit::CommitRecord;
use super::greedy::Queue;
use super::ops::EngineOp;
use super::ord::OrdF64;
use super::reach::ReadRegion;
use super::span::CriticalPath;
use super::state::{Engine, Parts};
use super::{MergeReport, RejectReason, StopReason};
use crate::plugin::{LocalSolver, MergeScorer};
use crate::topology::{ChartId, Topology};
use rayon::prelude::*;

/// Judgements each shadow may have queued or in progress at once. With fewer a shadow idles
/// while the master attempts an operation itself; with more, the master waits longer for the
/// one at the top. Four was the fastest of the caps tried on the shared models (see
/// `benches/results/moved-comments.md`); larger caps cut the shadow's idle time but made the
/// master wait longer, and the merge was no faster.
const MAX_IN_FLIGHT: usize = 4;

/// Judgements each shadow may have pending while the master attempts the top operation itself
/// (nobody could judge it ahead: a commit just changed one of its charts). The master is then
/// away for a whole attempt, and with `MAX_IN_FLIGHT` the shadow ran out of work. Raising the
/// cap only for that time keeps the short wait for the top operation that the smaller cap gives
/// everywhere else; the gain measured is small, near the noise.
const OWN_ATTEMPT_IN_FLIGHT: usize = 8;

/// The most shadow engines a queue runs with, whatever the thread count. Each holds a copy of the
/// topology and the engine state (a few hundred bytes per face), and the speed-up is bounded by
/// the queue's work over its span (see `span`), which the shared models keep to a few dozen: more
/// shadows would cost memory for judgements that wait on the same chains.
pub(super) const MAX_SHADOWS: usize = 15;

/// Queue entries looked at, from the top, for an operation the shadow may judge. Looking further
/// finds independent operations while the top of the queue is all of one large chart's, at the
/// cost of heap pops and pushes on the master. A few dozen entries measured best: much deeper
/// looks cost the master more than they found, and more judgements in flight were slower at
/// every depth because the master waits longer for the top one.
const LOOK_AHEAD: usize = 64;

/// The queue key of an entry (see `greedy::Queue`): the larger, the sooner the master settles it.
type Key = (OrdF64, Reverse<u32>, u32);

/// What the master sends the shadow, in order.
enum ToShadow {
    /// A commit of the master, to replay (one record shared by every shadow).
    Replay(Arc<CommitRecord>),
    /// An operation to judge (its table entry as the master has it, its queue key, its charts,
    /// and the master's commit count when it was asked for).
    Judge(Box<Request>),
    /// A request the master settles itself after all (see `Pending::forget`): judging it now
    /// would be work thrown away.
    Forget { op: u32, version: u32 },
}

/// An operation the shadow is asked to judge.
struct Request {
    op: u32,
    version: u32,
    entry: EngineOp,
    key: Key,
    charts: (ChartId, ChartId),
    at: usize,
    /// Whether the master's queue was in its first pass (see `MergeOptions::defer`).
    deferring: bool,
}

/// What the shadow sends back: a judgement, or word that a request was dropped unjudged because
/// a commit made since it was asked for touched one of its charts (its judgement could never be
/// taken).
enum FromShadow {
    Judged(Box<Judged>),
    Dropped { op: u32, version: u32 },
}

/// A judgement of the shadow.
struct Judged {
    op: u32,
    version: u32,
    /// Master commits replayed before judging.
    at: usize,
    charts: (ChartId, ChartId),
    /// The atlas energy sum it was judged against, and the (out, in) energies of every budget
    /// check on its way.
    energy_num: f64,
    checks: Vec<(f64, f64)>,
    outcome: Result<CommitRecord, RejectReason>,
    /// What a refused attempt read (see `reach`).
    read: Option<ReadRegion>,
    /// The counts and times of the attempt (no commit in them), and how long it took.
    report: MergeReport,
    ms: f64,
}

/// A judgement asked for and not yet received.
struct InFlight {
    op: u32,
    version: u32,
    at: usize,
    charts: (ChartId, ChartId),
    /// The shadow asked.
    shadow: usize,
}

/// What a shadow's `started` flag holds while it judges `op` at `version`; `NOT_STARTED` between
/// judgements (no operation has both an id and a version of `u32::MAX`).
fn started_key(op: u32, version: u32) -> u64 {
    (u64::from(op) << 32) | u64::from(version)
}

const NOT_STARTED: u64 = u64::MAX;

/// Whether charts `c` are untouched by the commits in `commits`.
fn untouched(c: (ChartId, ChartId), commits: &[(ChartId, ChartId)]) -> bool {
    commits.iter().all(|&(a, b)| a != c.0 && a != c.1 && b != c.0 && b != c.1)
}

/// Whether two pairs of charts share a chart.
fn share(x: (ChartId, ChartId), y: (ChartId, ChartId)) -> bool {
    x.0 == y.0 || x.0 == y.1 || x.1 == y.0 || x.1 == y.1
}

impl Engine<'_> {
    /// The greedy loop over the whole atlas (no scope) with one shadow engine per solver of
    /// `shadow_solvers` judging ahead: the same result as `run_queue`, in less time on more cores.
    pub(crate) fn run_queue_speculative(
        &mut self,
        scorer: &dyn MergeScorer,
        solver: &mut dyn LocalSolver,
        shadow_solvers: &mut [Box<dyn LocalSolver>],
        deadline: Option<Instant>,
    ) -> StopReason {
        // The copies are made on workers of the pool, whose allocator arenas hold what the
        // cluster forks of the earlier rounds freed: made on this thread they would come on top
        // of it and raise the peak memory. The topology and the engine's state are copied side
        // by side, and each shadow assembles its engine itself, so that the master waits for
        // neither longer than it must.
        let this = &*self;
        let copies: Vec<(Topology, Parts)> = (0..shadow_solvers.len())
            .into_par_iter()
            .map(|_| rayon::join(|| this.t.clone(), || this.parts()))
            .collect();
        let (shadow_tx, from_shadow) = channel::<FromShadow>();
        std::thread::scope(|s| {
            let mut to_shadows = Vec::with_capacity(copies.len());
            let started: Vec<Arc<AtomicU64>> =
                (0..copies.len()).map(|_| Arc::new(AtomicU64::new(NOT_STARTED))).collect();
            for (i, ((mut topo, parts), shadow_solver)) in
                copies.into_iter().zip(shadow_solvers.iter_mut()).enumerate()
            {
                let (to_shadow, shadow_rx) = channel::<ToShadow>();
                let (opts, tx) = (self.opts.clone(), shadow_tx.clone());
                let flag = Arc::clone(&started[i]);
                let shadow_loop = move || {
                    let mut shadow = Engine::assemble(&mut topo, opts, parts);
                    shadow_loop(&mut shadow, &mut **shadow_solver, shadow_rx, tx, &flag);
                };
                // Named for profilers; a thread that cannot be spawned drops its receiver, so
                // the master never asks it again and keeps the serial result.
                let spawned = std::thread::Builder::new()
                    .name(format!("scanatlas-shadow-{i}"))
                    .spawn_scoped(s, shadow_loop);
                to_shadows.push(spawned.is_ok().then_some(to_shadow));
            }
            // Only the shadows hold senders now: once they are all gone, waiting for a
            // judgement ends instead of hanging.
            drop(shadow_tx);
            // Dropping the senders on return ends the shadows' loops.
            let links = Links { to_shadows, started };
            self.speculative_loop(scorer, solver, links, &from_shadow, deadline)
        })
    }

    fn speculative_loop(
        &mut self,
        scorer: &dyn MergeScorer,
        solver: &mut dyn LocalSolver,
        links: Links,
        from_shadow: &Receiver<FromShadow>,
        deadline: Option<Instant>,
    ) -> StopReason {
        let mut queue = Queue::new();
        let mut path = CriticalPath::new(self.t.charts.len());
        self.deferring = self.opts.defer;
        let t = Instant::now();
        self.fill_queue(scorer, &mut queue, None);
        path.book_free(super::ms(t));
        let mut watermark = queue.len();
        let border_stop = self.opts.uv_border_target * self.border_len_input;
        let mut s = Pending {
            commits: Vec::new(),
            in_flight: Vec::new(),
            done: Vec::new(),
            links,
            judged: 0,
        };
        let stop = loop {
            if let Some(stop) = self.stop_now(border_stop, deadline) {
                break stop;
            }
            let Some((_, Reverse(op), version)) = queue.pop() else {
                // Every request was for an operation queued before: none is judged under the
                // wrong pass (the second pass queues new versions only).
                let t = Instant::now();
                if self.refill(scorer, &mut queue, None) {
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
            while let Ok(j) = from_shadow.try_recv() {
                s.receive(j);
            }
            // Judgements of operations settled or rescored since can never be taken.
            s.done.retain(|j| self.entry_live(j.op, j.version));
            self.dispatch(&mut queue, charts, &mut s);
            let judged =
                self.judgement(op, version, charts, &mut queue, &mut s, solver, from_shadow);
            // The settling (a taken judgement's commit and the rescoring) is timed from here.
            let settle_start;
            let (result, record, judged_ms) = match judged {
                Some(j) => {
                    self.report.absorb(&j.report);
                    self.report.timings.judgements_taken += 1;
                    settle_start = Instant::now();
                    match j.outcome {
                        Ok(r) => (Ok(self.apply_record(&r)), Some(r), j.ms),
                        Err(e) => {
                            self.trial.read = j.read;
                            (Err(e), None, j.ms)
                        }
                    }
                }
                None => {
                    s.forget(op, version);
                    // The master is away for a whole attempt: give the shadow enough to judge
                    // meanwhile (see `OWN_ATTEMPT_IN_FLIGHT`).
                    self.dispatch_up_to(&mut queue, charts, &mut s, OWN_ATTEMPT_IN_FLIGHT);
                    let t = Instant::now();
                    let (result, record) = self.attempt_recorded(op, solver);
                    settle_start = Instant::now();
                    (result, record, super::ms(t))
                }
            };
            let accepted = result.is_ok();
            if let Some(r) = record {
                let c = (r.g.a, r.g.b);
                s.commits.push(c);
                s.done.retain(|j| !share(j.charts, c));
                s.replay(Arc::new(r));
            }
            self.settle(op, result, scorer, &mut queue, None);
            path.book(charts, judged_ms, accepted.then(|| super::ms(settle_start)));
            self.prune_queue(&mut queue, &mut watermark);
        };
        self.report.timings.judged_ahead += s.judged;
        self.book_path(&path);
        stop
    }

    /// The first live operation below the top of the queue, within `LOOK_AHEAD` entries, that is
    /// not judged or pending already and whose charts are apart from `charts` (the operation
    /// being settled) and from those of every pending judgement.
    fn pick(
        &self,
        queue: &mut Queue,
        charts: (ChartId, ChartId),
        s: &Pending,
    ) -> Option<(Key, (ChartId, ChartId))> {
        let look_ahead = LOOK_AHEAD * s.links.to_shadows.len().max(1);
        let mut looked = Vec::with_capacity(look_ahead);
        let mut found = None;
        while looked.len() < look_ahead {
            let Some(entry) = queue.pop() else { break };
            let (_, Reverse(op), version) = entry;
            // Stale entries would only be skipped when popped: they need not go back.
            if !self.entry_live(op, version) {
                continue;
            }
            looked.push(entry);
            let c = self.op_charts(op);
            let known = s.done.iter().any(|j| (j.op, j.version) == (op, version))
                || s.in_flight.iter().any(|f| (f.op, f.version) == (op, version));
            if !known && !share(c, charts) && !s.in_flight.iter().any(|f| share(f.charts, c)) {
                found = Some((entry, c));
                break;
            }
        }
        // Every entry is distinct (versions only grow), so the heap pops the same order whatever
        // its inner arrangement: putting them back changes nothing.
        queue.extend(looked);
        found
    }

    /// Asks the shadows to judge operations from `pick` until each has `MAX_IN_FLIGHT` pending.
    fn dispatch(&self, queue: &mut Queue, charts: (ChartId, ChartId), s: &mut Pending) {
        self.dispatch_up_to(queue, charts, s, MAX_IN_FLIGHT);
    }

    /// Asks the shadows to judge operations from `pick` until each has `cap` pending: each
    /// request goes to the live shadow with the fewest pending (which shadow judges what never
    /// changes the result, only how soon a judgement comes).
    fn dispatch_up_to(
        &self,
        queue: &mut Queue,
        charts: (ChartId, ChartId),
        s: &mut Pending,
        cap: usize,
    ) {
        while let Some(shadow) = s.least_busy(cap) {
            let Some((key, c)) = self.pick(queue, charts, s) else { return };
            let (_, Reverse(op), version) = key;
            let at = s.commits.len();
            let entry = self.ops[op as usize].clone();
            let deferring = self.deferring;
            let request = Request { op, version, entry, key, charts: c, at, deferring };
            let sent = s.links.to_shadows[shadow]
                .as_ref()
                .is_some_and(|tx| tx.send(ToShadow::Judge(Box::new(request))).is_ok());
            if sent {
                s.in_flight.push(InFlight { op, version, at, charts: c, shadow });
            } else {
                s.links.to_shadows[shadow] = None;
            }
        }
    }

    /// A judgement of `op` at `version` that still holds, if there is one. While the shadow's
    /// judgement of it is pending and nothing has overturned it yet, the master judges other
    /// operations from `pick` itself rather than wait idle.
    #[allow(clippy::too_many_arguments)]
    fn judgement(
        &mut self,
        op: u32,
        version: u32,
        charts: (ChartId, ChartId),
        queue: &mut Queue,
        s: &mut Pending,
        solver: &mut dyn LocalSolver,
        from_shadow: &Receiver<FromShadow>,
    ) -> Option<Judged> {
        loop {
            if let Some(i) = s.done.iter().position(|j| (j.op, j.version) == (op, version)) {
                let j = s.done.swap_remove(i);
                let holds = untouched(j.charts, &s.commits[j.at..])
                    && j.checks.iter().all(|&(out, inn)| {
                        self.over_budget(j.energy_num, out, inn)
                            == self.over_budget(self.energy_num, out, inn)
                    });
                return holds.then_some(j);
            }
            let f = s.in_flight.iter().find(|f| (f.op, f.version) == (op, version))?;
            // A request its shadow has not started yet may wait behind a whole judgement of
            // another operation: the master, which has to settle this one next, judges it
            // itself rather than wait that long.
            if !untouched(f.charts, &s.commits[f.at..])
                || s.links.started[f.shadow].load(Ordering::Acquire) != started_key(op, version)
            {
                return None;
            }
            if let Ok(j) = from_shadow.try_recv() {
                s.receive(j);
                self.dispatch(queue, charts, s);
                continue;
            }
            if let Some(((_, Reverse(other), v), c)) = self.pick(queue, charts, s) {
                let j = self.judge(other, v, c, s.commits.len(), solver);
                s.judged += 1;
                s.done.push(j);
                continue;
            }
            let t = Instant::now();
            let received = from_shadow.recv();
            self.report.timings.wait_ms += t.elapsed().as_secs_f64() * 1e3;
            match received {
                Ok(j) => s.receive(j),
                Err(_) => return None,
            }
        }
    }

    /// Judges `op` on this engine without keeping it.
    fn judge(
        &mut self,
        op: u32,
        version: u32,
        charts: (ChartId, ChartId),
        at: usize,
        solver: &mut dyn LocalSolver,
    ) -> Judged {
        let report = std::mem::take(&mut self.report);
        self.checks.record_checks = true;
        self.checks.global_checks.clear();
        let energy_num = self.energy_num;
        let t = Instant::now();
        let outcome = self.attempt_speculative(op, solver);
        let ms = super::ms(t);
        self.checks.record_checks = false;
        Judged {
            op,
            version,
            at,
            charts,
            energy_num,
            checks: std::mem::take(&mut self.checks.global_checks),
            outcome,
            read: self.trial.read.take(),
            report: std::mem::replace(&mut self.report, report),
            ms,
        }
    }
}

/// The master's ends of its links to the shadows.
struct Links {
    /// One sender per shadow, `None` once that shadow is gone.
    to_shadows: Vec<Option<Sender<ToShadow>>>,
    /// Per shadow, the judgement it is making (see `started_key`).
    started: Vec<Arc<AtomicU64>>,
}

/// The master's bookkeeping of the judgements.
struct Pending {
    /// The charts of every commit so far, in order (the shadow has replayed a prefix).
    commits: Vec<(ChartId, ChartId)>,
    in_flight: Vec<InFlight>,
    done: Vec<Judged>,
    links: Links,
    /// Judgements made ahead so far.
    judged: u64,
}

impl Pending {
    /// The live shadow with the fewest judgements pending, if it has fewer than `cap` (the
    /// first such shadow on a tie).
    fn least_busy(&self, cap: usize) -> Option<usize> {
        (0..self.links.to_shadows.len())
            .filter(|&i| self.links.to_shadows[i].is_some())
            .map(|i| (self.in_flight.iter().filter(|f| f.shadow == i).count(), i))
            .min()
            .filter(|&(pending, _)| pending < cap)
            .map(|(_, i)| i)
    }

    /// Sends a commit to every live shadow to replay.
    fn replay(&mut self, record: Arc<CommitRecord>) {
        for slot in &mut self.links.to_shadows {
            if let Some(tx) = slot
                && tx.send(ToShadow::Replay(Arc::clone(&record))).is_err()
            {
                *slot = None;
            }
        }
    }

    /// Withdraws the request for `op` at `version`, if one is pending: the master attempts it
    /// itself. Its shadow would otherwise judge it next (it is the most urgent request there),
    /// alongside the master's own attempt, and throw the judgement away. A shadow that has
    /// already started it sends its judgement back anyway, which is then never taken.
    fn forget(&mut self, op: u32, version: u32) {
        let Some(i) = self.in_flight.iter().position(|f| (f.op, f.version) == (op, version)) else {
            return;
        };
        let f = self.in_flight.swap_remove(i);
        if let Some(tx) = &self.links.to_shadows[f.shadow]
            && tx.send(ToShadow::Forget { op, version }).is_err()
        {
            self.links.to_shadows[f.shadow] = None;
        }
    }

    fn receive(&mut self, msg: FromShadow) {
        match msg {
            FromShadow::Judged(j) => {
                self.judged += 1;
                self.in_flight.retain(|f| (f.op, f.version) != (j.op, j.version));
                self.done.push(*j);
            }
            FromShadow::Dropped { op, version } => {
                self.in_flight.retain(|f| (f.op, f.version) != (op, version));
            }
        }
    }
}

/// The shadow's side: replays the master's commits in order and judges what it is asked to,
/// the most urgent request first (the one the master will settle soonest, by queue key), after
/// every commit sent before it. A request that a commit made since it was asked for has touched
/// could never be taken: it is dropped unjudged, and the master told.
fn shadow_loop(
    shadow: &mut Engine<'_>,
    solver: &mut dyn LocalSolver,
    rx: Receiver<ToShadow>,
    tx: Sender<FromShadow>,
    started: &AtomicU64,
) {
    // The charts of every commit replayed so far, in order.
    let mut commits: Vec<(ChartId, ChartId)> = Vec::new();
    let mut pending: Vec<Request> = Vec::new();
    let mut open = true;
    loop {
        // Wait only when there is nothing to judge; then take everything that has arrived, so
        // the choice below sees every request and every commit sent so far.
        if pending.is_empty() {
            match rx.recv() {
                Ok(msg) => take(shadow, &mut commits, &mut pending, msg),
                Err(_) => return,
            }
        }
        while open {
            match rx.try_recv() {
                Ok(msg) => take(shadow, &mut commits, &mut pending, msg),
                Err(std::sync::mpsc::TryRecvError::Empty) => break,
                Err(std::sync::mpsc::TryRecvError::Disconnected) => open = false,
            }
        }
        if !open {
            // The master is done: nothing judged now could be taken.
            return;
        }
        let mut dropped = Vec::new();
        pending.retain(|r| {
            let live = untouched(r.charts, &commits[r.at.min(commits.len())..]);
            if !live {
                dropped.push((r.op, r.version));
            }
            live
        });
        for (op, version) in dropped {
            if tx.send(FromShadow::Dropped { op, version }).is_err() {
                return;
            }
        }
        let Some(i) = (0..pending.len()).max_by_key(|&i| pending[i].key) else { continue };
        let Request { op, version, entry, deferring, .. } = pending.swap_remove(i);
        shadow.deferring = deferring;
        let o = op as usize;
        if shadow.ops.len() <= o {
            shadow.ops.resize(o + 1, entry.clone());
        }
        shadow.ops[o] = entry;
        let charts = shadow.op_charts(op);
        started.store(started_key(op, version), Ordering::Release);
        let judged = shadow.judge(op, version, charts, commits.len(), solver);
        started.store(NOT_STARTED, Ordering::Release);
        if tx.send(FromShadow::Judged(Box::new(judged))).is_err() {
            return;
        }
    }
}

/// Takes one message of the master: a commit is replayed at once, a request is kept.
fn take(
    shadow: &mut Engine<'_>,
    commits: &mut Vec<(ChartId, ChartId)>,
    pending: &mut Vec<Request>,
    msg: ToShadow,
) {
    match msg {
        ToShadow::Replay(r) => {
            shadow.apply_record(&r);
            commits.push((r.g.a, r.g.b));
        }
        ToShadow::Judge(r) => pending.push(*r),
        ToShadow::Forget { op, version } => pending.retain(|r| (r.op, r.version) != (op, version)),
    }
}
