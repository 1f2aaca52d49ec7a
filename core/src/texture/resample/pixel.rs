//! Pixel access for resampling: loading and storing samples of every `PixelFormat`, converting an
//! input pixel to the output format, and the bilinear sampler over a memory-mapped `TileStore`.
//!
//! Values are carried in `f64` in the *output* format's units (0..255 for `U8`, 0..65535 for `U16`,
//! raw for `F32`), so a pixel whose format already matches is never rescaled and integer samples
//! survive interpolation with weight one exactly.

use crate::texture::{PixelFormat, SampleType, TileStore};

/// Reads sample `c` of a pixel's bytes in its own units (native byte order, as the store keeps
/// them).
#[inline(always)]
pub(super) fn load(px: &[u8], c: usize, t: SampleType) -> f64 {
    match t {
        SampleType::U8 => f64::from(px[c]),
        SampleType::U16 => f64::from(u16::from_ne_bytes([px[2 * c], px[2 * c + 1]])),
        SampleType::F32 => {
            f64::from(f32::from_ne_bytes([px[4 * c], px[4 * c + 1], px[4 * c + 2], px[4 * c + 3]]))
        }
    }
}

/// Writes sample `c` of a pixel, rounding to the nearest integer and clamping for integer types.
/// A NaN becomes 0 in integer formats (Rust's saturating cast), so bad input cannot panic here.
///
/// Rounding adds one half to the clamped, non-negative value and truncates, which equals
/// `f64::round` there but is an instruction instead of a libm call on baseline x86-64.
#[inline(always)]
pub(super) fn store(px: &mut [u8], c: usize, t: SampleType, v: f64) {
    match t {
        SampleType::U8 => px[c] = (v.clamp(0.0, 255.0) + 0.5) as u8,
        SampleType::U16 => px[2 * c..2 * c + 2]
            .copy_from_slice(&((v.clamp(0.0, 65535.0) + 0.5) as u16).to_ne_bytes()),
        SampleType::F32 => px[4 * c..4 * c + 4].copy_from_slice(&(v as f32).to_ne_bytes()),
    }
}

/// Writes the first `channels` values of `v` into a pixel of format `f`.
#[inline(always)]
pub(super) fn store_pixel(px: &mut [u8], f: PixelFormat, v: &[f64; 4]) {
    for (c, &x) in v.iter().enumerate().take(f.channels as usize) {
        store(px, c, f.sample, x);
    }
}

/// The full-scale value of a sample type: what "1.0" is in its units.
#[inline]
fn full_scale(t: SampleType) -> f64 {
    match t {
        SampleType::U8 => 255.0,
        SampleType::U16 => 65535.0,
        SampleType::F32 => 1.0,
    }
}

/// Reads pixels of one input format as values of the output format.
///
/// When the formats match this is a plain per-channel load. Otherwise the pixel goes through
/// normalized RGBA: gray is replicated, a missing alpha is opaque, and an output with one or two
/// channels takes the Rec. 709 luma of the colour; sample values are rescaled by the ratio of the
/// full-scale values (so `U8` 255 becomes `U16` 65535 and `F32` 1.0).
#[derive(Clone, Copy, Debug)]
pub(super) struct Conv {
    src: PixelFormat,
    dst: PixelFormat,
}

impl Conv {
    pub(super) fn new(src: PixelFormat, dst: PixelFormat) -> Self {
        Self { src, dst }
    }

    /// Whether input pixels can be copied byte for byte.
    #[inline]
    pub(super) fn is_identity(&self) -> bool {
        self.src == self.dst
    }

    /// The pixel `px` (input format) as output-format values in `out[..dst.channels]`.
    #[inline(always)]
    pub(super) fn read(&self, px: &[u8], out: &mut [f64; 4]) {
        if self.is_identity() {
            for (c, o) in out.iter_mut().enumerate().take(self.src.channels as usize) {
                *o = load(px, c, self.src.sample);
            }
            return;
        }
        let s = 1.0 / full_scale(self.src.sample);
        let t = self.src.sample;
        let rgba = match self.src.channels {
            1 => {
                let g = load(px, 0, t) * s;
                [g, g, g, 1.0]
            }
            2 => {
                let g = load(px, 0, t) * s;
                [g, g, g, load(px, 1, t) * s]
            }
            3 => [load(px, 0, t) * s, load(px, 1, t) * s, load(px, 2, t) * s, 1.0],
            _ => [load(px, 0, t) * s, load(px, 1, t) * s, load(px, 2, t) * s, load(px, 3, t) * s],
        };
        let d = full_scale(self.dst.sample);
        let luma = || {
            // Gray stays gray exactly, whatever the rounding of the weights.
            if rgba[0] == rgba[1] && rgba[1] == rgba[2] {
                rgba[0]
            } else {
                0.2126 * rgba[0] + 0.7152 * rgba[1] + 0.0722 * rgba[2]
            }
        };
        match self.dst.channels {
            1 => out[0] = luma() * d,
            2 => {
                out[0] = luma() * d;
                out[1] = rgba[3] * d;
            }
            n => {
                for (o, v) in out.iter_mut().zip(rgba).take(n as usize) {
                    *o = v * d;
                }
            }
        }
    }
}

/// Bilinear sample of `src` at texel-space point `p` (v up), as output-format values in `out`.
///
/// Texel-centre convention: the centre of pixel `(i, j)` is `(i + 0.5, H − j − 0.5)`, so the
/// continuous pixel coordinate of `p` is `(p.x − 0.5, H − p.y − 0.5)`; it is clamped to the
/// centres of the border pixels, which extends the sheet's edge texels outward. Taps of weight
/// zero are skipped, so a point on a texel centre returns that texel exactly (and an infinite
/// `F32` neighbour cannot turn it into NaN).
#[inline(always)]
pub(super) fn bilinear(src: &TileStore, conv: &Conv, p: [f64; 2], out: &mut [f64; 4]) {
    let (w, h) = (src.width(), src.height());
    let cx = (p[0] - 0.5).clamp(0.0, f64::from(w - 1));
    let cy = (f64::from(h) - p[1] - 0.5).clamp(0.0, f64::from(h - 1));
    // Both are clamped to be non-negative (a NaN casts to 0), so truncation is `floor`, without
    // the libm call.
    let (x0, y0) = (cx as u32, cy as u32);
    let (fx, fy) = (cx - f64::from(x0), cy - f64::from(y0));
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let n = conv.dst.channels as usize;
    out[..n].fill(0.0);
    let mut tap = [0.0f64; 4];
    let taps = [
        (x0, y0, (1.0 - fx) * (1.0 - fy)),
        (x1, y0, fx * (1.0 - fy)),
        (x0, y1, (1.0 - fx) * fy),
        (x1, y1, fx * fy),
    ];
    for (x, y, wgt) in taps {
        if wgt == 0.0 {
            continue;
        }
        conv.read(src.pixel(x, y), &mut tap);
        for (o, t) in out[..n].iter_mut().zip(&tap[..n]) {
            *o += wgt * t;
        }
    }
}

/// Copies one pixel of `bpp` bytes; the common sizes get fixed-length copies, which compile to a
/// move or two instead of a `memcpy` call per texel.
#[inline(always)]
pub(super) fn copy_pixel(dst: &mut [u8], src: &[u8], bpp: usize) {
    match bpp {
        3 => dst[..3].copy_from_slice(&src[..3]),
        4 => dst[..4].copy_from_slice(&src[..4]),
        8 => dst[..8].copy_from_slice(&src[..8]),
        16 => dst[..16].copy_from_slice(&src[..16]),
        _ => dst[..bpp].copy_from_slice(&src[..bpp]),
    }
}
