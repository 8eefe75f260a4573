//! Each tissue model's GPU kernels, one module per model named like its CPU module in
//! `needlesim_core::models`, each kernel a [`KernelSpec`] next to the CPU function it
//! mirrors. [`GpuModel`] is what the backend asks of a model; the dispatch over the models
//! comes from the core's registry ([`needlesim_core::for_each_model!`]).

mod continuum;
mod debunne_meshfree;
mod local_shape_matching;
mod mass_spring;
mod neo_hookean;
mod point_based;

use crate::buffers::{Binding, Buffers};
use crate::kernels::{KernelSpec, Pass};
use crate::params::Params;
use needlesim_core::models::{ModelShape, ShapeArray, ShapeInfo, TissueModel};
use needlesim_core::Material;

/// Binding (group 0) of the `node_material` array in the `_mixed` entry points that read
/// it.
pub const MATERIAL_BINDING: u32 = 10;

/// The `node_material` binding of the `_mixed` entry points.
pub(crate) const MATERIAL: (u32, Binding) =
    (MATERIAL_BINDING, Binding::Model(ShapeArray::NodeMaterial));

/// A tissue model on the GPU.
pub trait GpuModel: TissueModel {
    /// Every kernel of the model (for the shader tests).
    const KERNELS: &'static [&'static KernelSpec];

    /// Writes the model's constants into the parameter block.
    fn write_params(&self, params: &mut Params);

    /// The force kernels of one step, in order, for `shape`; with several materials
    /// (`mixed`) the entry points that read each node's constants from `node_material`.
    fn force_kernels(shape: &Self::Shape, mixed: bool) -> Vec<&'static KernelSpec>;

    /// The kernels that end a step, after the integration ([`ModelState::end_step`]);
    /// none by default.
    ///
    /// [`ModelState::end_step`]: needlesim_core::models::ModelState::end_step
    fn end_step_kernels(_shape: &Self::Shape) -> Vec<&'static KernelSpec> {
        Vec::new()
    }

    /// What of `shape` the kernels cannot run (with several materials: `mixed`), in a
    /// few words; `None` when they run all of it.
    fn unsupported(_shape: &Self::Shape, _mixed: bool) -> Option<&'static str> {
        None
    }
}

macro_rules! define_gpu_models {
    ($( $(#[$doc:meta])* $variant:ident($params:ty), )*) => {
        /// Writes the material's constants into the parameter block.
        pub(crate) fn write_params(material: &Material, params: &mut Params) {
            match material {
                $( Material::$variant(p) => p.write_params(params), )*
            }
        }

        /// The force kernels of the tissue's model, in order, bound to `b`.
        pub(crate) fn force_passes(
            device: &wgpu::Device,
            shape: &ShapeInfo,
            b: &Buffers,
        ) -> Vec<Pass> {
            let mixed = shape.node_material.is_some();
            let specs = match &shape.model {
                $( ModelShape::$variant(s) => <$params as GpuModel>::force_kernels(s, mixed), )*
            };
            specs.into_iter().map(|k| k.pass(device, b)).collect()
        }

        /// What of the tissue's model the kernels cannot run ([`GpuModel::unsupported`]).
        pub(crate) fn unsupported(shape: &ShapeInfo) -> Option<&'static str> {
            let mixed = shape.node_material.is_some();
            match &shape.model {
                $( ModelShape::$variant(s) => <$params as GpuModel>::unsupported(s, mixed), )*
            }
        }

        /// The kernels that end each step of the tissue's model, bound to `b`.
        pub(crate) fn end_step_passes(
            device: &wgpu::Device,
            shape: &ShapeInfo,
            b: &Buffers,
        ) -> Vec<Pass> {
            let specs = match &shape.model {
                $( ModelShape::$variant(s) => <$params as GpuModel>::end_step_kernels(s), )*
            };
            specs.into_iter().map(|k| k.pass(device, b)).collect()
        }

        /// Every model's kernels.
        #[cfg(test)]
        pub(crate) fn all_kernels() -> Vec<&'static KernelSpec> {
            let mut v = Vec::new();
            $( v.extend_from_slice(<$params as GpuModel>::KERNELS); )*
            v
        }
    };
}

needlesim_core::for_each_model!(define_gpu_models);

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// Every kernel's source parses and validates with naga, its entry point exists, and
    /// the bindings it uses are exactly those its spec declares (a binding renumbered in
    /// the WGSL or forgotten in the spec fails here, not at pipeline creation).
    #[test]
    fn every_kernel_validates_and_declares_its_bindings() {
        let mut specs = all_kernels();
        specs.push(&crate::kernels::INTEGRATE_NODE);
        specs.push(&continuum::VISCO_COMMIT);
        // A kernel two models share (the continuum gather) is checked once.
        specs.sort_by_key(|s| s.name);
        specs.dedup_by_key(|s| s.name);
        assert!(specs.len() >= 15, "{} kernels", specs.len());
        for spec in specs {
            let source = spec.sources.join("\n");
            let module = naga::front::wgsl::parse_str(&source)
                .unwrap_or_else(|e| panic!("{}: {}", spec.name, e.emit_to_string(&source)));
            let info = naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::default(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}: {e:?}", spec.name));
            let (index, _) = module
                .entry_points
                .iter()
                .enumerate()
                .find(|(_, e)| e.name == spec.entry)
                .unwrap_or_else(|| panic!("{}: no entry point `{}`", spec.name, spec.entry));
            let ep = info.get_entry_point(index);
            let used: BTreeSet<u32> = module
                .global_variables
                .iter()
                .filter(|(h, _)| !ep[*h].is_empty())
                .filter_map(|(_, g)| g.binding.as_ref().map(|b| b.binding))
                .collect();
            let declared: BTreeSet<u32> = spec.bindings.iter().map(|(b, _)| *b).collect();
            assert_eq!(used, declared, "{}: bindings used vs declared", spec.name);
        }
    }
}
