//! The needle insertion simulation (paper section 5.4): a tissue backend stepped by the
//! core [`Stepper`], the needle, and what one step of the needle does around the tissue's
//! force evaluation.
//!
//! One step ([`Simulation::step`]):
//! 1. the needle moves to its pose at `t + dt` (script or [`Simulation::set_pose`]);
//! 2. the puncture state machine ([`insertion`](self)): Outside tests the segment swept by
//!    the tip against the entering side of the surface; Touching compares the mean cone
//!    angle (or the force) with the thresholds; Inside adds or removes needle nodes,
//!    refreshes the Tip node and tests the tip against the leaving side of the surface;
//! 3. constraints: a sticking node (and the pinned Surface or Exit node while Touching)
//!    moves rigidly with the needle; a slipping node is projected onto the shaft and keeps
//!    only its axial velocity relative to the needle;
//! 4. elastic forces; only the needle nodes' forces are read back;
//! 5. friction ([`crate::friction`]) and the needle force: the elastic force of a pinned
//!    node, and the normal force minus the friction (and cutting) force of every other;
//! 6. loads, integration, held sets and the divergence guard ([`Stepper::finish_step`]).
//!
//! Only needle node rows cross between host and device each step (plus, near the surface,
//! the corners of the few candidate triangles).
//!
//! # One readback
//!
//! With the tip inside, a step without node edits reads back once
//! ([`Backend::readbacks`], issue 46): the needle nodes' forces after the force evaluation,
//! with the positions of the mesh nodes around the crack front and of the contact patch
//! (and the patch's forces), in one [`Backend::read_many`]. The friction needs this step's
//! forces and the integration needs the friction, so that read cannot go. The other one,
//! the needle nodes' positions and velocities at the start of the step, is not needed:
//! `constrain` writes every needle node's position and velocity, and `apply_friction` its
//! force, each step, and nothing else touches them before the integration, so the host
//! integrates them itself (`Simulation::integrate_written`: the backend's
//! [`integrate_node`] in the backend's position frame, from the zero remainder a position
//! write leaves). On the CPU that is the backend's result bit for bit (tested: a run that
//! reads every step back records the same history); a GPU's own integration of the same
//! values may round differently, and `constrain` overwrites it with the host's next step.
//! The host's copy serves one step and only while the needle nodes are those it
//! integrated; node edits, mutable access to the backend ([`Simulation::backend`]) and a
//! restored checkpoint read the nodes back instead. Steps that add, remove or refresh
//! needle nodes read more, as do the divergence guard, the Touching state (the split
//! triangle's corners) and, near the far surface, the far-side test's corners. Without a
//! needle, steps go to the backend in batches between divergence checks
//! ([`Stepper::run`]).
//!
//! Needle nodes (a stack, removed in reverse order of addition): the Surface node where
//! the tip first touched; Shaft nodes, one per spacing h of insertion; the Tip node at the
//! tip; the Exit node where the tip reached the far surface. The margins that add and
//! remove them are [`insertion::shaft_edit`](self); they keep any two needle nodes at least
//! h / 4 apart, but for a Shaft node the tissue crowds closer on the way out (at least
//! h / 10 apart while it hands its length over).
//!
//! The far side: when the tip leaves the body through its surface, the Tip node is
//! replaced by an Exit node pinned to the tip (state Touching: the surface dents outwards)
//! until the same puncture rule fires; then the tip is Outside past the body while the
//! shaft nodes stay on the needle. Pulled back past the Exit node, the tip re-enters
//! (Inside) through its hole. A tip that leaves the body again elsewhere after exiting is
//! not detected (one entry and one exit per needle path).

mod constraint;
mod handover;
mod insertion;
mod inside;
mod needle_force;
mod prepare;
mod settle;
mod shaft_loads;
mod snapshot;

pub use insertion::MAX_STEP_SPACINGS;
pub use prepare::Prepared;

use crate::config::Membrane;
use crate::friction::{FrictionModel, PerLengthFriction};
use crate::material_point::AffineFit;
use crate::needle::Needle;
use crate::node_editor::{EditError, NodeEditor};
use crate::nodes::{NeedleForce, NeedleNode, NeedleSample};
use crate::puncture::{PunctureState, Thresholds};
use crate::script::PoseScript;
use crate::state::{Integrated, NeedleState, Passage};
use crate::SimulationError;
use glam::DVec3;
use needlesim_core::boundary::{Boundary, Reaction};
use needlesim_core::integrator::integrate_node;
use needlesim_core::math::Vec4;
use needlesim_core::{Backend, NodeField, SimError, Stepper};

/// The needle's parameters in one tissue region, resolved from the scene.
#[derive(Debug, Clone, Copy)]
struct RegionParams {
    friction: FrictionModel,
    /// Grip of the per-length model, N/m.
    grip: f64,
    /// Shear stiffness per unit length of the sheath (per-length model), N/m^2.
    shear_stiffness: f64,
    /// Viscous coefficient per unit length of the sheath (per-length model), N s/m^2.
    shear_viscosity: f64,
    /// Young's modulus (Pa) and Poisson ratio the needle's contacts use.
    modulus: (f64, f64),
    cutting: f64,
    membrane: Membrane,
    /// Radius of the surface carrying the tip's load before the membrane gives, m.
    contact_radius: f64,
}

/// The needle parameters a step uses, resolved from the scene.
#[derive(Debug, Clone)]
struct NeedleParams {
    /// The `[needle]` table's friction model (per-length or the paper's, for all regions).
    friction: FrictionModel,
    /// Per region (region 0 first): friction, grip, cutting force and membrane.
    regions: Vec<RegionParams>,
    thresholds: Thresholds,
    puncture_force: Option<f64>,
    /// Tip travel between two Tip node refreshes, m.
    refresh: f64,
    /// Needle radius, m.
    radius: f64,
    /// Length of the needle's point: a membrane that gave releases its load, and the
    /// cutting force builds up, over it, m.
    point_length: f64,
    /// Most time a membrane that gave takes to let go of its load, s.
    tear_time: f64,
    /// The tissue's viscoelastic relaxation (empty: elastic): the grip of the slit on
    /// the shaft relaxes with the age of the cut ([`crate::friction::per_length`]).
    relaxation: needlesim_core::models::viscoelastic::Prony,
}

impl NeedleParams {
    fn per_length(&self) -> Option<PerLengthFriction> {
        match self.friction {
            FrictionModel::PerLength(p) => Some(p),
            FrictionModel::Paper(_) => None,
        }
    }
}

/// Needle insertion into a tissue on any backend.
pub struct Simulation {
    backend: Box<dyn Backend>,
    stepper: Stepper,
    editor: NodeEditor,
    script: Option<PoseScript>,
    params: NeedleParams,
    /// Node-adding threshold h, m.
    spacing: f64,
    /// Rest positions of the mesh nodes, m.
    rest: Vec<[f64; 3]>,
    state: NeedleState,
    fingerprint: Vec<(String, u32)>,
    /// Region of every mesh node.
    node_region: Vec<u16>,
    region_names: Vec<String>,
    /// Inverse mass of a needle node in each region, 1/kg.
    region_inv_mass: Vec<f32>,
    /// The fewest needle nodes the stack held during this step's edits (the nodes below
    /// it kept their place and their friction).
    low_water: usize,
}

/// What [`Simulation::read_needle`] reads.
struct NeedleRead {
    /// Needle node positions, oldest node first.
    positions: Vec<DVec3>,
    /// Their velocities.
    velocities: Vec<Vec4>,
    /// Positions of the extra nodes asked for.
    extra: Vec<Vec4>,
}

/// The point at axial coordinate `s` from the needle's base.
fn at(n: &Needle, s: f64) -> DVec3 {
    DVec3::from(n.base()) + DVec3::from(n.direction()) * s
}

fn xyz(p: [f32; 4]) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

fn vec4(p: DVec3, w: f32) -> [f32; 4] {
    [p.x as f32, p.y as f32, p.z as f32, w]
}

impl Simulation {
    /// The backend. Mutable access may change the needle nodes' state, so the next step
    /// reads it back instead of taking the host's integration of it (module docs, "One
    /// readback"); use [`Simulation::readbacks`] to count readbacks.
    pub fn backend(&mut self) -> &mut dyn Backend {
        self.state.integrated = None;
        self.backend.as_mut()
    }

    /// The backend's blocking readbacks so far ([`Backend::readbacks`]).
    pub fn readbacks(&self) -> u64 {
        self.backend.readbacks()
    }

    /// The node editor (neighbour rows and shape information as the backend has them).
    pub fn editor(&self) -> &NodeEditor {
        &self.editor
    }

    /// The needle, if the scene has one.
    pub fn needle(&self) -> Option<&Needle> {
        self.state.needle.as_ref()
    }

    /// Puts the needle at a pose for the next step (a haptic device or a planner). The
    /// scene's script, if any, is dropped.
    pub fn set_pose(&mut self, base: [f64; 3], direction: [f64; 3]) -> Result<(), SimulationError> {
        let n = self
            .state
            .needle
            .as_mut()
            .ok_or(SimulationError::NoNeedle)?;
        n.set_pose(base, direction)?;
        self.script = None;
        Ok(())
    }

    /// Turns the needle about its own axis to `roll` (radians, right-handed about its
    /// direction) for the next step: a haptic device's or a robot's spin. The change over
    /// the step is the circumferential sliding the shaft's friction sees
    /// ([`crate::sheath`]); the scene's script, if any, is dropped. A roll that is not
    /// finite is an error ([`crate::NeedleError::BadRoll`]).
    pub fn set_roll(&mut self, roll: f64) -> Result<(), SimulationError> {
        let n = self
            .state
            .needle
            .as_mut()
            .ok_or(SimulationError::NoNeedle)?;
        n.set_roll(roll)?;
        self.script = None;
        Ok(())
    }

    /// The puncture state: where the tip is (Outside also past the far surface, with the
    /// shaft still in the tissue: see [`Simulation::needle_nodes`]).
    pub fn state(&self) -> PunctureState {
        match (self.state.phase, self.state.denting) {
            // Denting an inner membrane: pressing on it, not through.
            (Passage::Inside, Some(_)) => PunctureState::Touching,
            _ => self.state.puncture_state(),
        }
    }

    /// Whether the tip has left the body through its far surface (state Outside with the
    /// shaft inside) or is denting it from inside (Touching).
    pub fn through_far_side(&self) -> bool {
        matches!(self.state.phase, Passage::ExitTouching | Passage::Exited)
    }

    /// The grip per unit length of the per-length friction model in region 0, N/m (0 for
    /// the paper's); [`Simulation::region_grip`] for the others.
    pub fn grip(&self) -> f64 {
        self.params.regions[0].grip
    }

    /// The grip per unit length in region `region`, N/m (`None` for an unknown region).
    pub fn region_grip(&self, region: u16) -> Option<f64> {
        self.params.regions.get(region as usize).map(|l| l.grip)
    }

    /// The region of every mesh node (an index into [`Simulation::region_names`]).
    pub fn node_regions(&self) -> &[u16] {
        &self.node_region
    }

    /// Names of the tissue regions, region 0 (`"tissue"`, nodes in no `[[region]]`) first.
    pub fn region_names(&self) -> &[String] {
        &self.region_names
    }

    /// The region the tip is in: the last membrane the crack front punctured, or where
    /// the tip is pulled back to; `None` while the tip is not inside.
    pub fn tip_region(&self) -> Option<u16> {
        match self.state.phase {
            Passage::Inside => self.state.region,
            _ => None,
        }
    }

    /// The region whose membrane the tip is denting, not yet punctured.
    pub fn denting(&self) -> Option<u16> {
        match self.state.phase {
            Passage::Inside => self.state.denting,
            _ => None,
        }
    }

    /// Depth of the tip in the undeformed tissue in the last step, m: the rest position of
    /// the tissue at the tip ([`crate::material_point`]) past the Surface node's, along the
    /// needle. 0 while denting the entry surface; while cutting it grows only with the
    /// tissue cut, not with the tissue pushed ahead or dragged along, so an inner
    /// membrane is dented and punctured at its own depth. `None` while the tip is not in
    /// the tissue (and past the far surface).
    pub fn tissue_depth(&self) -> Option<f64> {
        self.state.tissue_depth
    }

    /// The needle nodes, oldest first.
    pub fn needle_nodes(&self) -> &[NeedleNode] {
        &self.state.nodes
    }

    /// Surface triangles (node indices), with the split around the Surface node.
    pub fn triangles(&self) -> &[[u32; 3]] {
        self.state.surface.triangles()
    }

    /// The force on the needle in the last step.
    pub fn needle_force(&self) -> NeedleForce {
        self.state.force
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.stepper.time()
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.stepper.steps()
    }

    /// Time step, s.
    pub fn dt(&self) -> f64 {
        self.stepper.dt()
    }

    /// Node-adding threshold h, m.
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Duration of the needle's script (0 without one).
    pub fn script_duration(&self) -> f64 {
        self.script.as_ref().map_or(0.0, |s| s.duration())
    }

    /// Every step's record so far (the last [`Simulation::set_history_limit`] steps when
    /// bounded).
    pub fn history(&self) -> &[NeedleSample] {
        let keep = self.state.history_limit.unwrap_or(usize::MAX);
        let h = &self.state.history;
        &h[h.len().saturating_sub(keep)..]
    }

    /// Keeps at most the last `limit` steps in the history (`None`, the default, keeps
    /// every step: 160 bytes a step, the size of a [`NeedleSample`]). Samples past the
    /// limit are dropped oldest first; [`Simulation::take_history`] streams them out
    /// instead.
    pub fn set_history_limit(&mut self, limit: Option<usize>) {
        self.state.history_limit = limit;
        self.trim_history();
    }

    /// Most steps the history keeps (`None`: all).
    pub fn history_limit(&self) -> Option<usize> {
        self.state.history_limit
    }

    /// Returns the history and clears it (stream it to disk in a long run).
    pub fn take_history(&mut self) -> Vec<NeedleSample> {
        let keep = self.history().len();
        let mut h = std::mem::take(&mut self.state.history);
        h.drain(..h.len() - keep);
        h
    }

    /// Drops the oldest samples past the limit, in batches (amortised O(1) a step).
    fn trim_history(&mut self) {
        let h = &mut self.state.history;
        if let Some(limit) = self.state.history_limit {
            if h.len() > limit.saturating_mul(2).max(limit + 1024) {
                let drop = h.len() - limit;
                h.drain(..drop);
            }
        }
    }

    /// Whether [`Simulation::step`] appends to the history (default true).
    pub fn set_record(&mut self, on: bool) {
        self.state.record = on;
    }

    /// The point where the tip first touched the surface, if it has.
    pub fn entry_point(&self) -> Option<[f64; 3]> {
        self.state.entry
    }

    /// Depth of the tip past the first contact point along the needle, m: negative
    /// before the contact. A run that has not touched (or never touches) measures it from
    /// where the needle's axis at its first recorded step meets the tissue's rest
    /// surface, so a sweep's variants agree whether or not they reach the tissue; a needle
    /// aimed past the tissue measures it from its first recorded tip.
    pub fn depth_of(&self, tip: [f64; 3], direction: [f64; 3]) -> f64 {
        let origin = self.state.entry.or(self.state.depth_origin).unwrap_or(tip);
        (DVec3::from(tip) - DVec3::from(origin)).dot(DVec3::from(direction))
    }

    /// Where the line from `tip` along `direction` first enters the tissue's rest
    /// surface (the depth origin before a contact), or `tip` when it misses. Once per run.
    fn aim_point(&self, tip: [f64; 3], direction: [f64; 3]) -> [f64; 3] {
        let rest = |v: u32| self.rest_of(v);
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &self.rest {
            lo = lo.min(DVec3::from(*p));
            hi = hi.max(DVec3::from(*p));
        }
        let p0 = DVec3::from(tip);
        let reach = p0.distance(0.5 * (lo + hi)) + lo.distance(hi);
        if !reach.is_finite() {
            return tip;
        }
        let p1 = p0 + DVec3::from(direction) * reach;
        let triangles = self.state.surface.triangles();
        crate::surface_query::first_crossing(
            tip,
            p1.to_array(),
            0..triangles.len() as u32,
            crate::surface_query::Side::Entering,
            |id| triangles[id as usize].map(rest),
        )
        .map_or(tip, |h| h.point)
    }

    /// Rest positions of the active nodes (mesh nodes, then needle nodes), m.
    pub fn rest_positions(&self) -> Vec<[f64; 3]> {
        let mut r = self.rest.clone();
        r.extend((r.len()..self.editor.n_active()).map(|i| self.rest_of(i as u32)));
        r
    }

    /// Node indices of the needle nodes.
    pub fn needle_node_indices(&self) -> Vec<u32> {
        self.state.nodes.iter().map(|n| n.index).collect()
    }

    /// Runs `n` steps (without a needle, in batches between divergence checks: the GPU
    /// backend queues each batch without waiting).
    pub fn step_n(&mut self, n: u64) -> Result<(), SimulationError> {
        if self.state.needle.is_none() {
            return Ok(self.stepper.run(self.backend.as_mut(), n)?);
        }
        for _ in 0..n {
            self.step()?;
        }
        Ok(())
    }

    /// The force each held set's supports (`[[fixed]]`, `[[prescribed]]`) exert on the
    /// body, from the forces of the last step ([`Boundary::reactions`]).
    pub fn reactions(&mut self) -> Result<Vec<Reaction>, SimulationError> {
        Ok(self.stepper.reactions(self.backend.as_mut())?)
    }

    /// The held sets and loads.
    pub fn boundary(&self) -> &Boundary {
        self.stepper.boundary()
    }

    /// The divergence guard: an error naming the step and node if a position or velocity
    /// is not finite or a free node is faster than `physics.max_speed`. Run every
    /// `physics.check_every` steps by [`Simulation::step`] and [`Simulation::step_n`].
    pub fn check(&mut self) -> Result<(), SimulationError> {
        Ok(self.stepper.check(self.backend.as_mut())?)
    }

    /// [`Simulation::check`] on positions and velocities of the active nodes already read
    /// back (an output frame).
    pub fn check_read(
        &self,
        positions: &[[f32; 4]],
        velocities: &[[f32; 4]],
    ) -> Result<(), SimulationError> {
        Ok(self
            .stepper
            .check_read(self.backend.steps_taken(), positions, velocities)?)
    }

    /// Runs one step. A needle motion the contact cannot follow
    /// ([`SimulationError::TooFast`]) is refused before anything changes: the needle
    /// stays at its last pose.
    pub fn step(&mut self) -> Result<(), SimulationError> {
        let (Some(prev), Some(_)) = (self.state.prev, self.state.needle) else {
            return self.step_n(1);
        };
        if let Some(s) = &self.script {
            self.state.needle = Some(s.pose_at(self.stepper.time() + self.stepper.dt()));
        }
        // `prev` is the pose of the last step: the tip sweeps from there even when the
        // caller moved the needle with `set_pose` in between.
        let now = self.state.needle.expect("needle present");
        self.state.prev = Some(now);
        // Nothing of an earlier step's edits that ended in an error is carried over.
        self.state.written = None;
        self.state.before_edits.clear();
        self.state.edit_low = None;
        self.state.edit_shaft = false;
        self.state.edit_refresh = false;
        self.state.edit_front = None;
        if let Err(e) = self.contact(&prev, &now) {
            // A motion refused as too fast was refused before the contact changed
            // anything: the step leaves no trace and the needle stays at its last pose
            // (a second `step` no longer made the refused jump, and setting the pose
            // back to where the needle was is no motion).
            if matches!(e, SimulationError::TooFast { .. }) {
                self.state.prev = Some(prev);
                self.state.needle = Some(prev);
            }
            return Err(e);
        }
        self.hand_over_edits()?;
        self.constrain(&prev, &now)?;
        self.backend.compute_forces();
        if self.state.nodes.is_empty() {
            self.apply_handover()?;
        }
        self.apply_friction(&prev, &now)?;
        // What the host integrated last step serves this step only (an error below
        // leaves none behind).
        self.state.integrated = None;
        self.stepper.finish_step(self.backend.as_mut())?;
        self.integrate_written()?;
        if self.state.record {
            if self.state.depth_origin.is_none() {
                self.state.depth_origin = Some(self.aim_point(now.tip(), now.direction()));
            }
            let sample = NeedleSample {
                step: self.stepper.steps(),
                time: self.stepper.time(),
                tip: now.tip(),
                direction: now.direction(),
                force: self.state.force,
                state: self.state(),
                active_nodes: self.backend.n_active(),
                needle_nodes: self.state.nodes.len(),
                region: self.tip_region(),
                tissue_depth: self.state.tissue_depth,
            };
            self.state.history.push(sample);
            self.trim_history();
        }
        Ok(())
    }

    /// Velocity of the needle point at axial coordinate `s` over the last step.
    fn needle_velocity(&self, prev: &Needle, now: &Needle, s: f64) -> DVec3 {
        (at(now, s) - at(prev, s)) / self.stepper.dt()
    }

    /// The host's integration of what this step wrote to the needle nodes
    /// ([`Simulation::apply_friction`]): the same update as the backend's
    /// ([`integrate_node`], in the backend's position frame, from the remainder 0 a
    /// position write leaves), so the next step need not read the nodes back. The result
    /// is written back (stored positions and remainders, velocities: an upload, no
    /// readback), so the backend holds what the host does: bit for bit what the CPU
    /// backend computed anyway, and on a GPU, which may round its own integration
    /// differently, the same state whether or not anyone reads it between steps.
    fn integrate_written(&mut self) -> Result<(), SimError> {
        let Some(w) = self.state.written.take() else {
            return Ok(());
        };
        let frame = self.backend.position_frame();
        let params = *self.stepper.params();
        let (mut stored, mut velocities) = (w.positions, w.velocities);
        let mut remainders = vec![[0.0f32; 4]; stored.len()];
        frame.slice_to_frame(&mut stored);
        for (((x, v), r), f) in stored
            .iter_mut()
            .zip(&mut velocities)
            .zip(&mut remainders)
            .zip(&w.forces)
        {
            integrate_node(x, v, r, *f, &params);
        }
        if let Some(&first) = w.nodes.first() {
            let first = first as usize;
            self.backend
                .write(NodeField::StoredPosition, first, &stored)?;
            self.backend
                .write(NodeField::StoredRemainder, first, &remainders)?;
            self.backend
                .write(NodeField::Velocity, first, &velocities)?;
        }
        let mut positions = stored;
        frame.positions_to_world(&mut positions);
        self.state.integrated = Some(Integrated {
            nodes: w.nodes,
            positions,
            velocities,
        });
        Ok(())
    }

    /// The needle nodes' positions and velocities after the last step's integration, from
    /// the host's own integration of it ([`Simulation::integrate_written`]), once per step
    /// and only while the needle nodes are those it integrated (`None`: read them back).
    fn take_integrated(&mut self) -> Option<(Vec<Vec4>, Vec<Vec4>)> {
        let i = self.state.integrated.take()?;
        let same = i.nodes.len() == self.state.nodes.len()
            && i.nodes
                .iter()
                .zip(&self.state.nodes)
                .all(|(a, n)| *a == n.index);
        same.then_some((i.positions, i.velocities))
    }

    /// Positions and velocities of the needle nodes, and the positions of the nodes
    /// `extra`, in one [`Backend::read_many`] (only `extra` is read when the host
    /// integrated the needle nodes' last step, [`Simulation::take_integrated`]).
    fn read_needle(&mut self, extra: &[u32]) -> Result<NeedleRead, SimError> {
        let n0 = self.editor.n_mesh();
        let m = self.state.nodes.len();
        if let Some((p, v)) = self.take_integrated() {
            let mut e = vec![[0.0f32; 4]; extra.len()];
            if !extra.is_empty() {
                self.backend
                    .read_nodes(NodeField::Position, extra, &mut e)?;
            }
            return Ok(NeedleRead {
                positions: p.into_iter().map(xyz).collect(),
                velocities: v,
                extra: e,
            });
        }
        let (mut p, mut v) = (vec![[0.0f32; 4]; m], vec![[0.0f32; 4]; m]);
        let mut e = vec![[0.0f32; 4]; extra.len()];
        let mut requests = vec![
            (NodeField::Position, (n0..n0 + m).into()),
            (NodeField::Velocity, (n0..n0 + m).into()),
        ];
        let mut outs: Vec<&mut [Vec4]> = vec![&mut p, &mut v];
        if !extra.is_empty() {
            requests.push((NodeField::Position, extra.into()));
            outs.push(&mut e);
        }
        self.backend.read_many(&requests, &mut outs)?;
        Ok(NeedleRead {
            positions: p.into_iter().map(xyz).collect(),
            velocities: v,
            extra: e,
        })
    }

    /// Velocity of needle node `k`: from `known` (the needle nodes' velocities read this
    /// step, while no node was edited since) or read back.
    fn node_velocity(&mut self, k: usize, known: Option<&[Vec4]>) -> Result<DVec3, SimError> {
        if let Some(v) = known.and_then(|v| v.get(k)) {
            return Ok(xyz(*v));
        }
        let i = self.state.nodes[k].index as usize;
        let mut v = [[0.0f32; 4]];
        self.backend.read(NodeField::Velocity, i..i + 1, &mut v)?;
        Ok(xyz(v[0]))
    }

    /// Inverse mass of needle node `n` (its region's density times an interior node's
    /// volume).
    fn inv_mass_of(&self, n: &NeedleNode) -> f32 {
        self.region_inv_mass[n.region as usize]
    }

    /// The region of node `index` just added at `x`: that of the mesh node nearest at
    /// rest to the material point under it ([`Simulation::material_region`]).
    fn region_of_added(&mut self, index: u32, x: DVec3) -> Result<u16, SimError> {
        let nodes = self.mesh_neighbours(index);
        // Its neighbours are among those the addition just read (one readback fewer on
        // a GPU).
        let pos = match self.editor.last_neighbour_positions(&nodes) {
            Some(pos) => pos,
            None => {
                let mut pos = vec![[0.0f32; 4]; nodes.len()];
                self.backend
                    .read_nodes(NodeField::Position, &nodes, &mut pos)?;
                pos
            }
        };
        Ok(self.material_region(x, &nodes, &pos).map_or(0, |(_, r)| r))
    }

    /// The mesh nodes among the live neighbours of node `index`.
    fn mesh_neighbours(&self, index: u32) -> Vec<u32> {
        let n = self.node_region.len();
        self.editor
            .neighbours()
            .live(index as usize)
            .filter(|&(_, j, _)| j < n)
            .map(|(_, j, _)| j as u32)
            .collect()
    }

    /// The affine map from current to rest positions around world point `x`
    /// ([`crate::material_point`]), fitted to the mesh nodes `nodes` at current positions
    /// `pos`; `None` without nodes.
    fn fit_around(&self, x: DVec3, nodes: &[u32], pos: &[Vec4]) -> Option<AffineFit> {
        let pairs: Vec<(DVec3, DVec3)> = nodes
            .iter()
            .zip(pos)
            .map(|(&j, p)| (xyz(*p), DVec3::from(self.rest[j as usize])))
            .collect();
        AffineFit::around(x, &pairs)
    }

    /// The region of rest position `x0`: that of the node among `nodes` nearest to it at
    /// rest (region 0 without nodes).
    fn region_at(&self, x0: DVec3, nodes: &[u32]) -> u16 {
        self.region_near(x0, nodes, None)
    }

    /// [`Simulation::region_at`] with hysteresis: region `keep` stays while one of its
    /// nodes is within `h / 4` of the nearest node's distance, so that a material point
    /// jittering about an interface (midway between node planes) does not flip between
    /// the two regions every step.
    fn region_near(&self, x0: DVec3, nodes: &[u32], keep: Option<u16>) -> u16 {
        let d = |j: u32| DVec3::from(self.rest[j as usize]).distance(x0);
        let nearest = |region: Option<u16>| {
            nodes
                .iter()
                .filter(|&&j| region.is_none_or(|r| self.node_region[j as usize] == r))
                .map(|&j| (d(j), j))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        };
        let Some((best, j)) = nearest(None) else {
            return 0;
        };
        match keep.and_then(|r| nearest(Some(r)).map(|(dk, _)| (r, dk))) {
            Some((r, dk)) if dk <= best + 0.25 * self.spacing => r,
            _ => self.node_region[j as usize],
        }
    }

    /// The material point under world point `x` from the mesh nodes `nodes` at current
    /// positions `pos`, and its region ([`Simulation::region_at`]). `None` without nodes.
    fn material_region(&self, x: DVec3, nodes: &[u32], pos: &[Vec4]) -> Option<(DVec3, u16)> {
        let x0 = self.fit_around(x, nodes, pos)?.rest_of(x);
        Some((x0, self.region_at(x0, nodes)))
    }

    fn rest_of(&self, v: u32) -> [f64; 3] {
        self.editor.rest_position(v as usize)
    }

    fn edit(&self, source: EditError) -> SimulationError {
        SimulationError::Edit {
            step: self.stepper.steps(),
            source,
        }
    }
}
