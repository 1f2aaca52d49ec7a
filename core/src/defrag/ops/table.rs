//! The operation table of the greedy loop: each operation's linked pairs, where it stands, its
//! failures and its cached seam geometry. Plain data, below the engine state that holds it.

use super::super::RejectReason;
use super::super::reach::ReadRegion;
use crate::plugin::Veto;
use crate::topology::{ChartId, LinkId, OpKind, Topology};

/// Where an operation stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OpState {
    /// In the queue with its current appeal.
    Queued,
    /// Refused by the scorer; rescored when one of its charts changes.
    Vetoed(Veto),
    /// Attempted and rolled back; back in the queue only after a commit into one of its charts
    /// that can change the verdict (see `reach`), or in the sweep at the end of the queue.
    Failed(RejectReason),
    /// Accepted.
    Done,
    /// Replaced by an operation that joins its links with those of another (shared neighbour).
    Dead,
}

/// An operation of the greedy loop: the linked pairs it dissolves, all at once.
#[derive(Clone, Debug)]
pub(crate) struct EngineOp {
    pub kind: OpKind,
    pub links: Vec<LinkId>,
    /// The faces on the two sides of its first link, whose charts are the operation's (see
    /// `Engine::op_charts`): the settling after each commit asks for the charts of every operation
    /// of the merged chart and its neighbours, and going through the link table for each cost a
    /// chain of cache misses.
    pub sides: [u32; 2],
    pub state: OpState,
    /// How many times it was attempted and rolled back (the back-off exponent k).
    pub failures: u32,
    /// Bumped on every rescore; queue entries of older versions are stale.
    pub version: u32,
    /// The small-island look-ahead its last score saw (see `Engine::after_success`).
    pub island: bool,
    /// Its seam geometry as last computed for scoring (see `Engine::features`).
    pub geom: Option<CachedGeometry>,
    /// What its last refused attempt read, when the refusal depends only on that (see `reach`).
    pub read: Option<ReadRegion>,
    /// Failed, and a commit into one of its charts has come since, none of them near what its
    /// refusal read: it waits for one that is, or for the sweep at the end of the queue.
    pub parked: bool,
}

/// The part of an operation's geometry that rigid motions of either chart leave unchanged: the
/// dissolved length on each side, the mean alignment error and the number of vertex pairs. It
/// holds while the operation joins the same two charts and no vertex on its seams has changed
/// other than rigidly since `at` (a value of `Engine::commits`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct CachedGeometry {
    pub(super) charts: (ChartId, ChartId),
    pub(super) len: [f64; 2],
    pub(super) error: f64,
    pub(super) pairs: u32,
    pub(super) at: u32,
}

impl EngineOp {
    /// A new operation dissolving `links` (at least one) of `t`, in `state` (vetoed until its first
    /// scoring, for a new one).
    pub fn new(t: &Topology, kind: OpKind, links: Vec<LinkId>, state: OpState) -> Self {
        let [h0, h1] = t.links[links[0].idx()].sides;
        Self {
            kind,
            links,
            sides: [h0.face() as u32, h1.face() as u32],
            state,
            failures: 0,
            version: 0,
            island: false,
            geom: None,
            read: None,
            parked: false,
        }
    }

    pub fn is_live(&self) -> bool {
        !matches!(self.state, OpState::Done | OpState::Dead)
    }
}

/// The initial operation table: one engine operation per prepared operation, in id order.
pub(crate) fn initial_ops(t: &Topology) -> (Vec<EngineOp>, Vec<Vec<u32>>) {
    let mut ops = Vec::with_capacity(t.ops.len());
    let mut chart_ops = vec![Vec::new(); t.charts.len()];
    for (i, o) in t.ops.iter().enumerate() {
        let links: Vec<LinkId> = t.links_of_op(crate::topology::OpId::from_usize(i)).to_vec();
        if links.is_empty() {
            continue;
        }
        let id = ops.len() as u32;
        chart_ops[o.charts[0].idx()].push(id);
        if o.charts[1] != o.charts[0] {
            chart_ops[o.charts[1].idx()].push(id);
        }
        ops.push(EngineOp::new(t, o.kind, links, OpState::Vetoed(Veto::ZeroArea)));
    }
    (ops, chart_ops)
}
