//! One simulation step (forces + integration) per model (all four, plus the
//! shape-matching and Debunne variants), at the paper's smallest and
//! largest cube sizes (639 and 10932 target nodes), on one thread and on all threads.
//!
//! The cube starts stretched by 10% so that shape matching's rotation extraction does real
//! work (at rest it exits after one iteration).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use needlesim::{Backend, CpuBackend, Scene, Threading, Tissue};
use std::path::Path;

const MODELS: [(&str, &str); 6] = [
    (
        "msm",
        "model = \"mass_spring\"\nstiffness = 100.0\nspring_damping = 0.01",
    ),
    ("lshm", "model = \"local_shape_matching\"\nstiffness = 20.0"),
    (
        "lshm-cluster",
        "model = \"local_shape_matching\"\nstiffness = 20.0\nforces = \"cluster\"",
    ),
    (
        "deb",
        "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.45",
    ),
    (
        "deb-corotated",
        "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.45\ncorotated = true",
    ),
    (
        "pba",
        "model = \"point_based\"\nyoung_modulus = 1e4\npoisson_ratio = 0.45",
    ),
];

fn scene(material: &str, nodes: usize) -> Scene {
    let text = format!(
        "[tissue]\nneighbours = 16\ngeometry = {{ kind = \"box\", min = [0, 0, 0], max = [0.1, 0.1, 0.1], nodes = {nodes} }}\n\
         [material]\n{material}\n[physics]\ndt = 1e-4\ndamping = 20.0\n[initial]\nstretch = [1.1, 1.0, 1.0]\n"
    );
    Scene::from_toml_str(&text, Path::new(".")).unwrap()
}

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    group.sample_size(20);
    for (label, material) in MODELS {
        for nodes in [639usize, 10932] {
            let s = scene(material, nodes);
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
