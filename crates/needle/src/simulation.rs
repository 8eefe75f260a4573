//! The needle insertion simulation (paper section 5.4): a tissue backend, the needle, the
//! Outside / Touching / Inside state machine, needle nodes with stick-slip friction, and
//! the needle force of every step.
//!
//! One step ([`Simulation::step`]):
//! 1. the needle moves to its pose at `t + dt` (script or [`Simulation::set_pose`]);
//! 2. contact: Outside tests the segment swept by the tip against the entering side of the
//!    surface triangles near it; Touching compares the mean cone angle with the thresholds;
//!    Inside adds or removes needle nodes and refreshes the Tip node (below);
//! 3. needle nodes are constrained: a sticking node (and the Tip node, and the Surface node
//!    while Touching) moves rigidly with the needle (inverse mass 0, the needle's velocity);
//!    a slipping node is projected onto the shaft and keeps only its axial velocity
//!    relative to the needle;
//! 4. elastic forces; only the needle nodes' forces are read back;
//! 5. friction (paper 5.3): sticking nodes that exceed the static threshold slip; slipping
//!    nodes get the axial elastic force plus the dynamic friction force (the normal part is
//!    taken by the shaft) and stick again below the stick speed. The needle force is the
//!    sum of what the nodes exert on the needle: the elastic force of every sticking node,
//!    and the normal force minus the friction force of every slipping node;
//! 6. integration.
//!
//! Only needle node rows cross between host and device each step (plus, while Outside
//! near the surface, the corners of the few candidate triangles).
//!
//! Needle nodes (a stack, removed in reverse order of addition): the Surface node where
//! the tip first touched; Shaft nodes, one per spacing h of insertion; the Tip node at the
//! tip. Inside, with `d` the axial distance from the last non-tip node to the tip: a Shaft
//! node is added at `h` past the last node when `d >= 1.5 h` (so it never lands on the Tip
//! node), the last Shaft node is removed when `d < h / 2`, the Tip node exists while
//! `d >= h / 4` past the Surface node (added at `h / 2`), and is removed and re-added
//! (neighbour refresh, which also relaxes the tissue ahead of the tip: cutting) every
//! `tip_refresh * h` of tip motion. The needle is back Outside when the tip is pulled
//! back past the Surface node. The paper adds nodes at the tip when `d > h`; the margins
//! here keep any two needle nodes at least h / 4 apart.

use crate::config::NeedleConfig;
use crate::friction::{dynamic_friction, next_state, split, FrictionParams, FrictionState};
use crate::needle::Needle;
use crate::node_editor::{EditError, NodeEditor};
use crate::puncture::{
    mean_cone_angle, restore_triangle, split_triangle, PunctureState, Split, TouchingOutcome,
};
use crate::script::PoseScript;
use crate::surface_query::{segment_triangle, TriangleGrid};
use needlesim_core::math::Vec4;
use needlesim_core::{geometry, Backend, NodeField, Scene, SceneError, SimError, Tissue};
use thiserror::Error;

/// Why a needle simulation cannot be built or stepped.
#[derive(Debug, Error)]
pub enum SimulationError {
    /// The scene (or its `[needle]` table) is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A node could not be added or removed (for example the capacity is reached).
    #[error("step {step}: {source}")]
    Edit {
        /// Step at which it happened.
        step: u64,
        /// What went wrong.
        source: EditError,
    },
    /// The backend failed or the simulation diverged.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// A needle pose that cannot be simulated.
    #[error(transparent)]
    Needle(#[from] crate::NeedleError),
    /// The scene has no `[needle]` table.
    #[error("the scene has no needle (add a [needle] table)")]
    NoNeedle,
    /// The backend does not hold the tissue this simulation was prepared for.
    #[error("backend has {got} node slots, the prepared tissue {expected}")]
    BackendMismatch {
        /// Slots of the prepared tissue.
        expected: usize,
        /// Slots of the backend given.
        got: usize,
    },
}

/// Role of a needle node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeRole {
    /// Where the tip first touched the surface.
    Surface,
    /// Added along the shaft during insertion.
    Shaft,
    /// At the needle tip.
    Tip,
}

/// A needle node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeedleNode {
    /// Node index in the backend.
    pub index: u32,
    /// Its role.
    pub role: NodeRole,
    /// Friction state.
    pub friction: FrictionState,
    /// Axial coordinate from the needle base while sticking, m.
    pub s: f64,
}

/// The force the tissue exerts on the needle in one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NeedleForce {
    /// Total force on the needle, N.
    pub total: [f64; 3],
    /// Axial component against the needle direction, N: positive when the tissue resists
    /// insertion, negative when it resists extraction.
    pub axial: f64,
    /// Magnitude of the component normal to the shaft, N.
    pub lateral: f64,
}

/// One step of the needle's record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeedleSample {
    /// Steps taken.
    pub step: u64,
    /// Simulated time, s.
    pub time: f64,
    /// Tip position, m.
    pub tip: [f64; 3],
    /// Needle direction.
    pub direction: [f64; 3],
    /// Force on the needle.
    pub force: NeedleForce,
    /// Puncture state after the step.
    pub state: PunctureState,
    /// Active nodes.
    pub active_nodes: usize,
    /// Needle nodes.
    pub needle_nodes: usize,
}

/// A tissue built for a needle scene, waiting for a backend.
pub struct Prepared {
    /// The tissue with needle node slots; give it to a backend.
    pub tissue: Tissue,
    editor: NodeEditor,
    config: Option<NeedleConfig>,
    spacing: f64,
    rest: Vec<[f64; 3]>,
    guard: (f64, u64),
}

impl Prepared {
    /// Starts the simulation on `backend`, which must have been built from
    /// [`Prepared::tissue`].
    pub fn start(self, backend: Box<dyn Backend>) -> Result<Simulation, SimulationError> {
        if backend.capacity() != self.tissue.state.capacity() {
            return Err(SimulationError::BackendMismatch {
                expected: self.tissue.state.capacity(),
                got: backend.capacity(),
            });
        }
        let triangles = self.tissue.triangles.clone();
        let grid = TriangleGrid::build(&self.rest, &triangles, 2.0 * self.spacing);
        let (needle, script, friction, thresholds, refresh) = match &self.config {
            Some(c) => (
                Some(c.start()?),
                c.script().ok().flatten(),
                c.friction,
                c.thresholds,
                c.tip_refresh,
            ),
            None => (
                None,
                None,
                FrictionParams::default(),
                Default::default(),
                0.1,
            ),
        };
        Ok(Simulation {
            dt: self.tissue.step.dt as f64,
            backend,
            editor: self.editor,
            needle,
            prev: needle,
            script,
            friction,
            thresholds,
            refresh: refresh * self.spacing,
            spacing: self.spacing,
            triangles,
            grid,
            split: None,
            state: PunctureState::Outside,
            nodes: Vec::new(),
            velocities: Vec::new(),
            positions: Vec::new(),
            tip_placed: [0.0; 3],
            entry: None,
            time: 0.0,
            steps: 0,
            force: NeedleForce::default(),
            history: Vec::new(),
            record: true,
            rest: self.rest,
            max_speed: self.guard.0,
            check_every: self.guard.1,
        })
    }
}

/// Needle insertion into a tissue on any backend.
pub struct Simulation {
    dt: f64,
    backend: Box<dyn Backend>,
    editor: NodeEditor,
    needle: Option<Needle>,
    /// The pose at the end of the last step.
    prev: Option<Needle>,
    script: Option<PoseScript>,
    friction: FrictionParams,
    thresholds: crate::Thresholds,
    refresh: f64,
    spacing: f64,
    triangles: Vec<[u32; 3]>,
    grid: TriangleGrid,
    split: Option<Split>,
    state: PunctureState,
    nodes: Vec<NeedleNode>,
    /// Velocities written to the needle nodes this step.
    velocities: Vec<Vec4>,
    /// Positions written to the needle nodes this step.
    positions: Vec<Vec4>,
    tip_placed: [f64; 3],
    entry: Option<[f64; 3]>,
    time: f64,
    steps: u64,
    force: NeedleForce,
    history: Vec<NeedleSample>,
    record: bool,
    rest: Vec<[f64; 3]>,
    max_speed: f64,
    check_every: u64,
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn at(n: &Needle, s: f64) -> [f64; 3] {
    let (b, t) = (n.base(), n.direction());
    std::array::from_fn(|a| b[a] + s * t[a])
}
fn xyz(p: Vec4) -> [f64; 3] {
    [p[0] as f64, p[1] as f64, p[2] as f64]
}
fn f32x3(p: [f64; 3]) -> [f32; 3] {
    p.map(|x| x as f32)
}

impl Simulation {
    /// Builds the tissue of `scene` with room for the needle nodes its `[needle]` table
    /// needs (none without a needle). Build a backend from [`Prepared::tissue`], then call
    /// [`Prepared::start`].
    pub fn prepare(scene: &Scene) -> Result<Prepared, SimulationError> {
        let config = match &scene.needle {
            Some(t) => Some(NeedleConfig::from_table(t)?),
            None => None,
        };
        let cloud = geometry::build(&scene.tissue.geometry, &scene.base_dir)?;
        let rest = cloud.positions.clone();
        let mesh_spacing = (cloud.volume / rest.len().max(1) as f64).cbrt();
        let spacing = config
            .as_ref()
            .and_then(|c| c.spacing)
            .unwrap_or(mesh_spacing);
        let extra = config.as_ref().map_or(0, |c| c.node_slots(spacing));
        let tissue = Tissue::from_cloud(scene, cloud, extra)?;
        let editor = NodeEditor::new(&tissue, &rest, scene.tissue.weight);
        Ok(Prepared {
            tissue,
            editor,
            config,
            spacing,
            rest,
            guard: (scene.physics.max_speed, scene.physics.check_every),
        })
    }

    /// The backend.
    pub fn backend(&mut self) -> &mut dyn Backend {
        self.backend.as_mut()
    }

    /// The node editor (neighbour rows and shape information as the backend has them).
    pub fn editor(&self) -> &NodeEditor {
        &self.editor
    }

    /// The needle, if the scene has one.
    pub fn needle(&self) -> Option<&Needle> {
        self.needle.as_ref()
    }

    /// Puts the needle at a pose for the next step (a haptic device or a planner). The
    /// scene's script, if any, is dropped.
    pub fn set_pose(&mut self, base: [f64; 3], direction: [f64; 3]) -> Result<(), SimulationError> {
        let n = self.needle.as_mut().ok_or(SimulationError::NoNeedle)?;
        n.set_pose(base, direction)?;
        self.script = None;
        Ok(())
    }

    /// The puncture state.
    pub fn state(&self) -> PunctureState {
        self.state
    }

    /// The needle nodes, oldest first.
    pub fn needle_nodes(&self) -> &[NeedleNode] {
        &self.nodes
    }

    /// Surface triangles (node indices), with the split around the Surface node.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The force on the needle in the last step.
    pub fn needle_force(&self) -> NeedleForce {
        self.force
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Time step, s.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Node-adding threshold h, m.
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Duration of the needle's script (0 without one).
    pub fn script_duration(&self) -> f64 {
        self.script.as_ref().map_or(0.0, |s| s.duration())
    }

    /// Every step's record so far.
    pub fn history(&self) -> &[NeedleSample] {
        &self.history
    }

    /// Whether [`Simulation::step`] appends to the history (default true).
    pub fn set_record(&mut self, on: bool) {
        self.record = on;
    }

    /// The point where the tip first touched the surface, if it has.
    pub fn entry_point(&self) -> Option<[f64; 3]> {
        self.entry
    }

    /// Depth of the tip past the first contact point along the needle, m (from the start
    /// tip before any contact).
    pub fn depth_of(&self, tip: [f64; 3], direction: [f64; 3]) -> f64 {
        let origin = self
            .entry
            .or_else(|| self.history.first().map(|s| s.tip))
            .unwrap_or(tip);
        dot(sub(tip, origin), direction)
    }

    /// Rest positions of the active nodes (mesh nodes, then needle nodes), m.
    pub fn rest_positions(&self) -> Vec<[f64; 3]> {
        let mut r = self.rest.clone();
        r.extend((r.len()..self.editor.n_active()).map(|i| self.rest_of(i as u32)));
        r
    }

    /// Node indices of the needle nodes.
    pub fn needle_node_indices(&self) -> Vec<u32> {
        self.nodes.iter().map(|n| n.index).collect()
    }

    /// Runs `n` steps (without a needle, in batches between divergence checks: the GPU
    /// backend queues each batch without waiting).
    pub fn step_n(&mut self, n: u64) -> Result<(), SimulationError> {
        if self.needle.is_none() {
            let mut left = n;
            while left > 0 {
                let batch = left.min(self.check_every - self.steps % self.check_every);
                self.backend.step(batch);
                self.time += batch as f64 * self.dt;
                self.steps += batch;
                left -= batch;
                if self.steps.is_multiple_of(self.check_every) {
                    self.check()?;
                }
            }
            return Ok(());
        }
        for _ in 0..n {
            self.step()?;
        }
        Ok(())
    }

    /// The divergence guard: an error naming the step and node if a position or velocity
    /// is not finite or a free node is faster than `physics.max_speed`. Run every
    /// `physics.check_every` steps by [`Simulation::step`] and [`Simulation::step_n`].
    pub fn check(&mut self) -> Result<(), SimulationError> {
        needlesim_core::backend::check_bounded(self.backend.as_mut(), self.max_speed)?;
        Ok(())
    }

    /// Runs one step.
    pub fn step(&mut self) -> Result<(), SimulationError> {
        let (Some(prev), Some(_)) = (self.prev, self.needle) else {
            return self.step_n(1);
        };
        if let Some(s) = &self.script {
            self.needle = Some(s.pose_at(self.time + self.dt));
        }
        // `prev` is the pose of the last step: the tip sweeps from there even when the
        // caller moved the needle with `set_pose` in between.
        let now = self.needle.expect("needle present");
        self.prev = Some(now);
        let step = self.steps;
        let edit = |source| SimulationError::Edit { step, source };
        self.contact(&prev, &now).map_err(edit)?;
        self.constrain(&prev, &now)?;
        self.backend.compute_forces();
        self.apply_friction(&prev, &now)?;
        self.backend.integrate();
        self.time += self.dt;
        self.steps += 1;
        if self.steps.is_multiple_of(self.check_every) {
            self.check()?;
        }
        if self.record {
            self.history.push(NeedleSample {
                step: self.steps,
                time: self.time,
                tip: now.tip(),
                direction: now.direction(),
                force: self.force,
                state: self.state,
                active_nodes: self.backend.n_active(),
                needle_nodes: self.nodes.len(),
            });
        }
        Ok(())
    }

    /// Velocity of the needle point at axial coordinate `s` over the last step.
    fn needle_velocity(&self, prev: &Needle, now: &Needle, s: f64) -> [f64; 3] {
        let (a, b) = (at(prev, s), at(now, s));
        std::array::from_fn(|c| (b[c] - a[c]) / self.dt)
    }

    fn node_positions(&mut self) -> Result<Vec<[f64; 3]>, SimError> {
        let n0 = self.editor.n_mesh();
        let mut buf = vec![[0.0f32; 4]; self.nodes.len()];
        self.backend
            .read(NodeField::Position, n0..n0 + self.nodes.len(), &mut buf)?;
        Ok(buf.into_iter().map(xyz).collect())
    }

    fn add(
        &mut self,
        role: NodeRole,
        x: [f64; 3],
        s: f64,
        seeds: &[u32],
        v: [f64; 3],
    ) -> Result<(), EditError> {
        let cand = self.editor.rings(seeds, 2);
        let index = self
            .editor
            .add_node(self.backend.as_mut(), f32x3(x), f32x3(v), &cand)?;
        self.nodes.push(NeedleNode {
            index,
            role,
            friction: FrictionState::Stick,
            s,
        });
        Ok(())
    }

    fn remove(&mut self) -> Result<NeedleNode, EditError> {
        self.editor.remove_last(self.backend.as_mut())?;
        let node = self.nodes.pop().ok_or(EditError::NothingToRemove)?;
        if node.role == NodeRole::Surface {
            if let Some(sp) = self.split.take() {
                self.unsplit(&sp);
            }
            self.state = PunctureState::Outside;
        }
        Ok(node)
    }

    fn unsplit(&mut self, sp: &Split) {
        for id in [sp.triangle, sp.appended_at, sp.appended_at + 1] {
            self.grid.remove(id as u32);
        }
        restore_triangle(&mut self.triangles, sp);
        let corners = sp.original.map(|v| self.rest_of(v));
        self.grid.insert(sp.triangle as u32, corners);
    }

    fn rest_of(&self, v: u32) -> [f64; 3] {
        self.editor.rest_position(v as usize).map(|x| x as f64)
    }

    /// The state machine: surface contact, puncture, node addition and removal.
    fn contact(&mut self, prev: &Needle, now: &Needle) -> Result<(), EditError> {
        let t = now.direction();
        let tip = now.tip();
        let v_tip = self.needle_velocity(prev, now, now.length());
        match self.state {
            PunctureState::Outside => {
                let Some((id, point)) = self.surface_entry(prev.tip(), tip)? else {
                    return Ok(());
                };
                let corners = self.triangles[id];
                let s = dot(sub(point, now.base()), t);
                self.add(NodeRole::Surface, point, s, &corners, v_tip)?;
                let node = self.nodes.last().expect("just added").index;
                let sp = split_triangle(&mut self.triangles, id, node);
                self.grid.remove(id as u32);
                for tid in [id, sp.appended_at, sp.appended_at + 1] {
                    let c = self.triangles[tid].map(|v| {
                        if v == node {
                            self.editor.rest_position(v as usize).map(|x| x as f64)
                        } else {
                            self.rest_of(v)
                        }
                    });
                    self.grid.insert(tid as u32, c);
                }
                self.split = Some(sp);
                self.entry.get_or_insert(point);
                self.state = PunctureState::Touching;
            }
            PunctureState::Touching => {
                let sp = self.split.expect("Touching has a split triangle");
                let mut c = [[0.0f32; 4]; 3];
                self.backend
                    .read_nodes(NodeField::Position, &sp.original, &mut c)?;
                let surface = at(now, self.nodes[0].s);
                let angle = mean_cone_angle(surface, c.map(xyz), t);
                match self.thresholds.touching(angle) {
                    TouchingOutcome::Stay => {}
                    TouchingOutcome::Release => {
                        self.remove()?;
                    }
                    TouchingOutcome::Puncture => {
                        self.state = PunctureState::Inside;
                        self.nodes[0].friction = FrictionState::Slip;
                        self.inside(now, v_tip)?;
                    }
                }
            }
            PunctureState::Inside => self.inside(now, v_tip)?,
        }
        Ok(())
    }

    /// Inside: keep a Shaft node per spacing and the Tip node at the tip.
    fn inside(&mut self, now: &Needle, v_tip: [f64; 3]) -> Result<(), EditError> {
        let (t, tip, h) = (now.direction(), now.tip(), self.spacing);
        let mut pos = self.node_positions()?;
        let mut edited = false;
        loop {
            let has_tip = self.nodes.last().is_some_and(|n| n.role == NodeRole::Tip);
            let last = self.nodes.len() - 1 - has_tip as usize;
            let role = self.nodes[last].role;
            let d = dot(sub(tip, pos[last]), t);
            let seeds = |nodes: &[NeedleNode]| -> Vec<u32> {
                nodes.iter().rev().take(2).map(|n| n.index).collect()
            };
            if has_tip && (d >= 1.5 * h || (role == NodeRole::Shaft && d < 0.5 * h) || d < 0.25 * h)
            {
                self.remove()?;
                pos.pop();
                edited = true;
                continue;
            }
            if role == NodeRole::Shaft && d < 0.5 * h {
                self.remove()?;
                pos.pop();
                edited = true;
                continue;
            }
            if d >= 1.5 * h {
                let s = dot(sub(pos[last], now.base()), t) + h;
                let x = at(now, s);
                let seeds = seeds(&self.nodes);
                self.add(NodeRole::Shaft, x, s, &seeds, v_tip)?;
                pos.push(x);
                edited = true;
                continue;
            }
            if !has_tip && d >= 0.5 * h {
                let seeds = seeds(&self.nodes);
                self.add(NodeRole::Tip, tip, now.length(), &seeds, v_tip)?;
                pos.push(tip);
                self.tip_placed = tip;
                edited = true;
                continue;
            }
            if role == NodeRole::Surface && !has_tip && d < 0.0 {
                self.remove()?;
                return Ok(());
            }
            break;
        }
        let has_tip = self.nodes.last().is_some_and(|n| n.role == NodeRole::Tip);
        let moved = sub(tip, self.tip_placed);
        if has_tip && !edited && dot(moved, moved).sqrt() > self.refresh {
            let seeds: Vec<u32> = self.nodes.iter().rev().take(2).map(|n| n.index).collect();
            self.remove()?;
            self.add(NodeRole::Tip, tip, now.length(), &seeds, v_tip)?;
            self.tip_placed = tip;
            pos.pop();
            pos.push(tip);
        }
        // What the needle nodes' positions are now, so that `constrain` need not read
        // them back again.
        self.positions = pos
            .iter()
            .map(|x| [x[0] as f32, x[1] as f32, x[2] as f32, 0.0])
            .collect();
        Ok(())
    }

    /// The first surface triangle entered (from outside) by the segment `p0 -> p1`, and
    /// where.
    fn surface_entry(
        &mut self,
        p0: [f64; 3],
        p1: [f64; 3],
    ) -> Result<Option<(usize, [f64; 3])>, SimError> {
        if p0 == p1 {
            return Ok(None);
        }
        let cand = self.grid.candidates(p0, p1);
        if cand.is_empty() {
            return Ok(None);
        }
        let mut verts: Vec<u32> = cand
            .iter()
            .flat_map(|&c| self.triangles[c as usize])
            .collect();
        verts.sort_unstable();
        verts.dedup();
        let mut pos = vec![[0.0f32; 4]; verts.len()];
        self.backend
            .read_nodes(NodeField::Position, &verts, &mut pos)?;
        let p = |v: u32| xyz(pos[verts.binary_search(&v).expect("listed")]);
        let seg = sub(p1, p0);
        let mut best: Option<(f64, usize, [f64; 3])> = None;
        for &c in &cand {
            let [a, b, cc] = self.triangles[c as usize].map(p);
            let Some((s, w)) = segment_triangle(p0, p1, a, b, cc) else {
                continue;
            };
            // Outward normal (counter-clockwise winding): entering means against it.
            let (e1, e2) = (sub(b, a), sub(cc, a));
            let nrm = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            if dot(nrm, seg) >= 0.0 {
                continue;
            }
            if best.is_none_or(|(bs, _, _)| s < bs) {
                let hit = std::array::from_fn(|k| w[0] * a[k] + w[1] * b[k] + w[2] * cc[k]);
                best = Some((s, c as usize, hit));
            }
        }
        Ok(best.map(|(_, id, hit)| (id, hit)))
    }

    fn kinematic(&self, n: &NeedleNode) -> bool {
        n.role == NodeRole::Tip
            || (n.role == NodeRole::Surface && self.state == PunctureState::Touching)
            || n.friction == FrictionState::Stick
    }

    /// Puts sticking nodes on the needle and slipping nodes onto the shaft.
    fn constrain(&mut self, prev: &Needle, now: &Needle) -> Result<(), SimError> {
        let m = self.nodes.len();
        self.velocities.clear();
        if m == 0 {
            return Ok(());
        }
        let n0 = self.editor.n_mesh();
        let mut v = vec![[0.0f32; 4]; m];
        // Only sliding nodes need their own state; sticking ones follow the needle. The
        // positions come from the contact update when it read them this step.
        let mut p = std::mem::take(&mut self.positions);
        if self.nodes.iter().any(|n| !self.kinematic(n)) {
            if p.len() != m {
                p = vec![[0.0f32; 4]; m];
                self.backend.read(NodeField::Position, n0..n0 + m, &mut p)?;
            }
            self.backend.read(NodeField::Velocity, n0..n0 + m, &mut v)?;
        } else {
            p = vec![[0.0f32; 4]; m];
        }
        let t = now.direction();
        let inv_mass = self.editor.inverse_mass();
        for k in 0..m {
            let node = self.nodes[k];
            if self.kinematic(&node) {
                let x = at(now, node.s);
                let vn = self.needle_velocity(prev, now, node.s);
                p[k] = [x[0] as f32, x[1] as f32, x[2] as f32, 0.0];
                v[k] = [vn[0] as f32, vn[1] as f32, vn[2] as f32, 0.0];
            } else {
                let s = dot(sub(xyz(p[k]), now.base()), t);
                let x = at(now, s);
                let vn = self.needle_velocity(prev, now, s);
                let own = dot(xyz(v[k]), t) - dot(vn, t);
                p[k] = [x[0] as f32, x[1] as f32, x[2] as f32, inv_mass];
                v[k] = std::array::from_fn(|c| {
                    if c < 3 {
                        (vn[c] + own * t[c]) as f32
                    } else {
                        0.0
                    }
                });
            }
        }
        self.backend.write(NodeField::Position, n0, &p)?;
        self.backend.write(NodeField::Velocity, n0, &v)?;
        self.velocities = v;
        self.positions = p;
        Ok(())
    }

    /// Friction on the needle nodes and the needle force (after the force evaluation).
    fn apply_friction(&mut self, prev: &Needle, now: &Needle) -> Result<(), SimError> {
        let m = self.nodes.len();
        let mut total = [0.0f64; 3];
        if m > 0 {
            let n0 = self.editor.n_mesh();
            let mut f = vec![[0.0f32; 4]; m];
            self.backend.read(NodeField::Force, n0..n0 + m, &mut f)?;
            let t = now.direction();
            // The positions `constrain` wrote: the force evaluation does not move nodes.
            let p = std::mem::take(&mut self.positions);
            for k in 0..m {
                let fe = xyz(f[k]);
                let node = self.nodes[k];
                let s_now = dot(sub(xyz(p[k]), now.base()), t);
                let vn = self.needle_velocity(prev, now, s_now);
                let vk = xyz(self.velocities[k]);
                let pinned = node.role == NodeRole::Tip
                    || (node.role == NodeRole::Surface && self.state == PunctureState::Touching);
                if pinned {
                    total = std::array::from_fn(|c| total[c] + fe[c]);
                    continue;
                }
                let state = next_state(node.friction, fe, vk, vn, t, &self.friction);
                if state != node.friction {
                    self.nodes[k].friction = state;
                    self.nodes[k].s = s_now;
                }
                match node.friction {
                    FrictionState::Stick => {
                        total = std::array::from_fn(|c| total[c] + fe[c]);
                    }
                    FrictionState::Slip => {
                        let (axial, normal) = split(fe, t);
                        let fdf = dynamic_friction(fe, vk, vn, t, &self.friction);
                        let applied: [f64; 3] = std::array::from_fn(|c| axial * t[c] + fdf[c]);
                        f[k] = [applied[0] as f32, applied[1] as f32, applied[2] as f32, 0.0];
                        total = std::array::from_fn(|c| total[c] + normal[c] - fdf[c]);
                    }
                }
            }
            self.backend.write(NodeField::Force, n0, &f)?;
        }
        let t = now.direction();
        let along = dot(total, t);
        let lateral: [f64; 3] = std::array::from_fn(|c| total[c] - along * t[c]);
        self.force = NeedleForce {
            total,
            axial: -along,
            lateral: dot(lateral, lateral).sqrt(),
        };
        Ok(())
    }
}
