//! Compiled compute kernels: one WGSL file per kernel under the repository's top-level
//! `shaders/`, composed with the shared code at load time, one constructor per kernel.
//! Pipelines use `layout: None` and bind groups are made from `get_bind_group_layout(0)`, so
//! each entry point binds only what it uses. Kernels hold pipelines only; the buffers they
//! run on live in [`crate::Buffers`].
//!
//! With several materials (`ShapeInfo::node_material`) the force kernels that read material
//! constants have `_mixed` entry points taking them per node from the `node_material`
//! array at binding [`MATERIAL_BINDING`] (or from the pass before: the two that would
//! otherwise exceed the 8 storage buffers per kernel the device is asked for); the
//! single-material entry points do not bind it.
//!
//! The sources are read with `include_str!("../shaders/...")` through the relative symlink
//! `crates/gpu/shaders -> ../../shaders`. `cargo package` follows a symlinked directory
//! inside the package and stores the files it points to as ordinary files under
//! `shaders/`, so the published crate compiles on its own (check with
//! `cargo package -p needlesim-gpu --list`).

const COMMON: &str = include_str!("../shaders/common.wgsl");
const CLUSTER_FRAME: &str = include_str!("../shaders/cluster_frame.wgsl");
const INTEGRATE: &str = include_str!("../shaders/integrate.wgsl");
const MASS_SPRING: &str = include_str!("../shaders/mass_spring.wgsl");
const LSHM_FRAME: &str = include_str!("../shaders/lshm_frame.wgsl");
const LSHM_CLUSTER_FORCE: &str = include_str!("../shaders/lshm_cluster_force.wgsl");
const CONTINUUM_FIRST_PASS: &str = include_str!("../shaders/continuum_first_pass.wgsl");
const GATHER_FORCE: &str = include_str!("../shaders/gather_force.wgsl");

/// Nodes per workgroup (`@workgroup_size` of every kernel).
pub const WORKGROUP: u32 = 64;

/// Binding (group 0) of the `node_material` array in the `_mixed` entry points that read it.
pub const MATERIAL_BINDING: u32 = 10;

/// A compiled compute pipeline and its name.
#[derive(Debug)]
pub struct Kernel {
    /// Kernel name (file and entry point).
    pub name: &'static str,
    pipeline: wgpu::ComputePipeline,
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

/// `integrate.wgsl`: symplectic Euler with damping and fixed nodes.
pub fn integrate(device: &wgpu::Device) -> Kernel {
    Kernel::compile(device, "integrate", &[COMMON, INTEGRATE], "main")
}

/// `mass_spring.wgsl`: weighted mass-spring forces.
pub fn mass_spring(device: &wgpu::Device) -> Kernel {
    Kernel::compile(device, "mass_spring", &[COMMON, MASS_SPRING], "main")
}

/// `mass_spring.wgsl::mixed`: mass-spring forces, each spring with the series mean of its
/// nodes' stiffness and damping.
pub fn mass_spring_mixed(device: &wgpu::Device) -> Kernel {
    Kernel::compile(device, "mass_spring/mixed", &[COMMON, MASS_SPRING], "mixed")
}

/// `lshm_frame.wgsl::node_force`: shape matching frame and the paper's per-node force.
pub fn lshm_node_force(device: &wgpu::Device) -> Kernel {
    Kernel::compile(
        device,
        "lshm_frame/node_force",
        &[COMMON, CLUSTER_FRAME, LSHM_FRAME],
        "node_force",
    )
}

/// `lshm_frame.wgsl::node_force_mixed`: [`lshm_node_force`] with each node's own stiffness.
pub fn lshm_node_force_mixed(device: &wgpu::Device) -> Kernel {
    Kernel::compile(
        device,
        "lshm_frame/node_force_mixed",
        &[COMMON, CLUSTER_FRAME, LSHM_FRAME],
        "node_force_mixed",
    )
}

/// `lshm_frame.wgsl::cluster_frame`: shape matching frame (centre offset and rotation).
pub fn lshm_cluster_frame(device: &wgpu::Device) -> Kernel {
    Kernel::compile(
        device,
        "lshm_frame/cluster_frame",
        &[COMMON, CLUSTER_FRAME, LSHM_FRAME],
        "cluster_frame",
    )
}

/// `lshm_cluster_force.wgsl`: cluster forces gathered per node.
pub fn lshm_cluster_force(device: &wgpu::Device) -> Kernel {
    Kernel::compile(
        device,
        "lshm_cluster_force",
        &[COMMON, LSHM_CLUSTER_FORCE],
        "main",
    )
}

/// `lshm_frame.wgsl::cluster_frame_mixed`: [`lshm_cluster_frame`], with node i's stiffness
/// in the w lane of its centre offset for [`lshm_cluster_force_mixed`].
pub fn lshm_cluster_frame_mixed(device: &wgpu::Device) -> Kernel {
    Kernel::compile(
        device,
        "lshm_frame/cluster_frame_mixed",
        &[COMMON, CLUSTER_FRAME, LSHM_FRAME],
        "cluster_frame_mixed",
    )
}

/// `lshm_cluster_force.wgsl::mixed`: [`lshm_cluster_force`] with each cluster's own
/// stiffness (from [`lshm_cluster_frame_mixed`]).
pub fn lshm_cluster_force_mixed(device: &wgpu::Device) -> Kernel {
    Kernel::compile(
        device,
        "lshm_cluster_force/mixed",
        &[COMMON, LSHM_CLUSTER_FORCE],
        "mixed",
    )
}

/// `continuum_first_pass.wgsl`: `entry` is `deb_linear`, `deb_corotated` or `pba`, or one
/// of them with `_mixed` appended (the constants of each node from `node_material`;
/// `deb_corotated_mixed` after `deb_frame`, which stores the rotations it reads).
pub fn continuum_first_pass(device: &wgpu::Device, entry: &'static str) -> Kernel {
    let name = match entry {
        "deb_linear" => "continuum_first_pass/deb_linear",
        "deb_corotated" => "continuum_first_pass/deb_corotated",
        "deb_frame" => "continuum_first_pass/deb_frame",
        "deb_linear_mixed" => "continuum_first_pass/deb_linear_mixed",
        "deb_corotated_mixed" => "continuum_first_pass/deb_corotated_mixed",
        "pba_mixed" => "continuum_first_pass/pba_mixed",
        _ => "continuum_first_pass/pba",
    };
    Kernel::compile(
        device,
        name,
        &[COMMON, CLUSTER_FRAME, CONTINUUM_FIRST_PASS],
        entry,
    )
}

/// `gather_force.wgsl`: continuum forces gathered per node.
pub fn gather_force(device: &wgpu::Device) -> Kernel {
    Kernel::compile(device, "gather_force", &[COMMON, GATHER_FORCE], "main")
}
