//! Friction on the needle nodes and the force on the needle (paper section 5.4, and the
//! per-length model of [`crate::friction`]), after the force evaluation.
//!
//! Each node's elastic force splits into an axial part along the shaft and a normal part
//! the shaft takes. The needle force is the sum of what the nodes exert on the needle:
//! the elastic force of a pinned node, and the normal force minus the friction (and, at
//! the crack front, cutting) force of every other node. With the per-length model a node
//! stands for the shaft length [`shaft_lengths`] gives it.

use super::{vec4, xyz, Simulation};
use crate::config::Membrane;
use crate::friction::{
    paper_dynamic_friction, paper_next_state, per_length_step, split, AxialStep, FrictionModel,
    FrictionState, Limits,
};
use crate::needle::Needle;
use crate::nodes::{NeedleForce, NodeRole};
use crate::state::Phase;
use glam::DVec3;
use needlesim_core::{NodeField, SimError};

/// The shaft length each node at axial coordinate `s[k]` represents, m: half the way to
/// its neighbours along the shaft; the first counted from its own coordinate, the last to
/// `end` (the tip, or the Exit node past the far surface). Nodes with `counted[k]` false
/// (pinned ones) get 0.
pub(crate) fn shaft_lengths(s: &[f64], counted: &[bool], end: Option<f64>) -> Vec<f64> {
    let mut order: Vec<usize> = (0..s.len()).filter(|&k| counted[k]).collect();
    order.sort_by(|&a, &b| s[a].total_cmp(&s[b]));
    let mut l = vec![0.0; s.len()];
    let (Some(&first), Some(&last)) = (order.first(), order.last()) else {
        return l;
    };
    let lo = s[first];
    let hi = end.map_or(s[last], |e| e.max(s[last]));
    for (i, &k) in order.iter().enumerate() {
        let a = if i == 0 {
            lo
        } else {
            0.5 * (s[order[i - 1]] + s[k])
        };
        let b = if i + 1 == order.len() {
            hi
        } else {
            0.5 * (s[k] + s[order[i + 1]])
        };
        l[k] = (b - a).max(0.0);
    }
    l
}

impl Simulation {
    /// Friction on the needle nodes and the needle force (after the force evaluation).
    pub(super) fn apply_friction(&mut self, prev: &Needle, now: &Needle) -> Result<(), SimError> {
        let m = self.state.nodes.len();
        let mut total = DVec3::ZERO;
        let (t, base) = (DVec3::from(now.direction()), DVec3::from(now.base()));
        self.state.pinned_axial = 0.0;
        self.state.tissue_depth = None;
        if m > 0 {
            let n0 = self.editor.n_mesh();
            // The node at the crack front: the Tip node, or the deepest node until the Tip
            // node is added (none once the tip has left the body).
            let front = match self.state.phase {
                Phase::Inside if self.state.nodes[m - 1].role == NodeRole::Tip => m - 1,
                Phase::Inside => {
                    let s = |k: usize| (xyz(self.state.positions[k]) - base).dot(t);
                    (0..m).max_by(|&a, &b| s(a).total_cmp(&s(b))).unwrap_or(0)
                }
                _ => usize::MAX,
            };
            // The needle nodes' forces and, with the tip inside, the positions of the
            // mesh nodes around the crack front (for the tissue at the tip), in one read.
            let around = match front < m {
                true => self.mesh_neighbours(self.state.nodes[front].index),
                false => Vec::new(),
            };
            let mut f = vec![[0.0f32; 4]; m];
            let mut near = vec![[0.0f32; 4]; around.len()];
            if around.is_empty() {
                self.backend.read(NodeField::Force, n0..n0 + m, &mut f)?;
            } else {
                self.backend.read_many(
                    &[
                        (NodeField::Force, (n0..n0 + m).into()),
                        (NodeField::Position, around.as_slice().into()),
                    ],
                    &mut [&mut f, &mut near],
                )?;
            }
            // The positions `constrain` wrote: the force evaluation does not move nodes.
            let p = std::mem::take(&mut self.state.positions);
            let s: Vec<f64> = p.iter().map(|x| (xyz(*x) - base).dot(t)).collect();
            let counted: Vec<bool> = self.state.nodes.iter().map(|n| !self.pinned(n)).collect();
            let end = match self.state.phase {
                Phase::Exited => None,
                _ => Some(now.length()),
            };
            let lengths = shaft_lengths(&s, &counted, end);
            let tip_depth = self.depth_of(now.tip(), now.direction());
            // The tip cuts while it is at the deepest point it reached (the crack front).
            let cutting = tip_depth >= self.state.cut_depth - 1e-9;
            self.state.cut_depth = self.state.cut_depth.max(tip_depth);
            let mut released = Vec::new();
            // The tissue at the tip: the front node's own rest position (the material it
            // holds), moved by the local affine map over the front node's offset from
            // the tip (it slips behind the tip while cutting); its region.
            let material = match front < m {
                true => {
                    let (x_front, tip) = (xyz(p[front]), DVec3::from(now.tip()));
                    self.fit_around(tip, &around, &near).map(|fit| {
                        let x0 = DVec3::from(self.rest_of(self.state.nodes[front].index))
                            + fit.gradient * (tip - x_front);
                        (x0, self.region_near(x0, &around, self.state.region))
                    })
                }
                false => None,
            };
            let surface_rest = || DVec3::from(self.rest_of(self.state.nodes[0].index));
            self.state.tissue_depth = match self.state.phase {
                Phase::Touching => Some(0.0),
                Phase::Inside => material.map(|(x0, _)| (x0 - surface_rest()).dot(t)),
                Phase::ExitTouching => {
                    let exit = self.state.nodes[m - 1].index;
                    Some((DVec3::from(self.rest_of(exit)) - surface_rest()).dot(t))
                }
                Phase::Outside | Phase::Exited => None,
            };
            // The crack front meeting another region: a membrane to dent and puncture, or
            // none to cross (re-advancing in its track, no membrane). An intact membrane
            // is never crossed without being punctured, even while pulled back (the
            // material point jitters about the interface).
            if let Some((_, r)) = material {
                let current = self.state.region.unwrap_or(r);
                // A membrane being dented stays so until it gives or the tip is pulled
                // back.
                if !cutting {
                    self.state.denting = None;
                }
                if r != current && self.state.denting.is_none() {
                    let fresh = !self.state.punctured.contains(&r);
                    match self.contact.layers[r as usize].membrane {
                        Membrane::Force(_) | Membrane::Impenetrable if fresh => {
                            if cutting {
                                self.state.denting = Some(r);
                            }
                        }
                        _ => self.state.region = Some(r),
                    }
                }
            }
            let params = *self.stepper.params();
            let gravity = DVec3::from(params.gravity.map(|g| g as f64));
            for k in 0..m {
                let fe = xyz(f[k]);
                let node = self.state.nodes[k];
                let vn = self.needle_velocity(prev, now, s[k]);
                let vk = xyz(self.state.velocities[k]);
                if self.pinned(&node) {
                    total += fe;
                    self.state.pinned_axial = -fe.dot(t);
                    continue;
                }
                let (axial, normal) = split(fe.to_array(), t.to_array());
                let normal = DVec3::from(normal);
                let layer = self.contact.layers[node.region as usize];
                let phi = match (self.contact.friction, layer.friction) {
                    (FrictionModel::PerLength(_), FrictionModel::PerLength(pl)) => {
                        let load = layer.grip * lengths[k] + normal.length();
                        let mut lim = Limits::symmetric(
                            pl.static_coefficient() * load,
                            pl.coefficient * load,
                            pl.viscous * lengths[k],
                        );
                        if k == front && cutting {
                            // Cutting, or denting the membrane ahead (infinite: never
                            // punctured).
                            let ahead = match self
                                .state
                                .denting
                                .map(|r| self.contact.layers[r as usize].membrane)
                            {
                                Some(Membrane::Force(f)) => f,
                                Some(Membrane::Impenetrable) => f64::INFINITY,
                                _ => layer.cutting,
                            };
                            lim.static_forward += ahead;
                            lim.kinetic_forward += ahead;
                        }
                        let step = AxialStep {
                            elastic: axial,
                            velocity: vk.dot(t),
                            needle_velocity: vn.dot(t),
                            mass: 1.0 / self.inv_mass_of(&node) as f64,
                            dt: self.stepper.dt(),
                            damping_factor: params.damping_factor as f64,
                            gravity: gravity.dot(t),
                        };
                        let (state, phi) = per_length_step(node.friction, &step, &lim);
                        // The membrane gives when the front, held by it, starts to slip
                        // forward (a front still slipping from before it met the membrane
                        // is first caught: it slows to the needle's speed under the raised
                        // limit).
                        let gave = node.friction == FrictionState::Stick
                            && state == FrictionState::Slip
                            && phi > 0.0;
                        if k == front && gave {
                            // The membrane gave: punctured.
                            if let Some(r) = self.state.denting.take() {
                                self.state.region = Some(r);
                                self.state.punctured.push(r);
                            }
                        }
                        let n = &mut self.state.nodes[k];
                        n.limit = lim.static_forward;
                        if state != node.friction {
                            n.friction = state;
                            n.s = s[k];
                            if state == FrictionState::Slip {
                                released.push(k);
                            }
                        }
                        phi
                    }
                    (FrictionModel::Paper(pp), _) | (_, FrictionModel::Paper(pp)) => {
                        if self.kinematic(&node) && node.role == NodeRole::Tip {
                            total += fe;
                            continue;
                        }
                        let (fa, va, vna, ta) =
                            (fe.to_array(), vk.to_array(), vn.to_array(), t.to_array());
                        let state = paper_next_state(node.friction, fa, va, vna, ta, &pp);
                        if state != node.friction {
                            let n = &mut self.state.nodes[k];
                            n.friction = state;
                            n.s = s[k];
                        }
                        match node.friction {
                            FrictionState::Stick => -axial,
                            FrictionState::Slip => {
                                DVec3::from(paper_dynamic_friction(fa, va, vna, ta, &pp)).dot(t)
                            }
                        }
                    }
                };
                self.state.nodes[k].axial = phi;
                // The shaft takes the normal part; the node keeps its axial force plus
                // the needle's axial force on it.
                f[k] = vec4(t * (axial + phi), 0.0);
                total = total + normal - t * phi;
            }
            self.backend.write(NodeField::Force, n0, &f)?;
            // A node that started to slip this step moves under its force from now on.
            for k in released {
                let mut q = p[k];
                q[3] = self.inv_mass_of(&self.state.nodes[k]);
                self.backend.write(NodeField::Position, n0 + k, &[q])?;
            }
        }
        let along = total.dot(t);
        self.state.force = NeedleForce {
            total: total.to_array(),
            axial: -along,
            lateral: (total - t * along).length(),
        };
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::shaft_lengths;

    #[test]
    fn shaft_lengths_split_the_shaft_half_way_between_nodes() {
        // Surface node at 0 (pinned: not counted), nodes at 1, 2, 3.5, tip at 4.
        let s = [0.0, 1.0, 2.0, 3.5];
        let l = shaft_lengths(&s, &[false, true, true, true], Some(4.0));
        assert_eq!(l, vec![0.0, 0.5, 1.25, 1.25]);
        // Counted from the first node: the lengths add up to the shaft in the tissue.
        let l = shaft_lengths(&s, &[true; 4], Some(4.0));
        assert_eq!(l.iter().sum::<f64>(), 4.0);
        // Past the far surface the shaft ends at the last node; unordered input.
        let l = shaft_lengths(&[2.0, 0.0, 1.0], &[true; 3], None);
        assert_eq!(l, vec![0.5, 0.5, 1.0]);
        assert_eq!(shaft_lengths(&[1.0], &[false], Some(2.0)), vec![0.0]);
    }
}
