//! Seams: linked half-edge pairs (the two sides of a seam mesh edge, with the UV vertices to
//! fuse at each end) and their maximal chains (digest §3.4, §3.5, §3.7).

use super::charts::{UvVertices, pair_corners};
use super::edges::Adjacency;
use super::ids::{ChainId, ChartId, EdgeId, HalfEdgeId, LinkId, PosId, UvVertId};
use super::texel::FrozenReasons;

/// A pair of linked half-edges: the two sides of one seam mesh edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct LinkedPair {
    pub edge: EdgeId,
    /// Side `a` and side `b`; side `a` is on the chart with the smaller id (for an intra-chart
    /// seam, the smaller half-edge id).
    pub sides: [HalfEdgeId; 2],
    /// The charts of side `a` and side `b` (`charts[0] <= charts[1]`).
    pub charts: [ChartId; 2],
    /// For each endpoint of the mesh edge (`MeshEdge::v[0]`, `v[1]`): the UV vertex of side `a`
    /// and the UV vertex of side `b` there, paired by welded position. The two may be the same
    /// vertex at the tip of an intra-chart cut.
    pub fuse: [[UvVertId; 2]; 2],
}

/// A seam chain: linked pairs in order along a path whose inner vertices have seam valence 2 and
/// separate the same two charts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Chain {
    /// Start of its links in `Topology::chain_links`.
    pub first_link: u32,
    pub n_links: u32,
    /// The welded position the chain starts at (and ends at, when closed).
    pub start: PosId,
    /// Whether the chain is a closed loop.
    pub closed: bool,
    /// The unordered chart pair it separates (`charts[0] <= charts[1]`).
    pub charts: [ChartId; 2],
}

impl Chain {
    /// The chain's range in `Topology::chain_links`.
    #[inline]
    pub fn links(&self) -> std::ops::Range<usize> {
        self.first_link as usize..(self.first_link + self.n_links) as usize
    }
}

/// Output of the link stage.
pub(crate) struct Links {
    pub links: Vec<LinkedPair>,
    pub he_link: Vec<LinkId>,
    /// Two-sided edges with different UVs on their sides where a side is frozen: input seams
    /// that no operation dissolves.
    pub frozen_seams: u64,
    /// Two-sided edges whose sides had the same UVs in the input but lie in different charts
    /// because one side is frozen (borders created by isolating frozen faces).
    pub frozen_borders: u64,
}

/// Finds the linked pairs: two-sided, non-degenerate mesh edges whose sides are not UV twins
/// and whose faces are both mergeable. Ids follow mesh-edge order.
pub(crate) fn find_links(
    adj: &Adjacency,
    corner_pos: &[PosId],
    uv: &UvVertices,
    face_sheet: &[u32],
    face_flags: &[FrozenReasons],
    face_chart: &[ChartId],
    he_uv_twin: &[HalfEdgeId],
) -> Links {
    let (corner_uv, uv_pos) = (&uv.corner_uv, &uv.uv_pos);
    let mut links = Vec::new();
    let mut he_link = vec![LinkId::NONE; corner_pos.len()];
    let (mut frozen_seams, mut frozen_borders) = (0, 0);
    for (e, edge) in adj.edges.iter().enumerate() {
        if edge.n_sides != 2 || edge.is_degenerate() {
            continue;
        }
        let (mut a, mut b) = (
            adj.edge_sides[edge.first_side as usize],
            adj.edge_sides[edge.first_side as usize + 1],
        );
        if !he_uv_twin[a.idx()].is_none() {
            continue;
        }
        if face_flags[a.face()].is_frozen() || face_flags[b.face()].is_frozen() {
            let [[a0, b0], [a1, b1]] = pair_corners(corner_pos, a, b);
            let same =
                |x: usize, y: usize| uv_pos[corner_uv[x].idx()] == uv_pos[corner_uv[y].idx()];
            if face_sheet[a.face()] == face_sheet[b.face()] && same(a0, b0) && same(a1, b1) {
                frozen_borders += 1;
            } else {
                frozen_seams += 1;
            }
            continue;
        }
        if (face_chart[b.face()], b) < (face_chart[a.face()], a) {
            std::mem::swap(&mut a, &mut b);
        }
        let pairs = pair_corners(corner_pos, a, b);
        // `pair_corners` lists side a's start corner first; order by mesh-edge endpoint.
        let (lo, hi) = if corner_pos[pairs[0][0]] == edge.v[0] {
            (pairs[0], pairs[1])
        } else {
            (pairs[1], pairs[0])
        };
        let id = LinkId::from_usize(links.len());
        he_link[a.idx()] = id;
        he_link[b.idx()] = id;
        links.push(LinkedPair {
            edge: EdgeId::from_usize(e),
            sides: [a, b],
            charts: [face_chart[a.face()], face_chart[b.face()]],
            fuse: [[corner_uv[lo[0]], corner_uv[lo[1]]], [corner_uv[hi[0]], corner_uv[hi[1]]]],
        });
    }
    Links { links, he_link, frozen_seams, frozen_borders }
}

/// Output of the chain stage.
pub(crate) struct Chains {
    pub chains: Vec<Chain>,
    pub chain_links: Vec<LinkId>,
    pub link_chain: Vec<ChainId>,
}

/// Groups linked pairs into maximal chains.
///
/// The seam graph holds every non-degenerate mesh edge that is a UV border: linked pairs, mesh
/// boundaries, non-manifold edges and borders against frozen faces. A chain passes through a
/// position only when exactly two seam-graph edges meet there and both are linked pairs between
/// the same unordered chart pair; anywhere else the chain ends. Chains are discovered in link-id
/// order and walked from the end reached by leaving the seed link through its first endpoint.
pub(crate) fn build_chains(
    adj: &Adjacency,
    he_uv_twin: &[HalfEdgeId],
    links: &Links,
    n_pos: usize,
) -> Chains {
    let is_border = |e: &super::edges::MeshEdge| {
        !e.is_degenerate()
            && (e.n_sides != 2 || he_uv_twin[adj.edge_sides[e.first_side as usize].idx()].is_none())
    };
    // Seam-graph edges incident to each position (CSR).
    let mut start = vec![0u32; n_pos + 1];
    for e in adj.edges.iter().filter(|e| is_border(e)) {
        start[e.v[0].idx() + 1] += 1;
        start[e.v[1].idx() + 1] += 1;
    }
    for p in 0..n_pos {
        start[p + 1] += start[p];
    }
    let mut fill = start.clone();
    let mut incident = vec![EdgeId::NONE; start[n_pos] as usize];
    for (i, e) in adj.edges.iter().enumerate() {
        if is_border(e) {
            for v in e.v {
                incident[fill[v.idx()] as usize] = EdgeId::from_usize(i);
                fill[v.idx()] += 1;
            }
        }
    }
    drop(fill);

    let edge_link =
        |e: EdgeId| links.he_link[adj.edge_sides[adj.edges[e.idx()].first_side as usize].idx()];
    let other_end = |l: LinkId, v: PosId| {
        let ev = adj.edges[links.links[l.idx()].edge.idx()].v;
        if ev[0] == v { ev[1] } else { ev[0] }
    };
    // The link that continues the chain of `l` through position `v`, if `v` is a pass-through.
    let pass = |v: PosId, l: LinkId| -> Option<LinkId> {
        let (s, e) = (start[v.idx()] as usize, start[v.idx() + 1] as usize);
        if e - s != 2 {
            return None;
        }
        let own = links.links[l.idx()].edge;
        let other = if incident[s] == own { incident[s + 1] } else { incident[s] };
        let n = edge_link(other).get()?;
        (links.links[n.idx()].charts == links.links[l.idx()].charts).then_some(n)
    };

    let n_links = links.links.len();
    let mut link_chain = vec![ChainId::NONE; n_links];
    let mut chains = Vec::new();
    let mut chain_links = Vec::with_capacity(n_links);
    for seed in 0..n_links {
        if !link_chain[seed].is_none() {
            continue;
        }
        let seed = LinkId::from_usize(seed);
        let seed_v = adj.edges[links.links[seed.idx()].edge.idx()].v;
        // Walk backwards to the chain's end, or around the loop back to the seed.
        let (mut cur, mut v) = (seed, seed_v[0]);
        let mut closed = false;
        for _ in 0..n_links {
            match pass(v, cur) {
                None => break,
                Some(n) if n == seed => {
                    closed = true;
                    break;
                }
                Some(n) => {
                    v = other_end(n, v);
                    cur = n;
                }
            }
        }
        let (first, start_v) = if closed { (seed, seed_v[0]) } else { (cur, v) };
        let id = ChainId::from_usize(chains.len());
        let first_link = chain_links.len() as u32;
        let (mut cur, mut v) = (first, start_v);
        loop {
            link_chain[cur.idx()] = id;
            chain_links.push(cur);
            v = other_end(cur, v);
            match pass(v, cur) {
                Some(n) if n != first && link_chain[n.idx()].is_none() => cur = n,
                _ => break,
            }
        }
        chains.push(Chain {
            first_link,
            n_links: chain_links.len() as u32 - first_link,
            start: start_v,
            closed,
            charts: links.links[first.idx()].charts,
        });
    }
    Chains { chains, chain_links, link_chain }
}
