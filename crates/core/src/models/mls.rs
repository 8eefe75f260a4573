//! Moving-least-squares displacement gradient and the forces of a per-node strain energy,
//! shared by the two continuum models ([`super::debunne_meshfree`] and
//! [`super::point_based`]).
//!
//! Per node i, with rest offsets `x_ij = x0_j - x0_i`, weights `w_ij` and displacement
//! differences `du_ij = (x_j - x_i) - x_ij`:
//!
//! - moment matrix `A_i = sum_j w_ij x_ij x_ij^T`, stored inverted (the first 9 floats of
//!   a [`MomentRow`]);
//! - displacement gradient `J_i = (sum_j w_ij du_ij x_ij^T) A_i^-1`, `J_ab = du_a/dx_b`
//!   (Mueller et al. 2004, eq. 5): exact for any linear displacement field;
//! - a model's energy `U_i(F_i)`, `F_i = I + J_i`, with first Piola-Kirchhoff stress
//!   `P_i = dU_i/dF_i / V_i`. Its exact gradient is gathered per node k over k's mutual
//!   neighbours: with `Q_i = V_i P_i A_i^-1`,
//!   `f_k = sum_i w_ki Q_i x_ki + Q_k sum_j w_kj x_kj`.
//! - Hourglass control: a node's gradient ignores any neighbour motion that is not
//!   affine, so zig-zag fields cost no energy (measured: random noise on a bar leaves a
//!   permanent residue). The control penalises what a *quadratic* field cannot explain:
//!   with `s_ij` the six quadratic monomials of `x_ij` ([`monomials`]), the fit
//!   `du_ij ~ Jf_i x_ij + H_i s_ij` (weighted least squares, the same weights) leaves the
//!   residual `r_ij`, and the energy is `c_i/2 sum_j w_ij |r_ij|^2` with
//!   `c_i = alpha mu V_i / sum_j w_ij |x_ij|^2`. `(Jf_i, H_i)` minimise it, so its force
//!   does not depend on their derivatives: node k gets `c_k sum_j w_kj r_kj` from its own
//!   term and `-c_i w_ik r_ik` from each neighbour's. The fit is computed on top of `J_i`:
//!   the monomials are made orthogonal to the linear ones (`t_ij = s_ij - C_i x_ij`,
//!   `C_i = (sum_j w_ij s_ij x_ij^T) A_i^-1`), then `H_i = (sum_j w_ij du_ij t_ij^T)
//!   M_i^-1`, `M_i = sum_j w_ij t_ij t_ij^T`, and `Jf_i = J_i - H_i C_i` ([`MomentRow`]
//!   stores `C_i` and `M_i^-1`). In the gather, `-c_i Jf_i` joins `Q_i`, and each pair
//!   adds `w_ki ((c_i + c_k) du_ki + (c_i H_i - c_k H_k) s_ki)`.
//!
//!   Why quadratic: the energy is zero for every field that is quadratic over a
//!   neighbourhood, which includes bending, so alpha no longer trades zero-energy modes
//!   against bending stiffness. The first-order control this replaced (`r_ij = du_ij -
//!   J_i x_ij`, until 2026-11-27) penalised the curvature of every bent body: the
//!   report's cantilever at 2,989 nodes was 10.4% too stiff with alpha 4 and 0.01% off
//!   with 0.1, while resampled bodies needed 4 (the sphere case at 2,955 nodes: 15.6% off
//!   with 0.1, 1.6% with 4), so the report and the scenes set alpha per case (the
//!   issue-41 finding). With the quadratic control one value serves the report's cases
//!   and the needle scenes. Measured with `report_case` and `needlesim run` (dev machine,
//!   CPU, 2026-11-27; co-rotated Debunne, point based and neo-Hookean within 0.3 points of
//!   Debunne's errors at alpha 4), Debunne's error against the reference with alpha 4 / 8
//!   / 16:
//!
//!   | case | nodes | 4 | 8 | 16 |
//!   |---|---:|---:|---:|---:|
//!   | cantilever | 1,025 / 2,989 | 1.8 / 0.20% | 1.6 / 0.14% | 1.3 / 0.04% |
//!   | indentation | 2,197 / 4,913 | 5.2 / 3.5% | 6.2 / 4.3% | 7.7 / 5.3% |
//!   | sphere (resampled) | 2,955 / 9,031 | 4.9 / 3.6% | 3.3 / 2.3% | 2.1 / 1.5% |
//!   | column (resampled) | 2,255 / 3,551 | 5.9 / 4.1% | 5.2 / 3.8% | 4.5 / 3.5% |
//!   | liver needle scene: jumps, largest buzz | 4,913 | 9, 25.8% | 0, 3.2% | 0, 2.3% |
//!
//!   The default is 16 (`default_hourglass`): a needle loads single nodes, and one
//!   node pushed against its held neighbours then has 0.67 of the stiffness of a
//!   trilinear FEM on the same lattice (0.26 with 4; `tests/models.rs`), which is what
//!   the needle scenes' force needs (the row above; the first-order control with 4,
//!   which the needle scenes used until 2026-11-27, gave 0.53). What still depends on
//!   alpha is where the true field is not smooth on the node scale: the punch's edge
//!   (indentation, stiffer with alpha) and spurious modes of irregular surface nodes
//!   that a quadratic happens to fit (the resampled cases, softer with small alpha).
//!   Both shrink with the spacing. For a smooth field the control's energy density is
//!   `O(h^4)` relative to the strain energy's (the residual of a quadratic fit is
//!   `O(h^3)` against offsets of `O(h)`), so the control does not change what the method
//!   converges to. The stable time step falls as the control stiffens
//!   (the cantilever at 2,989 nodes: 0.53 ms with 4, 0.36 ms with 16). Point based
//!   animation's Green strain has no energy for an inverted neighbourhood, and the
//!   control does not resist a fold that is quadratic over a neighbourhood: its large
//!   deformations need the volume term (`scenes/cube_sag_pba.toml`). The idea of a
//!   control that is blind to the fields the element represents is that of Flanagan and
//!   Belytschko (1981, IJNME 17:679-706, hourglass modes orthogonal to the linear field);
//!   taking it to the quadratic fields is our choice. Cost: the first pass fits 9
//!   unknowns instead of 3 and the gather reads 28 floats per neighbour instead of 12;
//!   measured 2026-11-27, a Debunne step takes 2.3 times as long on one CPU thread
//!   (10,000 nodes, dev machine: 270 against 620 steps/s) and 2.0 to 2.3 times on an
//!   NVIDIA H100 (100k nodes: 87 against 38 us batched; 1M: 678 against 339 us; the
//!   gather, 52 against 22 us at 100k, is now the larger pass), on top of the smaller
//!   stable step.
//!
//! - Integration correction ([`super::consistency`]): the stress is taken from
//!   `J~_i = J_i + T_i E_i`, `T_i = sum_j w_ij du_ij t_ij^T` (the first pass forms it for
//!   the fit above) and `E_i` a per-node 6x3 matrix solved at the rest state (floats
//!   48..66 of the [`MomentRow`]) so that the nodal integration passes the linear patch
//!   test on any node cloud. `T_i` is zero for every linear field, so `J~_i` stays exact
//!   for them and for rigid motions; the hourglass fit keeps `J_i`. In the first pass
//!   `G_i = V_i P_i E_i^T` (3x6) joins `Q_i` as `-G_i C_i` and the quadratic columns as
//!   `-G_i`, and the gather is unchanged. (The Kelvin-Voigt viscous stress keeps the
//!   uncorrected operator: still dissipative.)
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
use nalgebra::{DMatrix, Matrix3, SMatrix, SVector, SymmetricEigen};

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
    /// The constants of a row `[lambda, mu, k_v, alpha mu]` (the neo-Hookean model's
    /// `node_material` row is read through it with `k_v` then set to 0; each law reads its
    /// own layout, [`super::continuum::ContinuumLaw::row_constants`]).
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

/// Hourglass control alpha by default: without it zig-zag fields cost no energy; why 16,
/// the module docs' table.
pub(crate) const fn default_hourglass() -> f64 {
    16.0
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
    /// Per node `A_i^-1` (row-major 3x3, the paper's Table 1), the quadratic basis of
    /// the hourglass control and the integration correction ([`MomentRow`]).
    pub inverse_moment: Vec<MomentRow>,
    /// How the volumes were chosen (and a needle node's volume is chosen).
    pub volume_rule: NodeVolumes,
    /// First-pass result of the current step ([`pack_first_pass`]).
    pub first_pass: Vec<FirstPassRow>,
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
        let rest_position = with_volumes(rest_position, node_volumes(rule, rest, nb, n, ctx));
        let inverse_moment = moment_rows(&rest_position, nb, n);
        ContinuumArrays {
            inverse_moment,
            rest_position,
            volume_rule: rule,
            first_pass: vec![[0.0; FIRST_PASS_ROW]; rest.len()],
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
        moments: &MomentRow,
        volume: f32,
        hourglass: f32,
    ) -> FirstPassRow {
        let s = relax(&split.s0, prev, next, coefficients);
        let p = split.push * s + split.extra;
        pack_first_pass(&p, &split.gradient, moments, volume, hourglass)
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
        // A rewritten row has no integration correction ([`super::consistency`]).
        let moments = moment_row(i, rest, nb);
        let mut out = vec![row(ShapeArray::InverseMoment, i, &[moments])];
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
    /// The displacement gradient `J_i` and the hourglass control's fit.
    pub gradient: Gradient,
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

/// Floats per node of a [`MomentRow`].
pub const MOMENT_ROW: usize = 66;

/// Offset of the integration correction `E_i` in a [`MomentRow`] (6x3 row-major;
/// [`super::consistency`]).
pub const CORRECTION_OFFSET: usize = 48;

/// Node i's moment data: `A_i^-1` (row-major 3x3, floats 0..9), the hourglass control's
/// quadratic basis `C_i = (sum_j w_ij s_ij x_ij^T) A_i^-1` (6x3 row-major, floats 9..27)
/// and the inverse of its moment matrix `M_i = sum_j w_ij t_ij t_ij^T`, `t_ij = s_ij - C_i
/// x_ij` (6x6 symmetric, upper triangle row by row, floats 27..48), with `s_ij` the
/// quadratic monomials of the rest offset ([`monomials`]), and the integration
/// correction `E_i` (6x3 row-major, floats 48..66;
/// [`super::consistency::integration_corrections`]). A row
/// whose quadratic part is zero gives the first-order hourglass control (the residual of
/// the affine fit only); a row whose correction is zero, the plain MLS gradient.
pub type MomentRow = [f32; MOMENT_ROW];

/// Floats per node of the first pass ([`pack_first_pass`]).
pub const FIRST_PASS_ROW: usize = 28;

/// A node's first-pass result ([`pack_first_pass`]).
pub type FirstPassRow = [f32; FIRST_PASS_ROW];

/// Bytes per node of the arrays every continuum model has: the rest position with its
/// volume, the [`MomentRow`] and the [`FirstPassRow`].
pub const CONTINUUM_BYTES_PER_NODE: f64 = (4 * (4 + MOMENT_ROW + FIRST_PASS_ROW)) as f64;

/// The quadratic monomials of an offset `d`: `[x^2, y^2, z^2, x y, y z, z x]`.
#[inline(always)]
pub fn monomials(d: Vec3) -> [f32; 6] {
    [
        d.x * d.x,
        d.y * d.y,
        d.z * d.z,
        d.x * d.y,
        d.y * d.z,
        d.z * d.x,
    ]
}

/// [`monomials`] in f64.
pub(crate) fn monomials64(d: glam::DVec3) -> SVector<f64, 6> {
    SVector::<f64, 6>::from([
        d.x * d.x,
        d.y * d.y,
        d.z * d.z,
        d.x * d.y,
        d.y * d.z,
        d.z * d.x,
    ])
}

/// Position of entry `(r, c)`, `r <= c`, of a packed upper triangle of a 6x6 matrix.
#[inline(always)]
const fn upper6(r: usize, c: usize) -> usize {
    r * 6 - r * (r + 1) / 2 + c
}

/// Truncated pseudo-inverse of a symmetric positive semi-definite matrix of any size, as
/// [`sym_pseudo_inverse`] does it for 3x3.
fn sym_pseudo_inverse_n(a: &DMatrix<f64>, rel_tol: f64) -> DMatrix<f64> {
    let n = a.nrows();
    let eigen = SymmetricEigen::new(a.clone());
    let max = eigen.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut out = DMatrix::zeros(n, n);
    for (e, &value) in eigen.eigenvalues.iter().enumerate() {
        if max.is_nan() || max <= 0.0 || value <= rel_tol * max {
            continue;
        }
        let v = eigen.eigenvectors.column(e);
        out += v * v.transpose() * (1.0 / value);
    }
    out
}

/// Node i's [`MomentRow`]: its inverse moment matrix, truncated as described above, and
/// the quadratic basis of the hourglass control (its 6x6 moment matrix inverted the same
/// way: a neighbourhood that cannot tell a quadratic monomial from a linear one, such as
/// a lattice face where `z^2 = h z` on every neighbour, drops that direction, and the
/// fit still reproduces every quadratic field on the neighbours).
pub fn moment_row(i: usize, rest: &[Vec4], nb: &Neighbours) -> MomentRow {
    let x0i = xyz(rest[i]);
    let mut a = Matrix3::<f64>::zeros();
    let mut sx = SMatrix::<f64, 6, 3>::zeros();
    for (_, j, w) in nb.live(i) {
        let d = (xyz(rest[j]) - x0i).as_dvec3();
        let wd = w as f64 * d;
        a += Matrix3::from_fn(|r, c| wd[r] * d[c]);
        let s = monomials64(d);
        sx += s * nalgebra::RowVector3::new(wd.x, wd.y, wd.z);
    }
    let (inv, _) = sym_pseudo_inverse(&a, MOMENT_TOLERANCE);
    let mut out = [0.0f32; MOMENT_ROW];
    for e in 0..9 {
        out[e] = inv[(e / 3, e % 3)] as f32;
    }
    let c = sx * inv;
    let mut m = DMatrix::<f64>::zeros(6, 6);
    for (_, j, w) in nb.live(i) {
        let d = (xyz(rest[j]) - x0i).as_dvec3();
        let t = monomials64(d) - c * nalgebra::Vector3::new(d.x, d.y, d.z);
        m += (w as f64) * t * t.transpose();
    }
    let m_inv = sym_pseudo_inverse_n(&m, MOMENT_TOLERANCE);
    for r in 0..6 {
        for col in 0..3 {
            out[9 + 3 * r + col] = c[(r, col)] as f32;
        }
        for col in r..6 {
            out[27 + upper6(r, col)] = m_inv[(r, col)] as f32;
        }
    }
    out
}

/// Moment rows of the first `n` nodes; the rest of `capacity` are zero.
pub fn moment_rows(rest: &[Vec4], nb: &Neighbours, n: usize) -> Vec<MomentRow> {
    let mut out = vec![[0.0f32; MOMENT_ROW]; rest.len()];
    for (i, a) in out.iter_mut().enumerate().take(n) {
        *a = moment_row(i, rest, nb);
    }
    out
}

/// The first nine floats of a stored row (`A_i^-1` of a [`MomentRow`], the first-pass
/// result) as a row-major matrix.
#[inline(always)]
pub fn unpack<const N: usize>(m: &[f32; N]) -> Mat3 {
    Mat3::from_cols(
        Vec3::new(m[0], m[3], m[6]),
        Vec3::new(m[1], m[4], m[7]),
        Vec3::new(m[2], m[5], m[8]),
    )
}

/// What the first pass fits to node i's neighbourhood.
#[derive(Debug, Clone, Copy)]
pub struct Gradient {
    /// The corrected displacement gradient `J~_i = J_i + T_i E_i` (the affine fit and
    /// the integration correction, [`super::consistency`]), which the stress is taken
    /// from.
    pub j: Mat3,
    /// `sum_j w_ij |x_ij|^2`, for the hourglass stiffness.
    pub trace: f32,
    /// The linear part `J_i - H_i C_i` of the quadratic fit (`J_i` itself without a
    /// quadratic basis).
    pub fit_j: Mat3,
    /// The quadratic part `H_i` of the fit: column `m` multiplies monomial `m`.
    pub hessian: [Vec3; 6],
}

/// Node i's displacement gradient and the quadratic fit of its neighbourhood's
/// displacements (the hourglass control's, see the module docs).
#[inline]
pub fn displacement_gradient(
    i: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    moments: &MomentRow,
) -> Gradient {
    let (xi, x0i) = (xyz(positions[i]), xyz(rest[i]));
    let mut b = Mat3::ZERO;
    let mut b2 = [Vec3::ZERO; 6];
    let mut trace = 0.0f32;
    for (_, j, w) in nb.live(i) {
        let d = xyz(positions[j]) - xi;
        let d0 = xyz(rest[j]) - x0i;
        // b += du d0^T with du = w (d - d0)
        let du = w * (d - d0);
        b += Mat3::from_cols(du * d0.x, du * d0.y, du * d0.z);
        for (col, s) in b2.iter_mut().zip(monomials(d0)) {
            *col += du * s;
        }
        trace += w * d0.dot(d0);
    }
    let j = b * unpack(moments);
    let c: [Vec3; 6] = std::array::from_fn(|r| basis_row(moments, r));
    let m_inv: [[f32; 6]; 6] = std::array::from_fn(|r| {
        std::array::from_fn(|col| moments[27 + upper6(r.min(col), r.max(col))])
    });
    // B2 - B C^T, then H = (B2 - B C^T) M^-1 and the fit's linear part J - H C.
    let t: [Vec3; 6] = std::array::from_fn(|r| b2[r] - b * c[r]);
    let hessian: [Vec3; 6] = std::array::from_fn(|col| {
        let mut h = Vec3::ZERO;
        for (tr, m) in t.iter().zip(&m_inv) {
            h += *tr * m[col];
        }
        h
    });
    let mut hc = Mat3::ZERO;
    for (h, cr) in hessian.iter().zip(&c) {
        hc += Mat3::from_cols(*h * cr.x, *h * cr.y, *h * cr.z);
    }
    // The integration correction: J~ = J + T E, T's column r the fit residual moment t_r.
    // (`T E` summed first, then added: the association mls.wgsl has, so the backends round
    // alike.)
    let mut te = Mat3::ZERO;
    for (r, tr) in t.iter().enumerate() {
        let e = correction_row(moments, r);
        te += Mat3::from_cols(*tr * e.x, *tr * e.y, *tr * e.z);
    }
    Gradient {
        j: j + te,
        trace,
        fit_j: j - hc,
        hessian,
    }
}

/// Row `r` of the hourglass control's quadratic basis `C_i` in a [`MomentRow`].
#[inline(always)]
pub(crate) fn basis_row(moments: &MomentRow, r: usize) -> Vec3 {
    Vec3::new(moments[9 + 3 * r], moments[10 + 3 * r], moments[11 + 3 * r])
}

/// Row `r` of node i's integration correction `E_i` in its [`MomentRow`].
#[inline(always)]
fn correction_row(moments: &MomentRow, r: usize) -> Vec3 {
    let o = CORRECTION_OFFSET + 3 * r;
    Vec3::new(moments[o], moments[o + 1], moments[o + 2])
}

/// First-pass result of node i from its stress `P_i`: `[V_i P_i A_i^-1 - G_i C_i - c_i
/// Jf_i (9 floats, row-major), c_i, c_i H_i - G_i (18 floats, column by column)]` with the
/// hourglass stiffness `c_i = alpha mu V_i / sum_j w_ij |x_ij|^2`, the fit `Jf_i`, `H_i` of
/// [`Gradient`] and the integration correction's `G_i = V_i P_i E_i^T` (3x6).
#[inline]
pub fn pack_first_pass(
    p: &Mat3,
    g: &Gradient,
    moments: &MomentRow,
    volume: f32,
    hourglass: f32,
) -> FirstPassRow {
    let q = *p * unpack(moments);
    let c = if g.trace > 0.0 {
        hourglass * volume / g.trace
    } else {
        0.0
    };
    // The correction's stress terms: G = V P E^T (column r: V P e_r); `G C` joins the
    // linear part, `-G` the quadratic one (the gather is unchanged; module docs).
    let gr: [Vec3; 6] = std::array::from_fn(|r| volume * (*p * correction_row(moments, r)));
    let mut gc = Mat3::ZERO;
    for (r, g_r) in gr.iter().enumerate() {
        let cr = basis_row(moments, r);
        gc += Mat3::from_cols(*g_r * cr.x, *g_r * cr.y, *g_r * cr.z);
    }
    let m = (volume * q - gc - c * g.fit_j).transpose().to_cols_array();
    let mut out = [0.0f32; FIRST_PASS_ROW];
    out[..9].copy_from_slice(&m);
    out[9] = c;
    for (col, h) in g.hessian.iter().enumerate() {
        out[10 + 3 * col..13 + 3 * col].copy_from_slice(&(c * *h - gr[col]).to_array());
    }
    out
}

/// Adds a stress `p` to the linear part of a packed first pass: `V_i p A_i^-1`, as
/// [`pack_first_pass`] writes its stress, without the integration correction's terms
/// (the viscous stresses: a dashpot's dissipation needs no patch test).
#[inline]
pub fn add_first_pass_stress(q: &mut FirstPassRow, p: &Mat3, moments: &MomentRow, volume: f32) {
    let m = (volume * *p * unpack(moments)).transpose().to_cols_array();
    for (a, b) in q.iter_mut().zip(m) {
        *a += b;
    }
}

/// Column `m` of `c_i H_i` in a first-pass row.
#[inline(always)]
fn hessian_col(q: &FirstPassRow, m: usize) -> Vec3 {
    Vec3::new(q[10 + 3 * m], q[11 + 3 * m], q[12 + 3 * m])
}

/// Second pass: force on node k from every node's first-pass result (see the module
/// docs).
#[inline]
pub fn gather_force(
    k_node: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    first: &[FirstPassRow],
) -> Vec4 {
    let (xk, x0k) = (xyz(positions[k_node]), xyz(rest[k_node]));
    let own = &first[k_node];
    let own_h: [Vec3; 6] = std::array::from_fn(|col| hessian_col(own, col));
    let mut f = Vec3::ZERO;
    let mut m = Vec3::ZERO;
    for (_, i, w) in nb.live(k_node) {
        let d0 = xyz(rest[i]) - x0k;
        let d = xyz(positions[i]) - xk;
        let qi = &first[i];
        let c = w * (qi[9] + own[9]);
        f += w * (unpack(qi) * d0) + c * (d - d0);
        let mut h = Vec3::ZERO;
        for (col, s) in monomials(d0).into_iter().enumerate() {
            h += (hessian_col(qi, col) - own_h[col]) * s;
        }
        f += w * h;
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
            let a = moment_row(0, &rest, &nb);
            // Inverse of the spanned directions only: at most 1 / (smallest kept eigenvalue).
            assert!(
                a[..9]
                    .iter()
                    .all(|x| x.is_finite() && x.abs() <= 1.0 / (h * h)),
                "{a:?}"
            );
            assert!(a.iter().all(|x| x.is_finite()), "{a:?}");
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
            let g = displacement_gradient(0, &x, &rest, &nb, &a);
            for e in g.j.to_cols_array() {
                assert!(e.is_finite() && e.abs() < 1.0, "{:?}", g.j);
            }
        }
    }

    /// The hourglass control's fit reproduces any quadratic field exactly, so its residual
    /// (what the control penalises) is zero: on an irregular neighbourhood and on a
    /// lattice face, where `z^2 = h z` on every neighbour and one direction of the
    /// quadratic basis is dropped. A cubic field leaves a residual.
    #[test]
    fn the_quadratic_fit_reproduces_quadratic_fields() {
        let h = 0.01f32;
        // 18 neighbours at irregular places (a fixed pseudo-random cloud of radius 2 h).
        let mut seed = 12345u32;
        let mut rnd = || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        };
        let irregular: Vec<[f32; 3]> = (0..18)
            .map(|_| [2.0 * h * rnd(), 2.0 * h * rnd(), 2.0 * h * rnd()])
            .collect();
        // A lattice face: z in {0, h}.
        let mut face = Vec::new();
        for (x, y, z) in [
            (1, 0, 0),
            (-1, 0, 0),
            (0, 1, 0),
            (0, -1, 0),
            (1, 1, 0),
            (1, -1, 0),
            (-1, 1, 0),
            (-1, -1, 0),
            (0, 0, 1),
            (1, 0, 1),
            (-1, 0, 1),
            (0, 1, 1),
            (0, -1, 1),
            (1, 1, 1),
            (-1, -1, 1),
            (2, 0, 0),
            (0, 2, 0),
        ] {
            face.push([x as f32 * h, y as f32 * h, z as f32 * h]);
        }
        let quadratic = |p: Vec3| {
            Vec3::new(
                0.3 * p.x * p.y - 0.2 * p.z * p.z + 0.01 * p.x,
                0.5 * p.y * p.y + 0.1 * p.x * p.z,
                -0.4 * p.x * p.x + 0.2 * p.y * p.z - 0.02 * p.z,
            )
        };
        let cubic = |p: Vec3| Vec3::new(40.0 * p.x * p.x * p.x, 0.0, 0.0);
        for (label, pts) in [("irregular", &irregular), ("face", &face)] {
            let (rest, nb) = star(pts);
            let row = moment_row(0, &rest, &nb);
            let residual = |field: &dyn Fn(Vec3) -> Vec3| {
                let x: Vec<Vec4> = rest
                    .iter()
                    .map(|p| with_w(xyz(*p) + field(xyz(*p)), 0.0))
                    .collect();
                let g = displacement_gradient(0, &x, &rest, &nb, &row);
                let (mut r, mut size) = (0.0f32, 0.0f32);
                for j in 1..rest.len() {
                    let d0 = xyz(rest[j]);
                    let du = (xyz(x[j]) - xyz(x[0])) - d0;
                    let mut fit = g.fit_j * d0;
                    for (m, s) in monomials(d0).into_iter().enumerate() {
                        fit += g.hessian[m] * s;
                    }
                    r = r.max((du - fit).length());
                    size = size.max(du.length());
                }
                r / size
            };
            let (q, c) = (residual(&quadratic), residual(&cubic));
            eprintln!("{label}: residual quadratic {q:e}, cubic {c:e}");
            assert!(q < 1e-3, "{label}: quadratic residual {q:e}");
            assert!(c > 1e-2, "{label}: cubic residual {c:e}");
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
