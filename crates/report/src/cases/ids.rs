//! The models and cases the report runs, what a run gives back and how it is run.

use crate::constants::*;
use needlesim_core::calibration;
use needlesim_core::models::neo_hookean::NeoHookeanParams;
use needlesim_core::scene::{
    BackendChoice, DebunneParams, ShapeMatchingForces, ShapeMatchingParams,
};
use needlesim_core::Material;
use std::time::Duration;

/// The model variants the report compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelId {
    /// Weighted mass-spring, stiffness from [`calibration::mass_spring_stiffness`].
    Msm,
    /// Local shape matching with the paper's per-node forces.
    LshmNode,
    /// Local shape matching with per-cluster (energy gradient) forces.
    LshmCluster,
    /// Debunne meshfree FEM, linear strain.
    Deb,
    /// Debunne meshfree FEM, co-rotated.
    DebCorotated,
    /// Point based animation.
    Pba,
    /// Compressible neo-Hookean.
    NeoHookean,
}

impl ModelId {
    /// Every variant, in report order.
    pub const ALL: [ModelId; 7] = [
        ModelId::Msm,
        ModelId::LshmNode,
        ModelId::LshmCluster,
        ModelId::Deb,
        ModelId::DebCorotated,
        ModelId::Pba,
        ModelId::NeoHookean,
    ];

    /// Short label used in tables and legends.
    pub fn label(self) -> &'static str {
        match self {
            ModelId::Msm => "msm",
            ModelId::LshmNode => "lshm-node",
            ModelId::LshmCluster => "lshm-cluster",
            ModelId::Deb => "deb",
            ModelId::DebCorotated => "deb-corotated",
            ModelId::Pba => "pba",
            ModelId::NeoHookean => "nh",
        }
    }

    /// Plot colour.
    pub fn colour(self) -> [u8; 3] {
        match self {
            ModelId::Msm => [31, 119, 180],
            ModelId::LshmNode => [255, 127, 14],
            ModelId::LshmCluster => [44, 160, 44],
            ModelId::Deb => [214, 39, 40],
            ModelId::DebCorotated => [148, 103, 189],
            ModelId::Pba => [140, 86, 75],
            ModelId::NeoHookean => [227, 119, 194],
        }
    }

    /// The material for Young's modulus `young` on a lattice of spacing `h` (mass-spring
    /// and shape matching take their stiffness from the calibration rule), Poisson ratio
    /// [`POISSON`], other parameters at their defaults.
    pub fn material(self, young: f64, h: f64) -> Material {
        let k = |c: Result<f64, calibration::UncalibratedNeighbours>| {
            c.expect("the report's K is calibrated (tested)")
        };
        match self {
            ModelId::Msm => {
                Material::mass_spring(k(calibration::mass_spring_stiffness(young, h, NEIGHBOURS)))
            }
            ModelId::LshmNode => Material::LocalShapeMatching(
                ShapeMatchingParams::new(k(calibration::shape_matching_stiffness(
                    young, h, NEIGHBOURS, false,
                )))
                .with_forces(ShapeMatchingForces::Node),
            ),
            ModelId::LshmCluster => Material::LocalShapeMatching(
                ShapeMatchingParams::new(k(calibration::shape_matching_stiffness(
                    young, h, NEIGHBOURS, true,
                )))
                .with_forces(ShapeMatchingForces::Cluster),
            ),
            ModelId::Deb => Material::debunne(young, POISSON),
            ModelId::DebCorotated => {
                Material::DebunneMeshfree(DebunneParams::new(young, POISSON).with_corotated(true))
            }
            ModelId::Pba => Material::point_based(young, POISSON),
            ModelId::NeoHookean => Material::NeoHookean(NeoHookeanParams::new(young, POISSON)),
        }
    }

    /// The least velocity damping the model needs, 1/s: the paper's per-node shape
    /// matching forces feed energy in at a rate of about `0.17 sqrt(k / m)` (measured,
    /// `local_shape_matching` docs); 0.2 sqrt(k / m) for a node of mass `rho h^3`.
    pub fn damping_floor(self, young: f64, h: f64) -> f64 {
        match self {
            ModelId::LshmNode => {
                let k = calibration::shape_matching_stiffness(young, h, NEIGHBOURS, false)
                    .expect("the report's K is calibrated (tested)");
                0.2 * (k / (DENSITY * h * h * h)).sqrt()
            }
            _ => 0.0,
        }
    }
}

/// Which reference case.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaseId {
    /// Cantilever tip deflection under gravity.
    Cantilever,
    /// Cantilever first bending period.
    Frequency,
    /// Free cube between rollers: end-plate stress and lateral strain.
    Stretch,
    /// Flat punch on a block: force and displacement field.
    Indentation,
    /// A free ball under uniform pressure: its uniform strain.
    Sphere,
    /// A standing cylinder with a fixed base sagging under its weight: its mean sag.
    Column,
}

impl CaseId {
    /// Every case.
    pub const ALL: [CaseId; 6] = [
        CaseId::Cantilever,
        CaseId::Frequency,
        CaseId::Stretch,
        CaseId::Indentation,
        CaseId::Sphere,
        CaseId::Column,
    ];

    /// Short label.
    pub fn label(self) -> &'static str {
        match self {
            CaseId::Cantilever => "cantilever",
            CaseId::Frequency => "frequency",
            CaseId::Stretch => "stretch",
            CaseId::Indentation => "indentation",
            CaseId::Sphere => "sphere",
            CaseId::Column => "column",
        }
    }

    /// What the error measures.
    pub fn error_meaning(self) -> &'static str {
        match self {
            CaseId::Cantilever => "tip deflection vs Timoshenko",
            CaseId::Frequency => "first bending period vs 3D FEM eigenvalue",
            CaseId::Stretch => "end-plate stress vs E eps (St Venant-Kirchhoff for PBA)",
            CaseId::Indentation => "punch force vs scikit-fem P2",
            CaseId::Sphere => "strain of a ball under pressure vs Lame's solution",
            CaseId::Column => "mean sag of a clamped cylinder vs scikit-fem P2 (axisymmetric)",
        }
    }

    /// How far the reference itself may be from the exact answer of the model's continuum,
    /// as a relative error: errors below it say nothing about convergence. Stretch: the
    /// equilibrium test's [`REL_TOL`]. Cantilever: 1% (a 3D clamp also holds the Poisson
    /// contraction that Timoshenko's clamp leaves free). Frequency: 1% (Euler-Bernoulli's
    /// first frequency is about 0.6% above Timoshenko's for this 10:1 beam). Indentation:
    /// 1% (the FEM reference's Richardson extrapolation, `reference/indentation_fem.md`; the
    /// displacement field is its N = 16 solution, whose force is 2.5% off the extrapolated
    /// one, so field errors near 1% are at its accuracy too). The stretch floor is a settle
    /// tolerance, not a bound: the remaining gap to equilibrium can be a small multiple of
    /// it.
    pub fn reference_accuracy(self) -> f64 {
        match self {
            CaseId::Stretch => REL_TOL,
            CaseId::Cantilever | CaseId::Frequency | CaseId::Indentation => 0.01,
            CaseId::Sphere => REL_TOL,
            // The FEM extrapolation is within 1e-4 (`reference/column_fem.md`).
            CaseId::Column => REL_TOL,
        }
    }

    /// Whether `errors` (coarsest first) fall with resolution: each error is below the one
    /// before it, or both are within [`Self::reference_accuracy`]. Non-finite errors (no
    /// result) never fall, nor does a single error.
    pub fn error_falls(self, errors: &[f64]) -> bool {
        let floor = self.reference_accuracy();
        errors.len() >= 2
            && errors.iter().all(|e| e.is_finite())
            && errors
                .windows(2)
                .all(|w| w[1] < w[0] || w[1].max(w[0]) < floor)
    }

    /// Lattice points per side for resolution level `level` (0 = coarsest): the beam's
    /// cross-section (`n^2 (10 (n - 1) + 1)` nodes) or the cube's side (`m^3` nodes; m - 1
    /// a multiple of 4, so that the punch edges at 2.5 and 7.5 cm fall on lattice lines);
    /// for the sphere, spacings per radius (463, 2,955, 9,031 and 20,275 nodes at 4, 8,
    /// 12 and 16); for the column, spacings per radius.
    pub fn points_per_side(self, level: usize) -> usize {
        match self {
            CaseId::Cantilever | CaseId::Frequency => [3, 4, 5, 7, 9, 11][level.min(5)],
            CaseId::Stretch | CaseId::Indentation => [5, 9, 13, 17, 21, 25][level.min(5)],
            CaseId::Sphere => [4, 8, 12, 16, 20, 24][level.min(5)],
            CaseId::Column => [3, 4, 5, 6, 8, 10][level.min(5)],
        }
    }
}

/// One run of a reference case.
#[derive(Debug, Clone)]
pub struct CaseResult {
    /// The case.
    pub case: CaseId,
    /// The model.
    pub model: ModelId,
    /// Nodes simulated.
    pub nodes: usize,
    /// Lattice spacing, m.
    pub spacing: f64,
    /// Time step, s.
    pub dt: f64,
    /// `dt` over the estimated critical step.
    pub dt_fraction: f64,
    /// Steps run.
    pub steps: u64,
    /// Wall time of the run (stepping, constraints and convergence checks).
    pub wall: Duration,
    /// The measured quantity (m, s, Pa or N).
    pub measured: f64,
    /// Its reference value.
    pub reference: f64,
    /// `|measured / reference - 1|`.
    pub error: f64,
    /// A second error: lateral strain vs nu (stretch), displacement-field RMS over the
    /// punch depth (indentation), Euler-Bernoulli deflection (cantilever); NaN otherwise.
    pub secondary: f64,
    /// Whether the equilibrium test passed (static cases) or two zero crossings were found
    /// (frequency).
    pub converged: bool,
}

/// Everything a case run needs besides the case and model.
#[derive(Debug, Clone, Copy)]
pub struct RunSpec {
    /// Resolution level (see [`CaseId::points_per_side`]).
    pub level: usize,
    /// Time step as a fraction of the estimated critical one.
    pub dt_fraction: f64,
    /// Backend that runs the case.
    pub backend: BackendChoice,
}
