//! The part of a continuum model that is not its material law: a model whose energy is
//! `U = sum_i V_i W(F_i)` on the moving-least-squares gradient ([`super::mls`]) implements
//! [`ContinuumLaw`] (its constants and its first pass, the stress of `F_i`), and
//! [`ContinuumShape`] gives it its arrays, its node rows and its CPU force. Point based
//! animation and the neo-Hookean model are such laws; the Debunne model adds a co-rotation
//! frame and keeps its own shape.
//!
//! # Tissue viscosity of a finite-strain law (Kelvin-Voigt)
//!
//! A law with a viscosity `eta` ([`ContinuumLaw::law_viscosity`]; the neo-Hookean model
//! and point based animation) gets, beside its elastic stress, the second Piola-Kirchhoff
//! stress of the deviator of the Green strain rate,
//!
//! `S_v = 2 eta dev(E_dot)`,  `E_dot = sym(F^T F_dot)`,  `P_v = F S_v`,
//!
//! with `F_dot = L_i` the point-set velocity gradient of node i,
//! `sum_j w_ij (v_j - v_i) (x0_j - x0_i)^T A_i^-1` (as
//! [`super::debunne_meshfree::velocity_gradient`]), and `F` the same operator applied to
//! the positions ([`point_set_gradients`], one loop over the neighbours for both; not the
//! integration-corrected gradient of the elastic law, whose correction term would make
//! `F^T F_dot` of a spinning, non-uniformly deformed neighbourhood other than skew). It is
//! the Debunne model's dashpot `2 eta dev(sym(L))` at small strain, and it is frame
//! indifferent at any strain: a rigid spin `v = W x + c` has `F_dot = W F`, `F^T F_dot`
//! skew, so `E_dot = 0` and no force, where `2 eta dev(sym(F_dot))` would brake a body
//! that turns. Its power `P_v : F_dot = S_v : E_dot = 2 eta |dev E_dot|^2` is never
//! negative, so it only dissipates (`tests/viscosity.rs` measures both, the spin on a
//! quadratically deformed body too). Shear only at small strain, as the Debunne model's
//! (the reasons are there: tissue's bulk viscosity is small, and a bulk dashpot would damp
//! the compression modes that set the step); at finite strain the deviator is taken in the
//! reference frame, so a volume change rate of a strained neighbourhood is damped a
//! little: for `F = diag(s, 1, 1)` a dilatation rate `a I` gives
//! `dev(E_dot) = a (s^2 - 1) / 3 diag(2, -1, -1)`, 7% of `a` at 10% stretch. (The spatial
//! form `J 2 eta dev(sym(F_dot F^-1)) F^-T` has none of it but divides by `J`, which a
//! crushed neighbourhood takes to 0.) Each region may have its own `eta` (the law's lane
//! of the `node_material` row, [`ContinuumLaw::row_viscosity`]).

use super::mls::{
    ContinuumArrays, ContinuumConstants, FirstPassRow, MomentRow, NodeVolumes, StressSplit,
};
use super::traits::{BuildContext, ForceInput, ModelState, ShapeArray, ShapeRow, TissueModel};
use crate::math::{xyz, Vec4};
use crate::neighbours::Neighbours;
use glam::{Mat3, Vec3};

/// A per-node hyperelastic law on the moving-least-squares gradient.
pub trait ContinuumLaw: TissueModel + Send + Sync {
    /// The constants the kernels use with one material.
    fn law_constants(&self) -> ContinuumConstants;

    /// The first pass of node `i` ([`super::mls::pack_first_pass`] of the law's stress).
    #[allow(clippy::too_many_arguments)]
    fn law_first_pass(
        i: usize,
        positions: &[Vec4],
        rest: &[Vec4],
        nb: &Neighbours,
        inverse_moment: &MomentRow,
        volume: f32,
        c: &ContinuumConstants,
    ) -> FirstPassRow;

    /// The material's Kelvin-Voigt shear viscosity, Pa s (module docs); 0 (the default)
    /// for a law without one.
    fn law_viscosity(&self) -> f32 {
        0.0
    }

    /// The viscosity in a node's `node_material` row ([`TissueModel::material_row`]); 0
    /// for a law without one.
    fn row_viscosity(_row: Vec4) -> f32 {
        0.0
    }

    /// The constants of a node's `node_material` row, in the law's own layout
    /// ([`TissueModel::material_row`]).
    fn row_constants(&self, row: Vec4) -> ContinuumConstants;

    /// Node `i`'s stress split for the viscoelastic update ([`StressSplit`]): the
    /// elastic stress of [`ContinuumLaw::law_first_pass`] written as `push S + extra`.
    fn law_split(
        i: usize,
        positions: &[Vec4],
        rest: &[Vec4],
        nb: &Neighbours,
        inverse_moment: &MomentRow,
        c: &ContinuumConstants,
    ) -> StressSplit;
}

/// The shape information of a [`ContinuumLaw`] model: its parameters and the continuum
/// arrays.
#[derive(Debug, Clone, PartialEq)]
pub struct ContinuumShape<L> {
    /// The parameters.
    pub params: L,
    /// Rest positions and volumes, inverse moments, first pass.
    pub continuum: ContinuumArrays,
    /// Some node has a viscosity (module docs): the first pass adds the viscous stress.
    /// Set from the material, and by [`crate::models::ShapeInfo::build`] when a region's
    /// material has one.
    pub viscous: bool,
}

impl<L: ContinuumLaw> ContinuumShape<L> {
    /// The shape of the first `n` of `rest` with volumes by `rule`.
    pub fn build(
        params: L,
        rule: NodeVolumes,
        rest: &[Vec4],
        nb: &Neighbours,
        n: usize,
        ctx: BuildContext,
    ) -> ContinuumShape<L> {
        let mut continuum = ContinuumArrays::build(rule, rest, nb, n, ctx);
        super::consistency::correct(&mut continuum, nb, n, ctx.triangles);
        ContinuumShape {
            params,
            continuum: continuum.with_prony(params.prony()),
            viscous: params.law_viscosity() > 0.0,
        }
    }
}

impl<L: ContinuumLaw> ContinuumShape<L> {
    /// Turns the viscous pass on when some node's material row has a viscosity
    /// ([`ContinuumLaw::row_viscosity`]; a region's own `viscosity`).
    pub fn note_row_viscosity(&mut self, rows: &[Vec4]) {
        self.viscous |= rows.iter().any(|row| L::row_viscosity(*row) > 0.0);
    }
}

impl<L: ContinuumLaw> ModelState for ContinuumShape<L> {
    fn arrays(&self) -> Vec<(ShapeArray, &[u8])> {
        self.continuum.arrays()
    }

    fn arrays_mut(&mut self) -> Vec<(ShapeArray, &mut [u8])> {
        self.continuum.arrays_mut()
    }

    fn node_rows(
        &self,
        i: usize,
        rest: &[Vec4],
        nb: &Neighbours,
        volume_scale: f64,
        rest_position: bool,
    ) -> Vec<ShapeRow> {
        self.continuum
            .node_rows(i, rest, nb, volume_scale, rest_position)
    }

    fn volume_scale(&self, rest: &[Vec4], nb: &Neighbours, n: usize) -> f64 {
        self.continuum.volume_scale(rest, nb, n)
    }

    fn node_volumes(&self, n: usize) -> Option<Vec<f32>> {
        Some(self.continuum.node_volumes(n))
    }

    fn cpu_forces(&mut self, input: &ForceInput, forces: &mut [Vec4]) {
        let ForceInput {
            positions: pos,
            nb,
            n,
            node_material: material,
            ..
        } = *input;
        let params = &self.params;
        let c = params.law_constants();
        let eta = params.law_viscosity();
        let viscous = self.viscous.then_some(input.velocities);
        let ContinuumArrays {
            rest_position,
            inverse_moment,
            first_pass: first,
            prony,
            visco,
            visco_next,
            ..
        } = &mut self.continuum;
        let (rest, a_inv) = (&rest_position[..], &inverse_moment[..]);
        // A local evaluation's gather reads the first pass of its nodes' neighbours.
        let ring = input.threads.one_ring(nb, n);
        let threads = input.threads.with_subset(ring.as_deref());
        if visco.is_empty() {
            threads.map_nodes(&mut first[..n], |i| {
                let c = material.map_or(c, |m| params.row_constants(m[i]));
                let mut q = L::law_first_pass(i, pos, rest, nb, &a_inv[i], rest[i][3], &c);
                if let Some(v) = viscous {
                    let eta = material.map_or(eta, |m| L::row_viscosity(m[i]));
                    add_viscous(&mut q, i, pos, v, rest, nb, &a_inv[i], eta);
                }
                q
            });
        } else {
            let coefficients = prony.coefficients(input.dt as f64);
            let prev = &visco[..];
            threads.for_each_node(&mut first[..n], &mut visco_next[..n], |i, out, next| {
                let c = material.map_or(c, |m| params.row_constants(m[i]));
                let split = L::law_split(i, pos, rest, nb, &a_inv[i], &c);
                *out = ContinuumArrays::visco_first_pass(
                    &split,
                    &prev[i],
                    next,
                    &coefficients,
                    &a_inv[i],
                    rest[i][3],
                    c.hourglass,
                );
                if let Some(v) = viscous {
                    let eta = material.map_or(eta, |m| L::row_viscosity(m[i]));
                    add_viscous(out, i, pos, v, rest, nb, &a_inv[i], eta);
                }
            });
        }
        self.continuum.gather_forces(input, forces);
    }

    fn end_step(&mut self) {
        self.continuum.end_step();
    }
}

/// The Kelvin-Voigt stress `P_v = F 2 eta dev(sym(F^T F_dot))` of a finite-strain law
/// (module docs), for the deformation gradient `f` and its rate `f_dot`.
#[inline]
pub fn finite_viscous_stress(f: &Mat3, f_dot: &Mat3, eta: f32) -> Mat3 {
    let c = f.transpose() * *f_dot;
    let e = (c + c.transpose()) * 0.5;
    let mean = (e.x_axis.x + e.y_axis.y + e.z_axis.z) / 3.0;
    *f * ((e - Mat3::from_diagonal(Vec3::splat(mean))) * (2.0 * eta))
}

/// Adds node i's viscous stress ([`finite_viscous_stress`]) to its packed first pass `q`
/// (nothing when `eta` is 0).
#[allow(clippy::too_many_arguments)]
#[inline]
fn add_viscous(
    q: &mut FirstPassRow,
    i: usize,
    positions: &[Vec4],
    velocities: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    inverse_moment: &MomentRow,
    eta: f32,
) {
    if eta <= 0.0 {
        return;
    }
    let (f, f_dot) = point_set_gradients(i, positions, velocities, rest, nb, inverse_moment);
    let p = finite_viscous_stress(&f, &f_dot, eta);
    super::mls::add_first_pass_stress(q, &p, inverse_moment, rest[i][3]);
}

/// The point-set gradients of the positions and of the velocities of node i,
/// `sum_j w_ij (x_j - x_i) (x0_j - x0_i)^T A_i^-1` and the same of `v` (module docs: one
/// operator for both, so that a rigid spin gives `F_dot = W F`), in one loop over the
/// neighbours (`kelvin_voigt.wgsl::point_set_gradients` sums in the same order).
#[inline]
pub fn point_set_gradients(
    i: usize,
    positions: &[Vec4],
    velocities: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    inverse_moment: &MomentRow,
) -> (Mat3, Mat3) {
    let (xi, vi, x0i) = (xyz(positions[i]), xyz(velocities[i]), xyz(rest[i]));
    let (mut bx, mut bv) = (Mat3::ZERO, Mat3::ZERO);
    for (_, j, w) in nb.live(i) {
        let d0 = xyz(rest[j]) - x0i;
        let dx = w * (xyz(positions[j]) - xi);
        let dv = w * (xyz(velocities[j]) - vi);
        bx += Mat3::from_cols(dx * d0.x, dx * d0.y, dx * d0.z);
        bv += Mat3::from_cols(dv * d0.x, dv * d0.y, dv * d0.z);
    }
    let a_inv = super::mls::unpack(inverse_moment);
    (bx * a_inv, bv * a_inv)
}
