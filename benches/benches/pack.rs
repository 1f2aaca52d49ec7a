//! The `horizon` packer (the paper's upper-and-inner-horizon packer on exact footprints) next to
//! the `skyline` packer (bottom-left skyline on bounding boxes) on 10,000 mixed chart footprints
//! (99 % up to 60 cells a side, 1 % up to 600) on 8192² sheets (charts per second); and `horizon`
//! alone on 60 charts of a small scan on a 4096² sheet, where it also tries seeded shuffled
//! orders.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use scanatlas_benches::{density, filled, mixed_charts, random_items, registry};
use scanatlas_core::plugin::{Params, check_packing};

const CHARTS: usize = 10_000;
const SHEET: (u32, u32) = (8192, 8192);

fn bench(c: &mut Criterion) {
    let r = registry();
    let items = mixed_charts(CHARTS);
    let mut g = c.benchmark_group("pack_10k_mixed_charts");
    g.sampling_mode(SamplingMode::Flat);
    g.sample_size(10);
    g.warm_up_time(Duration::from_secs(1));
    g.measurement_time(Duration::from_secs(45));
    g.throughput(Throughput::Elements(CHARTS as u64));
    for name in ["horizon", "skyline"] {
        let packer = r.packer(name, &Params::new()).unwrap();
        // One checked run first, for the result's quality.
        let t = Instant::now();
        let out = packer.pack(&items, SHEET).unwrap();
        let secs = t.elapsed().as_secs_f64();
        check_packing(&items, SHEET, &out).unwrap();
        eprintln!(
            "{name}: {:.2} s, {} sheets; footprint cells / trimmed sheet area {:.3}, bounding \
             boxes / trimmed sheet area {:.3}",
            secs,
            out.sheets.len(),
            density(&items, &out),
            density(&filled(&items), &out)
        );
        g.bench_function(name, |b| b.iter(|| black_box(packer.pack(black_box(&items), SHEET))));
    }
    g.finish();
}

/// A small scan's atlas: few enough charts that the shuffled orders run.
fn bench_few(c: &mut Criterion) {
    let r = registry();
    let mut items = random_items(21, 55, 120);
    items.extend(random_items(22, 5, 900));
    let mut g = c.benchmark_group("pack_60_charts");
    g.sample_size(20);
    g.measurement_time(Duration::from_secs(20));
    let packer = r.packer("horizon", &Params::new()).unwrap();
    let out = packer.pack(&items, (4096, 4096)).unwrap();
    check_packing(&items, (4096, 4096), &out).unwrap();
    g.bench_function("horizon", |b| {
        b.iter(|| black_box(packer.pack(black_box(&items), (4096, 4096))))
    });
    g.finish();
}

criterion_group!(benches, bench, bench_few);
criterion_main!(benches);
