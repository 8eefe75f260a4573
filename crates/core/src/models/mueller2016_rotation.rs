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

use crate::math::{cross, dot, norm, quat_mul, quat_to_mat, Mat3, Vec4};

/// Stop when the rotation update is below this angle, in radians (about ten f32 ulps of a
/// unit matrix entry; smaller updates are round-off).
pub const ANGLE_TOLERANCE: f32 = 1e-6;

/// Column `c` of a row-stored matrix.
#[inline(always)]
fn col(m: &Mat3, c: usize) -> Vec4 {
    [m[0][c], m[1][c], m[2][c], 0.0]
}

/// Refines the unit quaternion `q` (`[x, y, z, w]`) towards the rotation of A with at most
/// `iterations` iterations. A should be scaled to order 1 (the `1e-9` guard is absolute).
#[inline]
pub fn extract_rotation(a: &Mat3, mut q: Vec4, iterations: u32) -> Vec4 {
    for _ in 0..iterations {
        let r = quat_to_mat(q);
        let mut omega = [0.0f32; 4];
        let mut d = 0.0f32;
        for c in 0..3 {
            let rc = col(&r, c);
            let ac = col(a, c);
            let x = cross(rc, ac);
            omega = [omega[0] + x[0], omega[1] + x[1], omega[2] + x[2], 0.0];
            d += dot(rc, ac);
        }
        let inv = 1.0 / (d.abs() + 1e-9);
        omega = [omega[0] * inv, omega[1] * inv, omega[2] * inv, 0.0];
        let angle = norm(omega);
        // Also stops on NaN (a NaN angle fails every comparison).
        if angle.is_nan() || angle < ANGLE_TOLERANCE {
            break;
        }
        // The update quaternion (omega / 2, 1), normalised below, rotates by
        // 2 atan(|omega| / 2) = |omega| + O(|omega|^3) about omega: the same fixed point
        // without a sine and a cosine per iteration.
        q = quat_mul([0.5 * omega[0], 0.5 * omega[1], 0.5 * omega[2], 1.0], q);
        let len = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        q = [q[0] / len, q[1] / len, q[2] / len, q[3] / len];
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{mat_vec, quat_from_axis_angle, QUAT_IDENTITY};

    fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
        std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
    }

    #[test]
    fn recovers_rotation_of_rotated_stretch() {
        // A = R S with S symmetric positive definite; the method must return R.
        let axis = {
            let v = [0.3f32, -0.5, 0.8];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / l, v[1] / l, v[2] / l]
        };
        let r = quat_to_mat(quat_from_axis_angle(axis, 2.0));
        let s: Mat3 = [[1.3, 0.1, 0.0], [0.1, 0.8, 0.05], [0.0, 0.05, 1.1]];
        let a = mat_mul(&r, &s);
        let q = extract_rotation(&a, QUAT_IDENTITY, 50);
        let got = quat_to_mat(q);
        for i in 0..3 {
            for j in 0..3 {
                assert!((got[i][j] - r[i][j]).abs() < 1e-5, "{got:?} vs {r:?}");
            }
        }
    }

    #[test]
    fn degenerate_matrix_keeps_a_unit_quaternion() {
        let zero: Mat3 = [[0.0; 3]; 3];
        let q = extract_rotation(&zero, QUAT_IDENTITY, 10);
        assert_eq!(q, QUAT_IDENTITY);
        // Rank one (collinear cluster): still finite and unit length.
        let a: Mat3 = [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let q = extract_rotation(&a, quat_from_axis_angle([0.0, 1.0, 0.0], 1.0), 10);
        let len: f32 = q.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!((len - 1.0).abs() < 1e-5 && q.iter().all(|x| x.is_finite()));
        let v = mat_vec(&quat_to_mat(q), [1.0, 0.0, 0.0, 0.0]);
        assert!(
            (v[0] - 1.0).abs() < 1e-4,
            "x axis must map to itself: {v:?}"
        );
    }
}
