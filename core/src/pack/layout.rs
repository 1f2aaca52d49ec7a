//! `pack_layout`: the packing stage from final charts to output UVs, sheets and grid-preserving
//! transforms (see the module documentation of `pack` for the overall plan).

use std::time::Instant;

use rayon::prelude::*;

use super::anchor::{Anchor, RigidFace, best_group, compose, ranked_groups, rigid_image};
use super::footprint::{EPS, cell_bounds, min_area_angle, rasterize};
use super::texel_clash::{ChartClashes, separate};
use super::{LayoutInput, PackError, PackOptions, PackReport, PackedLayout};
use crate::geometry::GridTransform;
use crate::plugin::{
    ALL_ROTATIONS, MAX_FOOTPRINT_CELLS, PackItem, Packer, PackerError, check_packing,
    quarter_turn_frame,
};

/// The rigid map of a chart from current UVs to its frame: `L = (R(angle)·c − s) − b`.
#[derive(Clone, Copy, Debug)]
struct Frame {
    angle: f64,
    s: [f64; 2],
    b: [i64; 2],
    width: u32,
    height: u32,
    /// For anchored charts: the grid map from original UVs to the frame, `L ≈ g0(orig)`.
    g0: Option<GridTransform>,
}

impl Frame {
    #[inline]
    fn map(&self, c: [f64; 2]) -> [f64; 2] {
        let (sn, cs) = self.angle.sin_cos();
        let r = if self.angle == 0.0 { c } else { [cs * c[0] - sn * c[1], sn * c[0] + cs * c[1]] };
        [(r[0] - self.s[0]) - self.b[0] as f64, (r[1] - self.s[1]) - self.b[1] as f64]
    }
}

/// Compressed lists: the members of group `g` are `items[start[g]..start[g + 1]]`.
struct Csr {
    start: Vec<usize>,
    items: Vec<u32>,
}

impl Csr {
    fn of(&self, g: usize) -> &[u32] {
        &self.items[self.start[g]..self.start[g + 1]]
    }
}

fn check_len(what: &'static str, got: usize, expected: usize) -> Result<(), PackError> {
    if got == expected { Ok(()) } else { Err(PackError::Length { what, expected, got }) }
}

/// Checks the shapes and values of the input, and returns the chart of every UV vertex
/// (`u32::MAX` when no packed face uses it).
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
    let mut vert_chart = vec![u32::MAX; input.vert_uv.len()];
    for f in 0..nf {
        let chart = input.face_chart[f];
        if chart == u32::MAX {
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
            if *vc == u32::MAX {
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
    for &c in input.face_chart.iter().filter(|&&c| c != u32::MAX) {
        count[c as usize + 1] += 1;
    }
    for i in 0..n {
        count[i + 1] += count[i];
    }
    let mut fill = count.clone();
    let mut items = vec![0u32; count[n]];
    for (f, &c) in input.face_chart.iter().enumerate().filter(|(_, c)| **c != u32::MAX) {
        items[fill[c as usize]] = f as u32;
        fill[c as usize] += 1;
    }
    let faces = Csr { start: count, items };
    let mut vstart = vec![0usize; n + 1];
    for &c in vert_chart.iter().filter(|&&c| c != u32::MAX) {
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

/// Marks the faces of an anchor group that can be preserved (every corner claims its vertex's
/// original position; a face whose corner disagrees with an earlier claim on the same vertex is
/// resampled instead, so each vertex gets one exact value).
fn claim_group(input: &LayoutInput, group: &[u32], claim: &mut [[f64; 2]], preserved: &mut [bool]) {
    for &f in group {
        let vs = [0, 1, 2].map(|k| input.corner_vert[3 * f as usize + k] as usize);
        let os = [0, 1, 2].map(|k| input.orig_uv[3 * f as usize + k]);
        let free = |k: usize| claim[vs[k]][0].is_nan() || claim[vs[k]] == os[k];
        if (0..3).all(free) {
            for k in 0..3 {
                claim[vs[k]] = os[k];
            }
            preserved[f as usize] = true;
        }
    }
}

/// Undoes [`claim_group`] for a whole chart.
fn unclaim_chart(verts: &[u32], faces: &[u32], claim: &mut [[f64; 2]], preserved: &mut [bool]) {
    for &v in verts {
        claim[v as usize] = [f64::NAN; 2];
    }
    for &f in faces {
        preserved[f as usize] = false;
    }
}

/// How a chart without an anchor is turned.
#[derive(Clone, Copy, PartialEq, Eq)]
enum FreeTurn {
    /// To its minimum-area bounding rectangle.
    MinArea,
    /// Not at all: the merge stage bounded the box of this frame.
    AsMerged,
}

/// Anchor groups tried, heaviest first, when the heaviest one's turn does not fit a sheet.
const ANCHOR_TRIES: usize = 8;

/// The frame of one chart and its vertices' frame coordinates (written into `frame_uv`).
#[allow(clippy::too_many_arguments)]
fn chart_frame(
    input: &LayoutInput,
    chart: u32,
    verts: &[u32],
    anchor: Option<(&Anchor, &[[f64; 2]])>,
    free_turn: FreeTurn,
    pad: u32,
    frame_uv: &mut [[f64; 2]],
    scratch: &mut Vec<[f64; 2]>,
) -> Result<Frame, PackError> {
    let claim = anchor.map_or(&[][..], |a| a.1);
    let anchor = anchor.map(|a| a.0);
    let (angle, s, g_lin) = match anchor {
        Some(a) => (-a.residual, a.shift, Some(a.linear())),
        None if free_turn == FreeTurn::AsMerged => (0.0, [0.0, 0.0], None),
        None => {
            scratch.clear();
            scratch.extend(verts.iter().map(|&v| input.vert_uv[v as usize]));
            let psi = min_area_angle(scratch);
            (psi, [0.0, 0.0], None)
        }
    };
    let mut frame = Frame { angle, s, b: [0, 0], width: 0, height: 0, g0: None };
    // A vertex of a preserved face sits at its exact grid image `g0(orig)` already in the frame,
    // so the footprint covers the final triangles exactly, not only up to the group tolerance.
    let pos = |frame: &Frame, v: u32| match g_lin {
        Some(g) if !claim[v as usize][0].is_nan() => {
            let q = g.linear(claim[v as usize]);
            [q[0] + (-frame.b[0]) as f64, q[1] + (-frame.b[1]) as f64]
        }
        _ => frame.map(input.vert_uv[v as usize]),
    };
    let bounds = |frame: &Frame| {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &v in verts {
            let p = pos(frame, v);
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    };
    if anchor.is_none() {
        // Free charts may shift by any amount: put the minimum just past a cell boundary so the
        // conservative raster wastes no column or row.
        let (lo, _) = bounds(&frame);
        frame.s = [lo[0] - 2.0 * EPS, lo[1] - 2.0 * EPS];
    }
    // The integer part of the shift puts the first dilated cell at 0; rounding in the subtraction
    // may need a second correction.
    for _ in 0..3 {
        let (lo, hi) = bounds(&frame);
        let c = cell_bounds(lo, hi, pad);
        if ![c[2] - c[0], c[3] - c[1]].iter().all(|e| e.is_finite() && *e < f64::from(1u32 << 30)) {
            return Err(PackError::ChartTooLarge { chart, extent: [hi[0] - lo[0], hi[1] - lo[1]] });
        }
        if c[0] == 0.0 && c[1] == 0.0 {
            frame.width = c[2] as u32 + 1;
            frame.height = c[3] as u32 + 1;
            break;
        }
        frame.b = [frame.b[0] + c[0] as i64, frame.b[1] + c[1] as i64];
    }
    if frame.width == 0 || u64::from(frame.width) * u64::from(frame.height) > MAX_FOOTPRINT_CELLS {
        return Err(PackError::ChartTooLarge {
            chart,
            extent: [f64::from(frame.width), f64::from(frame.height)],
        });
    }
    frame.g0 = g_lin.map(|g| GridTransform { offset: [-frame.b[0], -frame.b[1]], ..g });
    for &v in verts {
        frame_uv[v as usize] = pos(&frame, v);
    }
    Ok(frame)
}

/// Fits `frame` again around its vertices after some of them moved by a fraction of a texel:
/// whole-texel shifts only, so every texel centre of the frame stays a texel centre.
fn refit(frame: &mut Frame, verts: &[u32], frame_uv: &mut [[f64; 2]], pad: u32) {
    for _ in 0..3 {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &v in verts {
            let p = frame_uv[v as usize];
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let c = cell_bounds(lo, hi, pad);
        frame.width = (c[2] - c[0]) as u32 + 1;
        frame.height = (c[3] - c[1]) as u32 + 1;
        if c[0] == 0.0 && c[1] == 0.0 {
            return;
        }
        for &v in verts {
            let p = &mut frame_uv[v as usize];
            *p = [p[0] - c[0], p[1] - c[1]];
        }
        frame.b = [frame.b[0] + c[0] as i64, frame.b[1] + c[1] as i64];
        if let Some(g0) = frame.g0.as_mut() {
            g0.offset = [-frame.b[0], -frame.b[1]];
        }
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The output sheet size limit: `--max-sheet-size`, else the largest input sheet (by area, then
/// width), else 1 × 1.
pub fn max_sheet_size(opts: &PackOptions, input_sheet_sizes: &[(u32, u32)]) -> (u32, u32) {
    match opts.max_sheet_size {
        Some(s) => s,
        None => input_sheet_sizes
            .iter()
            .copied()
            .max_by_key(|&(w, h)| (u64::from(w) * u64::from(h), w))
            .unwrap_or((1, 1)),
    }
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
            if fs.is_empty() {
                return ChartAnchors { rigid: Vec::new(), min_area: 0.0, best: None };
            }
            let (mut rigid, chart_area) = rigid_faces(input, fs, opts);
            let min_area = opts.anchor_min_fraction * chart_area;
            let best = best_group(&mut rigid, min_area);
            ChartAnchors { rigid, min_area, best }
        })
        .collect()
}

/// Packs the charts of `input` onto sheets with `packer`; see [`PackedLayout`] for what comes
/// out. Deterministic for a deterministic packer; the packer's answer is checked exactly.
pub fn pack_layout(
    input: &LayoutInput,
    packer: &dyn Packer,
    opts: &PackOptions,
) -> Result<PackedLayout, PackError> {
    let t = Instant::now();
    let vert_chart = validate(input, opts)?;
    let max_sheet = max_sheet_size(opts, input.input_sheet_sizes);
    if max_sheet.0 == 0 || max_sheet.1 == 0 {
        return Err(PackError::Options(format!("sheet size {max_sheet:?} is empty")));
    }
    let nf = input.face_chart.len();
    let (faces, verts) = chart_lists(input, &vert_chart);
    let mut report = PackReport { max_sheet_size: max_sheet, ..PackReport::default() };

    // (a) Anchors and frames.
    let mut claim = vec![[f64::NAN; 2]; input.vert_uv.len()];
    let mut face_preserved = vec![false; nf];
    let mut frame_uv = input.vert_uv.to_vec();
    let mut frames: Vec<Option<Frame>> = vec![None; input.n_charts];
    let mut scratch = Vec::new();
    let anchors = chart_anchors(input, &faces, opts);
    for ((c, slot), found) in frames.iter_mut().enumerate().zip(anchors) {
        let fs = faces.of(c);
        if fs.is_empty() {
            continue;
        }
        let vs = verts.of(c);
        let fits = |f: &Frame| {
            let (w, h) = (f.width, f.height);
            (w <= max_sheet.0 && h <= max_sheet.1) || (h <= max_sheet.0 && w <= max_sheet.1)
        };
        let ChartAnchors { mut rigid, min_area, best } = found;
        // The frame for one anchor group (claimed first) or for none, turned by `turn`.
        let mut frame_for = |group: Option<&(Anchor, Vec<u32>)>,
                             turn: FreeTurn,
                             claim: &mut [[f64; 2]],
                             preserved: &mut [bool]| {
            if let Some((_, faces)) = group {
                claim_group(input, faces, claim, preserved);
            }
            let anchor = group.map(|(a, _)| (a, &claim[..]));
            chart_frame(
                input,
                c as u32,
                vs,
                anchor,
                turn,
                opts.padding,
                &mut frame_uv,
                &mut scratch,
            )
        };
        let mut frame = None;
        if best.is_some() {
            let f = frame_for(best.as_ref(), FreeTurn::MinArea, &mut claim, &mut face_preserved)?;
            if fits(&f) {
                frame = Some(f);
            } else {
                unclaim_chart(vs, fs, &mut claim, &mut face_preserved);
            }
        }
        // Turned to its anchor, a chart that fits a sheet in the merge frame may no longer fit
        // (a residual turn of up to 45° widens its box by up to √2): try the lighter groups, then
        // no anchor (minimum-area turn, then the merge frame, whose box the merge stage bounded),
        // and only then give it an oversized sheet with its heaviest anchor.
        if frame.is_none() && best.is_some() {
            for group in ranked_groups(&mut rigid, min_area, ANCHOR_TRIES).iter().skip(1) {
                let f = frame_for(Some(group), FreeTurn::MinArea, &mut claim, &mut face_preserved)?;
                if fits(&f) {
                    report.anchors_changed_to_fit += 1;
                    frame = Some(f);
                    break;
                }
                unclaim_chart(vs, fs, &mut claim, &mut face_preserved);
            }
        }
        if frame.is_none() {
            for turn in [FreeTurn::MinArea, FreeTurn::AsMerged] {
                let f = frame_for(None, turn, &mut claim, &mut face_preserved)?;
                if fits(&f) || (best.is_none() && turn == FreeTurn::AsMerged) {
                    report.anchors_dropped_to_fit += usize::from(best.is_some());
                    frame = Some(f);
                    break;
                }
            }
        }
        let frame = match frame {
            Some(f) => f,
            None => frame_for(best.as_ref(), FreeTurn::AsMerged, &mut claim, &mut face_preserved)?,
        };
        report.anchored_charts += usize::from(frame.g0.is_some());
        *slot = Some(frame);
    }
    let packed: Vec<u32> =
        (0..input.n_charts as u32).filter(|&c| frames[c as usize].is_some()).collect();
    report.charts = packed.len();
    report.anchors_ms = ms(t);

    // (a') Texel clashes, separated chart by chart in parallel in the final frames (each chart's
    // result is a pure function of it), then applied and the frames refitted in chart order.
    let t = Instant::now();
    let mut clashing_pairs = Vec::new();
    if opts.separate_texel_clashes {
        // The index of each UV vertex in its chart's vertex list.
        let mut vert_local = vec![0u32; input.vert_uv.len()];
        for &c in &packed {
            for (i, &v) in verts.of(c as usize).iter().enumerate() {
                vert_local[v as usize] = i as u32;
            }
        }
        let found: Vec<ChartClashes> = packed
            .par_iter()
            .map(|&c| {
                let c = c as usize;
                separate(
                    input,
                    faces.of(c),
                    verts.of(c),
                    &vert_local,
                    &frame_uv,
                    |v| !claim[v as usize][0].is_nan(),
                    |f| face_preserved[f as usize],
                )
            })
            .collect();
        for (&c, r) in packed.iter().zip(found) {
            report.texel_clashes += r.found;
            report.texel_clashes_left += r.left.len();
            clashing_pairs.extend_from_slice(&r.left);
            report.texel_clash_vertices_moved += r.moves.len();
            report.texel_clash_vertices_freed += r.freed.len();
            if !r.freed.is_empty() {
                // A freed vertex is no longer held at its grid image, and its faces are resampled.
                for &v in &r.freed {
                    claim[v as usize] = [f64::NAN; 2];
                }
                for &f in faces.of(c as usize) {
                    let corners = [0, 1, 2].map(|k| input.corner_vert[3 * f as usize + k]);
                    if corners.iter().any(|v| r.freed.contains(v)) {
                        face_preserved[f as usize] = false;
                    }
                }
            }
            if r.moves.is_empty() {
                continue;
            }
            for (v, d) in r.moves {
                let p = &mut frame_uv[v as usize];
                *p = [p[0] + d[0], p[1] + d[1]];
            }
            if let Some(frame) = frames[c as usize].as_mut() {
                refit(frame, verts.of(c as usize), &mut frame_uv, opts.padding);
            }
        }
    }
    report.texel_clash_ms = ms(t);

    // (b) Footprints, one per packed chart, rasterized in parallel (the result is independent of
    // the thread count: each footprint is a pure function of its chart).
    let t = Instant::now();
    let items: Vec<PackItem> = packed
        .par_iter()
        .map(|&c| {
            let fr =
                frames[c as usize].as_ref().ok_or_else(|| PackerError::Failed("frame".into()))?;
            let tris = faces.of(c as usize).iter().map(|&f| {
                [0, 1, 2].map(|k| frame_uv[input.corner_vert[3 * f as usize + k] as usize])
            });
            let footprint = rasterize(tris, fr.width, fr.height, opts.padding)?;
            Ok(PackItem { footprint, rotations: ALL_ROTATIONS })
        })
        .collect::<Result<_, PackerError>>()?;
    report.footprint_cells = items.iter().map(|i| i.footprint.count()).sum();
    report.footprints_ms = ms(t);

    // (c) The packer, checked.
    let t = Instant::now();
    let out = packer.pack(&items, max_sheet)?;
    check_packing(&items, max_sheet, &out)?;
    report.oversized_charts =
        out.oversized.iter().filter_map(|&i| packed.get(i as usize).copied()).collect();
    report.packing_ms = ms(t);

    // (d, e) Placement maps, sheets renumbered in order of use, trimmed to the used texels.
    let t = Instant::now();
    let mut sheet_id = vec![u32::MAX; out.sheets.len()];
    let mut n_sheets = 0u32;
    for p in &out.placements {
        if sheet_id[p.sheet as usize] == u32::MAX {
            sheet_id[p.sheet as usize] = n_sheets;
            n_sheets += 1;
        }
    }
    let place = |i: usize, trim: [i64; 2]| {
        let (p, fr) = (out.placements[i], frames[packed[i] as usize].as_ref());
        let fr = fr.map_or((0, 0), |f| (f.width, f.height));
        let mut g = quarter_turn_frame(p.quarter_turns, fr.0, fr.1);
        g.offset[0] += i64::from(p.x) - trim[0];
        g.offset[1] += i64::from(p.y) - trim[1];
        g
    };
    let mut trims = vec![[0i64; 2]; n_sheets as usize];
    let mut sizes = vec![(0u32, 0u32); n_sheets as usize];
    let mut vert_uv = input.vert_uv.to_vec();
    let mut chart_transform: Vec<Option<GridTransform>> = vec![None; input.n_charts];
    let mut settled = false;
    for _round in 0..4 {
        // Place every vertex; preserved corners get their exact grid image.
        let mut lo = vec![[f64::INFINITY; 2]; n_sheets as usize];
        let mut hi = vec![[f64::NEG_INFINITY; 2]; n_sheets as usize];
        for (i, &c) in packed.iter().enumerate() {
            let s = sheet_id[out.placements[i].sheet as usize] as usize;
            let g = place(i, trims[s]);
            for &v in verts.of(c as usize) {
                vert_uv[v as usize] = g.apply(frame_uv[v as usize]);
            }
            let fr = frames[c as usize].as_ref();
            chart_transform[c as usize] = fr.and_then(|f| f.g0).map(|g0| compose(&g, &g0));
            if let Some(f_map) = chart_transform[c as usize] {
                for &f in faces.of(c as usize).iter().filter(|&&f| face_preserved[f as usize]) {
                    for k in 0..3 {
                        let v = input.corner_vert[3 * f as usize + k] as usize;
                        vert_uv[v] = f_map.apply(input.orig_uv[3 * f as usize + k]);
                    }
                }
            }
            for &v in verts.of(c as usize) {
                let p = vert_uv[v as usize];
                for k in 0..2 {
                    lo[s][k] = lo[s][k].min(p[k]);
                    hi[s][k] = hi[s][k].max(p[k]);
                }
            }
        }
        // Trim: the smallest integer box holding every UV strictly inside. A sheet needs another
        // round only if rounding put a UV on its border.
        let mut again = false;
        for s in 0..n_sheets as usize {
            let strict = sizes[s] != (0, 0)
                && (0..2).all(|k| {
                    let size = if k == 0 { sizes[s].0 } else { sizes[s].1 };
                    lo[s][k] > 0.0 && hi[s][k] < f64::from(size)
                });
            if strict {
                continue;
            }
            again = true;
            let mut size = [0u32; 2];
            for k in 0..2 {
                let first = lo[s][k].ceil() - 1.0;
                let last = hi[s][k].floor();
                let extra = if sizes[s] == (0, 0) { 0.0 } else { 1.0 };
                let cut = first - extra;
                trims[s][k] += cut as i64;
                size[k] = (last - cut + 1.0 + extra) as u32;
            }
            sizes[s] = (size[0], size[1]);
        }
        if !again {
            settled = true;
            break;
        }
    }
    if !settled || sizes.iter().any(|&(w, h)| w == 0 || h == 0) {
        return Err(PackError::Packer(PackerError::Failed(
            "trimming did not converge to sheets holding every UV strictly inside".into(),
        )));
    }
    let mut face_sheet = vec![u32::MAX; nf];
    let mut uv_area = 0.0;
    let (mut all_area, mut kept_area) = (0.0, 0.0);
    for (i, &c) in packed.iter().enumerate() {
        let s = sheet_id[out.placements[i].sheet as usize];
        for &f in faces.of(c as usize) {
            face_sheet[f as usize] = s;
            let t = [0, 1, 2].map(|k| vert_uv[input.corner_vert[3 * f as usize + k] as usize]);
            uv_area += 0.5
                * ((t[1][0] - t[0][0]) * (t[2][1] - t[0][1])
                    - (t[1][1] - t[0][1]) * (t[2][0] - t[0][0]))
                    .abs();
            let a = area_of(input.face_area_3d[f as usize]);
            all_area += a;
            if face_preserved[f as usize] {
                kept_area += a;
                report.preserved_faces += 1;
            }
        }
    }
    report.preserved_area_fraction = if all_area > 0.0 { kept_area / all_area } else { 0.0 };
    report.sheets = n_sheets as usize;
    report.texels = sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum();
    report.occupancy = if report.texels > 0 { uv_area / report.texels as f64 } else { 0.0 };
    report.finish_ms = ms(t);
    Ok(PackedLayout {
        vert_uv,
        face_sheet,
        sheet_sizes: sizes,
        face_preserved,
        chart_transform,
        clashing_pairs,
        report,
    })
}
