//! What the continuum models share on the GPU: `shaders/mls.wgsl` (the bindings, the
//! displacement gradient and the packing of a first pass, which each model's shader
//! completes with its stress and entry points) and `shaders/gather_force.wgsl`, the twins
//! of [`needlesim_core::models::mls`].

use super::MATERIAL;
use crate::buffers::Binding::{self, *};
use crate::kernels::{KernelSpec, COMMON};
use needlesim_core::models::mls::{ContinuumArrays, ContinuumConstants};
use needlesim_core::models::viscoelastic::Prony;
use needlesim_core::models::ShapeArray::{
    FirstPass, InverseMoment, RestPosition, Rotation, ShapeVector, Viscous,
};

/// The shared first-pass code a model's first-pass shader is appended to.
pub const MLS: &str = include_str!("../../shaders/mls.wgsl");
/// The Kelvin-Voigt viscosity's velocities, velocity gradient and first-pass addition,
/// composed after [`MLS`] (Debunne, neo-Hookean and point based animation).
pub const KELVIN_VOIGT: &str = include_str!("../../shaders/kelvin_voigt.wgsl");

/// The node velocities, for the viscous stress (`kelvin_voigt.wgsl::velocities`).
pub const VELOCITIES: (u32, Binding) = (12, Binding::Velocities);

/// A finite-strain law's viscous pass (`kelvin_voigt.wgsl::add_finite_viscous`): the first
/// pass's arrays and the velocities.
pub const FINITE_VISCOUS: [(u32, Binding); 8] = [
    FIRST_PASS[0],
    FIRST_PASS[1],
    FIRST_PASS[2],
    FIRST_PASS[3],
    FIRST_PASS[4],
    FIRST_PASS[5],
    FIRST_PASS[6],
    VELOCITIES,
];

/// [`FINITE_VISCOUS`] and the node materials.
pub const FINITE_VISCOUS_MIXED: [(u32, Binding); 9] = [
    FIRST_PASS[0],
    FIRST_PASS[1],
    FIRST_PASS[2],
    FIRST_PASS[3],
    FIRST_PASS[4],
    FIRST_PASS[5],
    FIRST_PASS[6],
    VELOCITIES,
    MATERIAL,
];

/// The force kernels of a finite-strain law ([`law_force_kernels`]) with its viscous pass
/// (`viscous`: plain and mixed) after the first pass when the tissue is viscous.
pub fn finite_force_kernels(
    arrays: &ContinuumArrays,
    mixed: bool,
    entries: [&'static KernelSpec; 4],
    viscous: Option<[&'static KernelSpec; 2]>,
) -> Vec<&'static KernelSpec> {
    let mut v = law_force_kernels(arrays, mixed, entries);
    if let Some(k) = viscous {
        // Before the gather, after the first pass it adds to.
        v.insert(1, k[usize::from(mixed)]);
    }
    v
}

/// The first pass's bindings.
pub const FIRST_PASS: [(u32, Binding); 7] = [
    (0, Params),
    (1, Positions),
    (2, Model(RestPosition)),
    (3, NeighbourIndex),
    (4, NeighbourWeight),
    (5, Model(InverseMoment)),
    (6, Model(FirstPass)),
];

/// [`FIRST_PASS`] and the node materials.
pub const FIRST_PASS_MIXED: [(u32, Binding); 8] = [
    FIRST_PASS[0],
    FIRST_PASS[1],
    FIRST_PASS[2],
    FIRST_PASS[3],
    FIRST_PASS[4],
    FIRST_PASS[5],
    FIRST_PASS[6],
    MATERIAL,
];

/// The viscoelastic state (committed rows, then the next ones): `mls.wgsl::visco`.
pub const VISCO: (u32, Binding) = (11, Model(Viscous));

/// [`FIRST_PASS`] and the viscoelastic state.
pub const FIRST_PASS_VISCO: [(u32, Binding); 8] = [
    FIRST_PASS[0],
    FIRST_PASS[1],
    FIRST_PASS[2],
    FIRST_PASS[3],
    FIRST_PASS[4],
    FIRST_PASS[5],
    FIRST_PASS[6],
    VISCO,
];

/// [`FIRST_PASS_MIXED`] and the viscoelastic state.
pub const FIRST_PASS_VISCO_MIXED: [(u32, Binding); 9] = [
    FIRST_PASS[0],
    FIRST_PASS[1],
    FIRST_PASS[2],
    FIRST_PASS[3],
    FIRST_PASS[4],
    FIRST_PASS[5],
    FIRST_PASS[6],
    MATERIAL,
    VISCO,
];

const COMMIT_BINDINGS: [(u32, Binding); 2] = [(0, Params), VISCO];

/// `mls.wgsl::visco_commit`: copies the viscoelastic state the step computed over the
/// committed one ([`ContinuumArrays::end_step`]), once per step after the integration.
///
/// [`ContinuumArrays::end_step`]: needlesim_core::models::mls::ContinuumArrays::end_step
pub const VISCO_COMMIT: KernelSpec = KernelSpec {
    name: "visco_commit",
    sources: &[COMMON, MLS],
    entry: "visco_commit",
    bindings: &COMMIT_BINDINGS,
};

/// The first pass of a [`ContinuumLaw`] model among its four entry points `[elastic,
/// elastic with several materials, viscoelastic, viscoelastic with several materials]`,
/// then the gather.
///
/// [`ContinuumLaw`]: needlesim_core::models::continuum::ContinuumLaw
pub fn law_force_kernels(
    arrays: &ContinuumArrays,
    mixed: bool,
    entries: [&'static KernelSpec; 4],
) -> Vec<&'static KernelSpec> {
    let visco = !arrays.visco.is_empty();
    let first = entries[usize::from(mixed) + 2 * usize::from(visco)];
    vec![first, &GATHER_FORCE]
}

/// [`VISCO_COMMIT`] for a viscoelastic material, nothing for an elastic one.
pub fn commit_kernels(arrays: &ContinuumArrays) -> Vec<&'static KernelSpec> {
    if arrays.visco.is_empty() {
        Vec::new()
    } else {
        vec![&VISCO_COMMIT]
    }
}

/// Writes the update coefficients of a Prony series for the step `params.dt`.
pub fn write_prony(prony: &Prony, params: &mut crate::params::Params) {
    let c = prony.coefficients(params.dt as f64);
    params.visco_terms = c.len as u32;
    params.visco_g_inf = c.g_inf;
    params.visco_a = c.a;
    params.visco_b = c.b;
}

/// The shape matching frame's arrays.
pub const SHAPE_VECTOR: (u32, Binding) = (8, Model(ShapeVector));
/// The warm-start rotations.
pub const ROTATION: (u32, Binding) = (9, Model(Rotation));

const GATHER_BINDINGS: [(u32, Binding); 7] = [
    (0, Params),
    (1, Positions),
    (2, Model(RestPosition)),
    (3, NeighbourIndex),
    (4, NeighbourWeight),
    (5, Model(FirstPass)),
    (6, Forces),
];

/// `gather_force.wgsl::main`: every node's force from the first-pass results
/// ([`mls::gather_force`]).
///
/// [`mls::gather_force`]: needlesim_core::models::mls::gather_force
pub const GATHER_FORCE: KernelSpec = KernelSpec {
    name: "gather_force",
    sources: &[COMMON, include_str!("../../shaders/gather_force.wgsl")],
    entry: "main",
    bindings: &GATHER_BINDINGS,
};

/// Writes a continuum model's constants.
pub fn write_constants(c: ContinuumConstants, params: &mut crate::params::Params) {
    params.lambda = c.lambda;
    params.mu = c.mu;
    params.volume_stiffness = c.volume_stiffness;
    params.hourglass = c.hourglass;
}
