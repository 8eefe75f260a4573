//! Needle benches (paper section 5):
//! - `add_remove/<nodes>`: one node addition at the cube's centre followed by its removal
//!   (NodeEditor on one CPU thread), at `NEEDLESIM_BENCH_SIZES` target node counts
//!   (default `639,10932,100000`): the cost should not grow with the node count;
//! - `step_inserted/<backend>/<nodes>`: one full `Simulation` step of an LSHM cube
//!   (`NEEDLESIM_NEEDLE_SIZES`, default 10932 nodes) with the needle 6 cm inside and held
//!   (Surface, Shaft and Tip nodes, friction, force readback), on one CPU thread, all CPU
//!   threads and the GPU when an adapter is found, and `step_inserted/tissue-only/...`:
//!   the same CPU backend stepped alone, so that the difference is the needle's cost; for
//!   the GPU, the blocking readbacks per step over [`COUNTED_STEPS`] steps are printed
//!   first (one: the needle nodes' forces, so the GPU's step time is the needle step's
//!   latency from submit to force available, what a haptic loop waits for) (`NEEDLESIM_BENCH_CPU_ONLY` leaves the GPU out; `NEEDLESIM_NEEDLE_MODEL` picks
//!   another tissue model, [`needle_material`]). Before the held benches, the
//!   CPU runs print the needle step while the needle advances against the tissue alone
//!   ([`advancing_overhead`]), and the GPU run prints the advancing step's latency
//!   distribution and its slowest step's time per backend call ([`advancing_latency`]). `NEEDLESIM_BENCH_BACKENDS` (`cpu-1,cpu-all,gpu`)
//!   picks backends.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use needlesim::core::backend::NodeSelection;
use needlesim::core::frame::PositionFrame;
use needlesim::core::models::ShapeArray;
use needlesim::core::scene::{Axis, NodeSet, ShapeMatchingForces, ShapeMatchingParams};
use needlesim::core::Vec4;
use needlesim::gpu::GpuBackend;
use needlesim::needle::{NodeEditor, PunctureState, Simulation};
use needlesim::{Backend, CpuBackend, Material, NodeField, Scene, SimError, Threading, Tissue};
use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::{Arc, Mutex};
use std::time::Instant;

mod common;
use common::{cube, MODELS};

fn sizes() -> Vec<usize> {
    std::env::var("NEEDLESIM_BENCH_SIZES")
        .ok()
        .map(|s| {
            s.split(',')
                .map(|x| x.trim().parse().expect("node count"))
                .collect()
        })
        .unwrap_or(vec![639, 10932, 100_000])
}

fn add_remove(c: &mut Criterion) {
    let mut group = c.benchmark_group("add_remove");
    group.sample_size(20);
    let (_, lshm) = MODELS[1];
    for nodes in sizes() {
        let scene = cube(lshm, nodes, 1e-3, 1.0);
        let rest = needlesim::core::geometry::build(&scene.tissue.geometry, &scene.base_dir)
            .unwrap()
            .positions;
        let tissue = Tissue::from_scene_with_capacity(&scene, 4).unwrap();
        let mut editor = NodeEditor::new(&tissue, &rest, scene.tissue.weight);
        let mut backend = CpuBackend::new(tissue, Threading::Single).unwrap();
        let centre = [0.0503f32, 0.0497, 0.0501];
        let nearest = (0..rest.len())
            .min_by(|&a, &b| {
                let d = |i: usize| {
                    (0..3)
                        .map(|k| (rest[i][k] - centre[k] as f64).powi(2))
                        .sum::<f64>()
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap() as u32;
        group.bench_function(BenchmarkId::from_parameter(rest.len()), |b| {
            b.iter(|| {
                let seeds = editor.rings(&[nearest], 2);
                editor
                    .add_node(&mut backend, centre, [0.0; 3], &seeds)
                    .unwrap();
                editor.remove_last(&mut backend).unwrap();
            })
        });
    }
    group.finish();
}

/// The `[needle]` table of `step_inserted` (read by `needlesim-needle`): 6.5 cm in, then
/// held.
const NEEDLE: &str = r#"
base = [-0.105, 0.0503, 0.0497]
direction = [1.0, 0.0, 0.0]
length = 0.1
[[keyframe]]
action = "move"
direction = [1.0, 0.0, 0.0]
speed = 0.1
duration = 0.65
[[keyframe]]
action = "pause"
duration = 100.0
"#;

/// An LSHM cube of about `nodes` nodes (K = 16) clamped at +x with the needle of
/// [`NEEDLE`].
fn inserted(nodes: usize) -> Scene {
    Scene::builder()
        .neighbours(16)
        .box_with_nodes([0.0; 3], [0.1; 3], nodes)
        .material(needle_material())
        .dt(2e-4)
        .damping(4.0)
        .fixed(NodeSet::above(Axis::X, 0.0995))
        .needle_toml(NEEDLE)
        .build()
        .unwrap()
}

/// The tissue of `step_inserted`: cluster shape matching, or the benches' model named by
/// `NEEDLESIM_NEEDLE_MODEL` (`msm`, `deb-corotated`, `pba`, ... as in `common::MODELS`),
/// so that the needle's overhead can be measured on every model.
fn needle_material() -> Material {
    match std::env::var("NEEDLESIM_NEEDLE_MODEL") {
        Ok(name) => {
            MODELS
                .iter()
                .find(|(label, _)| *label == name)
                .unwrap_or_else(|| panic!("NEEDLESIM_NEEDLE_MODEL: no model {name:?}"))
                .1
        }
        Err(_) => Material::LocalShapeMatching(
            ShapeMatchingParams::new(20.0).with_forces(ShapeMatchingForces::Cluster),
        ),
    }
}

/// Steps over which the GPU's readbacks per needle step are counted.
const COUNTED_STEPS: u64 = 200;

fn step_inserted(c: &mut Criterion) {
    let mut group = c.benchmark_group("step_inserted");
    group.sample_size(10);
    for nodes in needle_sizes() {
        step_inserted_at(&mut group, &inserted(nodes));
    }
    group.finish();
}

/// Cube sizes of `step_inserted`: `NEEDLESIM_NEEDLE_SIZES` (default `10932`; the issue's
/// `10932,100000` takes minutes on 2 cores).
fn needle_sizes() -> Vec<usize> {
    std::env::var("NEEDLESIM_NEEDLE_SIZES")
        .ok()
        .map(|s| {
            s.split(',')
                .map(|x| x.trim().parse().expect("node count"))
                .collect()
        })
        .unwrap_or(vec![10932])
}

/// One scene's needle step on every backend, then (CPU) the same backend stepped without
/// the needle's work: the needle's overhead.
fn step_inserted_at(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    scene: &Scene,
) {
    let scene = scene.clone();
    let prep = |scene: &Scene| Simulation::prepare(scene).unwrap();
    let mut runs: Vec<(&str, Threading, Simulation)> = Vec::new();
    for (name, threading) in [
        ("cpu-1", Threading::Single),
        ("cpu-all", Threading::Parallel),
    ] {
        if !backend_wanted(name) {
            continue;
        }
        let p = prep(&scene);
        let b = CpuBackend::new(p.tissue.clone(), threading).unwrap();
        runs.push((name, threading, p.start(Box::new(b)).unwrap()));
    }
    let p = prep(&scene);
    if std::env::var_os("NEEDLESIM_BENCH_CPU_ONLY").is_some() || !backend_wanted("gpu") {
        eprintln!("GPU bench skipped: NEEDLESIM_BENCH_CPU_ONLY or NEEDLESIM_BENCH_BACKENDS");
    } else {
        match GpuBackend::new(&p.tissue) {
            Ok(g) => {
                eprintln!("GPU: {}", g.adapter());
                runs.push(("gpu", Threading::Single, p.start(Box::new(g)).unwrap()));
            }
            Err(e) => eprintln!("GPU bench skipped: {e}"),
        }
    }
    for (name, threading, sim) in runs.iter_mut() {
        sim.set_record(false);
        // 6 cm in at 10 cm/s (3250 steps of 0.2 ms), then the needle holds still.
        sim.step_n(3300).unwrap();
        assert_eq!(sim.state(), PunctureState::Inside);
        if *name == "gpu" {
            let before = sim.readbacks();
            for _ in 0..COUNTED_STEPS {
                sim.step().unwrap();
            }
            let per_step = (sim.readbacks() - before) as f64 / COUNTED_STEPS as f64;
            eprintln!(
                "{name}: {per_step:.3} blocking readbacks per needle step over \
                 {COUNTED_STEPS} steps"
            );
        }
        let n = sim.backend().n_active();
        eprintln!(
            "{name}: {} needle nodes, {n} active nodes",
            sim.needle_nodes().len()
        );
        if *name != "gpu" {
            advancing_overhead(name, sim, &scene, *threading);
        } else {
            advancing_latency(sim, &scene);
        }
        group.bench_function(BenchmarkId::new(*name, n), |b| {
            b.iter(|| sim.step().unwrap())
        });
        sim.backend().check_finite().unwrap();
        if *name != "gpu" {
            // The same backend, nodes and needle nodes, stepped without the needle's
            // contact, friction and readbacks: what the needle adds is the difference.
            let b = sim.backend();
            group.bench_function(
                BenchmarkId::new(format!("tissue-only/{name}"), n),
                |bench| bench.iter(|| b.step(1)),
            );
        }
    }
}

/// Steps of [`advancing_overhead`]: 1 cm of advance at 10 cm/s in steps of 0.2 ms,
/// which crosses about two node spacings of the 10,932-node cube (4.5 mm), so the shaft
/// gains nodes on the way.
const ADVANCE_STEPS: usize = 500;

/// The needle step while the needle advances (cutting, node additions at the crack
/// front, the shaft sliding), against the same backend stepped alone for as many steps:
/// printed, best of 3 of each (a criterion loop cannot bound how far the needle would
/// travel). Each repetition starts from a checkpoint of `sim` on a simulation of its own
/// (`threading`), so all three do the same work, 1 cm of advance from where `sim` is, and
/// `sim` itself is left as it was. (Advancing `sim` itself three times took the tip to
/// 1 cm from the clamped face, where neo-Hookean runs away; and stepping the tissue
/// alone let the needle's nodes go, so a neo-Hookean shaft node sprang 14.7 mm ahead of
/// the tip and the needle stopped with `NodesLost`.)
fn advancing_overhead(name: &str, sim: &mut Simulation, scene: &Scene, threading: Threading) {
    let step_len = 0.1 * 2e-4;
    let mut needle_best = f64::INFINITY;
    let mut tissue_best = f64::INFINITY;
    let start = sim.checkpoint().unwrap();
    let nodes_before = sim.needle_nodes().len();
    let mut nodes_after = nodes_before;
    for _ in 0..3 {
        let p = Simulation::prepare(scene).unwrap();
        let b = CpuBackend::new(p.tissue.clone(), threading).unwrap();
        let mut sim = p.resume(Box::new(b), start.clone()).unwrap();
        sim.set_record(false);
        let t = std::time::Instant::now();
        for _ in 0..ADVANCE_STEPS {
            let n = sim.needle().expect("the scene has a needle");
            let (b, d) = (n.base(), n.direction());
            let base = [0, 1, 2].map(|k| b[k] + step_len * d[k]);
            sim.set_pose(base, d).unwrap();
            sim.step().unwrap();
        }
        needle_best = needle_best.min(t.elapsed().as_secs_f64());
        assert_eq!(sim.state(), PunctureState::Inside);
        nodes_after = sim.needle_nodes().len();
        let b = sim.backend();
        let t = std::time::Instant::now();
        b.step(ADVANCE_STEPS as u64);
        tissue_best = tissue_best.min(t.elapsed().as_secs_f64());
    }
    eprintln!(
        "{name}: advancing needle step {:.1} us, tissue-only {:.1} us: {:+.1}% \
         ({} -> {} needle nodes over 1 cm)",
        1e6 * needle_best / ADVANCE_STEPS as f64,
        1e6 * tissue_best / ADVANCE_STEPS as f64,
        100.0 * (needle_best / tissue_best - 1.0),
        nodes_before,
        nodes_after
    );
}

/// Whether `NEEDLESIM_BENCH_BACKENDS` (comma-separated `cpu-1`, `cpu-all`, `gpu`; default
/// all) names `name`: on a large cube the one-thread run's insertion alone takes minutes.
fn backend_wanted(name: &str) -> bool {
    match std::env::var("NEEDLESIM_BENCH_BACKENDS") {
        Ok(list) => list.split(',').any(|b| b.trim() == name),
        Err(_) => true,
    }
}

/// The GPU needle step while the needle advances ([`ADVANCE_STEPS`] steps, 1 cm, node
/// additions on the way), each step timed alone from the pose update to the force
/// available: the mean, median, 99th percentile and largest step, and the blocking
/// readbacks per step, printed. A haptic loop at 1 kHz needs the largest, not the mean,
/// under 1 ms. Runs on a GPU simulation of its own resumed from a checkpoint of `sim`.
fn advancing_latency(sim: &mut Simulation, scene: &Scene) {
    let step_len = 0.1 * 2e-4;
    let start = sim.checkpoint().unwrap();
    let p = Simulation::prepare(scene).unwrap();
    let g = GpuBackend::new(&p.tissue).unwrap();
    let calls = Calls::default();
    let timed = Timed {
        inner: g,
        calls: calls.clone(),
    };
    let mut sim = p.resume(Box::new(timed), start).unwrap();
    sim.set_record(false);
    let before = sim.readbacks();
    let nodes_before = sim.needle_nodes().len();
    let mut times = Vec::with_capacity(ADVANCE_STEPS);
    let mut slowest: (f64, BTreeMap<&'static str, (u64, f64)>) = (0.0, BTreeMap::new());
    for _ in 0..ADVANCE_STEPS {
        let n = sim.needle().expect("the scene has a needle");
        let (b, d) = (n.base(), n.direction());
        let base = [0, 1, 2].map(|k| b[k] + step_len * d[k]);
        calls.lock().unwrap().clear();
        let t = Instant::now();
        sim.set_pose(base, d).unwrap();
        sim.step().unwrap();
        let _ = sim.needle_force();
        let us = t.elapsed().as_secs_f64() * 1e6;
        times.push(us);
        if us > slowest.0 {
            slowest = (us, calls.lock().unwrap().clone());
        }
    }
    let per_step = (sim.readbacks() - before) as f64 / ADVANCE_STEPS as f64;
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    times.sort_by(f64::total_cmp);
    let at = |q: f64| times[((times.len() - 1) as f64 * q).round() as usize];
    eprintln!(
        "gpu: advancing needle step mean {mean:.1} us, median {:.1} us, p99 {:.1} us, \
         max {:.1} us; {per_step:.2} blocking readbacks per step ({} -> {} needle nodes \
         over 1 cm)",
        at(0.5),
        at(0.99),
        at(1.0),
        nodes_before,
        sim.needle_nodes().len()
    );
    let in_calls: f64 = slowest.1.values().map(|c| c.1).sum();
    eprintln!(
        "gpu: the slowest advancing step, {:.0} us: {:.0} us outside the backend's calls",
        slowest.0,
        slowest.0 - in_calls
    );
    for (name, (count, us)) in &slowest.1 {
        eprintln!("    {name:20} {count:4} calls {us:8.0} us");
    }
}

/// Per backend call: calls and microseconds, over one step ([`Timed`]).
type Calls = Arc<Mutex<BTreeMap<&'static str, (u64, f64)>>>;

/// A backend that times every call of the one it wraps (wall time; a GPU call that waits,
/// a readback, carries the work queued before it), for the breakdown of the slowest
/// advancing step.
struct Timed {
    inner: GpuBackend,
    calls: Calls,
}

impl Timed {
    fn time<R>(&mut self, name: &'static str, f: impl FnOnce(&mut GpuBackend) -> R) -> R {
        let t = Instant::now();
        let r = f(&mut self.inner);
        let mut calls = self.calls.lock().unwrap();
        let c = calls.entry(name).or_insert((0, 0.0));
        c.0 += 1;
        c.1 += t.elapsed().as_secs_f64() * 1e6;
        r
    }
}

impl Backend for Timed {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
    fn n_active(&self) -> usize {
        self.inner.n_active()
    }
    fn set_n_active(&mut self, n: usize) -> Result<(), SimError> {
        self.time("set_n_active", |b| b.set_n_active(n))
    }
    fn compute_forces(&mut self) {
        self.time("compute_forces", |b| b.compute_forces())
    }
    fn compute_forces_on(&mut self, nodes: &[u32]) {
        self.time("compute_forces_on", |b| b.compute_forces_on(nodes))
    }
    fn integrate(&mut self) {
        self.time("integrate", |b| b.integrate())
    }
    fn step(&mut self, n: u64) {
        self.time("step", |b| b.step(n))
    }
    fn position_frame(&self) -> PositionFrame {
        self.inner.position_frame()
    }
    fn steps_taken(&self) -> u64 {
        self.inner.steps_taken()
    }
    fn set_steps_taken(&mut self, steps: u64) {
        self.inner.set_steps_taken(steps)
    }
    fn finish(&mut self) {
        self.time("finish", |b| b.finish())
    }
    fn read(&mut self, f: NodeField, r: Range<usize>, out: &mut [Vec4]) -> Result<(), SimError> {
        self.time("read", |b| b.read(f, r, out))
    }
    fn read_nodes(&mut self, f: NodeField, n: &[u32], out: &mut [Vec4]) -> Result<(), SimError> {
        self.time("read_nodes", |b| b.read_nodes(f, n, out))
    }
    fn read_many(
        &mut self,
        requests: &[(NodeField, NodeSelection<'_>)],
        outs: &mut [&mut [Vec4]],
    ) -> Result<(), SimError> {
        self.time("read_many", |b| b.read_many(requests, outs))
    }
    fn readbacks(&self) -> u64 {
        self.inner.readbacks()
    }
    fn write(&mut self, f: NodeField, first: usize, data: &[Vec4]) -> Result<(), SimError> {
        self.time("write", |b| b.write(f, first, data))
    }
    fn write_neighbour_rows(&mut self, first: usize, i: &[u32], w: &[f32]) -> Result<(), SimError> {
        self.time("write_neighbour_rows", |b| {
            b.write_neighbour_rows(first, i, w)
        })
    }
    fn write_shape_bytes(&mut self, a: ShapeArray, at: usize, d: &[u8]) -> Result<(), SimError> {
        self.time("write_shape_bytes", |b| b.write_shape_bytes(a, at, d))
    }
    fn read_shape_bytes(&mut self, a: ShapeArray, at: usize, o: &mut [u8]) -> Result<(), SimError> {
        self.time("read_shape_bytes", |b| b.read_shape_bytes(a, at, o))
    }
    fn guard(&mut self, max_speed: f64) -> Result<(), SimError> {
        self.time("guard", |b| b.guard(max_speed))
    }
    fn check_finite(&mut self) -> Result<(), SimError> {
        self.time("check_finite", |b| b.check_finite())
    }
}

criterion_group!(benches, add_remove, step_inserted);
criterion_main!(benches);
