//! The paper's explicit (symplectic) Euler step with mass-proportional damping:
//!
//! `v <- (v + dt (f / m + g)) / (1 + dt c)`,  `x <- x + dt v`
//!
//! The damping term is taken implicitly (the division), which is stable for any `c >= 0`.
//! A node with inverse mass 0 (position w lane) is fixed: its velocity is zero and it does
//! not move.
//!
//! # Positions below f32 resolution
//!
//! Positions are f32, so a node 0.1 m from the origin moves in steps of 7.5e-9 m (1e-7 m
//! at 1 m). A plain `x + dt v` drops every increment smaller than half of that: with a
//! small step and strong damping the velocity near equilibrium is so small that the state
//! freezes far from the answer. Measured on the dev machine (a 10 cm cube of Debunne
//! tissue, E 10 kPa, clamped on one face, dt 1e-4 s, damping 60/s, 2 s): at 0.01% of
//! gravity the free end reached 1.4% of its sag, and translated 1 m from the origin the
//! cube did not move at 0.1% of gravity.
//!
//! The position update is therefore a compensated sum (Kahan 1965; Knuth's TwoSum,
//! TAOCP vol. 2, section 4.2.2): each node keeps the rounding error of its last update,
//! `r` ([`crate::backend::NodeField::PositionRemainder`]), and adds it to the next
//! increment. `x + r` is the position to about 2^-48 of its size, the stored `x` is its
//! nearest f32, and no increment is lost however small. The forces still see the f32 `x`
//! (an error of at most half a unit in the last place, the same as any f32 position); so
//! that this unit is the body's own and not that of its distance from the world's origin,
//! positions are stored in a per-body frame ([`crate::frame`]). The cost is one more
//! array of 16 bytes per node read and written by the integration.
//!
//! TwoSum is used rather than the shorter Fast2Sum because Fast2Sum needs `|x| >= |d|`,
//! which fails for a node near the origin.

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

/// `(s, e)` with `s = fl(a + b)` and `a + b = s + e` exactly (Knuth's TwoSum, for any
/// magnitudes; round-to-nearest f32 without reassociation, which Rust guarantees).
#[inline(always)]
pub fn two_sum(a: Vec3, b: Vec3) -> (Vec3, Vec3) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// Advances one node by one step; `r` is its position remainder (module docs).
#[inline(always)]
pub fn integrate_node(x: &mut Vec4, v: &mut Vec4, r: &mut Vec4, f: Vec4, p: &StepParams) {
    let inv_m = x[3];
    if inv_m == 0.0 {
        *v = [0.0; 4];
        return;
    }
    let vel = (xyz(*v) + p.dt * (xyz(f) * inv_m + Vec3::from_array(p.gravity))) * p.damping_factor;
    let (s, e) = two_sum(xyz(*x), p.dt * vel + xyz(*r));
    *x = with_w(s, inv_m);
    *r = with_w(e, 0.0);
    *v = with_w(vel, v[3]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_sum_is_exact() {
        // 1 + 2^-30 is not an f32: the sum rounds to 1 and the error is 2^-30 exactly.
        let tiny = 2f32.powi(-30);
        let (s, e) = two_sum(Vec3::splat(1.0), Vec3::splat(tiny));
        assert_eq!(s, Vec3::splat(1.0));
        assert_eq!(e, Vec3::splat(tiny));
        // The small operand first (where Fast2Sum would fail).
        let (s, e) = two_sum(Vec3::splat(tiny), Vec3::splat(1.0));
        assert_eq!((s, e), (Vec3::splat(1.0), Vec3::splat(tiny)));
    }

    #[test]
    fn increments_below_resolution_add_up() {
        // A node at 1 m moving 1e-9 m per step (1/120 of f32's spacing there): a plain sum
        // never moves; the compensated one is within one spacing of 1e-6 m after 1000 steps.
        let p = StepParams {
            dt: 1e-3,
            gravity: [0.0; 3],
            damping_factor: 1.0,
        };
        let mut x = [1.0, 1.0, 1.0, 1.0];
        let mut v = [1e-6, 0.0, -1e-6, 0.0];
        let mut r = [0.0; 4];
        for _ in 0..1000 {
            integrate_node(&mut x, &mut v, &mut r, [0.0; 4], &p);
        }
        let ulp = f32::EPSILON as f64;
        for (k, want) in [(0, 1.0 + 1e-6), (1, 1.0), (2, 1.0 - 1e-6)] {
            let got = x[k] as f64 + r[k] as f64;
            assert!(
                (got - want).abs() < 1e-3 * 1e-6,
                "lane {k}: {got} vs {want}"
            );
            assert!(
                (x[k] as f64 - want).abs() <= ulp,
                "lane {k}: stored {}",
                x[k]
            );
        }
        assert_eq!(x[3], 1.0, "inverse mass kept");
    }
}
