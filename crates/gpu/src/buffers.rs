//! The simulation's device buffers, named for the kernels that bind them.

use needlesim_core::models::ShapeArray;
use wgpu::util::DeviceExt;

/// What a kernel binds: one of the simulation's buffers or one of the model's arrays.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Binding {
    /// The uniform parameter block (`Params` in `shaders/common.wgsl`).
    Params,
    /// Node positions.
    Positions,
    /// Node velocities.
    Velocities,
    /// Node forces.
    Forces,
    /// The integrator's position remainders (`needlesim_core::integrator`).
    PositionRemainders,
    /// Neighbour indices, K per node.
    NeighbourIndex,
    /// Neighbour weights, K per node.
    NeighbourWeight,
    /// A shape information array of the model.
    Model(ShapeArray),
    /// The divergence guard's flag (one `u32`, set by the integration).
    Guard,
}

/// The simulation's buffers, apart from the kernels that use them.
#[derive(Debug)]
pub struct Buffers {
    pub(crate) params: wgpu::Buffer,
    pub(crate) positions: wgpu::Buffer,
    pub(crate) velocities: wgpu::Buffer,
    pub(crate) forces: wgpu::Buffer,
    pub(crate) position_remainders: wgpu::Buffer,
    pub(crate) nb_index: wgpu::Buffer,
    pub(crate) nb_weight: wgpu::Buffer,
    /// The model's arrays (those of `ShapeInfo::bytes`).
    pub(crate) model: Vec<(ShapeArray, wgpu::Buffer)>,
    pub(crate) readback: wgpu::Buffer,
    /// The divergence guard's flag: nonzero once the integration met a non-finite node
    /// or one faster than `Params::max_speed_sq` (16 bytes; the first word is the flag).
    pub(crate) guard: wgpu::Buffer,
}

impl Buffers {
    /// The buffer of `binding`. The passes of a model bind only arrays its shape
    /// information holds, which every buffer set is built from.
    pub(crate) fn get(&self, binding: Binding) -> &wgpu::Buffer {
        match binding {
            Binding::Params => &self.params,
            Binding::Positions => &self.positions,
            Binding::Velocities => &self.velocities,
            Binding::Forces => &self.forces,
            Binding::PositionRemainders => &self.position_remainders,
            Binding::NeighbourIndex => &self.nb_index,
            Binding::NeighbourWeight => &self.nb_weight,
            Binding::Guard => &self.guard,
            Binding::Model(array) => {
                let found = self.model.iter().find(|(a, _)| *a == array);
                &found.expect("the passes bind only their model's arrays").1
            }
        }
    }

    /// Bytes of every buffer, by name.
    pub fn sizes(&self) -> Vec<(&'static str, u64)> {
        let mut v = vec![
            ("position", self.positions.size()),
            ("velocity", self.velocities.size()),
            ("force", self.forces.size()),
            ("position_remainder", self.position_remainders.size()),
            ("neighbour_index", self.nb_index.size()),
            ("neighbour_weight", self.nb_weight.size()),
        ];
        v.extend(self.model.iter().map(|(a, b)| (a.name(), b.size())));
        v
    }
}

/// A storage buffer holding `bytes`, readable and writable by copies.
pub(crate) fn storage(device: &wgpu::Device, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
    })
}
