//! The neo-Hookean model on the GPU: the first passes of `shaders/neo_hookean.wgsl` and
//! the shared gather, the twins of [`needlesim_core::models::neo_hookean`].

use super::continuum::{
    commit_kernels, finite_force_kernels, write_constants, write_prony, FINITE_VISCOUS,
    FINITE_VISCOUS_MIXED, FIRST_PASS, FIRST_PASS_MIXED, FIRST_PASS_VISCO, FIRST_PASS_VISCO_MIXED,
    GATHER_FORCE, KELVIN_VOIGT, MLS,
};
use super::GpuModel;
use crate::kernels::{KernelSpec, COMMON};
use needlesim_core::models::neo_hookean::{NeoHookeanParams, Shape};

const SOURCES: &[&str] = &[
    COMMON,
    MLS,
    KELVIN_VOIGT,
    include_str!("../../shaders/neo_hookean.wgsl"),
];

/// `neo_hookean.wgsl::nh_viscous`: adds the Kelvin-Voigt stress of the Green strain rate
/// to the first pass, after it (`kelvin_voigt.wgsl::add_finite_viscous`,
/// [`finite_viscous_stress`]).
///
/// [`finite_viscous_stress`]: needlesim_core::models::continuum::finite_viscous_stress
pub const VISCOUS: KernelSpec = KernelSpec {
    name: "neo_hookean/nh_viscous",
    sources: SOURCES,
    entry: "nh_viscous",
    bindings: &FINITE_VISCOUS,
};

/// `neo_hookean.wgsl::nh_viscous_mixed`: [`VISCOUS`] with each node's viscosity.
pub const VISCOUS_MIXED: KernelSpec = KernelSpec {
    name: "neo_hookean/nh_viscous_mixed",
    sources: SOURCES,
    entry: "nh_viscous_mixed",
    bindings: &FINITE_VISCOUS_MIXED,
};

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

/// `neo_hookean.wgsl::neo_hookean_visco`: [`FIRST`] with the second Piola-Kirchhoff
/// stress relaxed by the Prony series ([`needlesim_core::models::viscoelastic`]).
pub const FIRST_VISCO: KernelSpec = KernelSpec {
    name: "neo_hookean/visco",
    sources: SOURCES,
    entry: "neo_hookean_visco",
    bindings: &FIRST_PASS_VISCO,
};

/// `neo_hookean.wgsl::neo_hookean_visco_mixed`: [`FIRST_VISCO`] with each node's constants.
pub const FIRST_VISCO_MIXED: KernelSpec = KernelSpec {
    name: "neo_hookean/visco_mixed",
    sources: SOURCES,
    entry: "neo_hookean_visco_mixed",
    bindings: &FIRST_PASS_VISCO_MIXED,
};

impl GpuModel for NeoHookeanParams {
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

#[cfg(test)]
mod tests {
    /// The shader continues the logarithm below the same volume ratio as the CPU law
    /// ([`needlesim_core::models::neo_hookean::J_MIN`]).
    #[test]
    fn shader_j_min_is_the_cpu_one() {
        let source = include_str!("../../shaders/neo_hookean.wgsl");
        let line = format!(
            "const J_MIN: f32 = {:?};",
            needlesim_core::models::neo_hookean::J_MIN
        );
        assert!(source.contains(&line), "shader lacks `{line}`");
    }
}
