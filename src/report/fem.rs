//! The indentation case's reference solution: a converged quadratic-tetrahedron solution
//! computed with scikit-fem by `scripts/fem_indentation.py` (see
//! `reference/indentation_fem.md`), shipped as the punch force and the displacement on a
//! 17 x 17 x 17 grid over the cube, interpolated trilinearly. The solution is linear, so
//! force and displacements are scaled from the reference depth (2 mm) to [`PUNCH_DEPTH`].

use super::cases::{ReportError, CUBE, PUNCH_DEPTH};
use std::sync::OnceLock;

const CSV: &str = include_str!("../../reference/indentation_fem.csv");
const MD: &str = include_str!("../../reference/indentation_fem.md");
const POINTS: usize = 17;
/// Punch depth of the shipped solution, m (checked against `indentation_fem.md`).
const REFERENCE_DEPTH: f64 = 0.002;

/// The reference solution.
#[derive(Debug)]
pub struct Indentation {
    /// Punch force at [`PUNCH_DEPTH`], N.
    pub force: f64,
    /// Displacements at [`PUNCH_DEPTH`], x outermost, z innermost.
    u: Vec<[f64; 3]>,
}

impl Indentation {
    /// The displacement at rest position `p` (trilinear in the grid; clamped to the cube).
    pub fn displacement(&self, p: [f64; 3]) -> [f64; 3] {
        let h = CUBE / (POINTS - 1) as f64;
        let mut base = [0usize; 3];
        let mut frac = [0.0; 3];
        for a in 0..3 {
            let s = (p[a] / h).clamp(0.0, (POINTS - 1) as f64);
            base[a] = (s.floor() as usize).min(POINTS - 2);
            frac[a] = s - base[a] as f64;
        }
        let mut out = [0.0; 3];
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let w: f64 = (0..3)
                .map(|a| if o[a] == 1 { frac[a] } else { 1.0 - frac[a] })
                .product();
            let i = ((base[0] + o[0]) * POINTS + base[1] + o[1]) * POINTS + base[2] + o[2];
            for (a, v) in out.iter_mut().enumerate() {
                *v += w * self.u[i][a];
            }
        }
        out
    }
}

fn parse() -> Result<Indentation, String> {
    // The shipped solution must be the one REFERENCE_DEPTH describes.
    if !MD.contains("u = (0, -0.002, 0)") {
        return Err(format!(
            "indentation_fem.md does not state the punch displacement u = (0, -{REFERENCE_DEPTH}, 0)"
        ));
    }
    let force = MD
        .lines()
        .find_map(|l| {
            l.trim()
                .trim_matches('`')
                .strip_prefix("reaction_force_N = ")
        })
        .ok_or("no `reaction_force_N = ` line in indentation_fem.md")?
        .trim()
        .trim_matches('`')
        .parse::<f64>()
        .map_err(|e| format!("reaction_force_N: {e}"))?;
    let mut lines = CSV.lines();
    if lines.next().map(str::trim) != Some("x,y,z,ux,uy,uz") {
        return Err("indentation_fem.csv: header is not x,y,z,ux,uy,uz".into());
    }
    let scale = PUNCH_DEPTH / REFERENCE_DEPTH;
    let h = CUBE / (POINTS - 1) as f64;
    let mut u = Vec::with_capacity(POINTS.pow(3));
    for (row, line) in lines.filter(|l| !l.trim().is_empty()).enumerate() {
        let v: Vec<f64> = line
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("indentation_fem.csv row {}: {e}", row + 2))?;
        let (ix, iy, iz) = (
            row / (POINTS * POINTS),
            (row / POINTS) % POINTS,
            row % POINTS,
        );
        let expect = [ix as f64 * h, iy as f64 * h, iz as f64 * h];
        if v.len() != 6 || (0..3).any(|a| (v[a] - expect[a]).abs() > 1e-6) {
            return Err(format!(
                "indentation_fem.csv row {}: expected the point {expect:?} with 3 components",
                row + 2
            ));
        }
        u.push([scale * v[3], scale * v[4], scale * v[5]]);
    }
    if u.len() != POINTS.pow(3) {
        return Err(format!(
            "indentation_fem.csv: {} points, expected {}",
            u.len(),
            POINTS.pow(3)
        ));
    }
    Ok(Indentation {
        force: scale * force,
        u,
    })
}

/// The parsed reference (parsed once).
pub fn indentation() -> Result<&'static Indentation, ReportError> {
    static CELL: OnceLock<Result<Indentation, String>> = OnceLock::new();
    CELL.get_or_init(parse)
        .as_ref()
        .map_err(|e| ReportError::Reference(e.clone()))
}
