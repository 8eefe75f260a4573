//! The GPU backend: the tissue's arrays in storage buffers sized for the capacity, the
//! chosen model's kernels, and the [`Backend`] operations (batched steps without readback,
//! range reads and writes, neighbour rows).

use crate::context::{GpuContext, GpuError};
use crate::kernels::{self, Kernel, WORKGROUP};
use bytemuck::{Pod, Zeroable};
use needlesim_core::backend::{check_range, check_rows, check_shape_write};
use needlesim_core::models::mls::ContinuumConstants;
use needlesim_core::models::{ShapeArray, ShapeInfo};
use needlesim_core::scene::{DebunneParams, MassSpringParams, Material, ShapeMatchingParams};
use needlesim_core::{Backend, NodeField, SimError, Tissue, Vec4};
use std::ops::Range;
use wgpu::util::DeviceExt;

/// The uniform parameter block (`Params` in the top-level `shaders/common.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Params {
    n_active: u32,
    k: u32,
    iterations: u32,
    groups_x: u32,
    dt: f32,
    damping_factor: f32,
    stiffness: f32,
    spring_damping: f32,
    gravity: [f32; 4],
    lambda: f32,
    mu: f32,
    volume_stiffness: f32,
    hourglass: f32,
    pad: [f32; 4],
}

/// Steps recorded per command buffer by [`Backend::step`].
const STEPS_PER_SUBMIT: u64 = 200;

/// The simulation's buffers, apart from the kernels that use them.
#[derive(Debug)]
pub struct Buffers {
    params: wgpu::Buffer,
    positions: wgpu::Buffer,
    velocities: wgpu::Buffer,
    forces: wgpu::Buffer,
    nb_index: wgpu::Buffer,
    nb_weight: wgpu::Buffer,
    /// The model's arrays (those of `ShapeInfo::bytes`).
    model: Vec<(ShapeArray, wgpu::Buffer)>,
    readback: wgpu::Buffer,
}

impl Buffers {
    /// The buffer of `array`. The force passes ask only for arrays their model's
    /// `ShapeInfo` variant holds, which every buffer set is built from.
    fn model(&self, array: ShapeArray) -> &wgpu::Buffer {
        let found = self.model.iter().find(|(a, _)| *a == array);
        &found.expect("the passes bind only their model's arrays").1
    }

    /// Bytes of every buffer, by name.
    pub fn sizes(&self) -> Vec<(&'static str, u64)> {
        let mut v = vec![
            ("position", self.positions.size()),
            ("velocity", self.velocities.size()),
            ("force", self.forces.size()),
            ("neighbour_index", self.nb_index.size()),
            ("neighbour_weight", self.nb_weight.size()),
        ];
        v.extend(self.model.iter().map(|(a, b)| (a.name(), b.size())));
        v
    }
}

/// A kernel with its bind group.
#[derive(Debug)]
struct Pass {
    kernel: Kernel,
    bind: wgpu::BindGroup,
}

/// The tissue stepped by wgpu compute shaders.
#[derive(Debug)]
pub struct GpuBackend {
    ctx: GpuContext,
    buffers: Buffers,
    force_passes: Vec<Pass>,
    integrate: Pass,
    params: Params,
    capacity: usize,
    steps: u64,
    max_groups_x: u32,
}

fn storage(device: &wgpu::Device, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
    })
}

/// Bytes of the largest buffer the tissue needs (for [`GpuContext::new`]).
pub fn largest_buffer(tissue: &Tissue) -> u64 {
    tissue
        .allocations()
        .iter()
        .map(|a| a.bytes as u64)
        .max()
        .unwrap_or(0)
}

impl GpuBackend {
    /// Creates a device for `tissue` ([`GpuContext::new`]) and uploads it.
    pub fn new(tissue: &Tissue) -> Result<GpuBackend, GpuError> {
        let ctx = GpuContext::new(largest_buffer(tissue))?;
        GpuBackend::with_context(ctx, tissue)
    }

    /// Uploads `tissue` to an existing device and compiles only its model's kernels.
    pub fn with_context(ctx: GpuContext, tissue: &Tissue) -> Result<GpuBackend, GpuError> {
        let device = &ctx.device;
        let limits = device.limits();
        for a in tissue.allocations() {
            if a.bytes as u64 > limits.max_storage_buffer_binding_size {
                return Err(GpuError::TooLarge {
                    buffer: a.name,
                    needed: a.bytes as u64,
                    allowed: limits.max_storage_buffer_binding_size,
                    adapter: ctx.adapter.name.clone(),
                });
            }
        }
        let st = &tissue.state;
        let capacity = st.capacity();
        let nb = &tissue.neighbours;
        let step = &tissue.step;
        let mut params = Params {
            n_active: 0,
            k: nb.k as u32,
            iterations: 0,
            groups_x: 1,
            dt: step.dt,
            damping_factor: step.damping_factor,
            stiffness: 0.0,
            spring_damping: 0.0,
            gravity: [step.gravity[0], step.gravity[1], step.gravity[2], 0.0],
            lambda: 0.0,
            mu: 0.0,
            volume_stiffness: 0.0,
            hourglass: 0.0,
            pad: [0.0; 4],
        };
        let b = |label, bytes: &[u8]| storage(device, label, bytes);
        let model: Vec<(ShapeArray, wgpu::Buffer)> = tissue
            .shape
            .bytes()
            .into_iter()
            .map(|(array, bytes)| (array, b(array.name(), bytes)))
            .collect();
        match tissue.material {
            Material::MassSpring(MassSpringParams {
                stiffness,
                spring_damping,
                ..
            }) => {
                params.stiffness = stiffness as f32;
                params.spring_damping = spring_damping as f32;
            }
            Material::LocalShapeMatching(ShapeMatchingParams {
                stiffness,
                rotation_iterations,
                ..
            }) => {
                params.stiffness = stiffness as f32;
                params.iterations = rotation_iterations;
            }
            Material::DebunneMeshfree(DebunneParams {
                rotation_iterations,
                ..
            }) => params.iterations = rotation_iterations,
            Material::PointBased(_) => {}
        }
        if let Some(c) = ContinuumConstants::of(&tissue.material) {
            params.lambda = c.lambda;
            params.mu = c.mu;
            params.volume_stiffness = c.volume_stiffness;
            params.hourglass = c.hourglass;
        }
        let buffers = Buffers {
            params: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            }),
            positions: b("positions", bytemuck::cast_slice(&st.positions)),
            velocities: b("velocities", bytemuck::cast_slice(&st.velocities)),
            forces: b("forces", bytemuck::cast_slice(&st.forces)),
            nb_index: b("neighbour_index", bytemuck::cast_slice(&nb.index)),
            nb_weight: b("neighbour_weight", bytemuck::cast_slice(&nb.weight)),
            model,
            readback: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: (capacity.max(1) * 16) as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        let force_passes = force_passes(device, &tissue.shape, &buffers);
        let integrate = {
            let kernel = kernels::integrate(device);
            let bu = &buffers;
            let bind = kernel.bind(
                device,
                &[
                    (0, &bu.params),
                    (1, &bu.positions),
                    (2, &bu.velocities),
                    (3, &bu.forces),
                ],
            );
            Pass { kernel, bind }
        };
        let mut backend = GpuBackend {
            max_groups_x: device.limits().max_compute_workgroups_per_dimension,
            ctx,
            buffers,
            force_passes,
            integrate,
            params,
            capacity,
            steps: 0,
        };
        backend
            .set_n_active(st.n_active)
            .expect("tissue's n_active within its capacity");
        Ok(backend)
    }

    /// The adapter, its driver and API.
    pub fn adapter(&self) -> String {
        self.ctx.describe()
    }

    /// The device buffers (sizes, for reports).
    pub fn buffers(&self) -> &Buffers {
        &self.buffers
    }

    /// Caps the workgroups per dispatch along x (for tests of the 2D dispatch that large
    /// scenes need); the default is the device limit.
    pub fn set_max_groups_x(&mut self, max: u32) {
        self.max_groups_x = max.max(1);
        let n = self.params.n_active as usize;
        self.set_n_active(n).expect("unchanged node count");
    }

    fn groups(&self) -> (u32, u32) {
        let n = self.params.n_active.div_ceil(WORKGROUP);
        let x = n.min(self.max_groups_x).max(1);
        (x, n.div_ceil(x))
    }

    fn record(&self, encoder: &mut wgpu::CommandEncoder, steps: u64, integrate: bool) {
        if self.params.n_active == 0 {
            return;
        }
        let groups = self.groups();
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("step"),
            timestamp_writes: None,
        });
        for _ in 0..steps {
            for p in &self.force_passes {
                p.kernel.dispatch(&mut pass, &p.bind, groups);
            }
            if integrate {
                self.integrate
                    .kernel
                    .dispatch(&mut pass, &self.integrate.bind, groups);
            }
        }
    }

    fn submit(&self, steps: u64, integrate: bool) {
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("steps"),
            });
        self.record(&mut encoder, steps, integrate);
        self.ctx.queue.submit([encoder.finish()]);
    }

    /// Copies runs `(first node, count)` of `field` into `out`, back to back.
    fn gather(
        &self,
        field: NodeField,
        runs: &[(usize, usize)],
        out: &mut [Vec4],
    ) -> Result<(), SimError> {
        let buffer = self.field(field);
        let copies: Vec<_> = runs
            .iter()
            .map(|&(first, count)| (buffer, (first * 16) as u64, (count * 16) as u64))
            .collect();
        self.copy_out(&copies, bytemuck::cast_slice_mut(out))
    }

    /// Copies `(buffer, byte offset, bytes)` pieces back to back into `out` through the
    /// readback buffer, in one submit and one mapping (the pieces must fit in it).
    fn copy_out(
        &self,
        copies: &[(&wgpu::Buffer, u64, u64)],
        out: &mut [u8],
    ) -> Result<(), SimError> {
        let bytes: u64 = copies.iter().map(|c| c.2).sum();
        if bytes == 0 {
            return Ok(());
        }
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("read"),
            });
        let mut at = 0u64;
        for &(buffer, offset, len) in copies {
            encoder.copy_buffer_to_buffer(buffer, offset, &self.buffers.readback, at, len);
            at += len;
        }
        self.ctx.queue.submit([encoder.finish()]);
        let slice = self.buffers.readback.slice(..bytes);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait();
        match rx.recv() {
            Ok(Ok(())) => {}
            other => {
                return Err(SimError::Device {
                    message: format!("mapping the readback buffer failed: {other:?}"),
                })
            }
        }
        {
            let view = slice.get_mapped_range().map_err(|e| SimError::Device {
                message: format!("reading the readback buffer failed: {e}"),
            })?;
            out.copy_from_slice(&view);
        }
        self.buffers.readback.unmap();
        Ok(())
    }

    fn field(&self, field: NodeField) -> &wgpu::Buffer {
        match field {
            NodeField::Position => &self.buffers.positions,
            NodeField::Velocity => &self.buffers.velocities,
            NodeField::Force => &self.buffers.forces,
        }
    }

    /// Waits until the device has finished all submitted work.
    pub fn wait(&self) {
        let _ = self.ctx.device.poll(wgpu::PollType::wait_indefinitely());
    }
}

/// The force kernels of the tissue's model, in order, bound to `b`.
fn force_passes(device: &wgpu::Device, shape: &ShapeInfo, b: &Buffers) -> Vec<Pass> {
    let pass = |kernel: Kernel, entries: &[(u32, &wgpu::Buffer)]| {
        let bind = kernel.bind(device, entries);
        Pass { kernel, bind }
    };
    match shape {
        ShapeInfo::MassSpring { .. } => vec![pass(
            kernels::mass_spring(device),
            &[
                (0, &b.params),
                (1, &b.positions),
                (2, &b.velocities),
                (3, &b.nb_index),
                (4, &b.nb_weight),
                (5, b.model(ShapeArray::RestLength)),
                (6, &b.forces),
            ],
        )],
        ShapeInfo::LocalShapeMatching { cluster_centre, .. } => {
            let frame = |kernel: Kernel, out: &wgpu::Buffer| {
                pass(
                    kernel,
                    &[
                        (0, &b.params),
                        (1, &b.positions),
                        (2, b.model(ShapeArray::RestPosition)),
                        (3, b.model(ShapeArray::ShapeVector)),
                        (4, &b.nb_index),
                        (5, &b.nb_weight),
                        (6, b.model(ShapeArray::Rotation)),
                        (7, out),
                    ],
                )
            };
            match cluster_centre {
                None => vec![frame(kernels::lshm_node_force(device), &b.forces)],
                Some(_) => vec![
                    frame(
                        kernels::lshm_cluster_frame(device),
                        b.model(ShapeArray::ClusterCentre),
                    ),
                    pass(
                        kernels::lshm_cluster_force(device),
                        &[
                            (0, &b.params),
                            (1, &b.positions),
                            (2, b.model(ShapeArray::RestPosition)),
                            (3, b.model(ShapeArray::ShapeVector)),
                            (4, &b.nb_index),
                            (5, &b.nb_weight),
                            (6, b.model(ShapeArray::Rotation)),
                            (7, b.model(ShapeArray::ClusterCentre)),
                            (8, &b.forces),
                        ],
                    ),
                ],
            }
        }
        ShapeInfo::DebunneMeshfree { .. } | ShapeInfo::PointBased { .. } => {
            let corotated = matches!(
                shape,
                ShapeInfo::DebunneMeshfree {
                    corotation: Some(_),
                    ..
                }
            );
            let mut entries = vec![
                (0, &b.params),
                (1, &b.positions),
                (2, b.model(ShapeArray::RestPosition)),
                (3, &b.nb_index),
                (4, &b.nb_weight),
                (5, b.model(ShapeArray::InverseMoment)),
                (6, b.model(ShapeArray::FirstPass)),
            ];
            let entry = match shape {
                ShapeInfo::PointBased { .. } => "pba",
                _ if corotated => {
                    entries.push((8, b.model(ShapeArray::ShapeVector)));
                    entries.push((9, b.model(ShapeArray::Rotation)));
                    "deb_corotated"
                }
                _ => "deb_linear",
            };
            vec![
                pass(kernels::continuum_first_pass(device, entry), &entries),
                pass(
                    kernels::gather_force(device),
                    &[
                        (0, &b.params),
                        (1, &b.positions),
                        (2, b.model(ShapeArray::RestPosition)),
                        (3, &b.nb_index),
                        (4, &b.nb_weight),
                        (5, b.model(ShapeArray::FirstPass)),
                        (6, &b.forces),
                    ],
                ),
            ]
        }
    }
}

impl Backend for GpuBackend {
    fn name(&self) -> String {
        format!("gpu ({})", self.ctx.adapter.name)
    }

    fn capacity(&self) -> usize {
        self.capacity
    }

    fn n_active(&self) -> usize {
        self.params.n_active as usize
    }

    fn set_n_active(&mut self, n: usize) -> Result<(), SimError> {
        check_range(&(0..n), self.capacity, "allocated")?;
        self.params.n_active = n as u32;
        self.params.groups_x = self.groups().0;
        self.ctx
            .queue
            .write_buffer(&self.buffers.params, 0, bytemuck::bytes_of(&self.params));
        Ok(())
    }

    fn compute_forces(&mut self) {
        self.submit(1, false);
    }

    fn integrate(&mut self) {
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("integrate"),
            });
        if self.params.n_active > 0 {
            let groups = self.groups();
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("integrate"),
                timestamp_writes: None,
            });
            self.integrate
                .kernel
                .dispatch(&mut pass, &self.integrate.bind, groups);
        }
        self.ctx.queue.submit([encoder.finish()]);
        self.steps += 1;
    }

    /// Records up to 200 steps per command buffer and submits them without waiting or
    /// reading anything back.
    fn step(&mut self, n: u64) {
        let mut left = n;
        while left > 0 {
            let batch = left.min(STEPS_PER_SUBMIT);
            self.submit(batch, true);
            left -= batch;
        }
        self.steps += n;
    }

    fn steps_taken(&self) -> u64 {
        self.steps
    }

    fn set_steps_taken(&mut self, steps: u64) {
        self.steps = steps;
    }

    fn finish(&mut self) {
        self.wait();
    }

    fn read(
        &mut self,
        field: NodeField,
        range: Range<usize>,
        out: &mut [Vec4],
    ) -> Result<(), SimError> {
        check_range(&range, self.capacity, "allocated")?;
        self.gather(field, &[(range.start, range.len())], out)
    }

    /// One copy per run of consecutive nodes, one submit, one mapping.
    fn read_nodes(
        &mut self,
        field: NodeField,
        nodes: &[u32],
        out: &mut [Vec4],
    ) -> Result<(), SimError> {
        needlesim_core::backend::check_gather(nodes, out)?;
        if nodes.len() > self.capacity {
            // The readback buffer holds `capacity` nodes: read in pieces.
            let c = self.capacity;
            for (n, o) in nodes.chunks(c).zip(out.chunks_mut(c)) {
                self.read_nodes(field, n, o)?;
            }
            return Ok(());
        }
        let mut runs: Vec<(usize, usize)> = Vec::new();
        for &i in nodes {
            let i = i as usize;
            check_range(&(i..i + 1), self.capacity, "allocated")?;
            match runs.last_mut() {
                Some((s, n)) if *s + *n == i => *n += 1,
                _ => runs.push((i, 1)),
            }
        }
        self.gather(field, &runs, out)
    }

    fn write(&mut self, field: NodeField, first: usize, data: &[Vec4]) -> Result<(), SimError> {
        check_range(&(first..first + data.len()), self.capacity, "allocated")?;
        self.ctx.queue.write_buffer(
            self.field(field),
            (first * 16) as u64,
            bytemuck::cast_slice(data),
        );
        Ok(())
    }

    fn write_neighbour_rows(
        &mut self,
        first: usize,
        index: &[u32],
        weight: &[f32],
    ) -> Result<(), SimError> {
        let k = self.params.k as usize;
        check_rows(first, index, weight, k, self.capacity)?;
        let offset = (first * k * 4) as u64;
        let q = &self.ctx.queue;
        q.write_buffer(&self.buffers.nb_index, offset, bytemuck::cast_slice(index));
        q.write_buffer(
            &self.buffers.nb_weight,
            offset,
            bytemuck::cast_slice(weight),
        );
        Ok(())
    }

    fn write_shape_bytes(
        &mut self,
        array: ShapeArray,
        offset: usize,
        data: &[u8],
    ) -> Result<(), SimError> {
        let target = self.buffers.model.iter().find(|(n, _)| *n == array);
        check_shape_write(
            array,
            offset,
            data.len(),
            target.map(|(_, b)| b.size() as usize),
        )?;
        if let Some((_, buffer)) = target {
            if !data.is_empty() {
                self.ctx.queue.write_buffer(buffer, offset as u64, data);
            }
        }
        Ok(())
    }

    /// Reads in pieces of the readback buffer's size.
    fn read_shape_bytes(
        &mut self,
        array: ShapeArray,
        offset: usize,
        out: &mut [u8],
    ) -> Result<(), SimError> {
        let source = self.buffers.model.iter().find(|(n, _)| *n == array);
        check_shape_write(
            array,
            offset,
            out.len(),
            source.map(|(_, b)| b.size() as usize),
        )?;
        let Some((_, buffer)) = source else {
            return Ok(());
        };
        // A multiple of 4, as copies must be (the buffer holds at least one node, 16 bytes).
        let piece = (self.buffers.readback.size() as usize) & !3;
        for (k, chunk) in out.chunks_mut(piece).enumerate() {
            let at = (offset + k * piece) as u64;
            self.copy_out(&[(buffer, at, chunk.len() as u64)], chunk)?;
        }
        Ok(())
    }
}
