//! # needlesim
//!
//! Needle insertion into soft tissue modelled with meshfree particle methods (Shahingohar,
//! de Ribaupierre and Eagleson, "GPU accelerated needle insertion simulation using meshfree
//! methods"). This facade re-exports the engine crates and adds the scene runner used by
//! the `needlesim` command line tool: it steps a scene, writes a CSV row and a ParaView
//! surface frame every few steps, and reports what a scene allocates. The command line
//! tool (crate `needlesim-cli`) and the validation report with its PNG plots (crate
//! `needlesim-report`) are crates of their own, so that this library pulls in no plotting
//! or command line dependencies.
//!
//! ```no_run
//! use needlesim::{run_scene, RunOptions, Scene};
//! let scene = Scene::from_file("scenes/cube_sag_lshm.toml")?;
//! let summary = run_scene(&scene, &RunOptions::new("out/cube"), |_, _| {})?;
//! println!("{} steps at {:.0} steps/s", summary.steps, summary.steps_per_second());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![warn(missing_docs)]

pub mod folder_lock;
pub mod frame;
pub mod info;
pub mod needle_output;
pub mod output;
pub mod runner;
pub mod sweep;

pub use frame::FrameMetrics;
pub use info::SceneInfo;
pub use needlesim_core as core;
pub use needlesim_core::{
    Backend, CpuBackend, GeometryError, Material, NodeField, Scene, SceneError, SimError,
    Threading, Tissue,
};
pub use needlesim_gpu as gpu;
/// The haptic loop (feature `haptic`).
#[cfg(feature = "haptic")]
pub use needlesim_haptic as haptic;
pub use needlesim_needle as needle;
/// The renderer: screenshots (feature `render`) and the live window (feature `view`).
#[cfg(feature = "render")]
pub use needlesim_view as view;
pub use runner::{
    make_backend, run_scene, start_simulation, start_simulation_on, time_step_warning, RunError,
    RunOptions, RunSummary, CHECKPOINT_FILE, MAX_PROBED_NODES,
};

/// The default scene of `needlesim run` without a scene file: the paper's experiment, a
/// needle moved 15 cm into a 639-node cube and rotated 25 degrees (local shape matching).
pub const DEFAULT_SCENE: &str = include_str!("../scenes/paper_insertion_lshm.toml");
