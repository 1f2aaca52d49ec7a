//! The preparation stage of the defragmentation engine: texel space, exact welds, 3D adjacency,
//! UV charts, seams (linked edge pairs), seam chains and candidate merge operations, built once
//! from a [`Model`] as an indexed, pointer-free structure (ARCHITECTURE §4–5, digest §2–3).
//!
//! Everything is stored in flat `Vec`s indexed by `u32` newtype ids (see [`ids`]), so the merge
//! engine can mutate it in place and undo a rejected merge from a log of `(slot, old value)`
//! records. Corners are addressed as `3·face + k` and are never reordered; half-edge `3·f + k`
//! runs from corner `k` to corner `k + 1` of face `f`. The two sides of a mesh edge are paired by
//! welded position, never by corner order, so inconsistently oriented faces keep their UVs.
//!
//! Chart definition. Two faces are in the same chart when they are linked through edges whose
//! two sides use the same two UV vertices (`(welded position, sheet, u, v)`), i.e. the evaluator's
//! `charts_edge`, with one refinement: "isolated" faces (no or non-finite UVs, no sheet size)
//! only join other isolated faces, so a chart is entirely mergeable or entirely frozen. Other
//! frozen faces (degenerate, zero 3D or UV area, on a non-manifold edge) ride along with the
//! chart they are UV-connected to, but no seam of theirs is dissolved.
//! [`PreparationReport::uv_components`] keeps the plain evaluator count for comparison.

pub mod charts;
pub mod edges;
pub mod ids;
pub mod ops;
pub mod seams;
pub mod texel;
mod weld;

#[cfg(test)]
mod tests;

use std::sync::Arc;
use std::time::Instant;

pub use charts::Chart;
pub use edges::MeshEdge;
pub use ids::{ChainId, ChartId, EdgeId, HalfEdgeId, LinkId, OpId, PosId, UvVertId};
pub use ops::{OpKind, Operation};
pub use seams::{Chain, LinkedPair};
pub use texel::{FrozenReasons, STRAY_UV_SPAN, ZERO_UV_AREA};

use crate::model::Model;

/// Why the preparation stage refused a model.
#[derive(Debug, thiserror::Error)]
pub enum TopologyError {
    #[error("{got} sheet sizes given for a model with {expected} sheets")]
    SheetSizeCount { expected: usize, got: usize },
    #[error("invalid model: {0}")]
    InvalidModel(String),
    #[error("model too large for 32-bit ids: {what} = {count}")]
    TooLarge { what: &'static str, count: usize },
}

/// Frozen faces by reason (a face may be counted under several reasons; `total` counts faces).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrozenCounts {
    pub total: u64,
    pub no_uv: u64,
    pub non_finite_uv: u64,
    pub no_sheet: u64,
    pub degenerate: u64,
    pub zero_area_3d: u64,
    pub zero_area_uv: u64,
    /// Faces whose UVs spanned more than any sheet and were collapsed to a point.
    pub stray_uv: u64,
}

/// Time spent in one preparation stage.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub ms: f64,
}

/// Everything the preparation stage counted, for the run report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PreparationReport {
    pub faces: u64,
    /// Distinct 3D positions referenced by faces.
    pub positions: u64,
    /// Distinct `(position, sheet, u, v)` tuples (the evaluator's `uv_vertices`).
    pub uv_vertices_welded: u64,
    /// UV vertices after splitting those shared by several charts (plus one per corner of faces
    /// without usable UVs).
    pub uv_vertices: u64,
    /// Edge-connected UV components over all faces (the evaluator's `charts_edge`).
    pub uv_components: u64,
    /// Charts (mergeable and frozen).
    pub charts: u64,
    pub frozen_charts: u64,
    pub flipped_charts: u64,
    pub mesh_edges: u64,
    pub boundary_edges: u64,
    pub non_manifold_edges: u64,
    /// Faces with a side on a non-manifold edge. They merge through their other edges; the
    /// non-manifold edge itself is never dissolved.
    pub non_manifold_faces: u64,
    pub degenerate_edges: u64,
    /// Two-sided edges whose faces are inconsistently oriented.
    pub inconsistent_edge_pairs: u64,
    /// Linked pairs (seams between mergeable faces).
    pub seams: u64,
    /// Two-sided edges with different UVs on their sides where a side is frozen (`seams +
    /// frozen_seams` is the evaluator's `uv_seam_edges_3d`).
    pub frozen_seams: u64,
    /// Two-sided edges with the same UVs on both sides that became chart borders because one
    /// side is frozen.
    pub frozen_borders: u64,
    pub chains: u64,
    pub closed_chains: u64,
    pub inter_ops: u64,
    pub intra_ops: u64,
    pub frozen_faces: FrozenCounts,
    /// UV coordinates (wedges) that are NaN or infinite.
    pub non_finite_uvs: u64,
    /// Charts shifted by whole periods to undo REPEAT wrapping.
    pub rebased_charts: u64,
    pub timings: Vec<StageTime>,
    pub total_ms: f64,
}

/// The prepared UV layout: corner tables, mesh edges, charts, seams, chains and operations.
///
/// Per-corner, per-half-edge and per-face tables are indexed by `3·f + k` and `f`. The "current"
/// UV lives on UV vertices (`uv_pos`); the "original" texel-space UV of every corner
/// (`orig_uv`) is the ARAP target and the resampling source and is never changed by merges.
///
/// The largest tables that nothing changes after preparation (`corner_pos`, `orig_uv`, the mesh
/// edges and the half-edges' edge and 3-D twin) are shared slices: a copy of the topology (the
/// merge's shadow engine, a cluster's fork) then costs only the tables a merge may change.
#[derive(Clone, Debug)]
pub struct Topology {
    /// Welded position of each model vertex.
    pub vertex_pos: Vec<PosId>,
    pub n_positions: usize,
    /// Welded position of each corner.
    pub corner_pos: Arc<[PosId]>,
    /// UV vertex of each corner.
    pub corner_uv: Vec<UvVertId>,
    /// Original texel-space UV of each corner (after REPEAT rebasing).
    pub orig_uv: Arc<[[f64; 2]]>,
    /// Current texel-space position of each UV vertex.
    pub uv_pos: Vec<[f64; 2]>,
    /// Welded position of each UV vertex.
    pub uv_vpos: Vec<PosId>,
    /// Chart of each UV vertex.
    pub uv_chart: Vec<ChartId>,
    /// Chart of each face.
    pub face_chart: Vec<ChartId>,
    /// Why each face is frozen (empty set for mergeable faces).
    pub face_flags: Vec<FrozenReasons>,
    /// Sheet of each face (`NONE` for none).
    pub face_sheet: Vec<u32>,
    pub edges: Arc<[MeshEdge]>,
    pub edge_sides: Arc<[HalfEdgeId]>,
    /// Mesh edge of each half-edge.
    pub he_edge: Arc<[EdgeId]>,
    /// 3D twin of each half-edge (two-sided, non-degenerate edges only).
    pub he_twin: Arc<[HalfEdgeId]>,
    /// UV twin of each half-edge (same chart, same two UV vertices); `NONE` on UV borders.
    pub he_uv_twin: Vec<HalfEdgeId>,
    /// Linked pair of each half-edge; `NONE` when the side is not on a seam.
    pub he_link: Vec<LinkId>,
    pub charts: Vec<Chart>,
    pub links: Vec<LinkedPair>,
    pub chains: Vec<Chain>,
    pub chain_links: Vec<LinkId>,
    /// Chain of each linked pair.
    pub link_chain: Vec<ChainId>,
    pub ops: Vec<Operation>,
    pub op_chains: Vec<ChainId>,
    pub op_links: Vec<LinkId>,
    pub op_pairs: Vec<[UvVertId; 2]>,
    pub report: PreparationReport,
}

impl Topology {
    /// Prepares `model` for defragmentation. `sheet_sizes[s]` is the pixel size of sheet `s`
    /// (`None` when unknown: its faces keep scale 1 and are frozen).
    pub fn build(model: &Model, sheet_sizes: &[Option<(u32, u32)>]) -> Result<Self, TopologyError> {
        let t_all = Instant::now();
        check_sizes(model, sheet_sizes)?;
        let mut timings = Vec::new();
        let mut t = Instant::now();
        let mut lap = |stage: &'static str, t: &mut Instant| {
            timings.push(StageTime { stage, ms: t.elapsed().as_secs_f64() * 1e3 });
            *t = Instant::now();
        };

        let texel::TexelSpace {
            corner_uv: mut orig_uv,
            face_sheet,
            mut face_flags,
            non_finite_uvs,
        } = texel::to_texel_space(model, sheet_sizes);
        lap("texel", &mut t);

        let (vertex_pos, n_positions) = weld::weld_positions(&model.positions);
        let face_vertices: Vec<[usize; 3]> =
            model.faces.iter().map(|f| [f.v[0].idx(), f.v[1].idx(), f.v[2].idx()]).collect();
        let corner_pos: Vec<PosId> =
            face_vertices.iter().flat_map(|v| v.map(|i| vertex_pos[i])).collect();
        lap("weld positions", &mut t);

        let adj = edges::build_adjacency(&corner_pos, n_positions);
        lap("mesh edges", &mut t);

        let non_manifold_faces = edges::flag_3d(
            &model.positions,
            face_vertices.iter().copied(),
            &corner_pos,
            &adj,
            &mut face_flags,
        );
        freeze_zero_area_uvs(&mut face_flags, &orig_uv);
        let uv_weld = weld::weld_uvs(model, &corner_pos, n_positions, &face_sheet, &face_flags);
        lap("weld uv", &mut t);

        let labels = charts::label_charts(&adj, &corner_pos, &uv_weld.corner_weld, &face_flags);
        let mut uv = charts::split_uv_vertices(
            &uv_weld.corner_weld,
            uv_weld.count,
            &labels.face_chart,
            &corner_pos,
            &orig_uv,
        );
        drop(uv_weld.corner_weld);
        lap("charts", &mut t);

        let rebased_charts = charts::rebase_charts(
            labels.n_charts,
            sheet_sizes,
            &face_sheet,
            &face_flags,
            &labels.face_chart,
            &mut uv,
            &mut orig_uv,
        );
        let (chart_list, he_uv_twin) = charts::chart_caches(
            &adj,
            &model.positions,
            &face_vertices,
            &face_flags,
            &face_sheet,
            &labels.face_chart,
            labels.n_charts,
            &uv,
        );
        lap("chart caches", &mut t);

        let links = seams::find_links(
            &adj,
            &corner_pos,
            &uv,
            &face_sheet,
            &face_flags,
            &labels.face_chart,
            &he_uv_twin,
        );
        let chains = seams::build_chains(&adj, &he_uv_twin, &links, n_positions);
        lap("seams", &mut t);
        let ops = ops::build_ops(&chains.chains, &chains.chain_links, &links.links);
        lap("operations", &mut t);

        let mut topo = Self {
            vertex_pos,
            n_positions,
            corner_pos: corner_pos.into(),
            corner_uv: uv.corner_uv,
            orig_uv: orig_uv.into(),
            uv_pos: uv.uv_pos,
            uv_vpos: uv.uv_vpos,
            uv_chart: uv.uv_chart,
            face_chart: labels.face_chart,
            face_flags,
            face_sheet,
            edges: adj.edges.into(),
            edge_sides: adj.edge_sides.into(),
            he_edge: adj.he_edge.into(),
            he_twin: adj.he_twin.into(),
            he_uv_twin,
            he_link: links.he_link,
            charts: chart_list,
            links: links.links,
            chains: chains.chains,
            chain_links: chains.chain_links,
            link_chain: chains.link_chain,
            ops: ops.ops,
            op_chains: ops.op_chains,
            op_links: ops.op_links,
            op_pairs: ops.op_pairs,
            // The figures only the stages know; `count_structures` adds the rest.
            report: PreparationReport {
                uv_vertices_welded: uv_weld.count as u64,
                uv_components: labels.uv_components as u64,
                charts: labels.n_charts as u64,
                boundary_edges: adj.boundary_edges,
                non_manifold_edges: adj.non_manifold_edges,
                non_manifold_faces,
                degenerate_edges: adj.degenerate_edges,
                inconsistent_edge_pairs: adj.inconsistent_pairs,
                frozen_seams: links.frozen_seams,
                frozen_borders: links.frozen_borders,
                non_finite_uvs,
                rebased_charts,
                timings,
                ..PreparationReport::default()
            },
        };
        topo.count_structures();
        topo.report.total_ms = t_all.elapsed().as_secs_f64() * 1e3;
        Ok(topo)
    }

    /// Fills the report's counts of the built structures: faces, positions, UV vertices,
    /// charts, edges, seams, chains and operations.
    fn count_structures(&mut self) {
        let mut referenced = vec![false; self.n_positions];
        for p in self.corner_pos.iter() {
            referenced[p.idx()] = true;
        }
        let r = &mut self.report;
        r.faces = self.face_flags.len() as u64;
        r.positions = referenced.iter().filter(|&&r| r).count() as u64;
        r.uv_vertices = self.uv_pos.len() as u64;
        r.frozen_charts = self.charts.iter().filter(|c| c.frozen).count() as u64;
        r.flipped_charts = self.charts.iter().filter(|c| c.flipped).count() as u64;
        r.mesh_edges = self.edges.len() as u64;
        r.seams = self.links.len() as u64;
        r.chains = self.chains.len() as u64;
        r.closed_chains = self.chains.iter().filter(|c| c.closed).count() as u64;
        r.inter_ops = self.ops.iter().filter(|o| o.kind == OpKind::Inter).count() as u64;
        r.intra_ops = self.ops.iter().filter(|o| o.kind == OpKind::Intra).count() as u64;
        r.frozen_faces = count_frozen(&self.face_flags);
    }

    /// The linked pairs of operation `op`.
    pub fn links_of_op(&self, op: OpId) -> &[LinkId] {
        &self.op_links[Operation::range(self.ops[op.idx()].links)]
    }

    /// The distinct UV vertex pairs operation `op` fuses.
    pub fn pairs_of_op(&self, op: OpId) -> &[[UvVertId; 2]] {
        &self.op_pairs[Operation::range(self.ops[op.idx()].pairs)]
    }

    /// The linked pairs of chain `c`, in order along the chain.
    pub fn links_of_chain(&self, c: ChainId) -> &[LinkId] {
        &self.chain_links[self.chains[c.idx()].links()]
    }

    /// The sides of mesh edge `e`.
    pub fn sides_of_edge(&self, e: EdgeId) -> &[HalfEdgeId] {
        &self.edge_sides[self.edges[e.idx()].sides()]
    }

    /// Gives corner `c` a UV vertex of its own at `uv`, in the chart of the vertex it had; the
    /// caller cuts the UV sides that no longer share it.
    pub fn split_corner(&mut self, c: usize, uv: [f64; 2]) -> UvVertId {
        let v = UvVertId::from_usize(self.uv_pos.len());
        self.uv_pos.push(uv);
        self.uv_vpos.push(self.corner_pos[c]);
        self.uv_chart.push(self.uv_chart[self.corner_uv[c].idx()]);
        self.corner_uv[c] = v;
        v
    }

    /// Makes half-edge `h` a UV border: it and its UV twin (if any) stop being twins.
    pub fn cut_uv_side(&mut self, h: usize) {
        let twin = self.he_uv_twin[h];
        if !twin.is_none() {
            self.he_uv_twin[twin.idx()] = HalfEdgeId::NONE;
            self.he_uv_twin[h] = HalfEdgeId::NONE;
        }
    }

    /// Cuts the faces `faces` (sorted, distinct) out of their UV chart together: each UV vertex
    /// they use is replaced, for them, by a new one at the same position, and every side between
    /// one of them and a face not in the list becomes a border. Their UVs do not move, so
    /// whatever was written for them stays true; only the packing may now place them apart. A
    /// vertex no other face used is left unused.
    pub fn detach_faces(&mut self, faces: &[u32]) {
        debug_assert!(faces.windows(2).all(|w| w[0] < w[1]), "faces sorted and distinct");
        let mut renamed = rustc_hash::FxHashMap::default();
        for &f in faces {
            for c in 3 * f as usize..3 * f as usize + 3 {
                let old = self.corner_uv[c];
                match renamed.get(&old) {
                    Some(&v) => self.corner_uv[c] = v,
                    None => {
                        let v = self.split_corner(c, self.uv_pos[old.idx()]);
                        renamed.insert(old, v);
                    }
                }
                let twin = self.he_uv_twin[c];
                if !twin.is_none() && faces.binary_search(&(twin.face() as u32)).is_err() {
                    self.cut_uv_side(c);
                }
            }
        }
    }
}

/// Refuses sheet sizes that do not match the model's sheets, an invalid model, or one too
/// large for 32-bit corner and position ids.
fn check_sizes(model: &Model, sheet_sizes: &[Option<(u32, u32)>]) -> Result<(), TopologyError> {
    if sheet_sizes.len() != model.sheets.len() {
        return Err(TopologyError::SheetSizeCount {
            expected: model.sheets.len(),
            got: sheet_sizes.len(),
        });
    }
    model.validate_indices().map_err(TopologyError::InvalidModel)?;
    let limit = u32::MAX as usize - 1;
    if model.faces.len().saturating_mul(3) > limit {
        return Err(TopologyError::TooLarge {
            what: "corners",
            count: model.faces.len().saturating_mul(3),
        });
    }
    if model.positions.len() > limit {
        return Err(TopologyError::TooLarge { what: "positions", count: model.positions.len() });
    }
    Ok(())
}

/// Freezes the faces with usable UVs whose UV area is below [`ZERO_UV_AREA`].
fn freeze_zero_area_uvs(face_flags: &mut [FrozenReasons], orig_uv: &[[f64; 2]]) {
    for (f, flags) in face_flags.iter_mut().enumerate() {
        if flags.has_usable_uv() {
            let a2 = texel::signed_area2(orig_uv[3 * f], orig_uv[3 * f + 1], orig_uv[3 * f + 2]);
            let area = 0.5 * a2.abs();
            // Finite UVs can still overflow to an infinite or NaN area: freeze those too.
            if area.is_nan() || area < ZERO_UV_AREA || area.is_infinite() {
                flags.0 |= FrozenReasons::ZERO_AREA_UV;
            }
        }
    }
}

/// Frozen faces counted by reason.
fn count_frozen(face_flags: &[FrozenReasons]) -> FrozenCounts {
    let mut frozen = FrozenCounts::default();
    for flags in face_flags {
        let count = |bit: u8| u64::from(flags.has(bit));
        frozen.total += u64::from(flags.is_frozen());
        frozen.no_uv += count(FrozenReasons::NO_UV);
        frozen.non_finite_uv += count(FrozenReasons::NON_FINITE_UV);
        frozen.no_sheet += count(FrozenReasons::NO_SHEET);
        frozen.degenerate += count(FrozenReasons::DEGENERATE);
        frozen.zero_area_3d += count(FrozenReasons::ZERO_AREA_3D);
        frozen.zero_area_uv += count(FrozenReasons::ZERO_AREA_UV);
        frozen.stray_uv += count(FrozenReasons::STRAY_UV);
    }
    frozen
}
