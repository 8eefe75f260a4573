#![allow(dead_code)]
use needlesim::core::geometry;
use needlesim::core::scene::ShapeMatchingForces;
use needlesim::{Backend, CpuBackend, Material, NodeField, Scene, Threading, Tissue};

/// The rotation-invariant force models under test: (label, material).
pub const MODELS: [(&str, Material); 5] = [
    ("msm", Material::mass_spring(100.0).with_spring_damping(0.0)),
    (
        "lshm-node",
        Material::shape_matching(20.0).with_forces(ShapeMatchingForces::Node),
    ),
    (
        "lshm-cluster",
        Material::shape_matching(20.0).with_forces(ShapeMatchingForces::Cluster),
    ),
    (
        "deb-corotated",
        Material::debunne(1e4, 0.3).with_corotated(true),
    ),
    ("pba", Material::point_based(1e4, 0.3)),
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
