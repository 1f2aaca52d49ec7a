//! Colour fidelity of the output against the input, as the evaluator measures it: points drawn at
//! random on the surface (faces by 3-D area, uniform inside a face), each looked up bilinearly in
//! the input's and the output's texture, PSNR of the differences. Reads the decoded tile stores,
//! so memory stays bounded; the draw is seeded, so the figure is the same on every run.

use rayon::prelude::*;

use super::compare::{FaceClass, Side, area_3d};
use crate::rng::SplitMix64;
use crate::texture::TileStore;

/// Points per parallel task, a constant so the sums do not depend on the thread count.
const CHUNK: usize = 1 << 14;

/// PSNR over a set of samples.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct ColourStats {
    pub samples: u64,
    /// `None` without samples; infinite when every sample is identical.
    pub psnr_db: Option<f64>,
}

/// Colour fidelity of every sample, and of the preserved and resampled faces apart, and of the
/// faces whose input UV triangle has no area (a point or a line of the input texture: the
/// evaluator's `zero_uv_area`, which the resampled figure includes).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct ColourFidelity {
    pub all: ColourStats,
    pub preserved: ColourStats,
    pub resampled: ColourStats,
    pub zero_uv_area: ColourStats,
}

/// Sums of squared differences and sample counts of the four groups of [`ColourFidelity`].
#[derive(Clone, Copy, Default)]
struct Sums {
    sq: [f64; 4],
    n: [u64; 4],
}

/// Bilinear 8-bit RGB at texel-space point `p` of `store` (the evaluator's `bilinear`).
fn bilinear(store: &TileStore, p: [f64; 2]) -> [f64; 3] {
    let (w, h) = (store.width(), store.height());
    let x = (p[0] - 0.5).clamp(0.0, f64::from(w - 1));
    let y = (f64::from(h) - p[1] - 0.5).clamp(0.0, f64::from(h - 1));
    let (x0, y0) = (x.floor() as u32, y.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - f64::from(x0), y - f64::from(y0));
    let at = |i, j| super::pictures::pixel_rgb(store.pixel(i, j), store.format()).map(f64::from);
    let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
    [0, 1, 2].map(|k| {
        (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
    })
}

fn stats(sq: f64, n: u64) -> ColourStats {
    let psnr_db = (n > 0).then(|| {
        let mse = sq / (3.0 * n as f64);
        if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64 * 255.0 / mse).log10() }
    });
    ColourStats { samples: n, psnr_db }
}

/// Draws `samples` points on the faces textured on both sides and compares their colours.
/// `before_stores[k]` and `after_stores[k]` are the decoded sheets (`None` where a sheet could not
/// be read; its samples are skipped).
pub fn fidelity(
    before: &Side,
    after: &Side,
    class: &[FaceClass],
    before_stores: &[Option<TileStore>],
    after_stores: &[Option<TileStore>],
    samples: usize,
) -> ColourFidelity {
    // Cumulative 3-D area of the faces textured on both sides.
    let mut cdf = Vec::with_capacity(class.len());
    let mut total = 0.0;
    for (f, c) in class.iter().enumerate() {
        if *c != FaceClass::Untextured {
            total += area_3d(before.model, f);
        }
        cdf.push(total);
    }
    if total.is_nan() || total <= 0.0 || samples == 0 {
        return ColourFidelity::default();
    }
    let chunks = samples.div_ceil(CHUNK);
    let sums: Vec<Sums> = (0..chunks)
        .into_par_iter()
        .map(|chunk| {
            let mut rng = SplitMix64::new(0x5ca7_a71a_5000 + chunk as u64);
            let mut s = Sums::default();
            let n = CHUNK.min(samples - chunk * CHUNK);
            for _ in 0..n {
                let r = rng.unit() * total;
                let f = cdf.partition_point(|&c| c <= r).min(class.len() - 1);
                let (r1, r2) = (rng.unit(), rng.unit());
                let sq = r1.sqrt();
                let bc = [1.0 - sq, sq * (1.0 - r2), sq * r2];
                let (Some((sa, ta)), Some((sb, tb))) = (before.texels(f), after.texels(f)) else {
                    continue;
                };
                let (Some(Some(ia)), Some(Some(ib))) =
                    (before_stores.get(sa as usize), after_stores.get(sb as usize))
                else {
                    continue;
                };
                let at = |t: [[f64; 2]; 3]| {
                    [0, 1].map(|c| bc[0] * t[0][c] + bc[1] * t[1][c] + bc[2] * t[2][c])
                };
                let (ca, cb) = (bilinear(ia, at(ta)), bilinear(ib, at(tb)));
                let d: f64 = (0..3).map(|k| (ca[k] - cb[k]).powi(2)).sum();
                let group = if class[f] == FaceClass::Preserved { 1 } else { 2 };
                for g in [0, group] {
                    s.sq[g] += d;
                    s.n[g] += 1;
                }
                if before.is_point(f) {
                    s.sq[3] += d;
                    s.n[3] += 1;
                }
            }
            s
        })
        .collect();
    let mut t = Sums::default();
    for s in &sums {
        for g in 0..4 {
            t.sq[g] += s.sq[g];
            t.n[g] += s.n[g];
        }
    }
    ColourFidelity {
        all: stats(t.sq[0], t.n[0]),
        preserved: stats(t.sq[1], t.n[1]),
        resampled: stats(t.sq[2], t.n[2]),
        zero_uv_area: stats(t.sq[3], t.n[3]),
    }
}
