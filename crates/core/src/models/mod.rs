//! The tissue models and their shape information (the paper's name for the arrays a model
//! needs beyond positions, velocities, forces and neighbours, section 4 and Table 1).
//!
//! # Where a model lives
//!
//! Each model is one module here that owns everything about it:
//!
//! - its parameters (`[material]` with `model = "<tag>"`): a serde struct with defaults, a
//!   builder, and [`TissueModel`] (validation, the per-node material row, calibration
//!   hooks, the memory estimate, how its shape information is built);
//! - its shape information: a `Shape` struct holding the parameters and the arrays, with
//!   [`ModelState`] (the arrays as bytes for the backends and checkpoints, the rows a
//!   needle node addition rewrites, and the CPU force);
//! - its GPU kernels sit in `crates/gpu/src/models/<module>.rs` next to their `.wgsl`.
//!
//! The registry [`for_each_model!`](crate::for_each_model) lists the models once; the
//! [`Material`] and [`ModelShape`] enums, the TOML tags, the [`MODELS`] table and every
//! dispatch are generated from it, so no `match` on the model outside a model's own module
//! names a model.
//!
//! Adding a model: write `models/<name>.rs` (parameters + `Shape`, the two traits), its
//! GPU module and shader, and one line in the registry.
//!
//! Only the chosen model's arrays are allocated.

pub mod consistency;
pub mod continuum;
pub mod debunne_meshfree;
pub mod local_shape_matching;
pub mod mass_spring;
pub mod mls;
pub mod mueller2016_rotation;
pub mod neo_hookean;
pub mod point_based;
pub mod viscoelastic;

mod traits;

pub use debunne_meshfree::Corotation;
pub use traits::{
    row, BuildContext, ForceInput, ModelInfo, ModelState, ShapeArray, ShapeRow, TissueModel,
};

use crate::calibration::UncalibratedNeighbours;
use crate::error::SceneError;
use crate::math::Vec4;
use crate::neighbours::Neighbours;
use crate::parallel::Threads;

/// The registry: every tissue model, once, as `Variant(parameter type)` with its docs.
/// Calls `$callback!` with the list; [`Material`], [`ModelShape`], [`MODELS`] and the
/// dispatch here and in the GPU crate are generated from it.
#[macro_export]
macro_rules! for_each_model {
    ($callback:ident) => {
        $callback! {
            /// `model = "mass_spring"`: weighted mass-spring model, one spring per
            /// neighbour pair.
            MassSpring($crate::models::mass_spring::MassSpringParams),
            /// `model = "local_shape_matching"`: one cluster per node (paper section 3).
            LocalShapeMatching($crate::models::local_shape_matching::ShapeMatchingParams),
            /// `model = "debunne_meshfree"`: linear elasticity, Navier's equation at every
            /// node with point-set operators (Debunne et al. 1999).
            DebunneMeshfree($crate::models::debunne_meshfree::DebunneParams),
            /// `model = "point_based"`: point based animation (Mueller et al. 2004), Green
            /// strain from a moving-least-squares displacement gradient.
            PointBased($crate::models::point_based::PointBasedParams),
            /// `model = "neo_hookean"`: compressible neo-Hookean solid for large strains.
            NeoHookean($crate::models::neo_hookean::NeoHookeanParams),
        }
    };
}

macro_rules! define_models {
    ($( $(#[$doc:meta])* $variant:ident($params:ty), )*) => {
        /// The tissue model and its parameters, chosen by the key `model` (one variant per
        /// model of the registry, [`for_each_model!`](crate::for_each_model)).
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub enum Material {
            $( $(#[$doc])* $variant($params), )*
        }

        /// A model's shape information (one variant per model of the registry).
        #[derive(Debug, Clone, PartialEq)]
        pub enum ModelShape {
            $( $(#[$doc])* $variant(<$params as TissueModel>::Shape), )*
        }

        $(
            impl From<$params> for Material {
                fn from(p: $params) -> Material {
                    Material::$variant(p)
                }
            }
        )*

        /// Every model of the registry, in its order.
        pub const MODELS: &[ModelInfo] = &[$( <$params as TissueModel>::INFO, )*];

        impl Material {
            /// The viscoelastic Prony series (empty: elastic).
            pub fn prony(&self) -> viscoelastic::Prony {
                match self {
                    $( Material::$variant(p) => p.prony(), )*
                }
            }

            /// The model's registry entry.
            pub fn info(&self) -> ModelInfo {
                match self {
                    $( Material::$variant(_) => <$params as TissueModel>::INFO, )*
                }
            }

            /// The material of TOML tag `tag` read from the rest of its table; `None` for
            /// a tag no model has.
            pub fn from_tagged(
                tag: &str,
                table: toml::Value,
            ) -> Option<Result<Material, toml::de::Error>> {
                $(
                    if tag == <$params as TissueModel>::INFO.tag {
                        return Some(table.try_into::<$params>().map(Material::$variant));
                    }
                )*
                None
            }

            /// Checks the parameters; errors name `{key}.<parameter>`.
            pub fn validate(&self, key: &str) -> Result<(), SceneError> {
                match self {
                    $( Material::$variant(p) => p.validate(key), )*
                }
            }

            /// See [`TissueModel::material_row`].
            pub fn material_row(&self) -> Vec4 {
                match self {
                    $( Material::$variant(p) => p.material_row(), )*
                }
            }

            /// See [`TissueModel::shape_bytes_per_node`].
            pub fn shape_bytes_per_node(&self, k: f64) -> f64 {
                match self {
                    $( Material::$variant(p) => p.shape_bytes_per_node(k), )*
                }
            }

            /// See [`TissueModel::elastic_moduli`].
            pub fn elastic_moduli(
                &self,
                spacing: f64,
                neighbours: usize,
            ) -> Result<(f64, f64), UncalibratedNeighbours> {
                match self {
                    $( Material::$variant(p) => p.elastic_moduli(spacing, neighbours), )*
                }
            }

            /// See [`TissueModel::limitation`].
            pub fn limitation(&self) -> Option<&'static str> {
                match self {
                    $( Material::$variant(p) => p.limitation(), )*
                }
            }

            /// See [`TissueModel::prepare_neighbours`].
            pub fn prepare_neighbours(
                &self,
                nb: &mut Neighbours,
                node_volumes: &[f64],
                spacing: f64,
                n: usize,
            ) {
                match self {
                    $( Material::$variant(p) => p.prepare_neighbours(nb, node_volumes, spacing, n), )*
                }
            }

            /// Every key of the material as its TOML table (without `model`).
            pub fn to_table(&self) -> toml::Table {
                match self {
                    $( Material::$variant(p) => table_of(p), )*
                }
            }

            fn build_shape(
                &self,
                rest: &[Vec4],
                nb: &Neighbours,
                n: usize,
                ctx: BuildContext,
            ) -> ModelShape {
                match self {
                    $( Material::$variant(p) => ModelShape::$variant(p.build(rest, nb, n, ctx)), )*
                }
            }
        }

        impl ModelShape {
            /// The model's shape information as the trait object its methods go through.
            pub fn state(&self) -> &dyn ModelState {
                match self {
                    $( ModelShape::$variant(s) => s, )*
                }
            }

            /// Mutable [`ModelShape::state`].
            pub fn state_mut(&mut self) -> &mut dyn ModelState {
                match self {
                    $( ModelShape::$variant(s) => s, )*
                }
            }
        }
    };
}

crate::for_each_model!(define_models);

/// A serialisable value as a TOML table (empty if it is not a table).
fn table_of<T: serde::Serialize>(v: &T) -> toml::Table {
    match toml::Value::try_from(v) {
        Ok(toml::Value::Table(t)) => t,
        _ => toml::Table::new(),
    }
}

impl Material {
    /// The model's short name as used in file names and tables.
    pub fn short_name(&self) -> &'static str {
        self.info().short_name
    }

    /// The model's TOML tag.
    pub fn tag(&self) -> &'static str {
        self.info().tag
    }

    /// The material with `key` set to `value`, as if written in its `[material]` table:
    /// an error names `material.<key>` when the model has no such key or the value does
    /// not fit it or is out of range.
    pub fn with_key(
        &self,
        key: &str,
        value: impl Into<toml::Value>,
    ) -> Result<Material, SceneError> {
        let mut table = self.to_table();
        table.insert(key.to_string(), value.into());
        let invalid = |e: String| SceneError::invalid(format!("material.{key}"), e);
        let m = match Material::from_tagged(self.tag(), toml::Value::Table(table)) {
            Some(r) => r.map_err(|e| invalid(e.to_string().trim_end().replace('\n', " ")))?,
            None => return Err(invalid(format!("no model `{}`", self.tag()))),
        };
        m.validate("material")?;
        Ok(m)
    }

    /// The first structural key ([`ModelInfo::structural_keys`]) in which `other`
    /// differs from `self`; `"model"` when it is another model.
    pub fn structural_difference(&self, other: &Material) -> Option<&'static str> {
        if self.tag() != other.tag() {
            return Some("model");
        }
        let (a, b) = (self.to_table(), other.to_table());
        self.info()
            .structural_keys
            .iter()
            .copied()
            .find(|k| a.get(*k) != b.get(*k))
    }
}

/// A node's material parameters as the kernels read them from the `node_material` array
/// ([`TissueModel::material_row`]).
pub fn material_row(material: &Material) -> Vec4 {
    material.material_row()
}

/// The name, in [`ShapeInfo::arrays`], of the viscoelastic state's second copy (the
/// next step's).
pub const VISCOUS_NEXT: &str = "viscous_state_next";

/// Name and size of one allocated array.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArrayInfo {
    /// Array name.
    pub name: &'static str,
    /// Bytes allocated.
    pub bytes: usize,
}

/// The chosen model's shape information, plus the per-node material rows when the tissue
/// has several materials.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeInfo {
    /// The model's arrays and parameters.
    pub model: ModelShape,
    /// Per-node material rows ([`material_row`]), only with several materials.
    pub node_material: Option<Vec<Vec4>>,
}

impl ShapeInfo {
    /// Builds the chosen model's shape information for the first `n` of `rest` (rest
    /// positions of all `capacity` slots).
    pub fn build(
        material: &Material,
        rest: &[Vec4],
        nb: &Neighbours,
        n: usize,
        ctx: BuildContext,
        node_material: Option<Vec<Vec4>>,
    ) -> ShapeInfo {
        let mut model = material.build_shape(rest, nb, n, ctx);
        // A region's viscosity turns the viscous pass on (the w lane of Debunne's and
        // point based animation's rows, the z lane of the neo-Hookean model's).
        match (&mut model, &node_material) {
            (ModelShape::DebunneMeshfree(s), Some(m)) => {
                s.viscous |= m.iter().any(|row| row[3] > 0.0);
            }
            (ModelShape::NeoHookean(s), Some(m)) => s.note_row_viscosity(m),
            (ModelShape::PointBased(s), Some(m)) => s.note_row_viscosity(m),
            _ => {}
        }
        ShapeInfo {
            model,
            node_material,
        }
    }

    /// The shape information of node `i` that depends on its neighbour row and the rest
    /// positions, as `(array, byte offset, bytes)` in the layout of [`ShapeInfo::bytes`]:
    /// what node addition (paper section 5.1, step 4) writes for every node whose row
    /// changed. `volume_scale` is [`ShapeInfo::volume_scale`]. With `rest_position` the
    /// node's rest position is included (a new node; for the continuum models with its
    /// volume in w, also rewritten for an existing node when `density` volumes depend on
    /// the neighbours). Warm-start rotations and per-step arrays are not included.
    pub fn node_rows(
        &self,
        i: usize,
        rest: &[Vec4],
        nb: &Neighbours,
        volume_scale: f64,
        rest_position: bool,
    ) -> Vec<ShapeRow> {
        let mut out = Vec::new();
        // A new node takes the material of its nearest neighbour at rest.
        if let (true, Some(m)) = (rest_position, self.node_material()) {
            let d = |j: usize| {
                let (a, b) = (rest[i], rest[j]);
                (0..3).map(|c| (a[c] - b[c]) * (a[c] - b[c])).sum::<f32>()
            };
            let nearest = nb
                .live(i)
                .map(|(_, j, _)| j)
                .min_by(|&a, &b| d(a).total_cmp(&d(b)).then(a.cmp(&b)));
            if let Some(j) = nearest {
                out.push(row(ShapeArray::NodeMaterial, i, &[m[j]]));
            }
        }
        out.extend(
            self.model
                .state()
                .node_rows(i, rest, nb, volume_scale, rest_position),
        );
        out
    }

    /// What a node added by the needle needs to get its volume, from the first `n` nodes:
    /// for `density` volumes the factor between the volumes and
    /// [`mls::raw_volume`], for `cell` and `uniform` volumes the mean volume (a
    /// needle node has no cell of its own); 1 for the models without volumes.
    pub fn volume_scale(&self, rest: &[Vec4], nb: &Neighbours, n: usize) -> f64 {
        self.model.state().volume_scale(rest, nb, n)
    }

    /// The node volumes `V_i` of the first `n` nodes (the w lane of the rest positions)
    /// for the continuum models; `None` for the others.
    pub fn node_volumes(&self, n: usize) -> Option<Vec<f32>> {
        self.model.state().node_volumes(n)
    }

    /// The per-node material rows, when the tissue has several materials.
    pub fn node_material(&self) -> Option<&[Vec4]> {
        self.node_material.as_deref()
    }

    /// Whether the tissue has a viscosity (the Kelvin-Voigt dashpot of a continuum model,
    /// in some region or everywhere): `dt = "auto"` then sizes the step for it too.
    pub fn viscous(&self) -> bool {
        match &self.model {
            ModelShape::DebunneMeshfree(s) => s.viscous,
            ModelShape::NeoHookean(s) => s.viscous,
            ModelShape::PointBased(s) => s.viscous,
            _ => false,
        }
    }

    /// Whether the model keeps a warm-start rotation per node (array `rotation`).
    pub fn has_rotation(&self) -> bool {
        self.bytes().iter().any(|(n, _)| *n == ShapeArray::Rotation)
    }

    /// Whether the `rotation` array holds warm starts only (co-rotated Debunne: each node's
    /// first pass refines its own and uses it at once), so that a local force evaluation
    /// ([`crate::Backend::compute_forces_on`]) may leave it as it was and give the same
    /// forces; shape matching's rotations are read by a later pass and are not.
    pub fn rotation_is_warm_start(&self) -> bool {
        matches!(&self.model, ModelShape::DebunneMeshfree(s) if s.corotation.is_some())
    }

    /// The arrays this model allocated, with their sizes.
    pub fn arrays(&self) -> Vec<ArrayInfo> {
        let mut out: Vec<ArrayInfo> = self
            .bytes()
            .into_iter()
            .map(|(array, b)| ArrayInfo {
                name: array.name(),
                bytes: b.len(),
            })
            .collect();
        // The viscoelastic state is held twice: committed, and the next step's (on the
        // GPU in the same buffer, [`ShapeArray::Viscous`]).
        if let Some(v) = out.iter().find(|a| a.name == ShapeArray::Viscous.name()) {
            out.push(ArrayInfo {
                name: VISCOUS_NEXT,
                bytes: v.bytes,
            });
        }
        out
    }

    /// Every array of the model as mutable raw bytes, by name.
    pub fn bytes_mut(&mut self) -> Vec<(ShapeArray, &mut [u8])> {
        let mut v = self.model.state_mut().arrays_mut();
        if let Some(m) = &mut self.node_material {
            v.push((ShapeArray::NodeMaterial, bytemuck::cast_slice_mut(m)));
        }
        v
    }

    /// Every array of the model as raw bytes, by name (the layout the GPU buffers use).
    pub fn bytes(&self) -> Vec<(ShapeArray, &[u8])> {
        let mut v = self.model.state().arrays();
        if let Some(m) = &self.node_material {
            v.push((ShapeArray::NodeMaterial, bytemuck::cast_slice(m)));
        }
        v
    }

    /// The model's force on each of the first `n` nodes into `forces[..n]` (`dt`: the
    /// step, for the viscoelastic update).
    #[allow(clippy::too_many_arguments)]
    pub fn cpu_forces(
        &mut self,
        positions: &[Vec4],
        velocities: &[Vec4],
        nb: &Neighbours,
        n: usize,
        threads: Threads,
        dt: f32,
        forces: &mut [Vec4],
    ) {
        let input = ForceInput {
            positions,
            velocities,
            nb,
            node_material: self.node_material.as_deref(),
            n,
            threads,
            dt,
        };
        self.model.state_mut().cpu_forces(&input, &mut forces[..n]);
    }

    /// Commits the step's model state ([`ModelState::end_step`]).
    pub fn end_step(&mut self) {
        self.model.state_mut().end_step();
    }
}
