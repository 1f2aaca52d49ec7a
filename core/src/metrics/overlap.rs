//! Texel overlaps exactly as evaluate.py's `raster_collisions()` and `overlap_pairs()` define
//! them: a texel is covered by a face when its centre lies strictly inside the face by
//! [`RASTER_EPS`] along the scanline; texels covered by two or more faces of one sheet overlap.
//!
//! Each sheet is cut into tiles of at most [`TILE_TEXELS`] texels (whole rows when the sheet is
//! narrower than that), laid over the bounding box of its faces. Tiles are processed in parallel,
//! each with its own owner and coverage buffers, so memory stays bounded whatever the sheet size.
//! Faces are visited in increasing index order inside a tile, so the first faces of each texel are
//! known without sorting.

use rayon::prelude::*;

use super::stats::{DEGENERATE, FINITE, Prep};
use super::{OVERLAP_PAIR_CAP, RASTER_EPS};
use crate::index::NONE;

/// Texels per tile (4 MiB of owners, 1 MiB of coverage counts).
const TILE_TEXELS: usize = 1 << 20;
/// Face pairs kept per tile before they are sorted and deduplicated, bounding tile memory.
const PAIR_FLUSH: usize = 1 << 22;

/// The overlap figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OverlapCounts {
    /// Texels covered by two or more faces.
    pub texels: u64,
    /// Distinct face pairs sharing such a texel.
    pub face_pairs: u64,
}

/// A face to rasterize: its index, texel corners, clamped row range `j0..=j1` and a clamped
/// column range `c0..=c1` that contains every texel centre it can cover.
struct RasterFace {
    f: u32,
    t: [[f64; 2]; 3],
    j0: u32,
    j1: u32,
    c0: u32,
    c1: u32,
}

/// Counts overlapping texels and face pairs over all sheets of known size.
pub(crate) fn overlaps(prep: &Prep<'_>, flags: &[u8]) -> OverlapCounts {
    let mut out = OverlapCounts::default();
    for key in 1..prep.size.len() {
        let Some((w, h)) = prep.size[key] else { continue };
        if w == 0 || h == 0 {
            continue;
        }
        // A face belongs to one sheet, so pairs of different sheets are distinct.
        let (texels, pairs) = sheet_overlaps(prep, flags, key as u32, w, h);
        out.texels += texels;
        out.face_pairs += pairs.len() as u64;
    }
    out
}

/// The faces of one sheet taking part in the raster (finite, non-degenerate UVs), with the rows
/// of texel centres evaluate.py considers for them.
fn sheet_faces(prep: &Prep<'_>, flags: &[u8], key: u32, w: u32, h: u32) -> Vec<RasterFace> {
    let nf = prep.model.faces.len();
    let clamp = |x: f64, n: u32| x.max(0.0).min(n as f64 - 1.0) as u32;
    (0..nf)
        .into_par_iter()
        .with_min_len(1 << 15)
        .filter(|&f| {
            prep.sheet_key[f] == key && flags[f] & FINITE != 0 && flags[f] & DEGENERATE == 0
        })
        .filter_map(|f| {
            let t = prep.texels(f);
            let ymin = t[0][1].min(t[1][1]).min(t[2][1]);
            let ymax = t[0][1].max(t[1][1]).max(t[2][1]);
            let j0 = ((ymin + RASTER_EPS - 0.5).ceil()).max(0.0);
            let j1 = ((ymax - RASTER_EPS - 0.5).floor()).min(h as f64 - 1.0);
            // Scanline crossings lie between the extreme x up to rounding; one texel of margin
            // keeps the column range a superset (spans are clipped to tiles exactly later).
            let xmin = t[0][0].min(t[1][0]).min(t[2][0]);
            let xmax = t[0][0].max(t[1][0]).max(t[2][0]);
            let (c0, c1) = (clamp(xmin.floor() - 1.0, w), clamp(xmax.ceil() + 1.0, w));
            // All finite here: the UVs are finite and the sheet size fits in u32.
            (j1 >= j0).then_some(RasterFace {
                f: f as u32,
                t,
                j0: j0 as u32,
                j1: j1 as u32,
                c0,
                c1,
            })
        })
        .collect()
}

/// The columns `i0..=i1` of texel centres strictly inside face `t` on the row of centre `y`,
/// computed with evaluate.py's formula and operation order so that decisions agree bit for bit.
#[inline]
fn span(t: &[[f64; 2]; 3], y: f64, w: u32) -> Option<(usize, usize)> {
    let mut xl = f64::INFINITY;
    let mut xr = f64::NEG_INFINITY;
    for e in 0..3 {
        let (xa, ya) = (t[e][0], t[e][1]);
        let (xb, yb) = (t[(e + 1) % 3][0], t[(e + 1) % 3][1]);
        // Canonical endpoint order, so both faces of a shared edge compute the same x.
        let sw = ya > yb || (ya == yb && xa > xb);
        let (x0, y0, x1, y1) = if sw { (xb, yb, xa, ya) } else { (xa, ya, xb, yb) };
        if y0 <= y && y <= y1 && y0 < y1 {
            let x = x0 + (y - y0) * (x1 - x0) / (y1 - y0);
            xl = xl.min(x);
            xr = xr.max(x);
        }
    }
    let i0 = (xl + RASTER_EPS - 0.5).ceil().max(0.0);
    let i1 = (xr - RASTER_EPS - 0.5).floor().min(w as f64 - 1.0);
    if !(i0.is_finite() && i1.is_finite()) || i1 < i0 {
        return None;
    }
    Some((i0 as usize, i1 as usize))
}

/// The tiling of one sheet: tiles of `tw × th` texels over rows `row0..` and columns `col0..`
/// (the bounding box of the faces), `ntx` tiles across.
#[derive(Clone, Copy)]
struct Tiling {
    w: u32,
    h: u32,
    tw: usize,
    th: usize,
    row0: usize,
    col0: usize,
    ntx: usize,
    nty: usize,
}

impl Tiling {
    fn new(faces: &[RasterFace], w: u32, h: u32) -> Self {
        let row0 = faces.iter().map(|f| f.j0).min().unwrap_or(0) as usize;
        let row1 = faces.iter().map(|f| f.j1).max().unwrap_or(0) as usize;
        let col0 = faces.iter().map(|f| f.c0).min().unwrap_or(0) as usize;
        let col1 = faces.iter().map(|f| f.c1).max().unwrap_or(0) as usize;
        let tw = (col1 - col0 + 1).min(TILE_TEXELS);
        let th = (TILE_TEXELS / tw).max(1);
        let ntx = (col1 - col0 + 1).div_ceil(tw);
        let nty = (row1 - row0 + 1).div_ceil(th);
        Self { w, h, tw, th, row0, col0, ntx, nty }
    }

    /// The tiles a face is listed in (row-major tile ids).
    fn tiles(&self, rf: &RasterFace) -> impl Iterator<Item = usize> + use<> {
        let (t, s) = (*self, rf);
        let ty = (s.j0 as usize - t.row0) / t.th..=(s.j1 as usize - t.row0) / t.th;
        let tx = (s.c0 as usize - t.col0) / t.tw..=(s.c1 as usize - t.col0) / t.tw;
        ty.flat_map(move |y| tx.clone().map(move |x| y * t.ntx + x))
    }

    /// Rows `r0..r1` and columns `x0..x1` of tile `k`, clipped to the sheet.
    fn bounds(&self, k: usize) -> (usize, usize, usize, usize) {
        let (ty, tx) = (k / self.ntx, k % self.ntx);
        let r0 = self.row0 + ty * self.th;
        let x0 = self.col0 + tx * self.tw;
        (r0, (r0 + self.th).min(self.h as usize), x0, (x0 + self.tw).min(self.w as usize))
    }
}

/// Overlapping texels and (sorted, distinct) face pairs of one sheet.
fn sheet_overlaps(prep: &Prep<'_>, flags: &[u8], key: u32, w: u32, h: u32) -> (u64, Vec<u64>) {
    let faces = sheet_faces(prep, flags, key, w, h);
    if faces.is_empty() {
        return (0, Vec::new());
    }
    let tiling = Tiling::new(&faces, w, h);
    let n_tiles = tiling.ntx * tiling.nty;
    // Faces per tile (CSR), in increasing face order. The tile grid covers only the faces'
    // bounding box, so its size is bounded by the texels the raster visits anyway.
    let mut start = vec![0u32; n_tiles + 1];
    for rf in &faces {
        for k in tiling.tiles(rf) {
            start[k + 1] += 1;
        }
    }
    for k in 0..n_tiles {
        start[k + 1] += start[k];
    }
    let mut fill: Vec<u32> = start[..n_tiles].to_vec();
    let mut members = vec![0u32; start[n_tiles] as usize];
    for (i, rf) in faces.iter().enumerate() {
        for k in tiling.tiles(rf) {
            members[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
    }
    drop(fill);

    let results: Vec<(u64, Vec<u64>)> = (0..n_tiles)
        .into_par_iter()
        .map(|k| {
            let list = &members[start[k] as usize..start[k + 1] as usize];
            tile_overlaps(&faces, list, tiling.bounds(k), w)
        })
        .collect();
    let mut texels = 0u64;
    let mut pairs = Vec::new();
    for (t, p) in results {
        texels += t;
        pairs.extend(p);
    }
    pairs.par_sort_unstable();
    pairs.dedup();
    (texels, pairs)
}

/// Rasterizes the faces `list` (indices into `faces`, increasing) over the tile of rows `r0..r1`
/// and columns `x0..x1`.
fn tile_overlaps(
    faces: &[RasterFace],
    list: &[u32],
    (r0, r1, x0, x1): (usize, usize, usize, usize),
    w: u32,
) -> (u64, Vec<u64>) {
    let tw = x1 - x0;
    let n = (r1 - r0) * tw;
    if list.len() < 2 || n == 0 {
        return (0, Vec::new());
    }
    // The first face covering each texel, and how many faces cover it (saturating).
    let mut owner = vec![NONE; n];
    let mut cov = vec![0u8; n];
    // (texel << 32 | face) for the 2nd..16th faces of each texel.
    let mut extra: Vec<u64> = Vec::new();
    let mut texels = 0u64;
    for &k in list {
        let rf = &faces[k as usize];
        let rows = (rf.j0 as usize).max(r0)..=(rf.j1 as usize).min(r1 - 1);
        for j in rows {
            let Some((i0, i1)) = span(&rf.t, j as f64 + 0.5, w) else { continue };
            let (i0, i1) = (i0.max(x0), i1.min(x1 - 1));
            if i1 < i0 {
                continue;
            }
            let row = (j - r0) * tw;
            for t in row + i0 - x0..=row + i1 - x0 {
                let c = cov[t];
                if c == 0 {
                    owner[t] = rf.f;
                } else {
                    texels += (c == 1) as u64;
                    if (c as usize) < OVERLAP_PAIR_CAP {
                        extra.push(((t as u64) << 32) | rf.f as u64);
                    }
                }
                cov[t] = c.saturating_add(1);
            }
        }
    }
    drop(cov);
    // Faces arrive in increasing order, so after sorting by texel each texel's faces are the
    // owner followed by its extra faces, all increasing: the lowest OVERLAP_PAIR_CAP faces.
    extra.sort_unstable();
    let mut pairs: Vec<u64> = Vec::new();
    let mut group: Vec<u32> = Vec::with_capacity(OVERLAP_PAIR_CAP);
    let mut i = 0;
    while i < extra.len() {
        let t = (extra[i] >> 32) as usize;
        group.clear();
        group.push(owner[t]);
        while i < extra.len() && (extra[i] >> 32) as usize == t {
            group.push(extra[i] as u32);
            i += 1;
        }
        for a in 0..group.len() {
            for b in a + 1..group.len() {
                pairs.push(((group[a] as u64) << 32) | group[b] as u64);
            }
        }
        if pairs.len() >= PAIR_FLUSH {
            pairs.sort_unstable();
            pairs.dedup();
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    (texels, pairs)
}
