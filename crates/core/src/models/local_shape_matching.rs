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
//! shape vector is computed with the same arithmetic as the kernel, so the rest state gives
//! exactly zero force. The model is not momentum conserving (each cluster pulls only its own
//! node), as in the paper.
//!
//! Shape information: `rest_position` (x0, needed for A), `shape_vector` (v) and
//! `rotation` (the warm-start quaternion `[x, y, z, w]`), one `[f32; 4]` each per node;
//! the `cluster` variant adds `cluster_centre` (c_i of the current step).
//! The paper's Table 1 lists only v; A cannot be formed without the rest positions.

use super::mueller2016_rotation::extract_rotation;
use crate::math::{with_w, xyz, Vec4};
use crate::neighbours::Neighbours;
use glam::{Mat3, Quat, Vec3};

/// Weighted mean of the neighbour offsets `d_j = p_j - p_i` over node i's cluster (the
/// node itself has offset 0 and weight 1).
#[inline(always)]
pub fn centre_offset(i: usize, p: &[Vec4], nb: &Neighbours) -> Vec3 {
    let xi = xyz(p[i]);
    let mut c = Vec3::ZERO;
    let mut wsum = 1.0f32;
    for (_, j, w) in nb.live(i) {
        c += w * (xyz(p[j]) - xi);
        wsum += w;
    }
    c * (1.0 / wsum)
}

/// Shape vector `v_i = -centre_offset(x0)` of node i (stored, w = 0).
pub fn shape_vector(i: usize, rest: &[Vec4], nb: &Neighbours) -> Vec4 {
    with_w(-centre_offset(i, rest, nb), 0.0)
}

/// Centre offset `c_i` and rotation `R_i` (as a quaternion, refined from the warm start
/// `rotation`) of node i's cluster.
#[inline]
pub fn cluster_frame(
    i: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    shape_vector: Vec4,
    nb: &Neighbours,
    iterations: u32,
    rotation: Quat,
) -> (Vec3, Quat) {
    // One pass over the cluster: with offsets d_j = x_j - x_i and d0_j = x0_j - x0_i
    // (the node itself has d = d0 = 0, weight 1),
    // A = sum w (d - c)(d0 - c0)^T = sum w d d0^T - c (sum w d0)^T.
    let xi = xyz(positions[i]);
    let x0i = xyz(rest[i]);
    let mut wsum = 1.0f32;
    let mut sd = Vec3::ZERO;
    let mut sd0 = Vec3::ZERO;
    let mut sdd0 = 0.0f32;
    let mut m = Mat3::ZERO;
    for (_, j, w) in nb.live(i) {
        let d = xyz(positions[j]) - xi;
        let d0 = xyz(rest[j]) - x0i;
        let wd0 = w * d0;
        sd += w * d;
        sd0 += wd0;
        m += outer(d, wd0);
        sdd0 += wd0.dot(d0);
        wsum += w;
    }
    let c = sd * (1.0 / wsum);
    let c0 = -xyz(shape_vector);
    // sum w |d0 - c0|^2 = sum w |d0|^2 - 2 c0 . sum w d0 + W |c0|^2
    let scale = sdd0 - 2.0 * c0.dot(sd0) + wsum * c0.dot(c0);
    let inv = if scale > 0.0 { 1.0 / scale } else { 1.0 };
    let a = (m - outer(c, sd0)) * inv;
    (c, extract_rotation(&a, rotation, iterations))
}

/// The outer product `u v^T`.
#[inline(always)]
fn outer(u: Vec3, v: Vec3) -> Mat3 {
    Mat3::from_cols(u * v.x, u * v.y, u * v.z)
}

/// The paper's force on node i (equation 1): `k_s (g_i - x_i) = k_s (c_i + R_i v_i)`.
/// Updates the node's stored warm-start quaternion `rotation`.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn node_force(
    i: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    shape_vector: Vec4,
    nb: &Neighbours,
    stiffness: f32,
    iterations: u32,
    rotation: &mut Vec4,
) -> Vec4 {
    let (c, q) = cluster_frame(
        i,
        positions,
        rest,
        shape_vector,
        nb,
        iterations,
        Quat::from_array(*rotation),
    );
    *rotation = q.to_array();
    with_w(stiffness * (c + quat_rotate(q, xyz(shape_vector))), 0.0)
}

/// Cluster forces on node j (second pass of the `cluster` variant): every cluster i that
/// contains j pulls it towards its goal `g_ij = C_i + R_i (x0_j - C0_i)` with weight w_ij,
/// `f_j = k_s sum_i w_ij (g_ij - x_j)`, its own cluster with weight 1. These are the
/// gradients of the shape matching energy `k_s/2 sum_i sum_j w_ij |g_ij - x_j|^2` (R_i
/// and C_i are its minimisers, so their derivatives drop out): conservative and
/// momentum-conserving. `centre` and `rotation` hold every node's `c_i` and `R_i` from
/// [`cluster_frame`], stored.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn cluster_force(
    j: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    shape_vectors: &[Vec4],
    nb: &Neighbours,
    stiffness: f32,
    centre: &[Vec4],
    rotation: &[Vec4],
) -> Vec4 {
    let xj = xyz(positions[j]);
    let x0j = xyz(rest[j]);
    let own = quat_rotate(Quat::from_array(rotation[j]), xyz(shape_vectors[j]));
    let mut f = xyz(centre[j]) + own;
    for (_, i, w) in nb.live(j) {
        // g_ij - x_j = (x_i - x_j) + c_i + R_i ((x0_j - x0_i) + v_i)
        let d = xyz(positions[i]) - xj;
        let q0 = x0j - xyz(rest[i]);
        let r = quat_rotate(Quat::from_array(rotation[i]), q0 + xyz(shape_vectors[i]));
        f += w * (d + xyz(centre[i]) + r);
    }
    with_w(stiffness * f, 0.0)
}

/// Rotates v by the unit quaternion q: `v + 2 w (u x v) + 2 u x (u x v)`, `u` the vector
/// part. This is the WGSL kernels' `quat_rotate`, kept instead of glam's `Quat * Vec3`
/// (another formula, vectorised) so that the CPU reference rounds like the GPU kernels.
#[inline(always)]
pub fn quat_rotate(q: Quat, v: Vec3) -> Vec3 {
    let u = q.xyz();
    let t = 2.0 * u.cross(v);
    v + q.w * t + u.cross(t)
}
