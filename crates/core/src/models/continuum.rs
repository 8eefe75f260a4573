//! The part of a continuum model that is not its material law: a model whose energy is
//! `U = sum_i V_i W(F_i)` on the moving-least-squares gradient ([`super::mls`]) implements
//! [`ContinuumLaw`] (its constants and its first pass, the stress of `F_i`), and
//! [`ContinuumShape`] gives it its arrays, its node rows and its CPU force. Point based
//! animation and the neo-Hookean model are such laws; the Debunne model adds a co-rotation
//! frame and keeps its own shape.

use super::mls::{
    ContinuumArrays, ContinuumConstants, FirstPassRow, MomentRow, NodeVolumes, StressSplit,
};
use super::traits::{BuildContext, ForceInput, ModelState, ShapeArray, ShapeRow, TissueModel};
use crate::math::Vec4;
use crate::neighbours::Neighbours;

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
        let c = self.params.law_constants();
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
                let c = material.map_or(c, |m| ContinuumConstants::from_row(m[i]));
                L::law_first_pass(i, pos, rest, nb, &a_inv[i], rest[i][3], &c)
            });
        } else {
            let coefficients = prony.coefficients(input.dt as f64);
            let prev = &visco[..];
            threads.for_each_node(&mut first[..n], &mut visco_next[..n], |i, out, next| {
                let c = material.map_or(c, |m| ContinuumConstants::from_row(m[i]));
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
            });
        }
        self.continuum.gather_forces(input, forces);
    }

    fn end_step(&mut self) {
        self.continuum.end_step();
    }
}
