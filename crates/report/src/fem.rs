//! The finite element reference solutions ([`indentation`], [`column()`]). Indentation: a
//! converged quadratic-tetrahedron solution computed with scikit-fem by
//! `scripts/fem_indentation.py` (see
//! `reference/indentation_fem.md`), shipped as the punch force and the displacement on a
//! 17 x 17 x 17 grid over the cube, interpolated trilinearly. The solution is linear, so
//! force and displacements are scaled from the reference depth (2 mm) to [`PUNCH_DEPTH`].

use crate::constants::{
    BEAM_LENGTH, BEAM_WIDTH, COLUMN_HEIGHT, COLUMN_RADIUS, CUBE, DENSITY, POISSON, PUNCH_DEPTH,
    YOUNG,
};
use crate::error::ReportError;
use std::sync::OnceLock;

const CSV: &str = include_str!("../reference/indentation_fem.csv");
const MD: &str = include_str!("../reference/indentation_fem.md");
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
    let force = md_value(MD, "indentation_fem.md", "reaction_force_N")?;
    let scale = PUNCH_DEPTH / REFERENCE_DEPTH;
    let h = CUBE / (POINTS - 1) as f64;
    let mut u = Vec::with_capacity(POINTS.pow(3));
    for (row, v) in csv_rows(CSV, "indentation_fem.csv", "x,y,z,ux,uy,uz")?
        .into_iter()
        .enumerate()
    {
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

/// The column case's reference: an axisymmetric quadratic-triangle solution from
/// scikit-fem (`scripts/fem_column.py`, `reference/column_fem.md`), shipped per unit
/// gravity as the mean sag and `(u_r, u_y)` on an 11 x 41 grid over the `(r, y)`
/// section, interpolated bilinearly; scaled linearly to the case's gravity.
#[derive(Debug)]
pub struct Column {
    /// Mean sag over the volume, `-(1/V) int u_y dV`, per unit gravity, m / (m/s^2).
    pub mean_sag_per_g: f64,
    /// Sag of the top face's centre per unit gravity, m / (m/s^2).
    pub top_sag_per_g: f64,
    /// `(u_r, u_y)` per unit gravity, r outermost.
    u: Vec<[f64; 2]>,
}

const COLUMN_CSV: &str = include_str!("../reference/column_fem.csv");
const COLUMN_MD: &str = include_str!("../reference/column_fem.md");
const COLUMN_R_POINTS: usize = 11;
const COLUMN_Y_POINTS: usize = 41;

impl Column {
    /// The displacement per unit gravity at rest position `p` (the column's axis is the
    /// y axis; `p` is clamped to the section).
    pub fn displacement_per_g(&self, p: [f64; 3]) -> [f64; 3] {
        let r = (p[0] * p[0] + p[2] * p[2]).sqrt();
        let steps = [
            COLUMN_RADIUS / (COLUMN_R_POINTS - 1) as f64,
            COLUMN_HEIGHT / (COLUMN_Y_POINTS - 1) as f64,
        ];
        let points = [COLUMN_R_POINTS, COLUMN_Y_POINTS];
        let mut base = [0usize; 2];
        let mut frac = [0.0; 2];
        for (a, v) in [r, p[1]].into_iter().enumerate() {
            let s = (v / steps[a]).clamp(0.0, (points[a] - 1) as f64);
            base[a] = (s.floor() as usize).min(points[a] - 2);
            frac[a] = s - base[a] as f64;
        }
        let mut u = [0.0; 2];
        for corner in 0..4 {
            let o = [corner & 1, corner >> 1];
            let w: f64 = (0..2)
                .map(|a| if o[a] == 1 { frac[a] } else { 1.0 - frac[a] })
                .product();
            let v = self.u[(base[0] + o[0]) * COLUMN_Y_POINTS + base[1] + o[1]];
            u[0] += w * v[0];
            u[1] += w * v[1];
        }
        let (cos, sin) = if r > 0.0 {
            (p[0] / r, p[2] / r)
        } else {
            (0.0, 0.0)
        };
        [u[0] * cos, u[1], u[0] * sin]
    }
}

/// The numbers of each non-empty row of a reference CSV after its `header` line.
fn csv_rows(text: &str, file: &str, header: &str) -> Result<Vec<Vec<f64>>, String> {
    let mut lines = text.lines();
    if lines.next().map(str::trim) != Some(header) {
        return Err(format!("{file}: header is not {header}"));
    }
    lines
        .filter(|l| !l.trim().is_empty())
        .enumerate()
        .map(|(row, line)| {
            line.split(',')
                .map(|s| s.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| format!("{file} row {}: {e}", row + 2))
        })
        .collect()
}

/// The value of the line `key = <number>` of a reference `.md`.
fn md_value(md: &str, file: &str, key: &str) -> Result<f64, String> {
    let prefix = format!("{key} = ");
    md.lines()
        .find_map(|l| l.trim().trim_matches('`').strip_prefix(prefix.as_str()))
        .ok_or_else(|| format!("no `{prefix}` line in {file}"))?
        .trim()
        .trim_matches('`')
        .parse::<f64>()
        .map_err(|e| format!("{file}: {key}: {e}"))
}

fn parse_column() -> Result<Column, String> {
    for (what, value) in [("R", COLUMN_RADIUS), ("H", COLUMN_HEIGHT)] {
        if !COLUMN_MD.contains(&format!("{what} = {value} m")) {
            return Err(format!("column_fem.md does not state {what} = {value} m"));
        }
    }
    let mean_sag_per_g = md_value(COLUMN_MD, "column_fem.md", "mean_sag_per_g")?;
    let top_sag_per_g = md_value(COLUMN_MD, "column_fem.md", "top_centre_sag_per_g")?;
    let mut u = Vec::with_capacity(COLUMN_R_POINTS * COLUMN_Y_POINTS);
    for (row, v) in csv_rows(COLUMN_CSV, "column_fem.csv", "r,y,ur,uy")?
        .into_iter()
        .enumerate()
    {
        let expect = [
            (row / COLUMN_Y_POINTS) as f64 * COLUMN_RADIUS / (COLUMN_R_POINTS - 1) as f64,
            (row % COLUMN_Y_POINTS) as f64 * COLUMN_HEIGHT / (COLUMN_Y_POINTS - 1) as f64,
        ];
        if v.len() != 4 || (0..2).any(|a| (v[a] - expect[a]).abs() > 1e-7) {
            return Err(format!(
                "column_fem.csv row {}: expected the point {expect:?} with 2 components",
                row + 2
            ));
        }
        u.push([v[2], v[3]]);
    }
    if u.len() != COLUMN_R_POINTS * COLUMN_Y_POINTS {
        return Err(format!(
            "column_fem.csv: {} points, expected {}",
            u.len(),
            COLUMN_R_POINTS * COLUMN_Y_POINTS
        ));
    }
    Ok(Column {
        mean_sag_per_g,
        top_sag_per_g,
        u,
    })
}

/// The parsed column reference (parsed once).
pub fn column() -> Result<&'static Column, ReportError> {
    static CELL: OnceLock<Result<Column, String>> = OnceLock::new();
    CELL.get_or_init(parse_column)
        .as_ref()
        .map_err(|e| ReportError::Reference(e.clone()))
}

const BEAM_MD: &str = include_str!("../reference/beam_modes_fem.md");

/// The frequency case's reference: the first bending period of the clamped bar, from
/// the lowest eigenvalue of the 3D linear-elastic problem with quadratic tetrahedra
/// (scikit-fem, `scripts/fem_beam_modes.py`, `reference/beam_modes_fem.md`), in s. It is
/// 0.34% longer than Euler-Bernoulli's (shear and rotary inertia of a 10:1 bar).
pub fn beam_period() -> Result<f64, ReportError> {
    static CELL: OnceLock<Result<f64, String>> = OnceLock::new();
    CELL.get_or_init(|| {
        let stated = format!(
            "Bar {BEAM_LENGTH} x {BEAM_WIDTH} x {BEAM_WIDTH} m along x, E = {YOUNG} Pa, nu = {POISSON}, density {DENSITY} kg/m^3"
        );
        if !BEAM_MD.contains(&stated) {
            return Err(format!("beam_modes_fem.md does not state `{stated}`"));
        }
        md_value(BEAM_MD, "beam_modes_fem.md", "first_bending_period")
    })
    .as_ref()
    .copied()
    .map_err(|e| ReportError::Reference(e.clone()))
}

#[cfg(test)]
mod tests {
    /// The shipped references parse and describe the report's geometry and material.
    #[test]
    fn shipped_references_parse() {
        super::indentation().unwrap();
        super::column().unwrap();
        let period = super::beam_period().unwrap();
        // Within 1% of Euler-Bernoulli's period (the 3D answer is 0.34% longer).
        let eb = 2.0 * std::f64::consts::PI / crate::cases::beam_omega();
        assert!((period / eb - 1.0).abs() < 0.01, "{period} against {eb}");
    }
}
