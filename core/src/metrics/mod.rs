//! The figures of ARCHITECTURE §9, with exactly the definitions of the independent evaluator
//! `shared/tools/evaluate.py` (its `analyze()`, `solidity()`, `raster_collisions()` and
//! `overlap_pairs()`), so that `scanatlas stats` and the evaluator agree on every model.
//!
//! Conventions copied from the evaluator:
//! - Texel space of a face is `(u·W, v·H)` with `W × H` the size of its sheet; faces without a sheet
//!   or whose sheet size is unknown use `W = H = 1`.
//! - A face without texture coordinates has the UV `(0, 0)` at all three corners (the evaluator's
//!   `M.UV` is zero there), so such faces still form UV vertices, edges and charts.
//! - 3D vertices are welded by exact position bits (`-0.0 == 0.0`). A UV vertex is a distinct
//!   `(welded position, sheet, u bits, v bits)` tuple, non-finite coordinates counting as `0.0`.
//! - `charts` joins faces sharing a UV vertex, `charts_edge` faces sharing a UV edge (both UV
//!   vertices); the latter is "the" chart count of scanatlas and of the reference code.
//!
//! The implementation is built for tens of millions of faces: exact grouping by counting sort on
//! dense integer keys followed by small per-bucket sorts, union-find over faces, rayon over chunks
//! whose bounds come from the data (never from the thread count, so sums are bit-identical for any
//! number of threads), and a texel raster processed in row bands of bounded size.

mod charts;
mod overlap;
pub mod seam;
mod stats;
mod weld;

#[cfg(test)]
mod tests;

use serde::Serialize;

use crate::model::Model;

pub use overlap::OverlapCounts;

/// Faces whose `|UV area|` in texel² is below this are degenerate (evaluate.py `DEGEN_AREA_TEXELS`).
pub const DEGEN_AREA_TEXELS: f64 = 1e-6;
/// Texel centres must lie inside a face by this much along the scanline to be covered by it
/// (evaluate.py `RASTER_EPS`).
pub const RASTER_EPS: f64 = 1e-6;
/// A UV seam whose two sides coincide within this many texels is a "crack" (evaluate.py `CRACK_TOL`).
pub const CRACK_TOL: f64 = 1e-3;
/// At most this many faces per texel take part in the overlapping face pairs (evaluate.py
/// `overlap_pairs(cap=16)`): the pairs among the 16 lowest face indices covering the texel.
pub const OVERLAP_PAIR_CAP: usize = 16;

/// What [`atlas_stats`] computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StatsOptions {
    /// Rasterize the faces to count overlapping texels and face pairs (the slowest figure).
    pub overlaps: bool,
}

impl Default for StatsOptions {
    fn default() -> Self {
        Self { overlaps: true }
    }
}

/// The size of one texture sheet as reported in [`AtlasStats::texture_sizes`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct TextureSize {
    /// The image path or embedded image name.
    pub name: String,
    pub width: Option<u32>,
    pub height: Option<u32>,
    /// Why the size is unknown, if it is.
    pub error: Option<String>,
}

/// The figures of the welded variant: charts additionally joined across "cracks", i.e. seams
/// whose two sides coincide within [`CRACK_TOL`] texels at both ends (typically float rounding
/// in a writer). Mirrors evaluate.py's `welded` object.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WeldedStats {
    pub crack_tolerance_texels: f64,
    pub charts_edge: u64,
    pub uv_boundary_length_texels: f64,
    pub atlas_solidity: Option<f64>,
}

/// The statistics of a textured model. Field names are evaluate.py's keys wherever it has the
/// figure; the others (`uv_zero_area_3d_faces`, `non_manifold_edges`, `overlap_face_pairs`) are
/// scanatlas additions.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AtlasStats {
    pub faces: u64,
    /// Distinct exact positions used by faces.
    pub vertices_3d: u64,
    /// Distinct `(welded position, sheet, u, v)` tuples over all face corners.
    pub uv_vertices: u64,
    /// `uv_vertices / vertices_3d`; `None` without vertices.
    pub vertex_replication: Option<f64>,
    /// Components of faces sharing a UV vertex.
    pub charts: u64,
    /// Components of faces sharing a UV edge.
    pub charts_edge: u64,
    /// Of those, the charts that cover some UV area: the chart count.
    pub charts_edge_with_area: u64,
    /// Faces of the other edge charts (no UV area: a point or a line of the texture each), counted
    /// apart from the charts.
    pub point_faces: u64,
    /// Components of faces sharing a UV record (`UvId`) of the model.
    pub charts_by_index: u64,
    /// Manifold mesh edges (exactly two faces) whose two sides use different UV vertices.
    pub uv_seam_edges_3d: u64,
    /// Seam edges whose two sides coincide within [`CRACK_TOL`] texels on the same sheet.
    pub uv_crack_edges: u64,
    /// Face edges not shared with another face through the same two UV vertices.
    pub uv_boundary_edges: u64,
    /// Sum of the texel-space lengths of those edges (every seam counted once per side).
    pub uv_boundary_length_texels: f64,
    /// Sum over faces of the absolute texel-space UV area.
    pub uv_area_texels: f64,
    /// Sum over edge charts of the absolute value of the chart's signed texel-space area.
    pub uv_area_charts_texels: f64,
    /// `2·sqrt(π·uv_area_charts_texels) / uv_boundary_length_texels`; `None` without boundary.
    pub atlas_solidity: Option<f64>,
    pub welded: WeldedStats,
    /// Sum of the 3D face areas, on positions as stored in the model (evaluate.py applies glTF
    /// node transforms first, so the two differ for glTF scenes with scaling nodes).
    pub area_3d: f64,
    pub texture_sheets: u64,
    pub texture_sizes: Vec<TextureSize>,
    /// Sum of `W·H` over sheets of known size.
    pub total_texels: u64,
    pub faces_without_texture: u64,
    pub faces_without_uv: u64,
    /// Faces whose UV orientation is opposite to that of their edge chart.
    pub uv_flipped_faces: u64,
    /// Faces with finite UVs and `|UV area| < DEGEN_AREA_TEXELS` texel².
    pub uv_degenerate_faces: u64,
    /// Faces whose 3D area is exactly zero.
    pub uv_zero_area_3d_faces: u64,
    pub uv_out_of_unit_wedges: u64,
    pub uv_out_of_unit_faces: u64,
    pub uv_nonfinite_wedges: u64,
    /// Mesh edges (on welded positions) with more than two incident face edges.
    pub non_manifold_edges: u64,
    /// Texels whose centre lies strictly inside two or more faces of the same sheet;
    /// `None` when [`StatsOptions::overlaps`] is off.
    pub overlap_texels: Option<u64>,
    /// Distinct face pairs sharing such a texel (pairs among the [`OVERLAP_PAIR_CAP`] lowest
    /// face indices of each texel); `None` when [`StatsOptions::overlaps`] is off.
    pub overlap_face_pairs: Option<u64>,
}

/// The chart and seam statistics of `model`.
///
/// `sheet_sizes[k]` is the size of `model.sheets[k]` as probed by the caller (`None` when the
/// image could not be read); faces of sheets of unknown size use `W = H = 1`, as evaluate.py does,
/// and take no part in the overlap raster.
///
/// # Panics
///
/// The model must satisfy [`Model::validate_indices`] (every reader guarantees it), and it must
/// have at most `u32::MAX / 3` faces (about 1.4 billion, far beyond what fits in memory), because
/// face corners are numbered with `u32`.
pub fn atlas_stats(
    model: &Model,
    sheet_sizes: &[Option<(u32, u32)>],
    opts: &StatsOptions,
) -> AtlasStats {
    let nf = model.faces.len();
    assert!(nf <= (u32::MAX / 3) as usize, "atlas_stats supports at most {} faces", u32::MAX / 3);
    let prep = stats::Prep::new(model, sheet_sizes);
    let fp = stats::face_pass(&prep);

    let (pid, n_pid) = weld::weld_positions(&model.positions);
    let vertices_3d = weld::used_ids(model, &pid, n_pid);
    let fw = weld::wedge_pids(model, &pid);
    drop(pid);
    let uvv = weld::uv_vertices(&prep, &fw, n_pid);

    let mut edges = charts::uv_edges(&prep, &uvv.uvid, uvv.count);
    let labels = edges.charts.flatten();
    let charts_edge = labels.iter().enumerate().filter(|&(i, &r)| r as usize == i).count() as u64;
    let (charts_edge_with_area, point_faces) = charts::charts_with_area(&labels, &fp.area);
    let (chart_sums, uv_area_charts) = charts::chart_areas(&labels, &fp.area);
    let uv_flipped_faces = charts::flipped_faces(&labels, &chart_sums, &fp.area, &fp.flags);
    drop(chart_sums);

    let mesh = charts::mesh_edges(&prep, &fw, n_pid, &uvv.uvid);
    let mut welded_uf = edges.charts;
    for &(a, b) in &mesh.cracks {
        welded_uf.union(a, b);
    }
    let welded_labels = welded_uf.flatten();
    drop(welded_uf);
    let welded_charts =
        welded_labels.iter().enumerate().filter(|&(i, &r)| r as usize == i).count() as u64;
    let (_, welded_area) = charts::chart_areas(&welded_labels, &fp.area);
    drop(welded_labels);
    let welded_border = edges.border_len - mesh.closed_len;

    let charts_by_index = charts::index_charts(&prep);

    let (overlap_texels, overlap_face_pairs) = if opts.overlaps {
        let o = overlap::overlaps(&prep, &fp.flags);
        (Some(o.texels), Some(o.face_pairs))
    } else {
        (None, None)
    };

    let texture_sizes = model
        .sheets
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let size = sheet_sizes.get(k).copied().flatten();
            TextureSize {
                name: s.image.describe(),
                width: size.map(|s| s.0),
                height: size.map(|s| s.1),
                error: size.is_none().then(|| "size not known".to_string()),
            }
        })
        .collect();
    let total_texels = (0..model.sheets.len())
        .filter_map(|k| sheet_sizes.get(k).copied().flatten())
        .map(|(w, h)| w as u64 * h as u64)
        .sum();

    AtlasStats {
        faces: nf as u64,
        vertices_3d,
        uv_vertices: uvv.count as u64,
        vertex_replication: (vertices_3d > 0).then(|| uvv.count as f64 / vertices_3d as f64),
        charts: uvv.charts,
        charts_edge,
        charts_edge_with_area,
        point_faces,
        charts_by_index,
        uv_seam_edges_3d: mesh.seams,
        uv_crack_edges: mesh.cracks.len() as u64,
        uv_boundary_edges: edges.border_edges,
        uv_boundary_length_texels: edges.border_len,
        uv_area_texels: fp.area_abs,
        uv_area_charts_texels: uv_area_charts,
        atlas_solidity: solidity(uv_area_charts, edges.border_len),
        welded: WeldedStats {
            crack_tolerance_texels: CRACK_TOL,
            charts_edge: welded_charts,
            uv_boundary_length_texels: welded_border,
            atlas_solidity: solidity(welded_area, welded_border),
        },
        area_3d: fp.area_3d,
        texture_sheets: model.sheets.len() as u64,
        texture_sizes,
        total_texels,
        faces_without_texture: fp.faces_without_texture,
        faces_without_uv: fp.faces_without_uv,
        uv_flipped_faces,
        uv_degenerate_faces: fp.degenerate,
        uv_zero_area_3d_faces: fp.zero_area_3d,
        uv_out_of_unit_wedges: fp.oob_wedges,
        uv_out_of_unit_faces: fp.oob_faces,
        uv_nonfinite_wedges: fp.nonfinite_wedges,
        non_manifold_edges: mesh.non_manifold,
        overlap_texels,
        overlap_face_pairs,
    }
}

/// The edge chart of every face, as [`atlas_stats`] groups faces into `charts_edge`: the label is
/// the lowest face index of the chart (faces sharing a UV edge, UV vertices welded by position,
/// sheet and exact UV), so two faces are in one chart exactly when their labels are equal.
///
/// # Panics
///
/// Under the same conditions as [`atlas_stats`].
pub fn edge_chart_labels(model: &Model, sheet_sizes: &[Option<(u32, u32)>]) -> Vec<u32> {
    let prep = stats::Prep::new(model, sheet_sizes);
    let (pid, n_pid) = weld::weld_positions(&model.positions);
    let fw = weld::wedge_pids(model, &pid);
    drop(pid);
    let uvv = weld::uv_vertices(&prep, &fw, n_pid);
    let mut edges = charts::uv_edges(&prep, &uvv.uvid, uvv.count);
    edges.charts.flatten()
}

/// Atlas solidity [MPCT20] as in evaluate.py: the perimeter of the circle enclosing the UV area,
/// `2·sqrt(π·A)`, over the UV border length `L`. 1 for a single disk-like chart; `None` when
/// there is no border.
pub fn solidity(area_uv: f64, border_uv: f64) -> Option<f64> {
    // The negated comparison also maps a NaN border to `None`, as Python's `<= 0` test would not;
    // a NaN border cannot arise because non-finite edge lengths are counted as zero.
    if border_uv.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    Some(2.0 * (std::f64::consts::PI * area_uv).sqrt() / border_uv)
}
