//! The step's side of [`crate::handover`]: the elastic forces before the step's edits
//! (recorded before each removal; for additions, evaluated with their rows put back), the
//! difference once the edits are done, and the share added after each force evaluation.

use super::Simulation;
use crate::handover::{refresh_handover_time, Handover, HANDOVER_TIME};
use crate::node_editor::EditError;
use crate::SimulationError;
use needlesim_core::{NodeField, NodeSelection, SimError, Vec4};

impl Simulation {
    /// Notes that the step edits the node stack now: the editor's log is at its lowest
    /// so far this step.
    pub(super) fn mark_edit(&mut self) {
        let n = self.editor.n_added();
        self.state.edit_low = Some(self.state.edit_low.map_or(n, |l| l.min(n)));
    }

    /// Before removing the last added node: the elastic forces of the nodes the removal
    /// can change, for those not yet recorded this step (per-length model only).
    pub(super) fn capture_before_removal(&mut self) -> Result<(), EditError> {
        self.capture_before_removal_with(&[], &mut [])
    }

    /// [`Simulation::capture_before_removal`], reading `extra` (positions or velocities,
    /// which it leaves as they are) into `outs` with the forces: one readback on a GPU
    /// where there were two. With nothing to record, `extra` is read alone.
    pub(super) fn capture_before_removal_with(
        &mut self,
        extra: &[(NodeField, NodeSelection<'_>)],
        outs: &mut [&mut [Vec4]],
    ) -> Result<(), EditError> {
        self.mark_edit();
        let read_alone = |sim: &mut Self, outs: &mut [&mut [Vec4]]| match extra.is_empty() {
            true => Ok(()),
            false => sim.backend.read_many(extra, outs).map_err(EditError::from),
        };
        if !self.sheathed() {
            return read_alone(self, outs);
        }
        // This step's additions (the node about to go may be one of them: a Tip node
        // refreshed and then replaced by the Exit node) are put back for the evaluation,
        // so that what is recorded is the force at the start of the step; their slots
        // are left out.
        let since = self.state.edit_low.unwrap_or(self.editor.n_added());
        let kept = self.editor.n_mesh() + since;
        let recorded = &self.state.before_edits;
        let fresh: Vec<u32> = self
            .editor
            .removal_reach()
            .into_iter()
            .filter(|&j| (j as usize) < kept && recorded.binary_search_by_key(&j, |e| e.0).is_err())
            .collect();
        if fresh.is_empty() {
            return read_alone(self, outs);
        }
        let f =
            self.editor
                .forces_before_with(self.backend.as_mut(), since, &fresh, extra, outs)?;
        let before = &mut self.state.before_edits;
        before.extend(fresh.into_iter().zip(f));
        before.sort_unstable_by_key(|e| e.0);
        Ok(())
    }

    /// After the step's edits: the change of the elastic forces they made, on the nodes
    /// that kept their slot, starts to be handed over (per-length model only).
    pub(super) fn hand_over_edits(&mut self) -> Result<(), SimulationError> {
        let Some(since) = self.state.edit_low.take() else {
            return Ok(());
        };
        let mut before = std::mem::take(&mut self.state.before_edits);
        let shaft = std::mem::take(&mut self.state.edit_shaft);
        let refresh = std::mem::take(&mut self.state.edit_refresh);
        if !self.sheathed() {
            return Ok(());
        }
        // A Shaft, Surface or Exit node event hands over in `HANDOVER_TIME`; a step that
        // only refreshed the Tip node within the time the tip takes at its speed to the
        // next refresh, so that refreshes never pile up (module docs); neither cuts short
        // what is left of a handover running. The tip element's share hands its change
        // over in the same time after every edit, those that hand no elastic change over
        // included (a Tip node the tissue carried ahead lifted while advancing, the Tip
        // node put on: both change the front node; [`crate::sheath::FreeFade`]).
        let own = match shaft {
            true => HANDOVER_TIME,
            false => {
                refresh_handover_time(self.params.refresh, self.state.advance, self.stepper.dt())
            }
        };
        self.state.edit_front = Some(own);
        if !(shaft || refresh) {
            return Ok(());
        }
        // Slots from the first one this step's additions took (or the removals freed) on
        // hold other nodes than before.
        let kept = self.editor.n_mesh() + since;
        before.retain(|e| (e.0 as usize) < kept);
        let added: Vec<u32> = self
            .editor
            .reach_since(since)
            .into_iter()
            .filter(|&j| (j as usize) < kept && before.binary_search_by_key(&j, |e| e.0).is_err())
            .collect();
        if !added.is_empty() {
            let f = self
                .editor
                .forces_before(self.backend.as_mut(), since, &added)
                .map_err(|e| self.edit(e))?;
            before.extend(added.into_iter().zip(f));
            before.sort_unstable_by_key(|e| e.0);
        }
        if before.is_empty() {
            return Ok(());
        }
        let nodes: Vec<u32> = before.iter().map(|e| e.0).collect();
        let after = self
            .editor
            .forces_before(self.backend.as_mut(), usize::MAX, &nodes)
            .map_err(|e| self.edit(e))?;
        let change: Vec<[f64; 3]> = before
            .iter()
            .zip(&after)
            .map(|((_, b), a)| [0, 1, 2].map(|c| b[c] as f64 - a[c] as f64))
            .collect();
        let now = self.stepper.time();
        if let Some(h) = self.state.handover.as_mut() {
            h.keep_below(kept);
        }
        let left = self
            .state
            .handover
            .as_ref()
            .map_or(0.0, |h| h.started + h.duration - now);
        self.state.handover = Some(Handover::start(
            self.state.handover.as_ref(),
            now,
            &nodes,
            &change,
            own.max(left),
        ));
        Ok(())
    }

    /// What is left of the handover at this step (and drops it once done): its nodes
    /// (sorted) and the forces to add to theirs.
    pub(super) fn handover_now(&mut self) -> Option<(Vec<u32>, Vec<[f64; 3]>)> {
        let now = self.stepper.time();
        let h = self.state.handover.as_mut()?;
        h.keep_below(self.backend.n_active());
        if h.done(now) || h.nodes.is_empty() {
            self.state.handover = None;
            return None;
        }
        Some((h.nodes.clone(), h.at(now)))
    }

    /// After the force evaluation with no needle node in the tissue (the needle's own
    /// force pass folds the handover into its read, [`Simulation::apply_friction`]):
    /// adds what is left of the handover to the elastic forces.
    pub(super) fn apply_handover(&mut self) -> Result<(), SimError> {
        let Some((nodes, add)) = self.handover_now() else {
            return Ok(());
        };
        let mut f = vec![[0.0f32; 4]; nodes.len()];
        self.backend.read_nodes(NodeField::Force, &nodes, &mut f)?;
        add_forces(&mut f, &add);
        needlesim_core::boundary::write_scattered(
            self.backend.as_mut(),
            NodeField::Force,
            &nodes,
            &f,
        )
    }
}

/// `f[k] += add[k]` (xyz).
pub(super) fn add_forces(f: &mut [[f32; 4]], add: &[[f64; 3]]) {
    for (f, a) in f.iter_mut().zip(add) {
        for (x, y) in f.iter_mut().zip(a) {
            *x = (*x as f64 + y) as f32;
        }
    }
}
