//! One step per model on every backend: one CPU thread, all CPU threads, and the GPU
//! (steps recorded in batches without readback, and one step per submit followed by a
//! needle-sized readback of 32 positions, as a haptic loop would do).
//!
//! Sizes: `NEEDLESIM_BENCH_SIZES` (comma-separated target node counts, default
//! `639,10932`); the full set is `639,10932,100000,1000000` (building the 1M cube
//! takes about a minute on 2 cores). Models: `NEEDLESIM_BENCH_MODELS` (default all).
//!
//! After the group, a table of GPU time per kernel (timestamp queries, where the device
//! has them) over [`PROFILED_STEPS`] batched steps of each model and size, run apart from
//! the timed benches.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use needlesim::gpu::{GpuBackend, KernelTime};
use needlesim::{Backend, CpuBackend, NodeField, Threading, Tissue};
use std::time::Instant;

mod common;
use common::{cube, MODELS};

/// Steps of the profiled run per model and size.
const PROFILED_STEPS: u64 = 200;

/// The summary rows: model, nodes, and the kernel times (or why there are none).
type Profile = (&'static str, usize, Result<Vec<KernelTime>, String>);

/// [`PROFILED_STEPS`] batched steps of `g` with kernel timing on.
fn profile(g: &mut GpuBackend) -> Result<Vec<KernelTime>, String> {
    g.enable_profiling(true).map_err(|e| e.to_string())?;
    g.reset_kernel_times();
    g.step(PROFILED_STEPS);
    let times = g.kernel_times().map_err(|e| e.to_string());
    g.enable_profiling(false).map_err(|e| e.to_string())?;
    times
}

fn print_profiles(rows: &[Profile]) {
    if rows.is_empty() {
        return;
    }
    eprintln!("\nGPU time per kernel, {PROFILED_STEPS} batched steps (timestamp queries):");
    eprintln!(
        "{:<14} {:>8}  {:<36} {:>10} {:>10} {:>10}",
        "model", "nodes", "kernel", "dispatches", "total ms", "mean ms"
    );
    for (label, nodes, times) in rows {
        match times {
            Ok(times) => {
                for t in times {
                    eprintln!(
                        "{label:<14} {nodes:>8}  {:<36} {:>10} {:>10.3} {:>10.4}",
                        t.name, t.dispatches, t.total_ms, t.mean_ms
                    );
                }
                let sum: f64 = times.iter().map(|t| t.total_ms).sum();
                eprintln!(
                    "{label:<14} {nodes:>8}  {:<36} {:>10} {:>10.3} {:>10.4}",
                    "(per step)",
                    "",
                    sum,
                    sum / PROFILED_STEPS as f64
                );
            }
            Err(e) => eprintln!("{label:<14} {nodes:>8}  no kernel times: {e}"),
        }
    }
}

fn env_list(name: &str) -> Option<Vec<String>> {
    std::env::var(name)
        .ok()
        .map(|s| s.split(',').map(|x| x.trim().to_string()).collect())
}

fn backends(c: &mut Criterion) {
    let sizes: Vec<usize> = env_list("NEEDLESIM_BENCH_SIZES")
        .map(|v| v.iter().map(|x| x.parse().expect("node count")).collect())
        .unwrap_or(vec![639, 10932]);
    let models = env_list("NEEDLESIM_BENCH_MODELS");
    let mut group = c.benchmark_group("backends");
    group.sample_size(10);
    let mut profiles: Vec<Profile> = Vec::new();
    for (label, material) in MODELS {
        if models
            .as_ref()
            .is_some_and(|m| !m.iter().any(|x| x == label))
        {
            continue;
        }
        for &nodes in &sizes {
            let tissue = Tissue::from_scene(&cube(material, nodes, 1e-5, 1.01)).unwrap();
            group.throughput(Throughput::Elements(tissue.n_mesh as u64));
            for (name, threading) in [
                ("cpu-1", Threading::Single),
                ("cpu-all", Threading::Parallel),
            ] {
                let mut b = CpuBackend::new(tissue.clone(), threading).unwrap();
                group.bench_function(
                    BenchmarkId::new(format!("{label}/{name}"), nodes),
                    |bench| bench.iter(|| b.step(1)),
                );
            }
            let mut g = match GpuBackend::new(&tissue) {
                Ok(g) => g,
                Err(e) => {
                    eprintln!("GPU benches skipped: {e}");
                    continue;
                }
            };
            eprintln!("GPU: {}", g.adapter());
            group.bench_function(
                BenchmarkId::new(format!("{label}/gpu-batched"), nodes),
                |bench| {
                    bench.iter_custom(|iters| {
                        let t = Instant::now();
                        g.step(iters);
                        g.finish();
                        t.elapsed()
                    })
                },
            );
            let mut needle = vec![[0.0f32; 4]; 32];
            group.bench_function(
                BenchmarkId::new(format!("{label}/gpu-step-readback"), nodes),
                |bench| {
                    bench.iter(|| {
                        g.step(1);
                        g.read(NodeField::Position, 0..32, &mut needle).unwrap();
                    })
                },
            );
            profiles.push((label, nodes, profile(&mut g)));
            g.check_finite().expect("bench scene stays finite");
        }
    }
    group.finish();
    print_profiles(&profiles);
}

criterion_group!(benches, backends);
criterion_main!(benches);
