//! The interface between a simulation driver (the needle, the CLI) and whatever computes
//! the tissue: the CPU backend here, the GPU backend in `needlesim-gpu`.
//!
//! A backend owns the node arrays; callers read and write ranges of nodes (the needle
//! nodes) and individual neighbour rows, and step it. On a GPU every read is a blocking
//! round trip ([`Backend::readbacks`] counts them): [`Backend::read_many`] and
//! [`Backend::read_nodes`] gather several pieces into one.

use crate::error::SimError;
use crate::frame::PositionFrame;
use crate::math::Vec4;
use crate::models::ShapeArray;
use std::ops::Range;

/// A per-node vector array of the backend.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeField {
    /// Positions in world coordinates, rounded to f32 (w = inverse mass). The backend may
    /// store them in a translated frame ([`Backend::position_frame`]); reads and writes
    /// convert.
    Position,
    /// Velocities.
    Velocity,
    /// Elastic forces of the last force evaluation.
    Force,
    /// The part of each world position below the f32 [`NodeField::Position`] (xyz in
    /// metres, w = 0): the integrator's carried rounding error ([`crate::integrator`])
    /// plus, in a translated frame, what rounding the position to world f32 dropped
    /// ([`crate::frame`]). Position plus remainder is the position to about 2^-48 of its
    /// distance from the world's origin. Writing [`NodeField::Position`] clears it for the
    /// nodes written (a written position is exact); a remainder written is added to the
    /// position.
    PositionRemainder,
    /// The positions as the backend stores them, in [`Backend::position_frame`] (the same
    /// as [`NodeField::Position`] in the world frame); writing them leaves the remainders
    /// alone. With [`NodeField::StoredRemainder`], what a checkpoint saves and restores
    /// bit for bit.
    StoredPosition,
    /// The integrator's remainders as the backend stores them (the same as
    /// [`NodeField::PositionRemainder`] in the world frame).
    StoredRemainder,
}

/// The nodes one request of [`Backend::read_many`] reads: a range, or a list (in its
/// order, repeats allowed).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NodeSelection<'a> {
    /// Nodes `start..end`.
    Range(Range<usize>),
    /// The listed nodes.
    List(&'a [u32]),
}

impl NodeSelection<'_> {
    /// Nodes selected (0 for a range that ends before it starts).
    pub fn len(&self) -> usize {
        match self {
            NodeSelection::Range(r) => r.end.saturating_sub(r.start),
            NodeSelection::List(l) => l.len(),
        }
    }

    /// Whether no node is selected.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl From<Range<usize>> for NodeSelection<'_> {
    fn from(r: Range<usize>) -> Self {
        NodeSelection::Range(r)
    }
}

impl<'a> From<&'a [u32]> for NodeSelection<'a> {
    fn from(l: &'a [u32]) -> Self {
        NodeSelection::List(l)
    }
}

/// Something that steps the tissue. `Send`, so that a simulation can run on another
/// thread (the Python bindings step with the interpreter released).
pub trait Backend: Send {
    /// Human-readable name (e.g. `cpu (1 thread)`).
    fn name(&self) -> String;
    /// Allocated node slots.
    fn capacity(&self) -> usize;
    /// Nodes currently simulated.
    fn n_active(&self) -> usize;
    /// Changes the number of simulated nodes (at most the capacity).
    fn set_n_active(&mut self, n: usize) -> Result<(), SimError>;
    /// Evaluates the elastic forces of all active nodes.
    fn compute_forces(&mut self);
    /// Evaluates the elastic forces of at least the listed active nodes (in any order;
    /// inactive ones are ignored); the forces of the other nodes may be left stale until the next
    /// [`Backend::compute_forces`], and model state that a force pass writes for the next
    /// step (the viscoelastic update) may be left partly written, so call
    /// `compute_forces` before integrating. The needle's settle asks for the forces on
    /// the few nodes it places, several times per edit. The CPU backend evaluates only
    /// those nodes and the neighbours their forces read; the default evaluates every node.
    /// Warm starts that only speed up the next pass (co-rotated Debunne's rotations,
    /// [`crate::models::ShapeInfo::rotation_is_warm_start`]) are left as they were by the CPU
    /// and GPU backends, so that how many local evaluations a step makes (the needle's
    /// node events) does not change the next full pass: the GPU backend, which evaluates
    /// every node, refined every node's rotation once more per local evaluation and its
    /// runs drifted from the CPU's by a few steps at the layered test's events when Tip
    /// refreshes were handed over (`tests/layers.rs`, 2026-11-27). This default, which
    /// calls `compute_forces`, does refine them: a backend that wraps another must
    /// forward this method. Shape matching's rotations are not warm starts only (its
    /// cluster forces read the neighbours'): a local evaluation writes those of the
    /// nodes it evaluates on the CPU and every node's on the GPU.
    fn compute_forces_on(&mut self, nodes: &[u32]) {
        let _ = nodes;
        self.compute_forces();
    }
    /// Advances positions and velocities by one time step using the current forces.
    fn integrate(&mut self);
    /// Runs `n` steps of force evaluation and integration.
    fn step(&mut self, n: u64) {
        for _ in 0..n {
            self.compute_forces();
            self.integrate();
        }
    }
    /// The frame the backend stores positions in ([`crate::frame`]): the world's, or for
    /// a body far from the origin, one translated to it. Reads and writes of
    /// [`NodeField::Position`] and [`NodeField::PositionRemainder`] are in world
    /// coordinates whatever it is. The default is the world frame: a backend that wraps
    /// another must forward it (the needle's node editor rounds the positions it writes
    /// through it to know what a read will return, `needlesim-needle`'s `NodeEditor`).
    fn position_frame(&self) -> PositionFrame {
        PositionFrame::WORLD
    }
    /// Steps run since creation (or the count [`Backend::set_steps_taken`] restored).
    fn steps_taken(&self) -> u64;
    /// Sets the step counter (a simulation restored from a checkpoint continues its count).
    fn set_steps_taken(&mut self, steps: u64);
    /// Blocks until all submitted work is done (a no-op on the CPU, where [`Backend::step`]
    /// returns when the work is done; a GPU backend only queues it). Call it before
    /// stopping a clock.
    fn finish(&mut self) {}
    /// Copies `range` of `field` into `out` (`out.len() == range.len()`).
    fn read(
        &mut self,
        field: NodeField,
        range: Range<usize>,
        out: &mut [Vec4],
    ) -> Result<(), SimError>;
    /// Copies the listed nodes of `field` into `out` (`out.len() == nodes.len()`), in one
    /// transfer where the backend can (the needle reads the few nodes around the tip this
    /// way). The default reads them one by one.
    fn read_nodes(
        &mut self,
        field: NodeField,
        nodes: &[u32],
        out: &mut [Vec4],
    ) -> Result<(), SimError> {
        check_gather(nodes, out)?;
        for (&i, o) in nodes.iter().zip(out.iter_mut()) {
            let i = i as usize;
            self.read(field, i..i + 1, std::slice::from_mut(o))?;
        }
        Ok(())
    }
    /// Copies `requests[i]` (a field and its nodes: a range or a list) into `outs[i]` for
    /// every `i` (`outs[i].len()` the number of nodes), in one transfer where the backend
    /// can: the GPU backend copies every piece into one staging buffer and maps it once.
    /// The needle reads the positions and velocities of its nodes, and the corners of the
    /// surface triangles near the tip, together this way. The default reads the requests
    /// one by one ([`Backend::read`], [`Backend::read_nodes`]). Lengths are checked before
    /// anything is read ([`SimError::BadReadLength`]).
    fn read_many(
        &mut self,
        requests: &[(NodeField, NodeSelection<'_>)],
        outs: &mut [&mut [Vec4]],
    ) -> Result<(), SimError> {
        check_many(requests, outs)?;
        for ((field, nodes), out) in requests.iter().zip(outs.iter_mut()) {
            match nodes {
                NodeSelection::Range(r) => self.read(*field, r.clone(), out)?,
                NodeSelection::List(l) => self.read_nodes(*field, l, out)?,
            }
        }
        Ok(())
    }
    /// Blocking device-to-host readbacks (a copy to host memory and a wait for it) since the
    /// backend was created. Every [`Backend::read`], [`Backend::read_nodes`],
    /// [`Backend::read_many`] and [`Backend::read_shape_bytes`] of the GPU backend is one,
    /// or one per staging buffer's worth of data when it reads more than the staging buffer
    /// holds (its capacity in nodes). A backend whose arrays are in host memory has none:
    /// the default returns 0.
    fn readbacks(&self) -> u64 {
        0
    }
    /// Overwrites `data.len()` nodes of `field` starting at `first`.
    ///
    /// Writing [`NodeField::Position`] also sets the written nodes'
    /// [`NodeField::PositionRemainder`] to zero; write the remainder after the positions
    /// to restore both (checkpoints do).
    fn write(&mut self, field: NodeField, first: usize, data: &[Vec4]) -> Result<(), SimError>;
    /// Overwrites the neighbour rows of nodes `first..first + index.len() / K`.
    fn write_neighbour_rows(
        &mut self,
        first: usize,
        index: &[u32],
        weight: &[f32],
    ) -> Result<(), SimError>;

    /// Overwrites `data.len()` bytes at byte `offset` of the model's shape information array
    /// `array` (the layout is that of `ShapeInfo::bytes`). The needle uses it to give a new node and
    /// its neighbours their shape information, on any backend.
    fn write_shape_bytes(
        &mut self,
        array: ShapeArray,
        offset: usize,
        data: &[u8],
    ) -> Result<(), SimError>;
    /// Copies `out.len()` bytes at byte `offset` of the model's shape information array
    /// `array` into `out` (checkpoints read the per-step arrays, such as the warm-start
    /// rotations, this way).
    fn read_shape_bytes(
        &mut self,
        array: ShapeArray,
        offset: usize,
        out: &mut [u8],
    ) -> Result<(), SimError>;
    /// Reads the positions and velocities of all active nodes and returns an error naming
    /// the first non-finite one ([`check_bounded`] without a speed bound).
    fn check_finite(&mut self) -> Result<(), SimError> {
        check_bounded(self, f64::INFINITY)
    }
    /// The divergence guard of the stepper, every `physics.check_every` steps: the same
    /// error as [`check_bounded`] for the state now. The default reads every position and
    /// velocity back; a backend that watches the integration itself (the GPU backend
    /// flags a non-finite or too fast node as it integrates) reads them only when
    /// something was flagged since the last call, so the error, when there is one, is
    /// the same.
    fn guard(&mut self, max_speed: f64) -> Result<(), SimError> {
        check_bounded(self, max_speed)
    }
}

/// Checks positions and velocities of the active nodes: an error names the first
/// non-finite value, or the fastest free node (inverse mass > 0) when it is faster than
/// `max_speed` m/s.
pub fn check_bounded<B: Backend + ?Sized>(backend: &mut B, max_speed: f64) -> Result<(), SimError> {
    let (p, v) = read_active_state(backend)?;
    check_arrays(backend.steps_taken(), &p, &v, max_speed)
}

/// The positions (inverse mass in w) and velocities of the active nodes, in one
/// [`Backend::read_many`].
pub(crate) fn read_active_state<B: Backend + ?Sized>(
    backend: &mut B,
) -> Result<(Vec<Vec4>, Vec<Vec4>), SimError> {
    let n = backend.n_active();
    let mut p = vec![[0.0f32; 4]; n];
    let mut v = vec![[0.0f32; 4]; n];
    backend.read_many(
        &[
            (NodeField::Position, (0..n).into()),
            (NodeField::Velocity, (0..n).into()),
        ],
        &mut [&mut p, &mut v],
    )?;
    Ok((p, v))
}

/// [`check_bounded`] on positions and velocities already read back (an output frame) at
/// step `step`.
pub fn check_arrays(
    step: u64,
    positions: &[Vec4],
    velocities: &[Vec4],
    max_speed: f64,
) -> Result<(), SimError> {
    for (buf, field) in [(positions, "position"), (velocities, "velocity")] {
        if let Some(node) = first_non_finite(buf) {
            return Err(SimError::Diverged { step, node, field });
        }
    }
    let fastest = positions
        .iter()
        .zip(velocities)
        .enumerate()
        .filter(|(_, (p, _))| p[3] > 0.0)
        .map(|(i, (_, v))| {
            let s = crate::math::xyz(*v).as_dvec3().length();
            (s, i)
        })
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match fastest {
        Some((speed, node)) if speed > max_speed => Err(SimError::Runaway {
            step,
            node,
            speed,
            limit: max_speed,
        }),
        _ => Ok(()),
    }
}

/// Index of the first vector with a NaN or infinite lane.
pub fn first_non_finite(v: &[Vec4]) -> Option<usize> {
    v.iter().position(|p| !p.iter().all(|c| c.is_finite()))
}

/// Checks that a [`Backend::read_nodes`] output has one slot per node.
pub fn check_gather(nodes: &[u32], out: &[Vec4]) -> Result<(), SimError> {
    if nodes.len() == out.len() {
        Ok(())
    } else {
        Err(SimError::BadRowLength {
            k: 1,
            len: out.len(),
        })
    }
}

/// Checks that a [`Backend::read_many`] has one output per request, each with one slot
/// per selected node (the nodes themselves are the backend's to check).
pub fn check_many(
    requests: &[(NodeField, NodeSelection<'_>)],
    outs: &[&mut [Vec4]],
) -> Result<(), SimError> {
    if requests.len() != outs.len() {
        return Err(SimError::BadReadLength {
            what: "outputs",
            expected: requests.len(),
            got: outs.len(),
        });
    }
    for ((_, nodes), out) in requests.iter().zip(outs) {
        let expected = nodes.len();
        if out.len() != expected {
            return Err(SimError::BadReadLength {
                what: "nodes",
                expected,
                got: out.len(),
            });
        }
    }
    Ok(())
}

/// Checks that `range` lies within `limit` nodes.
pub fn check_range(range: &Range<usize>, limit: usize, what: &'static str) -> Result<(), SimError> {
    if range.start > range.end || range.end > limit {
        Err(SimError::OutOfRange {
            start: range.start,
            end: range.end,
            limit,
            what,
        })
    } else {
        Ok(())
    }
}

/// Checks a neighbour row write (`index` and `weight` of whole rows of `k` slots starting
/// at node `first`, within `capacity`) and returns the rows it covers.
pub fn check_rows(
    first: usize,
    index: &[u32],
    weight: &[f32],
    k: usize,
    capacity: usize,
) -> Result<Range<usize>, SimError> {
    if !index.len().is_multiple_of(k) || weight.len() != index.len() {
        return Err(SimError::BadRowLength {
            k,
            len: index.len().max(weight.len()),
        });
    }
    let rows = first..first + index.len() / k;
    check_range(&rows, capacity, "allocated")?;
    Ok(rows)
}

/// Checks a shape array write of `len` bytes at `offset` into an array of `size` bytes
/// (`None`: the model has no such array). Offsets and lengths must be multiples of 4.
pub fn check_shape_write(
    array: ShapeArray,
    offset: usize,
    len: usize,
    size: Option<usize>,
) -> Result<(), SimError> {
    let err = |reason| {
        Err(SimError::BadShapeWrite {
            array: array.name().to_string(),
            offset,
            len,
            reason,
        })
    };
    match size {
        None => err("the model has no such array"),
        Some(_) if !offset.is_multiple_of(4) || !len.is_multiple_of(4) => {
            err("offset and length must be multiples of 4")
        }
        Some(size) if offset.checked_add(len).is_none_or(|end| end > size) => {
            err("past the end of the array")
        }
        Some(_) => Ok(()),
    }
}
