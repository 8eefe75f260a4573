//! Rotational part of a 3x3 matrix by the warm-started quaternion iteration of Mueller,
//! Bender, Chentanez and Macklin 2016, "A robust method to extract the rotational part of
//! deformations".
//!
//! The rotation R(q) that maximises `sum_c r_c . a_c` over the columns `a_c` of A is the
//! rotation of the polar decomposition A = R S. Each iteration rotates q about
//! `omega = sum_c r_c x a_c / (|sum_c r_c . a_c| + eps)` by about `|omega|`. Starting from the
//! previous step's rotation it converges in one or two iterations; it never divides by
//! zero, and for a degenerate A (collinear or collapsed cluster) it keeps a valid unit
//! quaternion.
//!
//! Kept hand-written rather than taken from nalgebra (`Rotation3::from_matrix_eps` runs the
//! same method on rotation matrices with an exact axis-angle update): the CPU kernel must
//! match the WGSL `extract_rotation` step for step, with one quaternion per node and no
//! sine or cosine per iteration.

use crate::math::sqrt4;
use glam::{Mat3, Quat, Vec3, Vec4 as Lanes4};

/// Stop when the rotation update is below this angle, in radians (about ten f32 ulps of a
/// unit matrix entry; smaller updates are round-off).
///
/// This dead band is what limits shape matching under very small loads: the rotation lags
/// by up to this angle, so a strain of 1e-4 is off by about 1%. A cube clamped on one
/// face (`tests/precision.rs`, dev machine) sags 0.3% (per-node forces) and 1.8%
/// (cluster forces) short at 0.1% of gravity, 3% and 19% at 0.01%. A smaller tolerance
/// does not fix it: at 1e-9 the round-off of a resting cluster's frame rotates it, and
/// a resting shape matching cube drifted (the needle scene of `tests/checkpoint.rs` never
/// touched its moved surface).
pub const ANGLE_TOLERANCE: f32 = 1e-6;

/// Iterations per step by default (the key `rotation_iterations`). Warm started from the
/// previous step, the rotation moves little per step; two iterations keep it converged
/// while halving the cost of eight (measured on the 10932-node bench).
pub const fn default_iterations() -> u32 {
    2
}

/// Refines the unit quaternion `q` towards the rotation of A with at most `iterations`
/// iterations. A should be scaled to order 1 (the `1e-9` guard is absolute).
#[inline]
pub fn extract_rotation(a: &Mat3, mut q: Quat, iterations: u32) -> Quat {
    for _ in 0..iterations {
        let r = Mat3::from_quat(q);
        let mut omega = Vec3::ZERO;
        let mut d = 0.0f32;
        for c in 0..3 {
            let (rc, ac) = (r.col(c), a.col(c));
            omega += rc.cross(ac);
            d += rc.dot(ac);
        }
        omega *= 1.0 / (d.abs() + 1e-9);
        let angle = omega.length();
        // Also stops on NaN (a NaN angle fails every comparison).
        if angle.is_nan() || angle < ANGLE_TOLERANCE {
            break;
        }
        // The update quaternion (omega / 2, 1), normalised below, rotates by
        // 2 atan(|omega| / 2) = |omega| + O(|omega|^3) about omega: the same fixed point
        // without a sine and a cosine per iteration.
        q = Quat::from_xyzw(0.5 * omega.x, 0.5 * omega.y, 0.5 * omega.z, 1.0) * q;
        q = q / q.length();
    }
    q
}

/// [`extract_rotation`] for four independent matrices at once, one per lane: `a[r][c]`
/// holds entry (row r, column c) of each lane's matrix and `q` its warm start as
/// `[x, y, z, w]` lanes. A lane stops where the scalar iteration would (update below
/// [`ANGLE_TOLERANCE`] or not a number) and keeps its quaternion while the others go on,
/// so each lane's result depends on its own inputs only, never on which lanes it shares.
/// The four dependency chains (square roots and divisions) overlap instead of running one
/// after the other.
#[inline]
pub fn extract_rotation4(a: &[[Lanes4; 3]; 3], q: [Lanes4; 4], iterations: u32) -> [Lanes4; 4] {
    let [mut x, mut y, mut z, mut w] = q;
    let (zero, one, half) = (Lanes4::ZERO, Lanes4::ONE, Lanes4::splat(0.5));
    let tol = Lanes4::splat(ANGLE_TOLERANCE);
    let mut active = Lanes4::ONE.cmpeq(one);
    for _ in 0..iterations {
        // R(q), glam's Mat3::from_quat, as columns r[c][row].
        let (x2, y2, z2) = (x + x, y + y, z + z);
        let (xx, xy, xz) = (x * x2, x * y2, x * z2);
        let (yy, yz, zz) = (y * y2, y * z2, z * z2);
        let (wx, wy, wz) = (w * x2, w * y2, w * z2);
        let r = [
            [one - (yy + zz), xy + wz, xz - wy],
            [xy - wz, one - (xx + zz), yz + wx],
            [xz + wy, yz - wx, one - (xx + yy)],
        ];
        let (mut ox, mut oy, mut oz, mut d) = (zero, zero, zero, zero);
        for (c, rc) in r.iter().enumerate() {
            let ac = [a[0][c], a[1][c], a[2][c]];
            ox += rc[1] * ac[2] - rc[2] * ac[1];
            oy += rc[2] * ac[0] - rc[0] * ac[2];
            oz += rc[0] * ac[1] - rc[1] * ac[0];
            d += rc[0] * ac[0] + rc[1] * ac[1] + rc[2] * ac[2];
        }
        let s = one / (d.abs() + Lanes4::splat(1e-9));
        let (ox, oy, oz) = (ox * s, oy * s, oz * s);
        let angle = sqrt4(ox * ox + oy * oy + oz * oz);
        // NaN compares false: a lane whose angle is not a number stops, as in the scalar.
        active &= angle.cmpge(tol);
        if !active.any() {
            break;
        }
        // p = (omega / 2, 1) * q, then normalised.
        let (px, py, pz) = (half * ox, half * oy, half * oz);
        let nx = w * px + x + (py * z - pz * y);
        let ny = w * py + y + (pz * x - px * z);
        let nz = w * pz + z + (px * y - py * x);
        let nw = w - (px * x + py * y + pz * z);
        let len = sqrt4(nx * nx + ny * ny + nz * nz + nw * nw);
        x = Lanes4::select(active, nx / len, x);
        y = Lanes4::select(active, ny / len, y);
        z = Lanes4::select(active, nz / len, z);
        w = Lanes4::select(active, nw / len, w);
    }
    [x, y, z, w]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_rotation_of_rotated_stretch() {
        // A = R S with S symmetric positive definite; the method must return R.
        let axis = Vec3::new(0.3, -0.5, 0.8).normalize();
        let r = Mat3::from_quat(Quat::from_axis_angle(axis, 2.0));
        let s = Mat3::from_cols_array_2d(&[[1.3, 0.1, 0.0], [0.1, 0.8, 0.05], [0.0, 0.05, 1.1]]);
        let a = r * s;
        let q = extract_rotation(&a, Quat::IDENTITY, 50);
        let got = Mat3::from_quat(q);
        assert!(got.abs_diff_eq(r, 1e-5), "{got:?} vs {r:?}");
    }

    #[test]
    fn degenerate_matrix_keeps_a_unit_quaternion() {
        let q = extract_rotation(&Mat3::ZERO, Quat::IDENTITY, 10);
        assert_eq!(q, Quat::IDENTITY);
        // Rank one (collinear cluster): still finite and unit length.
        let a = Mat3::from_cols(Vec3::X, Vec3::ZERO, Vec3::ZERO);
        let q = extract_rotation(&a, Quat::from_axis_angle(Vec3::Y, 1.0), 10);
        assert!((q.length() - 1.0).abs() < 1e-5 && q.is_finite());
        let v = Mat3::from_quat(q) * Vec3::X;
        assert!((v.x - 1.0).abs() < 1e-4, "x axis must map to itself: {v:?}");
    }

    /// Four lanes against four scalar extractions: rotated stretches of growing size,
    /// warm starts near and far, and a collapsed matrix; the quaternions agree to f32
    /// round-off of the different operation order (1e-5), each lane alone or in company.
    #[test]
    fn four_lanes_match_the_scalar_iteration() {
        let mats: Vec<Mat3> = (0..8)
            .map(|k| {
                let axis = Vec3::new(0.3 + k as f32, -0.5, 0.8).normalize();
                let r = Mat3::from_quat(Quat::from_axis_angle(axis, 0.3 * k as f32));
                let s = Mat3::from_cols_array_2d(&[
                    [1.0 + 0.1 * k as f32, 0.1, 0.0],
                    [0.1, 0.8, 0.05],
                    [0.0, 0.05, 1.1],
                ]);
                if k == 5 {
                    Mat3::ZERO
                } else {
                    r * s
                }
            })
            .collect();
        let starts: Vec<Quat> = (0..8)
            .map(|k| Quat::from_axis_angle(Vec3::Y, 0.2 * k as f32 - 0.5))
            .collect();
        for iterations in [1, 4, 20] {
            for group in [[0, 1, 2, 3], [4, 5, 6, 7], [5, 5, 0, 7]] {
                let a: [[Lanes4; 3]; 3] = std::array::from_fn(|r| {
                    std::array::from_fn(|c| Lanes4::from_array(group.map(|m| mats[m].col(c)[r])))
                });
                let q: [Lanes4; 4] = std::array::from_fn(|e| {
                    Lanes4::from_array(group.map(|m| starts[m].to_array()[e]))
                });
                let got = extract_rotation4(&a, q, iterations);
                for (lane, &m) in group.iter().enumerate() {
                    let want = extract_rotation(&mats[m], starts[m], iterations).to_array();
                    for e in 0..4 {
                        let g = got[e].to_array()[lane];
                        assert!(
                            (g - want[e]).abs() < 1e-5,
                            "matrix {m}, {iterations} iterations: {g} vs {}",
                            want[e]
                        );
                    }
                }
            }
        }
    }
}
