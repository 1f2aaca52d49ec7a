//! Colour continuity (paper §5) and the seam colour-jump measure.
//!
//! Along every frontier edge (two adjacent faces in charts of different photos) the edge is
//! seen in both photos. At texels along the edge in each chart we take the two colours `c_1`
//! (this chart's photo) and `c_2` (the neighbour's photo) and fix the correction `(c_1 + c_2)/2 −
//! c_1` there. The sparse corrections are then diffused over the chart's texels with the paper's
//! relaxation (`V' = d·V + k·ΔP`, `P += V'`, d = 0.97, k = 0.4375) inside a multigrid scheme:
//! restrict to coarser grids until no texel of the chart lacks a value, relax there, prolong as
//! the starting guess of the next finer grid, relax again, down to full resolution. The
//! correction is added to the chart's texels.

// Loops over the three coordinates index several arrays at once; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use crate::texture::{SampleType, TileStore};

/// The paper's damping and step.
pub const D: f64 = 0.97;
pub const K: f64 = 0.4375;

/// A colour in `[0, 1]` per channel (RGB; gray replicated).
pub type Rgb = [f64; 3];

#[inline]
fn full_scale(t: SampleType) -> f64 {
    match t {
        SampleType::U8 => 255.0,
        SampleType::U16 => 65535.0,
        SampleType::F32 => 1.0,
    }
}

/// Reads pixel `(x, y)` (row 0 at the top) as RGB in `[0, 1]`.
#[inline]
pub fn read_rgb(s: &TileStore, x: u32, y: u32) -> Rgb {
    let f = s.format();
    let px = s.pixel(x, y);
    let load = |c: usize| -> f64 {
        match f.sample {
            SampleType::U8 => f64::from(px[c]),
            SampleType::U16 => f64::from(u16::from_ne_bytes([px[2 * c], px[2 * c + 1]])),
            SampleType::F32 => f64::from(f32::from_ne_bytes([
                px[4 * c],
                px[4 * c + 1],
                px[4 * c + 2],
                px[4 * c + 3],
            ])),
        }
    };
    let k = 1.0 / full_scale(f.sample);
    if f.channels >= 3 {
        [load(0) * k, load(1) * k, load(2) * k]
    } else {
        let g = load(0) * k;
        [g, g, g]
    }
}

/// Writes pixel `(x, y)` from RGB in `[0, 1]` (clamped; other channels untouched).
#[inline]
pub fn write_rgb(s: &mut TileStore, x: u32, y: u32, v: Rgb) {
    let f = s.format();
    let fs = full_scale(f.sample);
    let n = if f.channels >= 3 { 3 } else { 1 };
    let px = s.pixel_mut(x, y);
    for (c, &val) in v.iter().enumerate().take(n) {
        let v = val.clamp(0.0, 1.0) * fs;
        match f.sample {
            SampleType::U8 => px[c] = (v + 0.5) as u8,
            SampleType::U16 => {
                px[2 * c..2 * c + 2].copy_from_slice(&((v + 0.5) as u16).to_ne_bytes())
            }
            SampleType::F32 => px[4 * c..4 * c + 4].copy_from_slice(&(v as f32).to_ne_bytes()),
        }
    }
}

/// Bilinear sample at a texel-space point (v up), clamped to the image.
pub fn sample(s: &TileStore, p: [f64; 2]) -> Rgb {
    let (w, h) = (s.width(), s.height());
    let x = (p[0] - 0.5).clamp(0.0, f64::from(w - 1));
    let y = (f64::from(h) - p[1] - 0.5).clamp(0.0, f64::from(h - 1));
    let (x0, y0) = (x.floor() as u32, y.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - f64::from(x0), y - f64::from(y0));
    let (a, b, c, d) =
        (read_rgb(s, x0, y0), read_rgb(s, x1, y0), read_rgb(s, x0, y1), read_rgb(s, x1, y1));
    let mut out = [0.0; 3];
    for k in 0..3 {
        out[k] =
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy;
    }
    out
}

/// A chart's region on its output sheet: a box of texels with a mask, the fixed corrections and
/// the unknowns, all row-major in the box.
pub struct ChartGrid {
    /// Box origin (column, row from the top) on the output sheet and size.
    pub x0: u32,
    pub y0: u32,
    pub w: u32,
    pub h: u32,
    /// Texel belongs to the chart.
    pub inside: Vec<bool>,
    /// Fixed correction (sum) and count of samples that fixed it; count 0 = unknown.
    pub fixed: Vec<Rgb>,
    pub count: Vec<u32>,
}

impl ChartGrid {
    pub fn new(x0: u32, y0: u32, w: u32, h: u32) -> Self {
        let n = (w * h) as usize;
        Self { x0, y0, w, h, inside: vec![false; n], fixed: vec![[0.0; 3]; n], count: vec![0; n] }
    }

    /// Adds a correction sample at sheet texel `(x, y)` (ignored outside the box).
    pub fn add(&mut self, x: u32, y: u32, v: Rgb) {
        if x < self.x0 || y < self.y0 || x >= self.x0 + self.w || y >= self.y0 + self.h {
            return;
        }
        let o = ((y - self.y0) * self.w + (x - self.x0)) as usize;
        for k in 0..3 {
            self.fixed[o][k] += v[k];
        }
        self.count[o] += 1;
    }
}

/// Relaxation sweeps of the paper's scheme on one grid: `p` values, `fixed` texels never move,
/// `active` texels are relaxed; neighbours outside `active ∪ fixed` mirror the centre (a
/// Neumann border, so the chart's outline does not pull the correction to zero). Stops when the
/// mean squared velocity falls below `tol` or after `max_iter` sweeps; returns the sweeps run.
pub fn relax(
    p: &mut [Rgb],
    active: &[bool],
    fixed: &[bool],
    w: usize,
    h: usize,
    tol: f64,
    max_iter: u32,
) -> u32 {
    let n = w * h;
    let mut v = vec![[0.0f64; 3]; n];
    let mut lap = vec![[0.0f64; 3]; n];
    let free: Vec<usize> = (0..n).filter(|&i| active[i] && !fixed[i]).collect();
    if free.is_empty() {
        return 0;
    }
    let known = |i: usize| active[i] || fixed[i];
    for it in 0..max_iter {
        for &i in &free {
            let (x, y) = (i % w, i / w);
            let c = p[i];
            let mut s = [0.0; 3];
            let mut add = |j: usize| {
                let q = if known(j) { p[j] } else { c };
                for k in 0..3 {
                    s[k] += q[k] - c[k];
                }
            };
            if x > 0 {
                add(i - 1)
            } else {
                add(i)
            }
            if x + 1 < w {
                add(i + 1)
            } else {
                add(i)
            }
            if y > 0 {
                add(i - w)
            } else {
                add(i)
            }
            if y + 1 < h {
                add(i + w)
            } else {
                add(i)
            }
            lap[i] = s;
        }
        let mut e = 0.0;
        for &i in &free {
            for k in 0..3 {
                v[i][k] = D * v[i][k] + K * lap[i][k];
                p[i][k] += v[i][k];
                e += v[i][k] * v[i][k];
            }
        }
        if e / (free.len() as f64) < tol {
            return it + 1;
        }
    }
    max_iter
}

/// Multigrid diffusion of a chart's sparse corrections (see the module text). Returns the
/// correction of every texel of the box (zero outside the chart) and the total sweeps.
pub fn diffuse(g: &ChartGrid, tol: f64, max_iter: u32) -> (Vec<Rgb>, u32) {
    let (w, h) = (g.w as usize, g.h as usize);
    let n = w * h;
    let mut p0 = vec![[0.0; 3]; n];
    let mut fixed0 = vec![false; n];
    for i in 0..n {
        if g.count[i] > 0 {
            let c = f64::from(g.count[i]);
            p0[i] = g.fixed[i].map(|v| v / c);
            fixed0[i] = true;
        }
    }
    if !fixed0.iter().any(|&f| f) {
        return (vec![[0.0; 3]; n], 0);
    }
    // Restriction: each coarser level averages the fixed values of its 2×2 children and marks a
    // texel active when any child is; stop when every active texel has a value.
    struct Level {
        w: usize,
        h: usize,
        p: Vec<Rgb>,
        fixed: Vec<bool>,
        active: Vec<bool>,
    }
    let mut levels = vec![Level { w, h, p: p0, fixed: fixed0, active: g.inside.clone() }];
    loop {
        let l = levels.last().expect("one level");
        let complete = (0..l.w * l.h).all(|i| !l.active[i] || l.fixed[i]);
        if complete || (l.w <= 1 && l.h <= 1) {
            break;
        }
        let (cw, ch) = (l.w.div_ceil(2), l.h.div_ceil(2));
        let mut c = Level {
            w: cw,
            h: ch,
            p: vec![[0.0; 3]; cw * ch],
            fixed: vec![false; cw * ch],
            active: vec![false; cw * ch],
        };
        for y in 0..ch {
            for x in 0..cw {
                let mut s = [0.0; 3];
                let mut m = 0.0;
                let mut act = false;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (fx, fy) = (2 * x + dx, 2 * y + dy);
                    if fx >= l.w || fy >= l.h {
                        continue;
                    }
                    let j = fy * l.w + fx;
                    act |= l.active[j] || l.fixed[j];
                    if l.fixed[j] {
                        for k in 0..3 {
                            s[k] += l.p[j][k];
                        }
                        m += 1.0;
                    }
                }
                let i = y * cw + x;
                c.active[i] = act;
                if m > 0.0 {
                    c.fixed[i] = true;
                    c.p[i] = s.map(|v| v / m);
                }
            }
        }
        levels.push(c);
    }
    // Prolongation and relaxation from the coarsest level up. The coarsest is complete, so its
    // relaxation is a no-op; each finer level starts from the parent's values.
    let mut sweeps = 0;
    for k in (0..levels.len()).rev() {
        if k + 1 < levels.len() {
            let (upper, lower) = levels.split_at_mut(k + 1);
            let (fine, coarse) = (&mut upper[k], &lower[0]);
            for y in 0..fine.h {
                for x in 0..fine.w {
                    let i = y * fine.w + x;
                    if !fine.fixed[i] {
                        fine.p[i] = coarse.p[(y / 2) * coarse.w + x / 2];
                    }
                }
            }
        }
        let l = &mut levels[k];
        sweeps += relax(&mut l.p, &l.active, &l.fixed, l.w, l.h, tol, max_iter);
    }
    let top = levels.swap_remove(0);
    let out =
        (0..n).map(|i| if g.inside[i] || top.fixed[i] { top.p[i] } else { [0.0; 3] }).collect();
    (out, sweeps)
}
