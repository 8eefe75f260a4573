use needlesim::core::backend::{Backend, NodeField, NodeSelection};
use needlesim::core::models::ShapeArray;
use needlesim::core::scene::{Axis, NodeSet, ShapeMatchingForces, ShapeMatchingParams};
use needlesim::core::Vec4;
use needlesim::gpu::GpuBackend;
use needlesim::needle::Simulation;
use needlesim::SimError;
use needlesim::{Material, Scene};
use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::{Arc, Mutex};
use std::time::Instant;
static TRACING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
type Log = Arc<Mutex<BTreeMap<&'static str, (u64, f64, u64)>>>;
struct T {
    inner: GpuBackend,
    log: Log,
}
impl T {
    fn rec<R>(&mut self, k: &'static str, n: u64, f: impl FnOnce(&mut GpuBackend) -> R) -> R {
        let t = Instant::now();
        let r = f(&mut self.inner);
        let e = t.elapsed().as_secs_f64() * 1e6;
        if std::env::var_os("TRACE").is_some() && TRACING.load(std::sync::atomic::Ordering::Relaxed)
        {
            println!("      {k} {n}");
        }
        let mut l = self.log.lock().unwrap();
        let x = l.entry(k).or_insert((0, 0.0, 0));
        x.0 += 1;
        x.1 += e;
        x.2 += n;
        r
    }
}
impl Backend for T {
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
        self.rec("set_n_active", 0, |b| b.set_n_active(n))
    }
    fn compute_forces(&mut self) {
        self.rec("compute_forces", 0, |b| b.compute_forces())
    }
    fn compute_forces_on(&mut self, nodes: &[u32]) {
        self.rec("compute_forces_on", nodes.len() as u64, |b| {
            b.compute_forces_on(nodes)
        })
    }
    fn integrate(&mut self) {
        self.rec("integrate", 0, |b| b.integrate())
    }
    fn step(&mut self, n: u64) {
        self.rec("step", n, |b| b.step(n))
    }
    fn position_frame(&self) -> needlesim::core::frame::PositionFrame {
        self.inner.position_frame()
    }
    fn steps_taken(&self) -> u64 {
        self.inner.steps_taken()
    }
    fn set_steps_taken(&mut self, s: u64) {
        self.inner.set_steps_taken(s)
    }
    fn finish(&mut self) {
        self.rec("finish", 0, |b| b.finish())
    }
    fn read(&mut self, f: NodeField, r: Range<usize>, o: &mut [Vec4]) -> Result<(), SimError> {
        self.rec("read", o.len() as u64, |b| b.read(f, r, o))
    }
    fn read_nodes(&mut self, f: NodeField, n: &[u32], o: &mut [Vec4]) -> Result<(), SimError> {
        self.rec("read_nodes", o.len() as u64, |b| b.read_nodes(f, n, o))
    }
    fn read_many(
        &mut self,
        r: &[(NodeField, NodeSelection<'_>)],
        o: &mut [&mut [Vec4]],
    ) -> Result<(), SimError> {
        let n = o.iter().map(|x| x.len() as u64).sum();
        self.rec("read_many", n, |b| b.read_many(r, o))
    }
    fn readbacks(&self) -> u64 {
        self.inner.readbacks()
    }
    fn write(&mut self, f: NodeField, first: usize, d: &[Vec4]) -> Result<(), SimError> {
        self.rec("write", d.len() as u64, |b| b.write(f, first, d))
    }
    fn write_neighbour_rows(&mut self, first: usize, i: &[u32], w: &[f32]) -> Result<(), SimError> {
        self.rec("write_rows", i.len() as u64, |b| {
            b.write_neighbour_rows(first, i, w)
        })
    }
    fn write_shape_bytes(&mut self, a: ShapeArray, off: usize, d: &[u8]) -> Result<(), SimError> {
        self.rec("write_shape", d.len() as u64, |b| {
            b.write_shape_bytes(a, off, d)
        })
    }
    fn read_shape_bytes(
        &mut self,
        a: ShapeArray,
        off: usize,
        o: &mut [u8],
    ) -> Result<(), SimError> {
        self.rec("read_shape", o.len() as u64, |b| {
            b.read_shape_bytes(a, off, o)
        })
    }
    fn guard(&mut self, m: f64) -> Result<(), SimError> {
        self.rec("guard", 0, |b| b.guard(m))
    }
    fn check_finite(&mut self) -> Result<(), SimError> {
        self.rec("check_finite", 0, |b| b.check_finite())
    }
}
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
fn main() {
    let nodes: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(10932);
    let scene = Scene::builder()
        .neighbours(16)
        .box_with_nodes([0.0; 3], [0.1; 3], nodes)
        .material(Material::LocalShapeMatching(
            ShapeMatchingParams::new(20.0).with_forces(ShapeMatchingForces::Cluster),
        ))
        .dt(2e-4)
        .damping(4.0)
        .fixed(NodeSet::above(Axis::X, 0.0995))
        .needle_toml(NEEDLE)
        .build()
        .unwrap();
    let p = Simulation::prepare(&scene).unwrap();
    if std::env::var_os("CPU").is_some() {
        let b = needlesim::CpuBackend::new(p.tissue.clone(), needlesim::Threading::Single).unwrap();
        let mut sim = p.start(Box::new(b)).unwrap();
        sim.set_record(false);
        sim.step_n(3300).unwrap();
        let t = Instant::now();
        for _ in 0..3000 {
            sim.step().unwrap();
        }
        let a = t.elapsed().as_secs_f64() / 3000.0 * 1e6;
        let b = sim.backend();
        let t = Instant::now();
        b.step(3000);
        let c = t.elapsed().as_secs_f64() / 3000.0 * 1e6;
        println!(
            "cpu-1 held {a:.1} us, tissue {c:.1} us, needle {:.1} us",
            a - c
        );
        return;
    }
    let g = GpuBackend::new(&p.tissue).unwrap();
    eprintln!("{}", g.adapter());
    let log: Log = Default::default();
    let mut sim = p
        .start(Box::new(T {
            inner: g,
            log: log.clone(),
        }))
        .unwrap();
    sim.set_record(false);
    sim.step_n(3300).unwrap();
    let thr: f64 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(15000.0);
    let step_len = 0.1 * 2e-4;
    for i in 0..500 {
        let n = sim.needle().unwrap();
        let (b, d) = (n.base(), n.direction());
        let base = [0, 1, 2].map(|k| b[k] + step_len * d[k]);
        let r0 = sim.readbacks();
        let nn = sim.needle_nodes().len();
        log.lock().unwrap().clear();
        TRACING.store(i == 20, std::sync::atomic::Ordering::Relaxed);
        let t = std::time::Instant::now();
        sim.set_pose(base, d).unwrap();
        sim.step().unwrap();
        let dt = t.elapsed().as_secs_f64() * 1e6;
        let nn2 = sim.needle_nodes().len();
        if dt > thr || nn2 != nn {
            println!(
                "step {i}: {dt:.0} us, {} readbacks, nodes {nn}->{nn2}",
                sim.readbacks() - r0
            );
            for (k, (c, t, n)) in log.lock().unwrap().iter() {
                println!("    {k:18} {c:4} calls {t:9.0} us  {n} items");
            }
        }
    }
    // Held: the average step's breakdown.
    log.lock().unwrap().clear();
    let t = std::time::Instant::now();
    let held = 300;
    let r0 = sim.readbacks();
    for _ in 0..held {
        sim.step().unwrap();
    }
    let total = t.elapsed().as_secs_f64() * 1e6 / held as f64;
    println!(
        "held: {total:.1} us per step, {:.2} readbacks",
        (sim.readbacks() - r0) as f64 / held as f64
    );
    let mut sum = 0.0;
    for (k, (c, t, n)) in log.lock().unwrap().iter() {
        sum += t;
        println!(
            "    {k:18} {:6.2} calls {:8.1} us  {} items",
            *c as f64 / held as f64,
            t / held as f64,
            n / held as u64
        );
    }
    println!(
        "    host outside the backend: {:.1} us",
        total - sum / held as f64
    );
}
