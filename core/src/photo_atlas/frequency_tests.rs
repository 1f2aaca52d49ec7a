//! Tests of the frequency analysis (Laplacian pyramids, detail levels), the greedy level
//! smoothing and the frequency-based chart splitting, on fixtures generated here.

#![allow(clippy::needless_range_loop)] // face loops index several per-face arrays

use super::frequency::{
    FrequencyOptions, assign_level, detail_content, level_changes, smooth_levels,
};
use super::partition::{NONE, face_adjacency};
use super::pyramid::{self, Plane, level_count, level_size, reduce_store, to_level};
use super::split::{SplitInput, split_charts};
use crate::rng::XorShift64;
use crate::texture::{PixelFormat, TileStore};

#[test]
fn laplacian_of_a_constant_image_is_zero_at_every_level() {
    // Odd and even sizes exercise both mirror cases at the borders.
    for (w, h) in [(203, 150), (256, 193)] {
        let mut g = Plane { w, h, data: vec![0.437; w * h] };
        let mut next = Plane::default();
        let levels = level_count(w as u32, h as u32);
        assert!(levels >= 4, "{w}x{h}: {levels} levels");
        for k in 0..levels - 1 {
            pyramid::reduce(&g, &mut next);
            assert_eq!((next.w, next.h), (w.div_ceil(1 << (k + 1)), h.div_ceil(1 << (k + 1))));
            assert!(next.data.iter().all(|&v| (v - 0.437).abs() < 1e-5), "G_{} constant", k + 1);
            pyramid::laplacian_in_place(&mut g, &next);
            let worst = g.data.iter().fold(0.0f32, |m, &v| m.max(v.abs()));
            assert!(worst < 1e-5, "{w}x{h}: |L_{k}| up to {worst}");
            std::mem::swap(&mut g, &mut next);
        }
    }
    // The colour levels of a constant photo are the same constant, and the right size.
    let dir = tempfile::tempdir().unwrap();
    let mut s = TileStore::create(dir.path(), 301, 260, PixelFormat::RGB8).unwrap();
    for y in 0..260 {
        for x in 0..301 {
            s.pixel_mut(x, y).copy_from_slice(&[17, 140, 251]);
        }
    }
    let g1 = reduce_store(&s, dir.path()).unwrap();
    let g2 = reduce_store(&g1, dir.path()).unwrap();
    assert_eq!((g2.width(), g2.height()), level_size(301, 260, 2));
    for y in 0..g2.height() {
        for x in 0..g2.width() {
            assert_eq!(g2.pixel(x, y), &[17, 140, 251]);
        }
    }
}

#[test]
fn level_texel_space_puts_each_texel_on_its_level_zero_pixel() {
    // Pixel i of level l is centred on pixel 2^l·i of level 0 (columns and rows from the top).
    let (w0, h0) = (100u32, 75u32);
    for l in 0..4 {
        let (_, hl) = level_size(w0, h0, l);
        for (i, j) in [(0u32, 0u32), (3, 5), (6, 4)] {
            let (x0, y0) = (i << l, j << l);
            let p0 = [f64::from(x0) + 0.5, f64::from(h0) - f64::from(y0) - 0.5];
            let p = to_level(p0, l, h0);
            let want = [f64::from(i) + 0.5, f64::from(hl) - f64::from(j) - 0.5];
            assert!((p[0] - want[0]).abs() < 1e-12 && (p[1] - want[1]).abs() < 1e-12, "{p:?}");
        }
    }
    // Level 0 is the identity, bit for bit.
    let p = [12.345678901, 0.1 + 0.2];
    assert_eq!(to_level(p, 0, 75), p);
}

/// A 512² gray photo: top half a step edge (50 | 200) at x = 256; bottom left a 2-pixel
/// checkerboard (fine texture); bottom right a smooth sine of wavelength 40 pixels.
fn test_photo(dir: &std::path::Path) -> TileStore {
    let mut s = TileStore::create(dir, 512, 512, PixelFormat::RGB8).unwrap();
    for y in 0..512u32 {
        for x in 0..512u32 {
            let v = if y < 256 {
                if x < 256 { 50.0 } else { 200.0 }
            } else if x < 256 {
                if ((x / 2) + (y / 2)) % 2 == 0 { 100.0 } else { 160.0 }
            } else {
                128.0 + 20.0 * (std::f64::consts::TAU * f64::from(x) / 40.0).sin()
            };
            let v = v as u8;
            s.pixel_mut(x, y).copy_from_slice(&[v, v, v]);
        }
    }
    s
}

/// A triangle with corners given in pixel coordinates (from the top-left corner), in the
/// texel space (v up) of a 512-pixel-high photo.
fn tri_px(c: [[f64; 2]; 3]) -> [[f64; 2]; 3] {
    c.map(|p| [p[0], 512.0 - p[1]])
}

#[test]
fn a_face_over_a_sharp_edge_gets_level_zero_and_a_flat_face_a_coarse_level() {
    let dir = tempfile::tempdir().unwrap();
    let photo = test_photo(dir.path());
    let faces = [
        tri_px([[248.0, 100.0], [264.0, 100.0], [256.0, 116.0]]), // over the step edge
        tri_px([[40.0, 40.0], [100.0, 40.0], [70.0, 100.0]]),     // flat
        tri_px([[60.0, 340.0], [120.0, 340.0], [90.0, 400.0]]),   // fine texture
        tri_px([[360.0, 340.0], [420.0, 340.0], [390.0, 400.0]]), // smooth sine
        tri_px([[70.0, 150.0], [70.3, 150.0], [70.0, 150.3]]),    // far below a texel, flat
    ];
    let uv0: Vec<[f64; 2]> = faces.iter().flatten().copied().collect();
    let face_photo = vec![0u32; faces.len()];
    let det = detail_content(std::slice::from_ref(&photo), &face_photo, &uv0);
    let o = FrequencyOptions::default();
    let levels: Vec<u8> = (0..faces.len())
        .map(|f| assign_level(&det.d[f][..usize::from(det.n_bands[f])], &o))
        .collect();
    assert_eq!(det.n_bands[0], 5, "512² photo: Gaussian levels 0..=5");
    let d = |f: usize| det.d[f][..5].to_vec();
    assert_eq!(levels[0], 0, "edge: {:?}", d(0));
    assert_eq!(levels[2], 0, "fine texture: {:?}", d(2));
    assert!(levels[1] >= 4, "flat: level {} from {:?}", levels[1], d(1));
    assert!(levels[4] >= 4, "tiny flat face: level {} from {:?}", levels[4], d(4));
    assert!((2..=3).contains(&levels[3]), "smooth sine: level {} from {:?}", levels[3], d(3));
    // Responses at the edge are large at every scale; on the flat face they are zero.
    assert!(d(0).iter().all(|&v| v > 0.1), "{:?}", d(0));
    assert!(d(1).iter().all(|&v| v < 1e-5), "{:?}", d(1));
}

#[test]
fn the_level_rule_decays_past_the_noise_floor_and_keeps_plateau_edges_fine() {
    let o = FrequencyOptions::default();
    // Fine detail that decays at once: level 0.
    assert_eq!(assign_level(&[0.2, 0.05, 0.01, 0.0, 0.0], &o), 0);
    // Detail peaking in band 2, decaying after: level 2 (the bands below are under the floor).
    assert_eq!(assign_level(&[0.002, 0.01, 0.03, 0.012, 0.001], &o), 2);
    // A blurred step: rising then flat across scales, never decaying; the budget keeps it fine.
    assert_eq!(assign_level(&[0.03, 0.045, 0.046, 0.046, 0.046], &o), 1);
    assert_eq!(assign_level(&[0.06, 0.07, 0.07, 0.07, 0.07], &o), 0);
    // A fall of less than the relative threshold is jitter, not a decay.
    assert_eq!(assign_level(&[0.0, 0.001, 0.02, 0.017, 0.018], &o), 4);
    let strict = FrequencyOptions { decay: 0.0, ..o.clone() };
    assert_eq!(assign_level(&[0.0, 0.001, 0.02, 0.017, 0.018], &strict), 2);
    // Everything under the noise floor: the coarsest level, capped by max_level.
    assert_eq!(assign_level(&[0.01, 0.004, 0.002, 0.001, 0.0], &o), 5);
    let capped = FrequencyOptions { max_level: 3, ..o.clone() };
    assert_eq!(assign_level(&[0.0; 5], &capped), 3);
    assert_eq!(assign_level(&[], &o), 0, "a photo too small for a pyramid");
}

/// A regular grid of `n × n` quads split into triangles, in the plane.
fn grid(n: u32) -> Vec<[u32; 3]> {
    let mut t = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let (a, b, c, d) = (
                y * (n + 1) + x,
                y * (n + 1) + x + 1,
                (y + 1) * (n + 1) + x,
                (y + 1) * (n + 1) + x + 1,
            );
            t.push([a, b, d]);
            t.push([a, d, c]);
        }
    }
    t
}

#[test]
fn greedy_smoothing_reduces_level_changes_and_only_refines() {
    let n = 30;
    let tris = grid(n);
    let adj = face_adjacency(&tris);
    let nf = tris.len();
    // Two charts (left and right halves) with coherent levels plus noise: a coarse region with
    // scattered coarser and finer faces.
    let chart: Vec<u32> = (0..nf).map(|f| u32::from((f as u32 / 2) % n >= n / 2)).collect();
    let mut rng = XorShift64(0x5EED);
    let base: Vec<u8> = (0..nf)
        .map(|f| {
            let x = (f as u32 / 2) % n;
            let clean = if x < n / 4 { 0 } else { 3 };
            let r = rng.signed();
            if r > 0.6 {
                clean.max(1) - 1
            } else if r < -0.6 {
                (clean + 1).min(5)
            } else {
                clean
            }
        })
        .collect();
    let mut levels = base.clone();
    let before = level_changes(&levels, &adj, &chart);
    let (passes, switches) = smooth_levels(&mut levels, &adj, &chart, 8);
    let after = level_changes(&levels, &adj, &chart);
    assert!(switches > 0 && (1..=8).contains(&passes));
    assert!(after < before * 3 / 4, "level changes {before} -> {after}");
    for f in 0..nf {
        assert!(levels[f] <= base[f], "face {f}: {} -> {}", base[f], levels[f]);
    }
    // Deterministic.
    let mut again = base.clone();
    smooth_levels(&mut again, &adj, &chart, 8);
    assert_eq!(again, levels);
    // Isolated coarse faces in a fine region are refined.
    let mut one = vec![0u8; nf];
    one[2 * (5 * n + 5) as usize] = 4;
    smooth_levels(&mut one, &adj, &vec![0; nf], 8);
    assert!(one.iter().all(|&l| l == 0));
}

#[test]
fn splitting_keeps_every_face_once_and_never_textures_a_face_coarser() {
    let n = 40;
    let tris = grid(n);
    let adj = face_adjacency(&tris);
    let nf = tris.len();
    // Vertices on a 4-texel grid of a 400-pixel-high photo; every face has area 8.
    let uv0: Vec<[f64; 2]> = tris
        .iter()
        .flat_map(|t| {
            t.map(|v| [f64::from(v % (n + 1)) * 4.0, 20.0 + f64::from(v / (n + 1)) * 4.0])
        })
        .collect();
    let area = vec![8.0; nf];
    // Chart 0: left half, fine on the left, coarse (level 3) on the right; chart 1: right half,
    // level 2 with a fine disc; face 0 has no chart.
    let col = |f: usize| (f as u32 / 2) % n;
    let row = |f: usize| (f as u32 / 2) / n;
    let mut chart: Vec<u32> = (0..nf).map(|f| u32::from(col(f) >= n / 2)).collect();
    chart[0] = NONE;
    let level: Vec<u8> = (0..nf)
        .map(|f| {
            let (x, y) = (col(f) as i64, row(f) as i64);
            if x < n as i64 / 2 {
                if x < 6 { 0 } else { 3 }
            } else if (x - 30).pow(2) + (y - 20).pow(2) < 25 {
                0
            } else {
                2
            }
        })
        .collect();
    let heights = [400u32, 400];
    let inp = SplitInput {
        face_chart: &chart,
        n_charts: 2,
        level: &level,
        adj: &adj,
        area: &area,
        uv0: &uv0,
        chart_height: &heights,
        padding: 2,
        max_rounds: 12,
    };
    let s = split_charts(&inp);
    assert_eq!(s.face_sub.len(), nf, "one entry per face, in face order");
    assert_eq!(s.face_sub[0], NONE, "a face without chart stays without");
    let mut count = vec![0usize; s.sub_chart.len()];
    for f in 1..nf {
        let sc = s.face_sub[f];
        assert_ne!(sc, NONE, "face {f} dropped");
        count[sc as usize] += 1;
        assert_eq!(s.sub_chart[sc as usize], chart[f], "a sub-chart stays in its chart");
        assert!(s.sub_level[sc as usize] <= level[f], "face {f} textured coarser than its level");
    }
    assert!(count.iter().all(|&c| c > 0), "no empty sub-chart");
    assert!(s.sub_chart.len() >= 4, "{} sub-charts", s.sub_chart.len());
    assert!(s.sub_level.contains(&3) && s.sub_level.contains(&2));
    assert!(s.rect_texels_after < s.rect_texels_before * 2 / 3, "{s:?}");
    // Sub-charts are edge-connected.
    assert!(super::tests::labels_connected(&s.face_sub, &adj), "sub-charts connected");
    // Deterministic whatever the thread count.
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let s1 = one.install(|| split_charts(&inp));
    assert_eq!((s1.face_sub, s1.sub_level), (s.face_sub.clone(), s.sub_level.clone()));
    // A chart of one level is one sub-chart at that level.
    let flat = vec![2u8; nf];
    let s2 = split_charts(&SplitInput { level: &flat, ..inp });
    assert_eq!(s2.sub_level, vec![2, 2]);
}

#[test]
fn a_gaussian_level_sampled_at_level_uvs_reproduces_a_linear_ramp() {
    // The binomial filter keeps linear functions, so G_l of a ramp is the ramp sampled at the
    // level's texel centres; a bilinear sample of G_l at `to_level(p)` must give the ramp at p.
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (256u32, 200u32);
    let ramp = |x: f64, y: f64| 20.0 + 0.5 * x + 0.4 * y; // x, y: pixel coordinates
    let mut s = TileStore::create(
        dir.path(),
        w,
        h,
        PixelFormat { channels: 1, sample: crate::texture::SampleType::F32 },
    )
    .unwrap();
    for y in 0..h {
        for x in 0..w {
            let v = ramp(f64::from(x) + 0.5, f64::from(y) + 0.5) as f32;
            s.pixel_mut(x, y).copy_from_slice(&v.to_ne_bytes());
        }
    }
    let mut level = reduce_store(&s, dir.path()).unwrap();
    for l in 1..=3 {
        if l > 1 {
            level = reduce_store(&level, dir.path()).unwrap();
        }
        for p in [[60.3, 70.9], [101.0, 150.5], [128.0, 100.0]] {
            let q = to_level(p, l, h);
            let got = crate::photo_atlas::smoothing::sample(&level, q)[0];
            let want = ramp(p[0], f64::from(h) - p[1]);
            assert!((got - want).abs() < 1e-3, "level {l} at {p:?}: {got} vs {want}");
        }
    }
}

#[test]
fn coarse_rings_copy_the_source_around_a_chart_and_nothing_else() {
    use super::photo_ring::{RingChart, fill_rings};
    use crate::geometry::GridTransform;
    use crate::texture::gutter::Coverage;
    use crate::texture::raster::{PixelRect, rasterize_triangle};
    let dir = tempfile::tempdir().unwrap();
    let mut src = TileStore::create(dir.path(), 40, 40, PixelFormat::RGB8).unwrap();
    for y in 0..40 {
        for x in 0..40 {
            src.pixel_mut(x, y).copy_from_slice(&[(3 * x) as u8, (5 * y) as u8, 7]);
        }
    }
    let mut out = vec![TileStore::create(dir.path(), 40, 40, PixelFormat::RGB8).unwrap()];
    // One triangle copied at an offset of (+5, +3) texels; a second face, of another chart, sits
    // right next to it and must keep its texels.
    let t = GridTransform { offset: [5, 3], ..GridTransform::IDENTITY };
    let tri = [[10.0, 10.0], [20.0, 10.0], [10.0, 20.0]].map(|p| t.apply(p));
    let other = [[26.0, 13.5], [30.0, 13.5], [26.0, 17.5]];
    let tris = [tri, other];
    // The chart's face texels are copies of the source, as the resampler makes them; the other
    // face's are a flat (1, 2, 3).
    let mut cov = vec![Coverage::for_store(&out[0])];
    let mut mine = Vec::new();
    for (k, tr) in tris.iter().enumerate() {
        rasterize_triangle(*tr, 40, PixelRect::new(0, 0, 40, 40), |i, j, _| {
            if k == 0 {
                mine.push((i, j));
            }
            let v = match t.source_pixel(i, j, 40, 40, 40) {
                Some((sx, sy)) if k == 0 => src.pixel(sx, sy).to_vec(),
                _ => vec![1, 2, 3],
            };
            out[0].pixel_mut(i, j).copy_from_slice(&v);
            cov[0].set(i, j);
        });
    }
    let chart = RingChart { out_sheet: 0, src_sheet: 0, transform: t, faces: vec![0] };
    let mut ring = Vec::new();
    let sources = [src];
    fill_rings(&[chart], &|f| tris[f], 2, &sources, &mut out, &cov, &mut ring);
    assert!(ring.len() > 20, "{} ring texels", ring.len());
    for &(_, x, y) in &ring {
        assert!(!cov[0].get(x, y), "a face texel was overwritten");
        let (sx, sy) = t.source_pixel(x, y, 40, 40, 40).unwrap();
        assert_eq!(out[0].pixel(x, y), sources[0].pixel(sx, sy), "ring texel ({x}, {y})");
    }
    // The ring is exactly the texels off every face within two texels of the chart.
    let mut want = Vec::new();
    for y in 0..40u32 {
        for x in 0..40u32 {
            let near = mine.iter().any(|&(i, j)| x.abs_diff(i) <= 2 && y.abs_diff(j) <= 2);
            if near && !cov[0].get(x, y) {
                want.push((0u32, x, y));
            }
        }
    }
    let mut got = ring.clone();
    got.sort_unstable_by_key(|&(s, x, y)| (s, y, x));
    want.sort_unstable_by_key(|&(s, x, y)| (s, y, x));
    assert_eq!(got, want);
    // The other chart's face texels are untouched.
    rasterize_triangle(other, 40, PixelRect::new(0, 0, 40, 40), |i, j, _| {
        assert_eq!(out[0].pixel(i, j), &[1, 2, 3]);
    });
}
