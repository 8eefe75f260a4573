//! Interior sampling of a closed surface, keeping the surface's own vertices as nodes
//! (`surface = "vertices"`; the default resamples them, [`super::resample`]).
//!
//! The surface vertices become nodes; the inside is filled with a cubic lattice of spacing
//! `h` (centred on the surface's bounding box). A lattice point is kept when it lies
//! inside ([`super::ray_columns`]) and at least `h / 2` from the surface, so no interior
//! node crowds a surface vertex. Node cell volumes come from [`super::cell_volume`].

use super::obj::Surface;
use super::ray_columns::ColumnCrossings;
use super::triangle_bins::TriangleBins;
use super::NodeCloud;
use glam::DVec3;

/// A cubic lattice of spacing `h` over a point set's bounds, centred on them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lattice {
    /// Position of lattice point (0, 0, 0).
    pub origin: [f64; 3],
    /// Points along each axis.
    pub dims: [usize; 3],
    /// Spacing in metres.
    pub spacing: f64,
}

impl Lattice {
    /// The lattice of spacing `h` whose points cover the bounds of `points` (centred on
    /// them), plus `margin` more points on every side.
    pub fn covering(points: &[[f64; 3]], h: f64, margin: usize) -> Lattice {
        let (lo, hi) = super::bounds(points);
        // A tolerance of 1e-9 spacings keeps an extent of exactly n spacings at n + 1
        // points (a lattice plane on both bounds), as for boxes.
        let inner: [usize; 3] =
            std::array::from_fn(|a| ((hi[a] - lo[a]) / h + 1e-9).floor() as usize + 1);
        Lattice {
            origin: std::array::from_fn(|a| {
                lo[a] + 0.5 * ((hi[a] - lo[a]) - (inner[a] - 1) as f64 * h) - margin as f64 * h
            }),
            dims: inner.map(|n| n + 2 * margin),
            spacing: h,
        }
    }

    /// Lattice points a surface with these bounds would need at spacing `h` (before
    /// building it, to reject absurd sizes).
    pub fn count(lo: [f64; 3], hi: [f64; 3], h: f64, margin: usize) -> f64 {
        (0..3)
            .map(|a| ((hi[a] - lo[a]) / h + 1e-9).floor() + 1.0 + 2.0 * margin as f64)
            .product()
    }

    /// Position of point `(i, j, k)`.
    pub fn point(&self, p: [usize; 3]) -> [f64; 3] {
        std::array::from_fn(|a| self.origin[a] + p[a] as f64 * self.spacing)
    }
}

/// Surface vertices plus the interior lattice points.
pub fn fill_lattice(surface: &Surface, h: f64) -> NodeCloud {
    let lattice = Lattice::covering(&surface.vertices, h, 0);
    let tris: Vec<[[f64; 3]; 3]> = surface
        .triangles
        .iter()
        .map(|t| t.map(|i| surface.vertices[i as usize]))
        .collect();
    let inside = ColumnCrossings::inside_grid(&tris, lattice.origin, h, lattice.dims);
    let bins = TriangleBins::new(tris, h);
    let mut positions = surface.vertices.clone();
    let [nx, ny, nz] = lattice.dims;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = lattice.point([i, j, k]);
                if inside[i + nx * (j + ny * k)] && bins.distance_capped(p, 0.5 * h) >= 0.5 * h {
                    positions.push(p);
                }
            }
        }
    }
    let node_volumes =
        super::cell_volume::estimate(&positions, bins.triangles(), &lattice, surface.volume);
    NodeCloud {
        positions,
        triangles: surface.triangles.clone(),
        volume: surface.volume,
        node_volumes,
        spacing: h,
    }
}

/// Generalised winding number of `p` with respect to a closed triangle surface: 1 inside,
/// 0 outside.
pub fn winding_number(p: [f64; 3], triangles: &[[[f64; 3]; 3]]) -> f64 {
    let p = DVec3::from(p);
    let mut total = 0.0;
    for t in triangles {
        let a = DVec3::from(t[0]) - p;
        let b = DVec3::from(t[1]) - p;
        let c = DVec3::from(t[2]) - p;
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let num = a.dot(b.cross(c));
        let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        total += 2.0 * num.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Distance from `p` to the nearest point of any triangle.
pub fn distance_to_triangles(p: [f64; 3], triangles: &[[[f64; 3]; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| DVec3::from(p).distance(closest_point_on_triangle(p, t).into()))
        .fold(f64::INFINITY, f64::min)
}

/// Closest point of triangle `t` to `p` (Voronoi regions of vertices, edges and face).
pub fn closest_point_on_triangle(p: [f64; 3], t: &[[f64; 3]; 3]) -> [f64; 3] {
    let p = DVec3::from(p);
    let [a, b, c] = t.map(DVec3::from);
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a.into();
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b.into();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v).into();
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c.into();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w).into();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w).into();
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + (ab * v + ac * w)).into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::box_lattice::BoxLattice;

    #[test]
    fn winding_number_is_one_inside_zero_outside() {
        let c = BoxLattice::with_spacing([0.0; 3], [1.0; 3], 0.5).cloud();
        let tris = c.triangle_corners();
        assert!((winding_number([0.3, 0.4, 0.6], &tris) - 1.0).abs() < 1e-9);
        assert!(winding_number([1.3, 0.4, 0.6], &tris).abs() < 1e-9);
        assert!((distance_to_triangles([0.5, 0.5, 0.9], &tris) - 0.1).abs() < 1e-12);
    }
}
