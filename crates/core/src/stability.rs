//! The stable time step of the explicit step, estimated from the model itself.
//!
//! Linearised about the current state, the elastic forces are `f(x0 + u) ~ f(x0) - K u`.
//! Undamped symplectic Euler (the integrator here, paper section 4) is stable for
//! `dt < 2 / sqrt(lambda_max)`, `lambda_max` the largest eigenvalue of `M^-1 K` (the square
//! of the highest natural frequency); velocity damping only helps. [`max_eigenvalue`]
//! finds `lambda_max` by power iteration on finite differences of the backend's own force
//! evaluation, so it works for every model and backend without a model-specific bound
//! (Gershgorin bounds are looser and differ per model). Fixed nodes are left out.
//!
//! A viscous material (the Kelvin-Voigt dashpot of a continuum model) adds the damping
//! `C v`. Symplectic Euler with it taken explicitly is stable for a mode with `M^-1 K`
//! eigenvalue `k` and `M^-1 C` eigenvalue `c` when `dt^2 k + 2 dt c < 4` (its
//! amplification matrix has determinant `1 - dt c` and trace `2 - dt^2 k - dt c`; Jury's
//! conditions). [`max_damping_eigenvalue`] finds the largest `c` the same way, on
//! velocities, and [`damped_critical_dt`] takes the two largest together (a bound: they
//! need not be the same mode's).
//!
//! The probe moves positions and restores them; it calls `compute_forces`, which also
//! refreshes the warm-start rotations of shape matching and co-rotated Debunne (their
//! next step starts from a rotation a little closer to the converged one).

use crate::backend::{Backend, NodeField};
use crate::error::SimError;
use crate::math::Vec4;

/// Force evaluations per probe state.
const ROTATION_SETTLE: usize = 8;

/// Result of the probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilityEstimate {
    /// Largest eigenvalue of `M^-1 K` found, 1/s^2.
    pub max_eigenvalue: f64,
    /// `2 / sqrt(max_eigenvalue)`, s: the largest stable undamped time step.
    pub critical_dt: f64,
    /// Power iterations run.
    pub iterations: usize,
}

/// Power iteration on `M^-1 K` with `iterations` force evaluations (40 is plenty for an
/// estimate within a few percent on the shipped scenes), from a fixed pseudo-random start.
pub fn max_eigenvalue(
    backend: &mut dyn Backend,
    iterations: usize,
) -> Result<StabilityEstimate, SimError> {
    let (n, p0, v0, free) = start_state(backend)?;
    // No velocities while probing: spring damping would add to the force differences.
    backend.write(NodeField::Velocity, 0, &vec![[0.0; 4]; n])?;
    let (lo, hi) = p0.iter().fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                std::array::from_fn(|a| lo[a].min(p[a] as f64)),
                std::array::from_fn(|a| hi[a].max(p[a] as f64)),
            )
        },
    );
    let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max).max(1e-6);
    // Probe displacement: small against the tissue, large against f32 round-off.
    let eps = 1e-5 * size;

    let forces = |backend: &mut dyn Backend, u: &[[f64; 3]]| -> Result<Vec<Vec4>, SimError> {
        let mut p = p0.clone();
        for (k, &i) in free.iter().enumerate() {
            for a in 0..3 {
                p[i][a] = (p0[i][a] as f64 + eps * u[k][a]) as f32;
            }
        }
        backend.write(NodeField::Position, 0, &p)?;
        // Repeated so that warm-started rotations (shape matching, co-rotated Debunne)
        // converge to this state's: a lagging rotation acts as extra stiffness.
        for _ in 0..ROTATION_SETTLE {
            backend.compute_forces();
        }
        let mut f = vec![[0.0f32; 4]; n];
        backend.read(NodeField::Force, 0..n, &mut f)?;
        Ok(f)
    };

    let zero = vec![[0.0f64; 3]; free.len()];
    let f0 = forces(backend, &zero)?;
    // y = M^-1 K u = -(f - f0) / (eps m)
    let (lambda, done) = power_iteration(free.len(), iterations, 0x9e37_79b9_7f4a_7c15, |u| {
        let f = forces(backend, u)?;
        Ok(free
            .iter()
            .map(|&i| {
                std::array::from_fn(|a| -(f[i][a] as f64 - f0[i][a] as f64) / eps * p0[i][3] as f64)
            })
            .collect())
    })?;
    backend.write(NodeField::Position, 0, &p0)?;
    backend.write(NodeField::Velocity, 0, &v0)?;
    backend.compute_forces();
    Ok(StabilityEstimate {
        max_eigenvalue: lambda,
        critical_dt: if lambda > 0.0 {
            2.0 / lambda.sqrt()
        } else {
            f64::INFINITY
        },
        iterations: done,
    })
}

/// Power iteration on `M^-1 C`, the velocity-proportional part of the forces (a viscous
/// material's damping), with `iterations` force evaluations at the current positions from
/// a fixed pseudo-random velocity field: its largest eigenvalue, 1/s (0 without damping).
/// Positions, velocities and forces are as they were afterwards.
pub fn max_damping_eigenvalue(
    backend: &mut dyn Backend,
    iterations: usize,
) -> Result<f64, SimError> {
    let (n, p0, v0, free) = start_state(backend)?;
    // Probe speed: any, the damping force is linear in the velocities.
    let speed = 1e-3f64;
    let forces = |backend: &mut dyn Backend, u: &[[f64; 3]]| -> Result<Vec<Vec4>, SimError> {
        let mut v = vec![[0.0f32; 4]; n];
        for (k, &i) in free.iter().enumerate() {
            for a in 0..3 {
                v[i][a] = (speed * u[k][a]) as f32;
            }
        }
        backend.write(NodeField::Velocity, 0, &v)?;
        backend.compute_forces();
        let mut f = vec![[0.0f32; 4]; n];
        backend.read(NodeField::Force, 0..n, &mut f)?;
        Ok(f)
    };
    let f0 = forces(backend, &vec![[0.0f64; 3]; free.len()])?;
    // y = M^-1 C u = -(f - f0) / (speed m)
    let (lambda, _) = power_iteration(free.len(), iterations, 0x2545_f491_4f6c_dd1d, |u| {
        let f = forces(backend, u)?;
        Ok(free
            .iter()
            .map(|&i| {
                std::array::from_fn(|a| {
                    -(f[i][a] as f64 - f0[i][a] as f64) / speed * p0[i][3] as f64
                })
            })
            .collect())
    })?;
    backend.write(NodeField::Velocity, 0, &v0)?;
    backend.compute_forces();
    Ok(lambda)
}

/// The largest stable time step with the largest eigenvalues `k` of `M^-1 K` and `c` of
/// `M^-1 C` (module docs): the root of `dt^2 k + 2 dt c = 4`, `2 / sqrt(k)` without
/// damping, `2 / c` without stiffness (`dt c < 2`).
pub fn damped_critical_dt(k: f64, c: f64) -> f64 {
    if k <= 0.0 {
        // Damping alone: `dt c < 2`.
        if c > 0.0 {
            2.0 / c
        } else {
            f64::INFINITY
        }
    } else if c <= 0.0 {
        2.0 / k.sqrt()
    } else {
        // 4 / (c + sqrt(c^2 + 4 k)): the root without cancellation.
        4.0 / (c + (c * c + 4.0 * k).sqrt())
    }
}

/// Power iteration of the operator `apply` on `len` 3-vectors from a pseudo-random start
/// drawn with `seed`, `iterations` applications at most: the norm of the last image of a
/// unit vector (the largest eigenvalue's magnitude) and the applications made.
fn power_iteration(
    len: usize,
    iterations: usize,
    mut seed: u64,
    mut apply: impl FnMut(&[[f64; 3]]) -> Result<Vec<[f64; 3]>, SimError>,
) -> Result<(f64, usize), SimError> {
    let mut u: Vec<[f64; 3]> = (0..len)
        .map(|_| {
            std::array::from_fn(|_| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
        })
        .collect();
    let norm = |u: &[[f64; 3]]| u.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    let (mut lambda, mut done) = (0.0f64, 0);
    for _ in 0..iterations {
        let un = norm(&u);
        if un == 0.0 {
            break;
        }
        u.iter_mut().flatten().for_each(|x| *x /= un);
        u = apply(&u)?;
        lambda = norm(&u);
        done += 1;
    }
    Ok((lambda, done))
}

/// What a probe starts from and restores: the active count, the positions (inverse mass
/// in w) and velocities of the active nodes, and the free ones (inverse mass above 0).
#[allow(clippy::type_complexity)]
fn start_state(
    backend: &mut dyn Backend,
) -> Result<(usize, Vec<Vec4>, Vec<Vec4>, Vec<usize>), SimError> {
    let (p0, v0) = crate::backend::read_active_state(backend)?;
    let n = p0.len();
    let free = (0..n).filter(|&i| p0[i][3] > 0.0).collect();
    Ok((n, p0, v0, free))
}
