//! Point based animation on the GPU: the first passes of `shaders/point_based.wgsl` and
//! the shared gather, the twins of
//! [`needlesim_core::models::point_based`].

use super::continuum::{
    commit_kernels, finite_force_kernels, write_constants, write_prony, FINITE_VISCOUS,
    FINITE_VISCOUS_MIXED, FIRST_PASS, FIRST_PASS_MIXED, FIRST_PASS_VISCO, FIRST_PASS_VISCO_MIXED,
    GATHER_FORCE, KELVIN_VOIGT, MLS,
};
use super::GpuModel;
use crate::kernels::{KernelSpec, COMMON};

const SOURCES: &[&str] = &[
    COMMON,
    MLS,
    KELVIN_VOIGT,
    include_str!("../../shaders/point_based.wgsl"),
];
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

/// `point_based.wgsl::pba_mixed`: [`FIRST`] with each node's constants (its row
/// `[lambda, mu, k_v, eta]` and the material's alpha).
pub const FIRST_MIXED: KernelSpec = KernelSpec {
    name: "point_based/pba_mixed",
    sources: SOURCES,
    entry: "pba_mixed",
    bindings: &FIRST_PASS_MIXED,
};

/// `point_based.wgsl::pba_visco`: [`FIRST`] with the Green-strain stress relaxed by the
/// Prony series ([`needlesim_core::models::viscoelastic`]).
pub const FIRST_VISCO: KernelSpec = KernelSpec {
    name: "point_based/pba_visco",
    sources: SOURCES,
    entry: "pba_visco",
    bindings: &FIRST_PASS_VISCO,
};

/// `point_based.wgsl::pba_visco_mixed`: [`FIRST_VISCO`] with each node's constants.
pub const FIRST_VISCO_MIXED: KernelSpec = KernelSpec {
    name: "point_based/pba_visco_mixed",
    sources: SOURCES,
    entry: "pba_visco_mixed",
    bindings: &FIRST_PASS_VISCO_MIXED,
};

/// `point_based.wgsl::pba_viscous`: adds the Kelvin-Voigt stress of the Green strain
/// rate to the first pass, after it (`kelvin_voigt.wgsl::add_finite_viscous`,
/// [`finite_viscous_stress`]).
///
/// [`finite_viscous_stress`]: needlesim_core::models::continuum::finite_viscous_stress
pub const VISCOUS: KernelSpec = KernelSpec {
    name: "point_based/pba_viscous",
    sources: SOURCES,
    entry: "pba_viscous",
    bindings: &FINITE_VISCOUS,
};

/// `point_based.wgsl::pba_viscous_mixed`: [`VISCOUS`] with each node's viscosity.
pub const VISCOUS_MIXED: KernelSpec = KernelSpec {
    name: "point_based/pba_viscous_mixed",
    sources: SOURCES,
    entry: "pba_viscous_mixed",
    bindings: &FINITE_VISCOUS_MIXED,
};

impl GpuModel for PointBasedParams {
    const KERNELS: &'static [&'static KernelSpec] = &[
        &FIRST,
        &FIRST_MIXED,
        &FIRST_VISCO,
        &FIRST_VISCO_MIXED,
        &VISCOUS,
        &VISCOUS_MIXED,
        &GATHER_FORCE,
    ];

    fn write_params(&self, params: &mut crate::params::Params) {
        write_constants(self.constants(), params);
        write_prony(&self.viscoelastic, params);
        params.viscosity = self.viscosity as f32;
        params.hourglass_alpha = self.hourglass as f32;
    }

    fn force_kernels(shape: &Shape, mixed: bool) -> Vec<&'static KernelSpec> {
        let entries = [&FIRST, &FIRST_MIXED, &FIRST_VISCO, &FIRST_VISCO_MIXED];
        let viscous = shape.viscous.then_some([&VISCOUS, &VISCOUS_MIXED]);
        finite_force_kernels(&shape.continuum, mixed, entries, viscous)
    }

    fn end_step_kernels(shape: &Shape) -> Vec<&'static KernelSpec> {
        commit_kernels(&shape.continuum)
    }
}
