//! The material point under a world point: where, in the undeformed tissue, the tissue now
//! at `x` came from.
//!
//! From the current positions `x_j` and rest positions `X_j` of nearby mesh nodes, the
//! weighted least-squares affine map `X(x) = X_c + A (x - x_c)`:
//!
//! `A = [sum w_j (X_j - X_c)(x_j - x_c)^T] [sum w_j (x_j - x_c)(x_j - x_c)^T]^-1`,
//!
//! with `x_c`, `X_c` the weighted centroids and `w_j = (1 - (d_j / r)^2)^2`, `d_j` the
//! distance of `x_j` from `x` and `r` 1.5 times the largest. An affine deformation
//! (stretch, compression, shear, rotation) is recovered exactly, unlike the rigid fit of
//! the node editor (paper section 5.1), which maps points of a compressed neighbourhood
//! back too close to its centroid. Used for the region of an added needle node, and, from
//! the crack front node's own rest position, for the depth of the tip in the tissue and
//! the region it is in ([`crate::Simulation::tissue_depth`]).

use glam::{DMat3, DVec3};

/// Smallest `det(M) / (tr(M) / 3)^3` of the position moment `M` for which the affine fit
/// is used: below it the nodes are nearly coplanar (or collinear) and the fit falls back
/// to the translation of the nearest node.
const MIN_SHAPE: f64 = 1e-6;

/// The affine map from current to rest positions fitted to a set of nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineFit {
    /// Weighted centroid of the current positions.
    pub centre: DVec3,
    /// Weighted centroid of the rest positions.
    pub rest_centre: DVec3,
    /// The gradient `A` (rest per current).
    pub gradient: DMat3,
}

impl AffineFit {
    /// The fit to `nodes` (current, rest), weighted for the point `x`: the least-squares
    /// affine map; with fewer than four nodes or nearly coplanar ones, the translation of
    /// the node nearest to `x` (`gradient` the identity). `None` without nodes.
    pub fn around(x: DVec3, nodes: &[(DVec3, DVec3)]) -> Option<AffineFit> {
        let nearest = nodes
            .iter()
            .min_by(|a, b| a.0.distance_squared(x).total_cmp(&b.0.distance_squared(x)))?;
        let rigid = AffineFit {
            centre: nearest.0,
            rest_centre: nearest.1,
            gradient: DMat3::IDENTITY,
        };
        let r = 1.5 * nodes.iter().map(|n| n.0.distance(x)).fold(0.0, f64::max);
        if nodes.len() < 4 || r <= 0.0 {
            return Some(rigid);
        }
        let w: Vec<f64> = nodes
            .iter()
            .map(|n| (1.0 - (n.0.distance(x) / r).powi(2)).powi(2))
            .collect();
        let total: f64 = w.iter().sum();
        let (mut c, mut c0) = (DVec3::ZERO, DVec3::ZERO);
        for (n, w) in nodes.iter().zip(&w) {
            c += n.0 * (w / total);
            c0 += n.1 * (w / total);
        }
        let (mut m, mut b) = (DMat3::ZERO, DMat3::ZERO);
        for (n, w) in nodes.iter().zip(&w) {
            let (d, d0) = (n.0 - c, n.1 - c0);
            // Outer products d d^T and d0 d^T, column by column.
            m += DMat3::from_cols(d * d.x, d * d.y, d * d.z) * *w;
            b += DMat3::from_cols(d0 * d.x, d0 * d.y, d0 * d.z) * *w;
        }
        let scale = (m.x_axis.x + m.y_axis.y + m.z_axis.z) / 3.0;
        if scale.is_nan() || scale <= 0.0 || m.determinant() / scale.powi(3) < MIN_SHAPE {
            return Some(rigid);
        }
        Some(AffineFit {
            centre: c,
            rest_centre: c0,
            gradient: b * m.inverse(),
        })
    }

    /// The rest position the map gives for current position `x`.
    pub fn rest_of(&self, x: DVec3) -> DVec3 {
        self.rest_centre + self.gradient * (x - self.centre)
    }
}

/// The rest position of the material now at `x`, from `nodes` (current, rest) positions
/// ([`AffineFit::around`]); `None` without nodes.
pub fn material_point(x: DVec3, nodes: &[(DVec3, DVec3)]) -> Option<DVec3> {
    AffineFit::around(x, nodes).map(|f| f.rest_of(x))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 x 3 x 3 lattice, 4 mm apart, at rest.
    fn lattice() -> Vec<DVec3> {
        let mut p = Vec::new();
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    p.push(DVec3::new(i as f64, j as f64, k as f64) * 0.004);
                }
            }
        }
        p
    }

    #[test]
    fn an_affine_deformation_is_inverted_exactly() {
        // Compressed 40 % along x, sheared, rotated and moved: any affine map.
        let rot = DMat3::from_rotation_z(0.7) * DMat3::from_rotation_x(-0.3);
        let f = rot
            * DMat3::from_cols(
                DVec3::new(0.6, 0.0, 0.0),
                DVec3::new(0.2, 1.1, 0.0),
                DVec3::new(0.0, -0.1, 0.9),
            );
        let shift = DVec3::new(0.01, -0.02, 0.005);
        let nodes: Vec<(DVec3, DVec3)> = lattice()
            .into_iter()
            .map(|x0| (f * x0 + shift, x0))
            .collect();
        for x0 in [
            DVec3::new(0.0031, 0.0042, 0.0017),
            DVec3::new(0.009, -0.001, 0.004),
        ] {
            let got = material_point(f * x0 + shift, &nodes).unwrap();
            // Round-off of a 3 x 3 solve on millimetre coordinates.
            assert!(got.distance(x0) < 1e-12, "{got} vs {x0}");
        }
    }

    #[test]
    fn a_rigid_fit_would_miss_compression_which_this_does_not() {
        // Compressed to half along x: the point at 3.2 mm at rest is now at 1.6 mm.
        let f = DMat3::from_diagonal(DVec3::new(0.5, 1.0, 1.0));
        let nodes: Vec<(DVec3, DVec3)> = lattice().into_iter().map(|x0| (f * x0, x0)).collect();
        let x0 = DVec3::new(0.0032, 0.004, 0.004);
        let got = material_point(f * x0, &nodes).unwrap();
        assert!(got.distance(x0) < 1e-12);
        // The translation of the centre node (4 mm at rest, 2 mm now) alone puts it at
        // 3.6 mm, 0.4 mm off.
        let rigid = nodes[13].1 + (f * x0 - nodes[13].0);
        assert!((rigid.x - x0.x - 4e-4).abs() < 1e-12);
    }

    #[test]
    fn coplanar_or_few_nodes_fall_back_to_the_nearest_node() {
        let flat: Vec<(DVec3, DVec3)> = (0..9)
            .map(|k| {
                let x0 = DVec3::new((k % 3) as f64, (k / 3) as f64, 0.0) * 0.004;
                (x0 + DVec3::Z * 0.001, x0)
            })
            .collect();
        let got = material_point(DVec3::new(0.0041, 0.0, 0.0011), &flat).unwrap();
        assert!(got.distance(DVec3::new(0.0041, 0.0, 0.0001)) < 1e-15);
        assert_eq!(material_point(DVec3::ZERO, &[]), None);
        let one = [(DVec3::X, DVec3::Y)];
        assert_eq!(
            material_point(DVec3::X * 2.0, &one),
            Some(DVec3::new(1.0, 1.0, 0.0))
        );
    }
}
