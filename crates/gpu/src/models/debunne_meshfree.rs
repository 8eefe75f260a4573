//! The Debunne meshfree model on the GPU: the first passes of
//! `shaders/debunne_meshfree.wgsl` and the shared gather, the twins of
//! [`needlesim_core::models::debunne_meshfree`].
//!
//! Mixed and co-rotated, the rotations come first in a pass of their own
//! ([`FRAME`]), to stay within 8 storage buffers per kernel.

use super::continuum::{
    commit_kernels, write_constants, write_prony, FIRST_PASS, FIRST_PASS_MIXED, FIRST_PASS_VISCO,
    FIRST_PASS_VISCO_MIXED, GATHER_FORCE, KELVIN_VOIGT, MLS, ROTATION, SHAPE_VECTOR, VELOCITIES,
    VISCO,
};
use super::{GpuModel, MATERIAL};
use crate::buffers::Binding;
use crate::kernels::{KernelSpec, CLUSTER_FRAME, COMMON};

/// The co-rotated entries use the shape matching frame.
const SOURCES: &[&str] = &[
    COMMON,
    CLUSTER_FRAME,
    MLS,
    KELVIN_VOIGT,
    include_str!("../../shaders/debunne_meshfree.wgsl"),
];
use needlesim_core::models::debunne_meshfree::{DebunneParams, Shape};

const F: [(u32, Binding); 7] = FIRST_PASS;
const COROTATED_BINDINGS: [(u32, Binding); 9] = [
    F[0],
    F[1],
    F[2],
    F[3],
    F[4],
    F[5],
    F[6],
    SHAPE_VECTOR,
    ROTATION,
];
const FRAME_BINDINGS: [(u32, Binding); 7] = [F[0], F[1], F[2], F[3], F[4], SHAPE_VECTOR, ROTATION];
const COROTATED_MIXED_BINDINGS: [(u32, Binding); 9] =
    [F[0], F[1], F[2], F[3], F[4], F[5], F[6], ROTATION, MATERIAL];

/// `debunne_meshfree.wgsl::deb_linear`: the linear stress
/// ([`debunne_meshfree::first_pass`] without rotation).
///
/// [`debunne_meshfree::first_pass`]: needlesim_core::models::debunne_meshfree::first_pass
pub const LINEAR: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_linear",
    sources: SOURCES,
    entry: "deb_linear",
    bindings: &FIRST_PASS,
};

/// `debunne_meshfree.wgsl::deb_linear_mixed`: [`LINEAR`] with each node's constants.
pub const LINEAR_MIXED: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_linear_mixed",
    sources: SOURCES,
    entry: "deb_linear_mixed",
    bindings: &FIRST_PASS_MIXED,
};

/// `debunne_meshfree.wgsl::deb_corotated`: the shape matching rotation and the
/// co-rotated stress in one pass.
pub const COROTATED: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_corotated",
    sources: SOURCES,
    entry: "deb_corotated",
    bindings: &COROTATED_BINDINGS,
};

/// `debunne_meshfree.wgsl::deb_frame`: the rotations only (before
/// [`COROTATED_MIXED`]).
pub const FRAME: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_frame",
    sources: SOURCES,
    entry: "deb_frame",
    bindings: &FRAME_BINDINGS,
};

/// `debunne_meshfree.wgsl::deb_corotated_mixed`: the co-rotated stress with each
/// node's constants, reading the rotations [`FRAME`] stored.
pub const COROTATED_MIXED: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_corotated_mixed",
    sources: SOURCES,
    entry: "deb_corotated_mixed",
    bindings: &COROTATED_MIXED_BINDINGS,
};

const COROTATED_VISCO_BINDINGS: [(u32, Binding); 9] =
    [F[0], F[1], F[2], F[3], F[4], F[5], F[6], ROTATION, VISCO];

/// `debunne_meshfree.wgsl::deb_linear_visco`: [`LINEAR`] with the stress relaxed by the
/// Prony series ([`needlesim_core::models::viscoelastic`]).
pub const LINEAR_VISCO: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_linear_visco",
    sources: SOURCES,
    entry: "deb_linear_visco",
    bindings: &FIRST_PASS_VISCO,
};

/// `debunne_meshfree.wgsl::deb_linear_visco_mixed`: [`LINEAR_VISCO`] with each node's
/// constants.
pub const LINEAR_VISCO_MIXED: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_linear_visco_mixed",
    sources: SOURCES,
    entry: "deb_linear_visco_mixed",
    bindings: &FIRST_PASS_VISCO_MIXED,
};

/// `debunne_meshfree.wgsl::deb_corotated_visco`: the co-rotated stress relaxed by the
/// Prony series, reading the rotations [`FRAME`] stored (the frame, the state and the
/// first pass's arrays would exceed 8 storage buffers in one kernel).
pub const COROTATED_VISCO: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_corotated_visco",
    sources: SOURCES,
    entry: "deb_corotated_visco",
    bindings: &COROTATED_VISCO_BINDINGS,
};

const VISCOUS_BINDINGS: [(u32, Binding); 7] = [F[0], VELOCITIES, F[2], F[3], F[4], F[5], F[6]];
const VISCOUS_MIXED_BINDINGS: [(u32, Binding); 8] =
    [F[0], VELOCITIES, F[2], F[3], F[4], F[5], F[6], MATERIAL];
const VISCOUS_COROTATED_BINDINGS: [(u32, Binding); 8] =
    [F[0], VELOCITIES, F[2], F[3], F[4], F[5], F[6], ROTATION];
const VISCOUS_COROTATED_MIXED_BINDINGS: [(u32, Binding); 9] = [
    F[0], VELOCITIES, F[2], F[3], F[4], F[5], F[6], ROTATION, MATERIAL,
];

/// `debunne_meshfree.wgsl::deb_viscous`: adds the Kelvin-Voigt viscous stress to the first
/// pass, after it ([`debunne_meshfree::viscous_stress`]).
///
/// [`debunne_meshfree::viscous_stress`]: needlesim_core::models::debunne_meshfree::viscous_stress
pub const VISCOUS: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_viscous",
    sources: SOURCES,
    entry: "deb_viscous",
    bindings: &VISCOUS_BINDINGS,
};

/// `debunne_meshfree.wgsl::deb_viscous_mixed`: [`VISCOUS`] with each node's viscosity.
pub const VISCOUS_MIXED: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_viscous_mixed",
    sources: SOURCES,
    entry: "deb_viscous_mixed",
    bindings: &VISCOUS_MIXED_BINDINGS,
};

/// `debunne_meshfree.wgsl::deb_viscous_corotated`: [`VISCOUS`] of `R^T L`, pushed by the
/// rotation the first pass stored.
pub const VISCOUS_COROTATED: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_viscous_corotated",
    sources: SOURCES,
    entry: "deb_viscous_corotated",
    bindings: &VISCOUS_COROTATED_BINDINGS,
};

/// `debunne_meshfree.wgsl::deb_viscous_corotated_mixed`: [`VISCOUS_COROTATED`] with each
/// node's viscosity.
pub const VISCOUS_COROTATED_MIXED: KernelSpec = KernelSpec {
    name: "debunne_meshfree/deb_viscous_corotated_mixed",
    sources: SOURCES,
    entry: "deb_viscous_corotated_mixed",
    bindings: &VISCOUS_COROTATED_MIXED_BINDINGS,
};

impl GpuModel for DebunneParams {
    const KERNELS: &'static [&'static KernelSpec] = &[
        &LINEAR,
        &LINEAR_MIXED,
        &COROTATED,
        &FRAME,
        &COROTATED_MIXED,
        &LINEAR_VISCO,
        &LINEAR_VISCO_MIXED,
        &COROTATED_VISCO,
        &VISCOUS,
        &VISCOUS_MIXED,
        &VISCOUS_COROTATED,
        &VISCOUS_COROTATED_MIXED,
        &GATHER_FORCE,
    ];

    fn write_params(&self, params: &mut crate::params::Params) {
        params.iterations = self.rotation_iterations;
        write_constants(self.constants(), params);
        write_prony(&self.viscoelastic, params);
        params.viscosity = self.viscosity as f32;
    }

    /// Co-rotated, viscoelastic and with several materials is refused before
    /// ([`GpuModel::unsupported`]: it would take 9 storage buffers).
    fn force_kernels(shape: &Shape, mixed: bool) -> Vec<&'static KernelSpec> {
        let visco = !shape.continuum.visco.is_empty();
        let mut v: Vec<&'static KernelSpec> = match (shape.corotation.is_some(), mixed, visco) {
            (false, false, false) => vec![&LINEAR],
            (false, true, false) => vec![&LINEAR_MIXED],
            (true, false, false) => vec![&COROTATED],
            (true, true, false) => vec![&FRAME, &COROTATED_MIXED],
            (false, false, true) => vec![&LINEAR_VISCO],
            (false, true, true) => vec![&LINEAR_VISCO_MIXED],
            (true, _, true) => vec![&FRAME, &COROTATED_VISCO],
        };
        if shape.viscous {
            v.push(match (shape.corotation.is_some(), mixed) {
                (false, false) => &VISCOUS,
                (false, true) => &VISCOUS_MIXED,
                (true, false) => &VISCOUS_COROTATED,
                (true, true) => &VISCOUS_COROTATED_MIXED,
            });
        }
        v.push(&GATHER_FORCE);
        v
    }

    fn unsupported(shape: &Shape, mixed: bool) -> Option<&'static str> {
        (shape.corotation.is_some() && mixed && !shape.continuum.visco.is_empty())
            .then_some("co-rotated viscoelastic Debunne with several materials")
    }

    fn end_step_kernels(shape: &Shape) -> Vec<&'static KernelSpec> {
        commit_kernels(&shape.continuum)
    }
}
