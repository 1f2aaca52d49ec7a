//! Frequency-based chart splitting (paper §4.2): Algorithm 1 (chart adding, growing and merging,
//! [`flood_partition`]) run on each chart separately with the metric `F(f, l) = |l − l_f|·a_f`,
//! giving sub-charts linked to (photo, pyramid level).
//!
//! One deliberate restriction on top of the paper: a face may only join a sub-chart at its own
//! level or a finer one (`l ≤ l_f`), and only at a level some face of the chart has. `F` still
//! ranks the candidates, but no face is ever textured coarser than the level that preserves its
//! detail, so the saving never costs detail; isolated fine faces become small sub-charts of
//! their own instead of being blurred into a coarse neighbour.
//!
//! Splitting a chart adds borders, each with packing padding. A chart whose sub-charts would
//! need more texels (padded bounding rectangles) than the whole chart at its finest level is
//! kept whole at that level.

use rayon::prelude::*;

use super::partition::{Metric, NONE, flood_partition};
use super::pyramid::{MAX_LEVELS, to_level};

/// The sub-charts of a split.
#[derive(Clone, Debug, Default)]
pub struct Split {
    /// Sub-chart of each face; [`NONE`] where the face has no chart.
    pub face_sub: Vec<u32>,
    /// Parent chart of each sub-chart.
    pub sub_chart: Vec<u32>,
    /// Pyramid level of each sub-chart.
    pub sub_level: Vec<u8>,
    /// Sub-charts before the per-chart merging (sum over charts).
    pub before_merge: usize,
    /// Charts left whole because splitting them would not have saved texels.
    pub kept_whole: usize,
    /// Padded bounding rectangles of the charts at level 0, in texels.
    pub rect_texels_before: u64,
    /// Padded bounding rectangles of the sub-charts at their levels, in texels.
    pub rect_texels_after: u64,
}

/// `F` on one chart's faces (local indices).
struct Frequency<'a> {
    level: &'a [u8],
    area: &'a [f64],
    /// Levels present in the chart, increasing.
    present: &'a [u32],
}

impl Metric for Frequency<'_> {
    fn labels(&self) -> usize {
        MAX_LEVELS
    }
    fn allowed(&self, f: usize) -> &[u32] {
        let l = u32::from(self.level[f]);
        &self.present[..self.present.partition_point(|&p| p <= l)]
    }
    fn cost(&self, f: usize, l: u32) -> f64 {
        f64::from(l.abs_diff(u32::from(self.level[f]))) * self.area[f]
    }
}

/// Inputs of [`split_charts`], all indexed by mesh face (corners `3f + k` for `uv0`).
pub struct SplitInput<'a> {
    pub face_chart: &'a [u32],
    pub n_charts: usize,
    /// Level of each face (after smoothing).
    pub level: &'a [u8],
    pub adj: &'a [[u32; 3]],
    pub area: &'a [f64],
    /// Corner projections into the chart's photo, level-0 texel space.
    pub uv0: &'a [[f64; 2]],
    /// Photo height of each chart (for the level mapping).
    pub chart_height: &'a [u32],
    /// Free texels around a packed chart.
    pub padding: u32,
    pub max_rounds: u32,
}

/// Splits every chart; see the module documentation. Charts are processed in parallel, each
/// independently, so the result does not depend on the thread count.
pub fn split_charts(inp: &SplitInput) -> Split {
    let nf = inp.face_chart.len();
    // Faces of each chart in increasing order (counting sort).
    let mut start = vec![0usize; inp.n_charts + 1];
    for &c in inp.face_chart.iter().filter(|&&c| c != NONE) {
        start[c as usize + 1] += 1;
    }
    for c in 0..inp.n_charts {
        start[c + 1] += start[c];
    }
    let mut fill = start.clone();
    let mut faces = vec![0u32; start[inp.n_charts]];
    for (f, &c) in inp.face_chart.iter().enumerate() {
        if c != NONE {
            faces[fill[c as usize]] = f as u32;
            fill[c as usize] += 1;
        }
    }
    let per_chart: Vec<ChartSplit> = (0..inp.n_charts)
        .into_par_iter()
        .map(|c| split_one(inp, c as u32, &faces[start[c]..start[c + 1]]))
        .collect();
    // Global sub-chart ids: chart by chart, then in each chart's order of first face.
    let mut out = Split { face_sub: vec![NONE; nf], ..Split::default() };
    for (c, cs) in per_chart.iter().enumerate() {
        let base = out.sub_chart.len() as u32;
        for &l in &cs.levels {
            out.sub_chart.push(c as u32);
            out.sub_level.push(l);
        }
        for (&f, &s) in faces[start[c]..start[c + 1]].iter().zip(&cs.local) {
            out.face_sub[f as usize] = base + s;
        }
        out.before_merge += cs.before_merge;
        out.kept_whole += usize::from(cs.kept_whole);
        out.rect_texels_before += cs.rect_before;
        out.rect_texels_after += cs.rect_after;
    }
    out
}

/// One chart's split, in local face order.
struct ChartSplit {
    local: Vec<u32>,
    levels: Vec<u8>,
    before_merge: usize,
    kept_whole: bool,
    rect_before: u64,
    rect_after: u64,
}

fn split_one(inp: &SplitInput, c: u32, faces: &[u32]) -> ChartSplit {
    let n = faces.len();
    let h0 = inp.chart_height[c as usize];
    // Local indices of the chart's faces: binary search in the sorted face list.
    let local_of = |g: u32| faces.binary_search(&g).ok().map(|i| i as u32);
    let adj: Vec<[u32; 3]> = faces
        .iter()
        .map(|&f| {
            inp.adj[f as usize].map(|g| {
                if g != NONE && inp.face_chart[g as usize] == c {
                    local_of(g).unwrap_or(NONE)
                } else {
                    NONE
                }
            })
        })
        .collect();
    let level: Vec<u8> = faces.iter().map(|&f| inp.level[f as usize]).collect();
    let area: Vec<f64> = faces.iter().map(|&f| inp.area[f as usize]).collect();
    let mut present: Vec<u32> = level.iter().map(|&l| u32::from(l)).collect();
    present.sort_unstable();
    present.dedup();
    let finest = present.first().copied().unwrap_or(0) as u8;
    let rect_before = rect_texels(inp, faces, 0, h0);
    let whole = |kept_whole| ChartSplit {
        local: vec![0; n],
        levels: vec![finest],
        before_merge: 1,
        kept_whole,
        rect_before,
        rect_after: rect_texels(inp, faces, finest, h0),
    };
    if present.len() <= 1 {
        return whole(false);
    }
    let metric = Frequency { level: &level, area: &area, present: &present };
    let r = flood_partition(&adj, &metric, inp.max_rounds);
    // Every face allows the chart's finest level, so the flooding reaches every face.
    if r.face_chart.contains(&NONE) {
        return whole(false);
    }
    // Bounding boxes of the sub-charts at their levels, in one pass over the faces.
    let mut boxes = vec![EMPTY_BOX; r.chart_label.len()];
    for (i, &s) in r.face_chart.iter().enumerate() {
        grow_box(&mut boxes[s as usize], inp, faces[i], r.chart_label[s as usize] as u8, h0);
    }
    let rect_after: u64 = boxes.iter().map(|b| padded_texels(b, inp.padding)).sum();
    let whole_after = rect_texels(inp, faces, finest, h0);
    if rect_after >= whole_after {
        return whole(true);
    }
    ChartSplit {
        local: r.face_chart,
        levels: r.chart_label.iter().map(|&l| l as u8).collect(),
        before_merge: r.charts_before_merge,
        kept_whole: false,
        rect_before,
        rect_after,
    }
}

const EMPTY_BOX: [f64; 4] = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];

/// Grows `b` by face `f`'s corners at `level`.
fn grow_box(b: &mut [f64; 4], inp: &SplitInput, f: u32, level: u8, h0: u32) {
    for k in 0..3 {
        let p = to_level(inp.uv0[3 * f as usize + k], usize::from(level), h0);
        b[0] = b[0].min(p[0]);
        b[1] = b[1].min(p[1]);
        b[2] = b[2].max(p[0]);
        b[3] = b[3].max(p[1]);
    }
}

/// Texels of a box on the texel grid with `padding` free texels on every side.
fn padded_texels(b: &[f64; 4], padding: u32) -> u64 {
    if !(b[0] <= b[2] && b[1] <= b[3]) {
        return 0;
    }
    let pad = 2.0 * f64::from(padding);
    let w = (b[2].ceil() - b[0].floor()).max(1.0) + pad;
    let h = (b[3].ceil() - b[1].floor()).max(1.0) + pad;
    (w * h) as u64
}

/// Texels of the padded bounding rectangle of `faces` at `level`.
fn rect_texels(inp: &SplitInput, faces: &[u32], level: u8, h0: u32) -> u64 {
    let mut b = EMPTY_BOX;
    for &f in faces {
        grow_box(&mut b, inp, f, level, h0);
    }
    padded_texels(&b, inp.padding)
}
