//! Adding a node to the tissue and removing it again exactly (paper sections 5.1 and 5.2).
//!
//! Adding node i at world position x (steps 1-4 of section 5.1):
//! 1. its K nearest current nodes N(i) among the candidates the caller gives (the needle
//!    passes the two-ring of neighbours around the tip, so the cost does not grow with the
//!    tissue);
//! 2. `C = mean x_j`, `C0 = mean x0_j` over N(i), the neighbourhood's rotation R from the
//!    polar decomposition of `sum (x_j - C)(x0_j - C0)^T` (Mueller 2016 iteration), shape
//!    vector `v = R^T (x - C)`;
//! 3. rest position `x0_i = C0 + v`: a neighbourhood that is only rotated and translated
//!    gets no artificial strain;
//! 4. weights `w_ij` from the scene's kernel on rest distances (the node's own length scale
//!    is its farthest neighbour), then the mutual slot rule: i goes into a zero-weight
//!    slot of j, or else replaces j's last slot, and the pair it drops (j, m) is broken on
//!    m's side (weight 0); then the shape information of every node whose row changed
//!    (i, N(i), and the dropped partners m, which are neighbours of neighbours) is
//!    recomputed. A node's shape information depends only on its own row and the rest
//!    positions in it, so these are all the nodes the paper's step 4 can affect.
//!
//! Every write (neighbour rows, shape bytes, the new slot's position and velocity) first
//! records the bytes it overwrites. Removal replays that record backwards: after any
//! sequence of additions and removals that ends with all removed, every array is bitwise
//! what it was, and an addition or removal touches O(K^2) rows whatever the tissue's size.
//!
//! New nodes get the mesh nodes' mass. The PBA volume of a recomputed node is its density
//! estimate times the factor the build normalised the volumes with (no global
//! renormalisation, which would touch every node).

use glam::{DMat3, DVec3, Mat3, Quat, Vec3};
use needlesim_core::frame::PositionFrame;
use needlesim_core::math::Vec4;
use needlesim_core::models::mueller2016_rotation::extract_rotation;
use needlesim_core::models::{ShapeArray, ShapeInfo};
use needlesim_core::neighbours::{kernel_length, kernel_weight, Neighbours};
use needlesim_core::scene::WeightKernel;
use needlesim_core::{Backend, NodeField, NodeSelection, SimError, Tissue};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// How an added node's rest position is found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Placement {
    /// Fitted from the neighbourhood, less an elastic offset (world frame, m).
    Offset([f64; 3]),
    /// Given (world frame), m.
    Rest([f64; 3]),
}

/// Why a node cannot be added or removed.
#[derive(Debug, Error)]
pub enum EditError {
    /// Every needle node slot is in use.
    #[error(
        "needle node capacity reached: all {capacity} node slots are in use (raise \
         `needle.length` or `needle.spacing`, which size the needle node slots)"
    )]
    Capacity {
        /// Allocated node slots.
        capacity: usize,
    },
    /// None of the candidate nodes can be a neighbour.
    #[error("cannot add a node at {position:?}: no active node among the candidates")]
    NoNeighbours {
        /// Where the node was to be added.
        position: [f32; 3],
    },
    /// A position that is not finite.
    #[error("cannot add a node at the non-finite position {0:?}")]
    NonFinite([f32; 3]),
    /// Nothing left to remove.
    #[error("no added node to remove")]
    NothingToRemove,
    /// The backend refused a read or write.
    #[error(transparent)]
    Backend(#[from] SimError),
}

/// One overwritten piece of state.
#[derive(Debug, Clone, Serialize, Deserialize)]
enum Undo {
    /// A neighbour row as it was.
    Row {
        node: u32,
        index: Vec<u32>,
        weight: Vec<f32>,
    },
    /// Shape bytes as they were (`array`: position in [`ShapeInfo::bytes`]).
    Shape {
        array: usize,
        offset: usize,
        bytes: Vec<u8>,
    },
    /// The new slot's position and velocity as they were.
    Slot {
        node: u32,
        position: Vec4,
        velocity: Vec4,
    },
}

/// What one addition changed.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Addition {
    node: u32,
    undo: Vec<Undo>,
    rest: Vec4,
    dk: f64,
}

/// The host side of node addition and removal: a mirror of the neighbour rows and the
/// shape information, the rest positions, and the undo log.
#[derive(Debug, Clone)]
pub struct NodeEditor {
    nb: Neighbours,
    shape: ShapeInfo,
    rest: Vec<Vec4>,
    /// Length scale of every node's kernel (`kernel_length` of its K slots' rest distances).
    dk: Vec<f64>,
    kernel: WeightKernel,
    volume_scale: f64,
    inv_mass: f32,
    n_mesh: usize,
    n_active: usize,
    log: Vec<Addition>,
    /// The frame of `rest` and of the shape information's rest positions
    /// ([`Tissue::frame`]); positions read from the backend are world ones.
    frame: PositionFrame,
    /// What the backend holds, while a sequence of edits that moves no node keeps it
    /// ([`NodeEditor::begin_memo`]).
    memo: Option<Memo>,
    /// The last addition's neighbours and their positions as it read them
    /// ([`NodeEditor::last_neighbour_positions`]; cleared by the next addition or
    /// removal, valid only until anything moves the tissue).
    last_neighbours: Vec<(u32, Vec4)>,
}

/// Positions and slot states read from the backend or written to it since
/// [`NodeEditor::begin_memo`], as a read would give them now: a settle re-places the same
/// few nodes several times among the same neighbours, and on a GPU each addition's read
/// was a blocking readback.
#[derive(Debug, Clone, Default)]
struct Memo {
    /// World positions by node.
    position: std::collections::HashMap<u32, Vec4>,
    /// Velocities by node.
    velocity: std::collections::HashMap<u32, Vec4>,
}

impl NodeEditor {
    /// The editor for `tissue` as built (before any step), with rest positions `rest` of
    /// its mesh nodes.
    pub fn new(tissue: &Tissue, rest: &[[f64; 3]], kernel: WeightKernel) -> NodeEditor {
        let capacity = tissue.state.capacity();
        let n = tissue.n_mesh;
        let mut r = vec![[0.0f32; 4]; capacity];
        let frame = tissue.frame;
        for (o, p) in r.iter_mut().zip(rest) {
            let q = frame.local(*p);
            *o = [q[0], q[1], q[2], 0.0];
        }
        let nb = tissue.neighbours.clone();
        let k = nb.k;
        let dk = (0..capacity)
            .map(|i| {
                if i >= n {
                    return 0.0;
                }
                kernel_length(
                    &mut (0..k)
                        .map(|s| dvec3(r[i]).distance(dvec3(r[nb.index[i * k + s] as usize])))
                        .collect::<Vec<_>>(),
                )
            })
            .collect();
        NodeEditor {
            volume_scale: tissue.shape.volume_scale(&r, &nb, n),
            shape: tissue.shape.clone(),
            nb,
            rest: r,
            dk,
            kernel,
            inv_mass: (1.0 / tissue.node_mass) as f32,
            n_mesh: n,
            n_active: tissue.state.n_active,
            log: Vec::new(),
            frame,
            memo: None,
            last_neighbours: Vec::new(),
        }
    }

    /// From now until [`NodeEditor::end_memo`], positions and velocities the editor reads
    /// or writes are remembered and not read again: for a sequence of removals and
    /// additions during which nothing else writes a velocity, no step is taken, and a
    /// position written outside the editor is told with [`NodeEditor::note_position`]
    /// (there is no such call for velocities: none may be written). A value written is
    /// remembered as a read would return it (through the backend's position frame, as
    /// [`Backend::write`] stores it).
    pub(crate) fn begin_memo(&mut self) {
        self.memo = Some(Memo::default());
    }

    /// Ends [`NodeEditor::begin_memo`].
    pub(crate) fn end_memo(&mut self) {
        self.memo = None;
    }

    /// The positions of `nodes` as the last addition read them, if it read all of them
    /// (they are among the K nearest it chose from): the caller that asks right after
    /// the addition, before anything moves the tissue, gets what a read would give,
    /// without one.
    pub(crate) fn last_neighbour_positions(&self, nodes: &[u32]) -> Option<Vec<Vec4>> {
        nodes
            .iter()
            .map(|j| {
                self.last_neighbours
                    .iter()
                    .find(|(i, _)| i == j)
                    .map(|(_, p)| *p)
            })
            .collect()
    }

    /// Records that `position` (world) was written to node `i` outside the editor, while
    /// a memo is kept.
    pub(crate) fn note_position(&mut self, backend: &dyn Backend, i: u32, position: Vec4) {
        if let Some(m) = self.memo.as_mut() {
            m.position.insert(i, stored_as_read(backend, position));
        }
    }

    /// Positions of `nodes` and the position and velocity of `slot`: from the memo where
    /// it has them, the rest in one read.
    fn read_around(
        &mut self,
        backend: &mut dyn Backend,
        nodes: &[u32],
        slot: usize,
    ) -> Result<(Vec<Vec4>, Vec4, Vec4), EditError> {
        let slot_u = slot as u32;
        // Without a memo, one kept for this call alone: everything is read, in one go.
        let mut scratch = Memo::default();
        let memo = self.memo.as_mut().unwrap_or(&mut scratch);
        let mut missing: Vec<u32> = nodes
            .iter()
            .copied()
            .filter(|j| !memo.position.contains_key(j))
            .collect();
        if !memo.position.contains_key(&slot_u) {
            missing.push(slot_u);
        }
        missing.sort_unstable();
        missing.dedup();
        let want_v = !memo.velocity.contains_key(&slot_u);
        if !missing.is_empty() || want_v {
            let mut pos = vec![[0.0f32; 4]; missing.len()];
            let mut v = [[0.0f32; 4]];
            let mut requests = vec![(NodeField::Position, missing.as_slice().into())];
            let mut outs: Vec<&mut [Vec4]> = vec![&mut pos];
            if want_v {
                requests.push((NodeField::Velocity, (slot..slot + 1).into()));
                outs.push(&mut v);
            }
            backend.read_many(&requests, &mut outs)?;
            memo.position.extend(missing.into_iter().zip(pos));
            if want_v {
                memo.velocity.insert(slot_u, v[0]);
            }
        }
        let pos = nodes.iter().map(|j| memo.position[j]).collect();
        Ok((pos, memo.position[&slot_u], memo.velocity[&slot_u]))
    }

    /// Writes node `i`'s position and velocity, and remembers them as a read would
    /// return them while a memo is kept.
    fn write_state(
        &mut self,
        backend: &mut dyn Backend,
        i: usize,
        position: Vec4,
        velocity: Vec4,
    ) -> Result<(), EditError> {
        backend.write(NodeField::Position, i, &[position])?;
        backend.write(NodeField::Velocity, i, &[velocity])?;
        if let Some(m) = self.memo.as_mut() {
            m.position
                .insert(i as u32, stored_as_read(backend, position));
            m.velocity.insert(i as u32, velocity);
        }
        Ok(())
    }

    /// Nodes simulated now.
    pub fn n_active(&self) -> usize {
        self.n_active
    }

    /// Nodes of the original mesh.
    pub fn n_mesh(&self) -> usize {
        self.n_mesh
    }

    /// Allocated node slots.
    pub fn capacity(&self) -> usize {
        self.rest.len()
    }

    /// Nodes added and not yet removed.
    pub fn n_added(&self) -> usize {
        self.log.len()
    }

    /// The neighbour rows as the backend has them.
    pub fn neighbours(&self) -> &Neighbours {
        &self.nb
    }

    /// The static shape information as the backend has it (per-step arrays such as
    /// rotations and first-pass results are those of the build).
    pub fn shape(&self) -> &ShapeInfo {
        &self.shape
    }

    /// Rest position of node `i` in world coordinates (the f32 rest position the shape
    /// information holds, moved out of [`Tissue::frame`]).
    pub fn rest_position(&self, i: usize) -> [f64; 3] {
        let r = self.rest[i];
        self.frame.global([r[0], r[1], r[2]])
    }

    /// The nodes whose elastic force removing the additions from log position `since` on
    /// (the last `n_added() - since` of them) would change: every node whose neighbour row
    /// they changed, and the nodes that row holds (with a nonzero weight) before and
    /// after. A node's force sums the contributions of the neighbourhoods it belongs to,
    /// and a neighbourhood's contribution depends only on its own row and its shape
    /// information, which an edit changes together. The slots those additions took are
    /// left out. Sorted, each once.
    pub fn reach_since(&self, since: usize) -> Vec<u32> {
        let adds = self.log.get(since..).unwrap_or(&[]);
        let Some(first) = adds.first().map(|a| a.node as usize) else {
            return Vec::new();
        };
        let k = self.nb.k;
        let mut out = Vec::new();
        for u in adds.iter().flat_map(|a| &a.undo) {
            if let Undo::Row {
                node,
                index,
                weight,
            } = u
            {
                out.push(*node);
                let t = *node as usize;
                let now = self.nb.index[t * k..(t + 1) * k]
                    .iter()
                    .zip(&self.nb.weight[t * k..(t + 1) * k]);
                for (j, w) in index.iter().zip(weight).chain(now) {
                    if *w != 0.0 {
                        out.push(*j);
                    }
                }
            }
        }
        out.retain(|&j| (j as usize) < first);
        out.sort_unstable();
        out.dedup();
        out
    }

    /// [`NodeEditor::reach_since`] for the last addition alone: the nodes whose elastic
    /// force removing the last added node can change.
    pub fn removal_reach(&self) -> Vec<u32> {
        self.reach_since(self.log.len().saturating_sub(1))
    }

    /// The elastic forces of `nodes` (all below the first slot the additions from log
    /// position `since` on took) as they were before those additions, at the current
    /// positions: the neighbour rows and static shape information the additions changed
    /// are put back on the backend for one partial force evaluation, then the current
    /// ones are written again and the additions' slots made active again (the editor's
    /// own copy is not touched). Per-step arrays (warm-start rotations, first-pass
    /// results, viscoelastic state) are left as they are. Without such additions, the
    /// forces as they are.
    pub fn forces_before(
        &self,
        backend: &mut dyn Backend,
        since: usize,
        nodes: &[u32],
    ) -> Result<Vec<Vec4>, EditError> {
        self.forces_before_with(backend, since, nodes, &[], &mut [])
    }

    /// [`NodeEditor::forces_before`], with `extra` (fields that a force evaluation does
    /// not change: positions, velocities) read into `extra_outs` in the same readback
    /// where the additions from `since` on are none (else just before).
    pub(crate) fn forces_before_with(
        &self,
        backend: &mut dyn Backend,
        since: usize,
        nodes: &[u32],
        extra: &[(NodeField, NodeSelection<'_>)],
        extra_outs: &mut [&mut [Vec4]],
    ) -> Result<Vec<Vec4>, EditError> {
        let adds = self.log.get(since..).unwrap_or(&[]);
        if !adds.is_empty() && !extra.is_empty() {
            backend.read_many(extra, extra_outs)?;
        }
        let merge = adds.is_empty();
        let mut f = vec![[0.0f32; 4]; nodes.len()];
        let mut evaluate = |backend: &mut dyn Backend| -> Result<(), SimError> {
            if let Some(first) = adds.first() {
                backend.set_n_active(first.node as usize)?;
                self.put_back(backend, adds, false)?;
            }
            backend.compute_forces_on(nodes);
            if !merge || extra.is_empty() {
                return backend.read_nodes(NodeField::Force, nodes, &mut f);
            }
            let mut requests = vec![(NodeField::Force, nodes.into())];
            requests.extend(extra.iter().cloned());
            let mut outs: Vec<&mut [Vec4]> = vec![&mut f];
            outs.extend(extra_outs.iter_mut().map(|o| &mut **o));
            backend.read_many(&requests, &mut outs)
        };
        let done = evaluate(backend);
        // The current rows and slots go back whatever failed above (the first error is
        // the one reported).
        let restored = match adds.is_empty() {
            true => Ok(()),
            false => self
                .put_back(backend, adds, true)
                .and_then(|_| backend.set_n_active(self.n_active)),
        };
        done.and(restored)?;
        Ok(f)
    }

    /// Writes the rows and static shape bytes `adds` changed: as they were before them
    /// (`current` false, latest addition first so that the oldest saved bytes are written
    /// last) or as they are now.
    fn put_back(
        &self,
        backend: &mut dyn Backend,
        adds: &[Addition],
        current: bool,
    ) -> Result<(), SimError> {
        let k = self.nb.k;
        let arrays = self.shape.bytes();
        let mut write = |u: &Undo| -> Result<(), SimError> {
            match u {
                Undo::Row {
                    node,
                    index,
                    weight,
                } => {
                    let t = *node as usize;
                    match current {
                        true => backend.write_neighbour_rows(
                            t,
                            &self.nb.index[t * k..(t + 1) * k],
                            &self.nb.weight[t * k..(t + 1) * k],
                        ),
                        false => backend.write_neighbour_rows(t, index, weight),
                    }
                }
                Undo::Shape {
                    array,
                    offset,
                    bytes,
                } => {
                    let (name, now) = &arrays[*array];
                    if matches!(
                        name,
                        ShapeArray::Rotation
                            | ShapeArray::ClusterCentre
                            | ShapeArray::FirstPass
                            | ShapeArray::Viscous
                    ) {
                        return Ok(());
                    }
                    let data = match current {
                        true => &now[*offset..*offset + bytes.len()],
                        false => &bytes[..],
                    };
                    backend.write_shape_bytes(*name, *offset, data)
                }
                Undo::Slot { .. } => Ok(()),
            }
        };
        if current {
            adds.iter().flat_map(|a| &a.undo).try_for_each(&mut write)
        } else {
            adds.iter()
                .rev()
                .flat_map(|a| a.undo.iter().rev())
                .try_for_each(&mut write)
        }
    }

    /// Inverse mass of a free node.
    pub fn inverse_mass(&self) -> f32 {
        self.inv_mass
    }

    /// The active nodes within `rings` neighbour hops of `seeds` (seeds included), sorted,
    /// each once.
    pub fn rings(&self, seeds: &[u32], rings: usize) -> Vec<u32> {
        let k = self.nb.k;
        let mut set: Vec<u32> = seeds
            .iter()
            .copied()
            .filter(|&s| (s as usize) < self.n_active)
            .collect();
        set.sort_unstable();
        set.dedup();
        let mut frontier = set.clone();
        for _ in 0..rings {
            let mut next = Vec::new();
            for &i in &frontier {
                let i = i as usize;
                for s in 0..k {
                    if self.nb.weight[i * k + s] != 0.0 {
                        next.push(self.nb.index[i * k + s]);
                    }
                }
            }
            next.sort_unstable();
            next.dedup();
            next.retain(|j| set.binary_search(j).is_err() && (*j as usize) < self.n_active);
            set.extend_from_slice(&next);
            set.sort_unstable();
            frontier = next;
        }
        set
    }

    /// Adds a node at world position `x` with velocity `v`, its neighbours chosen among
    /// `candidates` (active node indices; others are ignored). Returns its index.
    pub fn add_node(
        &mut self,
        backend: &mut dyn Backend,
        x: [f32; 3],
        v: [f32; 3],
        candidates: &[u32],
    ) -> Result<u32, EditError> {
        self.add_node_with_offset(backend, x, v, candidates, [0.0; 3])
    }

    /// The offset of node `i` from where a rigid motion of its neighbourhood would put it,
    /// `(x_i - C) - R (x0_i - C0)` over its live neighbours, m: the part of its position
    /// that strains the tissue around it.
    pub fn elastic_offset(&self, backend: &mut dyn Backend, i: u32) -> Result<[f64; 3], EditError> {
        let mut nodes: Vec<u32> = self.nb.live(i as usize).map(|(_, j, _)| j as u32).collect();
        nodes.push(i);
        let mut pos = vec![[0.0f32; 4]; nodes.len()];
        backend.read_nodes(NodeField::Position, &nodes, &mut pos)?;
        let xi = pos.pop().expect("node itself");
        nodes.pop();
        if nodes.is_empty() {
            return Ok([0.0; 3]);
        }
        let members: Vec<(u32, Vec4)> = nodes.into_iter().zip(pos).collect();
        let (c, c0, rot, _) = self.rigid_fit(&members);
        let d0 = dvec3(self.rest[i as usize]) - c0;
        Ok((dvec3(xi) - c - rot * d0).to_array())
    }

    /// Centroids (current, rest) of `members` (index, current position) and the rotation
    /// of the polar decomposition of `sum (x_j - C)(x0_j - C0)^T` (matrix and quaternion).
    fn rigid_fit(&self, members: &[(u32, Vec4)]) -> (DVec3, DVec3, DMat3, Vec4) {
        let m = members.len() as f64;
        let (mut c, mut c0) = (DVec3::ZERO, DVec3::ZERO);
        for (j, p) in members {
            c += dvec3(*p) / m;
            c0 += dvec3(self.rest[*j as usize]) / m;
        }
        let mut a_mat = DMat3::ZERO;
        let mut scale = 0.0f64;
        for (j, p) in members {
            let d = dvec3(*p) - c;
            let d0 = dvec3(self.rest[*j as usize]) - c0;
            // The outer product d d0^T, column by column.
            a_mat += DMat3::from_cols(d * d0.x, d * d0.y, d * d0.z);
            scale += d0.length_squared();
        }
        let q = extract_rotation(&(a_mat / scale.max(1e-300)).as_mat3(), Quat::IDENTITY, 50);
        (c, c0, Mat3::from_quat(q).as_dmat3(), q.to_array())
    }

    /// [`NodeEditor::add_node`] with an elastic offset (world frame, m): the rest position
    /// is `C0 + R^T ((x - C) - offset)`, so that a node re-added in place of one with that
    /// [`NodeEditor::elastic_offset`] strains the tissue around it as the old one did.
    pub fn add_node_with_offset(
        &mut self,
        backend: &mut dyn Backend,
        x: [f32; 3],
        v: [f32; 3],
        candidates: &[u32],
        offset: [f64; 3],
    ) -> Result<u32, EditError> {
        self.add_node_placed(backend, x, v, candidates, Placement::Offset(offset))
    }

    /// [`NodeEditor::add_node`] with the rest position as `placement` says: fitted less
    /// an elastic offset ([`NodeEditor::add_node_with_offset`]), or given (a node re-added
    /// for the same material point: the needle's Tip node refresh keeps the material at
    /// the tip, and so the load ahead of it, this way).
    pub fn add_node_placed(
        &mut self,
        backend: &mut dyn Backend,
        x: [f32; 3],
        v: [f32; 3],
        candidates: &[u32],
        placement: Placement,
    ) -> Result<u32, EditError> {
        if !x.iter().all(|c| c.is_finite()) {
            return Err(EditError::NonFinite(x));
        }
        if let Placement::Rest(r) = placement {
            if !r.iter().all(|c| c.is_finite()) {
                return Err(EditError::NonFinite(r.map(|c| c as f32)));
            }
        }
        self.last_neighbours.clear();
        let i = self.n_active;
        if i >= self.capacity() {
            return Err(EditError::Capacity {
                capacity: self.capacity(),
            });
        }
        let k = self.nb.k;

        // Step 1: the K nearest current nodes among the candidates.
        let mut cand: Vec<u32> = candidates
            .iter()
            .copied()
            .filter(|&c| (c as usize) < i)
            .collect();
        cand.sort_unstable();
        cand.dedup();
        if cand.is_empty() {
            return Err(EditError::NoNeighbours { position: x });
        }
        // The candidates' positions, with the slot's old state for the undo log (one
        // readback on a GPU, none for what a memo holds; nothing below writes the slot's
        // position or velocity before the log takes it).
        let (pos, old_p, old_v) = self.read_around(backend, &cand, i)?;
        let xi = [x[0], x[1], x[2], 0.0];
        let mut near: Vec<(f64, u32, Vec4)> = cand
            .iter()
            .zip(&pos)
            .map(|(&c, &p)| (dvec3(p).distance(dvec3(xi)), c, p))
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        near.truncate(k);

        // Steps 2 and 3: rotation of the neighbourhood, shape vector, rest position.
        let members: Vec<(u32, Vec4)> = near.iter().map(|(_, j, p)| (*j, *p)).collect();
        self.last_neighbours.clone_from(&members);
        let (c, c0, rot, q) = self.rigid_fit(&members);
        let x0: Vec4 = match placement {
            Placement::Offset(offset) => {
                let d = Vec3::from_array(x).as_dvec3() - c - DVec3::from_array(offset);
                // v = R^T d
                c0 + rot.transpose() * d
            }
            Placement::Rest(r) => DVec3::from_array(r) - DVec3::from_array(self.frame.origin()),
        }
        .as_vec3()
        .extend(0.0)
        .to_array();

        let mut undo = Vec::new();
        let old = Addition {
            node: i as u32,
            undo: Vec::new(),
            rest: self.rest[i],
            dk: self.dk[i],
        };
        self.rest[i] = x0;
        let dki = kernel_length(
            &mut near
                .iter()
                .map(|(_, j, _)| dvec3(self.rest[*j as usize]).distance(dvec3(x0)))
                .collect::<Vec<_>>(),
        );
        self.dk[i] = dki;

        // Step 4: weights and the mutual slot rule.
        let mut touched: Vec<u32> = Vec::new();
        let mut row_index = vec![0u32; k];
        let mut row_weight = vec![0.0f32; k];
        let mut filled = 0;
        let mut pairs = Vec::new();
        for (_, j, _) in &near {
            let ju = *j as usize;
            let r = dvec3(self.rest[ju]).distance(dvec3(x0));
            let w = kernel_weight(self.kernel, r, dki, self.dk[ju]) as f32;
            if w == 0.0 {
                continue;
            }
            row_index[filled] = *j;
            row_weight[filled] = w;
            filled += 1;
            pairs.push((*j, w));
        }
        if pairs.is_empty() {
            self.rest[i] = old.rest;
            self.dk[i] = old.dk;
            return Err(EditError::NoNeighbours { position: x });
        }
        self.save_row(i as u32, &mut touched, &mut undo);
        self.nb.index[i * k..(i + 1) * k].copy_from_slice(&row_index);
        self.nb.weight[i * k..(i + 1) * k].copy_from_slice(&row_weight);
        for &(j, w) in &pairs {
            let ju = j as usize;
            let row = ju * k..(ju + 1) * k;
            let slot = match self.nb.weight[row.clone()].iter().position(|&x| x == 0.0) {
                Some(s) => s,
                None => {
                    // Replace the last slot and break the dropped pair on the other side.
                    let s = k - 1;
                    let dropped = self.nb.index[ju * k + s] as usize;
                    if let Some(r) = (0..k).find(|&r| {
                        self.nb.index[dropped * k + r] == j
                            && self.nb.weight[dropped * k + r] != 0.0
                    }) {
                        self.save_row(dropped as u32, &mut touched, &mut undo);
                        self.nb.weight[dropped * k + r] = 0.0;
                    }
                    s
                }
            };
            self.save_row(j, &mut touched, &mut undo);
            self.nb.index[ju * k + slot] = i as u32;
            self.nb.weight[ju * k + slot] = w;
        }
        for &t in &touched {
            let t = t as usize;
            backend.write_neighbour_rows(
                t,
                &self.nb.index[t * k..(t + 1) * k],
                &self.nb.weight[t * k..(t + 1) * k],
            )?;
        }

        // Shape information of every node whose row changed.
        for &t in &touched {
            let rows = self.shape.node_rows(
                t as usize,
                &self.rest,
                &self.nb,
                self.volume_scale,
                t as usize == i,
            );
            for (array, offset, bytes) in rows {
                self.write_shape(backend, array, offset, &bytes, &mut undo)?;
            }
        }
        if self.shape.has_rotation() {
            self.write_shape(
                backend,
                ShapeArray::Rotation,
                i * 16,
                bytemuck::bytes_of(&q),
                &mut undo,
            )?;
        }

        // The slot's state (read with the candidates).
        undo.push(Undo::Slot {
            node: i as u32,
            position: old_p,
            velocity: old_v,
        });
        self.write_state(
            backend,
            i,
            [x[0], x[1], x[2], self.inv_mass],
            [v[0], v[1], v[2], 0.0],
        )?;
        backend.set_n_active(i + 1)?;
        self.n_active = i + 1;
        self.log.push(Addition { undo, ..old });
        Ok(i as u32)
    }

    /// Removes the most recently added node, restoring every row it changed.
    pub fn remove_last(&mut self, backend: &mut dyn Backend) -> Result<u32, EditError> {
        let add = self.log.pop().ok_or(EditError::NothingToRemove)?;
        self.last_neighbours.clear();
        let k = self.nb.k;
        let i = add.node as usize;
        backend.set_n_active(i)?;
        self.n_active = i;
        for u in add.undo.iter().rev() {
            match u {
                Undo::Row {
                    node,
                    index,
                    weight,
                } => {
                    let t = *node as usize;
                    self.nb.index[t * k..(t + 1) * k].copy_from_slice(index);
                    self.nb.weight[t * k..(t + 1) * k].copy_from_slice(weight);
                    backend.write_neighbour_rows(t, index, weight)?;
                }
                Undo::Shape {
                    array,
                    offset,
                    bytes,
                } => {
                    let mut arrays = self.shape.bytes_mut();
                    let (name, target) = &mut arrays[*array];
                    target[*offset..*offset + bytes.len()].copy_from_slice(bytes);
                    backend.write_shape_bytes(*name, *offset, bytes)?;
                }
                Undo::Slot {
                    node,
                    position,
                    velocity,
                } => {
                    let (n, p, v) = (*node as usize, *position, *velocity);
                    self.write_state(backend, n, p, v)?;
                }
            }
        }
        self.rest[i] = add.rest;
        self.dk[i] = add.dk;
        Ok(add.node)
    }

    /// Records row `node` before its first change in this addition.
    fn save_row(&self, node: u32, touched: &mut Vec<u32>, undo: &mut Vec<Undo>) {
        if touched.contains(&node) {
            return;
        }
        touched.push(node);
        let k = self.nb.k;
        let t = node as usize;
        undo.push(Undo::Row {
            node,
            index: self.nb.index[t * k..(t + 1) * k].to_vec(),
            weight: self.nb.weight[t * k..(t + 1) * k].to_vec(),
        });
    }

    fn shape_bytes(&mut self, array: ShapeArray) -> (usize, &mut [u8]) {
        self.shape
            .bytes_mut()
            .into_iter()
            .enumerate()
            .find(|(_, (n, _))| *n == array)
            .map(|(k, (_, b))| (k, b))
            .expect("array listed by ShapeInfo::node_rows")
    }

    fn write_shape(
        &mut self,
        backend: &mut dyn Backend,
        array: ShapeArray,
        offset: usize,
        bytes: &[u8],
        undo: &mut Vec<Undo>,
    ) -> Result<(), EditError> {
        let (k, target) = self.shape_bytes(array);
        let target = &mut target[offset..offset + bytes.len()];
        undo.push(Undo::Shape {
            array: k,
            offset,
            bytes: target.to_vec(),
        });
        target.copy_from_slice(bytes);
        backend.write_shape_bytes(array, offset, bytes)?;
        Ok(())
    }
}

/// The editor's changing state (the rows, shape information, rest positions and undo
/// log), as a checkpoint stores it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct EditorSnapshot {
    index: Vec<u32>,
    weight: Vec<f32>,
    shape: Vec<Vec<u8>>,
    rest: Vec<Vec4>,
    dk: Vec<f64>,
    n_active: usize,
    log: Vec<Addition>,
}

impl NodeEditor {
    /// The changing state.
    pub(crate) fn snapshot(&self) -> EditorSnapshot {
        EditorSnapshot {
            index: self.nb.index.clone(),
            weight: self.nb.weight.clone(),
            shape: self
                .shape
                .bytes()
                .into_iter()
                .map(|(_, b)| b.to_vec())
                .collect(),
            rest: self.rest.clone(),
            dk: self.dk.clone(),
            n_active: self.n_active,
            log: self.log.clone(),
        }
    }

    /// Puts back a state from [`NodeEditor::snapshot`] of an editor built from the same
    /// tissue; `Err` names the first array whose size differs.
    pub(crate) fn restore(&mut self, s: EditorSnapshot) -> Result<(), &'static str> {
        let sizes = self.shape.bytes().into_iter().map(|(n, b)| (n, b.len()));
        if s.shape.len() != self.shape.bytes().len() {
            return Err("shape arrays");
        }
        for ((name, len), saved) in sizes.zip(&s.shape) {
            if saved.len() != len {
                return Err(name.name());
            }
        }
        let capacity = self.rest.len();
        let rows = capacity * self.nb.k;
        let bad_undo = s.log.iter().flat_map(|a| &a.undo).any(|u| match u {
            Undo::Row {
                node,
                index,
                weight,
            } => {
                *node as usize >= capacity
                    || index.len() != self.nb.k
                    || weight.len() != self.nb.k
                    || index.iter().any(|&j| j as usize >= capacity)
            }
            Undo::Shape {
                array,
                offset,
                bytes,
            } => s
                .shape
                .get(*array)
                .is_none_or(|a| offset.checked_add(bytes.len()).is_none_or(|e| e > a.len())),
            Undo::Slot { node, .. } => *node as usize >= capacity,
        });
        if s.index.len() != rows
            || s.weight.len() != rows
            || s.index.iter().any(|&j| j as usize >= capacity)
        {
            return Err("neighbour rows");
        }
        if s.rest.len() != capacity || s.dk.len() != capacity {
            return Err("rest positions");
        }
        if s.n_active < self.n_mesh
            || s.n_active > capacity
            || s.log.len() != s.n_active - self.n_mesh
        {
            return Err("active nodes");
        }
        if bad_undo || s.log.iter().any(|a| a.node as usize >= capacity) {
            return Err("undo log");
        }
        self.nb.index = s.index;
        self.nb.weight = s.weight;
        for ((_, target), saved) in self.shape.bytes_mut().into_iter().zip(&s.shape) {
            target.copy_from_slice(saved);
        }
        self.rest = s.rest;
        self.dk = s.dk;
        self.n_active = s.n_active;
        self.log = s.log;
        Ok(())
    }
}

/// `position` (world) as a read of [`NodeField::Position`] returns it after a write:
/// stored in the backend's position frame, read back to the world's (a backend that
/// stores positions in another frame must say so through `Backend::position_frame`).
fn stored_as_read(backend: &dyn Backend, position: Vec4) -> Vec4 {
    let frame = backend.position_frame();
    match frame.is_world() {
        true => position,
        false => frame.to_world(frame.to_frame(position)),
    }
}

/// The position part of a node's `[x, y, z, w]`, in f64.
fn dvec3(p: Vec4) -> DVec3 {
    glam::Vec4::from_array(p).truncate().as_dvec3()
}
