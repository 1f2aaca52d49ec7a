//! Model parsing throughput (MB/s of model files read): OBJ+MTL and glTF+bin files of a synthetic
//! 200k-face scan written by the project's own writers into a temporary folder, read
//! back by `scanatlas_core::io::read_model` (the page cache is warm; images are never read, which
//! is why GLB, whose file embeds the sheets, is left out: its MB/s would count image bytes).

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use scanatlas_benches::{model_bytes, scan_params, write_scan};
use scanatlas_core::io::read_model;

const FACES: u32 = 200_000;

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let paths = write_scan(&scan_params(FACES, 2048, 1), dir.path(), &["obj", "gltf"]);
    let mut g = c.benchmark_group("parse_200k_faces");
    g.sample_size(20);
    g.sampling_mode(criterion::SamplingMode::Flat);
    g.warm_up_time(Duration::from_secs(1));
    g.measurement_time(Duration::from_secs(10));
    for path in &paths {
        let bytes = model_bytes(path);
        let m = read_model(path).unwrap();
        let ext = path.extension().unwrap().to_str().unwrap();
        eprintln!("{ext}: {:.1} MB, {} faces", bytes as f64 / 1e6, m.faces.len());
        g.throughput(Throughput::Bytes(bytes));
        g.bench_function(ext, |b| b.iter(|| black_box(read_model(black_box(path)).unwrap())));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
