//! Texel overlaps exactly as evaluate.py's `raster_collisions()` and `overlap_pairs()` define
//! them: a texel is covered by a face when its centre lies strictly inside the face by
//! [`RASTER_EPS`] along the scanline; texels covered by two or more faces of one sheet overlap.
//!
//! Each sheet is processed in row bands of at most [`BAND_TEXELS`] texels, in parallel, each band
//! with its own owner and coverage buffers, so memory stays bounded whatever the sheet size. Faces
//! are visited in increasing index order inside a band, so the first faces of a texel are known
//! without sorting.

use rayon::prelude::*;

use super::stats::{DEGENERATE, FINITE, Prep};
use super::{OVERLAP_PAIR_CAP, RASTER_EPS};

/// Texels per band (4 MiB of owners, 1 MiB of coverage counts).
const BAND_TEXELS: usize = 1 << 20;
/// Face pairs kept per band before they are sorted and deduplicated, bounding band memory.
const PAIR_FLUSH: usize = 1 << 22;

/// The overlap figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OverlapCounts {
    /// Texels covered by two or more faces.
    pub texels: u64,
    /// Distinct face pairs sharing such a texel.
    pub face_pairs: u64,
}

/// A face to rasterize: its index, texel corners and clamped row range `j0..=j1`.
struct RasterFace {
    f: u32,
    t: [[f64; 2]; 3],
    j0: u32,
    j1: u32,
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
fn sheet_faces(prep: &Prep<'_>, flags: &[u8], key: u32, h: u32) -> Vec<RasterFace> {
    let nf = prep.model.faces.len();
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
            // Both are finite here: the UVs are finite and the sheet size is small.
            (j1 >= j0).then(|| RasterFace { f: f as u32, t, j0: j0 as u32, j1: j1 as u32 })
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

/// Overlapping texels and (sorted, distinct) face pairs of one sheet.
fn sheet_overlaps(prep: &Prep<'_>, flags: &[u8], key: u32, w: u32, h: u32) -> (u64, Vec<u64>) {
    let faces = sheet_faces(prep, flags, key, h);
    let band_rows = (BAND_TEXELS / w as usize).max(1);
    let n_bands = (h as usize).div_ceil(band_rows);
    // Faces per band (CSR), in increasing face order.
    let mut start = vec![0u32; n_bands + 1];
    for rf in &faces {
        for b in rf.j0 as usize / band_rows..=rf.j1 as usize / band_rows {
            start[b + 1] += 1;
        }
    }
    for b in 0..n_bands {
        start[b + 1] += start[b];
    }
    let mut fill: Vec<u32> = start[..n_bands].to_vec();
    let mut members = vec![0u32; start[n_bands] as usize];
    for (k, rf) in faces.iter().enumerate() {
        for b in rf.j0 as usize / band_rows..=rf.j1 as usize / band_rows {
            members[fill[b] as usize] = k as u32;
            fill[b] += 1;
        }
    }
    drop(fill);

    let results: Vec<(u64, Vec<u64>)> = (0..n_bands)
        .into_par_iter()
        .map(|b| {
            let r0 = b * band_rows;
            let r1 = ((b + 1) * band_rows).min(h as usize);
            let list = &members[start[b] as usize..start[b + 1] as usize];
            band_overlaps(&faces, list, r0, r1, w)
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

/// Rasterizes the faces `list` (indices into `faces`, increasing) over rows `r0..r1`.
fn band_overlaps(
    faces: &[RasterFace],
    list: &[u32],
    r0: usize,
    r1: usize,
    w: u32,
) -> (u64, Vec<u64>) {
    let wu = w as usize;
    let n = (r1 - r0) * wu;
    // The first face covering each texel, and how many faces cover it (saturating).
    let mut owner = vec![u32::MAX; n];
    let mut cov = vec![0u8; n];
    // (texel << 32 | face) for the 2nd..16th faces of each texel.
    let mut extra: Vec<u64> = Vec::new();
    let mut texels = 0u64;
    for &k in list {
        let rf = &faces[k as usize];
        let rows = (rf.j0 as usize).max(r0)..=(rf.j1 as usize).min(r1 - 1);
        for j in rows {
            let Some((i0, i1)) = span(&rf.t, j as f64 + 0.5, w) else { continue };
            let row = (j - r0) * wu;
            for t in row + i0..=row + i1 {
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
