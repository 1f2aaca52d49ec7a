//! `pack_layout`: the packing stage from final charts to output UVs, sheets and grid-preserving
//! transforms (see the module documentation of `pack` for the overall plan).

use crate::index::NONE;
use crate::timing::ms;
use std::time::Instant;

use rayon::prelude::*;

use super::anchor::{Anchor, RigidFace, best_group, ranked_groups, rigid_image};
use super::footprint::rasterize;
use super::frame::{ANCHOR_TRIES, Frame, FreeTurn, chart_frame, claim_group, refit, unclaim_chart};
use super::place::{Placed, place_and_trim};
use super::texel_clash::{ChartClashes, separate};
use super::{LayoutInput, PackError, PackOptions, PackReport, PackedLayout};
use crate::plugin::{ALL_ROTATIONS, PackItem, PackOutput, Packer, PackerError, check_packing};

/// Compressed lists: the members of group `g` are `items[start[g]..start[g + 1]]`.
pub(super) struct Csr {
    start: Vec<usize>,
    items: Vec<u32>,
}

impl Csr {
    pub(super) fn of(&self, g: usize) -> &[u32] {
        &self.items[self.start[g]..self.start[g + 1]]
    }
}

fn check_len(what: &'static str, got: usize, expected: usize) -> Result<(), PackError> {
    if got == expected { Ok(()) } else { Err(PackError::Length { what, expected, got }) }
}

/// Checks the shapes and values of the input, and returns the chart of every UV vertex
/// (`NONE` when no packed face uses it).
fn validate(input: &LayoutInput, opts: &PackOptions) -> Result<Vec<u32>, PackError> {
    let nf = input.face_chart.len();
    check_len("corner_vert", input.corner_vert.len(), 3 * nf)?;
    check_len("orig_uv", input.orig_uv.len(), 3 * nf)?;
    check_len("face_sheet", input.face_sheet.len(), nf)?;
    check_len("face_area_3d", input.face_area_3d.len(), nf)?;
    if opts.padding > 1 << 16 {
        return Err(PackError::Options(format!("padding {} is absurd", opts.padding)));
    }
    if !(0.0..=1.0).contains(&opts.anchor_min_fraction) {
        return Err(PackError::Options("anchor_min_fraction must be within 0..=1".into()));
    }
    if !(opts.rigid_tolerance.is_finite() && opts.rigid_tolerance >= 0.0) {
        return Err(PackError::Options("rigid_tolerance must be finite and ≥ 0".into()));
    }
    let mut vert_chart = vec![NONE; input.vert_uv.len()];
    for f in 0..nf {
        let chart = input.face_chart[f];
        if chart == NONE {
            continue;
        }
        let face = f as u32;
        if chart as usize >= input.n_charts {
            return Err(PackError::Chart { face, chart, n_charts: input.n_charts });
        }
        let sheet = input.face_sheet[f];
        if sheet as usize >= input.input_sheet_sizes.len() {
            return Err(PackError::Sheet { face, sheet });
        }
        for k in 0..3 {
            let v = input.corner_vert[3 * f + k];
            let Some(uv) = input.vert_uv.get(v as usize) else {
                return Err(PackError::Corner { face, corner: k as u32 });
            };
            let o = input.orig_uv[3 * f + k];
            if !(uv.iter().chain(&o).all(|x| x.is_finite())) {
                return Err(PackError::NonFinite { face });
            }
            let vc = &mut vert_chart[v as usize];
            if *vc == NONE {
                *vc = chart;
            } else if *vc != chart {
                return Err(PackError::SharedVertex { vertex: v, a: *vc, b: chart });
            }
        }
    }
    Ok(vert_chart)
}

/// The faces of each chart and the UV vertices of each chart (in order of first use).
fn chart_lists(input: &LayoutInput, vert_chart: &[u32]) -> (Csr, Csr) {
    let n = input.n_charts;
    let mut count = vec![0usize; n + 1];
    for &c in input.face_chart.iter().filter(|&&c| c != NONE) {
        count[c as usize + 1] += 1;
    }
    for i in 0..n {
        count[i + 1] += count[i];
    }
    let mut fill = count.clone();
    let mut items = vec![0u32; count[n]];
    for (f, &c) in input.face_chart.iter().enumerate().filter(|(_, c)| **c != NONE) {
        items[fill[c as usize]] = f as u32;
        fill[c as usize] += 1;
    }
    let faces = Csr { start: count, items };
    let mut vstart = vec![0usize; n + 1];
    for &c in vert_chart.iter().filter(|&&c| c != NONE) {
        vstart[c as usize + 1] += 1;
    }
    for i in 0..n {
        vstart[i + 1] += vstart[i];
    }
    let mut vfill = vstart.clone();
    let mut vitems = vec![0u32; vstart[n]];
    let mut seen = vec![false; vert_chart.len()];
    for c in 0..n {
        for &f in faces.of(c) {
            for k in 0..3 {
                let v = input.corner_vert[3 * f as usize + k];
                if !std::mem::replace(&mut seen[v as usize], true) {
                    vitems[vfill[c]] = v;
                    vfill[c] += 1;
                }
            }
        }
    }
    (faces, Csr { start: vstart, items: vitems })
}

#[inline]
fn corners(input: &LayoutInput, f: u32) -> ([[f64; 2]; 3], [[f64; 2]; 3]) {
    let f = f as usize;
    let orig = [input.orig_uv[3 * f], input.orig_uv[3 * f + 1], input.orig_uv[3 * f + 2]];
    let cur = [0, 1, 2].map(|k| input.vert_uv[input.corner_vert[3 * f + k] as usize]);
    (orig, cur)
}

#[inline]
fn area_of(a: f64) -> f64 {
    if a.is_finite() && a > 0.0 { a } else { 0.0 }
}

/// The faces of a chart that are rigid images of their original triangles, and the chart's 3D
/// area.
fn rigid_faces(input: &LayoutInput, faces: &[u32], opts: &PackOptions) -> (Vec<RigidFace>, f64) {
    let chart_area: f64 = faces.iter().map(|&f| area_of(input.face_area_3d[f as usize])).sum();
    let rigid = faces
        .iter()
        .filter_map(|&f| {
            let (orig, cur) = corners(input, f);
            let r = rigid_image(orig, cur, opts.rigid_tolerance)?;
            let area = area_of(input.face_area_3d[f as usize]);
            Some(RigidFace {
                face: f,
                rigid: r,
                sheet: input.face_sheet[f as usize],
                orig0: orig[0],
                cur0: cur[0],
                area,
            })
        })
        .collect();
    (rigid, chart_area)
}

/// The faces each chart's heaviest anchor group would preserve (the group [`pack_layout`] tries
/// first), for the stages before packing that must leave them alone. A chart that cannot keep
/// that group on a sheet loses it in the packer anyway, so this may mark more than is preserved,
/// never less.
pub fn anchor_faces(input: &LayoutInput, opts: &PackOptions) -> Result<Vec<bool>, PackError> {
    let vert_chart = validate(input, opts)?;
    let (faces, _) = chart_lists(input, &vert_chart);
    let mut marked = vec![false; input.face_chart.len()];
    for found in chart_anchors(input, &faces, opts) {
        if let Some((_, group)) = found.best {
            for f in group {
                marked[f as usize] = true;
            }
        }
    }
    Ok(marked)
}

/// The rigid groups of every chart after its anchor group (the heaviest), each with at least
/// `min_fraction` of its chart's 3-D area, as `(chart, chart's 3-D area, faces sorted)` in chart
/// order, then by weight.
/// Each such group copies its texels verbatim only if it becomes a chart of its own: the anchor
/// can put one rigid group per chart back on the input grid.
pub fn rigid_groups_beyond_anchor(
    input: &LayoutInput,
    opts: &PackOptions,
    min_fraction: f64,
) -> Result<Vec<(u32, f64, Vec<u32>)>, PackError> {
    let vert_chart = validate(input, opts)?;
    if !opts.keeps_input_grid() {
        return Ok(Vec::new());
    }
    let (faces, _) = chart_lists(input, &vert_chart);
    let found: Vec<Vec<(u32, f64, Vec<u32>)>> = (0..input.n_charts)
        .into_par_iter()
        .map(|c| {
            let fs = faces.of(c);
            if fs.is_empty() {
                return Vec::new();
            }
            let (mut rigid, chart_area) = rigid_faces(input, fs, opts);
            let min_area = opts.anchor_min_fraction * chart_area;
            let groups = ranked_groups(&mut rigid, min_area, ANCHOR_TRIES);
            groups
                .into_iter()
                .skip(1)
                .filter(|(a, _)| a.area >= min_fraction * chart_area)
                .map(|(_, mut faces)| {
                    faces.sort_unstable();
                    (c as u32, chart_area, faces)
                })
                .collect()
        })
        .collect();
    Ok(found.into_iter().flatten().collect())
}

/// The rigid faces of one chart (largest area first), the chart's 3-D area and its heaviest
/// anchor group, if any covers enough of it.
struct ChartAnchors {
    rigid: Vec<RigidFace>,
    min_area: f64,
    best: Option<(Anchor, Vec<u32>)>,
}

/// [`ChartAnchors`] of every chart, found in parallel: each is a pure function of its chart,
/// so the result does not depend on the thread count.
fn chart_anchors(input: &LayoutInput, faces: &Csr, opts: &PackOptions) -> Vec<ChartAnchors> {
    (0..input.n_charts)
        .into_par_iter()
        .map(|c| {
            let fs = faces.of(c);
            if fs.is_empty() || !opts.keeps_input_grid() {
                return ChartAnchors { rigid: Vec::new(), min_area: 0.0, best: None };
            }
            let (mut rigid, chart_area) = rigid_faces(input, fs, opts);
            let min_area = opts.anchor_min_fraction * chart_area;
            let best = best_group(&mut rigid, min_area);
            ChartAnchors { rigid, min_area, best }
        })
        .collect()
}

/// The charts of one packing: the input and each chart's faces and UV vertices.
#[derive(Clone, Copy)]
pub(super) struct Charts<'a> {
    pub(super) input: &'a LayoutInput<'a>,
    pub(super) faces: &'a Csr,
    pub(super) verts: &'a Csr,
}

/// What framing the charts decided: claimed vertices (their original UV, NaN when free), faces
/// whose texels are copied verbatim, every vertex's frame position, and the frame of each packed
/// chart (`packed` lists those charts in order).
pub(super) struct Framed {
    claim: Vec<[f64; 2]>,
    pub(super) face_preserved: Vec<bool>,
    pub(super) frame_uv: Vec<[f64; 2]>,
    pub(super) frames: Vec<Option<Frame>>,
    pub(super) packed: Vec<u32>,
}

/// Packs the charts of `input` onto sheets with `packer`; see [`PackedLayout`] for what comes
/// out. Deterministic for a deterministic packer; the packer's answer is checked exactly.
///
/// The stages: frames (anchors), texel-clash separation, footprints, the packer, placement and
/// trimming, then the sheet sizes asked for (`sheet_size`, `pow2`, `align`; see `sheet_size`).
/// Free space for blocks that are not charts (a palette, say) is to be asked for at the packer:
/// appended as further [`PackItem`]s after the charts' items, their placements come back in the
/// same order after the charts', and trimming and the sheet sizes then account for them.
pub fn pack_layout(
    input: &LayoutInput,
    packer: &dyn Packer,
    opts: &PackOptions,
) -> Result<PackedLayout, PackError> {
    let t = Instant::now();
    let vert_chart = validate(input, opts)?;
    super::sheet_size::check_sheet_shape(opts).map_err(PackError::Options)?;
    let max_sheet = super::max_sheet_size(opts, input.input_sheet_sizes);
    if max_sheet.0 == 0 || max_sheet.1 == 0 {
        return Err(PackError::Options(format!("sheet size {max_sheet:?} is empty")));
    }
    let scaled: Vec<[f64; 2]>;
    let scaled_input;
    let input = if opts.texel_scale == 1.0 {
        input
    } else {
        // Every chart's texel footprint scaled about the origin: a uniform scale keeps each
        // chart's shape, and the texture stage resamples every face from its original UVs.
        let s = opts.texel_scale;
        scaled = input.vert_uv.iter().map(|p| [p[0] * s, p[1] * s]).collect();
        scaled_input = LayoutInput { vert_uv: &scaled, ..*input };
        &scaled_input
    };
    let (faces, verts) = chart_lists(input, &vert_chart);
    let cx = Charts { input, faces: &faces, verts: &verts };
    let mut report = PackReport { max_sheet_size: max_sheet, ..PackReport::default() };
    let mut framed = frame_charts(cx, opts, max_sheet, &mut report)?;
    report.anchors_ms = ms(t);

    let t = Instant::now();
    let clashing_pairs = if opts.separate_texel_clashes && opts.texel_scale == 1.0 {
        separate_clashes(cx, &mut framed, opts.padding, &mut report)
    } else {
        Vec::new()
    };
    report.texel_clash_ms = ms(t);

    let t = Instant::now();
    let items = pack_items(cx, &framed, opts.padding)?;
    report.footprint_cells = items.iter().map(|i| i.footprint.count()).sum();
    report.footprints_ms = ms(t);

    let t = Instant::now();
    let input_texels: u64 =
        input.input_sheet_sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum();
    let mut packing = pack_on(cx, &framed, &items, packer, max_sheet, opts)?;
    report.packing_ms = ms(t);
    if packing.texels > input_texels && super::reshape::may_reshape(opts) {
        let t = Instant::now();
        let shapes = super::reshape::reshaped_limits(max_sheet, opts, &items);
        report.sheet_shapes_tried = shapes.len();
        packing = super::reshape::fewest_texels(
            packing,
            &shapes,
            |s| pack_on(cx, &framed, &items, packer, s, opts),
            |p| p.texels,
            |p| p.sizes.len(),
        )?;
        report.reshape_ms = ms(t);
    }
    let Packing { out, placed, sizes: sheet_sizes, limit, off_size, .. } = packing;
    report.max_sheet_size = limit;
    report.input_texels = input_texels;
    report.sheets_off_size = off_size;
    report.oversized_charts =
        out.oversized.iter().filter_map(|&i| framed.packed.get(i as usize).copied()).collect();

    let t = Instant::now();
    let face_sheet = finish_report(cx, &framed, &placed, &sheet_sizes, &mut report);
    report.finish_ms = ms(t);
    Ok(PackedLayout {
        vert_uv: placed.vert_uv,
        face_sheet,
        sheet_sizes,
        face_preserved: framed.face_preserved,
        chart_transform: placed.chart_transform,
        clashing_pairs,
        report,
    })
}

/// One packing of the charts' footprints on sheets of at most `limit`, placed and trimmed: the
/// packer's answer, the placement, the output sheet sizes, how many of them are off a fixed size,
/// and their texels.
struct Packing {
    out: PackOutput,
    placed: Placed,
    sizes: Vec<(u32, u32)>,
    limit: (u32, u32),
    off_size: usize,
    texels: u64,
}

/// Packs `items` (the footprints of the charts `st.packed`) on sheets of at most `limit`, then
/// places and trims them and gives the sheets the sizes the options ask for.
fn pack_on(
    cx: Charts,
    st: &Framed,
    items: &[PackItem],
    packer: &dyn Packer,
    limit: (u32, u32),
    opts: &PackOptions,
) -> Result<Packing, PackError> {
    let out = packer.pack(items, limit)?;
    check_packing(items, limit, &out)?;
    let placed = place_and_trim(cx, st, &out)?;
    let mut sizes = Vec::with_capacity(placed.sizes.len());
    let mut off_size = 0;
    for &trimmed in &placed.sizes {
        let (size, off) = super::sheet_size::output_sheet_size(trimmed, opts);
        off_size += usize::from(off);
        sizes.push(size);
    }
    let texels = sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum();
    Ok(Packing { out, placed, sizes, limit, off_size, texels })
}

/// (a) The frame of every chart with faces, anchored where one of its rigid groups fits a sheet.
fn frame_charts(
    cx: Charts,
    opts: &PackOptions,
    max_sheet: (u32, u32),
    report: &mut PackReport,
) -> Result<Framed, PackError> {
    let input = cx.input;
    let mut st = Framed {
        claim: vec![[f64::NAN; 2]; input.vert_uv.len()],
        face_preserved: vec![false; input.face_chart.len()],
        frame_uv: input.vert_uv.to_vec(),
        frames: vec![None; input.n_charts],
        packed: Vec::new(),
    };
    let mut scratch = Vec::new();
    for (c, found) in chart_anchors(input, cx.faces, opts).into_iter().enumerate() {
        if cx.faces.of(c).is_empty() {
            continue;
        }
        let frame =
            frame_chart(cx, c, found, max_sheet, opts.padding, &mut st, &mut scratch, report)?;
        report.anchored_charts += usize::from(frame.g0.is_some());
        st.frames[c] = Some(frame);
        st.packed.push(c as u32);
    }
    report.charts = st.packed.len();
    Ok(st)
}

/// The frame of chart `c` for one anchor group (claimed first) or for none, turned by `turn`.
fn frame_with(
    cx: Charts,
    c: usize,
    group: Option<&(Anchor, Vec<u32>)>,
    turn: FreeTurn,
    pad: u32,
    st: &mut Framed,
    scratch: &mut Vec<[f64; 2]>,
) -> Result<Frame, PackError> {
    if let Some((_, faces)) = group {
        claim_group(cx.input, faces, &mut st.claim, &mut st.face_preserved);
    }
    let anchor = group.map(|(a, _)| (a, &st.claim[..]));
    let verts = cx.verts.of(c);
    chart_frame(cx.input, c as u32, verts, anchor, turn, pad, &mut st.frame_uv, scratch)
}

/// The frame of chart `c`: its heaviest anchor group when that fits a sheet.
///
/// Turned to its anchor, a chart that fits a sheet in the merge frame may no longer fit (a
/// residual turn of up to 45° widens its box by up to √2): the lighter groups are tried, then no
/// anchor (minimum-area turn, then the merge frame, whose box the merge stage bounded), and only
/// then does it get an oversized sheet with its heaviest anchor.
#[allow(clippy::too_many_arguments)]
fn frame_chart(
    cx: Charts,
    c: usize,
    found: ChartAnchors,
    max_sheet: (u32, u32),
    pad: u32,
    st: &mut Framed,
    scratch: &mut Vec<[f64; 2]>,
    report: &mut PackReport,
) -> Result<Frame, PackError> {
    let (fs, vs) = (cx.faces.of(c), cx.verts.of(c));
    let fits = |f: &Frame| {
        let (w, h) = (f.width, f.height);
        (w <= max_sheet.0 && h <= max_sheet.1) || (h <= max_sheet.0 && w <= max_sheet.1)
    };
    let ChartAnchors { mut rigid, min_area, best } = found;
    if best.is_some() {
        let f = frame_with(cx, c, best.as_ref(), FreeTurn::MinArea, pad, st, scratch)?;
        if fits(&f) {
            return Ok(f);
        }
        unclaim_chart(vs, fs, &mut st.claim, &mut st.face_preserved);
        for group in ranked_groups(&mut rigid, min_area, ANCHOR_TRIES).iter().skip(1) {
            let f = frame_with(cx, c, Some(group), FreeTurn::MinArea, pad, st, scratch)?;
            if fits(&f) {
                report.anchors_changed_to_fit += 1;
                return Ok(f);
            }
            unclaim_chart(vs, fs, &mut st.claim, &mut st.face_preserved);
        }
    }
    for turn in [FreeTurn::MinArea, FreeTurn::AsMerged] {
        let f = frame_with(cx, c, None, turn, pad, st, scratch)?;
        if fits(&f) || (best.is_none() && turn == FreeTurn::AsMerged) {
            report.anchors_dropped_to_fit += usize::from(best.is_some());
            return Ok(f);
        }
    }
    frame_with(cx, c, best.as_ref(), FreeTurn::AsMerged, pad, st, scratch)
}

/// (a') Texel clashes, separated chart by chart in parallel in the final frames (each chart's
/// result is a pure function of it), then applied and the frames refitted in chart order.
/// Returns the pairs left clashing.
fn separate_clashes(
    cx: Charts,
    st: &mut Framed,
    pad: u32,
    report: &mut PackReport,
) -> Vec<[u32; 2]> {
    let input = cx.input;
    // The index of each UV vertex in its chart's vertex list.
    let mut vert_local = vec![0u32; input.vert_uv.len()];
    for &c in &st.packed {
        for (i, &v) in cx.verts.of(c as usize).iter().enumerate() {
            vert_local[v as usize] = i as u32;
        }
    }
    let found: Vec<ChartClashes> = st
        .packed
        .par_iter()
        .map(|&c| {
            let c = c as usize;
            separate(
                input,
                cx.faces.of(c),
                cx.verts.of(c),
                &vert_local,
                &st.frame_uv,
                |v| !st.claim[v as usize][0].is_nan(),
                |f| st.face_preserved[f as usize],
            )
        })
        .collect();
    let mut clashing_pairs = Vec::new();
    for (&c, r) in st.packed.iter().zip(found) {
        report.texel_clashes += r.found;
        report.texel_clashes_left += r.left.len();
        clashing_pairs.extend_from_slice(&r.left);
        report.texel_clash_vertices_moved += r.moves.len();
        report.texel_clash_vertices_freed += r.freed.len();
        if !r.freed.is_empty() {
            // A freed vertex is no longer held at its grid image, and its faces are resampled.
            for &v in &r.freed {
                st.claim[v as usize] = [f64::NAN; 2];
            }
            for &f in cx.faces.of(c as usize) {
                let corners = [0, 1, 2].map(|k| input.corner_vert[3 * f as usize + k]);
                if corners.iter().any(|v| r.freed.contains(v)) {
                    st.face_preserved[f as usize] = false;
                }
            }
        }
        if r.moves.is_empty() {
            continue;
        }
        for (v, d) in r.moves {
            let p = &mut st.frame_uv[v as usize];
            *p = [p[0] + d[0], p[1] + d[1]];
        }
        if let Some(frame) = st.frames[c as usize].as_mut() {
            refit(frame, cx.verts.of(c as usize), &mut st.frame_uv, pad);
        }
    }
    clashing_pairs
}

/// (b) Footprints, one per packed chart, rasterized in parallel (the result is independent of
/// the thread count: each footprint is a pure function of its chart).
fn pack_items(cx: Charts, st: &Framed, pad: u32) -> Result<Vec<PackItem>, PackerError> {
    st.packed
        .par_iter()
        .map(|&c| {
            let fr = st.frames[c as usize]
                .as_ref()
                .ok_or_else(|| PackerError::Failed("frame".into()))?;
            let tris = cx.faces.of(c as usize).iter().map(|&f| {
                [0, 1, 2].map(|k| st.frame_uv[cx.input.corner_vert[3 * f as usize + k] as usize])
            });
            let footprint = rasterize(tris, fr.width, fr.height, pad)?;
            Ok(PackItem { footprint, rotations: ALL_ROTATIONS })
        })
        .collect()
}

/// The output sheet of every face, and the report's figures of the final layout.
fn finish_report(
    cx: Charts,
    st: &Framed,
    placed: &Placed,
    sheet_sizes: &[(u32, u32)],
    report: &mut PackReport,
) -> Vec<u32> {
    let input = cx.input;
    let mut face_sheet = vec![NONE; input.face_chart.len()];
    let mut uv_area = 0.0;
    let (mut all_area, mut kept_area) = (0.0, 0.0);
    for (i, &c) in st.packed.iter().enumerate() {
        let s = placed.chart_sheet[i];
        for &f in cx.faces.of(c as usize) {
            face_sheet[f as usize] = s;
            let t =
                [0, 1, 2].map(|k| placed.vert_uv[input.corner_vert[3 * f as usize + k] as usize]);
            uv_area += 0.5
                * ((t[1][0] - t[0][0]) * (t[2][1] - t[0][1])
                    - (t[1][1] - t[0][1]) * (t[2][0] - t[0][0]))
                    .abs();
            let a = area_of(input.face_area_3d[f as usize]);
            all_area += a;
            if st.face_preserved[f as usize] {
                kept_area += a;
                report.preserved_faces += 1;
            }
        }
    }
    report.preserved_area_fraction = if all_area > 0.0 { kept_area / all_area } else { 0.0 };
    report.sheets = sheet_sizes.len();
    report.texels = sheet_sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum();
    report.occupancy = if report.texels > 0 { uv_area / report.texels as f64 } else { 0.0 };
    face_sheet
}
