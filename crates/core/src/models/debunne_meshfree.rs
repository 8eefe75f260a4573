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
//! # Tissue viscosity (Kelvin-Voigt)
//!
//! `viscosity = eta` (Pa s, default 0) puts a dashpot beside the elastic law: node i's
//! stress gains the deviatoric viscous stress of its strain rate,
//!
//! `sigma_v,i = 2 eta_i dev(sym(L_i))`,  `L_i = sum_j w_ij (v_j - v_i) (x0_j - x0_i)^T A_i^-1`,
//!
//! the velocity gradient from the same point-set operator as `J_i` (exact for linear
//! velocity fields); co-rotated, of `R_i^T L_i`, pushed by `R_i` like the elastic stress,
//! so a rigid spin is not damped. It enters the first pass beside `P_i`, so the gather and
//! its momentum balance are unchanged, and it dissipates `2 eta |dev sym L|^2` per unit
//! volume exactly for a linear velocity field (`tests/viscosity.rs`). Shear only: the bulk
//! viscosity of tissue is small, and a bulk dashpot would damp the stiff compression modes
//! that set the explicit step (`dt = "auto"` accounts for what it adds,
//! [`crate::stability`]). With several regions each has its own `eta` (the w lane of the
//! node's material row).
//!
//! Why: the elastic tissue has only mass-proportional damping (`physics.damping`), a
//! loss that falls as `1 / omega`, so a released load (a membrane that gives under the
//! needle) rings at the tissue's own 100-500 Hz for a tenth of a second. Real tissue is
//! lossy there: multifrequency MR elastography of human liver (Asbach et al., Magn. Reson.
//! Med. 60:373-379, 2008) fits a spring of 1.16 kPa beside a spring of 1.97 kPa in series
//! with a 7.3 Pa s dashpot, a loss tangent `G'' / G'` of 0.42 at 50 Hz and 0.25 at
//! 100 Hz. A Kelvin-Voigt dashpot has the loss tangent `omega eta / mu`; the shipped
//! needle scenes give each region `eta = 0.5 ms x mu` (0.16 at 50 Hz, 0.31 at 100 Hz, so
//! within the measured band at the frequencies that ring). Unlike a Prony term
//! ([`crate::models::viscoelastic`]) it leaves the quasi-static modulus unchanged: at the
//! needle's strain rates (about 1/s) its stress is a thousandth of the elastic one.
//!
//! Shape information: rest positions with the node volume in w, inverse moment matrices (9
//! floats per node), and for
//! `corotated` the shape vectors and warm-start rotations of shape matching.

use super::local_shape_matching::{cluster_frame, rest_positions, shape_vector, shape_vectors};
use super::mls::{
    default_hourglass, pack_first_pass, unpack, ContinuumArrays, ContinuumConstants, FirstPassRow,
    MomentRow, NodeVolumes, StressSplit,
};
use super::mueller2016_rotation::default_iterations;
use super::viscoelastic::{visco_bytes, Prony};
use super::{
    row, BuildContext, ForceInput, ModelInfo, ModelState, ShapeArray, ShapeRow, TissueModel,
};
use crate::calibration::UncalibratedNeighbours;
use crate::error::SceneError;
use crate::math::{xyz, Vec4, QUAT_IDENTITY};
use crate::neighbours::Neighbours;
use glam::{Mat3, Quat, Vec3};

/// Parameters of the Debunne meshfree model.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DebunneParams {
    /// Young's modulus E in Pa.
    pub young_modulus: f64,
    /// Poisson ratio nu, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Co-rotate the linear model with each node's shape matching rotation R_i:
    /// `f_i = R_i sum_j K_ij (R_i^T (x_j - x_i) - (x0_j - x0_i))`. Off by default (the
    /// paper's plain linear model, which does not survive large rotations).
    #[serde(default)]
    pub corotated: bool,
    /// Quaternion iterations per step of the rotation extraction when `corotated`.
    #[serde(default = "crate::models::mueller2016_rotation::default_iterations")]
    pub rotation_iterations: u32,
    /// Hourglass control alpha (dimensionless, default 16): stiffness of the part of a
    /// neighbourhood's motion that a quadratic field does not explain, in units of
    /// `mu V_i / sum_j w_ij |x_ij|^2` ([`super::mls`]).
    #[serde(default = "crate::models::mls::default_hourglass")]
    pub hourglass: f64,
    /// The volume `V_i` that weights each node's strain energy: `cell` (default),
    /// `density` or `uniform` (see [`NodeVolumes`]).
    #[serde(default)]
    pub node_volumes: NodeVolumes,
    /// Viscoelastic Prony terms `[{ g, tau }, ...]` relaxing the (co-rotated) linear
    /// stress ([`crate::models::viscoelastic`]); empty (the default): elastic. The young
    /// modulus is then the instantaneous one.
    #[serde(default, skip_serializing_if = "Prony::is_empty")]
    pub viscoelastic: Prony,
    /// Shear viscosity eta of a Kelvin-Voigt dashpot beside the elastic law, Pa s
    /// (module docs); 0 (the default): none.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub viscosity: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl DebunneParams {
    /// `model = "debunne_meshfree"` with Young's modulus in Pa and the Poisson ratio, the
    /// other keys at their defaults (not co-rotated, hourglass 16, cell volumes).
    pub const fn new(young_modulus: f64, poisson_ratio: f64) -> DebunneParams {
        DebunneParams {
            young_modulus,
            poisson_ratio,
            corotated: false,
            rotation_iterations: default_iterations(),
            hourglass: default_hourglass(),
            node_volumes: NodeVolumes::Cell,
            viscoelastic: Prony::elastic(),
            viscosity: 0.0,
        }
    }

    /// `viscosity`: the Kelvin-Voigt shear viscosity in Pa s.
    pub const fn with_viscosity(mut self, viscosity: f64) -> Self {
        self.viscosity = viscosity;
        self
    }

    /// `viscoelastic`: the Prony series.
    pub const fn with_viscoelastic(mut self, viscoelastic: Prony) -> Self {
        self.viscoelastic = viscoelastic;
        self
    }

    /// `corotated`: co-rotate the linear model.
    pub const fn with_corotated(mut self, corotated: bool) -> Self {
        self.corotated = corotated;
        self
    }

    /// `rotation_iterations`.
    pub const fn with_rotation_iterations(mut self, iterations: u32) -> Self {
        self.rotation_iterations = iterations;
        self
    }

    /// `hourglass`: the hourglass control alpha.
    pub const fn with_hourglass(mut self, hourglass: f64) -> Self {
        self.hourglass = hourglass;
        self
    }

    /// `node_volumes`.
    pub const fn with_node_volumes(mut self, node_volumes: NodeVolumes) -> Self {
        self.node_volumes = node_volumes;
        self
    }
}

impl TissueModel for DebunneParams {
    type Shape = Shape;

    const INFO: ModelInfo = ModelInfo {
        tag: "debunne_meshfree",
        short_name: "deb",
        label: "Debunne meshfree",
        structural_keys: &[
            "corotated",
            "rotation_iterations",
            "node_volumes",
            "viscoelastic",
        ],
    };

    fn validate(&self, key: &str) -> Result<(), SceneError> {
        crate::validate::elastic_moduli(key, self.young_modulus, self.poisson_ratio)?;
        self.viscoelastic.validate(key)?;
        crate::validate::rotation_iterations_in_range(key, self.rotation_iterations)?;
        crate::validate::non_negative_finite(&format!("{key}.hourglass"), self.hourglass)?;
        crate::validate::non_negative_finite(&format!("{key}.viscosity"), self.viscosity)
    }

    /// `[lambda, mu, alpha mu, eta]`.
    fn material_row(&self) -> Vec4 {
        let c = self.constants();
        [c.lambda, c.mu, c.hourglass, self.viscosity as f32]
    }

    /// Rest position, inverse moment and first pass (and the frame when co-rotated).
    fn shape_bytes_per_node(&self, _k: f64) -> f64 {
        super::mls::CONTINUUM_BYTES_PER_NODE
            + if self.corotated { 32.0 } else { 0.0 }
            + visco_bytes(&self.viscoelastic)
    }

    fn prony(&self) -> Prony {
        self.viscoelastic
    }

    fn elastic_moduli(&self, _: f64, _: usize) -> Result<(f64, f64), UncalibratedNeighbours> {
        Ok((self.young_modulus, self.poisson_ratio))
    }

    fn build(&self, rest: &[Vec4], nb: &Neighbours, n: usize, ctx: BuildContext) -> Shape {
        let corotation = self.corotated.then(|| Corotation {
            shape_vector: shape_vectors(&rest_positions(rest), nb, n),
            rotation: vec![QUAT_IDENTITY; rest.len()],
        });
        let mut continuum = ContinuumArrays::build(self.node_volumes, rest, nb, n, ctx);
        super::consistency::correct(&mut continuum, nb, n, ctx.triangles);
        Shape {
            params: *self,
            continuum: continuum.with_prony(self.viscoelastic),
            corotation,
            viscous: self.viscosity > 0.0,
        }
    }
}

impl DebunneParams {
    /// The constants the kernels use.
    pub fn constants(&self) -> ContinuumConstants {
        ContinuumConstants::new(self.young_modulus, self.poisson_ratio, 0.0, self.hourglass)
    }
}

/// The shape matching frame used to co-rotate the Debunne model.
#[derive(Debug, Clone, PartialEq)]
pub struct Corotation {
    /// Shape vectors v = x0 - C0 (w = 0).
    pub shape_vector: Vec<Vec4>,
    /// Rotation quaternions `[x, y, z, w]` from the last step.
    pub rotation: Vec<Vec4>,
}

/// The Debunne model's shape information.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    /// The parameters.
    pub params: DebunneParams,
    /// Rest positions and volumes, inverse moments, first pass.
    pub continuum: ContinuumArrays,
    /// Shape vectors and warm-start rotations (`corotated = true` only).
    pub corotation: Option<Corotation>,
    /// Some node has a viscosity (module docs): the first pass adds the viscous stress.
    /// Set from the material, and by [`crate::models::ShapeInfo::build`] when a region's
    /// material has one.
    pub viscous: bool,
}

impl ModelState for Shape {
    fn arrays(&self) -> Vec<(ShapeArray, &[u8])> {
        let mut v = self.continuum.arrays();
        if let Some(c) = &self.corotation {
            v.push((
                ShapeArray::ShapeVector,
                bytemuck::cast_slice(&c.shape_vector[..]),
            ));
            v.push((ShapeArray::Rotation, bytemuck::cast_slice(&c.rotation[..])));
        }
        v
    }

    fn arrays_mut(&mut self) -> Vec<(ShapeArray, &mut [u8])> {
        let mut v = self.continuum.arrays_mut();
        if let Some(c) = &mut self.corotation {
            v.push((
                ShapeArray::ShapeVector,
                bytemuck::cast_slice_mut(&mut c.shape_vector[..]),
            ));
            v.push((
                ShapeArray::Rotation,
                bytemuck::cast_slice_mut(&mut c.rotation[..]),
            ));
        }
        v
    }

    fn node_rows(
        &self,
        i: usize,
        rest: &[Vec4],
        nb: &Neighbours,
        volume_scale: f64,
        rest_position: bool,
    ) -> Vec<ShapeRow> {
        let mut out = self
            .continuum
            .node_rows(i, rest, nb, volume_scale, rest_position);
        if self.corotation.is_some() {
            out.push(row(
                ShapeArray::ShapeVector,
                i,
                &[shape_vector(i, rest, nb)],
            ));
        }
        out
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
            threads,
            node_material: material,
            ..
        } = *input;
        let c = self.params.constants();
        let one = [c.lambda, c.mu, c.hourglass, 0.0];
        // `[lambda, mu, alpha mu]` of node i.
        let constants = |i: usize| material.map_or(one, |m| m[i]);
        let viscous = self.viscous.then_some(Viscous {
            velocities: input.velocities,
            eta: self.params.viscosity as f32,
            node_material: material,
        });
        if !self.continuum.visco.is_empty() {
            self.visco_first_pass(input, &constants, viscous.as_ref());
            self.continuum.gather_forces(input, forces);
            return;
        }
        let ContinuumArrays {
            rest_position,
            inverse_moment,
            first_pass: first,
            ..
        } = &mut self.continuum;
        let (rest, a_inv) = (&rest_position[..], &inverse_moment[..]);
        // A local evaluation's gather reads the first pass of its nodes' neighbours.
        let ring = threads.one_ring(nb, n);
        // A local evaluation uses the rotations it refines but keeps the warm starts
        // (`Corotation::rotation`) as they were, as the GPU backend's does.
        let keep_warm_starts = threads.subset.is_some();
        let threads = threads.with_subset(ring.as_deref());
        match &mut self.corotation {
            None => threads.map_nodes(&mut first[..n], |i| {
                let [lambda, mu, hg, _] = constants(i);
                let mut q = first_pass(
                    i, pos, rest, nb, &a_inv[i], rest[i][3], lambda, mu, hg, None,
                );
                if let Some(v) = &viscous {
                    v.add(&mut q, i, rest, nb, &a_inv[i], None);
                }
                q
            }),
            Some(Corotation {
                shape_vector,
                rotation,
            }) => {
                let (sv, iters) = (&shape_vector[..], self.params.rotation_iterations);
                threads.for_each_node(&mut first[..n], &mut rotation[..n], |i, q, rot| {
                    let (_, r) =
                        cluster_frame(i, pos, rest, sv[i], nb, iters, Quat::from_array(*rot));
                    if !keep_warm_starts {
                        *rot = r.to_array();
                    }
                    let [lambda, mu, hg, _] = constants(i);
                    let r = Mat3::from_quat(r);
                    *q = first_pass(
                        i,
                        pos,
                        rest,
                        nb,
                        &a_inv[i],
                        rest[i][3],
                        lambda,
                        mu,
                        hg,
                        Some(&r),
                    );
                    if let Some(v) = &viscous {
                        v.add(q, i, rest, nb, &a_inv[i], Some(&r));
                    }
                });
            }
        }
        self.continuum.gather_forces(input, forces);
    }

    fn end_step(&mut self) {
        self.continuum.end_step();
    }
}

impl Shape {
    /// The first pass of a viscoelastic material ([`crate::models::viscoelastic`]): the
    /// linear stress of `J` (co-rotated: of `R^T F - I`, pushed by `R`) relaxes.
    fn visco_first_pass(
        &mut self,
        input: &ForceInput,
        constants: &(dyn Fn(usize) -> Vec4 + Sync),
        viscous: Option<&Viscous>,
    ) {
        let ForceInput {
            positions: pos,
            nb,
            n,
            threads,
            dt,
            ..
        } = *input;
        let ContinuumArrays {
            rest_position,
            inverse_moment,
            first_pass: first,
            prony,
            visco,
            visco_next,
            ..
        } = &mut self.continuum;
        let (rest, a_inv, prev) = (&rest_position[..], &inverse_moment[..], &visco[..]);
        let ring = threads.one_ring(nb, n);
        let keep_warm_starts = threads.subset.is_some();
        let threads = threads.with_subset(ring.as_deref());
        let coefficients = prony.coefficients(dt as f64);
        let split = |i: usize, r: Option<&Mat3>, lambda: f32, mu: f32| {
            let g = super::mls::displacement_gradient(i, pos, rest, nb, &a_inv[i]);
            let j = g.j;
            let (s0, push) = match r {
                None => (linear_stress(&j, lambda, mu), Mat3::IDENTITY),
                Some(r) => {
                    let f = super::point_based::deformation_gradient(&j);
                    (
                        linear_stress(&(r.transpose() * f - Mat3::IDENTITY), lambda, mu),
                        *r,
                    )
                }
            };
            StressSplit {
                s0,
                push,
                extra: Mat3::ZERO,
                gradient: g,
            }
        };
        match &mut self.corotation {
            None => threads.for_each_node(&mut first[..n], &mut visco_next[..n], |i, out, next| {
                let [lambda, mu, hg, _] = constants(i);
                *out = ContinuumArrays::visco_first_pass(
                    &split(i, None, lambda, mu),
                    &prev[i],
                    next,
                    &coefficients,
                    &a_inv[i],
                    rest[i][3],
                    hg,
                );
                if let Some(v) = viscous {
                    v.add(out, i, rest, nb, &a_inv[i], None);
                }
            }),
            Some(Corotation {
                shape_vector,
                rotation,
            }) => {
                let (sv, iters) = (&shape_vector[..], self.params.rotation_iterations);
                threads.for_each_node3(
                    &mut first[..n],
                    &mut rotation[..n],
                    &mut visco_next[..n],
                    |i, out, rot, next| {
                        let (_, r) =
                            cluster_frame(i, pos, rest, sv[i], nb, iters, Quat::from_array(*rot));
                        if !keep_warm_starts {
                            *rot = r.to_array();
                        }
                        let [lambda, mu, hg, _] = constants(i);
                        let r = Mat3::from_quat(r);
                        *out = ContinuumArrays::visco_first_pass(
                            &split(i, Some(&r), lambda, mu),
                            &prev[i],
                            next,
                            &coefficients,
                            &a_inv[i],
                            rest[i][3],
                            hg,
                        );
                        if let Some(v) = viscous {
                            v.add(out, i, rest, nb, &a_inv[i], Some(&r));
                        }
                    },
                );
            }
        }
    }
}

/// What the first pass needs for the viscous stress (module docs).
struct Viscous<'a> {
    velocities: &'a [Vec4],
    /// The material's eta, Pa s (without node materials).
    eta: f32,
    node_material: Option<&'a [Vec4]>,
}

impl Viscous<'_> {
    /// Adds node i's viscous stress ([`viscous_stress`]) to its packed first pass `q`.
    #[inline]
    fn add(
        &self,
        q: &mut FirstPassRow,
        i: usize,
        rest: &[Vec4],
        nb: &Neighbours,
        inverse_moment: &MomentRow,
        rotation: Option<&Mat3>,
    ) {
        let eta = self.node_material.map_or(self.eta, |m| m[i][3]);
        if eta > 0.0 {
            let l = velocity_gradient(i, self.velocities, rest, nb, inverse_moment);
            let s = viscous_stress(&l, eta, rotation);
            super::mls::add_first_pass_stress(q, &s, inverse_moment, rest[i][3]);
        }
    }
}

/// The point-set velocity gradient `L_i = sum_j w_ij (v_j - v_i) (x0_j - x0_i)^T A_i^-1`
/// (the operator of [`super::mls::displacement_gradient`] before its integration
/// correction, applied to the velocities).
#[inline]
pub fn velocity_gradient(
    i: usize,
    velocities: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    inverse_moment: &MomentRow,
) -> Mat3 {
    let (vi, x0i) = (xyz(velocities[i]), xyz(rest[i]));
    let mut b = Mat3::ZERO;
    for (_, j, w) in nb.live(i) {
        let dv = w * (xyz(velocities[j]) - vi);
        let d0 = xyz(rest[j]) - x0i;
        b += Mat3::from_cols(dv * d0.x, dv * d0.y, dv * d0.z);
    }
    b * unpack(inverse_moment)
}

/// The Kelvin-Voigt viscous stress `2 eta dev(sym(L))` of a velocity gradient `L`;
/// with a rotation `R`, `R 2 eta dev(sym(R^T L))` (module docs).
#[inline]
pub fn viscous_stress(l: &Mat3, eta: f32, rotation: Option<&Mat3>) -> Mat3 {
    let local = rotation.map_or(*l, |r| r.transpose() * *l);
    let d = (local + local.transpose()) * 0.5;
    let mean = (d.x_axis.x + d.y_axis.y + d.z_axis.z) / 3.0;
    let s = (d - Mat3::from_diagonal(Vec3::splat(mean))) * (2.0 * eta);
    rotation.map_or(s, |r| *r * s)
}

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
    inverse_moment: &MomentRow,
    volume: f32,
    lambda: f32,
    mu: f32,
    hourglass: f32,
    rotation: Option<&Mat3>,
) -> FirstPassRow {
    let g = super::mls::displacement_gradient(i, positions, rest, nb, inverse_moment);
    let j = g.j;
    let p = match rotation {
        None => linear_stress(&j, lambda, mu),
        Some(r) => {
            // R^T F - I, the diagonal subtraction exact (Sterbenz) for entries in [0.5, 2].
            let f = super::point_based::deformation_gradient(&j);
            let h = r.transpose() * f - Mat3::IDENTITY;
            *r * linear_stress(&h, lambda, mu)
        }
    };
    pack_first_pass(&p, &g, inverse_moment, volume, hourglass)
}
