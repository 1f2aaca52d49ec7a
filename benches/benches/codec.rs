//! Throughput of the texture codecs alone (Mtexel/s): encoding a 2048² RGB8 sheet to PNG, JPEG,
//! TIFF and OpenEXR, and decoding each file back into a tile store. This is the ceiling of the
//! texture stage: a run decodes every input sheet once and encodes every output sheet once.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use scanatlas_core::model::ImageSource;
use scanatlas_core::rng::{hash3, unit_f64};
use scanatlas_core::texture::decode::decode_to_store;
use scanatlas_core::texture::encode::{EncodeOptions, write_image};
use scanatlas_core::texture::{ImageFormat, PixelFormat, TileStore};

const SIZE: u32 = 2048;

/// A sheet that compresses like a photograph rather than like noise or a flat colour: smooth
/// gradients with a few texels of grain (a fixed hash, so runs compare).
fn sheet(dir: &Path) -> TileStore {
    let mut s = TileStore::create(dir, SIZE, SIZE, PixelFormat::RGB8).unwrap();
    let mut row = vec![0u8; SIZE as usize * 3];
    for y in 0..SIZE {
        for x in 0..SIZE {
            let grain = unit_f64(hash3(7, u64::from(x), u64::from(y))) * 24.0;
            let (fx, fy) = (f64::from(x) / f64::from(SIZE), f64::from(y) / f64::from(SIZE));
            let base = [160.0 * fx + 40.0, 120.0 * fy + 60.0, 90.0 * (fx * fy) + 80.0];
            for (c, b) in base.iter().enumerate() {
                row[x as usize * 3 + c] = (b + grain) as u8;
            }
        }
        s.write_row(y, 0, &row);
    }
    s
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let src = sheet(dir.path());
    let formats = [
        ("png", ImageFormat::Png),
        ("jpeg", ImageFormat::Jpeg),
        ("tiff", ImageFormat::Tiff),
        ("exr", ImageFormat::Exr),
    ];
    let mut g = c.benchmark_group("codec_2048_rgb8");
    g.sampling_mode(SamplingMode::Flat);
    g.sample_size(10);
    g.throughput(Throughput::Elements(u64::from(SIZE) * u64::from(SIZE)));
    for (name, format) in formats {
        let path = dir.path().join(format!("sheet.{name}"));
        let opts = EncodeOptions { format: Some(format), ..EncodeOptions::default() };
        g.bench_function(format!("encode_{name}"), |b| {
            b.iter(|| write_image(black_box(&src), &path, &opts).unwrap())
        });
        let file = ImageSource::File(path.clone());
        g.bench_function(format!("decode_{name}"), |b| {
            b.iter(|| black_box(decode_to_store(&file, dir.path()).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
