//! One output tile of a resampled sheet: rasterize the tile's faces over texel centres, copy
//! grid-preserved texels verbatim and sample the others bilinearly, marking coverage bits.
//!
//! Everything a worker needs per texel is on the stack; the loops allocate nothing.

use super::pixel::{Conv, bilinear, copy_pixel, store_pixel};
use super::{FaceMapping, Plan};
use crate::texture::gutter::tile_bit;
use crate::texture::raster::{PixelRect, rasterize_triangle};
use crate::texture::store::TILE;
use crate::texture::{PixelFormat, TileStore};

/// Texel writes of one tile (or of many, summed).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Counts {
    pub copied: u64,
    pub sampled: u64,
}

impl Counts {
    pub(super) fn add(a: Self, b: Self) -> Self {
        Self { copied: a.copied + b.copied, sampled: a.sampled + b.sampled }
    }
}

/// What every tile worker reads: the inputs, the faces and their validated plans.
pub(super) struct Context<'a> {
    pub inputs: &'a [&'a TileStore],
    pub faces: &'a [FaceMapping],
    pub plans: &'a [Plan],
    /// Reader of each input sheet's pixels in the output format.
    pub convs: &'a [Conv],
    /// Format of the output sheets.
    pub format: PixelFormat,
}

impl Context<'_> {
    /// Paints the faces `bucket` (in increasing face order) into tile `px` / `bits`, which covers
    /// pixel rectangle `rect` of an output sheet `dst_h` pixels high.
    pub(super) fn paint_tile(
        &self,
        px: &mut [u8],
        bits: &mut [u64],
        rect: PixelRect,
        dst_h: u32,
        bucket: &[u32],
    ) -> Counts {
        let bpp = self.format.bytes_per_pixel();
        let mut counts = Counts::default();
        let mut value = [0.0f64; 4];
        for &k in bucket {
            let (f, plan) = (&self.faces[k as usize], self.plans[k as usize]);
            let src = self.inputs[f.src_sheet as usize];
            let conv = &self.convs[f.src_sheet as usize];
            let (sw, sh) = (src.width(), src.height());
            let s = f.src;
            rasterize_triangle(f.dst, dst_h, rect, |i, j, b| {
                let (lx, ly) = (i - rect.x0, j - rect.y0);
                let o = (ly * TILE + lx) as usize * bpp;
                let out = &mut px[o..o + bpp];
                let verbatim = plan.exact.and_then(|g| g.source_pixel(i, j, dst_h, sw, sh));
                match verbatim {
                    Some((x, y)) if conv.is_identity() => {
                        copy_pixel(out, src.pixel(x, y), bpp);
                        counts.copied += 1;
                    }
                    Some((x, y)) => {
                        // A grid-preserved texel of an input in another format: converted, so
                        // exact up to the format change only.
                        conv.read(src.pixel(x, y), &mut value);
                        store_pixel(out, self.format, &value);
                        counts.copied += 1;
                    }
                    None => {
                        let p = [
                            b[0] * s[0][0] + b[1] * s[1][0] + b[2] * s[2][0],
                            b[0] * s[0][1] + b[1] * s[1][1] + b[2] * s[2][1],
                        ];
                        bilinear(src, conv, p, &mut value);
                        store_pixel(out, self.format, &value);
                        counts.sampled += 1;
                    }
                }
                let (w, m) = tile_bit(lx, ly);
                bits[w] |= m;
            });
        }
        counts
    }
}
