//! 3D adjacency: mesh edges keyed by sorted welded-position pairs, with all their incident face
//! sides, the 3D twin of every side, and the face flags that come from the 3D mesh (degenerate,
//! zero 3D area, non-manifold edge).

use super::ids::{EdgeId, HalfEdgeId, PosId};
use super::texel::FrozenReasons;
use crate::vec3::triangle_area;

/// A mesh edge: an unordered pair of welded positions and the face sides lying on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshEdge {
    /// The two endpoints, `v[0] <= v[1]` (equal for a degenerate edge).
    pub v: [PosId; 2],
    /// Start of the edge's sides in `Topology::edge_sides`.
    pub first_side: u32,
    /// Number of incident face sides.
    pub n_sides: u32,
}

impl MeshEdge {
    /// Whether both endpoints weld to the same position.
    #[inline]
    pub fn is_degenerate(&self) -> bool {
        self.v[0] == self.v[1]
    }

    /// Whether more than two face sides lie on this (non-degenerate) edge.
    #[inline]
    pub fn is_non_manifold(&self) -> bool {
        !self.is_degenerate() && self.n_sides > 2
    }

    /// Whether exactly one face side lies on this (non-degenerate) edge.
    #[inline]
    pub fn is_boundary(&self) -> bool {
        !self.is_degenerate() && self.n_sides == 1
    }

    /// The sides' range in `Topology::edge_sides`.
    #[inline]
    pub fn sides(&self) -> std::ops::Range<usize> {
        self.first_side as usize..(self.first_side + self.n_sides) as usize
    }
}

/// Output of the adjacency stage.
pub(crate) struct Adjacency {
    pub edges: Vec<MeshEdge>,
    /// All face sides grouped by mesh edge, in edge order; inside an edge, by half-edge id.
    pub edge_sides: Vec<HalfEdgeId>,
    /// The mesh edge of every half-edge.
    pub he_edge: Vec<EdgeId>,
    /// The other side of a two-sided, non-degenerate edge; `NONE` otherwise.
    pub he_twin: Vec<HalfEdgeId>,
    pub non_manifold_edges: u64,
    pub boundary_edges: u64,
    pub degenerate_edges: u64,
    /// Two-sided edges whose sides run in the same direction (inconsistent face orientation).
    pub inconsistent_pairs: u64,
}

/// Groups the half-edges of all faces into mesh edges.
///
/// Half-edges are bucketed by their smaller endpoint with a counting sort and each bucket (one
/// vertex star) is sorted by the larger endpoint, which is linear in practice and avoids a global
/// sort of 64-bit keys. Edge ids follow the `(lo, hi)` order, independent of any hashing.
pub(crate) fn build_adjacency(corner_pos: &[PosId], n_pos: usize) -> Adjacency {
    let nh = corner_pos.len();
    let ends = |h: usize| {
        let a = corner_pos[h];
        let b = corner_pos[HalfEdgeId::from_usize(h).next().idx()];
        if a <= b { (a, b) } else { (b, a) }
    };
    let mut start = vec![0u32; n_pos + 1];
    for h in 0..nh {
        start[ends(h).0.idx() + 1] += 1;
    }
    for p in 0..n_pos {
        start[p + 1] += start[p];
    }
    // Each bucket slot packs `(hi << 32) | h`, so a bucket sorts as plain integers without
    // touching the corner table again.
    let mut fill = start.clone();
    let mut packed = vec![0u64; nh];
    for h in 0..nh {
        let (lo, hi) = ends(h);
        packed[fill[lo.idx()] as usize] = (u64::from(hi.0) << 32) | h as u64;
        fill[lo.idx()] += 1;
    }
    drop(fill);

    let mut edges = Vec::with_capacity(nh / 2 + 1);
    let mut he_edge = vec![EdgeId::NONE; nh];
    let mut edge_sides = vec![HalfEdgeId::NONE; nh];
    for p in 0..n_pos {
        let (s, e) = (start[p] as usize, start[p + 1] as usize);
        let star = &mut packed[s..e];
        star.sort_unstable();
        let mut i = 0;
        while i < star.len() {
            let hi = star[i] >> 32;
            let mut j = i;
            let id = EdgeId::from_usize(edges.len());
            while j < star.len() && star[j] >> 32 == hi {
                let h = (star[j] & 0xffff_ffff) as usize;
                he_edge[h] = id;
                edge_sides[s + j] = HalfEdgeId::from_usize(h);
                j += 1;
            }
            edges.push(MeshEdge {
                v: [PosId::from_usize(p), PosId(hi as u32)],
                first_side: (s + i) as u32,
                n_sides: (j - i) as u32,
            });
            i = j;
        }
    }

    let mut he_twin = vec![HalfEdgeId::NONE; nh];
    let (mut non_manifold_edges, mut boundary_edges, mut degenerate_edges) = (0, 0, 0);
    let mut inconsistent_pairs = 0;
    for e in &edges {
        if e.is_degenerate() {
            degenerate_edges += 1;
        } else if e.is_boundary() {
            boundary_edges += 1;
        } else if e.is_non_manifold() {
            non_manifold_edges += 1;
        } else {
            let (a, b) = (edge_sides[e.first_side as usize], edge_sides[e.first_side as usize + 1]);
            he_twin[a.idx()] = b;
            he_twin[b.idx()] = a;
            // Consistently oriented neighbours traverse their shared edge in opposite directions.
            if corner_pos[a.idx()] == corner_pos[b.idx()] {
                inconsistent_pairs += 1;
            }
        }
    }
    Adjacency {
        edges,
        edge_sides,
        he_edge,
        he_twin,
        non_manifold_edges,
        boundary_edges,
        degenerate_edges,
        inconsistent_pairs,
    }
}

/// Adds the 3D reasons to freeze a face: two corners welded together, or zero 3D area (exactly:
/// the reference deletes faces whose double area is `<= 0`). Returns how many faces have a side
/// on a non-manifold edge: those are not frozen (an edge with more than two sides is never
/// linked, so it stays a border, and the face merges through its other edges), only counted.
pub(crate) fn flag_3d(
    positions: &[[f64; 3]],
    face_vertices: impl Iterator<Item = [usize; 3]>,
    corner_pos: &[PosId],
    adjacency: &Adjacency,
    face_flags: &mut [FrozenReasons],
) -> u64 {
    let mut non_manifold = 0;
    for (f, v) in face_vertices.enumerate() {
        let p = [corner_pos[3 * f], corner_pos[3 * f + 1], corner_pos[3 * f + 2]];
        let mut flags = face_flags[f].0;
        if p[0] == p[1] || p[1] == p[2] || p[0] == p[2] {
            flags |= FrozenReasons::DEGENERATE;
        }
        let area = triangle_area([positions[v[0]], positions[v[1]], positions[v[2]]]);
        // `!(area > 0)` also freezes faces with NaN positions.
        if area.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            flags |= FrozenReasons::ZERO_AREA_3D;
        }
        non_manifold += u64::from(
            (0..3).any(|k| adjacency.edges[adjacency.he_edge[3 * f + k].idx()].is_non_manifold()),
        );
        face_flags[f] = FrozenReasons(flags);
    }
    non_manifold
}
