//! The loads the shaft carries across a node edit: the friction field before the edit
//! and its reassignment after it ([`crate::sheath::reassign`]), the load a Tip node
//! carries into its replacement, and a new Shaft node's motion.

use super::{xyz, Simulation};
use crate::friction::FrictionState;
use crate::needle::Needle;
use crate::node_editor::Placement;
use crate::sheath::{self, FieldPoint};
use crate::SimulationError;
use glam::DVec3;
use needlesim_core::math::Vec4;
use needlesim_core::NodeField;

/// The shaft's friction before an edit ([`Simulation::reassign_friction`]).
#[derive(Debug, Default)]
pub(super) struct FrictionField {
    /// Loads per unit length ([`FieldPoint::per_length`]) of every node in stack order.
    per_node: Vec<[f64; sheath::FIELD]>,
    /// The same at the nodes with a shaft length, sorted along the needle.
    points: Vec<FieldPoint>,
    /// Summed loads, N.
    total: [f64; sheath::FIELD],
}

impl Simulation {
    /// The shaft's loads as a field before an edit (nodes at positions `pos`, needle
    /// `now`): friction and normal force per length.
    pub(super) fn friction_field(&self, pos: &[DVec3], now: &Needle) -> FrictionField {
        let (t, base) = (DVec3::from(now.direction()), DVec3::from(now.base()));
        let s: Vec<f64> = pos.iter().map(|x| (*x - base).dot(t)).collect();
        let l = self.node_lengths(&s, now);
        let mut field = FrictionField::default();
        for (k, n) in self.state.nodes.iter().enumerate() {
            let loads = [
                n.axial,
                n.circumferential,
                n.normal[0],
                n.normal[1],
                n.normal[2],
            ];
            for (t, x) in field.total.iter_mut().zip(loads) {
                *t += x;
            }
            let per = match l[k] > 0.0 {
                true => loads.map(|x| x / l[k]),
                false => [0.0; sheath::FIELD],
            };
            field.per_node.push(per);
            if l[k] > 0.0 {
                field.points.push(FieldPoint {
                    s: s[k],
                    per_length: per,
                });
            }
        }
        field.points.sort_by(|a, b| a.s.total_cmp(&b.s));
        field
    }

    /// Gives the needle nodes after an edit the loads of the field before it
    /// ([`sheath::reassign`]): the nodes below the edit's low-water mark keep their loads
    /// per length, the others take the field's value at their place, and the totals stay.
    /// The friction is the new nodes' sheath state; the normal force is what they are
    /// settled to ([`Simulation::settle`]).
    pub(super) fn reassign_friction(&mut self, field: &FrictionField, pos: &[DVec3], now: &Needle) {
        let (t, base) = (DVec3::from(now.direction()), DVec3::from(now.base()));
        let s: Vec<f64> = pos.iter().map(|x| (*x - base).dot(t)).collect();
        let l = self.node_lengths(&s, now);
        let own: Vec<Option<[f64; sheath::FIELD]>> = (0..s.len())
            .map(|k| (k < self.low_water).then(|| field.per_node[k]))
            .collect();
        let loads = sheath::reassign(&field.points, field.total, &s, &l, &own);
        for (k, (n, f)) in self.state.nodes.iter_mut().zip(loads).enumerate() {
            n.axial = f[0];
            n.circumferential = f[1];
            n.reassigned = true;
            if k >= self.low_water {
                n.normal = [f[2], f[3], f[4]];
            }
        }
    }

    /// What the Tip node (the last node) carries into its replacement at `tip`: its
    /// friction state, velocity and, with the per-length model, the material at the tip.
    /// The replacement's rest position is the old node's, moved by the local affine map
    /// ([`crate::material_point`]) over the way from where the old node would be at the
    /// end of the step to `tip` (nothing while it sticks to the needle). When that way is
    /// longer than half a node spacing (a needle jerked through the tissue), the map is
    /// not trusted so far: the replacement strains the tissue around it as the old one
    /// did (its elastic offset). The paper's refresh places it strain-free.
    /// `known`: the needle nodes' velocities, if read since the last edit. Called just
    /// before the Tip node's removal: with the per-length model it also records the
    /// forces the removal's handover needs ([`Simulation::capture_before_removal`]).
    pub(super) fn tip_load(
        &mut self,
        known: Option<&[Vec4]>,
        tip: DVec3,
    ) -> Result<(FrictionState, DVec3, Placement), SimulationError> {
        let k = self.state.nodes.len() - 1;
        let state = self.state.nodes[k].friction;
        let v = self
            .node_velocity(k, known)
            .map_err(|e| self.edit(e.into()))?;
        if self.params.per_length().is_none() {
            return Ok((state, v, Placement::Offset([0.0; 3])));
        }
        let index = self.state.nodes[k].index;
        let mut nodes = self.mesh_neighbours(index);
        nodes.push(index);
        let mut pos = vec![[0.0f32; 4]; nodes.len()];
        let mut vel = vec![[0.0f32; 4]; nodes.len()];
        // The Tip node's removal follows: the forces it records before it come in the
        // same read (one readback on a GPU, where there were two).
        self.capture_before_removal_with(
            &[
                (NodeField::Position, nodes.as_slice().into()),
                (NodeField::Velocity, nodes.as_slice().into()),
            ],
            &mut [&mut pos, &mut vel],
        )
        .map_err(|e| self.edit(e))?;
        // The replacement moves with the tissue around it (the mean of its mesh
        // neighbours), not with whatever speed the old node had along the shaft.
        vel.pop();
        let v = match vel.is_empty() {
            true => v,
            false => vel.iter().map(|x| xyz(*x)).sum::<DVec3>() / vel.len() as f64,
        };
        let x_old = xyz(pos.pop().expect("the Tip node"));
        nodes.pop();
        let fit = self.fit_around(x_old, &nodes, &pos);
        let placement = match fit {
            Some(fit) if (tip - x_old).length() <= 0.5 * self.spacing => {
                let rest = DVec3::from(self.rest_of(index)) + fit.gradient * (tip - x_old);
                Placement::Rest(rest.to_array())
            }
            _ => Placement::Offset(
                self.editor
                    .elastic_offset(self.backend.as_mut(), index)
                    .map_err(|e| self.edit(e))?,
            ),
        };
        Ok((state, v, placement))
    }

    /// Velocity and friction state of a Shaft node added inside: with the per-length
    /// model, the tissue's velocity there (the mean of the last node's mesh neighbours)
    /// and slipping; with the paper's, the needle's and sticking. `known`: the needle nodes' velocities, if read
    /// since the last edit.
    pub(super) fn new_node_motion(
        &mut self,
        has_tip: bool,
        v_tip: DVec3,
        known: Option<&[Vec4]>,
    ) -> Result<(DVec3, FrictionState), SimulationError> {
        if self.params.per_length().is_none() {
            return Ok((v_tip, FrictionState::Stick));
        }
        // The tissue's velocity around the last node (the mean of its mesh neighbours).
        let _ = (has_tip, known);
        let last = self.state.nodes.last().expect("a needle node").index;
        let nodes = self.mesh_neighbours(last);
        if nodes.is_empty() {
            return Ok((v_tip, FrictionState::Slip));
        }
        let mut vel = vec![[0.0f32; 4]; nodes.len()];
        self.backend
            .read_nodes(NodeField::Velocity, &nodes, &mut vel)
            .map_err(|e| self.edit(e.into()))?;
        let v = vel.iter().map(|x| xyz(*x)).sum::<DVec3>() / vel.len() as f64;
        Ok((v, FrictionState::Slip))
    }
}
