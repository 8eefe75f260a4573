//! Debunne's meshfree linear elasticity (DEB; Debunne, Desbrun, Barr, Cani 1999,
//! "Interactive multiresolution animation of deformable models", the paper's \[DDBC99\]).
//!
//! Debunne et al. step Navier's equation of linear elasticity,
//! `rho a = mu Lap(u) + (lambda + mu) grad(div u)`, at every node, with the Laplacian and
//! grad(div) approximated by weighted sums of neighbour differences `u_j - u_i`. We keep
//! the model (small-strain linear elasticity on the node set, displacements `u = x - x0`
//! in the rest frame) but discretise it through its energy instead of evaluating the two
//! operators at each node (collocation):
//!
//! `U = sum_i V_i (mu eps_i : eps_i + lambda/2 tr(eps_i)^2)`, `eps_i = (J_i + J_i^T) / 2`,
//!
//! with `J_i` the point-set displacement gradient of [`super::mls`] and `V_i` the node's
//! volume ([`crate::scene::NodeVolumes`], by default its cell: `h^3` inside a lattice, halved
//! on each face). This sum is a nodal quadrature of the strain energy: weighting surface
//! nodes like interior ones (`V / n` for all) overestimates the bending stiffness of a
//! plate or beam with `n` nodes through its thickness by `(n + 1) / (n - 1)`.
//!
//! Inside the body its forces `-dU/dx` approximate `V_i (mu Lap(u) + (lambda + mu)
//! grad(div u))`; at the surface they leave the traction free, which collocation does not.
//! Why not collocation: we first implemented it (per-neighbour coefficients from a local
//! quadratic least-squares fit, exact for quadratic fields, plus a surface traction term
//! `-sigma_i a_i`). It passed the stretched-bar patch test (reaction 0.95 E eps, lateral
//! strain 0.93 nu eps) but its stiffness matrix is not symmetric: a clamped bar with
//! 1e-5 m noise grew 1000x in 1.4 s despite 30/s damping, and symmetrising the blocks made
//! it blow up at once. (Those runs used the neighbour lists before the point-symmetric
//! tie-break of [`crate::neighbours`]; asymmetric neighbourhoods may have contributed.)
//! The energy form is symmetric, conserves momentum, and is stable below the usual time
//! step limit. The constants of Debunne's original operators could not be checked
//! against the 1999 paper (not available to us); the energy form needs none.
//!
//! The model is linear: rigid translations and infinitesimal rotations give zero force,
//! finite rotations do not (the paper's observation that DEB breaks down under large
//! rotations). With `corotated = true` each node's shape matching rotation `R_i` (as in
//! [`super::local_shape_matching`]) is factored out first, `eps_i = sym(R_i^T F_i) - I`,
//! `P_i = R_i sigma_i`, which makes every rigid motion force free.
//!
//! Shape information: rest positions with the node volume in w, inverse moment matrices (9
//! floats per node), and for
//! `corotated` the shape vectors and warm-start rotations of shape matching.

use super::mls::pack_first_pass;
use crate::math::Vec4;
use crate::neighbours::Neighbours;
use glam::{Mat3, Vec3};

/// Linear stress `sigma = lambda tr(eps) I + 2 mu eps` of `eps = sym(H)`, where `H` is the
/// (rotated back) displacement gradient. Taking H rather than `F = I + H` avoids the
/// cancellation in `sym(F) - I`, whose rounding would depend on whether the compiler fuses
/// multiply-adds (it made the GPU and CPU results drift apart).
#[inline(always)]
pub fn linear_stress(h: &Mat3, lambda: f32, mu: f32) -> Mat3 {
    let tr = h.x_axis.x + h.y_axis.y + h.z_axis.z;
    let eps = (*h + h.transpose()) * 0.5;
    eps * (2.0 * mu) + Mat3::from_diagonal(Vec3::splat(lambda * tr))
}

/// First pass of node i (see [`super::mls`]): `P_i = sigma_i`, or `R_i sigma(R_i^T F_i)`
/// when `rotation` is given. `hourglass` is alpha times mu in Pa.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn first_pass(
    i: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    inverse_moment: &[f32; 9],
    volume: f32,
    lambda: f32,
    mu: f32,
    hourglass: f32,
    rotation: Option<&Mat3>,
) -> [f32; 12] {
    let (j, trace) = super::mls::displacement_gradient(i, positions, rest, nb, inverse_moment);
    let p = match rotation {
        None => linear_stress(&j, lambda, mu),
        Some(r) => {
            // R^T F - I, the diagonal subtraction exact (Sterbenz) for entries in [0.5, 2].
            let f = super::point_based::deformation_gradient(&j);
            let h = r.transpose() * f - Mat3::IDENTITY;
            *r * linear_stress(&h, lambda, mu)
        }
    };
    pack_first_pass(&p, &j, trace, inverse_moment, volume, hourglass)
}
