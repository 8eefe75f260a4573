//! The neo-Hookean model on the GPU: the first passes of `shaders/neo_hookean.wgsl` and
//! the shared gather, the twins of [`needlesim_core::models::neo_hookean`].

use super::continuum::{write_constants, FIRST_PASS, FIRST_PASS_MIXED, GATHER_FORCE, MLS};
use super::GpuModel;
use crate::kernels::{KernelSpec, COMMON};
use needlesim_core::models::neo_hookean::{NeoHookeanParams, Shape};

const SOURCES: &[&str] = &[COMMON, MLS, include_str!("../../shaders/neo_hookean.wgsl")];

/// `neo_hookean.wgsl::neo_hookean`: the neo-Hookean stress of the gradient
/// ([`neo_hookean::first_pass`]).
///
/// [`neo_hookean::first_pass`]: needlesim_core::models::neo_hookean::first_pass
pub const FIRST: KernelSpec = KernelSpec {
    name: "neo_hookean",
    sources: SOURCES,
    entry: "neo_hookean",
    bindings: &FIRST_PASS,
};

/// `neo_hookean.wgsl::neo_hookean_mixed`: [`FIRST`] with each node's constants.
pub const FIRST_MIXED: KernelSpec = KernelSpec {
    name: "neo_hookean/mixed",
    sources: SOURCES,
    entry: "neo_hookean_mixed",
    bindings: &FIRST_PASS_MIXED,
};

impl GpuModel for NeoHookeanParams {
    const KERNELS: &'static [&'static KernelSpec] = &[&FIRST, &FIRST_MIXED, &GATHER_FORCE];

    fn write_params(&self, params: &mut crate::params::Params) {
        write_constants(self.constants(), params);
    }

    fn force_kernels(_: &Shape, mixed: bool) -> Vec<&'static KernelSpec> {
        vec![if mixed { &FIRST_MIXED } else { &FIRST }, &GATHER_FORCE]
    }
}
