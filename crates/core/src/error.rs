//! Typed errors of the core crate. Every variant names what was wrong: the key of a scene
//! file, the file and line of a mesh, the node or the step of a simulation.

use std::path::PathBuf;
use thiserror::Error;

/// A scene that cannot be read or does not make sense.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("cannot read scene file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// TOML syntax error, unknown key, missing key or a value of the wrong type. The message
    /// of the TOML parser names the key and the line.
    #[error("scene {origin}: {message}")]
    Parse {
        /// Where the scene came from (a path or `<string>`).
        origin: String,
        /// The parser's message, which names the key.
        message: String,
    },
    /// A value has the right type but is out of its valid range.
    #[error("scene key `{key}`: {reason}")]
    InvalidValue {
        /// Dotted path of the key, e.g. `material.stiffness`.
        key: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The tissue geometry could not be built.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
}

impl SceneError {
    /// An out-of-range value of the dotted key `key`.
    pub fn invalid(key: impl Into<String>, reason: impl Into<String>) -> Self {
        SceneError::InvalidValue {
            key: key.into(),
            reason: reason.into(),
        }
    }
}

/// A surface mesh that cannot be used as tissue boundary.
#[derive(Debug, Error)]
pub enum GeometryError {
    /// The OBJ or STL file could not be loaded.
    #[error("cannot load surface file {path}: {message}")]
    ObjLoad {
        /// The file.
        path: PathBuf,
        /// The loader's message.
        message: String,
    },
    /// The surface file holds no triangle.
    #[error("surface file {path} contains no triangles")]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// A vertex coordinate is NaN or infinite (after `scale`; OBJ and STL coordinates are
    /// read as f32, so one beyond 3.4e38 in the file is infinite).
    #[error(
        "surface file {path}: vertex {vertex} has a coordinate that is not a finite number \
         (NaN, infinite, or beyond the 3.4e38 that an OBJ or STL coordinate can hold)"
    )]
    NonFiniteVertex {
        /// The file.
        path: PathBuf,
        /// Zero-based vertex index.
        vertex: usize,
    },
    /// A triangle references the same vertex twice or has zero area.
    #[error(
        "surface file {path}: triangle {triangle} is degenerate (repeated vertex or zero area)"
    )]
    DegenerateTriangle {
        /// The file.
        path: PathBuf,
        /// Zero-based triangle index.
        triangle: usize,
    },
    /// An edge is used by only one triangle: the surface has a hole.
    #[error("surface file {path}: surface is open, edge ({a}, {b}) belongs to only one triangle")]
    OpenSurface {
        /// The file.
        path: PathBuf,
        /// First vertex of the edge.
        a: u32,
        /// Second vertex of the edge.
        b: u32,
    },
    /// An edge is used by more than two triangles, or twice in the same direction.
    #[error(
        "surface file {path}: surface is not manifold or not consistently oriented at edge ({a}, {b})"
    )]
    NonManifold {
        /// The file.
        path: PathBuf,
        /// First vertex of the edge.
        a: u32,
        /// Second vertex of the edge.
        b: u32,
    },
    /// The closed surface encloses no volume (or is inside out).
    #[error("surface {path} encloses a non-positive volume ({volume} m^3): inside out or flat")]
    NonPositiveVolume {
        /// The file.
        path: PathBuf,
        /// Signed volume.
        volume: f64,
    },
    /// Resampling at the scene's spacing found no surface: the body is thinner than the
    /// spacing everywhere.
    #[error("surface {path}: no lattice point of spacing {spacing} m falls inside it (the body is thinner than the spacing; reduce `tissue.geometry.spacing`, or check `scale`)")]
    TooThin {
        /// The file.
        path: PathBuf,
        /// The spacing.
        spacing: f64,
    },
    /// Sampling produced too few nodes for the requested neighbour count.
    #[error("geometry has {nodes} nodes, too few for `tissue.neighbours` = {neighbours} (needs at least {neighbours} + 1)")]
    TooFewNodes {
        /// Nodes produced.
        nodes: usize,
        /// Neighbours per node asked for.
        neighbours: usize,
    },
}

/// An error while simulating.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SimError {
    /// A position or velocity became NaN or infinite: the simulation diverged.
    #[error(
        "simulation diverged at step {step}: node {node} has a non-finite {field} (a time \
         step above the stable one is the usual cause: reduce physics.dt, or use dt = \"auto\"; \
         `needlesim info` prints the critical time step; \"auto\" sizes the step at the \
         initial state, and a strongly deformed nonlinear material can need a smaller \
         one; with point based animation, a crushed neighbourhood collapses without \
         material.volume_stiffness: give it one, about young_modulus, or use neo_hookean)"
    )]
    Diverged {
        /// Step counter when it was detected.
        step: u64,
        /// The first node found with a non-finite value.
        node: usize,
        /// `position` or `velocity`.
        field: &'static str,
    },
    /// A free node moves faster than the scene's `physics.max_speed`: the explicit step is
    /// unstable (time step too large for the stiffness) and about to overflow.
    #[error(
        "simulation diverged at step {step}: node {node} moves at {speed:.3e} m/s, above \
         physics.max_speed = {limit} m/s (reduce physics.dt, or use dt = \"auto\"; \
         \"auto\" sizes the step at the initial state, and a strongly deformed nonlinear \
         material can need a smaller one; with point based animation, a crushed \
         neighbourhood collapses without material.volume_stiffness: give it one, about \
         young_modulus, or use neo_hookean)"
    )]
    Runaway {
        /// Step counter when it was detected.
        step: u64,
        /// The fastest free node.
        node: usize,
        /// Its speed in m/s.
        speed: f64,
        /// The bound.
        limit: f64,
    },
    /// A node range outside the active or allocated nodes.
    #[error("node range {start}..{end} is outside the {limit} {what} nodes")]
    OutOfRange {
        /// Range start.
        start: usize,
        /// Range end (exclusive).
        end: usize,
        /// The bound that was crossed.
        limit: usize,
        /// `active` or `allocated`.
        what: &'static str,
    },
    /// A neighbour row write whose length is not a multiple of K.
    #[error("neighbour rows must have {k} entries per node, got {len}")]
    BadRowLength {
        /// Neighbours per node.
        k: usize,
        /// Length given.
        len: usize,
    },
    /// A write to a shape information array the model does not have, or outside it.
    #[error("cannot write {len} bytes at byte {offset} of shape array `{array}`: {reason}")]
    BadShapeWrite {
        /// Array name (as listed by `Tissue::allocations`).
        array: String,
        /// Byte offset.
        offset: usize,
        /// Bytes given.
        len: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// The device (GPU) failed an operation.
    #[error("device error: {message}")]
    Device {
        /// What failed.
        message: String,
    },
    /// A batched read ([`crate::Backend::read_many`]) whose outputs do not match its
    /// requests: another number of outputs, or an output of another length than its range.
    #[error("batched read: {what}: expected {expected}, got {got}")]
    BadReadLength {
        /// `outputs` (their number) or `nodes` (an output's length).
        what: &'static str,
        /// Outputs, or nodes, the requests ask for.
        expected: usize,
        /// Outputs, or nodes, given.
        got: usize,
    },
}
