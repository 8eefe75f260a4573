//! Slot-major storage of the per-slot arrays (neighbour index, neighbour weight and
//! mass-spring's rest length) on the GPU.
//!
//! The core and the CPU backend keep these arrays node-major: slot `s` of node `i` at
//! `i K + s`, so that one node's row is contiguous for the CPU kernels, which walk one node
//! per thread and read its row with SIMD loads. On a GPU the 32 threads of a warp (or
//! the lanes of a subgroup) handle 32 consecutive nodes and read their slot `s` together:
//! node-major, those 32 reads are `4 K` bytes apart and touch 32 different 32-byte
//! sectors. Slot-major, slot `s` of node `i` at `s C + i` (`C` the capacity), they are
//! adjacent, one 128-byte line per warp and slot. Measured on an NVIDIA H200
//! (`docs/guide/performance.md`, "On a real GPU"): at 1M nodes the node-major
//! mass-spring kernel took 560 us per step, 26 times its 100k-node time, once the rows no
//! longer fit the 50 MB L2 cache.
//!
//! The kernels index through `slot(node, s)` in `shaders/common.wgsl`; the host converts
//! at upload, at every row write (`write_neighbour_rows`, the shape array writes of
//! node additions and removals) and at every read, so the layout is invisible outside
//! this crate and results are bitwise those of the node-major layout (the same values
//! are summed in the same order).

use std::ops::Range;

/// Bytes of one element of a per-slot array (`u32` or `f32`).
pub(crate) const ELEMENT: usize = 4;

/// `rows` (node-major, `capacity * k` elements of [`ELEMENT`] bytes) as slot-major bytes.
pub(crate) fn to_slot_major(rows: &[u8], k: usize, capacity: usize) -> Vec<u8> {
    assert_eq!(
        rows.len(),
        capacity * k * ELEMENT,
        "a per-slot array of capacity rows"
    );
    let mut out = vec![0u8; rows.len()];
    for node in 0..capacity {
        for s in 0..k {
            let from = (node * k + s) * ELEMENT;
            let to = (s * capacity + node) * ELEMENT;
            out[to..to + ELEMENT].copy_from_slice(&rows[from..from + ELEMENT]);
        }
    }
    out
}

/// One contiguous run of a node-major element range in the slot-major array: slot `slot`
/// of the nodes `nodes`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Run {
    /// The slot.
    pub slot: usize,
    /// The nodes whose slot `slot` lies in the range (consecutive).
    pub nodes: Range<usize>,
}

impl Run {
    /// Byte offset of the run in the slot-major array.
    pub fn offset(&self, capacity: usize) -> u64 {
        ((self.slot * capacity + self.nodes.start) * ELEMENT) as u64
    }

    /// Position of the run's `n`-th element in the node-major element range starting
    /// at element `first`.
    pub fn source(&self, n: usize, k: usize, first: usize) -> usize {
        (self.nodes.start + n) * k + self.slot - first
    }
}

/// The runs, one per slot that has any, covering node-major elements `elements` (a range
/// of `node * k + slot`): for a contiguous element range each slot's nodes are consecutive,
/// so a write or read of any range is at most `k` contiguous pieces.
pub(crate) fn runs(elements: Range<usize>, k: usize) -> Vec<Run> {
    let mut out = Vec::new();
    if elements.is_empty() {
        return out;
    }
    for slot in 0..k {
        // Nodes n with elements.start <= n k + slot < elements.end.
        let lo = elements.start.saturating_sub(slot).div_ceil(k);
        let end = elements.end - 1;
        if end < slot {
            continue;
        }
        let hi = (end - slot) / k;
        if lo <= hi {
            out.push(Run {
                slot,
                nodes: lo..hi + 1,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every element of a range lands in exactly one run, at its slot-major position.
    #[test]
    fn runs_cover_a_range_once_at_the_slot_major_positions() {
        let (k, capacity) = (5, 7);
        for start in 0..k * capacity {
            for end in start..=k * capacity {
                let mut seen = vec![0u32; k * capacity];
                for run in runs(start..end, k) {
                    for (n, node) in run.nodes.clone().enumerate() {
                        let element = node * k + run.slot;
                        assert!((start..end).contains(&element), "{start}..{end}: {run:?}");
                        assert_eq!(run.source(n, k, start), element - start);
                        let at = run.offset(capacity) as usize / ELEMENT + n;
                        assert_eq!(at, run.slot * capacity + node);
                        seen[element] += 1;
                    }
                }
                for (e, &count) in seen.iter().enumerate() {
                    assert_eq!(
                        count,
                        u32::from((start..end).contains(&e)),
                        "{start}..{end} {e}"
                    );
                }
            }
        }
    }

    #[test]
    fn slot_major_puts_slot_s_of_node_i_at_s_capacity_plus_i() {
        let (k, capacity) = (3, 4);
        let rows: Vec<u32> = (0..(k * capacity) as u32).collect();
        let out = to_slot_major(bytemuck::cast_slice(&rows), k, capacity);
        let out: &[u32] = bytemuck::cast_slice(&out);
        for i in 0..capacity {
            for s in 0..k {
                assert_eq!(out[s * capacity + i], rows[i * k + s]);
            }
        }
    }
}
