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
//! with `F_dot = L_i` the point-set velocity gradient of node i (the operator of `J_i`
//! applied to the velocities, [`super::debunne_meshfree::velocity_gradient`]). It is the
//! Debunne model's dashpot `2 eta dev(sym(L))` at small strain, and it is frame
//! indifferent at any strain: a rigid spin has `F^T F_dot` skew, so `E_dot = 0` and no
//! force, where `2 eta dev(sym(F_dot))` would brake a body that turns. Its power
//! `P_v : F_dot = S_v : E_dot = 2 eta |dev E_dot|^2` is never negative, so it only
//! dissipates (`tests/viscosity.rs` measures both). Shear only, as the Debunne model's
//! (the reasons are there: tissue's bulk viscosity is small, and a bulk dashpot would damp
//! the compression modes that set the step). Each region may have its own `eta` (the
//! law's lane of the `node_material` row, [`ContinuumLaw::row_viscosity`]).

use super::mls::{
    ContinuumArrays, ContinuumConstants, FirstPassRow, MomentRow, NodeVolumes, StressSplit,
};
use super::traits::{BuildContext, ForceInput, ModelState, ShapeArray, ShapeRow, TissueModel};
use crate::math::Vec4;
use crate::neighbours::Neighbours;
use glam::{Mat3, Vec3};

/// A per-node hyperelastic law on the moving-least-squares gradient.
pub trait ContinuumLaw: TissueModel + Send + Sync {
    /// The constants the kernels use, and the layout of the model's `node_material` row
    /// ([`ContinuumConstants::from_row`]).
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

    /// The constants of a node's `node_material` row (by default the layout
    /// `[lambda, mu, k_v, alpha mu]` of [`ContinuumConstants::from_row`]).
    fn row_constants(&self, row: Vec4) -> ContinuumConstants {
        ContinuumConstants::from_row(row)
    }

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
    let g = super::mls::displacement_gradient(i, positions, rest, nb, inverse_moment);
    let f_dot = super::debunne_meshfree::velocity_gradient(i, velocities, rest, nb, inverse_moment);
    let p = finite_viscous_stress(&(g.j + Mat3::IDENTITY), &f_dot, eta);
    super::mls::add_first_pass_stress(q, &p, inverse_moment, rest[i][3]);
}
