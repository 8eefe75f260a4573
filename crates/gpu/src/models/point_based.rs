//! Point based animation on the GPU: the first passes of `shaders/point_based.wgsl` and
//! the shared gather, the twins of
//! [`needlesim_core::models::point_based`].

use super::continuum::{write_constants, FIRST_PASS, FIRST_PASS_MIXED, GATHER_FORCE, MLS};
use super::GpuModel;
use crate::kernels::{KernelSpec, COMMON};

const SOURCES: &[&str] = &[COMMON, MLS, include_str!("../../shaders/point_based.wgsl")];
use needlesim_core::models::point_based::{PointBasedParams, Shape};

/// `point_based.wgsl::pba`: the first Piola-Kirchhoff stress of the Green
/// strain ([`point_based::first_pass`]).
///
/// [`point_based::first_pass`]: needlesim_core::models::point_based::first_pass
pub const FIRST: KernelSpec = KernelSpec {
    name: "point_based/pba",
    sources: SOURCES,
    entry: "pba",
    bindings: &FIRST_PASS,
};

/// `point_based.wgsl::pba_mixed`: [`FIRST`] with each node's constants.
pub const FIRST_MIXED: KernelSpec = KernelSpec {
    name: "point_based/pba_mixed",
    sources: SOURCES,
    entry: "pba_mixed",
    bindings: &FIRST_PASS_MIXED,
};

impl GpuModel for PointBasedParams {
    const KERNELS: &'static [&'static KernelSpec] = &[&FIRST, &FIRST_MIXED, &GATHER_FORCE];

    fn write_params(&self, params: &mut crate::params::Params) {
        write_constants(self.constants(), params);
    }

    fn force_kernels(_: &Shape, mixed: bool) -> Vec<&'static KernelSpec> {
        vec![if mixed { &FIRST_MIXED } else { &FIRST }, &GATHER_FORCE]
    }
}
