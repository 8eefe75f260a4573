//! Stiffness of the two models without elastic constants, from a Young's modulus.
//!
//! Mass-spring (N/m per spring) and local shape matching (`k_s`, N/m) have no E or nu.
//! On a lattice of spacing h a strain eps moves neighbours by about `eps h` and a node's
//! force acts on a face of area about `h^2`, so the stress is `~ k eps / h`: the rule is
//! `k = C E h`, one constant C per model, for the default neighbours (K = 16, poly6 kernel
//! of support 2).
//!
//! C is the bulk value: the free cube stretched 1% between rollers (the accuracy report's
//! `stretch` case) gives an implied C at each resolution (`C E eps / stress`); C is its
//! limit for h -> 0, extrapolated linearly in h from the two finest levels (21^3 and 25^3
//! nodes). So the rule is right for a body much larger than its spacing, and a coarse body
//! comes out stiffer. Measured stress error with these C (dev machine, report stretch
//! case, 125 / 729 / 2197 / 15,625 nodes):
//! - mass-spring: +9.4%, +4.2%, +2.7%, +1.4% (springs count by their share of the body,
//!   `spring_share = "cell"`; with every spring counted fully the implied C drifted
//!   from 0.38 to 0.72 over the same range);
//! - cluster shape matching: +37%, +15%, +9.4%, +4.4%;
//! - per-node shape matching (the paper's forces): +87%, +37%, +23%, +11%.
//!
//! Shape matching clusters at the surface are lopsided and have no share rule yet.
//! Poisson's ratio is whatever the model gives (measured at 15,625 nodes: about 0.24 for
//! mass-spring, near 0 for cluster shape matching, outside [0, 0.5] for the per-node
//! forces). Other kernels or K need their own C: `needlesim report` lists the C that the
//! stretch case implies at each resolution.
//!
//! K = 16 cuts the second shell of a cubic lattice (12 face diagonals for 10 slots), and
//! every node drops the same diagonal pair, so the lattice models are anisotropic there:
//! mass-spring's cantilever, bending in that plane, ends up too soft (11.9% at 12,221
//! nodes, not falling). With `neighbours = 18` the shells are complete: measured (report
//! cases with K = 18, dev machine) mass-spring's bulk C is 0.7501 and its cantilever tip
//! error falls 20.5%, 12.3%, 5.6%, 3.1%, 1.9% from 496 to 12,221 nodes. Use K = 18 and
//! `k = 0.7501 E h` for mass-spring on box lattices when bending matters.

/// C of [`mass_spring_stiffness`].
pub const MASS_SPRING_C: f64 = 0.8351;
/// C of [`shape_matching_stiffness`], per-node forces (the paper's).
pub const SHAPE_MATCHING_NODE_C: f64 = 3.224;
/// C of [`shape_matching_stiffness`], per-cluster forces.
pub const SHAPE_MATCHING_CLUSTER_C: f64 = 0.2126;

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
