//! The stable time step map: for a model and a stiffness, the largest time step that stays
//! bounded over a long run, found by bisection, next to the estimate `2 / sqrt(lambda_max)`
//! of [`needlesim_core::stability`] (power iteration on the model's own forces).
//!
//! The test body is a free 10 cm cube at rest with a 0.1 mm pseudo-random perturbation,
//! undamped (the paper's per-node shape matching gets its damping floor). "Bounded" means
//! no free node reaches 100 times the speed the perturbation starts at the highest
//! frequency, `1e-4 m * sqrt(lambda_max)`.

use super::cases::ModelId;
use crate::constants::{CUBE, NEIGHBOURS, YOUNG};
use crate::error::ReportError;
use needlesim_core::backend::check_bounded;
use needlesim_core::stability::max_eigenvalue;
use needlesim_core::{Backend, CpuBackend, NodeField, Scene, Threading, Tissue};

/// One point of the map.
#[derive(Debug, Clone)]
pub struct StableDt {
    /// The model.
    pub model: ModelId,
    /// Young's modulus (or the calibrated stiffness's modulus) over [`YOUNG`].
    pub stiffness_scale: f64,
    /// Nodes of the test cube.
    pub nodes: usize,
    /// Estimated critical step, s.
    pub estimate: f64,
    /// Largest bounded step found by bisection, s (midpoint of the final bracket).
    pub measured: f64,
    /// Width of the final bracket relative to `measured`.
    pub bracket: f64,
}

fn cube(model: ModelId, scale: f64, side: usize, dt: f64) -> Result<CpuBackend, ReportError> {
    let h = CUBE / (side - 1) as f64;
    let young = YOUNG * scale;
    let scene = Scene::builder()
        .neighbours(NEIGHBOURS)
        .box_with_spacing([0.0; 3], [CUBE; 3], h)
        .material(model.material(young, h))
        .dt(dt)
        .damping(model.damping_floor(young, h))
        .build()
        .expect("valid cube scene");
    let tissue = Tissue::from_scene(&scene).map_err(needlesim::runner::RunError::from)?;
    let mut b =
        CpuBackend::new(tissue, Threading::Parallel).map_err(needlesim::runner::RunError::from)?;
    let n = b.n_active();
    let mut p = vec![[0.0f32; 4]; n];
    b.read(NodeField::Position, 0..n, &mut p)?;
    let mut s = 11u64;
    for c in p.iter_mut().flat_map(|q| q[..3].iter_mut()) {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        *c += 1e-4 * ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) as f32;
    }
    b.write(NodeField::Position, 0, &p)?;
    Ok(b)
}

fn bounded(b: &mut CpuBackend, steps: u64, limit: f64) -> bool {
    let chunk = 50.min(steps).max(1);
    let mut done = 0;
    while done < steps {
        b.step(chunk);
        done += chunk;
        if check_bounded(b, limit).is_err() {
            return false;
        }
    }
    true
}

/// Estimate and bisection (`iterations` halvings of [0.25, 4] x the estimate, each trial
/// `steps` steps long) for one model and stiffness on a cube of `side^3` nodes.
pub fn stable_dt(
    model: ModelId,
    scale: f64,
    side: usize,
    steps: u64,
    iterations: usize,
) -> Result<StableDt, ReportError> {
    let mut probe = cube(model, scale, side, 1e-4)?;
    let est = max_eigenvalue(&mut probe, 60)?;
    let limit = 100.0 * 1e-4 * est.max_eigenvalue.sqrt();
    let (mut lo, mut hi) = (0.25, 4.0);
    for _ in 0..iterations {
        let mid = 0.5 * (lo + hi);
        let mut b = cube(model, scale, side, mid * est.critical_dt)?;
        if bounded(&mut b, steps, limit) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let mid = 0.5 * (lo + hi);
    Ok(StableDt {
        model,
        stiffness_scale: scale,
        nodes: probe.n_active(),
        estimate: est.critical_dt,
        measured: mid * est.critical_dt,
        bracket: (hi - lo) / mid,
    })
}
