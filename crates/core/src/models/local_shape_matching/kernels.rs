//! The shape matching kernels: cluster sums, frames and forces, per node or four slots at
//! a time (the equations are in the parent module).

use crate::math::{gather4, with_w, xyz, Vec4};
use crate::models::mueller2016_rotation::{extract_rotation, extract_rotation4};
use crate::neighbours::Neighbours;
use glam::{Mat3, Quat, Vec3, Vec4 as Lanes4};

/// Weighted mean of the neighbour offsets `d_j = p_j - p_i` over node i's cluster (the
/// node itself has offset 0 and weight 1), summed slot by slot as [`cluster_frame`] and the
/// WGSL kernels sum, so that the rest state gives exactly zero force there.
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

/// The sums over node i's cluster that its frame needs, with `d_j = x_j - x_i`,
/// `d0_j = x0_j - x0_i` and the node itself weight 1.
#[derive(Debug, Clone, Copy)]
struct ClusterSums {
    /// `sum w d`.
    sd: Vec3,
    /// `1 + sum w`.
    wsum: f32,
    /// `sum w d0`.
    sd0: Vec3,
    /// `sum w d d0^T`.
    m: Mat3,
    /// `sum w |d0|^2`.
    sdd0: f32,
}

/// [`ClusterSums`] four slots at a time: the neighbours' positions (and rest positions)
/// are gathered into x, y, z lanes, an empty slot (weight 0) is masked to a zero offset,
/// and the lanes are summed at the end, then the slots past the last group of four one by
/// one ([`slot_sums`]).
#[inline(always)]
fn cluster_sums(i: usize, positions: &[Vec4], rest: &[Vec4], nb: &Neighbours) -> ClusterSums {
    let k = nb.k;
    let row = i * k..(i + 1) * k;
    let (index, weight) = (&nb.index[row.clone()], &nb.weight[row]);
    let splat = |v: Vec4| [0, 1, 2].map(|a| Lanes4::splat(v[a]));
    let (x, x0) = (splat(positions[i]), splat(rest[i]));
    let z = Lanes4::ZERO;
    let (mut sd, mut sd0, mut m) = ([z; 3], [z; 3], [[z; 3]; 3]);
    let (mut sdd0, mut wsum) = (z, z);
    let groups = k / 4;
    for g in 0..groups {
        let s = 4 * g;
        let j = [index[s], index[s + 1], index[s + 2], index[s + 3]].map(|j| j as usize);
        let w = Lanes4::from_slice(&weight[s..s + 4]);
        let live = w.cmpne(z);
        let p = gather4(positions, j);
        let d = [p.x_axis, p.y_axis, p.z_axis];
        let d: [Lanes4; 3] = std::array::from_fn(|a| Lanes4::select(live, d[a] - x[a], z));
        for a in 0..3 {
            sd[a] += w * d[a];
        }
        wsum += w;
        let r = gather4(rest, j);
        let r = [r.x_axis, r.y_axis, r.z_axis];
        let d0: [Lanes4; 3] = std::array::from_fn(|a| Lanes4::select(live, r[a] - x0[a], z));
        let wd0 = d0.map(|c| w * c);
        for a in 0..3 {
            sd0[a] += wd0[a];
            for b in 0..3 {
                m[a][b] += d[a] * wd0[b];
            }
        }
        sdd0 += wd0[0] * d0[0] + wd0[1] * d0[1] + wd0[2] * d0[2];
    }
    let sum3 =
        |v: [Lanes4; 3]| Vec3::new(v[0].element_sum(), v[1].element_sum(), v[2].element_sum());
    let out = ClusterSums {
        sd: sum3(sd),
        wsum: 1.0 + wsum.element_sum(),
        sd0: sum3(sd0),
        m: Mat3::from_cols(
            Vec3::new(
                m[0][0].element_sum(),
                m[1][0].element_sum(),
                m[2][0].element_sum(),
            ),
            Vec3::new(
                m[0][1].element_sum(),
                m[1][1].element_sum(),
                m[2][1].element_sum(),
            ),
            Vec3::new(
                m[0][2].element_sum(),
                m[1][2].element_sum(),
                m[2][2].element_sum(),
            ),
        ),
        sdd0: sdd0.element_sum(),
    };
    slot_sums(i, 4 * groups..k, positions, rest, nb, out)
}

/// Adds the terms of node i's live slots `slots` (0-based within its row), one by one in
/// slot order, to `acc`.
#[inline(always)]
fn slot_sums(
    i: usize,
    slots: std::ops::Range<usize>,
    positions: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    mut acc: ClusterSums,
) -> ClusterSums {
    let (xi, x0i) = (xyz(positions[i]), xyz(rest[i]));
    for slot in slots.start + i * nb.k..slots.end + i * nb.k {
        let w = nb.weight[slot];
        if w == 0.0 {
            continue;
        }
        let j = nb.index[slot] as usize;
        let d = xyz(positions[j]) - xi;
        let d0 = xyz(rest[j]) - x0i;
        let wd0 = w * d0;
        acc.sd += w * d;
        acc.sd0 += wd0;
        acc.m += outer(d, wd0);
        acc.sdd0 += wd0.dot(d0);
        acc.wsum += w;
    }
    acc
}

/// Centre offset `c_i` and rotation `R_i` (as a quaternion, refined from the warm start
/// `rotation`) of node i's cluster, slot by slot in the WGSL kernels' order (used by the
/// cluster-force variant and co-rotated Debunne; [`cluster_frames`] is the four-node
/// form the paper's per-node forces use).
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
    let start = ClusterSums {
        sd: Vec3::ZERO,
        wsum: 1.0,
        sd0: Vec3::ZERO,
        m: Mat3::ZERO,
        sdd0: 0.0,
    };
    let s = slot_sums(i, 0..nb.k, positions, rest, nb, start);
    let (c, a) = frame_matrix(s, shape_vector);
    (c, extract_rotation(&a, rotation, iterations))
}

/// Centre offset `c_i` and the scaled matrix `A_i` of node i's cluster from the four-lane
/// sums.
#[inline(always)]
fn cluster_matrix(
    i: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    shape_vector: Vec4,
    nb: &Neighbours,
) -> (Vec3, Mat3) {
    frame_matrix(cluster_sums(i, positions, rest, nb), shape_vector)
}

/// `c = sum w d / W` and `A = (sum w d d0^T - c (sum w d0)^T) / sum w |d0 - c0|^2`, the
/// matrix whose rotation the frame takes (the node itself has d = d0 = 0, weight 1).
#[inline(always)]
fn frame_matrix(s: ClusterSums, shape_vector: Vec4) -> (Vec3, Mat3) {
    let c = s.sd * (1.0 / s.wsum);
    let c0 = -xyz(shape_vector);
    // sum w |d0 - c0|^2 = sum w |d0|^2 - 2 c0 . sum w d0 + W |c0|^2
    let scale = s.sdd0 - 2.0 * c0.dot(s.sd0) + s.wsum * c0.dot(c0);
    let inv = if scale > 0.0 { 1.0 / scale } else { 1.0 };
    (c, (s.m - outer(c, s.sd0)) * inv)
}

/// [`cluster_frame`] for the nodes `first..first + rotations.len()`, four at a time:
/// each node's sums and matrix, then one [`extract_rotation4`] for the four (the last
/// group padded with copies of its first node, whose extra lanes are dropped). Updates
/// each warm-start quaternion in `rotations` and calls `each(k, c, R)` for node
/// `first + k`. Each node's result depends only on its own cluster, so any chunking of the
/// nodes gives the same bits.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn cluster_frames(
    first: usize,
    rotations: &mut [Vec4],
    positions: &[Vec4],
    rest: &[Vec4],
    shape_vectors: &[Vec4],
    nb: &Neighbours,
    iterations: u32,
    mut each: impl FnMut(usize, Vec3, Quat),
) {
    for (g, q4) in rotations.chunks_mut(4).enumerate() {
        let base = first + 4 * g;
        let lane_node = |lane: usize| lane.min(q4.len() - 1);
        let frames: [(Vec3, Mat3); 4] = std::array::from_fn(|lane| {
            let i = base + lane_node(lane);
            cluster_matrix(i, positions, rest, shape_vectors[i], nb)
        });
        // Entry (r, c) of the four lanes' matrices, read in place: through
        // `frames.map(..)` (a copy of the four frames and an outlined call per entry)
        // this transpose took a fifth of the shape matching step (perf, peers harness,
        // 10,648 nodes, dev machine, 2026-11-28).
        let m = [frames[0].1, frames[1].1, frames[2].1, frames[3].1];
        let a = std::array::from_fn(|r| {
            std::array::from_fn(|c| {
                Lanes4::new(
                    m[0].col(c)[r],
                    m[1].col(c)[r],
                    m[2].col(c)[r],
                    m[3].col(c)[r],
                )
            })
        });
        let q = std::array::from_fn(|e| {
            Lanes4::from_array(std::array::from_fn(|lane| q4[lane_node(lane)][e]))
        });
        let q = extract_rotation4(&a, q, iterations).map(|v| v.to_array());
        for (lane, stored) in q4.iter_mut().enumerate() {
            let r = Quat::from_xyzw(q[0][lane], q[1][lane], q[2][lane], q[3][lane]);
            *stored = r.to_array();
            each(4 * g + lane, frames[lane].0, r);
        }
    }
}

/// [`node_force`] for the nodes `first..first + forces.len()` through [`cluster_frames`].
#[allow(clippy::too_many_arguments)]
pub fn node_forces(
    first: usize,
    forces: &mut [Vec4],
    rotations: &mut [Vec4],
    positions: &[Vec4],
    rest: &[Vec4],
    shape_vectors: &[Vec4],
    nb: &Neighbours,
    stiffness: f32,
    iterations: u32,
) {
    cluster_frames(
        first,
        rotations,
        positions,
        rest,
        shape_vectors,
        nb,
        iterations,
        |k, c, r| {
            let sv = xyz(shape_vectors[first + k]);
            forces[k] = with_w(stiffness * (c + quat_rotate(r, sv)), 0.0);
        },
    );
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

/// [`cluster_force`] with a stiffness per cluster (`material[i][0] = k_s,i`,
/// [`crate::models::material_row`]): `f_j = k_s,j (g_jj - x_j) + sum_i k_s,i w_ij (g_ij - x_j)`,
/// the gradient of `sum_i k_s,i / 2 sum_j w_ij |g_ij - x_j|^2`.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn cluster_force_mixed(
    j: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    shape_vectors: &[Vec4],
    nb: &Neighbours,
    material: &[Vec4],
    centre: &[Vec4],
    rotation: &[Vec4],
) -> Vec4 {
    let xj = xyz(positions[j]);
    let x0j = xyz(rest[j]);
    let own = quat_rotate(Quat::from_array(rotation[j]), xyz(shape_vectors[j]));
    let mut f = material[j][0] * (xyz(centre[j]) + own);
    for (_, i, w) in nb.live(j) {
        let d = xyz(positions[i]) - xj;
        let q0 = x0j - xyz(rest[i]);
        let r = quat_rotate(Quat::from_array(rotation[i]), q0 + xyz(shape_vectors[i]));
        f += (material[i][0] * w) * (d + xyz(centre[i]) + r);
    }
    with_w(f, 0.0)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Random clouds and rows (empty slots included) for every K from 1 to 19: the
    /// four-lane sums match a slot-by-slot sum to f32 reordering (relative 1e-5 of the sum
    /// of the terms' magnitudes).
    #[test]
    fn lane_sums_match_slot_by_slot_sums() {
        let mut rnd = crate::math::test_rng(0x9e37_79b9_7f4a_7c15u64);
        let n = 40;
        let pos: Vec<Vec4> = (0..n).map(|_| [rnd(), rnd(), rnd(), 1.0]).collect();
        let rest: Vec<Vec4> = (0..n).map(|_| [rnd(), rnd(), rnd(), 1.0]).collect();
        for k in 1..20 {
            let index: Vec<u32> = (0..n * k)
                .map(|_| (rnd() * n as f32) as u32 % n as u32)
                .collect();
            let weight: Vec<f32> = (0..n * k)
                .map(|_| if rnd() < 0.2 { 0.0 } else { rnd() })
                .collect();
            let nb = Neighbours { k, index, weight };
            for i in 0..n {
                let got = cluster_sums(i, &pos, &rest, &nb);
                let (mut sd, mut sd0, mut m, mut sdd0, mut wsum) =
                    (Vec3::ZERO, Vec3::ZERO, Mat3::ZERO, 0.0f32, 1.0f32);
                let mut mag = 0.0f32;
                for (_, j, w) in nb.live(i) {
                    let d = xyz(pos[j]) - xyz(pos[i]);
                    let d0 = xyz(rest[j]) - xyz(rest[i]);
                    sd += w * d;
                    sd0 += w * d0;
                    m += outer(d, w * d0);
                    sdd0 += w * d0.dot(d0);
                    wsum += w;
                    mag += w * (1.0 + d.length()) * (1.0 + d0.length());
                }
                let tol = 1e-5 * mag.max(1.0);
                let close = |a: f32, b: f32| (a - b).abs() <= tol;
                assert!((0..3).all(|a| close(got.sd[a], sd[a]) && close(got.sd0[a], sd0[a])));
                let (gm, rm) = (got.m.to_cols_array(), m.to_cols_array());
                assert!(
                    (0..9).all(|e| close(gm[e], rm[e])),
                    "K = {k}: {gm:?} vs {rm:?}"
                );
                assert!(
                    close(got.sdd0, sdd0) && close(got.wsum, wsum),
                    "K = {k}, node {i}"
                );
            }
        }
    }

    /// The four-node path gives each node what the one-node path gives (to f32 round-off
    /// of the rotation's different operation order), for node counts that leave a partial
    /// last group, and the same bits whatever the chunking.
    #[test]
    fn node_forces_match_node_force() {
        let mut rnd = crate::math::test_rng(0x1234_5678_9abc_def1u64);
        let n = 23;
        let k = 6;
        let rest: Vec<Vec4> = (0..n).map(|_| [rnd(), rnd(), rnd(), 1.0]).collect();
        let pos: Vec<Vec4> = rest
            .iter()
            .map(|r| [1.2 * r[0] + 0.05 * rnd(), r[1] - 0.3 * r[0], r[2], 1.0])
            .collect();
        let index: Vec<u32> = (0..n * k)
            .map(|s| ((s / k + 1 + s % k) % n) as u32)
            .collect();
        let weight: Vec<f32> = (0..n * k).map(|_| 0.2 + rnd()).collect();
        let nb = Neighbours { k, index, weight };
        let sv: Vec<Vec4> = (0..n).map(|i| shape_vector(i, &rest, &nb)).collect();
        let start = Quat::from_axis_angle(Vec3::Z, 0.1).to_array();
        let mut f = vec![[0.0; 4]; n];
        let mut q = vec![start; n];
        node_forces(0, &mut f, &mut q, &pos, &rest, &sv, &nb, 50.0, 4);
        let (mut f2, mut q2) = (vec![[0.0; 4]; n], vec![start; n]);
        for (first, len) in [(0, 5), (5, 9), (14, 9)] {
            let r = first..first + len;
            node_forces(
                first,
                &mut f2[r.clone()],
                &mut q2[r],
                &pos,
                &rest,
                &sv,
                &nb,
                50.0,
                4,
            );
        }
        assert_eq!((&f, &q), (&f2, &q2), "chunking changed the bits");
        for i in 0..n {
            let mut qi = start;
            let fi = node_force(i, &pos, &rest, sv[i], &nb, 50.0, 4, &mut qi);
            let scale = 50.0 * xyz(fi).length().max(1e-3);
            for c in 0..3 {
                assert!(
                    (f[i][c] - fi[c]).abs() < 1e-4 * scale,
                    "node {i}: {f:?} vs {fi:?}"
                );
            }
            assert!((0..4).all(|e| (q[i][e] - qi[e]).abs() < 1e-5), "node {i}");
        }
    }
}
