//! The merge stage (greedy chart merges with the `paper` scorer and the `arap` solver) on a
//! synthetic photogrammetry-like scan of about 200k faces: the serial baseline (one queue for the
//! whole atlas, one thread) against the default (the same queue with a second engine judging
//! ahead; the same result) and the cluster-parallel scheduler (clusters of 65,536 faces, one
//! solver per worker thread), each starting from a fresh copy of the same prepared topology.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use scanatlas_benches::{registry, scan_params, scan_topology, scorer, solvers};
use scanatlas_core::defrag::{MergeOptions, merge_charts_parallel};

const FACES: u32 = 200_000;

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let t = Instant::now();
    let (model, topo) = scan_topology(&scan_params(FACES, 4096, 2), dir.path());
    eprintln!(
        "synthetic scan: {} faces, {} charts, set-up {:.1} s",
        model.faces.len(),
        topo.charts.len(),
        t.elapsed().as_secs_f64()
    );
    let r = registry();
    let scorer = scorer(&r);
    let threads = rayon::current_num_threads();
    let serial = MergeOptions { speculate: false, ..MergeOptions::default() };
    let ahead = MergeOptions::default();
    let clusters = MergeOptions { cluster_faces: 65_536, ..MergeOptions::default() };
    let configs =
        [("serial", &serial, 1), ("ahead", &ahead, threads), ("clusters", &clusters, threads)];

    // One run of each first, so the merge report can be read beside criterion's figures.
    for (name, opts, n) in configs {
        let mut t = topo.clone();
        let start = Instant::now();
        let (rep, _) =
            merge_charts_parallel(&mut t, scorer.as_ref(), solvers(&r, n), opts).unwrap();
        eprintln!(
            "{name} ({n} solver(s), {threads} threads): {:.2} s, charts {} -> {}, {} of {} \
             attempts accepted, {} rounds",
            start.elapsed().as_secs_f64(),
            rep.charts_before,
            rep.charts_after,
            rep.accepted,
            rep.attempted,
            rep.rounds.len()
        );
    }

    let mut g = c.benchmark_group("merge_200k_faces");
    g.sampling_mode(SamplingMode::Flat);
    g.sample_size(10);
    g.warm_up_time(Duration::from_secs(1));
    g.measurement_time(Duration::from_secs(60));
    g.throughput(Throughput::Elements(model.faces.len() as u64));
    for (name, opts, n) in configs {
        g.bench_function(name, |b| {
            b.iter_batched(
                || (topo.clone(), solvers(&r, n)),
                |(mut t, s)| {
                    let out = merge_charts_parallel(&mut t, scorer.as_ref(), s, opts).unwrap();
                    black_box((out, t))
                },
                BatchSize::PerIteration,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
