//! Gaussian and Laplacian pyramids (Burt & Adelson) of the photos, for the frequency analysis
//! of the build (paper §4.1) and for texturing sub-charts from a coarser level (§4.2).
//!
//! `G_{k+1} = REDUCE(G_k)`: the 5-tap binomial filter `[1 4 6 4 1]/16` in both directions, then
//! every second pixel (pixel `i` of level `k+1` is centred on pixel `2i` of level `k`, so a level
//! is `ceil(W/2) × ceil(H/2)`). `L_k = G_k − EXPAND(G_{k+1})`, where EXPAND interpolates with the
//! same filter (weights `1/8, 3/4, 1/8` on even pixels, `1/2, 1/2` on odd ones). Borders mirror
//! without repeating the edge pixel. The analysis works on one `f32` plane of one colour channel
//! of one photo at a time, level by level, turning each `G_k` into `L_k` in place once `G_{k+1}`
//! exists, so at most `1.25` planes of the photo are in memory at a time. The colour levels a sub-chart needs are
//! built by [`reduce_store`] from memory-mapped [`TileStore`]s, a band of rows at a time.

use std::path::Path;

use rayon::prelude::*;

use crate::texture::{PixelFormat, SampleType, TextureError, TileStore};

/// Most Gaussian levels analysed and used (levels `0..MAX_LEVELS`; 5 = 1/32 of the resolution).
pub const MAX_LEVELS: usize = 6;
/// A level is only built while its smaller side keeps at least this many pixels.
pub const MIN_SIDE: u32 = 16;

const W5: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

/// Size of level `l` of a `w × h` image.
pub fn level_size(w: u32, h: u32, l: usize) -> (u32, u32) {
    let d = 1u64 << l;
    (u64::from(w).div_ceil(d) as u32, u64::from(h).div_ceil(d) as u32)
}

/// Gaussian levels of a `w × h` image: level 0 plus every level whose smaller side is still at
/// least [`MIN_SIDE`], at most [`MAX_LEVELS`].
pub fn level_count(w: u32, h: u32) -> usize {
    let mut n = 1;
    while n < MAX_LEVELS {
        let (a, b) = level_size(w, h, n);
        if a.min(b) < MIN_SIDE {
            break;
        }
        n += 1;
    }
    n
}

/// A level-0 texel-space point (v up) of an image `h0` pixels high, in the texel space of level
/// `l`. Pixel `i` of level `l` is centred on pixel `2^l·i` of level 0, so in pixel coordinates
/// (from the top-left corner) `x_l = x_0·2^-l + (1 − 2^-l)/2`; texel space flips y. Level 0 is
/// returned unchanged (bit for bit), which keeps a build without splitting identical.
#[inline]
pub fn to_level(p: [f64; 2], l: usize, h0: u32) -> [f64; 2] {
    if l == 0 {
        return p;
    }
    let s = 1.0 / (1u64 << l) as f64;
    let c = 0.5 * (1.0 - s);
    let hl = f64::from(level_size(1, h0, l).1);
    [p[0] * s + c, hl - (f64::from(h0) - p[1]) * s - c]
}

/// Mirror index `i` into `0..n` without repeating the edge sample.
#[inline]
fn mirror(i: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let n = n as isize;
    let i = if i < 0 { -i } else { i };
    let i = if i >= n { 2 * (n - 1) - i } else { i };
    i.clamp(0, n - 1) as usize
}

/// One channel of an image in `f32`, row-major, row 0 at the top.
#[derive(Clone, Debug, Default)]
pub struct Plane {
    pub w: usize,
    pub h: usize,
    pub data: Vec<f32>,
}

impl Plane {
    /// A zero plane.
    pub fn new(w: usize, h: usize) -> Self {
        Self { w, h, data: vec![0.0; w * h] }
    }

    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.w + x]
    }

    /// Resizes to `w × h` keeping the allocation when it is large enough (contents undefined).
    fn reshape(&mut self, w: usize, h: usize) {
        self.w = w;
        self.h = h;
        self.data.resize(w * h, 0.0);
    }
}

/// Colour channels a photo's analysis looks at: red, green and blue, or the one gray channel
/// (alpha is never detail).
pub fn colour_channels(f: PixelFormat) -> usize {
    if f.channels >= 3 { 3 } else { 1 }
}

/// Copies one channel of one row of pixel bytes into `out` with full scale 1; `load(px)` reads
/// the sample in its own units. Inlined per sample type so the loop is plain arithmetic.
#[inline(always)]
fn channel_row(row: &[u8], bpp: usize, scale: f32, load: impl Fn(&[u8]) -> f32, out: &mut [f32]) {
    for (v, px) in out.iter_mut().zip(row.chunks_exact(bpp)) {
        *v = scale * load(px);
    }
}

/// Channel `c` of a photo as a plane with full scale 1 (the stored, gamma-encoded values, which
/// is what the eye compares).
pub fn channel_plane(store: &TileStore, c: usize, out: &mut Plane) {
    let (w, h) = (store.width() as usize, store.height() as usize);
    let f = store.format();
    let bpp = f.bytes_per_pixel();
    out.reshape(w, h);
    out.data.par_chunks_mut(w).enumerate().for_each_init(
        || vec![0u8; w * bpp],
        |row, (y, dst)| {
            store.read_row(y as u32, 0, row);
            match f.sample {
                SampleType::U8 => channel_row(row, bpp, 1.0 / 255.0, |px| f32::from(px[c]), dst),
                SampleType::U16 => {
                    channel_row(row, bpp, 1.0 / 65535.0, |px| load(px, c, f.sample), dst)
                }
                SampleType::F32 => channel_row(row, bpp, 1.0, |px| load(px, c, f.sample), dst),
            }
        },
    );
}

/// The binomial filter at even columns of one row: `out[i] = Σ_m w_m·row[2i + m − 2]`.
#[inline]
fn filter_row_even(row: &[f32], out: &mut [f32]) {
    let n = row.len();
    for (i, o) in out.iter_mut().enumerate() {
        let x = 2 * i;
        *o = if x >= 2 && x + 2 < n {
            let r = &row[x - 2..x + 3];
            W5[0] * r[0] + W5[1] * r[1] + W5[2] * r[2] + W5[3] * r[3] + W5[4] * r[4]
        } else {
            let mut acc = 0.0;
            for (m, &wm) in W5.iter().enumerate() {
                acc += wm * row[mirror(x as isize + m as isize - 2, n)];
            }
            acc
        };
    }
}

/// `G_{k+1} = REDUCE(G_k)` into `dst` (reshaped to `ceil(w/2) × ceil(h/2)`).
pub fn reduce(src: &Plane, dst: &mut Plane) {
    let (dw, dh) = (src.w.div_ceil(2), src.h.div_ceil(2));
    dst.reshape(dw, dh);
    dst.data.par_chunks_mut(dw).enumerate().for_each_init(
        || vec![0.0f32; dw],
        |tmp, (j, out)| {
            out.iter_mut().for_each(|v| *v = 0.0);
            for (n, &wn) in W5.iter().enumerate() {
                let y = mirror(2 * j as isize + n as isize - 2, src.h);
                filter_row_even(&src.data[y * src.w..(y + 1) * src.w], tmp);
                for (o, &t) in out.iter_mut().zip(tmp.iter()) {
                    *o += wn * t;
                }
            }
        },
    );
}

/// The EXPAND taps of output position `x` over a level of `n` samples: indices and weights.
#[inline]
fn expand_taps(x: usize, n: usize) -> ([usize; 3], [f32; 3]) {
    let i = (x / 2) as isize;
    if x.is_multiple_of(2) {
        ([mirror(i - 1, n), mirror(i, n), mirror(i + 1, n)], [0.125, 0.75, 0.125])
    } else {
        ([mirror(i, n), mirror(i + 1, n), 0], [0.5, 0.5, 0.0])
    }
}

/// Turns `g = G_k` into `L_k = G_k − EXPAND(next)` in place, `next = G_{k+1}`.
pub fn laplacian_in_place(g: &mut Plane, next: &Plane) {
    let (w, nw, nh) = (g.w, next.w, next.h);
    g.data.par_chunks_mut(w).enumerate().for_each_init(
        || vec![0.0f32; nw],
        |col, (y, row)| {
            // Vertical interpolation first (one row of `next`'s width), then horizontal.
            let (ty, wy) = expand_taps(y, nh);
            for (i, c) in col.iter_mut().enumerate() {
                *c = wy[0] * next.data[ty[0] * nw + i]
                    + wy[1] * next.data[ty[1] * nw + i]
                    + wy[2] * next.data[ty[2] * nw + i];
            }
            // Interior columns need no mirroring: even x blends three samples, odd x two.
            let lo = 2.min(w);
            let hi = (2 * nw).saturating_sub(3).clamp(lo, w);
            for x in (0..lo).chain(hi..w) {
                let (tx, wx) = expand_taps(x, nw);
                row[x] -= wx[0] * col[tx[0]] + wx[1] * col[tx[1]] + wx[2] * col[tx[2]];
            }
            for (x, v) in row.iter_mut().enumerate().take(hi).skip(lo) {
                let i = x / 2;
                *v -= if x.is_multiple_of(2) {
                    0.125 * col[i - 1] + 0.75 * col[i] + 0.125 * col[i + 1]
                } else {
                    0.5 * (col[i] + col[i + 1])
                };
            }
        },
    );
}

/// Reads sample `c` of a pixel in its own units.
#[inline(always)]
fn load(px: &[u8], c: usize, t: SampleType) -> f32 {
    match t {
        SampleType::U8 => f32::from(px[c]),
        SampleType::U16 => f32::from(u16::from_ne_bytes([px[2 * c], px[2 * c + 1]])),
        SampleType::F32 => {
            f32::from_ne_bytes([px[4 * c], px[4 * c + 1], px[4 * c + 2], px[4 * c + 3]])
        }
    }
}

/// Writes sample `c` of a pixel, rounded and clamped for integer types.
#[inline]
fn store(px: &mut [u8], c: usize, t: SampleType, v: f32) {
    match t {
        SampleType::U8 => px[c] = (v.clamp(0.0, 255.0) + 0.5) as u8,
        SampleType::U16 => px[2 * c..2 * c + 2]
            .copy_from_slice(&((v.clamp(0.0, 65535.0) + 0.5) as u16).to_ne_bytes()),
        SampleType::F32 => px[4 * c..4 * c + 4].copy_from_slice(&v.to_ne_bytes()),
    }
}

/// Output rows computed per band of [`reduce_store`] before they are written.
const BAND: usize = 64;

/// `REDUCE` of a whole image in a tile store, every channel (alpha too), into a new store of
/// the same pixel format under `work_dir`. Rows are computed in parallel a band at a time and
/// written in order, so the result does not depend on the thread count.
pub fn reduce_store(src: &TileStore, work_dir: &Path) -> Result<TileStore, TextureError> {
    let f: PixelFormat = src.format();
    let (sw, sh) = (src.width() as usize, src.height() as usize);
    let (dw, dh) = (sw.div_ceil(2), sh.div_ceil(2));
    let mut dst = TileStore::create(work_dir, dw as u32, dh as u32, f)?;
    let ch = f.channels as usize;
    let bpp = f.bytes_per_pixel();
    let mut band = vec![0u8; BAND * dw * bpp];
    let mut j0 = 0;
    while j0 < dh {
        let rows = BAND.min(dh - j0);
        band[..rows * dw * bpp].par_chunks_mut(dw * bpp).enumerate().for_each_init(
            || (vec![0u8; sw * bpp], vec![0.0f32; sw], vec![0.0f32; dw], vec![0.0f32; dw * ch]),
            |(bytes, line, tmp, acc), (r, out)| {
                let j = j0 + r;
                acc.iter_mut().for_each(|v| *v = 0.0);
                for (n, &wn) in W5.iter().enumerate() {
                    let y = mirror(2 * j as isize + n as isize - 2, sh);
                    src.read_row(y as u32, 0, bytes);
                    for c in 0..ch {
                        for (x, v) in line.iter_mut().enumerate() {
                            *v = load(&bytes[x * bpp..(x + 1) * bpp], c, f.sample);
                        }
                        filter_row_even(line, tmp);
                        for (i, &t) in tmp.iter().enumerate() {
                            acc[i * ch + c] += wn * t;
                        }
                    }
                }
                for i in 0..dw {
                    for c in 0..ch {
                        store(&mut out[i * bpp..(i + 1) * bpp], c, f.sample, acc[i * ch + c]);
                    }
                }
            },
        );
        for r in 0..rows {
            dst.write_row((j0 + r) as u32, 0, &band[r * dw * bpp..(r + 1) * dw * bpp]);
        }
        j0 += rows;
    }
    // Both images have been swept whole; neither needs to stay resident.
    src.release_all();
    dst.release_all();
    Ok(dst)
}

/// The Gaussian levels `l` of a photo with `wanted[l]` (l ≥ 1), finest first, by repeated
/// [`reduce_store`]; a level on the way that is not wanted is dropped once the next one exists.
pub fn gaussian_levels(
    photo: &TileStore,
    wanted: &[bool; MAX_LEVELS],
    work_dir: &Path,
) -> Result<Vec<TileStore>, TextureError> {
    let top = wanted.iter().rposition(|&w| w).unwrap_or(0);
    let mut out: Vec<TileStore> = Vec::new();
    // The last level built when it is not wanted; otherwise it is `out`'s last.
    let mut scratch: Option<TileStore> = None;
    for &want in wanted.iter().take(top + 1).skip(1) {
        let next = match (&scratch, out.last()) {
            (Some(s), _) => reduce_store(s, work_dir)?,
            (None, Some(o)) => reduce_store(o, work_dir)?,
            (None, None) => reduce_store(photo, work_dir)?,
        };
        if want {
            out.push(next);
            scratch = None;
        } else {
            scratch = Some(next);
        }
    }
    Ok(out)
}
