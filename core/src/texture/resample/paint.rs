//! One output tile of a resampled sheet: rasterize the tile's faces over texel centres, copy
//! grid-preserved texels verbatim and sample the others bilinearly, marking coverage bits.
//!
//! Everything a worker needs per texel is on the stack; the loops allocate nothing.

use super::pixel::{Conv, bilinear, copy_pixel, store_pixel};
use super::{FaceMapping, Plan};
use crate::geometry::{GridTransform, barycentric, dist, jacobian, singular_values};
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
    /// Ring texels of resampled faces sampled from the input.
    pub ring_sampled: u64,
}

impl Counts {
    pub(super) fn add(a: Self, b: Self) -> Self {
        Self {
            copied: a.copied + b.copied,
            sampled: a.sampled + b.sampled,
            ring: a.ring + b.ring,
            ring_sampled: a.ring_sampled + b.ring_sampled,
        }
    }
}

/// The largest stretch (input texels per output texel) of a resampled face that paints a ring:
/// a thinner face's map, extended a texel past its edges, would reach far into the input, so its
/// neighbours paint the ring instead.
const MAX_RING_STRETCH: f64 = 4.0;

/// Whether the open square of half side 1 around texel centre `c` meets triangle `t`: whether
/// bilinear sampling at some point of `t` reads the texel (separating axes: the square's two and
/// the triangle's three edge normals).
pub(super) fn bilinear_reach(c: [f64; 2], t: &[[f64; 2]; 3]) -> bool {
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
        nearest: &mut RingScratch,
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
        self.paint_rings(px, bits, rect, dst_h, bucket, &mut counts, nearest);
        counts
    }

    /// Paints the ring of every face: the texels no face covers whose centres lie within one
    /// texel of the face, which bilinear sampling (and so every renderer) reads at the face's
    /// edge. Dilation would fill them with the nearest written colour, so the face would render
    /// differently from the input along the chart's border. A grid-preserved face's ring is
    /// copied from the input under its grid map, so the face renders exactly as in the input; a
    /// resampled face's ring is sampled from the input under its own affine map, extended past
    /// its edges, so the border renders as the input's did (the input's gutter included).
    ///
    /// A ring texel that another face covers keeps that face's colour, so rings are painted only
    /// where a chart ends (into its padding), never inside a chart. Where rings meet, copied
    /// rings go first (in increasing face order, the first to claim a texel wins); a texel left
    /// goes to the resampled face nearest to its centre, whose samples read it most (the lower
    /// face index on a tie). So the result is the same whatever the thread count.
    #[allow(clippy::too_many_arguments)]
    fn paint_rings(
        &self,
        px: &mut [u8],
        bits: &mut [u64],
        rect: PixelRect,
        dst_h: u32,
        bucket: &[u32],
        counts: &mut Counts,
        nearest: &mut RingScratch,
    ) {
        for &k in bucket {
            let (f, plan) = (&self.faces[k as usize], self.plans[k as usize]);
            if let Some(g) = plan.exact
                && let Some(span) = ring_span(&f.dst, dst_h, rect)
            {
                let src = self.inputs[f.src_sheet as usize];
                for_each_ring_texel(bits, rect, dst_h, span, &f.dst, |i, j, _| {
                    let (x, y) = g.source_pixel(i, j, dst_h, src.width(), src.height())?;
                    self.copy_ring_texel(px, rect, (i, j), f, plan, (x, y));
                    counts.ring += 1;
                    Some(())
                });
            }
        }
        // Claims first, then paints: a texel's colour must not depend on which face saw it
        // first. Only faces on a chart's border claim: a face whose every edge is shared has
        // neighbours all round, which cover its ring but for rare texels near its corners
        // (those are left to dilation), and skipping it saves scanning around every face.
        for &k in bucket {
            let (f, plan) = (&self.faces[k as usize], self.plans[k as usize]);
            if !plan.border || plan.exact.is_some() || !extends_well(f) {
                continue;
            }
            let Some(span) = ring_span(&f.dst, dst_h, rect) else { continue };
            let local = |i: u32, j: u32| ((j - rect.y0) * TILE + i - rect.x0) as usize;
            for_each_ring_texel(bits, rect, dst_h, span, &f.dst, |i, j, c| {
                nearest.claim(local(i, j), distance_to_triangle(c, &f.dst), k);
                None
            });
        }
        let bpp = self.format.bytes_per_pixel();
        let mut value = [0.0f64; 4];
        for (t, k) in nearest.drain() {
            let (f, plan) = (&self.faces[k as usize], self.plans[k as usize]);
            let (lx, ly) = (t as u32 % TILE, t as u32 / TILE);
            let (i, j) = (rect.x0 + lx, rect.y0 + ly);
            let c = [f64::from(i) + 0.5, f64::from(dst_h) - f64::from(j) - 0.5];
            let p = source_point(&f.src, barycentric(f.dst, c));
            let src = self.inputs[f.src_sheet as usize];
            bilinear(src, &self.convs[f.src_sheet as usize], p, &mut value);
            let out = &mut px[t * bpp..(t + 1) * bpp];
            store_pixel(out, self.format, &value);
            if let Some(turn) = plan.turn {
                turn.apply(out, self.format);
            }
            let (w, m) = tile_bit(lx, ly);
            bits[w] |= m;
            counts.ring_sampled += 1;
        }
    }

    /// Copies input pixel `(x, y)` into ring texel `(i, j)` of grid-preserved face `f`.
    fn copy_ring_texel(
        &self,
        px: &mut [u8],
        rect: PixelRect,
        (i, j): (u32, u32),
        f: &FaceMapping,
        plan: Plan,
        (x, y): (u32, u32),
    ) {
        let bpp = self.format.bytes_per_pixel();
        let src = self.inputs[f.src_sheet as usize];
        let conv = &self.convs[f.src_sheet as usize];
        let o = ((j - rect.y0) * TILE + i - rect.x0) as usize * bpp;
        let out = &mut px[o..o + bpp];
        if conv.is_identity() {
            copy_pixel(out, src.pixel(x, y), bpp);
        } else {
            let mut value = [0.0f64; 4];
            conv.read(src.pixel(x, y), &mut value);
            store_pixel(out, self.format, &value);
        }
        if let Some(turn) = plan.turn {
            turn.apply(out, self.format);
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
                let p = source_point(&f.src, b);
                bilinear(src, conv, p, &mut value);
                store_pixel(out, self.format, &value);
                counts.sampled += 1;
            }
        }
    }
}

/// Visits the texels of pixel span `[i0, i1) × [j0, j1)` (within `rect`) that no face covers and
/// that bilinear sampling on triangle `t` reads, with their centres; a visit returning `Some`
/// marks its texel covered.
fn for_each_ring_texel(
    bits: &mut [u64],
    rect: PixelRect,
    dst_h: u32,
    [i0, i1, j0, j1]: [u32; 4],
    t: &[[f64; 2]; 3],
    mut visit: impl FnMut(u32, u32, [f64; 2]) -> Option<()>,
) {
    for j in j0..j1 {
        for i in i0..i1 {
            let (w, m) = tile_bit(i - rect.x0, j - rect.y0);
            let c = [f64::from(i) + 0.5, f64::from(dst_h) - f64::from(j) - 0.5];
            if bits[w] & m == 0 && bilinear_reach(c, t) && visit(i, j, c).is_some() {
                bits[w] |= m;
            }
        }
    }
}

/// The distance from point `p` to triangle `t` (zero inside), in texels.
fn distance_to_triangle(p: [f64; 2], t: &[[f64; 2]; 3]) -> f64 {
    let b = barycentric(*t, p);
    if b.iter().all(|&x| x >= 0.0) {
        return 0.0;
    }
    (0..3)
        .map(|k| {
            let (a, e) = (t[k], [t[(k + 1) % 3][0] - t[k][0], t[(k + 1) % 3][1] - t[k][1]]);
            let len2 = e[0] * e[0] + e[1] * e[1];
            let s = if len2 > 0.0 {
                (((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            dist(p, [a[0] + s * e[0], a[1] + s * e[1]])
        })
        .fold(f64::INFINITY, f64::min)
}

/// Per-worker scratch of the sampled rings: for each texel of a tile, the nearest resampled face
/// that claims it, and the texels claimed so far (so a tile resets only those).
pub(super) struct RingScratch {
    best: Vec<(f64, u32)>,
    claimed: Vec<u32>,
}

impl RingScratch {
    pub(super) fn new() -> Self {
        Self { best: vec![(f64::INFINITY, u32::MAX); (TILE * TILE) as usize], claimed: Vec::new() }
    }

    /// Face `k` at distance `d` claims texel `t` (tile-local index) if it is nearer than the
    /// claim so far; faces come in increasing order, so a tie keeps the lower index.
    fn claim(&mut self, t: usize, d: f64, k: u32) {
        let slot = &mut self.best[t];
        if slot.1 == u32::MAX {
            self.claimed.push(t as u32);
        }
        if d < slot.0 {
            *slot = (d, k);
        }
    }

    /// The claimed texels with their faces, in claim order, leaving the scratch empty.
    fn drain(&mut self) -> impl Iterator<Item = (usize, u32)> + '_ {
        let best = &mut self.best;
        self.claimed.drain(..).map(move |t| {
            let t = t as usize;
            let k = best[t].1;
            best[t] = (f64::INFINITY, u32::MAX);
            (t, k)
        })
    }
}

/// The input texel-space point with barycentrics `b` in source triangle `s`.
#[inline]
fn source_point(s: &[[f64; 2]; 3], b: [f64; 3]) -> [f64; 2] {
    [
        b[0] * s[0][0] + b[1] * s[1][0] + b[2] * s[2][0],
        b[0] * s[0][1] + b[1] * s[1][1] + b[2] * s[2][1],
    ]
}

/// Whether face `f`'s map from output to input, extended past its edges, stays within
/// [`MAX_RING_STRETCH`] (a face without output area has no map at all).
fn extends_well(f: &FaceMapping) -> bool {
    jacobian(f.dst, f.src).is_some_and(|j| singular_values(j)[0] <= MAX_RING_STRETCH)
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
