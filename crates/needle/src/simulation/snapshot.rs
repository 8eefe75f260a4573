//! Checkpoints of a running simulation ([`crate::checkpoint`]): taking one and restoring
//! one onto a simulation freshly started from the same scene.

use super::Simulation;
use crate::checkpoint::{BackendSnapshot, Checkpoint, CheckpointError, SimSnapshot};
use crate::SimulationError;
use needlesim_core::{NodeField, SimError};
use std::path::PathBuf;

impl Simulation {
    /// The whole state as a [`Checkpoint`] (it reads every node and shape array back from
    /// the backend). Attach the scene's text ([`Checkpoint::scene`]) to make the file
    /// enough on its own.
    pub fn checkpoint(&mut self) -> Result<Checkpoint, SimulationError> {
        let b = self.backend.as_mut();
        let cap = b.capacity();
        let mut field = |f| -> Result<Vec<[f32; 4]>, SimError> {
            let mut out = vec![[0.0f32; 4]; cap];
            b.read(f, 0..cap, &mut out)?;
            Ok(out)
        };
        let (positions, velocities, forces, position_remainders) = (
            // As stored (in the tissue's frame), so that a body far from the origin
            // resumes bit for bit too.
            field(NodeField::StoredPosition)?,
            field(NodeField::Velocity)?,
            field(NodeField::Force)?,
            field(NodeField::StoredRemainder)?,
        );
        let mut shape = Vec::new();
        for (name, bytes) in self.editor.shape().bytes() {
            let mut out = vec![0u8; bytes.len()];
            b.read_shape_bytes(name, 0, &mut out)?;
            shape.push(out);
        }
        Ok(Checkpoint {
            scene: None,
            fingerprint: self.fingerprint.clone(),
            backend: BackendSnapshot {
                n_active: b.n_active(),
                steps: b.steps_taken(),
                positions,
                velocities,
                forces,
                position_remainders,
                shape,
            },
            editor: self.editor.snapshot(),
            sim: SimSnapshot {
                state: self.state.clone(),
                scripted: self.script.is_some(),
                time: self.stepper.time(),
                steps: self.stepper.steps(),
            },
            source: PathBuf::new(),
        })
    }

    /// Puts a checkpoint's state into this freshly started simulation.
    pub(super) fn restore(&mut self, c: Checkpoint) -> Result<(), SimulationError> {
        let corrupt = |reason: String| CheckpointError::Corrupt {
            path: c.source.clone(),
            reason,
        };
        for (part, hash) in &c.fingerprint {
            let same = self.fingerprint.iter().any(|(p, h)| p == part && h == hash);
            if !same {
                return Err(CheckpointError::SceneMismatch { part: part.clone() }.into());
            }
        }
        if c.fingerprint.len() != self.fingerprint.len() {
            return Err(corrupt("the scene fingerprint has another length".into()).into());
        }
        let cap = self.backend.capacity();
        let bs = c.backend;
        if [
            &bs.positions,
            &bs.velocities,
            &bs.forces,
            &bs.position_remainders,
        ]
        .iter()
        .any(|a| a.len() != cap)
            || bs.n_active > cap
        {
            return Err(corrupt(format!("node arrays do not fit {cap} node slots")).into());
        }
        let sim = c.sim;
        if sim
            .state
            .nodes
            .iter()
            .any(|n| n.index as usize >= bs.n_active)
            || !sim.state.surface.fits(bs.n_active)
        {
            return Err(corrupt("needle nodes or triangles name inactive nodes".into()).into());
        }
        self.editor
            .restore(c.editor)
            .map_err(|what| corrupt(format!("the {what} do not fit this tissue")))?;
        if self.editor.n_active() != bs.n_active {
            return Err(
                corrupt("the editor and the backend count other active nodes".into()).into(),
            );
        }
        let b = self.backend.as_mut();
        b.write(NodeField::StoredPosition, 0, &bs.positions)?;
        b.write(NodeField::Velocity, 0, &bs.velocities)?;
        b.write(NodeField::Force, 0, &bs.forces)?;
        b.write(NodeField::StoredRemainder, 0, &bs.position_remainders)?;
        let nb = self.editor.neighbours();
        b.write_neighbour_rows(0, &nb.index, &nb.weight)?;
        let names: Vec<_> = self.editor.shape().bytes().iter().map(|a| a.0).collect();
        if names.len() != bs.shape.len() {
            return Err(corrupt("shape arrays differ".into()).into());
        }
        for (name, bytes) in names.into_iter().zip(&bs.shape) {
            b.write_shape_bytes(name, 0, bytes)?;
        }
        b.set_n_active(bs.n_active)?;
        b.set_steps_taken(bs.steps);
        if !sim.scripted {
            self.script = None;
        }
        self.state = sim.state;
        self.stepper.set_clock(sim.time, sim.steps);
        Ok(())
    }
}
