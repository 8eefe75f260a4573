//! Shared by the benches: the model variants and the cube they step.

use needlesim::Scene;
use std::path::Path;

/// (label, `[material]` table body) of every model variant benched.
pub const MODELS: [(&str, &str); 6] = [
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

/// A free 10 cm cube of about `nodes` nodes, K = 16, stretched along x by `stretch`.
pub fn cube(material: &str, nodes: usize, dt: f64, stretch: f64) -> Scene {
    let text = format!(
        "[tissue]\nneighbours = 16\ngeometry = {{ kind = \"box\", min = [0, 0, 0], max = [0.1, 0.1, 0.1], nodes = {nodes} }}\n\
         [material]\n{material}\n[physics]\ndt = {dt}\ndamping = 20.0\n[initial]\nstretch = [{stretch}, 1.0, 1.0]\n"
    );
    Scene::from_toml_str(&text, Path::new(".")).unwrap()
}
