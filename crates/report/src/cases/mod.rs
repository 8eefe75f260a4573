//! The reference cases of the accuracy report, each with an answer known independently of
//! needlesim:
//!
//! - cantilever: a 10:1 beam clamped at x = 0 sagging under gravity; tip deflection
//!   against Timoshenko's `q L^4 / (8 E I) + q L^2 / (2 kappa G A)` (Euler-Bernoulli is the
//!   first term);
//! - frequency: the same beam released from its static shape without gravity; the period
//!   of the tip against the first bending period of the 3D problem, the lowest eigenvalue
//!   with quadratic tetrahedra from scikit-fem (`scripts/fem_beam_modes.py`, data in
//!   `reference/`: 3.9285 s); the second error is against Euler-Bernoulli's first mode
//!   `omega_1 = 1.8751^2 sqrt(E I / (rho A L^4))`, 0.34% shorter;
//! - stretch: a free cube stretched by eps along z between frictionless end plates
//!   (rollers); the stress on the end plate against `E eps` and the lateral strain against
//!   `-nu eps` (point based animation: the exact St Venant-Kirchhoff answer,
//!   [`stretch_reference`]);
//! - indentation: a bonded flat square punch (5 x 5 cm) pressed 0.1 mm into the top of a
//!   10 cm cube with a fixed bottom; the punch force and the displacement field against a
//!   converged quadratic-tetrahedron solution from scikit-fem (`scripts/fem_indentation.py`,
//!   data in `reference/`). The issue asked for the needle tip pressed into the surface;
//!   a point indenter has no converged continuum answer (its force goes to zero as the
//!   mesh is refined), so the tip is replaced by a punch of finite size;
//! - sphere: a free 10 cm ball (a finely triangulated sphere resampled at the case's
//!   spacing: no box lattice) under a uniform pressure `p` on its whole surface; Lame's
//!   solution is a uniform strain `eps = -p (1 - 2 nu) / E` (`u = eps x`), fitted over
//!   all nodes; the second error is the displacement field's RMS deviation from it over
//!   `|eps| R`;
//! - column: a standing solid cylinder (R 2.5 cm, H 10 cm, a finely triangulated cylinder
//!   resampled at the case's spacing) with its bottom face fixed, sagging under its own
//!   weight; the volume-mean sag `-(1/V) int u_y dV` (mass-weighted over the nodes)
//!   against a converged axisymmetric quadratic-triangle solution from scikit-fem
//!   (`scripts/fem_column.py`, checked there against a 3D quadratic-tetrahedron solution
//!   on a gmsh mesh; data in `reference/`); the second error is the displacement field's
//!   RMS deviation from it over the top centre's sag.
//!
//! Static cases relax with velocity damping `c = 2 omega_slow` (critical for the slowest
//! mode) until the measured quantity changes by less than [`REL_TOL`] relative over each
//! of two consecutive windows of `1 / omega_slow` (a speed criterion does not work: f32
//! round-off of the positions keeps nodes jittering at a level that depends on the model).

mod ids;
mod runs;
mod setup;

pub use crate::constants::*;
pub use crate::error::ReportError;
pub use ids::{CaseId, CaseResult, ModelId, RunSpec};
pub use runs::stretch_reference;
pub use setup::{beam_deflection_timoshenko, beam_gravity, beam_omega, case_backend};

use runs::{cantilever, column, frequency, indentation, sphere, stretch};

/// Runs one reference case.
pub fn run_case(case: CaseId, model: ModelId, spec: &RunSpec) -> Result<CaseResult, ReportError> {
    match case {
        CaseId::Cantilever => cantilever(model, spec),
        CaseId::Frequency => frequency(model, spec),
        CaseId::Stretch => stretch(model, spec),
        CaseId::Indentation => indentation(model, spec),
        CaseId::Sphere => sphere(model, spec),
        CaseId::Column => column(model, spec),
    }
}
