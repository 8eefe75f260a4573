//! Stiffness of the two models without elastic constants, from a Young's modulus.
//!
//! Mass-spring (N/m per spring) and local shape matching (`k_s`, N/m) have no E or nu.
//! On a lattice of spacing h a strain eps moves neighbours by about `eps h` and a node's
//! force acts on a face of area about `h^2`, so the stress is `~ k eps / h`: the rule is
//! `k = C E h`, with one constant C per model found by a one-case calibration: the free
//! cube stretched 1% between rollers (the accuracy report's `stretch` case at 13 x 13 x 13
//! nodes, h = 8.3 mm; default neighbours K = 16, poly6 kernel of support 2), C set so that
//! the end-plate stress equals `E eps`. The rule is not resolution independent: surface
//! nodes have fewer neighbours, and the effective modulus with the calibrated C falls from
//! about 1.6 E at 125 nodes to 1.15 E at 729 and 0.93 E at 4913 (measured, report).
//! Poisson's ratio is whatever the model gives (measured: about 0.29 for mass-spring,
//! near 0 for cluster shape matching, outside [0, 0.5] for the per-node forces). Other
//! kernels or K need their own calibration: `needlesim report` lists the C that the
//! stretch case implies at each resolution.

/// C of [`mass_spring_stiffness`].
pub const MASS_SPRING_C: f64 = 0.6289;
/// C of [`shape_matching_stiffness`], per-node forces (the paper's).
pub const SHAPE_MATCHING_NODE_C: f64 = 2.869;
/// C of [`shape_matching_stiffness`], per-cluster forces.
pub const SHAPE_MATCHING_CLUSTER_C: f64 = 0.1732;

/// Spring stiffness (N/m) giving Young's modulus `young` (Pa) on a lattice of spacing `h`
/// (m): `MASS_SPRING_C * young * h`.
pub fn mass_spring_stiffness(young: f64, h: f64) -> f64 {
    MASS_SPRING_C * young * h
}

/// Shape matching stiffness `k_s` (N/m) giving Young's modulus `young` (Pa) on a lattice of
/// spacing `h` (m), for per-cluster (`cluster = true`) or per-node forces.
pub fn shape_matching_stiffness(young: f64, h: f64, cluster: bool) -> f64 {
    let c = if cluster {
        SHAPE_MATCHING_CLUSTER_C
    } else {
        SHAPE_MATCHING_NODE_C
    };
    c * young * h
}
