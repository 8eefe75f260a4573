//! Moving-least-squares displacement gradient and the forces of a per-node strain energy,
//! shared by the two continuum models ([`super::debunne_meshfree`] and
//! [`super::point_based`]).
//!
//! Per node i, with rest offsets `x_ij = x0_j - x0_i`, weights `w_ij` and displacement
//! differences `du_ij = (x_j - x_i) - x_ij`:
//!
//! - moment matrix `A_i = sum_j w_ij x_ij x_ij^T`, stored inverted (9 floats);
//! - displacement gradient `J_i = (sum_j w_ij du_ij x_ij^T) A_i^-1`, `J_ab = du_a/dx_b`
//!   (Mueller et al. 2004, eq. 5): exact for any linear displacement field;
//! - a model's energy `U_i(F_i)`, `F_i = I + J_i`, with first Piola-Kirchhoff stress
//!   `P_i = dU_i/dF_i / V_i`. Its exact gradient is gathered per node k over k's mutual
//!   neighbours: with `Q_i = V_i P_i A_i^-1`,
//!   `f_k = sum_i w_ki Q_i x_ki + Q_k sum_j w_kj x_kj`.
//! - Hourglass control: a node's gradient ignores any neighbour motion that is not
//!   affine, so zig-zag fields cost no energy (measured: random noise on a bar leaves a
//!   permanent residue). The energy `c_i/2 sum_j w_ij |du_ij - J_i x_ij|^2` with
//!   `c_i = alpha mu V_i / sum_j w_ij |x_ij|^2` penalises exactly that residual (J_i is its
//!   least-squares minimiser, so its force does not depend on dJ) and is zero for every
//!   affine field, so the patch test is unchanged. Its force adds `-c_i J_i` to `Q_i` and
//!   the pair term `w_ki (c_i + c_k) du_ki`.
//!
//! All forces are gradients of one energy whose terms depend only on differences:
//! momentum is conserved and the rest state gives exactly zero force.
//!
//! Ill-conditioned moment matrices (flat or collinear neighbourhoods) are inverted by a
//! truncated eigen-decomposition ([`sym_pseudo_inverse`], nalgebra's `SymmetricEigen`,
//! relative threshold [`MOMENT_TOLERANCE`]): the gradient along a direction the neighbourhood does not span
//! is taken as zero instead of being amplified by a near-zero eigenvalue.

use super::traits::{row, BuildContext, ForceInput, ShapeArray, ShapeRow};
use super::viscoelastic::{relax, Prony, ViscoCoefficients, MAX_PRONY_TERMS, SYM};
use crate::math::{with_w, xyz, Vec4};
use crate::neighbours::Neighbours;
use glam::{Mat3, Vec3};
use nalgebra::{Matrix3, SymmetricEigen};

/// Material constants of the two continuum models, in Pa, as the kernels use them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContinuumConstants {
    /// Lame lambda.
    pub lambda: f32,
    /// Lame mu.
    pub mu: f32,
    /// Volume stiffness k_v (point based animation; 0 for Debunne).
    pub volume_stiffness: f32,
    /// Hourglass coefficient alpha times mu.
    pub hourglass: f32,
}

impl ContinuumConstants {
    /// The constants of point based animation's `node_material` row
    /// `[lambda, mu, k_v, alpha mu]` ([`super::material_row`]).
    pub fn from_row(row: Vec4) -> ContinuumConstants {
        ContinuumConstants {
            lambda: row[0],
            mu: row[1],
            volume_stiffness: row[2],
            hourglass: row[3],
        }
    }
}

/// The node volumes `V_i` of the continuum models: the weights of their nodal
/// integration `U = sum_i V_i W(F_i)`. All three add up to the volume enclosed by the
/// surface; they differ in how it is shared.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum NodeVolumes {
    /// The node's cell: the part of the body nearer to it than to any other node (exact on
    /// box lattices: `h^3`, halved on each face; sub-sampled for OBJ geometry). Nodes on
    /// the surface get less, which makes bending stiffness converge (the report's
    /// cantilever).
    #[default]
    Cell,
    /// The density estimate of Mueller et al. 2004, section 4.2: `V_i = m_i / rho_i`,
    /// `rho_i = sum_j m_j W_ij`. Surface nodes have fewer neighbours, a lower density and
    /// so a larger volume: too stiff in bending.
    Density,
    /// Every node `V / n`: also too stiff in bending, by `(n+1)/(n-1)` with `n` nodes
    /// through the thickness.
    Uniform,
}

/// Lame parameters `(lambda, mu)` from Young's modulus and the Poisson ratio.
pub fn lame(young_modulus: f64, poisson_ratio: f64) -> (f64, f64) {
    let (e, nu) = (young_modulus, poisson_ratio);
    (
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
        e / (2.0 * (1.0 + nu)),
    )
}

/// Hourglass control on by default: without it zig-zag fields cost no energy.
pub(crate) const fn default_hourglass() -> f64 {
    0.1
}

impl ContinuumConstants {
    /// The constants of Young's modulus `e`, Poisson ratio `nu`, volume stiffness `kv`
    /// and hourglass alpha.
    pub fn new(e: f64, nu: f64, kv: f64, alpha: f64) -> ContinuumConstants {
        let (lambda, mu) = lame(e, nu);
        ContinuumConstants {
            lambda: lambda as f32,
            mu: mu as f32,
            volume_stiffness: kv as f32,
            hourglass: (alpha * mu) as f32,
        }
    }
}

/// The arrays every continuum model has: rest positions with the node volumes, inverse
/// moment matrices and the per-step first-pass result.
#[derive(Debug, Clone, PartialEq)]
pub struct ContinuumArrays {
    /// Rest positions x0, w = the node volume V_i in m^3 ([`NodeVolumes`]).
    pub rest_position: Vec<Vec4>,
    /// `A_i^-1`, row-major 3x3 (the paper's Table 1).
    pub inverse_moment: Vec<[f32; 9]>,
    /// How the volumes were chosen (and a needle node's volume is chosen).
    pub volume_rule: NodeVolumes,
    /// First-pass result of the current step ([`pack_first_pass`]).
    pub first_pass: Vec<[f32; 12]>,
    /// The Prony series of a viscoelastic material (empty: elastic, and the two state
    /// arrays below are empty).
    pub prony: Prony,
    /// The committed viscoelastic state per node ([`super::viscoelastic`]).
    pub visco: Vec<ViscoRow>,
    /// The state the last force evaluation computed, committed by
    /// [`ContinuumArrays::end_step`].
    pub visco_next: Vec<ViscoRow>,
}

/// One node's viscoelastic state: `S_0` and one tensor per Prony term, six floats each
/// (rows have room for [`MAX_PRONY_TERMS`] terms).
pub type ViscoRow = [f32; SYM * (1 + MAX_PRONY_TERMS)];

impl ContinuumArrays {
    /// The arrays of the first `n` of `rest` with volumes by `rule`.
    pub fn build(
        rule: NodeVolumes,
        rest: &[Vec4],
        nb: &Neighbours,
        n: usize,
        ctx: BuildContext,
    ) -> ContinuumArrays {
        let rest_position = super::local_shape_matching::rest_positions(rest);
        ContinuumArrays {
            inverse_moment: inverse_moments(&rest_position, nb, n),
            rest_position: with_volumes(rest_position, node_volumes(rule, rest, nb, n, ctx)),
            volume_rule: rule,
            first_pass: vec![[0.0; 12]; rest.len()],
            prony: Prony::elastic(),
            visco: Vec::new(),
            visco_next: Vec::new(),
        }
    }

    /// With the viscoelastic state of `prony` (none for an elastic material): every node
    /// starts unstressed.
    pub fn with_prony(mut self, prony: Prony) -> ContinuumArrays {
        self.prony = prony;
        let rows = if prony.is_empty() {
            0
        } else {
            self.first_pass.len()
        };
        self.visco = vec![[0.0; SYM * (1 + MAX_PRONY_TERMS)]; rows];
        self.visco_next = self.visco.clone();
        self
    }

    /// Commits the viscoelastic state of the last force evaluation (a swap).
    pub fn end_step(&mut self) {
        if !self.visco.is_empty() {
            std::mem::swap(&mut self.visco, &mut self.visco_next);
        }
    }

    /// The first pass of node `i` of a viscoelastic material: relaxes the elastic stress
    /// `s0` (material frame) with the node's committed state, writes its next state into
    /// `next`, and packs `push S + extra` ([`pack_first_pass`]).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn visco_first_pass(
        split: &StressSplit,
        prev: &ViscoRow,
        next: &mut ViscoRow,
        coefficients: &ViscoCoefficients,
        inverse_moment: &[f32; 9],
        volume: f32,
        hourglass: f32,
    ) -> [f32; 12] {
        let s = relax(&split.s0, prev, next, coefficients);
        let p = split.push * s + split.extra;
        pack_first_pass(&p, &split.j, split.trace, inverse_moment, volume, hourglass)
    }

    /// `rest_position`, `inverse_moment`, `first_pass`.
    pub fn arrays(&self) -> Vec<(ShapeArray, &[u8])> {
        let mut v = vec![
            (
                ShapeArray::RestPosition,
                bytemuck::cast_slice(&self.rest_position[..]),
            ),
            (
                ShapeArray::InverseMoment,
                bytemuck::cast_slice(&self.inverse_moment[..]),
            ),
            (
                ShapeArray::FirstPass,
                bytemuck::cast_slice(&self.first_pass[..]),
            ),
        ];
        if !self.visco.is_empty() {
            v.push((ShapeArray::Viscous, bytemuck::cast_slice(&self.visco[..])));
        }
        v
    }

    /// [`ContinuumArrays::arrays`], mutable.
    pub fn arrays_mut(&mut self) -> Vec<(ShapeArray, &mut [u8])> {
        let mut v = vec![
            (
                ShapeArray::RestPosition,
                bytemuck::cast_slice_mut(&mut self.rest_position[..]),
            ),
            (
                ShapeArray::InverseMoment,
                bytemuck::cast_slice_mut(&mut self.inverse_moment[..]),
            ),
            (
                ShapeArray::FirstPass,
                bytemuck::cast_slice_mut(&mut self.first_pass[..]),
            ),
        ];
        if !self.visco.is_empty() {
            v.push((
                ShapeArray::Viscous,
                bytemuck::cast_slice_mut(&mut self.visco[..]),
            ));
        }
        v
    }

    /// Node `i`'s inverse moment, and its rest position with its volume (a new node, or
    /// any node with `density` volumes, which depend on the neighbours).
    pub fn node_rows(
        &self,
        i: usize,
        rest: &[Vec4],
        nb: &Neighbours,
        volume_scale: f64,
        rest_position: bool,
    ) -> Vec<ShapeRow> {
        let mut out = vec![row(
            ShapeArray::InverseMoment,
            i,
            &[inverse_moment(i, rest, nb)],
        )];
        if rest_position || self.volume_rule == NodeVolumes::Density {
            let v = added_node_volume(self.volume_rule, i, rest, nb, volume_scale);
            let r = rest[i];
            out.push(row(ShapeArray::RestPosition, i, &[[r[0], r[1], r[2], v]]));
        }
        if rest_position && !self.visco.is_empty() {
            // A new node starts unstressed (its slot may hold a removed node's state).
            out.push(row(
                ShapeArray::Viscous,
                i,
                &[[0.0f32; SYM * (1 + MAX_PRONY_TERMS)]],
            ));
        }
        out
    }

    /// See [`super::ShapeInfo::volume_scale`].
    pub fn volume_scale(&self, rest: &[Vec4], nb: &Neighbours, n: usize) -> f64 {
        let vol: f64 = self.rest_position[..n].iter().map(|p| p[3] as f64).sum();
        let raw: f64 = match self.volume_rule {
            NodeVolumes::Density => (0..n).map(|i| raw_volume(i, rest, nb)).sum(),
            NodeVolumes::Cell | NodeVolumes::Uniform => n as f64,
        };
        if raw > 0.0 {
            vol / raw
        } else {
            0.0
        }
    }

    /// The volumes of the first `n` nodes.
    pub fn node_volumes(&self, n: usize) -> Vec<f32> {
        self.rest_position[..n].iter().map(|p| p[3]).collect()
    }

    /// The second pass: every node's force from the first-pass results.
    pub fn gather_forces(&self, input: &ForceInput, forces: &mut [Vec4]) {
        let (pos, nb) = (input.positions, input.nb);
        let (rest, first) = (&self.rest_position[..], &self.first_pass[..]);
        input
            .threads
            .map_nodes(forces, |i| gather_force(i, pos, rest, nb, first));
    }
}

/// A node's stress split for the viscoelastic update: `P = push S + extra`, with `S` the
/// elastic stress in the material frame that relaxes and `extra` the part that does not
/// (point based animation's volume term), and the gradient the first pass packs.
#[derive(Debug, Clone, Copy)]
pub struct StressSplit {
    /// The elastic stress in the material frame (symmetric).
    pub s0: Mat3,
    /// What maps it to the first Piola-Kirchhoff stress (`I`, `R` or `F`).
    pub push: Mat3,
    /// A stress that stays elastic.
    pub extra: Mat3,
    /// The displacement gradient `J_i`.
    pub j: Mat3,
    /// `sum_j w_ij |x_ij|^2`, for the hourglass stiffness.
    pub trace: f32,
}

/// Checks the keys every continuum model has; errors name `{key}.<parameter>`.
pub(crate) fn validate_continuum(
    key: &str,
    young_modulus: f64,
    poisson_ratio: f64,
    hourglass: f64,
) -> Result<(), crate::error::SceneError> {
    crate::validate::elastic_moduli(key, young_modulus, poisson_ratio)?;
    crate::validate::non_negative_finite(&format!("{key}.hourglass"), hourglass)
}

/// Node volumes `V_i` of the first `n` nodes by `rule`, adding up to the enclosed volume;
/// slots `n..capacity` are 0.
pub fn node_volumes(
    rule: NodeVolumes,
    rest: &[Vec4],
    nb: &Neighbours,
    n: usize,
    ctx: BuildContext,
) -> Vec<f32> {
    match rule {
        NodeVolumes::Density => density_volumes(rest, nb, n, ctx.volume),
        NodeVolumes::Cell | NodeVolumes::Uniform => {
            let mut out = vec![0.0f32; rest.len()];
            for (i, v) in out.iter_mut().enumerate().take(n) {
                *v = match rule {
                    NodeVolumes::Cell => ctx.node_volumes[i] as f32,
                    _ => (ctx.volume / n as f64) as f32,
                };
            }
            out
        }
    }
}

/// `rest` with each node's volume in its w lane.
pub fn with_volumes(mut rest: Vec<Vec4>, volumes: Vec<f32>) -> Vec<Vec4> {
    for (p, v) in rest.iter_mut().zip(volumes) {
        p[3] = v;
    }
    rest
}

/// Volume of node `i` added by the needle, given [`super::ShapeInfo::volume_scale`]: its
/// scaled density estimate for `density` volumes, the mean node volume otherwise.
pub fn added_node_volume(
    rule: NodeVolumes,
    i: usize,
    rest: &[Vec4],
    nb: &Neighbours,
    scale: f64,
) -> f32 {
    match rule {
        NodeVolumes::Density => (raw_volume(i, rest, nb) * scale) as f32,
        _ => scale as f32,
    }
}

/// Relative eigenvalue threshold for inverting the moment matrix (condition number at
/// most 1000).
pub const MOMENT_TOLERANCE: f64 = 1e-3;

/// Truncated pseudo-inverse of a symmetric positive semi-definite 3x3 matrix:
/// eigen-directions whose eigenvalue is not above `rel_tol` times the largest are dropped
/// (their inverse is taken as 0), so a flat or collinear point set gives a bounded inverse
/// instead of a huge one. Returns the inverse and the number of directions kept (0 and a
/// zero matrix when the largest eigenvalue is not positive or is NaN).
pub fn sym_pseudo_inverse(a: &Matrix3<f64>, rel_tol: f64) -> (Matrix3<f64>, usize) {
    let eigen = SymmetricEigen::new(*a);
    let max = eigen.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut out = Matrix3::zeros();
    let mut rank = 0;
    for (e, &value) in eigen.eigenvalues.iter().enumerate() {
        if max.is_nan() || max <= 0.0 || value <= rel_tol * max {
            continue;
        }
        rank += 1;
        let v = eigen.eigenvectors.column(e);
        out += v * v.transpose() * (1.0 / value);
    }
    (out, rank)
}

/// Inverse moment matrix `A_i^-1` of node i (row-major), truncated as described above.
pub fn inverse_moment(i: usize, rest: &[Vec4], nb: &Neighbours) -> [f32; 9] {
    let x0i = xyz(rest[i]);
    let mut a = Matrix3::<f64>::zeros();
    for (_, j, w) in nb.live(i) {
        let d = (xyz(rest[j]) - x0i).as_dvec3();
        let wd = w as f64 * d;
        a += Matrix3::from_fn(|r, c| wd[r] * d[c]);
    }
    let (inv, _) = sym_pseudo_inverse(&a, MOMENT_TOLERANCE);
    std::array::from_fn(|e| inv[(e / 3, e % 3)] as f32)
}

/// Inverse moment matrices of the first `n` nodes; the rest of `capacity` are zero.
pub fn inverse_moments(rest: &[Vec4], nb: &Neighbours, n: usize) -> Vec<[f32; 9]> {
    let mut out = vec![[0.0f32; 9]; rest.len()];
    for (i, a) in out.iter_mut().enumerate().take(n) {
        *a = inverse_moment(i, rest, nb);
    }
    out
}

/// A stored row-major 9-float matrix (`inverse_moment`, the first-pass result) as a
/// matrix.
#[inline(always)]
pub fn unpack<const N: usize>(m: &[f32; N]) -> Mat3 {
    Mat3::from_cols(
        Vec3::new(m[0], m[3], m[6]),
        Vec3::new(m[1], m[4], m[7]),
        Vec3::new(m[2], m[5], m[8]),
    )
}

/// Displacement gradient `J_i` at node i and `sum_j w_ij |x_ij|^2` (for hourglass
/// control).
#[inline]
pub fn displacement_gradient(
    i: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    inverse_moment: &[f32; 9],
) -> (Mat3, f32) {
    let (xi, x0i) = (xyz(positions[i]), xyz(rest[i]));
    let mut b = Mat3::ZERO;
    let mut trace = 0.0f32;
    for (_, j, w) in nb.live(i) {
        let d = xyz(positions[j]) - xi;
        let d0 = xyz(rest[j]) - x0i;
        // b += du d0^T with du = w (d - d0)
        let du = w * (d - d0);
        b += Mat3::from_cols(du * d0.x, du * d0.y, du * d0.z);
        trace += w * d0.dot(d0);
    }
    (b * unpack(inverse_moment), trace)
}

/// First-pass result of node i from its stress `P_i`: `[V_i P_i A_i^-1 - c_i J_i (9
/// floats, row-major), c_i, 0, 0]` with the hourglass stiffness
/// `c_i = alpha mu V_i / sum_j w_ij |x_ij|^2`.
#[inline]
pub fn pack_first_pass(
    p: &Mat3,
    j: &Mat3,
    trace: f32,
    inverse_moment: &[f32; 9],
    volume: f32,
    hourglass: f32,
) -> [f32; 12] {
    let q = *p * unpack(inverse_moment);
    let c = if trace > 0.0 {
        hourglass * volume / trace
    } else {
        0.0
    };
    let m = (volume * q - c * *j).transpose().to_cols_array();
    let mut out = [0.0f32; 12];
    out[..9].copy_from_slice(&m);
    out[9] = c;
    out
}

/// Second pass: force on node k from every node's first-pass result (see the module
/// docs).
#[inline]
pub fn gather_force(
    k_node: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    first: &[[f32; 12]],
) -> Vec4 {
    let (xk, x0k) = (xyz(positions[k_node]), xyz(rest[k_node]));
    let own = &first[k_node];
    let mut f = Vec3::ZERO;
    let mut m = Vec3::ZERO;
    for (_, i, w) in nb.live(k_node) {
        let d0 = xyz(rest[i]) - x0k;
        let d = xyz(positions[i]) - xk;
        let qi = &first[i];
        let c = w * (qi[9] + own[9]);
        f += w * (unpack(qi) * d0) + c * (d - d0);
        m += w * d0;
    }
    with_w(f + unpack(own) * m, 0.0)
}

/// Node volumes of the first `n` nodes from Mueller 2004's density estimate, scaled to add up to
/// `total_volume`; slots `n..capacity` are 0.
pub fn density_volumes(rest: &[Vec4], nb: &Neighbours, n: usize, total_volume: f64) -> Vec<f32> {
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
        ell = ell.max((xyz(rest[j]) - xyz(rest[i])).length() as f64);
    }
    ell.powi(3) / wsum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Node 0 and `pts` as its neighbours (weight 1), in a 1-row neighbour table.
    fn star(pts: &[[f32; 3]]) -> (Vec<Vec4>, Neighbours) {
        let mut rest = vec![[0.0f32; 4]];
        rest.extend(pts.iter().map(|p| [p[0], p[1], p[2], 0.0]));
        let k = pts.len();
        let mut index = vec![0u32; rest.len() * k];
        let mut weight = vec![0.0f32; rest.len() * k];
        for s in 0..k {
            index[s] = s as u32 + 1;
            weight[s] = 1.0;
        }
        (rest, Neighbours { k, index, weight })
    }

    #[test]
    fn flat_and_collinear_neighbourhoods_give_bounded_gradients() {
        let h = 0.01f32;
        let flat = [
            [h, 0.0, 0.0],
            [-h, 0.0, 0.0],
            [0.0, h, 0.0],
            [0.0, -h, 0.0],
            [h, h, 0.0],
        ];
        let line = [[h, 0.0, 0.0], [-h, 0.0, 0.0], [2.0 * h, 0.0, 0.0]];
        for pts in [&flat[..], &line[..]] {
            let (rest, nb) = star(pts);
            let a = inverse_moment(0, &rest, &nb);
            // Inverse of the spanned directions only: at most 1 / (smallest kept eigenvalue).
            assert!(
                a.iter().all(|x| x.is_finite() && x.abs() <= 1.0 / (h * h)),
                "{a:?}"
            );
            // Stretch by 1% along x and lift the neighbours (not the node) by 0.3 h out of
            // their plane or line: the gradient stays finite and of order lift / h, with no
            // amplification by the missing directions.
            let x: Vec<Vec4> = rest
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let lift = if i == 0 { 0.0 } else { 0.3 * h };
                    [p[0] * 1.01, p[1] + lift, p[2] + lift, 0.0]
                })
                .collect();
            let (j, _) = displacement_gradient(0, &x, &rest, &nb, &a);
            for e in j.to_cols_array() {
                assert!(e.is_finite() && e.abs() < 1.0, "{j:?}");
            }
        }
    }

    #[test]
    fn pseudo_inverse_inverts_full_rank_and_drops_flat_directions() {
        let a = Matrix3::new(4.0, 1.0, 0.0, 1.0, 3.0, 0.5, 0.0, 0.5, 2.0);
        let (inv, rank) = sym_pseudo_inverse(&a, 1e-9);
        assert_eq!(rank, 3);
        let p = a * inv;
        for r in 0..3 {
            for c in 0..3 {
                let want = if r == c { 1.0 } else { 0.0 };
                assert!((p[(r, c)] - want).abs() < 1e-12, "{r}{c}: {}", p[(r, c)]);
            }
        }
        // A flat point set (all in z = 0) has no z information: the z row stays 0.
        let flat = Matrix3::new(2.0, 0.5, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 1e-14);
        let (inv, rank) = sym_pseudo_inverse(&flat, 1e-6);
        assert_eq!(rank, 2);
        assert!(inv[(2, 2)].abs() < 1e-12 && inv.iter().all(|x| x.is_finite()));
    }
}
