//! Friction on the needle nodes and the force on the needle (paper section 5.4, and the
//! per-length model of [`crate::friction`]), after the force evaluation.
//!
//! Each node's elastic force splits into an axial part along the shaft and a normal part
//! the shaft takes. The needle force is the sum of what the nodes exert on the needle:
//! the elastic force of a pinned node, and the normal force minus the friction (and, at
//! the crack front, cutting) force of every other node. With the per-length model a node
//! stands for the shaft length [`shaft_lengths`] gives it.
//!
//! With the per-length model the friction of a node is a Kelvin-Voigt sheath with a
//! Coulomb slider ([`crate::sheath`]): the spring and dashpot act on the node's motion
//! relative to the needle at the end of the step, solved with the node's own update, so
//! a node event, a reversal or a spin changes the force through the sheath's state, not
//! by a switch of the friction's sign (the liver scene's reversal: largest step 0.12% of
//! the force, `needlesim report --realism`). Before the puncture the tip loads the
//! surface through a contact patch of the region's contact radius (Sneddon's punch
//! stiffness); after it, the tip's front element carries the cutting force at the crack
//! front, and a membrane that gives is released over the tear ([`crate::sheath::Tear`]).

use super::insertion::{is_crowded, REMOVE, TIP_SPAN};
use super::{vec4, xyz, Simulation};
use crate::config::Membrane;
use crate::friction::{
    paper_dynamic_friction, paper_next_state, split, FrictionModel, FrictionState,
};
use crate::handover::{fade, HANDOVER_TIME};
use crate::needle::Needle;
use crate::nodes::{NeedleForce, NodeRole};
use crate::sheath::{
    front_step, front_viscosity, punch_compliance, sheath_step, FreeFade, SheathStep, Tear,
};
use crate::state::{Passage, Written};
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
    /// The lengths of shaft the needle nodes at axial coordinates `s` represent
    /// ([`shaft_lengths`]): every node but a pinned one and, with the per-length model,
    /// the Surface node while Touching (no shaft is in yet), up to the tip (up to the last
    /// node once the tip is out past the far surface).
    pub(super) fn node_lengths(&self, s: &[f64], now: &Needle) -> Vec<f64> {
        let counted: Vec<bool> = self
            .state
            .nodes
            .iter()
            .map(|n| {
                let waiting = n.role == NodeRole::Surface && self.state.phase == Passage::Touching;
                !(self.pinned(n) || waiting)
            })
            .collect();
        let end = match self.state.phase {
            Passage::Exited => None,
            _ => Some(now.length()),
        };
        let mut l = shaft_lengths(s, &counted, end);
        // With the per-length model the last Shaft node keeps only its share of its
        // length; the node before it takes the rest ([`Simulation::update_shares`]).
        let nodes = &self.state.nodes;
        let last = nodes.len().checked_sub(1);
        if let (true, Some(k)) = (self.sheathed(), last) {
            let before = (0..k)
                .filter(|&j| counted[j])
                .max_by(|&a, &b| s[a].total_cmp(&s[b]));
            if let Some(j) = before {
                let keep = nodes[k].share;
                l[j] += (1.0 - keep) * l[k];
                l[k] *= keep;
            }
        }
        l
    }

    /// The share of its length the newest needle node keeps (per-length model), while
    /// the needle is pulled back over it: a Shaft node's follows the tip's distance past
    /// it, from 1 at h / 2 (where it was added) to 0 at the distance it is removed at; the
    /// Tip node's from 1 with the tip at it to 0 a tenth of a spacing behind it (where it
    /// is taken off); a Shaft node the tissue crowded onto the node before it
    /// ([`is_crowded`]) while the needle is pulled back goes to 0 (it is taken off then). It
    /// changes by no more than the tip moved along the needle this step allows (a node let
    /// go moves towards the tip, which would otherwise hasten its own release). The node before takes the rest ([`Simulation::node_lengths`]); every
    /// other node keeps its whole length.
    fn update_shares(&mut self, s: &[f64], prev: &Needle, now: &Needle) {
        let h = self.spacing;
        let moved = (DVec3::from(now.tip()) - DVec3::from(prev.tip()))
            .dot(DVec3::from(now.direction()))
            .abs();
        let withdrawing = self.state.advance < -1e-12;
        let m = self.state.nodes.len();
        for (k, n) in self.state.nodes.iter_mut().enumerate() {
            let d = now.length() - s[k];
            let (target, span) = match n.role {
                // A last Shaft node the tissue crowded onto the node before it on the
                // way out hands its whole length over at the same rate, and is removed
                // once its share is 0 ([`Simulation::next_edit`]).
                NodeRole::Shaft
                    if k + 1 == m && withdrawing && k > 0 && is_crowded(s[k] - s[k - 1], h) =>
                {
                    (0.0, (0.5 - REMOVE) * h)
                }
                NodeRole::Shaft if k + 1 == m => {
                    let span = (0.5 - REMOVE) * h;
                    (((d - REMOVE * h) / span).clamp(0.0, 1.0), span)
                }
                NodeRole::Tip => {
                    let span = TIP_SPAN * h;
                    (((d + span) / span).clamp(0.0, 1.0), span)
                }
                _ => {
                    n.share = 1.0;
                    continue;
                }
            };
            let rate = moved / span;
            n.share += (target - n.share).clamp(-rate, rate);
        }
    }

    /// The share of its grip the tissue at `depth` past the entry still has: for a
    /// viscoelastic tissue the relaxation function `g` ([`Prony::relaxation`]) at the time
    /// since the crack front passed that depth (the slit the shaft holds open is a strain
    /// held since then, so the contact pressure relaxes as the tissue's stress does);
    /// 1 for an elastic tissue, and ahead of the crack front.
    ///
    /// [`Prony::relaxation`]: needlesim_core::models::viscoelastic::Prony::relaxation
    fn grip_relaxation(&self, depth: f64) -> f64 {
        let relaxation = &self.params.relaxation;
        if relaxation.is_empty() {
            return 1.0;
        }
        let cuts = &self.state.cut_times;
        let i = cuts.partition_point(|&(d, _)| d < depth);
        match cuts.get(i) {
            Some(&(_, cut)) => relaxation.relaxation((self.stepper.time() - cut).max(0.0)),
            None => 1.0,
        }
    }

    /// Friction on the needle nodes and the needle force (after the force evaluation).
    pub(super) fn apply_friction(&mut self, prev: &Needle, now: &Needle) -> Result<(), SimError> {
        let m = self.state.nodes.len();
        let mut total = DVec3::ZERO;
        let mut torque = 0.0;
        let mut tip = 0.0;
        let (t, base) = (DVec3::from(now.direction()), DVec3::from(now.base()));
        let sheathed = self.sheathed();
        self.state.pinned_axial = 0.0;
        self.state.tissue_depth = None;
        if m > 0 {
            let n0 = self.editor.n_mesh();
            // The node at the crack front: the Tip node, or the deepest node until the Tip
            // node is added (none once the tip has left the body).
            let front = match self.state.phase {
                Passage::Inside if self.state.nodes[m - 1].role == NodeRole::Tip => m - 1,
                Passage::Inside => {
                    let s = |k: usize| (xyz(self.state.positions[k]) - base).dot(t);
                    (0..m).max_by(|&a, &b| s(a).total_cmp(&s(b))).unwrap_or(0)
                }
                _ => usize::MAX,
            };
            if front >= m {
                // No crack front: nothing of the tip element's share carries over to the
                // next one (after an exit and a re-entry, say).
                self.state.front.free = None;
                self.state.front.free_fade = None;
            }
            // The needle nodes' forces, with the tip inside the positions of the mesh
            // nodes around the crack front (for the tissue at the tip), and the positions
            // of the contact patch's nodes, in one read.
            let around = match front < m {
                true => self.mesh_neighbours(self.state.nodes[front].index),
                false => Vec::new(),
            };
            let patch_nodes = self
                .state
                .patch
                .as_ref()
                .map_or(Vec::new(), |p| p.nodes.clone());
            let mut f = vec![[0.0f32; 4]; m];
            let mut near = vec![[0.0f32; 4]; around.len()];
            let mut patch_pos = vec![[0.0f32; 4]; patch_nodes.len()];
            // What is left of the handover of node edits ([`crate::handover`]): the mesh
            // nodes' forces read with the rest, the needle nodes' added below.
            let handover = self.handover_now();
            let (mesh, needle) = handover.as_ref().map_or((0, 0), |(nodes, _)| {
                let k = nodes.partition_point(|&j| (j as usize) < n0);
                (k, nodes.len() - k)
            });
            let mut handed = vec![[0.0f32; 4]; mesh];
            // The patch's nodes' forces, for its push ([`Simulation::sheath_forces`]), come
            // with the rest unless a handover changes mesh forces in between.
            let mut patch_force = match handover.is_none() {
                true => vec![[0.0f32; 4]; patch_nodes.len()],
                false => Vec::new(),
            };
            {
                let mut requests = vec![(NodeField::Force, (n0..n0 + m).into())];
                let mut outs: Vec<&mut [needlesim_core::math::Vec4]> = vec![&mut f];
                if !around.is_empty() {
                    requests.push((NodeField::Position, around.as_slice().into()));
                    outs.push(&mut near);
                }
                if !patch_nodes.is_empty() {
                    requests.push((NodeField::Position, patch_nodes.as_slice().into()));
                    outs.push(&mut patch_pos);
                    if !patch_force.is_empty() {
                        requests.push((NodeField::Force, patch_nodes.as_slice().into()));
                        outs.push(&mut patch_force);
                    }
                }
                if let (Some((nodes, _)), true) = (&handover, mesh > 0) {
                    requests.push((NodeField::Force, nodes[..mesh].into()));
                    outs.push(&mut handed);
                }
                self.backend.read_many(&requests, &mut outs)?;
            }
            if let Some((nodes, add)) = &handover {
                if mesh > 0 {
                    super::handover::add_forces(&mut handed, &add[..mesh]);
                    needlesim_core::boundary::write_scattered(
                        self.backend.as_mut(),
                        NodeField::Force,
                        &nodes[..mesh],
                        &handed,
                    )?;
                }
                for (j, a) in nodes[mesh..mesh + needle].iter().zip(&add[mesh..]) {
                    if let Some(fk) = f.get_mut(*j as usize - n0) {
                        super::handover::add_forces(
                            std::slice::from_mut(fk),
                            std::slice::from_ref(a),
                        );
                    }
                }
            }
            // The positions `constrain` wrote: the force evaluation does not move nodes.
            let p = std::mem::take(&mut self.state.positions);
            let s: Vec<f64> = p.iter().map(|x| (xyz(*x) - base).dot(t)).collect();
            if sheathed {
                self.update_shares(&s, prev, now);
            }
            let lengths = self.node_lengths(&s, now);
            let tip_depth = self.depth_of(now.tip(), now.direction());
            // The tip cuts while it is at the deepest point it reached (the crack front).
            let cutting = tip_depth >= self.state.cut_depth - 1e-9;
            if tip_depth > self.state.cut_depth && !self.params.relaxation.is_empty() {
                self.state.cut_times.push((tip_depth, self.stepper.time()));
            }
            self.state.cut_depth = self.state.cut_depth.max(tip_depth);
            // The tissue at the tip: the front node's own rest position (the material it
            // holds), moved by the local affine map over the front node's offset from
            // the tip (it slips behind the tip while cutting); its region.
            let material = match front < m {
                true => {
                    // The point the tip presses on: the tip, or while it dents an inner
                    // membrane the bottom of the membrane's dent in the resolved tissue.
                    let (x_front, tip) = (
                        xyz(p[front]),
                        DVec3::from(now.tip()) - t * self.state.front.dent,
                    );
                    self.fit_around(tip, &around, &near).map(|fit| {
                        let from = |k: usize, x: DVec3| {
                            DVec3::from(self.rest_of(self.state.nodes[k].index))
                                + fit.gradient * (tip - x)
                        };
                        let mut x0 = from(front, x_front);
                        // While the needle is pulled back over the front node, which hands
                        // its length over to the node before it ([`Simulation::update_shares`])
                        // and is removed when its share reaches 0, the material point moves
                        // over to the one seen from the node before by the same share: the
                        // tissue between them is sheared by the friction, so the two differ
                        // (by 0.4 mm in the insert-extract scene), and taking the node before
                        // only once the front node is gone made the tip's depth jump.
                        let share = self.state.nodes[front].share;
                        if sheathed && front + 1 == m && front > 0 && share < 1.0 {
                            let prev = from(front - 1, xyz(p[front - 1]));
                            x0 = share * x0 + (1.0 - share) * prev;
                        }
                        (x0, self.region_near(x0, &around, self.state.region))
                    })
                }
                false => None,
            };
            let surface_rest = || DVec3::from(self.rest_of(self.state.nodes[0].index));
            self.state.tissue_depth = match self.state.phase {
                Passage::Touching => Some(0.0),
                Passage::Inside => material.map(|(x0, _)| (x0 - surface_rest()).dot(t)),
                Passage::ExitTouching => {
                    let exit = self.state.nodes[m - 1].index;
                    Some((DVec3::from(self.rest_of(exit)) - surface_rest()).dot(t))
                }
                Passage::Outside | Passage::Exited => None,
            };
            // The crack front meeting another region: a membrane to dent and puncture, or
            // none to cross (re-advancing in its track, no membrane). An intact membrane
            // is never crossed without being punctured, even while pulled back (the
            // material point jitters about the interface).
            if let Some((_, r)) = material {
                let current = self.state.region.unwrap_or(r);
                // A membrane being dented stays so until it gives or the tip is pulled
                // back (with the per-length model: until the tip's element has let go
                // of it, [`Simulation::front_step`]).
                if !cutting && !sheathed {
                    self.state.denting = None;
                }
                // (With the per-length model not while the tip still tears through the
                // last membrane: it meets the next one with its cutting force.)
                // A crossing's blend holds back only the way it came (the material point
                // jitters about the interface it is crossing): an intact membrane ahead
                // still stops the point, as in a layer thinner than the point.
                let tear = sheathed.then_some(self.state.front.tear).flatten();
                let tearing = tear.is_some_and(|t| !t.is_crossing());
                let crossing = tear.is_some_and(|t| t.is_crossing());
                let fresh = !self.state.punctured.contains(&r);
                let membrane_ahead = fresh
                    && matches!(
                        self.params.regions[r as usize].membrane,
                        Membrane::Force(_) | Membrane::Impenetrable
                    );
                if r != current
                    && self.state.denting.is_none()
                    && !tearing
                    && (!crossing || membrane_ahead)
                {
                    match self.params.regions[r as usize].membrane {
                        Membrane::Force(_) | Membrane::Impenetrable if fresh => {
                            if cutting {
                                self.state.denting = Some(r);
                            }
                        }
                        _ => {
                            self.state.region = Some(r);
                            // The cutting force passes to the new region's as the point
                            // crosses the interface: by length only, the point cuts both
                            // tissues while it spans them (the tear time bounds how fast
                            // a membrane lets go, and there is none here).
                            if sheathed && cutting {
                                let f = &mut self.state.front;
                                f.tear = Some(Tear {
                                    from: f.force,
                                    to: self.params.regions[r as usize].cutting,
                                    at: self.state.cut_depth,
                                    length: self.params.point_length,
                                    started: self.stepper.time(),
                                    time: f64::MAX,
                                });
                            }
                        }
                    }
                }
            }
            let s_tip = (DVec3::from(now.tip()) - base).dot(t);
            let grip: Vec<f64> = s
                .iter()
                .map(|&sk| self.grip_relaxation(tip_depth - (s_tip - sk)))
                .collect();
            let ctx = Step {
                prev,
                now,
                s: &s,
                lengths: &lengths,
                grip: &grip,
                front,
                cutting,
                tip_depth,
            };
            if sheathed {
                let patch = (patch_pos.as_slice(), patch_force);
                self.sheath_forces(&ctx, &mut f, patch, &mut total, &mut torque)?;
                tip = self.state.patch.as_ref().map_or(0.0, |p| p.force)
                    + if front < m {
                        self.state.front.force
                    } else {
                        0.0
                    };
            } else {
                self.paper_forces(&ctx, &mut f, &mut total);
            }
            self.backend.write(NodeField::Force, n0, &f)?;
            self.state.written = Some(Written {
                nodes: self.state.nodes.iter().map(|n| n.index).collect(),
                positions: p,
                velocities: self.state.velocities.clone(),
                forces: f,
            });
        }
        let along = total.dot(t);
        self.state.force = NeedleForce {
            total: total.to_array(),
            axial: -along,
            lateral: (total - t * along).length(),
            torque,
            tip,
        };
        Ok(())
    }

    /// The paper's friction (equation 2, explicit stick-slip) on every needle node; adds
    /// what the nodes exert on the needle to `total`.
    fn paper_forces(&mut self, c: &Step, f: &mut [[f32; 4]], total: &mut DVec3) {
        let t = DVec3::from(c.now.direction());
        let FrictionModel::Paper(pp) = self.params.friction else {
            unreachable!("the paper's forces with the paper's model");
        };
        for (k, fk) in f.iter_mut().enumerate() {
            let fe = xyz(*fk);
            let node = self.state.nodes[k];
            let vn = self.needle_velocity(c.prev, c.now, c.s[k]);
            let vk = xyz(self.state.velocities[k]);
            if self.pinned(&node) || (self.kinematic(&node) && node.role == NodeRole::Tip) {
                *total += fe;
                if self.pinned(&node) {
                    self.state.pinned_axial = -fe.dot(t);
                }
                continue;
            }
            let (axial, normal) = split(fe.to_array(), t.to_array());
            let (fa, va, vna, ta) = (fe.to_array(), vk.to_array(), vn.to_array(), t.to_array());
            let state = paper_next_state(node.friction, fa, va, vna, ta, &pp);
            if state != node.friction {
                let n = &mut self.state.nodes[k];
                n.friction = state;
                n.s = c.s[k];
            }
            let phi = match node.friction {
                FrictionState::Stick => -axial,
                FrictionState::Slip => {
                    DVec3::from(paper_dynamic_friction(fa, va, vna, ta, &pp)).dot(t)
                }
            };
            self.state.nodes[k].axial = phi;
            // The shaft takes the normal part; the node keeps its axial force plus
            // the needle's axial force on it.
            *fk = vec4(t * (axial + phi), 0.0);
            *total += DVec3::from(normal) - t * phi;
        }
    }

    /// The per-length model's sheath ([`crate::sheath`]): friction on every needle node,
    /// the tip's element on the front node, the contact patch; adds what they exert on the
    /// needle to `total` (and the torque about its axis to `torque`).
    fn sheath_forces(
        &mut self,
        c: &Step,
        f: &mut [[f32; 4]],
        (patch_pos, patch_force): (&[[f32; 4]], Vec<[f32; 4]>),
        total: &mut DVec3,
        torque: &mut f64,
    ) -> Result<(), SimError> {
        let t = DVec3::from(c.now.direction());
        let base = DVec3::from(c.now.base());
        let dt = self.stepper.dt();
        let droll = c.now.roll() - c.prev.roll();
        let a = self.params.radius;
        let params = *self.stepper.params();
        let gravity = DVec3::from(params.gravity.map(|g| g as f64));
        // The contact patch: the tip pushes its weighted mean along the needle.
        if let Some(mut patch) = self.state.patch.take() {
            let mean = patch.surface * c.s[0]
                + patch
                    .weights
                    .iter()
                    .zip(patch_pos)
                    .map(|(w, x)| w * (xyz(*x) - base).dot(t))
                    .sum::<f64>();
            let now = self.stepper.time();
            let cap = match patch.tear {
                Some(tear) => tear.cap(self.state.cut_depth, now),
                None => self.entry_puncture_force().unwrap_or(f64::INFINITY),
            };
            if patch.mean.is_none() {
                patch.offset = c.s[0] - mean;
            }
            let moved = patch.mean.map_or(0.0, |m| mean - m);
            patch.force = front_step(patch.force, -patch.stiffness * moved, cap);
            patch.mean = Some(mean);
            self.state.pinned_axial = patch.force;
            // The share of the mesh nodes goes onto their forces; the Surface node's below.
            if patch.force > 0.0 {
                let mut g = patch_force;
                if g.len() != patch.nodes.len() {
                    g = vec![[0.0f32; 4]; patch.nodes.len()];
                    self.backend
                        .read_nodes(NodeField::Force, &patch.nodes, &mut g)?;
                }
                for (g, w) in g.iter_mut().zip(&patch.weights) {
                    for (ax, v) in g.iter_mut().take(3).enumerate() {
                        *v = (*v as f64 + w * patch.force * t[ax]) as f32;
                    }
                }
                needlesim_core::boundary::write_scattered(
                    self.backend.as_mut(),
                    NodeField::Force,
                    &patch.nodes,
                    &g,
                )?;
            }
            *total -= t * (patch.force * (1.0 - patch.surface));
            let gone = patch
                .tear
                .is_some_and(|tear| tear.done(self.state.cut_depth, now) && patch.force == 0.0);
            if !gone {
                self.state.patch = Some(patch);
            }
        }
        for (k, fk) in f.iter_mut().enumerate() {
            let fe = xyz(*fk);
            let node = self.state.nodes[k];
            if self.pinned(&node) {
                *total += fe;
                self.state.pinned_axial = -fe.dot(t);
                // Held in place, the node carries no sheath load to let go of.
                let n = &mut self.state.nodes[k];
                (n.reassigned, n.carried) = (false, 0.0);
                continue;
            }
            let (axial, normal) = split(fe.to_array(), t.to_array());
            let normal = DVec3::from(normal);
            let layer = self.params.regions[node.region as usize];
            let FrictionModel::PerLength(pl) = layer.friction else {
                unreachable!("regions share the per-length model");
            };
            let l = c.lengths[k];
            let u = self.needle_velocity(c.prev, c.now, c.s[k]).dot(t);
            // The node's relative motion since the last step (what the front element
            // takes): the node's own motion over the last step less the needle's over
            // this one. The sheath takes both implicitly (the node's in the last step,
            // the needle's in this one), so what is left for it is the node's motion
            // that the integrator did not give (an edit placing the node), zero
            // otherwise. Subtracting only the last step's relative motion instead left
            // `dt` times every change of the needle's speed in the sheath: a spurious
            // step of `K dt du` at each start, stop and reversal (10% of the force at the
            // reversal of `needle_insert_extract.toml`).
            let ds = c.s[k] - node.sigma;
            let untaken = ds + dt * u - node.slide;
            let stiffness = layer.shear_stiffness * l;
            // The static coefficient until the node slips, the kinetic one while it does.
            let mu = match node.friction {
                FrictionState::Stick => pl.static_coefficient(),
                FrictionState::Slip => pl.coefficient,
            };
            let v = xyz(self.state.velocities[k]).dot(t);
            // The resolved tissue's push counts with the node's share of its length: a
            // node fading out (pulled back over) or in (the Tip node) stands for less
            // tissue, so its push leaves the friction with it instead of at once when the
            // node is removed.
            let share = node.share;
            let cap = mu * (layer.grip * c.grip[k] * l + share * normal.length())
                + pl.viscous * l * (v - u).abs();
            // What an edit gave the node above its own cap is let go over the handover
            // time, not clipped in one step (`NeedleNode::carried`): measured on the
            // load the edit assigned (the sheath's elastic force after `reassign`; the
            // strain of the node's placement is the sheath's to take or slip on, as any
            // motion), and restarted only when that is more than what is left of an
            // earlier excess, so that the edits every few steps of a fast needle (Tip
            // refreshes) do not keep a fading excess alive.
            let now = self.stepper.time();
            let (carried, carried_at) = node
                .reassigned
                .then(|| node.axial.hypot(node.circumferential) - cap)
                .filter(|&e| e > node.carried * fade(now - node.carried_at, HANDOVER_TIME))
                .map_or((node.carried, node.carried_at), |e| (e, now));
            let cap = cap + carried * fade(now - carried_at, HANDOVER_TIME);
            // The needle's other pushes on the node: the tip's element at the front, the
            // contact patch's share on the Surface node.
            let (mut other, mut other_viscous, mut patch_push) = (0.0, 0.0, 0.0);
            if k == c.front {
                let (push, element) = self.front_step(c, ds, layer);
                other = push;
                other_viscous =
                    front_viscosity(element, layer.shear_viscosity, layer.shear_stiffness);
            }
            if k == 0 {
                if let Some(patch) = &self.state.patch {
                    patch_push = patch.surface * patch.force;
                }
            }
            let mass = 1.0 / self.inv_mass_of(&node) as f64;
            let damping = params.damping_factor as f64;
            let out = sheath_step(&SheathStep {
                elastic: [node.axial, node.circumferential],
                increment: [-stiffness * untaken, 0.0],
                spin: a * droll / dt,
                stiffness_dt: stiffness * dt,
                viscous: layer.shear_viscosity * l,
                free: damping * (v + dt * (axial / mass + gravity.dot(t))) - u,
                beta: damping * dt / mass,
                other,
                other_viscous,
                patch: patch_push,
                cap,
            });
            let (elastic, phi, slips) = (out.elastic, out.force, out.slips);
            let on_node = phi[0] + out.other;
            let n = &mut self.state.nodes[k];
            n.carried = carried;
            n.carried_at = carried_at;
            n.reassigned = false;
            n.axial = elastic[0];
            n.circumferential = elastic[1];
            n.slide = dt * (out.velocity + u);
            n.limit = cap;
            n.friction = if slips {
                FrictionState::Slip
            } else {
                FrictionState::Stick
            };
            n.sigma = c.s[k];
            n.normal = normal.to_array();
            // The shaft takes the normal part; the node keeps its axial force plus the
            // needle's axial force on it. The needle force counts the normal part by the
            // node's share of its length, as the friction cap does: a node pulled back
            // over (or the Tip node coming in) stands for less tissue, so its push leaves
            // the lateral force with its length instead of at once when it is removed.
            // (So the reported lateral force is not the whole reaction on a fading node:
            // the shaft still holds it.) Liver scene, first removal on the way out: the
            // lateral force stepped 0.084 -> 0.122 N at 5 mm spacing; at 10 mm spacing
            // the largest step at a removal went from 74.5 to 29.2 mN (`tests/needle.rs`).
            *fk = vec4(t * (axial + on_node), 0.0);
            *total += share * normal - t * on_node;
            *torque += a * phi[1];
        }
        Ok(())
    }

    /// The force the entry membrane gives at (N): `puncture_force`, or the touched
    /// region's membrane; `None` under the cone angle rule.
    pub(super) fn entry_puncture_force(&self) -> Option<f64> {
        let region = self.state.nodes.first().map_or(0, |n| n.region) as usize;
        match self.params.regions[region].membrane {
            Membrane::Force(f) => Some(f),
            Membrane::Impenetrable => Some(f64::INFINITY),
            Membrane::None => self.params.puncture_force,
        }
    }

    /// One step of the tip's element at the crack front ([`crate::sheath::FrontElement`]),
    /// the front node having moved `ds` along the needle; returns its force on the node
    /// (along the needle). At the crack front it cuts with the region's cutting force (off
    /// over one needle radius of retraction, on again over the last radius of a return
    /// along the track, nothing in a track already cut); it dents an inner membrane as an
    /// elastic element (the stiffness of a punch of the membrane's contact radius) up to
    /// the membrane's puncture force, then the membrane gives and tears. Also returns the
    /// element's stiffness while it pushes (N/m: the cutting element's `F_c / a`, the
    /// punch's; 0 when it does not push), for its dashpot
    /// ([`crate::sheath::front_viscosity`]).
    fn front_step(&mut self, c: &Step, ds: f64, layer: super::RegionParams) -> (f64, f64) {
        let cut = self.state.cut_depth;
        let mut front = self.state.front;
        let now = self.stepper.time();
        if front.tear.is_some_and(|t| t.done(cut, now)) {
            front.tear = None;
        }
        let denting = self
            .state
            .denting
            .map(|r| (r, self.params.regions[r as usize]));
        // A membrane met while the point still spans the last interface (a layer thinner
        // than the point): its dent takes over from the crossing's blend.
        if denting.is_some() && front.tear.is_some_and(|t| t.is_crossing()) {
            front.tear = None;
        }
        // The cutting force of the region the crack front is in (that of the front node's
        // until the tip has a region).
        let cutting = self
            .state
            .region
            .map_or(layer.cutting, |r| self.params.regions[r as usize].cutting);
        // The tip pushes the front node only while the node is not ahead of its face
        // (within a refresh distance, which a node may wobble by): a node carried further
        // past it (soft tissue behind a stiff one gives way) is let go over the next
        // refresh distance, and is not driven on ahead of the needle.
        let ahead = c.s[c.front] - c.now.length();
        let refresh = self.params.refresh;
        let own = ((2.0 * refresh - ahead) / refresh).clamp(0.0, 1.0);
        // An edit at the tip changes which node is the front, and with it that share:
        // the change is handed over ([`crate::sheath::FreeFade`]).
        if let Some(duration) = self.state.edit_front.take() {
            front.free_fade =
                FreeFade::start(front.free, own, front.free_fade.as_ref(), now, duration);
        }
        if front.free_fade.is_some_and(|f| f.done(now)) {
            front.free_fade = None;
        }
        let free = (own + front.free_fade.map_or(0.0, |f| f.at(now))).clamp(0.0, 1.0);
        front.free = Some(free);
        let (cap, stiffness) = match (front.tear, denting) {
            (None, Some((_, l))) => {
                // Denting an inner membrane: an elastic element, a punch of the membrane's
                // contact radius.
                let cap = match l.membrane {
                    Membrane::Force(f) => f,
                    _ => f64::INFINITY,
                };
                let (e, nu) = l.modulus;
                let punch = punch_compliance(e, nu, l.contact_radius);
                // The front node's own point-load compliance inside the tissue carries
                // part of the punch's: the sub-grid element adds only the rest.
                let point = INTERIOR_POINT_COMPLIANCE * (1.0 - nu * nu) / (e * self.spacing);
                let stiffness = 1.0 / (punch - point).max(0.1 * punch);
                // Engaged while the tip is within the element's compression at full load
                // behind the membrane.
                let reach = match cap.is_finite() {
                    true => cap / stiffness,
                    false => self.params.radius,
                };
                let engaged = ((c.tip_depth - (cut - reach)) / reach).clamp(0.0, 1.0);
                front.force = front_step(front.force, -stiffness * ds, cap * engaged * free);
                (cap, stiffness)
            }
            (tear, _) => {
                // Cutting (and tearing through a membrane that gave): the fracture of the
                // tissue ahead takes the cutting force whatever the tissue around does, while
                // the tip is at the crack front; it comes off over one needle radius when the
                // tip is drawn back from the front, and comes on again over the last radius
                // when the tip returns to it along its track.
                let cap = tear.map_or(cutting, |t| t.cap(cut, now));
                let a = self.params.radius;
                let engaged = ((c.tip_depth - (cut - a)) / a).clamp(0.0, 1.0);
                front.force = cap * engaged * free;
                (cap, 0.0)
            }
        };
        // The element's stiffness for its dashpot: the punch's while denting; while
        // cutting, `F_c / a` on the ramps where the force comes and goes with the node's
        // place (the tip drawn back from the crack front over one radius; the node carried
        // ahead, whose ramp over a refresh distance is `F_c / refresh`, of the same order:
        // a = 0.635 mm, refresh h / 10 = 0.3-0.5 mm in the shipped scenes), faded out
        // towards full engagement. The element's spring state (`front.force`, which the
        // puncture test reads) is the force before the dashpot. At the crack front the force is the cutting force
        // whatever the node's motion (the tip passes through the material at the
        // insertion speed), so no dashpot there: on that relative speed it would be a
        // viscous cutting force, and it stepped at every change of front node (paper
        // scenes: 15 mN, 5.7%, at the first Shaft node).
        let element = match (stiffness > 0.0, front.force > 0.0) {
            (_, false) => 0.0,
            (true, true) => stiffness,
            (false, true) => (cap / self.params.radius) * (1.0 - front.force / cap).max(0.0),
        };
        front.dent = match (denting, stiffness > 0.0) {
            (Some(_), true) => front.force / stiffness,
            _ => 0.0,
        };
        // The membrane gives when the tip's force on it reaches its puncture force.
        if let Some((r, l)) = denting {
            if cap.is_finite() && c.cutting && front.force >= cap * (1.0 - 1e-9) {
                self.state.denting = None;
                self.state.region = Some(r);
                self.state.punctured.push(r);
                front.dent = 0.0;
                front.tear = Some(Tear {
                    from: front.force,
                    to: l.cutting,
                    at: cut,
                    length: self.params.point_length,
                    started: self.stepper.time(),
                    time: self.params.tear_time,
                });
            } else if !c.cutting && front.force == 0.0 {
                // Pulled back off the membrane.
                self.state.denting = None;
            }
        }

        self.state.front = front;
        (front.force, element)
    }
}

/// Compliance of a point load on one node inside the resolved tissue, in units of
/// `(1 - nu^2) / (E h)`: half of the 0.68 the liver scene's surface dent measured at three
/// spacings before the contact patch (co-rotated Debunne with hourglass control 4: dents
/// of 7.7, 5.4 and 3.8 mm at 1 N for h = 3.5, 5 and 7.25 mm), a full space being about
/// twice as stiff as a half-space under a point load. The tip's element in front of an
/// inner membrane supplies what a punch of the membrane's contact radius has beyond it.
/// (Measured with the first-order hourglass control at 4; the quadratic one at its
/// default 16 makes a single node 1.26 times as stiff, 0.67 against 0.53 of a trilinear
/// FEM node, `tests/models.rs`: not re-measured.)
const INTERIOR_POINT_COMPLIANCE: f64 = 0.34;

/// What every node's friction in a step needs.
pub(super) struct Step<'a> {
    prev: &'a Needle,
    now: &'a Needle,
    /// Axial coordinates of the needle nodes, m.
    s: &'a [f64],
    /// Their shaft lengths, m.
    lengths: &'a [f64],
    /// The share of the grip each node's tissue still has: the relaxation function of a
    /// viscoelastic tissue at the age of the cut there, 1 for an elastic one.
    grip: &'a [f64],
    /// The front node (`usize::MAX`: none).
    front: usize,
    /// Whether the tip is at the crack front.
    cutting: bool,
    /// The tip's depth past the entry, m.
    tip_depth: f64,
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
