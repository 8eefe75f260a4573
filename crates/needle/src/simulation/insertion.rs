//! The puncture state machine (paper section 5.4): Outside, Touching, Inside, and the far
//! side (ExitTouching, Exited), with the addition and removal of needle nodes.
//!
//! Inside, with `d` the axial distance from the last non-tip node to the tip
//! ([`shaft_edit`]): a Shaft node is added at `h` past the last node when `d >= 1.5 h` (so
//! it never lands on the Tip node), the last Shaft node is removed when `d < 0.3 h` (a
//! margin below the `h / 2` it was added at), the
//! Tip node exists while `d >= h / 4` past the Surface node (added at `h / 2`), and is
//! removed and re-added (neighbour refresh) every `tip_refresh * h` of tip motion. The
//! paper adds nodes at the tip when `d > h`; these margins keep any two needle nodes at
//! least h / 4 apart, but for a Shaft node the tissue crowds closer on the way out, which
//! hands its shaft length over before it goes ([`CROWDED`]; at least h / 10 apart).
//!
//! With the per-length friction model, nodes added inside the tissue start slipping with
//! the velocity of the tissue at the tip (the shaft slides past the tissue it reaches), and
//! a refreshed Tip node keeps its friction state, velocity and elastic offset: the load
//! the tip carries is not released by a refresh, so the force has no sawtooth at the
//! refresh period.
//!
//! A Shaft node that the tissue pushes more than h / 2 ahead of an advancing tip (the
//! shaft no longer holding the tissue it is in) stops the run with
//! [`SimulationError::NodesLost`]; with the divergence guard's error instead when it is
//! more than [`MAX_STEP_SPACINGS`] spacings ahead and some node is faster than
//! `physics.max_speed` (a diverging run). Less than h / 2 ahead, it is removed.

use super::{at, vec4, xyz, Simulation};
use crate::config::Membrane;
use crate::friction::FrictionState;
use crate::needle::Needle;
use crate::node_editor::{EditError, Placement};
use crate::nodes::{NeedleNode, NodeRole};
use crate::puncture::{mean_cone_angle, TouchingOutcome};
use crate::sheath::{self, Patch, Tear};
use crate::state::Passage;
use crate::SimulationError;
use glam::DVec3;
use needlesim_core::NodeField;

/// Most needle node spacings a needle point may move in one step while in contact.
/// Node addition and removal handle several nodes per step (tested at 2.7 spacings a
/// step); at 8 spacings a step (a 90 m/s needle in the shipped scenes) the tip crossed the
/// whole body within the Touching phase and nodes were placed past the far surface until
/// the slots ran out. A haptic pose glitch is usually far larger.
pub const MAX_STEP_SPACINGS: f64 = 4.0;

/// The next edit of the needle node stack while Inside.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ShaftEdit {
    /// Take the Tip node off (to edit the shaft behind it, or because the tip is too close
    /// to the last node); it is re-added with its load.
    LiftTip,
    /// Remove the last Shaft node (the needle was pulled back past it).
    RemoveShaft,
    /// Add a Shaft node `h` past the last node.
    AddShaft,
    /// Add the Tip node at the tip.
    AddTip,
    /// The tip was pulled back out past the Surface node.
    LeaveSurface,
    /// Nothing to change.
    Keep,
}

/// A Shaft node is removed when the tip is within this many spacings past it: below the
/// h / 2 at which it was added (h past the node before it when the tip was 1.5 h past
/// that), so that a node the tissue carries forward a little does not go and come back
/// every step.
pub(super) const REMOVE: f64 = 0.3;

/// A Shaft node closer than this many spacings along the shaft to the node before it is
/// crowded: the tissue carried it there (the shaft behind a dented membrane, compressed
/// along it, or the tissue dragged out with a withdrawing needle), and it is taken off
/// ([`Simulation::next_edit`](super::inside)). On the way out with the per-length model
/// it first hands its shaft length over, as any last Shaft node does, unless it comes
/// within [`CROWDED_FLOOR`] spacings.
pub(super) const CROWDED: f64 = 0.25;

/// Whether a Shaft node `gap` m along the shaft past the node before it is crowded
/// ([`CROWDED`]): the one rule the edits (`Simulation::next_edit`) and the shares
/// (`Simulation::update_shares`) share.
pub(super) fn is_crowded(gap: f64, h: f64) -> bool {
    gap < CROWDED * h
}

/// The closest two needle nodes may come along the shaft before the nearer is taken off
/// at once, share or not: coincident nodes would leave the meshfree neighbourhoods
/// singular.
pub(super) const CROWDED_FLOOR: f64 = 0.1;

/// With the per-length model, the Tip node is taken off once the needle is pulled back
/// this many spacings behind it (having handed its shaft length over meanwhile).
pub(super) const TIP_SPAN: f64 = 0.1;

/// The margins: `has_tip` whether the last node is the Tip node, `last` the role of the
/// last other node, `d` the tip's axial distance past that node, `h` the node spacing.
pub(crate) fn shaft_edit(has_tip: bool, last: NodeRole, d: f64, h: f64) -> ShaftEdit {
    let shaft = last == NodeRole::Shaft;
    if has_tip && (d >= 1.5 * h || (shaft && d < REMOVE * h) || d < 0.25 * h) {
        ShaftEdit::LiftTip
    } else if shaft && d < REMOVE * h {
        ShaftEdit::RemoveShaft
    } else if d >= 1.5 * h {
        ShaftEdit::AddShaft
    } else if !has_tip && d >= 0.5 * h {
        ShaftEdit::AddTip
    } else if last == NodeRole::Surface && !has_tip && d < 0.0 {
        ShaftEdit::LeaveSurface
    } else {
        ShaftEdit::Keep
    }
}

impl Simulation {
    pub(super) fn add(
        &mut self,
        role: NodeRole,
        x: DVec3,
        s: f64,
        seeds: &[u32],
        v: DVec3,
        friction: FrictionState,
    ) -> Result<(), EditError> {
        self.add_placed(role, x, s, seeds, v, friction, Placement::Offset([0.0; 3]))
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn add_placed(
        &mut self,
        role: NodeRole,
        x: DVec3,
        s: f64,
        seeds: &[u32],
        v: DVec3,
        friction: FrictionState,
        placement: Placement,
    ) -> Result<(), EditError> {
        self.mark_edit();
        self.state.edit_shaft |= role != NodeRole::Tip;
        let cand = self.editor.rings(seeds, 2);
        let index = self.editor.add_node_placed(
            self.backend.as_mut(),
            x.as_vec3().to_array(),
            v.as_vec3().to_array(),
            &cand,
            placement,
        )?;
        let region = self.region_of_added(index, x).map_err(EditError::from)?;
        self.state.nodes.push(NeedleNode {
            index,
            role,
            friction,
            s,
            axial: 0.0,
            limit: 0.0,
            circumferential: 0.0,
            sigma: s,
            slide: 0.0,
            normal: [0.0; 3],
            share: 1.0,
            region,
            carried: 0.0,
            carried_at: 0.0,
            reassigned: false,
        });
        Ok(())
    }

    /// Removes the newest needle node; removing the Surface or Exit node undoes its split.
    pub(super) fn remove(&mut self) -> Result<NeedleNode, EditError> {
        self.capture_before_removal()?;
        self.editor.remove_last(self.backend.as_mut())?;
        self.mark_edit();
        if let Some(h) = self.state.handover.as_mut() {
            h.keep_below(self.editor.n_active());
        }
        let node = self.state.nodes.pop().ok_or(EditError::NothingToRemove)?;
        self.state.edit_shaft |= node.role != NodeRole::Tip;
        self.low_water = self.low_water.min(self.state.nodes.len());
        if matches!(node.role, NodeRole::Surface | NodeRole::Exit) {
            let editor = &self.editor;
            self.state
                .surface
                .unsplit(|v| editor.rest_position(v as usize));
            self.state.phase = if node.role == NodeRole::Surface {
                self.state.region = None;
                self.state.denting = None;
                self.state.punctured.clear();
                self.state.patch = None;
                self.state.front = Default::default();
                Passage::Outside
            } else {
                Passage::Inside
            };
        }
        Ok(node)
    }

    /// Adds the Surface or Exit node at `point` on surface triangle `id`, pinned to the
    /// needle (sticking), and splits the triangle around it.
    pub(super) fn pin_at_surface(
        &mut self,
        role: NodeRole,
        id: usize,
        point: DVec3,
        now: &Needle,
        v_tip: DVec3,
    ) -> Result<(), SimulationError> {
        let corners = self.state.surface.triangles()[id];
        let s = (point - DVec3::from(now.base())).dot(DVec3::from(now.direction()));
        // With the per-length model the entry's Surface node is not pinned: it starts with
        // the velocity of the surface it is added in (the mean of the triangle's corners),
        // not the needle's.
        let v = match role == NodeRole::Surface && self.sheathed() {
            true => {
                let mut c = [[0.0f32; 4]; 3];
                self.backend
                    .read_nodes(NodeField::Velocity, &corners, &mut c)
                    .map_err(|e| self.edit(e.into()))?;
                c.iter().map(|x| xyz(*x)).sum::<DVec3>() / 3.0
            }
            false => v_tip,
        };
        self.add(role, point, s, &corners, v, FrictionState::Stick)
            .map_err(|e| self.edit(e))?;
        let node = self.state.nodes.last().expect("just added").index;
        let editor = &self.editor;
        self.state
            .surface
            .split(id, node, |v| editor.rest_position(v as usize));
        if role == NodeRole::Surface && self.sheathed() {
            self.state.patch = Some(self.entry_patch());
            self.settle(0, now, &[point])?;
        }
        Ok(())
    }

    /// The contact patch around the Surface node just added ([`crate::sheath::Patch`]):
    /// the surface nodes within `R_p` of it at rest, weighted `(1 - (r / R_p)^2)^2` with
    /// the Surface node itself, and the stiffness of the sub-grid element that makes the
    /// patch as compliant as a rigid punch of the contact radius `R_c` on a half-space of
    /// the touched region's material. `R_p = max(2 h, 1.3 R_c, min(4 h, R_f / 2))`, `R_f`
    /// the distance to the nearest mesh node off the surface the needle presses (a node
    /// of a mesh triangle whose outward normal is not within 60 degrees of against the
    /// needle: the body's sides and its back, so a slab thinner than `8 h` is limited by
    /// its thickness, and an entry more than 60 degrees off the face's normal keeps two
    /// spacings): four spacings where the body has room for them (the dent then
    /// converges with the spacing and is nearly the same for every model:
    /// [`crate::sheath`]); within half that distance, so that the half-space compliance
    /// the element is sized by still describes the body (on a block a few spacings wide
    /// the patch would take the whole face, and the layered test block's GPU and CPU runs
    /// then drifted apart by up to 140 steps at node events); never under two spacings,
    /// which the lattice needs to carry the load at all.
    fn entry_patch(&self) -> Patch {
        let surface_node = self.state.nodes.last().expect("the Surface node");
        let layer = self.params.regions[surface_node.region as usize];
        let (young, nu) = layer.modulus;
        let rc = layer.contact_radius;
        let n_mesh = self.editor.n_mesh() as u32;
        let rest = |v: u32| DVec3::from(self.rest_of(v));
        let centre = rest(surface_node.index);
        // Surface cells: a third of every rest triangle at each corner, of the triangles
        // that face the needle (outward normal within 60 degrees of against it): the
        // contact is on the touched face, not on the sides of a body the patch reaches
        // around (a patch wider than a small block took its side faces in, and their
        // deeper mean let the tip go at once).
        let axis = DVec3::from(
            self.state
                .needle
                .as_ref()
                .map_or([1.0, 0.0, 0.0], |n| n.direction()),
        );
        let facing = |tri: &[u32; 3]| {
            let [a, b, c] = tri.map(rest);
            let normal = (b - a).cross(c - a);
            normal.dot(axis) <= -0.5 * normal.length()
        };
        // Room on the face: the nearest mesh node of a mesh triangle that does not face
        // the needle (a side or the back of the body). The triangles split around needle
        // nodes are left out: the Surface node sits at a fitted rest position, which can
        // tip a thin split triangle over.
        let edge = self
            .state
            .surface
            .triangles()
            .iter()
            .filter(|tri| tri.iter().all(|&v| v < n_mesh) && !facing(tri))
            .flat_map(|tri| tri.iter())
            .filter(|&&v| v < n_mesh)
            .map(|&v| rest(v).distance(centre))
            .fold(f64::INFINITY, f64::min);
        let radius = (4.0 * self.spacing)
            .min(0.5 * edge)
            .max(2.0 * self.spacing)
            .max(1.3 * rc);
        let mut cells: Vec<(u32, f64)> = Vec::new();
        for tri in self.state.surface.triangles() {
            if !facing(tri) && !tri.contains(&surface_node.index) {
                continue;
            }
            let [a, b, c] = tri.map(rest);
            let third = (b - a).cross(c - a).length() / 6.0;
            for &v in tri {
                if v >= n_mesh && v != surface_node.index {
                    continue;
                }
                if v == surface_node.index || rest(v).distance(centre) < radius {
                    cells.push((v, third));
                }
            }
        }
        cells.sort_by_key(|c| c.0);
        let mut nodes: Vec<(u32, f64)> = Vec::new();
        for (v, a) in cells {
            match nodes.last_mut() {
                Some(last) if last.0 == v => last.1 += a,
                _ => nodes.push((v, a)),
            }
        }
        let raw: Vec<f64> = nodes
            .iter()
            .map(|(v, _)| sheath::patch_weight(rest(*v).distance(centre), radius))
            .collect();
        let sum: f64 = raw.iter().sum();
        let x: Vec<DVec3> = nodes.iter().map(|(v, _)| rest(*v)).collect();
        let w: Vec<f64> = raw.iter().map(|r| r / sum).collect();
        let area: Vec<f64> = nodes.iter().map(|(_, a)| *a).collect();
        let punch = sheath::punch_compliance(young, nu, rc);
        let resolved = sheath::patch_compliance(young, nu, &x, &w, &area);
        // A contact radius the patch resolves leaves nothing below the grid; the element
        // keeps a tenth of the punch's compliance so that it never turns rigid.
        let compliance = (punch - resolved).max(0.1 * punch);
        let mut patch = Patch {
            nodes: Vec::new(),
            weights: Vec::new(),
            surface: 0.0,
            stiffness: 1.0 / compliance,
            mean: None,
            offset: 0.0,
            force: 0.0,
            tear: None,
        };
        for ((v, _), w) in nodes.iter().zip(&w) {
            if *v == surface_node.index {
                patch.surface += w;
            } else if *w > 0.0 {
                patch.nodes.push(*v);
                patch.weights.push(*w);
            }
        }
        patch
    }

    /// The first surface triangle the segment `p0 -> p1` crosses, entering or leaving,
    /// ignoring the triangles around needle nodes.
    pub(super) fn surface_crossing(
        &mut self,
        p0: DVec3,
        p1: DVec3,
        entering: bool,
    ) -> Result<Option<(usize, DVec3)>, SimulationError> {
        let skip: Vec<u32> = self.state.nodes.iter().map(|n| n.index).collect();
        let editor = &self.editor;
        let rest =
            |v: u32| ((v as usize) < editor.n_mesh()).then(|| editor.rest_position(v as usize));
        let hit = self
            .state
            .surface
            .crossing(
                self.backend.as_mut(),
                (p0.to_array(), p1.to_array()),
                entering,
                &skip,
                &rest,
            )
            .map_err(|e| self.edit(e.into()))?;
        Ok(hit.map(|(id, p)| (id, DVec3::from(p))))
    }

    /// Errs when a needle point moved more than [`MAX_STEP_SPACINGS`] node spacings over
    /// the step while the needle is in contact, or when it enters the body and ends more
    /// than that past the surface. (A rigid motion interpolated over the step moves the
    /// points of a segment most at its ends.)
    fn check_motion(
        &self,
        prev: &Needle,
        now: &Needle,
        entry: Option<DVec3>,
    ) -> Result<(), SimulationError> {
        let dist = |a: [f64; 3], b: DVec3| (DVec3::from(a) - b).length();
        let (moved, phase) = match (self.state.phase, entry) {
            (Passage::Outside, None) => return Ok(()),
            (Passage::Outside, Some(p)) => (dist(now.tip(), p), "entering the body"),
            (phase, _) => (
                dist(now.tip(), prev.tip().into()).max(dist(now.base(), prev.base().into())),
                match phase {
                    Passage::Touching | Passage::ExitTouching => "touching the surface",
                    Passage::Exited => "through the body",
                    _ => "inside the body",
                },
            ),
        };
        let limit = MAX_STEP_SPACINGS * self.spacing;
        if moved > limit {
            return Err(SimulationError::TooFast {
                step: self.stepper.steps() + 1,
                moved,
                limit,
                phase,
            });
        }
        Ok(())
    }

    /// The state machine: surface contact, puncture, node addition and removal.
    pub(super) fn contact(&mut self, prev: &Needle, now: &Needle) -> Result<(), SimulationError> {
        self.state.read_velocities.clear();
        let t = DVec3::from(now.direction());
        let tip = DVec3::from(now.tip());
        let v_tip = self.needle_velocity(prev, now, now.length());
        self.state.swept_from = prev.tip();
        self.state.advance =
            self.depth_of(now.tip(), now.direction()) - self.depth_of(prev.tip(), prev.direction());
        if self.state.phase != Passage::Outside {
            self.check_motion(prev, now, None)?;
        }
        match self.state.phase {
            Passage::Outside => {
                let hit = self.surface_crossing(prev.tip().into(), tip, true)?;
                let Some((id, point)) = hit else {
                    return Ok(());
                };
                self.check_motion(prev, now, Some(point))?;
                self.pin_at_surface(NodeRole::Surface, id, point, now, v_tip)?;
                self.state.entry.get_or_insert(point.to_array());
                self.state.phase = Passage::Touching;
            }
            Passage::Touching | Passage::ExitTouching => {
                let exit = self.state.phase == Passage::ExitTouching;
                let sp = *self
                    .state
                    .surface
                    .last_split()
                    .expect("Touching has a split triangle");
                let mut c = [[0.0f32; 4]; 3];
                self.backend
                    .read_nodes(NodeField::Position, &sp.original, &mut c)
                    .map_err(|e| self.edit(e.into()))?;
                // The cone's apex: the pinned node, or with the per-length model (whose
                // Surface node is not pinned) the tip, the bottom of the dent.
                let apex = match self.sheathed() && !exit {
                    true => tip,
                    false => at(now, self.state.nodes.last().expect("pinned node").s),
                };
                let corners = c.map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]);
                let angle = mean_cone_angle(apex.to_array(), corners, t.to_array());
                let mut outcome = self.params.thresholds.touching(angle);
                // Entering, the membrane of the region touched rules if it has one.
                let pinned_region = self.state.nodes.last().map_or(0, |n| n.region) as usize;
                let threshold = match (exit, self.params.regions[pinned_region].membrane) {
                    (false, Membrane::Force(f)) => Some(f),
                    (false, Membrane::Impenetrable) => Some(f64::INFINITY),
                    _ => self.params.puncture_force,
                };
                if let Some(f) = threshold {
                    // The patch's force is capped at the puncture force: reaching it
                    // is the membrane giving.
                    let gave = match (&self.state.patch, exit) {
                        (Some(p), false) => p.force >= f * (1.0 - 1e-9),
                        _ => self.state.pinned_axial > f,
                    };
                    outcome = match outcome {
                        TouchingOutcome::Release => TouchingOutcome::Release,
                        _ if gave => TouchingOutcome::Puncture,
                        _ => TouchingOutcome::Stay,
                    };
                }
                // With the contact patch the tip lets go when it no longer presses on it
                // and has drawn back past it (under a wide contact the dented surface is
                // flat, and the cone angle says nothing about contact).
                if let (Some(p), false) = (&self.state.patch, exit) {
                    let clear = p.force == 0.0
                        && p.mean.is_some_and(|m| now.length() < m + p.offset - 1e-9);
                    outcome = match outcome {
                        TouchingOutcome::Release if !clear => TouchingOutcome::Stay,
                        TouchingOutcome::Stay if clear => TouchingOutcome::Release,
                        o => o,
                    };
                }
                match (outcome, exit) {
                    (TouchingOutcome::Stay, _) => {}
                    (TouchingOutcome::Release, false) => {
                        self.remove().map_err(|e| self.edit(e))?;
                    }
                    (TouchingOutcome::Release, true) => {
                        self.remove().map_err(|e| self.edit(e))?;
                        self.inside(now, v_tip)?;
                    }
                    (TouchingOutcome::Puncture, false) => {
                        self.state.phase = Passage::Inside;
                        self.state.region = Some(pinned_region as u16);
                        self.state.denting = None;
                        self.state.punctured.push(pinned_region as u16);
                        self.state.nodes[0].friction = FrictionState::Slip;
                        self.state.cut_depth = self.depth_of(now.tip(), now.direction());
                        // The entry membrane tears: the tip carries on with the cutting
                        // force at once (when it was pressing harder than that), and the
                        // patch lets go of the rest over the tear ([`sheath::Tear`]).
                        let cut = self.state.cut_depth;
                        let cutting = self.params.regions[pinned_region].cutting;
                        let (length, time) = (self.params.point_length, self.params.tear_time);
                        let started = self.stepper.time();
                        let mut front = sheath::FrontElement::default();
                        if let Some(p) = self.state.patch.as_mut() {
                            front.force = cutting.min(p.force);
                            p.force -= front.force;
                            p.tear = Some(Tear {
                                from: p.force,
                                to: 0.0,
                                at: cut,
                                length,
                                started,
                                time,
                            });
                        }
                        // A membrane weaker than the cutting force: the cutting force comes
                        // up to its own over the same tear.
                        if front.force < cutting {
                            front.tear = Some(Tear {
                                from: front.force,
                                to: cutting,
                                at: cut,
                                length,
                                started,
                                time,
                            });
                        }
                        self.state.front = front;
                        self.inside(now, v_tip)?;
                    }
                    (TouchingOutcome::Puncture, true) => {
                        self.state.phase = Passage::Exited;
                        let exit = self.state.nodes.last_mut().expect("exit node");
                        exit.friction = FrictionState::Slip;
                        self.exited(now, v_tip)?;
                    }
                }
            }
            Passage::Inside => self.inside(now, v_tip)?,
            Passage::Exited => self.exited(now, v_tip)?,
        }
        Ok(())
    }

    /// Tip past the far surface: only the Exit node is checked; the tip re-enters when
    /// pulled back behind it.
    fn exited(&mut self, now: &Needle, v_tip: DVec3) -> Result<(), SimulationError> {
        let read = self.read_needle(&[]).map_err(|e| self.edit(e.into()))?;
        let exit = *read.positions.last().expect("exit node");
        let d = (DVec3::from(now.tip()) - exit).dot(DVec3::from(now.direction()));
        self.state.positions = read.positions.iter().map(|x| vec4(*x, 0.0)).collect();
        if d < 0.0 {
            self.remove().map_err(|e| self.edit(e))?;
            self.inside(now, v_tip)?;
        } else {
            self.state.read_velocities = read.velocities;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Moves the Tip node (held on the needle) to `tip`, then applies the edits to a
    /// one-dimensional stack of node coordinates (the Surface node at 0) until none is
    /// left, as `inside` does.
    fn settle(stack: &mut Vec<(NodeRole, f64)>, tip: f64, h: f64) {
        if let Some(n) = stack.last_mut().filter(|n| n.0 == NodeRole::Tip) {
            n.1 = tip;
        }
        for _ in 0..100 {
            let has_tip = stack.last().is_some_and(|n| n.0 == NodeRole::Tip);
            let last = stack.len() - 1 - has_tip as usize;
            let (role, s) = stack[last];
            match shaft_edit(has_tip, role, tip - s, h) {
                ShaftEdit::LiftTip | ShaftEdit::RemoveShaft => {
                    stack.pop();
                }
                ShaftEdit::AddShaft => stack.push((NodeRole::Shaft, s + h)),
                ShaftEdit::AddTip => stack.push((NodeRole::Tip, tip)),
                ShaftEdit::LeaveSurface => {
                    stack.pop();
                    return;
                }
                ShaftEdit::Keep => return,
            }
        }
        panic!("the edits do not settle at tip {tip}");
    }

    #[test]
    fn the_margins_are_those_documented() {
        let h = 1.0;
        use NodeRole::*;
        // No Tip node yet: the Tip node comes at h/2 past the last node, a Shaft node at 1.5 h.
        assert_eq!(shaft_edit(false, Surface, 0.49, h), ShaftEdit::Keep);
        assert_eq!(shaft_edit(false, Surface, 0.5, h), ShaftEdit::AddTip);
        assert_eq!(shaft_edit(false, Shaft, 0.5, h), ShaftEdit::AddTip);
        assert_eq!(shaft_edit(false, Shaft, 1.5, h), ShaftEdit::AddShaft);
        // With a Tip node: lifted at 1.5 h (to add a Shaft node behind it) ...
        assert_eq!(shaft_edit(true, Shaft, 1.49, h), ShaftEdit::Keep);
        assert_eq!(shaft_edit(true, Shaft, 1.5, h), ShaftEdit::LiftTip);
        // ... when the needle is pulled back to 0.3 h of a Shaft node (it was added at
        // h/2: a node carried a little forward stays), or h/4 of the Surface node.
        assert_eq!(shaft_edit(true, Shaft, 0.5, h), ShaftEdit::Keep);
        assert_eq!(shaft_edit(true, Shaft, 0.31, h), ShaftEdit::Keep);
        assert_eq!(shaft_edit(true, Shaft, 0.29, h), ShaftEdit::LiftTip);
        assert_eq!(shaft_edit(true, Surface, 0.25, h), ShaftEdit::Keep);
        assert_eq!(shaft_edit(true, Surface, 0.24, h), ShaftEdit::LiftTip);
        // Without the Tip node a Shaft node closer than 0.3 h goes; the Surface node only
        // when the tip is back out past it.
        assert_eq!(shaft_edit(false, Shaft, 0.29, h), ShaftEdit::RemoveShaft);
        assert_eq!(shaft_edit(false, Surface, 0.0, h), ShaftEdit::Keep);
        assert_eq!(
            shaft_edit(false, Surface, -1e-12, h),
            ShaftEdit::LeaveSurface
        );
    }

    #[test]
    fn nodes_stay_a_quarter_spacing_apart_through_insertion_and_extraction() {
        let h = 1.0;
        let mut stack = vec![(NodeRole::Surface, 0.0)];
        // In by 10.3 h and back out, in steps that do not divide h (up to 2.7 h a step).
        let mut path: Vec<f64> = (0..=140).map(|i| i as f64 * 0.0737).collect();
        path.extend((0..=140).rev().map(|i| i as f64 * 0.0737));
        path.extend([2.7, 5.4, 8.1, 5.4, 2.7, 0.1]);
        for &tip in &path {
            settle(&mut stack, tip, h);
            let s: Vec<f64> = stack.iter().map(|n| n.1).collect();
            for w in s.windows(2) {
                assert!(w[1] - w[0] >= 0.25 * h - 1e-12, "nodes {w:?} at tip {tip}");
            }
            // Shaft nodes one spacing apart from the Surface node on.
            for (k, n) in stack.iter().enumerate() {
                if n.0 == NodeRole::Shaft {
                    assert!((n.1 - k as f64 * h).abs() < 1e-12, "{stack:?}");
                }
            }
            // The Tip node is at the tip and past every other node; without one, the tip
            // is within h/2 of the last node.
            match stack.last() {
                Some((NodeRole::Tip, s)) => assert_eq!(*s, tip),
                Some((_, s)) => assert!(tip - s < 0.5 * h, "{stack:?} at {tip}"),
                None => unreachable!(),
            }
            // At most one node per spacing of depth, plus the Surface and Tip nodes.
            assert!(stack.len() as f64 <= tip.max(0.0) / h + 2.0, "{stack:?}");
        }
        assert_eq!(stack, vec![(NodeRole::Surface, 0.0)]);
    }
}
