//! The GPU backend: the tissue's arrays in storage buffers sized for the capacity, the
//! chosen model's kernels, and the [`Backend`] operations (batched steps without readback,
//! range reads and writes, neighbour rows), with a count of blocking readbacks and opt-in
//! per-kernel timestamps ([`GpuBackend::enable_profiling`]).

use crate::buffers::{storage, Binding, Buffers};
use crate::context::{GpuContext, GpuError};
use crate::kernels::{self, Pass, WORKGROUP};
use crate::layout;
use crate::params::Params;
use crate::profile::{map_read, KernelTime, Profiler};
use crate::scatter::{Scatter, DIRECT_RUN, DIRECT_WORDS};
use needlesim_core::backend::{check_many, check_range, check_rows, check_shape_write};
use needlesim_core::frame::PositionFrame;
use needlesim_core::models::mls::ViscoRow;
use needlesim_core::models::ShapeArray;
use needlesim_core::{Backend, NodeField, NodeSelection, SimError, Tissue, Vec4};
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use wgpu::util::DeviceExt;

/// Steps recorded per command buffer by [`Backend::step`].
const STEPS_PER_SUBMIT: u64 = 200;

/// One piece of a readback: `bytes.len()` bytes from byte `offset` of a device buffer.
type Piece<'a> = (&'a wgpu::Buffer, u64, &'a mut [u8]);

/// The tissue stepped by wgpu compute shaders.
#[derive(Debug)]
pub struct GpuBackend {
    ctx: GpuContext,
    buffers: Buffers,
    force_passes: Vec<Pass>,
    integrate: Pass,
    /// Kernels after the integration (the viscoelastic commit).
    end_step: Vec<Pass>,
    params: Params,
    capacity: usize,
    steps: u64,
    max_groups_x: u32,
    /// Blocking readbacks so far ([`Backend::readbacks`]).
    readbacks: AtomicU64,
    /// Timestamps per kernel, once profiling was enabled.
    profiler: Option<Profiler>,
    /// The frame the positions buffer holds ([`needlesim_core::frame`]).
    frame: PositionFrame,
    /// Row edits waiting for the next submit or readback ([`crate::scatter`]).
    scatter: Mutex<Scatter>,
    /// Where a local force evaluation keeps the warm-start rotations while it runs
    /// ([`Backend::compute_forces_on`]; co-rotated Debunne only).
    warm_starts: Option<wgpu::Buffer>,
}

/// The device buffers the tissue needs, by name: its arrays, with the viscoelastic
/// state's two copies in one buffer (`mls.wgsl::visco`).
fn device_allocations(tissue: &Tissue) -> Vec<needlesim_core::models::ArrayInfo> {
    let mut out = tissue.allocations();
    let next = out
        .iter()
        .position(|a| a.name == needlesim_core::models::VISCOUS_NEXT);
    if let Some(k) = next {
        let extra = out.remove(k).bytes;
        if let Some(v) = out
            .iter_mut()
            .find(|a| a.name == ShapeArray::Viscous.name())
        {
            v.bytes += extra;
        }
    }
    out
}

/// Floats of one node's viscoelastic state row (`mls.wgsl::VISCO_ROW`).
const VISCO_ROW: usize = std::mem::size_of::<ViscoRow>() / 4;

/// Refuses what the kernels do not compute (rather than running it elastic).
fn check_supported(tissue: &Tissue) -> Result<(), GpuError> {
    match crate::models::unsupported(&tissue.shape) {
        Some(feature) => Err(GpuError::Unsupported { feature }),
        None => Ok(()),
    }
}

/// Bytes of the largest buffer the tissue needs (for [`GpuContext::new`]).
pub fn largest_buffer(tissue: &Tissue) -> u64 {
    device_allocations(tissue)
        .iter()
        .map(|a| a.bytes as u64)
        .max()
        .unwrap_or(0)
}

impl GpuBackend {
    /// Creates a device for `tissue` ([`GpuContext::new`]) and uploads it.
    pub fn new(tissue: &Tissue) -> Result<GpuBackend, GpuError> {
        check_supported(tissue)?;
        let ctx = GpuContext::new(largest_buffer(tissue))?;
        GpuBackend::with_context(ctx, tissue)
    }

    /// Uploads `tissue` to an existing device and compiles only its model's kernels.
    pub fn with_context(ctx: GpuContext, tissue: &Tissue) -> Result<GpuBackend, GpuError> {
        check_supported(tissue)?;
        let device = &ctx.device;
        let limits = device.limits();
        for a in device_allocations(tissue) {
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
        let frame = tissue.frame;
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
            gravity: [step.gravity[0], step.gravity[1], step.gravity[2], 1.0],
            lambda: 0.0,
            mu: 0.0,
            volume_stiffness: 0.0,
            hourglass: 0.0,
            slot_stride: capacity as u32,
            visco_terms: 0,
            visco_g_inf: 1.0,
            max_speed_sq: f32::INFINITY,
            visco_a: [0.0; 4],
            visco_b: [0.0; 4],
            viscosity: 0.0,
            hourglass_alpha: 0.0,
            pad: [0.0; 2],
        };
        let b = |label, bytes: &[u8]| storage(device, label, bytes);
        let model: Vec<(ShapeArray, wgpu::Buffer)> = tissue
            .shape
            .bytes()
            .into_iter()
            .map(|(array, bytes)| {
                let buffer = if array.per_slot() {
                    b(array.name(), &layout::to_slot_major(bytes, nb.k, capacity))
                } else if array == ShapeArray::Viscous {
                    // Component-major like the per-slot arrays (a warp's threads read
                    // adjacent words), the committed rows, then as many for the next
                    // state (mls.wgsl).
                    let rows = layout::to_slot_major(bytes, VISCO_ROW, capacity);
                    b(
                        array.name(),
                        &[rows.as_slice(), &vec![0u8; rows.len()]].concat(),
                    )
                } else {
                    b(array.name(), bytes)
                };
                (array, buffer)
            })
            .collect();
        crate::models::write_params(&tissue.material, &mut params);
        let buffers = Buffers {
            params: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            }),
            positions: b("positions", bytemuck::cast_slice(&st.positions)),
            velocities: b("velocities", bytemuck::cast_slice(&st.velocities)),
            forces: b("forces", bytemuck::cast_slice(&st.forces)),
            position_remainders: b(
                "position_remainders",
                bytemuck::cast_slice(&st.position_remainders),
            ),
            nb_index: b(
                "neighbour_index",
                &layout::to_slot_major(bytemuck::cast_slice(&nb.index), nb.k, capacity),
            ),
            nb_weight: b(
                "neighbour_weight",
                &layout::to_slot_major(bytemuck::cast_slice(&nb.weight), nb.k, capacity),
            ),
            model,
            readback: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: (capacity.max(1) * 16) as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            guard: b("guard", &[0u8; 16]),
        };
        let force_passes = crate::models::force_passes(device, &tissue.shape, &buffers);
        let integrate = kernels::INTEGRATE_NODE.pass(device, &buffers);
        let end_step = crate::models::end_step_passes(device, &tissue.shape, &buffers);
        let scatter = Mutex::new(Scatter::new(device));
        let warm_starts = tissue.shape.rotation_is_warm_start().then(|| {
            let size = buffers.get(Binding::Model(ShapeArray::Rotation)).size();
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("warm_starts"),
                size,
                usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        });
        let mut backend = GpuBackend {
            max_groups_x: device.limits().max_compute_workgroups_per_dimension,
            ctx,
            buffers,
            force_passes,
            integrate,
            end_step,
            params,
            capacity,
            steps: 0,
            readbacks: AtomicU64::new(0),
            profiler: None,
            frame,
            scatter,
            warm_starts,
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

    /// Records `steps` times the force kernels (if `forces`) and the integration (if
    /// `integrate`): all in one compute pass, or, while profiling, one pass per dispatch
    /// with a timestamp at its beginning and end.
    fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        steps: u64,
        forces: bool,
        integrate: bool,
    ) {
        if self.params.n_active == 0 {
            return;
        }
        let groups = self.groups();
        let n_force = self.force_passes.len();
        let kernels = || {
            let force = self
                .force_passes
                .iter()
                .take(if forces { n_force } else { 0 });
            let last = integrate
                .then_some(std::iter::once(&self.integrate).chain(&self.end_step))
                .into_iter()
                .flatten();
            force.chain(last).enumerate().map(move |(k, p)| {
                // The integration's index is after the force kernels'.
                let id = if forces { k } else { n_force + k };
                (id, p)
            })
        };
        let Some(profiler) = self.profiler.as_mut().filter(|p| p.on) else {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("step"),
                timestamp_writes: None,
            });
            for _ in 0..steps {
                for (_, p) in kernels() {
                    p.kernel.dispatch(&mut pass, &p.bind, groups);
                }
            }
            return;
        };
        let per_step = kernels().count() as u64;
        profiler.reserve(&self.ctx.device, steps * per_step, &self.readbacks);
        for _ in 0..steps {
            for (id, p) in kernels() {
                let writes = profiler.next(encoder, id);
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(p.kernel.name),
                    timestamp_writes: Some(writes),
                });
                p.kernel.dispatch(&mut pass, &p.bind, groups);
            }
        }
        profiler.flush(encoder);
    }

    fn submit(&mut self, steps: u64, forces: bool, integrate: bool) {
        let mut encoder = self.encoder("steps");
        self.record(&mut encoder, steps, forces, integrate);
        self.ctx.queue.submit([encoder.finish()]);
    }

    /// Whether the device can time kernels (wgpu's `TIMESTAMP_QUERY` feature, which
    /// [`GpuContext::new`] asks for where the adapter has it).
    pub fn profiling_supported(&self) -> bool {
        self.ctx
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Turns per-kernel GPU timing on or off. While on, every dispatch runs in its own
    /// compute pass with timestamps at its beginning and end (the results are the same;
    /// batched steps lose a little speed to the extra passes); the timestamps stay on the
    /// device until [`GpuBackend::kernel_times`] reads them (or, every 8192 dispatches, the
    /// log they go to is full and is read back: one readback). Off, the default, nothing is
    /// recorded and stepping is unchanged. Times collected so far are kept when it is
    /// turned off. An error, and nothing changed, when the device cannot time kernels.
    pub fn enable_profiling(&mut self, on: bool) -> Result<(), GpuError> {
        if !on {
            if let Some(p) = &mut self.profiler {
                p.on = false;
            }
            return Ok(());
        }
        if !self.profiling_supported() {
            return Err(GpuError::ProfilingUnsupported {
                adapter: self.ctx.adapter.name.clone(),
            });
        }
        let kernels = self.force_passes.len() + 1 + self.end_step.len();
        let (device, queue) = (&self.ctx.device, &self.ctx.queue);
        let p = self.profiler.get_or_insert_with(|| {
            Profiler::new(device, queue, kernels, STEPS_PER_SUBMIT * kernels as u64)
        });
        p.on = true;
        Ok(())
    }

    /// Whether kernels are being timed ([`GpuBackend::enable_profiling`]).
    pub fn profiling(&self) -> bool {
        self.profiler.as_ref().is_some_and(|p| p.on)
    }

    /// GPU time per kernel since profiling was first enabled or last reset: one entry per
    /// kernel of the model, the force kernels in order, then `integrate` and the kernels
    /// that end a step (zero dispatches for a kernel not run while profiling). Waits for
    /// the submitted work and reads the timestamps back (one readback). [`GpuError::ProfilingUnsupported`] when the device
    /// cannot time kernels; [`GpuError::Readback`] when reading the timestamps failed.
    pub fn kernel_times(&mut self) -> Result<Vec<KernelTime>, GpuError> {
        if !self.profiling_supported() {
            return Err(GpuError::ProfilingUnsupported {
                adapter: self.ctx.adapter.name.clone(),
            });
        }
        let names: Vec<&'static str> = self
            .force_passes
            .iter()
            .chain([&self.integrate])
            .chain(&self.end_step)
            .map(|p| p.kernel.name)
            .collect();
        match &mut self.profiler {
            Some(p) => p
                .times(&self.ctx.device, &names, &self.readbacks)
                .map_err(GpuError::Readback),
            None => Ok(names
                .into_iter()
                .map(|name| KernelTime {
                    name,
                    dispatches: 0,
                    total_ms: 0.0,
                    mean_ms: 0.0,
                })
                .collect()),
        }
    }

    /// Forgets the kernel times collected so far (profiling stays on or off).
    pub fn reset_kernel_times(&mut self) {
        if let Some(p) = &mut self.profiler {
            p.reset();
        }
    }

    /// The pieces that copy `nodes` of `field` into `out` back to back: one per run of
    /// consecutive nodes. Errs on a node outside the allocated ones.
    fn pieces<'a>(
        &'a self,
        field: NodeField,
        nodes: &NodeSelection<'_>,
        out: &'a mut [Vec4],
        pieces: &mut Vec<Piece<'a>>,
    ) -> Result<(), SimError> {
        let mut runs: Vec<(usize, usize)> = Vec::new();
        match nodes {
            NodeSelection::Range(r) => {
                check_range(r, self.capacity, "allocated")?;
                runs.push((r.start, r.len()));
            }
            NodeSelection::List(list) => {
                for &i in list.iter() {
                    let i = i as usize;
                    check_range(&(i..i + 1), self.capacity, "allocated")?;
                    match runs.last_mut() {
                        Some((s, n)) if *s + *n == i => *n += 1,
                        _ => runs.push((i, 1)),
                    }
                }
            }
        }
        let buffer = self.field(field);
        let mut rest: &mut [u8] = bytemuck::cast_slice_mut(out);
        for (first, count) in runs {
            let (head, tail) = std::mem::take(&mut rest).split_at_mut(count * 16);
            pieces.push((buffer, (first * 16) as u64, head));
            rest = tail;
        }
        Ok(())
    }

    /// Reads `pieces` through the readback buffer: as many as fit in it per submit and
    /// mapping (a piece larger than the buffer is split), so small reads take one
    /// readback however many pieces they have. Offsets and lengths are multiples of 4.
    fn read_pieces(&self, pieces: Vec<Piece<'_>>) -> Result<(), SimError> {
        let room = self.buffers.readback.size();
        let mut batch: Vec<Piece<'_>> = Vec::new();
        let mut used = 0u64;
        for (buffer, mut offset, mut out) in pieces {
            while !out.is_empty() {
                if used == room {
                    self.copy_out(&mut batch)?;
                    batch.clear();
                    used = 0;
                }
                let take = (out.len() as u64).min(room - used) as usize;
                let (head, tail) = std::mem::take(&mut out).split_at_mut(take);
                batch.push((buffer, offset, head));
                used += take as u64;
                offset += take as u64;
                out = tail;
            }
        }
        if !batch.is_empty() {
            self.copy_out(&mut batch)?;
        }
        Ok(())
    }

    /// Writes node-major elements `elements` (`data`, [`layout::ELEMENT`] bytes each) of a
    /// per-slot array that the device stores slot-major (`target`). A slot's run of at
    /// least [`DIRECT_RUN`] nodes is one `write_buffer` (after the edits of `target` that
    /// wait, so that the order holds); shorter runs wait as word pairs for the next submit
    /// or readback ([`crate::scatter`]).
    fn write_per_slot(&self, target: Binding, k: usize, elements: Range<usize>, data: &[u8]) {
        let first = elements.start;
        // Pairs of `target` from before this call (this call's own are other words).
        let mut waiting = self.lock_scatter().pending_for(target);
        let word = |at: usize| {
            let at = at * layout::ELEMENT;
            u32::from_ne_bytes(data[at..at + layout::ELEMENT].try_into().expect("4 bytes"))
        };
        // This call's short runs (other words than its direct ones), queued at once.
        let mut short: Vec<[u32; 2]> = Vec::new();
        for run in layout::runs(elements, k) {
            let offset = run.offset(self.capacity);
            let len = run.nodes.len();
            if len >= DIRECT_RUN {
                if waiting {
                    self.flush_scatter();
                    waiting = false;
                }
                let words: Vec<u32> = (0..len).map(|n| word(run.source(n, k, first))).collect();
                self.ctx.queue.write_buffer(
                    self.buffers.get(target),
                    offset,
                    bytemuck::cast_slice(&words),
                );
            } else {
                let at = offset as usize / layout::ELEMENT;
                short.extend((0..len).map(|n| [(at + n) as u32, word(run.source(n, k, first))]));
            }
        }
        if !short.is_empty() {
            self.queue_pairs(target, short.into_iter());
        }
    }

    /// Writes `data` at byte `offset` of an array stored as the host has it (`target`,
    /// `buffer`): a few words wait as pairs with the per-slot edits ([`crate::scatter`]:
    /// a node edit writes a few words of each shape array per touched node, over a
    /// hundred small copies per Tip refresh); more go through `write_buffer` after what
    /// waits for that array.
    fn write_words(&self, target: Binding, buffer: &wgpu::Buffer, offset: usize, data: &[u8]) {
        let words = data.len() / layout::ELEMENT;
        let aligned =
            offset.is_multiple_of(layout::ELEMENT) && data.len().is_multiple_of(layout::ELEMENT);
        if aligned && words < DIRECT_WORDS {
            let at = offset / layout::ELEMENT;
            self.queue_pairs(
                target,
                data.chunks_exact(layout::ELEMENT)
                    .enumerate()
                    .map(|(n, w)| {
                        [
                            (at + n) as u32,
                            u32::from_ne_bytes(w.try_into().expect("4 bytes")),
                        ]
                    }),
            );
        } else {
            if self.lock_scatter().pending_for(target) {
                self.flush_scatter();
            }
            self.ctx.queue.write_buffer(buffer, offset as u64, data);
        }
    }

    fn lock_scatter(&self) -> std::sync::MutexGuard<'_, Scatter> {
        // A panic while the lock was held left at worst some edits pending.
        self.scatter.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A command encoder that starts with the waiting edits ([`crate::scatter`]): every
    /// submit and readback goes through one, so nothing recorded after can see the
    /// arrays without them.
    fn encoder(&self, label: &'static str) -> wgpu::CommandEncoder {
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        self.lock_scatter().record(
            &self.ctx.device,
            &self.ctx.queue,
            &self.buffers,
            &mut encoder,
            self.max_groups_x,
        );
        encoder
    }

    /// Queues `pairs` of `target` ([`crate::scatter`]), after submitting what waits when
    /// the batch is full.
    fn queue_pairs(&self, target: Binding, pairs: impl Iterator<Item = [u32; 2]>) {
        if self.lock_scatter().full() {
            self.flush_scatter();
        }
        self.lock_scatter().push(target, pairs);
    }

    /// Submits the waiting row edits on their own.
    fn flush_scatter(&self) {
        let encoder = self.encoder("scatter");
        self.ctx.queue.submit([encoder.finish()]);
    }

    /// Elements per node of an array the device stores component-major (`crate::layout`):
    /// the per-slot arrays (K) and the viscoelastic state ([`VISCO_ROW`]); `None` for an
    /// array stored as the host has it.
    fn strided(&self, array: ShapeArray) -> Option<usize> {
        if array.per_slot() {
            Some(self.params.k as usize)
        } else if array == ShapeArray::Viscous {
            Some(VISCO_ROW)
        } else {
            None
        }
    }

    /// Bytes of `array` as the host has it (the viscoelastic state's buffer also holds the
    /// next step's rows).
    fn host_size(&self, array: ShapeArray, buffer: &wgpu::Buffer) -> usize {
        match array {
            ShapeArray::Viscous => buffer.size() as usize / 2,
            _ => buffer.size() as usize,
        }
    }

    /// Copies `pieces` (at most the readback buffer's size in all) through the readback
    /// buffer in one submit and one mapping: one readback.
    fn copy_out(&self, pieces: &mut [Piece<'_>]) -> Result<(), SimError> {
        let bytes: u64 = pieces.iter().map(|p| p.2.len() as u64).sum();
        if bytes == 0 {
            return Ok(());
        }
        let mut encoder = self.encoder("read");
        let mut at = 0u64;
        for (buffer, offset, out) in pieces.iter() {
            let len = out.len() as u64;
            encoder.copy_buffer_to_buffer(buffer, *offset, &self.buffers.readback, at, len);
            at += len;
        }
        self.ctx.queue.submit([encoder.finish()]);
        map_read(
            &self.ctx.device,
            "readback",
            &self.buffers.readback,
            bytes,
            &self.readbacks,
            |data| {
                let mut at = 0;
                for (_, _, out) in pieces.iter_mut() {
                    let len = out.len();
                    out.copy_from_slice(&data[at..at + len]);
                    at += len;
                }
            },
        )
        .map_err(|message| SimError::Device { message })
    }

    fn field(&self, field: NodeField) -> &wgpu::Buffer {
        match field {
            NodeField::Position | NodeField::StoredPosition => &self.buffers.positions,
            NodeField::Velocity => &self.buffers.velocities,
            NodeField::Force => &self.buffers.forces,
            NodeField::PositionRemainder | NodeField::StoredRemainder => {
                &self.buffers.position_remainders
            }
        }
    }

    /// Waits until the device has finished all submitted work.
    pub fn wait(&self) {
        let _ = self.ctx.device.poll(wgpu::PollType::wait_indefinitely());
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
        self.submit(1, true, false);
    }

    /// Every node, as the default; the warm-start rotations of co-rotated Debunne are
    /// copied aside before and back after, on the device, so that the local evaluations a
    /// node event makes leave them as the CPU backend's do (the trait's docs).
    fn compute_forces_on(&mut self, nodes: &[u32]) {
        let _ = nodes;
        let Some(keep) = self.warm_starts.clone() else {
            return self.compute_forces();
        };
        let rotation = self
            .buffers
            .get(Binding::Model(ShapeArray::Rotation))
            .clone();
        // The encoder records the row edits waiting (a new node's rotation) first.
        let mut encoder = self.encoder("local forces");
        encoder.copy_buffer_to_buffer(&rotation, 0, &keep, 0, keep.size());
        self.record(&mut encoder, 1, true, false);
        encoder.copy_buffer_to_buffer(&keep, 0, &rotation, 0, keep.size());
        self.ctx.queue.submit([encoder.finish()]);
    }

    fn integrate(&mut self) {
        self.submit(1, false, true);
        self.steps += 1;
    }

    /// Records up to 200 steps per command buffer and submits them without waiting or
    /// reading anything back.
    fn step(&mut self, n: u64) {
        let mut left = n;
        while left > 0 {
            let batch = left.min(STEPS_PER_SUBMIT);
            self.submit(batch, true, true);
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
        self.read_many(&[(field, range.into())], &mut [out])
    }

    /// Every request's copies (one per run of consecutive nodes) go into the readback
    /// buffer in one submit and one mapping (more when they hold more than `capacity`
    /// nodes in all).
    fn read_many(
        &mut self,
        requests: &[(NodeField, NodeSelection<'_>)],
        outs: &mut [&mut [Vec4]],
    ) -> Result<(), SimError> {
        check_many(requests, outs)?;
        let frame = self.frame;
        // In a translated frame a remainder's world value needs the stored position too:
        // read in the same transfer.
        let mut stored: Vec<(usize, Vec<Vec4>)> = if frame.is_world() {
            Vec::new()
        } else {
            requests
                .iter()
                .enumerate()
                .filter(|(_, (field, _))| *field == NodeField::PositionRemainder)
                .map(|(i, _)| (i, vec![[0.0f32; 4]; outs[i].len()]))
                .collect()
        };
        let mut pieces = Vec::new();
        for ((field, nodes), out) in requests.iter().zip(outs.iter_mut()) {
            self.pieces(*field, nodes, out, &mut pieces)?;
        }
        for (i, out) in stored.iter_mut() {
            self.pieces(NodeField::Position, &requests[*i].1, out, &mut pieces)?;
        }
        self.read_pieces(pieces)?;
        for ((field, _), out) in requests.iter().zip(outs.iter_mut()) {
            if *field == NodeField::Position {
                frame.positions_to_world(out);
            }
        }
        for (i, positions) in stored {
            frame.remainders_to_world(outs[i], &positions);
        }
        Ok(())
    }

    fn position_frame(&self) -> PositionFrame {
        self.frame
    }

    fn readbacks(&self) -> u64 {
        self.readbacks.load(Ordering::Relaxed)
    }

    /// The integration raises a flag on the device when a free node's new position or
    /// velocity is not finite or its speed is above the bound (`integrate.wgsl`); the
    /// guard reads that one word back (a blocking readback of 4 bytes, where the default
    /// reads every position and velocity: 32 MB at 1M nodes; on an H100 Python's
    /// `step(n)` took 269 us a mass-spring step there against the batched bench's 172 us,
    /// and 155 us with this guard and the kernel change of the same day, 2.09 times the
    /// steps per second of before). Only when it is set, or on the first
    /// call with a new bound (steps before it were watched against the old one), are the
    /// arrays read and checked as on the CPU, so the error is the same; the flag is
    /// cleared then. A node that went too fast between two guards and slowed down again
    /// costs one full check and is no error, as before.
    fn guard(&mut self, max_speed: f64) -> Result<(), SimError> {
        // A hair below the bound, so that f32 rounding flags every node the f64 check
        // would name (a flag too many costs one full check, no error).
        let bound = (max_speed * max_speed * (1.0 - 1e-5)) as f32;
        let bound = if bound.is_nan() { f32::INFINITY } else { bound };
        let mut flag = [0u8; 4];
        if bound == self.params.max_speed_sq {
            self.read_pieces(vec![(&self.buffers.guard, 0, &mut flag[..])])?;
            if flag == [0u8; 4] {
                return Ok(());
            }
        } else {
            self.params.max_speed_sq = bound;
            self.ctx
                .queue
                .write_buffer(&self.buffers.params, 0, bytemuck::bytes_of(&self.params));
        }
        self.ctx
            .queue
            .write_buffer(&self.buffers.guard, 0, &[0u8; 4]);
        needlesim_core::backend::check_bounded(self, max_speed)
    }

    /// One copy per run of consecutive nodes, one submit, one mapping.
    fn read_nodes(
        &mut self,
        field: NodeField,
        nodes: &[u32],
        out: &mut [Vec4],
    ) -> Result<(), SimError> {
        needlesim_core::backend::check_gather(nodes, out)?;
        self.read_many(&[(field, nodes.into())], &mut [out])
    }

    fn write(&mut self, field: NodeField, first: usize, data: &[Vec4]) -> Result<(), SimError> {
        check_range(&(first..first + data.len()), self.capacity, "allocated")?;
        let offset = (first * 16) as u64;
        let queue = &self.ctx.queue;
        if field == NodeField::Position && !self.frame.is_world() {
            let mut stored = data.to_vec();
            self.frame.slice_to_frame(&mut stored);
            queue.write_buffer(self.field(field), offset, bytemuck::cast_slice(&stored));
        } else {
            queue.write_buffer(self.field(field), offset, bytemuck::cast_slice(data));
        }
        if field == NodeField::Position && !data.is_empty() {
            // A written position is exact (Backend::write).
            let zeros = vec![0u8; data.len() * 16];
            queue.write_buffer(&self.buffers.position_remainders, offset, &zeros);
        }
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
        let elements = first * k..first * k + index.len();
        self.write_per_slot(
            Binding::NeighbourIndex,
            k,
            elements.clone(),
            bytemuck::cast_slice(index),
        );
        self.write_per_slot(
            Binding::NeighbourWeight,
            k,
            elements,
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
            target.map(|(_, b)| self.host_size(array, b)),
        )?;
        if let Some((_, buffer)) = target {
            if let Some(k) = self.strided(array) {
                let first = offset / layout::ELEMENT;
                let elements = first..first + data.len() / layout::ELEMENT;
                self.write_per_slot(Binding::Model(array), k, elements, data);
            } else if !data.is_empty() {
                self.write_words(Binding::Model(array), buffer, offset, data);
            }
        }
        Ok(())
    }

    /// Reads in pieces of the readback buffer's size (one readback each).
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
            source.map(|(_, b)| self.host_size(array, b)),
        )?;
        let Some((_, buffer)) = source else {
            return Ok(());
        };
        let Some(k) = self.strided(array) else {
            return self.read_pieces(vec![(buffer, offset as u64, out)]);
        };
        // Slot-major on the device: read each slot's run, then put the elements back in
        // node-major order.
        let first = offset / layout::ELEMENT;
        let runs = layout::runs(first..first + out.len() / layout::ELEMENT, k);
        let mut parts: Vec<Vec<u8>> = runs
            .iter()
            .map(|r| vec![0u8; r.nodes.len() * layout::ELEMENT])
            .collect();
        let pieces = runs
            .iter()
            .zip(parts.iter_mut())
            .map(|(r, part)| (buffer, r.offset(self.capacity), part.as_mut_slice()))
            .collect();
        self.read_pieces(pieces)?;
        for (run, part) in runs.iter().zip(&parts) {
            for (n, element) in part.chunks_exact(layout::ELEMENT).enumerate() {
                let at = run.source(n, k, first) * layout::ELEMENT;
                out[at..at + layout::ELEMENT].copy_from_slice(element);
            }
        }
        Ok(())
    }
}
