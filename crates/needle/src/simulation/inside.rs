//! The Inside phase of one step: the shaft's nodes edited to the rules of [`shaft_edit`]
//! (the margins are in the docs of [`super::insertion`]), the Tip node refreshed, and the
//! far surface watched for the tip leaving the body.
//!
//! [`Simulation::inside`] runs three jobs in order on one [`InsideStep`] (what the step
//! knows about the needle nodes as it edits them): [`Simulation::edit_shaft`],
//! [`Simulation::refresh_tip`] and [`Simulation::far_side`]; then the new nodes take the
//! shaft's loads and are settled.

use super::insertion::{
    is_crowded, shaft_edit, ShaftEdit, CROWDED_FLOOR, MAX_STEP_SPACINGS, REMOVE,
};
use super::shaft_loads::FrictionField;
use super::{at, vec4, Simulation};
use crate::friction::FrictionState;
use crate::needle::Needle;
use crate::node_editor::Placement;
use crate::nodes::{NeedleNode, NodeRole};
use crate::splits::CrossingQuery;
use crate::state::Passage;
use crate::SimulationError;
use glam::DVec3;
use needlesim_core::math::Vec4;

/// What one Inside step knows while it edits the needle nodes.
struct InsideStep {
    /// Unit needle direction, base to tip.
    t: DVec3,
    /// The needle's tip and base at the end of the step.
    tip: DVec3,
    base: DVec3,
    /// Node spacing, m.
    h: f64,
    /// The tip moved forward along the needle this step.
    advancing: bool,
    /// The per-length friction model (nodes added inside start slipping).
    per_length: bool,
    /// The sheath carries the shaft's loads (per-length model).
    sheathed: bool,
    /// The Tip node dents an inner membrane.
    denting_membrane: bool,
    /// The needle nodes' positions as edited so far.
    pos: Vec<DVec3>,
    /// The needle nodes' velocities as read, until the first edit.
    known: Option<Vec<Vec4>>,
    /// Some node was added or removed.
    edited: bool,
    /// The load of a Tip node lifted to edit the shaft behind it, for its return.
    carried: Option<(FrictionState, DVec3, Placement)>,
    /// A Tip node was taken off for being ahead of the tip this step.
    dropped_ahead: bool,
    /// The Tip node went on again behind the crack front (advancing after a
    /// withdrawal took it off): it takes no share of the shaft's friction at once
    /// ([`Simulation::finish_inside`]).
    retracked_tip: bool,
}

/// The last two nodes, whose neighbours seed a new node's neighbour search.
fn seeds(nodes: &[NeedleNode]) -> Vec<u32> {
    nodes.iter().rev().take(2).map(|n| n.index).collect()
}

impl Simulation {
    /// Inside: keep a Shaft node per spacing and the Tip node at the tip; detect the far
    /// surface.
    pub(super) fn inside(&mut self, now: &Needle, v_tip: DVec3) -> Result<(), SimulationError> {
        let tip = DVec3::from(now.tip());
        // Advancing: the tip moved forward along the needle this step (by more than
        // rounding: a rotation about the entry point moves it sideways only).
        let advancing = self.state.advance > 1e-12;
        // The far-side test for the needle nodes as they are: the corners of its candidate
        // triangles (only near a surface) come back with the nodes' positions and
        // velocities in one readback, or alone when the host integrated the nodes' last
        // step. Both serve below while no edit changes the nodes (or the split triangles).
        let prev_tip = DVec3::from(self.state.swept_from);
        let query = match advancing {
            true => {
                let skip: Vec<u32> = self.state.nodes.iter().map(|n| n.index).collect();
                let (p0, p1) = (prev_tip.to_array(), tip.to_array());
                let editor = &self.editor;
                let rest = |v: u32| {
                    ((v as usize) < editor.n_mesh()).then(|| editor.rest_position(v as usize))
                };
                self.state
                    .surface
                    .crossing_query(p0, p1, false, &skip, &rest)
            }
            false => None,
        };
        let corners = query.as_ref().map_or(&[][..], |q| &q.corners[..]);
        let read = self.read_needle(corners).map_err(|e| self.edit(e.into()))?;
        // The shaft's friction before any edit, to carry over to the nodes after them.
        let field = self.friction_field(&read.positions, now);
        self.low_water = self.state.nodes.len();
        let sheathed = self.sheathed();
        let mut step = InsideStep {
            t: DVec3::from(now.direction()),
            tip,
            base: DVec3::from(now.base()),
            h: self.spacing,
            advancing,
            per_length: self.params.per_length().is_some(),
            sheathed,
            denting_membrane: sheathed && self.state.denting.is_some(),
            pos: read.positions,
            known: Some(read.velocities),
            edited: false,
            carried: None,
            dropped_ahead: false,
            retracked_tip: false,
        };
        if !self.edit_shaft(&mut step, now, v_tip)? {
            // The needle was pulled out past the Surface node.
            return Ok(());
        }
        self.refresh_tip(&mut step, now, v_tip)?;
        if advancing {
            self.far_side(&mut step, now, v_tip, prev_tip, query.as_ref(), &read.extra)?;
        }
        self.finish_inside(step, &field, now)
    }

    /// Adds and removes Shaft and Tip nodes until the stack fits the rules; `false` when
    /// the needle left the body backwards (the Surface node removed).
    fn edit_shaft(
        &mut self,
        st: &mut InsideStep,
        now: &Needle,
        v_tip: DVec3,
    ) -> Result<bool, SimulationError> {
        loop {
            let nodes = &self.state.nodes;
            let has_tip = nodes.last().is_some_and(|n| n.role == NodeRole::Tip);
            let last = nodes.len() - 1 - has_tip as usize;
            let role = nodes[last].role;
            let d = (st.tip - st.pos[last]).dot(st.t);
            let (edit, behind, ahead) = self.next_edit(st, now, has_tip, last, d);
            match edit {
                ShaftEdit::LiftTip if behind => {
                    self.remove().map_err(|e| self.edit(e))?;
                    // Pulled back off the crack front, the Tip node goes for good (it is
                    // not put back until the needle advances): its removal is handed
                    // over like a Shaft node's (`crate::handover`). Measured on
                    // `liver_insertion.toml` without: the Shaft node behind it jerked
                    // back at 52 mm/s and the needle force rose 19 mN in 1 ms.
                    self.state.edit_shaft |= !st.advancing;
                    st.pos.pop();
                    st.dropped_ahead = ahead;
                }
                ShaftEdit::LiftTip => {
                    // Taken off to edit the shaft behind it: re-added below with its load.
                    if st.carried.is_none() {
                        st.carried = Some(self.tip_load(st.known.as_deref(), st.tip)?);
                    }
                    self.remove().map_err(|e| self.edit(e))?;
                    st.pos.pop();
                }
                ShaftEdit::RemoveShaft => {
                    // A node up to h / 2 past the tip was carried there by the tissue
                    // springing back over the tip (a membrane just punctured): removed,
                    // as any node closer than h / 2. Farther, the shaft lost its grip.
                    if st.advancing && d < -0.5 * st.h {
                        return Err(self.lost(last, role, -d, st.h));
                    }
                    self.remove().map_err(|e| self.edit(e))?;
                    st.pos.pop();
                }
                ShaftEdit::AddShaft => self.add_shaft(st, now, v_tip, has_tip, last)?,
                ShaftEdit::AddTip => self.add_tip(st, now, v_tip, last)?,
                // The Surface node a little ahead of an advancing tip (the entry surface
                // springing back after the puncture) stays; more than h / 2 ahead, the
                // shaft lost its grip.
                ShaftEdit::LeaveSurface if st.advancing && d >= -0.5 * st.h => break,
                ShaftEdit::LeaveSurface => {
                    if st.advancing {
                        return Err(self.lost(last, role, -d, st.h));
                    }
                    self.remove().map_err(|e| self.edit(e))?;
                    return Ok(false);
                }
                ShaftEdit::Keep => break,
            }
            st.edited = true;
            st.known = None;
        }
        Ok(true)
    }

    /// The next edit of the stack whose last non-tip node is `last`, `d` behind the tip,
    /// with whether the Tip node is behind the crack front and whether it is ahead of the
    /// tip.
    fn next_edit(
        &self,
        st: &InsideStep,
        now: &Needle,
        has_tip: bool,
        last: usize,
        d: f64,
    ) -> (ShaftEdit, bool, bool) {
        let (nodes, h) = (&self.state.nodes, st.h);
        let role = nodes[last].role;
        // A Shaft node the tissue has crowded onto the node behind it (within h / 4
        // along the shaft: the shaft behind a dented membrane, compressed along it)
        // is taken off; the rules re-add one h past the node behind if the tip is far
        // enough. Coincident nodes would leave the meshfree neighbourhoods singular.
        // On the way out (per-length model) the last one hands its shaft length over
        // first, as the last Shaft node does when the tip is pulled back over it
        // ([`Simulation::update_shares`]), and is taken off when its share is 0:
        // taken off at once with its whole length, its friction went to the node
        // before, out of balance with the tissue's pull there, and the needle force
        // fell 20% within 0.6 ms (`layered_liver_biopsy.toml`, 9.36 s, the run's
        // largest buzz, 6.1%; CPU, 2026-11-28). Closer than `CROWDED_FLOOR * h` it
        // goes at once all the same.
        let gap = match last > 0 {
            true => (st.pos[last] - st.pos[last - 1]).dot(st.t),
            false => f64::INFINITY,
        };
        // (With the Tip node still on, the node keeps its place until the Tip node has
        // handed its own length over and gone: lifting it here would drop its share.
        // Held, the node stays as it is; advancing again, it goes at once.)
        let handing_over =
            st.sheathed && !st.advancing && nodes[last].share > 0.0 && gap >= CROWDED_FLOOR * h;
        let crowded = role == NodeRole::Shaft && is_crowded(gap, h) && !handing_over;
        // With the per-length model the Tip node marks the crack front: it is taken
        // off (and not put back) once the needle is pulled back behind it, and put on
        // again only when the needle advances.
        // A Tip node the tissue has carried more than two refresh distances ahead of
        // the advancing tip (springing back after a puncture; the tip's push is off
        // from there, [`Simulation::front_step`]) holds no crack front: it is taken off,
        // and put on at the tip again from the next step.
        let ahead = st.sheathed
            && has_tip
            && st.advancing
            && (st.pos[nodes.len() - 1] - st.base).dot(st.t)
                > now.length() + 2.0 * self.params.refresh;
        let behind = st.sheathed
            && has_tip
            && ((!st.advancing && nodes[nodes.len() - 1].share == 0.0) || ahead);
        // With the per-length model a Shaft node the tip is pulled back over is
        // removed once it has handed its shaft length over (its share is 0), or once
        // the tip is behind it.
        let d_edit = match st.sheathed && role == NodeRole::Shaft && nodes[last].share > 0.0 {
            true if d >= 0.0 => d.max(REMOVE * h),
            _ => d,
        };
        let edit = match (crowded, has_tip) {
            (true, true) => ShaftEdit::LiftTip,
            (true, false) => ShaftEdit::RemoveShaft,
            (false, _) if behind => ShaftEdit::LiftTip,
            // While the Tip node dents an inner membrane it stays where the membrane
            // holds it (behind the tip by the dent): no Shaft node goes in behind it
            // until the membrane gives.
            (false, true) if st.denting_membrane && d >= 1.5 * h => ShaftEdit::Keep,
            (false, _) => match shaft_edit(has_tip, role, d_edit, h) {
                ShaftEdit::AddTip | ShaftEdit::AddShaft if st.sheathed && !st.advancing => {
                    ShaftEdit::Keep
                }
                ShaftEdit::AddTip if st.dropped_ahead => ShaftEdit::Keep,
                e => e,
            },
        };
        (edit, behind, ahead)
    }

    /// The error for node `last` (of `role`) `ahead` m ahead of the tip. A node farther
    /// ahead than the needle may move in a step is a sign of a diverging run: the
    /// divergence guard is asked first, so that a divergence is reported as one.
    fn lost(&mut self, last: usize, role: NodeRole, ahead: f64, h: f64) -> SimulationError {
        match self.check() {
            Err(e) if ahead > MAX_STEP_SPACINGS * h => e,
            _ => SimulationError::NodesLost {
                step: self.stepper.steps(),
                node: self.state.nodes[last].index,
                role,
                ahead,
            },
        }
    }

    /// Adds a Shaft node `h` past node `last`.
    fn add_shaft(
        &mut self,
        st: &mut InsideStep,
        now: &Needle,
        v_tip: DVec3,
        has_tip: bool,
        last: usize,
    ) -> Result<(), SimulationError> {
        let (t, base) = (st.t, st.base);
        let s = (st.pos[last] - base).dot(t) + st.h;
        let x = at(now, s);
        let (v, state) = self.new_node_motion(has_tip, v_tip, st.known.as_deref())?;
        let sd = seeds(&self.state.nodes);
        // On the track between the last node and the material at the tip when the Tip
        // node was lifted for this (the shaft behind a tip denting a membrane runs
        // through tissue compressed and stretched along it, where the editor's rigid fit
        // can put the node at rest past the tip); else the editor's fit (paper section
        // 5.1).
        let placement = match st.carried {
            Some((_, _, Placement::Rest(front))) => {
                let r_last = DVec3::from(self.rest_of(self.state.nodes[last].index));
                let along = (s - (st.pos[last] - base).dot(t))
                    / (now.length() - (st.pos[last] - base).dot(t));
                let r = r_last + (DVec3::from(front) - r_last) * along.clamp(0.0, 1.0);
                Placement::Rest(r.to_array())
            }
            _ => Placement::Offset([0.0; 3]),
        };
        self.add_placed(NodeRole::Shaft, x, s, &sd, v, state, placement)
            .map_err(|e| self.edit(e))?;
        st.pos.push(x);
        Ok(())
    }

    /// Adds the Tip node at the tip, with the load it carried if it was lifted.
    fn add_tip(
        &mut self,
        st: &mut InsideStep,
        now: &Needle,
        v_tip: DVec3,
        last: usize,
    ) -> Result<(), SimulationError> {
        let sd = seeds(&self.state.nodes);
        let (state, v, placement) = match st.carried.take() {
            Some(load) => load,
            // The first Tip node takes over the crack front from the deepest node: it
            // strains the tissue ahead as that node did.
            None if st.per_length => {
                // Put on again behind the crack front (advancing after a withdrawal):
                // handed over like a Shaft node ([`crate::handover`]), as its last
                // removal was, once per re-insertion; its loads in `finish_inside`.
                if self.depth_of(now.tip(), now.direction()) < self.state.cut_depth - 1e-9 {
                    st.retracked_tip = true;
                    self.state.edit_shaft = true;
                }
                let front = self.state.nodes[last].index;
                let o = self
                    .editor
                    .elastic_offset(self.backend.as_mut(), front)
                    .map_err(|e| self.edit(e))?;
                (FrictionState::Slip, v_tip, Placement::Offset(o))
            }
            None => (FrictionState::Stick, v_tip, Placement::Offset([0.0; 3])),
        };
        self.add_placed(
            NodeRole::Tip,
            st.tip,
            now.length(),
            &sd,
            v,
            state,
            placement,
        )
        .map_err(|e| self.edit(e))?;
        st.pos.push(st.tip);
        self.state.tip_placed = st.tip.to_array();
        Ok(())
    }

    /// Re-adds the Tip node at the tip once the tip has moved a refresh distance from it
    /// (paper section 5.1), keeping the load it carries.
    fn refresh_tip(
        &mut self,
        st: &mut InsideStep,
        now: &Needle,
        v_tip: DVec3,
    ) -> Result<(), SimulationError> {
        let has_tip = self
            .state
            .nodes
            .last()
            .is_some_and(|n| n.role == NodeRole::Tip);
        // How far the Tip node is from the tip: with the per-length model, how far the tip
        // has cut past it along the needle (turning the needle sideways carries the Tip
        // node with it and cuts nothing); with the paper's, since placed.
        let moved = match (self.sheathed(), st.pos.last()) {
            (true, Some(x)) => now.length() - (*x - st.base).dot(st.t),
            _ => (st.tip - DVec3::from(self.state.tip_placed)).length(),
        };
        // (With the per-length model only while the tip advances: a Tip node the tissue
        // pushes back along a needle that turns or stands cuts nothing new.)
        // (Nor while the Tip node dents an inner membrane: it is the membrane the tip
        // presses on, not tissue the tip cuts.)
        let denting = st.sheathed && self.state.denting.is_some();
        let due = has_tip
            && !st.edited
            && moved > self.params.refresh
            && (st.advancing || !st.sheathed)
            && !denting;
        if !due {
            return Ok(());
        }
        // The refreshed Tip node keeps the load it carried: its friction state and, with
        // the per-length model, the tissue's velocity and the material at the tip, so the
        // load ahead of the tip is carried on, not released.
        let known = st.known.take();
        let (state, v, placement) = self.tip_load(known.as_deref(), st.tip)?;
        st.edited = true;
        let v = if st.per_length { v } else { v_tip };
        let sd = seeds(&self.state.nodes);
        self.remove().map_err(|e| self.edit(e))?;
        self.add_placed(
            NodeRole::Tip,
            st.tip,
            now.length(),
            &sd,
            v,
            state,
            placement,
        )
        .map_err(|e| self.edit(e))?;
        self.state.tip_placed = st.tip.to_array();
        self.state.edit_refresh = true;
        st.pos.pop();
        st.pos.push(st.tip);
        // The nodes below keep the velocities read at the start of the step, and the new
        // Tip node has the one just written (the settle re-places it with the same), so
        // `constrain` need not read them back (one readback fewer a refresh on a GPU).
        st.known = known.map(|mut k| {
            k.pop();
            k.push(vec4(v, 0.0));
            k
        });
        Ok(())
    }

    /// The far side: the tip leaving the body through a surface triangle this step
    /// (`query`/`corners`: the candidates read before any edit).
    fn far_side(
        &mut self,
        st: &mut InsideStep,
        now: &Needle,
        v_tip: DVec3,
        prev_tip: DVec3,
        query: Option<&CrossingQuery>,
        corners: &[Vec4],
    ) -> Result<(), SimulationError> {
        let hit = match (st.edited, query) {
            (true, _) => self.surface_crossing(prev_tip, st.tip, false)?,
            (false, Some(q)) => self
                .state
                .surface
                .crossing_at(q, corners)
                .map(|(id, p)| (id, DVec3::from(p))),
            (false, None) => None,
        };
        let Some((id, point)) = hit else {
            return Ok(());
        };
        st.known = None;
        if self
            .state
            .nodes
            .last()
            .is_some_and(|n| n.role == NodeRole::Tip)
        {
            self.remove().map_err(|e| self.edit(e))?;
            st.pos.pop();
        }
        self.pin_at_surface(NodeRole::Exit, id, point, now, v_tip)?;
        st.pos.push(point);
        self.state.phase = Passage::ExitTouching;
        Ok(())
    }

    /// After the edits: the new nodes take the shaft's loads (`field`, from before the
    /// edits) and are settled; what the needle nodes' positions (and, without edits,
    /// velocities) are now is kept, so that `constrain` need not read them back again.
    fn finish_inside(
        &mut self,
        st: InsideStep,
        field: &FrictionField,
        now: &Needle,
    ) -> Result<(), SimulationError> {
        if st.edited && self.sheathed() {
            // Back in its own track, the Tip node put on again starts without friction or
            // normal load (settled where the tissue pushes it neither way) and the nodes
            // behind keep theirs: moved by length at once, a Shaft node
            // kept the tissue's pull of its whole former length against the friction of
            // a part of it and slid (0.45 m/s, the force rang at about 280 Hz for 20 ms
            // on a liver re-insertion). What a node now carries above its shorter
            // length's limit is let go over the handover time (`NeedleNode::carried`),
            // and the Tip node's own friction builds up through the sheath as it slides.
            let kept: Vec<(f64, f64)> = match st.retracked_tip {
                true => self
                    .state
                    .nodes
                    .iter()
                    .map(|n| (n.axial, n.circumferential))
                    .collect(),
                false => Vec::new(),
            };
            self.reassign_friction(field, &st.pos, now);
            if st.retracked_tip && kept.len() == self.state.nodes.len() {
                let m = self.state.nodes.len();
                for (n, (a, c)) in self.state.nodes[..m - 1].iter_mut().zip(kept) {
                    (n.axial, n.circumferential) = (a, c);
                }
                let tip = &mut self.state.nodes[m - 1];
                (tip.axial, tip.circumferential, tip.normal) = (0.0, 0.0, [0.0; 3]);
            }
            // The new nodes are placed in equilibrium.
            self.settle(self.low_water, now, &st.pos)?;
        }
        self.state.positions = st.pos.iter().map(|x| vec4(*x, 0.0)).collect();
        self.state.read_velocities = st.known.unwrap_or_default();
        Ok(())
    }
}
