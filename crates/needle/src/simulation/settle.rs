//! New needle nodes placed in equilibrium (per-length model).
//!
//! The paper (section 5.1) places an added node's rest position by the shape vector of
//! its neighbourhood: strain-free for a neighbourhood that is only rotated, "a small
//! non-existent deformation in other methods". At the needle the neighbourhood is far
//! from a rigid motion: the tissue ahead of the tip is compressed by the cutting force,
//! the tissue along the shaft is dragged by friction. Measured on the liver scene, a Shaft
//! node placed that way started with an axial elastic force of -0.57 N against the 0.17 N
//! of friction it was to carry, and the Tip node re-added behind it with 0.18 N too much:
//! both were thrown back along the shaft at 1.5 m/s, and the tissue rang at its nodal
//! frequency (about 400 Hz) for a quarter of a second.
//!
//! Here the rest positions of the nodes an edit added are moved along the needle until
//! each one's axial elastic force balances the loads it carries (its share of the shaft's
//! friction, the tip's element on the front node, the contact patch's share on the Surface
//! node): a secant iteration on the force evaluation itself, so it holds for every tissue
//! model, with a finite-difference probe for the stiffness. Typically three evaluations
//! of the forces per edit (the cost of three steps, at a few edits per node spacing of
//! insertion). The edits stay exact: a node is re-placed by removing it and adding it
//! again with the new rest position, so the undo log is that of one addition.

use super::{xyz, Simulation};
use crate::needle::Needle;
use crate::node_editor::{EditError, Placement};
use crate::nodes::NodeRole;
use crate::state::Passage;
use crate::SimulationError;
use glam::DVec3;
use nalgebra::{DMatrix, DVector};
use needlesim_core::{NodeField, Vec4};

/// Most force evaluations spent on one edit.
const MAX_EVALUATIONS: usize = 8;
/// Relative residual at which a node counts as settled (of the largest load, or of the
/// force scale when every load is near zero).
const TOLERANCE: f64 = 0.001;

impl Simulation {
    /// Settles the needle nodes from stack position `first` on (all added this step): see
    /// the module docs. `now` is the needle this step, `pos` the needle nodes' positions.
    pub(super) fn settle(
        &mut self,
        first: usize,
        now: &Needle,
        pos: &[DVec3],
    ) -> Result<(), SimulationError> {
        // Nothing moves the tissue during a settle (force evaluations and the placed
        // nodes' own writes), so the editor need not read the neighbourhood again at
        // every re-placement (on a GPU, one blocking readback each).
        self.editor.begin_memo();
        let result = self.settle_placed(first, now, pos);
        self.editor.end_memo();
        result
    }

    /// [`Simulation::settle`], with the editor's memo kept.
    fn settle_placed(
        &mut self,
        first: usize,
        now: &Needle,
        pos: &[DVec3],
    ) -> Result<(), SimulationError> {
        let m = self.state.nodes.len();
        if first >= m || !self.sheathed() {
            return Ok(());
        }
        let t = DVec3::from(now.direction());
        let n0 = self.editor.n_mesh();
        // What each node's elastic force should be: the loads it carries along the needle
        // balanced, and the normal force its share of the shaft had before the edit.
        let targets: Vec<DVec3> = (first..m)
            .map(|k| DVec3::from(self.state.nodes[k].normal) - t * self.carried_load(k, now, pos))
            .collect();
        let scale = targets.iter().fold(0.0f64, |a, l| a.max(l.length()));
        let mut rest: Vec<DVec3> = (first..m)
            .map(|k| DVec3::from(self.rest_of(self.state.nodes[k].index)))
            .collect();
        // The residual of every node: its elastic force less its target.
        // Only these nodes' forces are needed: on the CPU a local evaluation (measured:
        // 230 whole-tissue evaluations over 1,500 advancing steps had cost +14.5% of the
        // step at 10,932 nodes).
        let placed: Vec<u32> = (n0 + first..n0 + m).map(|i| i as u32).collect();
        let to_residual = |f: &[Vec4]| -> Vec<DVec3> {
            f.iter().zip(&targets).map(|(f, g)| xyz(*f) - *g).collect()
        };
        let residual = |sim: &mut Self| -> Result<Vec<DVec3>, SimulationError> {
            sim.backend.compute_forces_on(&placed);
            let mut f = vec![[0.0f32; 4]; m - first];
            sim.backend
                .read(NodeField::Force, n0 + first..n0 + m, &mut f)
                .map_err(|e| sim.edit(e.into()))?;
            Ok(to_residual(&f))
        };
        let size = |r: &[DVec3]| r.iter().fold(0.0f64, |a, x| a.max(x.length()));
        // The first residual, read with the nodes' positions and velocities, which
        // re-placing them keeps (one readback on a GPU: the force evaluation moves
        // nothing).
        self.backend.compute_forces_on(&placed);
        let (mut p, mut v) = (vec![[0.0f32; 4]; m - first], vec![[0.0f32; 4]; m - first]);
        let mut f = vec![[0.0f32; 4]; m - first];
        let nodes = n0 + first..n0 + m;
        self.backend
            .read_many(
                &[
                    (NodeField::Position, nodes.clone().into()),
                    (NodeField::Velocity, nodes.clone().into()),
                    (NodeField::Force, nodes.into()),
                ],
                &mut [&mut p, &mut v, &mut f],
            )
            .map_err(|e| self.edit(e.into()))?;
        let state = (p, v);
        let mut r = to_residual(&f);
        // The force scale when the loads are small: what the tissue pushes with now.
        let tol = TOLERANCE * scale.max(0.1 * size(&r));
        if size(&r) <= tol {
            return Ok(());
        }
        // Probe: every node's rest moved a thousandth of a spacing forward gives its
        // stiffness against its own rest position, taken the same in every direction to
        // start Broyden's method (the nodes an edit adds are neighbours, so their
        // residuals are coupled; Broyden's rank-one updates learn the coupling from the
        // steps taken, one force evaluation each).
        let eps = 1e-3 * self.spacing;
        let probe: Vec<DVec3> = rest.iter().map(|x| *x + t * eps).collect();
        self.replace_rest(first, &probe, &state)?;
        let r1 = residual(self)?;
        let n = 3 * (m - first);
        let mut jac = DMatrix::<f64>::zeros(n, n);
        for (k, (a, b)) in r1.iter().zip(&r).enumerate() {
            let stiff = (*a - *b).dot(t) / eps;
            // A node that does not answer its rest position (or answers the wrong way) is
            // given the stiffness of the best-behaved one.
            let stiff = if stiff > 0.0 { stiff } else { f64::NAN };
            for c in 0..3 {
                jac[(3 * k + c, 3 * k + c)] = stiff;
            }
        }
        let good = (0..n)
            .map(|i| jac[(i, i)])
            .filter(|x| x.is_finite())
            .fold(0.0, f64::max);
        if good <= 0.0 {
            return Ok(());
        }
        for i in 0..n {
            if !jac[(i, i)].is_finite() {
                jac[(i, i)] = good;
            }
        }
        rest = probe;
        r = r1;
        // The best placement seen, kept if the iteration does not converge.
        let mut best = (size(&r), rest.clone());
        let flat = |r: &[DVec3]| DVector::from_iterator(n, r.iter().flat_map(|x| x.to_array()));
        let limit = 0.5 * self.spacing;
        for _ in 2..MAX_EVALUATIONS {
            if size(&r) <= tol {
                break;
            }
            let rv = flat(&r);
            let Some(step) = jac.clone().lu().solve(&(-&rv)) else {
                break;
            };
            let step = step.map(|d| d.clamp(-limit, limit));
            let next: Vec<DVec3> = rest
                .iter()
                .enumerate()
                .map(|(k, x)| *x + DVec3::new(step[3 * k], step[3 * k + 1], step[3 * k + 2]))
                .collect();
            self.replace_rest(first, &next, &state)?;
            let r2 = residual(self)?;
            // Good Broyden: J += (dr - J dx) dx^T / (dx . dx).
            let dr = flat(&r2) - rv;
            let dd = step.dot(&step);
            if dd > 0.0 {
                let u = (dr - &jac * &step) / dd;
                jac += u * step.transpose();
            }
            rest = next;
            r = r2;
            if size(&r) < best.0 {
                best = (size(&r), rest.clone());
            }
        }
        if size(&r) > best.0 {
            self.replace_rest(first, &best.1, &state)?;
        }
        Ok(())
    }

    /// The axial load needle node `k` carries (N, along the needle): its friction, the
    /// tip's element at the front, the contact patch's share on the Surface node.
    fn carried_load(&self, k: usize, now: &Needle, pos: &[DVec3]) -> f64 {
        let node = &self.state.nodes[k];
        let mut load = node.axial;
        let m = self.state.nodes.len();
        let front = match self.state.phase {
            Passage::Inside if self.state.nodes[m - 1].role == NodeRole::Tip => Some(m - 1),
            Passage::Inside => {
                let (t, base) = (DVec3::from(now.direction()), DVec3::from(now.base()));
                let s = |k: usize| (pos[k] - base).dot(t);
                (0..m).max_by(|&a, &b| s(a).total_cmp(&s(b)))
            }
            _ => None,
        };
        if front == Some(k) {
            load += self.state.front.force;
        }
        if k == 0 {
            if let Some(p) = &self.state.patch {
                load += p.surface * p.force;
            }
        }
        load
    }

    /// Re-places the needle nodes from stack position `first` on with the rest positions
    /// `rest` (one per node, in order): removes them and adds them again at their
    /// positions and velocities `state` (as read before the first re-placement), among
    /// the same candidates.
    #[allow(clippy::type_complexity)]
    fn replace_rest(
        &mut self,
        first: usize,
        rest: &[DVec3],
        state: &(Vec<[f32; 4]>, Vec<[f32; 4]>),
    ) -> Result<(), SimulationError> {
        let m = self.state.nodes.len();
        let (p, v) = state;
        for _ in first..m {
            self.editor
                .remove_last(self.backend.as_mut())
                .map_err(|e| self.edit(e))?;
        }
        for (j, k) in (first..m).enumerate() {
            let seeds = self.seeds_of(k);
            let cand = self.editor.rings(&seeds, 2);
            let index = self
                .editor
                .add_node_placed(
                    self.backend.as_mut(),
                    [p[j][0], p[j][1], p[j][2]],
                    [v[j][0], v[j][1], v[j][2]],
                    &cand,
                    Placement::Rest(rest[j].to_array()),
                )
                .map_err(|e: EditError| self.edit(e))?;
            debug_assert_eq!(index, self.state.nodes[k].index);
            // The inverse mass the constraint gave the node (the slot's w lane).
            let mut q = [p[j]];
            q[0][3] = p[j][3];
            self.backend
                .write(NodeField::Position, index as usize, &q)
                .map_err(|e| self.edit(e.into()))?;
            self.editor
                .note_position(self.backend.as_ref(), index, q[0]);
        }
        Ok(())
    }

    /// The seeds the needle node at stack position `k` was added with: the split
    /// triangle's corners for the Surface node, else the two nodes below it.
    fn seeds_of(&self, k: usize) -> Vec<u32> {
        if k == 0 {
            return self
                .state
                .surface
                .last_split()
                .map_or_else(Vec::new, |s| s.original.to_vec());
        }
        self.state.nodes[..k]
            .iter()
            .rev()
            .take(2)
            .map(|n| n.index)
            .collect()
    }
}
