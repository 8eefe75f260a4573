//! Compiled compute kernels: one WGSL file per kernel under the repository's top-level
//! `shaders/`, composed with the shared code at load time. Each entry point is declared
//! once as a [`KernelSpec`] (its sources, entry point and the buffer at each binding),
//! next to the CPU twin it mirrors: the integration here, the models' kernels in
//! [`crate::models`]. A unit test validates every shader with naga and checks that each
//! entry point uses exactly the bindings its spec declares.
//! Pipelines use `layout: None` and bind groups are made from `get_bind_group_layout(0)`, so
//! each entry point binds only what it uses. Kernels hold pipelines only; the buffers they
//! run on live in [`crate::Buffers`].
//!
//! With several materials (`ShapeInfo::node_material`) the force kernels that read material
//! constants have `_mixed` entry points taking them per node from the `node_material`
//! array at binding [`crate::models::MATERIAL_BINDING`] (or from the pass before: the two that would
//! otherwise exceed the 8 storage buffers per kernel the device is asked for); the
//! single-material entry points do not bind it.
//!
//! The sources are read with `include_str!("../shaders/...")` through the relative symlink
//! `crates/gpu/shaders -> ../../shaders`. `cargo package` follows a symlinked directory
//! inside the package and stores the files it points to as ordinary files under
//! `shaders/`, so the published crate compiles on its own (check with
//! `cargo package -p needlesim-gpu --list`).

use crate::buffers::{Binding, Buffers};

/// The parameter block and helpers every kernel includes first.
pub const COMMON: &str = include_str!("../shaders/common.wgsl");
/// The shape matching frame shared by shape matching and co-rotated Debunne.
pub const CLUSTER_FRAME: &str = include_str!("../shaders/cluster_frame.wgsl");
const INTEGRATE: &str = include_str!("../shaders/integrate.wgsl");

/// Nodes per workgroup (`@workgroup_size` of every kernel).
pub const WORKGROUP: u32 = 64;

/// A compiled compute pipeline and its name.
#[derive(Debug)]
pub struct Kernel {
    /// Kernel name (file and entry point).
    pub name: &'static str,
    pipeline: wgpu::ComputePipeline,
}

/// A kernel with its bind group.
#[derive(Debug)]
pub struct Pass {
    pub(crate) kernel: Kernel,
    pub(crate) bind: wgpu::BindGroup,
}

/// One WGSL entry point: where its source is and what it binds.
#[derive(Debug)]
pub struct KernelSpec {
    /// Name in labels and kernel times (`file` or `file/entry`).
    pub name: &'static str,
    /// The WGSL sources, concatenated in this order ([`COMMON`] first).
    pub sources: &'static [&'static str],
    /// Entry point.
    pub entry: &'static str,
    /// The buffer at each binding of group 0.
    pub bindings: &'static [(u32, Binding)],
}

impl KernelSpec {
    /// The kernel compiled on `device`.
    pub fn compile(&self, device: &wgpu::Device) -> Kernel {
        Kernel::compile(device, self.name, self.sources, self.entry)
    }

    /// The kernel compiled on `device` and bound to `b`.
    pub fn pass(&self, device: &wgpu::Device, b: &Buffers) -> Pass {
        let kernel = self.compile(device);
        let entries: Vec<(u32, &wgpu::Buffer)> = self
            .bindings
            .iter()
            .map(|(i, binding)| (*i, b.get(*binding)))
            .collect();
        let bind = kernel.bind(device, &entries);
        Pass { kernel, bind }
    }
}

impl Kernel {
    fn compile(device: &wgpu::Device, name: &'static str, parts: &[&str], entry: &str) -> Kernel {
        let source = parts.join("\n");
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(name),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(name),
            layout: None,
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
        Kernel { name, pipeline }
    }

    /// A bind group with `buffers[b]` at binding `b.0` of group 0.
    pub fn bind(&self, device: &wgpu::Device, buffers: &[(u32, &wgpu::Buffer)]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding: *binding,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(self.name),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }

    /// The layout of bind group 0 (for a bind group that binds part of a buffer).
    pub(crate) fn bind_group_layout(&self) -> wgpu::BindGroupLayout {
        self.pipeline.get_bind_group_layout(0)
    }

    /// Records one dispatch of `groups` workgroups (x, y) in `pass`.
    pub fn dispatch(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        bind: &wgpu::BindGroup,
        groups: (u32, u32),
    ) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }
}

/// `integrate.wgsl`: symplectic Euler with damping and fixed nodes, positions summed with
/// their remainders (the GPU twin of [`needlesim_core::integrator::integrate_node`]); it
/// also raises the divergence guard's flag ([`crate::GpuBackend`]'s `Backend::guard`).
pub const INTEGRATE_NODE: KernelSpec = KernelSpec {
    name: "integrate",
    sources: &[COMMON, INTEGRATE],
    entry: "main",
    bindings: &[
        (0, Binding::Params),
        (1, Binding::Positions),
        (2, Binding::Velocities),
        (3, Binding::Forces),
        (4, Binding::PositionRemainders),
        (5, Binding::Guard),
    ],
};
