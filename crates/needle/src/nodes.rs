//! The needle nodes and the needle's per-step record.

use crate::friction::FrictionState;
use crate::puncture::PunctureState;

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
    /// Axial force the needle exerted on the node in the last step, N, positive along the
    /// needle direction: its friction (with the paper's model, also the cutting force at
    /// the crack front; with the per-length model the cutting force is the front
    /// element's, [`crate::sheath::FrontElement`]).
    pub axial: f64,
    /// The friction limit in the last step (per-length model: the Coulomb cap of the
    /// node's sheath, [`crate::sheath`]), N.
    pub limit: f64,
    /// Circumferential friction force of the node's sheath in the last step (per-length
    /// model), N, positive in the sense the needle spins (right-handed about its
    /// direction). It turns the needle, not the node.
    #[serde(default)]
    pub circumferential: f64,
    /// Axial coordinate of the node from the needle base at the end of the last step, m
    /// (per-length model: the sheath's relative motion is measured from it).
    #[serde(default)]
    pub sigma: f64,
    /// The node's own motion along the needle over the last step as the sheath took it
    /// in (implicitly, end-of-step velocity times the step), m: the next step's measured
    /// motion minus this is what the sheath has still to take
    /// ([`crate::sheath::sheath_step`]).
    #[serde(default)]
    pub slide: f64,
    /// The tissue's force on the node normal to the shaft in the last step (world frame,
    /// N): what the shaft holds it with sideways.
    #[serde(default)]
    pub normal: [f64; 3],
    /// The share of its shaft length the node keeps (per-length model): 1, falling to 0
    /// while the needle is pulled back over the last Shaft node, which is removed once it
    /// has handed its length (and friction) over to the node before it.
    #[serde(default = "one")]
    pub share: f64,
    /// The tissue region the node was added in (that of its nearest neighbour at rest);
    /// its friction is that region's.
    #[serde(default)]
    pub region: u16,
    /// Friction above the node's Coulomb cap that an edit gave it (per-length model), N:
    /// the load the shaft's field assigns a node can exceed what its own tissue holds (a
    /// node of a softer layer added next to a gripping one). The cap keeps it at the edit
    /// and lets it go over [`crate::handover::HANDOVER_TIME`] from `carried_at` instead
    /// of clipping it in one step ([`crate::sheath`], node events).
    #[serde(default)]
    pub carried: f64,
    /// Simulated time `carried` was set, s.
    #[serde(default)]
    pub carried_at: f64,
    /// The node's loads were reassigned by an edit this step; its `carried` is measured at
    /// its next friction step.
    #[serde(default)]
    pub reassigned: bool,
}

fn one() -> f64 {
    1.0
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
    /// Torque of the tissue about the needle's own axis, N m, positive when it resists a
    /// right-handed spin (the circumferential friction of the sheath; 0 with the paper's
    /// model).
    #[serde(default)]
    pub torque: f64,
    /// The part of the axial force the tip's elements carry, N (per-length model: the
    /// cutting force, a membrane being dented or torn, the contact patch before the entry
    /// punctures; the rest of `axial` is the shaft's friction).
    #[serde(default)]
    pub tip: f64,
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
    /// The tissue region the tip is in ([`crate::Simulation::tip_region`]); `None` before
    /// the entry surface is punctured and once the tip is out.
    #[serde(default)]
    pub region: Option<u16>,
    /// Depth of the tip in the undeformed tissue ([`crate::Simulation::tissue_depth`]),
    /// m; `None` while the tip is not in contact.
    #[serde(default)]
    pub tissue_depth: Option<f64>,
}
