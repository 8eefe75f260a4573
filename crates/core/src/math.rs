//! Small fixed-size vector, matrix and quaternion helpers on `[f32; 4]` node vectors
//! (the w lane is ignored by the vector operations) and `[[f32; 3]; 3]` matrices stored
//! as rows.

/// A node vector: x, y, z and a free w lane.
pub type Vec4 = [f32; 4];
/// A 3x3 matrix stored as three rows.
pub type Mat3 = [[f32; 3]; 3];

/// `a + b` on xyz, w = 0.
#[inline(always)]
pub fn add(a: Vec4, b: Vec4) -> Vec4 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2], 0.0]
}
/// `a - b` on xyz, w = 0.
#[inline(always)]
pub fn sub(a: Vec4, b: Vec4) -> Vec4 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2], 0.0]
}
/// `s a` on xyz, w = 0.
#[inline(always)]
pub fn scale(a: Vec4, s: f32) -> Vec4 {
    [a[0] * s, a[1] * s, a[2] * s, 0.0]
}
/// Dot product of the xyz parts.
#[inline(always)]
pub fn dot(a: Vec4, b: Vec4) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// Cross product of the xyz parts.
#[inline(always)]
pub fn cross(a: Vec4, b: Vec4) -> Vec4 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
        0.0,
    ]
}
/// Euclidean length of the xyz part.
#[inline(always)]
pub fn norm(a: Vec4) -> f32 {
    dot(a, a).sqrt()
}
/// Builds a node vector from xyz and w.
#[inline(always)]
pub fn v4(x: [f32; 3], w: f32) -> Vec4 {
    [x[0], x[1], x[2], w]
}

/// Matrix times vector (xyz), w = 0.
#[inline(always)]
pub fn mat_vec(m: &Mat3, v: Vec4) -> Vec4 {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
        0.0,
    ]
}

/// Transposed matrix times vector (xyz), w = 0.
#[inline(always)]
pub fn mat_t_vec(m: &Mat3, v: Vec4) -> Vec4 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
        0.0,
    ]
}

/// Rotation matrix of a unit quaternion stored as `[x, y, z, w]`.
#[inline(always)]
pub fn quat_to_mat(q: Vec4) -> Mat3 {
    let [x, y, z, w] = q;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, xz, yz) = (x * y, x * z, y * z);
    let (wx, wy, wz) = (w * x, w * y, w * z);
    [
        [1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)],
        [2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)],
        [2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)],
    ]
}

/// Hamilton product `a * b` of quaternions stored as `[x, y, z, w]`.
#[inline(always)]
pub fn quat_mul(a: Vec4, b: Vec4) -> Vec4 {
    let [ax, ay, az, aw] = a;
    let [bx, by, bz, bw] = b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

/// Unit quaternion `[x, y, z, w]` of a rotation by `angle` radians about the unit `axis`.
pub fn quat_from_axis_angle(axis: [f32; 3], angle: f32) -> Vec4 {
    let (s, c) = (0.5 * angle).sin_cos();
    [axis[0] * s, axis[1] * s, axis[2] * s, c]
}

/// The identity quaternion.
pub const QUAT_IDENTITY: Vec4 = [0.0, 0.0, 0.0, 1.0];

/// Eigen-decomposition of a symmetric `n x n` matrix (row-major, f64) by cyclic Jacobi
/// rotations: returns the eigenvalues and the eigenvectors as the columns of a row-major
/// matrix. Used only when building shape information, never per step.
pub fn sym_eigen(n: usize, a: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut m = a.to_vec();
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    let scale: f64 = m.iter().map(|x| x * x).sum::<f64>().sqrt();
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|p| (0..n).filter(move |&q| q != p).map(move |q| (p, q)))
            .map(|(p, q)| m[p * n + q] * m[p * n + q])
            .sum::<f64>()
            .sqrt();
        if off <= 1e-15 * scale || scale == 0.0 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = m[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (m[q * n + q] - m[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                // m <- J^T m J with J the rotation in the (p, q) plane.
                for k in 0..n {
                    let mkp = m[k * n + p];
                    let mkq = m[k * n + q];
                    m[k * n + p] = c * mkp - s * mkq;
                    m[k * n + q] = s * mkp + c * mkq;
                }
                for k in 0..n {
                    let mpk = m[p * n + k];
                    let mqk = m[q * n + k];
                    m[p * n + k] = c * mpk - s * mqk;
                    m[q * n + k] = s * mpk + c * mqk;
                }
                for k in 0..n {
                    let vkp = v[k * n + p];
                    let vkq = v[k * n + q];
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..n).map(|i| m[i * n + i]).collect(), v)
}

/// Truncated pseudo-inverse of a symmetric positive semi-definite `n x n` matrix:
/// eigen-directions whose eigenvalue is below `rel_tol` times the largest are dropped
/// (their inverse is taken as 0), so a flat or collinear point set gives a bounded
/// inverse instead of a huge one. Returns the inverse and the number of directions kept.
pub fn sym_pseudo_inverse(n: usize, a: &[f64], rel_tol: f64) -> (Vec<f64>, usize) {
    let (vals, vecs) = sym_eigen(n, a);
    let max = vals.iter().cloned().fold(0.0, f64::max);
    let mut out = vec![0.0; n * n];
    let mut rank = 0;
    for e in 0..n {
        if max.is_nan() || max <= 0.0 || vals[e] <= rel_tol * max {
            continue;
        }
        rank += 1;
        let inv = 1.0 / vals[e];
        for r in 0..n {
            for c in 0..n {
                out[r * n + c] += vecs[r * n + e] * inv * vecs[c * n + e];
            }
        }
    }
    (out, rank)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_matrix_rotates_x_to_y_about_z() {
        let q = quat_from_axis_angle([0.0, 0.0, 1.0], std::f32::consts::FRAC_PI_2);
        let r = quat_to_mat(q);
        let v = mat_vec(&r, [1.0, 0.0, 0.0, 0.0]);
        assert!((v[0]).abs() < 1e-6 && (v[1] - 1.0).abs() < 1e-6 && v[2].abs() < 1e-6);
        let back = mat_t_vec(&r, v);
        assert!((back[0] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn quaternion_product_composes_rotations() {
        let a = quat_from_axis_angle([0.0, 0.0, 1.0], 0.3);
        let b = quat_from_axis_angle([0.0, 0.0, 1.0], 0.4);
        let c = quat_mul(a, b);
        let d = quat_from_axis_angle([0.0, 0.0, 1.0], 0.7);
        for k in 0..4 {
            assert!((c[k] - d[k]).abs() < 1e-6);
        }
    }

    #[test]
    fn pseudo_inverse_inverts_full_rank_and_drops_flat_directions() {
        let a = [4.0, 1.0, 0.0, 1.0, 3.0, 0.5, 0.0, 0.5, 2.0];
        let (inv, rank) = sym_pseudo_inverse(3, &a, 1e-9);
        assert_eq!(rank, 3);
        for r in 0..3 {
            for c in 0..3 {
                let p: f64 = (0..3).map(|k| a[r * 3 + k] * inv[k * 3 + c]).sum();
                assert!(
                    (p - if r == c { 1.0 } else { 0.0 }).abs() < 1e-12,
                    "{r}{c}: {p}"
                );
            }
        }
        // A flat point set (all in z = 0) has no z information: the z row stays 0.
        let flat = [2.0, 0.5, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 1e-14];
        let (inv, rank) = sym_pseudo_inverse(3, &flat, 1e-6);
        assert_eq!(rank, 2);
        assert!(inv[8].abs() < 1e-12 && inv.iter().all(|x| x.is_finite()));
    }
}
