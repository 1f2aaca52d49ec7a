//! The palette: faces whose input UV triangle has no area keep their colour.
//!
//! Photogrammetry exporters collapse faces that no camera saw onto a UV point (or a segment),
//! often in a sheet's margin. Such a face shows one colour: the input texel under its point.
//! Packed like any chart, it would land on a corner of a neighbouring chart or on gutter fill,
//! because a face without area covers no texel centre and so writes nothing of its own.
//!
//! Instead, every distinct colour point gets one square block of texels in the free space of the
//! output sheets, painted with the input's bilinear colour at that point, and every face of that
//! point is mapped onto the block's centre. A segment face (its corners on a line) shows the
//! colours along its segment: its block is a strip, each column painted with the input's colour
//! at its point of the segment (every row alike), and the face is mapped onto the line through the
//! block's middle at the segment's input length (so it keeps its UV border), each corner at its
//! own place. A segment longer than the block is shortened to fit; bilinear sampling along the line
//! then interpolates the input's colours along it at the block's resolution.
//!
//! The block is aligned to a multiple of its side on the pixel grid (columns from the left, rows
//! from the top, as the encoders see them) and sized so that nothing reading it mixes in another
//! colour: bilinear sampling at the centre reads the four middle texels; mip level 1 halves an
//! even-aligned block; JPEG codes 8×8 blocks (16×16 with chroma subsampling), so a lossy sheet
//! needs a block that fills one whole. Blocks keep the padding away from every chart, like two
//! charts do; they may touch each other, since nothing reads across a block's edge.
//!
//! Specks (charts smaller than a hundredth of a texel, see `PackOptions::speck_area`) come here
//! too, as point faces at their centroid: they show one colour as well, and a chart of their own
//! would cost its padding for nothing a renderer can show.
//!
//! Blocks go first into free cells inside the packed sheets (in sheet, row, column order), then
//! into columns added on the right of the last sheet (which moves no existing texel), then, past
//! the sheet size limit, onto new sheets of their own.

use std::collections::HashMap;

use crate::geometry::signed_area2;
use crate::metrics::DEGEN_AREA_TEXELS;
use crate::texture::ImageFormat;
use crate::texture::resample::FaceMapping;

/// Whether a texel-space UV triangle has no area, by the threshold of the atlas figures (the
/// evaluator's), so that both count the same faces.
pub fn zero_uv_area(tri: [[f64; 2]; 3]) -> bool {
    (0.5 * signed_area2(tri)).abs() < DEGEN_AREA_TEXELS
}

/// The segment whose colours a face without UV area keeps: its two farthest corners (one point
/// twice for a point face), and where each corner lies along it (0 at the first end, 1 at the
/// second; 0.5 for a point).
pub fn colour_segment(tri: [[f64; 2]; 3]) -> ([[f64; 2]; 2], [f64; 3]) {
    let d2 = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2);
    let mut best = (d2(tri[0], tri[1]), 0, 1);
    for (i, j) in [(1, 2), (0, 2)] {
        let d = d2(tri[i], tri[j]);
        if d > best.0 {
            best = (d, i, j);
        }
    }
    let (a, b) = (tri[best.1], tri[best.2]);
    if best.0 == 0.0 {
        return ([a, a], [0.5; 3]);
    }
    let along = tri.map(|p| {
        let t = ((p[0] - a[0]) * (b[0] - a[0]) + (p[1] - a[1]) * (b[1] - a[1])) / best.0;
        t.clamp(0.0, 1.0)
    });
    ([a, b], along)
}

/// The side in texels of a palette block for sheets written in `format`: a whole JPEG block
/// (16 texels where chroma is subsampled, as below quality 90 and in lossy WebP), else 4, which
/// keeps bilinear sampling and the first two mip levels pure.
pub fn block_side(format: ImageFormat, quality: u8, lossy_webp: bool) -> u32 {
    match format {
        ImageFormat::Jpeg if quality >= 90 => 8,
        ImageFormat::Jpeg => 16,
        ImageFormat::Webp if lossy_webp => 16,
        _ => 4,
    }
}

/// A face to put on the palette.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaletteFace {
    pub face: u32,
    /// Input sheet of the face.
    pub src_sheet: u32,
    /// The input texel-space segment whose colours the face keeps, and where its corners lie
    /// along it (see [`colour_segment`]).
    pub ends: [[f64; 2]; 2],
    pub along: [f64; 3],
}

/// One block: cell `(col, row)` of output sheet `sheet` (pixel columns `col·side ..` from the
/// left, rows `row·side ..` from the top), painted with the colours along segment `ends` (a
/// point when both are one) on input sheet `src_sheet`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaletteBlock {
    pub sheet: u32,
    pub col: u32,
    pub row: u32,
    pub src_sheet: u32,
    pub ends: [[f64; 2]; 2],
}

/// What the palette did, for the run report.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PaletteReport {
    /// Faces whose input UV triangle has no area, mapped onto a block: the point faces.
    pub point_faces: usize,
    /// Of those, faces whose input UVs span a segment rather than a point.
    pub segment_faces: usize,
    /// Charts too small to be worth one (specks, see `PackOptions::speck_area`) mapped onto a
    /// block as point faces, and their faces (counted in `point_faces` too).
    pub speck_charts: usize,
    pub speck_faces: usize,
    /// Blocks (distinct colour points) and their side in texels.
    pub blocks: usize,
    pub block_side: u32,
    /// Sheets widened to hold blocks, sheets added for them, and the texels both added.
    pub sheets_widened: usize,
    pub sheets_added: usize,
    pub texels_added: u64,
}

/// The placed palette.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Palette {
    pub side: u32,
    pub blocks: Vec<PaletteBlock>,
    /// `(face, block)` for every palette face, in increasing face order.
    pub face_block: Vec<(u32, u32)>,
    /// Where each of those faces' corners lie along their block's segment (see
    /// [`Palette::corner`]), in the same order.
    pub face_along: Vec<[f64; 3]>,
    pub report: PaletteReport,
}

/// Where the palette may go.
#[derive(Clone, Copy, Debug)]
pub struct PaletteSpace {
    /// Block side in texels (see [`block_side`]).
    pub side: u32,
    /// Free texels kept between a block and any chart.
    pub padding: u32,
    /// Largest output sheet.
    pub max_sheet_size: (u32, u32),
    /// Whether the last sheet may be widened for blocks that find no free cell; not when the
    /// user fixed every sheet's size (`--sheet-size`): new sheets open instead.
    pub may_widen: bool,
}

impl Palette {
    /// The texel-space centre of block `b`, on a sheet `height` texels high.
    pub fn centre(&self, b: u32, height: u32) -> [f64; 2] {
        self.corner(b, 0.5, height)
    }

    /// Where a face corner lying at `t` along block `b`'s segment goes, on a sheet `height`
    /// texels high: on the line through the block's middle, the segment at its input length (at
    /// most the distance between the first and last columns' centres) centred on the block; the
    /// block's centre for a point.
    pub fn corner(&self, b: u32, t: f64, height: u32) -> [f64; 2] {
        let block = &self.blocks[b as usize];
        let (start, len) = self.strip(block);
        let y = f64::from(height) - f64::from(block.row * self.side) - 0.5 * f64::from(self.side);
        [start + t * len, y]
    }

    /// Where a block's segment starts on its middle line, and its length there (0 for a point):
    /// the input length, so that the face keeps its UV border, but no more than fits between
    /// the centres of the first and last columns.
    fn strip(&self, block: &PaletteBlock) -> (f64, f64) {
        let s = f64::from(self.side);
        let [a, e] = block.ends;
        let len = (e[0] - a[0]).hypot(e[1] - a[1]).min(s - 1.0).max(0.0);
        (f64::from(block.col * self.side) + 0.5 * (s - len), len)
    }

    /// Two face mappings per block that paint its texels with the colours of its segment: a
    /// point block's input triangles collapse onto the point, so every texel samples it; a
    /// segment block's map the strip's middle line onto the segment (see [`Palette::corner`]),
    /// every row alike, and beyond its ends onto the line's continuation.
    pub fn mappings(&self, sheet_sizes: &[(u32, u32)]) -> Vec<FaceMapping> {
        let s = f64::from(self.side);
        let mut out = Vec::with_capacity(2 * self.blocks.len());
        for b in &self.blocks {
            let h = f64::from(sheet_sizes[b.sheet as usize].1);
            let (x0, top) = (f64::from(b.col) * s, h - f64::from(b.row) * s);
            let (x1, bottom) = (x0 + s, top - s);
            // The input points of the block's left and right edges.
            let [a, e] = b.ends;
            let (start, len) = self.strip(b);
            let at = |x: f64| {
                let t = if len > 0.0 { (x - start) / len } else { 0.0 };
                [a[0] + t * (e[0] - a[0]), a[1] + t * (e[1] - a[1])]
            };
            let (left, right) = (at(x0), at(x1));
            for (dst, src) in [
                ([[x0, bottom], [x1, bottom], [x1, top]], [left, right, right]),
                ([[x0, bottom], [x1, top], [x0, top]], [left, right, left]),
            ] {
                out.push(FaceMapping {
                    dst_sheet: b.sheet,
                    dst,
                    src_sheet: b.src_sheet,
                    src,
                    exact: None,
                });
            }
        }
        out
    }
}

/// Cells of one sheet taken by charts (with their padding) or by placed blocks.
struct Cells {
    cols: u32,
    rows: u32,
    taken: Vec<bool>,
}

impl Cells {
    fn new(cols: u32, rows: u32) -> Self {
        Self { cols, rows, taken: vec![false; cols as usize * rows as usize] }
    }

    /// Marks the cells that pixel rectangle `[i0, i1) × [j0, j1)` touches.
    fn mark(&mut self, side: u32, [i0, i1, j0, j1]: [i64; 4]) {
        let s = i64::from(side);
        let c0 = i0.div_euclid(s).max(0);
        let c1 = (i1 - 1).div_euclid(s).min(i64::from(self.cols) - 1);
        let r0 = j0.div_euclid(s).max(0);
        let r1 = (j1 - 1).div_euclid(s).min(i64::from(self.rows) - 1);
        for r in r0..=r1 {
            for c in c0..=c1 {
                self.taken[(r * i64::from(self.cols) + c) as usize] = true;
            }
        }
    }

    /// Takes the first free cell in row-major order among columns `cols` (if any).
    fn take(&mut self, cols: std::ops::Range<u32>, from: &mut usize) -> Option<(u32, u32)> {
        while *from < self.taken.len() {
            let k = *from;
            *from += 1;
            let (c, r) = (k as u32 % self.cols, k as u32 / self.cols);
            if !self.taken[k] && cols.contains(&c) {
                self.taken[k] = true;
                return Some((c, r));
            }
        }
        None
    }
}

/// Places one block per distinct colour segment (or point) of `faces` (in face order) around the charts
/// `charts` (output sheet and texel-space triangle of every packed face), widening the last
/// sheet or adding sheets to `sheet_sizes` when the free cells do not suffice.
pub fn place_palette(
    faces: &[PaletteFace],
    segment_faces: usize,
    charts: impl Iterator<Item = (u32, [[f64; 2]; 3])>,
    sheet_sizes: &mut Vec<(u32, u32)>,
    space: PaletteSpace,
) -> Palette {
    let (max_w, max_h) = space.max_sheet_size;
    // A limit below the block side would leave no cell anywhere: the block shrinks to fit.
    let side = space.side.min(max_w.max(1)).min(max_h.max(1)).max(1);
    let mut palette = Palette { side, ..Palette::default() };
    let mut by_segment: HashMap<(u32, [u64; 4]), u32> = HashMap::new();
    let mut wanted: Vec<(u32, [[f64; 2]; 2])> = Vec::new();
    let mut placed: Vec<(u32, u32, [f64; 3])> = Vec::with_capacity(faces.len());
    for f in faces {
        let [a, b] = f.ends;
        let key = (f.src_sheet, [a[0], a[1], b[0], b[1]].map(f64::to_bits));
        let next = wanted.len() as u32;
        let b = *by_segment.entry(key).or_insert(next);
        if b == next {
            wanted.push((f.src_sheet, f.ends));
        }
        placed.push((f.face, b, f.along));
    }
    placed.sort_unstable_by_key(|p| (p.0, p.1));
    palette.face_block = placed.iter().map(|p| (p.0, p.1)).collect();
    palette.face_along = placed.iter().map(|p| p.2).collect();
    palette.report = PaletteReport {
        point_faces: faces.len(),
        segment_faces,
        blocks: wanted.len(),
        block_side: side,
        ..PaletteReport::default()
    };
    if wanted.is_empty() {
        return palette;
    }
    let cells = cell_grids(charts, sheet_sizes, side, space.padding, wanted.len(), max_w);
    let slots = assign_cells(cells, sheet_sizes, side, wanted.len(), space, &mut palette.report);
    palette.blocks = slots
        .into_iter()
        .zip(wanted)
        .map(|((sheet, col, row), (src_sheet, ends))| PaletteBlock {
            sheet,
            col,
            row,
            src_sheet,
            ends,
        })
        .collect();
    palette
}

/// The cell grid of every sheet, with the cells charts take marked. The last sheet's grid reaches
/// far enough right to hold every block in added columns (up to the width limit).
fn cell_grids(
    charts: impl Iterator<Item = (u32, [[f64; 2]; 3])>,
    sheet_sizes: &[(u32, u32)],
    side: u32,
    padding: u32,
    blocks: usize,
    max_w: u32,
) -> Vec<Cells> {
    let n = sheet_sizes.len();
    let mut grids: Vec<Cells> = sheet_sizes
        .iter()
        .enumerate()
        .map(|(s, &(w, h))| {
            let rows = h / side;
            let mut cols = w.div_ceil(side);
            if s + 1 == n && rows > 0 {
                let extra = (blocks as u32).div_ceil(rows) + padding.div_ceil(side) + 1;
                cols = (cols + extra).min(max_w / side).max(cols);
            }
            Cells::new(cols, rows)
        })
        .collect();
    // A chart's texels, its padding and one texel more for bilinear reads at its edge.
    let margin = f64::from(padding) + 1.0;
    for (s, tri) in charts {
        let (Some(grid), Some(&(_, h))) = (grids.get_mut(s as usize), sheet_sizes.get(s as usize))
        else {
            continue;
        };
        let xs = tri.map(|p| p[0]);
        let ys = tri.map(|p| p[1]);
        let (x0, x1) = (
            xs.iter().copied().fold(f64::INFINITY, f64::min),
            xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        let (y0, y1) = (
            ys.iter().copied().fold(f64::INFINITY, f64::min),
            ys.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        let hf = f64::from(h);
        let rect = [
            (x0 - margin).floor() as i64,
            (x1 + margin).ceil() as i64,
            (hf - y1 - margin).floor() as i64,
            (hf - y0 + margin).ceil() as i64,
        ];
        grid.mark(side, rect);
    }
    grids
}

/// Hands out `count` cells: free ones inside the sheets first, then added columns of the last
/// sheet, then new sheets. Updates `sheet_sizes` and the report's growth figures.
fn assign_cells(
    mut grids: Vec<Cells>,
    sheet_sizes: &mut Vec<(u32, u32)>,
    side: u32,
    count: usize,
    space: PaletteSpace,
    report: &mut PaletteReport,
) -> Vec<(u32, u32, u32)> {
    let mut slots = Vec::with_capacity(count);
    // Inside the sheets: whole cells only.
    for (s, grid) in grids.iter_mut().enumerate() {
        let inside = 0..sheet_sizes[s].0 / side;
        let mut from = 0;
        while slots.len() < count {
            let Some((c, r)) = grid.take(inside.clone(), &mut from) else { break };
            slots.push((s as u32, c, r));
        }
    }
    // Columns added on the right of the last sheet, column by column.
    let last = grids.len().saturating_sub(1) as u32;
    if let (Some(grid), Some(size)) = (grids.last_mut(), sheet_sizes.last_mut())
        && slots.len() < count
        && space.may_widen
    {
        let s = last;
        let first = size.0 / side;
        let mut widest = 0;
        'cols: for c in first..grid.cols {
            for r in 0..grid.rows {
                let k = (r * grid.cols + c) as usize;
                if slots.len() == count {
                    break 'cols;
                }
                if !grid.taken[k] {
                    grid.taken[k] = true;
                    slots.push((s, c, r));
                    widest = c + 1;
                }
            }
        }
        if widest > 0 {
            let w = (widest * side).max(size.0);
            report.texels_added += u64::from(w - size.0) * u64::from(size.1);
            report.sheets_widened += 1;
            size.0 = w;
        }
    }
    // New sheets, as square as the limit allows.
    let (max_cols, max_rows) = (space.max_sheet_size.0 / side, space.max_sheet_size.1 / side);
    while slots.len() < count {
        let left = (count - slots.len()) as u32;
        let cols = ((f64::from(left)).sqrt().ceil() as u32).clamp(1, max_cols.max(1));
        let rows = left.div_ceil(cols).clamp(1, max_rows.max(1));
        let s = sheet_sizes.len() as u32;
        sheet_sizes.push((cols * side, rows * side));
        report.sheets_added += 1;
        report.texels_added += u64::from(cols * side) * u64::from(rows * side);
        for k in 0..(cols * rows).min(left) {
            slots.push((s, k % cols, k / cols));
        }
    }
    slots
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::raster::{PixelRect, TriangleRaster};

    fn space(side: u32, max: (u32, u32)) -> PaletteSpace {
        PaletteSpace { side, padding: 4, max_sheet_size: max, may_widen: true }
    }

    fn face(face: u32, point: [f64; 2]) -> PaletteFace {
        PaletteFace { face, src_sheet: 0, ends: [point; 2], along: [0.5; 3] }
    }

    /// The pixels `(column, row)` each mapping covers, by the resampler's raster.
    fn covered(m: &FaceMapping, (w, h): (u32, u32)) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        if let Some(r) = TriangleRaster::new(m.dst, h, PixelRect::new(0, 0, w, h)) {
            r.for_each_span(|j, a, b| out.extend((a..=b).map(|i| (i, j))));
        }
        out
    }

    #[test]
    fn zero_area_and_colour_segment() {
        assert!(zero_uv_area([[3.0, 4.0]; 3]));
        assert!(zero_uv_area([[0.0, 0.0], [2.0, 2.0], [5.0, 5.0]]));
        assert!(!zero_uv_area([[0.0, 0.0], [1.0, 0.0], [0.0, 0.01]]));
        assert_eq!(colour_segment([[3.0, 4.0]; 3]), ([[3.0, 4.0]; 2], [0.5; 3]));
        let (ends, along) = colour_segment([[2.0, 2.0], [0.0, 0.0], [6.0, 6.0]]);
        assert_eq!((ends, along), ([[0.0, 0.0], [6.0, 6.0]], [1.0 / 3.0, 0.0, 1.0]));
    }

    #[test]
    fn one_block_per_point_painted_whole_and_away_from_charts() {
        // A chart fills the left half of a 64 × 32 sheet.
        let chart = [[0.0, 0.0], [32.0, 0.0], [32.0, 32.0]];
        let chart2 = [[0.0, 0.0], [32.0, 32.0], [0.0, 32.0]];
        let faces = [face(3, [1.5, 2.5]), face(5, [7.0, 7.0]), face(9, [1.5, 2.5])];
        let mut sizes = vec![(64, 32)];
        let charts = [(0, chart), (0, chart2)].into_iter();
        let p = place_palette(&faces, 0, charts, &mut sizes, space(8, (64, 64)));
        assert_eq!(sizes, vec![(64, 32)], "the free right half holds both blocks");
        assert_eq!(p.blocks.len(), 2);
        assert_eq!(p.face_block, vec![(3, 0), (5, 1), (9, 0)]);
        let maps = p.mappings(&sizes);
        for (b, block) in p.blocks.iter().enumerate() {
            // Every block keeps the padding and a texel more away from the chart's right edge.
            assert!(block.col * 8 >= 32 + 5, "block {b} at column {}", block.col);
            let mut px: Vec<(u32, u32)> =
                maps[2 * b..2 * b + 2].iter().flat_map(|m| covered(m, sizes[0])).collect();
            px.sort_unstable();
            let expect: Vec<(u32, u32)> = (block.col * 8..block.col * 8 + 8)
                .flat_map(|i| (block.row * 8..block.row * 8 + 8).map(move |j| (i, j)))
                .collect();
            let mut expect = expect;
            expect.sort_unstable();
            assert_eq!(px, expect, "block {b} is painted whole, each texel once");
            assert!(maps[2 * b].src.iter().all(|&s| s == block.ends[0]));
            // The centre lies on the block's middle texel corner.
            let c = p.centre(b as u32, sizes[0].1);
            assert_eq!(c, [f64::from(block.col * 8) + 4.0, 32.0 - f64::from(block.row * 8) - 4.0]);
        }
    }

    #[test]
    fn a_segment_block_holds_the_colours_along_its_segment() {
        // A segment face from (2, 3) to (8, 6) with its third corner a third of the way along.
        let (ends, along) = colour_segment([[2.0, 3.0], [8.0, 6.0], [4.0, 4.0]]);
        assert_eq!(ends, [[2.0, 3.0], [8.0, 6.0]]);
        let faces = [PaletteFace { face: 0, src_sheet: 0, ends, along }, face(1, [5.0, 5.0])];
        let mut sizes = vec![(32, 32)];
        let p = place_palette(&faces, 1, std::iter::empty(), &mut sizes, space(4, (32, 32)));
        assert_eq!((p.blocks.len(), p.face_along[0]), (2, along));
        let (block, h) = (p.blocks[0], 32u32);
        let maps = p.mappings(&sizes);
        // The segment is 6.7 texels long, more than the 3 between the first and last columns'
        // centres: it is shortened to them, and every texel centre of the strip samples the
        // segment's point for its column, whatever its row (the first column the first end, the
        // last the second).
        for m in &maps[0..2] {
            for (i, j) in covered(m, sizes[0]) {
                let c = [f64::from(i) + 0.5, f64::from(h - j) - 0.5];
                let [a, b, d] = m.dst;
                let det = (b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]);
                let u = ((c[0] - a[0]) * (d[1] - a[1]) - (c[1] - a[1]) * (d[0] - a[0])) / det;
                let v = ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) / det;
                let src = [0, 1].map(|k| {
                    m.src[0][k] + u * (m.src[1][k] - m.src[0][k]) + v * (m.src[2][k] - m.src[0][k])
                });
                let t = f64::from(i - block.col * 4) / 3.0;
                let want = [2.0 + 6.0 * t, 3.0 + 3.0 * t];
                assert!((src[0] - want[0]).abs() < 1e-9 && (src[1] - want[1]).abs() < 1e-9);
            }
        }
        // The face's corners go on the strip's middle line at their place along it.
        let x0 = f64::from(block.col * 4);
        let y = f64::from(h - block.row * 4) - 2.0;
        assert_eq!(p.corner(0, 0.0, h), [x0 + 0.5, y]);
        assert_eq!(p.corner(0, 1.0, h), [x0 + 3.5, y]);
        assert_eq!(p.centre(1, h)[1], f64::from(h - p.blocks[1].row * 4) - 2.0);
        // A short segment keeps its input length, centred on the block.
        let short = PaletteFace { face: 2, src_sheet: 0, ends: [[2.0, 3.0], [3.0, 3.0]], along };
        let p = place_palette(&[short], 1, std::iter::empty(), &mut sizes, space(4, (32, 32)));
        let x0 = f64::from(p.blocks[0].col * 4);
        assert_eq!((p.corner(0, 0.0, h)[0], p.corner(0, 1.0, h)[0]), (x0 + 1.5, x0 + 2.5));
    }

    #[test]
    fn a_full_sheet_is_widened_then_new_sheets_open() {
        let full = [[0.0, 0.0], [40.0, 0.0], [40.0, 40.0]];
        let full2 = [[0.0, 0.0], [40.0, 40.0], [0.0, 40.0]];
        let faces: Vec<PaletteFace> = (0..10).map(|k| face(k, [f64::from(k) + 0.5, 0.5])).collect();
        let mut sizes = vec![(40, 40)];
        let charts = [(0, full), (0, full2)].into_iter();
        let p = place_palette(&faces, 0, charts, &mut sizes, space(4, (64, 64)));
        // Columns from 48 on (40 + 4 padding + 1, rounded up to a block) hold 10 rows each.
        assert_eq!(sizes, vec![(52, 40)]);
        assert_eq!(p.report.sheets_widened, 1);
        assert!(p.blocks.iter().all(|b| b.col * 4 >= 45 && b.sheet == 0));
        // With a width limit of 40 nothing fits beside the chart: a new sheet opens.
        let mut sizes = vec![(40, 40)];
        let charts = [(0, full), (0, full2)].into_iter();
        let p = place_palette(&faces, 0, charts, &mut sizes, space(4, (40, 40)));
        assert_eq!(p.report.sheets_added, 1);
        assert_eq!(sizes.len(), 2);
        assert!(p.blocks.iter().all(|b| b.sheet == 1));
        let mut cells: Vec<(u32, u32)> = p.blocks.iter().map(|b| (b.col, b.row)).collect();
        cells.sort_unstable();
        cells.dedup();
        assert_eq!(cells.len(), 10, "no two blocks share a cell");
        assert!(cells.iter().all(|&(c, r)| (c + 1) * 4 <= sizes[1].0 && (r + 1) * 4 <= sizes[1].1));
    }

    #[test]
    fn a_fixed_size_sheet_is_never_widened() {
        let full = [[0.0, 0.0], [40.0, 0.0], [40.0, 40.0]];
        let full2 = [[0.0, 0.0], [40.0, 40.0], [0.0, 40.0]];
        let faces: Vec<PaletteFace> = (0..10).map(|k| face(k, [f64::from(k) + 0.5, 0.5])).collect();
        let mut sizes = vec![(40, 40)];
        let charts = [(0, full), (0, full2)].into_iter();
        let fixed = PaletteSpace { may_widen: false, ..space(4, (64, 64)) };
        let p = place_palette(&faces, 0, charts, &mut sizes, fixed);
        assert_eq!(sizes[0], (40, 40));
        assert_eq!((p.report.sheets_widened, p.report.sheets_added), (0, 1));
        assert!(p.blocks.iter().all(|b| b.sheet == 1));
    }

    #[test]
    fn block_sides_fill_whole_jpeg_blocks() {
        assert_eq!(block_side(ImageFormat::Png, 90, false), 4);
        assert_eq!(block_side(ImageFormat::Jpeg, 90, false), 8);
        assert_eq!(block_side(ImageFormat::Jpeg, 75, false), 16);
        assert_eq!(block_side(ImageFormat::Webp, 75, true), 16);
    }
}
