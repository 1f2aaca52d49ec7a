//! Throughput of texture resampling (Mtexel/s): grid-preserved verbatim copy and bilinear
//! sampling of a fully covered 2048² RGBA8 sheet, next to a plain copy of the same tile bytes as
//! the memory-bandwidth baseline.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rayon::prelude::*;
use scanatlas_core::geometry::GridTransform;
use scanatlas_core::texture::resample::{FaceMapping, ResampleOptions, resample_sheets};
use scanatlas_core::texture::{PixelFormat, TileStore};

const SIZE: u32 = 2048;
const CELL: u32 = 32;

/// An input sheet of pseudo-random bytes (a fixed xorshift sequence, so runs compare).
fn input(dir: &std::path::Path) -> TileStore {
    let mut s = TileStore::create(dir, SIZE, SIZE, PixelFormat::RGBA8).unwrap();
    let mut rng = scanatlas_core::rng::XorShift64(0x2545_F491_4F6C_DD1D);
    let mut row = vec![0u8; SIZE as usize * 4];
    for y in 0..SIZE {
        for b in row.iter_mut() {
            *b = rng.next_u64() as u8;
        }
        s.write_row(y, 0, &row);
    }
    s
}

/// Two triangles per `CELL²` square covering the whole output sheet, their sources given by
/// `src_of` and their grid transform by `exact`.
fn faces(src_of: impl Fn([f64; 2]) -> [f64; 2], exact: Option<GridTransform>) -> Vec<FaceMapping> {
    let mut v = Vec::new();
    let c = f64::from(CELL);
    for y in 0..SIZE / CELL {
        for x in 0..SIZE / CELL {
            let (x0, y0) = (f64::from(x) * c, f64::from(y) * c);
            let q = [[x0, y0], [x0 + c, y0], [x0 + c, y0 + c], [x0, y0 + c]];
            for t in [[0, 1, 2], [0, 2, 3]] {
                let dst = t.map(|k| q[k]);
                v.push(FaceMapping {
                    dst_sheet: 0,
                    dst,
                    src_sheet: 0,
                    src: dst.map(&src_of),
                    exact,
                });
            }
        }
    }
    v
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let src = input(dir.path());
    let opts = ResampleOptions {
        dilate: 0,
        push_pull: false,
        work_dir: dir.path().to_path_buf(),
        normals: false,
    };
    // A quarter turn onto the same square: every texel copied verbatim.
    let turn = GridTransform { mirror: false, quarter_turns: 1, offset: [i64::from(SIZE), 0] };
    let exact = faces(|p| turn.invert(p), Some(turn));
    // The identity: every input row copied as runs of bytes.
    let same = faces(|p| p, Some(GridTransform::IDENTITY));
    // A slight rotation and shrink: every texel interpolated from four taps.
    let (co, si) = (0.99 * 1f64.to_radians().cos(), 0.99 * 1f64.to_radians().sin());
    let sampled = faces(|p| [co * p[0] - si * p[1] + 30.0, si * p[0] + co * p[1] + 5.0], None);

    // One run of each configuration first, so the stage timings of the report can be read
    // beside criterion's figures.
    for (name, f, o) in [
        ("grid_preserved_copy", &exact, &opts),
        ("grid_preserved_copy_unturned", &same, &opts),
        ("bilinear_sample", &sampled, &opts),
    ] {
        let r = resample_sheets(&[&src], f, &[(SIZE, SIZE)], o).unwrap().report;
        eprintln!(
            "{name}: bucket {:.1} ms, raster {:.1} ms ({:.1} Mtexel/s), dilate {:.1} ms, \
             push-pull {:.1} ms, total {:.1} ms",
            r.ms_bucket,
            r.ms_raster,
            r.raster_mtexel_per_s,
            r.ms_dilate,
            r.ms_push_pull,
            r.ms_total
        );
    }
    let mut g = c.benchmark_group("resample_2048_rgba8");
    g.throughput(Throughput::Elements(u64::from(SIZE) * u64::from(SIZE)));
    g.sample_size(10);
    let mut dst = TileStore::create(dir.path(), SIZE, SIZE, PixelFormat::RGBA8).unwrap();
    g.bench_function("memcpy_tiles_existing_store", |b| {
        b.iter(|| {
            dst.par_tiles_mut().for_each(|(tx, ty, t)| t.copy_from_slice(src.tile(tx, ty)));
            black_box(&dst);
        })
    });
    g.bench_function("memcpy_tiles_new_store", |b| {
        b.iter(|| {
            let mut d = TileStore::create(dir.path(), SIZE, SIZE, PixelFormat::RGBA8).unwrap();
            d.par_tiles_mut().for_each(|(tx, ty, t)| t.copy_from_slice(src.tile(tx, ty)));
            black_box(d)
        })
    });
    g.bench_function("grid_preserved_copy", |b| {
        b.iter(|| black_box(resample_sheets(&[&src], &exact, &[(SIZE, SIZE)], &opts).unwrap()))
    });
    g.bench_function("grid_preserved_copy_unturned", |b| {
        b.iter(|| black_box(resample_sheets(&[&src], &same, &[(SIZE, SIZE)], &opts).unwrap()))
    });
    g.bench_function("bilinear_sample", |b| {
        b.iter(|| black_box(resample_sheets(&[&src], &sampled, &[(SIZE, SIZE)], &opts).unwrap()))
    });
    // Gutters on a half-covered sheet: dilation by 4 and push-pull of the rest.
    let half: Vec<FaceMapping> = exact.iter().copied().step_by(2).collect();
    let gutter = ResampleOptions { dilate: 4, push_pull: true, ..opts.clone() };
    g.bench_function("half_covered_copy_dilate4_push_pull", |b| {
        b.iter(|| black_box(resample_sheets(&[&src], &half, &[(SIZE, SIZE)], &gutter).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
