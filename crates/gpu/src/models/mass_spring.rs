//! Mass-spring on the GPU: `shaders/mass_spring.wgsl`, the twin of
//! [`needlesim_core::models::mass_spring`].

use super::{GpuModel, MATERIAL};
use crate::buffers::Binding::{self, *};
use crate::kernels::{KernelSpec, COMMON};
use needlesim_core::models::mass_spring::{MassSpringParams, Shape};
use needlesim_core::models::ShapeArray::RestLength;

const SOURCE: &str = include_str!("../../shaders/mass_spring.wgsl");

const BINDINGS: [(u32, Binding); 7] = [
    (0, Params),
    (1, Positions),
    (2, Velocities),
    (3, NeighbourIndex),
    (4, NeighbourWeight),
    (5, Model(RestLength)),
    (6, Forces),
];

/// `mass_spring.wgsl::main`: the spring forces per node ([`mass_spring::force`]).
///
/// [`mass_spring::force`]: needlesim_core::models::mass_spring::force
pub const FORCE: KernelSpec = KernelSpec {
    name: "mass_spring",
    sources: &[COMMON, SOURCE],
    entry: "main",
    bindings: &BINDINGS,
};

/// `mass_spring.wgsl::mixed`: each spring with the series mean of its nodes' stiffness
/// and damping ([`mass_spring::force_mixed`]).
///
/// [`mass_spring::force_mixed`]: needlesim_core::models::mass_spring::force_mixed
pub const FORCE_MIXED: KernelSpec = KernelSpec {
    name: "mass_spring/mixed",
    sources: &[COMMON, SOURCE],
    entry: "mixed",
    bindings: &[
        BINDINGS[0],
        BINDINGS[1],
        BINDINGS[2],
        BINDINGS[3],
        BINDINGS[4],
        BINDINGS[5],
        BINDINGS[6],
        MATERIAL,
    ],
};

impl GpuModel for MassSpringParams {
    const KERNELS: &'static [&'static KernelSpec] = &[&FORCE, &FORCE_MIXED];

    fn write_params(&self, params: &mut crate::params::Params) {
        params.stiffness = self.stiffness as f32;
        params.spring_damping = self.spring_damping as f32;
    }

    fn force_kernels(_: &Shape, mixed: bool) -> Vec<&'static KernelSpec> {
        vec![if mixed { &FORCE_MIXED } else { &FORCE }]
    }
}
