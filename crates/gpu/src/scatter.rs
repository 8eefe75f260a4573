//! Small host edits of the arrays the device stores component-major (the per-slot arrays
//! and the viscoelastic state, [`crate::layout`]), batched into one upload and one
//! dispatch (`shaders/scatter.wgsl`).
//!
//! The other shape arrays' small writes (a few words per node an edit touches) wait with
//! them, so an edit's writes are not hundreds of separate copies either.
//!
//! A node's row is contiguous on the host and scattered on the device: slot `s` of node `i`
//! at `s C + i`. Written with `queue.write_buffer`, one row is K copies of 4 bytes per
//! array, and a Tip refresh, which rewrites about a hundred rows, issued over 5,000 of
//! them. Measured on an NVIDIA H100 (`docs/guide/performance.md`, "The needle step on a
//! real GPU"): 5 ms of the host's time in those calls and about 7 ms more in the readbacks
//! that submitted them, a 13 ms step in a haptic loop that has 1 ms. Here each word
//! becomes an `(at, bits)` pair; the pairs wait on the host until the next submit or
//! readback ([`Scatter::record`] at the start of its command buffer), so the edits made
//! between two submits or readbacks reach the device in one upload and one dispatch per
//! edited array (more for a batch beyond one dispatch's workgroups), before any kernel
//! or copy that could read them. Runs of at least [`DIRECT_RUN`] consecutive nodes
//! (checkpoint restores of a capacity of at least that many nodes) still go through
//! `write_buffer`, after the pending pairs of that array ([`crate::GpuBackend`]'s
//! `write_per_slot`), so the order of writes is kept.

use crate::buffers::{Binding, Buffers};
use crate::kernels::{Kernel, KernelSpec, WORKGROUP};

/// `scatter.wgsl`: writes each pair's word into the bound array.
pub(crate) const SCATTER: KernelSpec = KernelSpec {
    name: "scatter",
    sources: &[include_str!("../shaders/scatter.wgsl")],
    entry: "main",
    // Binding 1 is the edited array, chosen per dispatch ([`Scatter::record`]).
    bindings: &[],
};

/// Consecutive nodes from which a per-slot run is written directly: each of its K pieces
/// is then at least 256 bytes, one copy each, and a whole-array write (a checkpoint's
/// restore, with a capacity of at least this many nodes) does not go through host pairs.
pub(crate) const DIRECT_RUN: usize = 64;

/// Words from which a write of an array stored as the host has it (a shape array that
/// is not per slot) goes through `write_buffer` rather than as pairs: 1 KiB.
pub(crate) const DIRECT_WORDS: usize = 256;

/// Pending pairs from which a write submits them first, so that the host's batch (8 bytes
/// per word) stays bounded.
const MAX_PENDING: usize = 1 << 20;

/// The edits not yet on the device, and the kernel and upload buffer that apply them.
#[derive(Debug)]
pub(crate) struct Scatter {
    kernel: Kernel,
    /// Per edited array, its `[word, bits]` pairs in the order written (a later pair for
    /// the same word wins: the dispatch writes them in order only within a thread, so
    /// duplicates are dropped before upload, [`Scatter::record`]).
    pending: Vec<(Binding, Vec<[u32; 2]>)>,
    /// The upload buffer of the pairs (grown as needed).
    upload: Option<wgpu::Buffer>,
    /// A bit per word written ([`last_write_wins`]), clear between flushes.
    seen: Vec<u64>,
}

impl Scatter {
    /// The kernel compiled on `device`, nothing pending.
    pub(crate) fn new(device: &wgpu::Device) -> Scatter {
        Scatter {
            kernel: SCATTER.compile(device),
            pending: Vec::new(),
            upload: None,
            seen: Vec::new(),
        }
    }

    /// Whether edits of `target` wait.
    pub(crate) fn pending_for(&self, target: Binding) -> bool {
        self.pending
            .iter()
            .any(|(b, p)| *b == target && !p.is_empty())
    }

    /// Whether no edit waits.
    pub(crate) fn is_empty(&self) -> bool {
        self.pending.iter().all(|(_, p)| p.is_empty())
    }

    /// Whether so many pairs wait that the next write should submit them first.
    pub(crate) fn full(&self) -> bool {
        self.pending.iter().map(|(_, p)| p.len()).sum::<usize>() >= MAX_PENDING
    }

    /// Queues `[word, bits]` pairs: word `word` of `target` is to be set to `bits`.
    pub(crate) fn push(&mut self, target: Binding, words: impl Iterator<Item = [u32; 2]>) {
        match self.pending.iter_mut().find(|(b, _)| *b == target) {
            Some((_, p)) => p.extend(words),
            None => self.pending.push((target, words.collect())),
        }
    }

    /// Records the pending edits at the current point of `encoder` (one compute pass, a
    /// dispatch per array and per `max_groups` workgroups of pairs) and clears them; the
    /// pairs are uploaded with `queue.write_buffer`, which the queue runs before the
    /// command buffer.
    pub(crate) fn record(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        buffers: &Buffers,
        encoder: &mut wgpu::CommandEncoder,
        max_groups: u32,
    ) {
        if self.is_empty() {
            return;
        }
        let limits = device.limits();
        // Pairs per aligned offset (the alignment is a power of two of at least 32 bytes).
        let align = (limits.min_storage_buffer_offset_alignment as usize / 8).max(1);
        let chunk_max = (WORKGROUP * max_groups) as usize / align * align;
        let mut words: Vec<[u32; 2]> = Vec::new();
        // (target, first pair, pairs) per dispatch.
        let mut dispatches: Vec<(Binding, usize, usize)> = Vec::new();
        for (target, pairs) in self.pending.drain(..) {
            let pairs = last_write_wins(pairs, &mut self.seen);
            for chunk in pairs.chunks(chunk_max.max(align)) {
                let first = words.len();
                words.extend_from_slice(chunk);
                words.resize(words.len().next_multiple_of(align), [u32::MAX, 0]);
                dispatches.push((target, first, words.len() - first));
            }
        }
        let bytes = (words.len() * 8) as u64;
        if self.upload.as_ref().is_none_or(|b| b.size() < bytes) {
            self.upload = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("scatter pairs"),
                size: bytes.next_power_of_two().max(256),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        let upload = self.upload.as_ref().expect("allocated above");
        queue.write_buffer(upload, 0, bytemuck::cast_slice(&words));
        let layout = self.kernel.bind_group_layout();
        let groups: Vec<(wgpu::BindGroup, u32)> = dispatches
            .iter()
            .map(|&(target, first, n)| {
                let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("scatter"),
                    layout: &layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: upload,
                                offset: (first * 8) as u64,
                                size: wgpu::BufferSize::new((n * 8) as u64),
                            }),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: buffers.get(target).as_entire_binding(),
                        },
                    ],
                });
                (bind, (n as u32).div_ceil(WORKGROUP))
            })
            .collect();
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("scatter"),
            timestamp_writes: None,
        });
        for (bind, n) in &groups {
            self.kernel.dispatch(&mut pass, bind, (*n, 1));
        }
    }
}

/// `pairs` with only the last write of each word, in the order of those last writes
/// (threads of a dispatch run in no set order, so two writes of one word would race).
/// `seen` is a bit per word, all clear on entry and on return (a refresh's few thousand
/// pairs through a `HashMap` cost about 0.1 ms a flush; a bit set, a few microseconds).
fn last_write_wins(pairs: Vec<[u32; 2]>, seen: &mut Vec<u64>) -> Vec<[u32; 2]> {
    let mut out = Vec::with_capacity(pairs.len());
    for p in pairs.iter().rev() {
        let (word, bit) = ((p[0] >> 6) as usize, 1u64 << (p[0] & 63));
        if word >= seen.len() {
            seen.resize(word + 1, 0);
        }
        if seen[word] & bit == 0 {
            seen[word] |= bit;
            out.push(*p);
        }
    }
    for p in &out {
        seen[(p[0] >> 6) as usize] = 0;
    }
    out.reverse();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shader validates with naga and binds exactly the pairs (0) and the target (1).
    #[test]
    fn the_scatter_kernel_validates_and_binds_its_two_arrays() {
        let source = SCATTER.sources.join("\n");
        let module = naga::front::wgsl::parse_str(&source)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap();
        let bindings: Vec<u32> = module
            .global_variables
            .iter()
            .filter_map(|(_, g)| g.binding.as_ref().map(|b| b.binding))
            .collect();
        assert_eq!(bindings, [0, 1]);
        assert!(module.entry_points.iter().any(|e| e.name == SCATTER.entry));
    }

    #[test]
    fn a_later_write_of_a_word_replaces_the_earlier() {
        let mut seen = Vec::new();
        let pairs = vec![[3, 1], [5, 2], [3, 7], [9, 4], [200, 1], [70, 2], [200, 3]];
        assert_eq!(
            last_write_wins(pairs, &mut seen),
            [[5, 2], [3, 7], [9, 4], [70, 2], [200, 3]]
        );
        assert!(seen.iter().all(|&w| w == 0), "the bit set is left clear");
        let distinct = vec![[1, 1], [2, 2]];
        assert_eq!(last_write_wins(distinct.clone(), &mut seen), distinct);
    }
}
