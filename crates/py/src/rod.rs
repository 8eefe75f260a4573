//! `needlesim.flexible_needle`: the flexible shaft of `needlesim::needle::rod` (issue 43's
//! first step) from Python, as a cantilever clamped at the origin along +z.

use needlesim::needle::rod::{solve, DQuat, DVec3, Loads, PointLoad, ShaftSpec};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// The centre line of a flexible needle clamped at the origin along +z, in equilibrium
/// under point forces and moments and a load per length: an (N + 2, 3) float64 array of
/// the base, the N hinges and the tip (m). `forces` and `moments` are sequences of
/// `(s, x, y, z)`: arc length from the base (m) and the vector (N, N m), both in the
/// clamp's frame. A chain of `segments` rigid elements with their bending and torsion
/// lumped at their middles (`needlesim::needle::rod`); 20 elements are within 0.13% of
/// the Euler-Bernoulli cantilever. A ValueError names a bad parameter, a load off the
/// shaft, or a load the solve finds no equilibrium for.
#[pyfunction]
#[pyo3(signature = (length, outer_diameter, inner_diameter = 0.0, *, young_modulus = 193e9,
    poisson_ratio = 0.29, segments = None, forces = Vec::new(), moments = Vec::new(),
    per_length = (0.0, 0.0, 0.0)),
    text_signature = "(length, outer_diameter, inner_diameter=0.0, *, young_modulus=193e9, \
        poisson_ratio=0.29, segments=20, forces=..., moments=..., per_length=...)")]
#[allow(clippy::too_many_arguments)]
pub fn flexible_needle<'py>(
    py: Python<'py>,
    length: f64,
    outer_diameter: f64,
    inner_diameter: f64,
    young_modulus: f64,
    poisson_ratio: f64,
    segments: Option<&Bound<'py, PyAny>>,
    forces: Vec<(f64, f64, f64, f64)>,
    moments: Vec<(f64, f64, f64, f64)>,
    per_length: (f64, f64, f64),
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let segments =
        crate::opt_count_arg(segments, "segments", usize::MAX as u64)?.unwrap_or(20) as usize;
    let spec = ShaftSpec {
        length,
        outer_diameter,
        inner_diameter,
        young_modulus,
        poisson_ratio,
        segments,
    };
    let forces = forces.into_iter().map(|(s, x, y, z)| PointLoad {
        s,
        force: DVec3::new(x, y, z),
        moment: DVec3::ZERO,
    });
    let moments = moments.into_iter().map(|(s, x, y, z)| PointLoad {
        s,
        force: DVec3::ZERO,
        moment: DVec3::new(x, y, z),
    });
    let loads = Loads {
        points: forces.chain(moments).collect(),
        per_length: DVec3::new(per_length.0, per_length.1, per_length.2),
    };
    let shape = py
        .detach(|| solve(&spec, DVec3::ZERO, DQuat::IDENTITY, &loads))
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let flat: Vec<f64> = shape.points.iter().flat_map(|p| p.to_array()).collect();
    let n = shape.points.len();
    PyArray1::from_vec(py, flat).reshape([n, 3])
}
