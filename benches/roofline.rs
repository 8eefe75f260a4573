//! The roofline of the CPU step: the machine's limits measured in the same run, then every
//! model's step against them.
//!
//! - Memory bandwidth: a STREAM triad `a[i] = b[i] + s c[i]` over three f32 arrays of
//!   64 MiB each (far beyond any last-level cache), on one thread and on all threads,
//!   best of 5; it moves 12 bytes per element (the write-allocate of `a` not counted, as
//!   STREAM counts).
//! - Peak f32 throughput: 12 independent multiply-add chains of 4 lanes (12 of SSE2's 16
//!   vector registers, enough chains to cover the multiply and add latencies), on one
//!   thread and on all threads; 2 flops per multiply and add. The default x86-64 target
//!   has SSE2, not FMA or AVX: this is the peak the shipped build can reach, not the
//!   chip's. (The first version ran 16 chains of 8 lanes, 32 registers' worth: they
//!   spilled to memory and it measured 11.9 GFLOP/s on the dev machine where 12 x 4
//!   reaches 60.)
//! - Each model's step (forces + integration) at `NEEDLESIM_ROOFLINE_NODES` target nodes
//!   (default 100000; a free stretched cube, K = 16, as the other benches), median of 20
//!   steps on one thread, and its compulsory memory traffic per node-step: every array
//!   of the step read once (neighbour rows, shape information), the positions and
//!   velocities read twice (forces, integration) and written once, the forces written
//!   once and read once; the gathers of neighbours' positions are taken to hit the cache
//!   (lattice order keeps them close). The table gives that traffic over the step time
//!   against the triad's bandwidth: a kernel near 100% is bound by memory, one far below
//!   by its arithmetic (the rotation extractions, the continuum models' 3x3 products) or
//!   by latency.
//! - Flops per node-step ([`flops_per_node_step`]), counted by hand from the CPU kernels
//!   (a multiply, an add, a division or a square root is one flop; the four-lane loops
//!   count every slot of a row, the scalar ones the live slots), against the peak. The
//!   counts are within about 10%; the shape matching frames count the rotation
//!   extraction's full iteration budget, which a converged frame cuts short.
//!
//! - The integration alone (every model's last pass): 112 bytes and 36 flops per node.
//!
//! `cargo bench --bench roofline` (a few minutes on 2 cores); `NEEDLESIM_ROOFLINE_MODELS=msm,deb`
//! measures only the models with those labels (the machine's limits and the integration
//! always).

use needlesim::core::models::VISCOUS_NEXT;
use needlesim::{Backend, CpuBackend, Threading, Tissue};
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;

mod common;
use common::{cube, MODELS};

/// Elements of each triad array: 16 Mi f32, 64 MiB.
const TRIAD_LEN: usize = 16 << 20;

/// `a = b + s c` over one chunk.
fn triad_chunk(a: &mut [f32], b: &[f32], c: &[f32], s: f32) {
    for ((a, b), c) in a.iter_mut().zip(b).zip(c) {
        *a = b + s * c;
    }
}

/// Best triad bandwidth (GB/s) of 5 repeats, on one thread or on rayon's pool, in chunks
/// of 64 Ki elements either way.
fn triad(parallel: bool) -> f64 {
    const CHUNK: usize = 1 << 16;
    let (mut a, b, c) = (
        vec![0.5f32; TRIAD_LEN],
        vec![1.0f32; TRIAD_LEN],
        vec![2.0f32; TRIAD_LEN],
    );
    let s = black_box(3.0f32);
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        if parallel {
            a.par_chunks_mut(CHUNK)
                .zip(b.par_chunks(CHUNK))
                .zip(c.par_chunks(CHUNK))
                .for_each(|((a, b), c)| triad_chunk(a, b, c, s));
        } else {
            a.chunks_mut(CHUNK)
                .zip(b.chunks(CHUNK))
                .zip(c.chunks(CHUNK))
                .for_each(|((a, b), c)| triad_chunk(a, b, c, s));
        }
        black_box(&a);
        best = best.min(t.elapsed().as_secs_f64());
    }
    (12 * TRIAD_LEN) as f64 / best / 1e9
}

/// Multiply-add chains per thread (independent, so their latency overlaps).
const CHAINS: usize = 12;
/// Lanes per chain: one SSE register each.
const LANES: usize = 4;

/// f32 GFLOP/s of `iterations` multiply-adds on [`CHAINS`] x [`LANES`] accumulators.
fn fma_rate(iterations: usize) -> f64 {
    let mut acc = [[1.0f32; LANES]; CHAINS];
    let (m, k) = (black_box(0.999_999f32), black_box(1e-7f32));
    let t = Instant::now();
    for _ in 0..iterations {
        for chain in acc.iter_mut() {
            for x in chain.iter_mut() {
                // A multiply and an add (a fused multiply-add would be a library call
                // without the FMA target feature, which the default target lacks).
                *x = *x * m + k;
            }
        }
    }
    black_box(&acc);
    (2 * iterations * CHAINS * LANES) as f64 / t.elapsed().as_secs_f64() / 1e9
}

/// Peak f32 GFLOP/s on one thread or on every thread of rayon's pool (best of 3).
fn peak_flops(parallel: bool) -> f64 {
    let iterations = 20_000_000;
    (0..3)
        .map(|_| {
            if parallel {
                let threads = rayon::current_num_threads();
                (0..threads)
                    .into_par_iter()
                    .map(|_| fma_rate(iterations))
                    .sum::<f64>()
            } else {
                fma_rate(iterations)
            }
        })
        .fold(0.0, f64::max)
}

/// Compulsory bytes per node-step of the step of `tissue` (module docs).
fn bytes_per_node_step(tissue: &Tissue) -> f64 {
    let cap = tissue.state.capacity() as f64;
    let once: usize = tissue
        .allocations()
        .iter()
        .filter(|a| a.name != VISCOUS_NEXT)
        .map(|a| match a.name {
            // Positions and velocities: read by the forces and the integration, written
            // by the integration; forces: written, then read by the integration.
            "position" | "velocity" => 3 * a.bytes,
            "force" => 2 * a.bytes,
            // The viscoelastic state: read, and the next one written; the integrator's
            // position remainders likewise.
            "viscous_state" | "position_remainder" => 2 * a.bytes,
            _ => a.bytes,
        })
        .sum();
    once as f64 / cap
}

/// Flops of one node-step of the model `label` (module docs), with `k` neighbour slots
/// per node of which `live` are live on average. The parts, from the kernels:
///
/// - integration (every model): velocity 15, position 6, its TwoSum 15: 36;
/// - mass-spring, four lanes over every slot: offset 3, length 6, spring force 4,
///   damping 11 (the benches' springs are damped), accumulation 7: 31 per slot; the lane
///   sums 9;
/// - a shape matching frame, four lanes over every slot: cluster sums 43 per slot, lane
///   sums 51, the scaled matrix 49, and at most 130 per rotation iteration (2);
///   per-node forces add the goal 36; cluster forces 51 per live slot and 36;
/// - the continuum models' moving least squares: gradient 37 per live slot and 45, with
///   the hourglass control's quadratic fit 42 more per live slot (six monomials, their
///   outer product with the displacement difference) and 441 (`B2 - B C^T` 108, `H =
///   (..) M^-1` 216, `H C` 108, `J - H C` 9), the integration correction 360 (`T E` 108,
///   `G = V P E^T` 108, `G C` 108, folding them in 36: `J + T E` 9, `- G C` 9, `- G` 18),
///   the packed first pass 92, the gather 110
///   per live slot (44, and 66 for the quadratic term) and 18; the stress: linear 34,
///   point based (Green strain, `F S`) 124, neo-Hookean 79, co-rotated (`R` from its
///   quaternion, `R^T F - I`, linear, `R sigma`) 154 plus a shape matching frame; a
///   viscoelastic Debunne adds the push of the relaxed stress 54 and 6 + 30 per Prony
///   term; a Kelvin-Voigt Debunne adds the velocity gradient (27 per live slot: the
///   weighted velocity difference 6, the rest offset 3, the outer product 18; the moment
///   product 45) and its stress (`dev sym`, scaled, added to the first pass: 36).
fn flops_per_node_step(label: &str, k: f64, live: f64) -> f64 {
    const INTEGRATE: f64 = 36.0;
    let frame = 43.0 * k + 51.0 + 49.0 + 130.0 * 2.0;
    let mls = |stress: f64| 79.0 * live + 486.0 + 360.0 + stress + 92.0 + 110.0 * live + 18.0;
    INTEGRATE
        + match label {
            "msm" => 31.0 * k + 9.0,
            "lshm" => frame + 36.0,
            "lshm-cluster" => frame + 51.0 * live + 36.0,
            "deb" => mls(34.0),
            "deb-corotated" => frame + mls(154.0),
            "pba" => mls(124.0),
            "nh" => mls(79.0),
            // Two Prony terms (benches/common).
            "deb-visco" => mls(34.0) + 54.0 + 6.0 + 30.0 * 2.0,
            "deb-kv" => mls(34.0) + 27.0 * live + 45.0 + 36.0,
            other => panic!("no flop count for the model `{other}`"),
        }
}

/// Median seconds of one integration of `b` alone (no force pass) over `steps`.
fn integration_time(b: &mut CpuBackend, steps: usize) -> f64 {
    b.integrate();
    let mut t: Vec<f64> = (0..steps)
        .map(|_| {
            let s = Instant::now();
            b.integrate();
            s.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Median seconds of one step of `b` over `steps` single steps.
fn step_time(b: &mut CpuBackend, steps: usize) -> f64 {
    b.step(3);
    let mut t: Vec<f64> = (0..steps)
        .map(|_| {
            let s = Instant::now();
            b.step(1);
            s.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn main() {
    // `cargo bench` passes `--bench`; a filter is not supported.
    let nodes: usize = std::env::var("NEEDLESIM_ROOFLINE_NODES")
        .ok()
        .map(|s| s.trim().parse().expect("node count"))
        .unwrap_or(100_000);
    let threads = rayon::current_num_threads();
    let (bw1, bw_all) = (triad(false), triad(true));
    let (fl1, fl_all) = (peak_flops(false), peak_flops(true));
    println!("Roofline of this machine ({threads} threads):");
    println!("  triad bandwidth  {bw1:8.2} GB/s on 1 thread, {bw_all:8.2} GB/s on {threads}");
    println!("  f32 mul + add    {fl1:8.2} GFLOP/s on 1 thread, {fl_all:8.2} GFLOP/s on {threads}");
    println!();
    println!(
        "{:<14} {:>8} {:>10} {:>10} {:>9} {:>7} {:>9} {:>8} {:>8}",
        "model",
        "nodes",
        "bytes/n-s",
        "flops/n-s",
        "step ms",
        "GB/s",
        "GFLOP/s",
        "% triad",
        "% peak"
    );
    // `NEEDLESIM_ROOFLINE_MODELS=msm,deb` measures only those labels (the first column
    // of the table; benches/common/mod.rs `MODELS`).
    let only: Option<Vec<String>> = std::env::var("NEEDLESIM_ROOFLINE_MODELS")
        .ok()
        .map(|s| s.split(',').map(|m| m.trim().to_string()).collect());
    for (label, material) in MODELS {
        if only.as_ref().is_some_and(|o| !o.iter().any(|m| m == label)) {
            continue;
        }
        let tissue = Tissue::from_scene(&cube(material, nodes, 1e-5, 1.01)).unwrap();
        let bytes = bytes_per_node_step(&tissue);
        let n = tissue.n_mesh;
        let nb = &tissue.neighbours;
        let live = nb.weight[..n * nb.k].iter().filter(|&&w| w != 0.0).count() as f64 / n as f64;
        let flops = flops_per_node_step(label, nb.k as f64, live);
        let mut b = CpuBackend::new(tissue, Threading::Single).unwrap();
        let t = step_time(&mut b, 20);
        let (rate, flop_rate) = (bytes * n as f64 / t / 1e9, flops * n as f64 / t / 1e9);
        println!(
            "{label:<14} {n:>8} {bytes:>10.0} {flops:>10.0} {:>9.3} {rate:>7.2} {flop_rate:>9.2} {:>7.1}% {:>7.1}%",
            1e3 * t,
            100.0 * rate / bw1,
            100.0 * flop_rate / fl1
        );
    }
    // The integration alone: position, velocity and position remainder read and written,
    // the force read (112 bytes per node), 36 flops.
    let (_, material) = MODELS[0];
    let tissue = Tissue::from_scene(&cube(material, nodes, 1e-5, 1.01)).unwrap();
    let n = tissue.n_mesh;
    let bytes = 112.0;
    let flops = 36.0;
    let mut b = CpuBackend::new(tissue, Threading::Single).unwrap();
    let t = integration_time(&mut b, 50);
    let (rate, flop_rate) = (bytes * n as f64 / t / 1e9, flops * n as f64 / t / 1e9);
    println!(
        "{:<14} {n:>8} {bytes:>10.0} {flops:>10.0} {:>9.3} {rate:>7.2} {flop_rate:>9.2} {:>7.1}% {:>7.1}%",
        "integration",
        1e3 * t,
        100.0 * rate / bw1,
        100.0 * flop_rate / fl1
    );
}
