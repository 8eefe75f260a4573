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

use glam::{Mat3, Quat, Vec3};

/// Stop when the rotation update is below this angle, in radians (about ten f32 ulps of a
/// unit matrix entry; smaller updates are round-off).
pub const ANGLE_TOLERANCE: f32 = 1e-6;

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
}
