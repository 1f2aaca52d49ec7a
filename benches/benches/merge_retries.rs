//! The serial merge stage on a small synthetic terrain scan (the parameters are below), a shape
//! whose merge refuses attempts for overlaps: the cost of the attempts an operation makes again
//! after a refusal, whose solves the engine keeps (see `defrag::attempt::memo`). Small enough to
//! compare two builds of the engine.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use scanatlas_benches::{registry, scorer, solvers};
use scanatlas_core::defrag::{MergeOptions, merge_charts_parallel};
use scanatlas_core::synth::{self, Shape, SynthParams};
use scanatlas_core::topology::Topology;

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let params = SynthParams {
        shape: Shape::Terrain,
        faces: 30_000,
        cameras: 24,
        sheets: 2,
        sheet_size: 1024,
        seed: 3,
        ..SynthParams::default()
    };
    let out = synth::generate(&params, dir.path()).expect("synthetic scan");
    let sizes: Vec<Option<(u32, u32)>> = out.model.sheets.iter().map(|s| s.size).collect();
    let topo = Topology::build(&out.model, &sizes).expect("topology");
    let r = registry();
    let scorer = scorer(&r);
    let serial = MergeOptions { speculate: false, ..MergeOptions::default() };

    // One run first, so the merge report can be read beside criterion's figures.
    let mut t = topo.clone();
    let start = Instant::now();
    let (rep, _) = merge_charts_parallel(&mut t, scorer.as_ref(), solvers(&r, 1), &serial).unwrap();
    eprintln!(
        "serial: {:.2} s, charts {} -> {}, {} of {} attempts accepted, {} solver iterations",
        start.elapsed().as_secs_f64(),
        rep.charts_before,
        rep.charts_after,
        rep.accepted,
        rep.attempted,
        rep.solver_iterations
    );

    let mut g = c.benchmark_group("merge_retries_30k_faces");
    g.sampling_mode(SamplingMode::Flat);
    g.sample_size(10);
    g.warm_up_time(Duration::from_secs(1));
    g.measurement_time(Duration::from_secs(30));
    g.throughput(Throughput::Elements(out.model.faces.len() as u64));
    g.bench_function("serial", |b| {
        b.iter_batched(
            || (topo.clone(), solvers(&r, 1)),
            |(mut t, s)| {
                let out = merge_charts_parallel(&mut t, scorer.as_ref(), s, &serial).unwrap();
                black_box((out, t))
            },
            BatchSize::PerIteration,
        )
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
