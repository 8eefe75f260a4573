//! Compressible neo-Hookean meshfree solid (`model = "neo_hookean"`): the large-strain
//! material a liver needs at 20% strain and beyond, where the other continuum models are
//! off: Debunne's stress is linear in the strain (co-rotated or not), and point based
//! animation's St Venant-Kirchhoff energy softens in compression (its uniaxial nominal
//! stress `E (s^3 - s) / 2` at nu = 0 peaks at 42% compression and falls beyond, so a
//! strongly compressed neighbourhood can collapse).
//!
//! Strain energy per unit reference volume (Bonet and Wood, *Nonlinear Continuum
//! Mechanics for Finite Element Analysis*, 2nd ed., 2008, section 6.4.3):
//!
//! `W(F) = mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2`,  `I1 = tr(F^T F)`, `J = det F`,
//!
//! with the Lame constants of Young's modulus and the Poisson ratio, so that at small
//! strain it is Hooke's law with those E and nu. Its first Piola-Kirchhoff stress is
//!
//! `P = mu (F - F^-T) + lambda ln J F^-T = mu F + (lambda ln J - mu) cof(F) / J`.
//!
//! `F = I + J_i` is the moving-least-squares gradient of [`super::mls`], the energy
//! `U = sum_i V_i W(F_i)` is integrated at the nodes with the node volumes `V_i`, and its
//! exact gradient is gathered as for the other continuum models, with the same hourglass
//! control (alpha, default 16). Rigid motions give zero force (W depends on `F^T F` and
//! J only); the rest state gives exactly zero (`F = I` bitwise).
//!
//! Collapsed neighbourhoods: `ln J` has no value for `J <= 0`, which a node's neighbours
//! can reach when a needle pushes one through another. Below `J_MIN` the logarithm is
//! continued by its tangent, `l(J) = ln J_MIN + (J - J_MIN) / J_MIN`, so the energy and
//! its force stay finite and keep pushing the volume back for any F.
//!
//! Why `J_MIN = 0.62`: the law stiffens in compression, and the explicit step does not
//! follow it. Its volume terms stiffen without bound as `J` falls: under uniaxial strain
//! `F = diag(s, 1, 1)` (`J = s`) the tangent `dP_11 / ds` is
//! `mu (1 + 1/s^2) + lambda (1 - ln s) / s^2`, `lambda + 2 mu` at rest; its ratio to the
//! rest value is largest for `lambda >> mu`, `(1 - ln s) / s^2`, 3.85 at `s = 0.62`, and
//! below `J_MIN` the continued law's is at most `1 / J_MIN^2` = 2.6. `dt = "auto"` takes
//! half the critical step of the rest state ([`crate::scene::AUTO_DT_SAFETY`]), which stays
//! stable while the stiffest mode's stiffness grows up to 4 times: the volume terms now
//! stay within that (module test `compression_stiffens_at_most_fourfold`). What the
//! continuation does not bound is the stiffening with the change of shape, which every
//! hyperelastic law has at large strain: squashed along one axis at constant volume,
//! `F = diag(s, s^-1/2, s^-1/2)`, the tangent is `mu + (lambda + mu) / s^2`, 3.7 times the
//! rest value at `s = 0.5` (nu = 0.45), 5.8 at 0.4, 10 at 0.3 (same test); a needle that
//! squashes a neighbourhood that far can still need a smaller step than `"auto"`'s. With
//! the earlier 0.05 the volume terms alone could reach about 1,600 times:
//! `scenes/layered_liver_biopsy.toml` with this model (its viscosities removed) diverged
//! under `dt = "auto"` where the needle crushed a node's neighbourhood at the fascia's
//! puncture (4.13 s), and still at 0.48 and 0.7 of that step (dev machine, CPU,
//! 2026-11-28); with 0.62 it runs to the end. The law is exact for `J >= 0.62`, a 38% loss
//! of volume: more than uniaxial compression by half takes from a solid of `nu >= 0.2`
//! (`J` = 0.65 at `nu` = 0.2, 0.73 at 0.3, 0.9 at 0.45); for `nu` below about 0.15 the
//! continuation starts within moderate compression (at `nu` = 0, `J = s`: 38%).
//!
//! Shape information: that of the continuum models ([`ContinuumShape`]).

use super::continuum::{ContinuumLaw, ContinuumShape};
use super::mls::StressSplit;
use super::mls::{
    default_hourglass, pack_first_pass, validate_continuum, ContinuumConstants, FirstPassRow,
    MomentRow, NodeVolumes,
};
use super::traits::{BuildContext, ModelInfo, TissueModel};
use super::viscoelastic::{visco_bytes, Prony};
use crate::calibration::UncalibratedNeighbours;
use crate::error::SceneError;
use crate::math::Vec4;
use crate::neighbours::Neighbours;
use glam::Mat3;

/// Below this volume ratio the logarithm of the energy is continued linearly (module
/// docs: the volume terms' stiffness stays within 4 times the rest state's).
pub const J_MIN: f32 = 0.62;

/// Parameters of the neo-Hookean model.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct NeoHookeanParams {
    /// Young's modulus E in Pa (the small-strain modulus).
    pub young_modulus: f64,
    /// Poisson ratio nu, in (-1, 0.5) (the small-strain ratio).
    pub poisson_ratio: f64,
    /// Hourglass control alpha, as for the other continuum models (default 16).
    #[serde(default = "default_hourglass")]
    pub hourglass: f64,
    /// The volume `V_i` that weights each node's strain energy (see [`NodeVolumes`]).
    #[serde(default)]
    pub node_volumes: NodeVolumes,
    /// Viscoelastic Prony terms `[{ g, tau }, ...]` relaxing the second Piola-Kirchhoff
    /// stress ([`crate::models::viscoelastic`]); empty (the default): elastic. The young
    /// modulus is then the instantaneous one.
    #[serde(default, skip_serializing_if = "Prony::is_empty")]
    pub viscoelastic: Prony,
    /// Shear viscosity eta of a Kelvin-Voigt dashpot beside the elastic law, Pa s
    /// ([`super::continuum`]: the Green strain rate's deviator, so a rigid spin is not
    /// damped); 0 (the default): none. Each `[[region]]` may give its own.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub viscosity: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl NeoHookeanParams {
    /// `model = "neo_hookean"` with Young's modulus in Pa and the Poisson ratio, the other
    /// keys at their defaults (hourglass 16, cell volumes).
    pub const fn new(young_modulus: f64, poisson_ratio: f64) -> NeoHookeanParams {
        NeoHookeanParams {
            young_modulus,
            poisson_ratio,
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

    /// The constants the kernels use (`volume_stiffness` 0).
    pub fn constants(&self) -> ContinuumConstants {
        ContinuumConstants::new(self.young_modulus, self.poisson_ratio, 0.0, self.hourglass)
    }
}

/// `(l(J), l'(J))`: `ln J` and `1 / J`, continued by the tangent below [`J_MIN`].
#[inline(always)]
pub fn log_volume(j: f32) -> (f32, f32) {
    if j >= J_MIN {
        (j.ln(), 1.0 / j)
    } else {
        (J_MIN.ln() + (j - J_MIN) / J_MIN, 1.0 / J_MIN)
    }
}

/// First Piola-Kirchhoff stress `P = mu F + (lambda l(J) - mu) l'(J) cof(F)` of the
/// deformation gradient `f`.
#[inline]
pub fn stress(f: &Mat3, lambda: f32, mu: f32) -> Mat3 {
    // Rows of the cofactor matrix: the cross products of the rows of F.
    let (r0, r1, r2) = (f.row(0), f.row(1), f.row(2));
    let cof = Mat3::from_cols(r1.cross(r2), r2.cross(r0), r0.cross(r1)).transpose();
    let (l, dl) = log_volume(r0.dot(r1.cross(r2)));
    *f * mu + cof * ((lambda * l - mu) * dl)
}

/// Strain energy density `W(F)` in Pa (with the same continuation as [`stress`]).
pub fn energy_density(f: &Mat3, lambda: f32, mu: f32) -> f32 {
    let i1 = f.x_axis.length_squared() + f.y_axis.length_squared() + f.z_axis.length_squared();
    let (l, _) = log_volume(f.determinant());
    0.5 * mu * (i1 - 3.0) - mu * l + 0.5 * lambda * l * l
}

/// First pass of node i: the stress of `F_i = I + J_i`, packed by [`pack_first_pass`].
#[inline]
pub fn first_pass(
    i: usize,
    positions: &[Vec4],
    rest: &[Vec4],
    nb: &Neighbours,
    inverse_moment: &MomentRow,
    volume: f32,
    c: &ContinuumConstants,
) -> FirstPassRow {
    let g = super::mls::displacement_gradient(i, positions, rest, nb, inverse_moment);
    let j = g.j;
    let p = stress(&(j + Mat3::IDENTITY), c.lambda, c.mu);
    pack_first_pass(&p, &g, inverse_moment, volume, c.hourglass)
}

impl TissueModel for NeoHookeanParams {
    type Shape = Shape;

    const INFO: ModelInfo = ModelInfo {
        tag: "neo_hookean",
        short_name: "nh",
        label: "neo-Hookean",
        structural_keys: &["node_volumes", "viscoelastic"],
    };

    fn validate(&self, key: &str) -> Result<(), SceneError> {
        validate_continuum(key, self.young_modulus, self.poisson_ratio, self.hourglass)?;
        self.viscoelastic.validate(key)?;
        crate::validate::non_negative_finite(&format!("{key}.viscosity"), self.viscosity)
    }

    /// `[lambda, mu, eta, alpha mu]`.
    fn material_row(&self) -> Vec4 {
        let c = self.constants();
        [c.lambda, c.mu, self.viscosity as f32, c.hourglass]
    }

    /// Rest position, inverse moment and first pass.
    fn shape_bytes_per_node(&self, _k: f64) -> f64 {
        super::mls::CONTINUUM_BYTES_PER_NODE + visco_bytes(&self.viscoelastic)
    }

    fn prony(&self) -> Prony {
        self.viscoelastic
    }

    fn elastic_moduli(&self, _: f64, _: usize) -> Result<(f64, f64), UncalibratedNeighbours> {
        Ok((self.young_modulus, self.poisson_ratio))
    }

    fn build(&self, rest: &[Vec4], nb: &Neighbours, n: usize, ctx: BuildContext) -> Shape {
        ContinuumShape::build(*self, self.node_volumes, rest, nb, n, ctx)
    }
}

/// The neo-Hookean model's shape information: the continuum arrays ([`ContinuumShape`]).
pub type Shape = ContinuumShape<NeoHookeanParams>;

impl ContinuumLaw for NeoHookeanParams {
    fn law_constants(&self) -> ContinuumConstants {
        self.constants()
    }

    fn law_viscosity(&self) -> f32 {
        self.viscosity as f32
    }

    /// The z lane of `[lambda, mu, eta, alpha mu]`.
    fn row_viscosity(row: Vec4) -> f32 {
        row[2]
    }

    /// `[lambda, mu, eta, alpha mu]`: no volume stiffness.
    fn row_constants(&self, row: Vec4) -> ContinuumConstants {
        ContinuumConstants {
            volume_stiffness: 0.0,
            ..ContinuumConstants::from_row(row)
        }
    }

    fn law_first_pass(
        i: usize,
        positions: &[Vec4],
        rest: &[Vec4],
        nb: &Neighbours,
        inverse_moment: &MomentRow,
        volume: f32,
        c: &ContinuumConstants,
    ) -> FirstPassRow {
        first_pass(i, positions, rest, nb, inverse_moment, volume, c)
    }

    /// `S = F^-1 P` of [`stress`], pushed by `F`.
    fn law_split(
        i: usize,
        positions: &[Vec4],
        rest: &[Vec4],
        nb: &Neighbours,
        inverse_moment: &MomentRow,
        c: &ContinuumConstants,
    ) -> StressSplit {
        let g = super::mls::displacement_gradient(i, positions, rest, nb, inverse_moment);
        let j = g.j;
        let f = j + Mat3::IDENTITY;
        StressSplit {
            s0: f.inverse() * stress(&f, c.lambda, c.mu),
            push: f,
            extra: Mat3::ZERO,
            gradient: g,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// The stress is the derivative of the energy density: central differences of W
    /// against P for random gradients, stretched, compressed and past `J_MIN`, within
    /// f32 round-off (1e-2 relative to the largest entry; the differences of W lose about
    /// 4 digits).
    #[test]
    fn stress_is_the_gradient_of_the_energy() {
        let mut rnd = crate::math::test_rng(0x5eed_1234);
        let (lambda, mu) = (9.0f32, 1.0f32);
        for scale in [0.1f32, 0.4, 1.2] {
            for _ in 0..20 {
                let h = Mat3::from_cols_array(&std::array::from_fn(|_| scale * (rnd() - 0.5)));
                let f = Mat3::IDENTITY + h;
                let p = stress(&f, lambda, mu);
                let big = p.to_cols_array().iter().fold(0.0f32, |a, v| a.max(v.abs()));
                let e = 1e-3f32;
                for k in 0..9 {
                    let mut a = f.to_cols_array();
                    let mut b = a;
                    a[k] += e;
                    b[k] -= e;
                    let (fa, fb) = (Mat3::from_cols_array(&a), Mat3::from_cols_array(&b));
                    let d = (energy_density(&fa, lambda, mu) - energy_density(&fb, lambda, mu))
                        / (2.0 * e);
                    let pk = p.to_cols_array()[k];
                    assert!(
                        (d - pk).abs() <= 1e-2 * big.max(1.0),
                        "scale {scale}, entry {k}: dW/dF {d} vs P {pk}"
                    );
                }
            }
        }
    }

    /// Small strain: the stress is Hooke's law `lambda tr(eps) I + 2 mu eps` to first
    /// order (relative 1e-2 at a strain of 1e-3: the quadratic terms are 1e-3 of it);
    /// rest and rigid rotations give zero stress.
    #[test]
    fn small_strain_is_hookes_law_and_rigid_motion_is_free() {
        let (lambda, mu) = (9.0f32, 1.0f32);
        assert_eq!(stress(&Mat3::IDENTITY, lambda, mu), Mat3::ZERO);
        let eps = Mat3::from_cols(
            Vec3::new(1.0, 0.3, -0.2),
            Vec3::new(0.3, -0.5, 0.1),
            Vec3::new(-0.2, 0.1, 0.4),
        ) * 1e-3;
        let p = stress(&(Mat3::IDENTITY + eps), lambda, mu);
        let tr = eps.x_axis.x + eps.y_axis.y + eps.z_axis.z;
        let hooke = eps * (2.0 * mu) + Mat3::from_diagonal(Vec3::splat(lambda * tr));
        let d = (p - hooke).to_cols_array();
        let big = hooke
            .to_cols_array()
            .iter()
            .fold(0.0f32, |a, v| a.max(v.abs()));
        assert!(d.iter().all(|v| v.abs() <= 1e-2 * big), "{p} vs {hooke}");
        let r = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        let pr = stress(&r, lambda, mu);
        assert!(pr.to_cols_array().iter().all(|v| v.abs() < 1e-5), "{pr}");
    }

    /// Under uniaxial strain `F = diag(s, 1, 1)` the tangent `dP_11 / ds` (central
    /// differences of [`stress`], step 1e-3) stays within 4 times its rest value
    /// `lambda + 2 mu` for every s from -0.5 (inverted) to 3 and every Poisson ratio from
    /// -0.5 to 0.499 (module docs: what `dt = "auto"` allows); and the bound is not
    /// needlessly low: for nu = 0.499 the largest ratio, just above `J_MIN`, is above 3.5
    /// (the continuation starts where the law really stiffens). The stiffening with shape
    /// at constant volume, which the continuation leaves, is recorded too.
    #[test]
    fn compression_stiffens_at_most_fourfold() {
        for nu in [-0.5f64, 0.0, 0.2, 0.3, 0.45, 0.49, 0.499] {
            let (lambda, mu) = crate::scene::lame(1.0, nu);
            let (lambda, mu) = (lambda as f32, mu as f32);
            let rest = lambda + 2.0 * mu;
            let p11 = |s: f32| {
                stress(&Mat3::from_diagonal(Vec3::new(s, 1.0, 1.0)), lambda, mu)
                    .x_axis
                    .x
            };
            let mut largest = 0.0f32;
            for k in 0..=3500 {
                let s = -0.5 + 1e-3 * k as f32;
                let e = 1e-3f32;
                let tangent = (p11(s + e) - p11(s - e)) / (2.0 * e);
                largest = largest.max(tangent / rest);
            }
            assert!(
                largest <= 4.0,
                "nu {nu}: tangent {largest} x the rest value"
            );
            if nu == 0.499 {
                assert!(largest > 3.5, "nu {nu}: largest ratio only {largest}");
            }
        }
        // Squashed at constant volume, F = diag(s, t, t) with t = s^-1/2, the law is not
        // continued (J = 1) and stiffens with the shape as the exact law does:
        // dP_11 / dF_11 = mu + (lambda + mu) / s^2 (within 1%), 3.7 times the rest value
        // at s = 0.5 and 10 times at 0.3 for nu = 0.45 (module docs).
        let (lambda, mu) = crate::scene::lame(1.0, 0.45);
        let (lambda, mu) = (lambda as f32, mu as f32);
        for (s, ratio) in [(0.5f32, 3.73f32), (0.4, 5.77), (0.3, 10.2)] {
            let t = 1.0 / s.sqrt();
            let diag = |a: f32| Mat3::from_diagonal(Vec3::new(a, t, t));
            let p11 = |a: f32| stress(&diag(a), lambda, mu).x_axis.x;
            let e = 1e-3f32;
            let tangent = (p11(s + e) - p11(s - e)) / (2.0 * e);
            let exact = mu + (lambda + mu) / (s * s);
            assert!(
                (tangent / exact - 1.0).abs() < 1e-2,
                "s {s}: {tangent} vs {exact}"
            );
            let r = tangent / (lambda + 2.0 * mu);
            assert!(
                (r / ratio - 1.0).abs() < 1e-2,
                "s {s}: {r} x the rest value"
            );
        }
    }

    /// An inverted gradient (J < 0) gives a finite stress that pushes the volume back:
    /// along the direction that increases J the energy falls.
    #[test]
    fn an_inverted_neighbourhood_is_pushed_back() {
        let f = Mat3::from_diagonal(Vec3::new(-0.2, 1.0, 1.0));
        let p = stress(&f, 9.0, 1.0);
        assert!(p.to_cols_array().iter().all(|v| v.is_finite()));
        // dW/dF11 < 0 at F11 = -0.2: increasing F11 (towards J > 0) lowers W.
        assert!(p.x_axis.x < 0.0, "{p}");
    }
}
