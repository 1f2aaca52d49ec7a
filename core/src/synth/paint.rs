//! Texels of the synthetic sheets: every texel centre inside a triangle gets the true colour of
//! the 3D point it maps to, then gutters are dilated around the charts.
//!
//! Sheets are filled tile by tile in parallel: triangles are bucketed per tile (CSR arrays over
//! all sheets), and each worker rasterizes its tile's triangles clipped to the tile, so pixel
//! working memory is one tile per worker and the pixels themselves live in memory-mapped
//! [`TileStore`] files.

use std::path::Path;

use rayon::prelude::*;

use super::color::{linear_to_srgb8, true_color};
use crate::model::Model;
use crate::texture::gutter::{Coverage, dilate, tile_bit};
use crate::texture::raster::{PixelRect, rasterize_triangle};
use crate::texture::store::TILE;
use crate::texture::{PixelFormat, TextureError, TileStore};

/// Texel counts of the painted sheets.
#[derive(Clone, Copy, Debug, Default)]
pub struct PaintStats {
    /// Texels inside triangles.
    pub written: u64,
    /// Texels filled by gutter dilation.
    pub gutter: u64,
}

/// The texel-space triangle of a face (UVs times the sheet size, as every reader computes it).
#[inline]
fn texel_tri(model: &Model, f: usize, size: f64) -> Option<[[f64; 2]; 3]> {
    let t = model.faces[f].uv?;
    Some(t.map(|i| {
        let uv = model.uvs[i.idx()];
        [uv[0] * size, uv[1] * size]
    }))
}

/// The tiles `[tx0, tx1] × [ty0, ty1]` a texel-space triangle may touch.
#[inline]
fn tile_span(tri: &[[f64; 2]; 3], size: u32, tiles: u32) -> Option<(u32, u32, u32, u32)> {
    let (mut x0, mut x1, mut y0, mut y1) =
        (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for p in tri {
        x0 = x0.min(p[0]);
        x1 = x1.max(p[0]);
        y0 = y0.min(p[1]);
        y1 = y1.max(p[1]);
    }
    if !(x0.is_finite() && x1.is_finite() && y0.is_finite() && y1.is_finite()) {
        return None;
    }
    let s = size as f64;
    // Columns and rows (row 0 at the top) the bounding box overlaps, clamped to the sheet.
    let col = |x: f64| (x.floor().clamp(0.0, s - 1.0) as u32) / TILE;
    let row = |y: f64| ((s - y).floor().clamp(0.0, s - 1.0) as u32) / TILE;
    let (tx0, tx1, ty0, ty1) = (col(x0), col(x1), row(y1), row(y0));
    (tx0 < tiles && ty0 < tiles).then_some((tx0, tx1.min(tiles - 1), ty0, ty1.min(tiles - 1)))
}

/// Paints `sheets` square sheets of `size` pixels for `model` (one material per sheet, material
/// `k` on sheet `k`) into tile stores under `work_dir`, with gutters `gutter` texels wide.
pub fn paint(
    model: &Model,
    sheets: usize,
    size: u32,
    gutter: u32,
    work_dir: &Path,
) -> Result<(Vec<TileStore>, PaintStats), TextureError> {
    let tiles = size.div_ceil(TILE);
    let per_sheet = (tiles * tiles) as usize;
    let fsize = size as f64;
    let sheet_of = |f: usize| model.faces[f].material.map(|m| m.idx()).filter(|&m| m < sheets);
    // Bucket faces per (sheet, tile): count, prefix-sum, fill (faces in increasing order).
    let mut start = vec![0u32; sheets * per_sheet + 1];
    let each = |f: usize, visit: &mut dyn FnMut(usize)| {
        let (Some(k), Some(tri)) = (sheet_of(f), texel_tri(model, f, fsize)) else { return };
        if let Some((tx0, tx1, ty0, ty1)) = tile_span(&tri, size, tiles) {
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    visit(k * per_sheet + (ty * tiles + tx) as usize);
                }
            }
        }
    };
    for f in 0..model.faces.len() {
        each(f, &mut |key| start[key + 1] += 1);
    }
    for i in 0..start.len() - 1 {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut bucket = vec![0u32; *start.last().unwrap_or(&0) as usize];
    for f in 0..model.faces.len() {
        each(f, &mut |key| {
            bucket[fill[key] as usize] = f as u32;
            fill[key] += 1;
        });
    }
    drop(fill);

    let mut stats = PaintStats::default();
    let mut out = Vec::with_capacity(sheets);
    for k in 0..sheets {
        let mut store = TileStore::create(work_dir, size, size, PixelFormat::RGB8)?;
        let mut cov = Coverage::for_store(&store);
        store.par_tiles_mut().zip(cov.par_tiles_mut()).for_each(|((tx, ty, px), (_, _, bits))| {
            let key = k * per_sheet + (ty * tiles + tx) as usize;
            let (x0, y0) = (tx * TILE, ty * TILE);
            let clip = PixelRect::new(x0, y0, (x0 + TILE).min(size), (y0 + TILE).min(size));
            for &f in &bucket[start[key] as usize..start[key + 1] as usize] {
                let f = f as usize;
                let Some(tri) = texel_tri(model, f, fsize) else { continue };
                let p = model.faces[f].v.map(|v| model.positions[v.idx()]);
                rasterize_triangle(tri, size, clip, |i, j, b| {
                    let q = [
                        b[0] * p[0][0] + b[1] * p[1][0] + b[2] * p[2][0],
                        b[0] * p[0][1] + b[1] * p[1][1] + b[2] * p[2][1],
                        b[0] * p[0][2] + b[1] * p[1][2] + b[2] * p[2][2],
                    ];
                    let c = true_color(q);
                    let (lx, ly) = (i - x0, j - y0);
                    let o = (ly * TILE + lx) as usize * 3;
                    px[o] = linear_to_srgb8(c[0]);
                    px[o + 1] = linear_to_srgb8(c[1]);
                    px[o + 2] = linear_to_srgb8(c[2]);
                    let (w, m) = tile_bit(lx, ly);
                    bits[w] |= m;
                });
            }
        });
        stats.written += cov.count();
        stats.gutter += dilate(&mut store, &mut cov, gutter)?;
        // Let the kernel start writing the finished sheet back, so its dirty pages do not pile up.
        store.flush_async()?;
        // Drop the finished sheet from the resident set: its pixels live on in the tile file and
        // the page cache, so a run of many big sheets costs RSS of about one sheet, not all.
        store.release_tile_rows(0, store.tiles_y());
        out.push(store);
    }
    Ok((out, stats))
}
