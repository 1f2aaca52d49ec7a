//! Exposure compensation: one colour gain per photo, estimated from the surface seen by several
//! photos, so that every chart is textured at the capture's common exposure.
//!
//! Photos of one capture differ in exposure and white balance. The paper's colour smoothing (§5)
//! only evens out the step at each seam, towards the mean of the two photos there: a chart
//! whose photo is 10% too bright stays about 10% too bright inside. Here each photo `k` gets a
//! gain `g_k` per channel, with the model `photo_k(x) = g_k · colour(x)` in linear light, and the
//! gains are the least-squares fit over faces seen by several photos (in logarithms, so a gain
//! is a shift): `Σ_f Σ_{k sees f} w (ln v_{f,k} − ln g_k − ln c_f)²`, the per-face colours `c_f`
//! eliminated, the mean of `ln g_k` over the photos pinned to 0 (the capture's mean exposure is
//! the reference, the only one a capture without a colour chart has), and a small pull of each
//! `ln g_k` towards 0 for photos that share no surface with the others. Outliers (occlusions the
//! z-buffer misses, specular highlights) are down-weighted by a few Huber reweighting rounds, as
//! in the gain compensation of panorama stitching (Brown & Lowe 2007).
//!
//! Photos are read one at a time in camera order (their pages released after), so a capture of
//! hundreds of large photos costs no more memory than one photo's sampled pages.

use crate::photo_atlas::cameras::PhotoCamera;
use crate::photo_atlas::smoothing::{self, Rgb};
use crate::photo_atlas::visibility::Visibility;
use crate::texture::{SampleType, TileStore};

/// Options of the estimate.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ExposureOptions {
    /// Faces sampled at most (an even stride over the mesh): enough for a few hundred photos.
    pub max_faces: usize,
    /// Huber threshold in natural-log units (0.05 ≈ a 5% colour ratio).
    pub huber: f64,
    /// Reweighting rounds after the first plain least-squares solve.
    pub rounds: u32,
    /// Linear values below this are too dark to carry a ratio (noise, background).
    pub min_linear: f64,
    /// sRGB values above this may be clipped.
    pub max_encoded: f64,
}

impl Default for ExposureOptions {
    fn default() -> Self {
        Self { max_faces: 200_000, huber: 0.05, rounds: 4, min_linear: 0.004, max_encoded: 0.98 }
    }
}

/// The estimated gains and the figures of the fit.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Exposure {
    /// Per photo, the gain of each channel (photo = gain · common exposure, linear light); 1 for
    /// photos that took no part.
    pub gains: Vec<[f64; 3]>,
    /// Faces sampled, and those seen usably by at least two photos.
    pub faces_sampled: usize,
    pub faces_used: usize,
    /// Observations (face, photo) used.
    pub observations: usize,
    /// Root mean square of the log-ratio between the photos and the per-face mean, before and
    /// after the gains: how far apart the photos were, and what remains (detail, occlusion).
    pub rms_before: f64,
    pub rms_after: f64,
    /// Largest deviation of any gain from 1.
    pub max_deviation: f64,
}

/// Barycentric points a face is sampled at: its centroid and three points towards its corners,
/// averaged, so that photos with different pixel grids agree on detailed surface.
const POINTS: [[f64; 3]; 4] = [
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
    [2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0],
    [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
    [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0],
];

/// sRGB transfer, for photos stored with it (8- and 16-bit); float photos are linear.
#[inline]
pub fn to_linear(v: f64, sample: SampleType) -> f64 {
    if sample == SampleType::F32 {
        return v;
    }
    if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

/// The inverse of [`to_linear`].
#[inline]
pub fn from_linear(l: f64, sample: SampleType) -> f64 {
    if sample == SampleType::F32 {
        return l;
    }
    let l = l.max(0.0);
    if l <= 0.003_130_8 { l * 12.92 } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 }
}

impl Exposure {
    /// No correction for `n` photos.
    pub fn identity(n: usize) -> Self {
        Self { gains: vec![[1.0; 3]; n], ..Self::default() }
    }

    /// `rgb` (encoded, `[0, 1]`) of photo `k` brought to the common exposure.
    #[inline]
    pub fn correct(&self, k: usize, rgb: Rgb, sample: SampleType) -> Rgb {
        let g = self.gains.get(k).copied().unwrap_or([1.0; 3]);
        [0, 1, 2].map(|c| from_linear(to_linear(rgb[c], sample) / g[c], sample))
    }

    /// Per channel, the corrected value of every 8-bit code of photo `k`.
    pub fn lut8(&self, k: usize) -> [[u8; 256]; 3] {
        let g = self.gains.get(k).copied().unwrap_or([1.0; 3]);
        let mut t = [[0u8; 256]; 3];
        for (c, row) in t.iter_mut().enumerate() {
            for (v, out) in row.iter_mut().enumerate() {
                let l = to_linear(v as f64 / 255.0, SampleType::U8) / g[c];
                *out = (from_linear(l, SampleType::U8).clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            }
        }
        t
    }

    /// Whether any gain differs from 1.
    pub fn is_identity(&self) -> bool {
        self.gains.iter().all(|g| g.iter().all(|&v| v == 1.0))
    }
}

/// Estimates one gain per photo from the faces several photos see. `photos[k]` is photo `k`'s
/// decoded store, or `None` for photos that were not decoded (they keep gain 1 and take no
/// part).
pub fn estimate(
    positions: &[[f64; 3]],
    tris: &[[u32; 3]],
    vis: &Visibility,
    cams: &[PhotoCamera],
    photos: &[Option<&TileStore>],
    opts: &ExposureOptions,
) -> Exposure {
    let n_cams = cams.len();
    let nf = tris.len();
    let stride = nf.div_ceil(opts.max_faces.max(1)).max(1);
    let sampled: Vec<usize> = (0..nf).step_by(stride).collect();
    // Observation slots of the sampled faces (CSR over `vis`), filled photo by photo.
    let mut start = Vec::with_capacity(sampled.len() + 1);
    start.push(0usize);
    for &f in &sampled {
        let n = vis.of(f).iter().filter(|&&k| photos[k as usize].is_some()).count();
        start.push(start.last().copied().unwrap_or(0) + n);
    }
    let n_obs = *start.last().unwrap_or(&0);
    let mut obs_cam = vec![0u32; n_obs];
    // ln of the mean linear colour per channel; NaN = unusable.
    let mut obs_val = vec![[f64::NAN; 3]; n_obs];
    // Slots of each photo, so every photo is read in one sweep.
    let mut by_cam: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n_cams];
    for (i, &f) in sampled.iter().enumerate() {
        let mut slot = start[i];
        for &k in vis.of(f) {
            if photos[k as usize].is_some() {
                obs_cam[slot] = k;
                by_cam[k as usize].push((f as u32, slot as u32));
                slot += 1;
            }
        }
    }
    for (k, list) in by_cam.iter().enumerate() {
        let Some(photo) = photos[k] else { continue };
        let sample_type = photo.format().sample;
        for &(f, slot) in list {
            let p = tris[f as usize].map(|v| positions[v as usize]);
            let mut sum = [0.0; 3];
            let mut ok = true;
            for b in POINTS {
                let x = [0, 1, 2].map(|d| b[0] * p[0][d] + b[1] * p[1][d] + b[2] * p[2][d]);
                let Some(q) = cams[k].project_texel(x) else {
                    ok = false;
                    break;
                };
                let (w, h) = (f64::from(photo.width()), f64::from(photo.height()));
                if !(q[0] >= 0.5 && q[1] >= 0.5 && q[0] <= w - 0.5 && q[1] <= h - 0.5) {
                    ok = false;
                    break;
                }
                let c = smoothing::sample(photo, q);
                for ch in 0..3 {
                    if c[ch] > opts.max_encoded {
                        ok = false;
                    }
                    sum[ch] += to_linear(c[ch], sample_type);
                }
            }
            if !ok {
                continue;
            }
            obs_val[slot as usize] = sum.map(|s| {
                let m = s / POINTS.len() as f64;
                if m >= opts.min_linear { m.ln() } else { f64::NAN }
            });
        }
        photo.release_all();
    }

    let mut out = Exposure::identity(n_cams);
    out.faces_sampled = sampled.len();
    let mut rms = [[0.0f64; 2]; 3];
    let mut counted = [0usize; 3];
    let mut faces_used = vec![false; sampled.len()];
    for ch in 0..3 {
        let (l, used, r) = solve_channel(&start, &obs_cam, &obs_val, ch, n_cams, opts);
        for (k, g) in out.gains.iter_mut().enumerate() {
            g[ch] = l[k].exp();
        }
        for (i, u) in used.iter().enumerate() {
            faces_used[i] |= *u;
        }
        rms[ch] = [r.0, r.1];
        counted[ch] = r.2;
    }
    out.faces_used = faces_used.iter().filter(|&&u| u).count();
    out.observations = counted.iter().copied().max().unwrap_or(0);
    let mean_sq = |i: usize| (0..3).map(|c| rms[c][i] * rms[c][i]).sum::<f64>() / 3.0;
    out.rms_before = mean_sq(0).sqrt();
    out.rms_after = mean_sq(1).sqrt();
    out.max_deviation =
        out.gains.iter().flat_map(|g| g.iter()).map(|&v| (v - 1.0).abs()).fold(0.0, f64::max);
    out
}

/// The log-gains of one channel (see the module text); also which faces took part, and the
/// residual RMS before and after with the number of observations.
fn solve_channel(
    start: &[usize],
    obs_cam: &[u32],
    obs_val: &[[f64; 3]],
    ch: usize,
    n_cams: usize,
    opts: &ExposureOptions,
) -> (Vec<f64>, Vec<bool>, (f64, f64, usize)) {
    let n_faces = start.len() - 1;
    let mut weight: Vec<f64> =
        obs_val.iter().map(|v| if v[ch].is_nan() { 0.0 } else { 1.0 }).collect();
    let used: Vec<bool> = (0..n_faces)
        .map(|i| (start[i]..start[i + 1]).filter(|&s| weight[s] > 0.0).count() >= 2)
        .collect();
    let mut l = vec![0.0; n_cams];
    let mut participating = vec![false; n_cams];
    for i in (0..n_faces).filter(|&i| used[i]) {
        for s in (start[i]..start[i + 1]).filter(|&s| weight[s] > 0.0) {
            participating[obs_cam[s] as usize] = true;
        }
    }
    let n_part = participating.iter().filter(|&&p| p).count();
    if n_part < 2 {
        return (l, used, (0.0, 0.0, 0));
    }
    let faces = || (0..n_faces).filter(|&i| used[i]).map(|i| start[i]..start[i + 1]);
    let before = rms_of(faces(), obs_cam, obs_val, ch, &weight, &l);
    for round in 0..=opts.rounds {
        // Normal equations of the problem with the per-face colours eliminated (a weighted
        // graph Laplacian of the photos), dense: a capture has at most a few thousand photos.
        let mut a = nalgebra::DMatrix::<f64>::zeros(n_cams, n_cams);
        let mut b = nalgebra::DVector::<f64>::zeros(n_cams);
        for slots in faces() {
            let live = slots.clone().filter(|&s| weight[s] > 0.0);
            let wsum: f64 = live.clone().map(|s| weight[s]).sum();
            if wsum <= 0.0 {
                continue;
            }
            // Unusable observations hold NaN: they must not enter even with weight 0.
            let wy: f64 = live.map(|s| weight[s] * obs_val[s][ch]).sum();
            for s in slots.clone().filter(|&s| weight[s] > 0.0) {
                let (k, w) = (obs_cam[s] as usize, weight[s]);
                a[(k, k)] += w;
                b[k] += w * (obs_val[s][ch] - wy / wsum);
                for s2 in slots.clone().filter(|&s2| weight[s2] > 0.0) {
                    a[(k, obs_cam[s2] as usize)] -= w * weight[s2] / wsum;
                }
            }
        }
        // The mean log-gain of the participating photos is pinned to 0, and a faint ridge keeps
        // photos that share no surface with the rest at gain 1.
        let mean_diag = (0..n_cams).map(|k| a[(k, k)]).sum::<f64>() / n_part as f64;
        let ridge = 1e-4 * mean_diag.max(1e-12);
        let pin = mean_diag.max(1e-12) / n_part as f64;
        for k in 0..n_cams {
            a[(k, k)] += ridge;
            if participating[k] {
                for k2 in (0..n_cams).filter(|&k2| participating[k2]) {
                    a[(k, k2)] += pin;
                }
            }
        }
        let Some(chol) = a.cholesky() else { break };
        let x = chol.solve(&b);
        for k in 0..n_cams {
            // A gain beyond 2× either way is no exposure difference but a failed fit.
            l[k] = if participating[k] && x[k].is_finite() { x[k].clamp(-LN_2, LN_2) } else { 0.0 };
        }
        if round == opts.rounds {
            break;
        }
        // Huber weights from the residuals against each face's weighted mean colour.
        for slots in faces() {
            let t = face_mean(slots.clone(), obs_cam, obs_val, ch, &weight, &l);
            for s in slots.filter(|&s| !obs_val[s][ch].is_nan()) {
                let r = (obs_val[s][ch] - l[obs_cam[s] as usize] - t).abs();
                weight[s] = if r <= opts.huber { 1.0 } else { opts.huber / r };
            }
        }
    }
    let after = rms_of(faces(), obs_cam, obs_val, ch, &weight, &l);
    (l, used, (before.0, after.0, before.1))
}

const LN_2: f64 = std::f64::consts::LN_2;

/// The weighted mean of a face's corrected log-colours.
fn face_mean(
    slots: std::ops::Range<usize>,
    obs_cam: &[u32],
    obs_val: &[[f64; 3]],
    ch: usize,
    weight: &[f64],
    l: &[f64],
) -> f64 {
    let (mut sw, mut swy) = (0.0, 0.0);
    for s in slots.filter(|&s| weight[s] > 0.0) {
        sw += weight[s];
        swy += weight[s] * (obs_val[s][ch] - l[obs_cam[s] as usize]);
    }
    if sw > 0.0 { swy / sw } else { 0.0 }
}

/// Root mean square of the corrected log-colours about each face's mean, over the inliers
/// (weight 1), and how many there were.
fn rms_of(
    faces: impl Iterator<Item = std::ops::Range<usize>>,
    obs_cam: &[u32],
    obs_val: &[[f64; 3]],
    ch: usize,
    weight: &[f64],
    l: &[f64],
) -> (f64, usize) {
    let (mut sq, mut n) = (0.0, 0usize);
    for slots in faces {
        let t = face_mean(slots.clone(), obs_cam, obs_val, ch, weight, l);
        for s in slots.filter(|&s| weight[s] >= 1.0) {
            let r = obs_val[s][ch] - l[obs_cam[s] as usize] - t;
            sq += r * r;
            n += 1;
        }
    }
    (if n > 0 { (sq / n as f64).sqrt() } else { 0.0 }, n)
}

/// Brings texels to the common exposure: an 8-bit lookup table per photo, made when first
/// needed, or the float path for other formats.
pub struct ExposureLuts<'a> {
    gains: &'a Exposure,
    luts: Vec<Option<[[u8; 256]; 3]>>,
}

impl<'a> ExposureLuts<'a> {
    pub fn new(gains: &'a Exposure) -> Self {
        Self { gains, luts: vec![None; gains.gains.len()] }
    }

    /// Texel `(x, y)` of `store`, taken from photo `cam`, to the common exposure.
    pub fn apply(&mut self, store: &mut TileStore, x: u32, y: u32, cam: usize) {
        let format = store.format();
        if format.sample == SampleType::U8 && format.channels >= 3 {
            let lut = self.luts[cam].get_or_insert_with(|| self.gains.lut8(cam));
            let px = store.pixel_mut(x, y);
            for c in 0..3 {
                px[c] = lut[c][usize::from(px[c])];
            }
        } else {
            let v = smoothing::read_rgb(store, x, y);
            smoothing::write_rgb(store, x, y, self.gains.correct(cam, v, format.sample));
        }
    }
}
