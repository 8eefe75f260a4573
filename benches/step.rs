//! One simulation step (forces + integration) per model (all four, plus the
//! shape-matching and Debunne variants), at the paper's smallest and
//! largest cube sizes (639 and 10932 target nodes), on one thread and on all threads.
//!
//! The cube starts stretched by 10% so that shape matching's rotation extraction does real
//! work (at rest it exits after one iteration).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use needlesim::{Backend, CpuBackend, Threading, Tissue};

mod common;
use common::{cube, MODELS};

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    group.sample_size(20);
    for (label, material) in MODELS {
        for nodes in [639usize, 10932] {
            let s = cube(material, nodes, 1e-4, 1.1);
            let tissue = Tissue::from_scene(&s).unwrap();
            group.throughput(Throughput::Elements(tissue.n_mesh as u64));
            for (threads, threading) in [("1", Threading::Single), ("all", Threading::Parallel)] {
                let mut b = CpuBackend::new(tissue.clone(), threading).unwrap();
                let id = BenchmarkId::new(format!("{label}/threads-{threads}"), nodes);
                group.bench_function(id, |bench| bench.iter(|| b.step(1)));
                b.check_finite().expect("bench scene stays finite");
            }
        }
    }
    group.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);
