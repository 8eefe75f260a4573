//! # needlesim-needle
//!
//! Needle insertion (paper section 5): the rigid needle and its pose ([`needle`]), pose
//! scripts of keyframes ([`script`]), the scene's `[needle]` table ([`config`]), the
//! segment-against-surface query with a grid broad phase ([`surface_query`]), the puncture
//! states, the 1-to-3 triangle split and the cone angle ([`puncture`]), node addition and
//! exact removal ([`node_editor`]), stick-slip friction ([`friction`]) and the sub-grid
//! sheath that carries it, the cutting force and the contact before puncture
//! ([`sheath`]), and the
//! [`Simulation`] that drives any [`needlesim_core::Backend`] through them and records the
//! needle force of every step ([`simulation`]), and checkpoints of its whole state
//! ([`checkpoint`]).
//!
//! ```no_run
//! use needlesim_core::{CpuBackend, Scene, Threading};
//! use needlesim_needle::Simulation;
//! let scene = Scene::from_file("scenes/needle_insert_extract.toml")?;
//! let prepared = Simulation::prepare(&scene)?;
//! let backend = CpuBackend::new(prepared.tissue.clone(), Threading::Parallel)?;
//! let mut sim = prepared.start(Box::new(backend))?;
//! for _ in 0..3000 {
//!     sim.step()?;
//! }
//! println!("{:?}: axial force {:.3} N", sim.state(), sim.needle_force().axial);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![warn(missing_docs)]

pub mod checkpoint;
pub mod config;
mod error;
pub mod friction;
pub mod handover;
pub mod material_point;
pub mod needle;
pub mod node_editor;
mod nodes;
pub mod puncture;
pub mod rod;
pub mod script;
pub mod sheath;
pub mod simulation;
mod splits;
mod state;
pub mod surface_query;

pub use checkpoint::{Checkpoint, CheckpointError, SceneText};
pub use config::NeedleConfig;
pub use error::SimulationError;
pub use friction::{FrictionModel, FrictionState, PaperFriction, PerLengthFriction};
pub use needle::{Needle, NeedleError};
pub use node_editor::{EditError, NodeEditor};
pub use nodes::{NeedleForce, NeedleNode, NeedleSample, NodeRole};
pub use puncture::{PunctureState, Thresholds};
pub use script::{Keyframe, PoseScript};
pub use simulation::{Prepared, Simulation, MAX_STEP_SPACINGS};
pub use surface_query::{segment_triangle, SurfaceHit, TriangleGrid};
