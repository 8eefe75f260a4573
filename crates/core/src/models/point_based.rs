//! Point based animation (PBA; Mueller, Keiser, Nealen, Pauly, Gross, Alexa 2004, "Point
//! based animation of elastic, plastic and melting objects", the paper's \[MKN*04\]).
//!
//! The moving-least-squares gradient `J_i` of [`super::mls`] gives `F_i = I + J_i`, the
//! Green-Saint-Venant strain `E = (F^T F - I) / 2` and the linear isotropic stress
//! `S = lambda tr(E) I + 2 mu E` (section 4.1). The strain energy `V_i E : S / 2` and the
//! optional volume-conserving energy `k_v / 2 V_i (det F - 1)^2` (section 4.3) have the
//! first Piola-Kirchhoff stress `P = F S + k_v (det F - 1) cof F`; the forces are the
//! exact gradients of these energies, gathered as in [`super::mls`]. Mueller 2004 writes
//! `f_j = -2 V_i F S d_j`; the factor 2 does not follow from `U = V E : S / 2`, and the
//! stretched-bar patch test (reaction force = E eps times the area) holds with factor 1.
//!
//! Green strain is rotation invariant: any rigid motion gives zero force.
//!
//! Node volumes `V_i` (w lane of the rest positions) are the nodes' cells by default
//! ([`crate::scene::NodeVolumes`]). Mueller 2004 (section 4.2) takes them from the density
//! estimate `rho_i = sum_j m_j W_ij` (`node_volumes = "density"`): with equal masses
//! `V_i = m / rho_i` is proportional to `l_i^3 / (1 + sum_j w_ij)`, `l_i` the node's
//! farthest neighbour distance (the kernel's length scale), scaled so that the volumes add
//! up to the volume enclosed by the surface. Surface nodes have fewer neighbours and so
//! too large a volume: the report's cantilever is 38% too stiff at 1025 nodes with it, 4%
//! with cell volumes.
use super::mls::{mat_mul, pack_first_pass, ContinuumConstants};
use crate::math::{cross, sub, Mat3, Vec4};
use crate::neighbours::Neighbours;

/// Node volumes of the first `n` nodes from the density estimate, scaled to add up to
/// `total_volume`; slots `n..capacity` are 0.
pub fn volumes(rest: &[Vec4], nb: &Neighbours, n: usize, total_volume: f64) -> Vec<f32> {
    let raw: Vec<f64> = (0..n).map(|i| raw_volume(i, rest, nb)).collect();
    let sum: f64 = raw.iter().sum();
    let mut out = vec![0.0f32; rest.len()];
    for i in 0..n {
        out[i] = if sum > 0.0 {
            (raw[i] * total_volume / sum) as f32
        } else {
            0.0
        };
    }
    out
}

/// The unscaled density-estimate volume `l_i^3 / (1 + sum_j w_ij)` of node i.
pub fn raw_volume(i: usize, rest: &[Vec4], nb: &Neighbours) -> f64 {
    let (mut wsum, mut ell) = (1.0f64, 0.0f64);
    for (_, j, w) in nb.live(i) {
        let w = w as f64;
        wsum += w;
        let d = sub(rest[j], rest[i]);
        ell = ell.max(crate::math::norm(d) as f64);
    }
    ell.powi(3) / wsum
}

/// `I + J`.
#[inline(always)]
pub fn deformation_gradient(j: &Mat3) -> Mat3 {
    std::array::from_fn(|r| std::array::from_fn(|c| j[r][c] + if r == c { 1.0 } else { 0.0 }))
}

/// Second Piola-Kirchhoff stress `S = lambda tr(E) I + 2 mu E` of the Green strain of
/// `F = I + J`.
pub fn green_stress(j: &Mat3, lambda: f32, mu: f32) -> Mat3 {
    let f = deformation_gradient(j);
    let e: Mat3 = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            0.5 * ((0..3).map(|t| f[t][r] * f[t][c]).sum::<f32>() - if r == c { 1.0 } else { 0.0 })
        })
    });
    let tr = e[0][0] + e[1][1] + e[2][2];
    std::array::from_fn(|r| {
        std::array::from_fn(|c| 2.0 * mu * e[r][c] + if r == c { lambda * tr } else { 0.0 })
    })
}

/// First pass of node i: `P = F S + k_v (det F - 1) cof F`, packed by
/// [`pack_first_pass`].
#[inline]
pub fn first_pass(
    i: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    inverse_moment: &[f32; 9],
    volume: f32,
    c: &ContinuumConstants,
) -> [f32; 12] {
    let (j, trace) = super::mls::displacement_gradient(i, positions, rest, nb, inverse_moment);
    let f = deformation_gradient(&j);
    let mut p = mat_mul(&f, &green_stress(&j, c.lambda, c.mu));
    if c.volume_stiffness > 0.0 {
        let row = |r: usize| [f[r][0], f[r][1], f[r][2], 0.0];
        let cof = [
            cross(row(1), row(2)),
            cross(row(2), row(0)),
            cross(row(0), row(1)),
        ];
        let det = f[0][0] * cof[0][0] + f[0][1] * cof[0][1] + f[0][2] * cof[0][2];
        let s = c.volume_stiffness * (det - 1.0);
        for r in 0..3 {
            for t in 0..3 {
                p[r][t] += s * cof[r][t];
            }
        }
    }
    pack_first_pass(&p, &j, trace, inverse_moment, volume, c.hourglass)
}
