//! Packing orchestration (ARCHITECTURE §7, paper §4.5–4.6): grid-preserving anchors, chart
//! footprints, the `Packer` plugin over one or more sheets, trimming, and the integer placement
//! that lands preserved triangles exactly on the input texel grid.
//!
//! Every chart goes through one rigid map `current UV → chart frame` chosen before rasterization
//! (for anchored charts: undo the group's sub-quarter-turn angle and its sub-texel offset; for the
//! others: the minimum-area box orientation), then through the grid transform of its placement.
//! Because the footprint is rasterized from exactly the frame the chart is placed in, the
//! packer's no-overlap guarantee holds for the final UVs, and no sub-texel shift is needed after
//! packing (unlike the reference's `IntegerShift`, which moves charts after the fact).

mod anchor;
mod footprint;
mod frame;
mod layout;
pub mod palette;
mod place;
mod reshape;
mod sheet_size;
mod texel_clash;

#[cfg(test)]
mod tests;

pub use layout::{anchor_faces, pack_layout, rigid_groups_beyond_anchor};
pub use sheet_size::{
    MAX_ALIGN, MAX_TEXEL_SCALE, MIN_TEXEL_SCALE, check_sheet_shape, max_sheet_size,
    output_sheet_size,
};

use crate::geometry::GridTransform;
use crate::plugin::PackerError;

/// What the packing stage reads: the final charts in texel space, and the original UVs.
#[derive(Clone, Copy, Debug)]
pub struct LayoutInput<'a> {
    /// UV vertex of each corner `3·f + k`; `NONE` for faces without UVs.
    pub corner_vert: &'a [u32],
    /// Current texel-space position of each UV vertex (after merging).
    pub vert_uv: &'a [[f64; 2]],
    /// Per corner: the ORIGINAL texel-space UV, on input sheet `face_sheet[f]`.
    pub orig_uv: &'a [[f64; 2]],
    /// Chart of each face, dense `0..n_charts`; `NONE` = no UV (left out of packing).
    pub face_chart: &'a [u32],
    /// Input sheet of each face.
    pub face_sheet: &'a [u32],
    /// 3D area of each face.
    pub face_area_3d: &'a [f64],
    pub n_charts: usize,
    /// Width and height of each input sheet, in pixels.
    pub input_sheet_sizes: &'a [(u32, u32)],
}

/// Options of the packing stage.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PackOptions {
    /// Free texels around every chart; two charts end up at least `2·padding` texels apart.
    pub padding: u32,
    /// Output sheet size limit; `None` = the largest input sheet (by area, then width).
    pub max_sheet_size: Option<(u32, u32)>,
    /// Fixed output sheet size: the packer fills sheets of exactly this size, as many as needed
    /// (excludes `max_sheet_size`). See `sheet_size` for the rule.
    pub sheet_size: Option<(u32, u32)>,
    /// Every output sheet side is a power of two.
    pub pow2: bool,
    /// Every output sheet side is a multiple of this (1: any side).
    pub align: u32,
    /// Factor on every chart's texel footprint. At 1 the charts keep the input's texel density
    /// and grid-preserving anchors copy texels verbatim; at any other value every face is
    /// resampled (below 1 this loses resolution).
    pub texel_scale: f64,
    /// A chart is anchored when its largest rigid group covers at least this fraction of the
    /// chart's 3D area (the paper's 5%).
    pub anchor_min_fraction: f64,
    /// A face is a rigid image of its original triangle when every corner is within this many
    /// texels, relative to the triangle's size (at least 1 texel), of the best rigid fit.
    pub rigid_tolerance: f64,
    /// Move free UV vertices by up to two texels so that no two faces of a chart cover the centre
    /// of a texel they did not share in the input (see `texel_clash`).
    pub separate_texel_clashes: bool,
    /// Before packing, a rigid group of a chart other than its anchor group (at least
    /// `anchor_min_fraction` of the chart) becomes a chart of its own when the fraction of the
    /// atlas's 3-D area it would bring back onto the input grid is at least this many times the
    /// fraction by which the seam it opens lengthens the atlas's UV border (0: never). See the
    /// defrag pipeline's `rigid_split`.
    pub split_rigid_ratio: f64,
    /// A chart whose faces cover less than this input UV area (texels²) and fit within one texel
    /// each way is a speck: its faces become point faces of the palette, showing the input's
    /// colour at its centroid, rather than a chart of its own (0: never).
    pub speck_area: f64,
}

impl Default for PackOptions {
    fn default() -> Self {
        Self {
            padding: 4,
            max_sheet_size: None,
            sheet_size: None,
            pow2: false,
            align: 1,
            texel_scale: 1.0,
            anchor_min_fraction: 0.05,
            rigid_tolerance: 1e-6,
            separate_texel_clashes: true,
            split_rigid_ratio: 1.0,
            speck_area: 0.01,
        }
    }
}

/// Figures of a packing, for the run report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PackReport {
    /// Footprints the packer placed (its charts with at least one face). Not the atlas's chart
    /// count: a footprint may hold several edge-connected charts, and the palette's faces have
    /// none; the output's `charts_edge_with_area` and `point_faces` count those.
    pub charts: usize,
    /// Charts with a grid-preserving anchor.
    pub anchored_charts: usize,
    /// Charts anchored to a lighter rigid group because the heaviest one's turn did not fit on
    /// a sheet.
    pub anchors_changed_to_fit: usize,
    /// Charts left without an anchor because no group's turn fitted on a sheet.
    pub anchors_dropped_to_fit: usize,
    /// Faces whose texels are copied verbatim.
    pub preserved_faces: usize,
    /// 3D area of the preserved faces over the 3D area of all packed faces.
    pub preserved_area_fraction: f64,
    /// Output sheets.
    pub sheets: usize,
    /// Charts too large for a sheet of the size limit, each given a sheet of its own.
    pub oversized_charts: Vec<u32>,
    /// Texels of all trimmed output sheets.
    pub texels: u64,
    /// Pairs of faces of one chart covering the centre of a texel they did not share in the
    /// input, before and after the sub-texel moves that separate them, and the vertices moved.
    pub texel_clashes: usize,
    pub texel_clashes_left: usize,
    pub texel_clash_vertices_moved: usize,
    /// Fixed vertices freed for a clashing pair with no free corner (their faces lose grid
    /// preservation).
    pub texel_clash_vertices_freed: usize,
    /// Faces cut out of their charts (each packed as a chart of its own, and the atlas packed
    /// again) because the moves left them clashing, and how many times the atlas was packed
    /// again for them.
    pub faces_detached: usize,
    pub detach_rounds: usize,
    /// Rigid groups made charts of their own before packing (see `split_rigid_ratio`).
    pub rigid_split: RigidSplitReport,
    /// Faces without input UV area, kept apart from the charts on blocks of their own colour
    /// (see `palette`).
    pub palette: palette::PaletteReport,
    /// Cells of all footprints (padding included).
    pub footprint_cells: u64,
    /// UV area of all packed faces over `texels`.
    pub occupancy: f64,
    /// The size limit used.
    pub max_sheet_size: (u32, u32),
    /// Texels of all input sheets, and how many other sheet shapes of the default limit's area
    /// were tried because the packing at that limit needed more (see `reshape`; the limit kept
    /// is `max_sheet_size`).
    pub input_texels: u64,
    pub sheet_shapes_tried: usize,
    /// Sheets of a fixed-size run (`sheet_size`) that could not keep that size, because a chart
    /// is larger than the fixed sheet; each is rounded up to the allowed sides instead.
    pub sheets_off_size: usize,
    /// Wall-clock milliseconds per step (informative only; never affects the output).
    pub anchors_ms: f64,
    pub texel_clash_ms: f64,
    pub footprints_ms: f64,
    pub packing_ms: f64,
    pub finish_ms: f64,
    pub reshape_ms: f64,
    /// Wall-clock milliseconds of the steps of the pipeline's pack stage around the packings:
    /// taking the palette's faces out, the rigid split, the untangle (its anchors and its
    /// repair), cutting out the faces of texel clashes, and placing the palette.
    pub palette_faces_ms: f64,
    pub split_rigid_ms: f64,
    pub untangle_ms: f64,
    pub detach_ms: f64,
    pub palette_ms: f64,
}

/// What the split of rigid groups before packing did (all zero when it is off).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct RigidSplitReport {
    /// Rigid groups beyond the anchor, of at least `anchor_min_fraction` of their chart.
    pub candidates: usize,
    /// Those made charts of their own, and their faces (with the pieces of their chart that only
    /// they held to the rest).
    pub charts_made: usize,
    pub faces_moved: usize,
    /// The fraction of the atlas's 3-D area of the split groups, and the UV border the split
    /// opened over the border before (both sides of each new seam).
    pub area_fraction: f64,
    pub border_fraction: f64,
}

/// The packed atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct PackedLayout {
    /// Output texel-space position of each UV vertex, in its output sheet. Vertices no packed
    /// face uses keep their input value.
    pub vert_uv: Vec<[f64; 2]>,
    /// Output sheet of each face (`NONE` for faces left out).
    pub face_sheet: Vec<u32>,
    /// Trimmed output sheet sizes.
    pub sheet_sizes: Vec<(u32, u32)>,
    /// The face's output triangle is exactly `chart_transform.apply(orig)`, so its texels may be
    /// copied verbatim from its input sheet.
    pub face_preserved: Vec<bool>,
    /// Per chart: for anchored charts, the map from input texels of the chart's preserved source
    /// sheet to output texels of its output sheet.
    pub chart_transform: Vec<Option<GridTransform>>,
    /// Pairs of faces (input ids, in chart order) that still cover the centre of a texel they did
    /// not share in the input after the texel-clash step (`report.texel_clashes_left` of them).
    pub clashing_pairs: Vec<[u32; 2]>,
    pub report: PackReport,
}

/// Errors of the packing stage.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PackError {
    #[error("{what} has {got} entries, expected {expected}")]
    Length { what: &'static str, expected: usize, got: usize },
    #[error("face {face}: chart {chart} is not below the chart count {n_charts}")]
    Chart { face: u32, chart: u32, n_charts: usize },
    #[error("face {face}: input sheet {sheet} does not exist")]
    Sheet { face: u32, sheet: u32 },
    #[error("face {face}: corner {corner} has no valid UV vertex")]
    Corner { face: u32, corner: u32 },
    #[error("face {face}: non-finite UV coordinates")]
    NonFinite { face: u32 },
    #[error("UV vertex {vertex} is used by charts {a} and {b}")]
    SharedVertex { vertex: u32, a: u32, b: u32 },
    #[error("chart {chart} spans {extent:?} texels, too large to rasterize")]
    ChartTooLarge { chart: u32, extent: [f64; 2] },
    #[error("bad packing options: {0}")]
    Options(String),
    #[error("packer: {0}")]
    Packer(#[from] PackerError),
}
