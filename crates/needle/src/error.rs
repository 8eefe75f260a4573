//! Why a needle simulation cannot be built or stepped.

use crate::node_editor::EditError;
use crate::nodes::NodeRole;
use needlesim_core::{SceneError, SimError};
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
        /// The limit ([`crate::simulation::MAX_STEP_SPACINGS`] node spacings), m.
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
