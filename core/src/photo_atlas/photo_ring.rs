//! Gutters of sub-charts copied from their photo (at the sub-chart's pyramid level) instead of
//! dilated.
//!
//! Bilinear filtering near a chart's border blends in texels just outside its faces: the
//! renderer does, and so does any measure that samples the texture near a seam. Dilation puts
//! copies of the border texels there, which differ from the photo by the colour change over one
//! texel: on detailed surface a faint seam around every chart, and around a sub-chart at level
//! `l`, whose texel spans `2^l` photo pixels, a visible one. Every sub-chart is an exact grid
//! placement of its level's texels, so the ring of texels around it that filtering reads can be
//! copied from that level instead (the build copies one texel; dilation continues from there).
//! A ring texel also carries the difference between the output and the source at the texel it
//! continues (the exposure gain and, after smoothing, the colour correction), so the ring stays
//! consistent with the corrected interior.
use super::partition::NONE;
use crate::geometry::GridTransform;
use crate::photo_atlas::smoothing::{read_rgb, write_rgb};
use crate::texture::TileStore;
use crate::texture::gutter::Coverage;
use crate::texture::raster::{PixelRect, rasterize_triangle};

/// A sub-chart as packed, with the source it is an exact copy of.
#[derive(Clone, Debug)]
pub struct RingChart {
    /// Output sheet and the source sheet (the photo's pyramid level) it is copied from.
    pub out_sheet: u32,
    pub src_sheet: u32,
    /// Source texel space to output texel space.
    pub transform: GridTransform,
    /// Its faces.
    pub faces: Vec<u32>,
}

/// The eight neighbours, in the fixed order that decides which texel a ring texel continues.
const NEIGHBOURS: [(i32, i32); 8] =
    [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (1, -1), (-1, 1), (1, 1)];

/// Fills the ring of `radius` texels around each chart of `charts` on `sheets` from `sources`
/// and lists the texels written in `ring` as `(sheet, column, row)`, for the gutter stage to
/// keep. `faces_covered` holds every face texel of each output sheet: those are never written.
/// Texels whose source falls outside the source image are left to dilation. Running it again
/// (after smoothing) rewrites the same texels. Charts are filled in order, each ring
/// layer after the previous one, so the result does not depend on the thread count. A source
/// and output of different pixel formats is skipped (its ring is dilated as usual).
pub fn fill_rings(
    charts: &[RingChart],
    out_tri: &dyn Fn(usize) -> [[f64; 2]; 3],
    radius: u32,
    sources: &[TileStore],
    sheets: &mut [TileStore],
    faces_covered: &[Coverage],
    ring: &mut Vec<(u32, u32, u32)>,
) {
    ring.clear();
    let r = radius as i64;
    let mut state: Vec<u8> = Vec::new();
    let mut layer: Vec<(u32, u32, u32, u32)> = Vec::new();
    for ch in charts {
        let (Some(src), Some(out)) =
            (sources.get(ch.src_sheet as usize), sheets.get(ch.out_sheet as usize))
        else {
            continue;
        };
        if src.format() != out.format() || ch.faces.is_empty() {
            continue;
        }
        let (w, h) = (out.width(), out.height());
        let (sw, sh) = (src.width(), src.height());
        // The chart's box in pixels (row 0 at the top), grown by the ring.
        let (mut x0, mut y0, mut x1, mut y1) =
            (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
        for &f in &ch.faces {
            for p in out_tri(f as usize) {
                x0 = x0.min(p[0]);
                x1 = x1.max(p[0]);
                y0 = y0.min(f64::from(h) - p[1]);
                y1 = y1.max(f64::from(h) - p[1]);
            }
        }
        if !(x0 <= x1 && y0 <= y1) {
            continue;
        }
        let bx0 = (x0.floor() as i64 - r - 1).clamp(0, i64::from(w)) as u32;
        let by0 = (y0.floor() as i64 - r - 1).clamp(0, i64::from(h)) as u32;
        let bx1 = (x1.ceil() as i64 + r + 1).clamp(0, i64::from(w)) as u32;
        let by1 = (y1.ceil() as i64 + r + 1).clamp(0, i64::from(h)) as u32;
        if bx0 >= bx1 || by0 >= by1 {
            continue;
        }
        let bw = (bx1 - bx0) as usize;
        state.clear();
        state.resize(bw * (by1 - by0) as usize, 0);
        // 1 = a face texel of this chart; k + 1 = filled in ring layer k.
        let rect = PixelRect::new(bx0, by0, bx1, by1);
        for &f in &ch.faces {
            rasterize_triangle(out_tri(f as usize), h, rect, |i, j, _| {
                state[(j - by0) as usize * bw + (i - bx0) as usize] = 1;
            });
        }
        let cov = &faces_covered[ch.out_sheet as usize];
        let out = &mut sheets[ch.out_sheet as usize];
        let bpp = out.format().bytes_per_pixel();
        let alpha = out.format().channels.is_multiple_of(2);
        for k in 1..=radius.min(250) as u8 {
            layer.clear();
            for y in by0..by1 {
                for x in bx0..bx1 {
                    let o = (y - by0) as usize * bw + (x - bx0) as usize;
                    if state[o] != 0 || cov.get(x, y) {
                        continue;
                    }
                    let nb = NEIGHBOURS.iter().find_map(|&(dx, dy)| {
                        let (nx, ny) = (i64::from(x) + i64::from(dx), i64::from(y) + i64::from(dy));
                        if nx < i64::from(bx0)
                            || ny < i64::from(by0)
                            || nx >= i64::from(bx1)
                            || ny >= i64::from(by1)
                        {
                            return None;
                        }
                        let s = state
                            [(ny - i64::from(by0)) as usize * bw + (nx - i64::from(bx0)) as usize];
                        (s != 0 && s <= k).then_some((nx as u32, ny as u32))
                    });
                    if let Some((nx, ny)) = nb {
                        layer.push((x, y, nx, ny));
                    }
                }
            }
            for &(x, y, nx, ny) in &layer {
                let t = &ch.transform;
                let (Some(ps), Some(pn)) =
                    (t.source_pixel(x, y, h, sw, sh), t.source_pixel(nx, ny, h, sw, sh))
                else {
                    continue;
                };
                let (vs, vn, on) =
                    (read_rgb(src, ps.0, ps.1), read_rgb(src, pn.0, pn.1), read_rgb(out, nx, ny));
                write_rgb(out, x, y, [0, 1, 2].map(|c| vs[c] + on[c] - vn[c]));
                if alpha {
                    // The alpha samples are the last of a pixel: continue the neighbour's.
                    let s = out.format().sample.bytes();
                    let mut a = [0u8; 4];
                    a[..s].copy_from_slice(&out.pixel(nx, ny)[bpp - s..]);
                    out.pixel_mut(x, y)[bpp - s..].copy_from_slice(&a[..s]);
                }
                state[(y - by0) as usize * bw + (x - bx0) as usize] = k + 1;
                ring.push((ch.out_sheet, x, y));
            }
        }
    }
}

/// The packed sub-charts that were placed as exact grid copies of their source: `face_sub` is
/// each face's sub-chart ([`NONE`] for the unseen), `sub_sheet` each sub-chart's input sheet.
pub fn ring_charts(
    face_sub: &[u32],
    sub_sheet: &[u32],
    packed: &crate::pack::PackedLayout,
) -> Vec<RingChart> {
    let mut index = vec![NONE; sub_sheet.len()];
    let mut out: Vec<RingChart> = Vec::new();
    for (f, &s) in face_sub.iter().enumerate() {
        if s == NONE {
            continue;
        }
        let Some(transform) = packed.chart_transform[s as usize] else { continue };
        if index[s as usize] == NONE {
            index[s as usize] = out.len() as u32;
            out.push(RingChart {
                out_sheet: packed.face_sheet[f],
                src_sheet: sub_sheet[s as usize],
                transform,
                faces: Vec::new(),
            });
        }
        out[index[s as usize] as usize].faces.push(f as u32);
    }
    out
}
