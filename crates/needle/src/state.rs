//! The needle simulation's changing state: everything a step updates besides the backend's
//! arrays and the node editor. A checkpoint stores it whole.

use crate::handover::Handover;
use crate::needle::Needle;
use crate::nodes::{NeedleForce, NeedleNode, NeedleSample};
use crate::puncture::PunctureState;
use crate::sheath::{FrontElement, Patch};
use crate::splits::SurfaceSplits;
use needlesim_core::math::Vec4;

/// The stage of the needle's passage through the body: in through the entry surface
/// (Outside, Touching, Inside) and out through the far one (ExitTouching, Exited). The
/// public [`PunctureState`] is the tip's view of it (three states).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(crate) enum Passage {
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

impl Passage {
    pub(crate) fn state(self) -> PunctureState {
        match self {
            Passage::Outside | Passage::Exited => PunctureState::Outside,
            Passage::Touching | Passage::ExitTouching => PunctureState::Touching,
            Passage::Inside => PunctureState::Inside,
        }
    }
}

/// What a step wrote to the needle nodes (indices `n_mesh..n_mesh + len`) before the
/// integration.
#[derive(Debug, Clone, Default)]
pub(crate) struct Written {
    /// The needle nodes' indices when written.
    pub nodes: Vec<u32>,
    pub positions: Vec<Vec4>,
    pub velocities: Vec<Vec4>,
    pub forces: Vec<Vec4>,
}

/// The needle nodes' state after an integration, for the nodes `nodes` (their indices,
/// oldest first): positions (world, with the inverse mass in `w`) and velocities, as a
/// read of [`needlesim_core::NodeField::Position`] and `Velocity` would give them.
#[derive(Debug, Clone, Default)]
pub(crate) struct Integrated {
    pub nodes: Vec<u32>,
    pub positions: Vec<Vec4>,
    pub velocities: Vec<Vec4>,
}

/// The needle simulation's state besides the tissue arrays.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct NeedleState {
    /// The pose for the coming step.
    pub needle: Option<Needle>,
    /// The pose at the end of the last step.
    pub prev: Option<Needle>,
    /// Surface triangles with the entry and exit splits.
    pub surface: SurfaceSplits,
    pub phase: Passage,
    /// Needle nodes, oldest first (a stack).
    pub nodes: Vec<NeedleNode>,
    /// Velocities written to the needle nodes this step.
    pub velocities: Vec<Vec4>,
    /// Positions written to the needle nodes this step.
    pub positions: Vec<Vec4>,
    /// Velocities of the needle nodes as read with their positions at the start of this
    /// step, while no needle node has been edited since (else empty), for `constrain`. Not
    /// in checkpoints: a restored run reads them again.
    #[serde(skip)]
    pub read_velocities: Vec<Vec4>,
    /// What this step wrote to the needle nodes before the integration: positions (with
    /// their inverse masses), velocities and forces, for [`NeedleState::integrated`].
    #[serde(skip)]
    pub written: Option<Written>,
    /// The needle nodes' positions and velocities after the last step's integration, as
    /// the host integrated them from what it wrote ([`crate::simulation`] module docs,
    /// "One readback"); taken by the next step's first use. Not in checkpoint files: a
    /// run restored from one reads them back once (an in-memory checkpoint keeps them;
    /// either way they equal what the backend holds, which the host wrote back).
    #[serde(skip)]
    pub integrated: Option<Integrated>,
    /// Where the Tip node was last placed.
    pub tip_placed: [f64; 3],
    /// How far the tip advanced along the needle this step, m (its depth past the entry
    /// point now less then: a turn about the entry point advances nothing). Set at the
    /// start of a step.
    #[serde(skip)]
    pub advance: f64,
    /// The tip at the start of this step's sweep.
    pub swept_from: [f64; 3],
    /// Where the tip first touched the surface.
    pub entry: Option<[f64; 3]>,
    /// Deepest tip depth past the entry so far (the crack front), m.
    pub cut_depth: f64,
    /// `(depth, time)` each time the crack front advanced, in order, with a viscoelastic
    /// tissue only (the age of the cut at a depth sets how far its grip has relaxed).
    pub cut_times: Vec<(f64, f64)>,
    /// Axial force of the pinned (Surface or Exit) node on the needle in the last step, N
    /// (per-length model: of the contact patch while Touching the entry).
    pub pinned_axial: f64,
    /// The tip's element at the crack front (per-length model, [`crate::sheath`]).
    pub front: FrontElement,
    /// The contact patch on the entry surface, while Touching and while the entry
    /// membrane tears (per-length model).
    pub patch: Option<Patch>,
    /// The region the crack front has cut into (the last membrane punctured); `None`
    /// while the tip is not inside.
    #[serde(default)]
    pub region: Option<u16>,
    /// The region whose membrane the crack front is denting, not yet punctured.
    #[serde(default)]
    pub denting: Option<u16>,
    /// The regions whose membranes this insertion has punctured (in order): the crack
    /// front crosses back into them without a membrane.
    #[serde(default)]
    pub punctured: Vec<u16>,
    /// Depth of the tip in the undeformed tissue in the last step, m.
    #[serde(default)]
    pub tissue_depth: Option<f64>,
    /// The elastic forces node edits (additions and removals) changed, still being
    /// handed over ([`crate::handover`]).
    pub handover: Option<Handover>,
    /// This step's edits so far: the elastic force of each node a removal can change, as
    /// it was before the step's first edit that could change it (sorted by node). Emptied
    /// when the step's edits are done.
    #[serde(skip)]
    pub before_edits: Vec<(u32, [f32; 4])>,
    /// The fewest nodes the node editor's log held during this step's edits (`None`
    /// before the step's first edit; cleared when they are done): the additions above it
    /// are this step's.
    #[serde(skip)]
    pub edit_low: Option<usize>,
    /// Whether this step's edits are handed over in full ([`crate::handover`]): a node other
    /// than the Tip node added or removed, or the Tip node's last removal on the way out
    /// or its return behind the crack front.
    #[serde(skip)]
    pub edit_shaft: bool,
    /// Whether this step refreshed the Tip node ([`crate::handover`]: handed over within
    /// the time to the next refresh).
    #[serde(skip)]
    pub edit_refresh: bool,
    /// The handover time of this step's edits (any edit of the per-length model's needle
    /// nodes), for the tip element's share ([`crate::sheath::FreeFade`]); `None` when the
    /// step made none.
    #[serde(skip)]
    pub edit_front: Option<f64>,
    /// The force on the needle in the last step.
    pub force: NeedleForce,
    pub history: Vec<NeedleSample>,
    /// Whether a step appends to the history.
    pub record: bool,
    /// Most history samples kept (the oldest go first); `None` keeps every one.
    pub history_limit: Option<usize>,
    /// The depth origin before any contact: where the needle's axis at the first
    /// recorded step meets the tissue's rest surface (that step's tip when it misses).
    pub depth_origin: Option<[f64; 3]>,
}

impl NeedleState {
    /// The state before the first step: needle at its start pose, no contact.
    pub fn new(needle: Option<Needle>, surface: SurfaceSplits) -> NeedleState {
        NeedleState {
            needle,
            prev: needle,
            surface,
            phase: Passage::Outside,
            nodes: Vec::new(),
            velocities: Vec::new(),
            positions: Vec::new(),
            read_velocities: Vec::new(),
            written: None,
            integrated: None,
            tip_placed: [0.0; 3],
            advance: 0.0,
            swept_from: [0.0; 3],
            entry: None,
            cut_depth: f64::NEG_INFINITY,
            cut_times: Vec::new(),
            pinned_axial: 0.0,
            front: FrontElement::default(),
            patch: None,
            region: None,
            denting: None,
            punctured: Vec::new(),
            tissue_depth: None,
            handover: None,
            before_edits: Vec::new(),
            edit_low: None,
            edit_shaft: false,
            edit_refresh: false,
            edit_front: None,
            force: NeedleForce::default(),
            history: Vec::new(),
            record: true,
            history_limit: None,
            depth_origin: None,
        }
    }

    /// The puncture state the tip is in.
    pub fn puncture_state(&self) -> PunctureState {
        self.phase.state()
    }
}
