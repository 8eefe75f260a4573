//! The node storage type and its boundary with the math crates.
//!
//! Vector, matrix and quaternion arithmetic is done with [`glam`] (`Vec3`, `Mat3`, `Quat`
//! in f32 in the kernels, `DVec3` in the f64 geometry code) and the f64 linear algebra of
//! shape building with [`nalgebra`] (the symmetric eigen-decomposition behind the moment
//! matrix pseudo-inverse in [`crate::models::mls`]). The kernels use glam's scalar `Vec3`,
//! not the SIMD `Vec3A`: its operations round like the hand-written code they replaced and
//! like the WGSL kernels they mirror.
//!
//! What is kept here is the storage layout. Node arrays (positions, velocities, forces,
//! the models' per-node vectors and rotation quaternions) stay `[f32; 4]`: it is the GPU's
//! `vec4<f32>` layout, it is what bytemuck casts to buffer bytes and what checkpoints
//! serialise, and it is the element type of the public [`crate::Backend`] API. A kernel
//! reads a node with [`xyz`] and writes one with [`with_w`]; a stored rotation quaternion
//! `[x, y, z, w]` converts with `glam::Quat::from_array` / `to_array`.

use glam::Vec3;

/// A node vector as stored: x, y, z and a free w lane (inverse mass in positions, node
/// volume in the continuum models' rest positions, 0 elsewhere); also a stored rotation
/// quaternion `[x, y, z, w]`.
pub type Vec4 = [f32; 4];

/// The identity quaternion in the stored `[x, y, z, w]` form.
pub const QUAT_IDENTITY: Vec4 = [0.0, 0.0, 0.0, 1.0];

/// Storage boundary, read: the xyz part of a stored node vector (w is dropped).
#[inline(always)]
pub fn xyz(p: Vec4) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

/// Storage boundary, read, in one 16-byte SIMD load: the xyz part of a stored node vector
/// as `Vec3A` (its operations ignore the w lane and round as `Vec3`'s do).
#[inline(always)]
pub fn xyz_a(p: Vec4) -> glam::Vec3A {
    glam::Vec3A::from_vec4(glam::Vec4::from_array(p))
}

/// Storage boundary, write: a stored node vector from xyz and the w lane.
#[inline(always)]
pub fn with_w(v: Vec3, w: f32) -> Vec4 {
    [v.x, v.y, v.z, w]
}

/// The x, y, z and w lanes (the columns of the result) of the four nodes `j` of `array`:
/// one load per node and a 4x4 transpose, for kernels that work on four neighbour slots
/// at once.
#[inline(always)]
pub fn gather4(array: &[Vec4], j: [usize; 4]) -> glam::Mat4 {
    glam::Mat4::from_cols_array_2d(&[array[j[0]], array[j[1]], array[j[2]], array[j[3]]])
        .transpose()
}

/// Lane-wise square root: `sqrtps` on x86-64 (glam's `Vec4::sqrt` takes four scalar roots
/// there), glam's elsewhere.
#[inline(always)]
pub fn sqrt4(v: glam::Vec4) -> glam::Vec4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        // SAFETY: SSE2 is part of the x86-64 baseline (and required by the cfg).
        #[allow(unused_unsafe)]
        unsafe {
            glam::Vec4::from(std::arch::x86_64::_mm_sqrt_ps(v.into()))
        }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        v.sqrt()
    }
}

/// A small deterministic generator of f32 in [0, 1) (xorshift64) for the kernels' unit
/// tests.
#[cfg(test)]
pub(crate) fn test_rng(mut seed: u64) -> impl FnMut() -> f32 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32
    }
}
