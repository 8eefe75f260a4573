#![allow(dead_code)]
use needlesim::core::geometry;
use needlesim::core::models::neo_hookean::NeoHookeanParams;
use needlesim::core::scene::{
    DebunneParams, MassSpringParams, ShapeMatchingForces, ShapeMatchingParams,
};
use needlesim::gpu::{GpuBackend, GpuError};
use needlesim::needle::{NeedleSample, PunctureState, Simulation};
use needlesim::{Backend, CpuBackend, Material, NodeField, Scene, Threading, Tissue};

/// The rotation-invariant force models under test: (label, material).
pub const MODELS: [(&str, Material); 6] = [
    (
        "msm",
        Material::MassSpring(MassSpringParams::new(100.0).with_spring_damping(0.0)),
    ),
    (
        "lshm-node",
        Material::LocalShapeMatching(
            ShapeMatchingParams::new(20.0).with_forces(ShapeMatchingForces::Node),
        ),
    ),
    (
        "lshm-cluster",
        Material::LocalShapeMatching(
            ShapeMatchingParams::new(20.0).with_forces(ShapeMatchingForces::Cluster),
        ),
    ),
    (
        "deb-corotated",
        Material::DebunneMeshfree(DebunneParams::new(1e4, 0.3).with_corotated(true)),
    ),
    ("pba", Material::point_based(1e4, 0.3)),
    ("nh", Material::NeoHookean(NeoHookeanParams::new(1e4, 0.3))),
];

/// The plain (linear, not co-rotated) Debunne model: not rotation invariant.
pub const LINEAR_DEB: (&str, Material) = ("deb", Material::debunne(1e4, 0.3));

/// Every model variant.
pub fn all_models() -> Vec<(&'static str, Material)> {
    MODELS.iter().copied().chain([LINEAR_DEB]).collect()
}

/// A free 10 cm cube of about `nodes` nodes with the given material, damping and stretch.
pub fn cube_scene(material: Material, nodes: usize, damping: f64, stretch: [f64; 3]) -> Scene {
    Scene::builder()
        .box_with_nodes([0.0; 3], [0.1; 3], nodes)
        .material(material)
        .dt(1e-3)
        .damping(damping)
        .stretch(stretch)
        .build()
        .expect("valid test scene")
}

pub fn rest_positions(scene: &Scene) -> Vec<[f64; 3]> {
    geometry::build(&scene.tissue.geometry, &scene.base_dir)
        .unwrap()
        .positions
}

pub fn backend(scene: &Scene, threading: Threading) -> CpuBackend {
    CpuBackend::new(Tissue::from_scene(scene).unwrap(), threading).unwrap()
}

pub fn read(b: &mut dyn Backend, field: NodeField) -> Vec<[f32; 4]> {
    let n = b.n_active();
    let mut out = vec![[0.0; 4]; n];
    b.read(field, 0..n, &mut out).unwrap();
    out
}

/// Length of a node vector's xyz, in f64 (glam at the storage boundary).
pub fn norm3(v: [f32; 4]) -> f64 {
    needlesim::core::math::xyz(v).as_dvec3().length()
}

pub fn max_norm(v: &[[f32; 4]]) -> f64 {
    v.iter().map(|x| norm3(*x)).fold(0.0, f64::max)
}

/// A simulation of `scene` on the single-threaded CPU backend.
pub fn cpu_sim(scene: &Scene) -> Simulation {
    let prep = Simulation::prepare(scene).unwrap();
    let b = CpuBackend::new(prep.tissue.clone(), Threading::Single).unwrap();
    prep.start(Box::new(b)).unwrap()
}

/// A simulation of `scene` on the GPU backend; `None` (skipped) when no adapter is found
/// and `NEEDLESIM_REQUIRE_GPU` is not set.
pub fn gpu_sim(scene: &Scene) -> Option<Simulation> {
    let prep = Simulation::prepare(scene).unwrap();
    match GpuBackend::new(&prep.tissue) {
        Ok(b) => Some(prep.start(Box::new(b)).unwrap()),
        Err(GpuError::NoAdapter(m)) if std::env::var("NEEDLESIM_REQUIRE_GPU").is_err() => {
            eprintln!("skipped, no GPU adapter: {m}");
            None
        }
        Err(e) => panic!("GPU backend: {e}"),
    }
}

/// Asserts the same puncture states and needle node counts in two runs, each change
/// within two steps of the other run's (a puncture, a node edit and a region change are
/// thresholds that f32 rounding moves: the layered scene added a node one step apart,
/// with forces 0.05% apart), and returns the largest |axial force| of `hc` and the
/// largest per-step axial force difference up to time `until`, relative to that scale.
pub fn same_states_force_difference(
    hg: &[NeedleSample],
    hc: &[NeedleSample],
    until: f64,
) -> (f64, f64) {
    let changes = |h: &[NeedleSample]| -> Vec<(usize, (PunctureState, usize))> {
        (0..h.len())
            .filter(|&i| {
                i == 0 || (h[i].state, h[i].needle_nodes) != (h[i - 1].state, h[i - 1].needle_nodes)
            })
            .map(|i| (i, (h[i].state, h[i].needle_nodes)))
            .collect()
    };
    let (cg, cc) = (changes(hg), changes(hc));
    assert_eq!(
        cg.iter().map(|c| c.1).collect::<Vec<_>>(),
        cc.iter().map(|c| c.1).collect::<Vec<_>>(),
        "states and node counts"
    );
    for (a, b) in cg.iter().zip(&cc) {
        assert!(
            a.0.abs_diff(b.0) <= 2,
            "GPU {a:?} at step {}, CPU {b:?}",
            hg[a.0].step
        );
    }
    let scale = hc.iter().map(|s| s.force.axial.abs()).fold(0.0, f64::max);
    let mut largest = 0.0f64;
    for (a, b) in hg.iter().zip(hc) {
        if a.time <= until {
            largest = largest.max((a.force.axial - b.force.axial).abs() / scale);
        }
    }
    (scale, largest)
}

/// Least-squares slope of the displacement along `axis` against the rest coordinate over
/// the mesh nodes: the mean strain along `axis`.
pub fn mean_strain(sim: &mut Simulation, axis: usize) -> f64 {
    let rest = sim.rest_positions();
    let n = rest.len();
    let mut p = vec![[0.0f32; 4]; n];
    sim.backend()
        .read(NodeField::Position, 0..n, &mut p)
        .unwrap();
    let mean = |f: &dyn Fn(usize) -> f64| (0..n).map(f).sum::<f64>() / n as f64;
    let xm = mean(&|i| rest[i][axis]);
    let um = mean(&|i| p[i][axis] as f64 - rest[i][axis]);
    let cov = mean(&|i| (rest[i][axis] - xm) * (p[i][axis] as f64 - rest[i][axis] - um));
    let var = mean(&|i| (rest[i][axis] - xm).powi(2));
    cov / var
}

/// The longest one generated case of a property test may take: a case takes
/// milliseconds, so a case that takes this long is stuck (a hang is a failure like a
/// panic).
pub const CASE_TIME_LIMIT: std::time::Duration = std::time::Duration::from_secs(20);

/// Runs `f` on its own thread; a panic there is resumed here, and a run longer than
/// [`CASE_TIME_LIMIT`] panics naming the input (the stuck thread is left behind).
pub fn within_time(input: &str, f: impl FnOnce() + Send + 'static) {
    let (tx, rx) = std::sync::mpsc::channel();
    let worker = std::thread::spawn(move || {
        f();
        let _ = tx.send(());
    });
    match rx.recv_timeout(CASE_TIME_LIMIT) {
        Ok(()) => {
            let _ = worker.join();
        }
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            if let Err(panic) = worker.join() {
                std::panic::resume_unwind(panic);
            }
        }
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            panic!("no result after {CASE_TIME_LIMIT:?} for the input:\n{input}")
        }
    }
}

/// The octahedron of radius 1 about the origin: its vertices ...
pub const OCTAHEDRON_VERTICES: [[f32; 3]; 6] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
];

/// ... and its outward triangles (0-based).
pub const OCTAHEDRON_TRIANGLES: [[u32; 3]; 8] = [
    [0, 2, 4],
    [2, 1, 4],
    [1, 3, 4],
    [3, 0, 4],
    [2, 0, 5],
    [1, 2, 5],
    [3, 1, 5],
    [0, 3, 5],
];

/// A resampled ball (surface-net vertices over an interior lattice) of radius 5 cm at
/// 12.5 mm spacing, 463 nodes: the node clouds whose plain nodal integration is not
/// consistent (`core/src/models/consistency.rs`).
pub fn resampled_ball(material: Material) -> needlesim::Tissue {
    use needlesim::core::geometry::{resample::resample, shapes::capsule};
    let (r, h) = (0.05, 0.0125);
    let scene = needlesim::Scene::builder()
        .density(1000.0)
        .neighbours(18)
        .box_with_spacing([0.0; 3], [0.1; 3], h)
        .material(material)
        .dt(1e-4)
        .build()
        .unwrap();
    let surface = capsule([0.0, -r, 0.0], 2.0 * r, r, 48, 24);
    let cloud = resample(&surface, h, std::path::Path::new("ball")).unwrap();
    needlesim::Tissue::from_cloud(&scene, cloud, 0).unwrap()
}
