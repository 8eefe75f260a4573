#![allow(dead_code)]
use needlesim::core::geometry;
use needlesim::{Backend, CpuBackend, NodeField, Scene, Threading, Tissue};
use std::path::Path;

/// The rotation-invariant force models under test: (label, [material] table body).
pub const MODELS: [(&str, &str); 5] = [
    (
        "msm",
        "model = \"mass_spring\"\nstiffness = 100.0\nspring_damping = 0.0",
    ),
    (
        "lshm-node",
        "model = \"local_shape_matching\"\nstiffness = 20.0\nforces = \"node\"",
    ),
    (
        "lshm-cluster",
        "model = \"local_shape_matching\"\nstiffness = 20.0\nforces = \"cluster\"",
    ),
    (
        "deb-corotated",
        "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\ncorotated = true",
    ),
    (
        "pba",
        "model = \"point_based\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3",
    ),
];

/// The plain (linear, not co-rotated) Debunne model: not rotation invariant.
pub const LINEAR_DEB: (&str, &str) = (
    "deb",
    "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3",
);

/// Every model variant.
pub fn all_models() -> Vec<(&'static str, &'static str)> {
    MODELS.iter().copied().chain([LINEAR_DEB]).collect()
}

/// A free 10 cm cube of about `nodes` nodes with the given material, damping and stretch.
pub fn cube_scene(material: &str, nodes: usize, damping: f64, stretch: [f64; 3]) -> Scene {
    let text = format!(
        "[tissue]\ngeometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = {nodes} }}\n\
         [material]\n{material}\n[physics]\ndt = 1e-3\ndamping = {damping}\n\
         [initial]\nstretch = [{}, {}, {}]\n",
        stretch[0], stretch[1], stretch[2]
    );
    Scene::from_toml_str(&text, Path::new(".")).expect("valid test scene")
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

pub fn norm3(v: [f32; 4]) -> f64 {
    (0..3).map(|a| (v[a] as f64).powi(2)).sum::<f64>().sqrt()
}

pub fn max_norm(v: &[[f32; 4]]) -> f64 {
    v.iter().map(|x| norm3(*x)).fold(0.0, f64::max)
}
