//! Shared by the benches: the model variants and the cube they step.

use needlesim::core::models::viscoelastic::{Prony, PronyTerm};
use needlesim::core::scene::{
    DebunneParams, MassSpringParams, NeoHookeanParams, ShapeMatchingForces, ShapeMatchingParams,
};
use needlesim::{Material, Scene};

/// (label, material) of every model variant benched.
pub const MODELS: [(&str, Material); 9] = [
    (
        "msm",
        Material::MassSpring(MassSpringParams::new(100.0).with_spring_damping(0.01)),
    ),
    ("lshm", Material::shape_matching(20.0)),
    (
        "lshm-cluster",
        Material::LocalShapeMatching(
            ShapeMatchingParams::new(20.0).with_forces(ShapeMatchingForces::Cluster),
        ),
    ),
    ("deb", Material::debunne(1e4, 0.45)),
    (
        "deb-corotated",
        Material::DebunneMeshfree(DebunneParams::new(1e4, 0.45).with_corotated(true)),
    ),
    ("pba", Material::point_based(1e4, 0.45)),
    ("nh", Material::NeoHookean(NeoHookeanParams::new(1e4, 0.45))),
    // Debunne with two Prony terms: the cost of the viscoelastic state.
    (
        "deb-visco",
        Material::DebunneMeshfree(DebunneParams::new(1e4, 0.45).with_viscoelastic(PRONY)),
    ),
    // Debunne with a Kelvin-Voigt dashpot, eta = 0.5 ms x mu as in the shipped scenes: the
    // cost of the velocity-gradient pass (a second neighbour loop).
    (
        "deb-kv",
        Material::DebunneMeshfree(DebunneParams::new(1e4, 0.45).with_viscosity(1.7)),
    ),
];

/// The Prony series of the viscoelastic variant: two terms.
const PRONY: Prony = Prony::new_const([
    PronyTerm { g: 0.3, tau: 0.15 },
    PronyTerm { g: 0.2, tau: 1.0 },
]);

/// A free 10 cm cube of about `nodes` nodes, K = 16, stretched along x by `stretch`.
pub fn cube(material: Material, nodes: usize, dt: f64, stretch: f64) -> Scene {
    Scene::builder()
        .neighbours(16)
        .box_with_nodes([0.0; 3], [0.1; 3], nodes)
        .material(material)
        .dt(dt)
        .damping(20.0)
        .stretch([stretch, 1.0, 1.0])
        .build()
        .unwrap()
}
