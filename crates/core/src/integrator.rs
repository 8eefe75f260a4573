//! The paper's explicit (symplectic) Euler step with mass-proportional damping:
//!
//! `v <- (v + dt (f / m + g)) / (1 + dt c)`,  `x <- x + dt v`
//!
//! The damping term is taken implicitly (the division), which is stable for any `c >= 0`.
//! A node with inverse mass 0 (position w lane) is fixed: its velocity is zero and it does
//! not move.

use crate::math::{with_w, xyz, Vec4};
use crate::scene::Physics;
use glam::Vec3;

/// Time-stepping parameters in the f32 form the kernels use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepParams {
    /// Time step in s.
    pub dt: f32,
    /// Gravity in m/s^2.
    pub gravity: [f32; 3],
    /// `1 / (1 + dt c)` for damping c in 1/s.
    pub damping_factor: f32,
}

impl StepParams {
    /// From the time step `dt` in seconds and the scene's physics table.
    pub fn new(dt: f64, p: &Physics) -> StepParams {
        StepParams {
            dt: dt as f32,
            gravity: p.gravity.map(|g| g as f32),
            damping_factor: (1.0 / (1.0 + dt * p.damping)) as f32,
        }
    }
}

/// Advances one node by one step.
#[inline(always)]
pub fn integrate_node(x: &mut Vec4, v: &mut Vec4, f: Vec4, p: &StepParams) {
    let inv_m = x[3];
    if inv_m == 0.0 {
        *v = [0.0; 4];
        return;
    }
    let vel = (xyz(*v) + p.dt * (xyz(f) * inv_m + Vec3::from_array(p.gravity))) * p.damping_factor;
    *x = with_w(xyz(*x) + p.dt * vel, inv_m);
    *v = with_w(vel, v[3]);
}
