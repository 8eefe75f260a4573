//! # needlesim-core
//!
//! The CPU side of needlesim: scenes (TOML files, or made in code with
//! [`Scene::builder`]), tissue geometry (generated boxes, OBJ surfaces filled with nodes),
//! neighbour lists, node state, the tissue models, the integrator, the [`Backend`] trait
//! and the CPU backend.
//!
//! ```no_run
//! use needlesim_core::{Backend, CpuBackend, Scene, Threading, Tissue};
//! let scene = Scene::from_file("scenes/cube_sag_lshm.toml")?;
//! let tissue = Tissue::from_scene(&scene)?;
//! let mut backend = CpuBackend::new(tissue, Threading::Parallel)?;
//! backend.step(100);
//! backend.check_finite()?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![warn(missing_docs)]
// Index loops over x, y, z and over neighbour slots read closer to the equations.
#![allow(clippy::needless_range_loop)]

pub mod backend;
pub mod boundary;
mod build_tissue;
pub mod calibration;
pub mod cpu;
pub mod error;
pub mod frame;
pub mod geometry;
pub mod integrator;
pub mod math;
pub mod models;
pub mod neighbours;
pub mod parallel;
pub mod regions;
pub mod scene;
pub mod stability;
pub mod state;
pub mod stepper;
pub mod tissue;
mod validate;

/// The vector math crate the kernels use (f32 `Vec3`, `Mat3`, `Quat`; f64 `DVec3`),
/// re-exported so that callers of the model functions use the same version.
pub use glam;

pub use backend::{Backend, NodeField, NodeSelection};
pub use cpu::{CpuBackend, Threading};
pub use error::{GeometryError, SceneError, SimError};
pub use math::Vec4;
pub use scene::builder as scene_builder;
pub use scene::builder::SceneBuilder;
pub use scene::{Material, Scene};
pub use stepper::Stepper;
pub use tissue::Tissue;
