//! The elastic constants each model actually has, measured from its forces under a
//! homogeneous strain: what a user gets when asking for E and nu.
//!
//! A cube of `n^3` nodes is given the affine deformation `x = F X` (about its centre) for
//! a small strain `e`, and its forces are evaluated once. For a model whose forces are the
//! gradient of an energy `U(F)`, the virial `-sum_i f_i (X_i)^T` is `dU/dF`, the nominal
//! stress times the body's volume, exactly; the cube's surface is included, so the
//! constants are those of the body, not of an unbounded lattice. Two strains give the
//! cubic constants: uniaxial strain `e_xx` (`C11 = s_xx / e`, `C12 = s_yy / e`) and pure
//! shear `e_xy` (`C44 = s_xy / (2 e_xy)`). For an isotropic material `C11 = lambda + 2
//! mu`, `C12 = lambda`, `C44 = mu`; the table gives the isotropic values the constants
//! imply (`nu = C12 / (C11 + C12)`, `E = (C11 - C12)(C11 + 2 C12) / (C11 + C12)`, bulk
//! `K = (C11 + 2 C12) / 3`, shear `G = C44`) and the anisotropy `A = 2 C44 / (C11 - C12)`
//! (1 when isotropic).
//!
//! The paper's per-node shape matching forces are not the gradient of an energy; their
//! virial is still the force the body's surface must carry, so the same constants
//! describe how it answers a homogeneous strain.

use crate::cases::{ModelId, NEIGHBOURS, POISSON, YOUNG};
use crate::error::ReportError;
use needlesim_core::{Backend, CpuBackend, NodeField, Scene, Threading, Tissue};
use std::fmt::Write as _;

/// Strain of the measurement (small: the constants are the tangent ones at rest, and the
/// f32 forces keep six digits).
const STRAIN: f64 = 1e-3;

/// Side of the cube, m.
const SIDE: f64 = 0.1;

/// The constants one model shows on one cube.
#[derive(Debug, Clone, PartialEq)]
pub struct Effective {
    /// The model.
    pub model: ModelId,
    /// Nodes of the cube.
    pub nodes: usize,
    /// Cubic constants C11, C12, C44, Pa.
    pub c: [f64; 3],
    /// The isotropic Young's modulus they imply, Pa.
    pub young: f64,
    /// The isotropic Poisson ratio they imply.
    pub poisson: f64,
    /// Bulk modulus, Pa.
    pub bulk: f64,
    /// Shear modulus, Pa.
    pub shear: f64,
    /// Anisotropy `2 C44 / (C11 - C12)`.
    pub anisotropy: f64,
}

/// The nominal stress (Pa) of the cube under the deformation gradient `f`.
fn stress(
    b: &mut CpuBackend,
    rest: &[[f64; 3]],
    f: [[f64; 3]; 3],
) -> Result<[[f64; 3]; 3], ReportError> {
    let n = rest.len();
    let c = [0.5 * SIDE; 3];
    let pos: Vec<[f32; 4]> = rest
        .iter()
        .map(|x| {
            let d = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
            let mut p = [0.0f32; 4];
            for a in 0..3 {
                p[a] = (c[a] + (0..3).map(|k| f[a][k] * d[k]).sum::<f64>()) as f32;
            }
            p
        })
        .collect();
    let mut old = vec![[0.0f32; 4]; n];
    b.read(NodeField::Position, 0..n, &mut old)?;
    let pos: Vec<[f32; 4]> = pos
        .iter()
        .zip(&old)
        .map(|(p, o)| [p[0], p[1], p[2], o[3]])
        .collect();
    b.write(NodeField::Position, 0, &pos)?;
    b.compute_forces();
    let mut force = vec![[0.0f32; 4]; n];
    b.read(NodeField::Force, 0..n, &mut force)?;
    let mut s = [[0.0f64; 3]; 3];
    for (fi, x) in force.iter().zip(rest) {
        for a in 0..3 {
            for k in 0..3 {
                s[a][k] -= fi[a] as f64 * (x[k] - c[k]);
            }
        }
    }
    let v = SIDE * SIDE * SIDE;
    Ok(s.map(|row| row.map(|x| x / v)))
}

/// The constants of `model` (E and nu of the report, the discrete models' stiffness from
/// the calibration `k = C E h`) on a free cube of `n^3` nodes.
pub fn effective(model: ModelId, n: usize) -> Result<Effective, ReportError> {
    let h = SIDE / (n - 1) as f64;
    let scene = Scene::builder()
        .neighbours(NEIGHBOURS)
        .box_with_spacing([0.0; 3], [SIDE; 3], h)
        .material(model.material(YOUNG, h))
        .build()
        .map_err(|e| ReportError::Scene(e.to_string()))?;
    let tissue = Tissue::from_scene(&scene).map_err(|e| ReportError::Scene(e.to_string()))?;
    let rest: Vec<[f64; 3]> = tissue.state.positions[..tissue.state.n_active]
        .iter()
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect();
    let mut b = CpuBackend::new(tissue, Threading::Single)
        .map_err(|e| ReportError::Scene(e.to_string()))?;
    let e = STRAIN;
    let uniaxial = stress(
        &mut b,
        &rest,
        [[1.0 + e, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    )?;
    let shear = stress(
        &mut b,
        &rest,
        [[1.0, e, 0.0], [e, 1.0, 0.0], [0.0, 0.0, 1.0]],
    )?;
    let c11 = uniaxial[0][0] / e;
    let c12 = 0.5 * (uniaxial[1][1] + uniaxial[2][2]) / e;
    let c44 = 0.5 * (shear[0][1] + shear[1][0]) / (2.0 * e);
    Ok(Effective {
        model,
        nodes: rest.len(),
        c: [c11, c12, c44],
        young: (c11 - c12) * (c11 + 2.0 * c12) / (c11 + c12),
        poisson: c12 / (c11 + c12),
        bulk: (c11 + 2.0 * c12) / 3.0,
        shear: c44,
        anisotropy: 2.0 * c44 / (c11 - c12),
    })
}

/// Every model of the report at `n^3` nodes.
pub fn run(n: usize) -> Result<Vec<Effective>, ReportError> {
    ModelId::ALL.iter().map(|&m| effective(m, n)).collect()
}

/// The table as CSV.
pub fn csv(rows: &[Effective]) -> String {
    let mut s = String::from(
        "model,nodes,c11_pa,c12_pa,c44_pa,young_pa,poisson,bulk_pa,shear_pa,anisotropy\n",
    );
    for r in rows {
        writeln!(
            s,
            "{},{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            r.model.label(),
            r.nodes,
            r.c[0],
            r.c[1],
            r.c[2],
            r.young,
            r.poisson,
            r.bulk,
            r.shear,
            r.anisotropy
        )
        .unwrap();
    }
    s
}

/// Appends the section to the report's markdown.
pub fn markdown(md: &mut String, rows: &[Effective]) {
    let (e, nu) = (YOUNG, POISSON);
    writeln!(md, "\n## What each model represents\n").unwrap();
    writeln!(
        md,
        "Every model asked for E = {:.0} kPa and nu = {nu} (mass-spring and shape matching through \
         their calibrated stiffness `k = C E h`), on a free cube under a homogeneous strain of \
         {STRAIN:e}; the constants come from the virial of the forces (module \
         `needlesim_report::effective`). Requested: K = {:.2} kPa, G = {:.2} kPa.\n",
        e / 1e3,
        e / (3.0 * (1.0 - 2.0 * nu)) / 1e3,
        e / (2.0 * (1.0 + nu)) / 1e3
    )
    .unwrap();
    writeln!(
        md,
        "| model | nodes | E, kPa | nu | bulk K, kPa | shear G, kPa | anisotropy 2 C44 / (C11 - C12) |"
    )
    .unwrap();
    writeln!(md, "|---|---|---|---|---|---|---|").unwrap();
    for r in rows {
        writeln!(
            md,
            "| {} | {} | {:.2} | {:.3} | {:.2} | {:.2} | {:.3} |",
            r.model.label(),
            r.nodes,
            r.young / 1e3,
            r.poisson,
            r.bulk / 1e3,
            r.shear / 1e3,
            r.anisotropy
        )
        .unwrap();
    }
    writeln!(
        md,
        "\nThe continuum models have the E and nu they are given. Mass-spring is a lattice of \
         central springs: its Poisson ratio is fixed near 1/4 and its bulk and shear stiffness \
         are not independent, whatever the scene asks. Shape matching pulls each node \
         towards a rigid goal: with cluster forces it has a Poisson ratio near 0 (no lateral \
         contraction), with the paper's per-node forces its constants do not form an \
         isotropic material at all. Use a continuum model where nu matters."
    )
    .unwrap();
}
