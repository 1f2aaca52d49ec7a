//! The `arap` local solver (as-rigid-as-possible against the original UV triangles) on disk
//! patches of about 1k, 10k and 100k vertices: a triangulated grid disk with its boundary ring
//! fixed, started from the regular grid, with slightly distorted targets (vertices per second);
//! plain local/global steps (`anderson = 0`) against the default Anderson-accelerated ones.

use std::hint::black_box;
use std::time::Duration;

use criterion::{
    BatchSize, BenchmarkId, Criterion, SamplingMode, Throughput, criterion_group, criterion_main,
};
use scanatlas_benches::disk_problem;
use scanatlas_core::geometry::mean_isometric_energy;
use scanatlas_core::plugin::LocalSolver;
use scanatlas_plugins::solvers::{ArapParams, ArapSolver};

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("arap_disk");
    g.sampling_mode(SamplingMode::Flat);
    g.sample_size(10);
    g.warm_up_time(Duration::from_secs(1));
    g.measurement_time(Duration::from_secs(10));
    for (label, anderson) in [("plain", 0), ("anderson", ArapParams::default().anderson)] {
        let mut solver = ArapSolver::new(ArapParams { anderson, ..ArapParams::default() });
        sizes(&mut g, label, &mut solver);
    }
    g.finish();
}

fn sizes(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    label: &str,
    solver: &mut ArapSolver,
) {
    for size in [1_000, 10_000, 100_000] {
        let problem = disk_problem(size);
        let n = problem.uv.len();
        // One solve first, for the iteration count and the energies.
        let mut p = problem.clone();
        let rep = solver.solve(&mut p).unwrap();
        eprintln!(
            "{label}, disk {size}: {n} vertices ({} fixed), {} triangles, {} iterations, energy {:.6} -> \
             {:.6} (check {:.6})",
            problem.fixed.iter().filter(|&&f| f).count(),
            problem.triangles.len(),
            rep.iterations,
            rep.energy_before,
            rep.energy_after,
            mean_isometric_energy(&p.triangles, &p.uv, &p.targets)
        );
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new(label, size), &problem, |b, problem| {
            b.iter_batched(
                || problem.clone(),
                |mut p| {
                    let rep = solver.solve(&mut p).unwrap();
                    black_box((rep, p))
                },
                BatchSize::LargeInput,
            )
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
