//! Placement and trimming (stages d and e of `pack_layout`): each chart's grid transform from
//! its frame and the packer's placement, preserved corners on their exact grid image, and the
//! sheets trimmed to the smallest integer boxes holding every UV strictly inside.

use super::PackError;
use super::anchor::compose;
use super::layout::{Charts, Framed};
use crate::geometry::GridTransform;
use crate::index::NONE;
use crate::plugin::{PackOutput, PackerError, quarter_turn_frame};

/// Where the charts landed: output UVs, grid maps of anchored charts, the output sheet of each
/// packed chart (by its index in `packed`) and the trimmed sheet sizes.
pub(super) struct Placed {
    pub(super) vert_uv: Vec<[f64; 2]>,
    pub(super) chart_transform: Vec<Option<GridTransform>>,
    pub(super) chart_sheet: Vec<u32>,
    pub(super) sizes: Vec<(u32, u32)>,
}

/// The output sheet of each packer sheet, numbered in order of first use.
fn renumber_sheets(out: &PackOutput) -> (Vec<u32>, usize) {
    let mut sheet_id = vec![NONE; out.sheets.len()];
    let mut n_sheets = 0u32;
    for p in &out.placements {
        if sheet_id[p.sheet as usize] == NONE {
            sheet_id[p.sheet as usize] = n_sheets;
            n_sheets += 1;
        }
    }
    (sheet_id, n_sheets as usize)
}

/// (d, e) Placement maps, sheets renumbered in order of use and trimmed to the used texels: the
/// smallest integer box holding every UV strictly inside, found in at most four rounds.
pub(super) fn place_and_trim(
    cx: Charts,
    st: &Framed,
    out: &PackOutput,
) -> Result<Placed, PackError> {
    let (sheet_id, n_sheets) = renumber_sheets(out);
    let chart_sheet: Vec<u32> = out.placements.iter().map(|p| sheet_id[p.sheet as usize]).collect();
    let mut placed = Placed {
        vert_uv: cx.input.vert_uv.to_vec(),
        chart_transform: vec![None; cx.input.n_charts],
        chart_sheet,
        sizes: vec![(0, 0); n_sheets],
    };
    let mut trims = vec![[0i64; 2]; n_sheets];
    for _round in 0..4 {
        let bounds = place_round(cx, st, out, &trims, &mut placed);
        if !trim_sheets(&bounds, &mut trims, &mut placed.sizes) {
            if placed.sizes.iter().any(|&(w, h)| w == 0 || h == 0) {
                break;
            }
            return Ok(placed);
        }
    }
    Err(PackError::Packer(PackerError::Failed(
        "trimming did not converge to sheets holding every UV strictly inside".into(),
    )))
}

/// Places every vertex with the sheets' current trims; preserved corners get their exact grid
/// image. Returns the bounds `(lo, hi)` of the UVs on each sheet.
fn place_round(
    cx: Charts,
    st: &Framed,
    out: &PackOutput,
    trims: &[[i64; 2]],
    placed: &mut Placed,
) -> Vec<([f64; 2], [f64; 2])> {
    let input = cx.input;
    let mut bounds = vec![([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]); trims.len()];
    for (i, &c) in st.packed.iter().enumerate() {
        let c = c as usize;
        let s = placed.chart_sheet[i] as usize;
        let (p, fr) = (out.placements[i], st.frames[c].as_ref());
        let dims = fr.map_or((0, 0), |f| (f.width, f.height));
        let mut g = quarter_turn_frame(p.quarter_turns, dims.0, dims.1);
        g.offset[0] += i64::from(p.x) - trims[s][0];
        g.offset[1] += i64::from(p.y) - trims[s][1];
        for &v in cx.verts.of(c) {
            placed.vert_uv[v as usize] = g.apply(st.frame_uv[v as usize]);
        }
        placed.chart_transform[c] = fr.and_then(|f| f.g0).map(|g0| compose(&g, &g0));
        if let Some(f_map) = placed.chart_transform[c] {
            for &f in cx.faces.of(c).iter().filter(|&&f| st.face_preserved[f as usize]) {
                for k in 0..3 {
                    let v = input.corner_vert[3 * f as usize + k] as usize;
                    placed.vert_uv[v] = f_map.apply(input.orig_uv[3 * f as usize + k]);
                }
            }
        }
        let (lo, hi) = &mut bounds[s];
        for &v in cx.verts.of(c) {
            let p = placed.vert_uv[v as usize];
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    bounds
}

/// Trims each sheet to the smallest integer box holding its UVs strictly inside. A sheet needs
/// another round only if rounding put a UV on its border; returns whether any does.
fn trim_sheets(
    bounds: &[([f64; 2], [f64; 2])],
    trims: &mut [[i64; 2]],
    sizes: &mut [(u32, u32)],
) -> bool {
    let mut again = false;
    for (s, &(lo, hi)) in bounds.iter().enumerate() {
        let strict = sizes[s] != (0, 0)
            && (0..2).all(|k| {
                let size = if k == 0 { sizes[s].0 } else { sizes[s].1 };
                lo[k] > 0.0 && hi[k] < f64::from(size)
            });
        if strict {
            continue;
        }
        again = true;
        let mut size = [0u32; 2];
        for k in 0..2 {
            let first = lo[k].ceil() - 1.0;
            let last = hi[k].floor();
            let extra = if sizes[s] == (0, 0) { 0.0 } else { 1.0 };
            let cut = first - extra;
            trims[s][k] += cut as i64;
            size[k] = (last - cut + 1.0 + extra) as u32;
        }
        sizes[s] = (size[0], size[1]);
    }
    again
}
