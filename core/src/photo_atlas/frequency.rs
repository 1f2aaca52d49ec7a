//! Chart frequency analysis (paper §4.1) and the greedy level smoothing of §4.2: the detail
//! content of every face at every level of its photo's Laplacian pyramid, the pyramid level
//! that still preserves it, and a pass that evens out isolated levels before splitting.
//!
//! Detail content `d_k(f)` is the largest `|L_k|` over the red, green and blue pyramids (full
//! scale 1; a luminance pyramid alone misses the edges between colours of equal brightness, which
//! photographed surfaces have plenty of) over the texels the face covers at level `k` (its photo projection scaled by `2^-k`; at least the texel holding
//! its centroid) and their immediate neighbours (a band-pass response is zero on the line of an
//! edge itself). Following Mallat, the paper reads regularity from how `d_k` evolves across
//! scales: the first level `k` at which it decays means level `k − 1` is the last to hold the
//! face's detail, so the face gets level `k − 1`. See [`assign_level`] for how that test is made
//! robust and for the error budget that guards step edges, whose response never decays.

use rayon::prelude::*;

use super::partition::NONE;
use super::pyramid::{self, MAX_LEVELS, Plane};
use crate::texture::TileStore;
use crate::texture::coords::pixel_of_texel;
use crate::texture::raster::{PixelRect, rasterize_triangle};

/// Tuning of the frequency analysis. Thresholds are in full-scale units of a colour channel.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FrequencyOptions {
    /// Detail content at or below this is sensor and quantization noise: it neither counts as
    /// detail nor can it decay. 4/255 is above the noise of 8-bit photos of a calibrated capture.
    pub noise_floor: f64,
    /// Relative decay threshold: `d_k` must fall below `(1 − decay)·d_{k−1}` to count as a decay,
    /// so the jitter of a maximum over a few texels (sampling phase, noise) does not.
    pub decay: f64,
    /// Error budget: a face never gets a level `m` with `Σ_{j<m} d_j` above this, which bounds
    /// the colour lost by texturing it from `G_m` instead of the photo.
    pub budget: f64,
    /// Coarsest level assigned (at most [`MAX_LEVELS`] − 1).
    pub max_level: usize,
    /// Bound on the passes of [`smooth_levels`].
    pub smoothing_passes: u32,
}

impl Default for FrequencyOptions {
    fn default() -> Self {
        Self {
            noise_floor: 4.0 / 255.0,
            decay: 0.2,
            budget: 10.0 / 255.0,
            max_level: MAX_LEVELS - 1,
            smoothing_passes: 8,
        }
    }
}

/// Detail content of the faces: `d[f][k]` for `k < n_bands[f]` (the Laplacian levels of the
/// face's photo, one fewer than its Gaussian levels); zero elsewhere and for unseen faces.
#[derive(Clone, Debug, Default)]
pub struct Detail {
    pub d: Vec<[f32; MAX_LEVELS]>,
    pub n_bands: Vec<u8>,
}

/// The detail content of every face `f` with `face_photo[f] != NONE`, from its photo's Laplacian
/// pyramid; `uv0[3f + k]` is corner `k` projected into that photo (level-0 texel space).
/// Photos are analysed one after another, and each one channel after another (each in parallel
/// inside), so only one channel pyramid of one photo is ever in memory; photos that texture no
/// face are never read.
pub fn detail_content(photos: &[TileStore], face_photo: &[u32], uv0: &[[f64; 2]]) -> Detail {
    let nf = face_photo.len();
    let mut out = Detail { d: vec![[0.0; MAX_LEVELS]; nf], n_bands: vec![0; nf] };
    // The faces of each photo, in increasing face order (counting sort).
    let mut start = vec![0usize; photos.len() + 1];
    for &p in face_photo.iter().filter(|&&p| p != NONE) {
        start[p as usize + 1] += 1;
    }
    for k in 0..photos.len() {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut faces = vec![0u32; start[photos.len()]];
    for (f, &p) in face_photo.iter().enumerate() {
        if p != NONE {
            faces[fill[p as usize]] = f as u32;
            fill[p as usize] += 1;
        }
    }
    let (mut g, mut next) = (Plane::default(), Plane::default());
    let mut vals: Vec<f32> = Vec::new();
    for (p, photo) in photos.iter().enumerate() {
        let fs = &faces[start[p]..start[p + 1]];
        if fs.is_empty() {
            continue;
        }
        let (w0, h0) = (photo.width(), photo.height());
        let bands = pyramid::level_count(w0, h0) - 1;
        for &f in fs {
            out.n_bands[f as usize] = bands as u8;
        }
        if bands == 0 {
            continue;
        }
        for c in 0..pyramid::colour_channels(photo.format()) {
            pyramid::channel_plane(photo, c, &mut g);
            for k in 0..bands {
                pyramid::reduce(&g, &mut next);
                pyramid::laplacian_in_place(&mut g, &next);
                fs.par_iter()
                    .map(|&f| face_max(&g, k, h0, &uv0[3 * f as usize..]))
                    .collect_into_vec(&mut vals);
                for (&f, &v) in fs.iter().zip(&vals) {
                    let d = &mut out.d[f as usize][k];
                    *d = d.max(v);
                }
                std::mem::swap(&mut g, &mut next);
            }
        }
        // The photo has been read whole; drop its pages before the next one is.
        photo.release_all();
    }
    out
}

/// Largest `|L_k|` over the texels of level `k` whose centres the face covers, or the texel
/// holding its centroid when it covers none (a face smaller than a texel of that level), and
/// their 8 neighbours. The neighbours matter: a band-pass response is zero on the very line of
/// a step edge and peaks a texel either side, so a face narrower than a texel that sits on an
/// edge would otherwise read nothing there and seem to lose its detail; they are also the
/// texels bilinear filtering blends into the face.
fn face_max(l: &Plane, k: usize, h0: u32, uv: &[[f64; 2]]) -> f32 {
    let (w, h) = (l.w as u32, l.h as u32);
    let tri = [0, 1, 2].map(|c| pyramid::to_level(uv[c], k, h0));
    // The rasterizer visits rows in order and each row's texels left to right as one run, so
    // the covered texels arrive as spans; each span is read with a one-texel margin.
    let mut m = -1.0f32;
    let mut span: Option<(u32, u32, u32)> = None;
    let flush = |s: (u32, u32, u32), m: &mut f32| {
        let (j, i0, i1) = s;
        for y in j.saturating_sub(1)..(j + 2).min(h) {
            let row = &l.data[y as usize * l.w..(y as usize + 1) * l.w];
            for &v in &row[i0.saturating_sub(1) as usize..(i1 + 2).min(w) as usize] {
                *m = m.max(v.abs());
            }
        }
    };
    rasterize_triangle(tri, h, PixelRect::new(0, 0, w, h), |i, j, _| match span {
        Some((sj, i0, _)) if sj == j => span = Some((sj, i0, i)),
        Some(s) => {
            flush(s, &mut m);
            span = Some((j, i, i));
        }
        None => span = Some((j, i, i)),
    });
    if let Some(s) = span {
        flush(s, &mut m);
        return m;
    }
    let c = [0, 1].map(|d| (tri[0][d] + tri[1][d] + tri[2][d]) / 3.0);
    // Clamp into the level so a centroid on the border still reads its nearest texel.
    let c = [c[0].clamp(0.0, f64::from(w) - 0.5), c[1].clamp(0.5, f64::from(h))];
    match pixel_of_texel(c, w, h) {
        Some((i, j)) => {
            flush((j, i, i), &mut m);
            m.max(0.0)
        }
        None => 0.0,
    }
}

/// The pyramid level of a face from its detail content `d` (one entry per Laplacian level of its
/// photo; `d.len() + 1` Gaussian levels).
///
/// * Decay (the paper's rule): the first `k` with `d_{k−1} > noise_floor` and
///   `d_k < (1 − decay)·d_{k−1}` gives level `k − 1`. Past the last measured band `d` counts as
///   zero, so a face whose coarsest band still holds detail gets that band's level, and a face
///   with no detail above the floor anywhere gets the coarsest level.
/// * Budget (added): the level is at most the largest `m` with `Σ_{j<m} d_j ≤ budget`. Since
///   `G_0 = L_0 + EXPAND(L_1 + EXPAND(…G_m))`, that sum bounds what texturing from `G_m` loses.
///   It matters at step edges: their response is the same at every scale (Mallat's regularity
///   0), so they show no decay at all once slightly blurred, yet they need full resolution.
///
/// The result is also capped at `max_level`.
pub fn assign_level(d: &[f32], o: &FrequencyOptions) -> u8 {
    let n = d.len();
    let floor = o.noise_floor as f32;
    let keep = 1.0 - o.decay as f32;
    let mut decay = n;
    for k in 1..=n {
        let (prev, cur) = (d[k - 1], if k < n { d[k] } else { 0.0 });
        if prev > floor && cur < keep * prev {
            decay = k - 1;
            break;
        }
    }
    let mut budget = 0;
    let mut lost = 0.0f64;
    for &v in d {
        lost += f64::from(v);
        if lost > o.budget {
            break;
        }
        budget += 1;
    }
    decay.min(budget).min(o.max_level) as u8
}

/// Greedy level smoothing (§4.2): in face order, a face switches to a finer level (a lower
/// index) taken by one of its neighbours when that strictly lowers the number of its neighbours
/// at a different level; among equally good levels the coarsest wins, to keep the saving. Only
/// neighbours in the same chart count (charts are split separately). Each switch removes level
/// changes across the face's edges and changes no other edge, so the number of level changes
/// strictly falls; faces only ever get finer, so no detail is lost. Runs until a pass changes
/// nothing or after `max_passes`; returns (passes, switches).
pub fn smooth_levels(
    levels: &mut [u8],
    adj: &[[u32; 3]],
    face_chart: &[u32],
    max_passes: u32,
) -> (u32, usize) {
    let mut passes = 0;
    let mut switches = 0;
    while passes < max_passes {
        passes += 1;
        let mut changed = 0;
        for f in 0..levels.len() {
            let c = face_chart[f];
            if c == NONE {
                continue;
            }
            let mut nb = [0u8; 3];
            let mut n = 0;
            for &g in &adj[f] {
                if g != NONE && face_chart[g as usize] == c {
                    nb[n] = levels[g as usize];
                    n += 1;
                }
            }
            let nb = &nb[..n];
            let differing = |l: u8| nb.iter().filter(|&&x| x != l).count();
            let cur = levels[f];
            let mut best = (differing(cur), cur);
            for &l in nb {
                if l < cur {
                    let d = differing(l);
                    if d < best.0 || (d == best.0 && best.1 != cur && l > best.1) {
                        best = (d, l);
                    }
                }
            }
            if best.1 != cur {
                levels[f] = best.1;
                changed += 1;
            }
        }
        switches += changed;
        if changed == 0 {
            break;
        }
    }
    (passes, switches)
}

/// Edges between two faces of one chart at different levels.
pub fn level_changes(levels: &[u8], adj: &[[u32; 3]], face_chart: &[u32]) -> usize {
    let mut n = 0;
    for (f, a) in adj.iter().enumerate() {
        for &g in a {
            if g != NONE
                && (g as usize) > f
                && face_chart[f] != NONE
                && face_chart[f] == face_chart[g as usize]
                && levels[f] != levels[g as usize]
            {
                n += 1;
            }
        }
    }
    n
}
