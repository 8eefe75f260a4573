//! Local shape matching (LSHM), paper section 3 and Algorithm 1.
//!
//! One cluster per node i: the node (weight 1) and its neighbours (weights w_ij). With
//! offsets from the node, `d_j = x_j - x_i` and `d0_j = x0_j - x0_i`, the cluster centre is
//! `c_i = sum_j w_ij d_j / W_i` (so `C_i = x_i + c_i`) and the shape vector is
//! `v_i = x0_i - C0_i = -sum_j w_ij d0_j / W_i`. Each step:
//!
//! - `A_i = sum_j w_ij (d_j - c_i)(d0_j - c0_i)^T`, scaled by `1 / sum_j w_ij |d0_j - c0_i|^2`;
//! - `R_i` = rotation of the polar decomposition of `A_i`, by the warm-started quaternion
//!   iteration of [`super::mueller2016_rotation`] (the quaternion is kept per node);
//! - goal `g_i = C_i + R_i v_i` and force `f_i = k_s (g_i - x_i) = k_s (c_i + R_i v_i)`
//!   ([`node_force`], variant `node`, the paper's equation 1).
//!
//! The paper's force acts only on the cluster's own node and is not the gradient of any
//! energy: its rotation term feeds energy into the system, and an undamped cube oscillating
//! about rest gains energy at a rate that grows like `sqrt(k_s / m)` (measured: a 1% stretch
//! of a 648-node cube with k_s = 100 N/m grows from 1e-3 J to 80 J kinetic energy in 4 s
//! without damping; with the rotation frozen the energy stays bounded). Velocity damping
//! above that rate keeps it stable. Variant `cluster` ([`cluster_force`]) instead lets
//! every cluster pull all its members towards its goals (the gradient of the shape
//! matching energy, as in Mueller et al. 2005): conservative and momentum-conserving, at
//! the cost of a second pass and one more array (`cluster_centre`).
//!
//! Offsets from the node keep f32 round-off independent of where the tissue is, and the
//! shape vector is computed with the same arithmetic as the slot-by-slot kernels (the GPU's,
//! [`cluster_frame`]), so the rest state gives exactly zero force there; the CPU's
//! four-lane per-node path ([`node_forces`]) sums in another order, so its rest force is
//! f32 round-off. The model is not momentum conserving (each cluster pulls only its own
//! node), as in the paper.
//!
//! Shape information: `rest_position` (x0, needed for A), `shape_vector` (v) and
//! `rotation` (the warm-start quaternion `[x, y, z, w]`), one `[f32; 4]` each per node;
//! the `cluster` variant adds `cluster_centre` (c_i of the current step).
//! The paper's Table 1 lists only v; A cannot be formed without the rest positions.

mod kernels;

pub use kernels::*;

use super::{
    row, BuildContext, ForceInput, ModelInfo, ModelState, ShapeArray, ShapeRow, TissueModel,
};
use crate::calibration::{calibration, UncalibratedNeighbours};
use crate::error::SceneError;
use crate::math::{with_w, Vec4, QUAT_IDENTITY};
use crate::models::mueller2016_rotation::default_iterations;
use crate::neighbours::Neighbours;
use crate::validate::{positive_finite, rotation_iterations_in_range};
use glam::Quat;

/// Parameters of local shape matching.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ShapeMatchingParams {
    /// Restoring stiffness k_s in N/m of `f = k_s (g - x)`.
    pub stiffness: f64,
    /// Most quaternion iterations per step of the rotation extraction, warm started from
    /// the previous step (default 2).
    #[serde(default = "crate::models::mueller2016_rotation::default_iterations")]
    pub rotation_iterations: u32,
    /// Which nodes a cluster pulls: `node` (the paper) or `cluster` (conservative).
    #[serde(default)]
    pub forces: ShapeMatchingForces,
}

/// Which nodes a shape matching cluster acts on.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum ShapeMatchingForces {
    /// Only its own node, `f_i = k_s (g_i - x_i)` (paper equation 1). Not conservative:
    /// needs velocity damping to stay stable at high stiffness.
    #[default]
    Node,
    /// All its members towards their goals: the gradient of the shape matching energy,
    /// conservative and momentum-conserving.
    Cluster,
}

impl ShapeMatchingParams {
    /// `model = "local_shape_matching"` with restoring `stiffness` in N/m, the other keys
    /// at their defaults (`forces = "node"`, 2 rotation iterations).
    pub const fn new(stiffness: f64) -> ShapeMatchingParams {
        ShapeMatchingParams {
            stiffness,
            rotation_iterations: default_iterations(),
            forces: ShapeMatchingForces::Node,
        }
    }

    /// `forces`: which nodes a cluster pulls.
    pub const fn with_forces(mut self, forces: ShapeMatchingForces) -> Self {
        self.forces = forces;
        self
    }

    /// `rotation_iterations`.
    pub const fn with_rotation_iterations(mut self, iterations: u32) -> Self {
        self.rotation_iterations = iterations;
        self
    }
}

/// The shape vectors of the first `n` nodes (the rest of the `rest_position.len()` slots
/// zero).
pub fn shape_vectors(rest_position: &[Vec4], nb: &Neighbours, n: usize) -> Vec<Vec4> {
    let mut v = vec![[0.0f32; 4]; rest_position.len()];
    for (i, v) in v.iter_mut().enumerate().take(n) {
        *v = shape_vector(i, rest_position, nb);
    }
    v
}

/// `rest` with w = 0.
pub(crate) fn rest_positions(rest: &[Vec4]) -> Vec<Vec4> {
    rest.iter().map(|p| [p[0], p[1], p[2], 0.0]).collect()
}

impl TissueModel for ShapeMatchingParams {
    type Shape = Shape;

    const INFO: ModelInfo = ModelInfo {
        tag: "local_shape_matching",
        short_name: "lshm",
        label: "local shape matching",
        structural_keys: &["forces", "rotation_iterations"],
    };

    fn validate(&self, key: &str) -> Result<(), SceneError> {
        positive_finite(&format!("{key}.stiffness"), self.stiffness)?;
        rotation_iterations_in_range(key, self.rotation_iterations)
    }

    /// `[k_s, 0, 0, 0]`.
    fn material_row(&self) -> Vec4 {
        [self.stiffness as f32, 0.0, 0.0, 0.0]
    }

    /// Rest position, shape vector and rotation (and the cluster centre).
    fn shape_bytes_per_node(&self, _k: f64) -> f64 {
        48.0 + if self.forces == ShapeMatchingForces::Cluster {
            16.0
        } else {
            0.0
        }
    }

    /// `E = k_s / (C h)` with the calibration constant of the force variant; the
    /// lattice's Poisson ratio is about 0 (docs/report).
    fn elastic_moduli(
        &self,
        spacing: f64,
        neighbours: usize,
    ) -> Result<(f64, f64), UncalibratedNeighbours> {
        let cal = calibration(neighbours)?;
        let c = match self.forces {
            ShapeMatchingForces::Cluster => cal.shape_matching_cluster,
            ShapeMatchingForces::Node => cal.shape_matching_node,
        };
        Ok((self.stiffness / (c * spacing), 0.0))
    }

    /// Measured on a free 13^3-node cube (the report's "What each model represents", K =
    /// 18): Poisson ratio 0.0002 with cluster forces (bulk modulus 0.44, shear 1.40 of an
    /// isotropic solid with the same E and nu = 0.3) and -0.014 with the paper's per-node
    /// forces (shear 2.0, anisotropy 1.28).
    fn limitation(&self) -> Option<&'static str> {
        Some(match self.forces {
            ShapeMatchingForces::Cluster => {
                "shape matching pulls nodes to rigid goals: its Poisson ratio is about 0 (no \
                 lateral contraction) and its bulk stiffness is about half an isotropic \
                 solid's, whatever the material asks; use a continuum model where nu matters"
            }
            ShapeMatchingForces::Node => {
                "the paper's per-node shape matching forces do not form an isotropic elastic \
                 material (Poisson ratio about 0, shear twice too stiff, anisotropic) and need \
                 velocity damping to stay stable; use a continuum model where nu matters"
            }
        })
    }

    fn build(&self, rest: &[Vec4], nb: &Neighbours, n: usize, _ctx: BuildContext) -> Shape {
        let capacity = rest.len();
        let rest_position = rest_positions(rest);
        Shape {
            params: *self,
            shape_vector: shape_vectors(&rest_position, nb, n),
            rest_position,
            rotation: vec![QUAT_IDENTITY; capacity],
            cluster_centre: (self.forces == ShapeMatchingForces::Cluster)
                .then(|| vec![[0.0; 4]; capacity]),
        }
    }
}

/// Local shape matching's shape information.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    /// The parameters.
    pub params: ShapeMatchingParams,
    /// Rest positions x0 (w = 0).
    pub rest_position: Vec<Vec4>,
    /// Shape vectors v = x0 - C0 (w = 0).
    pub shape_vector: Vec<Vec4>,
    /// Rotation quaternions `[x, y, z, w]` from the last step.
    pub rotation: Vec<Vec4>,
    /// Cluster centre offsets c_i of the current step (`cluster` variant only).
    pub cluster_centre: Option<Vec<Vec4>>,
}

impl ModelState for Shape {
    fn arrays(&self) -> Vec<(ShapeArray, &[u8])> {
        let mut v = vec![
            (
                ShapeArray::RestPosition,
                bytemuck::cast_slice(&self.rest_position[..]),
            ),
            (
                ShapeArray::ShapeVector,
                bytemuck::cast_slice(&self.shape_vector[..]),
            ),
            (
                ShapeArray::Rotation,
                bytemuck::cast_slice(&self.rotation[..]),
            ),
        ];
        if let Some(c) = &self.cluster_centre {
            v.push((ShapeArray::ClusterCentre, bytemuck::cast_slice(&c[..])));
        }
        v
    }

    fn arrays_mut(&mut self) -> Vec<(ShapeArray, &mut [u8])> {
        let mut v = vec![
            (
                ShapeArray::RestPosition,
                bytemuck::cast_slice_mut(&mut self.rest_position[..]),
            ),
            (
                ShapeArray::ShapeVector,
                bytemuck::cast_slice_mut(&mut self.shape_vector[..]),
            ),
            (
                ShapeArray::Rotation,
                bytemuck::cast_slice_mut(&mut self.rotation[..]),
            ),
        ];
        if let Some(c) = &mut self.cluster_centre {
            v.push((
                ShapeArray::ClusterCentre,
                bytemuck::cast_slice_mut(&mut c[..]),
            ));
        }
        v
    }

    fn node_rows(
        &self,
        i: usize,
        rest: &[Vec4],
        nb: &Neighbours,
        _volume_scale: f64,
        rest_position: bool,
    ) -> Vec<ShapeRow> {
        let mut out = Vec::new();
        if rest_position {
            out.push(row(
                ShapeArray::RestPosition,
                i,
                &rest_positions(&rest[i..=i]),
            ));
        }
        out.push(row(
            ShapeArray::ShapeVector,
            i,
            &[shape_vector(i, rest, nb)],
        ));
        out
    }

    fn cpu_forces(&mut self, input: &ForceInput, forces: &mut [Vec4]) {
        let ForceInput {
            positions: pos,
            nb,
            n,
            threads,
            node_material: material,
            ..
        } = *input;
        let (k, iters) = (
            self.params.stiffness as f32,
            self.params.rotation_iterations,
        );
        let (rest, sv) = (&self.rest_position[..], &self.shape_vector[..]);
        let rotation = &mut self.rotation;
        match &mut self.cluster_centre {
            None => {
                // With a stiffness per node: the unit-stiffness force times k_s,i (the
                // same product as with one stiffness).
                let k = if material.is_some() { 1.0 } else { k };
                threads.for_each_chunk(forces, &mut rotation[..n], |first, f, q| {
                    node_forces(first, f, q, pos, rest, sv, nb, k, iters);
                    if let Some(m) = material {
                        for (o, f) in f.iter_mut().enumerate() {
                            let k = m[first + o][0];
                            *f = [k * f[0], k * f[1], k * f[2], 0.0];
                        }
                    }
                });
            }
            Some(centre) => {
                // A local evaluation's forces read the frames of its nodes' neighbours.
                let ring = threads.one_ring(nb, n);
                let frames = threads.with_subset(ring.as_deref());
                frames.for_each_node(&mut centre[..n], &mut rotation[..n], |i, c, q| {
                    let (c_i, q_i) =
                        cluster_frame(i, pos, rest, sv[i], nb, iters, Quat::from_array(*q));
                    *c = with_w(c_i, 0.0);
                    *q = q_i.to_array();
                });
                let (centre, rotation) = (&centre[..], &rotation[..]);
                threads.map_nodes(forces, |j| match material {
                    None => cluster_force(j, pos, rest, sv, nb, k, centre, rotation),
                    Some(m) => cluster_force_mixed(j, pos, rest, sv, nb, m, centre, rotation),
                });
            }
        }
    }
}
