//! Push-pull fill of unwritten texels [GGSC96], as the reference does it after rendering
//! (`vcg::PullPush`), but tiled and out of core.
//!
//! Pull: level `k + 1` (half size, rounded up) takes in each texel the mean of the written texels
//! among its 2×2 children, and is unwritten when none is; children beyond an odd edge count as
//! unwritten. Pulling stops at the first level with no unwritten texel (at the latest 1×1).
//! Push: from the coarsest level down, every unwritten texel of level `k` gets the bilinear
//! up-sample of level `k + 1`: weights 9/3/3/1 for its parent, the two edge neighbours of the
//! parent towards the texel's quadrant and the diagonal one, renormalized where a neighbour lies
//! beyond the border. Written texels never change, and the colours spread outward smoothly, so
//! no mip level of the sheet blends in background black.
//!
//! Memory: level 0 is the sheet's own [`TileStore`]; each coarser level is another `TileStore`
//! file in the work directory in the sheet's pixel format (so sums are rounded to that format at
//! every level, as in the reference's 8-bit images) plus a heap [`Coverage`] of one bit per
//! texel. Levels `≥ 1` together cost about a third of the sheet's tile file on disk and in the
//! page cache, and a few MiB of heap for the masks;
//! a level is dropped (its file deleted) as soon as the level below has been pushed. Pull and push
//! run a band of tile rows at a time and drop the rows of both levels they are done with from the
//! resident set, so a gigapixel sheet costs a band's pages, not the sheet's. Every level is built
//! tile by tile in parallel; a tile reads only the level below or above, never its own level, so
//! the result does not depend on the thread count.

use std::path::Path;

use rayon::prelude::*;

use super::pixel::{load, store_pixel};
use crate::texture::gutter::{Coverage, TILE_WORDS, tile_bit};
use crate::texture::raster::PixelRect;
use crate::texture::store::TILE;
use crate::texture::{TextureError, TileStore};

/// What one push-pull fill did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct PushPullStats {
    /// Texels of the sheet filled.
    pub filled: u64,
    /// Pyramid levels built above the sheet itself.
    pub levels: u32,
    /// Bytes of the tile files of those levels (disk and page cache, not heap).
    pub pyramid_bytes: u64,
}

/// The pixel rectangle of tile `(tx, ty)` of a `w × h` image.
#[inline]
fn rect_of(tx: u32, ty: u32, w: u32, h: u32) -> PixelRect {
    PixelRect::new(tx * TILE, ty * TILE, ((tx + 1) * TILE).min(w), ((ty + 1) * TILE).min(h))
}

/// Fills every texel of `store` not set in `coverage` by push-pull and sets its bit; written
/// texels keep their bytes. Temporary levels go to `work_dir`. A sheet with no written texel is
/// left as it is (there is no colour to spread).
pub fn push_pull(
    store: &mut TileStore,
    coverage: &mut Coverage,
    work_dir: &Path,
) -> Result<PushPullStats, TextureError> {
    let (w, h) = (store.width(), store.height());
    if coverage.width() != w || coverage.height() != h {
        return Err(TextureError::Size {
            image: "coverage mask".into(),
            width: u64::from(coverage.width()),
            height: u64::from(coverage.height()),
            msg: format!("does not match the {w}x{h} sheet"),
        });
    }
    let total = |c: &Coverage| u64::from(c.width()) * u64::from(c.height());
    let covered = coverage.count();
    let mut stats = PushPullStats::default();
    if covered == 0 || covered == total(coverage) {
        return Ok(stats);
    }
    // Pull until a level is complete. Level 0 has a written texel, so every level has one, and
    // a 1×1 level is complete.
    let mut levels: Vec<(TileStore, Coverage)> = Vec::new();
    loop {
        let (prev, prev_cov) = match levels.last() {
            Some((s, c)) => (s, c),
            None => (&*store, &*coverage),
        };
        if prev_cov.count() == total(prev_cov) {
            break;
        }
        let (nw, nh) = (prev.width().div_ceil(2), prev.height().div_ceil(2));
        let mut next = TileStore::create(work_dir, nw, nh, prev.format())?;
        let mut next_cov = Coverage::new(nw, nh);
        pull(prev, prev_cov, &mut next, &mut next_cov);
        prev.release_tile_rows(0, prev.tiles_y());
        stats.levels += 1;
        stats.pyramid_bytes +=
            u64::from(next.tiles_x()) * u64::from(next.tiles_y()) * next.tile_bytes() as u64;
        levels.push((next, next_cov));
    }
    // Push, coarsest level first; each parent is complete when its children are filled.
    while let Some((parent, _)) = levels.pop() {
        match levels.last_mut() {
            Some((s, c)) => {
                push(s, c, &parent);
            }
            None => stats.filled = push(store, coverage, &parent),
        }
    }
    Ok(stats)
}

/// Builds level `next` from `prev`: each texel is the mean of its written children. A band of
/// tile rows at a time, dropping the pages of `next` and `prev` it is done with from the resident
/// set (see [`TileStore::release_tile_rows`]): otherwise a pass over a gigapixel level leaves its
/// whole tile file resident.
fn pull(prev: &TileStore, prev_cov: &Coverage, next: &mut TileStore, next_cov: &mut Coverage) {
    // A band reads two tile rows of `prev`, each twice as wide, per tile row of `next`: sized
    // by what it reads, so that both levels' pages of one band stay near the band size.
    let band = super::band_rows(4 * next.tiles_x() as usize * next.tile_bytes());
    let mut ty0 = 0;
    while ty0 < next.tiles_y() {
        let ty1 = ty0.saturating_add(band);
        pull_rows(prev, prev_cov, next, next_cov, ty0, ty1);
        next.release_tile_rows(ty0, ty1);
        // Tile row `ty` of `next` reads tile rows `2·ty` and `2·ty + 1` of `prev` only.
        prev.release_tile_rows(2 * ty0, 2 * ty1);
        ty0 = ty1;
    }
}

/// Pulls tile rows `ty0..ty1` of `next` (see [`pull`]).
fn pull_rows(
    prev: &TileStore,
    prev_cov: &Coverage,
    next: &mut TileStore,
    next_cov: &mut Coverage,
    ty0: u32,
    ty1: u32,
) {
    let (nw, nh) = (next.width(), next.height());
    let format = next.format();
    let (ch, sample, bpp) = (format.channels as usize, format.sample, format.bytes_per_pixel());
    let tiles = next.par_tile_rows_mut(ty0, ty1).zip(next_cov.par_tile_rows_mut(ty0, ty1));
    tiles.for_each(|((tx, ty, px), (_, _, bits))| {
        let rect = rect_of(tx, ty, nw, nh);
        let mut acc = [0.0f64; 4];
        for y in rect.y0..rect.y1 {
            for x in rect.x0..rect.x1 {
                acc.fill(0.0);
                let mut n = 0u32;
                for (cx, cy) in
                    [(2 * x, 2 * y), (2 * x + 1, 2 * y), (2 * x, 2 * y + 1), (2 * x + 1, 2 * y + 1)]
                {
                    // `get` is false beyond the image, which handles odd sizes.
                    if prev_cov.get(cx, cy) {
                        n += 1;
                        let p = prev.pixel(cx, cy);
                        for (c, a) in acc.iter_mut().enumerate().take(ch) {
                            *a += load(p, c, sample);
                        }
                    }
                }
                if n > 0 {
                    let inv = 1.0 / f64::from(n);
                    for a in &mut acc[..ch] {
                        *a *= inv;
                    }
                    let (lx, ly) = (x - rect.x0, y - rect.y0);
                    let o = (ly * TILE + lx) as usize * bpp;
                    store_pixel(&mut px[o..o + bpp], format, &acc);
                    let (wi, m) = tile_bit(lx, ly);
                    bits[wi] |= m;
                }
            }
        }
    });
}

/// Fills the unwritten texels of `child` from the complete level `parent` above it, sets their
/// bits, and returns how many there were. A band of tile rows at a time, releasing the pages it
/// is done with, as [`pull`] does.
fn push(child: &mut TileStore, child_cov: &mut Coverage, parent: &TileStore) -> u64 {
    let band = super::band_rows(child.tiles_x() as usize * child.tile_bytes());
    let mut filled = 0;
    let mut ty0 = 0;
    while ty0 < child.tiles_y() {
        let ty1 = ty0.saturating_add(band);
        filled += push_rows(child, child_cov, parent, ty0, ty1);
        child.release_tile_rows(ty0, ty1);
        // Tile row `ty` of `child` reads `parent` from a texel above its top row on: the rows
        // of `parent` above `ty1 / 2 - 1` are done with.
        parent.release_tile_rows((ty0 / 2).saturating_sub(1), (ty1 / 2).saturating_sub(1));
        ty0 = ty1;
    }
    filled
}

/// Pushes into tile rows `ty0..ty1` of `child` (see [`push`]).
fn push_rows(
    child: &mut TileStore,
    child_cov: &mut Coverage,
    parent: &TileStore,
    ty0: u32,
    ty1: u32,
) -> u64 {
    let (cw, chh) = (child.width(), child.height());
    let (pw, ph) = (parent.width(), parent.height());
    let format = child.format();
    let (ch, sample, bpp) = (format.channels as usize, format.sample, format.bytes_per_pixel());
    child
        .par_tile_rows_mut(ty0, ty1)
        .zip(child_cov.par_tile_rows_mut(ty0, ty1))
        .map(|((tx, ty, px), (_, _, bits))| {
            let rect = rect_of(tx, ty, cw, chh);
            // A complete tile needs no work (padding bits are never set).
            let texels = u64::from((rect.x1 - rect.x0) * (rect.y1 - rect.y0));
            let set: u64 = bits[..TILE_WORDS].iter().map(|w| u64::from(w.count_ones())).sum();
            if set == texels {
                return 0;
            }
            let mut n = 0u64;
            let mut acc = [0.0f64; 4];
            for y in rect.y0..rect.y1 {
                for x in rect.x0..rect.x1 {
                    let (lx, ly) = (x - rect.x0, y - rect.y0);
                    let (wi, m) = tile_bit(lx, ly);
                    if bits[wi] & m != 0 {
                        continue;
                    }
                    let (qx, qy) = (x / 2, y / 2);
                    // The parent neighbours on the side of the texel's quadrant, if inside.
                    let nx = if x % 2 == 0 {
                        qx.checked_sub(1)
                    } else {
                        Some(qx + 1).filter(|&v| v < pw)
                    };
                    let ny = if y % 2 == 0 {
                        qy.checked_sub(1)
                    } else {
                        Some(qy + 1).filter(|&v| v < ph)
                    };
                    acc.fill(0.0);
                    let mut wsum = 0.0;
                    let mut tap = |px_: &[u8], wgt: f64| {
                        wsum += wgt;
                        for (c, a) in acc.iter_mut().enumerate().take(ch) {
                            *a += wgt * load(px_, c, sample);
                        }
                    };
                    tap(parent.pixel(qx, qy), 9.0);
                    if let Some(nx) = nx {
                        tap(parent.pixel(nx, qy), 3.0);
                    }
                    if let Some(ny) = ny {
                        tap(parent.pixel(qx, ny), 3.0);
                    }
                    if let (Some(nx), Some(ny)) = (nx, ny) {
                        tap(parent.pixel(nx, ny), 1.0);
                    }
                    let inv = 1.0 / wsum;
                    for a in &mut acc[..ch] {
                        *a *= inv;
                    }
                    let o = (ly * TILE + lx) as usize * bpp;
                    store_pixel(&mut px[o..o + bpp], format, &acc);
                    bits[wi] |= m;
                    n += 1;
                }
            }
            n
        })
        .sum()
}
