//! Candidate merge operations (paper §4.1, digest §3.6): one inter-chart operation per linked
//! chart pair dissolving every seam between them at once, and one intra-chart operation per
//! chain whose two sides lie on the same chart.

use super::ids::{ChainId, ChartId, LinkId, UvVertId};
use super::seams::{Chain, LinkedPair};

/// Whether an operation joins two charts or closes a cut inside one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum OpKind {
    Inter,
    Intra,
}

/// A candidate operation. Its lists live in the flat `Topology::op_*` tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Operation {
    pub kind: OpKind,
    /// The two charts (`charts[0] < charts[1]` for inter-chart, equal for intra-chart).
    pub charts: [ChartId; 2],
    /// Its chains in `Topology::op_chains`.
    pub chains: [u32; 2],
    /// Its linked pairs (chain by chain, in chain order) in `Topology::op_links`.
    pub links: [u32; 2],
    /// Its distinct UV vertex pairs to fuse, `(side a, side b)`, sorted, in `Topology::op_pairs`.
    /// Intra-chart pairs are stored as `(smaller, larger)`; pairs of a vertex with itself (the tip
    /// of a cut) are left out.
    pub pairs: [u32; 2],
}

impl Operation {
    /// Range helper for the `[start, end)` fields.
    #[inline]
    pub fn range(r: [u32; 2]) -> std::ops::Range<usize> {
        r[0] as usize..r[1] as usize
    }
}

/// Output of the operation stage.
pub(crate) struct Ops {
    pub ops: Vec<Operation>,
    pub op_chains: Vec<ChainId>,
    pub op_links: Vec<LinkId>,
    pub op_pairs: Vec<[UvVertId; 2]>,
}

/// Builds the candidate operations, ordered by chart pair and then by chain id: deterministic
/// by construction (a sort of chain ids, no hash maps).
pub(crate) fn build_ops(chains: &[Chain], chain_links: &[LinkId], links: &[LinkedPair]) -> Ops {
    let mut order: Vec<u32> = (0..chains.len() as u32).collect();
    order.sort_unstable_by_key(|&c| (chains[c as usize].charts, c));
    let mut out = Ops {
        ops: Vec::new(),
        op_chains: Vec::with_capacity(chains.len()),
        op_links: Vec::with_capacity(chain_links.len()),
        op_pairs: Vec::new(),
    };
    let mut scratch: Vec<[UvVertId; 2]> = Vec::new();
    let mut i = 0;
    while i < order.len() {
        let charts = chains[order[i] as usize].charts;
        let intra = charts[0] == charts[1];
        // An inter-chart operation takes every chain of its chart pair; an intra-chart one takes
        // a single chain.
        let mut j = i + 1;
        if !intra {
            while j < order.len() && chains[order[j] as usize].charts == charts {
                j += 1;
            }
        }
        let (c0, l0, p0) = (out.op_chains.len(), out.op_links.len(), out.op_pairs.len());
        scratch.clear();
        for &c in &order[i..j] {
            out.op_chains.push(ChainId(c));
            for &l in &chain_links[chains[c as usize].links()] {
                out.op_links.push(l);
                for [a, b] in links[l.idx()].fuse {
                    if a != b {
                        scratch.push(if intra && b < a { [b, a] } else { [a, b] });
                    }
                }
            }
        }
        scratch.sort_unstable();
        scratch.dedup();
        out.op_pairs.extend_from_slice(&scratch);
        out.ops.push(Operation {
            kind: if intra { OpKind::Intra } else { OpKind::Inter },
            charts,
            chains: [c0 as u32, out.op_chains.len() as u32],
            links: [l0 as u32, out.op_links.len() as u32],
            pairs: [p0 as u32, out.op_pairs.len() as u32],
        });
        i = j;
    }
    out
}
