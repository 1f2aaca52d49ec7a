//! Tests of texture resampling: verbatim copies, bilinear accuracy, coverage, determinism across
//! thread counts, push-pull, several sheets and formats, and refused inputs.

use std::path::Path;

use super::*;
use crate::rng::SplitMix64;
use crate::texture::SampleType;
use crate::texture::raster::{PixelRect, rasterize_triangle};

/// A store of random bytes (for `F32` any bit pattern, NaNs included: a verbatim copy must keep
/// them too).
fn random_store(dir: &Path, w: u32, h: u32, format: PixelFormat, seed: u64) -> TileStore {
    let mut s = TileStore::create(dir, w, h, format).unwrap();
    let mut rng = SplitMix64::new(seed);
    let mut row = vec![0u8; w as usize * format.bytes_per_pixel()];
    for y in 0..h {
        row.iter_mut().for_each(|b| *b = rng.next_u64() as u8);
        s.write_row(y, 0, &row);
    }
    s
}

/// A store whose sample `c` of pixel `(i, j)` is `f(i, j, c)`.
fn store_from(
    dir: &Path,
    w: u32,
    h: u32,
    format: PixelFormat,
    f: impl Fn(u32, u32, usize) -> f64,
) -> TileStore {
    let mut s = TileStore::create(dir, w, h, format).unwrap();
    for j in 0..h {
        for i in 0..w {
            let px = s.pixel_mut(i, j);
            for c in 0..format.channels as usize {
                pixel::store(px, c, format.sample, f(i, j, c));
            }
        }
    }
    s
}

/// All pixel bytes of a store, row by row.
fn bytes(s: &TileStore) -> Vec<u8> {
    let mut out = Vec::new();
    let mut row = vec![0u8; s.width() as usize * s.format().bytes_per_pixel()];
    for y in 0..s.height() {
        s.read_row(y, 0, &mut row);
        out.extend_from_slice(&row);
    }
    out
}

/// The pixels whose centres a texel-space triangle covers.
fn covered(tri: [[f64; 2]; 3], w: u32, h: u32) -> Vec<(u32, u32, [f64; 3])> {
    let mut v = Vec::new();
    rasterize_triangle(tri, h, PixelRect::new(0, 0, w, h), |i, j, b| v.push((i, j, b)));
    v
}

fn opts(dir: &Path, dilate: u32, push_pull: bool) -> ResampleOptions {
    ResampleOptions { dilate, push_pull, work_dir: dir.to_path_buf(), normals: false }
}

/// Texel-space point of a face's source for barycentrics `b`.
fn src_point(src: &[[f64; 2]; 3], b: [f64; 3]) -> [f64; 2] {
    [
        b[0] * src[0][0] + b[1] * src[1][0] + b[2] * src[2][0],
        b[0] * src[0][1] + b[1] * src[1][1] + b[2] * src[2][1],
    ]
}

/// The grid transform of `mirror` and `k` quarter turns with the integer offset that places
/// `src` inside the output sheets of the tests below.
fn placed_inside(mirror: bool, k: u8, src: &[[f64; 2]; 3]) -> GridTransform {
    let mut g = GridTransform { mirror, quarter_turns: k, offset: [0, 0] };
    let lin: Vec<[f64; 2]> = src.iter().map(|&p| g.linear(p)).collect();
    let minx = lin.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
    let miny = lin.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
    g.offset = [(5.0 - minx).ceil() as i64 + 3, (2.0 - miny).ceil() as i64 + 11];
    g
}

#[test]
fn grid_preserved_faces_are_bit_exact_for_every_mirror_and_turn() {
    let dir = tempfile::tempdir().unwrap();
    let formats = [
        PixelFormat::RGBA8,
        PixelFormat { channels: 3, sample: SampleType::U16 },
        PixelFormat { channels: 2, sample: SampleType::F32 },
    ];
    for (fi, &format) in formats.iter().enumerate() {
        // Sizes that cross tile borders in the input and the output.
        let (sw, sh, ow, oh) = (300, 280, 330, 320);
        let input = random_store(dir.path(), sw, sh, format, 7 + fi as u64);
        // Corners off the texel grid on purpose: exactness must not depend on them.
        let src = [[3.25, 4.0], [290.5, 17.75], [40.0, 271.125]];
        for mirror in [false, true] {
            for k in 0..4u8 {
                let g = placed_inside(mirror, k, &src);
                let dst = src.map(|p| g.apply(p));
                let face = FaceMapping { dst_sheet: 0, dst, src_sheet: 0, src, exact: Some(g) };
                let out =
                    resample_sheets(&[&input], &[face], &[(ow, oh)], &opts(dir.path(), 0, false))
                        .unwrap();
                let px = covered(dst, ow, oh);
                assert!(px.len() > 30_000, "{g:?} covers {}", px.len());
                assert_eq!(out.report.texels_copied, px.len() as u64, "{g:?}");
                assert_eq!(out.report.texels_sampled, 0, "{g:?}");
                assert_eq!(out.report.faces_exact, 1);
                let sheet = &out.sheets[0];
                for &(i, j, _) in &px {
                    let (x, y) = g.source_pixel(i, j, oh, sw, sh).unwrap();
                    assert_eq!(sheet.pixel(i, j), input.pixel(x, y), "{g:?} {format:?} ({i},{j})");
                }
            }
        }
    }
}

#[test]
fn a_wrong_grid_transform_is_rejected_and_sampled() {
    let dir = tempfile::tempdir().unwrap();
    let input = random_store(dir.path(), 64, 64, PixelFormat::RGB8, 1);
    let src = [[1.0, 1.0], [60.0, 2.0], [3.0, 50.0]];
    let g = GridTransform { offset: [2, 0], ..GridTransform::IDENTITY };
    let face = FaceMapping { dst_sheet: 0, dst: src, src_sheet: 0, src, exact: Some(g) };
    let out =
        resample_sheets(&[&input], &[face], &[(64, 64)], &opts(dir.path(), 0, false)).unwrap();
    assert_eq!(out.report.faces_exact_rejected, 1);
    assert_eq!(out.report.texels_copied, 0);
    // The identity sampled at texel centres returns the texels unchanged all the same.
    for (i, j, _) in covered(src, 64, 64) {
        assert_eq!(out.sheets[0].pixel(i, j), input.pixel(i, j));
    }
}

#[test]
fn bilinear_sampling_of_a_linear_ramp_is_exact_to_rounding() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (300u32, 290u32);
    let ramp = |x: f64, y: f64| 100.0 * x + 37.0 * y + 5.0;
    for format in [
        PixelFormat { channels: 1, sample: SampleType::U16 },
        PixelFormat { channels: 1, sample: SampleType::F32 },
    ] {
        let input = store_from(dir.path(), w, h, format, |i, j, _| ramp(i as f64, j as f64));
        // A rotated, scaled copy that stays inside the texel centres of the input, so no
        // clamping is involved.
        let (c, s) = (0.4f64.cos() * 0.77, 0.4f64.sin() * 0.77);
        let dst = [[10.0, 10.0], [250.0, 30.0], [60.0, 240.0]];
        let src = dst.map(|p| [c * p[0] - s * p[1] + 110.0, s * p[0] + c * p[1] + 20.0]);
        let face = FaceMapping { dst_sheet: 0, dst, src_sheet: 0, src, exact: None };
        let out = resample_sheets(&[&input], &[face], &[(260, 260)], &opts(dir.path(), 0, false))
            .unwrap();
        let mut n = 0;
        for (i, j, b) in covered(dst, 260, 260) {
            let p = src_point(&src, b);
            let (cx, cy) = (p[0] - 0.5, h as f64 - p[1] - 0.5);
            assert!(cx >= 0.0 && cy >= 0.0 && cx <= (w - 1) as f64 && cy <= (h - 1) as f64);
            let want = ramp(cx, cy);
            let got = pixel::load(out.sheets[0].pixel(i, j), 0, format.sample);
            let tol = if format.sample == SampleType::F32 { 1e-2 } else { 0.5 + 1e-6 };
            assert!((got - want).abs() <= tol, "{format:?} ({i},{j}): {got} vs {want}");
            n += 1;
        }
        assert!(n > 20_000);
        assert_eq!(out.report.texels_sampled, n);
    }
}

#[test]
fn sampling_clamps_at_the_sheet_edges() {
    let dir = tempfile::tempdir().unwrap();
    let input = store_from(dir.path(), 8, 6, PixelFormat::RGB8, |i, j, c| {
        (i * 30 + j * 5 + c as u32) as f64
    });
    let conv = pixel::Conv::new(PixelFormat::RGB8, PixelFormat::RGB8);
    let mut v = [0.0; 4];
    // Beyond every border and corner the nearest edge texel is returned unchanged.
    for (p, (i, j)) in [
        ([-3.0, 2.5], (0, 3)),
        ([20.0, 2.5], (7, 3)),
        ([3.5, -1.0], (3, 5)),
        ([3.5, 9.0], (3, 0)),
        ([-1.0, -1.0], (0, 5)),
        ([8.0, 6.0], (7, 0)),
    ] {
        pixel::bilinear(&input, &conv, p, &mut v);
        let want = input.pixel(i, j);
        for c in 0..3 {
            assert_eq!(v[c], want[c] as f64, "{p:?} channel {c}");
        }
    }
    // Half-way between two texel centres along a border: their mean.
    pixel::bilinear(&input, &conv, [1.0, 0.5], &mut v);
    assert_eq!(v[0], (0.0 + 30.0 + 2.0 * 25.0) / 2.0);
}

#[test]
fn a_sampled_triangle_of_a_smooth_image_reaches_high_psnr() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (400u32, 400u32);
    let f = |x: f64, y: f64, c: usize| {
        128.0 + 90.0 * (x / 23.0 + c as f64).sin() * (y / 31.0).cos() + 0.05 * (x - y)
    };
    let input = store_from(dir.path(), w, h, PixelFormat::RGB8, |i, j, c| f(i as f64, j as f64, c));
    // Magnified and rotated by 30°: every output texel is interpolated.
    let (c, s) = (30f64.to_radians().cos() / 1.3, 30f64.to_radians().sin() / 1.3);
    let dst = [[5.0, 5.0], [300.0, 20.0], [40.0, 290.0]];
    let src = dst.map(|p| [c * p[0] - s * p[1] + 150.0, s * p[0] + c * p[1] + 40.0]);
    let face = FaceMapping { dst_sheet: 0, dst, src_sheet: 0, src, exact: None };
    let out =
        resample_sheets(&[&input], &[face], &[(310, 300)], &opts(dir.path(), 0, false)).unwrap();
    let (mut se, mut n) = (0.0, 0u64);
    for (i, j, b) in covered(dst, 310, 300) {
        let p = src_point(&src, b);
        let (cx, cy) = (p[0] - 0.5, h as f64 - p[1] - 0.5);
        let px = out.sheets[0].pixel(i, j);
        for (ch, &v) in px.iter().enumerate() {
            let d = v as f64 - f(cx, cy, ch).round().clamp(0.0, 255.0);
            se += d * d;
            n += 1;
        }
    }
    let mse = se / n as f64;
    let psnr = 10.0 * (255.0 * 255.0 / mse.max(1e-12)).log10();
    assert!(psnr > 40.0, "PSNR {psnr:.1} dB");
}

#[test]
fn triangles_sharing_an_edge_leave_no_gap_and_write_no_texel_twice() {
    let dir = tempfile::tempdir().unwrap();
    let input = random_store(dir.path(), 256, 256, PixelFormat::RGB8, 3);
    // A square of integer corners split along its diagonal, spanning four output tiles; one half
    // grid-preserved, the other sampled, so the two halves differ in kind too.
    let (a, b, c, d) = ([200.0, 210.0], [330.0, 210.0], [330.0, 300.0], [200.0, 300.0]);
    let g = GridTransform { offset: [150, 160], ..GridTransform::IDENTITY };
    let inv = |p: [f64; 2]| g.invert(p);
    let faces = [
        FaceMapping {
            dst_sheet: 0,
            dst: [a, b, c],
            src_sheet: 0,
            src: [a, b, c].map(inv),
            exact: Some(g),
        },
        FaceMapping {
            dst_sheet: 0,
            dst: [a, c, d],
            src_sheet: 0,
            src: [[10.0, 10.0], [100.0, 40.0], [20.0, 90.0]],
            exact: None,
        },
    ];
    let out =
        resample_sheets(&[&input], &faces, &[(400, 400)], &opts(dir.path(), 0, false)).unwrap();
    let r = &out.report;
    // Both halves' rings outside the square are painted too (see `paint_rings`).
    assert!(r.texels_ring > 0 && r.texels_ring_sampled > 0, "{r:?}");
    assert_eq!(
        r.texels_written,
        130 * 90 + r.texels_ring + r.texels_ring_sampled,
        "every texel of the square, no gap"
    );
    assert_eq!(r.texels_copied + r.texels_sampled, 130 * 90);
    assert_eq!(r.texels_overdrawn, 0);
    assert!(r.texels_copied > 0 && r.texels_sampled > 0);
}

/// The ring of a resampled face (the texels outside it that bilinear sampling on it reads) holds
/// the input under the face's map extended past its edges, so the face renders as in the input
/// up to its edges; a face too thin for its map to be extended paints no ring.
#[test]
fn the_ring_of_a_resampled_face_continues_its_map() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (200u32, 200u32);
    // A linear ramp, which bilinear sampling reproduces exactly away from the sheet's edges.
    let ramp = |x: f64, y: f64, c: usize| 20.0 + 0.7 * x + 0.3 * y + 10.0 * c as f64;
    let input =
        store_from(dir.path(), w, h, PixelFormat::RGB8, |i, j, c| ramp(i as f64, j as f64, c));
    // Shifted by a quarter texel and turned by 20°: not grid-preserved.
    let (c, s) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
    let dst = [[30.0, 30.0], [110.0, 40.0], [50.0, 120.0]];
    let src = dst.map(|p| [c * p[0] - s * p[1] + 40.25, s * p[0] + c * p[1] + 10.25]);
    // A sliver a tenth of a texel high, mapped onto a wide input triangle.
    let thin_dst = [[140.0, 150.0], [180.0, 150.0], [160.0, 150.1]];
    let thin_src = [[20.0, 150.0], [60.0, 150.0], [40.0, 180.0]];
    let faces = [
        FaceMapping { dst_sheet: 0, dst, src_sheet: 0, src, exact: None },
        FaceMapping { dst_sheet: 0, dst: thin_dst, src_sheet: 0, src: thin_src, exact: None },
    ];
    let out = resample_sheets(&[&input], &faces, &[(w, h)], &opts(dir.path(), 0, false)).unwrap();
    let inside: std::collections::HashSet<(u32, u32)> =
        covered(dst, w, h).into_iter().map(|(i, j, _)| (i, j)).collect();
    let mut ring = 0;
    for j in 0..h {
        for i in 0..w {
            let centre = [i as f64 + 0.5, h as f64 - j as f64 - 0.5];
            let b = crate::geometry::barycentric(dst, centre);
            // Outside the face, but read by bilinear sampling on it: its ring.
            if inside.contains(&(i, j)) || !paint::bilinear_reach(centre, &dst) {
                continue;
            }
            let p = src_point(&src, b);
            let px = out.sheets[0].pixel(i, j);
            for (ch, &v) in px.iter().enumerate() {
                let want = ramp(p[0] - 0.5, h as f64 - p[1] - 0.5, ch);
                assert!((v as f64 - want).abs() <= 1.0, "ring texel ({i}, {j}): {v} for {want}");
            }
            ring += 1;
        }
    }
    assert!(ring > 200, "{ring} ring texels");
    assert_eq!(out.report.texels_ring_sampled, ring as u64, "the thin face paints no ring");
}

/// Random faces over two output sheets, overlapping one another, some grid-preserved.
fn random_faces(
    rng: &mut SplitMix64,
    n: usize,
    inputs: &[(u32, u32)],
    outputs: &[(u32, u32)],
) -> Vec<FaceMapping> {
    (0..n)
        .map(|k| {
            let si = k % inputs.len();
            let so = (k / 2) % outputs.len();
            let (ow, oh) = outputs[so];
            let (iw, ih) = inputs[si];
            let o = [rng.unit() * (ow as f64 - 60.0), rng.unit() * (oh as f64 - 60.0)];
            let dst = [0, 1, 2].map(|_| [o[0] + rng.unit() * 60.0, o[1] + rng.unit() * 60.0]);
            if k % 3 == 0 {
                let g = GridTransform {
                    mirror: rng.next_u64().is_multiple_of(2),
                    quarter_turns: (rng.next_u64() % 4) as u8,
                    offset: [(rng.next_u64() % 50) as i64, (rng.next_u64() % 50) as i64],
                };
                FaceMapping {
                    dst_sheet: so as u32,
                    dst,
                    src_sheet: si as u32,
                    src: dst.map(|p| g.invert(p)),
                    exact: Some(g),
                }
            } else {
                let src = [0, 1, 2].map(|_| [rng.unit() * iw as f64, rng.unit() * ih as f64]);
                FaceMapping { dst_sheet: so as u32, dst, src_sheet: si as u32, src, exact: None }
            }
        })
        .collect()
}

#[test]
fn output_bytes_do_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let ins = [(300u32, 260u32), (128, 128)];
    let outs = [(520u32, 300u32), (257, 513)];
    let inputs: Vec<TileStore> = ins
        .iter()
        .enumerate()
        .map(|(k, &(w, h))| random_store(dir.path(), w, h, PixelFormat::RGBA8, 11 + k as u64))
        .collect();
    let refs: Vec<&TileStore> = inputs.iter().collect();
    let faces = random_faces(&mut SplitMix64::new(5), 300, &ins, &outs);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let out = resample_sheets(&refs, &faces, &outs, &opts(dir.path(), 4, true)).unwrap();
            let mut r = out.report.clone();
            for t in [&mut r.ms_bucket, &mut r.ms_raster, &mut r.ms_dilate, &mut r.ms_push_pull] {
                *t = 0.0;
            }
            (r.ms_total, r.raster_mtexel_per_s, r.mtexel_per_s) = (0.0, 0.0, 0.0);
            (out.sheets.iter().map(bytes).collect::<Vec<_>>(), r)
        })
    };
    let (a, ra) = run(1);
    assert!(ra.texels_overdrawn > 0, "the faces overlap, so write order matters");
    assert_eq!(ra.texels_written + ra.texels_dilated + ra.texels_push_pull, ra.texels_total);
    for k in [2, 3] {
        let (b, rb) = run(k);
        assert!(a == b, "sheets differ between 1 and {k} threads");
        assert_eq!(ra, rb);
    }
}

#[test]
fn push_pull_fills_every_texel_and_keeps_written_ones() {
    let dir = tempfile::tempdir().unwrap();
    // Odd sizes, several tiles: odd pyramid levels and tile seams at every level.
    let (w, h) = (601u32, 283u32);
    for format in [PixelFormat::RGB8, PixelFormat { channels: 4, sample: SampleType::F32 }] {
        let mut store = TileStore::create(dir.path(), w, h, format).unwrap();
        let mut cov = Coverage::for_store(&store);
        let mut written = Vec::new();
        let mut rng = SplitMix64::new(9);
        // Scattered blobs of one colour.
        let colour = [40.0, 200.0, 90.0, 255.0];
        for _ in 0..25 {
            let (cx, cy) = ((rng.unit() * w as f64) as u32, (rng.unit() * h as f64) as u32);
            for y in cy.saturating_sub(3)..(cy + 3).min(h) {
                for x in cx.saturating_sub(5)..(cx + 5).min(w) {
                    pixel::store_pixel(store.pixel_mut(x, y), format, &colour);
                    cov.set(x, y);
                    written.push((x, y));
                }
            }
        }
        let before: Vec<Vec<u8>> =
            written.iter().map(|&(x, y)| store.pixel(x, y).to_vec()).collect();
        let n0 = cov.count();
        let stats = push_pull(&mut store, &mut cov, dir.path()).unwrap();
        assert_eq!(cov.count(), u64::from(w * h), "no texel left unwritten");
        assert_eq!(stats.filled, u64::from(w * h) - n0);
        assert!(stats.levels >= 3 && stats.pyramid_bytes > 0);
        for (&(x, y), b) in written.iter().zip(&before) {
            assert_eq!(store.pixel(x, y), &b[..], "written texel ({x},{y}) unchanged");
        }
        // One colour spreads as itself: nothing black bleeds in anywhere.
        let mut v = [0.0; 4];
        for y in 0..h {
            for x in 0..w {
                pixel::Conv::new(format, format).read(store.pixel(x, y), &mut v);
                for c in 0..format.channels as usize {
                    assert!((v[c] - colour[c]).abs() < 1e-3, "({x},{y}) channel {c}: {}", v[c]);
                }
            }
        }
        // A complete or empty sheet is left alone.
        assert_eq!(push_pull(&mut store, &mut cov, dir.path()).unwrap(), PushPullStats::default());
        let mut empty = TileStore::create(dir.path(), 9, 9, format).unwrap();
        let mut ecov = Coverage::for_store(&empty);
        assert_eq!(push_pull(&mut empty, &mut ecov, dir.path()).unwrap().filled, 0);
    }
}

#[test]
fn push_pull_blends_two_colours_smoothly() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (64u32, 8u32);
    let mut store = TileStore::create(dir.path(), w, h, PixelFormat::RGB8).unwrap();
    let mut cov = Coverage::for_store(&store);
    for y in 0..h {
        store.pixel_mut(0, y).copy_from_slice(&[0, 0, 0]);
        store.pixel_mut(w - 1, y).copy_from_slice(&[250, 0, 0]);
        cov.set(0, y);
        cov.set(w - 1, y);
    }
    push_pull(&mut store, &mut cov, dir.path()).unwrap();
    // Between a dark and a red border the fill rises monotonically along each row.
    for y in 0..h {
        let row: Vec<u8> = (0..w).map(|x| store.pixel(x, y)[0]).collect();
        assert!(row.windows(2).all(|p| p[0] <= p[1]), "row {y}: {row:?}");
        assert!(row[w as usize / 2] > 60 && row[w as usize / 2] < 190, "{row:?}");
    }
}

#[test]
fn several_input_and_output_sheets_take_texels_from_the_right_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let sizes = [(100u32, 80u32), (300, 270), (64, 200)];
    let inputs: Vec<TileStore> = sizes
        .iter()
        .enumerate()
        .map(|(k, &(w, h))| random_store(dir.path(), w, h, PixelFormat::RGB8, 100 + k as u64))
        .collect();
    let refs: Vec<&TileStore> = inputs.iter().collect();
    let outs = [(280u32, 300u32), (128, 96)];
    let mut faces = Vec::new();
    // Each input sheet's lower-left block goes to a different place of a different output.
    for (k, &(w, h)) in sizes.iter().enumerate() {
        let (bw, bh) = ((w.min(60)) as f64, (h.min(60)) as f64);
        let so = k % 2;
        let offset = [[10, 10], [70, 80], [200, 200]][k];
        let g = GridTransform { mirror: k == 1, quarter_turns: [0, 1, 2][k], offset };
        let quad = [[0.0, 0.0], [bw, 0.0], [bw, bh], [0.0, bh]];
        for tri in [[0, 1, 2], [0, 2, 3]] {
            let src = tri.map(|c| quad[c]);
            let dst = src.map(|p| g.apply(p));
            faces.push(FaceMapping {
                dst_sheet: so as u32,
                dst,
                src_sheet: k as u32,
                src,
                exact: Some(g),
            });
        }
    }
    let out = resample_sheets(&refs, &faces, &outs, &opts(dir.path(), 2, true)).unwrap();
    assert_eq!(out.sheets.len(), 2);
    assert_eq!((out.sheets[1].width(), out.sheets[1].height()), (128, 96));
    assert_eq!(out.report.texels_sampled, 0);
    let mut checked = 0u64;
    for f in &faces {
        let (ow, oh) = outs[f.dst_sheet as usize];
        let input = &inputs[f.src_sheet as usize];
        let g = f.exact.unwrap();
        for (i, j, _) in covered(f.dst, ow, oh) {
            let (x, y) = g.source_pixel(i, j, oh, input.width(), input.height()).unwrap();
            assert_eq!(out.sheets[f.dst_sheet as usize].pixel(i, j), input.pixel(x, y));
            checked += 1;
        }
    }
    assert_eq!(checked, out.report.texels_copied);
    assert_eq!(out.report.texels_total, 280 * 300 + 128 * 96);
    assert_eq!(
        out.report.texels_written + out.report.texels_dilated + out.report.texels_push_pull,
        out.report.texels_total
    );
}

#[test]
fn inputs_of_another_format_are_converted_to_the_first_ones() {
    let dir = tempfile::tempdir().unwrap();
    let a =
        store_from(dir.path(), 32, 32, PixelFormat::RGBA8, |_, _, c| [10.0, 20.0, 30.0, 40.0][c]);
    let b = store_from(
        dir.path(),
        32,
        32,
        PixelFormat { channels: 1, sample: SampleType::U16 },
        |_, _, _| 257.0 * 77.0,
    );
    let tri = [[0.0, 0.0], [32.0, 0.0], [0.0, 32.0]];
    let faces = [
        FaceMapping {
            dst_sheet: 0,
            dst: tri,
            src_sheet: 0,
            src: tri,
            exact: Some(GridTransform::IDENTITY),
        },
        FaceMapping {
            dst_sheet: 1,
            dst: tri,
            src_sheet: 1,
            src: tri,
            exact: Some(GridTransform::IDENTITY),
        },
    ];
    let out =
        resample_sheets(&[&a, &b], &faces, &[(32, 32), (32, 32)], &opts(dir.path(), 0, false))
            .unwrap();
    assert_eq!(out.report.converted_inputs, 1);
    assert_eq!(out.sheets[1].format(), PixelFormat::RGBA8);
    assert_eq!(out.sheets[0].pixel(1, 30), &[10, 20, 30, 40]);
    assert_eq!(out.sheets[1].pixel(1, 30), &[77, 77, 77, 255], "gray to RGB, opaque");
}

#[test]
fn bad_mappings_and_options_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let input = random_store(dir.path(), 16, 16, PixelFormat::RGB8, 1);
    let tri = [[0.0, 0.0], [8.0, 0.0], [0.0, 8.0]];
    let good = FaceMapping { dst_sheet: 0, dst: tri, src_sheet: 0, src: tri, exact: None };
    let o = opts(dir.path(), 4, true);
    let run = |faces: &[FaceMapping], sizes: &[(u32, u32)], o: &ResampleOptions| {
        resample_sheets(&[&input], faces, sizes, o)
    };
    assert!(run(&[good], &[(16, 16)], &o).is_ok());
    assert!(resample_sheets(&[], &[], &[(16, 16)], &o).is_err(), "no input");
    assert!(run(&[FaceMapping { dst_sheet: 1, ..good }], &[(16, 16)], &o).is_err());
    assert!(run(&[FaceMapping { src_sheet: 1, ..good }], &[(16, 16)], &o).is_err());
    let nan = [[f64::NAN, 0.0], [8.0, 0.0], [0.0, 8.0]];
    assert!(run(&[FaceMapping { src: nan, ..good }], &[(16, 16)], &o).is_err());
    assert!(run(&[FaceMapping { dst: nan, ..good }], &[(16, 16)], &o).is_err());
    assert!(run(&[good], &[(0, 16)], &o).is_err(), "zero-sized output");
    assert!(run(&[good], &[(16, 16)], &opts(dir.path(), MAX_RADIUS + 1, true)).is_err());
    // Faces outside the output sheet or far outside the input are harmless.
    let far = [[-50.0, -50.0], [-40.0, -50.0], [-50.0, -40.0]];
    let out = run(&[FaceMapping { dst: far, src: far, ..good }], &[(16, 16)], &o).unwrap();
    assert_eq!((out.report.texels_written, out.report.empty_sheets), (0, 1));
}

#[test]
fn bilinear_sampling_of_a_grid_preserved_face_reads_only_input_texels() {
    let dir = tempfile::tempdir().unwrap();
    let format = PixelFormat::RGBA8;
    let (sw, sh, ow, oh) = (300, 280, 330, 320);
    let input = random_store(dir.path(), sw, sh, format, 11);
    let src = [[3.25, 4.0], [290.5, 17.75], [40.0, 271.125]];
    for (mirror, k) in [(false, 0u8), (true, 1), (false, 3)] {
        let g = placed_inside(mirror, k, &src);
        let dst = src.map(|p| g.apply(p));
        let face = FaceMapping { dst_sheet: 0, dst, src_sheet: 0, src, exact: Some(g) };
        let out =
            resample_sheets(&[&input], &[face], &[(ow, oh)], &opts(dir.path(), 3, true)).unwrap();
        assert!(out.report.texels_ring > 100, "{:?}", out.report);
        // Every texel that bilinear sampling at points inside the face reads (brute force over
        // a dense grid of interior points) is the input's texel under the grid map.
        let sheet = &out.sheets[0];
        let n = 400;
        for a in 1..n {
            for b in 1..n - a {
                let (u, v) = ((a as f64 + 0.37) / n as f64, (b as f64 + 0.21) / n as f64);
                let w = [1.0 - u - v, u, v];
                if w[0] <= 0.0 {
                    continue;
                }
                let p = [0, 1].map(|c| w[0] * dst[0][c] + w[1] * dst[1][c] + w[2] * dst[2][c]);
                let x = (p[0] - 0.5).floor() as u32;
                let y = (f64::from(oh) - p[1] - 0.5).floor() as u32;
                for (i, j) in [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)] {
                    let (si, sj) = g.source_pixel(i, j, oh, sw, sh).unwrap();
                    assert_eq!(sheet.pixel(i, j), input.pixel(si, sj), "{g:?} ({i},{j})");
                }
            }
        }
    }
}
