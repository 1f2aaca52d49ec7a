//! UV charts: edge-connected UV components, the split of UV vertices shared by several charts,
//! per-chart REPEAT rebasing, UV twins and the per-chart cached quantities (digest §3.1, §3.3).

use super::edges::Adjacency;
use super::ids::{ChartId, HalfEdgeId, PosId, UvVertId};
use super::texel::{FrozenReasons, rebase_shift, signed_area2};
use crate::index::NONE;
use crate::index::SheetId;
use crate::union_find::UnionFind;
use crate::vec3::triangle_area;

/// A chart and the quantities the scorer reads from it (reference `FaceGroup::UpdateCache`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Chart {
    /// Frozen charts are made of isolated faces only (see `FrozenReasons::is_isolated`) and take
    /// part in no operation.
    pub frozen: bool,
    /// The sheet of its faces (a UV vertex includes the sheet, so a chart never mixes sheets).
    pub sheet: Option<SheetId>,
    pub n_faces: u32,
    /// Sum of the signed texel-space areas of its faces (texel²).
    pub area_signed: f64,
    /// `|area_signed|`: the reference's `AreaUV`.
    pub area_uv: f64,
    /// Whether `area_signed < 0` (the chart is mirrored in UV).
    pub flipped: bool,
    pub area_3d: f64,
    /// Texel-space length of its UV border: every side without a UV twin in the chart (seams on
    /// both sides, intra-chart seams twice, mesh boundaries, non-manifold and frozen borders).
    pub perimeter_uv: f64,
    /// Texel-space bounding box `[min u, min v, max u, max v]` of its UV vertices (all zeros for a
    /// chart without usable UVs).
    pub bbox: [f64; 4],
}

/// The corners of two sides of one mesh edge, paired by welded position (never by corner order,
/// so inconsistently oriented neighbours pair correctly): `[(a0, b?), (a1, b?)]`.
#[inline]
pub(crate) fn pair_corners(corner_pos: &[PosId], a: HalfEdgeId, b: HalfEdgeId) -> [[usize; 2]; 2] {
    let (a0, a1, b0, b1) = (a.idx(), a.next().idx(), b.idx(), b.next().idx());
    if corner_pos[a0] == corner_pos[b0] { [[a0, b0], [a1, b1]] } else { [[a0, b1], [a1, b0]] }
}

/// Output of chart labelling.
pub(crate) struct Labels {
    pub face_chart: Vec<ChartId>,
    pub n_charts: usize,
    /// Edge-connected components over all faces with usable UVs, frozen or not: the evaluator's
    /// `charts_edge`.
    pub uv_components: usize,
}

/// Labels charts: mergeable faces join across two-sided edges whose sides share both UV
/// vertices; isolated faces join only other isolated faces, across any edge whose sides share both
/// UV vertices. Chart ids follow the order of each chart's first face.
pub(crate) fn label_charts(
    adj: &Adjacency,
    corner_pos: &[PosId],
    corner_weld: &[u32],
    face_flags: &[FrozenReasons],
) -> Labels {
    let nf = face_flags.len();
    let mut charts = UnionFind::new(nf);
    let mut components = UnionFind::new(nf);
    let mut scratch: Vec<(u32, u32, u32)> = Vec::new();
    let weld_pair = |h: HalfEdgeId| {
        let (x, y) = (corner_weld[h.idx()], corner_weld[h.next().idx()]);
        if x <= y { (x, y) } else { (y, x) }
    };
    for e in &adj.edges {
        let sides = &adj.edge_sides[e.sides()];
        if e.n_sides == 2 && !e.is_degenerate() {
            let (a, b) = (sides[0], sides[1]);
            let (fa, fb) = (a.face(), b.face());
            if !(face_flags[fa].has_usable_uv() && face_flags[fb].has_usable_uv()) {
                continue;
            }
            let [[a0, b0], [a1, b1]] = pair_corners(corner_pos, a, b);
            if corner_weld[a0] == corner_weld[b0] && corner_weld[a1] == corner_weld[b1] {
                components.union(fa, fb);
                if face_flags[fa].is_isolated() == face_flags[fb].is_isolated() {
                    charts.union(fa, fb);
                }
            }
        } else if e.n_sides > 1 {
            // Non-manifold and degenerate edges: every face on them is frozen, so sides sharing
            // the same UV pair join both partitions (charts only between faces of the same
            // isolation, so a chart is never part isolated, part mergeable).
            scratch.clear();
            for &h in sides {
                if face_flags[h.face()].has_usable_uv() {
                    let (x, y) = weld_pair(h);
                    scratch.push((x, y, h.face() as u32));
                }
            }
            scratch.sort_unstable();
            for w in scratch.windows(2) {
                if (w[0].0, w[0].1) == (w[1].0, w[1].1) {
                    components.union(w[0].2 as usize, w[1].2 as usize);
                    let (f0, f1) = (w[0].2 as usize, w[1].2 as usize);
                    if face_flags[f0].is_isolated() == face_flags[f1].is_isolated() {
                        charts.union(w[0].2 as usize, w[1].2 as usize);
                    }
                }
            }
        }
    }
    let mut label = vec![ChartId::NONE; nf];
    let mut face_chart = vec![ChartId::NONE; nf];
    let mut n_charts = 0;
    let mut uv_components = 0;
    for (f, chart) in face_chart.iter_mut().enumerate() {
        let r = charts.find(f);
        if label[r].is_none() {
            label[r] = ChartId::from_usize(n_charts);
            n_charts += 1;
        }
        *chart = label[r];
        if components.find(f) == f {
            uv_components += 1;
        }
    }
    Labels { face_chart, n_charts, uv_components }
}

/// The UV vertex tables.
pub(crate) struct UvVertices {
    pub corner_uv: Vec<UvVertId>,
    pub uv_pos: Vec<[f64; 2]>,
    pub uv_vpos: Vec<PosId>,
    pub uv_chart: Vec<ChartId>,
}

/// Creates one UV vertex per `(weld, chart)`, so a welded UV vertex shared by several charts
/// (bow-ties, frozen faces touching mergeable ones) is split and every UV vertex belongs to
/// exactly one chart. Corners without usable UVs each get a vertex of their own at the origin.
/// Ids follow corner order.
pub(crate) fn split_uv_vertices(
    corner_weld: &[u32],
    n_weld: usize,
    face_chart: &[ChartId],
    corner_pos: &[PosId],
    corner_texel: &[[f64; 2]],
) -> UvVertices {
    let nc = corner_weld.len();
    let mut head = vec![NONE; n_weld];
    // `next` chains the vertices made from one weld (almost always a single one).
    let mut next: Vec<u32> = Vec::with_capacity(n_weld);
    let mut out = UvVertices {
        corner_uv: vec![UvVertId::NONE; nc],
        uv_pos: Vec::with_capacity(n_weld),
        uv_vpos: Vec::with_capacity(n_weld),
        uv_chart: Vec::with_capacity(n_weld),
    };
    for c in 0..nc {
        let chart = face_chart[c / 3];
        let w = corner_weld[c];
        let mut found = NONE;
        if w != NONE {
            let mut u = head[w as usize];
            while u != NONE {
                if out.uv_chart[u as usize] == chart {
                    found = u;
                    break;
                }
                u = next[u as usize];
            }
        }
        if found == NONE {
            found = out.uv_pos.len() as u32;
            out.uv_pos.push(corner_texel[c]);
            out.uv_vpos.push(corner_pos[c]);
            out.uv_chart.push(chart);
            if w != NONE {
                next.push(head[w as usize]);
                head[w as usize] = found;
            } else {
                next.push(NONE);
            }
        }
        out.corner_uv[c] = UvVertId(found);
    }
    out
}

/// Shifts every chart whose texel bounding box leaves its sheet by whole periods (REPEAT
/// wrapping, digest §2.9), in both the current UV vertices and the original corner UVs, so the
/// resampler never needs to wrap. Runs before the chart caches are computed, so they see the
/// rebased positions. Returns the number of charts moved.
pub(crate) fn rebase_charts(
    n_charts: usize,
    sheet_sizes: &[Option<(u32, u32)>],
    face_sheet: &[u32],
    face_flags: &[FrozenReasons],
    face_chart: &[ChartId],
    uv: &mut UvVertices,
    corner_texel: &mut [[f64; 2]],
) -> u64 {
    // The period of each chart: the size of its sheet, when every face of the chart has finite
    // UVs on a sheet of known size (faces without one are frozen in charts of their own kind).
    let mut period: Vec<Option<(u32, u32)>> = vec![None; n_charts];
    for (f, flags) in face_flags.iter().enumerate() {
        if flags.has_usable_uv() && !flags.has(FrozenReasons::NO_SHEET) {
            period[face_chart[f].idx()] = sheet_sizes[face_sheet[f] as usize];
        }
    }
    let mut bbox =
        vec![[f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY]; n_charts];
    for (p, c) in uv.uv_pos.iter().zip(&uv.uv_chart) {
        let b = &mut bbox[c.idx()];
        *b = [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])];
    }
    let mut shift: Vec<[f64; 2]> = vec![[0.0; 2]; n_charts];
    let mut rebased = 0;
    for c in 0..n_charts {
        if let Some(s) = period[c].and_then(|size| rebase_shift(bbox[c], size)) {
            shift[c] = s;
            rebased += 1;
        }
    }
    if rebased > 0 {
        for (p, c) in uv.uv_pos.iter_mut().zip(&uv.uv_chart) {
            let s = shift[c.idx()];
            *p = [p[0] + s[0], p[1] + s[1]];
        }
        for (c, t) in corner_texel.iter_mut().enumerate() {
            let s = shift[face_chart[c / 3].idx()];
            *t = [t[0] + s[0], t[1] + s[1]];
        }
    }
    rebased
}

/// Computes the UV twin of every half-edge (the other side of the same mesh edge in the same
/// chart with the same two UV vertices; `NONE` on UV borders) and the per-chart caches.
#[allow(clippy::too_many_arguments)]
pub(crate) fn chart_caches(
    adj: &Adjacency,
    positions: &[[f64; 3]],
    face_vertices: &[[usize; 3]],
    face_flags: &[FrozenReasons],
    face_sheet: &[u32],
    face_chart: &[ChartId],
    n_charts: usize,
    uv: &UvVertices,
) -> (Vec<Chart>, Vec<HalfEdgeId>) {
    let nf = face_flags.len();
    let mut charts = vec![
        Chart {
            frozen: false,
            sheet: None,
            n_faces: 0,
            area_signed: 0.0,
            area_uv: 0.0,
            flipped: false,
            area_3d: 0.0,
            perimeter_uv: 0.0,
            bbox: [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY],
        };
        n_charts
    ];
    for f in 0..nf {
        let ch = &mut charts[face_chart[f].idx()];
        ch.frozen = face_flags[f].is_isolated();
        ch.sheet = (face_sheet[f] != NONE).then_some(SheetId(face_sheet[f]));
        ch.n_faces += 1;
        let v = face_vertices[f];
        ch.area_3d += triangle_area([positions[v[0]], positions[v[1]], positions[v[2]]]);
        if face_flags[f].has_usable_uv() {
            let t = |k: usize| uv.uv_pos[uv.corner_uv[3 * f + k].idx()];
            ch.area_signed += 0.5 * signed_area2(t(0), t(1), t(2));
        }
    }
    for (p, c) in uv.uv_pos.iter().zip(&uv.uv_chart) {
        let b = &mut charts[c.idx()].bbox;
        *b = [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])];
    }
    for ch in &mut charts {
        ch.area_uv = ch.area_signed.abs();
        ch.flipped = ch.area_signed < 0.0;
        if !(ch.bbox[0] <= ch.bbox[2] && ch.bbox[1] <= ch.bbox[3]) {
            ch.bbox = [0.0; 4];
        }
    }

    let nh = 3 * nf;
    let mut he_uv_twin = vec![HalfEdgeId::NONE; nh];
    let mut border = vec![true; nh];
    let uv_pair = |h: HalfEdgeId| {
        let (x, y) = (uv.corner_uv[h.idx()], uv.corner_uv[h.next().idx()]);
        if x <= y { (x, y) } else { (y, x) }
    };
    let mut scratch: Vec<(UvVertId, UvVertId, HalfEdgeId)> = Vec::new();
    for e in &adj.edges {
        let sides = &adj.edge_sides[e.sides()];
        if sides.len() == 2 && uv_pair(sides[0]) == uv_pair(sides[1]) {
            // Equal UV vertices imply the same chart (a UV vertex has one chart).
            border[sides[0].idx()] = false;
            border[sides[1].idx()] = false;
            if !e.is_degenerate() {
                he_uv_twin[sides[0].idx()] = sides[1];
                he_uv_twin[sides[1].idx()] = sides[0];
            }
        } else if sides.len() > 2 {
            scratch.clear();
            scratch.extend(sides.iter().map(|&h| {
                let (x, y) = uv_pair(h);
                (x, y, h)
            }));
            scratch.sort_unstable();
            for w in scratch.windows(2) {
                if (w[0].0, w[0].1) == (w[1].0, w[1].1) {
                    border[w[0].2.idx()] = false;
                    border[w[1].2.idx()] = false;
                }
            }
        }
    }
    for (h, &b) in border.iter().enumerate() {
        if b {
            let he = HalfEdgeId::from_usize(h);
            let (p, q) =
                (uv.uv_pos[uv.corner_uv[h].idx()], uv.uv_pos[uv.corner_uv[he.next().idx()].idx()]);
            charts[face_chart[h / 3].idx()].perimeter_uv +=
                crate::geometry::norm(q[0] - p[0], q[1] - p[1]);
        }
    }
    (charts, he_uv_twin)
}
