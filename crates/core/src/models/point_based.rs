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
//! `viscosity = eta` adds the Kelvin-Voigt dashpot of the finite-strain laws, the
//! deviator of the Green strain rate (`P_v = F 2 eta dev(sym(F^T F_dot))`,
//! [`super::continuum`]), per region too. The node rows are `[lambda, mu, k_v, eta]`: the
//! hourglass alpha is the material's, one for every region (a structural key), and each
//! node's `alpha mu` follows from its own mu.
//!
//! Node volumes `V_i` (w lane of the rest positions) are the nodes' cells by default
//! ([`NodeVolumes`]). Mueller 2004 (section 4.2) takes them from the density
//! estimate `rho_i = sum_j m_j W_ij` (`node_volumes = "density"`): with equal masses
//! `V_i = m / rho_i` is proportional to `l_i^3 / (1 + sum_j w_ij)`, `l_i` the node's
//! farthest neighbour distance (the kernel's length scale), scaled so that the volumes add
//! up to the volume enclosed by the surface. Surface nodes have fewer neighbours and so
//! too large a volume: the report's cantilever is 38% too stiff at 1025 nodes with it, 4%
//! with cell volumes.
use super::continuum::{ContinuumLaw, ContinuumShape};
use super::mls::{
    default_hourglass, pack_first_pass, validate_continuum, ContinuumConstants, FirstPassRow,
    MomentRow, NodeVolumes, StressSplit,
};
use super::traits::{BuildContext, ModelInfo, TissueModel};
use super::viscoelastic::{visco_bytes, Prony};
use crate::calibration::UncalibratedNeighbours;
use crate::error::SceneError;
use crate::math::Vec4;
use crate::neighbours::Neighbours;
use glam::{Mat3, Vec3};

/// Parameters of point based animation.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PointBasedParams {
    /// Young's modulus E in Pa.
    pub young_modulus: f64,
    /// Poisson ratio nu, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Stiffness k_v in Pa of the volume-conserving energy `k_v/2 V (det F - 1)^2`
    /// (Mueller et al. 2004, section 4.3); 0 (the default) switches it off. The Green
    /// strain has no energy for an inverted neighbourhood, so large deformations need it
    /// (`scenes/cube_sag_pba.toml`).
    #[serde(default)]
    pub volume_stiffness: f64,
    /// Hourglass control alpha, as for the Debunne model (default 16): it removes the
    /// zig-zag modes without changing the patch test or bending. 0 is the original
    /// method, whose zig-zag modes cost no energy: a 343-node cube twisted 90 degrees and
    /// released then kept 2.2% of its twist (the report's extreme cases, K = 18; 0.01%
    /// with the first-order control at 0.1).
    #[serde(default = "crate::models::mls::default_hourglass")]
    pub hourglass: f64,
    /// The volume `V_i` that weights each node's strain energy: `cell` (default),
    /// `density` (the original method) or `uniform` (see [`NodeVolumes`]).
    #[serde(default)]
    pub node_volumes: NodeVolumes,
    /// Viscoelastic Prony terms `[{ g, tau }, ...]` relaxing the Green-strain stress
    /// ([`crate::models::viscoelastic`]); empty (the default): elastic. The young modulus
    /// is then the instantaneous one.
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

impl PointBasedParams {
    /// `model = "point_based"` with Young's modulus in Pa and the Poisson ratio, the other
    /// keys at their defaults (no volume term, hourglass 16, cell volumes).
    pub const fn new(young_modulus: f64, poisson_ratio: f64) -> PointBasedParams {
        PointBasedParams {
            young_modulus,
            poisson_ratio,
            volume_stiffness: 0.0,
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

    /// `volume_stiffness` in Pa.
    pub const fn with_volume_stiffness(mut self, volume_stiffness: f64) -> Self {
        self.volume_stiffness = volume_stiffness;
        self
    }

    /// The constants the kernels use.
    pub fn constants(&self) -> ContinuumConstants {
        ContinuumConstants::new(
            self.young_modulus,
            self.poisson_ratio,
            self.volume_stiffness,
            self.hourglass,
        )
    }
}

impl TissueModel for PointBasedParams {
    type Shape = Shape;

    const INFO: ModelInfo = ModelInfo {
        tag: "point_based",
        short_name: "pba",
        label: "point based animation",
        // `hourglass` too: the node rows hold the viscosity where the other continuum
        // models hold alpha mu, so alpha is one for the whole tissue.
        structural_keys: &["node_volumes", "viscoelastic", "hourglass"],
    };

    fn validate(&self, key: &str) -> Result<(), SceneError> {
        validate_continuum(key, self.young_modulus, self.poisson_ratio, self.hourglass)?;
        self.viscoelastic.validate(key)?;
        crate::validate::non_negative_finite(
            &format!("{key}.volume_stiffness"),
            self.volume_stiffness,
        )?;
        crate::validate::non_negative_finite(&format!("{key}.viscosity"), self.viscosity)
    }

    /// `[lambda, mu, k_v, eta]`: the hourglass alpha is the material's, one for every
    /// region (a structural key), and alpha mu follows from each node's mu
    /// ([`ContinuumLaw::row_constants`]).
    fn material_row(&self) -> Vec4 {
        let c = self.constants();
        [c.lambda, c.mu, c.volume_stiffness, self.viscosity as f32]
    }

    /// Rest position, inverse moment and first pass (and the viscoelastic state).
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

/// Point based animation's shape information: the continuum arrays ([`ContinuumShape`]).
pub type Shape = ContinuumShape<PointBasedParams>;

impl ContinuumLaw for PointBasedParams {
    fn law_constants(&self) -> ContinuumConstants {
        self.constants()
    }

    fn law_viscosity(&self) -> f32 {
        self.viscosity as f32
    }

    /// The w lane of `[lambda, mu, k_v, eta]`.
    fn row_viscosity(row: Vec4) -> f32 {
        row[3]
    }

    /// `[lambda, mu, k_v, eta]` with the material's alpha times the node's mu (in f32, as
    /// `point_based.wgsl::pba_mixed` computes it).
    fn row_constants(&self, row: Vec4) -> ContinuumConstants {
        ContinuumConstants {
            lambda: row[0],
            mu: row[1],
            volume_stiffness: row[2],
            hourglass: self.hourglass as f32 * row[1],
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

    /// `S` the Green-strain stress, pushed by `F`; the volume term stays elastic.
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
        let f = deformation_gradient(&j);
        StressSplit {
            s0: green_stress(&j, c.lambda, c.mu),
            push: f,
            extra: volume_term(&f, c.volume_stiffness),
            gradient: g,
        }
    }
}

/// Point based animation's volume term `k_v (det F - 1) cof F` (0 when `k_v` is 0).
#[inline]
fn volume_term(f: &Mat3, volume_stiffness: f32) -> Mat3 {
    if volume_stiffness <= 0.0 {
        return Mat3::ZERO;
    }
    let (r0, r1, r2) = (f.row(0), f.row(1), f.row(2));
    let cof = [r1.cross(r2), r2.cross(r0), r0.cross(r1)];
    let det = r0.dot(cof[0]);
    Mat3::from_cols(cof[0], cof[1], cof[2]).transpose() * (volume_stiffness * (det - 1.0))
}

/// `I + J`.
#[inline(always)]
pub fn deformation_gradient(j: &Mat3) -> Mat3 {
    *j + Mat3::IDENTITY
}

/// Second Piola-Kirchhoff stress `S = lambda tr(E) I + 2 mu E` of the Green strain of
/// `F = I + J`.
pub fn green_stress(j: &Mat3, lambda: f32, mu: f32) -> Mat3 {
    let f = deformation_gradient(j);
    let e = 0.5 * (f.transpose() * f - Mat3::IDENTITY);
    let tr = e.x_axis.x + e.y_axis.y + e.z_axis.z;
    e * (2.0 * mu) + Mat3::from_diagonal(Vec3::splat(lambda * tr))
}

/// First pass of node i: `P = F S + k_v (det F - 1) cof F`, packed by
/// [`pack_first_pass`].
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
    let f = deformation_gradient(&j);
    let mut p = f * green_stress(&j, c.lambda, c.mu);
    if c.volume_stiffness > 0.0 {
        // Rows of the cofactor matrix: the cross products of the rows of F.
        let (r0, r1, r2) = (f.row(0), f.row(1), f.row(2));
        let cof = [r1.cross(r2), r2.cross(r0), r0.cross(r1)];
        let det = r0.dot(cof[0]);
        let s = c.volume_stiffness * (det - 1.0);
        p += Mat3::from_cols(cof[0], cof[1], cof[2]).transpose() * s;
    }
    pack_first_pass(&p, &g, inverse_moment, volume, c.hourglass)
}
