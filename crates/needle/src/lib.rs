//! # needlesim-needle
//!
//! Needle insertion (paper section 5). Written so far: the rigid needle and its pose
//! ([`needle`]), pose scripts of keyframes ([`script`]), and the segment-against-surface
//! query with a grid broad phase that the Outside state needs ([`surface_query`]), and the
//! surface side of the puncture state machine: states, the 1-to-3 triangle split and its
//! exact reversal, the cone angle and its thresholds ([`puncture`]), and the stick-slip
//! friction law ([`friction`]). Still to come (see the project's issues): node addition and
//! exact removal, the state machine driving a backend, and the needle force.

#![warn(missing_docs)]

pub mod config;
pub mod friction;
pub mod needle;
pub mod node_editor;
pub mod puncture;
pub mod script;
pub mod simulation;
pub mod surface_query;

pub use config::NeedleConfig;
pub use friction::{FrictionParams, FrictionState};
pub use needle::{Needle, NeedleError};
pub use node_editor::{EditError, NodeEditor};
pub use puncture::{PunctureState, Thresholds};
pub use script::{Keyframe, PoseScript};
pub use simulation::{
    NeedleForce, NeedleNode, NeedleSample, NodeRole, Prepared, Simulation, SimulationError,
};
pub use surface_query::{segment_triangle, SurfaceHit, TriangleGrid};
