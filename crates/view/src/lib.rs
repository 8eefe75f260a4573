//! # needlesim-view
//!
//! Draws a needle insertion with wgpu: the deforming tissue surface (per-vertex normals from
//! the triangles, two-sided Blinn-Phong lighting, translucent so the shaft inside shows),
//! the needle as a shaded cylinder with a conical tip, the needle nodes as camera-facing
//! squares drawn over everything, and an inset plot of the axial needle force against the
//! tip depth in the bottom-right corner.
//!
//! Gathering and drawing are separate: [`Frame::gather`] copies what is drawn out of a
//! [`Simulation`], and [`Renderer`] draws any [`Frame`] (tests build synthetic ones).
//! [`Renderer::render_to_image`] renders offscreen and reads the pixels back;
//! [`screenshot`] does everything for one PNG. With the feature `window`,
//! `window::run_window` opens an interactive window (winit, X11).
//!
//! ```no_run
//! # fn demo(sim: &mut needlesim_needle::Simulation) -> Result<(), needlesim_view::ViewError> {
//! needlesim_view::screenshot(sim, std::path::Path::new("frame.png"), 800, 600)?;
//! # Ok(()) }
//! ```
//!
//! The colours of the picture are fixed ([`colors`]), so that tests can find each element
//! in the pixels. No text is drawn (no font dependency).

#![warn(missing_docs)]

pub mod camera;
pub mod colors;
pub mod frame;
pub mod geometry;
pub mod render;
#[cfg(feature = "window")]
pub mod window;

pub use camera::Camera;
pub use frame::{Frame, Marker};
pub use render::{headless_device, Image, Renderer, MAX_SIZE};

use needlesim_needle::Simulation;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why a picture could not be made.
#[derive(Debug, Error)]
pub enum ViewError {
    /// No GPU adapter (no Vulkan, Metal or DX12 driver).
    #[error(
        "no GPU adapter for rendering ({0}); on Linux without a GPU install Mesa's software \
         Vulkan driver (apt-get install mesa-vulkan-drivers)"
    )]
    NoAdapter(String),
    /// The adapter refused the device.
    #[error("the GPU adapter {adapter} cannot create a rendering device: {message}")]
    Device {
        /// Adapter name.
        adapter: String,
        /// wgpu's message.
        message: String,
    },
    /// An image size of zero or beyond what the device allows.
    #[error("image size {width}x{height} is out of range (1 to {max} pixels per side)")]
    BadSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// Largest side allowed.
        max: u32,
    },
    /// wgpu reported an error while rendering (a validation error).
    #[error("rendering failed: {0}")]
    Render(String),
    /// Mapping the readback buffer failed.
    #[error("reading the rendered image back failed: {0}")]
    Readback(String),
    /// Reading the simulation's state failed.
    #[error("reading the simulation state: {0}")]
    Read(#[from] needlesim_core::SimError),
    /// Stepping the simulation failed (window mode).
    #[error("stepping the simulation: {0}")]
    Simulation(#[from] needlesim_needle::SimulationError),
    /// Writing a file failed.
    #[error("writing {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Encoding the PNG failed.
    #[error("encoding the PNG {path}: {message}")]
    Png {
        /// The file.
        path: PathBuf,
        /// The encoder's message.
        message: String,
    },
    /// The closure that builds the simulation failed (window mode: start and reset).
    #[error("building the simulation: {0}")]
    Build(String),
    /// The simulation's GPU device could not be made on the window's adapter.
    #[error(transparent)]
    Gpu(#[from] needlesim_gpu::GpuError),
    /// The window could not be opened or driven.
    #[error("window: {0}")]
    Window(String),
}

/// Renders the current state of `sim` (camera framed automatically) into a PNG of
/// `width` x `height` pixels, on a device of its own.
pub fn screenshot(
    sim: &mut Simulation,
    path: &Path,
    width: u32,
    height: u32,
) -> Result<(), ViewError> {
    render::check_size(width, height, MAX_SIZE)?;
    let frame = Frame::gather(sim)?;
    let camera = Camera::frame(&frame);
    let mut renderer = Renderer::headless()?;
    renderer
        .render_to_image(&frame, &camera, width, height)?
        .save_png(path)
}
