//! Local shape matching on the GPU: `shaders/lshm_frame.wgsl` (frame and the paper's
//! per-node force) and `shaders/lshm_cluster_force.wgsl` (the conservative cluster
//! forces), the twins of [`needlesim_core::models::local_shape_matching`].

use super::{GpuModel, MATERIAL};
use crate::buffers::Binding::{self, *};
use crate::kernels::{KernelSpec, CLUSTER_FRAME, COMMON};
use needlesim_core::models::local_shape_matching::{Shape, ShapeMatchingParams};
use needlesim_core::models::ShapeArray::{ClusterCentre, RestPosition, Rotation, ShapeVector};

const FRAME_SOURCE: &str = include_str!("../../shaders/lshm_frame.wgsl");
const CLUSTER_FORCE_SOURCE: &str = include_str!("../../shaders/lshm_cluster_force.wgsl");

/// The frame kernels' bindings, writing their result to `out`.
const fn frame(out: Binding) -> [(u32, Binding); 8] {
    [
        (0, Params),
        (1, Positions),
        (2, Model(RestPosition)),
        (3, Model(ShapeVector)),
        (4, NeighbourIndex),
        (5, NeighbourWeight),
        (6, Model(Rotation)),
        (7, out),
    ]
}

/// [`frame`] plus the node materials.
const fn frame_mixed(out: Binding) -> [(u32, Binding); 9] {
    let f = frame(out);
    [f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], MATERIAL]
}

const NODE_FORCE_BINDINGS: [(u32, Binding); 8] = frame(Forces);
const NODE_FORCE_MIXED_BINDINGS: [(u32, Binding); 9] = frame_mixed(Forces);
const CLUSTER_FRAME_BINDINGS: [(u32, Binding); 8] = frame(Model(ClusterCentre));
const CLUSTER_FRAME_MIXED_BINDINGS: [(u32, Binding); 9] = frame_mixed(Model(ClusterCentre));

/// `lshm_frame.wgsl::node_force`: the frame and the paper's per-node force
/// ([`local_shape_matching::node_force`]).
///
/// [`local_shape_matching::node_force`]: needlesim_core::models::local_shape_matching::node_force
pub const NODE_FORCE: KernelSpec = KernelSpec {
    name: "lshm_frame/node_force",
    sources: &[COMMON, CLUSTER_FRAME, FRAME_SOURCE],
    entry: "node_force",
    bindings: &NODE_FORCE_BINDINGS,
};

/// `lshm_frame.wgsl::node_force_mixed`: [`NODE_FORCE`] with each node's own stiffness.
pub const NODE_FORCE_MIXED: KernelSpec = KernelSpec {
    name: "lshm_frame/node_force_mixed",
    sources: &[COMMON, CLUSTER_FRAME, FRAME_SOURCE],
    entry: "node_force_mixed",
    bindings: &NODE_FORCE_MIXED_BINDINGS,
};

/// `lshm_frame.wgsl::cluster_frame`: centre offset and rotation of every cluster
/// ([`local_shape_matching::cluster_frame`]).
///
/// [`local_shape_matching::cluster_frame`]: needlesim_core::models::local_shape_matching::cluster_frame
pub const FRAME: KernelSpec = KernelSpec {
    name: "lshm_frame/cluster_frame",
    sources: &[COMMON, CLUSTER_FRAME, FRAME_SOURCE],
    entry: "cluster_frame",
    bindings: &CLUSTER_FRAME_BINDINGS,
};

/// `lshm_frame.wgsl::cluster_frame_mixed`: [`FRAME`], with node i's stiffness in the w
/// lane of its centre offset for [`CLUSTER_FORCE_MIXED`].
pub const FRAME_MIXED: KernelSpec = KernelSpec {
    name: "lshm_frame/cluster_frame_mixed",
    sources: &[COMMON, CLUSTER_FRAME, FRAME_SOURCE],
    entry: "cluster_frame_mixed",
    bindings: &CLUSTER_FRAME_MIXED_BINDINGS,
};

const CLUSTER_FORCE_BINDINGS: [(u32, Binding); 9] = [
    (0, Params),
    (1, Positions),
    (2, Model(RestPosition)),
    (3, Model(ShapeVector)),
    (4, NeighbourIndex),
    (5, NeighbourWeight),
    (6, Model(Rotation)),
    (7, Model(ClusterCentre)),
    (8, Forces),
];

/// `lshm_cluster_force.wgsl::main`: the cluster forces gathered per node
/// ([`local_shape_matching::cluster_force`]).
///
/// [`local_shape_matching::cluster_force`]: needlesim_core::models::local_shape_matching::cluster_force
pub const CLUSTER_FORCE: KernelSpec = KernelSpec {
    name: "lshm_cluster_force",
    sources: &[COMMON, CLUSTER_FORCE_SOURCE],
    entry: "main",
    bindings: &CLUSTER_FORCE_BINDINGS,
};

/// `lshm_cluster_force.wgsl::mixed`: [`CLUSTER_FORCE`] with each cluster's own stiffness
/// (from [`FRAME_MIXED`]).
pub const CLUSTER_FORCE_MIXED: KernelSpec = KernelSpec {
    name: "lshm_cluster_force/mixed",
    sources: &[COMMON, CLUSTER_FORCE_SOURCE],
    entry: "mixed",
    bindings: &CLUSTER_FORCE_BINDINGS,
};

impl GpuModel for ShapeMatchingParams {
    const KERNELS: &'static [&'static KernelSpec] = &[
        &NODE_FORCE,
        &NODE_FORCE_MIXED,
        &FRAME,
        &FRAME_MIXED,
        &CLUSTER_FORCE,
        &CLUSTER_FORCE_MIXED,
    ];

    fn write_params(&self, params: &mut crate::params::Params) {
        params.stiffness = self.stiffness as f32;
        params.iterations = self.rotation_iterations;
    }

    fn force_kernels(shape: &Shape, mixed: bool) -> Vec<&'static KernelSpec> {
        match (shape.cluster_centre.is_some(), mixed) {
            (false, false) => vec![&NODE_FORCE],
            (false, true) => vec![&NODE_FORCE_MIXED],
            (true, false) => vec![&FRAME, &CLUSTER_FORCE],
            (true, true) => vec![&FRAME_MIXED, &CLUSTER_FORCE_MIXED],
        }
    }
}
