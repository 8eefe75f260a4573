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
use crate::math::{cross, sub, Mat3, Vec4};
use crate::neighbours::Neighbours;

/// Weighted mean of the neighbour offsets `d_j = p_j - p_i` over node i's cluster (the
/// node itself has offset 0 and weight 1).
#[inline(always)]
pub fn centre_offset(i: usize, p: &[Vec4], nb: &Neighbours) -> Vec4 {
    let xi = p[i];
    let mut c = [0.0f32; 4];
    let mut wsum = 1.0f32;
    for (_, j, w) in nb.live(i) {
        let d = sub(p[j], xi);
        c[0] += w * d[0];
        c[1] += w * d[1];
        c[2] += w * d[2];
        wsum += w;
    }
    let inv = 1.0 / wsum;
    [c[0] * inv, c[1] * inv, c[2] * inv, 0.0]
}

/// Shape vector `v_i = -centre_offset(x0)` of node i.
pub fn shape_vector(i: usize, rest: &[Vec4], nb: &Neighbours) -> Vec4 {
    let c = centre_offset(i, rest, nb);
    [-c[0], -c[1], -c[2], 0.0]
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
    rotation: Vec4,
) -> (Vec4, Vec4) {
    // One pass over the cluster: with offsets d_j = x_j - x_i and d0_j = x0_j - x0_i
    // (the node itself has d = d0 = 0, weight 1),
    // A = sum w (d - c)(d0 - c0)^T = sum w d d0^T - c (sum w d0)^T.
    let xi = positions[i];
    let x0i = rest[i];
    let mut wsum = 1.0f32;
    let mut sd = [0.0f32; 3];
    let mut sd0 = [0.0f32; 3];
    let mut sdd0 = 0.0f32;
    let mut m: Mat3 = [[0.0; 3]; 3];
    for (_, j, w) in nb.live(i) {
        let d = sub(positions[j], xi);
        let d0 = sub(rest[j], x0i);
        let wd0 = [w * d0[0], w * d0[1], w * d0[2]];
        for r in 0..3 {
            sd[r] += w * d[r];
            sd0[r] += wd0[r];
            for t in 0..3 {
                m[r][t] += d[r] * wd0[t];
            }
        }
        sdd0 += wd0[0] * d0[0] + wd0[1] * d0[1] + wd0[2] * d0[2];
        wsum += w;
    }
    let inv_w = 1.0 / wsum;
    let c = [sd[0] * inv_w, sd[1] * inv_w, sd[2] * inv_w, 0.0];
    let c0 = [-shape_vector[0], -shape_vector[1], -shape_vector[2]];
    // sum w |d0 - c0|^2 = sum w |d0|^2 - 2 c0 . sum w d0 + W |c0|^2
    let scale = sdd0 - 2.0 * (c0[0] * sd0[0] + c0[1] * sd0[1] + c0[2] * sd0[2])
        + wsum * (c0[0] * c0[0] + c0[1] * c0[1] + c0[2] * c0[2]);
    let inv = if scale > 0.0 { 1.0 / scale } else { 1.0 };
    let a: Mat3 = std::array::from_fn(|r| std::array::from_fn(|t| (m[r][t] - c[r] * sd0[t]) * inv));
    (c, extract_rotation(&a, rotation, iterations))
}

/// The paper's force on node i (equation 1): `k_s (g_i - x_i) = k_s (c_i + R_i v_i)`.
/// Updates the node's warm-start quaternion `rotation`.
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
    let (c, q) = cluster_frame(i, positions, rest, shape_vector, nb, iterations, *rotation);
    *rotation = q;
    let rv = quat_rotate(q, shape_vector);
    [
        stiffness * (c[0] + rv[0]),
        stiffness * (c[1] + rv[1]),
        stiffness * (c[2] + rv[2]),
        0.0,
    ]
}

/// Cluster forces on node j (second pass of the `cluster` variant): every cluster i that
/// contains j pulls it towards its goal `g_ij = C_i + R_i (x0_j - C0_i)` with weight w_ij,
/// `f_j = k_s sum_i w_ij (g_ij - x_j)`, its own cluster with weight 1. These are the
/// gradients of the shape matching energy `k_s/2 sum_i sum_j w_ij |g_ij - x_j|^2` (R_i
/// and C_i are its minimisers, so their derivatives drop out): conservative and
/// momentum-conserving. `centre` and `rotation` hold every node's `c_i` and `R_i` from
/// [`cluster_frame`].
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
    let xj = positions[j];
    let x0j = rest[j];
    let own = quat_rotate(rotation[j], shape_vectors[j]);
    let cj = centre[j];
    let mut f = [cj[0] + own[0], cj[1] + own[1], cj[2] + own[2], 0.0];
    for (_, i, w) in nb.live(j) {
        // g_ij - x_j = (x_i - x_j) + c_i + R_i ((x0_j - x0_i) + v_i)
        let d = sub(positions[i], xj);
        let q0 = sub(x0j, rest[i]);
        let v = shape_vectors[i];
        let r = quat_rotate(rotation[i], [q0[0] + v[0], q0[1] + v[1], q0[2] + v[2], 0.0]);
        let ci = centre[i];
        f[0] += w * (d[0] + ci[0] + r[0]);
        f[1] += w * (d[1] + ci[1] + r[1]);
        f[2] += w * (d[2] + ci[2] + r[2]);
    }
    [stiffness * f[0], stiffness * f[1], stiffness * f[2], 0.0]
}

/// Rotates v by the unit quaternion q (`[x, y, z, w]`): `v + 2 w (u x v) + 2 u x (u x v)`.
#[inline(always)]
pub fn quat_rotate(q: Vec4, v: Vec4) -> Vec4 {
    let u = [q[0], q[1], q[2], 0.0];
    let t = cross(u, v);
    let t = [2.0 * t[0], 2.0 * t[1], 2.0 * t[2], 0.0];
    let ut = cross(u, t);
    [
        v[0] + q[3] * t[0] + ut[0],
        v[1] + q[3] * t[1] + ut[1],
        v[2] + q[3] * t[2] + ut[2],
        0.0,
    ]
}
