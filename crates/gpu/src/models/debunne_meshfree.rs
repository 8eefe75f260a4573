//! The Debunne meshfree model on the GPU: the `deb_*` entry points of
//! `shaders/continuum_first_pass.wgsl` and the shared gather, the twins of
//! [`needlesim_core::models::debunne_meshfree`].
//!
//! Mixed and co-rotated, the rotations come first in a pass of their own
//! ([`FRAME`]), to stay within 8 storage buffers per kernel.

use super::continuum::{
    write_constants, FIRST_PASS, FIRST_PASS_MIXED, FIRST_PASS_SOURCES, GATHER_FORCE, ROTATION,
    SHAPE_VECTOR,
};
use super::{GpuModel, MATERIAL};
use crate::buffers::Binding;
use crate::kernels::KernelSpec;
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

/// `continuum_first_pass.wgsl::deb_linear`: the linear stress
/// ([`debunne_meshfree::first_pass`] without rotation).
///
/// [`debunne_meshfree::first_pass`]: needlesim_core::models::debunne_meshfree::first_pass
pub const LINEAR: KernelSpec = KernelSpec {
    name: "continuum_first_pass/deb_linear",
    sources: FIRST_PASS_SOURCES,
    entry: "deb_linear",
    bindings: &FIRST_PASS,
};

/// `continuum_first_pass.wgsl::deb_linear_mixed`: [`LINEAR`] with each node's constants.
pub const LINEAR_MIXED: KernelSpec = KernelSpec {
    name: "continuum_first_pass/deb_linear_mixed",
    sources: FIRST_PASS_SOURCES,
    entry: "deb_linear_mixed",
    bindings: &FIRST_PASS_MIXED,
};

/// `continuum_first_pass.wgsl::deb_corotated`: the shape matching rotation and the
/// co-rotated stress in one pass.
pub const COROTATED: KernelSpec = KernelSpec {
    name: "continuum_first_pass/deb_corotated",
    sources: FIRST_PASS_SOURCES,
    entry: "deb_corotated",
    bindings: &COROTATED_BINDINGS,
};

/// `continuum_first_pass.wgsl::deb_frame`: the rotations only (before
/// [`COROTATED_MIXED`]).
pub const FRAME: KernelSpec = KernelSpec {
    name: "continuum_first_pass/deb_frame",
    sources: FIRST_PASS_SOURCES,
    entry: "deb_frame",
    bindings: &FRAME_BINDINGS,
};

/// `continuum_first_pass.wgsl::deb_corotated_mixed`: the co-rotated stress with each
/// node's constants, reading the rotations [`FRAME`] stored.
pub const COROTATED_MIXED: KernelSpec = KernelSpec {
    name: "continuum_first_pass/deb_corotated_mixed",
    sources: FIRST_PASS_SOURCES,
    entry: "deb_corotated_mixed",
    bindings: &COROTATED_MIXED_BINDINGS,
};

impl GpuModel for DebunneParams {
    const KERNELS: &'static [&'static KernelSpec] = &[
        &LINEAR,
        &LINEAR_MIXED,
        &COROTATED,
        &FRAME,
        &COROTATED_MIXED,
        &GATHER_FORCE,
    ];

    fn write_params(&self, params: &mut crate::params::Params) {
        params.iterations = self.rotation_iterations;
        write_constants(self.constants(), params);
    }

    fn force_kernels(shape: &Shape, mixed: bool) -> Vec<&'static KernelSpec> {
        let mut v: Vec<&'static KernelSpec> = match (shape.corotation.is_some(), mixed) {
            (false, false) => vec![&LINEAR],
            (false, true) => vec![&LINEAR_MIXED],
            (true, false) => vec![&COROTATED],
            (true, true) => vec![&FRAME, &COROTATED_MIXED],
        };
        v.push(&GATHER_FORCE);
        v
    }
}
