//! # needlesim-gpu
//!
//! The wgpu compute backend (one pipeline wrapper per WGSL kernel in `shaders/`,
//! implementing `needlesim_core::Backend`). Not written yet: this crate reserves its place
//! in the workspace and exports nothing.
