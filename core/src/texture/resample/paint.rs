//! One output tile of a resampled sheet: rasterize the tile's faces over texel centres, copy
//! grid-preserved texels verbatim and sample the others bilinearly, marking coverage bits.
//!
//! Everything a worker needs per texel is on the stack; the loops allocate nothing.

use super::pixel::{Conv, bilinear, copy_pixel, store_pixel};
use super::{FaceMapping, Plan};
use crate::geometry::GridTransform;
use crate::texture::gutter::tile_bit;
use crate::texture::raster::{PixelRect, TriangleRaster};
use crate::texture::store::TILE;
use crate::texture::{PixelFormat, TileStore};

/// Texel writes of one tile (or of many, summed).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Counts {
    pub copied: u64,
    pub sampled: u64,
    /// Ring texels of grid-preserved faces copied from the input (see [`Context::paint_rings`]).
    pub ring: u64,
}

impl Counts {
    pub(super) fn add(a: Self, b: Self) -> Self {
        Self { copied: a.copied + b.copied, sampled: a.sampled + b.sampled, ring: a.ring + b.ring }
    }
}

/// Whether the open square of half side 1 around texel centre `c` meets triangle `t`: whether
/// bilinear sampling at some point of `t` reads the texel (separating axes: the square's two and
/// the triangle's three edge normals).
fn bilinear_reach(c: [f64; 2], t: &[[f64; 2]; 3]) -> bool {
    for axis in 0..2 {
        let lo = t.iter().map(|p| p[axis]).fold(f64::INFINITY, f64::min);
        let hi = t.iter().map(|p| p[axis]).fold(f64::NEG_INFINITY, f64::max);
        if lo >= c[axis] + 1.0 || hi <= c[axis] - 1.0 {
            return false;
        }
    }
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let n = [b[1] - a[1], a[0] - b[0]];
        let dot = |p: [f64; 2]| n[0] * p[0] + n[1] * p[1];
        let (tri_lo, tri_hi) = (dot(a).min(dot(t[(k + 2) % 3])), dot(a).max(dot(t[(k + 2) % 3])));
        let (centre, reach) = (dot(c), n[0].abs() + n[1].abs());
        if tri_lo >= centre + reach || tri_hi <= centre - reach {
            return false;
        }
    }
    true
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

/// The change of the input pixel `(column, row)` when the output column grows by one, under a
/// grid transform: a unit step along one axis.
fn source_step(g: GridTransform) -> (i64, i64) {
    let (a, o) = (g.invert([1.0, 0.0]), g.invert([0.0, 0.0]));
    // Texel space has y up and rows count down.
    ((a[0] - o[0]) as i64, (o[1] - a[1]) as i64)
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
        for &k in bucket {
            let (f, plan) = (&self.faces[k as usize], self.plans[k as usize]);
            let Some(raster) = TriangleRaster::new(f.dst, dst_h, rect) else { continue };
            let src = self.inputs[f.src_sheet as usize];
            let conv = &self.convs[f.src_sheet as usize];
            let (sw, sh) = (src.width(), src.height());
            let step = plan.exact.map(source_step);
            raster.for_each_span(|j, first, last| {
                let ly = j - rect.y0;
                for i in first..=last {
                    let (w, m) = tile_bit(i - rect.x0, ly);
                    bits[w] |= m;
                }
                // A grid-preserved span whose two ends have input pixels has them all (the map
                // is affine): copied as runs of bytes, without a texel-centre computation each.
                if let (Some(g), Some(step)) = (plan.exact, step)
                    && conv.is_identity()
                    && let Some(start) = g.source_pixel(first, j, dst_h, sw, sh)
                    && g.source_pixel(last, j, dst_h, sw, sh).is_some()
                {
                    let o = (ly * TILE + first - rect.x0) as usize * bpp;
                    let n = last - first + 1;
                    let run = &mut px[o..o + n as usize * bpp];
                    copy_run(run, src, start, step, n, bpp);
                    if let Some(turn) = plan.turn {
                        run.chunks_exact_mut(bpp).for_each(|p| turn.apply(p, self.format));
                    }
                    counts.copied += u64::from(n);
                    return;
                }
                for i in first..=last {
                    let o = (ly * TILE + i - rect.x0) as usize * bpp;
                    let out = &mut px[o..o + bpp];
                    self.paint_texel(
                        out,
                        f,
                        plan,
                        src,
                        conv,
                        raster.bary(i, j),
                        (i, j),
                        dst_h,
                        &mut counts,
                    );
                    if let Some(turn) = plan.turn {
                        turn.apply(out, self.format);
                    }
                }
            });
        }
        self.paint_rings(px, bits, rect, dst_h, bucket, &mut counts);
        counts
    }

    /// Copies the ring of every grid-preserved face from the input: the texels no face covers
    /// whose centres lie within one texel of the face, which bilinear sampling (and so every
    /// renderer) reads at the face's edge. Dilation would fill them with the nearest written
    /// colour; copied, the preserved face renders exactly as in the input. A ring texel that
    /// another face covers keeps that face's colour, so a ring is copied only where the chart
    /// ends (into its padding), never inside a chart. Faces in increasing order, the first
    /// ring to claim a texel wins, so the result is the same whatever the thread count.
    fn paint_rings(
        &self,
        px: &mut [u8],
        bits: &mut [u64],
        rect: PixelRect,
        dst_h: u32,
        bucket: &[u32],
        counts: &mut Counts,
    ) {
        let bpp = self.format.bytes_per_pixel();
        let mut value = [0.0f64; 4];
        for &k in bucket {
            let (f, plan) = (&self.faces[k as usize], self.plans[k as usize]);
            let Some(g) = plan.exact else { continue };
            let src = self.inputs[f.src_sheet as usize];
            let conv = &self.convs[f.src_sheet as usize];
            let Some([i0, i1, j0, j1]) = ring_span(&f.dst, dst_h, rect) else { continue };
            for j in j0..j1 {
                for i in i0..i1 {
                    let (w, m) = tile_bit(i - rect.x0, j - rect.y0);
                    let c = [f64::from(i) + 0.5, f64::from(dst_h) - f64::from(j) - 0.5];
                    if bits[w] & m != 0 || !bilinear_reach(c, &f.dst) {
                        continue;
                    }
                    let Some((x, y)) = g.source_pixel(i, j, dst_h, src.width(), src.height())
                    else {
                        continue;
                    };
                    let o = ((j - rect.y0) * TILE + i - rect.x0) as usize * bpp;
                    if conv.is_identity() {
                        copy_pixel(&mut px[o..o + bpp], src.pixel(x, y), bpp);
                    } else {
                        conv.read(src.pixel(x, y), &mut value);
                        store_pixel(&mut px[o..o + bpp], self.format, &value);
                    }
                    if let Some(turn) = plan.turn {
                        turn.apply(&mut px[o..o + bpp], self.format);
                    }
                    bits[w] |= m;
                    counts.ring += 1;
                }
            }
        }
    }

    /// One texel of face `f` at output pixel `(i, j)` with barycentrics `b`: verbatim (converted
    /// when the formats differ) where the face is grid-preserved and the input pixel exists,
    /// else sampled bilinearly.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn paint_texel(
        &self,
        out: &mut [u8],
        f: &FaceMapping,
        plan: Plan,
        src: &TileStore,
        conv: &Conv,
        b: [f64; 3],
        (i, j): (u32, u32),
        dst_h: u32,
        counts: &mut Counts,
    ) {
        let bpp = self.format.bytes_per_pixel();
        let mut value = [0.0f64; 4];
        let verbatim =
            plan.exact.and_then(|g| g.source_pixel(i, j, dst_h, src.width(), src.height()));
        match verbatim {
            Some((x, y)) if conv.is_identity() => {
                copy_pixel(out, src.pixel(x, y), bpp);
                counts.copied += 1;
            }
            Some((x, y)) => {
                // A grid-preserved texel of an input in another format: converted, so exact up
                // to the format change only.
                conv.read(src.pixel(x, y), &mut value);
                store_pixel(out, self.format, &value);
                counts.copied += 1;
            }
            None => {
                let s = f.src;
                let p = [
                    b[0] * s[0][0] + b[1] * s[1][0] + b[2] * s[2][0],
                    b[0] * s[0][1] + b[1] * s[1][1] + b[2] * s[2][1],
                ];
                bilinear(src, conv, p, &mut value);
                store_pixel(out, self.format, &value);
                counts.sampled += 1;
            }
        }
    }
}

/// The pixels `[i0, i1) × [j0, j1)` of `rect` that the bounding box of output triangle `t`, grown
/// by one texel, touches; `None` when it misses `rect`.
fn ring_span(t: &[[f64; 2]; 3], dst_h: u32, rect: PixelRect) -> Option<[u32; 4]> {
    let lo = |a: usize| t.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min);
    let hi = |a: usize| t.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max);
    let h = f64::from(dst_h);
    let clamp = |v: f64, a: u32, b: u32| v.clamp(f64::from(a), f64::from(b)) as u32;
    let i0 = clamp((lo(0) - 1.5).floor(), rect.x0, rect.x1);
    let i1 = clamp((hi(0) + 1.5).ceil(), rect.x0, rect.x1);
    let j0 = clamp((h - hi(1) - 1.5).floor(), rect.y0, rect.y1);
    let j1 = clamp((h - lo(1) + 1.5).ceil(), rect.y0, rect.y1);
    (i0 < i1 && j0 < j1).then_some([i0, i1, j0, j1])
}

/// Copies `n` input pixels into `out`, starting at input pixel `start` and moving by `step` per
/// output pixel: along an input row forwards in runs of whole tile rows, else pixel by pixel.
fn copy_run(
    out: &mut [u8],
    src: &TileStore,
    start: (u32, u32),
    step: (i64, i64),
    n: u32,
    bpp: usize,
) {
    let (mut x, y) = start;
    if step == (1, 0) {
        let mut done = 0u32;
        while done < n {
            let run = (n - done).min(TILE - x % TILE);
            let o = done as usize * bpp;
            out[o..o + run as usize * bpp].copy_from_slice(src.pixel_run(x, y, run));
            done += run;
            x += run;
        }
        return;
    }
    let (mut cx, mut cy) = (i64::from(start.0), i64::from(start.1));
    for k in 0..n as usize {
        copy_pixel(&mut out[k * bpp..(k + 1) * bpp], src.pixel(cx as u32, cy as u32), bpp);
        cx += step.0;
        cy += step.1;
    }
}
