//! # needlesim-gpu
//!
//! The wgpu compute backend: every tissue model as WGSL kernels (the repository's top-level
//! `shaders/`, one file per kernel plus shared code), on any GPU that wgpu drives (Vulkan,
//! Metal, DX12) and on Mesa's software Vulkan driver (lavapipe) in CI. The CPU backend of `needlesim-core` is
//! the reference each kernel mirrors; the tests compare the two. Every blocking readback is
//! counted ([`needlesim_core::Backend::readbacks`]); where the device has timestamp queries,
//! [`GpuBackend::enable_profiling`] times each kernel ([`GpuBackend::kernel_times`]).
//!
//! ```no_run
//! use needlesim_core::{Backend, Scene, Tissue};
//! use needlesim_gpu::GpuBackend;
//! let scene = Scene::from_file("scenes/cube_sag_lshm.toml")?;
//! let tissue = Tissue::from_scene(&scene)?;
//! let mut gpu = GpuBackend::new(&tissue)?;
//! println!("{}", gpu.adapter());
//! gpu.step(1000); // recorded in batches, no readback
//! gpu.check_finite()?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![warn(missing_docs)]

mod backend;
mod buffers;
mod context;
pub mod kernels;
mod layout;
pub mod models;
mod params;
mod profile;
mod scatter;

pub use backend::{largest_buffer, GpuBackend};
pub use buffers::{Binding, Buffers};
pub use context::{GpuContext, GpuError};
pub use profile::KernelTime;
