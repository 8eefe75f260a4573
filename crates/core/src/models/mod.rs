//! The tissue models and their shape information (the paper's name for the arrays a model
//! needs beyond positions, velocities, forces and neighbours, section 4 and Table 1).
//!
//! Only the chosen model's arrays are allocated.

pub mod debunne_meshfree;
pub mod local_shape_matching;
pub mod mass_spring;
pub mod mls;
pub mod mueller2016_rotation;
pub mod point_based;

use crate::math::{Vec4, QUAT_IDENTITY};
use crate::neighbours::Neighbours;
use crate::scene::{
    DebunneParams, Material, NodeVolumes, PointBasedParams, ShapeMatchingForces,
    ShapeMatchingParams,
};

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
    /// Per-node material parameters ([`material_row`]), only with several materials.
    NodeMaterial,
}

impl ShapeArray {
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
        }
    }
}

impl std::fmt::Display for ShapeArray {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Per-model shape information arrays, sized for the full capacity.
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeInfo {
    /// Mass-spring: rest length per neighbour slot.
    MassSpring {
        /// `capacity * K` rest lengths in metres.
        rest_length: Vec<f32>,
        /// Per-node `[k, c, 0, 0]` with several materials ([`material_row`]).
        node_material: Option<Vec<Vec4>>,
    },
    /// Local shape matching: rest positions, shape vectors and warm-start rotations.
    LocalShapeMatching {
        /// Rest positions x0 (w = 0).
        rest_position: Vec<Vec4>,
        /// Shape vectors v = x0 - C0 (w = 0).
        shape_vector: Vec<Vec4>,
        /// Rotation quaternions `[x, y, z, w]` from the last step.
        rotation: Vec<Vec4>,
        /// Cluster centre offsets c_i of the current step (`cluster` variant only).
        cluster_centre: Option<Vec<Vec4>>,
        /// Per-node `[k_s, 0, 0, 0]` with several materials ([`material_row`]).
        node_material: Option<Vec<Vec4>>,
    },
    /// Debunne meshfree linear elasticity: rest positions, inverse moment matrices, the
    /// per-step first-pass result, plus the shape matching frame when co-rotated.
    DebunneMeshfree {
        /// Rest positions x0, w = the node volume V_i in m^3
        /// ([`crate::scene::NodeVolumes`]).
        rest_position: Vec<Vec4>,
        /// `A_i^-1`, row-major 3x3.
        inverse_moment: Vec<[f32; 9]>,
        /// How the volumes were chosen (and a needle node's volume is chosen).
        volume_rule: NodeVolumes,
        /// First-pass result of the current step ([`mls::pack_first_pass`]).
        first_pass: Vec<[f32; 12]>,
        /// Shape vectors and warm-start rotations (`corotated = true` only).
        corotation: Option<Corotation>,
        /// Per-node `[lambda, mu, alpha mu, 0]` with several materials ([`material_row`]).
        node_material: Option<Vec<Vec4>>,
    },
    /// Point based animation: rest positions and volumes, inverse moment matrices and the
    /// per-step first-pass result.
    PointBased {
        /// Rest positions x0, w = the node volume V_i in m^3
        /// ([`crate::scene::NodeVolumes`]).
        rest_position: Vec<Vec4>,
        /// `A_i^-1`, row-major 3x3 (the paper's Table 1).
        inverse_moment: Vec<[f32; 9]>,
        /// How the volumes were chosen (and a needle node's volume is chosen).
        volume_rule: NodeVolumes,
        /// First-pass result of the current step ([`mls::pack_first_pass`]).
        first_pass: Vec<[f32; 12]>,
        /// Per-node `[lambda, mu, k_v, alpha mu]` with several materials ([`material_row`]).
        node_material: Option<Vec<Vec4>>,
    },
}

/// A node's material parameters as the kernels read them from the `node_material` array
/// (f32, in the units of the scene): mass-spring `[k, c, 0, 0]`; shape matching
/// `[k_s, 0, 0, 0]`; Debunne `[lambda, mu, alpha mu, 0]`; point based animation
/// `[lambda, mu, k_v, alpha mu]`.
pub fn material_row(material: &Material) -> Vec4 {
    match material {
        Material::MassSpring(p) => [p.stiffness as f32, p.spring_damping as f32, 0.0, 0.0],
        Material::LocalShapeMatching(p) => [p.stiffness as f32, 0.0, 0.0, 0.0],
        Material::DebunneMeshfree(_) | Material::PointBased(_) => {
            let c = mls::ContinuumConstants::of(material).expect("continuum material");
            match material {
                Material::PointBased(_) => [c.lambda, c.mu, c.volume_stiffness, c.hourglass],
                _ => [c.lambda, c.mu, c.hourglass, 0.0],
            }
        }
    }
}

/// The shape matching frame used to co-rotate the Debunne model.
#[derive(Debug, Clone, PartialEq)]
pub struct Corotation {
    /// Shape vectors v = x0 - C0 (w = 0).
    pub shape_vector: Vec<Vec4>,
    /// Rotation quaternions `[x, y, z, w]` from the last step.
    pub rotation: Vec<Vec4>,
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

/// The model's arrays as `(name, bytes)` in a fixed order, through `$cast` and `$slice`
/// (shared or mutable), so that [`ShapeInfo::bytes`] and [`ShapeInfo::bytes_mut`] list the
/// same arrays.
macro_rules! named_arrays {
    ($self:expr, $cast:path, $slice:ident) => {{
        let (mut v, node_material) = match $self {
            ShapeInfo::MassSpring {
                rest_length,
                node_material,
            } => (
                vec![(ShapeArray::RestLength, $cast(rest_length.$slice()))],
                node_material,
            ),
            ShapeInfo::LocalShapeMatching {
                rest_position,
                shape_vector,
                rotation,
                cluster_centre,
                node_material,
            } => {
                let mut v = vec![
                    (ShapeArray::RestPosition, $cast(rest_position.$slice())),
                    (ShapeArray::ShapeVector, $cast(shape_vector.$slice())),
                    (ShapeArray::Rotation, $cast(rotation.$slice())),
                ];
                if let Some(c) = cluster_centre {
                    v.push((ShapeArray::ClusterCentre, $cast(c.$slice())));
                }
                (v, node_material)
            }
            ShapeInfo::DebunneMeshfree {
                rest_position,
                inverse_moment,
                first_pass,
                corotation,
                node_material,
                ..
            } => {
                let mut v = vec![
                    (ShapeArray::RestPosition, $cast(rest_position.$slice())),
                    (ShapeArray::InverseMoment, $cast(inverse_moment.$slice())),
                    (ShapeArray::FirstPass, $cast(first_pass.$slice())),
                ];
                if let Some(c) = corotation {
                    v.push((ShapeArray::ShapeVector, $cast(c.shape_vector.$slice())));
                    v.push((ShapeArray::Rotation, $cast(c.rotation.$slice())));
                }
                (v, node_material)
            }
            ShapeInfo::PointBased {
                rest_position,
                inverse_moment,
                first_pass,
                node_material,
                ..
            } => (
                vec![
                    (ShapeArray::RestPosition, $cast(rest_position.$slice())),
                    (ShapeArray::InverseMoment, $cast(inverse_moment.$slice())),
                    (ShapeArray::FirstPass, $cast(first_pass.$slice())),
                ],
                node_material,
            ),
        };
        if let Some(m) = node_material {
            v.push((ShapeArray::NodeMaterial, $cast(m.$slice())));
        }
        v
    }};
}

/// Name and size of one allocated array.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArrayInfo {
    /// Array name.
    pub name: &'static str,
    /// Bytes allocated.
    pub bytes: usize,
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
        let capacity = rest.len();
        let rest_position =
            || -> Vec<Vec4> { rest.iter().map(|p| [p[0], p[1], p[2], 0.0]).collect() };
        let shape_vectors = |rest_position: &[Vec4]| -> Vec<Vec4> {
            let mut v = vec![[0.0f32; 4]; capacity];
            for (i, v) in v.iter_mut().enumerate().take(n) {
                *v = local_shape_matching::shape_vector(i, rest_position, nb);
            }
            v
        };
        match material {
            Material::MassSpring(_) => ShapeInfo::MassSpring {
                rest_length: mass_spring::rest_lengths(rest, nb, n),
                node_material,
            },
            Material::LocalShapeMatching(ShapeMatchingParams { forces, .. }) => {
                let rest_position = rest_position();
                let shape_vector = shape_vectors(&rest_position);
                ShapeInfo::LocalShapeMatching {
                    rest_position,
                    shape_vector,
                    rotation: vec![QUAT_IDENTITY; capacity],
                    cluster_centre: (*forces == ShapeMatchingForces::Cluster)
                        .then(|| vec![[0.0; 4]; capacity]),
                    node_material,
                }
            }
            Material::DebunneMeshfree(DebunneParams {
                corotated,
                node_volumes,
                ..
            }) => {
                let rest_position = rest_position();
                let corotation = corotated.then(|| Corotation {
                    shape_vector: shape_vectors(&rest_position),
                    rotation: vec![QUAT_IDENTITY; capacity],
                });
                ShapeInfo::DebunneMeshfree {
                    inverse_moment: mls::inverse_moments(&rest_position, nb, n),
                    rest_position: mls::with_volumes(
                        rest_position,
                        mls::node_volumes(*node_volumes, rest, nb, n, ctx),
                    ),
                    volume_rule: *node_volumes,
                    first_pass: vec![[0.0; 12]; capacity],
                    corotation,
                    node_material,
                }
            }
            Material::PointBased(PointBasedParams { node_volumes, .. }) => {
                let rest_position = rest_position();
                ShapeInfo::PointBased {
                    inverse_moment: mls::inverse_moments(&rest_position, nb, n),
                    rest_position: mls::with_volumes(
                        rest_position,
                        mls::node_volumes(*node_volumes, rest, nb, n, ctx),
                    ),
                    volume_rule: *node_volumes,
                    first_pass: vec![[0.0; 12]; capacity],
                    node_material,
                }
            }
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
    ) -> Vec<(ShapeArray, usize, Vec<u8>)> {
        fn row<T: bytemuck::Pod>(
            array: ShapeArray,
            i: usize,
            v: &[T],
        ) -> (ShapeArray, usize, Vec<u8>) {
            let b: &[u8] = bytemuck::cast_slice(v);
            (array, i * b.len(), b.to_vec())
        }
        let r0 = [rest[i][0], rest[i][1], rest[i][2], 0.0];
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
        if rest_position && matches!(self, ShapeInfo::LocalShapeMatching { .. }) {
            out.push(row(ShapeArray::RestPosition, i, &[r0]));
        }
        // Continuum models: x0 with the node volume in w.
        let volume_row = |rule: NodeVolumes| {
            (rest_position || rule == NodeVolumes::Density).then(|| {
                let v = mls::added_node_volume(rule, i, rest, nb, volume_scale);
                row(ShapeArray::RestPosition, i, &[[r0[0], r0[1], r0[2], v]])
            })
        };
        match self {
            ShapeInfo::MassSpring { .. } => {
                out.push(row(
                    ShapeArray::RestLength,
                    i,
                    &mass_spring::rest_length_row(i, rest, nb),
                ));
            }
            ShapeInfo::LocalShapeMatching { .. } => {
                out.push(row(
                    ShapeArray::ShapeVector,
                    i,
                    &[local_shape_matching::shape_vector(i, rest, nb)],
                ));
            }
            ShapeInfo::DebunneMeshfree {
                corotation,
                volume_rule,
                ..
            } => {
                out.push(row(
                    ShapeArray::InverseMoment,
                    i,
                    &[mls::inverse_moment(i, rest, nb)],
                ));
                out.extend(volume_row(*volume_rule));
                if corotation.is_some() {
                    out.push(row(
                        ShapeArray::ShapeVector,
                        i,
                        &[local_shape_matching::shape_vector(i, rest, nb)],
                    ));
                }
            }
            ShapeInfo::PointBased { volume_rule, .. } => {
                out.extend(volume_row(*volume_rule));
                out.push(row(
                    ShapeArray::InverseMoment,
                    i,
                    &[mls::inverse_moment(i, rest, nb)],
                ));
            }
        }
        out
    }

    /// What a node added by the needle needs to get its volume, from the first `n` nodes:
    /// for `density` volumes the factor between the volumes and
    /// [`mls::raw_volume`], for `cell` and `uniform` volumes the mean volume (a
    /// needle node has no cell of its own); 1 for the models without volumes.
    pub fn volume_scale(&self, rest: &[Vec4], nb: &Neighbours, n: usize) -> f64 {
        match self {
            ShapeInfo::PointBased {
                rest_position,
                volume_rule,
                ..
            }
            | ShapeInfo::DebunneMeshfree {
                rest_position,
                volume_rule,
                ..
            } => {
                let vol: f64 = rest_position[..n].iter().map(|p| p[3] as f64).sum();
                let raw: f64 = match volume_rule {
                    NodeVolumes::Density => (0..n).map(|i| mls::raw_volume(i, rest, nb)).sum(),
                    NodeVolumes::Cell | NodeVolumes::Uniform => n as f64,
                };
                if raw > 0.0 {
                    vol / raw
                } else {
                    0.0
                }
            }
            _ => 1.0,
        }
    }

    /// The node volumes `V_i` of the first `n` nodes (the w lane of the rest positions)
    /// for the continuum models; `None` for the others.
    pub fn node_volumes(&self, n: usize) -> Option<Vec<f32>> {
        match self {
            ShapeInfo::DebunneMeshfree { rest_position, .. }
            | ShapeInfo::PointBased { rest_position, .. } => {
                Some(rest_position[..n].iter().map(|p| p[3]).collect())
            }
            _ => None,
        }
    }

    /// The per-node material rows, when the tissue has several materials.
    pub fn node_material(&self) -> Option<&[Vec4]> {
        match self {
            ShapeInfo::MassSpring { node_material, .. }
            | ShapeInfo::LocalShapeMatching { node_material, .. }
            | ShapeInfo::DebunneMeshfree { node_material, .. }
            | ShapeInfo::PointBased { node_material, .. } => node_material.as_deref(),
        }
    }

    /// Whether the model keeps a warm-start rotation per node (array `rotation`).
    pub fn has_rotation(&self) -> bool {
        self.bytes().iter().any(|(n, _)| *n == ShapeArray::Rotation)
    }

    /// The arrays this model allocated, with their sizes.
    pub fn arrays(&self) -> Vec<ArrayInfo> {
        self.bytes()
            .into_iter()
            .map(|(array, b)| ArrayInfo {
                name: array.name(),
                bytes: b.len(),
            })
            .collect()
    }

    /// Every array of the model as mutable raw bytes, by name.
    pub fn bytes_mut(&mut self) -> Vec<(ShapeArray, &mut [u8])> {
        named_arrays!(self, bytemuck::cast_slice_mut, as_mut_slice)
    }

    /// Every array of the model as raw bytes, by name (the layout the GPU buffers use).
    pub fn bytes(&self) -> Vec<(ShapeArray, &[u8])> {
        named_arrays!(self, bytemuck::cast_slice, as_slice)
    }
}
