//! What every tissue model implements ([`TissueModel`] for its parameters, [`ModelState`]
//! for its shape information) and the types they exchange with the backends.

use crate::calibration::UncalibratedNeighbours;
use crate::error::SceneError;
use crate::math::Vec4;
use crate::neighbours::Neighbours;
use crate::parallel::Threads;

/// A shape information array, as backends and the needle's node editor name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum ShapeArray {
    /// Mass-spring rest length per neighbour slot.
    RestLength,
    /// Rest positions (w: 0, or the node volume of the continuum models).
    RestPosition,
    /// Shape matching's shape vectors.
    ShapeVector,
    /// Warm-start rotation quaternions.
    Rotation,
    /// Cluster centre offsets of the current step.
    ClusterCentre,
    /// Inverse moment matrices of the continuum models.
    InverseMoment,
    /// The continuum models' per-step first-pass result.
    FirstPass,
    /// Per-node material parameters ([`super::material_row`]), only with several materials.
    NodeMaterial,
    /// The viscoelastic state of the continuum models with Prony terms
    /// ([`super::viscoelastic`]): per node `S_0` and one tensor per term, committed at the
    /// end of each step.
    Viscous,
}

impl ShapeArray {
    /// Whether the array holds one 4-byte element per neighbour slot (`capacity * K`,
    /// node-major like the neighbour rows) rather than one entry per node. A backend may
    /// store such arrays in another order (the GPU stores them slot-major); the byte
    /// offsets of [`crate::Backend::write_shape_bytes`] always count node-major.
    pub const fn per_slot(self) -> bool {
        matches!(self, ShapeArray::RestLength)
    }

    /// The array's name in reports and errors (`rest_length`, ...).
    pub const fn name(self) -> &'static str {
        match self {
            ShapeArray::RestLength => "rest_length",
            ShapeArray::RestPosition => "rest_position",
            ShapeArray::ShapeVector => "shape_vector",
            ShapeArray::Rotation => "rotation",
            ShapeArray::ClusterCentre => "cluster_centre",
            ShapeArray::InverseMoment => "inverse_moment",
            ShapeArray::FirstPass => "first_pass",
            ShapeArray::NodeMaterial => "node_material",
            ShapeArray::Viscous => "viscous_state",
        }
    }
}

impl std::fmt::Display for ShapeArray {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A model's entry in the registry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelInfo {
    /// The TOML tag: `model = "<tag>"` in `[material]`.
    pub tag: &'static str,
    /// Short name for file names, tables and plots (`msm`, `deb`, ...).
    pub short_name: &'static str,
    /// Human-readable name.
    pub label: &'static str,
    /// The keys that change the model's structure (its arrays or kernels): every
    /// `[[region]]` must share them with `[material]`.
    pub structural_keys: &'static [&'static str],
}

/// One row of shape information: `(array, byte offset, bytes)` in the layout of
/// [`super::ShapeInfo::bytes`].
pub type ShapeRow = (ShapeArray, usize, Vec<u8>);

/// Row `i` of `array` holding `v`.
pub fn row<T: bytemuck::Pod>(array: ShapeArray, i: usize, v: &[T]) -> ShapeRow {
    let b: &[u8] = bytemuck::cast_slice(v);
    (array, i * b.len(), b.to_vec())
}

/// A tissue model's parameters: what the registry needs to know about a model.
///
/// Implemented by the parameter struct of each model module (`MassSpringParams`, ...).
pub trait TissueModel:
    Copy + PartialEq + std::fmt::Debug + serde::Serialize + serde::de::DeserializeOwned
{
    /// The model's shape information (its arrays, with a copy of the parameters).
    type Shape: ModelState + Clone + PartialEq + std::fmt::Debug + Send + Sync;

    /// The registry entry.
    const INFO: ModelInfo;

    /// Checks the parameters; errors name `{key}.<parameter>`.
    fn validate(&self, key: &str) -> Result<(), SceneError>;

    /// The node's material parameters as the kernels read them from the `node_material`
    /// array with several materials (f32, in the units of the scene).
    fn material_row(&self) -> Vec4;

    /// Bytes per node of the shape information with `k` neighbour slots (memory
    /// estimate, [`crate::geometry::memory`]).
    fn shape_bytes_per_node(&self, k: f64) -> f64;

    /// Young's modulus (Pa) and Poisson ratio the model shows at node spacing `spacing`
    /// with `neighbours` slots (the needle's sheath needs them); the discrete models
    /// convert their calibrated stiffness ([`crate::calibration`]).
    fn elastic_moduli(
        &self,
        spacing: f64,
        neighbours: usize,
    ) -> Result<(f64, f64), UncalibratedNeighbours>;

    /// What the model cannot represent of an isotropic elastic solid, in one sentence
    /// for `needlesim info` and the docs; `None` for a model that takes E and nu as they
    /// are given.
    fn limitation(&self) -> Option<&'static str> {
        None
    }

    /// The viscoelastic Prony series ([`super::viscoelastic`]); empty (elastic) by default.
    fn prony(&self) -> super::viscoelastic::Prony {
        super::viscoelastic::Prony::elastic()
    }

    /// Adjusts the neighbour weights of the first `n` nodes before anything is built from
    /// them (mass-spring's spring shares); nothing by default.
    fn prepare_neighbours(
        &self,
        _nb: &mut Neighbours,
        _node_volumes: &[f64],
        _spacing: f64,
        _n: usize,
    ) {
    }

    /// Builds the shape information for the first `n` of `rest` (rest positions of all
    /// `capacity` slots).
    fn build(&self, rest: &[Vec4], nb: &Neighbours, n: usize, ctx: BuildContext) -> Self::Shape;
}

/// What a model's CPU force reads.
#[derive(Clone, Copy)]
pub struct ForceInput<'a> {
    /// Positions of all slots.
    pub positions: &'a [Vec4],
    /// Velocities of all slots.
    pub velocities: &'a [Vec4],
    /// Neighbour lists.
    pub nb: &'a Neighbours,
    /// Per-node material rows, with several materials ([`TissueModel::material_row`]).
    pub node_material: Option<&'a [Vec4]>,
    /// Active nodes.
    pub n: usize,
    /// Where the kernels run, and with a [`Threads::subset`] on which nodes: a model
    /// then has to get the force on each of those nodes right and may leave the others'
    /// as they were (the two-pass models evaluate their first pass on the subset's one
    /// ring, [`Threads::one_ring`]).
    pub threads: Threads<'a>,
    /// The time step in s (the viscoelastic update needs it).
    pub dt: f32,
}

/// A model's shape information: its arrays and parameters, and what it computes from them.
pub trait ModelState {
    /// The model's arrays as raw bytes, in a fixed order (not `node_material`).
    fn arrays(&self) -> Vec<(ShapeArray, &[u8])>;

    /// The same arrays, mutable.
    fn arrays_mut(&mut self) -> Vec<(ShapeArray, &mut [u8])>;

    /// The rows of node `i` that depend on its neighbour row and the rest positions, for
    /// [`super::ShapeInfo::node_rows`].
    fn node_rows(
        &self,
        i: usize,
        rest: &[Vec4],
        nb: &Neighbours,
        volume_scale: f64,
        rest_position: bool,
    ) -> Vec<ShapeRow>;

    /// See [`super::ShapeInfo::volume_scale`]; 1 for the models without volumes.
    fn volume_scale(&self, _rest: &[Vec4], _nb: &Neighbours, _n: usize) -> f64 {
        1.0
    }

    /// The node volumes of the first `n` nodes; `None` for the models without volumes.
    fn node_volumes(&self, _n: usize) -> Option<Vec<f32>> {
        None
    }

    /// The elastic (and damping) force on each of the first `input.n` nodes (only on
    /// `input.threads.subset` when it is set).
    fn cpu_forces(&mut self, input: &ForceInput, forces: &mut [Vec4]);

    /// Commits what the last force evaluation computed for the next step (the
    /// viscoelastic state); called once per step, after the integration. Nothing by
    /// default.
    fn end_step(&mut self) {}
}

/// What building shape information needs besides positions and neighbours.
#[derive(Debug, Clone, Copy)]
pub struct BuildContext<'a> {
    /// Surface triangles over the mesh nodes.
    pub triangles: &'a [[u32; 3]],
    /// Volume enclosed by the surface in m^3.
    pub volume: f64,
    /// Cell volume of each mesh node in m^3 ([`crate::geometry::NodeCloud::node_volumes`]).
    pub node_volumes: &'a [f64],
}
