//! Memory estimate of a scene before anything is allocated.
//!
//! The node count comes from the scene alone (a box: the product of its lattice counts;
//! a surface file: its enclosed volume over `spacing^3` plus its surface nodes, once the
//! file is read and before it is sampled), the bytes from [`bytes_per_node`]. A scene
//! whose estimate exceeds `run.max_memory_gib` (default [`DEFAULT_MAX_MEMORY_GIB`]) is an
//! error naming the key that asked for the nodes, instead of an abort on allocation.
//! Counts are kept in f64 until they are known to fit, so no integer overflows.

use crate::error::SceneError;
use crate::scene::{Material, Scene, DEFAULT_NEIGHBOURS};

pub use crate::scene::DEFAULT_MAX_MEMORY_GIB;

/// Bytes per lattice point while a surface is sampled (inside flags and their regularised
/// copy, the cube's vertex index, column crossings).
pub const LATTICE_BYTES_PER_POINT: f64 = 8.0;

/// Bytes of one node, counted conservatively: the simulation arrays (positions,
/// velocities, forces and position remainders as 4 x 16 bytes, K neighbour slots of 8 bytes, the model's shape
/// arrays) twice (the backend's and the node editor's or device's copy), plus what
/// building needs once (f64 rest position, cell volume and mass, the f32 rest position,
/// K f64 neighbour distances and the kernel length; for the continuum models, the
/// integration corrections' solve).
pub fn bytes_per_node(material: &Material, k: usize) -> f64 {
    let k = k as f64;
    let shape = material.shape_bytes_per_node(k);
    let simulation = 64.0 + 8.0 * k + shape;
    let build = 24.0 + 8.0 + 8.0 + 16.0 + 8.0 * k + 8.0;
    // The continuum models' integration corrections (models::consistency) hold about
    // 1.2 kB of f64 per node while they are solved: M^-1/2 (288), the unknowns, the
    // search direction and the gradient (3 x 144), two mapped copies (2 x 144), the
    // residual and target (48) and L^T's output (144).
    let corrections = match material {
        Material::DebunneMeshfree(_) | Material::PointBased(_) | Material::NeoHookean(_) => {
            288.0 + 3.0 * 144.0 + 2.0 * 144.0 + 48.0 + 144.0
        }
        _ => 0.0,
    };
    2.0 * simulation + build + corrections
}

/// The nodes a tissue geometry will have, estimated before it is built.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshEstimate {
    /// Nodes (an upper bound for surfaces; may be infinite for absurd input).
    pub nodes: f64,
    /// Points of the sampling lattice (0 for a box, whose lattice is its nodes).
    pub lattice_points: f64,
    /// The scene key that sets the count, for the error.
    pub key: &'static str,
    /// What the count comes from, in words, for the error.
    pub what: String,
}

impl MeshEstimate {
    /// An already built node cloud of `nodes` nodes.
    pub fn built(nodes: usize) -> MeshEstimate {
        MeshEstimate {
            nodes: nodes as f64,
            lattice_points: 0.0,
            key: "tissue.geometry",
            what: format!("{nodes} tissue nodes"),
        }
    }
}

/// A scene's memory estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryEstimate {
    /// Nodes: tissue plus extra (needle) slots.
    pub nodes: f64,
    /// Estimated bytes.
    pub bytes: f64,
    /// The limit in bytes (`run.max_memory_gib`).
    pub limit: f64,
}

const GIB: f64 = (1u64 << 30) as f64;

/// The estimate of `mesh` plus `extra_nodes` node slots for `scene`, or an error if it
/// exceeds `run.max_memory_gib`. The error names `extra_key` when the extra nodes are the
/// larger part, `tissue.neighbours` when the nodes would fit with the default number of
/// neighbours but not with more, else `mesh.key`; it gives the node count, the bytes and
/// the override key.
pub fn check_memory(
    scene: &Scene,
    mesh: &MeshEstimate,
    extra_nodes: f64,
    extra_key: &str,
) -> Result<MemoryEstimate, SceneError> {
    let k = scene.tissue.neighbours;
    let per_node = bytes_per_node(&scene.material, k);
    let nodes = mesh.nodes + extra_nodes;
    let bytes_at = |per_node: f64| nodes * per_node + mesh.lattice_points * LATTICE_BYTES_PER_POINT;
    let bytes = bytes_at(per_node);
    let limit = scene.run.max_memory_gib * GIB;
    // Written so that NaN fails too.
    if bytes <= limit {
        return Ok(MemoryEstimate {
            nodes,
            bytes,
            limit,
        });
    }
    let at_default = bytes_at(bytes_per_node(&scene.material, DEFAULT_NEIGHBOURS));
    let (key, cure) = if extra_nodes > mesh.nodes {
        (
            extra_key.to_string(),
            format!("fewer nodes for `{extra_key}`"),
        )
    } else if k > DEFAULT_NEIGHBOURS && at_default <= limit {
        (
            "tissue.neighbours".to_string(),
            "fewer `tissue.neighbours`".to_string(),
        )
    } else {
        let cure = match mesh.key {
            "tissue.geometry.spacing" => "a coarser `tissue.geometry.spacing`".to_string(),
            "tissue.geometry.scale" => {
                "a smaller `tissue.geometry.scale` (0.001 for a file in millimetres)".to_string()
            }
            "tissue.geometry.nodes" => "fewer `tissue.geometry.nodes`".to_string(),
            other => format!("a smaller `{other}`"),
        };
        (mesh.key.to_string(), cure)
    };
    let extra = if extra_nodes > 0.0 {
        format!(" and {extra_nodes:.3e} node slots for `{extra_key}`")
    } else {
        String::new()
    };
    Err(SceneError::invalid(
        key,
        format!(
            "needs about {nodes:.3e} nodes ({}{extra}) and {:.3e} bytes ({:.1} GiB, {per_node:.0} \
             bytes per node with {k} neighbours and model {}), more than the limit of {} GiB: \
             choose {cure}, or raise `run.max_memory_gib`",
            mesh.what,
            bytes,
            bytes / GIB,
            scene.material.short_name(),
            scene.run.max_memory_gib,
        ),
    ))
}
