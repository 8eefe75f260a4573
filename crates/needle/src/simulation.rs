//! The needle insertion simulation (paper section 5.4): a tissue backend, the needle, the
//! Outside / Touching / Inside state machine, needle nodes with stick-slip friction, and
//! the needle force of every step.
//!
//! One step ([`Simulation::step`]):
//! 1. the needle moves to its pose at `t + dt` (script or [`Simulation::set_pose`]);
//! 2. contact: Outside tests the segment swept by the tip against the entering side of the
//!    surface triangles near it; Touching compares the mean cone angle (or the force) with
//!    the thresholds; Inside adds or removes needle nodes, refreshes the Tip node and tests
//!    the tip against the leaving side of the surface (the far side);
//! 3. needle nodes are constrained: a sticking node (and the Surface node while Touching)
//!    moves rigidly with the needle (inverse mass 0, the needle's velocity); a slipping
//!    node is projected onto the shaft and keeps only its axial velocity relative to the
//!    needle;
//! 4. elastic forces; only the needle nodes' forces are read back;
//! 5. friction ([`crate::friction`]): each node's axial force from the needle, its normal
//!    force taken by the shaft. The needle force is the sum of what the nodes exert on the
//!    needle: the elastic force of a pinned node, and the normal force minus the friction
//!    (and cutting) force of every other node;
//! 6. integration.
//!
//! Only needle node rows cross between host and device each step (plus, near the surface,
//! the corners of the few candidate triangles).
//!
//! Needle nodes (a stack, removed in reverse order of addition): the Surface node where
//! the tip first touched; Shaft nodes, one per spacing h of insertion; the Tip node at the
//! tip; the Exit node where the tip reached the far surface. Inside, with `d` the axial
//! distance from the last non-tip node to the tip: a Shaft node is added at `h` past the
//! last node when `d >= 1.5 h` (so it never lands on the Tip node), the last Shaft node is
//! removed when `d < h / 2`, the Tip node exists while `d >= h / 4` past the Surface node
//! (added at `h / 2`), and is removed and re-added (neighbour refresh) every
//! `tip_refresh * h` of tip motion. The paper adds nodes at the tip when `d > h`; the
//! margins here keep any two needle nodes at least h / 4 apart.
//!
//! With the per-length friction model, nodes added inside the tissue start slipping with
//! the velocity of the tissue at the tip (the shaft slides past the tissue it reaches), and
//! a refreshed Tip node keeps its friction state and velocity: the load the tip carries
//! (cutting force, friction) is not released by a refresh, so the force has no sawtooth at
//! the refresh period.
//!
//! The far side: when the tip leaves the body through its surface, the Tip node is
//! replaced by an Exit node pinned to the tip (state Touching: the surface dents outwards)
//! until the same puncture rule fires; then the tip is Outside past the body while the
//! shaft nodes stay on the needle. Pulled back past the Exit node, the tip re-enters
//! (Inside) through its hole. A tip that leaves the body again elsewhere after exiting is
//! not detected (one entry and one exit per needle path).
//!
//! A needle node that the tissue pushes ahead of an advancing tip (the shaft no longer
//! holding the tissue it is in) stops the run with [`SimulationError::NodesLost`].

use crate::checkpoint::{BackendSnapshot, Checkpoint, CheckpointError};
use crate::config::NeedleConfig;
use crate::friction::{
    grip_from_modulus, paper_dynamic_friction, paper_next_state, per_length_step, split, AxialStep,
    FrictionModel, FrictionState, Limits, PerLengthFriction,
};
use crate::needle::Needle;
use crate::node_editor::{EditError, NodeEditor};
use crate::puncture::{
    mean_cone_angle, restore_triangle, split_triangle, PunctureState, Split, TouchingOutcome,
};
use crate::script::PoseScript;
use crate::surface_query::{segment_triangle, TriangleGrid};
use needlesim_core::boundary::{Boundary, Reaction};
use needlesim_core::integrator::StepParams;
use needlesim_core::math::Vec4;
use needlesim_core::scene::Material;
use needlesim_core::{geometry, Backend, NodeField, Scene, SceneError, SimError, Tissue};
use std::path::PathBuf;
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
    /// The needle starts with its tip (or shaft) inside the tissue: the puncture state
    /// machine starts Outside, so it would never see the tissue the needle is in.
    #[error(
        "the needle starts inside the tissue: its {what} at {point:?} m is {where_} (start \
         the needle outside the body, with its tip before the surface, and insert it with \
         keyframes or set_pose)"
    )]
    StartsInside {
        /// `tip`, `base` or `shaft`.
        what: &'static str,
        /// The point inside the body or where the shaft crosses the surface, m.
        point: [f64; 3],
        /// `inside the body` or `crossing the surface`.
        where_: &'static str,
    },
    /// The needle moved further in one step than the contact can resolve (a very fast
    /// needle, or a pose that jumped, as from a glitching haptic device).
    #[error(
        "step {step}: the needle moved {moved:.3e} m in one step while {phase}, more than \
         {limit:.3e} m (4 needle node spacings): the contact cannot follow (lower the \
         speed, refine physics.dt, or move the needle in smaller steps)"
    )]
    TooFast {
        /// Step at which it happened.
        step: u64,
        /// Largest displacement of a needle point over the step, m.
        moved: f64,
        /// The limit ([`MAX_STEP_SPACINGS`] node spacings), m.
        limit: f64,
        /// The contact phase it happened in.
        phase: &'static str,
    },
    /// A checkpoint cannot be written, read or restored.
    #[error(transparent)]
    Checkpoint(#[from] crate::checkpoint::CheckpointError),
    /// The needle stopped holding the tissue it is in: a needle node was pushed ahead of
    /// the advancing tip (for example by a friction law that drives nodes faster than the
    /// needle), which would let the needle pass through the tissue unnoticed.
    #[error(
        "step {step}: needle node {node} ({role:?}) was pushed {ahead:.3e} m ahead of the \
         advancing tip: the needle no longer holds the tissue it is in (lower the friction \
         or the speed, or refine the time step)"
    )]
    NodesLost {
        /// Step at which it happened.
        step: u64,
        /// Node index.
        node: u32,
        /// Its role.
        role: NodeRole,
        /// How far past the point where it should be, m.
        ahead: f64,
    },
}

/// Most needle node spacings a needle point may move in one step while in contact.
/// Node addition and removal handle several nodes per step (tested at 2.7 spacings a
/// step); at 8 spacings a step (a 90 m/s needle in the shipped scenes) the tip crossed the
/// whole body within the Touching phase and nodes were placed past the far surface until
/// the slots ran out. A haptic pose glitch is usually far larger.
pub const MAX_STEP_SPACINGS: f64 = 4.0;

/// Role of a needle node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum NodeRole {
    /// Where the tip first touched the surface.
    Surface,
    /// Added along the shaft during insertion.
    Shaft,
    /// At the needle tip.
    Tip,
    /// Where the tip reached the far surface from inside.
    Exit,
}

/// A needle node.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NeedleNode {
    /// Node index in the backend.
    pub index: u32,
    /// Its role.
    pub role: NodeRole,
    /// Friction state.
    pub friction: FrictionState,
    /// Axial coordinate from the needle base while sticking, m.
    pub s: f64,
    /// Axial force the needle exerted on the node in the last step (friction, and
    /// cutting at the crack front), N, positive along the needle direction.
    pub axial: f64,
    /// The static limit of that force forward in the last step (per-length model), N.
    pub limit: f64,
}

/// The force the tissue exerts on the needle in one step.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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

/// Where the needle is in its path through the body (the public [`PunctureState`] is the
/// tip's view of it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
enum Phase {
    /// No contact.
    Outside,
    /// Denting the entry surface.
    Touching,
    /// Tip inside.
    Inside,
    /// Denting the far surface from inside.
    ExitTouching,
    /// Tip out past the far surface, shaft inside.
    Exited,
}

impl Phase {
    fn state(self) -> PunctureState {
        match self {
            Phase::Outside | Phase::Exited => PunctureState::Outside,
            Phase::Touching | Phase::ExitTouching => PunctureState::Touching,
            Phase::Inside => PunctureState::Inside,
        }
    }
}

/// The needle parameters a step uses, resolved from the scene.
#[derive(Debug, Clone, Copy)]
struct Contact {
    friction: FrictionModel,
    /// Grip of the per-length model, N/m.
    grip: f64,
    cutting: f64,
    thresholds: crate::Thresholds,
    puncture_force: Option<f64>,
    refresh: f64,
}

/// A tissue built for a needle scene, waiting for a backend.
pub struct Prepared {
    /// The tissue with needle node slots; give it to a backend.
    pub tissue: Tissue,
    editor: NodeEditor,
    config: Option<NeedleConfig>,
    spacing: f64,
    grip: f64,
    rest: Vec<[f64; 3]>,
    guard: (f64, u64),
    fingerprint: Vec<(String, u64)>,
}

impl Prepared {
    /// Starts the simulation on `backend` (built from [`Prepared::tissue`]) in the state of
    /// `checkpoint`, taken from a simulation of the same scene; a checkpoint of another
    /// scene is [`CheckpointError::SceneMismatch`]. On the CPU backends the run then
    /// continues bitwise as the checkpointed one would have.
    pub fn resume(
        self,
        backend: Box<dyn Backend>,
        checkpoint: Checkpoint,
    ) -> Result<Simulation, SimulationError> {
        let mut sim = self.start(backend)?;
        sim.restore(checkpoint)?;
        Ok(sim)
    }

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
        let (needle, script, contact) = match &self.config {
            Some(c) => (
                Some(c.start()?),
                c.script().ok().flatten(),
                Contact {
                    friction: c.friction,
                    grip: self.grip,
                    cutting: c.cutting,
                    thresholds: c.thresholds,
                    puncture_force: c.puncture_force,
                    refresh: c.tip_refresh * self.spacing,
                },
            ),
            None => (
                None,
                None,
                Contact {
                    friction: FrictionModel::default(),
                    grip: 0.0,
                    cutting: 0.0,
                    thresholds: Default::default(),
                    puncture_force: None,
                    refresh: 0.1 * self.spacing,
                },
            ),
        };
        let mut sim = Simulation {
            dt: self.tissue.step.dt as f64,
            params: self.tissue.step,
            backend,
            editor: self.editor,
            needle,
            prev: needle,
            script,
            contact,
            spacing: self.spacing,
            triangles,
            grid,
            splits: Vec::new(),
            phase: Phase::Outside,
            nodes: Vec::new(),
            velocities: Vec::new(),
            positions: Vec::new(),
            tip_placed: [0.0; 3],
            swept_from: [0.0; 3],
            entry: None,
            cut_depth: f64::NEG_INFINITY,
            pinned_axial: 0.0,
            time: 0.0,
            steps: 0,
            force: NeedleForce::default(),
            history: Vec::new(),
            record: true,
            history_limit: None,
            start_tip: None,
            rest: self.rest,
            max_speed: self.guard.0,
            check_every: self.guard.1,
            boundary: self.tissue.boundary.clone(),
            fingerprint: self.fingerprint,
        };
        if let Some(n) = sim.needle {
            sim.check_start_outside(&n)?;
        }
        // Prescribed displacements hold from the start (a ramp starts at zero).
        sim.boundary.project(sim.backend.as_mut(), 0.0)?;
        Ok(sim)
    }
}

/// Needle insertion into a tissue on any backend.
pub struct Simulation {
    dt: f64,
    params: StepParams,
    backend: Box<dyn Backend>,
    editor: NodeEditor,
    needle: Option<Needle>,
    /// The pose at the end of the last step.
    prev: Option<Needle>,
    script: Option<PoseScript>,
    contact: Contact,
    spacing: f64,
    triangles: Vec<[u32; 3]>,
    grid: TriangleGrid,
    /// The entry split, then the exit split.
    splits: Vec<Split>,
    phase: Phase,
    nodes: Vec<NeedleNode>,
    /// Velocities written to the needle nodes this step.
    velocities: Vec<Vec4>,
    /// Positions written to the needle nodes this step.
    positions: Vec<Vec4>,
    tip_placed: [f64; 3],
    /// The tip at the start of this step's sweep.
    swept_from: [f64; 3],
    entry: Option<[f64; 3]>,
    /// Deepest tip depth past the entry so far (the crack front), m.
    cut_depth: f64,
    /// Axial force of the pinned (Surface or Exit) node on the needle in the last step, N.
    pinned_axial: f64,
    time: f64,
    steps: u64,
    force: NeedleForce,
    history: Vec<NeedleSample>,
    record: bool,
    /// Most history samples kept (the oldest go first); `None` keeps every one.
    history_limit: Option<usize>,
    /// The tip before the first recorded step (the depth origin before any contact).
    start_tip: Option<[f64; 3]>,
    rest: Vec<[f64; 3]>,
    max_speed: f64,
    check_every: u64,
    boundary: Boundary,
    fingerprint: Vec<(String, u64)>,
}

/// The simulation's own changing state, as a checkpoint stores it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct SimSnapshot {
    needle: Option<Needle>,
    prev: Option<Needle>,
    scripted: bool,
    triangles: Vec<[u32; 3]>,
    grid: TriangleGrid,
    splits: Vec<Split>,
    phase: Phase,
    nodes: Vec<NeedleNode>,
    velocities: Vec<Vec4>,
    positions: Vec<Vec4>,
    tip_placed: [f64; 3],
    swept_from: [f64; 3],
    entry: Option<[f64; 3]>,
    cut_depth: f64,
    pinned_axial: f64,
    pub(crate) time: f64,
    pub(crate) steps: u64,
    force: NeedleForce,
    history: Vec<NeedleSample>,
    record: bool,
    history_limit: Option<usize>,
    start_tip: Option<[f64; 3]>,
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
fn vec4(p: [f64; 3], w: f32) -> Vec4 {
    [p[0] as f32, p[1] as f32, p[2] as f32, w]
}

/// The grip per unit length (N/m) of the per-length friction model: the scene's
/// `friction.grip`, or from the material's Young's modulus (for mass-spring and shape
/// matching, the one their calibrated stiffness gives at the mesh spacing `h`).
fn resolve_grip(scene: &Scene, c: &NeedleConfig, h: f64) -> Result<f64, SceneError> {
    let FrictionModel::PerLength(PerLengthFriction { grip, .. }) = c.friction else {
        return Ok(0.0);
    };
    if let Some(g) = grip {
        return Ok(g);
    }
    use needlesim_core::calibration::calibration;
    let k = scene.tissue.neighbours;
    let uncalibrated = |e: needlesim_core::calibration::UncalibratedNeighbours| {
        SceneError::invalid(
            "needle.friction.grip",
            format!("cannot be derived from this material's stiffness ({e}); give it in N/m"),
        )
    };
    // Mass-spring's lattice Poisson ratio is about 1/4; cluster shape matching's lateral
    // contraction is about 0 (docs/report).
    let (young, nu) = match scene.material {
        Material::DebunneMeshfree(p) => (p.young_modulus, p.poisson_ratio),
        Material::PointBased(p) => (p.young_modulus, p.poisson_ratio),
        Material::MassSpring(p) => {
            let cal = calibration(k).map_err(uncalibrated)?;
            (p.stiffness / (cal.mass_spring * h), 0.25)
        }
        Material::LocalShapeMatching(p) => {
            let cal = calibration(k).map_err(uncalibrated)?;
            let c = if p.forces == needlesim_core::scene::ShapeMatchingForces::Cluster {
                cal.shape_matching_cluster
            } else {
                cal.shape_matching_node
            };
            (p.stiffness / (c * h), 0.0)
        }
    };
    Ok(grip_from_modulus(young, nu, c.radius))
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
        // The needle's slots enter the memory estimate before anything is allocated (with
        // its own spacing; the mesh spacing is known only after the build, checked below).
        let given = config
            .as_ref()
            .and_then(|c| c.spacing.map(|h| c.length / h + 4.0))
            .unwrap_or(0.0);
        let cloud = geometry::build_checked(scene, given, "needle.spacing")?;
        let rest = cloud.positions.clone();
        let mesh_spacing = (cloud.volume / rest.len().max(1) as f64).cbrt();
        let spacing = config
            .as_ref()
            .and_then(|c| c.spacing)
            .unwrap_or(mesh_spacing);
        let grip = match &config {
            Some(c) => {
                c.check_radius(spacing)?;
                resolve_grip(scene, c, mesh_spacing)?
            }
            None => 0.0,
        };
        if let Some(c) = &config {
            let key = if c.spacing.is_some() {
                "needle.spacing"
            } else {
                "needle.length"
            };
            geometry::check_memory(
                scene,
                &geometry::MeshEstimate::built(rest.len()),
                c.length / spacing + 4.0,
                key,
            )?;
        }
        let extra = config.as_ref().map_or(0, |c| c.node_slots(spacing));
        let tissue = Tissue::from_cloud(scene, cloud, extra)?;
        let editor = NodeEditor::new(&tissue, &rest, scene.tissue.weight);
        let fingerprint = crate::checkpoint::fingerprint(scene, &tissue.state.positions);
        Ok(Prepared {
            fingerprint,
            tissue,
            editor,
            config,
            spacing,
            grip,
            rest,
            guard: (scene.physics.max_speed, scene.physics.check_every),
        })
    }

    /// The whole state as a [`Checkpoint`] (it reads every node and shape array back from
    /// the backend). Attach the scene's text ([`Checkpoint::scene`]) to make the file
    /// enough on its own.
    pub fn checkpoint(&mut self) -> Result<Checkpoint, SimulationError> {
        let b = self.backend.as_mut();
        let cap = b.capacity();
        let mut field = |f| -> Result<Vec<Vec4>, SimError> {
            let mut out = vec![[0.0f32; 4]; cap];
            b.read(f, 0..cap, &mut out)?;
            Ok(out)
        };
        let (positions, velocities, forces) = (
            field(NodeField::Position)?,
            field(NodeField::Velocity)?,
            field(NodeField::Force)?,
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
                shape,
            },
            editor: self.editor.snapshot(),
            sim: SimSnapshot {
                needle: self.needle,
                prev: self.prev,
                scripted: self.script.is_some(),
                triangles: self.triangles.clone(),
                grid: self.grid.clone(),
                splits: self.splits.clone(),
                phase: self.phase,
                nodes: self.nodes.clone(),
                velocities: self.velocities.clone(),
                positions: self.positions.clone(),
                tip_placed: self.tip_placed,
                swept_from: self.swept_from,
                entry: self.entry,
                cut_depth: self.cut_depth,
                pinned_axial: self.pinned_axial,
                time: self.time,
                steps: self.steps,
                force: self.force,
                history: self.history.clone(),
                record: self.record,
                history_limit: self.history_limit,
                start_tip: self.start_tip,
            },
        })
    }

    /// Errs when the start pose has the tip or the base inside the body (odd crossings of a
    /// ray to far outside) or the shaft crossing its surface, on the rest surface.
    fn check_start_outside(&self, n: &Needle) -> Result<(), SimulationError> {
        let corners = |t: &[u32; 3]| t.map(|v| self.rest[v as usize]);
        let crossings = |p0: [f64; 3], p1: [f64; 3]| -> Vec<f64> {
            self.triangles
                .iter()
                .filter_map(|t| {
                    let [a, b, c] = corners(t);
                    segment_triangle(p0, p1, a, b, c).map(|h| h.0)
                })
                .collect()
        };
        let (lo, hi) = geometry::bounds(&self.rest);
        let reach = 4.0 * (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
        // A direction unlikely to graze edges of axis-aligned or regular meshes.
        let ray = [0.5377, 0.6143, 0.5773];
        let inside = |p: [f64; 3]| {
            let far = std::array::from_fn(|a| p[a] + reach * ray[a]);
            let mut t = crossings(p, far);
            // A hit on an edge is found in both triangles sharing it.
            t.sort_by(f64::total_cmp);
            t.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
            t.len() % 2 == 1
        };
        let (base, tip) = (n.base(), n.tip());
        for (what, p) in [("tip", tip), ("base", base)] {
            if inside(p) {
                return Err(SimulationError::StartsInside {
                    what,
                    point: p,
                    where_: "inside the body",
                });
            }
        }
        if let Some(t) = crossings(base, tip).into_iter().min_by(f64::total_cmp) {
            return Err(SimulationError::StartsInside {
                what: "shaft",
                point: std::array::from_fn(|a| base[a] + t * (tip[a] - base[a])),
                where_: "crossing the surface",
            });
        }
        Ok(())
    }

    /// Errs when a needle point moved more than [`MAX_STEP_SPACINGS`] node spacings over
    /// the step while the needle is in contact, or when it enters the body and ends more
    /// than that past the surface. (A rigid motion interpolated over the step moves the
    /// points of a segment most at its ends.)
    fn check_motion(
        &self,
        prev: &Needle,
        now: &Needle,
        entry: Option<[f64; 3]>,
    ) -> Result<(), SimulationError> {
        let dist = |a: [f64; 3], b: [f64; 3]| dot(sub(a, b), sub(a, b)).sqrt();
        let (moved, phase) = match (self.phase, entry) {
            (Phase::Outside, None) => return Ok(()),
            (Phase::Outside, Some(p)) => (dist(now.tip(), p), "entering the body"),
            (phase, _) => (
                dist(now.tip(), prev.tip()).max(dist(now.base(), prev.base())),
                match phase {
                    Phase::Touching | Phase::ExitTouching => "touching the surface",
                    Phase::Exited => "through the body",
                    _ => "inside the body",
                },
            ),
        };
        let limit = MAX_STEP_SPACINGS * self.spacing;
        if moved > limit {
            return Err(SimulationError::TooFast {
                step: self.steps + 1,
                moved,
                limit,
                phase,
            });
        }
        Ok(())
    }

    /// Puts a checkpoint's state into this freshly started simulation.
    fn restore(&mut self, c: Checkpoint) -> Result<(), SimulationError> {
        let corrupt = |reason: String| CheckpointError::Corrupt {
            path: PathBuf::new(),
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
        if [&bs.positions, &bs.velocities, &bs.forces]
            .iter()
            .any(|a| a.len() != cap)
            || bs.n_active > cap
        {
            return Err(corrupt(format!("node arrays do not fit {cap} node slots")).into());
        }
        let sim = c.sim;
        let bad_node = |i: u32| i as usize >= bs.n_active;
        if sim.nodes.iter().any(|n| bad_node(n.index))
            || sim.triangles.iter().flatten().any(|&i| bad_node(i))
            || sim.splits.len() > 2
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
        b.write(NodeField::Position, 0, &bs.positions)?;
        b.write(NodeField::Velocity, 0, &bs.velocities)?;
        b.write(NodeField::Force, 0, &bs.forces)?;
        let nb = self.editor.neighbours();
        b.write_neighbour_rows(0, &nb.index, &nb.weight)?;
        let names: Vec<&str> = self.editor.shape().bytes().iter().map(|a| a.0).collect();
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
        self.needle = sim.needle;
        self.prev = sim.prev;
        self.triangles = sim.triangles;
        self.grid = sim.grid;
        self.splits = sim.splits;
        self.phase = sim.phase;
        self.nodes = sim.nodes;
        self.velocities = sim.velocities;
        self.positions = sim.positions;
        self.tip_placed = sim.tip_placed;
        self.swept_from = sim.swept_from;
        self.entry = sim.entry;
        self.cut_depth = sim.cut_depth;
        self.pinned_axial = sim.pinned_axial;
        self.time = sim.time;
        self.steps = sim.steps;
        self.force = sim.force;
        self.history = sim.history;
        self.record = sim.record;
        self.history_limit = sim.history_limit;
        self.start_tip = sim.start_tip;
        Ok(())
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

    /// The puncture state: where the tip is (Outside also past the far surface, with the
    /// shaft still in the tissue: see [`Simulation::needle_nodes`]).
    pub fn state(&self) -> PunctureState {
        self.phase.state()
    }

    /// Whether the tip has left the body through its far surface (state Outside with the
    /// shaft inside) or is denting it from inside (Touching).
    pub fn through_far_side(&self) -> bool {
        matches!(self.phase, Phase::ExitTouching | Phase::Exited)
    }

    /// The grip per unit length of the per-length friction model, N/m (0 for the paper's).
    pub fn grip(&self) -> f64 {
        self.contact.grip
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

    /// Every step's record so far (the last [`Simulation::set_history_limit`] steps when
    /// bounded).
    pub fn history(&self) -> &[NeedleSample] {
        let keep = self.history_limit.unwrap_or(usize::MAX);
        &self.history[self.history.len().saturating_sub(keep)..]
    }

    /// Keeps at most the last `limit` steps in the history (`None`, the default, keeps
    /// every step: about 120 bytes a step). Samples past the limit are dropped oldest
    /// first; [`Simulation::take_history`] streams them out instead.
    pub fn set_history_limit(&mut self, limit: Option<usize>) {
        self.history_limit = limit;
        self.trim_history();
    }

    /// Most steps the history keeps (`None`: all).
    pub fn history_limit(&self) -> Option<usize> {
        self.history_limit
    }

    /// Returns the history and clears it (stream it to disk in a long run).
    pub fn take_history(&mut self) -> Vec<NeedleSample> {
        let keep = self.history().len();
        let mut h = std::mem::take(&mut self.history);
        h.drain(..h.len() - keep);
        h
    }

    /// Drops the oldest samples past the limit, in batches (amortised O(1) a step).
    fn trim_history(&mut self) {
        if let Some(limit) = self.history_limit {
            if self.history.len() > limit.saturating_mul(2).max(limit + 1024) {
                let drop = self.history.len() - limit;
                self.history.drain(..drop);
            }
        }
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
        let origin = self.entry.or(self.start_tip).unwrap_or(tip);
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
        if self.needle.is_none() && !self.boundary.acts_each_step() {
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

    /// The force each held set's supports (`[[fixed]]`, `[[prescribed]]`) exert on the
    /// body, from the forces of the last step ([`Boundary::reactions`]).
    pub fn reactions(&mut self) -> Result<Vec<Reaction>, SimulationError> {
        let g = self.params.gravity.map(|g| g as f64);
        Ok(self.boundary.reactions(self.backend.as_mut(), g)?)
    }

    /// The held sets and loads.
    pub fn boundary(&self) -> &Boundary {
        &self.boundary
    }

    /// The divergence guard: an error naming the step and node if a position or velocity
    /// is not finite or a free node is faster than `physics.max_speed`. Run every
    /// `physics.check_every` steps by [`Simulation::step`] and [`Simulation::step_n`].
    pub fn check(&mut self) -> Result<(), SimulationError> {
        needlesim_core::backend::check_bounded(self.backend.as_mut(), self.max_speed)?;
        Ok(())
    }

    /// The second half of a step, once the forces are in: the surface loads, the
    /// integration, the clock, the held sets' projection and the divergence guard.
    fn load_integrate_project(&mut self) -> Result<(), SimulationError> {
        self.boundary
            .apply_loads(self.backend.as_mut(), self.time)?;
        self.backend.integrate();
        self.time += self.dt;
        self.steps += 1;
        self.boundary.project(self.backend.as_mut(), self.time)?;
        if self.steps.is_multiple_of(self.check_every) {
            self.check()?;
        }
        Ok(())
    }

    /// Runs one step.
    pub fn step(&mut self) -> Result<(), SimulationError> {
        let (Some(prev), Some(_)) = (self.prev, self.needle) else {
            if !self.boundary.acts_each_step() {
                return self.step_n(1);
            }
            self.backend.compute_forces();
            return self.load_integrate_project();
        };
        if let Some(s) = &self.script {
            self.needle = Some(s.pose_at(self.time + self.dt));
        }
        // `prev` is the pose of the last step: the tip sweeps from there even when the
        // caller moved the needle with `set_pose` in between.
        let now = self.needle.expect("needle present");
        self.prev = Some(now);
        self.contact(&prev, &now)?;
        self.constrain(&prev, &now)?;
        self.backend.compute_forces();
        self.apply_friction(&prev, &now)?;
        self.load_integrate_project()?;
        if self.record {
            self.start_tip.get_or_insert(now.tip());
            self.history.push(NeedleSample {
                step: self.steps,
                time: self.time,
                tip: now.tip(),
                direction: now.direction(),
                force: self.force,
                state: self.state(),
                active_nodes: self.backend.n_active(),
                needle_nodes: self.nodes.len(),
            });
            self.trim_history();
        }
        Ok(())
    }

    fn per_length(&self) -> Option<PerLengthFriction> {
        match self.contact.friction {
            FrictionModel::PerLength(p) => Some(p),
            FrictionModel::Paper(_) => None,
        }
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

    fn node_velocity(&mut self, k: usize) -> Result<[f64; 3], SimError> {
        let i = self.nodes[k].index as usize;
        let mut v = [[0.0f32; 4]];
        self.backend.read(NodeField::Velocity, i..i + 1, &mut v)?;
        Ok(xyz(v[0]))
    }

    #[allow(clippy::too_many_arguments)]
    fn add(
        &mut self,
        role: NodeRole,
        x: [f64; 3],
        s: f64,
        seeds: &[u32],
        v: [f64; 3],
        friction: FrictionState,
    ) -> Result<(), EditError> {
        self.add_with_offset(role, x, s, seeds, v, friction, [0.0; 3])
    }

    #[allow(clippy::too_many_arguments)]
    fn add_with_offset(
        &mut self,
        role: NodeRole,
        x: [f64; 3],
        s: f64,
        seeds: &[u32],
        v: [f64; 3],
        friction: FrictionState,
        offset: [f64; 3],
    ) -> Result<(), EditError> {
        let cand = self.editor.rings(seeds, 2);
        let index = self.editor.add_node_with_offset(
            self.backend.as_mut(),
            f32x3(x),
            f32x3(v),
            &cand,
            offset,
        )?;
        self.nodes.push(NeedleNode {
            index,
            role,
            friction,
            s,
            axial: 0.0,
            limit: 0.0,
        });
        Ok(())
    }

    fn remove(&mut self) -> Result<NeedleNode, EditError> {
        self.editor.remove_last(self.backend.as_mut())?;
        let node = self.nodes.pop().ok_or(EditError::NothingToRemove)?;
        if matches!(node.role, NodeRole::Surface | NodeRole::Exit) {
            if let Some(sp) = self.splits.pop() {
                self.unsplit(&sp);
            }
            self.phase = if node.role == NodeRole::Surface {
                Phase::Outside
            } else {
                Phase::Inside
            };
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

    /// Adds the Surface or Exit node at `point` on surface triangle `id`, pinned to the
    /// needle (sticking), and splits the triangle around it.
    fn pin_at_surface(
        &mut self,
        role: NodeRole,
        id: usize,
        point: [f64; 3],
        now: &Needle,
        v_tip: [f64; 3],
    ) -> Result<(), SimulationError> {
        let corners = self.triangles[id];
        let s = dot(sub(point, now.base()), now.direction());
        self.add(role, point, s, &corners, v_tip, FrictionState::Stick)
            .map_err(|e| self.edit(e))?;
        self.split_at_last(id);
        Ok(())
    }

    /// Splits triangle `id` around the newest needle node.
    fn split_at_last(&mut self, id: usize) {
        let node = self.nodes.last().expect("just added").index;
        let sp = split_triangle(&mut self.triangles, id, node);
        self.grid.remove(id as u32);
        for tid in [id, sp.appended_at, sp.appended_at + 1] {
            let c = self.triangles[tid].map(|v| self.rest_of(v));
            self.grid.insert(tid as u32, c);
        }
        self.splits.push(sp);
    }

    fn rest_of(&self, v: u32) -> [f64; 3] {
        self.editor.rest_position(v as usize).map(|x| x as f64)
    }

    fn edit(&self, source: EditError) -> SimulationError {
        SimulationError::Edit {
            step: self.steps,
            source,
        }
    }

    /// The state machine: surface contact, puncture, node addition and removal.
    fn contact(&mut self, prev: &Needle, now: &Needle) -> Result<(), SimulationError> {
        let t = now.direction();
        let tip = now.tip();
        let v_tip = self.needle_velocity(prev, now, now.length());
        self.swept_from = prev.tip();
        if self.phase != Phase::Outside {
            self.check_motion(prev, now, None)?;
        }
        match self.phase {
            Phase::Outside => {
                let hit = self
                    .surface_crossing(prev.tip(), tip, true)
                    .map_err(|e| self.edit(e.into()))?;
                let Some((id, point)) = hit else {
                    return Ok(());
                };
                self.check_motion(prev, now, Some(point))?;
                self.pin_at_surface(NodeRole::Surface, id, point, now, v_tip)?;
                self.entry.get_or_insert(point);
                self.phase = Phase::Touching;
            }
            Phase::Touching | Phase::ExitTouching => {
                let exit = self.phase == Phase::ExitTouching;
                let sp = *self.splits.last().expect("Touching has a split triangle");
                let mut c = [[0.0f32; 4]; 3];
                self.backend
                    .read_nodes(NodeField::Position, &sp.original, &mut c)
                    .map_err(|e| self.edit(e.into()))?;
                let pinned = at(now, self.nodes.last().expect("pinned node").s);
                let angle = mean_cone_angle(pinned, c.map(xyz), t);
                let mut outcome = self.contact.thresholds.touching(angle);
                if let Some(f) = self.contact.puncture_force {
                    outcome = match outcome {
                        TouchingOutcome::Release => TouchingOutcome::Release,
                        _ if self.pinned_axial > f => TouchingOutcome::Puncture,
                        _ => TouchingOutcome::Stay,
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
                        self.phase = Phase::Inside;
                        self.nodes[0].friction = FrictionState::Slip;
                        self.cut_depth = self.depth_of(tip, t);
                        self.inside(now, v_tip)?;
                    }
                    (TouchingOutcome::Puncture, true) => {
                        self.phase = Phase::Exited;
                        self.nodes.last_mut().expect("exit node").friction = FrictionState::Slip;
                        self.exited(now, v_tip)?;
                    }
                }
            }
            Phase::Inside => self.inside(now, v_tip)?,
            Phase::Exited => self.exited(now, v_tip)?,
        }
        Ok(())
    }

    /// Tip past the far surface: only the Exit node is checked; the tip re-enters when
    /// pulled back behind it.
    fn exited(&mut self, now: &Needle, v_tip: [f64; 3]) -> Result<(), SimulationError> {
        let pos = self.node_positions().map_err(|e| self.edit(e.into()))?;
        let d = dot(
            sub(now.tip(), *pos.last().expect("exit node")),
            now.direction(),
        );
        self.positions = pos.iter().map(|x| vec4(*x, 0.0)).collect();
        if d < 0.0 {
            self.remove().map_err(|e| self.edit(e))?;
            self.inside(now, v_tip)?;
        }
        Ok(())
    }

    /// Inside: keep a Shaft node per spacing and the Tip node at the tip; detect the far
    /// surface.
    fn inside(&mut self, now: &Needle, v_tip: [f64; 3]) -> Result<(), SimulationError> {
        let (t, tip, h) = (now.direction(), now.tip(), self.spacing);
        let advancing = dot(v_tip, t) > 0.0;
        let per_length = self.per_length().is_some();
        let mut pos = self.node_positions().map_err(|e| self.edit(e.into()))?;
        let mut edited = false;
        let mut carried = None;
        let seeds = |nodes: &[NeedleNode]| -> Vec<u32> {
            nodes.iter().rev().take(2).map(|n| n.index).collect()
        };
        loop {
            let has_tip = self.nodes.last().is_some_and(|n| n.role == NodeRole::Tip);
            let last = self.nodes.len() - 1 - has_tip as usize;
            let role = self.nodes[last].role;
            let d = dot(sub(tip, pos[last]), t);
            if has_tip && (d >= 1.5 * h || (role == NodeRole::Shaft && d < 0.5 * h) || d < 0.25 * h)
            {
                // Taken off to edit the shaft behind it: re-added below with its load.
                if carried.is_none() {
                    carried = Some(self.tip_load()?);
                }
                self.remove().map_err(|e| self.edit(e))?;
                pos.pop();
                edited = true;
                continue;
            }
            let lost = |sim: &Self, ahead: f64| SimulationError::NodesLost {
                step: sim.steps,
                node: sim.nodes[last].index,
                role,
                ahead,
            };
            if role == NodeRole::Shaft && d < 0.5 * h {
                if advancing && d < 0.0 {
                    return Err(lost(self, -d));
                }
                self.remove().map_err(|e| self.edit(e))?;
                pos.pop();
                edited = true;
                continue;
            }
            if d >= 1.5 * h {
                let s = dot(sub(pos[last], now.base()), t) + h;
                let x = at(now, s);
                let (v, state) = self.new_node_motion(has_tip, v_tip)?;
                let sd = seeds(&self.nodes);
                self.add(NodeRole::Shaft, x, s, &sd, v, state)
                    .map_err(|e| self.edit(e))?;
                pos.push(x);
                edited = true;
                continue;
            }
            if !has_tip && d >= 0.5 * h {
                let sd = seeds(&self.nodes);
                let (state, v, offset) = match carried.take() {
                    Some(load) => load,
                    // The first Tip node takes over the crack front from the deepest node:
                    // it strains the tissue ahead as that node did.
                    None if per_length => {
                        let front = self.nodes[last].index;
                        let o = self
                            .editor
                            .elastic_offset(self.backend.as_mut(), front)
                            .map_err(|e| self.edit(e))?;
                        (FrictionState::Slip, v_tip, o)
                    }
                    None => (FrictionState::Stick, v_tip, [0.0; 3]),
                };
                self.add_with_offset(NodeRole::Tip, tip, now.length(), &sd, v, state, offset)
                    .map_err(|e| self.edit(e))?;
                pos.push(tip);
                self.tip_placed = tip;
                edited = true;
                continue;
            }
            if role == NodeRole::Surface && !has_tip && d < 0.0 {
                if advancing {
                    return Err(lost(self, -d));
                }
                self.remove().map_err(|e| self.edit(e))?;
                return Ok(());
            }
            break;
        }
        let has_tip = self.nodes.last().is_some_and(|n| n.role == NodeRole::Tip);
        let moved = sub(tip, self.tip_placed);
        if has_tip && !edited && dot(moved, moved).sqrt() > self.contact.refresh {
            // The refreshed Tip node keeps the load it carried: its friction state and,
            // with the per-length model, the tissue's velocity.
            // It also keeps its strain of the tissue around it (its elastic offset), so
            // that the load ahead of the tip is carried on, not released.
            let (state, v, offset) = self.tip_load()?;
            let v = if per_length { v } else { v_tip };
            let sd = seeds(&self.nodes);
            self.remove().map_err(|e| self.edit(e))?;
            self.add_with_offset(NodeRole::Tip, tip, now.length(), &sd, v, state, offset)
                .map_err(|e| self.edit(e))?;
            self.tip_placed = tip;
            pos.pop();
            pos.push(tip);
        }
        // The far side: the tip leaving the body through a surface triangle.
        let prev_tip = self.swept_from;
        if advancing {
            if let Some((id, point)) = self
                .surface_crossing(prev_tip, tip, false)
                .map_err(|e| self.edit(e.into()))?
            {
                if self.nodes.last().is_some_and(|n| n.role == NodeRole::Tip) {
                    self.remove().map_err(|e| self.edit(e))?;
                    pos.pop();
                }
                self.pin_at_surface(NodeRole::Exit, id, point, now, v_tip)?;
                pos.push(point);
                self.phase = Phase::ExitTouching;
            }
        }
        // What the needle nodes' positions are now, so that `constrain` need not read
        // them back again.
        self.positions = pos.iter().map(|x| vec4(*x, 0.0)).collect();
        Ok(())
    }

    /// What the Tip node (the last node) carries into its replacement: its friction state,
    /// velocity and, with the per-length model, its elastic offset (the paper's refresh
    /// places it strain-free).
    fn tip_load(&mut self) -> Result<(FrictionState, [f64; 3], [f64; 3]), SimulationError> {
        let k = self.nodes.len() - 1;
        let state = self.nodes[k].friction;
        let v = self.node_velocity(k).map_err(|e| self.edit(e.into()))?;
        let offset = if self.per_length().is_some() {
            self.editor
                .elastic_offset(self.backend.as_mut(), self.nodes[k].index)
                .map_err(|e| self.edit(e))?
        } else {
            [0.0; 3]
        };
        Ok((state, v, offset))
    }

    /// Velocity and friction state of a Shaft node added inside: with the per-length
    /// model, the tissue's velocity at the tip (the Tip node's) and slipping; with the
    /// paper's, the needle's and sticking.
    fn new_node_motion(
        &mut self,
        has_tip: bool,
        v_tip: [f64; 3],
    ) -> Result<([f64; 3], FrictionState), SimulationError> {
        if self.per_length().is_none() {
            return Ok((v_tip, FrictionState::Stick));
        }
        let k = self.nodes.len() - 1;
        let v = if has_tip {
            self.node_velocity(k).map_err(|e| self.edit(e.into()))?
        } else {
            v_tip
        };
        Ok((v, FrictionState::Slip))
    }

    /// The first surface triangle crossed by the segment `p0 -> p1`, from outside
    /// (`entering`) or from inside, and where. Triangles around needle nodes (the entry
    /// split) are skipped when leaving.
    fn surface_crossing(
        &mut self,
        p0: [f64; 3],
        p1: [f64; 3],
        entering: bool,
    ) -> Result<Option<(usize, [f64; 3])>, SimError> {
        if p0 == p1 {
            return Ok(None);
        }
        let needle_nodes: Vec<u32> = self.nodes.iter().map(|n| n.index).collect();
        let mut cand = self.grid.candidates(p0, p1);
        cand.retain(|&c| {
            !self.triangles[c as usize]
                .iter()
                .any(|v| needle_nodes.contains(v))
        });
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
            if (dot(nrm, seg) < 0.0) != entering {
                continue;
            }
            if best.is_none_or(|(bs, _, _)| s < bs) {
                let hit = std::array::from_fn(|k| w[0] * a[k] + w[1] * b[k] + w[2] * cc[k]);
                best = Some((s, c as usize, hit));
            }
        }
        Ok(best.map(|(_, id, hit)| (id, hit)))
    }

    /// Whether node `n` is held rigidly on the needle this step.
    fn kinematic(&self, n: &NeedleNode) -> bool {
        self.pinned(n)
            || n.friction == FrictionState::Stick
            || (n.role == NodeRole::Tip && self.per_length().is_none())
    }

    /// The Surface node while Touching the entry, the Exit node while Touching the far
    /// surface: pinned to the tip in every direction.
    fn pinned(&self, n: &NeedleNode) -> bool {
        (n.role == NodeRole::Surface && self.phase == Phase::Touching)
            || (n.role == NodeRole::Exit && self.phase == Phase::ExitTouching)
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
                p[k] = vec4(x, 0.0);
                v[k] = vec4(vn, 0.0);
            } else {
                let s = dot(sub(xyz(p[k]), now.base()), t);
                let x = at(now, s);
                let vn = self.needle_velocity(prev, now, s);
                let own = dot(xyz(v[k]), t) - dot(vn, t);
                p[k] = vec4(x, inv_mass);
                v[k] = vec4(std::array::from_fn(|c| vn[c] + own * t[c]), 0.0);
            }
        }
        self.backend.write(NodeField::Position, n0, &p)?;
        self.backend.write(NodeField::Velocity, n0, &v)?;
        self.velocities = v;
        self.positions = p;
        Ok(())
    }

    /// The shaft length each needle node represents (0 for pinned nodes), m: half the way
    /// to its neighbours along the shaft, from the entry node to the tip (or to the Exit
    /// node when the tip is past the far surface).
    fn shaft_lengths(&self, s: &[f64], length: f64) -> Vec<f64> {
        let mut order: Vec<usize> = (0..s.len())
            .filter(|&k| !self.pinned(&self.nodes[k]))
            .collect();
        order.sort_by(|&a, &b| s[a].total_cmp(&s[b]));
        let mut l = vec![0.0; s.len()];
        let (Some(&first), Some(&last)) = (order.first(), order.last()) else {
            return l;
        };
        let lo = s[first];
        let hi = match self.phase {
            Phase::Exited => s[last],
            _ => length.max(s[last]),
        };
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

    /// Friction on the needle nodes and the needle force (after the force evaluation).
    fn apply_friction(&mut self, prev: &Needle, now: &Needle) -> Result<(), SimError> {
        let m = self.nodes.len();
        let mut total = [0.0f64; 3];
        let t = now.direction();
        self.pinned_axial = 0.0;
        if m > 0 {
            let n0 = self.editor.n_mesh();
            let mut f = vec![[0.0f32; 4]; m];
            self.backend.read(NodeField::Force, n0..n0 + m, &mut f)?;
            // The positions `constrain` wrote: the force evaluation does not move nodes.
            let p = std::mem::take(&mut self.positions);
            let s: Vec<f64> = p.iter().map(|x| dot(sub(xyz(*x), now.base()), t)).collect();
            let lengths = self.shaft_lengths(&s, now.length());
            let tip_depth = self.depth_of(now.tip(), t);
            // The tip cuts while it is at the deepest point it reached (the crack front).
            let cutting = tip_depth >= self.cut_depth - 1e-9;
            self.cut_depth = self.cut_depth.max(tip_depth);
            let mut released = Vec::new();
            // The node at the crack front: the Tip node, or the deepest node until the Tip
            // node is added (none once the tip has left the body).
            let front = match self.phase {
                Phase::Inside => (0..m).max_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap_or(0),
                _ => usize::MAX,
            };
            for k in 0..m {
                let fe = xyz(f[k]);
                let node = self.nodes[k];
                let vn = self.needle_velocity(prev, now, s[k]);
                let vk = xyz(self.velocities[k]);
                if self.pinned(&node) {
                    total = std::array::from_fn(|c| total[c] + fe[c]);
                    self.pinned_axial = -dot(fe, t);
                    continue;
                }
                let (axial, normal) = split(fe, t);
                let phi = match self.contact.friction {
                    FrictionModel::PerLength(pl) => {
                        let load = self.contact.grip * lengths[k] + dot(normal, normal).sqrt();
                        let mut lim = Limits::symmetric(
                            pl.static_coefficient() * load,
                            pl.coefficient * load,
                            pl.viscous * lengths[k],
                        );
                        if k == front && cutting {
                            lim.static_forward += self.contact.cutting;
                            lim.kinetic_forward += self.contact.cutting;
                        }
                        let step = AxialStep {
                            elastic: axial,
                            velocity: dot(vk, t),
                            needle_velocity: dot(vn, t),
                            mass: 1.0 / self.editor.inverse_mass() as f64,
                            dt: self.dt,
                            damping_factor: self.params.damping_factor as f64,
                            gravity: dot(self.params.gravity.map(|g| g as f64), t),
                        };
                        let (state, phi) = per_length_step(node.friction, &step, &lim);
                        self.nodes[k].limit = lim.static_forward;
                        if state != node.friction {
                            self.nodes[k].friction = state;
                            self.nodes[k].s = s[k];
                            if state == FrictionState::Slip {
                                released.push(k);
                            }
                        }
                        phi
                    }
                    FrictionModel::Paper(pp) => {
                        if self.kinematic(&node) && node.role == NodeRole::Tip {
                            total = std::array::from_fn(|c| total[c] + fe[c]);
                            continue;
                        }
                        let state = paper_next_state(node.friction, fe, vk, vn, t, &pp);
                        if state != node.friction {
                            self.nodes[k].friction = state;
                            self.nodes[k].s = s[k];
                        }
                        match node.friction {
                            FrictionState::Stick => -axial,
                            FrictionState::Slip => {
                                dot(paper_dynamic_friction(fe, vk, vn, t, &pp), t)
                            }
                        }
                    }
                };
                self.nodes[k].axial = phi;
                // The shaft takes the normal part; the node keeps its axial force plus
                // the needle's axial force on it.
                f[k] = vec4(t.map(|x| (axial + phi) * x), 0.0);
                total = std::array::from_fn(|c| total[c] + normal[c] - phi * t[c]);
            }
            self.backend.write(NodeField::Force, n0, &f)?;
            // A node that started to slip this step moves under its force from now on.
            let inv_mass = self.editor.inverse_mass();
            for k in released {
                let mut q = p[k];
                q[3] = inv_mass;
                self.backend.write(NodeField::Position, n0 + k, &[q])?;
            }
        }
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
